"""What drives a chain besides the striker: a harmonic or chirped force on bead 1, or the
prescribed position of a massless driver pressed against bead 1 (docs/guide/crystals.rst).

The drive signal (both quantities; A the amplitude in N or m):

    s(t) = A r(t) sin(phi(t)),    phi(t) = 2 pi (f0 t + (f1 - f0) t^2 / (2 T)) for t <= T,

continued at f1 after T (``type = "chirp"``, T = ``sweep_time``; a harmonic drive has f1 = f0),
or any history read from a CSV file (``type = "history"``, :func:`read_history`: s(t) interpolated
linearly between its rows, held at its last value after them, no ramp), and the ramp r(t) = sin^2(pi t / (2 T_r)) for t < T_r = ``ramp_cycles`` / f0, 1 after it, so that
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
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from ..errors import ConfigError

__all__ = ["Drive", "check_drive_fits", "drive_parameters", "drive_table", "read_history"]

TYPES = ("harmonic", "chirp", "history")
#: Cycles a driven run lasts after the ramp with ``run.duration = "auto"``.
AUTO_CYCLES = 100
#: The sweep time [s] of a harmonic drive: never reached (finite, so that 0 * T stays 0).
NEVER = 1e300
QUANTITIES = ("force", "displacement")
ENDS = ("first", "last")


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
    end : {"first", "last"}
        Where the drive enters: bead 1 (default; the wall after bead N), or bead N, the chain then
        resting with bead 1 on the wall (:mod:`hertzchain.crystal.ends`): the transmission is
        measured at the other end in both cases.
    striker : bool
        Keep the striker (a force drive only): it hits bead 1 as usual while the drive acts.
        False (default): no striker (contact 0 is absent, or is the driver's).
    file : str, optional
        A history's CSV file (``type = "history"``): columns ``time_s`` and ``value`` (N or m),
        times increasing from 0, first value 0 (the run starts from the static state).
    table : tuple of numpy.ndarray, optional
        The history's rows (times [s], values [N or m]), read from ``file`` by the constructor;
        not given by the caller.
    """

    type: Literal["harmonic", "chirp"] = "harmonic"
    quantity: Literal["force", "displacement"] = "force"
    amplitude: float = 1.0
    frequency: float = 1000.0
    ramp_cycles: float = 5.0
    frequency_end: float | None = None
    sweep_time: float | None = None
    end: Literal["first", "last"] = "first"
    striker: bool = False
    file: str | None = None
    table: tuple | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        if self.type == "history":
            if self.file is None:
                raise ConfigError("drive.file", "a history drive (type = 'history') needs its CSV file")
            object.__setattr__(self, "table", read_history(self.file))
        elif self.file is not None:
            raise ConfigError("drive.file", "belongs to a history drive (drive.type = 'history')")
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
        if self.end not in ENDS:
            raise ConfigError("drive.end", f"must be 'first' (bead 1) or 'last' (bead N), got {self.end!r}")
        if self.striker and self.end == "last":
            raise ConfigError("drive.striker", "the striker hits bead 1, which rests on the wall when the drive "
                              "enters at bead N (drive.end = 'last'): leave drive.striker out")
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
        if self.type == "history":
            return float(self.table[0][-1])
        if self.type == "chirp":
            assert self.sweep_time is not None and self.frequency_end is not None  # a chirp has both (__post_init__)
            return self.ramp_time + self.sweep_time + AUTO_CYCLES / self.frequency_end
        return self.ramp_time + AUTO_CYCLES / self.frequency

    @property
    def highest_frequency(self) -> float:
        """The highest frequency the drive reaches [Hz] (a history: the Nyquist frequency of its rows)."""
        if self.type == "history":
            return float(0.5 / np.min(np.diff(self.table[0])))
        return max(self.frequency, self.frequency_end or 0.0)

    def signal(self, t: np.ndarray) -> np.ndarray:
        """s(t) [N or m] at times ``t`` [s] (module docstring); the compiled loop computes the same."""
        p = drive_parameters(self)
        t = np.asarray(t, dtype=float)
        if self.type == "history":
            return np.interp(t, self.table[0], self.table[1])
        f0, rate, tsw, tr = p[1], p[2], p[3], p[4]
        ts = np.minimum(t, tsw)
        phase = 2.0 * np.pi * (f0 * ts + 0.5 * rate * ts * ts + (f0 + rate * tsw) * np.maximum(t - tsw, 0.0))
        ramp = np.where(t < tr, np.sin(0.5 * np.pi * t / np.where(tr > 0, tr, 1.0)) ** 2, 1.0)
        return p[0] * ramp * np.sin(phase)

    def describe(self) -> dict:
        """Plain-data description (stored in result attributes)."""
        out: dict[str, Any] = {"type": self.type, "quantity": self.quantity, "amplitude": self.amplitude,
                               "frequency": self.frequency, "ramp_cycles": self.ramp_cycles, "striker": self.striker}
        if self.end != "first":  # (left out at the default: the fingerprints of earlier spectra stay)
            out["end"] = self.end
        if self.type == "chirp":
            out.update(frequency_end=self.frequency_end, sweep_time=self.sweep_time)
        if self.type == "history":
            out.update(file=str(self.file), rows=int(self.table[0].size))
        return out


