"""The batched engine on the CPU: every member of a packed batch advanced by one compiled loop.

One compiled loop per thread (:mod:`.dealt`: the members dealt to threads) hands every member to the very same
:func:`hertzchain.integrate.core.kernels._verlet_run` on slices of the flat buffers of a
:class:`~hertzchain.integrate.batch.buffers._Packed` (slices are views, so the kernel writes
straight into the outputs), taken by the loop as three typed structures (:class:`Members`,
:class:`FlatBuffers`, :class:`Records`) and handed to the kernel as its own. Velocity Verlet
has no cross-member coupling and no reductions across members, so the thread that runs a member
cannot change its result: every member's numbers are those of :func:`hertzchain.simulate` of it
alone. :func:`_engine` runs the loop in chunks of samples (progress reports between them).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from ...errors import ConfigError
from ...interrupts import check as check_interrupt
from ..core import kernels
from ..core.kernels import RUN_ELASTIC, RUN_EXTENDED, RUN_GENERAL, RUN_PLASTIC
from ..core.structures import ChainArrays, ContactArrays, Extension, VerletControl, VerletProbes, VerletState
from .buffers import _Packed, check_members_finite
from .dealt import default_threads, run_dealt
from .rkn import rkn_engine, rkn_members
from ..core.generated import is_generated, law_kernels


#: Work (padded slot-steps summed over members) per compiled call between two progress reports:
#: about 0.3 s on one core at the ~6.7e8 slot-steps/s of the kernel, times the thread count.
CHUNK_SLOT_STEPS = 2e8


class Members(NamedTuple):
    """Where each member lives in the flat buffers, and its parameters (one entry per member).

    Member m owns the slots from ``off[m]`` of :class:`FlatBuffers` (``P + 1`` slots,
    ``P = n_slots[m]``, rounded up to whole cache lines; see ``batch_buffers._outputs``): the
    ``P``-sized arrays (mass, kappa, ...) use the first ``P``, ``u, v, g`` the first ``P + 1``
    (layout of :mod:`hertzchain.integrate.core.kernels`). Its recorded contacts are
    ``rec[rec_off[m]:rec_off[m+1]]``; its force samples the flat block ``out_f[f_off[m]:f_off[m+1]]``
    seen as (K, n_rec); its running maximum forces ``fmax[fmax_off[m]:fmax_off[m+1]]``; its
    velocities ``out_v[v_off[m]:v_off[m+1]]`` seen as (v_rows[m], nbody[m] = N + 1) (:class:`Records`).
    An extended member's extension array is ``ext[ext_off[m]:ext_off[m + 1]]`` and a member with a
    protected body records it in ``out_b[b_off[m]:b_off[m + 1]]`` seen as (K, 4). The rest are the
    fields of :class:`~hertzchain.integrate.core.structures.VerletControl` and of the kernel's
    other arguments, per member."""

    off: np.ndarray
    n_slots: np.ndarray
    rec_off: np.ndarray
    f_off: np.ndarray
    v_off: np.ndarray
    v_rows: np.ndarray
    nbody: np.ndarray
    fmax_off: np.ndarray
    ext_off: np.ndarray
    b_off: np.ndarray
    law: np.ndarray
    general: np.ndarray
    wall_slot: np.ndarray
    stride: np.ndarray
    n_sub: np.ndarray
    n_eval: np.ndarray
    c_steps: np.ndarray
    relax: np.ndarray
    record_v: np.ndarray
    ext_on: np.ndarray
    body_slot: np.ndarray


class FlatBuffers(NamedTuple):
    """Every member's per-slot arrays one after another (``_Packed.flat``, :class:`Members`); the
    elastic-plastic buffers (``dyield`` ... ``kres``) are empty in a batch without such a member:
    their slices are then empty and never read; ``ext`` the extended members' extension arrays."""

    u: np.ndarray
    v: np.ndarray
    a: np.ndarray
    g: np.ndarray
    mass: np.ndarray
    inv_mass: np.ndarray
    kappa: np.ndarray
    damping: np.ndarray
    d0: np.ndarray
    fext: np.ndarray
    de: np.ndarray
    dx0: np.ndarray
    rsum: np.ndarray
    dcap: np.ndarray
    dyield: np.ndarray
    dmax: np.ndarray
    dres: np.ndarray
    kres: np.ndarray
    ext: np.ndarray


