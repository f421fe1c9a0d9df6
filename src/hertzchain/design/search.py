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

Geometric constraints (smallest bead, length, mass, bead count) are checked without a run, and
optima often lie on them: in a space with a real variable, a candidate that breaks one is moved
onto its boundary by root finding on the geometry (:func:`_to_boundary`), towards the nearest
feasible point of the initial sample, towards the best feasible point in CMA-ES (which learns
from the point it sampled, charged with the distance it was moved), or along its coordinate in
the polish; and the initial sample also holds the boundary point of every discrete choice it
samples (:func:`_repair_initial`, :func:`_choice_boundaries`).

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
random streams, history, evaluated candidates) is written to ``checkpoint.pkl`` (at most once
a second when generations are faster than that); a rerun with
the same design and output folder resumes from it and ends with the same result as an
uninterrupted run. The random streams are seeded by ``[design].seed`` only.
"""

from __future__ import annotations

import math
import pickle
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..errors import ConfigError, HertzchainError
from .constraints import has_geometric_constraints
from .objectives import INFEASIBLE, Evaluator, Fidelity
from .problem import DesignProblem, search_fidelity

__all__ = ["DesignResult", "run_design", "DesignMismatch", "DesignLocked"]

_CHECKPOINT = "checkpoint.pkl"
#: Generations without a better best after which the population phase hands over to the polish.
_STALL_GENERATIONS = 5
#: Most IPOP restarts: a fully explored discrete space ends the search.
_MAX_RESTARTS = 6
#: The population doubles at the first restarts only: a generation is one engine call whose
#: records (wall force, energies) grow with its size.
_MAX_DOUBLINGS = 2
#: Initial and smallest polish step (unit-cube coordinates).
_POLISH_H0, _POLISH_HMIN = 0.05, 1e-4
#: A population candidate that breaks a geometric constraint is moved onto the constraint's
#: boundary to 2^-steps (1/64) of its distance to the anchor point.
_REPAIR_STEPS = 6
#: A point that meets the geometric constraints with a relative slack below this is on the
#: boundary (0.1 % of the limit: 0.015 mm of a 15 mm smallest bead): the search stops there.
_BOUNDARY_SLACK = 1e-3


class DesignMismatch(HertzchainError):
    """The output folder holds the checkpoint of a different design."""


class DesignLocked(HertzchainError):
    """Another design search is writing into the same output folder."""


class _Randn:
    """Picklable normal sampler for CMA-ES (so the checkpoint carries its random stream)."""

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
    try:
        from pymoo.algorithms.moo.nsga2 import NSGA2
        from pymoo.core.problem import Problem
    except ImportError:
        raise ConfigError("design.objective", "several objectives (a Pareto front) need pymoo: install the "
                          "'design' extra (pip install -e \".[design]\") or give one objective") from None

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
              clock: Callable[[], float]):
    """Evaluate unit-cube points in one engine call; append them to the history; return their fitness."""
    space = problem.space
    values = [space.values(x) for x in xs]
    keys = [space.key_of(v) for v in values]
    evaluator.cache = state.full_cache if evaluator.fidelity.name == "full" and phase == "verify" else state.cache
    evs = evaluator.evaluate(keys, [lambda v=v: space.config(v) for v in values])
    elapsed = clock()
    for x, vals, ev in zip(xs, values, evs):
        state.n_evaluations += ev.engine_runs
        state.history.append({**_row(problem, state, phase, x, ev, vals), "elapsed_s": elapsed})
    return [ev.fitness(problem.objectives) for ev in evs]


def _best_row(problem: DesignProblem, history: list[dict], fidelity: str | None = None) -> dict | None:
    """Best feasible row (least infeasible when none is), among the rows of ``fidelity`` when given."""
    if fidelity is not None:
        history = [r for r in history if r["fidelity"] == fidelity]
    if not history:
        return None
    obj = problem.objectives[0]
    feasible = [r for r in history if r["feasible"]]
    if feasible:
        return min(feasible, key=lambda r: (r[obj], r["evaluation"]))
    return min(history, key=lambda r: (r["violation"], r["evaluation"]))


def pareto_rows(problem: DesignProblem, history: list[dict]) -> list[dict]:
    """Non-dominated feasible rows (one per distinct design), sorted by the first objective."""
    names = problem.objectives
    rows, seen = [], set()
    for r in history:
        key = tuple(r[n] for n in names)
        if r["feasible"] and key not in seen:
            seen.add(key)
            rows.append(r)
    if not rows:
        return []
    f = np.array([[r[n] for n in names] for r in rows])
    # Row i is dominated when another row is no worse in every objective and better in one.
    front = [r for r, a in zip(rows, f) if not np.any(np.all(f <= a, axis=1) & np.any(f < a, axis=1))]
    return sorted(front, key=lambda r: r[names[0]])


def _save(out: Path, state: _State) -> None:
    from ..fileio import write_bytes

    # NumPy's global stream too: pymoo draws from it, and cma seeds it.
    write_bytes(out / _CHECKPOINT, pickle.dumps((state, np.random.get_state()), protocol=pickle.HIGHEST_PROTOCOL))


#: What a checkpoint may name when it is read back: the search's own state (hertzchain.design),
#: the optimisers (cma, pymoo) and NumPy's arrays and generators, and plain containers. Anything
#: else (os.system, eval, ...) is refused, so that a design folder received from someone else
#: cannot run code on --resume (a pickle may call any importable function).
_CHECKPOINT_MODULES = ("hertzchain.design", "cma", "pymoo", "numpy", "collections", "copyreg")
_CHECKPOINT_BUILTINS = frozenset({"dict", "list", "set", "frozenset", "tuple", "int", "float", "complex", "bool",
                                  "str", "bytes", "bytearray", "slice", "range", "object"})


class _CheckpointUnpickler(pickle.Unpickler):
    def find_class(self, module: str, name: str):
        allowed = (name in _CHECKPOINT_BUILTINS if module == "builtins"
                   else any(module == m or module.startswith(m + ".") for m in _CHECKPOINT_MODULES))
        if allowed:
            return super().find_class(module, name)
        raise pickle.UnpicklingError(f"a design checkpoint never refers to {module}.{name}")


def _load(out: Path, problem: DesignProblem, force: bool) -> _State | None:
    import io

    path = out / _CHECKPOINT
    if not path.exists():
        return None
    try:
        state, global_random = _CheckpointUnpickler(io.BytesIO(path.read_bytes())).load()
    except pickle.UnpicklingError as exc:
        if "never refers to" in str(exc) and not force:
            raise DesignMismatch(f"{path} is not a checkpoint this program wrote ({exc}): it is not loaded; remove it "
                                 "or use --force to start afresh") from None
        return None
    except Exception:  # an unreadable checkpoint (another version, truncated copy): start afresh
        return None
    if getattr(state, "hash", None) != problem.hash:
        if force:
            return None
        raise DesignMismatch(f"{out} holds the checkpoint of a different design (hash {str(state.hash)[:12]}, this one "
                             f"{problem.hash[:12]}); choose another --out or use --force to start afresh")
    np.random.set_state(global_random)
    return state


def _repairs(problem: DesignProblem) -> bool:
    """Whether candidates past a geometric constraint are moved onto its boundary: when there is
    such a constraint and a real variable. Bisection approaches a boundary along continuous
    coordinates; in a space of discrete coordinates only (integers, catalogue sizes, materials)
    the boundary's points are grid points that the search's own steps reach, and moving a point
    across many bins at once only crowded the first sample (a 14-bead catalogue design found a
    22 % worse optimum with it)."""
    return has_geometric_constraints(problem.section.constraints) and bool(problem.space.real.any())


def _margin(problem: DesignProblem, evaluator: Evaluator, x: np.ndarray) -> float:
    """Geometric margin of unit-cube point ``x`` (>= 0: meets the geometric constraints); the
    chain it builds is kept for the candidate's run (:meth:`Evaluator.candidate`)."""
    space = problem.space
    vals = space.values(x)
    return evaluator.candidate(space.key_of(vals), lambda: space.config(vals)).margin


