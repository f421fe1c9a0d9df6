"""The residual bootstrap of a fit (``hertzchain fit --bootstrap N``), here or on a Dask cluster.

Each refit is independent: the best model plus the fit's residuals drawn with replacement
(scaled by sqrt(n / (n - p)), so that their spread is the noise's), fitted again from the optimum.
The draws are made here, from the seed, before any refit runs; each refit is then a task (the
problem, its resampled records and the solver's settings) that starts from the state the fit
left: the refits give the same numbers in any order, here or on any worker, and the spread of
their parameters is an uncertainty that does not assume the model linear over the error bars.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["bootstrap"]


@dataclass
class _Refit:
    """One refit: the problem (a ``lab.fit._Problem``), its resampled records and the solver's settings."""

    problem: Any
    solve: Any  # lab.fit._solve (passed in: this module does not import the fit)
    y: list
    x: np.ndarray
    scale: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    max_evaluations: int


def _refit(task: _Refit) -> tuple[np.ndarray, int, int]:
    """Fit ``task.problem`` to ``task.y`` from ``task.x``; the parameters, and the engine calls and
    chains it cost. The problem is left as it was (its records and caches restored)."""
    prob = task.problem
    saved = (prob.y, prob._cache, prob._sim_cache, prob.n_evaluations, prob.n_members)
    prob.y, prob._cache = task.y, {}
    try:
        x = task.solve(prob.residuals, prob.jacobian, task.x, task.scale, task.lower, task.upper,
                   task.max_evaluations).x
        return x, prob.n_evaluations - saved[3], prob.n_members - saved[4]
    finally:
        prob.y, prob._cache, prob._sim_cache = saved[:3]
        prob.n_evaluations, prob.n_members = saved[3:]


def bootstrap(prob, solve, x: np.ndarray, parts: list, n_refits: int, seed: int | None, scale: np.ndarray,
              lower: np.ndarray, upper: np.ndarray, max_evaluations: int, client=None) -> np.ndarray:
    """Residual bootstrap: ``n_refits`` refits on the best model + resampled residuals.

    Parameters
    ----------
    prob : hertzchain.lab.fit._Problem
        The fitted problem (its records are the measured ones).
    solve : callable
        The fit's solver, ``solve(fun, jac, x0, scale, lower, upper, max_evaluations)`` with an ``x``.
    x : numpy.ndarray
        The best parameters.
    parts : list
        Per trace, what ``prob.model(x)`` gave: (sim time, sim force, model at the scope's times,
        model seen through the instrument).
    n_refits : int
        Number of refits.
    seed : int or None
        Seed of the resampling.
    scale, lower, upper : numpy.ndarray
        The solver's natural scales and bounds (as in the fit).
    max_evaluations : int
        Most residual evaluations per refit.
    client : object
        None (refits here, one after the other) or a Dask client / executor
        (:func:`hertzchain.parallel.results_in_order`): one task per refit.

    Returns
    -------
    numpy.ndarray
        The refits' parameters, shape (n_refits, parameters), in the order of the draws; the
        engine calls they cost are added to ``prob.n_evaluations`` and ``prob.n_members``.
    """
    from ..parallel import results_in_order

    rng = np.random.default_rng(seed)
    data = prob.y
    n = sum(y.size for y in data)
    inflate = math.sqrt(n / max(n - x.size, 1))
    best = [parts[k][3] for k in range(len(data))]
    tasks = [_Refit(prob, solve, [m + inflate * rng.choice(y - m, size=y.size) for y, m in zip(data, best)], x, scale,
                    lower, upper, max_evaluations) for _ in range(n_refits)]
    out = results_in_order(client, _refit, tasks)
    prob.n_evaluations += sum(r[1] for r in out)
    prob.n_members += sum(r[2] for r in out)
    return np.array([r[0] for r in out])
