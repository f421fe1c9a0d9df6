"""The rows of a design search's history (one per evaluated candidate: its unit-cube point ``x``,
objectives, ``feasible``, ``violation``, ``evaluation``, ``fidelity``): the best of them and the
Pareto front. The search itself is in :mod:`hertzchain.design.search`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .problem import DesignProblem

__all__ = ["best_row", "best_x", "pareto_rows"]


def best_x(problem: DesignProblem, history: list[dict]) -> np.ndarray:
    """The unit-cube point of the best row of a history that holds rows."""
    best = best_row(problem, history)
    assert best is not None  # (a history with rows)
    return np.asarray(best["x"])


def best_row(problem: DesignProblem, history: list[dict], fidelity: str | None = None) -> dict | None:
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
