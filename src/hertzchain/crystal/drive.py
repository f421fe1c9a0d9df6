"""What drives a chain besides the striker: a harmonic or chirped force on bead 1, or the
prescribed position of a massless driver pressed against bead 1 (docs/guide/crystals.rst).

The drive signal (both quantities; A the amplitude in N or m):

    s(t) = A r(t) sin(phi(t)),    phi(t) = 2 pi (f0 t + (f1 - f0) t^2 / (2 T)) for t <= T,

continued at f1 after T (``type = "chirp"``, T = ``sweep_time``; a harmonic drive has f1 = f0),
and the ramp r(t) = sin^2(pi t / (2 T_r)) for t < T_r = ``ramp_cycles`` / f0, 1 after it, so that
the drive starts with zero force and zero slope (a smaller transient than a step in amplitude).

- ``quantity = "force"``: s(t) [N] is added to bead 1's forces, along the chain towards the wall;
- ``quantity = "displacement"``: the driver (body 0, massless) sits at u_0(t) = s(t) [m] from its
  static place, touching bead 1 through a Hertz contact of the striker's face and material (the
  precompression F0 is then applied by the driver through that contact, so contact 0 carries F0
  at rest). Its force on bead 1 is the contact force F_0.

This module holds the description only (checked fields, the signal in NumPy for analysis); the
compiled loop is :mod:`hertzchain.crystal.drive_kernel`.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from typing import Literal

import numpy as np

from ..errors import ConfigError

__all__ = ["Drive", "drive_parameters"]

TYPES = ("harmonic", "chirp")
#: Cycles a driven run lasts after the ramp with ``run.duration = "auto"``.
AUTO_CYCLES = 100
#: The sweep time [s] of a harmonic drive: never reached (finite, so that 0 * T stays 0).
NEVER = 1e300
QUANTITIES = ("force", "displacement")


def _positive(value, name: str, what: str, allow_zero: bool = False) -> float:
    ok = isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(value)
    if not ok or value < 0 or (value == 0 and not allow_zero):
        raise ConfigError(f"drive.{name}", f"must be {what}, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class Drive:
    """A drive on bead 1 (see the module docstring for the signal).

    Parameters
    ----------
    type : {"harmonic", "chirp"}
        Constant frequency, or a linear sweep from ``frequency`` to ``frequency_end`` over
        ``sweep_time``.
    quantity : {"force", "displacement"}
        A force [N] on bead 1, or the position [m] of a massless driver in Hertz contact with it.
    amplitude : float
        A [N] or [m], > 0.
    frequency : float
        Drive frequency f0 [Hz] (a chirp's start), > 0.
    ramp_cycles : float
        Cycles of f0 over which the amplitude rises as sin^2 (0: at once).
    frequency_end : float, optional
        A chirp's final frequency f1 [Hz].
    sweep_time : float, optional
        A chirp's duration T [s].
    striker : bool
        Keep the striker (a force drive only): it hits bead 1 as usual while the drive acts.
        False (default): no striker (contact 0 is absent, or is the driver's).
    """

    type: Literal["harmonic", "chirp"] = "harmonic"
    quantity: Literal["force", "displacement"] = "force"
    amplitude: float = 1.0
    frequency: float = 1000.0
    ramp_cycles: float = 5.0
    frequency_end: float | None = None
    sweep_time: float | None = None
    striker: bool = False

    def __post_init__(self) -> None:
        if self.type not in TYPES:
            raise ConfigError("drive.type", f"must be one of {', '.join(TYPES)}, got {self.type!r}")
        if self.quantity not in QUANTITIES:
            raise ConfigError("drive.quantity", f"must be 'force' or 'displacement', got {self.quantity!r}")
        unit = "N" if self.quantity == "force" else "m"
        object.__setattr__(self, "amplitude", _positive(self.amplitude, "amplitude", f"a positive amplitude in {unit}"))
        object.__setattr__(self, "frequency", _positive(self.frequency, "frequency", "a positive frequency in Hz"))
        object.__setattr__(self, "ramp_cycles", _positive(self.ramp_cycles, "ramp_cycles", "a number of cycles >= 0",
                                                          allow_zero=True))
        if self.type == "chirp":
            if self.frequency_end is None or self.sweep_time is None:
                raise ConfigError("drive.frequency_end" if self.frequency_end is None else "drive.sweep_time",
                                  "a chirp needs frequency_end [Hz] and sweep_time [s]")
            object.__setattr__(self, "frequency_end", _positive(self.frequency_end, "frequency_end",
                                                                "a positive frequency in Hz"))
            object.__setattr__(self, "sweep_time", _positive(self.sweep_time, "sweep_time", "a positive time in s"))
        elif self.frequency_end is not None or self.sweep_time is not None:
            raise ConfigError("drive.frequency_end" if self.frequency_end is not None else "drive.sweep_time",
                              "belongs to a chirp (drive.type = 'chirp')")
        if not isinstance(self.striker, bool):
            raise ConfigError("drive.striker", f"must be true or false, got {self.striker!r}")
        if self.striker and self.quantity == "displacement":
            raise ConfigError("drive.striker", "a displacement drive's driver takes the striker's place at bead 1: "
                              "drive.striker = true is supported with quantity = 'force' only")

    @property
    def ramp_time(self) -> float:
        """T_r = ramp_cycles / f0 [s]."""
        return self.ramp_cycles / self.frequency

    @property
    def auto_duration(self) -> float:
        """The duration [s] of ``run.duration = "auto"``: the ramp and AUTO_CYCLES cycles of f0 (a
        chirp: its sweep and AUTO_CYCLES cycles of its last frequency after it)."""
        if self.type == "chirp":
            return self.ramp_time + self.sweep_time + AUTO_CYCLES / self.frequency_end
        return self.ramp_time + AUTO_CYCLES / self.frequency

    @property
    def highest_frequency(self) -> float:
        """The highest frequency the drive reaches [Hz]."""
        return max(self.frequency, self.frequency_end or 0.0)

    def signal(self, t: np.ndarray) -> np.ndarray:
        """s(t) [N or m] at times ``t`` [s] (module docstring); the compiled loop computes the same."""
        p = drive_parameters(self)
        t = np.asarray(t, dtype=float)
        f0, rate, tsw, tr = p[1], p[2], p[3], p[4]
        ts = np.minimum(t, tsw)
        phase = 2.0 * np.pi * (f0 * ts + 0.5 * rate * ts * ts + (f0 + rate * tsw) * np.maximum(t - tsw, 0.0))
        ramp = np.where(t < tr, np.sin(0.5 * np.pi * t / np.where(tr > 0, tr, 1.0)) ** 2, 1.0)
        return p[0] * ramp * np.sin(phase)

    def describe(self) -> dict:
        """Plain-data description (stored in result attributes)."""
        out = {"type": self.type, "quantity": self.quantity, "amplitude": self.amplitude, "frequency": self.frequency,
               "ramp_cycles": self.ramp_cycles, "striker": self.striker}
        if self.type == "chirp":
            out.update(frequency_end=self.frequency_end, sweep_time=self.sweep_time)
        return out


def drive_parameters(drive: Drive) -> np.ndarray:
    """The scalars the compiled loop reads: (A, f0, sweep rate (f1 - f0) / T [Hz/s], T [s], T_r [s])."""
    if drive.type == "chirp":
        rate, tsw = (drive.frequency_end - drive.frequency) / drive.sweep_time, drive.sweep_time
    else:
        rate, tsw = 0.0, NEVER
    return np.array([drive.amplitude, drive.frequency, rate, tsw, drive.ramp_time])
