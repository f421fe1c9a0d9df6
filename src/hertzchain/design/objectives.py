"""Design objectives, robust forms, and the evaluation of a whole generation in one engine call.

Objectives (all minimised, SI units):

- ``peak_wall_force`` [N]: the largest force on the wall (contact N), refined between samples
  by the engine (the value ``hertzchain run`` reports);
- ``peak_contact_force`` [N]: the largest force of any contact (striker included);
- ``max_force_over_yield`` [1]: the largest contact force over its elastic limit F_Y (Sec. II);
- ``front_momentum_at_wall`` [N s]: Q_F of the wall pulse, the integral of the wall force up
  to T + tau of its cos^6 fit (paper Sec. III, Fig. 5d);
- ``energy_at_wall`` [J]: the largest elastic energy stored in the bead N - wall contact,
  (2/5) kappa delta^(5/2) = (2/5) F^(5/3) / kappa^(2/3) with delta = (F / kappa)^(2/3) (paper
  eq. 1), within ``window`` = [t0, t1] [s] when given: the energy the pulse delivers into the
  wall's contact;
- ``plastic_work`` [J] and ``residual_overlap_max`` [m] (the elastoplastic law, Thornton 1997):
  the plastic work done in all contacts by the end of the run, and the largest permanent
  overlap a contact was left with (the dent a protector keeps).

With a protected body (``wall.type = "body"``), what reaches the body itself:
``peak_body_force``, ``peak_body_acceleration``, ``energy_to_body`` (:mod:`hertzchain.design.body`).

Robust forms (``[design.robust]``): every candidate is run in several *scenarios*: each striker
speed of ``velocities`` times ``draws`` Monte Carlo draws of manufacturing tolerances (the
sweep's tolerance model: phi_n (1 + diameter_rel z), e_n + offset_mm z', seeded per draw
index, so every candidate sees the same draws: common random numbers). The objective is then
the ``worst`` case, the ``mean``, or ``mean+ksigma`` (mean + k standard deviations) over the
scenarios; run constraints must hold in every scenario.

All scenario runs of all candidates of a generation go to the batched engine in one
:func:`hertzchain.runs.batch.run_batch` call (or one per chunk on a Dask cluster), which
returns the engine's arrays without building a Dataset (the design needs a handful of numbers
per member, not the stacked result).

Fidelity (:class:`Fidelity`): the search may run candidates at a coarser accuracy than the base
config (fewer adaptive steps per radian, fewer samples); the best candidates are then run again
at the base config's own accuracy, and only those values are reported (see
:mod:`hertzchain.design.search`).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field, replace
from typing import Any, Callable, Literal, NamedTuple

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from ..config import build_model, build_probes, chain_parts, parse_config
from ..errors import PulseNotFound
from .body import BODY_OBJECTIVES, body_objective, body_records
from .constraints import Constraints, geometric_margin, geometric_violation, geometry, run_violation

__all__ = ["OBJECTIVES", "PLASTIC_OBJECTIVES", "Robust", "Evaluation", "Evaluator", "Candidate", "Fidelity", "member_metrics",
           "search_interval"]

#: Objective names with their units and meaning.
OBJECTIVES: dict[str, tuple[str, str]] = {
    "peak_wall_force": ("N", "peak force on the wall"),
    "peak_contact_force": ("N", "peak force of any contact"),
    "max_force_over_yield": ("1", "largest contact force over its elastic limit F_Y"),
    "front_momentum_at_wall": ("N s", "front momentum Q_F of the wall pulse (paper Sec. III)"),
    "energy_at_wall": ("J", "largest elastic energy in the bead N - wall contact"),
    "peak_body_force": ("N", "peak force the protected body passes to the ground"),
    "peak_body_acceleration": ("m s-2", "peak acceleration of the protected body"),
    "energy_to_body": ("J", "most energy delivered to the protected body"),
    "plastic_work": ("J", "plastic work done in all contacts (elastoplastic law)"),
    "residual_overlap_max": ("m", "largest permanent overlap of any contact (elastoplastic law)"),
}

#: Objectives that need the elastoplastic law (the other laws do no plastic work).
PLASTIC_OBJECTIVES = frozenset({"plastic_work", "residual_overlap_max"})


#: Fitness of an infeasible candidate: above any feasible objective value, ranked by violation.
INFEASIBLE = 1e12

#: Objectives computed from the engine's per-step trackers alone (the wall peak is tracked and
#: refined at every step; the plastic work and residual overlaps follow from every contact's
#: largest overlap, a state updated at every step), so that sampling the records more coarsely
#: does not change them. The
#: others read sampled records: the largest contact forces (peak_contact_force,
#: max_force_over_yield) are maxima over the samples, Q_F and the energy are read off the
#: sampled wall force.
SAMPLING_FREE = frozenset({"peak_wall_force", "plastic_work", "residual_overlap_max"})


#: Samples per wall pulse that coarse search records keep (the pulse-arrival check needs a few).
SEARCH_SAMPLES_PER_PULSE = 10


@dataclass(frozen=True)
class Fidelity:
    """The accuracy candidates are run at.

    Attributes
    ----------
    name : str
        ``"full"`` (the base config's own accuracy, what ``hertzchain run`` of the candidate
        gives) or ``"search"`` (coarser, for the search only).
    steps_per_radian : float or None
        Adaptive-step accuracy (``run.steps_per_radian``); None: the config's own.
    coarse_sampling : bool
        Sample each engine call every whole multiple of ``run.sample_interval`` that still
        leaves SEARCH_SAMPLES_PER_PULSE samples in the shortest wall pulse its members can give
        (:func:`search_interval`); False: every ``run.sample_interval``.
    """

    name: str = "full"
    steps_per_radian: float | None = None
    coarse_sampling: bool = False


def search_interval(models: list, interval: float, duration: float) -> float:
    """Sample interval [s] of a coarse search call: the largest multiple of ``interval`` that
    leaves SEARCH_SAMPLES_PER_PULSE samples in the shortest wall pulse of ``models``.

    A pulse of speed v lasts tau = sqrt(10) phi_N / (2 v) at the last bead (paper Sec. III),
    v from the last bead's largest possible velocity V (paper eq. 5, second form): all the
    striker's energy in bead N, V = v_0 sqrt(m_s / m_N), bounds it (the wave is faster, so
    shorter, at larger V). A precompressed chain carries faster waves than this bound knows of:
    its records keep the base interval.
    """
    from ..theory import pulse_duration, solitary_wave_speed_from_velocity

    if any(m.precompression for m in models):
        return interval
    tau = math.inf
    by_material: dict[Any, list[tuple[float, float]]] = {}  # last bead's material: (V, phi_N) per model
    for m in models:
        mat, d = m.chain.materials[-1], float(m.chain.diameters[-1])
        vmax = m.striker.velocity * math.sqrt(m.striker.mass / (mat.density * math.pi * d ** 3 / 6.0))
        if vmax > 0:
            by_material.setdefault(mat, []).append((vmax, d))
    for mat, rows in by_material.items():
        v, d = np.array(rows).T
        tau = min(tau, float(np.min(pulse_duration(d, solitary_wave_speed_from_velocity(mat, v)))))
    k = max(1, math.floor(tau / (SEARCH_SAMPLES_PER_PULSE * interval))) if math.isfinite(tau) else 1
    return k * interval if k * interval <= duration else interval


class Robust(BaseModel):
    """``[design.robust]``: scenarios every candidate is run in, and how they are summarised.

    Attributes
    ----------
    velocities : list of float
        Striker speeds [m/s] (default: the base config's only).
    tolerances : dict
        The sweep's tolerance model: ``diameter_rel`` (1 sigma), ``offset_mm`` [mm],
        ``distribution`` ("normal" or "uniform"), ``seed``.
    draws : int
        Monte Carlo draws of the tolerances per speed.
    statistic : {"worst", "mean", "mean+ksigma"}
        Summary of the scenarios' objective values.
    k : float
        Number of standard deviations for ``mean+ksigma``.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, allow_inf_nan=False)

    velocities: list[float] | None = None
    tolerances: dict[str, Any] | None = None
    draws: int = Field(default=1, ge=1)
    statistic: Literal["worst", "mean", "mean+ksigma"] = "worst"
    k: float = Field(default=2.0, ge=0)