def _to_boundary(problem: DesignProblem, evaluator: Evaluator, good: np.ndarray, bad: np.ndarray,
                 steps: int, f_good: float | None = None, f_bad: float | None = None,
                 slack: float = _BOUNDARY_SLACK) -> np.ndarray:
    """The last point of the segment from ``good`` (meets the geometric constraints) to ``bad``
    (breaks one) that still meets them, to 2^-steps of its length, from the geometry alone (no
    engine run). Optima often lie on such a boundary (the smallest bead allowed, the longest
    chain): a candidate that crosses it is moved onto it rather than thrown away.

    The boundary is found by Chandrupatla's method (Advances in Engineering Software 28, 145,
    1997) on the signed geometric margin: inverse quadratic interpolation through the last three
    points where it is safe, bisection where not, the bracket always kept; the first step is
    false position. It aims at the middle of the accepted band (a margin from 0 to ``slack``,
    default :data:`_BOUNDARY_SLACK`) and stops at the first point inside it, or, when the bracket is
    below 2^-steps of the segment (or after 2 (steps + 1) checks), at the bracket's end that
    meets the constraints. On the repairs of the n-q problem's first generations (30 seeds) it
    needs 2.8 geometry checks where the ITP method needed 3.7. ``f_good`` and ``f_bad`` are the
    ends' margins when known.
    """
    eps = 2.0 ** -(steps + 1)  # half the tolerated bracket
    half = 0.5 * slack

    def point(t: float) -> np.ndarray:
        return problem.space.centre(good + t * (bad - good))

    # g: the margin less half the band, so that |g| <= half is the accepted band.
    g1 = (_margin(problem, evaluator, point(0.0)) if f_good is None else f_good) - half
    if abs(g1) <= half or not math.isfinite(g1):
        return point(0.0)
    g2 = (_margin(problem, evaluator, point(1.0)) if f_bad is None else f_bad) - half
    # x1: the newest point; x2: the bracket's other end (g of the other sign); x3: the one before.
    x1, x2 = 0.0, 1.0
    x3, g3 = x2, g2
    t = g1 / (g1 - g2)
    for _ in range(2 * (steps + 1)):
        xt = x1 + t * (x2 - x1)
        gt = _margin(problem, evaluator, point(xt)) - half
        if abs(gt) <= half:
            return point(xt)
        if (gt > 0) == (g1 > 0):
            x3, g3 = x1, g1
        else:
            x3, g3 = x2, g2
            x2, g2 = x1, g1
        x1, g1 = xt, gt
        if abs(x2 - x1) <= 2.0 * eps:
            break
        tl = eps / abs(x2 - x1)
        t = 0.5
        if g3 != g1 and g3 != g2:
            xi = (x1 - x2) / (x3 - x2)
            phi = (g1 - g2) / (g3 - g2)
            if phi * phi < xi and (1.0 - phi) ** 2 < 1.0 - xi:  # inverse quadratic interpolation is safe
                t = g1 / (g2 - g1) * g3 / (g2 - g3) + (x3 - x1) / (x2 - x1) * g1 / (g3 - g1) * g2 / (g3 - g2)
        t = min(1.0 - tl, max(tl, t))
    return point(x1 if g1 > 0 else x2)  # the bracket's end that meets the constraints (g > -half)


