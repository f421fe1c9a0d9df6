"""Running a sweep: :func:`run_sweep` validates it, then computes the chunks not yet on disk
(:func:`compute_chunk`, here or mapped over a Dask client or an executor) and writes each one as
it comes back; the metrics table is collected at the end.
"""

from __future__ import annotations

import importlib.util
import json
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np

from ..errors import ConfigError, SimulationDiverged
from .schema import SweepConfig, _member_ensemble, load_sweep, parse_sweep
from .storage import (_CHUNK_NAME, _METRIC_UNITS, METRIC_COLUMNS, PLASTIC_METRICS, _chunk_is_done, _folder_lock,
                      _metrics_table, _prepare_out_dir, _write_chunk)

# ------------------------------------------------------------------------------ computing chunks
@dataclass
class _ChunkTask:
    """Everything a worker needs for one chunk (picklable; no file access on the worker)."""

    index: int
    members: list[int]
    models: Any  # the members: a list of Models, or an Ensemble (array set-up) when they share a layout
    params: list[dict]
    duration: float
    probes: Any
    dt: float | None
    n_threads: int | None
    sweep_hash: str
    device: str = "auto"
    steps_per_radian: float | None = None


def _wall_metrics(time: np.ndarray, force: np.ndarray) -> dict[str, float]:
    """Wall-pulse metrics F_m [N], T [s], tau [s], Q_F [N s], Q_T [N s] by :func:`hertzchain.analysis.fit_pulse`.

    Raises :class:`hertzchain.errors.PulseNotFound` when the record holds no pulse.
    """
    from ..analysis import fit_pulse

    fit = fit_pulse(time, force)
    return {col: float(getattr(fit, attr)) for col, attr in METRIC_COLUMNS.items()}


def compute_chunk(task: _ChunkTask):
    """Simulate one chunk with the batched engine and fit the wall pulses; returns its Dataset.

    Runs wherever it is sent (locally, a Dask worker): it only needs the task. Elastic-limit
    warnings are not raised per member (a sweep would print thousands); the
    ``elastic_limit_exceeded`` variable and the metrics table carry them.
    """
    import xarray as xr

    from ..errors import ElasticLimitWarning, PulseNotFound, PulseNotReachedWarning
    from ..integrate.batch import simulate_batch

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ElasticLimitWarning)
        warnings.simplefilter("ignore", PulseNotReachedWarning)  # fit_error says "no pulse" per member
        ds = simulate_batch(task.models, task.duration, task.probes, dt=task.dt, n_threads=task.n_threads,
                            configs=None, device=task.device, steps_per_radian=task.steps_per_radian)
    ds = ds.assign_coords(member=("member", np.asarray(task.members, dtype=np.int64), ds["member"].attrs))
    _check_members_energy(ds, task)
    values = {k: np.full(len(task.members), np.nan) for k in METRIC_COLUMNS}
    errors = [""] * len(task.members)
    time = ds["time"].values
    for i in range(len(task.members)):
        if not ds["has_wall"].values[i]:
            errors[i] = "no wall: no wall pulse"
            continue
        try:
            m = _wall_metrics(time, ds["wall_force"].values[i])
        except PulseNotFound as exc:
            errors[i] = f"no pulse: {exc}"
            continue
        for k in METRIC_COLUMNS:
            values[k][i] = m[k]
    for k, (units, long_name) in _METRIC_UNITS.items():
        ds[k] = xr.Variable(("member",), values[k], attrs={"units": units, "long_name": long_name})
    if "plastic_work" in ds:  # an elastoplastic member: its plastic work and largest permanent overlap
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN rows of the other members
            plastic = {"plastic_work": ds["plastic_work"].values[:, -1],
                       "residual_overlap_max": np.nanmax(ds["residual_overlap"].values, axis=1)}
        for k, (var, units, long_name) in PLASTIC_METRICS.items():
            ds[var] = xr.Variable(("member",), plastic[k], attrs={"units": units, "long_name": long_name})
    ds["fit_error"] = xr.Variable(("member",), np.array(errors, dtype=object),
                                  attrs={"long_name": "why the wall pulse has no metrics (empty when fitted)"})
    ds["parameters"] = xr.Variable(("member",), np.array([json.dumps(p) for p in task.params], dtype=object),
                                   attrs={"long_name": "swept parameter values of the member (JSON)"})
    ds.attrs.update(sweep_hash=task.sweep_hash, chunk=task.index, title="hertzchain sweep chunk")
    # A chunk is a function of the sweep and its index: no creation time (sweep.json has the
    # sweep's), so that a recomputed chunk has the same bytes and checksum as the first one.
    ds.attrs.pop("created_utc", None)
    return ds


