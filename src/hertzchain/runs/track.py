"""Lateral freedom: beads that may leave the chain's axis, held by a track (the 2D path).

The 1D engine holds a misaligned bead rigidly on its offset line and keeps the axial part of its
contact forces. The paper (Sec. IV, Fig. 3a-b) notes that results depend on whether beads may
move laterally; :func:`simulate_lateral` lets them: every body gets a transverse coordinate,
contact forces act along the line of centres (both components), and a :class:`Track` holds the
beads (a groove's gravity restoring force, an optional spring, Coulomb friction). The compiled
kernels are in :mod:`hertzchain.integrate.drivers.lateral`; an aligned chain gives exactly the 1D
engine's results.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import xarray as xr

from ..errors import ConfigError
from ..model import Model
from ..probes import Probes
from ..checks import check_after_run, check_before_run
from ..result import build_dataset
from .simulation import warn_elastic_limit
from ..laws import spec_of

if TYPE_CHECKING:  # the compiled 2D path (Numba) loads only when a lateral run is made
    from ..integrate.drivers.lateral import LateralArrays

__all__ = ["Track", "simulate_lateral", "check_lateral", "lateral_arrays"]


@dataclass(frozen=True)
class Track:
    """The track that holds the bodies (striker and beads) across the chain's axis.

    Every body i rests on a line y = e_i (its offset; 0 for aligned beads and the striker). A
    transverse displacement y - e_i meets

    - the groove: a round groove of cross-section radius ``groove_radius`` R_g lifts a bead of
      radius R by ~ (y - e)^2 / (2 (R_g - R)), so gravity pulls it back with m g (y - e) / (R_g - R)
      (small-slope pendulum); None is a flat bed (no restoring force);
    - a spring of stiffness ``spring`` [N/m] per body (a stiff guide; 0 = none);
    - Coulomb friction mu m g against the transverse velocity w, regularised as
      mu m g w / sqrt(w^2 + v_s^2) with v_s = ``slip_velocity`` (so that it never adds energy).

    Parameters
    ----------
    groove_radius : float or None
        Radius [m] of the groove's cross-section, larger than every bead and the striker; None:
        flat bed.
    spring : float
        Transverse spring stiffness [N/m] per body.
    friction : float
        Coulomb coefficient mu with the track (normal force m g).
    slip_velocity : float
        Regularisation speed v_s [m/s] of the friction.
    gravity : float
        g [m/s^2].
    """

    groove_radius: float | None = None
    spring: float = 0.0
    friction: float = 0.0
    slip_velocity: float = 1e-5
    gravity: float = 9.81

    def __post_init__(self) -> None:
        if self.groove_radius is not None and not (math.isfinite(self.groove_radius) and self.groove_radius > 0):
            raise ConfigError("track.groove_radius", f"must be a positive radius in m or None, got {self.groove_radius!r}")
        for name in ("spring", "friction", "gravity"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ConfigError(f"track.{name}", f"must be a finite number >= 0, got {value!r}")
        if not (math.isfinite(self.slip_velocity) and self.slip_velocity > 0):
            raise ConfigError("track.slip_velocity", f"must be a positive speed in m/s, got {self.slip_velocity!r}")

    def describe(self) -> dict:
        """Plain-data description (stored in result attributes)."""
        return {"groove_radius": self.groove_radius, "spring": self.spring, "friction": self.friction,
                "slip_velocity": self.slip_velocity, "gravity": self.gravity}


def lateral_arrays(model: Model, track: Track) -> LateralArrays:
    """Per-body transverse stiffness [N/m], full-slip friction force [N] and rest line [m] of ``model`` on ``track``.

    Parameters
    ----------
    model : Model
        Chain, striker, wall and contact law.
    track : Track
        The track holding the bodies.

    Returns
    -------
    LateralArrays
        (N+2,) arrays (bodies 0..N and the wall ghost, which gets zeros).
    """
    from ..integrate.drivers.lateral import LateralArrays

    n = model.chain.n_beads
    assert model.striker is not None  # a lateral run takes plain models: a sphere striker (simulate_lateral)
    mass = np.concatenate([[model.striker.mass], model.chain.masses, [0.0]])
    radius = np.concatenate([[model.striker.diameter / 2], model.chain.radii, [0.0]])
    stiffness = np.full(n + 2, float(track.spring))
    if track.groove_radius is not None:
        if track.groove_radius <= radius.max():
            raise ConfigError("track.groove_radius", f"({track.groove_radius * 1e3:g} mm) must exceed the largest body "
                              f"radius ({radius.max() * 1e3:g} mm)")
        stiffness += mass * track.gravity / (track.groove_radius - radius)
    stiffness[n + 1] = 0.0
    rest = np.concatenate([[0.0], model.chain.offsets, [0.0]])
    return LateralArrays(stiffness=stiffness, friction=track.friction * mass * track.gravity, rest=rest,
                         slip_velocity=float(track.slip_velocity))


_LATERAL_VARIABLES = {
    "lateral_kinetic_energy": ("J", "kinetic energy of the transverse motion"),
    "friction_loss": ("J", "energy dissipated by the track's Coulomb friction"),
    "contact_loss": ("J", "energy dissipated by the contact law"),
    "lateral_displacement": ("m", "transverse displacement y - e of the body from its rest line"),
    "momentum": ("kg m s-1", "total momentum of striker and beads (axial, transverse)"),
}


def check_lateral(model: Model, duration: float, probes: Probes, *, integrator: str = "verlet",
                  dt: float | None = None):
    """What :func:`simulate_lateral` refuses (ConfigError naming the field) before it allocates or
    compiles anything: the duration and probes, a model the lateral path does not take, the
    integrator, and the 1D run's checks (static overlaps, memory). Returns ``model.system()``."""
    if not (math.isfinite(duration) and duration > 0):
        raise ConfigError("run.duration", f"must be a positive time in s, got {duration!r}")
    if probes.sample_interval > duration:
        raise ConfigError("run.sample_interval", f"({probes.sample_interval:g} s) is longer than run.duration ({duration:g} s)")
    if model.precompression > 0:
        raise ConfigError("chain.precompression", "is not supported with lateral freedom")
    if spec_of(model.law).generated:
        raise ConfigError("contact.law", f"law {model.law.name!r} runs on the axial engines only; run it without [track]")
    if spec_of(model.law).plastic:
        raise ConfigError("contact.law", "the elastoplastic law is not supported with lateral freedom (its "
                          "per-contact history is carried by the axial engine only); run it without [track]")
    if not model.plain:
        field_name = ("wall.type" if model.wall.is_body else "chain.gravity" if model.gravity else
                      "chain.elements" if not model.chain.plain else "striker")
        raise ConfigError(field_name, "lateral freedom ([track]) models spheres hit by a sphere against a flat or "
                          "a free end, without gravity along the chain; this model is for the 1D engine only")
    system = model.system()
    probes.validate(model.chain.n_beads, model.wall.present)
    if integrator not in ("verlet", "dop853"):
        raise ConfigError("run.integrator", f"must be 'verlet' or 'dop853' with lateral freedom, got {integrator!r}")
    check_before_run(model, system, duration, probes, dt=dt, integrator=integrator)  # the 1D run's checks
    return system