def _repair_point(problem: DesignProblem, evaluator: Evaluator, anchor: np.ndarray, bad: np.ndarray,
                  f_anchor: float | None, f_bad: float) -> np.ndarray:
    """``bad`` (breaks a geometric constraint) moved onto the boundary on its way to ``anchor``
    (meets them). The discrete coordinates (bead counts, catalogue sizes, materials) the
    optimiser chose are kept when the anchor's real coordinates meet the constraints with them:
    only the real ones then move, a smooth one-dimensional search that ends on the boundary of
    the candidate's own bin (the largest taper ratio its bead count allows); otherwise the whole
    segment to the anchor is searched."""
    space = problem.space
    real = space.real
    if not np.array_equal(space.centre(anchor)[~real], space.centre(bad)[~real]):
        start = np.where(real, anchor, bad)
        f_start = _margin(problem, evaluator, start)
        if f_start >= 0:
            return _to_boundary(problem, evaluator, start, bad, _REPAIR_STEPS, f_start, f_bad)
    return _to_boundary(problem, evaluator, anchor, bad, _REPAIR_STEPS, f_anchor, f_bad)


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
            if repair and v.kind == "real":
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
    best = _best_row(problem, state.history)
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


def _repair_initial(problem: DesignProblem, evaluator: Evaluator, xs: list[np.ndarray]) -> list[np.ndarray]:
    """The initial sample with every point that breaks a geometric constraint moved onto its
    boundary on its way to the nearest point that meets them (:func:`_to_boundary`): a point
    beyond the boundary says nothing the boundary itself does not. Followed by the boundary
    points of the discrete choices whose sampled points all meet the constraints
    (:func:`_choice_boundaries`; up to half the sample more)."""
    if not _repairs(problem):
        return xs
    margins = np.array([_margin(problem, evaluator, x) for x in xs])
    bad = margins < 0
    if bad.all() or not bad.any():
        return xs
    pts = np.asarray(xs, float)
    good = np.flatnonzero(~bad)
    real = problem.space.real
    bins = [tuple(problem.space.centre(x)[~real].tolist()) for x in pts]  # each point's discrete choice
    # The direction in which the limits bind: from the mean real coordinates of the points that
    # meet them to the mean of those that break them.
    binds = pts[bad][:, real].mean(axis=0) - pts[good][:, real].mean(axis=0)
    out = list(xs)
    # With one real coordinate, a choice's boundary along it is one point: found once, then given
    # to the choice's other points beyond it (searching again would find the same point, and the
    # near-copy would cost a run of its own).
    single = int(real.sum()) == 1
    found: dict[tuple, list[np.ndarray]] = {}
    for i in np.flatnonzero(bad):
        x, b = pts[i], bins[i]
        same = [j for j in good if bins[j] == b]
        start = f_start = None
        if same:
            # An anchor in the candidate's own discrete bin: the repair is then a search along the
            # real coordinates alone, with no check spent on a start point.
            near = same[int(np.argmin(np.sum((pts[same] - x) ** 2, axis=1)))]
            start, f_start = pts[near], margins[near]
        else:
            # No sampled point of this choice meets the limits: back off against the binding
            # direction to the box's edge, and search from there if it meets them (the choice
            # keeps its boundary point rather than giving it up for a neighbour's).
            back = _to_edge(x, -binds, real)
            f_back = _margin(problem, evaluator, back) if back is not None else -1.0
            if f_back >= 0:
                start, f_start = back, f_back
        if start is None:
            near = good[int(np.argmin(np.sum((pts[good] - x) ** 2, axis=1)))]
            out[i] = _repair_point(problem, evaluator, pts[near], x, margins[near], margins[i])
            continue
        known = [y for y in found.get(b, ()) if float(((y - start)[real] * (x - y)[real]).sum()) >= 0.0]
        if known:
            out[i] = known[0]
            continue
        out[i] = _to_boundary(problem, evaluator, start, x, _REPAIR_STEPS, f_start, margins[i])
        if single:
            found.setdefault(b, []).append(out[i])
    return out + _choice_boundaries(problem, evaluator, pts, bad, margins, bins, binds, len(xs) // 2)


def _to_edge(x: np.ndarray, d: np.ndarray, real: np.ndarray) -> np.ndarray | None:
    """``x`` moved along ``d`` (real coordinates) to the edge of the unit box; None when ``d`` is
    zero or ``x`` is on that edge already."""
    xr = x[real]
    # How far along d each coordinate may go before it leaves [0, 1] (a few coordinates: plain floats).
    t = min(((1.0 - xi) / di if di > 0 else -xi / di for xi, di in zip(xr.tolist(), d.tolist()) if di != 0),
            default=math.inf)
    if not 0.0 < t < math.inf:
        return None
    out = x.copy()
    out[real] = np.clip(xr + t * d, 0.0, 1.0)
    return out


def _choice_boundaries(problem: DesignProblem, evaluator: Evaluator, pts: np.ndarray, bad: np.ndarray,
                       margins: np.ndarray, bins: list[tuple], binds: np.ndarray, most: int) -> list[np.ndarray]:
    """Boundary points of the discrete choices (``bins``: each point's) the initial sample met only
    inside the geometric limits (at most ``most`` of them).

    The repair puts every sampled point past a limit onto it, so each discrete choice (bead
    count, catalogue size, material) with such a point has a boundary point in the first
    generation. A choice whose sampled points all meet the limits gets one too: its point
    furthest in the direction ``binds`` in which the limits bind (from the mean real coordinates
    of the sample's points that meet them to the mean of those that break them) is pushed that
    way to the box's edge, then back onto the boundary by :func:`_to_boundary` when the edge
    breaks a limit. Designs under geometric limits tend to be best on them (the steepest taper the
    smallest bead allows): without this, whether the first generation holds the best choice's
    boundary point is down to the sample (n-q benchmark problem: 40 % of seeds; with it, every
    seed).
    """
    real = problem.space.real
    if real.all() or most < 1 or not np.any(binds):
        return []
    crossed = {bins[j] for j in np.flatnonzero(bad)}
    good = np.flatnonzero(~bad)
    out: list[np.ndarray] = []
    for b in dict.fromkeys(bins[j] for j in good):
        if b in crossed:
            continue
        members = [j for j in good if bins[j] == b]
        j = members[int(np.argmax(pts[members][:, real] @ binds))]
        x = pts[j]
        edge = _to_edge(x, binds, real)
        if edge is None:
            continue
        f = _margin(problem, evaluator, edge)
        if f < 0:
            edge = _to_boundary(problem, evaluator, x, edge, _REPAIR_STEPS, margins[j], f)
        if problem.space.key(edge) != problem.space.key(x):
            out.append(edge)
            if len(out) == most:
                break
    return out


def _verify(problem: DesignProblem, search: Evaluator, state: _State, budget: int, clock) -> None:
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
        least = _best_row(problem, state.history, "search")
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
        _evaluate(problem, full, state, batch, "verify", clock)
        if any(r["feasible"] for r in state.history if r["fidelity"] == "full"):
            return
        k = min(k, (budget - state.n_evaluations) // per)
        if k < 1:
            return


def run_design(problem: DesignProblem, out_dir: str | Path, *, client=None, device: str | None = None,
               progress: Callable[[int, int], None] | None = None, force: bool = False,
               checkpoint_interval: float = 1.0) -> DesignResult:
    """Run (or resume) a design search; the state is checkpointed after engine calls (see checkpoint_interval).

    Parameters
    ----------
    problem : DesignProblem
        From :func:`hertzchain.load_design` / :func:`hertzchain.parse_design`.
    out_dir : str or Path
        Output folder: ``checkpoint.pkl`` during the search (see :func:`hertzchain.write_report`
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
    """
    from ..sweep.storage import _folder_lock

    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(str(out), f"cannot create the output folder: {exc.strerror}") from None
    # Two searches writing one checkpoint would corrupt each other: the folder is locked (flock).
    with _folder_lock(out, "design", DesignLocked):
        return _run_design(problem, out, client, device, progress, force, checkpoint_interval)


def _run_design(problem: DesignProblem, out: Path, client, device, progress, force: bool,
                checkpoint_interval: float) -> DesignResult:
    """:func:`run_design` with the output folder locked."""
    sec = problem.section
    fidelity = search_fidelity(problem)
    coarse = fidelity.name != "full"
    evaluator = Evaluator(problem.objectives, sec.constraints, sec.robust,
                          None if sec.window is None else tuple(sec.window), client, sec.chunk_size, device,
                          fidelity=fidelity, base=problem.base)
    state = _load(out, problem, force)
    resumed = state is not None
    if state is None:
        state = _State(problem.hash)
    per_candidate = evaluator.n_scenarios
    # The full-accuracy runs of the best candidates are set aside from the budget of the search.
    reserve = sec.verify_top * per_candidate if coarse else 0
    if coarse and sec.budget <= reserve:
        raise ConfigError("design.budget", f"{sec.budget} engine runs leave nothing to search with after the "
                          f"{reserve} set aside to run the design.verify_top = {sec.verify_top} best candidates "
                          "again at full accuracy; raise the budget, lower design.verify_top, or set "
                          "design.search_steps_per_radian = \"full\"")
    budget = sec.budget - reserve
    multi = len(problem.objectives) > 1
    t_start = time.perf_counter()
    t_saved = state.elapsed_s

    def clock() -> float:
        return t_saved + time.perf_counter() - t_start

    # The first save comes after checkpoint_interval too: a kill loses at most that much work,
    # and a search shorter than that saves once, at the end.
    last_save = [t_saved]

    def checkpoint(final: bool = False) -> None:
        state.elapsed_s = clock()
        # Saving costs a pickle and an fsync (~10 ms): on fast generations, at most one save per
        # checkpoint_interval seconds, so a kill loses at most that much work.
        if final or state.elapsed_s - last_save[0] >= checkpoint_interval:
            _save(out, state)
            last_save[0] = state.elapsed_s
        if progress is not None:
            progress(min(state.n_evaluations, budget), budget)

    if progress is not None:
        progress(min(state.n_evaluations, budget), budget)
    def improved() -> bool:
        """Whether the best fitness improved since the last call (tracks stagnation)."""
        best = _best_row(problem, state.history)
        f = best[problem.objectives[0]] if best["feasible"] else INFEASIBLE * (1.0 + best["violation"])
        if f < state.best_f - 1e-12 * abs(state.best_f):
            state.best_f = f
            return True
        return False

    def next_cycle() -> None:
        """After a converged or stalled population phase: polish; after a polish: restart (IPOP)."""
        if state.phase == "population" and sec.polish and not multi:
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
            if len({problem.space.key(x) for x in xs}) * per_candidate > budget:
                raise ConfigError("design.budget", f"{budget} engine runs cannot pay for one generation of {pop0} "
                                  f"candidates x {per_candidate} scenarios; raise the budget or lower design.population")
            _evaluate(problem, evaluator, state, xs, "population", clock)
            improved()
            state.optimiser = _new_optimiser(problem, x0=np.asarray(_best_row(problem, state.history)["x"]))
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
            fit = _evaluate(problem, evaluator, state, [_coords(problem, x) for x in xs], "population", clock)
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
                state.polish_x = problem.space.centre(np.asarray(_best_row(problem, state.history)["x"]))
                state.polish_h = _POLISH_H0
            x = state.polish_x
            f0 = state.cache[problem.space.key(x)].fitness(problem.objectives)[0]  # evaluated: the best so far
            neigh = _polish_neighbours(problem, x, state.polish_h, evaluator)
            new = [y for y in neigh if problem.space.key(y) not in state.cache]
            if not neigh or len(new) * per_candidate > budget - state.n_evaluations:
                state.phase = "done"  # the budget cannot pay for this step
                continue
            fit = _evaluate(problem, evaluator, state, neigh, "polish", clock)
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
        _verify(problem, evaluator, state, sec.budget, clock)
        state.verified = True
    checkpoint(final=True)
    best = _best_row(problem, state.history, "full" if coarse else None)
    best_out = None
    if best is not None:
        values = problem.space.values(np.asarray(best["x"]))
        objective: Any = ({n: best[n] for n in problem.objectives} if multi else best[problem.objectives[0]])
        best_out = {"objective": objective, "variables": values, "feasible": bool(best["feasible"]),
                    "config": problem.space.config(values),
                    "metrics": {k: best[k] for k in ("min_diameter_mm", "length_mm", "mass_kg", "n_beads",
                                                     "force_over_yield", "pulse_at_wall") if k in best}}
    pareto = pareto_rows(problem, state.history) if multi else ([best] if best and best["feasible"] else [])
    return DesignResult(problem, best_out, state.history, pareto, state.n_evaluations, state.generation,
                        t_saved + time.perf_counter() - t_start, out, resumed)
