"""Batched engine: many independent chains integrated in one compiled call across all cores.

Members may differ in everything (length, diameters, materials, striker, offsets, contact law,
wall, time step); they share the duration and the sample interval, so every member has the same
time axis. The results are *bit for bit* those of :func:`hertzchain.simulate`, because nothing
numerical is re-implemented here:

- each member is packed with :func:`hertzchain.integrate.layout.pack` and initialised with the
  same kernel calls, in the same order, as :func:`hertzchain.integrate.verlet.run_verlet`;
- the padded arrays of all members are concatenated into flat ragged buffers (one offset table);
- one ``@njit(parallel=True)`` loop (Numba ``prange``) hands every member to the very same
  :func:`hertzchain.integrate.kernels.verlet_run` on slices of those buffers (slices are views,
  so the kernel writes straight into the outputs). Velocity Verlet has no cross-member coupling
  and no reductions across members, so the thread that runs a member cannot change its result.

Set-up. Members are set up with array code (:class:`~hertzchain.integrate.ensemble.Ensemble`,
:func:`_pack_groups`: a few microseconds per member, the same numbers as the member-by-member
:func:`_pack_models`), one group of members sharing a layout (number of beads, end, contact law
kind) and one Probes at a time, all groups into one packed batch and one engine call. Batches
of one group also get their stacked Dataset from the (member, ...) buffers
(:func:`_ensemble_dataset`) and can run on a GPU (``device=``, :mod:`hertzchain.integrate.cuda`).

Public entry points: :func:`simulate_many` (a list of single-run Datasets, identical to
:func:`~hertzchain.simulation.simulate`'s) and :func:`simulate_batch` (one Dataset stacked along a
``member`` dimension, identical to :func:`stack_results` of :func:`simulate_many`'s but built
straight from the engine's arrays: no Dataset per member, and the output buffers that already
have the stacked layout, such as the (member, time) energies, are used without a copy).
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import threading
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import Callable, NamedTuple, Sequence

import numba
import numpy as np
import xarray as xr
from numba import njit, prange

from ..errors import ConfigError, SimulationDiverged
from ..model import Model
from ..probes import Probes
from ..checks import _smaller_radius, smaller_radii, warn_members_hertz_range, warn_members_pulse_not_reached
from ..simulation import warn_elastic_limit
from . import kernels, verlet
from .ensemble import Ensemble, Ragged, layout_key, ragged, same_layout, systems
from .layout import PAD, pack
from .verlet import (ADAPTIVE_STEPS_PER_RADIAN, MAX_OMEGA_DT, RELAX_EVALUATIONS, RawRun, StepPlan,
                     horizon_radians, initialise, step_plan)

__all__ = ["simulate_batch", "simulate_many", "run_batch", "stack_results"]

#: Work (padded slot-steps summed over members) per compiled call between two progress reports:
#: about 0.3 s on one core at the ~6.7e8 slot-steps/s of the kernel, times the thread count.
CHUNK_SLOT_STEPS = 2e8


#: Doubles per 64-byte cache line.
_LINE = 8


def _aligned_zeros(n: int) -> np.ndarray:
    """Zeros of length ``n`` starting on a 64-byte boundary."""
    buf = np.zeros(n + _LINE)
    start = (-(buf.ctypes.data // 8)) % _LINE
    return buf[start:start + n]


@njit(parallel=True, cache=True)
def _batch_kernel(order, off, n_slots, u, v, a, g, mass, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, dcap,
                  law, general, wall_slot, interval, stride, n_sub, n_eval, c_steps, relax, k_start, k_stop, rec, rec_off, out_f, f_off, out_ke, out_pe, out_ed,
                  out_v, v_off, v_rows, nbody, record_v, fmax, fmax_off, peak, acc, status):
    """Advance every member from sample ``k_start`` to ``k_stop`` with :func:`kernels.verlet_run`.

    Member m owns the slots from ``off[m]`` of the body/contact buffers (``P + 1`` slots,
    ``P = n_slots[m]``, rounded up to whole cache lines; see :func:`_outputs`): the ``P``-sized arrays (mass, kappa, ...)
    use the first ``P``, ``u, v, g`` the first ``P + 1`` (layout of
    :mod:`hertzchain.integrate.kernels`). Its recorded contacts are ``rec[rec_off[m]:rec_off[m+1]]``;
    its force samples the flat block ``out_f[f_off[m]:f_off[m+1]]`` seen as (K, n_rec); its
    running maximum forces ``fmax[fmax_off[m]:fmax_off[m+1]]``; its velocities
    ``out_v[v_off[m]:v_off[m+1]]`` seen as (v_rows[m], nbody[m] = N + 1). Members are visited in
    the order ``order`` (most expensive first, so that dynamic scheduling does not leave one long
    member for the end). ``status[m]`` is the kernel's return value; a member that diverged is
    not advanced again.
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
        status[m] = kernels.verlet_run(u[s:s + p + 1], v[s:s + p + 1], a[s:s + p], g[s:s + p + 1], mass[s:s + p],
                                       inv_mass[s:s + p], kappa[s:s + p], damping[s:s + p], d0[s:s + p],
                                       de[s:s + p], dx0[s:s + p], rsum[s:s + p], fext[s:s + p], dcap[s:s + p],
                                       law[m], general[m], wall_slot[m], interval, stride[m], n_sub[m], n_eval[m],
                                       c_steps[m], relax[m], k_start, k_stop, rec[r0:r1], f, out_ke[m], out_pe[m],
                                       out_ed[m], vv, record_v[m], fmax[fmax_off[m]:fmax_off[m + 1]], peak[m],
                                       acc[m])


# The workqueue threading layer (the one available without TBB/OpenMP) aborts the process when two
# threads launch parallel kernels at once, e.g. two Dask worker threads in one process; one launch
# already uses every core, so serialising launches costs nothing.
_LAUNCH_LOCK = threading.Lock()


def _flush_stale_cache(*kernels_using: object) -> None:
    """Drop the on-disk cache of these compiled functions when ``kernels.py`` is newer than it.

    Numba's cache only checks the source file of the cached function itself, not of the
    functions it calls; :func:`_batch_kernel` and :func:`_init_kernel` compile the functions of
    ``kernels`` into themselves, so an edit of ``kernels.py`` would otherwise leave the batched
    engine running the old kernel.
    """
    for fn in kernels_using:
        try:
            index = Path(fn._cache._cache_file._index_path)
            if index.exists() and index.stat().st_mtime < Path(kernels.__file__).stat().st_mtime:
                fn._cache.flush()
        except (AttributeError, OSError):  # private Numba API moved or no cache: nothing to protect
            pass




@dataclass
class _Member:
    """What one member needs besides the shared buffers (mirrors the locals of run_verlet)."""

    system: object
    rec: np.ndarray
    plan: StepPlan
    record_v: bool


def _as_list(x, n: int, name: str) -> list:
    """Broadcast a scalar/None to ``n`` members, or check a per-member sequence's length."""
    if x is None or isinstance(x, (int, float, Probes)):
        return [x] * n
    x = list(x)
    if len(x) != n:
        raise ConfigError(name, f"needs one value per member ({n}), got {len(x)}")
    return x


def _check_inputs(models: Sequence[Model], duration: float, probes, dt) -> tuple[list[Probes], list]:
    """The checks of :func:`hertzchain.simulate`, per member, plus a shared sample interval."""
    if len(models) == 0:
        raise ConfigError("models", "the batch is empty: give at least one model")
    for i, m in enumerate(models):
        if not isinstance(m, Model):
            raise ConfigError(f"models[{i}]", f"must be a hertzchain Model, got {type(m).__name__}")
    if not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration > 0):
        raise ConfigError("run.duration", f"must be a positive time in s, got {duration!r}")
    plist = [p or Probes() for p in _as_list(probes, len(models), "probes")]
    dts = _as_list(dt, len(models), "run.dt")
    interval = plist[0].sample_interval
    for i, p in enumerate(plist):
        if p.sample_interval != interval:
            raise ConfigError(f"probes[{i}].sample_interval", f"all members must share one sample interval "
                              f"({interval:g} s for member 0, {p.sample_interval:g} s here)")
        if p.sample_interval > duration:
            raise ConfigError("run.sample_interval",
                              f"({p.sample_interval:g} s) is longer than run.duration ({duration:g} s)")
        p.validate(models[i].chain.n_beads, models[i].wall.present)
    return plist, dts


