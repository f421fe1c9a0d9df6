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

Public entry points: :func:`simulate_many` (a list of single-run Datasets, identical to
:func:`~hertzchain.simulation.simulate`'s) and :func:`simulate_batch` (one Dataset stacked along a
``member`` dimension, identical to :func:`stack_results` of :func:`simulate_many`'s but built
straight from the engine's arrays: no Dataset per member, and the output buffers that already
have the stacked layout, such as the (member, time) energies, are used without a copy).
"""

from __future__ import annotations

import datetime as _dt
import math
import threading
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import Callable, Sequence

import numba
import numpy as np
import xarray as xr
from numba import njit, prange

from ..errors import ConfigError, SimulationDiverged
from ..model import Model
from ..probes import Probes
from ..simulation import warn_elastic_limit
from . import kernels
from .layout import pack
from .verlet import RawRun, StepPlan, _dt_used, initialise, refine_peak, step_plan

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

    Member m owns the slots ``off[m]:off[m + 1]`` of the body/contact buffers (``P + 1`` slots,
    ``P = n_slots[m]``, rounded up to whole cache lines): the ``P``-sized arrays (mass, kappa, ...)
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


def _flush_stale_cache() -> None:
    """Drop the on-disk cache of :func:`_batch_kernel` when ``kernels.py`` is newer than it.

    Numba's cache only checks the source file of the cached function itself, not of the
    functions it calls; :func:`_batch_kernel` compiles ``kernels.verlet_run`` into itself, so an
    edit of ``kernels.py`` would otherwise leave the batched engine running the old kernel.
    """
    try:
        index = Path(_batch_kernel._cache._cache_file._index_path)
        if index.exists() and index.stat().st_mtime < Path(kernels.__file__).stat().st_mtime:
            _batch_kernel._cache.flush()
    except (AttributeError, OSError):  # private Numba API moved or no cache: nothing to protect
        pass


_flush_stale_cache()


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
              n_threads: int | None = None) -> list[RawRun]:
    """Integrate every model with the batched compiled Verlet; one :class:`RawRun` per member.

    Parameters are those of :func:`simulate_batch`. The RawRuns are identical to what
    :func:`hertzchain.integrate.verlet.run_verlet` returns for each member alone.
    """
    plist, dts = _check_inputs(models, duration, probes, dt)
    return _run(models, duration, plist, dts, progress, n_threads)[0]


def _run(models: Sequence[Model], duration: float, plist: list[Probes], dts: list, progress, n_threads
         ) -> tuple[list[RawRun], list, dict[str, np.ndarray]]:
    """:func:`run_batch` on checked inputs. Also returns every member's ``Model.system()`` and the
    output buffers that are already stacked along ``member`` (row m is RawRun m's array): the
    energies always, ``recorded_force`` (member, time, recorded contact) when every member
    records the same contacts, ``velocity`` when every member records velocities of as many bodies."""
    if n_threads is not None and not (isinstance(n_threads, (int, np.integer))
                                      and 1 <= n_threads <= numba.config.NUMBA_NUM_THREADS):
        raise ConfigError("n_threads", f"must be an integer in 1..{numba.config.NUMBA_NUM_THREADS}, got {n_threads!r}")
    interval = plist[0].sample_interval
    nmem = len(models)
    n_samples = int(math.floor(duration / interval + 1e-9)) + 1

    if any(p.positions for p in plist):
        raise ConfigError("probes.positions", "batches and sweeps do not record positions; simulate the run "
                          "to animate alone (hertzchain run, hertzchain.simulate)")
    members: list[_Member] = []
    for model, p, dti in zip(models, plist, dts):
        system = model.system()
        plan = step_plan(system, interval, dti)
        rec = p.recorded_contacts(model.chain.n_beads, model.wall.present)
        members.append(_Member(system, rec, plan, bool(p.velocities)))

    # ---- ragged layout: member m owns off[m]:off[m+1] (P + 1 slots) of every body/contact buffer
    packs = [pack(mb.system) for mb in members]
    # P + 1 slots rounded up to whole 64-byte cache lines, on an aligned buffer: two threads
    # never write to one cache line (false sharing would cost a line transfer per step).
    sizes = np.array([-(-(w.n_slots + 1) // _LINE) * _LINE for w in packs], dtype=np.int64)
    off = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    n_slots = np.array([w.n_slots for w in packs], dtype=np.int64)
    total = int(off[-1])
    names = ("mass", "inv_mass", "kappa", "damping", "d0", "de", "dx0", "rsum", "fext", "dcap")
    flat = {k: _aligned_zeros(total) for k in names + ("u", "v", "g", "a")}
    for m, w in enumerate(packs):
        s, p = off[m], w.n_slots
        for k in names:
            flat[k][s:s + p] = getattr(w, k)
        flat["u"][s:s + p + 1] = w.u
        flat["v"][s:s + p + 1] = w.v

    nrec = np.array([mb.rec.size for mb in members], dtype=np.int64)
    rec_off = np.concatenate([[0], np.cumsum(nrec)]).astype(np.int64)
    rec = np.concatenate([mb.rec for mb in members]).astype(np.int64) if rec_off[-1] else np.zeros(0, np.int64)
    f_off = np.concatenate([[0], np.cumsum(nrec * n_samples)]).astype(np.int64)
    out_f = np.empty(int(f_off[-1]))
    out_ke = np.empty((nmem, n_samples))
    out_pe = np.empty((nmem, n_samples))
    out_ed = np.empty((nmem, n_samples))
    nb = np.array([mb.system.n_beads + 1 for mb in members], dtype=np.int64)
    v_rows = np.array([n_samples if mb.record_v else 1 for mb in members], dtype=np.int64)
    v_off = np.concatenate([[0], np.cumsum(v_rows * nb)]).astype(np.int64)
    out_v = np.empty(int(v_off[-1]))
    n_contacts = np.array([mb.system.n_contacts for mb in members], dtype=np.int64)
    fmax_off = np.concatenate([[0], np.cumsum(n_contacts)]).astype(np.int64)
    fmax = np.zeros(int(fmax_off[-1]))
    # Written every step: one cache line (8 doubles) per member (see ``sizes``).
    peak = _aligned_zeros(nmem * _LINE).reshape(nmem, _LINE)
    acc = _aligned_zeros(nmem * _LINE).reshape(nmem, _LINE)

    # ---- initial state: the very function run_verlet uses, on per-member views
    views = []
    for m, (mb, w) in enumerate(zip(members, packs)):
        s, p = off[m], w.n_slots
        u, v, g, a = (flat["u"][s:s + p + 1], flat["v"][s:s + p + 1], flat["g"][s:s + p + 1], flat["a"][s:s + p])
        f = out_f[f_off[m]:f_off[m + 1]].reshape(n_samples, nrec[m])
        vv = out_v[v_off[m]:v_off[m + 1]].reshape(v_rows[m], nb[m])
        initialise(mb.system, w, u, v, g, a, mb.rec, f, out_ke[m], out_pe[m], out_ed[m], vv, mb.record_v,
                   fmax[fmax_off[m]:fmax_off[m + 1]], peak[m], acc[m])
        views.append((f, vv))

    law = np.array([mb.system.law for mb in members], dtype=np.int64)
    general = np.array([mb.system.general for mb in members], dtype=np.bool_)
    wall_slot = np.array([w.wall_slot for w in packs], dtype=np.int64)
    stride = np.array([mb.plan.stride for mb in members], dtype=np.int64)
    n_sub = np.array([mb.plan.n_sub for mb in members], dtype=np.int64)
    n_eval = np.array([mb.plan.n_eval for mb in members], dtype=np.int64)
    c_steps = np.array([mb.plan.c_steps for mb in members], dtype=np.float64)
    relax = np.array([mb.plan.relax for mb in members], dtype=np.int64)
    steps_per_sample = np.array([interval / mb.plan.dt for mb in members])
    record_v = np.array([mb.record_v for mb in members], dtype=np.bool_)
    status = np.zeros(nmem, dtype=np.int64)
    # Cost of one sample per member (the general force loop is roughly twice the elastic one):
    # the most expensive members go first so that the threads finish together.
    cost = steps_per_sample * (n_slots + 1) * np.where(general, 2, 1)
    order = np.argsort(-cost, kind="stable").astype(np.int64)
    samples_per_call = max(1, int(CHUNK_SLOT_STEPS * max(1, n_threads or numba.get_num_threads()) // cost.sum()))

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
                    _batch_kernel(order, off, n_slots, flat["u"], flat["v"], flat["a"], flat["g"], flat["mass"],
                                  flat["inv_mass"], flat["kappa"], flat["damping"], flat["d0"], flat["de"],
                                  flat["dx0"], flat["rsum"], flat["fext"], flat["dcap"], law, general, wall_slot,
                                  interval, stride, n_sub, n_eval, c_steps, relax, k, k_stop, rec, rec_off, out_f, f_off, out_ke, out_pe, out_ed, out_v, v_off, v_rows,
                                  nb, record_v, fmax, fmax_off, peak, acc, status)
            finally:
                numba.set_num_threads(previous)
        bad = np.flatnonzero(status)
        if bad.size:
            raise SimulationDiverged(
                f"the integration of member(s) {bad.tolist()[:10]} diverged (non-finite state) before "
                f"t = {k_stop * interval:.4g} s; use a smaller run.dt (or the automatic one) or check their inputs")
        k = k_stop
        if progress is not None:
            progress(k - 1, n_samples - 1)

    time = np.arange(n_samples) * interval
    runs = []
    for m, mb in enumerate(members):
        f, vv = views[m]
        fpk, t_pk = refine_peak(peak[m])
        dt_min, dt_max = _dt_used(mb.plan, acc[m], interval)
        runs.append(RawRun(time=time.copy(), contact_force=f, kinetic_energy=out_ke[m], potential_energy=out_pe[m],
                           dissipated_energy=out_ed[m], velocity=vv if mb.record_v else None,
                           max_force=fmax[fmax_off[m]:fmax_off[m + 1]], peak_wall_force=fpk, peak_wall_time=t_pk,
                           dt=dt_min, integrator="verlet", n_steps=int(acc[m, 2]), contacts=mb.rec, dt_max=dt_max,
                           adaptive=mb.plan.adaptive))
    # The output buffers seen as (member, time, ...) where every member has the same layout: row m
    # is exactly what RawRun m holds (its arrays are views of these rows).
    stacked = {"kinetic_energy": out_ke, "potential_energy": out_pe, "dissipated_energy": out_ed}
    if all(np.array_equal(mb.rec, members[0].rec) for mb in members):
        stacked["recorded_force"] = out_f.reshape(nmem, n_samples, nrec[0])
    if record_v.all() and np.all(nb == nb[0]):
        stacked["velocity"] = out_v.reshape(nmem, n_samples, nb[0])
    return runs, [mb.system for mb in members], stacked


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
    attrs = {
        "title": "hertzchain batch simulation",
        "hertzchain_version": a0["hertzchain_version"],
        "integrator": a0["integrator"],
        "engine": "batched compiled velocity Verlet (numba prange), bit-identical to single runs",
        "duration": a0["duration"],
        "sample_interval": a0["sample_interval"],
        "n_members": nmem,
        "created_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "conventions": a0["conventions"],
    }
    return xr.Dataset(data, coords=coords, attrs=attrs)


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


def simulate_batch(models: Sequence[Model], duration: float, probes: Probes | Sequence[Probes] | None = None, *,
                   dt: float | Sequence[float | None] | None = None, progress: Callable[[int, int], None] | None = None,
                   n_threads: int | None = None, configs: Sequence[dict | None] | None = None) -> xr.Dataset:
    """Simulate many independent chains in one parallel compiled call; results stacked along ``member``.

    Every member's arrays are bit-identical to :func:`hertzchain.simulate` run on it alone (see
    the module docstring for why). Layout: the variables of a single run with a leading
    ``member`` dimension; ``contact`` / ``bead`` / ``sensor`` / ``body`` are the union over the
    members, NaN where a member has no such item (see :func:`stack_results`, which also lists the
    per-member variables ``dt``, ``n_steps``, ``peak_wall_force``, ``peak_wall_time``,
    ``n_beads``, ``n_contacts``, ``has_wall``, ``model``, ``config``). The Dataset is the one
    ``stack_results(simulate_many(...))`` gives (but for ``created_utc``), built without a
    Dataset per member; where the members share a layout, variables are views of the engine's
    output buffers (``contact_force`` and ``wall_force`` may then share one buffer).

    Parameters
    ----------
    models
        The members: chains of any length, diameters, materials, offsets, contact law, wall.
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

    Returns
    -------
    xarray.Dataset
        The members' results stacked along the leading ``member`` dimension (SI units).

    Warns
    -----
    ElasticLimitWarning
        Once per member whose contact forces pass the elastic limit.
    """
    from ..result import run_fields

    # What stack_results(simulate_many(...)) gives, without one Dataset per member: every member's
    # run_fields (the arrays and attributes build_dataset would wrap) go straight into the stack.
    plist, dts = _check_inputs(models, duration, probes, dt)
    cfgs = _as_list(configs, len(models), "configs") if configs is not None else [None] * len(models)
    runs, systems, stacked = _run(models, duration, plist, dts, progress, n_threads)
    parts, time = [], None
    for i, (raw, model, p, cfg, system) in enumerate(zip(runs, models, plist, cfgs, systems)):
        fields = run_fields(raw, model, p, duration=duration, config=cfg, system=system)
        if time is None:
            time = fields.coords["time"]  # every member has this time axis (shared duration and interval)
        part = _part_of_fields(fields)
        if part.attrs["elastic_limit_exceeded"]:
            # What warn_elastic_limit reads of a member's Dataset (building one per member costs ~0.2 ms).
            warn_elastic_limit(SimpleNamespace(attrs=part.attrs, max_contact_force=part.data["max_contact_force"][1],
                                               yield_force=part.data["yield_force"][1]),
                               f"member {i}: " if len(models) > 1 else "")
        parts.append(part)
    return _stack(parts, time, runs[0].time.size, None, ready=_ready(stacked, runs[0], models[0], parts[0]))


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
