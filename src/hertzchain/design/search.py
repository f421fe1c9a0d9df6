"""The search: a population method, then a local polish; one engine call per generation, checkpointed.

One objective: a Latin hypercube over the whole space, then CMA-ES (:mod:`cma`) from its best
point (restarted with a doubled population whenever it converges
while budget is left: IPOP-CMA-ES) in the unit cube of the design space (bounds [0, 1]; integer,
catalogue and categorical coordinates are binned, see :mod:`hertzchain.design.space`, and keep a
minimal step so that they go on exploring), then a batched compass search: all neighbours of the
best point (+- h on every real coordinate, the next bin up and down on every discrete one) in
one engine call; move to the best improving neighbour, else halve h, until h < 1e-4 or the
budget is spent. Several objectives: NSGA-II (:mod:`pymoo`) and the non-dominated feasible
candidates ever evaluated as the Pareto front.

Gradients: where every variable is a continuous config field that the sensitivity engine
differentiates and the objective is one it knows (:func:`~hertzchain.design.gradient.gradient_support`:
per-bead profiles, striker, law constants; no geometric constraint, no robust scenarios), the
initial sample is followed by local searches on exact gradients (L-BFGS-B,
:mod:`hertzchain.design.gradient`) from its best points, each outside the basins already
searched; CMA-ES restarts supply new starts when those run out (a local search is one generation).

Geometric constraints (smallest bead, length, mass, bead count) are checked without a run, and
optima often lie on them: in a space with a real variable, a candidate that breaks one is moved
onto its boundary by root finding on the geometry (:mod:`hertzchain.design.boundary`), towards the
nearest feasible point of the initial sample, towards the best feasible point in CMA-ES (which
learns from the point it sampled, charged with the distance it was moved), or along its
coordinate in the polish; and the initial sample also holds the boundary point of every discrete
choice it samples.

Multi-fidelity: the search runs candidates at the coarse accuracy of
:func:`~hertzchain.design.problem.search_fidelity` (``design.search_steps_per_radian``); when it
ends, the ``design.verify_top`` best distinct feasible candidates are run again at the base
config's own accuracy in one engine call (phase ``verify``), and the best is chosen among those
values only, so that ``best.toml`` run by ``hertzchain run`` gives the reported objective. A
candidate feasible at search accuracy but not at full accuracy is dropped (the next best ones are
verified while the budget allows). Those runs are set aside from the budget before the search
starts; ``history.csv`` says which fidelity each row has.

Every generation (population or polish step) is evaluated in ONE batched engine call
(:class:`~hertzchain.design.objectives.Evaluator`), then the whole search state (optimiser,
random streams, history, evaluated candidates) is written to ``checkpoint.npz`` (at most once
a second when generations are faster than that), as data only (:mod:`hertzchain.design.checkpoint`);
a rerun with the same design and output folder replays the saved generations without engine
runs and ends with the same result as an uninterrupted run. The random streams are seeded by
``[design].seed`` only.
"""

from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..errors import ConfigError, HertzchainError
from ..parallel import worker_threads
from .boundary import _BOUNDARY_SLACK, _margin, _repair_initial, _repair_point, _repairs, _to_boundary
from .checkpoint import DesignMismatch, Replay, ReplayDiverged, _load, _save, set_aside
from .gradient import gradient_step, gradient_support, initial_points
from .history import best_row, best_x, pareto_rows
from .objectives import INFEASIBLE, Evaluator, Fidelity
from .problem import DesignProblem, search_fidelity

__all__ = ["DesignResult", "run_design", "DesignMismatch", "DesignLocked"]

#: Generations without a better best after which the population phase hands over to the polish.
_STALL_GENERATIONS = 5
#: Most IPOP restarts: a fully explored discrete space ends the search.
_MAX_RESTARTS = 6
#: The population doubles at the first restarts only: a generation is one engine call whose
#: records (wall force, energies) grow with its size.
_MAX_DOUBLINGS = 2
#: Initial and smallest polish step (unit-cube coordinates).
_POLISH_H0, _POLISH_HMIN = 0.05, 1e-4


