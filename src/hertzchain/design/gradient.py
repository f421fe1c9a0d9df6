"""The gradient phase of a design search: local searches on exact gradients where every variable is
continuous.

A design whose variables are all real config fields that :func:`hertzchain.sensitivity`
differentiates (bead diameters, offsets, the striker, law constants, materials...), with one
objective and no robust scenarios, is searched with gradients: L-BFGS-B (scipy; Byrd, Lu,
Nocedal & Zhu 1995) from the best points of the initial sample, one after the other, each
evaluation one run and its reverse sweep (the value and the whole gradient, charged as
:data:`GRADIENT_RUNS` engine runs). Per-bead profiles have tens to hundreds of variables, where
derivative-free methods scale badly; with the gradient a local search converges in a few dozen
evaluations whatever the dimension.

Coordinates: the search works in the unit cube. A monotone list range (``monotone = true``:
decreasing away from the impact end) is written as ratios, x_1 = z_1, x_i = x_{i-1} z_i with every
z_i in [0, 1] (increasing: the same from the last item), so that every point of the box
[0, 1]^d is a monotone profile inside the bounds and L-BFGS-B's box is the whole feasible set.

Feasibility: the geometric constraints are not handled here (a design with one keeps the
population search and its compass polish); a run constraint that fails (the pulse does not reach
the wall, a force past max_force_over_yield) makes the evaluation worse than the start, so the
line search steps back. Every evaluation is a row of the history (phase ``gradient``), at the
search's fidelity, and the best are run again at full accuracy like any other (``verify``).
"""

from __future__ import annotations

import math
import warnings
from typing import Callable

import numpy as np

from .objectives import Evaluation, Evaluator, _pulses_passed
from .problem import DesignProblem
from .space import Space

__all__ = ["GRADIENT_RUNS", "gradient_support", "Coordinates", "local_search", "initial_points", "pick_start",
           "evaluate_with_gradient", "gradient_step"]

#: Engine runs one value-and-gradient evaluation is charged: the taped run, then the reverse sweep
#: (a replay of the steps and their adjoint, about two runs more; benchmarks/gradient.py).
GRADIENT_RUNS = 3
#: Design objectives the gradient phase takes (their values are the sensitivity engine's, the same
#: numbers and sense as :mod:`hertzchain.design.objectives`, all minimised). ``plastic_work`` and
#: ``residual_overlap_max`` are left to the population search: where no contact yields they are
#: 0, the best a design can reach, but the sensitivity engine refuses them there (every derivative
#: 0) and this phase would mark such a point infeasible.
GRADIENT_OBJECTIVES = frozenset({"peak_wall_force", "peak_contact_force", "max_force_over_yield",
                                 "front_momentum_at_wall", "energy_at_wall",
                                 "peak_body_force", "peak_body_acceleration", "energy_to_body"})
#: A local search stops when an iteration improves the objective by less than this fraction.
FTOL = 1e-7
#: ... or when its best has not improved by STALL_GAIN (relative) in STALL_EVALUATIONS
#: evaluations: most of a local search's gain comes in its first ten or so evaluations, and the
#: rest crawls (per-bead profiles: within 0.5 % of the end after 5-9 of 40-85 evaluations), so
#: the budget goes to more starts, i.e. more basins.
STALL_EVALUATIONS = 20
STALL_GAIN = 1e-3
#: The local searches minimise the soft maximum of the wall force over its samples, of width
#: SOFT_WIDTH times the start's peak (:func:`hertzchain.gradients.objectives.soft_peak`): the
#: best profiles level several pulse peaks, where the peak itself has kinks (a 10-bead profile:
#: best of 12 starts 3.65 N instead of 3.89 N).
SOFT_WIDTH = 3e-3
#: The search's coordinates are the box's times this: L-BFGS-B's first step is one unit long, and
#: on the box itself it jumped to a corner (a step profile), a local minimum it stayed in.
STEP_SCALE = 30.0