def simulate_lateral(model: Model, track: Track, duration: float, probes: Probes | None = None, *,
                     integrator: str = "verlet", dt: float | None = None,
                     rtol: float = 1e-12, config: dict | None = None) -> xr.Dataset:
    """Simulate ``model`` with transverse freedom on ``track`` for ``duration`` [s].

    The result has the layout of :func:`hertzchain.simulate` (``contact_force`` and
    ``wall_force`` are the axial components, what a sensor on the axis reads; ``kinetic_energy``
    includes the transverse motion, ``potential_energy`` the track's, ``dissipated_energy`` the
    contact law's and the friction's), plus ``lateral_kinetic_energy``, ``friction_loss``,
    ``contact_loss``, ``lateral_displacement`` (time, body) and ``momentum`` (time, component).

    Parameters
    ----------
    model : Model
        Chain (its offsets are the rest lines of the beads), striker, wall, contact law; no
        precompression.
    track : Track
        What holds the bodies across the axis.
    duration : float
        Simulated time [s].
    probes : Probes, optional
        Sample interval, recorded contacts and sensors (velocities are not recorded here).
    integrator : {"verlet", "dop853"}
        Compiled velocity Verlet (adaptive step when ``dt`` is None) or the scipy DOP853 reference.
    dt : float, optional
        Fixed Verlet step [s].
    rtol : float
        Relative tolerance of the DOP853 reference.
    config : dict, optional
        The input that produced the run (stored as JSON in the ``config`` attribute).

    Returns
    -------
    xarray.Dataset
        The run, SI units.

    Raises
    ------
    ConfigError
        A bad input (precompression, the elastoplastic law, integrator, track) or records that cannot
        fit in memory.
    SimulationDiverged
        The integration became non-finite or gained energy (:mod:`hertzchain.checks`).

    Warns
    -----
    ElasticLimitWarning
        When a recorded contact force passes the contact's elastic limit (paper Sec. II).
    """
    probes = probes or Probes()
    system = check_lateral(model, duration, probes, integrator=integrator, dt=dt)
    from ..integrate.drivers.lateral import LateralRun, run_lateral, run_lateral_reference

    rec = probes.recorded_contacts(model.chain.n_beads, model.wall.present)
    lat = lateral_arrays(model, track)
    if integrator == "verlet":
        run: LateralRun = run_lateral(system, lat, duration, probes.sample_interval, dt=dt, contacts=rec)
    else:
        run = run_lateral_reference(system, lat, duration, probes.sample_interval, rtol=rtol)
        keep = np.searchsorted(run.raw.contacts, rec)
        run.raw.contact_force = run.raw.contact_force[:, keep]
        run.raw.contacts = np.asarray(rec)
        run.raw.velocity = None
    ds = build_dataset(run.raw, model, probes, duration=duration, system=system, config=config,
                       extra_attrs={"lateral_freedom": 1, "track": json.dumps(track.describe())})
    n = model.chain.n_beads
    values = {"lateral_kinetic_energy": (("time",), run.lateral_kinetic_energy),
              "friction_loss": (("time",), run.friction_loss),
              "contact_loss": (("time",), run.contact_loss),
              "lateral_displacement": (("time", "body"), run.lateral_position - lat.rest[: n + 1]),
              "momentum": (("time", "component"), run.momentum)}
    for name, (dims, arr) in values.items():
        units, long_name = _LATERAL_VARIABLES[name]
        ds[name] = xr.Variable(dims, arr, attrs={"units": units, "long_name": long_name})
    ds = ds.assign_coords(body=np.arange(n + 1), component=["axial", "transverse"])
    # energy balance (friction losses counted as dissipated), Hertz range, pulse arrival
    check_after_run(ds, model, system, dt=dt, integrator=integrator, rtol=rtol, stacklevel=3)
    warn_elastic_limit(ds, stacklevel=3)
    return ds