@dataclass
class Evaluation:
    """What one candidate gave.

    Attributes
    ----------
    objectives : dict
        ``{name: value}`` [SI] summarised over the scenarios (NaN when not simulated).
    feasible : bool
        Every constraint holds (in every scenario).
    violation : float
        Summed relative constraint violation (0 when feasible).
    metrics : dict
        Geometry (``min_diameter_mm``, ``length_mm``, ``mass_kg``, ``n_beads``) and run outcomes
        (``force_over_yield``, ``pulse_at_wall``, ``energy_ok``: the energy balance held; with the
        elastoplastic law ``plastic_work_worst`` [J] and ``residual_overlap_max_worst`` [m], the
        largest over the scenarios).
    engine_runs : int
        Members simulated for it (0 when rejected on geometry or taken from the cache).
    fidelity : str
        :attr:`Fidelity.name` of the runs (``"full"`` or ``"search"``).
    """

    objectives: dict[str, float]
    feasible: bool
    violation: float
    metrics: dict[str, Any]
    engine_runs: int = 0
    fidelity: str = "full"

    def fitness(self, names: list[str]) -> list[float]:
        """Values the search minimises: the objectives when feasible, else INFEASIBLE + violation."""
        if self.feasible:
            return [self.objectives[n] for n in names]
        return [INFEASIBLE * (1.0 + self.violation)] * len(names)


