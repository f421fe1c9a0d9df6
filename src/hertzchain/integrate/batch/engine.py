"""The batched engine on the CPU: every member of a packed batch advanced by one compiled loop.

One ``@njit(parallel=True)`` loop (Numba ``prange``) hands every member to the very same
:func:`hertzchain.integrate.core.kernels.verlet_run` on slices of the flat buffers of a
:class:`~hertzchain.integrate.batch.buffers._Packed` (slices are views, so the kernel writes
straight into the outputs). Velocity Verlet has no cross-member coupling and no reductions across
members, so the thread that runs a member cannot change its result: every member's numbers are
those of :func:`hertzchain.simulate` of it alone. :func:`_engine` runs the loop in chunks of
samples (progress reports between them), one launch at a time.
"""

from __future__ import annotations

import threading

import numba
import numpy as np
from numba import njit, prange

from ...errors import ConfigError
from ...interrupts import check as check_interrupt
from ..core import kernels
from .buffers import _Packed, check_members_finite
from .rkn import rkn_engine, rkn_members
from ..core.generated import is_generated, law_kernels


#: Work (padded slot-steps summed over members) per compiled call between two progress reports:
#: about 0.3 s on one core at the ~6.7e8 slot-steps/s of the kernel, times the thread count.
CHUNK_SLOT_STEPS = 2e8