def run_batch(models: Sequence[Model], duration: float, probes: Probes | Sequence[Probes] | None = None, *,
              dt: float | Sequence[float | None] | None = None, progress: Callable[[int, int], None] | None = None,
              n_threads: int | None = None, steps_per_radian: float | None = None, return_systems: bool = False
              ) -> list[RawRun] | tuple[list[RawRun], list]:
    """Integrate every model with the batched compiled Verlet; one :class:`RawRun` per member.

    Parameters are those of :func:`simulate_batch`. The RawRuns are identical to what
    :func:`hertzchain.integrate.verlet.run_verlet` returns for each member alone. Members of
    the elastic, viscoelastic and dashpot laws are set up with array code, one group of members
    of one layout (number of beads, end, law kind) and one Probes at a time, into one engine
    call; a batch with a size-scaled viscoelastic member is set up member by member. With
    ``return_systems`` also every member's :class:`MemberSystem` (bead count, Hertz constants and
    elastic limits, computed for the run anyway; no ``Model.system()`` per member).
    """
    plist, dts = _check_inputs(models, duration, probes, dt)
    runs, sys_list, _ = _run(models, duration, plist, dts, progress, n_threads, steps_per_radian)
    return (runs, sys_list) if return_systems else runs


def _check_no_positions(plist) -> None:
    if any(p.positions for p in plist):
        raise ConfigError("probes.positions", "batches and sweeps do not record positions; simulate the run "
                          "to animate alone (hertzchain run, hertzchain.simulate)")


def _check_threads(n_threads) -> None:
    if n_threads is not None and not (isinstance(n_threads, (int, np.integer))
                                      and 1 <= n_threads <= numba.config.NUMBA_NUM_THREADS):
        raise ConfigError("n_threads", f"must be an integer in 1..{numba.config.NUMBA_NUM_THREADS}, got {n_threads!r}")


@dataclass
class _Packed:
    """A batch laid out for the engine: ragged flat buffers (see :func:`_batch_kernel`), per-member
    step plans and parameters, output buffers (sample 0 written) and the kernel's trackers."""

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
    out_v: np.ndarray
    v_off: np.ndarray
    v_rows: np.ndarray
    nb: np.ndarray
    record_v: np.ndarray
    fmax: np.ndarray
    fmax_off: np.ndarray
    peak: np.ndarray
    acc: np.ndarray

    @property
    def n_members(self) -> int:
        return self.n_slots.size


_NAMES = ("mass", "inv_mass", "kappa", "damping", "d0", "de", "dx0", "rsum", "fext", "dcap")


