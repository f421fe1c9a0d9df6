"""The thread function of the fourth-order integrator ``"rkn4"`` on several cores: one thread's
share of :func:`hertzchain.integrate.drivers.rkn_kernels.rkn_run` (aligned elastic chains).

Every thread owns a block of slots [s, e) (:class:`RknTeam`, a multiple of ``layout.PAD`` so that
no cache line is written by two threads) and runs SRKN_6^b's stages over it with the same per-body
arithmetic in the same order as one thread (``rkn_kernels._stage``, ``_closing``; paper eq. 1):
the force of the contact on a block's left comes from the left neighbour's last position and the
block's own first one, the last body's from the right neighbour's first position, each published
before the stage in one of two slots that alternate from stage to stage and read after one
barrier (:mod:`hertzchain.integrate.core.barrier`). So positions, velocities and forces are bit
for bit those of one thread.

The step control (``rkn_kernels.next_step``) is a maximum over contacts of three bounds: each
thread takes its block's, the chain's is the largest over blocks (exact, whatever the order), and
every thread computes the same step from it; two barriers (the first also keeps a block's
neighbour from moving its first body before the block has read it). One step: two barriers for
the step (one for a fixed step), five for the stages that evaluate forces, one after the closing
kick (the end data read the neighbour's first body). The samples are interpolated per block as in ``rkn_run`` (each contact's
force from its own end data; the crossing contacts listed per block); the energies are block sums
added in block order, which rounds differently from one sum over the chain (relative ~1e-15
sqrt(N)), and ``end_data``'s own sums are reassociated (fastmath) in either case.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from ..core.barrier import barrier
from ..core.kernels import DELTA_MIN
from . import rkn_kernels as rk
from .rkn_kernels import (A_H, A_HMAX, A_HMIN, A_STEPS, A_T, A_TPREV, E_DKE, E_DPE, E_KE, E_PE, LAND_ERROR, LAND_FLOOR,
                          MAX_GROWTH, MAX_OMEGA_H, R_D, R_DDF, R_DF, R_F, R_Q, R_R)
from .thread_blocks import COMPILED_IN
from ..core.disk_cache import INTEGRATE, files_digest, on_disk

__all__ = ["RknTeam", "rkn_thread_run"]


class RknTeam(NamedTuple):
    """The ``nthr`` threads of one compiled call: thread t owns slots [bounds[t], bounds[t + 1])
    and the recorded contacts rec[rbounds[t]:rbounds[t + 1]]; ``bar`` their barrier; ``pub``
    (2, nthr, 2) the blocks' first and last positions [m] by parity; ``part`` (nthr, 3) the blocks'
    step bounds (max h_j^-10, the stability term, the landing 1/tau); ``energy`` (nthr, 2, 4) the
    blocks' energies and rates at the last two step ends (``rkn_kernels.E_*``)."""

    nthr: int
    bounds: np.ndarray
    rbounds: np.ndarray
    bar: np.ndarray
    pub: np.ndarray
    part: np.ndarray
    energy: np.ndarray


@njit(cache=True, nogil=True, error_model="numpy")
def _block_bounds(u, v, kappa, d0, inv_mass, eps, h_prev, sx, sw, st, sc):
    """``rkn_kernels.next_step``'s per-contact bounds, the same expressions, over the contacts of
    ``kappa`` (views from the block's first: module docstring): (max h_j^-10, max of the
    stability term)."""
    rk.contact_bounds(u, v, kappa, d0, inv_mass, eps, h_prev, sx, sw, st, sc)
    return rk._max4(sx), rk._max4(sw)


@njit(cache=True, nogil=True, error_model="numpy")
def _block_landing(h, st, sc):
    """``rkn_kernels.next_step``'s landing bound over the block's contacts (views) for the step h."""
    h5 = h * h * h * h * h
    inv_h = 1.0 / h
    for j in range(st.shape[0]):
        y = st[j]
        st[j] = y if (y > inv_h and y * LAND_FLOOR < inv_h and sc[j] * h5 > LAND_ERROR) else 0.0
    return rk._max4(st)


