"""What is recorded and when: the laboratory's sensors and the simulation's own probes.

Sensors follow docs/conventions.rst: the wall sensor reads the wall contact force F_N; a sensor
embedded in bead n (bead cut in two halves around a stiff piezo, mass compensated) reads, in the
rigid limit, F_s = (F_{n-1} + F_n) / 2.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import ConfigError
from .strict import count, real

__all__ = ["Probes", "sensor_forces", "default_probes", "AUTO_ALL_CONTACTS", "AUTO_SAMPLED_CONTACTS",
           "DEFAULT_MAX_SAMPLES"]

#: ``contacts = "auto"`` (the default) records every contact of a chain with at most this many
#: contacts (the paper's chains, every example), ...
AUTO_ALL_CONTACTS = 256
#: ... and of a longer one the wall's, the sensors' and this many contacts spread evenly along it
#: (contact 0 and the last included): a 1e4-bead chain recorded every contact (1.6 GB) before.
AUTO_SAMPLED_CONTACTS = 33
#: :func:`default_probes` (``simulate(model, duration)`` without probes) records at most this many
#: samples: the interval is 100 ns, or longer when the run is (a 1e5-bead chain's automatic duration).
DEFAULT_MAX_SAMPLES = 100_000


@dataclass(frozen=True)
class Probes:
    """Recording schedule and signals.

    Parameters
    ----------
    sample_interval
        Time between samples [s], like an oscilloscope's (default 100 ns).
    sensors
        Beads (1..N) with an embedded sensor.
    contacts
        ``"auto"`` (default): every contact of a chain with at most :data:`AUTO_ALL_CONTACTS`
        contacts, else the wall's, the sensors' and :data:`AUTO_SAMPLED_CONTACTS` contacts spread
        evenly along the chain; ``None`` for all of them (a full record, on request); or contact
        numbers (0..N) whose forces are stored. The wall contact and the two contacts of every
        sensor bead are always computed.
    velocities
        Also store the velocity of every body (0 = striker, 1..N beads).
    positions:
        Also store the displacement of every body from its place at impact [m] (what
        ``hertzchain animate`` draws; off by default, so ordinary results stay small).
    """

    sample_interval: float = 1e-7
    sensors: tuple[int, ...] = field(default=())
    contacts: tuple[int, ...] | None | str = "auto"
    velocities: bool = False
    positions: bool = False

    def __post_init__(self) -> None:
        interval = real(self.sample_interval, "run.sample_interval", unit="s")
        if not interval > 0:
            raise ConfigError("run.sample_interval", f"must be a positive time in s, got {self.sample_interval!r}")
        object.__setattr__(self, "sample_interval", interval)
        # Bead and contact numbers are counts (2.7 is refused, not truncated); ranges: validate().
        object.__setattr__(self, "sensors", tuple(count(s, f"probes.sensors[{i}]", low=-2**62)
                                                  for i, s in enumerate(self.sensors)))
        if isinstance(self.contacts, str):
            if self.contacts != "auto":
                raise ConfigError("probes.contacts", f"must be 'auto', 'all' (None) or contact numbers, got {self.contacts!r}")
        elif self.contacts is not None:
            object.__setattr__(self, "contacts", tuple(count(c, f"probes.contacts[{i}]", low=-2**62)
                                                       for i, c in enumerate(self.contacts)))

    def validate(self, n_beads: int, has_wall: bool) -> None:
        """Check bead and contact numbers against a chain of ``n_beads`` beads."""
        for i, s in enumerate(self.sensors):
            if not (1 <= s <= n_beads):
                raise ConfigError(f"probes.sensors[{i}]", f"bead {s} does not exist: beads are numbered 1..{n_beads}")
        if len(set(self.sensors)) != len(self.sensors):
            raise ConfigError("probes.sensors", "a bead is listed twice")
        last = n_beads if has_wall else n_beads - 1
        for i, c in enumerate(self.contacts if isinstance(self.contacts, tuple) else ()):
            if not (0 <= c <= last):
                raise ConfigError(f"probes.contacts[{i}]", f"contact {c} does not exist: contacts are 0..{last}")

    def recorded_contacts(self, n_beads: int, has_wall: bool) -> np.ndarray:
        """Sorted contact numbers the integrator must record (requested + wall + sensors')."""
        n_contacts = n_beads + (1 if has_wall else 0)
        if self.contacts is None or (self.contacts == "auto" and n_contacts <= AUTO_ALL_CONTACTS):
            return np.arange(n_contacts)
        if self.contacts == "auto":
            need = set(np.linspace(0, n_contacts - 1, AUTO_SAMPLED_CONTACTS).round().astype(int).tolist())
        else:
            need = set(self.contacts)
        if has_wall:
            need.add(n_beads)
        for s in self.sensors:
            need.update((s - 1, s) if s < n_contacts else (s - 1,))
        return np.array(sorted(need), dtype=np.int64)


def default_probes(duration: float) -> Probes:
    """What ``simulate(model, duration)`` records without probes: the energies and the contacts of
    ``contacts = "auto"`` every 100 ns, or every ``duration / DEFAULT_MAX_SAMPLES`` when that is
    longer (the record stays within ~1e5 samples however long the run: a 1e5-bead chain's
    automatic duration).

    Parameters
    ----------
    duration : float
        Simulated time [s].

    Returns
    -------
    Probes
        The probes.
    """
    default = Probes.__dataclass_fields__["sample_interval"].default
    assert isinstance(default, float)
    return Probes(sample_interval=max(default, duration / DEFAULT_MAX_SAMPLES))


def sensor_forces(contact_force: np.ndarray, contacts: np.ndarray, sensors: tuple[int, ...]) -> np.ndarray:
    """Force read by sensors embedded in beads ``sensors``: F_s = (F_{n-1} + F_n) / 2 [N].

    ``contact_force`` is (time, contact) for the contact numbers ``contacts``. For the last bead
    of a chain with a free end F_n = 0.
    """
    index = {int(c): i for i, c in enumerate(contacts)}
    out = np.empty((contact_force.shape[0], len(sensors)))
    for k, n in enumerate(sensors):
        left = contact_force[:, index[n - 1]]
        right = contact_force[:, index[n]] if n in index else 0.0
        out[:, k] = 0.5 * (left + right)
    return out
