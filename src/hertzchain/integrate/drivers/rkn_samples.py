"""Interpolants inside a step of the ``"rkn4"`` kernels whose force is the law's own at the
interpolated overlap and rate (the damped kernels of :mod:`.rkn_damped_kernels` and the state
kernels of :mod:`.rkn_state_kernels`): their samples, taken a block at a time, and the root of a
cubic Hermite (where an event lies in a step).

At the default 100 ns a step of the paper's chains holds ~20-30 samples, and ~20 of chain 1's 31
contacts carry a force at each: the samples cost about as much as the steps (issue 37). Each
contact's path over a step is written once as polynomials in theta = (t - t_b) / h: its overlap
as the quintic Hermite through (delta, d delta/dt, d^2 delta/dt^2) at both ends (the interpolant
of :func:`.rkn_kernels.quintic`'s weights, in powers of theta) and its rate as the cubic Hermite
through (rate, d rate/dt) (:func:`.rkn_kernels.hermite`'s). A sample then costs two Horner
evaluations and the law's force, one contact at a time over the step's samples, instead of the
weights and every contact's path from them for each sample. The two forms are the same
polynomials: they differ by rounding (~1e-16 of the overlap), far below the interpolant's own
error. Measured on chain 1 (2.5 ms at 100 ns, one thread): the damped kernel's run 10-20 % faster;
the state kernels' within noise of before, their law's force (a division and a square root, with
its branch and state) being what a sample costs.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .rkn_kernels import hermite, quintic, quintic_row

__all__ = ["PATH_ROWS", "path_coefficients", "path_at", "axial", "block_of_samples", "record_bodies", "hermite_root",
           "FIT_NODES", "FIT_MATRIX", "FIT_SAMPLES", "FIT_CLEARANCE", "FIT_FLOOR", "smooth_over_step", "fit_coefficients", "fit_at"]

#: Rows of a contact's path coefficients ``pc[:, j]``: six of the overlap's quintic, four of the
#: rate's cubic (powers of theta, lowest first).
PATH_ROWS = 10


@njit(cache=True, nogil=True, inline="always")
def path_coefficients(ed, b, c, j, h, pc, r_d):
    """Contact j's path over the step from end data ``ed[b]`` to ``ed[c]`` (rows ``r_d``, ``r_d + 1``,
    ``r_d + 2``: overlap, its rate, the rate's rate) into ``pc[:, j]``."""
    hh = 0.5 * h * h
    quintic_row(pc, j, ed[b, r_d, j], h * ed[b, r_d + 1, j], hh * ed[b, r_d + 2, j], ed[c, r_d, j],
                h * ed[c, r_d + 1, j], hh * ed[c, r_d + 2, j])
    r0 = ed[b, r_d + 1, j]
    g0 = h * ed[b, r_d + 2, j]
    r1 = ed[c, r_d + 1, j]
    g1 = h * ed[c, r_d + 2, j]
    pc[6, j] = r0
    pc[7, j] = g0
    pc[8, j] = 3.0 * (r1 - r0) - 2.0 * g0 - g1
    pc[9, j] = 2.0 * (r0 - r1) + g0 + g1


@njit(cache=True, nogil=True, inline="always")
def path_at(pc, j, x):
    """(overlap [m], rate [m/s]) of contact j at theta = x of the step (:func:`path_coefficients`)."""
    d = pc[0, j] + x * (pc[1, j] + x * (pc[2, j] + x * (pc[3, j] + x * (pc[4, j] + x * pc[5, j]))))
    r = pc[6, j] + x * (pc[7, j] + x * (pc[8, j] + x * pc[9, j]))
    return d, r


@njit(cache=True, nogil=True, inline="always")
def axial_factor(de2, rsum, d):
    """dx / dist of an offset pair at overlap d [m]: the share of its force along the chain's axis
    (de2: the square of its centres' distance across the axis, rsum = R_j + R_{j+1}, dist = rsum - d
    the centres' distance). Without a branch, so that a loop over samples of it vectorises."""
    dist = rsum - d
    x = dist * dist - de2
    return np.sqrt(x if x > 0.0 else 0.0) / dist


@njit(cache=True, nogil=True, inline="always")
def axial(f, off, j, d):
    """The part along the chain's axis of a contact force f [N] at overlap d [m]: f itself for an
    aligned pair, f dx / dist for a pair whose centres are ``off[0, j]`` apart across the axis
    (:func:`axial_factor`; ``off`` without columns, or None, for an aligned chain)."""
    if off is not None and off.shape[1] > 0:
        de = off[0, j]
        if de != 0.0:
            f *= axial_factor(de * de, off[2, j], d)
    return f


@njit(cache=True, nogil=True, inline="always")
def block_of_samples(k, k_stop, interval, tp, t, h, th):
    """Samples k, k + 1, ... (``interval`` [s] apart) that lie in the step (tp, tp + h = t], at most
    ``th.shape[0]`` and none from k_stop on: their theta into ``th``; returns the first sample
    after them."""
    kb = k
    while True:
        th[kb - k] = (kb * interval - tp) / h
        kb += 1
        if kb >= k_stop or kb - k >= th.shape[0] or kb * interval > t:
            return kb