@njit(cache=True, nogil=True)
def _agree_step(team, tid, sense, u, v, kappa, d0, inv_mass, eps, hl, h_max, s, e, scratch):
    """``rkn_kernels.next_step`` across the threads (module docstring): (h, sense)."""
    sx, sw, st, sc = scratch.sx, scratch.sw, scratch.st, scratch.sc
    part = team.part
    xb, wb = _block_bounds(u[s:], v[s:], kappa[s:e], d0[s:e], inv_mass[s:], eps, hl, sx[s:e], sw[s:e], st[s:e],
                           sc[s:e])
    part[tid, 0] = xb
    part[tid, 1] = wb
    sense = barrier(team.bar, team.nthr, sense)
    x = 0.0
    w = 0.0
    for t in range(team.nthr):
        x = part[t, 0] if part[t, 0] > x else x
        w = part[t, 1] if part[t, 1] > w else w
    h = h_max
    if hl > 0.0 and MAX_GROWTH * hl < h:
        h = MAX_GROWTH * hl
    if w > 0.0:
        hw = MAX_OMEGA_H / np.sqrt(6.0 * np.sqrt(w))
        h = hw if hw < h else h
    if x > 0.0:
        hx = x ** -0.1
        h = hx if hx < h else h
    part[tid, 2] = _block_landing(h, st[s:e], sc[s:e])
    sense = barrier(team.bar, team.nthr, sense)
    y = 0.0
    for t in range(team.nthr):
        y = part[t, 2] if part[t, 2] > y else y
    if y > 0.0:
        h = 1.0 / y
    return h, sense


@njit(cache=True, nogil=True, inline="always")
def _hertz(kappa, d):
    d = d if d > DELTA_MIN else 0.0
    return kappa * d * np.sqrt(d)


@njit(cache=True, nogil=True)
def _publish(team, tid, par, u, s, e, sense):
    """The block's first and last positions into ``pub[par]``, then the barrier (every block's are
    published before any is read); returns the sense."""
    pub = team.pub
    pub[par, tid, 0] = u[s]
    pub[par, tid, 1] = u[e - 1]
    return barrier(team.bar, team.nthr, sense)


@njit(cache=True, nogil=True, inline="always")
def _edges(team, tid, par, u, kappa, d0, s, e):
    """The force of contact s - 1 (0 for the first block) and the position of body e (the right
    neighbour's, published; this block's own padding slot for the last block)."""
    fprev = _hertz(kappa[s - 1], team.pub[par, tid - 1, 1] - u[s] + d0[s - 1]) if tid > 0 else 0.0
    ur = team.pub[par, tid + 1, 0] if tid < team.nthr - 1 else u[e]
    return fprev, ur


@njit(cache=True, nogil=True)
def _stage(team, tid, par, u, v, kappa, d0, fext, inv_mass, kick, drift, s, e):
    """``rkn_kernels._stage`` over bodies [s, e)."""
    fprev, ur = _edges(team, tid, par, u, kappa, d0, s, e)
    fprev = _stage_from(u[s:e], v[s:e], kappa[s:e], d0[s:e], fext[s:e], inv_mass[s:e], kick, drift, fprev)
    i = e - 1
    f = _hertz(kappa[i], u[i] - ur + d0[i])
    v[i] += kick * ((fprev - f + fext[i]) * inv_mass[i])
    u[i] += drift * v[i]


@njit(cache=True, nogil=True, inline="always")
def _stage_from(u, v, kappa, d0, fext, inv_mass, kick, drift, fprev):
    """``rkn_kernels._stage``'s loop over the bodies of the views but the last (indexed from 0:
    a loop from a block's first slot would check every index for wraparound and not vectorise);
    returns the force of the contact on the last one's left."""
    for i in range(inv_mass.shape[0] - 1):
        d = u[i] - u[i + 1] + d0[i]
        d = d if d > DELTA_MIN else 0.0
        f = kappa[i] * d * np.sqrt(d)
        v[i] += kick * ((fprev - f + fext[i]) * inv_mass[i])
        u[i] += drift * v[i]
        fprev = f
    return fprev


