"""Steady-state transmission of a driven chain against frequency (stepped sine) and amplitude.

For each drive frequency f the chain is driven (``Model.drive``, :mod:`hertzchain.crystal.drive`)
for its ramp, ``settle_cycles`` cycles for the transient to die out, and ``measure_cycles`` cycles
over which the output force and the drive's force are projected onto the drive frequency
(:func:`lock_in`: a least-squares fit of c + a cos(2 pi f t) + b sin(2 pi f t) over whole periods,
which is the Fourier coefficient at f, free of the mean and of the harmonics). The transmission is

    T(f) = abs(F_out(f)) / abs(F_in(f)),

F_out the last contact's force (the wall's; contact N - 1 with a free end), F_in the drive's
force on bead 1 (its amplitude A for a force drive, contact 0's force for a displacement drive):
DESIGN convention, docs/guide/crystals.rst. The transient decays only through dissipation: an
elastic chain driven at a resonance never settles (give the contact law some damping).

:func:`transmission_spectrum` runs the frequencies a batch at a time on the batched driven engine
(:func:`transmission_batch`: one compiled call, one member per frequency, each with its own step
and state, so each frequency's result is that of its run alone, :func:`transmission_run`, bit for
bit), writes each batch as it completes (``DIR/transmission.csv``, rewritten atomically), and a
rerun with the same settings skips the frequencies already there.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from pathlib import Path
from typing import Callable

import numpy as np
import xarray as xr

from ..errors import ConfigError

__all__ = ["lock_in", "steady_transmission", "transmission_run", "transmission_batch", "transmission_spectrum",
           "SpectrumSettings", "read_rows", "transmission_against_amplitude", "DEFAULT_BATCH"]

#: Drives run in one compiled call by default (the frequencies a spectrum writes at a time).
DEFAULT_BATCH = 8

CSV_HEADER = "frequency_Hz,transmission,output_amplitude_N,input_amplitude_N"


def lock_in(time: np.ndarray, signal: np.ndarray, frequency: float, cycles: float) -> complex:
    """Complex amplitude [units of ``signal``] at ``frequency`` [Hz] over the last whole ``cycles``
    periods of the record: a + i b of the least-squares fit c + a cos(w t) + b sin(w t) (its modulus is the
    amplitude)."""
    n = int(math.floor(cycles + 1e-9))
    if n < 1:
        raise ConfigError("measure_cycles", f"must be at least one whole period, got {cycles!r}")
    t_end = float(time[-1])
    start = t_end - n / frequency
    sel = time >= start - 1e-9 / frequency
    t, y = time[sel], signal[sel]
    if t.size > 1 and abs((t[-1] - t[0]) * frequency - n) < 1e-6:
        t, y = t[:-1], y[:-1]  # uniform samples over exactly n periods: drop the repeated end point
    w = 2.0 * np.pi * frequency
    basis = np.column_stack([np.ones_like(t), np.cos(w * t), np.sin(w * t)])
    coef = np.linalg.lstsq(basis, y, rcond=None)[0]
    return complex(coef[1], coef[2])


def steady_transmission(ds: xr.Dataset, frequency: float, measure_cycles: float) -> tuple[float, float, float]:
    """(T, abs(F_out) [N], abs(F_in) [N]) of a driven run ``ds`` over its last ``measure_cycles`` periods."""
    out = ds.wall_force.values if "wall_force" in ds else ds.contact_force.isel(contact=-1).values
    return _ratio(ds.time.values, out, ds.drive_force.values, frequency, measure_cycles)


def _ratio(t, out, drive_force, frequency: float, measure_cycles: float) -> tuple[float, float, float]:
    f_out = abs(lock_in(t, out, frequency, measure_cycles))
    f_in = abs(lock_in(t, drive_force, frequency, measure_cycles))
    return f_out / f_in, f_out, f_in


@dataclasses.dataclass(frozen=True)
class SpectrumSettings:
    """How each frequency is run: ``settle_cycles`` after the drive's ramp, then ``measure_cycles``
    measured, ``samples_per_period`` samples per drive period; ``steps_per_radian`` the fixed step's
    accuracy (None: the driven path's default) and ``dt`` [s] a given step."""

    settle_cycles: float = 200.0
    measure_cycles: float = 20.0
    samples_per_period: int = 32
    steps_per_radian: float | None = None
    dt: float | None = None

    def __post_init__(self) -> None:
        for name, low in (("settle_cycles", 0.0), ("measure_cycles", 1.0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not (isinstance(v, (int, float)) and math.isfinite(v) and v >= low):
                raise ConfigError(name, f"must be a number of cycles >= {low:g}, got {v!r}")
        if not (isinstance(self.samples_per_period, int) and 8 <= self.samples_per_period <= 10_000):
            raise ConfigError("samples_per_period", f"must be a whole number from 8 to 10000, got "
                              f"{self.samples_per_period!r}")


def _frequency_model(model, frequency: float, amplitude: float | None = None):
    drive = dataclasses.replace(model.drive, frequency=float(frequency),
                                **({} if amplitude is None else {"amplitude": float(amplitude)}))
    return dataclasses.replace(model, drive=drive)


def _member(model, frequency: float, settings: SpectrumSettings, amplitude: float | None = None):
    """The run of one drive: (model at ``frequency`` [Hz] and ``amplitude``, its duration [s], its
    probes: the output contact at ``samples_per_period`` samples per period)."""
    from ..probes import Probes

    if model.drive is None or model.drive.type != "harmonic":
        raise ConfigError("drive.type", "a transmission spectrum needs a harmonic drive ([drive] type = 'harmonic')")
    m = _frequency_model(model, frequency, amplitude)
    d = m.drive
    period = 1.0 / d.frequency
    cycles = math.ceil(d.ramp_cycles + settings.settle_cycles + settings.measure_cycles)
    n = model.chain.n_beads
    out = n if model.wall.present else n - 1
    if d.end == "last":  # bead 1 rests on the wall (hertzchain.crystal.ends)
        out = 0
    return m, cycles * period, Probes(period / settings.samples_per_period, contacts=(out,))


def transmission_run(model, frequency: float, settings: SpectrumSettings = SpectrumSettings(),
                     amplitude: float | None = None) -> tuple[float, float, float]:
    """Drive ``model`` at ``frequency`` [Hz] (and ``amplitude``, N or m, when given) to its steady
    state with :func:`hertzchain.simulate`; returns (T, abs(F_out) [N], abs(F_in) [N])."""
    from ..runs.simulation import simulate

    m, duration, probes = _member(model, frequency, settings, amplitude)
    ds = simulate(m, duration, probes, dt=settings.dt, steps_per_radian=settings.steps_per_radian)
    return steady_transmission(ds, m.drive.frequency, settings.measure_cycles)


def transmission_batch(model, frequencies, settings: SpectrumSettings = SpectrumSettings(),
                       amplitudes=None, progress: Callable[[float], None] | None = None) -> list[tuple[float, float, float]]:
    """:func:`transmission_run` for several drives in one compiled call (the batched driven engine,
    :func:`hertzchain.crystal.driven.run_driven_batch`: one member per drive, on the threads in turn).

    Parameters
    ----------
    model : hertzchain.Model
        The chain with a harmonic ``drive``.
    frequencies : array_like
        Each member's drive frequency [Hz].
    settings : SpectrumSettings
        Cycles, samples and step.
    amplitudes : array_like, optional
        Each member's drive amplitude [N or m] (None: the drive's).
    progress : callable, optional
        ``progress(fraction)`` as the members advance (every member's samples, 0..1).

    Returns
    -------
    list of (T, abs(F_out) [N], abs(F_in) [N])
        One per member, equal to :func:`transmission_run`'s bit for bit (each member's step, records
        and lock-in are those of its run alone).
    """
    from .driven import run_driven_batch
    from .ends import from_driven_end

    freqs = np.atleast_1d(np.asarray(frequencies, dtype=float))
    amps = [None] * freqs.size if amplitudes is None else np.atleast_1d(np.asarray(amplitudes, dtype=float))
    members = [_member(model, float(f), settings, None if a is None else float(a)) for f, a in zip(freqs, amps)]
    # a drive entering at bead N: the chain read from there, its output contact 0 -> N (ends.py)
    turned = [from_driven_end(m) for m, _, _ in members]
    n = model.chain.n_beads
    probes = [pr if t is m else dataclasses.replace(pr, contacts=(n - pr.contacts[0],))
              for t, (m, _, pr) in zip(turned, members)]
    runs = run_driven_batch(turned, [d for _, d, _ in members], probes, dt=settings.dt,
                            steps_per_radian=settings.steps_per_radian,
                            progress=None if progress is None else (lambda done, total: progress(done / total)))
    _warn_elastic_limit(turned[0], [r[3] for r in runs])
    return [_ratio(t, forces[:, 0], drive_force, m.drive.frequency, settings.measure_cycles)
            for (m, _, _), (t, forces, drive_force, _) in zip(members, runs)]


def _warn_elastic_limit(model, fmax: list) -> None:
    """One ElasticLimitWarning when a member's contact forces passed the elastic limit (as simulate warns)."""
    import warnings

    from ..errors import ElasticLimitWarning
    from ..laws import is_plastic

    limit = model.system().yield_force[: fmax[0].size]
    ratio = max(float(np.max(f / limit)) for f in fmax)
    if ratio > 1.0 and not is_plastic(model.law.name):
        warnings.warn(ElasticLimitWarning(f"a driven run's contact force reached {ratio:.3g} x its elastic limit "
                                          "F_Y (paper Sec. II): beads would yield; lower drive.amplitude"),
                      stacklevel=3)


def read_rows(path: Path) -> dict[float, tuple[float, float, float]]:
    """The rows of a transmission CSV written by :func:`transmission_spectrum` (every field checked)."""
    rows: dict[float, tuple[float, float, float]] = {}
    lines = path.read_text(encoding="utf-8").splitlines()
    if not lines or lines[0].strip() != CSV_HEADER:
        raise ConfigError(str(path), f"is not a transmission table of hertzchain (its first line must be {CSV_HEADER})")
    for k, line in enumerate(lines[1:], start=2):
        parts = line.split(",")
        try:
            values = [float(x) for x in parts]
        except ValueError:
            values = []
        if len(values) != 4 or not all(math.isfinite(v) for v in values) or values[0] <= 0:
            raise ConfigError(str(path), f"line {k} is not four finite numbers with a positive frequency: {line!r}")
        rows[values[0]] = (values[1], values[2], values[3])
    return rows


def _csv_text(rows: dict[float, tuple[float, float, float]]) -> str:
    body = "".join(f"{f!r},{r[0]!r},{r[1]!r},{r[2]!r}\n" for f, r in sorted(rows.items()))
    return CSV_HEADER + "\n" + body


def _fingerprint(model, settings: SpectrumSettings) -> str:
    text = json.dumps({"model": {**model.describe(), "drive": {**model.drive.describe(), "frequency": None}},
                       "settings": dataclasses.asdict(settings)}, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def transmission_spectrum(model, frequencies, out: str | Path | None = None,
                          settings: SpectrumSettings = SpectrumSettings(),
                          progress: Callable[[int, int], None] | None = None, batch: int = DEFAULT_BATCH) -> xr.Dataset:
    """Stepped-sine transmission T(f) of a driven chain (module docstring).

    Parameters
    ----------
    model : hertzchain.Model
        The chain with a harmonic ``drive`` (its amplitude [N or m] and ramp are used; its
        frequency is replaced by each of ``frequencies``).
    frequencies : array_like
        Drive frequencies [Hz].
    out : path, optional
        Folder for ``transmission.csv`` (columns ``frequency_Hz``, ``transmission``, and the two
        amplitudes [N]) and ``spectrum.json`` (what the table belongs to), written after every
        batch of frequencies; a rerun with the same model and settings skips the frequencies
        already done (another model or settings there is refused).
    settings : SpectrumSettings
        Cycles, samples and step.
    progress : callable, optional
        ``progress(done, total)`` as the frequencies advance (fractions within a batch).
    batch : int
        Frequencies run in one compiled call (:func:`transmission_batch`); the results do not
        depend on it (each frequency's run is its own), only how much an interruption loses.

    Returns
    -------
    xarray.Dataset
        ``transmission`` [-], ``output_amplitude`` and ``input_amplitude`` [N] over ``frequency`` [Hz].
    """
    from ..fileio import json_text, write_text

    freqs = np.unique(np.asarray(frequencies, dtype=float))
    if freqs.size == 0 or not np.all(np.isfinite(freqs)) or freqs[0] <= 0:
        raise ConfigError("frequencies", "must be positive finite frequencies in Hz")
    if model.drive is None:
        raise ConfigError("drive", "a transmission spectrum needs a [drive] (type = 'harmonic')")
    # pre-flight for every frequency before any run: the step, the samples, the run's length
    preflight(model, freqs, settings)
    rows: dict[float, tuple[float, float, float]] = {}
    folder = None if out is None else Path(out)
    if folder is not None:
        folder.mkdir(parents=True, exist_ok=True)
        stamp = folder / "spectrum.json"
        fp = _fingerprint(model, settings)
        if stamp.exists():
            try:
                old = json.loads(stamp.read_text(encoding="utf-8")).get("fingerprint")
            except (ValueError, AttributeError):
                old = None
            if old != fp:
                raise ConfigError("--out", f"{folder} holds a spectrum of another model or other settings: choose "
                                  "another folder or remove it")
            if (folder / "transmission.csv").exists():
                rows = read_rows(folder / "transmission.csv")
        else:
            write_text(stamp, json_text({"fingerprint": fp, "model": model.describe(),
                                         "settings": dataclasses.asdict(settings)}))
    if isinstance(batch, bool) or not (isinstance(batch, (int, np.integer)) and 1 <= batch <= 10_000):
        raise ConfigError("--batch", f"must be a whole number of frequencies from 1 to 10000, got {batch!r}")
    done_keys = np.array(sorted(rows))
    todo = [f for f in freqs if not (done_keys.size and np.min(np.abs(done_keys - f)) <= 1e-12 * f)]
    done = freqs.size - len(todo)
    if progress is not None:
        progress(done, freqs.size)
    for start in range(0, len(todo), int(batch)):
        part = todo[start : start + int(batch)]
        within = _within(progress, done, len(part), freqs.size)
        rows.update(zip(map(float, part), transmission_batch(model, part, settings, progress=within)))
        if folder is not None:  # after every batch: an interruption loses the batch under way only
            write_text(folder / "transmission.csv", _csv_text(rows))
        done += len(part)
        if progress is not None:
            progress(done, freqs.size)
    keys = [min(rows, key=lambda k: abs(k - f)) for f in freqs]
    data = np.array([rows[k] for k in keys]).reshape(-1, 3)
    ds = xr.Dataset({"transmission": ("frequency", data[:, 0], {"units": "1", "long_name": "force transmission"}),
                     "output_amplitude": ("frequency", data[:, 1], {"units": "N", "long_name": "output force amplitude"}),
                     "input_amplitude": ("frequency", data[:, 2], {"units": "N", "long_name": "drive force amplitude"})},
                    coords={"frequency": ("frequency", freqs, {"units": "Hz", "long_name": "drive frequency"})})
    ds.attrs.update(title="hertzchain transmission spectrum", model=json.dumps(model.describe()),
                    settings=json.dumps(dataclasses.asdict(settings)))
    return ds


def _within(progress, done: int, count: int, total: int):
    """``progress(done + fraction x count, total)`` as a batch of ``count`` members advances (None: none)."""
    if progress is None:
        return None
    return lambda fraction: progress(done + fraction * count, total)


def transmission_against_amplitude(model, frequency: float, amplitudes,
                                   settings: SpectrumSettings = SpectrumSettings(),
                                   progress: Callable[[int, int], None] | None = None,
                                   batch: int = DEFAULT_BATCH) -> xr.Dataset:
    """Steady-state transmission at one ``frequency`` [Hz] against the drive's amplitude (the
    nonlinear regime: a gap that stops a small drive transmits above a threshold amplitude).

    Parameters
    ----------
    model : hertzchain.Model
        The chain with a harmonic ``drive`` (its amplitude is replaced by each of ``amplitudes``).
    frequency : float
        Drive frequency [Hz].
    amplitudes : array_like
        Drive amplitudes [N] (force) or [m] (displacement), > 0.
    settings : SpectrumSettings
        Cycles, samples and step.
    progress : callable, optional
        ``progress(done, total)`` as the amplitudes advance (fractions within a batch).
    batch : int
        Amplitudes run in one compiled call (:func:`transmission_batch`).

    Returns
    -------
    xarray.Dataset
        ``transmission`` [-], ``output_amplitude`` and ``input_amplitude`` [N] over ``amplitude``.
    """
    amps = np.asarray(amplitudes, dtype=float)
    if amps.ndim != 1 or amps.size == 0 or not np.all(np.isfinite(amps) & (amps > 0)):
        raise ConfigError("drive.amplitude", "the amplitudes must be positive finite numbers (N or m)")
    if model.drive is None:
        raise ConfigError("drive", "a transmission needs a [drive] (type = 'harmonic')")
    preflight(model, np.array([float(frequency)]), settings)
    rows: list = []
    for start in range(0, amps.size, int(batch)):
        part = amps[start : start + int(batch)]
        within = _within(progress, len(rows), part.size, amps.size)
        rows += transmission_batch(model, np.full(part.size, float(frequency)), settings, amplitudes=part,
                                   progress=within)
        if progress is not None:
            progress(len(rows), amps.size)
    data = np.array(rows)
    unit = "N" if model.drive.quantity == "force" else "m"
    return xr.Dataset({"transmission": ("amplitude", data[:, 0], {"units": "1", "long_name": "force transmission"}),
                       "output_amplitude": ("amplitude", data[:, 1], {"units": "N"}),
                       "input_amplitude": ("amplitude", data[:, 2], {"units": "N"})},
                      coords={"amplitude": ("amplitude", amps, {"units": unit, "long_name": "drive amplitude"})},
                      attrs={"frequency": float(frequency)})


def preflight(model, freqs: np.ndarray, settings: SpectrumSettings) -> float:
    """Check every frequency before any run (the driven path's own checks at each, and the total
    step count); returns the estimated steps in all."""
    from .driven import MAX_DRIVE_STEPS, drive_step
    from .ends import from_driven_end

    if model.drive.type != "harmonic":
        raise ConfigError("drive.type", "a transmission spectrum needs a harmonic drive ([drive] type = 'harmonic')")
    total = 0.0
    for f in freqs:
        m = from_driven_end(_frequency_model(model, f))  # the chain the run integrates (ends.py)
        system = m.system()
        dt = settings.dt if settings.dt is not None else drive_step(system, m.drive, settings.steps_per_radian)
        if settings.dt is not None and 1.0 / (f * dt) < 50:
            raise ConfigError("drive.frequency", f"{f:.4g} Hz is beyond what run.dt = {dt:.3g} s resolves (at least "
                              "50 steps per period): lower --fmax or shorten run.dt")
        cycles = math.ceil(m.drive.ramp_cycles + settings.settle_cycles + settings.measure_cycles)
        total += cycles / f / dt
    if total > MAX_DRIVE_STEPS:
        raise ConfigError("--settle-cycles", f"the spectrum would take {total:.3g} steps in all (more than "
                          f"{MAX_DRIVE_STEPS:.0e}): fewer frequencies (--points), fewer cycles, or a higher --fmin")
    return total
