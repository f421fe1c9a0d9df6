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


#: Taylor coefficients (-1)^k / (2k)! of cos and (-1)^k / (2k + 1)! of sin, k = 0..10: on |u| < pi/2
#: the remainders are below 3e-17, under half an ulp of 1 (see :func:`_cos_sin`).
_COS = tuple((-1.0) ** k / math.factorial(2 * k) for k in range(11))
_SIN = tuple((-1.0) ** k / math.factorial(2 * k + 1) for k in range(11))


@njit(cache=True, inline="always")
def _cos_sin(u):
    """cos u and sin u for |u| < pi/2 as polynomials (Horner in u^2), to ~1 ulp like libm's: plain
    arithmetic, so that the fit's loop over samples compiles to vector instructions (no vector
    libm here)."""
    u2 = u * u
    c = _COS[10]
    sn = _SIN[10]
    for k in range(9, -1, -1):
        c = c * u2 + _COS[k]
        sn = sn * u2 + _SIN[k]
    return c, sn * u


@njit(cache=True, fastmath={"reassoc", "contract"})
def _normal_equations(s, z, lo, hi, a, b, c):
    """J^T J (symmetric: six sums) and J^T r of the cos^6 fit on samples lo..hi - 1, with the
    Jacobian's columns (cos^6 u, 6 a cos^5 u sin u / c, u times the second), u = (s - b) / c;
    samples with |u| >= pi/2 (outside the pulse, where the model is 0) count for nothing. The
    sums are reassociated (vector lanes): rounding-level changes only."""
    s00 = s01 = s02 = s11 = s12 = s22 = 0.0
    g0 = g1 = g2 = 0.0
    inv_c = 1.0 / c
    for i in range(lo, hi):
        u = (s[i] - b) * inv_c
        inside = 1.0 if abs(u) < HALF_PI else 0.0
        uc = u if abs(u) < HALF_PI else 0.0  # keeps the polynomials on their interval
        cu, su = _cos_sin(uc)
        c2 = cu * cu
        c5 = c2 * c2 * cu * inside
        j0 = c5 * cu
        j1 = 6.0 * a * c5 * su * inv_c
        j2 = j1 * u
        r = z[i] - a * j0
        g0 += j0 * r
        g1 += j1 * r
        g2 += j2 * r
        s00 += j0 * j0
        s01 += j0 * j1
        s02 += j0 * j2
        s11 += j1 * j1
        s12 += j1 * j2
        s22 += j2 * j2
    return s00, s01, s02, s11, s12, s22, g0, g1, g2


#: Rank test of the normal equations (``np.linalg.matrix_rank``'s tolerance, 3 eps times the
#: largest singular value, with the trace, which bounds it, in its place).
_RANK_EPS = 3.0 * np.finfo(np.float64).eps


@njit(cache=True, inline="always")
def _solve_normal(s00, s01, s02, s11, s12, s22, g0, g1, g2):
    """(ok, x) with J^T J x = J^T r by Cholesky's factorisation of the symmetric 3x3 matrix (no
    LAPACK call: a few ns instead of the microseconds of an SVD and a general solve per
    Gauss-Newton step); ok False when a pivot falls below the rank tolerance (:data:`_RANK_EPS`)."""
    tol = _RANK_EPS * (s00 + s11 + s22)
    if not s00 > tol:
        return False, 0.0, 0.0, 0.0
    l00 = math.sqrt(s00)
    l10 = s01 / l00
    l20 = s02 / l00
    d11 = s11 - l10 * l10
    if not d11 > tol:
        return False, 0.0, 0.0, 0.0
    l11 = math.sqrt(d11)
    l21 = (s12 - l20 * l10) / l11
    d22 = s22 - l20 * l20 - l21 * l21
    if not d22 > tol:
        return False, 0.0, 0.0, 0.0
    l22 = math.sqrt(d22)
    y0 = g0 / l00
    y1 = (g1 - l10 * y0) / l11
    y2 = (g2 - l20 * y0 - l21 * y1) / l22
    x2 = y2 / l22
    x1 = (y1 - l21 * x2) / l11
    x0 = (y0 - l10 * x1 - l20 * x2) / l00
    return True, x0, x1, x2


@njit(cache=True)
def _gauss_newton(s, z, lo, hi, p, steps):
    """Gauss-Newton fit of a cos^6((s - b)/c) to z[lo:hi] from p = (a, b, c), in place; True when it
    converged to a physical pulse (a > 0, c > 0)."""
    for _ in range(steps):
        s00, s01, s02, s11, s12, s22, g0, g1, g2 = _normal_equations(s, z, lo, hi, p[0], p[1], p[2])
        ok, x0, x1, x2 = _solve_normal(s00, s01, s02, s11, s12, s22, g0, g1, g2)
        if not (ok and math.isfinite(x0) and math.isfinite(x1) and math.isfinite(x2)):
            return False
        p[0] += x0
        p[1] += x1
        p[2] += x2
        if not (p[0] > 0.0 and p[2] > 0.0):
            return False
        if (abs(x0) <= 1e-11 * (1.0 + abs(p[0])) and abs(x1) <= 1e-11 * (1.0 + abs(p[1]))
                and abs(x2) <= 1e-11 * (1.0 + abs(p[2]))):
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

    A window that comes back to the one of two updates before cycles between the two from there
    on (each fit is the least-squares fit of its window, whatever it started from): the result of
    the ``max_iter - 1`` updates is then the fit of the same parity, without making them.
    """
    p = p0.copy()
    older = p0.copy()  # the parameters one update before p
    prev_lo, prev_hi, moves = -1, -1, 0
    prev2_lo, prev2_hi = -1, -1
    for _ in range(max_iter - 1):
        lo, hi = _window(s, p[1], p[2], w_lo, w_hi)
        if hi - lo < min_points:
            return p0.copy(), 0
        if lo == prev_lo and hi == prev_hi:
            return p, moves
        if moves >= 2 and lo == prev2_lo and hi == prev2_hi:
            # updates moves + 1, moves + 2, ... give the fits of older's and p's windows in turn
            return (p if (max_iter - 1 - moves) % 2 == 0 else older), max_iter - 1
        prev2_lo, prev2_hi = prev_lo, prev_hi
        prev_lo, prev_hi = lo, hi
        older[:] = p
        if not _gauss_newton(s, z, lo, hi, p, 50):
            return p0.copy(), 0
        moves += 1
    return p, moves