@njit(cache=True, nogil=True)
def _closing(team, tid, par, u, v, a, g, sq, kappa, d0, fext, inv_mass, kick, s, e):
    """``rkn_kernels._closing`` over bodies [s, e)."""
    fprev, ur = _edges(team, tid, par, u, kappa, d0, s, e)
    fprev = _closing_from(u[s:e], v[s:e], a[s:e], g[s + 1:e + 1], sq[s:e], kappa[s:e], d0[s:e], fext[s:e],
                          inv_mass[s:e], kick, fprev)
    i = e - 1
    d = u[i] - ur + d0[i]
    d = d if d > DELTA_MIN else 0.0
    sqd = np.sqrt(d)
    f = kappa[i] * d * sqd
    g[i + 1] = f
    sq[i] = sqd
    ai = (fprev - f + fext[i]) * inv_mass[i]
    a[i] = ai
    v[i] += kick * ai


@njit(cache=True, nogil=True, inline="always")
def _closing_from(u, v, a, g, sq, kappa, d0, fext, inv_mass, kick, fprev):
    """``rkn_kernels._closing``'s loop over the bodies of the views but the last (``g`` from
    contact s, not shifted); returns the force of the contact on the last one's left."""
    for i in range(inv_mass.shape[0] - 1):
        d = u[i] - u[i + 1] + d0[i]
        d = d if d > DELTA_MIN else 0.0
        sqd = np.sqrt(d)
        f = kappa[i] * d * sqd
        g[i] = f
        sq[i] = sqd
        ai = (fprev - f + fext[i]) * inv_mass[i]
        a[i] = ai
        v[i] += kick * ai
        fprev = f
    return fprev


@njit(cache=True, nogil=True, fastmath={"reassoc"}, error_model="numpy")
def _end_data(u, v, a, g, sq, kappa, d0, fext, mass, ed, energy, c):
    """``rkn_kernels.end_data`` over the views' contacts (``ed`` the (ROWS, n) rows of the block,
    ``g`` from contact s, not shifted), the block's energies into ``energy[c]``."""
    ke = 0.0
    dke = 0.0
    pe = 0.0
    dpe = 0.0
    for i in range(mass.shape[0]):
        d = u[i] - u[i + 1] + d0[i]
        r = v[i] - v[i + 1]
        q = a[i] - a[i + 1]
        f = g[i]
        si = sq[i]
        k = 1.5 * kappa[i]
        ed[R_F, i] = f
        ed[R_DF, i] = k * si * r
        x = k * (0.5 * r * r / si + si * q)
        ed[R_DDF, i] = x if si > 0.0 else 0.0
        ed[R_D, i] = d
        ed[R_R, i] = r
        ed[R_Q, i] = q
        mv = mass[i] * v[i]
        ke += mv * v[i]
        dke += mv * a[i]
        pe += 0.4 * f * d - fext[i] * u[i]
        dpe += f * r - fext[i] * v[i]
    energy[c, E_KE] = 0.5 * ke
    energy[c, E_DKE] = dke
    energy[c, E_PE] = pe
    energy[c, E_DPE] = dpe


@njit(cache=True, nogil=True)
def _sample_setup(edb, edc, h, coef, cross):
    """``rkn_run``'s set-up of a step's samples over the block (views from its first contact:
    indices from 0): the crossing contacts into ``cross``, then the force quintics'
    coefficients (``rkn_kernels._quintic_coefficients``) of the loaded ones. Returns (lo, hi,
    ncross): the contacts loaded at either end lie in [lo, hi) (the others' force is 0)."""
    ncross = 0
    lo, hi = cross.shape[0], 0
    for j in range(cross.shape[0]):
        da, db = edb[R_D, j], edc[R_D, j]
        ca, cb = da > DELTA_MIN, db > DELTA_MIN
        if ca or cb:
            lo = j if j < lo else lo
            hi = j + 1
        if ca != cb or (ca and da < abs(edb[R_R, j]) * h) or (cb and db < abs(edc[R_R, j]) * h):
            cross[ncross] = j
            ncross += 1
    hh = h * h
    for j in range(lo, hi):
        rk.quintic_row(coef, j, edb[R_F, j], h * edb[R_DF, j], 0.5 * hh * edb[R_DDF, j], edc[R_F, j],
                       h * edc[R_DF, j], 0.5 * hh * edc[R_DDF, j])
    return lo, hi, ncross