def check_drive_fits(drive, has_striker: bool, has_wall: bool) -> None:
    """Refuse a drive that does not fit its model (ConfigError naming the field): not a Drive, a
    drive entering at bead N with no wall to push the chain onto, the striker kept without one."""
    if getattr(drive, "quantity", None) not in QUANTITIES:
        raise ConfigError("drive", f"must be a hertzchain.Drive, got {drive!r}")
    if drive.end == "last" and not has_wall:
        raise ConfigError("drive.end", "a drive entering at bead N (drive.end = 'last') pushes the chain onto the "
                          "wall at bead 1's end: wall.type = 'none' leaves nothing to transmit to")
    if drive.striker and not has_striker:
        raise ConfigError("drive.striker", "keeps the striker hitting bead 1, but the model has none (striker=None)")


def drive_parameters(drive: Drive) -> np.ndarray:
    """The scalars the compiled loop reads: (A, f0, sweep rate (f1 - f0) / T [Hz/s], T [s], T_r [s],
    1 for a history else 0)."""
    if drive.type == "history":
        return np.array([1.0, 1.0, 0.0, NEVER, 0.0, 1.0])
    if drive.type == "chirp":
        assert drive.sweep_time is not None and drive.frequency_end is not None  # a chirp has both (__post_init__)
        rate, tsw = (drive.frequency_end - drive.frequency) / drive.sweep_time, drive.sweep_time
    else:
        rate, tsw = 0.0, NEVER
    return np.array([drive.amplitude, drive.frequency, rate, tsw, drive.ramp_time, 0.0])


def drive_table(drive: Drive) -> tuple[np.ndarray, np.ndarray]:
    """(times [s], values) the compiled loop interpolates (two dummy rows for a harmonic or chirp)."""
    if drive.type == "history":
        return drive.table
    return np.array([0.0, 1.0]), np.zeros(2)


#: Rows a history file may hold.
MAX_HISTORY_ROWS = 10_000_000


def read_history(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Read a drive history: a CSV file with the header ``time_s,value`` and rows of two finite
    numbers, times strictly increasing from 0, first value 0 (every field checked; ConfigError
    naming ``drive.file`` and the line)."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError("drive.file", f"cannot read {path}: {exc}") from None
    if not lines or [x.strip() for x in lines[0].split(",")] != ["time_s", "value"]:
        raise ConfigError("drive.file", f"{path}: the first line must be the header time_s,value")
    rows = [x for x in lines[1:] if x.strip()]
    if not 2 <= len(rows) <= MAX_HISTORY_ROWS:
        raise ConfigError("drive.file", f"{path}: needs 2 to {MAX_HISTORY_ROWS} rows, has {len(rows)}")
    data = np.empty((len(rows), 2))
    for k, line in enumerate(rows):
        parts = line.split(",")
        try:
            data[k] = [float(x) for x in parts] if len(parts) == 2 else [math.nan, math.nan]
        except ValueError:
            data[k] = math.nan
        if not np.all(np.isfinite(data[k])):
            raise ConfigError("drive.file", f"{path}: row {k + 1} is not two finite numbers: {line!r}")
    t, v = data[:, 0].copy(), data[:, 1].copy()
    if t[0] != 0.0 or v[0] != 0.0:
        raise ConfigError("drive.file", f"{path}: the history must start at time_s = 0 with value 0 (the run starts "
                          f"from the static state), got {t[0]!r}, {v[0]!r}")
    if np.any(np.diff(t) <= 0):
        k = int(np.flatnonzero(np.diff(t) <= 0)[0]) + 2
        raise ConfigError("drive.file", f"{path}: times must increase strictly (row {k})")
    return t, v