def gradient_support(problem: DesignProblem) -> str | None:
    """Why the design cannot be searched with gradients, or None when it can.

    Parameters
    ----------
    problem : DesignProblem
        The design.

    Returns
    -------
    str or None
        The reason (a discrete variable, several objectives, robust scenarios, a geometric
        constraint, a field or model the sensitivity engine does not differentiate), or None.
    """
    from ..config import parse_config
    from ..errors import ConfigError
    from .constraints import has_geometric_constraints

    sec = problem.section
    if len(problem.objectives) != 1 or problem.objectives[0] not in GRADIENT_OBJECTIVES:
        return "one objective of " + ", ".join(sorted(GRADIENT_OBJECTIVES)) + " is needed"
    if sec.robust is not None:
        return "robust scenarios ([design.robust]) are searched without gradients"
    if has_geometric_constraints(sec.constraints):
        return "geometric constraints are handled by the population search"
    if problem.space.shape is not None:
        return "chain shapes ([design.shape]) are searched without gradients"
    bad = [v.path for v in problem.space.variables if v.kind != "real"]
    if bad:
        return f"{bad[0]} is not a real variable"
    try:
        from ..gradients.api import _prepare
        from ..gradients.objectives import check_objective
        from ..gradients.setup import setup_derivatives

        cfg = parse_config(problem.base)
        _, system, _ = _prepare(cfg)
        check_objective(problem.objectives[0], system)  # e.g. energy_at_wall of a law without Hertz's 3/2
        setup_derivatives(cfg, system, [v.path for v in problem.space.variables])
    except ConfigError as exc:
        return f"{exc.field}: {exc.message}"
    return None


class Coordinates:
    """Unit-cube points x and the search's coordinates z (ratios along monotone ranges).

    Parameters
    ----------
    space : Space
        The design space (its ``monotone`` groups).
    """

    def __init__(self, space: Space) -> None:
        self.dim = space.dim
        groups: dict[str, list[int]] = {}
        for i, v in enumerate(space.variables):
            groups.setdefault(v.group, []).append(i)
        # each monotone group as indices from its largest item to its smallest
        self.chains = [idx if direction == "decreasing" else idx[::-1]
                       for g, direction in space.monotone.items() for idx in [groups[g]]]

    def sort(self, x: np.ndarray) -> np.ndarray:
        """``x`` with every monotone group in its order (the candidate :meth:`Space.values` makes of it)."""
        x = np.clip(np.asarray(x, float), 0.0, 1.0).copy()
        for idx in self.chains:
            x[idx] = np.sort(x[idx])[::-1]
        return x

    def z_of(self, x: np.ndarray) -> np.ndarray:
        """Coordinates of a sorted point (ratios x_i / x_{i-1}; 0 after a zero)."""
        z = np.asarray(x, float).copy()
        for idx in self.chains:
            v = z[idx]
            r = np.empty_like(v)
            r[0] = v[0]
            with np.errstate(divide="ignore", invalid="ignore"):
                r[1:] = np.where(v[:-1] > 0, v[1:] / np.where(v[:-1] > 0, v[:-1], 1.0), 0.0)
            z[idx] = np.clip(r, 0.0, 1.0)
        return z

    def x_of(self, z: np.ndarray) -> np.ndarray:
        """The unit-cube point of coordinates ``z`` (cumulative products along monotone groups)."""
        x = np.asarray(z, float).copy()
        for idx in self.chains:
            x[idx] = np.cumprod(x[idx])
        return x

    def gradient(self, z: np.ndarray, gx: np.ndarray) -> np.ndarray:
        """dJ/dz from dJ/dx: along a group, dJ/dz_k = (prod_{m<k} z_m) T_k with
        T_k = gx_k + z_{k+1} T_{k+1} (the chain rule through the cumulative products)."""
        gz = np.asarray(gx, float).copy()
        for idx in self.chains:
            zz, g = z[idx], gx[idx]
            t = np.empty_like(g)
            acc = 0.0
            for k in range(g.size - 1, -1, -1):
                acc = g[k] + (zz[k + 1] * acc if k + 1 < g.size else 0.0)
                t[k] = acc
            pre = np.concatenate([[1.0], np.cumprod(zz[:-1])])
            gz[idx] = pre * t
        return gz


def initial_points(problem: DesignProblem, xs: list[np.ndarray]) -> list[np.ndarray]:
    """The initial sample of a gradient search: half its Latin-hypercube points as drawn (their
    monotone groups sorted: nearly straight profiles), half read as the search's own coordinates
    (:meth:`Coordinates.x_of`: ratios, profiles that fall off geometrically), so that the local
    searches start from both kinds of profile. A space without a monotone range is unchanged.

    Parameters
    ----------
    problem : DesignProblem
        The design.
    xs : list of numpy.ndarray
        The sample's unit-cube points.

    Returns
    -------
    list of numpy.ndarray
        The points to evaluate.
    """
    coords = Coordinates(problem.space)
    if not coords.chains:
        return xs
    return [coords.x_of(x) if i % 2 else x for i, x in enumerate(xs)]


class _Spent(Exception):
    """The local search's budget is spent."""