class DesignLocked(HertzchainError):
    """Another design search is writing into the same output folder."""


class _Randn:
    """Normal sampler of CMA-ES with a generator of its own (seeded from ``[design].seed``; its
    state is part of the checkpoint)."""

    def __init__(self, seed: int, restart: int):
        self.rng = np.random.default_rng([seed, 12, restart])

    def __call__(self, *shape: int) -> np.ndarray:
        return self.rng.standard_normal(shape)


@dataclass
class _State:
    hash: str
    phase: str = "population"          # "population" -> "polish" -> "done"
    generation: int = 0
    optimiser: Any = None
    restarts: int = 0
    stall: int = 0
    best_f: float = math.inf
    polish_x: np.ndarray | None = None
    polish_h: float = _POLISH_H0
    history: list[dict] = field(default_factory=list)
    cache: dict = field(default_factory=dict)
    full_cache: dict = field(default_factory=dict)  # candidates run again at full accuracy (verify)
    verified: bool = False
    n_evaluations: int = 0
    elapsed_s: float = 0.0
    # JSON text of the history rows and cache entries already written to the checkpoint: they never
    # change once added, so a save serialises only what is new (hertzchain.design.checkpoint._save).
    written: dict = field(default_factory=dict, repr=False)
    gradient_used: list = field(default_factory=list)    # starts of the gradient phase's local searches
    gradient_optima: list = field(default_factory=list)  # where they ended


@dataclass
class DesignResult:
    """What :func:`hertzchain.run_design` found.

    Attributes
    ----------
    problem : DesignProblem
        The design.
    best : dict or None
        ``{"objective": value or {name: value}, "variables": {PATH: value}, "feasible": bool,
        "config": run config, "metrics": {...}}`` of the best feasible candidate (the least
        infeasible one when none is feasible).
    history : list of dict
        One row per candidate evaluated (generation, phase, variables, objectives, feasibility,
        ``fidelity``: ``"search"`` for the coarse search runs, ``"full"`` for runs at the base
        config's accuracy).
    pareto : list of dict
        Non-dominated feasible rows (several objectives; the best row for one).
    n_evaluations : int
        Engine runs made (candidates x scenarios; cached repeats and geometry rejections are free).
    generations : int
        Engine calls made (population generations and polish steps).
    elapsed_s : float
        Wall-clock time of the search [s], summed over resumed runs.
    out_dir : Path
        Output folder.
    resumed : bool
        The run continued from a checkpoint.
    """

    problem: DesignProblem
    best: dict | None
    history: list[dict]
    pareto: list[dict]
    n_evaluations: int
    generations: int
    elapsed_s: float
    out_dir: Path
    resumed: bool

    def __repr__(self) -> str:
        # The history holds a row per candidate (thousands): the summary says what was found.
        best = "no candidate"
        if self.best is not None:
            obj = self.best["objective"]
            value = (", ".join(f"{k} = {v:.4g}" for k, v in obj.items()) if isinstance(obj, dict)
                     else f"{', '.join(self.problem.objectives)} = {obj:.4g}")
            feasible = "" if self.best.get("feasible", True) else " (infeasible: the least violating)"
            best = f"best {value} at {self.best['variables']}{feasible}"
        front = f", Pareto front of {len(self.pareto)}" if len(self.problem.objectives) > 1 else ""
        return (f"DesignResult({best}{front}; {self.n_evaluations} engine runs, {len(self.history)} candidates, "
                f"{self.elapsed_s:.3g} s; {str(self.out_dir)!r})")


def _population(problem: DesignProblem) -> int:
    """Candidates per generation: ``[design].population``, else 40 for NSGA-II (several
    objectives) and max(8, CMA-ES's 4 + 3 ln d) for CMA-ES. Each candidate costs its own set-up
    and run (~0.1 ms for a short chain at search accuracy), so CMA-ES's small generations reach
    a given quality sooner than generations of a few dozen (n-q benchmark problem, 20 seeds: a
    median 25 ms to 1 % with 8, 36 ms with 32)."""
    if problem.section.population:
        return problem.section.population
    if len(problem.objectives) > 1:
        return 40
    return max(8, 4 + int(3 * math.log(max(problem.space.dim, 2))))


