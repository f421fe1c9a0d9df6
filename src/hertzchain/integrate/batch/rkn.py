"""The batched engine on the fourth-order path: ``"rkn4"`` for y'' = f(y, y') member by member in one
compiled loop.

:func:`rkn_engine` runs every member of a packed batch (:class:`~.buffers._Packed`) with
:func:`hertzchain.integrate.drivers.rkn_damped_kernels.damped_run`, the kernel of ``simulate(model,
integrator="rkn4")`` on a chain with offsets or the Kuwabara-Kono or dashpot law (what
``integrator="auto"`` picks for such a chain alone), inside one compiled loop over the members
per thread (:mod:`.dealt`): no Python per member. Its
step control (``rtol`` :data:`~hertzchain.integrate.drivers.rkn.RKN_RTOL`, peak wall force within
~4e-7 of DOP853 on chain 1) needs ~1.3e3 steps where the Verlet of the batch takes ~7e4 on a
misaligned chain 1 (3 ms at 100 ns samples).

The recorded forces and the energies at the samples are those of the single run, number for number;
the largest contact forces (``max_contact_force``) are the largest over the run instead of over the
samples when ``all_forces`` is False (``damped_run``'s docstring): what a sweep that keeps only its
metrics asks for, since interpolating every contact at every sample would cost more than the steps.
"""

from __future__ import annotations


import numpy as np
from numba import njit

from ..core import kernels
from ..core.kernels import LAW_DASHPOT, LAW_ELASTIC, LAW_VISCOELASTIC
from ..drivers import rkn_damped_kernels as rk
from ..drivers import rkn_kernels, rkn_samples
from ..drivers.rkn import DAMPED_EPS, RKN_RTOL
from ..drivers.rkn_kernels import SAMPLE_BLOCK, ChainArrays, ProbeBuffers, StepControl
from .buffers import _Packed, check_members_finite
from .dealt import run_dealt

__all__ = ["rkn_members", "rkn_engine"]


def rkn_members(pk: _Packed) -> bool:
    """True when ``"auto"`` would run every member of the batch alone with ``damped_run``: an
    adaptive step (no ``dt``), no velocities recorded, no protected body or mass-in-mass beads, and the
    Kuwabara-Kono or dashpot law, or the elastic law with beads offset from the axis (an aligned
    elastic chain runs the symplectic ``rkn_kernels`` alone, which the batch does not have)."""
    s = pk.off
    misaligned = np.array([np.any(pk.flat["de"][s[m]:s[m] + pk.n_slots[m]] != 0.0) for m in range(pk.n_members)],
                          dtype=bool) if pk.n_members else np.zeros(0, dtype=bool)
    viscous = np.isin(pk.law, (LAW_VISCOELASTIC, LAW_DASHPOT))
    ok = (pk.stride == 0) & ~pk.record_v & ~pk.ext_on & (pk.body_slot < 0)
    ok &= viscous | ((pk.law == LAW_ELASTIC) & misaligned)
    return bool(pk.n_members) and bool(ok.all())


