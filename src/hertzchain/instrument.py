"""A laboratory measurement chain applied to an ideal simulated force signal.

The paper (Melo et al., PRE 2006, Sec. II) measures forces with piezoelectric sensors (wall
sensor PCB 208A11, 112.40 mV/N; sensor embedded in a bead, PCB 200B02, 11.24 mV/N) read through
a conditioner (PCB 482A16) by a two-channel digital oscilloscope (Tektronix TDS340: 8-bit
vertical resolution, 1000 points per record), triggering one channel with the other sensor and
averaging nine acquisitions. :class:`Instrument` reproduces the errors that chain adds to a
force, so that a simulation can be compared with the measurement the way the lab sees it.

The instrument is *opt-in*: nothing in the package applies it unless asked, and
:meth:`Instrument.acquire` never modifies its inputs, so the ideal signal always remains
available next to the "measured" one.

What one acquisition does, in order (all conversions are linear):

1. **Trigger.** The trigger time ``t_c`` [s] is the first upward crossing of
   ``trigger_level_N`` by the triggering signal (``trigger_signal`` when given, else the force
   itself): the first sample pair with ``s[i-1] < level <= s[i]``, located by linear
   interpolation between the two simulation samples. The trigger is evaluated on the ideal
   (noise free) signal; the sample-clock uncertainty of a real scope is modelled by the jitter.
2. **Sampling.** The scope samples at ``sample_rate`` [Hz] with interval ``dt = 1/sample_rate``;
   its record holds ``record_length`` points, ``n_pre = round(pretrigger_fraction *
   record_length)`` of them before the trigger, so sample ``k`` is taken at
   ``t_c + (k - n_pre) dt + phi``. ``phi`` [s] is 0 without jitter; with ``trigger_jitter`` it
   is drawn uniformly in ``[0, dt)`` for every acquisition (the free-running sample clock puts
   the first sample at or after the trigger anywhere within one interval). The reported time
   axis is the nominal one, ``(k - n_pre) dt``, so jitter shows up as a small random advance
   of the signal, and averaging smooths the fastest edges a little, as on a real scope.
   The values come from **linear interpolation** of the simulation's own time grid, which must
   therefore sample at least as finely as the scope (``max diff(time) <= 1/sample_rate`` over
   the record); a coarser simulation gets an :class:`InstrumentWarning`. Before the first
   simulated instant the first value is held (the chain is at rest before the impact); after
   the last the last value is held, with a warning, and :attr:`Acquisition.covered` says which
   samples were actually simulated.
3. **Sensor.** Volts = force [N] x ``sensitivity_mV_per_N`` / 1000. The sensor and conditioner
   are otherwise ideal (flat response, no discharge time constant, no resonance).
4. **Noise.** Independent gaussian white noise of rms ``noise_rms_mV`` [mV] is added to every
   sample of every acquisition (the sensor/conditioner output noise seen at the scope's rate).
5. **Digitisation.** Vertical convention (kept simple, like a signed ADC): the window spans
   ``full_scale_V`` [V] centred on ``offset_V`` [V], split into ``2**bits`` levels of step
   ``q = full_scale_V / 2**bits``. A sample becomes the nearest level
   ``offset_V + c q`` with the integer code ``c`` clipped to ``[-2**(bits-1), 2**(bits-1) - 1]``,
   so the representable voltages run from ``offset_V - full_scale_V/2`` to
   ``offset_V + full_scale_V/2 - q`` and ``offset_V`` itself (a zero baseline by default) is a
   level. On an 8-division screen ``full_scale_V = 8 x volts/div``. Clipping triggers an
   :class:`InstrumentWarning`.
6. **Averaging.** ``n_average`` acquisitions (each with its own noise and jitter) are digitised
   separately and their mean is returned, like the scope's average mode (the paper uses nine).
   The mean of several digitised records is in general no longer on the level grid.

The defaults describe the paper's wall channel: PCB 208A11 sensitivity, TDS340 record (1000
points, 8 bits), a +-5 V window (the sensors' rated output span), 1 MS/s (100 us/div on a
10-division time base), no noise, one acquisition.
"""

from __future__ import annotations

import math
import numbers
import warnings
from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any

import numpy as np

from .errors import ConfigError

__all__ = [
    "Instrument",
    "Acquisition",
    "InstrumentWarning",
    "PCB_208A11_MV_PER_N",
    "PCB_200B02_MV_PER_N",
    "SENSOR_STIFFNESS",
    "sensor_wall",
    "TDS340_RECORD_LENGTH",
    "TDS340_BITS",
]