@njit(cache=True, nogil=True, inline="always")
def record_bodies(out_v, record_v, out_u, record_u, k, x, h, up, vp, ap, u, v, a):
    """Sample k at theta = x of the step from (up, vp, ap) to (u, v, a): the bodies' velocities
    (cubic Hermite) into ``out_v[k]`` and displacements (quintic Hermite) into ``out_u[k]``, where
    they are recorded."""
    if record_v:
        w0, w0d, w1, w1d = hermite(x, h)
        for i in range(out_v.shape[1]):
            out_v[k, i] = w0 * vp[i] + w0d * ap[i] + w1 * v[i] + w1d * a[i]
    if record_u:
        q0, q0d, q0dd, q1, q1d, q1dd = quintic(x, h)
        for i in range(out_u.shape[1]):
            out_u[k, i] = q0 * up[i] + q0d * vp[i] + q0dd * ap[i] + q1 * u[i] + q1d * v[i] + q1dd * a[i]


@njit(cache=True, nogil=True, error_model="numpy")
def hermite_root(y0, s0, y1, s1, h):
    """theta in [0, 1] where the cubic Hermite through (y0, y0') and (y1, y1') (rates per second,
    step h) crosses 0, y0 and y1 of opposite signs (Illinois regula falsi; the straight line
    when a rate is not finite)."""
    if not (np.isfinite(s0) and np.isfinite(s1)):
        s0 = s1 = (y1 - y0) / h
    lo, hi = 0.0, 1.0
    flo, fhi = y0, y1
    x = 0.0
    side = 0
    for _ in range(60):
        x = (lo * fhi - hi * flo) / (fhi - flo)
        w0, w0d, w1, w1d = hermite(x, h)
        fx = w0 * y0 + w0d * s0 + w1 * y1 + w1d * s1
        if (fx > 0.0) == (flo > 0.0):
            lo, flo = x, fx
            if side == -1:
                fhi *= 0.5
            side = -1
        else:
            hi, fhi = x, fx
            if side == 1:
                flo *= 0.5
            side = 1
        if hi - lo < 1e-12:
            break
    return x


#: Nodes in theta of the polynomial fitted to a smooth contact's force over a step (the Chebyshev
#: points of [0, 1], six: degree 5, the order of the overlap's quintic).
FIT_NODES = 0.5 - 0.5 * np.cos((2.0 * np.arange(6) + 1.0) * np.pi / 12.0)
#: Its monomial coefficients from the forces at the nodes: c = FIT_MATRIX @ f.
FIT_MATRIX = np.linalg.inv(np.vander(FIT_NODES, 6, increasing=True))
#: A step holding at least this many samples fits its smooth contacts' forces (six law evaluations
#: each) instead of evaluating the law at every sample.
FIT_SAMPLES = 8.0
#: A contact is smooth over a step when its gap beyond the law's opening exceeds this many times
#: the step's travel |rate| h at both ends: the nearest singularity of its force (delta^(1/2) at
#: the opening) then lies at least that many steps away in time. The fit's largest error on
#: (theta + k)^(3/2) over [0, 1] is 2.6e-7 of the force for k = 1 step, 1.2e-8 for 2, 3.7e-10 for 4
#: (far below the interpolated path's own error); nearer the opening the law is evaluated at
#: every sample.
FIT_CLEARANCE = 4.0
#: ... or when its force stays at or below this fraction of the largest force sampled so far in
#: the run (the numerical precursor ahead of a pulse: forces ~1e-20-1e-35 N, overlaps that grow
#: by a large factor a step, so rarely clear of their opening). The fit then interpolates forces
#: within [0, FIT_FLOOR scale] at its nodes and the step's ends, and errs by at most a few times
#: that (the overlap's quintic stays within ~2x its values at six Chebyshev nodes): ~1e-11 of the
#: run's largest force, where evaluating the law at every sample cost the elastic-plastic law a
#: quarter of its run on chain 1 (200,000 evaluations, most of them on the precursor).
FIT_FLOOR = 1e-12


@njit(cache=True, nogil=True, inline="always")
def smooth_over_step(gap0, r0, gap1, r1, h):
    """Whether a contact with gaps ``gap0``, ``gap1`` [m] and rates ``r0``, ``r1`` [m/s] at a step's
    ends is far enough from its opening for a fitted force (:data:`FIT_CLEARANCE`)."""
    return gap0 > FIT_CLEARANCE * abs(r0) * h and gap1 > FIT_CLEARANCE * abs(r1) * h


@njit(cache=True, nogil=True, inline="always")
def fit_coefficients(vals, fc, j):
    """Monomial coefficients (in theta) of the degree-5 polynomial through ``vals`` at
    :data:`FIT_NODES` into ``fc[:, j]``."""
    for m in range(6):
        s = 0.0
        for i in range(6):
            s += FIT_MATRIX[m, i] * vals[i]
        fc[m, j] = s


@njit(cache=True, nogil=True, inline="always")
def fit_at(fc, j, x):
    """Contact j's fitted force at theta = x (:func:`fit_coefficients`), clipped at 0."""
    f = fc[0, j] + x * (fc[1, j] + x * (fc[2, j] + x * (fc[3, j] + x * (fc[4, j] + x * fc[5, j]))))
    return f if f > 0.0 else 0.0