class Records(NamedTuple):
    """Every member's probes (flat or one row per member, :class:`Members`) and its wall-peak
    tracker and accumulators (``peak[m]``, ``acc[m]``: ``kernels._verlet_run``'s)."""

    rec: np.ndarray
    out_f: np.ndarray
    out_ke: np.ndarray
    out_pe: np.ndarray
    out_ed: np.ndarray
    out_wp: np.ndarray
    out_v: np.ndarray
    fmax: np.ndarray
    peak: np.ndarray
    acc: np.ndarray
    out_b: np.ndarray


def batch_structures(pk: _Packed) -> tuple[Members, FlatBuffers, Records]:
    """The packed batch as the member loops take it (views of its buffers)."""
    f = pk.flat
    members = Members(pk.off, pk.n_slots, pk.rec_off, pk.f_off, pk.v_off, pk.v_rows, pk.nb, pk.fmax_off,
                      pk.ext_off, pk.b_off, pk.law, pk.general, pk.wall_slot, pk.stride, pk.n_sub, pk.n_eval,
                      pk.c_steps, pk.relax, pk.record_v, pk.ext_on, pk.body_slot)
    flat = FlatBuffers(f["u"], f["v"], f["a"], f["g"], f["mass"], f["inv_mass"], f["kappa"], f["damping"], f["d0"],
                       f["fext"], f["de"], f["dx0"], f["rsum"], f["dcap"], f["dyield"], f["dmax"], f["dres"],
                       f["kres"], pk.ext)
    records = Records(pk.rec, pk.out_f, pk.out_ke, pk.out_pe, pk.out_ed, pk.out_wp, pk.out_v, pk.fmax, pk.peak,
                      pk.acc, pk.out_b)
    return members, flat, records