def _initial_sample(problem: DesignProblem) -> int:
    """Points of the Latin hypercube that starts a one-objective search: ``[design].population``,
    else the CMA-ES population and at least 16 points where the first sample is repaired onto the
    geometric limits (:func:`_repair_initial`: a limit and a real variable), 32 elsewhere: the
    whole space is surveyed once before CMA-ES starts from its best point. With the repair and
    the discrete choices' boundary points 16 points did as well as 32 for less (n-q benchmark
    problem, 40 seeds: the optimum in the first generation every time either way, 10 ms against
    14.5 ms; ``examples/design_taper.toml``: the same optimum on 3 seeds). Without them
    (``examples/design_robust.toml``: catalogue sizes only) the sample is all there is to start
    from, and 32 it stays."""
    if problem.section.population:
        return problem.section.population
    return max(16 if _repairs(problem) else 32, _population(problem))


def _new_optimiser(problem: DesignProblem, restart: int = 0, x0: np.ndarray | None = None):
    """CMA-ES from ``x0`` (one objective; ``restart`` r > 0: population x 2^r from a random start,
    IPOP-CMA-ES) or NSGA-II (several)."""
    sec = problem.section
    dim = problem.space.dim
    if len(problem.objectives) == 1:
        import cma

        pop = _population(problem) * 2 ** min(restart, _MAX_DOUBLINGS)
        # A discrete coordinate keeps a step of ~1/3 of its bin: otherwise CMA-ES freezes it as
        # soon as the step is below one bin (a plateau of equal fitness), before it has settled.
        minstd = [0.3 / v.n_values if v.kind != "real" else 0.0 for v in problem.space.variables]
        # cma needs two coordinates: a 1-D space gets a dummy one that decodes to nothing (_coords).
        minstd += [0.0] * (max(dim, 2) - dim)
        randn = _Randn(sec.seed, restart)
        start = np.full(max(dim, 2), 0.5)
        if x0 is not None:
            start[:dim] = x0
        elif restart > 0:
            start = randn.rng.uniform(0.0, 1.0, max(dim, 2))
        opts = {"bounds": [0.0, 1.0], "seed": sec.seed + 1, "popsize": pop, "randn": randn,
                "verbose": -9, "verb_log": 0, "verb_disp": 0, "minstd": minstd, "tolfun": 1e-9, "tolx": 1e-6}
        return cma.CMAEvolutionStrategy(start, 0.2 if x0 is not None else 0.3, opts)
    from pymoo.algorithms.moo.nsga2 import NSGA2  # the [design] extra, checked by run_design
    from pymoo.core.problem import Problem

    algo = NSGA2(pop_size=_population(problem))
    algo.setup(Problem(n_var=dim, n_obj=len(problem.objectives), xl=0.0, xu=1.0), seed=sec.seed, verbose=False)
    return algo


def _coords(problem: DesignProblem, x: np.ndarray) -> np.ndarray:
    """The space's coordinates of an optimiser point (drops the dummy coordinate of a 1-D space)."""
    return np.asarray(x, float)[: problem.space.dim]


def _row(problem: DesignProblem, state: _State, phase: str, x: np.ndarray, ev, values: dict) -> dict:
    row = {"evaluation": len(state.history), "generation": state.generation, "phase": phase}
    row.update({k: (list(v) if isinstance(v, (list, tuple)) else v) for k, v in values.items()})
    row.update(ev.objectives)
    row.update(feasible=ev.feasible, violation=ev.violation, **ev.metrics, engine_runs=ev.engine_runs,
               fidelity=ev.fidelity, x=[float(v) for v in x])
    return row