def _slot_sizes(n_slots: np.ndarray) -> np.ndarray:
    """Slots a member owns in the flat buffers: P + 1 rounded up to whole 64-byte cache lines (on
    an aligned buffer two threads then never write to one cache line: false sharing would cost a
    line transfer per step)."""
    return -(-(n_slots + 1) // _LINE) * _LINE


def _outputs(interval: float, n_samples: int, n_slots: np.ndarray, nrec: np.ndarray, rec: np.ndarray,
             nb: np.ndarray, record_v: np.ndarray, n_contacts: np.ndarray, slot_order: np.ndarray | None = None,
             **members) -> _Packed:
    """Offsets and zeroed buffers of a batch (member m owns :func:`_slot_sizes` slots from
    ``off[m]``). The members' slots follow one another in the order ``slot_order`` (default: the
    members' own); every other buffer is in the members' order."""
    nmem = n_slots.size
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
    rec_off = np.concatenate([[0], np.cumsum(nrec)]).astype(np.int64)
    f_off = np.concatenate([[0], np.cumsum(nrec * n_samples)]).astype(np.int64)
    v_rows = np.where(record_v, n_samples, 1).astype(np.int64)
    v_off = np.concatenate([[0], np.cumsum(v_rows * nb)]).astype(np.int64)
    fmax_off = np.concatenate([[0], np.cumsum(n_contacts)]).astype(np.int64)
    return _Packed(interval=interval, n_samples=n_samples, flat=flat, off=off, n_slots=n_slots, rec=rec,
                   rec_off=rec_off, nrec=nrec, out_f=np.empty(int(f_off[-1])), f_off=f_off,
                   out_ke=np.empty((nmem, n_samples)), out_pe=np.empty((nmem, n_samples)),
                   out_ed=np.empty((nmem, n_samples)), out_v=np.empty(int(v_off[-1])), v_off=v_off, v_rows=v_rows,
                   nb=nb, record_v=record_v, fmax=np.zeros(int(fmax_off[-1])), fmax_off=fmax_off,
                   # Written every step: one cache line (8 doubles) per member (see ``sizes``).
                   peak=_aligned_zeros(nmem * _LINE).reshape(nmem, _LINE),
                   acc=_aligned_zeros(nmem * _LINE).reshape(nmem, _LINE), **members)


def _pack_models(members: list[_Member], interval: float, n_samples: int) -> _Packed:
    """A batch of arbitrary models, member by member (see :func:`_pack_ensemble` for the fast path)."""
    packs = [pack(mb.system) for mb in members]
    pk = _outputs(interval, n_samples, n_slots=np.array([w.n_slots for w in packs], dtype=np.int64),
                  nrec=np.array([mb.rec.size for mb in members], dtype=np.int64),
                  rec=np.concatenate([mb.rec for mb in members]).astype(np.int64),
                  nb=np.array([mb.system.n_beads + 1 for mb in members], dtype=np.int64),
                  record_v=np.array([mb.record_v for mb in members], dtype=np.bool_),
                  n_contacts=np.array([mb.system.n_contacts for mb in members], dtype=np.int64),
                  law=np.array([mb.system.law for mb in members], dtype=np.int64),
                  general=np.array([mb.system.general for mb in members], dtype=np.bool_),
                  wall_slot=np.array([w.wall_slot for w in packs], dtype=np.int64),
                  stride=np.array([mb.plan.stride for mb in members], dtype=np.int64),
                  n_sub=np.array([mb.plan.n_sub for mb in members], dtype=np.int64),
                  n_eval=np.array([mb.plan.n_eval for mb in members], dtype=np.int64),
                  c_steps=np.array([mb.plan.c_steps for mb in members], dtype=np.float64),
                  relax=np.array([mb.plan.relax for mb in members], dtype=np.int64),
                  plan_dt=np.array([mb.plan.dt for mb in members], dtype=np.float64))
    flat = pk.flat
    for m, w in enumerate(packs):
        s, p = pk.off[m], w.n_slots
        for k in _NAMES:
            flat[k][s:s + p] = getattr(w, k)
        flat["u"][s:s + p + 1] = w.u
        flat["v"][s:s + p + 1] = w.v
    # ---- initial state: the very function run_verlet uses, on per-member views
    for m, (mb, w) in enumerate(zip(members, packs)):
        s, p = pk.off[m], w.n_slots
        u, v, g, a = (flat["u"][s:s + p + 1], flat["v"][s:s + p + 1], flat["g"][s:s + p + 1], flat["a"][s:s + p])
        initialise(mb.system, w, u, v, g, a, mb.rec, _member_forces(pk, m),
                   pk.out_ke[m], pk.out_pe[m], pk.out_ed[m], _member_velocities(pk, m), mb.record_v,
                   pk.fmax[pk.fmax_off[m]:pk.fmax_off[m + 1]], pk.peak[m], pk.acc[m])
    return pk


@njit(cache=True)
def _init_kernel(off, n_slots, u, v, a, g, mass, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, law, general,
                 wall_slot, rec, rec_off, out_f, f_off, out_ke, out_pe, out_ed, out_v, v_off, v_rows, nbody,
                 record_v, fmax, fmax_off, peak, acc):
    """:func:`hertzchain.integrate.verlet.initialise` of every member (same kernel calls, same order)."""
    nk = out_ke.shape[1]
    for m in range(n_slots.shape[0]):
        s = off[m]
        p = n_slots[m]
        uu, vv, gg, aa = u[s:s + p + 1], v[s:s + p + 1], g[s:s + p + 1], a[s:s + p]
        power0 = 0.0
        if general[m]:
            power0 = kernels.forces_general(uu, vv, kappa[s:s + p], damping[s:s + p], d0[s:s + p], de[s:s + p],
                                            dx0[s:s + p], rsum[s:s + p], law[m], gg)
        else:
            kernels.forces_elastic(uu, kappa[s:s + p], d0[s:s + p], gg)
        kernels.accelerations(gg, fext[s:s + p], inv_mass[s:s + p], aa)
        r0 = rec_off[m]
        nr = rec_off[m + 1] - r0
        f = out_f[f_off[m]:f_off[m + 1]].reshape((nk, nr))
        for j in range(nr):
            f[0, j] = gg[rec[r0 + j] + 1]
        out_ke[m, 0] = kernels.kinetic_energy(vv, mass[s:s + p])
        out_pe[m, 0] = kernels.potential_energy(uu, gg, kappa[s:s + p], d0[s:s + p], de[s:s + p], dx0[s:s + p],
                                                rsum[s:s + p], fext[s:s + p], False)
        out_ed[m, 0] = 0.0
        if record_v[m]:
            for i in range(nbody[m]):
                out_v[v_off[m] + i] = vv[i]
        for j in range(fmax_off[m + 1] - fmax_off[m]):
            fmax[fmax_off[m] + j] = gg[j + 1]
        fw0 = gg[wall_slot[m] + 1]
        peak[m, 0] = fw0
        peak[m, 5] = fw0
        for i in (1, 2, 3, 4, 6, 7):
            peak[m, i] = 0.0
        for i in range(7):
            acc[m, i] = 0.0
        acc[m, 1] = power0
        acc[m, 7] = np.inf


_flush_stale_cache(_batch_kernel, _init_kernel)


def _step_plans(w: np.ndarray, interval: float, dts: np.ndarray, check,
                steps_per_radian: float | None = None) -> dict[str, np.ndarray]:
    """:func:`hertzchain.integrate.verlet.step_plan` of every member (``dts``: NaN = adaptive step).

    ``check(i, dt)`` is :func:`hertzchain.integrate.verlet.check_time_step` on member i: called
    for the members whose user step is not positive or too large for their omega_max, it raises
    the single run's error (the bound is tested here with array code, the message comes from there).
    """
    nmem = w.size
    fixed = ~np.isnan(dts)
    with np.errstate(invalid="ignore"):
        suspect = fixed & ~((dts > 0) & np.isfinite(dts) & (w * dts <= MAX_OMEGA_DT))
    for i in np.flatnonzero(suspect).tolist():
        try:
            check(i, float(dts[i]))
        except ConfigError as exc:
            raise ConfigError(exc.field, f"member {i}: {exc.message}") from None
    stride = np.zeros(nmem, dtype=np.int64)
    plan_dt = np.empty(nmem)
    n_sub = np.ones(nmem, dtype=np.int64)
    n_eval = np.ones(nmem, dtype=np.int64)
    c_steps = np.zeros(nmem)
    relax = np.zeros(nmem, dtype=np.int64)
    # fixed step, shortened to divide the sample interval (verlet._stride)
    sf = np.maximum(1, np.ceil(interval / dts[fixed] - 1e-9)).astype(np.int64)
    stride[fixed] = sf
    plan_dt[fixed] = interval / sf
    still = ~fixed & (w <= 0.0)  # nothing moves: any step is exact
    stride[still] = 1
    plan_dt[still] = interval
    ad = ~fixed & (w > 0.0)
    wa = w[ad]
    c = ADAPTIVE_STEPS_PER_RADIAN if steps_per_radian is None else float(steps_per_radian)
    with np.errstate(divide="ignore"):
        bmax = horizon_radians(c) / wa
    short = interval <= bmax
    ns = np.where(short, 1, np.ceil(interval / bmax - 1e-9)).astype(np.int64)
    ne = np.where(short, np.maximum(1, np.floor(bmax / interval)), 1).astype(np.int64)
    block = interval / ns
    plan_dt[ad] = block / np.ceil(block * c * wa - 1e-9)
    n_sub[ad] = ns
    n_eval[ad] = ne
    c_steps[ad] = c
    relax[ad] = RELAX_EVALUATIONS
    return {"stride": stride, "plan_dt": plan_dt, "n_sub": n_sub, "n_eval": n_eval, "c_steps": c_steps,
            "relax": relax}


def _ensemble_dts(dt, nmem: int) -> np.ndarray:
    """Per-member user steps [s] as floats, NaN where the step is automatic."""
    if dt is None:
        return np.full(nmem, np.nan)
    if isinstance(dt, (int, float)):
        return np.full(nmem, float(dt))
    vals = list(dt)
    if len(vals) != nmem:
        raise ConfigError("run.dt", f"needs one value per member ({nmem}), got {len(vals)}")
    return np.array([np.nan if x is None else x for x in vals], dtype=float)


#: Members whose System arrays are computed at once by :func:`_pack_groups`: ~0.5 MB per
#: array for 30 beads, so the temporaries stay in the caches (one pass over 1e5 members at once
#: was ~4x slower, mostly page faults on fresh 25 MB temporaries).
SETUP_BLOCK = 2048


@dataclass
class _EnsembleArrays:
    """What the results need of one group's System arrays (group member, ...)."""

    bead_mass: np.ndarray    # (M, N) kg
    kappa_slots: np.ndarray  # (M, N + 1): System.kappa of every member (0 in a free end's slot)
    yield_slots: np.ndarray  # (M, N + 1): System.yield_force of every member
    n_contacts: int

    @property
    def kappa(self) -> np.ndarray:
        """(M, n_contacts) Hertz constants of the real contacts [N/m^1.5]."""
        return self.kappa_slots[:, :self.n_contacts]

    @property
    def yield_force(self) -> np.ndarray:
        """(M, n_contacts) elastic limits of the real contacts [N]."""
        return self.yield_slots[:, :self.n_contacts]


@dataclass
class _Group:
    """Members of one end, law kind and Probes, set up together with array code: member j of
    ``ens`` (one layout, or ragged: any bead counts) is member ``rows[j]`` of the batch (None: the
    batch is this group)."""

    ens: Ensemble | Ragged
    probes: Probes
    rows: np.ndarray | None = None


class MemberSystem(NamedTuple):
    """What a batch's results need of a member's ``Model.system()``, without computing it.

    The batched set-up computes every member's System arrays with array code
    (:func:`hertzchain.integrate.ensemble.systems`); a member's rows of them are kept here.

    Parameters
    ----------
    n_beads
        Number of beads N.
    has_wall
        Whether the chain ends on a wall.
    kappa
        (N + 1,) Hertz constants of contacts 0..N [N/m^1.5] (paper eq. 1), as ``System.kappa``:
        contact N joins bead N and the wall, 0 for a free end.
    yield_force
        (N + 1,) force at which each contact reaches its elastic limit [N], as
        ``System.yield_force`` (inf where not defined).
    """

    n_beads: int
    has_wall: bool
    kappa: np.ndarray
    yield_force: np.ndarray

    @property
    def n_contacts(self) -> int:
        """Number of real contacts: N + 1 with a wall, N without."""
        return self.n_beads + (1 if self.has_wall else 0)


def _pack_groups(groups: Sequence[_Group], dts: np.ndarray, interval: float, n_samples: int,
                 check: Callable[[int, float], None], steps_per_radian: float | None = None
                 ) -> tuple[_Packed, list[tuple[np.ndarray, np.ndarray, np.ndarray]]]:
    """A batch of members of several layouts with array code: what :func:`_pack_models` builds
    member by member, bit for bit, into one :class:`_Packed` (one initialisation, one engine call).

    A group is an :class:`~hertzchain.integrate.ensemble.Ensemble` (one layout) or a
    :class:`~hertzchain.integrate.ensemble.Ragged` (one end and law, any bead counts) and one
    Probes; :func:`~hertzchain.integrate.ensemble.systems` computes its members' arrays a block at
    a time. ``dts``: every member's user step [s] (NaN: adaptive), in the batch's order;
    ``check(i, dt)``: :func:`hertzchain.integrate.verlet.check_time_step` of member i (see
    :func:`_step_plans`). Every per-member array of the _Packed is in the batch's order; the
    slots of the flat body/contact buffers are laid out group after group, so that the members of
    an Ensemble (one width) are the rows of a 2-D view of each buffer; a Ragged group's members
    are written through one index of their N_i + 1 real slots. Returns the packed batch and, per
    group, its members' bead masses (M, N), Hertz constants and elastic limits (M, N + 1), padded
    past a ragged member's N_i.
    """
    nmem = dts.size
    n_slots, nrec, nb, n_contacts, wall_slot = (np.empty(nmem, dtype=np.int64) for _ in range(5))
    record_v = np.empty(nmem, dtype=np.bool_)
    index, counts, recs = [], [], []
    for g in groups:
        ens = g.ens
        wall = 1 if ens.has_wall else 0
        rows = np.arange(ens.n_members) if g.rows is None else g.rows
        n_each = getattr(ens, "n_each", None)
        n_each = np.full(rows.size, ens.n_beads, dtype=np.int64) if n_each is None else n_each
        n_slots[rows] = -(-(n_each + 2) // PAD) * PAD  # layout.pack: moving bodies + wall ghost, rounded up
        nb[rows] = n_each + 1
        n_contacts[rows] = n_each + wall
        wall_slot[rows] = n_each
        record_v[rows] = bool(g.probes.velocities)
        distinct, which = np.unique(n_each, return_inverse=True)
        rec = [g.probes.recorded_contacts(n, ens.has_wall).astype(np.int64) for n in distinct.tolist()]
        nrec[rows] = np.array([r.size for r in rec], dtype=np.int64)[which]
        index.append(rows)
        counts.append(n_each)
        recs.append((rec, which))
    if len(groups) == 1 and len(recs[0][0]) == 1 and groups[0].rows is None:
        rec_all, slot_order = np.tile(recs[0][0][0], nmem), None
    else:
        # member i's recorded contacts go to rec_all[rec_off[i]:rec_off[i + 1]], in the batch's order
        rec_off = np.concatenate([[0], np.cumsum(nrec)])
        rec_all = np.empty(int(rec_off[-1]), dtype=np.int64)
        for rows, (rec, which) in zip(index, recs):
            for k, r in enumerate(rec):
                rec_all[rec_off[rows[which == k]][:, None] + np.arange(r.size)] = r
        slot_order = np.concatenate(index)
    zeros_i, zeros_f = np.zeros(nmem, dtype=np.int64), np.zeros(nmem)
    pk = _outputs(interval, n_samples, n_slots=n_slots, nrec=nrec, rec=rec_all, nb=nb, record_v=record_v,
                  n_contacts=n_contacts, slot_order=slot_order, law=np.zeros(nmem, dtype=np.int64),
                  general=np.zeros(nmem, dtype=np.bool_), wall_slot=wall_slot, stride=zeros_i, plan_dt=zeros_f,
                  n_sub=zeros_i, n_eval=zeros_i, c_steps=zeros_f, relax=zeros_i)
    w = np.empty(nmem)
    out = []
    flat = pk.flat
    for g, rows, n_each in zip(groups, index, counts):
        ens = g.ens
        m, n = ens.n_members, ens.n_beads
        is_ragged = hasattr(ens, "n_each")
        first = int(pk.off[rows[0]])
        last = first + m * _slot_sizes(int(n_slots[rows[0]]))  # an Ensemble's slots, one row per member
        kept: list[tuple[np.ndarray, ...]] = []
        for lo in range(0, m, SETUP_BLOCK):
            hi = min(m, lo + SETUP_BLOCK)
            sy = systems(ens, lo, hi)
            # the N + 1 slots of every body array (bodies 0..N) and contact array (contacts 0..N)
            cols = {"mass": sy.mass, "inv_mass": sy.inv_mass, "kappa": sy.kappa, "damping": sy.damping, "d0": sy.d0,
                    "de": sy.de, "dx0": sy.dx0, "rsum": sy.rsum, "fext": sy.fext, "dcap": sy.max_overlap,
                    "u": sy.u0, "v": sy.v0}
            if is_ragged:
                r_idx, c_idx = np.nonzero(np.arange(n + 1) <= n_each[lo:hi, None])
                dst = pk.off[rows[lo:hi]][r_idx] + c_idx
                for k, x in cols.items():
                    flat[k][dst] = x[r_idx, c_idx]
            else:
                for k, x in cols.items():
                    flat[k][first:last].reshape(m, -1)[lo:hi, :n + 1] = x[:, :n + 1]
            at = slice(lo, hi) if g.rows is None else rows[lo:hi]
            pk.law[at] = sy.law
            pk.general[at] = sy.general
            w[at] = sy.max_frequency
            kept.append((sy.bead_mass, sy.kappa, sy.yield_force))
        # one block (a design's group): systems()'s own arrays, nothing copied
        out.append(tuple(parts[0] if len(kept) == 1 else np.concatenate(parts) for parts in zip(*kept)))
    for k, x in _step_plans(w, interval, dts, check, steps_per_radian).items():
        setattr(pk, k, x)
    f = flat
    _init_kernel(pk.off, pk.n_slots, f["u"], f["v"], f["a"], f["g"], f["mass"], f["inv_mass"], f["kappa"],
                 f["damping"], f["d0"], f["de"], f["dx0"], f["rsum"], f["fext"], pk.law, pk.general, pk.wall_slot,
                 pk.rec, pk.rec_off, pk.out_f, pk.f_off, pk.out_ke, pk.out_pe, pk.out_ed, pk.out_v, pk.v_off,
                 pk.v_rows, pk.nb, pk.record_v, pk.fmax, pk.fmax_off, pk.peak, pk.acc)
    return pk, out


def _pack_ensemble(ens: Ensemble, probes: Probes, dts: np.ndarray, interval: float,
                   n_samples: int, steps_per_radian: float | None = None) -> tuple[_Packed, _EnsembleArrays]:
    """The batch of an ensemble with array code: :func:`_pack_groups` of one group."""
    def check(i: int, dt: float) -> None:
        verlet.check_time_step(ens.model(i).system(), dt)

    pk, (arrays,) = _pack_groups([_Group(ens, probes)], dts, interval, n_samples, check, steps_per_radian)
    return pk, _EnsembleArrays(*arrays, n_contacts=ens.n_beads + (1 if ens.has_wall else 0))


def _groups(models: Sequence[Model], plist: Sequence[Probes]) -> list[_Group] | None:
    """The models as groups of one end, law kind and Probes (first appearance order, members in the
    batch's order within each): an Ensemble where they share the bead count, else a Ragged group;
    None when one has a law the array set-up does not compute."""
    rows: dict[tuple, list[int]] = {}
    for i, (model, p) in enumerate(zip(models, plist)):
        key = layout_key(model)
        if key is None:
            return None
        rows.setdefault((key[1:], p), []).append(i)
    groups = []
    for (_, p), r in rows.items():
        members = models if len(rows) == 1 else [models[i] for i in r]
        n0 = members[0].chain.n_beads
        same = all(mdl.chain.n_beads == n0 for mdl in members)
        groups.append(_Group(Ensemble.from_models(members) if same else ragged(members), p,
                             None if len(rows) == 1 else np.array(r, dtype=np.int64)))
    return groups


def _member_forces(pk: _Packed, m: int) -> np.ndarray:
    """Member m's force samples, a (time, recorded contact) view of the flat buffer."""
    return pk.out_f[pk.f_off[m]:pk.f_off[m + 1]].reshape(pk.n_samples, pk.nrec[m])


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


def _engine(pk: _Packed, progress, n_threads) -> None:
    """Run the packed batch to the end on the CPU (all cores), in compiled calls of ~CHUNK_SLOT_STEPS."""
    interval, n_samples = pk.interval, pk.n_samples
    steps_per_sample = interval / pk.plan_dt
    status = np.zeros(pk.n_members, dtype=np.int64)
    # Cost of one sample per member (the general force loop is roughly twice the elastic one):
    # the most expensive members go first so that the threads finish together.
    cost = steps_per_sample * (pk.n_slots + 1) * np.where(pk.general, 2, 1)
    order = np.argsort(-cost, kind="stable").astype(np.int64)
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
                    _batch_kernel(order, pk.off, pk.n_slots, flat["u"], flat["v"], flat["a"], flat["g"], flat["mass"],
                                  flat["inv_mass"], flat["kappa"], flat["damping"], flat["d0"], flat["de"],
                                  flat["dx0"], flat["rsum"], flat["fext"], flat["dcap"], pk.law, pk.general,
                                  pk.wall_slot, interval, pk.stride, pk.n_sub, pk.n_eval, pk.c_steps, pk.relax, k,
                                  k_stop, pk.rec, pk.rec_off, pk.out_f, pk.f_off, pk.out_ke, pk.out_pe, pk.out_ed,
                                  pk.out_v, pk.v_off, pk.v_rows, pk.nb, pk.record_v, pk.fmax, pk.fmax_off, pk.peak,
                                  pk.acc, status)
            finally:
                numba.set_num_threads(previous)
        check_members_finite(status, k_stop * interval)
        k = k_stop
        if progress is not None:
            progress(k - 1, n_samples - 1)


def _setup_members(models: Sequence[Model], plist: Sequence[Probes], dts: list, interval: float, n_samples: int,
                   steps_per_radian: float | None = None) -> tuple[_Packed, list[MemberSystem]]:
    """The batch set up member by member (``Model.system()``, :func:`step_plan`, :func:`_pack_models`):
    any law; the reference the array set-up (:func:`_setup_groups`) reproduces bit for bit."""
    members: list[_Member] = []
    for model, p, dti in zip(models, plist, dts):
        system = model.system()
        plan = step_plan(system, interval, dti, steps_per_radian)
        rec = p.recorded_contacts(model.chain.n_beads, model.wall.present)
        members.append(_Member(system, rec, plan, bool(p.velocities)))
    return _pack_models(members, interval, n_samples), [
        MemberSystem(mb.system.n_beads, mb.system.has_wall, mb.system.kappa, mb.system.yield_force) for mb in members]


def _setup_groups(models: Sequence[Model], plist: Sequence[Probes], dts: list, interval: float, n_samples: int,
                  steps_per_radian: float | None = None) -> tuple[_Packed, list[MemberSystem]] | None:
    """The batch set up with array code, one group of one layout and Probes at a time
    (:func:`_pack_groups`); None when a member's law needs the member-by-member set-up."""
    groups = _groups(models, plist)
    if groups is None:
        return None

    def check(i: int, dt: float) -> None:
        verlet.check_time_step(models[i].system(), dt)

    pk, arrays = _pack_groups(groups, _ensemble_dts(dts, len(models)), interval, n_samples, check, steps_per_radian)
    member_systems: list[MemberSystem | None] = [None] * len(models)
    for g, (_, kappa, fy) in zip(groups, arrays):
        wall = g.ens.has_wall
        rows = range(g.ens.n_members) if g.rows is None else g.rows.tolist()
        n_each = getattr(g.ens, "n_each", None)
        if n_each is None:
            n = g.ens.n_beads
            for i, k, f in zip(rows, kappa, fy):  # row views
                member_systems[i] = MemberSystem(n, wall, k, f)
        else:
            for i, n, k, f in zip(rows, n_each.tolist(), kappa, fy):
                member_systems[i] = MemberSystem(n, wall, k[:n + 1], f[:n + 1])
    return pk, member_systems


def _run(models: Sequence[Model], duration: float, plist: list[Probes], dts: list, progress, n_threads,
         steps_per_radian: float | None = None) -> tuple[list[RawRun], list[MemberSystem], dict[str, np.ndarray]]:
    """:func:`run_batch` on checked inputs. Also returns every member's :class:`MemberSystem` and
    the output buffers that are already stacked along ``member`` (row m is RawRun m's array): the
    energies always, ``recorded_force`` (member, time, recorded contact) when every member
    records the same contacts, ``velocity`` when every member records velocities of as many bodies."""
    _check_threads(n_threads)
    interval = plist[0].sample_interval
    nmem = len(models)
    n_samples = int(math.floor(duration / interval + 1e-9)) + 1

    _check_no_positions(plist)
    pk, member_systems = (_setup_groups(models, plist, dts, interval, n_samples, steps_per_radian)
                          or _setup_members(models, plist, dts, interval, n_samples, steps_per_radian))
    _engine(pk, progress, n_threads)
    runs = _member_runs(pk)
    # The output buffers seen as (member, time, ...) where every member has the same layout: row m
    # is exactly what RawRun m holds (its arrays are views of these rows).
    stacked = {"kinetic_energy": pk.out_ke, "potential_energy": pk.out_pe, "dissipated_energy": pk.out_ed}
    nrec = int(pk.nrec[0])
    if np.all(pk.nrec == nrec) and np.array_equal(pk.rec.reshape(nmem, nrec), np.broadcast_to(pk.rec[:nrec],
                                                                                              (nmem, nrec))):
        stacked["recorded_force"] = pk.out_f.reshape(nmem, n_samples, nrec)
    if pk.record_v.all() and np.all(pk.nb == pk.nb[0]):
        stacked["velocity"] = pk.out_v.reshape(nmem, n_samples, pk.nb[0])
    return runs, member_systems, stacked


def simulate_many(models: Sequence[Model], duration: float, probes: Probes | Sequence[Probes] | None = None, *,
                  dt: float | Sequence[float | None] | None = None, progress: Callable[[int, int], None] | None = None,
                  n_threads: int | None = None, configs: Sequence[dict | None] | None = None) -> list[xr.Dataset]:
    """Simulate every model in one batched compiled call; one Dataset per member.

    Each Dataset is the one :func:`hertzchain.simulate` (Verlet) returns for that model alone,
    with bit-identical arrays; only the ``created_utc`` attribute may differ.

    Parameters
    ----------
    models
        The members (any mix of chains, strikers, walls and contact laws).
    duration
        Simulated time [s] after impact, shared by all members.
    probes
        One :class:`Probes` for all members or one per member (default: every contact force and
        the energies every 100 ns). All members must share the sample interval [s].
    dt
        Verlet time step [s]: None (each member's automatic step), one value for all, or one per
        member (None entries are automatic).
    progress
        Called as ``progress(done, total)`` in samples between compiled calls.
    n_threads
        Threads of the parallel loop (default: Numba's, i.e. every core).
    configs
        Per-member input stored in each result's ``config`` attribute (as ``simulate(config=)``).

    Returns
    -------
    list of xarray.Dataset
        One result per member, in the order of ``models``.

    Warns
    -----
    ElasticLimitWarning
        For every member whose recorded contact forces pass the elastic limit.
    """
    from ..result import build_dataset

    plist, dts = _check_inputs(models, duration, probes, dt)
    cfgs = _as_list(configs, len(models), "configs") if configs is not None else [None] * len(models)
    runs, systems, _ = _run(models, duration, plist, dts, progress, n_threads)
    out = []
    for i, (raw, model, p, cfg, system) in enumerate(zip(runs, models, plist, cfgs, systems)):
        ds = build_dataset(raw, model, p, duration=duration, config=cfg, system=system)
        warn_elastic_limit(ds, f"member {i}: " if len(models) > 1 else "")
        out.append(ds)
    return out


#: The ``engine`` attribute of a batch computed on the CPU.
_ENGINE_CPU = "batched compiled velocity Verlet (numba prange), bit-identical to single runs"

#: Per-member scalar attributes of a single run that become variables along ``member``.
_MEMBER_ATTRS = {
    "dt": ("s", "Verlet time step of the member"),
    "n_steps": ("1", "number of Verlet steps"),
    "peak_wall_force": ("N", "peak wall force, refined between steps (NaN without a wall)"),
    "peak_wall_time": ("s", "time of the peak wall force (NaN without a wall)"),
    "elastic_limit_exceeded": ("1", "1 when a recorded contact force passed the elastic limit"),
}


@dataclass
class _Part:
    """One member as the stacker needs it, in plain NumPy (from a Dataset or from ``run_fields``).

    ``data``: data variables in Dataset order, ``(dims, values, attrs)``; ``dims``: every
    dimension but ``time`` in the Dataset's dimension order, ``(coordinate values, attrs)``;
    ``attrs``: the Dataset attributes.
    """

    data: dict[str, tuple[tuple[str, ...], np.ndarray, dict]]
    dims: dict[str, tuple[np.ndarray, dict]]
    attrs: dict


def _part_of_dataset(ds: xr.Dataset) -> _Part:
    """The :class:`_Part` of a single-run Dataset (a dimension without coordinate counts 0, 1, ...)."""
    data = {}
    for name in ds.data_vars:
        var = ds.variables[name]
        data[name] = (var.dims, var.values, var.attrs)
    dims = {}
    for d in ds.dims:
        if d != "time":
            var = ds.variables.get(d)
            dims[d] = (var.values, var.attrs) if var is not None else (np.arange(ds.sizes[d]), {})
    return _Part(data, dims, ds.attrs)


def _part_of_fields(f) -> _Part:
    """The :class:`_Part` of a :class:`hertzchain.result.RunFields`, dimensions in the order the
    Dataset of :func:`hertzchain.result.build_dataset` has them (first use by a data variable,
    then by a coordinate)."""
    dims = {}
    for dim_names in [v[0] for v in f.data.values()] + [(c[0],) for c in f.coords.values()]:
        for d in dim_names:
            if d != "time" and d not in dims:
                dims[d] = (f.coords[d][1], f.coords[d][2])
    return _Part(f.data, dims, f.attrs)


def _positions(union: np.ndarray, values: np.ndarray):
    """Where ``values`` sit in the sorted ``union``: a slice when they are one increasing run
    (cheap basic indexing), else the index array."""
    pos = np.searchsorted(union, values)
    if pos.size <= 1 or bool(np.all(np.diff(pos) == 1)):
        start = int(pos[0]) if pos.size else 0
        return slice(start, start + pos.size)
    return pos


def _stack(parts: Sequence[_Part], time, n_time: int, member, ready: dict[str, np.ndarray] | None = None
           ) -> xr.Dataset:
    """The stacked Dataset of :func:`stack_results` (see there) from members in plain NumPy.

    ``time`` is the shared time coordinate (a Variable or a ``(dim, values, attrs)`` tuple) of
    ``n_time`` samples. Members with equal coordinate arrays share the index work, so a batch
    of similar members costs one slice assignment per member and variable. ``ready`` may hold
    variables already in the stacked layout, row i being member i's array (the engine's output
    buffers): one is used as it is, not copied, when every member has the variable with exactly
    the stacked coordinates (so there is nothing to pad); otherwise it is ignored.
    """
    ready = ready or {}
    nmem = len(parts)
    # Union of every dimension's coordinates; identical arrays (the usual case) are merged once.
    distinct: dict[str, dict[tuple, np.ndarray]] = {}
    coord_attrs: dict[str, dict] = {}
    keys = []
    for p in parts:
        pk = {}
        for d, (vals, attrs) in p.dims.items():
            key = (vals.dtype.str, vals.shape, vals.tobytes())
            pk[d] = key
            distinct.setdefault(d, {}).setdefault(key, vals)
            coord_attrs.setdefault(d, dict(attrs))
        keys.append(pk)
    dims = {d: np.unique(np.concatenate([v.ravel() for v in arrays.values()]))
            for d, arrays in distinct.items()}
    where = {d: {key: _positions(dims[d], vals) for key, vals in arrays.items()} for d, arrays in distinct.items()}

    var_names: list[str] = []
    for p in parts:
        var_names += [k for k in p.data if k not in var_names]
    data = {}
    indexers: dict[tuple, tuple] = {}

    def indexer(i: int, var_dims: tuple[str, ...]) -> tuple:
        """Where member i's array of a variable with ``var_dims`` goes in the stacked one (minus member)."""
        ck = (var_dims,) + tuple(keys[i][d] for d in var_dims if d != "time")
        idx = indexers.get(ck)
        if idx is None:
            idx = tuple(slice(None) if d == "time" else where[d][keys[i][d]] for d in var_dims)
            if not all(isinstance(x, slice) for x in idx):
                idx = np.ix_(*(np.arange(n_time) if d == "time" else
                               (np.arange(dims[d].size)[x] if isinstance(x, slice) else x)
                               for d, x in zip(var_dims, idx)))
            indexers[ck] = idx
        return idx

    for name in var_names:
        first_dims, _, first_attrs = next(p.data[name] for p in parts if name in p.data)
        shape = (nmem,) + tuple(n_time if d == "time" else dims[d].size for d in first_dims)
        idxs = [indexer(i, first_dims) if name in p.data else None for i, p in enumerate(parts)]
        full = tuple(slice(None) if d == "time" else slice(0, dims[d].size) for d in first_dims)
        if (name in ready and ready[name].shape == shape
                and all(idx is not None and all(isinstance(x, slice) and x == f for x, f in zip(idx, full))
                        for idx in idxs)):
            out = ready[name]  # every member fills its whole row: nothing to pad, nothing to copy
        else:
            out = np.full(shape, np.nan)
            for i, (p, idx) in enumerate(zip(parts, idxs)):
                if idx is not None:
                    out[i][idx] = p.data[name][1]
        data[name] = xr.Variable(("member",) + tuple(first_dims), out, attrs=dict(first_attrs))

    has_wall = np.array(["wall_force" in p.data for p in parts])
    for key, (units, long_name) in _MEMBER_ATTRS.items():
        vals = np.array([p.attrs[key] for p in parts], dtype=float)
        if key.startswith("peak_wall"):
            vals = np.where(has_wall, vals, np.nan)  # the kernel tracks a kappa = 0 contact: 0 N, not a peak
        data[key] = xr.Variable(("member",), vals, attrs={"units": units, "long_name": long_name})
    n_beads = np.array([p.dims["bead"][0].size for p in parts], dtype=np.int64)
    data["n_beads"] = xr.Variable(("member",), n_beads, attrs={"units": "1", "long_name": "number of beads N"})
    data["n_contacts"] = xr.Variable(
        ("member",), n_beads + has_wall.astype(np.int64),
        attrs={"units": "1", "long_name": "number of real contacts (N + 1 with a wall, N without)"})
    data["has_wall"] = xr.Variable(("member",), has_wall.astype(np.int8),
                                   attrs={"units": "1", "long_name": "1 when the chain ends on a wall"})
    for key, long_name in (("model", "model description (JSON)"), ("config", "input of the member (JSON)")):
        data[key] = xr.Variable(("member",), np.array([p.attrs[key] for p in parts], dtype=object),
                                attrs={"long_name": long_name})

    coords = {"member": ("member", np.arange(nmem) if member is None else np.asarray(member, dtype=np.int64),
                         {"long_name": "member of the batch"}),
              "time": time}
    for d, vals in dims.items():
        coords[d] = (d, vals, coord_attrs[d])
    a0 = parts[0].attrs
    return xr.Dataset(data, coords=coords, attrs=_batch_attrs(a0, nmem))


def _batch_attrs(a0, nmem: int) -> dict:
    """Attributes of a stacked batch, from one member's (or the template's) attributes ``a0``."""
    return {
        "title": "hertzchain batch simulation",
        "hertzchain_version": a0["hertzchain_version"],
        "integrator": a0["integrator"],
        "engine": _ENGINE_CPU,
        "duration": a0["duration"],
        "sample_interval": a0["sample_interval"],
        "n_members": nmem,
        "created_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "conventions": a0["conventions"],
    }


def stack_results(datasets: Sequence[xr.Dataset], member: Sequence[int] | None = None) -> xr.Dataset:
    """Stack single-run Datasets (same time axis) along a new ``member`` dimension.

    Dimensions other than ``time`` (``contact``, ``bead``, ``sensor``, ``body``) become the sorted
    union of the members' coordinates; values a member lacks (a shorter chain, no wall) are NaN.
    ``n_beads``, ``n_contacts`` (real contacts: N + 1 with a wall, N without) and ``has_wall``
    say what is real. Per-member attributes (``dt``, ``n_steps``, ``peak_wall_force``,
    ``peak_wall_time``, ``elastic_limit_exceeded``, ``model``, ``config``) become variables along
    ``member``; the shared ones (duration, sample interval, version...) stay attributes.
    :func:`simulate_batch` builds the same Dataset straight from the engine's arrays.
    """
    if not datasets:
        raise ConfigError("datasets", "nothing to stack")
    time = datasets[0]["time"]
    for i, ds in enumerate(datasets):
        if ds.sizes["time"] != time.size or not np.array_equal(ds["time"].values, time.values):
            raise ConfigError(f"datasets[{i}]", "all members must share one time axis (duration and sample interval)")
    return _stack([_part_of_dataset(ds) for ds in datasets], time.variable, time.size, member)


def simulate_batch(models: Sequence[Model] | Ensemble, duration: float,
                   probes: Probes | Sequence[Probes] | None = None, *,
                   dt: float | Sequence[float | None] | None = None, progress: Callable[[int, int], None] | None = None,
                   n_threads: int | None = None, configs: Sequence[dict | None] | None = None,
                   device: str = "auto", steps_per_radian: float | None = None) -> xr.Dataset:
    """Simulate many independent chains in one parallel compiled call; results stacked along ``member``.

    Every member's arrays are bit-identical to :func:`hertzchain.simulate` run on it alone (see
    the module docstring for why; on the GPU they agree to ~1e-14 instead, see ``device``).
    Layout: the variables of a single run with a leading ``member`` dimension; ``contact`` /
    ``bead`` / ``sensor`` / ``body`` are the union over the members, NaN where a member has no
    such item (see :func:`stack_results`, which also lists the per-member variables ``dt``,
    ``n_steps``, ``peak_wall_force``, ``peak_wall_time``, ``n_beads``, ``n_contacts``,
    ``has_wall``, ``model``, ``config``). The Dataset is the one ``stack_results(simulate_many(...))``
    gives (but for ``created_utc``), built without a Dataset per member; variables are views of
    the engine's output buffers where the members share a layout (``contact_force`` and
    ``wall_force`` may then share one buffer).

    Members that share a layout (same number of beads, end and contact law kind) and one
    :class:`Probes` are set up with array code (``hertzchain.Ensemble``,
    ~microseconds per member instead of ~0.2 ms); pass an ``Ensemble`` directly to avoid building
    one :class:`Model` per member at all.

    Parameters
    ----------
    models
        The members: chains of any length, diameters, materials, offsets, contact law, wall; or
        an ``hertzchain.Ensemble`` (a base model plus per-member arrays).
    duration
        Simulated time [s] after impact, shared by all members.
    probes
        One :class:`Probes` or one per member; all must share ``sample_interval`` [s].
    dt
        Verlet step [s]: None (each member's own automatic step), one value, or one per member.
    progress
        ``progress(done, total)`` in samples, between compiled calls.
    n_threads
        Threads of the parallel loop (default: every core Numba sees).
    configs
        Per-member input stored in the ``config`` variable.
    device
        ``"cpu"`` (the compiled batched engine), ``"cuda"`` (the numba.cuda engine of
        ``hertzchain.integrate.cuda``: members must share a layout and one Probes; an error
        when no usable GPU is present) or ``"auto"`` (default: the GPU when one is usable and the
        batch has at least ``hertzchain.integrate.cuda.AUTO_MIN_MEMBERS`` members, else the CPU).
    steps_per_radian
        Accuracy of the adaptive step, as ``simulate(steps_per_radian=)`` (``run.steps_per_radian``):
        None for the default ``ADAPTIVE_STEPS_PER_RADIAN``; one value for every member.

    Returns
    -------
    xarray.Dataset
        The members' results stacked along the leading ``member`` dimension (SI units).

    Warns
    -----
    ElasticLimitWarning
        Once per member whose contact forces pass the elastic limit.
    PulseNotReachedWarning
        Once per batch, naming the members on a wall whose record ended before the pulse reached it.
    """
    from . import cuda as _cuda

    _cuda.check_device(device)
    ens = None
    if isinstance(models, Ensemble):
        ens = models
    elif isinstance(models, Sequence) and same_layout(models) and _one_probes(probes, len(models)) is not None:
        ens = Ensemble.from_models(models)
    if ens is not None:
        ds = _simulate_ensemble(ens, duration, _one_probes(probes, ens.n_members), dt, progress, n_threads,
                                configs, device, steps_per_radian)
    elif device == "cuda":
        _cuda.require_gpu()
        raise ConfigError("device", "the CUDA engine runs batches whose members share one layout (number of "
                          "beads, end, contact law kind) and one Probes; this batch mixes them: split it, or use "
                          "device='cpu'")
    else:
        ds = _simulate_models(models, duration, probes, dt, progress, n_threads, configs, steps_per_radian)
    warn_members_pulse_not_reached(ds)
    return ds


def _one_probes(probes, n: int) -> Probes | None:
    """The one Probes all ``n`` members use, or None when they differ."""
    if probes is None or isinstance(probes, Probes):
        return probes or Probes()
    plist = list(probes)
    if len(plist) != n or not all(isinstance(p, Probes) for p in plist):
        return None
    first = plist[0] or Probes()
    return first if all((p or Probes()) == first for p in plist) else None


def _simulate_ensemble(ens: Ensemble, duration: float, probes: Probes, dt, progress, n_threads, configs,
                       device: str, steps_per_radian: float | None = None) -> xr.Dataset:
    """:func:`simulate_batch` of an ensemble: set up, run and stacked with array code."""
    from . import cuda as _cuda

    _check_threads(n_threads)
    nmem = ens.n_members
    if not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration > 0):
        raise ConfigError("run.duration", f"must be a positive time in s, got {duration!r}")
    if probes.sample_interval > duration:
        raise ConfigError("run.sample_interval",
                          f"({probes.sample_interval:g} s) is longer than run.duration ({duration:g} s)")
    probes.validate(ens.n_beads, ens.has_wall)
    _check_no_positions([probes])
    cfgs = _as_list(configs, nmem, "configs") if configs is not None else None
    dts = _ensemble_dts(dt, nmem)
    interval = probes.sample_interval
    n_samples = int(math.floor(duration / interval + 1e-9)) + 1
    on_gpu = _cuda.use_gpu(device, nmem)  # before the set-up: 'cuda' without a GPU fails at once
    pk, arrays = _pack_ensemble(ens, probes, dts, interval, n_samples, steps_per_radian)
    if on_gpu:
        _cuda.run_packed(pk, progress)
    else:
        _engine(pk, progress, n_threads)
    # checks.check_after_run's Hertz range, for every member at once
    smaller = smaller_radii(ens.striker_diameter, ens.diameters)[:, :arrays.n_contacts]
    warn_members_hertz_range(pk.fmax.reshape(nmem, arrays.n_contacts), arrays.kappa, smaller, stacklevel=4)
    ds = _ensemble_dataset(ens, arrays, pk, probes, duration, cfgs)
    if ds is None:  # member 0's results hold a variable the array path does not know: stack member by member
        ds = _stack_members(_member_runs(pk), [ens.model(i) for i in range(nmem)], [probes] * nmem,
                            cfgs or [None] * nmem, duration, None)
    if on_gpu:
        ds.attrs["engine"] = _cuda.ENGINE
    return ds


def _dts_used(pk: _Packed) -> tuple[np.ndarray, np.ndarray]:
    """:func:`hertzchain.integrate.verlet._dt_used` of every member: smallest and largest step [s]."""
    adaptive = pk.stride == 0
    block = pk.interval / pk.n_sub
    with np.errstate(divide="ignore"):
        dt_min = np.where(adaptive & (pk.acc[:, 6] != 0), block / pk.acc[:, 6], pk.plan_dt)
        dt_max = np.where(adaptive & (pk.acc[:, 7] != 0), block / pk.acc[:, 7], pk.plan_dt)
    return dt_min, dt_max


def _member_runs(pk: _Packed) -> list[RawRun]:
    """Every member's :class:`RawRun`, views of the packed outputs."""
    time = np.arange(pk.n_samples) * pk.interval
    fpk, tpk = _refine_peaks(pk.peak)
    dt_min, dt_max = _dts_used(pk)
    per_member = zip(fpk.tolist(), tpk.tolist(), dt_min.tolist(), dt_max.tolist(), pk.acc[:, 2].tolist(),
                     (pk.stride == 0).tolist(), pk.record_v.tolist(), pk.rec_off.tolist(), pk.fmax_off.tolist())
    runs = []
    for m, (f_peak, t_peak, dt0, dt1, steps, adaptive, record_v, r0, c0) in enumerate(per_member):
        runs.append(RawRun(time=time.copy(), contact_force=_member_forces(pk, m), kinetic_energy=pk.out_ke[m],
                           potential_energy=pk.out_pe[m], dissipated_energy=pk.out_ed[m],
                           velocity=_member_velocities(pk, m) if record_v else None,
                           max_force=pk.fmax[c0:pk.fmax_off[m + 1]], peak_wall_force=f_peak, peak_wall_time=t_peak,
                           dt=dt0, integrator="verlet", n_steps=int(steps), contacts=pk.rec[r0:pk.rec_off[m + 1]],
                           dt_max=dt1, adaptive=adaptive))
    return runs


def _simulate_models(models, duration, probes, dt, progress, n_threads, configs,
                     steps_per_radian: float | None = None) -> xr.Dataset:
    """:func:`simulate_batch` of arbitrary models (members of different layouts or probes)."""
    # What stack_results(simulate_many(...)) gives, without one Dataset per member: every member's
    # run_fields (the arrays and attributes build_dataset would wrap) go straight into the stack.
    plist, dts = _check_inputs(models, duration, probes, dt)
    cfgs = _as_list(configs, len(models), "configs") if configs is not None else [None] * len(models)
    runs, sys_list, stacked = _run(models, duration, plist, dts, progress, n_threads, steps_per_radian)
    width = max(sy.n_contacts for sy in sys_list)
    fmax, kappa, smaller = (np.full((len(models), width), np.nan) for _ in range(3))
    for i, (run, model, sy) in enumerate(zip(runs, models, sys_list)):
        nc = sy.n_contacts
        fmax[i, :nc], kappa[i, :nc] = run.max_force[:nc], sy.kappa[:nc]
        smaller[i, :nc] = _smaller_radius(model)[:nc]
    warn_members_hertz_range(fmax, kappa, smaller, stacklevel=4)
    return _stack_members(runs, models, plist, cfgs, duration, sys_list, stacked)


def _stack_members(runs, models, plist, cfgs, duration, sys_list, stacked=None) -> xr.Dataset:
    """The stacked Dataset from every member's RawRun (run_fields per member, then :func:`_stack`)."""
    from ..result import run_fields

    parts, time = [], None
    sys_list = sys_list or [None] * len(models)
    for i, (raw, model, p, cfg, system) in enumerate(zip(runs, models, plist, cfgs, sys_list)):
        fields = run_fields(raw, model, p, duration=duration, config=cfg, system=system)
        if time is None:
            time = fields.coords["time"]  # every member has this time axis (shared duration and interval)
        part = _part_of_fields(fields)
        if part.attrs["elastic_limit_exceeded"]:
            # What warn_elastic_limit reads of a member's Dataset (building one per member costs ~0.2 ms).
            warn_elastic_limit(SimpleNamespace(attrs=part.attrs, max_contact_force=part.data["max_contact_force"][1],
                                               yield_force=part.data["yield_force"][1]),
                               f"member {i}: " if len(models) > 1 else "", stacklevel=4)
        parts.append(part)
    ready = _ready(stacked, runs[0], models[0], parts[0]) if stacked else None
    return _stack(parts, time, runs[0].time.size, None, ready=ready)


def _refine_peaks(peak: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`hertzchain.integrate.verlet.refine_peak` of every row of ``peak`` (same arithmetic)."""
    fpk, t_pk, fb, fa, h0, h1 = (peak[:, i] for i in (0, 1, 2, 3, 6, 7))
    ok = (t_pk > 0) & (peak[:, 4] == 0.0) & (h0 > 0) & (h1 > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        s01 = (fpk - fb) / h0
        s12 = (fa - fpk) / h1
        c = (s12 - s01) / (h0 + h1)
        ok &= c < 0.0
        b = s12 - c * h1
        return np.where(ok, fpk - 0.25 * b * b / c, fpk), np.where(ok, t_pk - 0.5 * b / c, t_pk)


#: Variables of a single run that :func:`_ensemble_dataset` knows how to stack.
_KNOWN = {"contact_force", "kinetic_energy", "potential_energy", "dissipated_energy", "diameter", "mass", "offset",
          "kappa", "yield_force", "max_contact_force", "wall_force", "sensor_force", "velocity"}


def _ensemble_dataset(ens: Ensemble, sy: _EnsembleArrays, pk: _Packed, probes: Probes, duration: float,
                      configs) -> xr.Dataset | None:
    """The stacked Dataset of :func:`simulate_batch` for an ensemble, straight from the buffers.

    Same variables, order, coordinates and attributes as :func:`_stack` of every member's
    :func:`hertzchain.result.run_fields` (member 0's is built as the template), with the values
    taken from the (member, ...) buffers by array code. None when member 0's fields hold a
    variable this function does not know (the caller then stacks member by member).
    """
    from ..result import run_fields

    nmem, n = ens.n_members, ens.n_beads
    ns, nc = pk.n_samples, sy.n_contacts
    interval = pk.interval
    fpk, tpk = _refine_peaks(pk.peak)
    adaptive = pk.stride == 0
    dt_min, dt_max = _dts_used(pk)
    rec = pk.rec[:pk.nrec[0]]
    forces = pk.out_f.reshape(nmem, ns, rec.size)
    velocity = pk.out_v.reshape(nmem, ns, n + 1) if probes.velocities else None
    fmax = pk.fmax.reshape(nmem, nc)
    time = np.arange(ns) * interval
    raw0 = RawRun(time=time, contact_force=forces[0], kinetic_energy=pk.out_ke[0], potential_energy=pk.out_pe[0],
                  dissipated_energy=pk.out_ed[0], velocity=None if velocity is None else velocity[0],
                  max_force=fmax[0], peak_wall_force=float(fpk[0]), peak_wall_time=float(tpk[0]), dt=float(dt_min[0]),
                  integrator="verlet", n_steps=int(pk.acc[0, 2]), contacts=rec, dt_max=float(dt_max[0]),
                  adaptive=bool(adaptive[0]))
    cfg0 = None if configs is None else configs[0]
    fields0 = run_fields(raw0, ens.model(0), probes, duration=duration, config=cfg0)
    template = _part_of_fields(fields0)
    if not set(template.data) <= _KNOWN:
        return None

    wanted = template.dims["contact"][0]
    cols = np.searchsorted(rec, wanted)
    if cols.size and np.array_equal(cols, np.arange(cols[0], cols[0] + cols.size)):
        cf = forces[:, :, cols[0]:cols[0] + cols.size]
    else:
        cf = forces[:, :, cols]
    values = {"contact_force": cf, "kinetic_energy": pk.out_ke, "potential_energy": pk.out_pe,
              "dissipated_energy": pk.out_ed, "diameter": np.array(ens.diameters, dtype=float),
              "mass": sy.bead_mass, "offset": np.array(ens.offsets, dtype=float), "kappa": sy.kappa,
              "yield_force": sy.yield_force, "max_contact_force": fmax}
    if ens.has_wall:
        values["wall_force"] = forces[:, :, int(np.searchsorted(rec, n))]
    sensors = np.unique(np.array(probes.sensors, dtype=np.int64))
    if sensors.size:
        index = {int(c): i for i, c in enumerate(rec)}
        sf = np.empty((nmem, ns, sensors.size))
        for k, s in enumerate(sensors.tolist()):  # probes.sensor_forces, F_s = (F_{n-1} + F_n) / 2
            left = forces[:, :, index[s - 1]]
            right = forces[:, :, index[s]] if s in index else 0.0
            sf[:, :, k] = 0.5 * (left + right)
        values["sensor_force"] = sf
    if velocity is not None:
        values["velocity"] = velocity

    data = {}
    for name, (dims, _, attrs) in template.data.items():
        data[name] = xr.Variable(("member",) + tuple(dims), values[name], attrs=dict(attrs))
    ratio = fmax / sy.yield_force
    over = ratio > 1.0
    exceeded = over.any(axis=1)
    member_vals = {"dt": dt_min, "n_steps": pk.acc[:, 2].copy(), "peak_wall_force": fpk, "peak_wall_time": tpk,
                   "elastic_limit_exceeded": exceeded.astype(float)}
    for key, (units, long_name) in _MEMBER_ATTRS.items():
        vals = member_vals[key]
        if key.startswith("peak_wall") and not ens.has_wall:
            vals = np.full(nmem, np.nan)
        data[key] = xr.Variable(("member",), vals, attrs={"units": units, "long_name": long_name})
    data["n_beads"] = xr.Variable(("member",), np.full(nmem, n, dtype=np.int64),
                                  attrs={"units": "1", "long_name": "number of beads N"})
    data["n_contacts"] = xr.Variable(("member",), np.full(nmem, nc, dtype=np.int64), attrs={
        "units": "1", "long_name": "number of real contacts (N + 1 with a wall, N without)"})
    data["has_wall"] = xr.Variable(("member",), np.full(nmem, int(ens.has_wall), dtype=np.int8),
                                   attrs={"units": "1", "long_name": "1 when the chain ends on a wall"})
    described = ens.describe()
    if configs is None:
        config_text = ['{"model": ' + d + "}" for d in described]  # json.dumps({"model": described})
    else:
        config_text = [json.dumps(c if c is not None else {"model": json.loads(d)}) for c, d in zip(configs, described)]
    data["model"] = xr.Variable(("member",), np.array(described, dtype=object),
                                attrs={"long_name": "model description (JSON)"})
    data["config"] = xr.Variable(("member",), np.array(config_text, dtype=object),
                                 attrs={"long_name": "input of the member (JSON)"})

    for i in np.flatnonzero(exceeded).tolist():
        attrs = {"elastic_limit_exceeded": 1, "elastic_limit_contacts": json.dumps(np.flatnonzero(over[i]).tolist()),
                 "elastic_limit_ratio": float(ratio[i].max())}
        warn_elastic_limit(SimpleNamespace(attrs=attrs, max_contact_force=fmax[i], yield_force=sy.yield_force[i]),
                           f"member {i}: " if nmem > 1 else "", stacklevel=4)

    coords = {"member": ("member", np.arange(nmem), {"long_name": "member of the batch"}),
              "time": fields0.coords["time"]}
    for d, (vals, attrs) in template.dims.items():
        coords[d] = (d, np.unique(vals), dict(attrs))
    a0 = template.attrs
    return xr.Dataset(data, coords=coords, attrs=_batch_attrs(a0, nmem))


def _ready(stacked: dict[str, np.ndarray], raw: RawRun, model: Model, part: _Part) -> dict[str, np.ndarray]:
    """The engine's buffers as the stacked variables of ``run_fields`` (row m = member m's array),
    assuming every member is laid out as member 0 (``raw``, ``model``, ``part``); :func:`_stack`
    uses one only where that holds. Views where possible, so a uniform batch copies nothing."""
    ready = {k: stacked[k] for k in ("kinetic_energy", "potential_energy", "dissipated_energy", "velocity")
             if k in stacked}
    forces = stacked.get("recorded_force")
    if forces is not None:
        # the columns run_fields takes from raw.contact_force (= forces[m])
        cols = np.searchsorted(raw.contacts, part.dims["contact"][0])
        if cols.size and np.array_equal(cols, np.arange(cols[0], cols[0] + cols.size)):
            ready["contact_force"] = forces[:, :, cols[0]:cols[0] + cols.size]
        else:
            ready["contact_force"] = forces[:, :, cols]
        if model.wall.present:
            ready["wall_force"] = forces[:, :, np.searchsorted(raw.contacts, model.chain.n_beads)]
    return ready