def _check_members_energy(ds, task: _ChunkTask) -> None:
    """The energy balance of every member (hertzchain.checks), which the batched engine does not
    check itself: a member that gains energy stops the sweep, naming the member and the cause."""
    from ..checks import check_energy_balance, energy_cause, energy_tolerance

    time = ds["time"].values
    ke, pe, ed = (ds[v].values for v in ("kinetic_energy", "potential_energy", "dissipated_energy"))
    if "plastic_work" in ds:  # every loss counts: viscous and plastic (NaN rows: other laws)
        ed = ed + np.nan_to_num(ds["plastic_work"].values)
    for i, model in enumerate(task.models):
        dt = task.dt[i] if isinstance(task.dt, list) else task.dt
        # the adaptive step's largest step is not stored per member: the minimum allowance then
        tol = energy_tolerance(model.system(), dt) if dt is not None else energy_tolerance(model.system(), 0.0)
        try:
            check_energy_balance(time, ke[i], pe[i], ed[i], tolerance=tol, cause=energy_cause(model, dt))
        except SimulationDiverged as exc:
            raise SimulationDiverged(f"sweep member {task.members[i]} ({task.params[i]}): {exc}") from None



def _results(client, fn: Callable, tasks: list) -> Iterator:
    """Yield ``fn(task)`` for every task, each as soon as it is available.

    ``client``: None (here, in order), a Dask ``distributed.Client`` (``submit`` +
    ``as_completed``), a ``concurrent.futures.Executor``, anything with ``submit`` and ``gather``,
    or anything with ``map`` (results taken as the iterator yields them).
    """
    if client is None:
        for t in tasks:
            yield fn(t)
        return
    try:
        import distributed
    except ImportError:  # pragma: no cover - a dependency, but keep the generic paths usable
        distributed = None
    import concurrent.futures as cf

    if distributed is not None and isinstance(client, distributed.Client):
        futures = [client.submit(fn, t, pure=False) for t in tasks]
        try:
            for fut in distributed.as_completed(futures):
                yield fut.result()
                fut.release()
        finally:  # stopped early (error, kill): do not leave work running on the cluster
            client.cancel([f for f in futures if not f.done()])
    elif isinstance(client, cf.Executor):
        futures = [client.submit(fn, t) for t in tasks]
        try:
            for fut in cf.as_completed(futures):
                yield fut.result()
        finally:
            for f in futures:
                f.cancel()
    elif hasattr(client, "submit") and hasattr(client, "gather"):
        futures = [client.submit(fn, t) for t in tasks]
        for fut in futures:
            yield client.gather(fut)
    elif hasattr(client, "map"):
        yield from client.map(fn, tasks)
    else:
        raise ConfigError("client", f"must have submit/gather or map (a Dask client, an executor), "
                          f"got {type(client).__name__}")