def evaluate_with_gradient(problem: DesignProblem, evaluator: Evaluator, x: np.ndarray, smoothing: float | None = None):
    """Value, gradient in the unit cube and Evaluation of the sorted point ``x`` (at the search's
    fidelity: its steps per radian; the config's own sample interval).

    Returns
    -------
    (float, numpy.ndarray, Evaluation, dict)
        The value the search minimises (the soft maximum with ``smoothing`` [N], else the
        fitness, :meth:`Evaluation.fitness`), its gradient dJ/dx, the evaluation and the
        candidate's values.
    """
    from ..errors import ElasticLimitWarning, PulseNotFound, PulseNotReachedWarning
    from ..gradients import sensitivity
    from .constraints import geometric_violation, run_violation

    space = problem.space
    values = space.values(x)
    key = space.key_of(values)
    cand = evaluator.candidate(key, lambda: space.config(values))
    cfg = dict(cand.config)
    spr = evaluator.fidelity.steps_per_radian
    if spr is not None:
        cfg["run"] = {**cfg.get("run", {}), "steps_per_radian": spr}
    name = problem.objectives[0]
    w = problem.section.window
    window = None if w is None else (float(w[0]), float(w[1]))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ElasticLimitWarning)
        warnings.simplefilter("ignore", PulseNotReachedWarning)
        try:
            s = sensitivity(cfg, [v.path for v in space.variables], name, window=window,
                            smoothing=smoothing if name == "peak_wall_force" else None)
            value, grad = s.value, np.array([s.gradient[v.path] for v in space.variables])
        except PulseNotFound:  # no pulse to fit at the wall: infeasible, no direction
            s, value, grad = None, math.nan, np.zeros(space.dim)
    span = np.array([v.high - v.low for v in space.variables])
    con = problem.section.constraints
    geo = cand.geometry
    if s is not None:
        rec = s.records
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = float(np.nanmax(rec["max_contact_force"] / rec["yield_force"]))
        pulse = bool(_pulses_passed(rec["wall_force"][None, :])[0])
    else:
        ratio, pulse = math.nan, False
    viol = geometric_violation(con, geo) + run_violation(con, ratio, pulse)
    if not math.isfinite(value):
        viol = max(viol, 1.0)
    metrics = {**geo, "force_over_yield": ratio, "pulse_at_wall": pulse, "energy_ok": True}
    ev = Evaluation({name: value}, viol == 0, viol, metrics, engine_runs=GRADIENT_RUNS,
                    fidelity=evaluator.fidelity.name)
    evaluator.candidates.pop(key, None)
    target = s.smooth_value if s is not None and s.smooth_value is not None else ev.fitness([name])[0]
    return target, grad * span, ev, values


def local_search(problem: DesignProblem, x0: np.ndarray, max_evaluations: int,
                 evaluate: Callable[[np.ndarray, float | None], tuple[float, np.ndarray, Evaluation]],
                 start_value: float = math.nan) -> tuple[np.ndarray, float, int]:
    """L-BFGS-B from unit-cube point ``x0`` in the coordinates of :class:`Coordinates`, until it
    converges, stalls (:data:`STALL_EVALUATIONS`) or spends ``max_evaluations``.

    Parameters
    ----------
    problem : DesignProblem
        The design (:func:`gradient_support` is None).
    x0 : numpy.ndarray
        Start (unit cube; monotone groups are sorted first).
    max_evaluations : int
        Most value-and-gradient evaluations.
    evaluate : callable
        ``evaluate(x, smoothing) -> (value minimised, its gradient dJ/dx, Evaluation)`` of a
        sorted unit-cube point (:func:`evaluate_with_gradient`, or a replay of saved rows).
    start_value : float
        The objective at ``x0`` (its peak wall force sets the soft maximum's width; NaN: none).

    Returns
    -------
    (numpy.ndarray, float, int)
        The best point (by the objective itself), its fitness, and the evaluations made.
    """
    from scipy.optimize import minimize

    coords = Coordinates(problem.space)
    z0 = coords.z_of(coords.sort(x0))
    # the soft maximum's width, fixed from the start's peak (the function minimised must not change)
    smoothing = SOFT_WIDTH * start_value if problem.objectives[0] == "peak_wall_force" and start_value > 0 else None
    best: list = [None, math.inf]  # the best point (unit cube) and its true objective
    count = [0]
    worst = [0.0]
    last_gain = [0, math.inf]  # evaluation and value of the last improvement by STALL_GAIN

    def fun(w):
        if count[0] >= max_evaluations or count[0] - last_gain[0] >= STALL_EVALUATIONS:
            raise _Spent
        z = np.clip(w / STEP_SCALE, 0.0, 1.0)
        x = coords.x_of(z)
        f, gx, ev = evaluate(x, smoothing)
        count[0] += 1
        if not ev.feasible:
            # worse than anything seen, no direction: the line search steps back
            return 2.0 * max(worst[0], abs(best[1]) if math.isfinite(best[1]) else 1.0), np.zeros_like(z)
        worst[0] = max(worst[0], abs(f))
        true = ev.fitness(problem.objectives)[0]
        if true < best[1]:
            best[0], best[1] = x, true
        if f < last_gain[1] - STALL_GAIN * abs(last_gain[1]) or not math.isfinite(last_gain[1]):
            last_gain[0], last_gain[1] = count[0], f
        return f, coords.gradient(z, gx) / STEP_SCALE

    try:
        minimize(fun, STEP_SCALE * z0, jac=True, method="L-BFGS-B", bounds=[(0.0, STEP_SCALE)] * z0.size,
                 options={"maxfun": max_evaluations, "ftol": FTOL, "gtol": 1e-10, "maxls": 12})
    except _Spent:
        pass
    return (best[0] if best[0] is not None else coords.x_of(z0)), best[1], count[0]