#: Sensitivity of the wall sensor of the paper, PCB 208A11 [mV/N].
PCB_208A11_MV_PER_N = 112.40
#: Sensitivity of the sensor embedded in a bead, PCB 200B02 [mV/N].
PCB_200B02_MV_PER_N = 11.24
#: Stiffness of the paper's sensors, k_s = 1.9 kN/um (Sec. II) [N/m].
SENSOR_STIFFNESS = 1.9e9
#: Points per channel recorded by the Tektronix TDS340.
TDS340_RECORD_LENGTH = 1000
#: Vertical resolution of the Tektronix TDS340 [bits].
TDS340_BITS = 8

# Largest supported resolution: codes up to 2**47 stay exact integers in float64 (2**53), so
# "practically infinite" resolution (a step ~1e-14 of the window) is still computed exactly.
_MAX_BITS = 48


class InstrumentWarning(UserWarning):
    """The measurement is degraded in a way the user should know of (clipping, coarse simulation
    grid, record running past the simulated time)."""


def _is_int(value: Any) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def _is_real(value: Any) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


@dataclass(frozen=True)
class Instrument:
    """Sensor + conditioner + digital oscilloscope, applied to an ideal force signal.

    See the module docstring for the exact model and conventions.

    Parameters
    ----------
    sensitivity_mV_per_N
        Sensor (and conditioner) sensitivity [mV/N], > 0. Default: PCB 208A11, 112.40 mV/N.
    noise_rms_mV
        Rms of the additive gaussian white noise at the conditioner output [mV], >= 0,
        drawn independently for every sample of every acquisition.
    sample_rate
        Oscilloscope sampling rate [Hz], > 0. The simulation must be recorded at least as
        finely (time step <= 1/sample_rate), since the scope samples are linearly interpolated.
    record_length
        Number of points in a record, >= 2 (TDS340: 1000).
    trigger_level_N
        Trigger level [N] of the triggering signal (in that signal's own newtons); the record is
        aligned on its first upward crossing.
    pretrigger_fraction
        Fraction of the record taken before the trigger, in [0, 1).
    bits
        Vertical resolution [bits], integer in 1..48 (TDS340: 8).
    full_scale_V
        Height of the vertical window [V], > 0 (8 divisions x volts/div).
    offset_V
        Voltage at the centre of the vertical window [V].
    n_average
        Number of acquisitions averaged, >= 1 (the paper averages nine).
    trigger_jitter
        If True each acquisition's sample clock is shifted by a random phase, uniform in
        [0, 1/sample_rate), with respect to the trigger.
    seed
        Seed (integer >= 0, or None for fresh entropy) of the random generator used when
        :meth:`acquire` gets no ``rng``. With a fixed seed every call draws the same noise.
    """

    sensitivity_mV_per_N: float = PCB_208A11_MV_PER_N
    noise_rms_mV: float = 0.0
    sample_rate: float = 1.0e6
    record_length: int = TDS340_RECORD_LENGTH
    trigger_level_N: float = 1.0
    pretrigger_fraction: float = 0.1
    bits: int = TDS340_BITS
    full_scale_V: float = 10.0
    offset_V: float = 0.0
    n_average: int = 1
    trigger_jitter: bool = True
    seed: int | None = 0

    # --- validation ----------------------------------------------------------------------------
    def __post_init__(self) -> None:
        def real(name: str, *, positive: bool = False, nonneg: bool = False, unit: str = "") -> None:
            value = getattr(self, name)
            what = "a finite number" + (" > 0" if positive else " >= 0" if nonneg else "")
            if unit:
                what += f" ({unit})"
            if not _is_real(value) or not math.isfinite(value):
                raise ConfigError(f"instrument.{name}", f"must be {what}, got {value!r}")
            if (positive and not value > 0) or (nonneg and not value >= 0):
                raise ConfigError(f"instrument.{name}", f"must be {what}, got {value!r}")

        def integer(name: str, lo: int, hi: int | None = None) -> None:
            value = getattr(self, name)
            span = f"in {lo}..{hi}" if hi is not None else f">= {lo}"
            if not _is_int(value) or value < lo or (hi is not None and value > hi):
                raise ConfigError(f"instrument.{name}", f"must be an integer {span}, got {value!r}")

        real("sensitivity_mV_per_N", positive=True, unit="mV/N")
        real("noise_rms_mV", nonneg=True, unit="mV")
        real("sample_rate", positive=True, unit="Hz")
        integer("record_length", 2)
        real("trigger_level_N", unit="N")
        real("pretrigger_fraction", nonneg=True)
        if not self.pretrigger_fraction < 1:
            raise ConfigError("instrument.pretrigger_fraction",
                              f"must be in [0, 1) (fraction of the record), got {self.pretrigger_fraction!r}")
        integer("bits", 1, _MAX_BITS)
        real("full_scale_V", positive=True, unit="V")
        real("offset_V", unit="V")
        integer("n_average", 1)
        if not isinstance(self.trigger_jitter, (bool, np.bool_)):
            raise ConfigError("instrument.trigger_jitter", f"must be True or False, got {self.trigger_jitter!r}")
        if self.seed is not None and (not _is_int(self.seed) or self.seed < 0):
            raise ConfigError("instrument.seed", f"must be None or an integer >= 0, got {self.seed!r}")

    # --- presets -------------------------------------------------------------------------------
    @classmethod
    def _preset(cls, sensitivity: float, overrides: dict[str, Any]) -> Instrument:
        names = {f.name for f in fields(cls)}
        for key in overrides:
            if key not in names:
                raise ConfigError(f"instrument.{key}", f"unknown setting; known: {', '.join(sorted(names))}")
        return cls(**{"sensitivity_mV_per_N": sensitivity, **overrides})

    @classmethod
    def pcb_208a11(cls, **overrides: Any) -> Instrument:
        """The paper's wall sensor, PCB 208A11 (112.40 mV/N), on a TDS340 channel.

        Any field can be overridden by keyword, e.g. ``Instrument.pcb_208a11(n_average=9)``.
        """
        return cls._preset(PCB_208A11_MV_PER_N, overrides)

    @classmethod
    def pcb_200b02(cls, **overrides: Any) -> Instrument:
        """The paper's sensor embedded in a bead, PCB 200B02 (11.24 mV/N), on a TDS340 channel.

        Any field can be overridden by keyword, e.g. ``Instrument.pcb_200b02(offset_V=-4.0)``.
        """
        return cls._preset(PCB_200B02_MV_PER_N, overrides)

    def replace(self, **changes: Any) -> Instrument:
        """A copy with some fields changed (validated again)."""
        return replace(self, **changes)

    def as_dict(self) -> dict[str, Any]:
        """The settings as a plain dict (for result metadata)."""
        return asdict(self)

    # --- derived quantities --------------------------------------------------------------------
    @property
    def sample_interval(self) -> float:
        """Time between two scope samples, 1/sample_rate [s]."""
        return 1.0 / self.sample_rate

    @property
    def record_duration(self) -> float:
        """Duration covered by one record, record_length/sample_rate [s]."""
        return self.record_length / self.sample_rate

    @property
    def pretrigger_points(self) -> int:
        """Index of the trigger sample in the record: round(pretrigger_fraction*record_length)."""
        return min(int(round(self.pretrigger_fraction * self.record_length)), self.record_length - 1)

    @property
    def volts_per_N(self) -> float:
        """Conversion factor force -> voltage [V/N]."""
        return self.sensitivity_mV_per_N * 1e-3

    @property
    def volts_per_div(self) -> float:
        """Vertical scale [V/div] of an 8-division screen showing the full window."""
        return self.full_scale_V / 8.0

    @property
    def quantisation_step_V(self) -> float:
        """Voltage between two adjacent levels, full_scale_V / 2**bits [V]."""
        return self.full_scale_V / 2.0**self.bits

    @property
    def quantisation_step_N(self) -> float:
        """Force between two adjacent levels, quantisation_step_V / sensitivity [N]."""
        return self.quantisation_step_V / self.volts_per_N

    @property
    def range_V(self) -> tuple[float, float]:
        """Lowest and highest representable voltages [V] (the top is one step below the edge)."""
        half = 2 ** (self.bits - 1)
        q = self.quantisation_step_V
        return self.offset_V - half * q, self.offset_V + (half - 1) * q

    @property
    def range_N(self) -> tuple[float, float]:
        """Lowest and highest representable forces [N]."""
        lo, hi = self.range_V
        return lo / self.volts_per_N, hi / self.volts_per_N

    # --- the measurement -----------------------------------------------------------------------
    def quantise(self, volts: np.ndarray) -> tuple[np.ndarray, int]:
        """Digitise voltages [V]: nearest level, clipped to the window.

        Returns the quantised voltages [V] and the number of samples that were clipped.
        """
        volts = np.asarray(volts, dtype=float)
        q = self.quantisation_step_V
        half = 2 ** (self.bits - 1)
        code = np.rint((volts - self.offset_V) / q)
        clipped = int(np.count_nonzero((code < -half) | (code > half - 1)))
        code = np.clip(code, -half, half - 1)
        return self.offset_V + code * q, clipped

    def acquire(
        self,
        time: np.ndarray,
        force: np.ndarray,
        trigger_signal: np.ndarray | None = None,
        rng: np.random.Generator | int | None = None,
    ) -> Acquisition:
        """Measure an ideal force signal the way the laboratory does.

        Parameters
        ----------
        time:
            Simulation time grid [s], 1-D, strictly increasing, at least 2 points. It must be at
            least as fine as the scope (step <= 1/sample_rate); see the module docstring.
        force:
            Ideal force [N] on ``time`` (same shape). Not modified.
        trigger_signal:
            Signal [N] on ``time`` whose first upward crossing of ``trigger_level_N`` triggers
            the record (the paper triggers one sensor with the other). Default: ``force``.
        rng:
            Random generator (or integer seed) for the noise and the jitter; default a fresh
            ``numpy.random.default_rng(self.seed)``.

        Returns
        -------
        Acquisition
            The averaged record: time [s] relative to the trigger, force [N], volts [V], and
            the settings used.

        Raises
        ------
        ConfigError
            Bad arrays (fields ``acquire.time``, ``acquire.force``, ``acquire.trigger_signal``)
            or a trigger signal that never crosses the level upward
            (``instrument.trigger_level_N``).
        """
        t = _as_1d("acquire.time", time)
        if t.size < 2:
            raise ConfigError("acquire.time", f"needs at least 2 samples, got {t.size}")
        if not np.all(np.diff(t) > 0):
            raise ConfigError("acquire.time", "must be strictly increasing")
        f = _as_1d("acquire.force", force)
        if f.shape != t.shape:
            raise ConfigError("acquire.force", f"must have the shape of time {t.shape}, got {f.shape}")
        if trigger_signal is None:
            trig = f
        else:
            trig = _as_1d("acquire.trigger_signal", trigger_signal)
            if trig.shape != t.shape:
                raise ConfigError("acquire.trigger_signal",
                                  f"must have the shape of time {t.shape}, got {trig.shape}")

        t_c = self._trigger_time(t, trig)

        if rng is None or _is_int(rng):
            rng = np.random.default_rng(self.seed if rng is None else rng)
        elif not isinstance(rng, np.random.Generator):
            raise ConfigError("acquire.rng", f"must be a numpy Generator, an integer seed or None, got {rng!r}")

        dt = self.sample_interval
        n_pre = self.pretrigger_points
        rel = (np.arange(self.record_length) - n_pre) * dt
        n = self.n_average
        if self.trigger_jitter:
            jitter = rng.random(n) * dt
        else:
            jitter = np.zeros(n)
        sample_times = t_c + rel[None, :] + jitter[:, None]          # (n_average, record_length)

        self._check_grid(t, sample_times)
        covered = np.all((sample_times >= t[0]) & (sample_times <= t[-1]), axis=0)

        # np.interp holds the end values outside [t[0], t[-1]] (documented behaviour above).
        volts = np.interp(sample_times, t, f) * self.volts_per_N
        if self.noise_rms_mV > 0:
            volts = volts + rng.standard_normal(volts.shape) * (self.noise_rms_mV * 1e-3)
        digitised, n_clipped = self.quantise(volts)
        if n_clipped:
            lo, hi = self.range_N
            warnings.warn(
                f"{n_clipped} sample(s) clipped at the vertical range [{lo:.4g}, {hi:.4g}] N "
                f"(full_scale_V={self.full_scale_V:g}, offset_V={self.offset_V:g}); widen the range",
                InstrumentWarning, stacklevel=2,
            )
        mean_volts = digitised.mean(axis=0)
        return Acquisition(
            time=rel,
            force=mean_volts / self.volts_per_N,
            volts=mean_volts,
            instrument=self,
            trigger_time=t_c,
            trigger_index=n_pre,
            jitter=jitter,
            covered=covered,
            n_clipped=n_clipped,
        )

    def _trigger_time(self, t: np.ndarray, trig: np.ndarray) -> float:
        """First upward crossing of trigger_level_N, linearly interpolated [s]."""
        level = self.trigger_level_N
        hits = np.flatnonzero((trig[:-1] < level) & (trig[1:] >= level))
        if hits.size == 0:
            raise ConfigError(
                "instrument.trigger_level_N",
                f"the trigger signal never rises through {level:g} N (its range is "
                f"[{trig.min():.4g}, {trig.max():.4g}] N, starting at {trig[0]:.4g} N); the scope "
                "would wait forever. Lower the level or trigger on another signal",
            )
        i = int(hits[0])
        s0, s1 = trig[i], trig[i + 1]
        return float(t[i] + (level - s0) / (s1 - s0) * (t[i + 1] - t[i]))

    def _check_grid(self, t: np.ndarray, sample_times: np.ndarray) -> None:
        dt = self.sample_interval
        first, last = sample_times.min(), sample_times.max()
        # Simulation steps that overlap the record window.
        i0 = max(int(np.searchsorted(t, first, side="right")) - 1, 0)
        i1 = min(int(np.searchsorted(t, last, side="left")) + 1, t.size)
        if i1 - i0 >= 2:
            coarsest = float(np.max(np.diff(t[i0:i1])))
            if coarsest > dt * (1 + 1e-6):
                warnings.warn(
                    f"the simulation is recorded every {coarsest:.4g} s in the record window, "
                    f"coarser than the oscilloscope's 1/sample_rate = {dt:.4g} s; linear "
                    "interpolation cannot restore the missing detail: record the simulation at "
                    "least as finely as the scope samples",
                    InstrumentWarning, stacklevel=3,
                )
        if last > t[-1]:
            warnings.warn(
                f"the record runs {last - t[-1]:.4g} s past the end of the simulated signal "
                f"(t = {t[-1]:.4g} s); the last simulated value is held there (see "
                "Acquisition.covered). Simulate longer or shorten the record",
                InstrumentWarning, stacklevel=3,
            )


