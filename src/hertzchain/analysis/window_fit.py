"""The fixed point of the cos^6 fit window, compiled: the inner loop of :func:`~hertzchain.analysis.fit_pulse`.

:func:`fit_pulse` fits F(t) = F_m cos^6[(t - T)/tau] (paper Sec. III, eq. 4) on the samples with
(t - T)/tau in a window, and refits with the new window until the set of samples stops changing.
On a simulated pulse that takes ~8 window updates, and each scipy ``curve_fit`` call costs ~0.4 ms
of Python wrapping: most of the time of a metrics-only ensemble. Here the window updates run as
plain Gauss-Newton steps in compiled code (microseconds each); scipy then fits once on the final
window, which gives the answer and its covariance.

Times are increasing, so a window is a contiguous run of samples: (first, end) indices.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

HALF_PI = 0.5 * math.pi


@njit(cache=True)
def _window(s, b, c, w_lo, w_hi):
    """First index with s > b + w_lo c and one past the last with s <= b + w_hi c."""
    return np.searchsorted(s, b + w_lo * c, side="right"), np.searchsorted(s, b + w_hi * c, side="right")


@njit(cache=True)
def _gauss_newton(s, z, lo, hi, p, steps):
    """Gauss-Newton fit of a cos^6((s - b)/c) to z[lo:hi] from p = (a, b, c), in place; True when it
    converged to a physical pulse (a > 0, c > 0)."""
    for _ in range(steps):
        A = np.zeros((3, 3))
        g = np.zeros(3)
        a, b, c = p[0], p[1], p[2]
        for i in range(lo, hi):
            u = (s[i] - b) / c
            if abs(u) >= HALF_PI:
                continue
            cu, su = math.cos(u), math.sin(u)
            c5 = cu ** 5
            j = (c5 * cu, 6.0 * a * c5 * su / c, 6.0 * a * c5 * su * u / c)
            r = z[i] - a * c5 * cu
            for k in range(3):
                g[k] += j[k] * r
                for m in range(3):
                    A[k, m] += j[k] * j[m]
        if np.linalg.matrix_rank(A) < 3:
            return False
        step = np.linalg.solve(A, g)
        if not np.all(np.isfinite(step)):
            return False
        p += step
        if not (p[0] > 0.0 and p[2] > 0.0):
            return False
        if np.all(np.abs(step) <= 1e-11 * (1.0 + np.abs(p))):
            return True
    return False


@njit(cache=True)
def window_fixed_point(s, z, p0, w_lo, w_hi, min_points, max_iter):
    """Window updates from p0 until the window stops changing, at most ``max_iter - 1`` of them.

    Returns (p, moves): the parameters after ``moves`` window updates, at the fixed point or, when
    the window keeps moving (it may cycle between two sample sets), after ``max_iter - 1`` updates,
    so that the caller's last scipy fit is its ``max_iter``-th, as without this function. (p0, 0)
    when a window holds fewer than ``min_points`` samples or a fit fails: the caller's scipy loop
    then does every update itself (and reports what went wrong).
    """
    p = p0.copy()
    prev_lo, prev_hi, moves = -1, -1, 0
    for _ in range(max_iter - 1):
        lo, hi = _window(s, p[1], p[2], w_lo, w_hi)
        if hi - lo < min_points:
            return p0.copy(), 0
        if lo == prev_lo and hi == prev_hi:
            return p, moves
        prev_lo, prev_hi = lo, hi
        if not _gauss_newton(s, z, lo, hi, p, 50):
            return p0.copy(), 0
        moves += 1
    return p, moves