def _evaluate(problem: DesignProblem, evaluator: Evaluator, state: _State, xs: list[np.ndarray], phase: str,
              clock: Callable[[], float], replay: Replay | None = None):
    """Evaluate unit-cube points in one engine call; append them to the history; return their fitness.
    While ``replay`` has saved generations left, they are taken from it instead (no engine run)."""
    if replay is not None and replay.active:
        evaluator.candidates.clear()  # as evaluate() does: the repair's chains were for this generation
        return replay.evaluate(problem, state, xs, phase)
    space = problem.space
    values = [space.values(x) for x in xs]
    keys = [space.key_of(v) for v in values]
    evaluator.cache = state.full_cache if evaluator.fidelity.name == "full" and phase == "verify" else state.cache
    evs = evaluator.evaluate(keys, [functools.partial(space.config, v) for v in values])
    elapsed = clock()
    for x, vals, ev in zip(xs, values, evs):
        state.n_evaluations += ev.engine_runs
        state.history.append({**_row(problem, state, phase, x, ev, vals), "elapsed_s": elapsed})
    return [ev.fitness(problem.objectives) for ev in evs]


def _polish_neighbours(problem: DesignProblem, x: np.ndarray, h: float, evaluator: Evaluator) -> list[np.ndarray]:
    """Compass neighbours of ``x``: +- h on every real coordinate, the next bin on every discrete
    one; a real step that breaks a geometric constraint stops on its boundary instead."""
    out = []
    repair = _repairs(problem)
    f_x = _margin(problem, evaluator, x) if repair else None
    for j, v in enumerate(problem.space.variables):
        step = h if v.kind == "real" else 1.0 / v.n_values
        for s in (-step, step):
            y = x.copy()
            y[j] = min(max(y[j] + s, 0.0), 1.0)
            y = problem.space.centre(y)
            # stop on the boundary only from a point inside it (f_x: set when repairing)
            if f_x is not None and v.kind == "real" and f_x >= 0:
                f_y = _margin(problem, evaluator, y)
                if f_y < 0:
                    # The accepted band narrows with the step, so that the polish closes in on the
                    # boundary (at the first steps' width, every step would stop as far from it).
                    y = _to_boundary(problem, evaluator, x, y, max(1, math.ceil(math.log2(h / _POLISH_HMIN))),
                                     f_x, f_y, slack=_BOUNDARY_SLACK * min(1.0, h / _POLISH_H0))
            if not np.array_equal(y, x):
                out.append(y)
    return out


def _repair(problem: DesignProblem, evaluator: Evaluator, state: _State, xs: list[np.ndarray]) -> list[np.ndarray]:
    """Population candidates that break a geometric constraint, moved onto its boundary on their
    way to the best feasible point so far (:func:`_to_boundary`); the others unchanged."""
    best = best_row(problem, state.history)
    if best is None or not best["feasible"] or not _repairs(problem):
        return xs
    good = np.asarray(best["x"], float)
    out = []
    for x in xs:
        c = _coords(problem, x)
        f = _margin(problem, evaluator, c)
        if f < 0:
            c = _repair_point(problem, evaluator, good, c, None, f)
            x = np.concatenate([c, np.asarray(x, float)[problem.space.dim:]])
        out.append(x)
    return out



