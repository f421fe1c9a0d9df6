"""The wall-pulse fit of many records at once, compiled end to end: an ensemble's metrics.

:func:`fit_pulses` gives, for every row of a (members, samples) force array, the numbers of
:func:`hertzchain.analysis.fit_pulse` with ``compiled=True`` and the default detection settings:
F_m [N], T [s], tau [s] of the cos^6 fit of the loading part (paper Sec. III, eq. 4) and the
front and tail momenta Q_F, Q_T [N s] (Fig. 5d). The same steps run in one compiled loop over the
members per core (threads without the GIL), with no Python per member: the clipping test, the
noise estimate, the detection of the first pulse and its start values, the loading part resampled ``refine`` times
finer by the not-a-knot cubic spline (scipy's ``CubicSpline``), the window's fixed point by
Gauss-Newton steps (:func:`~hertzchain.analysis.window_fit.window_fixed_point`), the baseline
loop and the momenta.

One difference: ``fit_pulse`` ends with one scipy Levenberg-Marquardt fit on the settled window,
which refines the Gauss-Newton parameters only to the solvers' own convergence (~1e-9 relative),
and gives the covariance; here the Gauss-Newton parameters are the answer (no standard errors: an
ensemble's metrics table has none). Every record whose fit leaves the regular path (a flat top
that may be clipped, no pulse above the noise, a window that never settles, too few samples...)
gets status 1 and no numbers: the caller fits it with ``fit_pulse`` itself, which says why.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from numba import njit

from ..parallel import on_threads, usable_cores
from ..theory import HALF_MAX_PHASE
from .pulse import MIN_BASELINE_POINTS, MIN_FIT_POINTS, PRE_PULSE_GAP, _D2_CORRELATION
from .window_fit import _gauss_newton, _window, window_fixed_point

__all__ = ["fit_pulses", "PULSE_COLUMNS"]

#: The columns of :func:`fit_pulses`'s values, as ``PulseFit``'s fields.
PULSE_COLUMNS = ("peak_force", "time_of_flight", "duration", "front_momentum", "tail_momentum")

#: Status of a row: fitted here, or to be fitted by ``fit_pulse`` (which raises or explains).
FITTED, FALLBACK = 0, 1


@njit(cache=True)
def _noise(f, block):
    """:func:`hertzchain.analysis.pulse.estimate_noise` of one record [N]."""
    n2 = f.size - 2
    if n2 < 8:
        if n2 <= 0:
            return 0.0
        s = 0.0
        for i in range(n2):
            d = f[i + 2] - 2.0 * f[i + 1] + f[i]
            s += d * d
        return math.sqrt(s / n2 / 6.0)
    block = min(block, max(4, n2 // 8))
    n_blocks = n2 // block
    ms = np.empty(n_blocks)
    for k in range(n_blocks):
        s = 0.0
        for i in range(k * block, (k + 1) * block):
            d = f[i + 2] - 2.0 * f[i + 1] + f[i]
            s += d * d
        ms[k] = s / block
    spread = math.sqrt(2.0 * _D2_CORRELATION / block)
    ref = _quantile(ms.copy(), 0.25) / max(1.0 - 0.674 * spread, 0.2)
    for _ in range(4):
        s = 0.0
        count = 0
        limit = (1.0 + 4.0 * spread) * ref
        for k in range(n_blocks):
            if ms[k] <= limit:
                s += ms[k]
                count += 1
        if count == 0:
            break
        ref = s / count
    return math.sqrt(ref / 6.0)


@njit(cache=True)
def _min_count(y):
    """(smallest value of y, how many samples hold it): one pass, no copy."""
    lo = y[0]
    count = 0
    for v in y:
        if v < lo:
            lo = v
            count = 1
        elif v == lo:
            count += 1
    return lo, count


@njit(cache=True)
def _select(w, k):
    """The k-th smallest value of ``w`` (from 0), ``w`` reordered in place so that every value after
    index k is at least it (quickselect, Hoare's partition about a median of three). Written here
    rather than ``np.partition``/``np.percentile``/``np.median``: Numba compiles those in ~1-3 s
    each, and the first ensemble, sweep or Dask worker waited for them (issue 37)."""
    lo = 0
    hi = w.size - 1
    while lo < hi:
        a, b, c = w[lo], w[(lo + hi) // 2], w[hi]
        pivot = max(min(a, b), min(max(a, b), c))
        i, j = lo, hi
        while i <= j:
            while w[i] < pivot:
                i += 1
            while w[j] > pivot:
                j -= 1
            if i <= j:
                w[i], w[j] = w[j], w[i]
                i += 1
                j -= 1
        if k <= j:
            hi = j
        elif k >= i:
            lo = i
        else:  # between the two parts: equal to the pivot
            break
    return w[k]


@njit(cache=True)
def _quantile(w, q):
    """``np.quantile(w, q)`` (numpy's linear method, its rounding), ``w`` a scratch copy
    (reordered)."""
    x = q * (w.size - 1)
    k = int(math.floor(x))
    a = _select(w, k)
    b = w[k + 1:].min() if k + 1 < w.size else a
    frac = x - k
    d = b - a
    return b - d * (1.0 - frac) if frac >= 0.5 else a + d * frac


@njit(cache=True)
def _percentile_10(y):
    """``np.percentile(y, 10)``; the smallest value when more than the lowest 10 % (plus one)
    hold it (a wall's record before its pulse arrives: the same number without the copy)."""
    k = int(math.floor(0.1 * (y.size - 1)))
    lo, count = _min_count(y)
    if count > k + 1:  # both order statistics the interpolation takes are the minimum
        return lo
    return _quantile(y.copy(), 0.1)


@njit(cache=True)
def _median(y):
    """``np.median(y)``; the smallest value, without the copy, when more than half the samples hold
    it (then both middle order statistics are that value)."""
    lo, count = _min_count(y)
    n = y.size
    if count > n // 2 + 1:
        return lo
    w = y.copy()
    b = _select(w, n // 2)
    if n % 2:
        return b
    return (w[:n // 2].max() + b) / 2.0  # numpy's mean of the two middle values


@njit(cache=True)
def _flat_top(y, base):
    """True when the record's maximum is held by three or more samples of the part above half
    its height (``saturation.find_clipping``'s first test, ``base`` its 10th percentile: a smooth
    record has one), so that the clipping test proper (``fit_pulse``'s) must decide."""
    i = np.argmax(y)
    top = y[i]
    if not top > base:
        return False
    half = base + 0.5 * (top - base)
    a = i
    while a > 0 and y[a - 1] > half:
        a -= 1
    b = i
    while b < y.size - 1 and y[b + 1] > half:
        b += 1
    on_top = 0
    for k in range(a, b + 1):
        if y[k] == top:
            on_top += 1
    return on_top >= 3


@njit(cache=True)
def _half_max_time(t, y, ip):
    """``pulse._half_max_time``: the time the rise to sample ip last crosses y[ip]/2 (NaN: never)."""
    half = 0.5 * y[ip]
    for k in range(ip - 1, -1, -1):
        if y[k] < half:
            return t[k] + (half - y[k]) * (t[k + 1] - t[k]) / (y[k + 1] - y[k])
    return np.nan


@njit(cache=True)
def _first_pulse_peak(t, y, threshold):
    """``pulse._first_pulse_peak``; -1 when there is no pulse or the record ends at its maximum."""
    ip = -1
    for k in range(y.size):
        if y[k] > threshold:
            ip = k
            break
    if ip < 0:
        return -1
    for _ in range(y.size):
        while ip + 1 < y.size and y[ip + 1] >= y[ip]:
            ip += 1
        t_half = _half_max_time(t, y, ip)
        rise = t[ip] - t_half if not math.isnan(t_half) else t[ip] - t[0]
        rise = max(rise, t[min(ip + 1, t.size - 1)] - t[ip])
        lo = np.searchsorted(t, t[ip] - rise, side="left")
        hi = np.searchsorted(t, t[ip] + rise, side="right")
        j = lo + np.argmax(y[lo:hi])
        if y[j] <= y[ip]:
            break
        ip = j
    if ip == y.size - 1:
        return -1
    return ip


@njit(cache=True)
def _spline_slopes(x, y):
    """First derivatives at the knots of the not-a-knot cubic spline through (x, y) (scipy's
    ``CubicSpline`` system, tridiagonal, by the Thomas algorithm); needs x.size >= 4."""
    n = x.size
    dx = np.empty(n - 1)
    slope = np.empty(n - 1)
    for i in range(n - 1):  # (np.diff: ~0.5 s more to compile)
        dx[i] = x[i + 1] - x[i]
        slope[i] = (y[i + 1] - y[i]) / dx[i]
    lower = np.zeros(n)  # A[i, i - 1]
    diag = np.zeros(n)
    upper = np.zeros(n)  # A[i, i + 1]
    rhs = np.zeros(n)
    for i in range(1, n - 1):
        lower[i] = dx[i]
        diag[i] = 2.0 * (dx[i - 1] + dx[i])
        upper[i] = dx[i - 1]
        rhs[i] = 3.0 * (dx[i] * slope[i - 1] + dx[i - 1] * slope[i])
    d = x[2] - x[0]
    diag[0] = dx[1]
    upper[0] = d
    rhs[0] = ((dx[0] + 2.0 * d) * dx[1] * slope[0] + dx[0] ** 2 * slope[1]) / d
    d = x[n - 1] - x[n - 3]
    diag[n - 1] = dx[n - 3]
    lower[n - 1] = d
    rhs[n - 1] = (dx[n - 2] ** 2 * slope[n - 3] + (2.0 * d + dx[n - 2]) * dx[n - 3] * slope[n - 2]) / d
    for i in range(1, n):  # forward elimination
        w = lower[i] / diag[i - 1]
        diag[i] -= w * upper[i - 1]
        rhs[i] -= w * rhs[i - 1]
    m = np.empty(n)
    m[n - 1] = rhs[n - 1] / diag[n - 1]
    for i in range(n - 2, -1, -1):
        m[i] = (rhs[i] - upper[i] * m[i + 1]) / diag[i]
    return m


@njit(cache=True)
def _refined(t, y, T, tau, w_lo, w_hi, refine):
    """``pulse._refined``: the record around the loading part resampled ``refine`` times finer by
    the not-a-knot cubic spline through its samples (the record itself when too short)."""
    span = (w_hi - w_lo + 2.0) * tau
    lo = np.searchsorted(t, T + w_lo * tau - span, side="left")
    hi = np.searchsorted(t, T + w_hi * tau + span, side="right")
    lo, hi = max(lo - 2, 0), min(hi + 2, t.size)
    if hi - lo < 4:
        return t.copy(), y.copy()
    x = t[lo:hi]
    yy = y[lo:hi]
    m = _spline_slopes(x, yy)
    tf = np.linspace(t[lo], t[hi - 1], (hi - lo - 1) * refine + 1)
    n = x.size
    c0 = np.empty(n - 1)  # scipy's PPoly coefficients of each interval, once per interval
    c1 = np.empty(n - 1)
    for i in range(n - 1):
        h = x[i + 1] - x[i]
        s = (yy[i + 1] - yy[i]) / h
        c = (m[i] + m[i + 1] - 2.0 * s) / h
        c0[i] = c / h
        c1[i] = (s - m[i]) / h - c
    yf = np.empty(tf.size)
    i = 0
    for k in range(tf.size):
        # scipy's PPoly: the interval [x_i, x_i+1) holding tf[k] (tf increases: a walk, not a search)
        while i < n - 2 and tf[k] >= x[i + 1]:
            i += 1
        u = tf[k] - x[i]
        yf[k] = ((c0[i] * u + c1[i]) * u + m[i]) * u + yy[i]
    return tf, yf


@njit(cache=True)
def _fit_loading(t, y, p0, w_lo, w_hi, max_iter, refine, out):
    """``pulse._fit_loading`` up to its last scipy fit: F_m, T, tau into out[:3]; False when the
    fit leaves the regular path (``fit_pulse`` then decides)."""
    if refine > 1:
        t, y = _refined(t, y, p0[1], p0[2], w_lo, w_hi, refine)
    f_scale, t_ref, t_scale = p0[0], p0[1], p0[2]
    s = (t - t_ref) / t_scale
    z = y / f_scale
    p, moves = window_fixed_point(s, z, np.array([1.0, 0.0, 1.0]), w_lo, w_hi, MIN_FIT_POINTS, max_iter)
    if moves == 0:  # a failed fit: scipy's loop does every update (and says what went wrong)
        return False
    if moves == max_iter - 1:
        # the window kept moving (a cycle): fit_pulse's last scipy fit, on the window of p
        lo, hi = _window(s, p[1], p[2], w_lo, w_hi)
        if hi - lo < MIN_FIT_POINTS * refine or not _gauss_newton(s, z, lo, hi, p, 50):
            return False
    lo = np.searchsorted(s, p[1] + w_lo * p[2], side="right")
    hi = np.searchsorted(s, p[1] + w_hi * p[2], side="right")
    if hi - lo < MIN_FIT_POINTS * refine:
        return False
    out[0] = p[0] * f_scale
    out[1] = p[1] * t_scale + t_ref
    out[2] = p[2] * t_scale
    return True


@njit(cache=True)
def _momenta(t, f, b, split):
    """``pulse.front_tail_momenta`` of f - b split at ``split`` [s]."""
    n = t.size
    k = np.searchsorted(t, split, side="right") if t[0] < split < t[n - 1] else 0
    total = 0.0
    front = 0.0
    for i in range(n - 1):  # one pass: the front's terms are the total's first k - 1, in the same order
        total += 0.5 * ((f[i] - b) + (f[i + 1] - b)) * (t[i + 1] - t[i])
        if i == k - 2:
            front = total
    if split <= t[0]:
        return 0.0, total
    if split >= t[n - 1]:
        return total, 0.0
    f_split = (f[k - 1] - b) + ((f[k] - b) - (f[k - 1] - b)) * (split - t[k - 1]) / (t[k] - t[k - 1])
    front += 0.5 * ((f[k - 1] - b) + f_split) * (split - t[k - 1])
    return front, total - front


@njit(cache=True)
def _fit_one(t, f, min_prominence, snr_min, w_lo, w_hi, max_iter, refine, out):
    """``fit_pulse(t, f, compiled=True, refine=refine)`` with an estimated baseline, into out[:5];
    False where that call would take another path (it is then made as it is)."""
    if t.size < 2 * MIN_FIT_POINTS or not np.all(np.isfinite(f)):
        return False
    b = _percentile_10(f)
    if _flat_top(f, b):
        return False
    noise = _noise(f, 32)
    y = f - b
    height = y.max()
    if not height > snr_min * noise:
        return False
    ip = _first_pulse_peak(t, y, max(min_prominence * height, snr_min * noise))
    if ip < 0:
        return False
    T0 = t[ip]
    if 0 < ip < t.size - 1:
        ym, y0, yp = y[ip - 1], y[ip], y[ip + 1]
        curv = ym - 2.0 * y0 + yp
        if curv < 0:
            T0 += 0.5 * (ym - yp) / curv * (t[ip + 1] - t[ip - 1]) / 2.0
    t_half = _half_max_time(t, y, ip)
    if math.isnan(t_half):
        return False
    p0 = np.array([y[ip], T0, max(T0 - t_half, t[ip] - t_half) / -HALF_MAX_PHASE])
    value = np.empty(3)
    converged = False
    for _ in range(5):
        if not _fit_loading(t, f - b, p0, w_lo, w_hi, max_iter, refine, value):
            return False
        count = 0
        for k in range(t.size):
            if t[k] < value[1] - PRE_PULSE_GAP * value[2]:
                count += 1
        b_new = _median(f[:count]) if count >= MIN_BASELINE_POINTS else 0.0  # t increases: the first ones
        converged = abs(b_new - b) <= 1e-9 * value[0]
        b = b_new
        p0[:] = value
        if converged:
            break
    if not converged and not _fit_loading(t, f - b, p0, w_lo, w_hi, max_iter, refine, value):
        return False
    if not (value[0] > snr_min * noise and t[0] <= value[1] <= t[t.size - 1]):
        return False
    out[0], out[1], out[2] = value[0], value[1], value[2]
    out[3], out[4] = _momenta(t, f, b, value[1] + value[2])
    return True


@njit(cache=True, nogil=True)
def _fit_rows(rows, t, force, min_prominence, snr_min, w_lo, w_hi, max_iter, refine, out, status):
    """The rows ``rows`` of ``force``: each core a share of the rows in a thread of its own
    (:func:`hertzchain.parallel.on_threads`; a plain loop without the GIL: Numba's ``prange``
    compiled for ~6 s more, and two Dask worker threads launching it at once aborted its
    threading layer)."""
    for m in rows:
        ok = _fit_one(t, force[m], min_prominence, snr_min, w_lo, w_hi, max_iter, refine, out[m])
        status[m] = FITTED if ok else FALLBACK


#: Rows per thread below which one thread fits them all (a thread's start costs more than a fit).
_ROWS_PER_THREAD = 8


def fit_pulses(time: np.ndarray, force: np.ndarray, *, refine: int = 1, max_iter: int = 50,
               min_prominence: float = 0.2, snr_min: float = 8.0,
               fit_window: tuple[float, float] = (-1.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """The first-pulse fits of many records sharing one time axis (module docstring).

    Parameters
    ----------
    time:
        Sample times [s], shape (K,), strictly increasing (not checked here: the records of a
        batched run).
    force:
        Force records [N], shape (M, K), finite.
    refine, max_iter, min_prominence, snr_min, fit_window:
        As :func:`hertzchain.analysis.fit_pulse`'s.

    Returns
    -------
    values : numpy.ndarray
        Shape (M, 5): :data:`PULSE_COLUMNS` (F_m [N], T [s], tau [s], Q_F [N s], Q_T [N s]); NaN
        where the status is not 0.
    status : numpy.ndarray
        Shape (M,): 0 fitted here, 1 to be fitted by ``fit_pulse`` (which raises or explains).
    """
    t = np.ascontiguousarray(time, dtype=float)
    f = np.ascontiguousarray(force, dtype=float)
    out = np.full((f.shape[0], len(PULSE_COLUMNS)), np.nan)
    status = np.empty(f.shape[0], dtype=np.int64)
    threads = max(1, min(usable_cores(), f.shape[0] // _ROWS_PER_THREAD))
    on_threads(_fit_rows, np.array_split(np.arange(f.shape[0]), threads), t, f, float(min_prominence), float(snr_min),
               float(fit_window[0]), float(fit_window[1]), int(max_iter), int(refine), out, status)
    out[status != FITTED] = np.nan
    return out, status


def _flush_stale_cache() -> None:
    """Drop the on-disk cache of the functions here that compile in ``window_fit.py``'s or
    ``pulse.py``'s code (constants included) when either is newer than it: Numba's cache checks
    only the file of the cached function, and a caller compiles its callees' cached code in."""
    newest = max(Path(__file__).with_name(n).stat().st_mtime for n in ("window_fit.py", "pulse.py"))
    compiled: tuple[Any, ...] = (_fit_loading, _fit_one, _fit_rows)  # (their cache: private Numba API, untyped)
    for fn in compiled:
        try:
            index = Path(fn._cache._cache_file._index_path)
            if index.exists() and index.stat().st_mtime < newest:
                fn._cache.flush()
        except (AttributeError, OSError):  # private Numba API moved or no cache: nothing to protect
            pass


_flush_stale_cache()