@njit(parallel=True, cache=True)
def _batch_kernel(order, off, n_slots, u, v, a, g, mass, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, dcap,
                  dyield, dmax, dres, kres, law, general, wall_slot, interval, stride, n_sub, n_eval, c_steps, relax,
                  k_start, k_stop, rec, rec_off, out_f, f_off, out_ke, out_pe, out_ed, out_wp, out_v, v_off, v_rows,
                  nbody, record_v, fmax, fmax_off, peak, acc, ext, ext_off, ext_on, body_slot, out_b, b_off, status):
    """Advance every member from sample ``k_start`` to ``k_stop`` with :func:`kernels.verlet_run`.

    Member m owns the slots from ``off[m]`` of the body/contact buffers (``P + 1`` slots,
    ``P = n_slots[m]``, rounded up to whole cache lines; see ``batch_buffers._outputs``): the
    ``P``-sized arrays (mass, kappa, ...) use the first ``P``, ``u, v, g`` the first ``P + 1`` (layout of
    :mod:`hertzchain.integrate.core.kernels`). Its recorded contacts are ``rec[rec_off[m]:rec_off[m+1]]``;
    its force samples the flat block ``out_f[f_off[m]:f_off[m+1]]`` seen as (K, n_rec); its
    running maximum forces ``fmax[fmax_off[m]:fmax_off[m+1]]``; its velocities
    ``out_v[v_off[m]:v_off[m+1]]`` seen as (v_rows[m], nbody[m] = N + 1). Members are visited in
    the order ``order`` (most expensive first, so that dynamic scheduling does not leave one long
    member for the end). ``status[m]`` is the kernel's return value; a member that diverged is
    not advanced again. The elastic-plastic buffers (``dyield`` ... ``kres``, ``out_wp``) are
    empty in a batch without such a member: their slices are then empty and never read. An
    extended member's extension array is ``ext[ext_off[m]:ext_off[m + 1]]`` and a member with a
    protected body records it in ``out_b[b_off[m]:b_off[m + 1]]`` seen as (K, 4).
    """
    nk = out_ke.shape[1]
    for i in prange(order.shape[0]):
        m = order[i]
        if status[m] != 0:
            continue
        s = off[m]
        p = n_slots[m]
        r0 = rec_off[m]
        r1 = rec_off[m + 1]
        f = out_f[f_off[m]:f_off[m + 1]].reshape((nk, r1 - r0))
        vv = out_v[v_off[m]:v_off[m + 1]].reshape((v_rows[m], nbody[m]))
        bb = out_b[b_off[m]:b_off[m + 1]].reshape(((b_off[m + 1] - b_off[m]) // 4, 4))
        status[m] = kernels.verlet_run(u[s:s + p + 1], v[s:s + p + 1], a[s:s + p], g[s:s + p + 1], mass[s:s + p],
                                       inv_mass[s:s + p], kappa[s:s + p], damping[s:s + p], d0[s:s + p],
                                       de[s:s + p], dx0[s:s + p], rsum[s:s + p], fext[s:s + p], dcap[s:s + p],
                                       dyield[s:s + p], dmax[s:s + p], dres[s:s + p], kres[s:s + p],
                                       law[m], general[m], wall_slot[m], interval, stride[m], n_sub[m], n_eval[m],
                                       c_steps[m], relax[m], k_start, k_stop, rec[r0:r1], f, out_ke[m], out_pe[m],
                                       out_ed[m], out_wp[m], vv, record_v[m], fmax[fmax_off[m]:fmax_off[m + 1]],
                                       peak[m], acc[m], ext[ext_off[m]:ext_off[m + 1]], ext_on[m], body_slot[m], bb)


_GENERATED: dict = {}


def _generated_batch_kernel(code: int):
    """:func:`_batch_kernel` with the stepping loop generated from law ``code`` (:mod:`.generated`)
    in place of ``kernels.verlet_run``; compiled once per law and process."""
    if code not in _GENERATED:
        run = law_kernels(code)[1]

        @njit(parallel=True)
        def kernel(order, off, n_slots, u, v, a, g, mass, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, dcap,
                   dyield, dmax, dres, kres, law, general, wall_slot, interval, stride, n_sub, n_eval, c_steps, relax,
                   k_start, k_stop, rec, rec_off, out_f, f_off, out_ke, out_pe, out_ed, out_wp, out_v, v_off, v_rows,
                   nbody, record_v, fmax, fmax_off, peak, acc, ext, ext_off, ext_on, body_slot, out_b, b_off, status):
            nk = out_ke.shape[1]
            for i in prange(order.shape[0]):
                m = order[i]
                if status[m] != 0:
                    continue
                s = off[m]
                p = n_slots[m]
                r0 = rec_off[m]
                r1 = rec_off[m + 1]
                f = out_f[f_off[m]:f_off[m + 1]].reshape((nk, r1 - r0))
                vv = out_v[v_off[m]:v_off[m + 1]].reshape((v_rows[m], nbody[m]))
                bb = out_b[b_off[m]:b_off[m + 1]].reshape(((b_off[m + 1] - b_off[m]) // 4, 4))
                status[m] = run(u[s:s + p + 1], v[s:s + p + 1], a[s:s + p], g[s:s + p + 1], mass[s:s + p],
                                               inv_mass[s:s + p], kappa[s:s + p], damping[s:s + p], d0[s:s + p],
                                               de[s:s + p], dx0[s:s + p], rsum[s:s + p], fext[s:s + p], dcap[s:s + p],
                                               dyield[s:s + p], dmax[s:s + p], dres[s:s + p], kres[s:s + p],
                                               law[m], general[m], wall_slot[m], interval, stride[m], n_sub[m], n_eval[m],
                                               c_steps[m], relax[m], k_start, k_stop, rec[r0:r1], f, out_ke[m], out_pe[m],
                                               out_ed[m], out_wp[m], vv, record_v[m], fmax[fmax_off[m]:fmax_off[m + 1]],
                                               peak[m], acc[m], ext[ext_off[m]:ext_off[m + 1]], ext_on[m], body_slot[m], bb)

        _GENERATED[code] = kernel
    return _GENERATED[code]


# The workqueue threading layer (the one available without TBB/OpenMP) aborts the process when two
# threads launch parallel kernels at once, e.g. two Dask worker threads in one process; one launch
# already uses every core, so serialising launches costs nothing.
_LAUNCH_LOCK = threading.Lock()


kernels.flush_stale_cache(_batch_kernel)


def _engine(pk: _Packed, progress, n_threads, integrator: str = "verlet", all_forces: bool = True,
            rtol: float | None = None) -> None:
    """Run the packed batch to the end on the CPU (all cores), in compiled calls of ~CHUNK_SLOT_STEPS.

    ``integrator``: ``"verlet"``, or ``"rkn4"`` / ``"auto"``: the fourth-order engine of
    :mod:`.rkn` when it runs every member (:func:`~.rkn.rkn_members`; ``"rkn4"`` refuses
    a batch it does not, ``"auto"`` then runs the Verlet), each member in one compiled call (no
    progress within a member). ``all_forces`` False: the largest contact forces over the run
    rather than over the samples, with ``"rkn4"`` (``batch.rkn``'s docstring); ``rtol`` its step
    tolerance (None: the default).
    """
    if integrator != "verlet":
        if rkn_members(pk):
            with _LAUNCH_LOCK:
                previous = numba.get_num_threads()
                try:
                    if n_threads is not None:
                        numba.set_num_threads(int(n_threads))
                    pk.rkn_steps = rkn_engine(pk, all_forces, rtol)
                finally:
                    numba.set_num_threads(previous)
            pk.integrator = "rkn4"
            check_interrupt()
            if progress is not None:
                progress(pk.n_samples - 1, pk.n_samples - 1)
            return
        if integrator == "rkn4":
            raise ConfigError("integrator", "'rkn4' runs a batch whose members all have offsets or the Kuwabara-Kono "
                              "or dashpot law, an automatic step (no dt), no recorded velocities and no protected "
                              "body or mass-in-mass beads; use 'verlet' or 'auto'")
    interval, n_samples = pk.interval, pk.n_samples
    steps_per_sample = interval / pk.plan_dt
    status = np.zeros(pk.n_members, dtype=np.int64)
    # Cost of one sample per member (the general force loop is roughly twice the elastic one):
    # the most expensive members go first so that the threads finish together.
    cost = steps_per_sample * (pk.n_slots + 1) * np.where(pk.general, 2, 1) * np.where(pk.ext_on, 2, 1)
    order = np.argsort(-cost, kind="stable").astype(np.int64)
    # one launch per engine: the hand-written loop for the built-in laws, each generated law's own
    generated = np.array([is_generated(c) for c in pk.law[order]], dtype=bool)
    groups = [(_batch_kernel, order[~generated])] if not generated.all() else []
    groups += [(_generated_batch_kernel(int(c)), order[pk.law[order] == c]) for c in np.unique(pk.law[order[generated]])]
    samples_per_call = max(1, int(CHUNK_SLOT_STEPS * max(1, n_threads or numba.get_num_threads()) // cost.sum()))
    flat = pk.flat
    k = 1
    while k < n_samples:
        k_stop = min(n_samples, k + samples_per_call)
        with _LAUNCH_LOCK:
            previous = numba.get_num_threads()
            try:
                if n_threads is not None:
                    numba.set_num_threads(int(n_threads))
                # Chunk size 1: members are handed out one at a time (dynamic scheduling), since
                # their costs differ; the default static split would wait for the slowest block.
                with numba.parallel_chunksize(1):
                    for kernel, members in groups:
                        kernel(members, pk.off, pk.n_slots, flat["u"], flat["v"], flat["a"], flat["g"], flat["mass"],
                               flat["inv_mass"], flat["kappa"], flat["damping"], flat["d0"], flat["de"],
                               flat["dx0"], flat["rsum"], flat["fext"], flat["dcap"], flat["dyield"],
                               flat["dmax"], flat["dres"], flat["kres"], pk.law, pk.general,
                               pk.wall_slot, interval, pk.stride, pk.n_sub, pk.n_eval, pk.c_steps, pk.relax, k,
                               k_stop, pk.rec, pk.rec_off, pk.out_f, pk.f_off, pk.out_ke, pk.out_pe, pk.out_ed,
                               pk.out_wp, pk.out_v, pk.v_off, pk.v_rows, pk.nb, pk.record_v, pk.fmax, pk.fmax_off, pk.peak,
                               pk.acc, pk.ext, pk.ext_off, pk.ext_on, pk.body_slot, pk.out_b, pk.b_off, status)
            finally:
                numba.set_num_threads(previous)
        check_members_finite(status, k_stop * interval)
        check_interrupt()  # a Ctrl-C swallowed by a cleanup while the kernel ran (hertzchain.interrupts)
        k = k_stop
        if progress is not None:
            progress(k - 1, n_samples - 1)