def _pulses_passed(force: np.ndarray) -> np.ndarray:
    """Per member (rows of ``force``): the wall record holds a whole first pulse, it peaked before
    the end and fell to half its peak."""
    m, n = force.shape
    if n < 3:
        return np.zeros(m, dtype=bool)
    finite = np.all(np.isfinite(force), axis=1)
    f = np.where(finite[:, None], force, 0.0)
    peak = f.max(axis=1)
    top = np.argmax(f >= 0.999 * peak[:, None], axis=1)  # first sample at the pulse's top
    after = np.where(np.arange(n) >= top[:, None], f, np.inf).min(axis=1)
    return finite & (peak > 0.0) & (top < n - 1) & (after < 0.5 * peak)


def member_metrics(ds, objectives: list[str], window: tuple[float, float] | None = None) -> dict[str, np.ndarray]:
    """Per-member objective values and run outcomes of a stacked batch result.

    Parameters
    ----------
    ds : xarray.Dataset
        :func:`~hertzchain.runs.batch.simulate_batch` result (with ``wall_force``).
    objectives : list of str
        Names from :data:`OBJECTIVES` to compute.
    window : (float, float) or None
        Time window [s] of ``energy_at_wall``.

    Returns
    -------
    dict
        ``{name: array (member,)}`` for each objective, plus ``force_over_yield`` and
        ``pulse_at_wall`` (bool), and ``plastic_work`` and ``residual_overlap_max`` when a
        member has the elastoplastic law.
    """
    return _metrics(_records_of_dataset(ds), objectives, window)


@dataclass
class _Records:
    """What the objectives and checks read of a batch, (member, ...) arrays: times [s], wall force
    samples [N], refined peak wall force [N], largest sampled force of every contact [N] (NaN
    padded) and its F_Y [N], kappa of the bead N - wall contact [N/m^1.5], energies [J]
    (``dissipated``: viscous and plastic losses), and the elastoplastic law's plastic work [J]
    and largest residual overlap [m] at the end (None when no member has that law; 0 for the
    members of other laws)."""

    time: np.ndarray
    wall: np.ndarray
    peak_wall_force: np.ndarray
    fmax: np.ndarray
    yield_force: np.ndarray
    kappa_wall: np.ndarray
    kinetic: np.ndarray
    potential: np.ndarray
    dissipated: np.ndarray
    body: dict | None = None  # protected body: body_force [N], body_acceleration [m/s^2], body_energy [J]
    plastic_work: np.ndarray | None = None
    residual_overlap_max: np.ndarray | None = None


def _records_of_dataset(ds) -> "_Records":
    """:class:`_Records` of a stacked batch result."""
    nb = ds["n_beads"].values.astype(int)
    body = {k: ds[k].values for k in ("body_force", "body_acceleration", "body_energy")} if "body_force" in ds else None
    dissipated = ds["dissipated_energy"].values
    plastic = {}
    if "plastic_work" in ds:
        wp = np.nan_to_num(ds["plastic_work"].values)
        dissipated = dissipated + wp
        plastic = {"plastic_work": wp[:, -1],
                   "residual_overlap_max": np.nan_to_num(ds["residual_overlap"].values).max(axis=1)}
    return _Records(time=ds["time"].values, wall=ds["wall_force"].values, peak_wall_force=ds["peak_wall_force"].values,
                    fmax=ds["max_contact_force"].values, yield_force=ds["yield_force"].values,
                    kappa_wall=ds["kappa"].values[np.arange(nb.size), nb],  # contact N joins bead N and the wall
                    kinetic=ds["kinetic_energy"].values, potential=ds["potential_energy"].values,
                    dissipated=dissipated, body=body, **plastic)



