"""The design file: ``[base]`` (a run config) and ``[design]`` (objective, variables, constraints, search).

::

    [base]            # a run config, as `hertzchain run` takes it
    chain = { uniform = { n = 16, diameter_mm = 26.0 }, taper = { n = 14, q = 0.05 } }
    striker = { diameter_mm = 8.0, velocity = 0.2 }
    run = { duration = 3.0e-3, sample_interval = 1e-7 }

    [design]
    objective = "peak_wall_force"        # or a list of several: a Pareto front
    variables = { "chain.taper.n" = [4, 30], "chain.taper.q" = [0.0, 0.2] }
    constraints = { min_diameter_mm = 10.0 }
    budget = 2000                        # engine evaluations at most
    seed = 1

Optional keys of ``[design]``: ``population`` (candidates per generation), ``polish`` (local
search after the population method, default true), ``window = [t0, t1]`` [s] (of
``energy_at_wall``), ``chunk_size`` (members per Dask task), ``[design.robust]``
(:class:`~hertzchain.design.objectives.Robust`), ``[design.shape]``
(:class:`~hertzchain.design.space.Shape`), ``search_steps_per_radian`` and ``verify_top``
(multi-fidelity search, :func:`search_fidelity`).
"""

from __future__ import annotations

import copy
import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator

from ..errors import ConfigError
from .constraints import Constraints
from .body import BODY_OBJECTIVES
from .objectives import OBJECTIVES, PLASTIC_OBJECTIVES, SAMPLING_FREE, Fidelity, Robust
from .space import Space, parse_shape, parse_variables
from ..laws import get_law

__all__ = ["DesignProblem", "parse_design", "load_design", "search_fidelity"]

#: Default adaptive-step accuracy of the search runs (``design.search_steps_per_radian``): the
#: peak wall force of the n-q design's chains is then within ~1e-4 of the full-accuracy value
#: (error ~ (1 / steps_per_radian)^2: 3e-4 at 10, 7e-5 at 20, 2e-5 at 40, 1e-6 at 400; measured
#: in tests/test_design_fidelity.py), far below the differences the search ranks.
SEARCH_STEPS_PER_RADIAN = 20.0


class DesignSection(BaseModel):
    """The ``[design]`` table (variables and shape are checked by :mod:`hertzchain.design.space`)."""

    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, allow_inf_nan=False)

    objective: str | list[str] = "peak_wall_force"
    variables: dict[str, Any]
    constraints: Constraints = Constraints()
    budget: int = Field(default=2000, ge=1)
    # NumPy and cma seed their generators with it (and seed + 1): 32-bit unsigned integers.
    seed: int = Field(default=0, ge=0, le=2**32 - 2)
    population: int | None = Field(default=None, ge=4)
    polish: bool = True
    window: list[float] | None = None
    chunk_size: int = Field(default=64, ge=1)
    robust: Robust | None = None
    shape: dict[str, Any] | None = None
    search_steps_per_radian: float | str = SEARCH_STEPS_PER_RADIAN
    verify_top: int = Field(default=4, ge=1, le=1000)

    @field_validator("search_steps_per_radian", mode="before")
    @classmethod
    def _full_or_number(cls, v: Any) -> Any:
        # Checked here in full, so that the error names the field with the allowed values.
        from ..config import BOUNDS

        if v == "full":
            return v
        lo, hi = BOUNDS["steps_per_radian"]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (lo <= v <= hi):
            raise ValueError(f"must be 'full' (search at the base config's accuracy) or a number of adaptive "
                             f"steps per radian from {lo:g} to {hi:g}")
        return float(v)


class _DesignFile(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, allow_inf_nan=False)

    base: dict[str, Any]
    design: DesignSection


@dataclass
class DesignProblem:
    """A validated design: the space, the objectives, the constraints and the search settings.

    Attributes
    ----------
    base : dict
        The base run config.
    section : DesignSection
        The validated ``[design]`` table.
    space : Space
        Variables (unit-cube coordinates) and the chain shape.
    objectives : list of str
        Objective names (one: a single optimum; several: a Pareto front).
    hash : str
        SHA-256 of the normalised file: a checkpoint is resumed only by the same design.
    """

    base: dict
    section: DesignSection
    space: Space
    objectives: list[str]
    hash: str

    @property
    def objective_name(self) -> str:
        """The objectives joined by ``+`` (design.json's ``objective_name``)."""
        return "+".join(self.objectives)


