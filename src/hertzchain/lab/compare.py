"""Put a measured pulse next to a simulated one (``hertzchain compare``).

Both records are fitted as in the paper (Sec. III: F_m cos^6((t - T)/tau) on the loading part,
:func:`hertzchain.analysis.fit_pulse`); the differences simulated - measured of F_m, T and tau
are reported. The simulated record is then shifted onto the measured clock, either so that the
two fitted times of flight coincide (``align="fit"``, the default) or by the lag that maximises
their cross-correlation (``align="xcorr"``), interpolated at the measured sample times, and the
residual simulated - measured (the sign of the reported differences) gives the rms difference.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigError

__all__ = ["Comparison", "compare_traces", "UNITS"]

#: Units of the numbers of :meth:`Comparison.as_json` (SI), by key (the pulse fits' keys included).
UNITS = {"peak_force_diff": "N", "time_of_flight_diff": "s", "duration_diff": "s", "rms_residual": "N", "shift": "s",
         "peak_force": "N", "peak_force_err": "N", "time_of_flight": "s", "time_of_flight_err": "s", "duration": "s",
         "duration_err": "s"}


@dataclass
class Comparison:
    """Result of :func:`compare_traces` (SI units; differences are simulated - measured).

    Attributes
    ----------
    peak_force_diff : float
        F_m(simulated) - F_m(measured) [N].
    time_of_flight_diff : float
        T(simulated) - T(measured) [s], each on its own clock (impact for a simulation, trigger
        for a scope record).
    duration_diff : float
        tau(simulated) - tau(measured) [s].
    rms_residual : float
        Root mean square of measured - aligned simulated over the measured samples [N].
    shift : float
        Time added to the measured clock to read the simulation [s].
    align : str
        How the shift was found: ``"fit"`` (equal fitted T) or ``"xcorr"`` (cross-correlation).
    measured, simulated : dict
        The paper's pulse parameters of each (``peak_force``, ``time_of_flight``, ``duration``
        and their ``_err``) [N, s].
    time, measured_force, simulated_force, residual : numpy.ndarray
        The measured samples [s, N], the aligned simulation there [N] and the residual
        simulated - measured [N] (the sign of the ``*_diff`` fields: positive where the
        simulation is above the measurement).
    """

    peak_force_diff: float
    time_of_flight_diff: float
    duration_diff: float
    rms_residual: float
    shift: float
    align: str
    measured: dict
    simulated: dict
    time: np.ndarray = field(repr=False)
    measured_force: np.ndarray = field(repr=False)
    simulated_force: np.ndarray = field(repr=False)
    residual: np.ndarray = field(repr=False)

    def as_json(self) -> dict:
        """The numbers (no arrays) as a JSON-ready mapping.

        Returns
        -------
        dict
            ``peak_force_diff`` [N], ``time_of_flight_diff`` [s], ``duration_diff`` [s],
            ``rms_residual`` [N], ``shift`` [s], ``align``, both pulse fits and ``units`` (the
            unit of every number, by key; the pulse fits' keys too).
        """
        keys = ("peak_force_diff", "time_of_flight_diff", "duration_diff", "rms_residual", "shift", "align",
                "measured", "simulated")
        return {**{k: getattr(self, k) for k in keys}, "units": dict(UNITS)}


def _pulse(da, what: str) -> dict:
    from ..analysis.pulse import fit_pulse
    from ..errors import PulseClipped, PulseNotFound

    valid_max = da.attrs.get("valid_max")
    try:
        fit = fit_pulse(da["time"].values, da.values, valid_max=None if valid_max is None else float(valid_max))
    except PulseClipped as exc:
        raise ConfigError(what, f"cannot be compared: {exc}") from None
    except PulseNotFound as exc:
        raise ConfigError(what, f"no pulse found to compare ({exc})") from None
    return {k: float(getattr(fit, k)) for k in ("peak_force", "peak_force_err", "time_of_flight",
                                                 "time_of_flight_err", "duration", "duration_err")}


def compare_traces(measured, simulated, align: str = "fit") -> Comparison:
    """Compare a measured force record with a simulated one.

    Parameters
    ----------
    measured, simulated : xarray.DataArray
        Force [N] along ``time`` [s] (from :func:`~hertzchain.lab.read_trace`, or a result's
        signal with its time dimension named ``time``).
    align : {"fit", "xcorr"}
        How the simulation is put on the measured clock: equal fitted times of flight T
        (paper Sec. III), or the lag of the largest cross-correlation.

    Returns
    -------
    Comparison
        ``peak_force_diff`` [N], ``time_of_flight_diff`` [s], ``duration_diff`` [s],
        ``rms_residual`` [N], the shift [s] and the aligned records.

    Raises
    ------
    ConfigError
        Unknown ``align``, a record without a fittable pulse, or a clipped one (its pulse reaches
        the ``valid_max`` attribute, the scope's full scale, or its top is cut flat).
    """
    if align not in ("fit", "xcorr"):
        raise ConfigError("--align", f"must be 'fit' or 'xcorr', got {align!r}")
    pm = _pulse(measured, "MEASURED")
    ps = _pulse(simulated, "SIMULATED")
    tm, ym = np.asarray(measured["time"].values, float), np.asarray(measured.values, float)
    ts, ys = np.asarray(simulated["time"].values, float), np.asarray(simulated.values, float)
    if align == "fit":
        shift = ps["time_of_flight"] - pm["time_of_flight"]
    else:
        from scipy.signal import correlate

        dt = min(float(np.median(np.diff(ts))), float(np.median(np.diff(tm))))
        grid_s = np.arange(ts[0], ts[-1], dt)
        grid_m = np.arange(tm[0], tm[-1], dt)
        fs, fm = np.interp(grid_s, ts, ys), np.interp(grid_m, tm, ym)
        c = correlate(fs - fs.mean(), fm - fm.mean(), mode="full", method="fft")
        shift = float(grid_s[0] + (int(np.argmax(c)) - (grid_m.size - 1)) * dt - grid_m[0])
    sim_on_m = np.interp(tm + shift, ts, ys, left=ys[0], right=ys[-1])
    residual = sim_on_m - ym  # simulated - measured, like the differences of F_m, T and tau
    return Comparison(
        peak_force_diff=ps["peak_force"] - pm["peak_force"],
        time_of_flight_diff=ps["time_of_flight"] - pm["time_of_flight"],
        duration_diff=ps["duration"] - pm["duration"],
        rms_residual=float(np.sqrt(np.mean(residual**2))), shift=float(shift), align=align,
        measured=pm, simulated=ps, time=tm, measured_force=ym, simulated_force=sim_on_m, residual=residual)
