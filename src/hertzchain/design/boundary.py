"""The geometric limits of a design search: candidates moved onto them rather than thrown away.

Geometric constraints (smallest bead, length, mass, bead count) are checked from the candidate's
chain alone, without a run (:meth:`~hertzchain.design.objectives.Evaluator.candidate`), and
optima often lie on them (the steepest taper the smallest bead allows). In a space with a real
variable, a candidate that breaks one is moved onto its boundary by root finding on the signed
geometric margin (:func:`_to_boundary`): towards a point that meets them (:func:`_repair_point`,
used by the search's population and polish steps), and for the initial sample towards its
nearest such point, with the boundary point of every discrete choice it samples added
(:func:`_repair_initial`, :func:`_choice_boundaries`). The search itself is in
:mod:`hertzchain.design.search`.
"""

from __future__ import annotations

import math

import numpy as np

from .constraints import has_geometric_constraints
from .objectives import Evaluator
from .problem import DesignProblem

#: A population candidate that breaks a geometric constraint is moved onto the constraint's
#: boundary to 2^-steps (1/64) of its distance to the anchor point.
_REPAIR_STEPS = 6
#: A point that meets the geometric constraints with a relative slack below this is on the
#: boundary (0.1 % of the limit: 0.015 mm of a 15 mm smallest bead): the search stops there.
_BOUNDARY_SLACK = 1e-3


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
    if not (g1 > 0 > g2 or g1 < 0 < g2):  # no boundary between them (both outside): nothing to find
        return point(0.0)
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