def search_fidelity(problem: DesignProblem) -> Fidelity:
    """The accuracy the search runs candidates at (multi-fidelity search).

    Coarse (``name = "search"``) when ``design.search_steps_per_radian`` is a number below the
    base config's ``run.steps_per_radian``, the base uses the adaptive step (no ``run.dt``) and
    there is one objective: candidates are then run with that many steps per radian (peak error
    ~ (1 / steps_per_radian)^2), and, when the objective and constraints read no sampled record
    (objective ``peak_wall_force``, refined at every step; no ``max_force_over_yield``
    constraint), sampled more coarsely (``coarse_sampling``: still
    :data:`~hertzchain.design.objectives.SEARCH_SAMPLES_PER_PULSE` samples per wall pulse for
    the pulse-arrival check, :func:`~hertzchain.design.objectives.search_interval`). The best
    ``verify_top`` candidates are then run again at full accuracy.
    Otherwise (``"full"``, a fixed step, several objectives: a Pareto front's values are all
    reported) the search runs at the base config's own accuracy.

    Parameters
    ----------
    problem : DesignProblem
        The design.

    Returns
    -------
    Fidelity
        ``Fidelity("full")`` or ``Fidelity("search", steps_per_radian, coarse_sampling)``.
    """
    from ..config import parse_config

    sec = problem.section
    run = parse_config(problem.base).run
    if (sec.search_steps_per_radian == "full" or run.dt is not None or len(problem.objectives) > 1
            or sec.search_steps_per_radian >= run.steps_per_radian):
        return Fidelity()
    # (the plastic constraints, like the plastic objectives, read the per-step state: sampling-free)
    coarse_sampling = set(problem.objectives) <= SAMPLING_FREE and sec.constraints.max_force_over_yield is None
    return Fidelity("search", float(sec.search_steps_per_radian), coarse_sampling)


def _loc(prefix: tuple, loc: tuple) -> str:
    out = ""
    for part in prefix + tuple(loc):
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out


