"""Running a sweep: :func:`run_sweep` validates it, then computes the chunks not yet on disk
(:func:`compute_chunk`, here or on a Dask cluster or an executor) and writes each one as it comes
back; the metrics table is collected at the end.

A chunk task is a recipe (the base config, the chunk's parameter values and tolerances), not
its models: a worker in another process or on another machine builds its members itself
(:func:`~hertzchain.sweep.schema.chunk_members`, the same numbers wherever it runs), so a
task is small and a million-member ensemble never exists in memory at once. Results come back
as arrays (an xarray Dataset in memory); only this process writes files.
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
from .schema import SweepConfig, chunk_members, load_sweep, parse_sweep
from .storage import (_CHUNK_NAME, _METRIC_UNITS, METRIC_COLUMNS, PLASTIC_METRICS, RUN_METRICS, _chunk_is_done,
                      _drop_replaced, _folder_lock, _metrics_table, _prepare_out_dir, _traces_path, _write_chunk)

def _table_sidecar(cfg: SweepConfig, df) -> dict:
    """``metrics.csv.json``: what a reader of ``metrics.csv`` alone needs to know about it.

    Every column's unit and meaning, the hertzchain version, and the sweep's definition (base
    config, parameters, tolerances and seed, as in ``sweep.json``).
    """
    from .. import __version__
    from .storage import _BODY_COLUMNS, COLUMN_UNITS, PLASTIC_METRICS

    meaning = {"member": ("", "member index"), "chunk": ("", "chunk file holding the member"),
               "dt": ("s", "time step of the member's run"), "peak_wall_force": ("N", "peak wall force, refined "
               "between the engine's steps"), "peak_wall_time": ("s", "time of the peak wall force"),
               "elastic_limit_exceeded": ("1", "a contact force passed the elastic limit F_Y"),
               "fit_error": ("", "why the wall pulse has no metrics (empty when fitted)"),
               "striker_velocity": ("m/s", "drawn impact velocity"),
               **_METRIC_UNITS, **RUN_METRICS,
               **{k: (u, d) for k, (_, u, d) in PLASTIC_METRICS.items()},
               **{k: (u, "peak of the protected body") for k, u in _BODY_COLUMNS.items()}}
    columns = {}
    for c in df.columns:
        unit, text = meaning.get(c, (COLUMN_UNITS.get(c, ""), ""))
        for prefix, what in (("diameter_mm_", "drawn diameter of bead "), ("offset_mm_", "drawn offset of bead ")):
            if c.startswith(prefix) and c[len(prefix):].isdigit():
                unit, text = "mm", what + c[len(prefix):]
        if c in cfg.parameter_names:
            text = "swept parameter (config path)"
        columns[c] = {"units": unit, "long_name": text}
    return {"table": "metrics.csv", "hertzchain_version": __version__, "n_members": int(len(df)),
            "columns": columns, "definition": cfg.definition()}


def _drawn_columns(cfg: SweepConfig, members: np.ndarray) -> dict[str, np.ndarray]:
    """Each member's drawn tolerances, for the metrics table beside its metrics.

    The draws depend on (seed, member index) alone (:mod:`hertzchain.sweep.tolerances`), so they
    are drawn again here, chunk by chunk, exactly as the chunks drew them, rather than carried
    in every chunk file: ``diameter_mm_N`` [mm] of bead N (1-based), ``offset_mm_N`` [mm] when
    offsets are drawn, ``striker_velocity`` [m/s] when the speed is. A spread of a metric can
    then be traced to the deviations that made it (a regression, a scatter plot).

    Parameters
    ----------
    cfg : SweepConfig
        The sweep.
    members : numpy.ndarray
        The table's member indices, in its row order.

    Returns
    -------
    dict
        Column name -> values in the table's row order (empty without tolerances); NaN for
        beads a shorter member lacks.
    """
    tol = cfg.sweep.tolerances
    if tol is None:
        return {}
    from ..interrupts import check
    from .tolerances import _any

    order = np.argsort(members)

    def widen(a: np.ndarray, width: int) -> np.ndarray:
        return np.pad(a, ((0, 0), (0, width - a.shape[1])), constant_values=np.nan)

    diam: np.ndarray | None = None
    offs: np.ndarray | None = None
    vel: np.ndarray | None = None
    built: dict = {}
    for chunk in cfg.chunks():
        check()
        models, _ = chunk_members(cfg, chunk, built)
        if hasattr(models, "diameters"):  # one Ensemble: arrays (members, beads)
            d, e, v = models.diameters, models.offsets, models.striker_velocity
        else:  # members of different layouts: NaN past each one's last bead
            width = max(m.chain.n_beads for m in models)
            d, e = np.full((len(models), width), np.nan), np.full((len(models), width), np.nan)
            for r, m in enumerate(models):
                d[r, :m.chain.n_beads], e[r, :m.chain.n_beads] = m.chain.diameters, m.chain.offsets
            v = np.array([m.striker.velocity for m in models])
        if diam is None or d.shape[1] > diam.shape[1]:  # (re)allocate to the widest member so far
            diam = np.full((members.size, d.shape[1]), np.nan) if diam is None else widen(diam, d.shape[1])
            offs = np.full((members.size, d.shape[1]), np.nan) if offs is None else widen(offs, d.shape[1])
            vel = np.full(members.size, np.nan) if vel is None else vel
        assert offs is not None and vel is not None  # (allocated with diam)
        rows = order[np.searchsorted(members, np.asarray(chunk), sorter=order)]  # the chunk's table rows
        diam[rows, :d.shape[1]], offs[rows, :d.shape[1]], vel[rows] = d * 1e3, e * 1e3, v
    assert diam is not None and offs is not None and vel is not None  # (a sweep has a chunk)
    cols = {f"diameter_mm_{j + 1}": diam[:, j] for j in range(diam.shape[1])}
    if _any(tol.offset_mm):
        cols |= {f"offset_mm_{j + 1}": offs[:, j] for j in range(offs.shape[1])}
    if tol.has_velocity:
        cols["striker_velocity"] = vel
    return cols


# ------------------------------------------------------------------------------ computing chunks
@dataclass
class _ChunkTask:
    """Everything a worker needs for one chunk (picklable and small; no file access on the worker).

    ``recipe`` is the sweep with only this chunk's members (:meth:`SweepConfig.subset`);
    ``probes`` what every member records; ``traced`` the members (of this chunk) whose full
    records, with ``trace_probes``, come back too (store = "metrics").
    """

    index: int
    members: list[int]
    recipe: SweepConfig
    duration: float
    probes: Any
    n_threads: int | None
    sweep_hash: str
    device: str = "auto"
    steps_per_radian: float | None = None
    integrator: str = "auto"
    rtol: float | None = None
    metrics_only: bool = False
    traced: tuple[int, ...] = ()
    trace_probes: Any = None


#: Resampling factor of the wall-pulse fits of a sweep's members (:func:`hertzchain.analysis.fit_pulse`).
F_M_REFINE = 8


def _wall_metrics(time: np.ndarray, force: np.ndarray) -> dict[str, float]:
    """Wall-pulse metrics F_m [N], T [s], tau [s], Q_F [N s], Q_T [N s] by :func:`hertzchain.analysis.fit_pulse`.

    Raises :class:`hertzchain.errors.PulseNotFound` when the record holds no pulse.
    """
    from ..analysis import fit_pulse

    # The records the compiled fit of a chunk (analysis.pulse_batch) leaves, one at a time. On the
    # record resampled 8 times finer, F_m's sampling error (a comb of ~0.2 % steps at 1 us samples)
    # falls to ~0.03 %, below the spreads of a tolerance ensemble (a few tenths of a per cent).
    fit = fit_pulse(time, force, compiled=True, refine=F_M_REFINE)
    return {col: float(getattr(fit, attr)) for col, attr in METRIC_COLUMNS.items()}


def compute_chunk(task: _ChunkTask):
    """Build one chunk's members, simulate them with the batched engine and fit the wall pulses.

    Runs wherever it is sent (here, a Dask worker): it only needs the task. Elastic-limit
    warnings are not raised per member (a sweep would print thousands); the
    ``elastic_limit_exceeded`` variable and the metrics table carry them.

    Parameters
    ----------
    task : _ChunkTask
        The chunk.

    Returns
    -------
    xarray.Dataset or tuple
        The chunk's Dataset: the batched results stacked along ``member`` with every member's
        metrics; with ``task.metrics_only`` the metrics alone (per-member variables, a few
        hundred bytes per member) and the Dataset of the traced members (or None), as a pair.
    """
    import xarray as xr

    from ..analysis.pulse_batch import PULSE_COLUMNS, fit_pulses
    from ..errors import ElasticLimitWarning, PulseNotFound, PulseNotReachedWarning
    from ..runs.batch import simulate_batch
    from ..interrupts import check

    models, dts = chunk_members(task.recipe, task.members)

    def simulate(which, which_dts, probes):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ElasticLimitWarning)
            warnings.simplefilter("ignore", PulseNotReachedWarning)  # fit_error says "no pulse" per member
            # The largest contact forces over the run (force_over_yield), whatever is stored: the
            # fourth-order engine then interpolates only the recorded contacts at the samples (a
            # metrics-only chunk: the wall), and every store gives the same metrics.
            return simulate_batch(which, task.duration, probes, dt=which_dts, n_threads=task.n_threads,
                                  configs=None, device=task.device, steps_per_radian=task.steps_per_radian,
                                  integrator=task.integrator, rtol=task.rtol, max_force="run")

    ds = simulate(models, dts, task.probes)
    ds = ds.assign_coords(member=("member", np.asarray(task.members, dtype=np.int64), ds["member"].attrs))
    _check_members_energy(ds, models, dts, task)
    values = {k: np.full(len(task.members), np.nan) for k in METRIC_COLUMNS}
    errors = [""] * len(task.members)
    time = ds["time"].values
    walled = np.flatnonzero(ds["has_wall"].values)
    # Every wall pulse fitted at once in compiled code; the records it leaves (status 1: possibly
    # clipped, no pulse, a fit that fails...) are fitted below by fit_pulse, which says why.
    wall = ds["wall_force"].values
    fitted, status = fit_pulses(time, wall if walled.size == wall.shape[0] else wall[walled], refine=F_M_REFINE)
    for k, attr in METRIC_COLUMNS.items():
        values[k][walled] = fitted[:, PULSE_COLUMNS.index(attr)]
    done = np.zeros(len(task.members), dtype=bool)
    done[walled[status == 0]] = True
    check()
    for i in np.flatnonzero(~done).tolist():
        check()  # a Ctrl-C swallowed by a cleanup stops the chunk here
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
    metrics = {k: xr.Variable(("member",), values[k], attrs={"units": u, "long_name": n})
               for k, (u, n) in _METRIC_UNITS.items()}
    metrics.update(_run_metrics(ds))
    if "plastic_work" in ds:  # an elastoplastic member: its plastic work and largest permanent overlap
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN rows of the other members
            plastic = {"plastic_work": ds["plastic_work"].values[:, -1],
                       "residual_overlap_max": np.nanmax(ds["residual_overlap"].values, axis=1)}
        for k, (var, units, long_name) in PLASTIC_METRICS.items():
            metrics[var] = xr.Variable(("member",), plastic[k], attrs={"units": units, "long_name": long_name})
    metrics["fit_error"] = xr.Variable(("member",), np.array(errors, dtype=object),
                                       attrs={"long_name": "why the wall pulse has no metrics (empty when fitted)"})
    metrics["parameters"] = xr.Variable(("member",), np.array([json.dumps(task.recipe.members[m])
                                                               for m in task.members], dtype=object),
                                        attrs={"long_name": "swept parameter values of the member (JSON)"})
    attrs = dict(sweep_hash=task.sweep_hash, chunk=task.index, title="hertzchain sweep chunk")
    if not task.metrics_only:
        ds = ds.assign(metrics)
        ds.attrs.update(attrs)
        # A chunk is a function of the sweep and its index: no creation time (sweep.json has the
        # sweep's), so that a recomputed chunk has the same bytes and checksum as the first one.
        ds.attrs.pop("created_utc", None)
        return ds
    # The per-member numbers; not the member's description (``model``, ``config``: ~1 kB each, and
    # the sweep file and the member's index give it again: SweepConfig.member_model).
    keep = [v for v in ds.data_vars if ds[v].dims == ("member",) and v not in ("model", "config")]
    table = xr.Dataset({**{v: ds[v].variable for v in keep}, **metrics}, coords={"member": ds["member"]},
                       attrs={**attrs, "title": "hertzchain sweep chunk (metrics only)", "engine": ds.attrs.get("engine", "")})
    traces = None
    if task.traced:
        rows = [task.members.index(m) for m in task.traced]
        sub = models.subset(rows) if hasattr(models, "subset") else [models[r] for r in rows]
        traces = simulate(sub, [dts[r] for r in rows], task.trace_probes)
        traces = traces.assign_coords(member=("member", np.asarray(task.traced, dtype=np.int64),
                                              traces["member"].attrs))
        traces = traces.assign({k: v[rows] for k, v in metrics.items()})
        traces.attrs.update({**attrs, "title": "hertzchain sweep traces"})
        traces.attrs.pop("created_utc", None)
    return table, traces


def _run_metrics(ds) -> dict:
    """Per-member energies at the end [J] and the largest contact force over its yield force."""
    import xarray as xr

    out = {}
    for name, var in (("kinetic_energy_end", "kinetic_energy"), ("potential_energy_end", "potential_energy"),
                      ("dissipated_energy_end", "dissipated_energy")):
        out[name] = ds[var].values[:, -1].copy()
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = ds["max_contact_force"].values / ds["yield_force"].values
    # NaN where a member has no such contact (members of different lengths)
    ratio = np.where(np.isnan(ratio), -np.inf, ratio).max(axis=1)
    out["force_over_yield"] = np.where(np.isfinite(ratio), ratio, np.nan)
    return {k: xr.Variable(("member",), v, attrs={"units": RUN_METRICS[k][0], "long_name": RUN_METRICS[k][1]})
            for k, v in out.items()}


#: Members whose energy balance is checked together (see _check_members_energy).
_ENERGY_ROWS = 16


def _check_members_energy(ds, models, dts: list, task: _ChunkTask) -> None:
    """The energy balance of every member (hertzchain.checks), which the batched engine does not
    check itself: a member that gains energy stops the sweep, naming the member and the cause.

    All members at once; the tolerance of a member with an automatic step is the floor
    (its largest step is not stored per member), of one with a fixed step that of its step."""
    from ..checks import check_energy_balance, energy_cause, energy_gain, energy_tolerance

    ke, pe, ed = (ds[v].values for v in ("kinetic_energy", "potential_energy", "dissipated_energy"))
    if "plastic_work" in ds:  # every loss counts: viscous and plastic (NaN rows: other laws)
        ed = ed + np.nan_to_num(ds["plastic_work"].values)
    model = models.model if hasattr(models, "model") else models.__getitem__
    tol = np.array([energy_tolerance(model(i).system(), dt) if dt is not None else energy_tolerance(None, 0.0)
                    for i, dt in enumerate(dts)])
    # A block of members at a time: the gain's temporaries stay a few rows, not a chunk's worth of
    # records (the memory estimate counts the records and the engine's buffers only).
    bad = np.empty(0, dtype=np.int64)
    for r in range(0, len(dts), _ENERGY_ROWS):
        rows = slice(r, r + _ENERGY_ROWS)
        gain = energy_gain(ke[rows], pe[rows], ed[rows])
        bad = np.flatnonzero(np.any(~np.isfinite(gain) | (gain > tol[rows, None]), axis=1)) + r
        if bad.size:
            break
    if bad.size:
        i = int(bad[0])
        try:
            check_energy_balance(ds["time"].values, ke[i], pe[i], ed[i], tolerance=tol[i],
                                 cause=energy_cause(model(i), dts[i]))
        except SimulationDiverged as exc:
            member = task.members[i]
            raise SimulationDiverged(f"sweep member {member} ({task.recipe.members[member]}): {exc}") from None


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
        ``distributed.Client`` (worker processes here or on other machines), a
        ``concurrent.futures.Executor``, anything with ``submit`` + ``gather`` or with ``map``:
        chunks are sent to it and written here as they come back (the workers need no access
        to ``out_dir``; a worker that dies costs only its chunk, run again elsewhere).
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
        member has no wall or no fitted pulse), ``kinetic_energy_end``, ``potential_energy_end``,
        ``dissipated_energy_end`` [J] and ``force_over_yield``; with protected bodies also
        ``peak_body_force`` [N], ``peak_body_acceleration`` [m/s^2] and ``peak_body_energy`` [J];
        with an elastoplastic member also ``plastic_work`` [J] and ``residual_overlap_max`` [m]
        (NaN for members of other laws). Also written to ``metrics.csv`` (and ``metrics.parquet``
        when pyarrow is installed).

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
    from ..interrupts import latched

    if isinstance(sweep_cfg, (str, Path)):
        cfg = load_sweep(sweep_cfg)
    elif isinstance(sweep_cfg, dict):
        cfg = parse_sweep(sweep_cfg)
    else:
        cfg = sweep_cfg
    out = Path(out_dir)
    from ..integrate.cuda.launch import check_device

    check_device(device)
    with latched():  # a Ctrl-C is never swallowed (hertzchain.interrupts)
        # the projected time is shared by the cores the chunks run on: the local engine's, or the
        # cluster's workers' threads; the advice names only what is not in use already
        gaps = cfg.sweep.analysis == "dispersion"  # a band-gap map: band structures, no runs (sweep/gaps.py)
        plan = None if gaps else _plan(cfg, device, *_where(client, cfg.sweep.n_threads))
        if out.exists() and not out.is_dir():
            raise ConfigError(str(out), "exists and is not a folder; --out names the sweep's output folder")
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ConfigError(str(out), f"cannot create the output folder: {exc.strerror}") from None
        if gaps:
            from .gaps import run_gap_sweep

            df = run_gap_sweep(cfg, out, progress, force)
            return SweepResult(metrics=df, out_dir=out, computed=list(range(len(cfg.chunks()))), skipped=[])
        assert plan is not None  # (made for every sweep but a band-gap map)
        with _folder_lock(out):
            chunks_dir = _prepare_out_dir(cfg, out, force)
            return _run_chunks(cfg, plan, out, chunks_dir, client, progress)


@dataclass
class _Plan:
    """What every chunk of a validated sweep shares (:func:`_plan`)."""

    duration: float
    probes: Any
    trace_probes: Any
    device: str
    steps_per_radian: float | None
    integrator: str = "auto"
    rtol: float | None = None
    estimate: Any = None
    table_bytes: int = 0  # the metrics table per member [bytes] (_table_bytes)


def _where(client, n_threads: int | None) -> tuple[int, str]:
    """The cores a sweep's chunks run on, and what would make it faster that it does not use yet.

    Parameters
    ----------
    client : object or None
        None (the local engine), a Dask ``distributed.Client`` or an executor.
    n_threads : int or None
        ``sweep.n_threads`` (the local engine's threads; None: every usable core).

    Returns
    -------
    (int, str)
        Cores, and the advice ending the long-run warning.
    """
    from ..parallel import _is_dask, usable_cores, worker_threads

    if client is None:
        cores = n_threads or usable_cores()
        return cores, ((f"that is on {cores} cores; " if cores > 1 else "") + "fewer members (sweep.n), a shorter "
                       "run.duration or a Dask cluster (--scheduler) would be faster")
    cores = worker_threads(client)
    where = f"the Dask cluster's {cores} worker threads" if _is_dask(client) else f"the executor's {cores} workers"
    return cores, f"that is on {where}; fewer members (sweep.n), a shorter run.duration or more workers would be faster"


def _plan(cfg: SweepConfig, device: str, cores: int = 1, advice: str | None = None) -> _Plan:
    """Validate every member (chunk by chunk: nothing but the estimates' inputs is kept), fix the
    shared duration and probes, and check that a chunk fits in memory.

    Everything is validated (every member's model and deviations, the memory a chunk needs)
    before anything is written: an invalid sweep leaves no sweep.json behind to block the
    corrected one.
    """
    from ..config import build_probes, parse_config
    from ..interrupts import check
    from ..probes import Probes

    run_cfg = parse_config(cfg.base)
    base_probes = build_probes(run_cfg)
    if cfg.sweep.store == "probes":
        probes: Any = base_probes
    elif cfg.sweep.store == "wall":
        # The wall force (always recorded with contacts=()), the sensors and the energies only:
        # every contact of every member would be ~N times larger and the metrics do not need it.
        probes = Probes(sample_interval=base_probes.sample_interval, sensors=base_probes.sensors, contacts=())
    else:  # metrics: what the metrics need, the wall force and the energies, and nothing is kept
        probes = Probes(sample_interval=base_probes.sample_interval, contacts=())
    auto = run_cfg.run.duration == "auto"
    duration = 0.0 if isinstance(run_cfg.run.duration, str) else run_cfg.run.duration
    built: dict = {}
    largest = None  # (beads, a model of that length, its dt)
    for members in cfg.chunks():
        check()
        models, dts = chunk_members(cfg, members, built)
        n_beads = models.n_beads if hasattr(models, "n_beads") else max(m.chain.n_beads for m in models)
        if largest is None or n_beads > largest[0]:
            r = 0 if hasattr(models, "n_beads") else max(range(len(models)), key=lambda i: models[i].chain.n_beads)
            largest = (n_beads, models.model(r) if hasattr(models, "model") else models[r], dts[r])
        if auto:
            from ..runs.simulation import auto_duration

            # Members share one time axis (the batched engine): the slowest member's duration.
            duration = max(duration, max(auto_duration(m) for m in models))
    assert largest is not None  # (a sweep has a chunk)
    est = _sweep_estimate(cfg, largest[1], largest[2], duration, probes, base_probes if cfg.sweep.traces else None,
                          _batch_integrator(run_cfg, largest[1], largest[2]))
    table_bytes = _table_bytes(cfg, largest[0])
    _check_sweep_resources(cfg, est, cores, advice, table_bytes)
    return _Plan(duration=duration, probes=probes, trace_probes=base_probes, device=device,
                 steps_per_radian=run_cfg.run.verlet_steps_per_radian, estimate=est, table_bytes=table_bytes,
                 # the batched engines: the fourth-order one where "auto" picks it for every member
                 integrator=run_cfg.run.integrator if run_cfg.run.integrator in ("auto", "rkn4") else "verlet",
                 rtol=run_cfg.run.rtol)


#: Memory of metrics.csv's table while it is collected and written, per member [bytes]: its numeric
#: columns and the Python strings of its text columns (447 measured for 1e6 members of an ensemble).
TABLE_BYTES_PER_MEMBER = 450


def _table_bytes(cfg: SweepConfig, n_beads: int) -> int:
    """Bytes per member of the metrics table: :data:`TABLE_BYTES_PER_MEMBER` and, in an ensemble,
    the drawn tolerances' columns (a float per bead for the diameters and the offsets, one for
    the speed: :func:`_drawn_columns`)."""
    tol = cfg.sweep.tolerances
    return TABLE_BYTES_PER_MEMBER + (0 if tol is None else 8 * (2 * n_beads + 1))


def _batch_integrator(run_cfg, model, dt) -> str:
    """The batched engine that runs ``model`` in a chunk (``simulate_batch(integrator=...)``'s
    ``"auto"``): ``"rkn4"`` for offset beads or the Kuwabara-Kono or dashpot law with an automatic
    step, unless the config names the Verlet or sets its accuracy; else ``"verlet"``."""
    from ..engine_choice import choose_engine

    run = run_cfg.run
    if run.integrator not in ("auto", "rkn4") or run.verlet_steps_per_radian is not None or dt is not None:
        return "verlet"
    # the single run's choice (the registry's answer: the laws rkn4 integrates), but for aligned
    # elastic chains, whose symplectic rkn4 has no batched engine, and the elastic-plastic and
    # registry laws, whose rkn4 (drivers/rkn_laws.py) is not batched either
    from ..laws import law_of_code

    system = model.system()
    spec = law_of_code(system.law)
    if (choose_engine(system, "auto", 1).integrator != "rkn4" or not (system.law or system.misaligned)
            or spec.generated or spec.plastic):
        return "verlet"
    return "rkn4"


def _sweep_estimate(cfg: SweepConfig, model, dt, duration: float, probes, trace_probes, integrator: str = "verlet"):
    """The memory of one chunk (the largest member stands for all, ``dt`` its fixed step), and of
    the metrics table at the end, whichever is larger; the run time of the whole sweep on the
    batched engine ``integrator``."""
    from dataclasses import replace as _replace

    from ..checks import estimate_resources

    members = min(cfg.sweep.chunk_size, cfg.n_members)
    system = model.system()
    est = estimate_resources(system, duration, probes, dt=dt, members=members, written=cfg.sweep.store != "metrics",
                             integrator=integrator)
    if trace_probes is not None:  # the traced members of a chunk are run again with every probe
        extra = estimate_resources(system, duration, trace_probes, dt=dt, members=min(members, len(cfg.sweep.traces)),
                                   integrator=integrator)
        est = _replace(est, memory_bytes=est.memory_bytes + extra.memory_bytes)
    return est


def _check_sweep_resources(cfg: SweepConfig, est, cores: int = 1, advice: str | None = None,
                           table_bytes: int = TABLE_BYTES_PER_MEMBER) -> None:
    """Refuse a chunk that cannot fit in memory (naming sweep.chunk_size); warn on a long sweep,
    its projected time shared by the ``cores`` the chunks run on (:func:`_where`), ending with
    ``advice`` (what would be faster and is not in use)."""
    from dataclasses import replace as _replace

    from ..checks import check_resources

    check_resources(_replace(est, seconds=0.0), memory_field="sweep.chunk_size")
    # the metrics table of every member, collected at the end (450 MB for a million members)
    check_resources(_replace(est, seconds=0.0, memory_bytes=table_bytes * cfg.n_members),
                    memory_field="sweep.n")
    total = _replace(est, members=cfg.n_members, memory_bytes=0,
                     seconds=est.seconds / est.members * cfg.n_members / cores)
    check_resources(total, time_hint=advice or _where(None, cores)[1])


def estimate_sweep(cfg: SweepConfig):
    """What a sweep will need, before it runs (every member is validated to know it).

    Parameters
    ----------
    cfg : SweepConfig
        The sweep.

    Returns
    -------
    hertzchain.checks.ResourceEstimate
        ``members``: a chunk's; ``memory_bytes``: what the process allocates at most, a chunk's
        records or the metrics table of every member at the end, whichever is larger;
        ``peak_bytes``: the process's peak resident memory; ``seconds``: one chunk on one core.
    """
    from dataclasses import replace as _replace

    plan = _plan(cfg, "auto")
    est = plan.estimate
    return _replace(est, memory_bytes=max(est.memory_bytes, plan.table_bytes * cfg.n_members))


def _tasks(cfg: SweepConfig, plan: _Plan, todo: list[int]) -> Iterator[_ChunkTask]:
    """The tasks of the chunks ``todo``, made one at a time as they are submitted."""
    chunks = cfg.chunks()
    traced = set(cfg.sweep.traces)
    for index in todo:
        members = list(chunks[index])
        yield _ChunkTask(index=index, members=members, recipe=cfg.subset(members), duration=plan.duration,
                         probes=plan.probes, n_threads=cfg.sweep.n_threads, sweep_hash=cfg.hash,
                         device=plan.device, steps_per_radian=plan.steps_per_radian, integrator=plan.integrator,
                         rtol=plan.rtol,
                         metrics_only=cfg.sweep.store == "metrics",
                         traced=tuple(m for m in members if m in traced), trace_probes=plan.trace_probes)


def _run_chunks(cfg: SweepConfig, plan: _Plan, out: Path, chunks_dir: Path, client, progress) -> SweepResult:
    """Compute the chunks not yet on disk and write the metrics table (folder lock held)."""
    from ..fileio import atomic_path, json_text, write_text
    from ..interrupts import check
    from ..parallel import results_as_completed

    total = cfg.n_members
    done_members = 0
    skipped, todo = [], []
    traced = set(cfg.sweep.traces)
    for index, members in enumerate(cfg.chunks()):
        path = chunks_dir / _CHUNK_NAME.format(index)
        if _chunk_is_done(path, cfg.hash, members, [m for m in members if m in traced]):
            skipped.append(index)
            done_members += len(members)
        else:
            todo.append(index)
    if progress is not None:
        progress(done_members, total)

    computed = []
    for result in results_as_completed(client, compute_chunk, _tasks(cfg, plan, todo)):
        check()  # a Ctrl-C swallowed while the chunk came back stops the sweep here
        table, traces = result if isinstance(result, tuple) else (result, None)
        index = int(table.attrs["chunk"])
        path = chunks_dir / _CHUNK_NAME.format(index)
        if traces is not None:  # first: a chunk file on disk says its traces are too
            _write_chunk(traces, _traces_path(path))
        _write_chunk(table, path)
        check()  # ... or while it was written (h5py's cleanups run weakref callbacks)
        computed.append(index)
        done_members += table.sizes["member"]
        # let the chunk go before the next one is computed (a chunk's records are the estimate)
        del result, table, traces
        if progress is not None:
            progress(done_members, total)

    from ..runs.batch import release_records

    release_records()  # the last chunk's record pages, kept for a next chunk, go before the table comes
    df = _metrics_table(cfg, chunks_dir)
    for name, values in (_drawn_columns(cfg, df["member"].to_numpy()).items()):
        df.insert(df.columns.get_loc("dt"), name, values)  # inputs, before dt; the metrics follow it
    with atomic_path(out / "metrics.csv") as tmp:
        df.to_csv(tmp, index=False)
    write_text(out / "metrics.csv.json", json_text(_table_sidecar(cfg, df)))
    if importlib.util.find_spec("pyarrow") is not None:
        with atomic_path(out / "metrics.parquet") as tmp:
            df.to_parquet(tmp, index=False)
    _drop_replaced(out)  # complete: the results of a sweep this one replaced (--force) can go
    return SweepResult(metrics=df, out_dir=out, computed=sorted(computed), skipped=skipped)