def _verify(problem: DesignProblem, search: Evaluator, state: _State, budget: int, clock,
            replay: Replay | None = None) -> None:
    """Run the best distinct candidates of the search again at full accuracy (phase ``verify``).

    The ``verify_top`` best feasible search rows go to one engine call; when none of them is
    feasible at full accuracy (a constraint the coarse runs met only just), the next ones are
    run while the budget allows. Without any feasible search row, the least infeasible one is
    run, so that the reported best always has a full-accuracy value.
    """
    from dataclasses import replace as _replace

    full = _replace(search, fidelity=Fidelity(), cache=state.full_cache)
    space = problem.space
    obj = problem.objectives[0]
    rows = sorted((r for r in state.history if r["fidelity"] == "search" and r["feasible"]),
                  key=lambda r: (r[obj], r["evaluation"]))
    if not rows:
        least = best_row(problem, state.history, "search")
        rows = [least] if least is not None else []
    queue, seen = [], set()
    for r in rows:
        key = space.key(np.asarray(r["x"]))
        if key not in seen:
            seen.add(key)
            queue.append(np.asarray(r["x"], float))
    k = problem.section.verify_top
    per = full.n_scenarios
    while queue:
        batch, queue = queue[:k], queue[k:]
        _evaluate(problem, full, state, batch, "verify", clock, replay)
        if any(r["feasible"] for r in state.history if r["fidelity"] == "full"):
            return
        k = min(k, (budget - state.n_evaluations) // per)
        if k < 1:
            return


def preflight(problem: DesignProblem, client=None, chunk_size: int | None = None):
    """The design's pre-flight, before any candidate is built: one generation must fit the budget
    and the memory, and a search projected past a few minutes says so (LongRunWarning).

    A generation is ``design.population`` candidates x the robust scenarios, run in one engine
    call (a Dask ``chunk_size`` at a time with a client); its records are estimated from the base
    config's chain, and the search's time as ``design.budget`` runs of the base chain at the
    search's accuracy, over the cores.

    Parameters
    ----------
    problem : DesignProblem
        The design.
    client : object
        The Dask client, or None (one local engine call per generation).
    chunk_size : int or None
        Members per Dask task (``design.chunk_size``).

    Returns
    -------
    hertzchain.checks.ResourceEstimate
        The estimate of the whole search (``members``: one generation's engine runs).

    Raises
    ------
    ConfigError
        One generation costs more engine runs than the budget (naming ``design.population``), or
        its records do not fit in memory (naming ``design.population`` or ``design.chunk_size``).
    """
    from dataclasses import replace as _replace

    import numba

    from ..checks import check_resources, estimate_memory, estimate_resources
    from ..config import build_model, parse_config
    from ..probes import Probes

    sec = problem.section
    per = Evaluator(problem.objectives, sec.constraints, sec.robust).n_scenarios
    fidelity = search_fidelity(problem)
    # The full-accuracy runs of the best candidates are set aside from the budget of the search.
    reserve = sec.verify_top * per if fidelity.name != "full" else 0
    if reserve and sec.budget <= reserve:
        raise ConfigError("design.budget", f"{sec.budget} engine runs leave nothing to search with after the "
                          f"{reserve} set aside to run the design.verify_top = {sec.verify_top} best candidates "
                          "again at full accuracy; raise the budget, lower design.verify_top, or set "
                          "design.search_steps_per_radian = \"full\"")
    distinct = math.prod(v.n_values for v in problem.space.variables) if not problem.space.real.any() else math.inf
    first = min(_initial_sample(problem), distinct)
    if first * per > sec.budget - reserve:
        raise ConfigError("design.population", f"a generation of {first:,} candidates x {per} scenario(s) costs "
                          f"{first * per:,} engine runs, more than the {sec.budget - reserve:,} of design.budget = "
                          f"{sec.budget:,} left for the search: lower design.population or raise design.budget")
    model = build_model(cfg := parse_config(problem.base))
    members = int(min(max(_population(problem), first) * per, sec.budget))  # later generations: checked as they come
    members = members if client is None else min(members, chunk_size or sec.chunk_size)
    probes = Probes(sample_interval=cfg.run.sample_interval, contacts=())
    assert isinstance(cfg.run.duration, float)  # build_problem wrote the automatic duration into [base.run]
    one = estimate_resources(model.system(), cfg.run.duration, probes, dt=cfg.run.dt,
                             steps_per_radian=fidelity.steps_per_radian or cfg.run.steps_per_radian)
    mem = estimate_memory(model.chain.n_beads, model.wall.present, cfg.run.duration, probes, members)
    threads = numba.config.NUMBA_NUM_THREADS  # type: ignore[attr-defined]  # numba sets it at import
    parallel = max(1, min(threads, members)) if client is None else worker_threads(client)
    est = _replace(mem, steps=one.steps, seconds=one.seconds * sec.budget / parallel)
    field = "design.population" if client is None else "design.chunk_size"
    check_resources(est, memory_field=field,
                    memory_hint=f"lower {field} ({members:,} engine runs a generation at most), raise "
                                "run.sample_interval of [base] or shorten its run.duration",
                    time_hint="lower design.budget, or spread the generations over a Dask cluster (--scheduler)"
                    if client is None else f"that is on the cluster's {parallel} worker threads; lower design.budget")
    return est


def run_design(problem: DesignProblem, out_dir: str | Path, *, client=None, device: str | None = None,
               progress: Callable[[int, int], None] | None = None, force: bool = False,
               checkpoint_interval: float = 1.0) -> DesignResult:
    """Run (or resume) a design search; the state is checkpointed after engine calls (see checkpoint_interval).

    Parameters
    ----------
    problem : DesignProblem
        From :func:`hertzchain.load_design` / :func:`hertzchain.parse_design`.
    out_dir : str or Path
        Output folder: ``checkpoint.npz`` during the search (see :func:`hertzchain.write_report`
        for the files written at the end).
    client : object
        None: each generation is one local engine call on all cores. A Dask
        ``distributed.Client`` (or an executor): a generation is split into tasks of
        ``[design].chunk_size`` members spread over its workers.
    device : str or None
        Passed to the engine (``simulate_batch(..., device=)``) when given.
    progress : callable
        ``progress(evaluations_done, budget)`` after every engine call.
    force : bool
        Start afresh when ``out_dir`` holds the checkpoint of another design.
    checkpoint_interval : float
        Least time [s] between two checkpoint saves (0: after every generation); the state is
        always saved at the end.

    Returns
    -------
    DesignResult
        The best candidate, the history, the Pareto front and the counts.

    Raises
    ------
    DesignMismatch
        ``out_dir`` holds the checkpoint of another design (and ``force`` is false).
    DesignLocked
        Another search is writing into ``out_dir``.
    ConfigError
        A bad setting, or one the pre-flight (:func:`preflight`) refuses: a generation beyond the
        budget or the memory.
    """
    from ..extras import require
    from ..sweep.storage import _folder_lock

    # CMA-ES, the best.toml writer and (a Pareto front) pymoo: the [design] extra, said before any work.
    several = len(problem.objectives) > 1
    require("design", "design.objective" if several else "design", ("cma", "tomli_w") + ("pymoo",) * several)
    preflight(problem, client)  # before any candidate or folder: the budget, the memory, the time
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(str(out), f"cannot create the output folder: {exc.strerror}") from None
    from ..interrupts import latched

    # Two searches writing one checkpoint would corrupt each other: the folder is locked (flock);
    # a Ctrl-C is never swallowed by a cleanup between engine calls (hertzchain.interrupts).
    with _folder_lock(out, "design", DesignLocked), latched():
        saved = _load(out, problem, force)
        try:
            return _run_design(problem, out, client, device, progress, checkpoint_interval, saved)
        except ReplayDiverged as exc:
            assert saved is not None  # (only a saved search replays)
            # Another program version (or an edited file) wrote it: its generations are not this
            # search's. Kept aside, and the search starts from its seed.
            set_aside(saved.path, f"does not replay to the search it was saved from ({exc})")
            return _run_design(problem, out, client, device, progress, checkpoint_interval, None)


def _run_design(problem: DesignProblem, out: Path, client, device, progress, checkpoint_interval: float,
                saved) -> DesignResult:
    """:func:`run_design` with the output folder locked, replaying the checkpoint ``saved`` (or None)."""
    sec = problem.section
    fidelity = search_fidelity(problem)
    coarse = fidelity.name != "full"
    evaluator = Evaluator(problem.objectives, sec.constraints, sec.robust,
                          None if sec.window is None else (sec.window[0], sec.window[1]), client, sec.chunk_size,
                          device, fidelity=fidelity, base=problem.base)
    replay = Replay(saved) if saved is not None else None
    resumed = replay is not None
    state = _State(problem.hash)
    per_candidate = evaluator.n_scenarios
    # The full-accuracy runs of the best candidates are set aside from the budget of the search.
    reserve = sec.verify_top * per_candidate if coarse else 0  # checked by the pre-flight: < budget
    budget = sec.budget - reserve
    multi = len(problem.objectives) > 1
    # Continuous variables and an objective the sensitivity engine differentiates: local searches
    # on exact gradients (design.gradient) take the place of CMA-ES after the initial sample.
    gradients = not multi and sec.polish and gradient_support(problem) is None
    t_start = time.perf_counter()
    t_saved = saved.elapsed_s if saved is not None else 0.0

    def clock() -> float:
        return t_saved + time.perf_counter() - t_start

    # The first save comes after checkpoint_interval too: a kill loses at most that much work,
    # and a search shorter than that saves once, at the end.
    last_save = [t_saved]

    def checkpoint(final: bool = False) -> None:
        state.elapsed_s = clock()
        if replay is not None:
            replay.check(state)  # once the saved generations are replayed: the saved state reached?
            if replay.active:  # nothing new to save yet
                return
        # Saving costs a serialisation and an fsync (~10 ms): on fast generations, at most one save
        # per checkpoint_interval seconds, so a kill loses at most that much work.
        if final or state.elapsed_s - last_save[0] >= checkpoint_interval:
            _save(out, state)
            last_save[0] = state.elapsed_s
        if progress is not None:
            progress(min(state.n_evaluations, budget), budget)

    if progress is not None:
        progress(min(state.n_evaluations, budget), budget)
    def improved() -> bool:
        """Whether the best fitness improved since the last call (tracks stagnation)."""
        best = best_row(problem, state.history)
        assert best is not None  # (called after a generation: the history holds its rows)
        f = best[problem.objectives[0]] if best["feasible"] else INFEASIBLE * (1.0 + best["violation"])
        if f < state.best_f - 1e-12 * abs(state.best_f):
            state.best_f = f
            return True
        return False

    def restart() -> bool:
        """A CMA-ES restart (IPOP) for the gradient phase, whose best is searched next; False when
        the restarts are spent."""
        if state.restarts >= _MAX_RESTARTS:
            return False
        state.restarts += 1
        state.optimiser = _new_optimiser(problem, state.restarts)
        state.phase, state.stall = "population", 0
        return True

    def next_cycle() -> None:
        """After a converged or stalled population phase: polish (with gradients where the design
        allows them); after a polish: restart (IPOP)."""
        if state.phase == "population" and gradients:
            state.phase = "gradient"
        elif state.phase == "population" and sec.polish and not multi:
            state.phase, state.polish_x = "polish", None
        elif state.restarts < _MAX_RESTARTS and not multi:
            state.restarts += 1
            state.optimiser = _new_optimiser(problem, state.restarts)
            state.phase, state.stall = "population", 0
        else:
            state.phase = "done"

    while state.phase != "done":
        if state.phase == "population" and state.optimiser is None and not multi:
            # Generation 0: a Latin hypercube over the whole space (seeded), so that CMA-ES starts
            # from the best region found rather than from the centre of the box.
            from scipy.stats import qmc

            pop0 = _initial_sample(problem)
            xs = list(qmc.LatinHypercube(d=problem.space.dim, seed=np.random.default_rng([sec.seed, 11])).random(pop0))
            xs = _repair_initial(problem, evaluator, xs)
            if gradients:
                xs = initial_points(problem, xs)
            if len({problem.space.key(x) for x in xs}) * per_candidate > budget:
                raise ConfigError("design.budget", f"{budget} engine runs cannot pay for one generation of {pop0} "
                                  f"candidates x {per_candidate} scenarios; raise the budget or lower design.population")
            _evaluate(problem, evaluator, state, xs, "population", clock, replay)
            improved()
            state.optimiser = _new_optimiser(problem, x0=best_x(problem, state.history))
            if gradients:
                state.phase = "gradient"
        elif state.phase == "gradient":
            gradient_step(problem, evaluator, state, budget, clock, replay, _row, restart)
            improved()
        elif state.phase == "population":
            if state.optimiser is None:
                state.optimiser = _new_optimiser(problem)
            opt = state.optimiser
            if multi:
                pop = opt.ask()
                xs = asked = [np.asarray(x, float) for x in pop.get("X")]
            else:
                # Candidates past a geometric constraint are moved onto its boundary (evaluated there).
                asked = [np.asarray(x, float) for x in opt.ask()]
                xs = _repair(problem, evaluator, state, asked)
            # What this generation costs: its candidates not evaluated before (repeats come from the cache).
            cost = len({problem.space.key(_coords(problem, x)) for x in xs} - state.cache.keys()) * per_candidate
            if state.n_evaluations + cost > budget:
                if state.generation == 0:
                    raise ConfigError("design.budget", f"{budget} engine runs cannot pay for one generation of "
                                      f"{len(xs)} candidates x {per_candidate} scenarios; raise the budget or lower "
                                      "design.population")
                state.phase = "polish" if sec.polish and not multi else "done"
                if state.phase == "polish":
                    state.polish_x = None
                continue
            fit = _evaluate(problem, evaluator, state, [_coords(problem, x) for x in xs], "population", clock, replay)
            if multi:
                pop.set("F", np.array(fit))
                opt.tell(infills=pop)
            else:
                # CMA-ES learns from the points it sampled: a moved point's value is charged with
                # the squared distance it was moved (repair and penalise), so that the
                # distribution is drawn to the boundary without being pulled across it.
                opt.tell(asked, [f[0] * (1.0 + float(np.sum((a - x) ** 2))) for f, a, x in zip(fit, asked, xs)])
                state.stall = 0 if improved() else state.stall + 1
                # Converged, or no progress for a while (e.g. sliding along a constraint): polish the
                # best point, then restart with a doubled population from a random point.
                if opt.stop() or state.stall >= _STALL_GENERATIONS:
                    next_cycle()
        else:  # polish: batched compass search around the best point
            if state.polish_x is None:
                state.polish_x = problem.space.centre(best_x(problem, state.history))
                state.polish_h = _POLISH_H0
            x = state.polish_x
            f0 = state.cache[problem.space.key(x)].fitness(problem.objectives)[0]  # evaluated: the best so far
            neigh = _polish_neighbours(problem, x, state.polish_h, evaluator)
            new = [y for y in neigh if problem.space.key(y) not in state.cache]
            if not neigh or len(new) * per_candidate > budget - state.n_evaluations:
                state.phase = "done"  # the budget cannot pay for this step
                continue
            fit = _evaluate(problem, evaluator, state, neigh, "polish", clock, replay)
            improved()
            j = int(np.argmin([f[0] for f in fit]))
            if fit[j][0] < f0 - 1e-12 * abs(f0):
                state.polish_x = neigh[j]
            else:
                state.polish_h /= 2.0
                if state.polish_h < _POLISH_HMIN:
                    next_cycle()
        state.generation += 1
        if state.n_evaluations >= budget:
            state.phase = "done"
        checkpoint()

    if coarse and not state.verified:
        _verify(problem, evaluator, state, sec.budget, clock, replay)
        state.verified = True
    checkpoint(final=True)
    if state.history and not any(r["engine_runs"] for r in state.history):
        # Every candidate broke a geometric constraint: nothing could be run, so there is no best.
        from .constraints import broken_geometry

        least = best_row(problem, state.history)
        assert least is not None  # (the history is not empty)
        closest = problem.space.values(np.asarray(least["x"]))
        raise ConfigError("design.constraints", f"no candidate of the design space meets the geometric constraints "
                          f"({len(state.history)} tried); the closest one, {closest}"
                          f", breaks {'; '.join(broken_geometry(sec.constraints, least))}: relax the constraints or "
                          "widen the variables' ranges")
    best = best_row(problem, state.history, "full" if coarse else None)
    best_out = None
    if best is not None:
        values = problem.space.values(np.asarray(best["x"]))
        objective: Any = ({n: best[n] for n in problem.objectives} if multi else best[problem.objectives[0]])
        best_out = {"objective": objective, "variables": values, "feasible": bool(best["feasible"]),
                    "config": problem.space.config(values),
                    "metrics": {k: best[k] for k in ("min_diameter_mm", "length_mm", "mass_kg", "n_beads",
                                                     "force_over_yield", "pulse_at_wall", "plastic_work_worst",
                                                     "residual_overlap_max_worst") if k in best}}
    pareto = pareto_rows(problem, state.history) if multi else ([best] if best and best["feasible"] else [])
    return DesignResult(problem, best_out, state.history, pareto, state.n_evaluations, state.generation,
                        t_saved + time.perf_counter() - t_start, out, resumed)
