"""Fit the front pulse of a force signal the way the paper does (Melo et al., PRE 2006, Sec. III).

The loading part (-tau < t - T < 0) of the first pulse of a force record is fitted with
Nesterenko's profile F(t) = F_m cos^6[(t - T) / tau] (paper eq. 4 in the time domain), which
gives the peak force F_m [N], the time of flight T [s] and the duration tau [s]. The front and
tail momenta of Fig. 5d, Q_F = int_{-inf}^{T + tau} F dt and Q_T = int_{T + tau}^{+inf} F dt
[N s], are integrals of the baseline-corrected record split at T + tau.

Only numpy arrays in SI units come in; nothing here knows about simulations.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import curve_fit

from ..errors import ConfigError, PulseClipped, PulseNotFound
from ..theory import HALF_MAX_PHASE

__all__ = ["PulseFit", "fit_pulse", "cos6_pulse", "estimate_noise", "front_tail_momenta"]

#: Fewest samples on the loading part for a 3-parameter fit with one degree of freedom left.
MIN_FIT_POINTS = 4
#: The baseline is the median of the samples before T - PRE_PULSE_GAP * tau: the cos^6 hump
#: starts at T - (pi/2) tau, and the discrete solitary wave's front decays super-exponentially.
PRE_PULSE_GAP = 2.0
#: Fewest pre-pulse samples for a baseline estimate; with fewer, the record is assumed to start
#: at rest (baseline 0), which is the case of a simulated contact force recorded from t = 0.
MIN_BASELINE_POINTS = 5


def cos6_pulse(t: np.ndarray | float, peak_force: float, time_of_flight: float,
               duration: float) -> np.ndarray | float:
    """Nesterenko pulse in time, F_m cos^6[(t - T)/tau] on |t - T| < (pi/2) tau, 0 outside (eq. 4).

    Parameters
    ----------
    t:
        Time [s].
    peak_force:
        F_m [N].
    time_of_flight:
        T [s], the time of the maximum.
    duration:
        tau [s].
    """
    phase = (np.asarray(t, dtype=float) - time_of_flight) / duration
    force = np.where(np.abs(phase) < math.pi / 2.0, peak_force * np.cos(phase) ** 6, 0.0)
    return float(force) if force.ndim == 0 else force


@dataclass(frozen=True)
class PulseFit:
    """Result of :func:`fit_pulse` (all SI units).

    Attributes
    ----------
    peak_force, peak_force_err
        F_m and its standard error [N].
    time_of_flight, time_of_flight_err
        T, the time of the fitted maximum, and its standard error [s] (same origin as the input
        time axis).
    duration, duration_err
        tau and its standard error [s].
    front_momentum
        Q_F = integral of (F - baseline) from the start of the record to T + tau [N s].
    tail_momentum
        Q_T = integral of (F - baseline) from T + tau to the end of the record [N s].
    total_momentum
        Q_F + Q_T, the integral of the whole baseline-corrected record [N s].
    baseline
        Offset removed from the signal before fitting [N].
    noise
        Robust estimate of the sample-to-sample noise standard deviation [N].
    window
        (start, end) [s] of the samples used in the final fit.
    n_points
        Number of samples in the final fit.
    residual_rms
        Root-mean-square residual of the final fit [N].
    peak_index
        Index of the sample at the detected maximum of the first pulse.
    iterations
        Number of window updates until the fitted window stopped changing.
    """

    peak_force: float
    time_of_flight: float
    duration: float
    peak_force_err: float
    time_of_flight_err: float
    duration_err: float
    front_momentum: float
    tail_momentum: float
    total_momentum: float
    baseline: float
    noise: float
    window: tuple[float, float]
    n_points: int
    residual_rms: float
    peak_index: int
    iterations: int

    def model(self, t: np.ndarray | float) -> np.ndarray | float:
        """Fitted profile F_m cos^6[(t - T)/tau] + baseline [N] at times ``t`` [s]."""
        return cos6_pulse(t, self.peak_force, self.time_of_flight, self.duration) + self.baseline

    def as_dict(self) -> dict:
        """The fields as a plain dict (``window`` as a 2-tuple)."""
        return asdict(self)

    def _rows(self) -> list[tuple[str, str]]:
        from ..display import value_text

        return [("F_m", value_text(self.peak_force, self.peak_force_err, "N")),
                ("T", value_text(self.time_of_flight, self.time_of_flight_err, "ms", 1e3)),
                ("tau", value_text(self.duration, self.duration_err, "µs", 1e6)),
                ("Q_F, Q_T", f"{self.front_momentum * 1e3:.4g}, {self.tail_momentum * 1e3:.4g} mN s"),
                ("fit", f"{self.n_points} points, rms residual {self.residual_rms:.2g} N, "
                        f"baseline {self.baseline:.2g} N")]

    def __repr__(self) -> str:
        return "PulseFit(" + ", ".join(f"{k} = {v}" for k, v in self._rows()[:3]) + ")"

    def _repr_html_(self) -> str:
        from ..display import html_table

        return html_table("PulseFit (paper Sec. III: F_m cos^6((t - T)/tau))", self._rows())


# --------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------
def _as_signal(time, force) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(time, dtype=float)
    f = np.asarray(force, dtype=float)
    if t.ndim != 1 or f.ndim != 1 or t.shape != f.shape:
        raise ConfigError("time/force", f"must be 1-D arrays of equal length, got shapes {t.shape} and {f.shape}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(f))):
        raise ConfigError("time/force", "contain NaN or infinite values")
    if t.size >= 2 and np.any(np.diff(t) <= 0):
        raise ConfigError("time", "must be strictly increasing")
    return t, f


#: Sum of the squared autocorrelations of the second differences of white noise (lag 0: 1, lag
#: 1: -4/6, lag 2: 1/6): the mean square of a block of b of them has a relative spread of
#: sqrt(2 * 1.944 / b).
_D2_CORRELATION = 1.0 + 2.0 * (4.0 / 6.0) ** 2 + 2.0 * (1.0 / 6.0) ** 2


def estimate_noise(force: np.ndarray, block: int = 32) -> float:
    """Sample-to-sample noise standard deviation [N] of a record, unbiased for quantised records.

    White noise of standard deviation sigma gives second differences of variance 6 sigma^2, while
    a smooth pulse sampled finely gives almost none, so the mean square of the second
    differences measures the noise. The record is cut into blocks (of ``block`` differences,
    fewer in a short record so that there are at least eight); blocks holding the pulse's
    curvature stand out and are left out: starting from the lower quartile of the blocks' mean
    squares (so that a pulse covering most of a coarsely sampled record does not set the scale),
    the blocks within 4 relative spreads of the mean of the kept ones are kept, four times over.

    A mean square, unlike a median of absolute values, stays unbiased when the samples are
    quantised (an 8-bit scope: most second differences are 0 or one code step, and their median
    is then ~25 % low at a noise of one code step, 100 % at a third of one). The estimate is the
    noise plus the quantisation error (variance sigma^2 + q^2 / 12), which is what the residuals
    of a perfect model hold: a fit weighted by it has a residual variance per degree of
    freedom of ~1.

    Parameters
    ----------
    force : numpy.ndarray
        The record [N].
    block : int
        Second differences per block (at most).

    Returns
    -------
    float
        sigma [N] (0 for fewer than three samples or a noise-free flat record).
    """
    d2 = np.diff(np.asarray(force, dtype=float), 2)
    if d2.size < 8:
        return float(math.sqrt(np.mean(d2**2) / 6.0)) if d2.size else 0.0
    block = int(min(block, max(4, d2.size // 8)))
    n_blocks = d2.size // block
    ms = np.mean(d2[: n_blocks * block].reshape(n_blocks, block) ** 2, axis=1)
    spread = math.sqrt(2.0 * _D2_CORRELATION / block)
    ref = float(np.percentile(ms, 25)) / max(1.0 - 0.674 * spread, 0.2)  # a quartile of noise blocks -> their mean
    for _ in range(4):
        kept = ms[ms <= (1.0 + 4.0 * spread) * ref]
        if kept.size == 0:
            break
        ref = float(np.mean(kept))
    return float(math.sqrt(ref / 6.0))


def _half_max_time(t: np.ndarray, y: np.ndarray, ip: int) -> float | None:
    """Time [s] where the rise towards sample ``ip`` last crosses y[ip]/2 (linear interpolation)."""
    half = 0.5 * y[ip]
    below = np.nonzero(y[:ip] < half)[0]
    if below.size == 0:
        return None
    k = below[-1]
    return float(t[k] + (half - y[k]) * (t[k + 1] - t[k]) / (y[k + 1] - y[k]))


def _first_pulse_peak(t: np.ndarray, y: np.ndarray, threshold: float) -> int:
    """Index of the maximum of the first pulse of ``y`` that rises above ``threshold``.

    Starting at the first sample above the threshold, the candidate moves to the largest sample
    within +- its own half-max rise time until it is the maximum of that neighbourhood. A noise
    wiggle on the rise is never the largest sample over a rise time (the rise goes on above it),
    while a later, larger pulse lies farther than one rise time from the first maximum; the
    candidate only ever moves up, so the search ends.
    """
    above = np.nonzero(y > threshold)[0]
    if above.size == 0:
        raise PulseNotFound("no sample rises above the detection threshold")
    ip = int(above[0])
    for _ in range(y.size):
        # climb to the local maximum first (cheap, and exact for clean signals)
        while ip + 1 < y.size and y[ip + 1] >= y[ip]:
            ip += 1
        t_half = _half_max_time(t, y, ip)
        rise = t[ip] - t_half if t_half is not None else t[ip] - t[0]
        rise = max(rise, t[min(ip + 1, t.size - 1)] - t[ip])  # at least one sample ahead
        lo = np.searchsorted(t, t[ip] - rise, side="left")
        hi = np.searchsorted(t, t[ip] + rise, side="right")
        j = lo + int(np.argmax(y[lo:hi]))
        if y[j] <= y[ip]:
            break
        ip = j
    if ip == y.size - 1:
        raise PulseNotFound("the record ends before the first pulse reaches its maximum")
    return ip


def _refined(t: np.ndarray, y: np.ndarray, p0: tuple[float, float, float], fit_window: tuple[float, float],
             refine: int) -> tuple[np.ndarray, np.ndarray]:
    """The record around the loading part, resampled ``refine`` times finer by a cubic spline.

    On the record's own samples the fitted window gains or loses a whole sample as the sampling
    phase moves, and F_m jumps with it (a comb of ~0.2 % steps at 1 us samples of a 30 us pulse,
    F_m's "sampling error"); on a grid ``refine`` times finer the steps shrink as much, while the
    spline's error on a smooth pulse, ~(dt / tau)^4, stays far below them.
    """
    from scipy.interpolate import CubicSpline

    T, tau = p0[1], p0[2]
    span = (fit_window[1] - fit_window[0] + 2.0) * tau
    lo = int(np.searchsorted(t, T + fit_window[0] * tau - span, side="left"))
    hi = int(np.searchsorted(t, T + fit_window[1] * tau + span, side="right"))
    lo, hi = max(lo - 2, 0), min(hi + 2, t.size)
    if hi - lo < 4:
        return t, y
    tf = np.linspace(t[lo], t[hi - 1], (hi - lo - 1) * refine + 1)
    return tf, CubicSpline(t[lo:hi], y[lo:hi])(tf)


def _fit_loading(t: np.ndarray, y: np.ndarray, p0: tuple[float, float, float],
                 fit_window: tuple[float, float], max_iter: int, compiled: bool = False, refine: int = 1):
    """Fit F_m cos^6((t - T)/tau) on the window fit_window*tau around T, iterated to a fixed point.

    The fit runs in scaled variables (force / F_0, (t - T_0) / tau_0) so that the three
    parameters are O(1) for the Levenberg-Marquardt solver whatever the units and time origin.
    With ``refine`` > 1 it runs on the record resampled that much finer (:func:`_refined`); the
    standard errors are then those of the record's own samples (times sqrt(refine): the
    resampled points are not independent).
    """
    if refine > 1:
        t, y = _refined(t, y, p0, fit_window, refine)
    f_scale, t_ref, t_scale = p0[0], p0[1], p0[2]
    s = (t - t_ref) / t_scale
    z = y / f_scale
    params = np.array([1.0, 0.0, 1.0])  # F_m, T, tau in scaled units

    def model(x, a, b, c):
        u = (x - b) / c
        return np.where(np.abs(u) < math.pi / 2.0, a * np.cos(u) ** 6, 0.0)

    def jac(x, a, b, c):
        u = (x - b) / c
        inside = np.abs(u) < math.pi / 2.0
        cu, su = np.cos(u), np.sin(u)
        d_a = np.where(inside, cu**6, 0.0)
        d_b = np.where(inside, 6.0 * a * cu**5 * su / c, 0.0)
        d_c = np.where(inside, 6.0 * a * cu**5 * su * u / c, 0.0)
        return np.column_stack([d_a, d_b, d_c])

    moves = 0
    if compiled:
        # The window's fixed point found first by plain Gauss-Newton steps in compiled code
        # (microseconds each), so that scipy's Levenberg-Marquardt, whose Python wrapping costs
        # ~0.4 ms a call, runs once on the final window instead of once per window update (~8 on
        # a simulated pulse, 50 when the window cycles). Loading the compiled code costs ~0.2 s
        # once per process: worth it for many fits (an ensemble), not for one.
        from .window_fit import window_fixed_point

        params, moves = window_fixed_point(s, z, params, float(fit_window[0]), float(fit_window[1]),
                                           MIN_FIT_POINTS, max_iter)
    previous = None
    for iteration in range(moves + 1, max_iter + 1):
        a, b, c = params
        sel = (s > b + fit_window[0] * c) & (s <= b + fit_window[1] * c)
        idx = np.nonzero(sel)[0]
        if idx.size < MIN_FIT_POINTS * refine:  # the record's own samples count, not the resampled ones
            raise PulseNotFound(
                f"only {idx.size // refine} samples on the loading part of the first pulse (need at least "
                f"{MIN_FIT_POINTS}); the pulse (rise time ~{t_scale:.3g} s) is sampled too coarsely")
        if previous is not None and np.array_equal(idx, previous):
            # the window settled; the first scipy fit after Gauss-Newton's settled window
            # refitted that window, which is not an update of its own
            iteration -= 1 if moves else 0
            break
        previous = idx
        try:
            popt, pcov = curve_fit(model, s[idx], z[idx], p0=params, jac=jac,
                                   xtol=1e-14, ftol=1e-14, gtol=1e-14, maxfev=2000)
        except (RuntimeError, ValueError) as exc:
            raise PulseNotFound(f"the cos^6 fit of the loading part did not converge: {exc}") from exc
        if not (popt[0] > 0 and popt[2] > 0 and np.all(np.isfinite(popt))):
            raise PulseNotFound(f"the cos^6 fit gave an unphysical pulse (F_m, T, tau) = {popt}")
        params = popt
    resid = z[idx] - model(s[idx], *params)
    if idx.size > 3:
        err = np.sqrt(np.clip(np.diag(pcov), 0.0, None))
    else:  # no degree of freedom left: curve_fit cannot estimate the residual variance
        err = np.full(3, math.nan)
    scale = np.array([f_scale, t_scale, t_scale]) * math.sqrt(refine)
    value = params * scale / math.sqrt(refine) + np.array([0.0, t_ref, 0.0])
    window = (float(t[idx[0]]), float(t[idx[-1]]), int(round(idx.size / refine)))
    return (value, err * scale, window, float(f_scale * np.sqrt(np.mean(resid**2))), iteration)


def front_tail_momenta(time: np.ndarray, force: np.ndarray, split: float) -> tuple[float, float]:
    """Trapezoid integrals [N s] of ``force`` before and after time ``split`` [s].

    The record is linearly interpolated at ``split`` so that the two parts add up exactly to
    the trapezoid integral of the whole record (paper Fig. 5d: Q_F + Q_T = const).
    """
    t, f = np.asarray(time, dtype=float), np.asarray(force, dtype=float)
    total = float(np.trapezoid(f, t))
    if split <= t[0]:
        return 0.0, total
    if split >= t[-1]:
        return total, 0.0
    k = int(np.searchsorted(t, split, side="right"))  # t[k-1] <= split < t[k]
    f_split = f[k - 1] + (f[k] - f[k - 1]) * (split - t[k - 1]) / (t[k] - t[k - 1])
    front = float(np.trapezoid(f[:k], t[:k])) + 0.5 * (f[k - 1] + f_split) * (split - t[k - 1])
    return front, total - front


# --------------------------------------------------------------------------------------------
# main entry point
# --------------------------------------------------------------------------------------------
def fit_pulse(time: ArrayLike, force: ArrayLike, *, baseline: float | None = None, min_prominence: float = 0.2,
              snr_min: float = 8.0, fit_window: tuple[float, float] = (-1.0, 0.0),
              max_iter: int = 50, valid_max: float | None = None, compiled: bool = False,
              refine: int = 1) -> PulseFit:
    """Fit the first pulse of a force record with Nesterenko's profile (paper Sec. III, eq. 4).

    Method, as in the paper: the loading part -tau < t - T < 0 of the first pulse is fitted with
    F(t) = F_m cos^6[(t - T)/tau] (scipy ``curve_fit``), which defines the peak force F_m, the
    time of flight T and the duration tau. Steps:

    1. baseline: the median of the record before the pulse (t < T - 2 tau), or 0 when the record
       has fewer than 5 such samples (it starts at rest);
    2. detection: the first pulse is the first local maximum, on the scale of its own rise time,
       of the first excursion above ``max(min_prominence * max(F), snr_min * noise)``; a later,
       larger pulse (wall reflection, secondary wave) is therefore never taken for it;
    3. start values: T at the (parabolically refined) maximum, tau from the half-maximum rise
       time, since cos^6 is at half its maximum at (t - T)/tau = -arccos(2^(-1/6)) = -0.4715;
    4. fit on the samples with t - T in ``fit_window`` * tau, refit with the new window until the
       set of samples no longer changes; then the baseline is re-estimated with the fitted T and
       tau and the fit repeated until the baseline is stable.

    Parameters
    ----------
    time
        Sample times [s], strictly increasing.
    force
        Force [N] at those times (compression positive).
    baseline
        Known offset [N] to remove; None estimates it (step 1).
    min_prominence
        Fraction of the record's largest excursion above the baseline that the first pulse must
        reach to be detected (0.2: the front pulse is found even when a later pulse is up to five
        times larger).
    snr_min
        The first pulse must also rise above ``snr_min`` times the noise standard deviation
        (estimated from second differences); a noise-only record then has no pulse.
    fit_window
        Fitted range of (t - T)/tau; the paper's loading part is (-1, 0).
    max_iter
        Most window updates.
    valid_max
        The largest value the scope could record [N] (its full scale), when known: a pulse that
        reaches it is clipped.
    compiled
        Run the window updates of step 4 as compiled Gauss-Newton steps and fit with scipy once on
        the final window: the same fit (window, updates, and parameters to the solver's own
        convergence, ~1e-9), ~1 ms less per pulse of a 30,000-sample record (4.1 -> 3.1 ms), ~20 ms
        less when the window cycles between two sample sets; loading the compiled code costs
        ~0.2 s once per process: for many fits (ensembles, the explorer).
    refine
        Fit on the loading part resampled ``refine`` times finer by a cubic spline (1: the
        record's own samples, the paper's method). The fitted window then moves in steps of
        dt / refine instead of dt as the sampling phase changes, so F_m's sampling error (a
        comb of ~0.2 % steps at 1 us samples of a 30 us pulse) shrinks ``refine`` times: what
        an ensemble needs, whose spread of F_m may be only a few tenths of a per cent.

    Returns
    -------
    PulseFit
        F_m [N], T [s], tau [s] with standard errors from the fit covariance, the front and tail
        momenta Q_F, Q_T [N s], the baseline [N] and fit diagnostics.

    Raises
    ------
    PulseNotFound
        No pulse stands out of the noise, the record is too short, it ends before the first
        maximum or starts after the rise, or the pulse is sampled too coarsely to fit.
    PulseClipped
        The pulse is clipped: it reaches ``valid_max`` or its top is cut flat
        (:func:`~hertzchain.analysis.saturation.find_clipping`).
    ConfigError
        The arrays are malformed (shapes, NaN, time not increasing).
    """
    t, f = _as_signal(time, force)
    if t.size < 2 * MIN_FIT_POINTS:
        raise PulseNotFound(f"the record has only {t.size} samples; at least {2 * MIN_FIT_POINTS} are needed")
    if not (0.0 < min_prominence <= 1.0):
        raise ConfigError("min_prominence", f"must lie in (0, 1], got {min_prominence!r}")
    if not (isinstance(refine, (int, np.integer)) and 1 <= refine <= 64):
        raise ConfigError("refine", f"must be an integer in 1..64, got {refine!r}")
    if not (fit_window[0] < fit_window[1]):
        raise ConfigError("fit_window", f"must be (low, high) with low < high, got {fit_window!r}")

    from .saturation import find_clipping

    clipped = find_clipping(t, f, valid_max=valid_max)
    if clipped is not None:
        raise PulseClipped(f"the pulse is clipped: {clipped}")
    noise = estimate_noise(f)
    # First guess of the baseline, only used to detect the pulse: a low percentile sits at the
    # quiet level of the record whether or not the record has a long pre-pulse part.
    b = float(baseline) if baseline is not None else float(np.percentile(f, 10))
    y = f - b
    height = float(y.max())
    if not height > snr_min * noise:
        raise PulseNotFound(f"no pulse: the largest excursion above the baseline ({height:.3g} N) does not "
                            f"exceed {snr_min:g} x the noise level ({noise:.3g} N)")
    threshold = max(min_prominence * height, snr_min * noise)
    ip = _first_pulse_peak(t, y, threshold)

    # start values from the discrete maximum (parabola through 3 samples) and the half-max time
    T0 = float(t[ip])
    if 0 < ip < t.size - 1:
        ym, y0, yp = y[ip - 1], y[ip], y[ip + 1]
        curv = ym - 2.0 * y0 + yp
        if curv < 0:
            shift = 0.5 * (ym - yp) / curv
            T0 += shift * (t[ip + 1] - t[ip - 1]) / 2.0
    t_half = _half_max_time(t, y, ip)
    if t_half is None:
        raise PulseNotFound("the record starts during the rise of the first pulse (no half-maximum point before it)")
    tau0 = max(T0 - t_half, t[ip] - t_half) / -HALF_MAX_PHASE
    p0 = (float(y[ip]), T0, tau0)

    for _ in range(5):
        value, err, window, rms, iterations = _fit_loading(t, f - b, p0, fit_window, max_iter, compiled, refine)
        if baseline is not None:
            break
        pre = t < value[1] - PRE_PULSE_GAP * value[2]
        b_new = float(np.median(f[pre])) if np.count_nonzero(pre) >= MIN_BASELINE_POINTS else 0.0
        converged = abs(b_new - b) <= 1e-9 * value[0]
        b = b_new
        p0 = (float(value[0]), float(value[1]), float(value[2]))
        if converged:
            break
    else:  # the baseline kept moving: fit once more with the last one
        value, err, window, rms, iterations = _fit_loading(t, f - b, p0, fit_window, max_iter, compiled, refine)

    peak_force, tof, duration = (float(v) for v in value)
    if not peak_force > snr_min * noise:  # e.g. a fit to a noise wiggle of a noise-only record
        raise PulseNotFound(f"no pulse: the fitted peak force {peak_force:.3g} N does not exceed "
                            f"{snr_min:g} x the noise level ({noise:.3g} N)")
    if not (t[0] <= tof <= t[-1]):
        raise PulseNotFound(f"the fitted time of flight {tof:.6g} s lies outside the record")
    front, tail = front_tail_momenta(t, f - b, tof + duration)
    return PulseFit(
        peak_force=peak_force, time_of_flight=tof, duration=duration,
        peak_force_err=float(err[0]), time_of_flight_err=float(err[1]), duration_err=float(err[2]),
        front_momentum=front, tail_momentum=tail, total_momentum=front + tail,
        baseline=b, noise=noise, window=window[:2], n_points=window[2], residual_rms=rms, peak_index=ip, iterations=iterations,
    )