@njit(cache=True, nogil=True)
def _rkn_kernel(order, off, n_slots, u0, v0, mass, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, law, wall_slot,
                interval, n_samples, eps, h_max, rec, rec_off, out_f, f_off, out_ke, out_pe, out_ed, fmax, fmax_off,
                peak, acc_out, all_forces, status):
    """Every member of ``order`` from rest to the last sample (``rkn_damped.run_rkn_damped``'s set-up
    and ``damped_run``), on the slices of the flat buffers (layout of ``batch_engine._batch_kernel``).

    ``acc_out[m]`` receives [steps, smallest step, largest step] and ``peak[m]`` [largest wall force,
    its time]; ``status[m]`` is ``damped_run``'s return value."""
    for i in range(order.shape[0]):
        m = order[i]
        s = off[m]
        p = n_slots[m]
        r0 = rec_off[m]
        r1 = rec_off[m + 1]
        c0 = fmax_off[m]
        nc = fmax_off[m + 1] - c0
        u = u0[s:s + p + 1].copy()
        v = v0[s:s + p + 1].copy()
        a = np.zeros(p + 1)
        an = np.zeros(p + 1)
        un = np.zeros(p + 1)
        vn = np.zeros(p + 1)
        us = np.zeros(p + 1)
        vs = np.zeros(p + 1)
        k2 = np.zeros(p)
        k3 = np.zeros(p)
        k4 = np.zeros(p)
        up = np.zeros(p)
        vp = np.zeros(p)
        ap = np.zeros(p)
        pw = np.zeros(p)
        mode = np.zeros(p)
        last = np.zeros(p)
        fi = np.zeros((nc, SAMPLE_BLOCK))
        ed = np.zeros((2, rk.ROWS, p))
        ends = np.zeros((2, rk.ENDS))
        # an aligned member's offsets have no columns: its contact loops skip the offset geometry
        # (rk.G_DE's comment) instead of taking it by selects
        off3 = np.empty((3, p if np.any(de[s:s + p] != 0.0) else 0))
        if off3.shape[1] > 0:
            off3[rk.G_DE] = de[s:s + p]
            off3[rk.G_DX0] = dx0[s:s + p]
            off3[rk.G_RSUM] = rsum[s:s + p]
        ms, ims, ka, da, dz, fx = mass[s:s + p], inv_mass[s:s + p], kappa[s:s + p], damping[s:s + p], d0[s:s + p], \
            fext[s:s + p]
        lw = law[m]
        rk.accelerations(u, v, ka, da, dz, off3, fx, ims, lw, a)
        rk.end_data(u, v, a, ka, da, dz, off3, fx, ms, lw, last, 0.0, ed, ends, 0)
        rk.set_modes(ed, 0, last)
        rk.end_data(u, v, a, ka, da, dz, off3, fx, ms, lw, last, 0.0, ed, ends, 0)
        f = out_f[f_off[m]:f_off[m + 1]].reshape((n_samples, r1 - r0))
        recm = rec[r0:r1]
        for r in range(r1 - r0):
            f[0, r] = ed[0, rk.R_F, recm[r]]
        out_ke[m, 0] = ends[0, rk.E_KE]
        out_pe[m, 0] = ends[0, rk.E_PE]
        out_ed[m, 0] = 0.0
        fm = fmax[c0:c0 + nc]
        for j in range(nc):
            fm[j] = ed[0, rk.R_F, j]
        pk = np.array([ed[0, rk.R_F, wall_slot[m]] if wall_slot[m] < nc else 0.0, 0.0])
        acc = np.array([0.0, 0.0, 0.0, 0.0, np.inf, 0.0, 0.0])
        no_v = np.empty((1, p + 1))
        state = rk.DampedState(u, v, a, un, vn, an, us, vs, k2, k3, k4, pw, mode, last, up, vp, ap, fi, ed, ends)
        probes = ProbeBuffers(recm, f, out_ke[m], out_pe[m], out_ed[m], no_v, False, no_v, False, fm, pk)
        status[m] = rk.damped_run(state, ChainArrays(ms, ims, ka, da, dz, fx, wall_slot[m]), off3, lw, probes,
                                  StepControl(interval, 0.0, eps[m], h_max), 1, n_samples, acc, all_forces)
        peak[m, 0] = pk[0]
        peak[m, 1] = pk[1]
        acc_out[m, 0] = acc[rk.A_STEPS]
        acc_out[m, 1] = acc[rk.A_HMIN]
        acc_out[m, 2] = acc[rk.A_HMAX]


def _flush_stale_cache() -> None:
    """Drop the on-disk cache of :func:`_rkn_kernel` when ``rkn_damped_kernels.py`` (whose
    ``damped_run`` it compiles in) or a file that compiles in is newer than it. Numba's cache
    checks only the file of the cached function."""
    kernels.flush_stale_cache(_rkn_kernel, also=(rk.__file__, rkn_kernels.__file__, rkn_samples.__file__))


_flush_stale_cache()


def rkn_engine(pk: _Packed, all_forces: bool = True, rtol: float | None = None,
               n_threads: int | None = None) -> np.ndarray:
    """Run every member of ``pk`` (:func:`rkn_members` holds) to the end on ``n_threads`` threads
    (:func:`.dealt.run_dealt`; None: Numba's thread count); (M, 3) array of [steps, smallest step
    [s], largest step [s]] per member.

    ``pk.peak[m, :2]`` receive the largest wall force [N] and its time [s] (``peak[m, 4] = 1``: the
    Verlet's parabola refinement does not apply); the step tolerance of member m is ``rtol``
    (None: :data:`~hertzchain.integrate.drivers.rkn.RKN_RTOL`) times
    :data:`~hertzchain.integrate.drivers.rkn.DAMPED_EPS` times its striker speed, as ``run_rkn``'s.
    """
    flat = pk.flat
    v_ref = np.array([np.max(np.abs(flat["v"][pk.off[m]:pk.off[m] + pk.n_slots[m] + 1])) for m in range(pk.n_members)])
    eps = (RKN_RTOL if rtol is None else rtol) * DAMPED_EPS * np.where(v_ref > 0, v_ref, 1.0)
    duration = (pk.n_samples - 1) * pk.interval
    # most contacts first, dealt round-robin, so that the threads finish together
    order = np.argsort(-pk.n_slots, kind="stable").astype(np.int64)
    status = np.zeros(pk.n_members, dtype=np.int64)
    acc = np.zeros((pk.n_members, 3))
    run_dealt(_rkn_kernel, order, n_threads, pk.off, pk.n_slots, flat["u"], flat["v"], flat["mass"], flat["inv_mass"],
              flat["kappa"], flat["damping"], flat["d0"], flat["de"], flat["dx0"], flat["rsum"], flat["fext"], pk.law,
              pk.wall_slot, pk.interval, pk.n_samples, eps, duration, pk.rec, pk.rec_off, pk.out_f, pk.f_off,
              pk.out_ke, pk.out_pe, pk.out_ed, pk.fmax, pk.fmax_off, pk.peak, acc, all_forces, status)
    check_members_finite(status, duration)
    pk.peak[:, 4] = 1.0
    return acc