@njit(cache=True, nogil=True)
def _open(u, v, a, c, d):
    """The opening kick v += c a and drift u += d v of ``rkn_kernels.step`` over the views."""
    for i in range(u.shape[0]):
        v[i] += c * a[i]
        u[i] += d * v[i]


@njit(cache=True, nogil=True)
def _step(team, tid, sense, u, v, a, g, sq, kappa, d0, fext, inv_mass, h, s, e):
    """One SRKN_6^b step of size h over the block (``rkn_kernels.step``); returns the sense."""
    _open(u[s:e], v[s:e], a[s:e], rk.B1 * h, rk.A1 * h)
    par = 0
    for m in range(rk.INNER_KICKS.shape[0]):
        sense = _publish(team, tid, par, u, s, e, sense)
        _stage(team, tid, par, u, v, kappa, d0, fext, inv_mass, rk.INNER_KICKS[m] * h, rk.INNER_DRIFTS[m] * h, s, e)
        par = 1 - par
    sense = _publish(team, tid, par, u, s, e, sense)
    _closing(team, tid, par, u, v, a, g, sq, kappa, d0, fext, inv_mass, rk.B1 * h, s, e)
    return barrier(team.bar, team.nthr, sense)


def rkn_thread_run(tid, team, state, scratch, chain, probes, control, k_start, k_stop, acc):
    """Thread ``tid``'s share of ``rkn_kernels.rkn_run`` (the same arguments, ``team`` an
    :class:`RknTeam`): samples ``k_start`` to ``k_stop - 1`` of its block. Thread 0 keeps ``acc``
    and writes the energies; the others keep a copy (the same numbers). The block's crossing
    contacts are listed in ``cross[s:]``. Returns 0, or 1 when the state became non-finite (on
    every thread: the test reads the summed energy and the first contact's force)."""
    u, v, a, g, sq, ed, _ = state  # the energies' end data: per block in team.energy
    up, vp, ap, fis, _, cross, coef, _, _, _, _ = scratch
    fi = fis[:, 0]  # the sampled forces (rkn_run's first sample column: one sample at a time here)
    mass, inv_mass, kappa, _, d0, fext, ws = chain
    rec, out_f, out_ke, out_pe, _, out_v, record_v, out_u, record_u, fmax, peak = probes
    interval, h_fixed, eps, h_max = control
    nthr = team.nthr
    s = team.bounds[tid]
    e = team.bounds[tid + 1]
    owns_wall = s <= ws < e
    my = acc if tid == 0 else acc.copy()
    energy = team.energy[tid]
    nc = fmax.shape[0]
    ce = min(e, nc)  # the block's real contacts [s, ce)
    sense = 0
    t = my[A_T]
    tp = my[A_TPREV]
    hl = my[A_H]
    steps = int(my[A_STEPS])
    ncross = -1
    lo, hi = s, s
    for k in range(k_start, k_stop):
        tk = k * interval
        while t < tk:
            if record_v or record_u:
                for i in range(s, e):
                    up[i] = u[i]
                    vp[i] = v[i]
                    ap[i] = a[i]
            if h_fixed > 0.0:
                h = h_fixed
                # every block has read its right neighbour's first body (end data) before it moves
                sense = barrier(team.bar, nthr, sense)
            else:  # (its first barrier does the same)
                h, sense = _agree_step(team, tid, sense, u, v, kappa, d0, inv_mass, eps, hl, h_max, s, e, scratch)
            sense = _step(team, tid, sense, u, v, a, g, sq, kappa, d0, fext, inv_mass, h, s, e)
            steps += 1
            c = steps % 2
            _end_data(u[s:], v[s:], a[s:], g[s + 1:], sq[s:e], kappa[s:e], d0[s:e], fext[s:e], mass[s:e], ed[c, :, s:e],
                      energy, c)
            b = 1 - c
            if owns_wall:
                dk, x = rk.quintic_peak(ed[b, R_D, ws], ed[b, R_R, ws], ed[b, R_Q, ws], ed[c, R_D, ws],
                                        ed[c, R_R, ws], ed[c, R_Q, ws], h)
                fk = kappa[ws] * dk * np.sqrt(dk) if dk > DELTA_MIN else 0.0
                if fk > peak[0]:
                    peak[0] = fk
                    peak[1] = t + x
            tp = t
            t += h
            hl = h
            ncross = -1
            my[A_HMIN] = h if h < my[A_HMIN] else my[A_HMIN]
            my[A_HMAX] = h if h > my[A_HMAX] else my[A_HMAX]
        # --- probes at tk (rkn_run's, over the block); every block's energies are written
        sense = barrier(team.bar, nthr, sense)
        c = steps % 2
        b = 1 - c
        if ncross < 0:
            lo, hi, ncross = _sample_setup(ed[b, :, s:ce], ed[c, :, s:ce], hl, coef[:, s:ce], cross[s:ce])
            lo += s
            hi += s
        theta = (tk - tp) / hl
        for j in range(lo, hi):
            f = coef[0, j] + theta * (coef[1, j] + theta * (coef[2, j] + theta * (
                coef[3, j] + theta * (coef[4, j] + theta * coef[5, j]))))
            fi[j] = f if f > 0.0 else 0.0
        if ncross > 0:
            q0, q0d, q0dd, q1, q1d, q1dd = rk.quintic(theta, hl)
            for m in range(ncross):
                j = s + cross[s + m]
                d = (q0 * ed[b, R_D, j] + q0d * ed[b, R_R, j] + q0dd * ed[b, R_Q, j] + q1 * ed[c, R_D, j]
                     + q1d * ed[c, R_R, j] + q1dd * ed[c, R_Q, j])
                fi[j] = kappa[j] * d * np.sqrt(d) if d > DELTA_MIN else 0.0
        for j in range(lo, hi):
            f = fi[j]
            fmax[j] = f if f > fmax[j] else fmax[j]
        for r in range(team.rbounds[tid], team.rbounds[tid + 1]):
            j = rec[r]
            out_f[k, r] = fi[j] if lo <= j < hi else 0.0
        w0, w0d, w1, w1d = rk.hermite(theta, hl)
        eb = team.energy
        ke = 0.0
        pe = 0.0
        for q in range(nthr):  # block order: the same sums on every thread
            ke += w0 * eb[q, b, E_KE] + w0d * eb[q, b, E_DKE] + w1 * eb[q, c, E_KE] + w1d * eb[q, c, E_DKE]
            pe += w0 * eb[q, b, E_PE] + w0d * eb[q, b, E_DPE] + w1 * eb[q, c, E_PE] + w1d * eb[q, c, E_DPE]
        if tid == 0:
            out_ke[k] = ke
            out_pe[k] = pe
        if record_v:
            for i in range(s, min(e, out_v.shape[1])):
                out_v[k, i] = w0 * vp[i] + w0d * ap[i] + w1 * v[i] + w1d * a[i]
        if record_u:
            q0, q0d, q0dd, q1, q1d, q1dd = rk.quintic(theta, hl)
            for i in range(s, min(e, out_u.shape[1])):
                out_u[k, i] = q0 * up[i] + q0d * vp[i] + q0dd * ap[i] + q1 * u[i] + q1d * v[i] + q1dd * a[i]
        if not np.isfinite(ke) or not np.isfinite(g[1]):
            my[A_T], my[A_TPREV], my[A_H], my[A_STEPS] = t, tp, hl, steps
            return 1
    my[A_T], my[A_TPREV], my[A_H], my[A_STEPS] = t, tp, hl, steps
    return 0


# compiled once per installation: its cache key holds this module's text, rkn_kernels.py's and
# the thread modules' (an edit of any compiles it afresh)
rkn_thread_run = on_disk(njit(nogil=True)(rkn_thread_run), "rkn4-elastic", sources=files_digest(
    *(INTEGRATE / name for name in ("drivers/rkn_threaded_kernels.py", "drivers/rkn_kernels.py", *COMPILED_IN))))