def _as_1d(name: str, values: Any) -> np.ndarray:
    try:
        arr = np.asarray(values, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ConfigError(name, f"must be an array of numbers ({exc})") from None
    if arr.ndim != 1:
        raise ConfigError(name, f"must be 1-D, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ConfigError(name, "must hold finite numbers only")
    return arr


@dataclass(frozen=True)
class Acquisition:
    """One (possibly averaged) oscilloscope record.

    Attributes
    ----------
    time:
        Nominal sample times relative to the trigger [s], ``(k - trigger_index) / sample_rate``.
    force:
        Measured force [N] = ``volts`` / sensitivity.
    volts:
        Averaged digitised voltages [V].
    instrument:
        The settings used.
    trigger_time:
        Time of the trigger crossing on the simulation's clock [s].
    trigger_index:
        Index of the trigger sample (``time[trigger_index] == 0``).
    jitter:
        Sample-clock phase of each averaged acquisition [s], in [0, 1/sample_rate).
    covered:
        True where every acquisition's sample lay inside the simulated time span.
    n_clipped:
        Number of samples, over all acquisitions, clipped at the vertical range.
    """

    time: np.ndarray
    force: np.ndarray
    volts: np.ndarray
    instrument: Instrument
    trigger_time: float
    trigger_index: int
    jitter: np.ndarray = field(repr=False)
    covered: np.ndarray = field(repr=False)
    n_clipped: int = 0

    @property
    def absolute_time(self) -> np.ndarray:
        """Nominal sample times on the simulation's clock [s] (``time + trigger_time``)."""
        return self.time + self.trigger_time


def sensor_wall(mass: float, material=None, damping: float = 0.0, stiffness: float = SENSOR_STIFFNESS):
    """The paper's wall sensor as a spring-mass instead of a perfect gauge: a protected body.

    The sensor's cap (the flat the last bead hits) and the part of the quartz stack that moves
    with it are a rigid mass on the stack's stiffness, k_s = 1.9 kN/um (paper Sec. II), whose
    other side is the rigid support; the piezo reads the force through the stack, k x + c v:
    the run's ``body_force``, which :func:`measure_dataset` then measures. The paper neglects the
    coupling (k_s much larger than the Hertz contact stiffness); this model shows what it costs.

    Parameters
    ----------
    mass : float
        The sensor's moving mass [kg] (cap and half the stack; the paper does not give it).
    material : str or Material, optional
        The cap's material (default: the chain's first material, as for a flat wall).
    damping : float
        Internal damping of the stack [N s/m].
    stiffness : float
        Its stiffness [N/m] (default: the paper's).

    Returns
    -------
    hertzchain.Wall
        ``Wall("body", material, mass, stiffness, damping)``.
    """
    from .model import Wall

    return Wall("body", material, mass, stiffness, damping)


def measure_dataset(ds, wall: Instrument | None = None, sensors: Instrument | None = None,
                    trigger: str = "self"):
    """Add "measured" signals to a simulation result, keeping the ideal ones.

    Parameters
    ----------
    ds:
        A result :class:`xarray.Dataset` (``wall_force``, ``sensor_force``).
    wall, sensors:
        Instruments for the wall sensor and for the embedded sensors (None: not measured). The
        wall sensor reads ``wall_force``, or ``body_force`` when the chain ends on a body (the
        sensor modelled as a spring-mass, :func:`sensor_wall`: the force through its stack).
    trigger:
        ``"self"``: each channel triggers on itself; ``"wall"``: every channel triggers on the
        wall force (the paper triggers the embedded sensor's acquisition with the wall sensor in
        the uniform chain, Sec. II).

    Returns
    -------
    A new Dataset with ``measured_wall_force(wall_scope_time)`` and
    ``measured_sensor_force(sensor_scope_time, sensor)`` [N], time axes relative to the trigger
    [s], the trigger times on the simulation clock, and each instrument's settings in the
    variable attributes. Each sensor gets its own random stream (seeded from the instrument's
    seed and the sensor bead), so two sensors never share noise.
    """
    import json

    import xarray as xr

    if trigger not in ("self", "wall"):
        raise ConfigError("instrument.trigger", f"must be 'self' or 'wall', got {trigger!r}")
    if trigger == "wall" and "wall_force" not in ds:
        raise ConfigError("instrument.trigger", "'wall' needs a wall (wall.type = 'flat')")
    out = ds.copy()
    t = ds.time.values
    read = ds.body_force.values if "body_force" in ds else ds.wall_force.values if "wall_force" in ds else None
    trig = read if trigger == "wall" else None
    if wall is not None:
        if read is None:
            raise ConfigError("instrument.wall", "the run has no wall to measure (wall.type = 'none')")
        acq = wall.acquire(t, read, trigger_signal=trig)
        out = out.assign_coords(wall_scope_time=("wall_scope_time", acq.time, {"units": "s",
                                "long_name": "oscilloscope time relative to the trigger"}))
        out["measured_wall_force"] = xr.Variable(("wall_scope_time",), acq.force, attrs={
            "units": "N", "long_name": "wall force as measured (sensor, noise, scope, averaging)"
            + ("; the sensor's stack force (body_force)" if "body_force" in ds else ""),
            "trigger_time": acq.trigger_time, "n_clipped": acq.n_clipped, "valid_max": wall.range_N[1],
            "instrument": json.dumps(wall.as_dict())})
    if sensors is not None:
        if "sensor_force" not in ds:
            raise ConfigError("instrument.sensors", "the run has no embedded sensors (probes.sensors is empty)")
        records, trig_times = [], []
        for bead in ds.sensor.values:
            seed = None if sensors.seed is None else np.random.SeedSequence([sensors.seed, int(bead)])
            acq = sensors.acquire(t, ds.sensor_force.sel(sensor=bead).values, trigger_signal=trig,
                                  rng=np.random.default_rng(seed))
            records.append(acq.force)
            trig_times.append(acq.trigger_time)
        out = out.assign_coords(sensor_scope_time=("sensor_scope_time", acq.time, {"units": "s",
                                "long_name": "oscilloscope time relative to the trigger"}))
        out["measured_sensor_force"] = xr.Variable(("sensor_scope_time", "sensor"), np.array(records).T, attrs={
            "units": "N", "long_name": "embedded-sensor force as measured", "valid_max": sensors.range_N[1],
            "instrument": json.dumps(sensors.as_dict())})
        out["sensor_trigger_time"] = xr.Variable(("sensor",), np.array(trig_times), attrs={
            "units": "s", "long_name": "trigger time of each sensor's record on the simulation clock"})
    return out