@dataclass
class SweepResult:
    """What :func:`run_sweep` did.

    Attributes
    ----------
    metrics:
        One row per member (pandas DataFrame, see :func:`run_sweep`).
    out_dir:
        The output folder.
    computed, skipped:
        Indices of the chunks computed by this call and of those found finished on disk.
    """

    metrics: Any
    out_dir: Path
    computed: list[int]
    skipped: list[int]

    @property
    def metrics_path(self) -> Path:
        return self.out_dir / "metrics.csv"



def run_sweep(sweep_cfg: SweepConfig | dict | str | Path, out_dir: str | Path, *, client=None,
              progress: Callable[[int, int], None] | None = None, force: bool = False,
              device: str = "auto") -> SweepResult:
    """Run (or resume) a sweep; every finished chunk is on disk at once.

    Parameters
    ----------
    sweep_cfg
        A :class:`SweepConfig`, a sweep mapping, or the path of a TOML sweep file.
    out_dir
        Output folder (see the module docstring for its content).
    client
        None: chunks are computed here, one after the other, each across all cores. A Dask
        ``distributed.Client``, a ``concurrent.futures.Executor``, anything with ``submit`` +
        ``gather`` or with ``map``: chunks are sent to it and written here as they come back (the
        workers need no access to ``out_dir``).
    progress
        Called as ``progress(done_members, total_members)`` after each chunk file is written
        (and once at the start with the members found finished on disk).
    force
        Replace the results of a different sweep found in ``out_dir`` instead of refusing.
    device:
        Where the chunks run: ``"cpu"``, ``"cuda"`` (the GPU engine; an error without a usable
        GPU) or ``"auto"`` (the GPU for chunks large enough to gain, when one is usable); see
        :func:`hertzchain.simulate_batch`.

    Returns
    -------
    SweepResult
        With ``metrics``: one row per member: ``member``, ``chunk``, one column per swept
        parameter (named by its path), ``dt`` [s], ``peak_wall_force`` [N] and ``peak_wall_time``
        [s] (integrator), ``elastic_limit_exceeded``, the wall-pulse metrics ``F_m`` [N], ``T``
        [s], ``tau`` [s], ``Q_F`` [N s], ``Q_T`` [N s] (NaN with ``fit_error`` saying why when the
        member has no wall or no fitted pulse); with protected bodies also ``peak_body_force`` [N],
        ``peak_body_acceleration`` [m/s^2] and ``peak_body_energy`` [J]; with an elastoplastic
        member also ``plastic_work`` [J] and ``residual_overlap_max`` [m] (NaN for members of other
        laws). Also written to ``metrics.csv`` (and ``metrics.parquet`` when pyarrow is installed).

    Raises
    ------
    ConfigError
        Invalid sweep (naming the field), or a chunk that cannot fit in memory
        (``sweep.chunk_size``); nothing is written then.
    SweepMismatch
        ``out_dir`` holds another sweep.
    SweepLocked
        Another sweep is writing into ``out_dir``.
    """
    from ..config import build_probes, parse_config
    from ..probes import Probes

    if isinstance(sweep_cfg, (str, Path)):
        cfg = load_sweep(sweep_cfg)
    elif isinstance(sweep_cfg, dict):
        cfg = parse_sweep(sweep_cfg)
    else:
        cfg = sweep_cfg
    out = Path(out_dir)
    from ..integrate.cuda import check_device

    check_device(device)
    # Everything is validated (every member's model, the memory a chunk needs) before anything is
    # written: an invalid sweep leaves no sweep.json behind to block the corrected one. Members
    # that share a layout are built as one array ensemble (microseconds per member), others as
    # one Model each.
    ensemble, member_dts = _member_ensemble(cfg)
    models = ensemble if ensemble is not None else cfg.models()
    run_cfg = parse_config(cfg.base)
    base_probes = build_probes(run_cfg)
    if cfg.sweep.store == "wall":
        # The wall force (always recorded with contacts=()), the sensors and the energies only:
        # every contact of every member would be ~N times larger and the metrics do not need it.
        probes: Any = Probes(sample_interval=base_probes.sample_interval, sensors=base_probes.sensors, contacts=())
    else:
        probes = base_probes
    duration = run_cfg.run.duration
    if duration == "auto":
        from ..simulation import auto_duration

        # Members share one time axis (the batched engine): the slowest member's duration.
        duration = max(auto_duration(m) for m in models)
    _check_sweep_resources(cfg, models, duration, probes, member_dts)

    if out.exists() and not out.is_dir():
        raise ConfigError(str(out), "exists and is not a folder; --out names the sweep's output folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(str(out), f"cannot create the output folder: {exc.strerror}") from None
    with _folder_lock(out):
        chunks_dir = _prepare_out_dir(cfg, out, force)
        return _run_chunks(cfg, out, chunks_dir, models, duration, probes, member_dts, client, progress, device)


def _check_sweep_resources(cfg: SweepConfig, models, duration: float, probes, member_dts: list) -> None:
    """Refuse a chunk that cannot fit in memory (naming sweep.chunk_size); warn on a long sweep.

    ``models``: a list of Models, or an Ensemble (members of one length: member 0 stands for all).
    """
    from dataclasses import replace as _replace

    from ..checks import check_resources, estimate_resources

    if isinstance(models, list):
        largest = max(range(len(models)), key=lambda i: models[i].chain.n_beads)
        model = models[largest]
    else:
        largest, model = 0, models.model(0)
    members = min(cfg.sweep.chunk_size, cfg.n_members)
    est = estimate_resources(model.system(), duration, probes, dt=member_dts[largest], members=members)
    check_resources(_replace(est, seconds=0.0), memory_field="sweep.chunk_size")
    total = _replace(est, members=cfg.n_members, memory_bytes=0, seconds=est.seconds / members * cfg.n_members)
    check_resources(total)


def _run_chunks(cfg: SweepConfig, out: Path, chunks_dir: Path, models, duration: float, probes,
                member_dts: list, client, progress, device: str = "auto") -> SweepResult:
    """Compute the chunks not yet on disk and write the metrics table (folder lock held).

    ``models``: a list of Models, or an Ensemble whose rows are the members; ``device`` as in
    :func:`run_sweep`.
    """
    from ..config import parse_config
    from ..fileio import atomic_path

    steps_per_radian = parse_config(cfg.base).run.steps_per_radian  # shared by every member (_SHARED)

    total = cfg.n_members
    done_members = 0
    skipped, todo = [], []
    for index, members in enumerate(cfg.chunks()):
        if _chunk_is_done(chunks_dir / _CHUNK_NAME.format(index), cfg.hash, members):
            skipped.append(index)
            done_members += len(members)
        else:
            chunk_models = [models[m] for m in members] if isinstance(models, list) else models.subset(members)
            todo.append(_ChunkTask(index=index, members=list(members), models=chunk_models,
                                   params=[cfg.members[m] for m in members], duration=duration,
                                   probes=probes, dt=[member_dts[m] for m in members],
                                   n_threads=cfg.sweep.n_threads, sweep_hash=cfg.hash, device=device,
                                   steps_per_radian=steps_per_radian))
    if progress is not None:
        progress(done_members, total)

    computed = []
    for ds in _results(client, compute_chunk, todo):
        index = int(ds.attrs["chunk"])
        _write_chunk(ds, chunks_dir / _CHUNK_NAME.format(index))
        computed.append(index)
        done_members += ds.sizes["member"]
        if progress is not None:
            progress(done_members, total)

    df = _metrics_table(cfg, chunks_dir)
    with atomic_path(out / "metrics.csv") as tmp:
        df.to_csv(tmp, index=False)
    if importlib.util.find_spec("pyarrow") is not None:
        with atomic_path(out / "metrics.parquet") as tmp:
            df.to_parquet(tmp, index=False)
    return SweepResult(metrics=df, out_dir=out, computed=sorted(computed), skipped=skipped)
