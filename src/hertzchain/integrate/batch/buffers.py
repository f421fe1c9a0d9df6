"""The packed batch: the flat ragged buffers both batched engines (CPU and CUDA) run on.

The set-up (:mod:`hertzchain.integrate.batch.pack`) lays a batch out as one :class:`_Packed`:
the padded per-slot arrays of every member concatenated into flat buffers (one offset table),
per-member step plans and parameters, the output buffers with sample 0 written, and the
kernel's trackers. An engine then advances it in place, the CPU engine
(:mod:`hertzchain.integrate.batch.engine`) or the GPU engine (:mod:`hertzchain.integrate.cuda.launch`),
and :mod:`hertzchain.runs.batch_results` reads the results out of it. Nothing here depends
on the device: both engines import this module and neither imports the other.
"""

from __future__ import annotations

import mmap
import threading
import weakref
from dataclasses import dataclass
from typing import TypeVar

import numpy as np

from ...errors import SimulationDiverged


#: Doubles per 64-byte cache line.
_LINE = 8
#: A slot count: one member's (int) or every member's (array).
_Slots = TypeVar("_Slots", int, np.ndarray)


def _aligned_zeros(n: int) -> np.ndarray:
    """Zeros of length ``n`` starting on a 64-byte boundary."""
    buf = np.zeros(n + _LINE)
    start = (-(buf.ctypes.data // 8)) % _LINE
    return buf[start:start + n]


#: Records from this size on [bytes] are mapped without transparent huge pages (:func:`_records`).
_SMALL_PAGES_FROM = 1 << 22


def _records(*shape: int, zeros: bool = False) -> np.ndarray:
    """A float64 array for the probes' records, in small (4 kB) pages; uninitialised, or zeros
    with ``zeros``.

    NumPy advises transparent huge pages for arrays over 4 MB (``madvise(MADV_HUGEPAGE)``); with
    a kernel whose THP defrag setting is ``madvise`` (common), the first write to each 2 MB page
    zeroes it and may compact memory synchronously. A batch's set-up writes sample 0 of every
    member, one 2 MB page every few members: set-up of 500 chain-1 members at 100 ns for 3 ms
    (480 MB of records) took 0.5-2.7 s, against 0.17 s for first writes in small pages, spread over
    the engine's threads. An anonymous mapping with ``MADV_NOHUGEPAGE`` (Linux) keeps them small;
    elsewhere, or below ``_SMALL_PAGES_FROM``, this is ``np.empty`` (``np.zeros``). (A fresh
    anonymous mapping reads as zeros.) A mapping of an earlier batch whose arrays are all gone is
    reused (:data:`_KEPT`).
    """
    n = int(np.prod(shape, dtype=np.int64))
    advice = getattr(mmap, "MADV_NOHUGEPAGE", None)
    if advice is None or n * 8 < _SMALL_PAGES_FROM:
        return np.zeros(shape) if zeros else np.empty(shape)
    with _KEPT_LOCK:  # two threads (a Dask worker's) never take the same free mapping
        return _mapped(n, shape, zeros, advice)


def _mapped(n: int, shape: tuple, zeros: bool, advice: int) -> np.ndarray:
    """:func:`_records` of ``n`` doubles in a mapping, a kept free one of that size if any."""
    free = [k for k in _KEPT if k[1]() is None]
    for k in free:
        if len(k[0]) == n * 8:  # a mapping whose arrays are gone: its pages are still there
            _KEPT.remove(k)
            flat = np.frombuffer(k[0], dtype=np.float64)
            _KEPT.append((k[0], weakref.ref(flat.base)))
            if zeros:
                flat.fill(0.0)
            return flat.reshape(shape)
    for k in free:  # not of this size: unmapped before a new one, so that the peak stays the live records'
        _KEPT.remove(k)
    buf = mmap.mmap(-1, n * 8)
    try:
        buf.madvise(advice)
    except OSError:  # a kernel without transparent huge pages: nothing to advise against
        pass
    flat = np.frombuffer(buf, dtype=np.float64)
    _KEPT.append((buf, weakref.ref(flat.base)))  # the buffer view every array of it holds
    del _KEPT[:-_KEEP]
    return flat.reshape(shape)


#: The record mappings of :func:`_records` this process keeps, most recent last: (mapping, weak
#: reference to the buffer view its arrays hold, dead once they are all gone). The next batch of
#: the same size reuses a free one instead of mapping fresh pages: a sweep's chunks of 500 chain-1
#: members would otherwise take ~240 page faults per member (~0.8 ms of system time). Free mappings
#: stay resident until a batch of another size (which unmaps them first), :func:`release_records`
#: or the process's end.
_KEPT: list = []
#: ... at most this many (a batch maps up to ~6: forces, energies, work, velocities, body).
_KEEP = 8
_KEPT_LOCK = threading.Lock()


def release_records() -> None:
    """Stop keeping record mappings for reuse (:data:`_KEPT`): those whose arrays are gone are
    unmapped now, the others when their arrays go (a sweep calls it after its last chunk, before
    it collects the metrics table)."""
    with _KEPT_LOCK:
        _KEPT.clear()


@dataclass
class _Packed:
    """A batch laid out for the engine: ragged flat buffers (see ``batch_engine._batch_members``),
    per-member step plans and parameters, output buffers (sample 0 written) and the kernel's
    trackers."""

    interval: float
    n_samples: int
    flat: dict[str, np.ndarray]
    off: np.ndarray
    n_slots: np.ndarray
    law: np.ndarray
    general: np.ndarray
    wall_slot: np.ndarray
    stride: np.ndarray
    n_sub: np.ndarray
    n_eval: np.ndarray
    c_steps: np.ndarray
    relax: np.ndarray
    plan_dt: np.ndarray
    rec: np.ndarray
    rec_off: np.ndarray
    nrec: np.ndarray
    out_f: np.ndarray
    f_off: np.ndarray
    out_ke: np.ndarray
    out_pe: np.ndarray
    out_ed: np.ndarray
    out_wp: np.ndarray
    out_v: np.ndarray
    v_off: np.ndarray
    v_rows: np.ndarray
    nb: np.ndarray
    record_v: np.ndarray
    fmax: np.ndarray
    fmax_off: np.ndarray
    peak: np.ndarray
    acc: np.ndarray
    ext: np.ndarray               # (rows, EXT_COLUMNS): the extended members' extension arrays, one after another
    ext_off: np.ndarray           # member m's rows: ext[ext_off[m]:ext_off[m + 1]] (none when not extended)
    ext_on: np.ndarray            # (M,) bool
    body_slot: np.ndarray         # (M,) N + 1 for a member with a protected body, else -1
    out_b: np.ndarray             # flat: member m's body record out_b[b_off[m]:b_off[m + 1]] seen as (K, 4)
    b_off: np.ndarray
    integrator: str = "verlet"    # the engine that ran it: "verlet" or "rkn4" (integrate.batch.rkn)
    rkn_steps: np.ndarray | None = None  # (M, 3) with "rkn4": steps, smallest and largest step [s] per member

    @property
    def n_members(self) -> int:
        return self.n_slots.size


_NAMES = ("mass", "inv_mass", "kappa", "damping", "d0", "de", "dx0", "rsum", "fext", "dcap")
#: Per-slot arrays of the elastic-plastic law (yield overlap and per-contact state, see
#: ``layout.Packed``): full size only in a batch with an elastic-plastic member, else empty.
_STATE = ("dyield", "dmax", "dres", "kres")


def _slot_sizes(n_slots: _Slots) -> _Slots:
    """Slots a member owns in the flat buffers: P + 1 rounded up to whole 64-byte cache lines (on
    an aligned buffer two threads then never write to one cache line: false sharing would cost a
    line transfer per step)."""
    return -(-(n_slots + 1) // _LINE) * _LINE


def _outputs(interval: float, n_samples: int, n_slots: np.ndarray, nrec: np.ndarray, rec: np.ndarray,
             nb: np.ndarray, record_v: np.ndarray, n_contacts: np.ndarray, slot_order: np.ndarray | None = None,
             plastic: bool = False, ext_on: np.ndarray | None = None, body_slot: np.ndarray | None = None,
             **members) -> _Packed:
    """Offsets and zeroed buffers of a batch (member m owns :func:`_slot_sizes` slots from
    ``off[m]``). The members' slots follow one another in the order ``slot_order`` (default: the
    members' own); every other buffer is in the members' order. With ``plastic`` (a member has
    the elastic-plastic law) the _STATE buffers and the plastic-work samples are allocated in
    full, else empty (the kernel never reads them). ``ext_on`` (default: none) marks the members
    with an extension array (P rows each), ``body_slot`` (default: -1) those with a protected body
    (a (K, 4) record each)."""
    from ..core.extension import EXT_COLUMNS

    nmem = n_slots.size
    ext_on = np.zeros(nmem, dtype=np.bool_) if ext_on is None else ext_on
    body_slot = np.full(nmem, -1, dtype=np.int64) if body_slot is None else body_slot
    ext_off = np.concatenate([[0], np.cumsum(np.where(ext_on, n_slots, 0))]).astype(np.int64)
    b_off = np.concatenate([[0], np.cumsum(np.where(body_slot >= 0, 4 * n_samples, 0))]).astype(np.int64)
    sizes = _slot_sizes(n_slots)
    if slot_order is None:
        off = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    else:
        starts = np.concatenate([[0], np.cumsum(sizes[slot_order])]).astype(np.int64)
        off = np.empty(nmem + 1, dtype=np.int64)
        off[slot_order] = starts[:-1]
        off[nmem] = starts[-1]  # the buffers' length
    total = int(off[-1])
    flat = {k: _aligned_zeros(total) for k in _NAMES + ("u", "v", "g", "a")}
    flat.update({k: _aligned_zeros(total if plastic else 0) for k in _STATE})
    rec_off = np.concatenate([[0], np.cumsum(nrec)]).astype(np.int64)
    f_off = np.concatenate([[0], np.cumsum(nrec * n_samples)]).astype(np.int64)
    v_rows = np.where(record_v, n_samples, 1).astype(np.int64)
    v_off = np.concatenate([[0], np.cumsum(v_rows * nb)]).astype(np.int64)
    fmax_off = np.concatenate([[0], np.cumsum(n_contacts)]).astype(np.int64)
    return _Packed(interval=interval, n_samples=n_samples, flat=flat, off=off, n_slots=n_slots, rec=rec,
                   rec_off=rec_off, nrec=nrec, out_f=_records(int(f_off[-1])), f_off=f_off,
                   out_ke=_records(nmem, n_samples), out_pe=_records(nmem, n_samples),
                   out_ed=_records(nmem, n_samples), out_wp=_records(nmem, n_samples if plastic else 1, zeros=True),
                   out_v=_records(int(v_off[-1])), v_off=v_off, v_rows=v_rows,
                   nb=nb, record_v=record_v, fmax=np.zeros(int(fmax_off[-1])), fmax_off=fmax_off,
                   # Written every step: one cache line (8 doubles) per member (see ``sizes``).
                   peak=_aligned_zeros(nmem * _LINE).reshape(nmem, _LINE),
                   acc=_aligned_zeros(nmem * _LINE).reshape(nmem, _LINE), ext=np.zeros((int(ext_off[-1]), EXT_COLUMNS)),
                   ext_off=ext_off, ext_on=ext_on, body_slot=body_slot, out_b=_records(int(b_off[-1])), b_off=b_off,
                   **members)


def _member_forces(pk: _Packed, m: int) -> np.ndarray:
    """Member m's force samples, a (time, recorded contact) view of the flat buffer."""
    return pk.out_f[pk.f_off[m]:pk.f_off[m + 1]].reshape(pk.n_samples, pk.nrec[m])


def _member_body(pk: _Packed, m: int) -> np.ndarray:
    """Member m's protected-body record, a (time, 4) view ((time, 0)... (0, 4) without a body)."""
    return pk.out_b[pk.b_off[m]:pk.b_off[m + 1]].reshape(-1, 4)


def _member_ext(pk: _Packed, m: int) -> np.ndarray:
    """Member m's extension array (P, EXT_COLUMNS) view ((0, EXT_COLUMNS) when not extended)."""
    return pk.ext[pk.ext_off[m]:pk.ext_off[m + 1]]


def _member_velocities(pk: _Packed, m: int) -> np.ndarray:
    """Member m's velocity samples, a (time or 1, body) view of the flat buffer."""
    return pk.out_v[pk.v_off[m]:pk.v_off[m + 1]].reshape(pk.v_rows[m], pk.nb[m])


def check_members_finite(status: np.ndarray, t: float) -> None:
    """Raise SimulationDiverged naming the members whose ``status`` is set (state no longer finite
    before time ``t`` [s]); shared by the CPU and CUDA engines."""
    bad = np.flatnonzero(status)
    if bad.size:
        raise SimulationDiverged(
            f"the integration of member(s) {bad.tolist()[:10]} diverged (non-finite state) before "
            f"t = {t:.4g} s; use a smaller run.dt (or the automatic one) or check their inputs")