def _records(runs, systems) -> _Records:
    """:class:`_Records` of :func:`hertzchain.runs.batch.run_batch`'s RawRuns and
    :class:`~hertzchain.runs.batch.MemberSystem` rows (``return_systems=True``): each member's
    bead count, Hertz constants and elastic limits, computed by the batched set-up (no
    ``Model.system()`` per member)."""
    m = len(runs)
    nc = max(r.max_force.size for r in runs)
    fmax = np.full((m, nc), np.nan)
    fy = np.full((m, nc), np.nan)
    for i, (r, sy) in enumerate(zip(runs, systems)):
        fmax[i, :r.max_force.size] = r.max_force
        fy[i, :r.max_force.size] = sy.yield_force[:r.max_force.size]
    n = np.array([sy.n_beads for sy in systems])
    wall = np.stack([r.contact_force[:, int(np.searchsorted(r.contacts, k))] for r, k in zip(runs, n)])
    dissipated = np.stack([r.dissipated_energy for r in runs])
    plastic = {}
    if any(r.plastic_work is not None for r in runs):
        wp = np.stack([np.zeros(r.time.size) if r.plastic_work is None else r.plastic_work for r in runs])
        dissipated = dissipated + wp
        plastic = {"plastic_work": wp[:, -1], "residual_overlap_max": np.array(
            [0.0 if r.residual_overlap is None or r.residual_overlap.size == 0 else float(r.residual_overlap.max())
             for r in runs])}
    return _Records(time=runs[0].time, wall=wall, peak_wall_force=np.array([r.peak_wall_force for r in runs]),
                    fmax=fmax, yield_force=fy, kappa_wall=np.array([sy.kappa[k] for sy, k in zip(systems, n)]),
                    kinetic=np.stack([r.kinetic_energy for r in runs]),
                    potential=np.stack([r.potential_energy for r in runs]), dissipated=dissipated,
                    body=body_records(runs, systems), **plastic)


def _metrics(rec: _Records, objectives: list[str], window: tuple[float, float] | None) -> dict[str, np.ndarray]:
    """:func:`member_metrics` of :class:`_Records`."""
    from ..analysis import fit_pulse

    fmax, wall, time = rec.fmax, rec.wall, rec.time
    n = wall.shape[0]
    ratio = np.nanmax(fmax / rec.yield_force, axis=1)
    out: dict[str, np.ndarray] = {"force_over_yield": ratio,
                                  "pulse_at_wall": _pulses_passed(wall)}
    if rec.plastic_work is not None:
        out["plastic_work"] = rec.plastic_work
        out["residual_overlap_max"] = rec.residual_overlap_max
    for name in objectives:
        if name == "peak_wall_force":
            out[name] = np.asarray(rec.peak_wall_force, dtype=float)
        elif name == "peak_contact_force":
            out[name] = np.nanmax(fmax, axis=1)
        elif name == "max_force_over_yield":
            out[name] = ratio
        elif name == "front_momentum_at_wall":
            q = np.full(n, np.nan)
            for i in range(n):  # analysis of the finished runs (the simulation itself was one call)
                try:
                    q[i] = fit_pulse(time, wall[i]).front_momentum
                except PulseNotFound:
                    out["pulse_at_wall"][i] = False
            out[name] = q
        elif name in PLASTIC_OBJECTIVES:
            if name not in out:  # no member has the elastoplastic law: no plastic work done
                out[name] = np.zeros(n)
        elif name == "energy_at_wall":
            kappa = rec.kappa_wall
            mask = np.ones(time.size, bool) if window is None else (time >= window[0]) & (time <= window[1])
            fpk = np.max(np.where(mask, np.maximum(wall, 0.0), 0.0), axis=1)
            out[name] = 0.4 * fpk ** (5.0 / 3.0) / kappa ** (2.0 / 3.0)
        elif name in BODY_OBJECTIVES:
            out[name] = body_objective(name, rec.body, wall.shape)
    return out