def parse_design(data: dict) -> DesignProblem:
    """Validate a design mapping (``{"base": ..., "design": ...}``).

    Parameters
    ----------
    data : dict
        The design file as read from TOML.

    Returns
    -------
    DesignProblem
        The validated problem.

    Raises
    ------
    ConfigError
        Naming the first bad field (``design.budget``, ``design.variables["chain.taper.q"]``,
        ``base.chain.taper.q``), what was wrong and what is allowed.
    """
    from pydantic import ValidationError

    from ..config import build_model, parse_config
    from ..sweep.tolerances import Tolerances

    try:
        parsed = _DesignFile.model_validate(data)
    except ValidationError as exc:
        err = exc.errors()[0]
        name = _loc((), err["loc"])
        if err["type"] == "missing":
            raise ConfigError(name, "is required") from None
        if err["type"] == "extra_forbidden":
            raise ConfigError(name, "unknown key") from None
        msg = err["msg"].removeprefix("Value error, ")
        if not isinstance(err.get("input"), (dict, list)):
            msg += f" (got {err.get('input')!r})"
        raise ConfigError(name or "design", msg) from None
    sec = parsed.design
    base = parsed.base
    try:
        base_cfg = parse_config(base)
        build_model(base_cfg)
    except ConfigError as exc:
        raise ConfigError(f"base.{exc.field}", exc.message) from None
    if base_cfg.run.integrator not in ("verlet", "auto"):
        raise ConfigError("base.run.integrator", "designs run on the batched Verlet engine; use 'auto' (the default) or 'verlet'")
    if base_cfg.wall.type == "none":
        raise ConfigError("base.wall.type", "a design is judged at the wall: use type = 'flat' or 'body'")
    if base_cfg.wall.material is None:
        # Every candidate meets the same wall: the base chain's first material, written into the
        # base (a candidate whose first bead changes material would otherwise change its wall).
        base = copy.deepcopy(base)
        base.setdefault("wall", {})["material"] = build_model(base_cfg).wall_material.name
    if base_cfg.run.integrator == "auto":
        # Candidates are judged by the batched Verlet engine: their configs name it, so that a
        # candidate's config run alone (best.toml) gives the objective the design reports.
        base = copy.deepcopy(base)
        base.setdefault("run", {})["integrator"] = "verlet"

    objectives = [sec.objective] if isinstance(sec.objective, str) else list(sec.objective)
    if not objectives:
        raise ConfigError("design.objective", f"needs at least one of {', '.join(OBJECTIVES)}")
    for i, name in enumerate(objectives):
        field = "design.objective" if isinstance(sec.objective, str) else f"design.objective[{i}]"
        if name not in OBJECTIVES:
            raise ConfigError(field, f"unknown objective {name!r}; allowed: {', '.join(OBJECTIVES)}")
        if name in BODY_OBJECTIVES and base_cfg.wall.type != "body":
            raise ConfigError(field, f"{name!r} measures a protected body: set [base.wall] type = 'body' (with its "
                              "mass, stiffness and damping)")
    if len(set(objectives)) != len(objectives):
        raise ConfigError("design.objective", "lists an objective twice")
    plastic = [n for n in objectives if n in PLASTIC_OBJECTIVES] + [
        f"constraints.{k}" for k in ("max_plastic_work", "max_residual_overlap") if getattr(sec.constraints, k) is not None]
    if plastic and not get_law(base_cfg.contact.law).plastic:
        raise ConfigError("design.objective" if plastic[0] in PLASTIC_OBJECTIVES else f"design.{plastic[0]}",
                          f"{plastic[0]} needs contact yield: set [base.contact] law = 'elastoplastic' (the "
                          f"{base_cfg.contact.law} law does no plastic work)")
    if sec.window is not None and not (len(sec.window) == 2 and 0 <= sec.window[0] < sec.window[1]):
        raise ConfigError("design.window", f"must be [t0, t1] in s with 0 <= t0 < t1, got {list(sec.window)}")
    if sec.robust is not None:
        if sec.robust.tolerances is not None:
            try:
                Tolerances(**sec.robust.tolerances)
            except (ValidationError, TypeError) as exc:
                raise ConfigError("design.robust.tolerances", f"{exc}".splitlines()[-1].strip() +
                                  f"; allowed keys: {', '.join(Tolerances.model_fields)}") from None
        for i, v in enumerate(sec.robust.velocities or []):
            if not v > 0:
                raise ConfigError(f"design.robust.velocities[{i}]", f"must be a striker speed > 0 in m/s, got {v!r}")
        if sec.robust.velocities == []:
            raise ConfigError("design.robust.velocities", "needs at least one speed (or leave it out)")

    shape = parse_shape(sec.shape)
    variables, monotone = parse_variables(sec.variables, base, shape)
    space = Space(base, variables, shape, monotone)
    # Every corner and the centre of the space must be a valid run config: fail now, naming the
    # variable, not after an hour of search.
    probes = []
    for x in (np.zeros(space.dim), np.ones(space.dim), np.full(space.dim, 0.5)):
        vals = space.values(x)
        try:
            cfg = space.config(vals)
            build_model(parse_config(cfg))
        except ConfigError as exc:
            raise ConfigError(exc.field, f"{exc.message} (candidate {vals}; check the ranges in design.variables)") from None
        probes.append(cfg)
    if base_cfg.run.duration == "auto":
        # Candidates share one time axis (one batched call per generation): the automatic duration
        # is resolved once, the longest over the space's corners and centre at every robust speed,
        # and written into [base.run] (so best.toml holds it). A candidate whose pulse still does
        # not arrive in time is infeasible (constraint pulse_at_wall), never a false optimum.
        from ..runs.simulation import auto_duration

        speeds = sec.robust.velocities if sec.robust is not None and sec.robust.velocities else [None]
        longest = max(auto_duration(build_model(parse_config(
            c if v is None else {**c, "striker": {**c.get("striker", {}), "velocity": v}}))) for c in probes for v in speeds)
        base = copy.deepcopy(base)
        base.setdefault("run", {})["duration"] = longest
        space = Space(base, variables, shape, monotone)

    definition = {"base": base, "design": sec.model_dump(mode="json")}
    digest = hashlib.sha256(json.dumps(definition, sort_keys=True, default=str).encode()).hexdigest()
    return DesignProblem(base, sec, space, objectives, digest)


def load_design(path: str | Path, overrides=()) -> DesignProblem:
    """Read and validate a TOML design file; ``--set`` overrides address ``[base]`` (prefix ``base``).

    Parameters
    ----------
    path : str or Path
        The design file.
    overrides : iterable of str
        ``DOTTED.PATH=VALUE`` assignments relative to ``[base]`` (see
        ``hertzchain.config.apply_overrides``).

    Returns
    -------
    DesignProblem
        The validated problem.
    """
    from ..config import apply_overrides, read_toml

    return parse_design(apply_overrides(read_toml(path, "design file"), overrides, prefix="base"))
