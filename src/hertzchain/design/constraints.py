"""Design constraints: geometry (checked before any simulation) and run outcomes (after it).

Geometry of a candidate chain: smallest bead diameter [mm], total length along the axis (sum
of the diameters) [mm], total bead mass [kg] (m_n = rho pi phi_n^3 / 6) and bead count. Run
outcomes: the largest contact force over its elastic limit F/F_Y (paper Sec. II; 1 is the
onset of yield, with every law), whether the wall pulse arrived and passed within the run (a
design that only looks good because the pulse never reached the wall is infeasible), and with
the elastoplastic law the plastic work [J] and the largest permanent overlap [m].

A violation is measured relatively, (value - limit) / |limit| summed over the violated
constraints, so that the search can rank infeasible candidates by how far they are from the
feasible set.
"""

from __future__ import annotations

import math
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

__all__ = ["Constraints", "has_geometric_constraints", "geometry", "geometric_violation", "geometric_margin",
           "run_violation", "broken_geometry", "broken_run"]


class Constraints(BaseModel):
    """``[design].constraints``: every key optional.

    Attributes
    ----------
    min_diameter_mm : float
        Smallest bead allowed [mm].
    max_length_mm : float
        Longest chain (sum of diameters) [mm].
    max_mass_kg : float
        Heaviest chain (sum of bead masses) [kg].
    min_beads, max_beads : int
        Bead count limits.
    max_force_over_yield : float
        Largest contact force over its elastic limit F_Y (1 = onset of yield, paper Sec. II).
    max_plastic_work : float
        Largest plastic work done in all contacts [J] (elastoplastic law).
    max_residual_overlap : float
        Largest permanent overlap of any contact [m] (elastoplastic law).
    pulse_at_wall : bool
        The wall pulse must peak and fall to half its peak within the run (default true).
    """

    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, allow_inf_nan=False)

    min_diameter_mm: float | None = Field(default=None, gt=0)
    max_length_mm: float | None = Field(default=None, gt=0)
    max_mass_kg: float | None = Field(default=None, gt=0)
    min_beads: int | None = Field(default=None, ge=1)
    max_beads: int | None = Field(default=None, ge=1)
    max_force_over_yield: float | None = Field(default=None, gt=0)
    max_plastic_work: float | None = Field(default=None, gt=0)
    max_residual_overlap: float | None = Field(default=None, gt=0)
    pulse_at_wall: bool = True


def has_geometric_constraints(c: Constraints) -> bool:
    """Whether any constraint is checked on the geometry (before a run)."""
    return any(v is not None for v in (c.min_diameter_mm, c.max_length_mm, c.max_mass_kg, c.min_beads, c.max_beads))


def geometry(chain) -> dict[str, float]:
    """Smallest diameter [mm], length [mm], mass [kg] and bead count of a :class:`~hertzchain.Chain`."""
    d = chain.diameters
    # no beads (the striker onto the wall, a reference): no bead is below any minimum diameter
    return {"min_diameter_mm": float(d.min() * 1e3) if d.size else math.inf, "length_mm": float(d.sum() * 1e3),
            "mass_kg": float(chain.masses.sum()), "n_beads": d.size}


def _excess(value: float, limit: float | None, upper: bool) -> float:
    if limit is None:
        return 0.0
    d = (value - limit) if upper else (limit - value)
    return max(d, 0.0) / abs(limit)


def geometric_violation(c: Constraints, geo: dict[str, Any]) -> float:
    """Summed relative violation of the geometric constraints (0 when all hold)."""
    return (_excess(geo["min_diameter_mm"], c.min_diameter_mm, upper=False)
            + _excess(geo["length_mm"], c.max_length_mm, upper=True)
            + _excess(geo["mass_kg"], c.max_mass_kg, upper=True)
            + _excess(geo["n_beads"], c.min_beads, upper=False)
            + _excess(geo["n_beads"], c.max_beads, upper=True))


def broken_geometry(c: Constraints, geo: dict[str, Any]) -> list[str]:
    """The geometric constraints ``geo`` breaks, each as ``design.constraints.KEY = limit (value)``.

    Parameters
    ----------
    c : Constraints
        The design's constraints.
    geo : dict
        A candidate's :func:`geometry` (or a history row holding its keys).

    Returns
    -------
    list of str
        One entry per broken constraint.
    """
    out = []
    for name, key, limit, upper in (("min_diameter_mm", "min_diameter_mm", c.min_diameter_mm, False),
                                    ("max_length_mm", "length_mm", c.max_length_mm, True),
                                    ("max_mass_kg", "mass_kg", c.max_mass_kg, True),
                                    ("min_beads", "n_beads", c.min_beads, False),
                                    ("max_beads", "n_beads", c.max_beads, True)):
        if _excess(geo[key], limit, upper) > 0:
            out.append(f"design.constraints.{name} = {limit:g} (it has {geo[key]:.4g})")
    return out


def broken_run(c: Constraints, metrics: dict[str, Any]) -> list[str]:
    """The run constraints a run breaks, each as ``design.constraints.KEY = limit (value)``.

    Parameters
    ----------
    c : Constraints
        The design's constraints.
    metrics : dict
        A candidate's metrics: ``force_over_yield``, ``pulse_at_wall`` and with the elastoplastic
        law ``plastic_work_worst`` [J] and ``residual_overlap_max_worst`` [m] (worst over the scenarios).

    Returns
    -------
    list of str
        One entry per broken constraint.
    """
    out = []
    for name, key, limit in (("max_force_over_yield", "force_over_yield", c.max_force_over_yield),
                             ("max_plastic_work", "plastic_work_worst", c.max_plastic_work),
                             ("max_residual_overlap", "residual_overlap_max_worst", c.max_residual_overlap)):
        if _excess(metrics.get(key, 0.0), limit, upper=True) > 0:
            out.append(f"design.constraints.{name} = {limit:g} (it has {metrics[key]:.4g})")
    if c.pulse_at_wall and not metrics["pulse_at_wall"]:
        out.append("design.constraints.pulse_at_wall (its pulse does not reach the wall within the run)")
    return out


def geometric_margin(c: Constraints, geo: dict[str, Any]) -> float:
    """Signed distance to the nearest geometric limit: the smallest relative slack
    (limit - value) / |limit| of an upper limit, (value - limit) / |limit| of a lower one; >= 0
    exactly when :func:`geometric_violation` is 0, negative past a limit, inf without geometric
    constraints. Continuous across the boundary, so the search can find it by false position."""
    slack = [((limit - geo[key]) if upper else (geo[key] - limit)) / abs(limit)
             for key, limit, upper in (("min_diameter_mm", c.min_diameter_mm, False),
                                       ("length_mm", c.max_length_mm, True), ("mass_kg", c.max_mass_kg, True),
                                       ("n_beads", c.min_beads, False), ("n_beads", c.max_beads, True))
             if limit is not None]
    return min(slack, default=float("inf"))


def run_violation(c: Constraints, force_over_yield: float, pulse_at_wall: bool, plastic_work: float = 0.0,
                  residual_overlap_max: float = 0.0) -> float:
    """Summed relative violation of the run constraints (worst over the scenarios; 0 when all hold);
    the plastic work [J] and largest residual overlap [m] are 0 without the elastoplastic law."""
    v = _excess(force_over_yield, c.max_force_over_yield, upper=True)
    v += _excess(plastic_work, c.max_plastic_work, upper=True)
    v += _excess(residual_overlap_max, c.max_residual_overlap, upper=True)
    if c.pulse_at_wall and not pulse_at_wall:
        v += 1.0
    return v