@dataclass
class _Task:
    """One engine call: models that share the duration and sample interval (picklable for Dask)."""

    models: list
    duration: float
    probes: Any
    dt: float | None
    objectives: list[str]
    window: tuple[float, float] | None
    device: str | None = None
    steps_per_radian: float | None = None


def _on_gpu(task: _Task) -> bool:
    """Whether the engine would run this task on the GPU (simulate_batch's device choice)."""
    from ..integrate.cuda import launch as cuda
    from ..integrate.batch.ensemble import same_layout

    if task.device in (None, "auto"):
        return (len(task.models) >= cuda.AUTO_MIN_MEMBERS and same_layout(task.models) and cuda.gpu_usable())
    return task.device == "cuda"


def run_task(task: _Task) -> dict[str, np.ndarray]:
    """Simulate a task's models in ONE batched engine call and return their :func:`member_metrics`.

    On the CPU the engine's arrays are used as they are (:func:`~hertzchain.runs.batch.run_batch`,
    no Dataset: stacking one costs more than a coarse run of a short chain); a task the GPU runs
    goes through :func:`~hertzchain.runs.batch.simulate_batch`.
    """
    from ..errors import ElasticLimitWarning, PulseNotReachedWarning
    from ..runs.batch import run_batch, simulate_batch

    with warnings.catch_warnings():
        # Designs past the elastic limit, or whose pulse misses the wall, are ranked by constraints
        # (max_force_over_yield, the pulse-at-wall one), not warned about.
        warnings.simplefilter("ignore", ElasticLimitWarning)
        warnings.simplefilter("ignore", PulseNotReachedWarning)
        if _on_gpu(task):
            ds = simulate_batch(task.models, task.duration, task.probes, dt=task.dt, device=task.device or "auto",
                                steps_per_radian=task.steps_per_radian)
            rec = _records_of_dataset(ds)
        else:
            runs, systems = run_batch(task.models, task.duration, task.probes, dt=task.dt,
                                      steps_per_radian=task.steps_per_radian, return_systems=True)
            rec = _records(runs, systems)
    out = _metrics(rec, task.objectives, task.window)
    out["energy_ok"] = _energy_ok(rec, task)
    return out


def _energy_ok(rec: _Records, task: _Task) -> np.ndarray:
    """Whether each member's energy balance holds (:mod:`hertzchain.checks`; the batched engine does
    not check it): a member that gains energy has wrong forces, so it is infeasible, never best."""
    from ..checks import energy_gain, energy_tolerance

    if task.dt is None:
        # the adaptive step's largest step is not stored per member: the minimum allowance then
        # (it needs no System: omega_max is only read for a user step)
        tol = np.full(len(task.models), energy_tolerance(None, 0.0))
    else:
        tol = np.array([energy_tolerance(model.system(), task.dt) for model in task.models])
    gain = energy_gain(rec.kinetic, rec.potential, rec.dissipated)
    return np.all(np.isfinite(gain) & (gain <= tol[:, None]), axis=1)


def summarise(values: np.ndarray, statistic: str, k: float) -> float:
    """Worst case, mean, or mean + k sigma of one candidate's scenario values."""
    if values.size == 1:
        return float(values[0])
    if statistic == "worst":
        return float(values.max())
    if statistic == "mean":
        return float(values.mean())
    return float(values.mean() + k * values.std(ddof=1))


class Candidate(NamedTuple):
    """What a candidate's geometry check built: its run config, its validated ``[chain]``
    section, its :class:`~hertzchain.chain.Chain`, its
    :func:`~hertzchain.design.constraints.geometry` and its
    :func:`~hertzchain.design.constraints.geometric_margin` (>= 0: meets the geometric
    constraints). A named tuple: a search builds thousands."""

    config: dict
    section: Any
    chain: Any
    geometry: dict
    margin: float