def pick_start(problem: DesignProblem, history: list[dict], used: list, optima: list, radius: float = 0.05):
    """The best feasible row of a population generation (the initial sample, CMA-ES) not yet used as a
    start and farther than ``radius`` (largest coordinate difference, monotone groups sorted) from
    every local optimum found; None when there is none.

    Parameters
    ----------
    problem : DesignProblem
        The design.
    history : list of dict
        The search's rows (``x``, fitness by the objective, ``feasible``).
    used : list
        Starts already taken (sorted points).
    optima : list
        Local optima found (sorted points).
    radius : float
        Distance under which a start is in a known basin.

    Returns
    -------
    (numpy.ndarray, float) or None
        The start and its objective value.
    """
    coords = Coordinates(problem.space)
    name = problem.objectives[0]
    rows = sorted((r for r in history if r["feasible"] and r["phase"] == "population"),
                  key=lambda r: (r[name], r["evaluation"]))
    for r in rows:
        x = coords.sort(np.asarray(r["x"], float))
        near = [p for p in used + optima if np.max(np.abs(p - x)) < radius]
        if not near:
            return x, float(r[name])
    return None


def gradient_step(problem: DesignProblem, evaluator: Evaluator, state, budget: int, clock: Callable[[], float],
                  replay, row: Callable, restart: Callable[[], bool]) -> None:
    """One generation of the gradient phase of :func:`hertzchain.design.search.run_design`: a local
    search from the best point of the population generations not yet tried outside the basins
    already searched (:func:`pick_start`, :func:`local_search`); without such a point, a CMA-ES
    restart (``restart()``; the phase ends when it returns False) whose best is searched next.

    Each evaluation is a history row (``row(problem, state, "gradient", x, evaluation, values)``)
    that also keeps the value the search minimised and its gradient (``search_value``,
    ``gradient``): while ``replay`` (:class:`hertzchain.design.checkpoint.Replay`) has saved rows
    left, they are taken from it, without engine runs, and L-BFGS-B retraces its steps.

    Parameters
    ----------
    problem : DesignProblem
        The design.
    evaluator : Evaluator
        The search's evaluator.
    state : hertzchain.design.search._State
        The search state (history, caches, counters, ``gradient_used``, ``gradient_optima``).
    budget : int
        Engine runs of the search.
    clock : callable
        Seconds since the search started.
    replay : Replay or None
        The checkpoint being replayed.
    row : callable
        The search's history row builder.
    restart : callable
        Restarts CMA-ES (IPOP) and returns True, or returns False when the restarts are spent.
    """
    from dataclasses import replace

    left = (budget - state.n_evaluations) // GRADIENT_RUNS
    start = pick_start(problem, state.history, state.gradient_used, state.gradient_optima)
    if left < 2:
        state.phase = "done"
        return
    if start is None:
        if not restart():
            state.phase = "done"
        return
    x0, f0 = start
    state.gradient_used.append(x0)
    space = problem.space

    def evaluate(x: np.ndarray, smoothing: float | None):
        if replay is not None and replay.active:
            replay.evaluate(problem, state, [x], "gradient")
            saved = state.history[-1]
            return float(saved["search_value"]), np.asarray(saved["gradient"], float), state.cache[space.key(x)]
        value, grad, ev, values = evaluate_with_gradient(problem, evaluator, x, smoothing)
        state.n_evaluations += ev.engine_runs
        state.cache.setdefault(space.key_of(values), replace(ev, engine_runs=0))
        state.history.append({**row(problem, state, "gradient", x, ev, values), "elapsed_s": clock(),
                              "search_value": float(value), "gradient": [float(g) for g in grad]})
        return value, grad, ev

    x, _, _ = local_search(problem, x0, left, evaluate, start_value=f0)
    state.gradient_optima.append(x)
