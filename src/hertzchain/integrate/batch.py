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
``member`` dimension).
"""

from __future__ import annotations

import datetime as _dt
import math
import threading
from dataclasses import dataclass
from pathlib import Path
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
    if n_threads is not None and not (isinstance(n_threads, (int, np.integer))
                                      and 1 <= n_threads <= numba.config.NUMBA_NUM_THREADS):
        raise ConfigError("n_threads", f"must be an integer in 1..{numba.config.NUMBA_NUM_THREADS}, got {n_threads!r}")
    interval = plist[0].sample_interval
    nmem = len(models)
    n_samples = int(math.floor(duration / interval + 1e-9)) + 1

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
    return runs


def simulate_many(models: Sequence[Model], duration: float, probes: Probes | Sequence[Probes] | None = None, *,
                  dt: float | Sequence[float | None] | None = None, progress: Callable[[int, int], None] | None = None,
                  n_threads: int | None = None, configs: Sequence[dict | None] | None = None) -> list[xr.Dataset]:
    """Simulate every model in one batched compiled call; one Dataset per member.

    Each Dataset is the one :func:`hertzchain.simulate` (Verlet) returns for that model alone,
    with bit-identical arrays; only the ``created_utc`` attribute may differ.

    Parameters
    ----------
    models:
        The members (any mix of chains, strikers, walls and contact laws).
    duration:
        Simulated time [s] after impact, shared by all members.
    probes:
        One :class:`Probes` for all members or one per member (default: every contact force and
        the energies every 100 ns). All members must share the sample interval [s].
    dt:
        Verlet time step [s]: None (each member's automatic step), one value for all, or one per
        member (None entries are automatic).
    progress:
        Called as ``progress(done, total)`` in samples between compiled calls.
    n_threads:
        Threads of the parallel loop (default: Numba's, i.e. every core).
    configs:
        Per-member input stored in each result's ``config`` attribute (as ``simulate(config=)``).

    Warns
    -----
    ElasticLimitWarning
        For every member whose recorded contact forces pass the elastic limit.
    """
    from ..result import build_dataset

    plist, _ = _check_inputs(models, duration, probes, dt)
    cfgs = _as_list(configs, len(models), "configs") if configs is not None else [None] * len(models)
    runs = run_batch(models, duration, plist, dt=dt, progress=progress, n_threads=n_threads)
    out = []
    for i, (raw, model, p, cfg) in enumerate(zip(runs, models, plist, cfgs)):
        ds = build_dataset(raw, model, p, duration=duration, config=cfg)
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


def stack_results(datasets: Sequence[xr.Dataset], member: Sequence[int] | None = None) -> xr.Dataset:
    """Stack single-run Datasets (same time axis) along a new ``member`` dimension.

    Dimensions other than ``time`` (``contact``, ``bead``, ``sensor``, ``body``) become the sorted
    union of the members' coordinates; values a member lacks (a shorter chain, no wall) are NaN.
    ``n_beads``, ``n_contacts`` (real contacts: N + 1 with a wall, N without) and ``has_wall``
    say what is real. Per-member attributes (``dt``, ``n_steps``, ``peak_wall_force``,
    ``peak_wall_time``, ``elastic_limit_exceeded``, ``model``, ``config``) become variables along
    ``member``; the shared ones (duration, sample interval, version...) stay attributes.
    """
    if not datasets:
        raise ConfigError("datasets", "nothing to stack")
    nmem = len(datasets)
    time = datasets[0]["time"]
    for i, ds in enumerate(datasets):
        if ds.sizes["time"] != time.size or not np.array_equal(ds["time"].values, time.values):
            raise ConfigError(f"datasets[{i}]", "all members must share one time axis (duration and sample interval)")
    dims: dict[str, np.ndarray] = {}
    coord_attrs: dict[str, dict] = {}
    for ds in datasets:
        for d in ds.dims:
            if d == "time":
                continue
            vals = ds[d].values
            dims[d] = np.union1d(dims[d], vals) if d in dims else np.unique(vals)
            coord_attrs.setdefault(d, dict(ds[d].attrs))
    var_names: list[str] = []
    for ds in datasets:
        var_names += [k for k in ds.data_vars if k not in var_names]

    data = {}
    for name in var_names:
        first = next(ds[name] for ds in datasets if name in ds)
        shape = (nmem,) + tuple(time.size if d == "time" else dims[d].size for d in first.dims)
        out = np.full(shape, np.nan)
        for i, ds in enumerate(datasets):
            if name not in ds:
                continue
            idx = tuple(np.arange(time.size) if d == "time" else np.searchsorted(dims[d], ds[d].values)
                        for d in first.dims)
            out[i][np.ix_(*idx)] = ds[name].values
        data[name] = xr.Variable(("member",) + first.dims, out, attrs=dict(first.attrs))

    has_wall = np.array(["wall_force" in ds for ds in datasets])
    for key, (units, long_name) in _MEMBER_ATTRS.items():
        vals = np.array([ds.attrs[key] for ds in datasets], dtype=float)
        if key.startswith("peak_wall"):
            vals = np.where(has_wall, vals, np.nan)  # the kernel tracks a kappa = 0 contact: 0 N, not a peak
        data[key] = xr.Variable(("member",), vals, attrs={"units": units, "long_name": long_name})
    data["n_beads"] = xr.Variable(("member",), np.array([ds.sizes["bead"] for ds in datasets], dtype=np.int64),
                                  attrs={"units": "1", "long_name": "number of beads N"})
    data["n_contacts"] = xr.Variable(
        ("member",), np.array([ds.sizes["bead"] + int(w) for ds, w in zip(datasets, has_wall)], dtype=np.int64),
        attrs={"units": "1", "long_name": "number of real contacts (N + 1 with a wall, N without)"})
    data["has_wall"] = xr.Variable(("member",), has_wall.astype(np.int8),
                                   attrs={"units": "1", "long_name": "1 when the chain ends on a wall"})
    for key, long_name in (("model", "model description (JSON)"), ("config", "input of the member (JSON)")):
        data[key] = xr.Variable(("member",), np.array([ds.attrs[key] for ds in datasets], dtype=object),
                                attrs={"long_name": long_name})

    coords = {"member": ("member", np.arange(nmem) if member is None else np.asarray(member, dtype=np.int64),
                         {"long_name": "member of the batch"}),
              "time": time.variable}
    for d, vals in dims.items():
        coords[d] = (d, vals, coord_attrs[d])
    a0 = datasets[0].attrs
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


def simulate_batch(models: Sequence[Model], duration: float, probes: Probes | Sequence[Probes] | None = None, *,
                   dt: float | Sequence[float | None] | None = None, progress: Callable[[int, int], None] | None = None,
                   n_threads: int | None = None, configs: Sequence[dict | None] | None = None) -> xr.Dataset:
    """Simulate many independent chains in one parallel compiled call; results stacked along ``member``.

    Every member's arrays are bit-identical to :func:`hertzchain.simulate` run on it alone (see
    the module docstring for why). Layout: the variables of a single run with a leading
    ``member`` dimension; ``contact`` / ``bead`` / ``sensor`` / ``body`` are the union over the
    members, NaN where a member has no such item (see :func:`stack_results`, which also lists the
    per-member variables ``dt``, ``n_steps``, ``peak_wall_force``, ``peak_wall_time``,
    ``n_beads``, ``n_contacts``, ``has_wall``, ``model``, ``config``).

    Parameters
    ----------
    models:
        The members: chains of any length, diameters, materials, offsets, contact law, wall.
    duration:
        Simulated time [s] after impact, shared by all members.
    probes:
        One :class:`Probes` or one per member; all must share ``sample_interval`` [s].
    dt:
        Verlet step [s]: None (each member's own automatic step), one value, or one per member.
    progress:
        ``progress(done, total)`` in samples, between compiled calls.
    n_threads:
        Threads of the parallel loop (default: every core Numba sees).
    configs:
        Per-member input stored in the ``config`` variable.

    Warns
    -----
    ElasticLimitWarning
        Once per member whose contact forces pass the elastic limit.
    """
    return stack_results(simulate_many(models, duration, probes, dt=dt, progress=progress, n_threads=n_threads,
                                       configs=configs))