@dataclass
class Evaluator:
    """Evaluates candidates (run configs): geometry first, then every scenario in one engine call.

    Parameters
    ----------
    objectives : list of str
        Objective names (:data:`OBJECTIVES`).
    constraints : Constraints
        The design's constraints.
    robust : Robust or None
        Scenarios (speeds x tolerance draws).
    window : (float, float) or None
        Time window [s] of ``energy_at_wall``.
    client : object
        None (one local call per generation) or a Dask client / executor (chunks of
        ``chunk_size`` members per task).
    chunk_size : int
        Members per task when a client spreads a generation.
    device : str or None
        Passed to the engine when it takes one.
    fidelity : Fidelity
        The accuracy the candidates are run at (default: each config's own).
    base : dict or None
        The base run config the candidates derive from (:class:`~hertzchain.design.space.Space`
        copies on write): a candidate that differs from it in ``[chain]`` only gets its model
        from the base's validated sections and the chain its geometry check built. None: every
        candidate's config is validated whole.
    candidates : dict
        :class:`Candidate` by candidate key, built by :meth:`candidate` since the last
        :meth:`evaluate` (which empties it: the repair's checks of a generation are what its run
        reuses, and a search's worth of chains would only weigh on memory).
    """

    objectives: list[str]
    constraints: Constraints
    robust: Robust | None = None
    window: tuple[float, float] | None = None
    client: Any = None
    chunk_size: int = 64
    device: str | None = None
    cache: dict = field(default_factory=dict)
    fidelity: Fidelity = Fidelity()
    base: dict | None = None
    candidates: dict = field(default_factory=dict, repr=False)
    _base_run: Any = field(default=None, init=False, repr=False)
    _memory_checked: set = field(default_factory=set, init=False, repr=False)

    @property
    def n_scenarios(self) -> int:
        """Engine runs per candidate."""
        if self.robust is None:
            return 1
        return len(self.robust.velocities or [None]) * self.robust.draws

    def _scenario_models(self, cfg: dict, nominal) -> list:
        from ..sweep.tolerances import Tolerances, apply_to_model

        if self.robust is None:
            return [nominal]
        out = []
        tol = Tolerances(**self.robust.tolerances) if self.robust.tolerances else None
        for v in self.robust.velocities or [None]:
            model = nominal if v is None else build_model(parse_config(
                {**cfg, "striker": {**cfg.get("striker", {}), "velocity": v}}))
            for d in range(self.robust.draws):
                out.append(model if tol is None else apply_to_model(model, tol, d))
        return out

    def _check_memory(self, models: list, duration: float, probes) -> None:
        """Refuse an engine call whose records cannot fit in memory (hertzchain.checks), naming the
        setting that sizes it: the population (one call per generation) or the Dask chunk size.
        The records' size depends on the largest bead count and the member count only: each pair
        is checked once."""
        from ..checks import check_resources, estimate_memory

        members = len(models) if self.client is None else min(self.chunk_size, len(models))
        n_beads = max(m.chain.n_beads for m in models)
        has_wall = any(m.wall.present for m in models)
        seen = (n_beads, has_wall, members, duration, probes.sample_interval)
        if seen in self._memory_checked:
            return
        check_resources(estimate_memory(n_beads, has_wall, duration, probes, members),
                        memory_field="design.population" if self.client is None else "design.chunk_size")
        self._memory_checked.add(seen)

    def candidate(self, key, config: dict | Callable[[], dict]) -> Candidate:
        """The chain and geometry of a candidate (no run), built once per ``key``.

        Parameters
        ----------
        key : hashable
            The candidate's identity (:meth:`~hertzchain.design.space.Space.key`).
        config : dict or callable
            Its run config, or a function that builds it (called only when ``key`` is new).

        Returns
        -------
        Candidate
            Section, chain, geometry and geometric margin (>= 0: every geometric constraint holds).
        """
        cand = self.candidates.get(key)
        if cand is None:
            cfg = config() if callable(config) else config
            section, chain = chain_parts(cfg)
            geo = geometry(chain)
            cand = Candidate(cfg, section, chain, geo, geometric_margin(self.constraints, geo))
            self.candidates[key] = cand
        return cand

    def _run_config(self, cand: Candidate):
        """The validated run config of a candidate: the base's sections with the candidate's
        ``[chain]`` when nothing else differs (the sections are shared by identity: copy on
        write), else the whole config validated."""
        cfg = cand.config
        base = self.base
        if (base is not None and cfg.keys() == base.keys()
                and all(v is base[k] for k, v in cfg.items() if k != "chain")):
            if self._base_run is None:
                self._base_run = parse_config(base)
            return self._base_run.model_copy(update={"chain": cand.section})
        return parse_config(cfg)

    def evaluate(self, keys: list, configs: list[dict | Callable[[], dict]]) -> list[Evaluation]:
        """Evaluate candidates (``keys`` identify equal candidates: each is simulated once, ever;
        ``configs``: their run configs, or functions that build them, called only for candidates
        not evaluated before)."""
        from ..probes import Probes

        results: dict[int, Evaluation] = {}
        pending: dict[Any, tuple[int, dict, dict, Any]] = {}
        run0 = None
        for i, (key, cfg) in enumerate(zip(keys, configs)):
            if key in self.cache:
                results[i] = replace(self.cache[key], engine_runs=0)
                continue
            if key in pending:
                continue
            cand = self.candidate(key, cfg)
            cfg = cand.config
            geo = cand.geometry
            viol = geometric_violation(self.constraints, geo)
            if viol > 0:
                ev = Evaluation({n: math.nan for n in self.objectives}, False, viol, dict(geo),
                                fidelity=self.fidelity.name)
                self.cache[key] = ev
                results[i] = ev
            else:
                run_cfg = self._run_config(cand)
                run0 = run0 or run_cfg
                pending[key] = (i, cfg, geo, build_model(run_cfg, chain=cand.chain))
        if pending:
            models, counts = [], []  # each candidate's scenario runs are contiguous
            for _i, cfg, _geo, model in pending.values():
                ms = self._scenario_models(cfg, model)
                models += ms
                counts.append(len(ms))
            fid = self.fidelity
            interval = build_probes(run0).sample_interval
            if fid.coarse_sampling:  # from every scenario: a faster striker gives a shorter pulse
                interval = search_interval(models, interval, run0.run.duration)
            probes = Probes(sample_interval=interval, contacts=())
            spr = fid.steps_per_radian or run0.run.steps_per_radian
            self._check_memory(models, run0.run.duration, probes)
            tasks = [_Task(models[s:s + self.chunk_size], run0.run.duration, probes, run0.run.dt, self.objectives,
                           self.window, self.device, spr)
                     for s in range(0, len(models), self.chunk_size)] if self.client is not None else \
                [_Task(models, run0.run.duration, probes, run0.run.dt, self.objectives, self.window, self.device, spr)]
            parts = _gather(self.client, tasks)
            merged = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
            # Per candidate, over its scenario runs: worst yield ratio, every pulse arrived, every
            # energy balance held (as Python values, once for the whole generation).
            starts = np.cumsum([0] + counts[:-1])
            fys = np.maximum.reduceat(merged["force_over_yield"], starts).tolist()
            pulses = np.logical_and.reduceat(merged["pulse_at_wall"], starts).tolist()
            energies = np.logical_and.reduceat(merged["energy_ok"], starts).tolist()
            # elastoplastic law: the worst plastic work and permanent overlap over the scenarios
            plastic = {k: np.maximum.reduceat(merged[k], starts).tolist()
                       for k in ("plastic_work", "residual_overlap_max") if k in merged}
            values = {n: merged[n].tolist() for n in self.objectives}
            for j, (key, (i, _cfg, geo, _)) in enumerate(pending.items()):
                s0, c = int(starts[j]), counts[j]
                fy, pulse, energy = fys[j], pulses[j], energies[j]
                objs = {n: (summarise(merged[n][s0:s0 + c], self.robust.statistic, self.robust.k) if self.robust
                            else values[n][s0]) for n in self.objectives}
                worst = {k: v[j] for k, v in plastic.items()}
                viol = run_violation(self.constraints, fy, pulse, **worst)
                if any(not math.isfinite(v) for v in objs.values()) or not energy:
                    viol = max(viol, 1.0)  # no objective value (no pulse to fit) or a wrong run: infeasible
                metrics = {**geo, "force_over_yield": fy, "pulse_at_wall": pulse, "energy_ok": energy,
                           **{f"{k}_worst": v for k, v in worst.items()}}
                self.cache[key] = Evaluation(objs, viol == 0, viol, metrics, fidelity=fid.name)
                results[i] = Evaluation(objs, viol == 0, viol, metrics, engine_runs=c, fidelity=fid.name)
        self.candidates.clear()
        out = []
        for i, key in enumerate(keys):
            out.append(results[i] if i in results else replace(self.cache[key], engine_runs=0))
        return out


def _gather(client, tasks: list[_Task]) -> list[dict]:
    """Run the tasks here (client None) or on the client, results in task order."""
    from ..parallel import results_in_order

    return results_in_order(client, run_task, tasks)