@njit(cache=True, nogil=True)
def _member(m, members, flat, records, interval):
    """Member m's typed structures for the stepping loop: views of the flat buffers (slices are
    views, so the loop writes straight into the outputs). A call, not inlined: inlined into the
    parallel loop, Numba's array analysis of it failed (an assertion on the slices' shapes)."""
    s = members.off[m]
    p = members.n_slots[m]
    r0 = members.rec_off[m]
    r1 = members.rec_off[m + 1]
    nk = records.out_ke.shape[1]
    f = records.out_f[members.f_off[m]:members.f_off[m + 1]].reshape((nk, r1 - r0))
    vv = records.out_v[members.v_off[m]:members.v_off[m + 1]].reshape((members.v_rows[m], members.nbody[m]))
    b0 = members.b_off[m]
    b1 = members.b_off[m + 1]
    bb = records.out_b[b0:b1].reshape(((b1 - b0) // 4, 4))
    state = VerletState(flat.u[s:s + p + 1], flat.v[s:s + p + 1], flat.a[s:s + p], flat.g[s:s + p + 1],
                        records.acc[m])
    chain = ChainArrays(flat.mass[s:s + p], flat.inv_mass[s:s + p], flat.kappa[s:s + p], flat.damping[s:s + p],
                        flat.d0[s:s + p], flat.fext[s:s + p], members.wall_slot[m])
    contacts = ContactArrays(flat.de[s:s + p], flat.dx0[s:s + p], flat.rsum[s:s + p], flat.dcap[s:s + p],
                             flat.dyield[s:s + p], flat.dmax[s:s + p], flat.dres[s:s + p], flat.kres[s:s + p])
    extension = Extension(flat.ext[members.ext_off[m]:members.ext_off[m + 1]], members.ext_on[m],
                          members.body_slot[m])
    probes = VerletProbes(records.rec[r0:r1], f, records.out_ke[m], records.out_pe[m], records.out_ed[m],
                          records.out_wp[m], vv, members.record_v[m], vv[:0], False,
                          records.fmax[members.fmax_off[m]:members.fmax_off[m + 1]], records.peak[m], bb)
    control = VerletControl(interval, members.stride[m], members.n_sub[m], members.n_eval[m], members.c_steps[m],
                            members.relax[m])
    return state, chain, contacts, extension, probes, control


@njit(cache=True, nogil=True, inline="always")
def _batch_members(kind, order, members, flat, records, interval, k_start, k_stop, status):
    """Advance the members ``order`` (a thread's share, :mod:`.dealt`) from sample ``k_start`` to
    ``k_stop`` with the compiled Verlet run of ``kind`` (``kernels.run_kind``: every member of
    ``order`` of that kind; a constant, so that a batch compiles only the runs its members need).

    Members (:class:`Members`, :class:`FlatBuffers`, :class:`Records`). ``status[m]`` is the
    kernel's return value; a member that diverged is not advanced again.
    """
    for i in range(order.shape[0]):
        m = order[i]
        if status[m] != 0:
            continue
        state, chain, contacts, extension, probes, control = _member(m, members, flat, records, interval)
        law, general = members.law[m], members.general[m]
        if kind == RUN_ELASTIC:
            status[m] = kernels.verlet_run_elastic(state, chain, contacts, extension, probes, control, law, general,
                                                   k_start, k_stop)
        elif kind == RUN_GENERAL:
            status[m] = kernels.verlet_run_general(state, chain, contacts, extension, probes, control, law, general,
                                                   k_start, k_stop)
        elif kind == RUN_PLASTIC:
            status[m] = kernels.verlet_run_plastic(state, chain, contacts, extension, probes, control, law, general,
                                                   k_start, k_stop)
        else:
            status[m] = kernels.verlet_run_extended(state, chain, contacts, extension, probes, control, law, general,
                                                    k_start, k_stop)


@njit(cache=True, nogil=True)
def _batch_elastic(order, members, flat, records, interval, k_start, k_stop, status):
    _batch_members(RUN_ELASTIC, order, members, flat, records, interval, k_start, k_stop, status)


@njit(cache=True, nogil=True)
def _batch_general(order, members, flat, records, interval, k_start, k_stop, status):
    _batch_members(RUN_GENERAL, order, members, flat, records, interval, k_start, k_stop, status)


@njit(cache=True, nogil=True)
def _batch_plastic(order, members, flat, records, interval, k_start, k_stop, status):
    _batch_members(RUN_PLASTIC, order, members, flat, records, interval, k_start, k_stop, status)


@njit(cache=True, nogil=True)
def _batch_extended(order, members, flat, records, interval, k_start, k_stop, status):
    _batch_members(RUN_EXTENDED, order, members, flat, records, interval, k_start, k_stop, status)


#: The batch kernel of each kind of Verlet run (``kernels.run_kind``).
_BATCH_KERNELS = (_batch_elastic, _batch_general, _batch_plastic, _batch_extended)


_GENERATED: dict = {}


def _generated_batch_kernel(code: int, extended: bool):
    """:func:`_batch_members` with the stepping loop generated from law ``code`` (:mod:`.generated`)
    for members without or with the extension (``extended``) in place of ``kernels._verlet_run``;
    compiled once per law, kind and process."""
    if (code, extended) not in _GENERATED:
        run = law_kernels(code)[1][int(extended)]

        @njit(nogil=True)
        def kernel(order, members, flat, records, interval, k_start, k_stop, status):
            for i in range(order.shape[0]):
                m = order[i]
                if status[m] != 0:
                    continue
                state, chain, contacts, extension, probes, control = _member(m, members, flat, records, interval)
                status[m] = run(state, chain, contacts, extension, probes, control, members.law[m],
                                members.general[m], k_start, k_stop)

        _GENERATED[code, extended] = kernel
    return _GENERATED[code, extended]


kernels.flush_stale_cache(*_BATCH_KERNELS)


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
            pk.rkn_steps = rkn_engine(pk, all_forces, rtol, n_threads)
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
    # the most expensive members first, dealt round-robin, so that the threads finish together.
    cost = steps_per_sample * (pk.n_slots + 1) * np.where(pk.general, 2, 1) * np.where(pk.ext_on, 2, 1)
    order = np.argsort(-cost, kind="stable").astype(np.int64)
    # one launch per engine: the hand-written loop for the built-in laws, each generated law's own
    generated = np.array([is_generated(c) for c in pk.law[order]], dtype=bool)
    kinds = np.array([kernels.run_kind(int(c), bool(gen), bool(ext))
                      for c, gen, ext in zip(pk.law[order], pk.general[order], pk.ext_on[order])], dtype=np.int64)
    groups = [(_BATCH_KERNELS[kind], order[~generated & (kinds == kind)])
              for kind in np.unique(kinds[~generated])]
    ext = pk.ext_on[order]
    groups += [(_generated_batch_kernel(int(c), bool(e)), order[(pk.law[order] == c) & (ext == e)])
               for c in np.unique(pk.law[order[generated]]) for e in np.unique(ext[generated & (pk.law[order] == c)])]
    samples_per_call = max(1, int(CHUNK_SLOT_STEPS * default_threads(n_threads) // cost.sum()))
    structures = batch_structures(pk)
    k = 1
    while k < n_samples:
        k_stop = min(n_samples, k + samples_per_call)
        for kernel, subset in groups:
            run_dealt(kernel, subset, n_threads, *structures, interval, k, k_stop, status)
        check_members_finite(status, k_stop * interval)
        check_interrupt()  # a Ctrl-C swallowed by a cleanup while the kernel ran (hertzchain.interrupts)
        k = k_stop
        if progress is not None:
            progress(k - 1, n_samples - 1)
