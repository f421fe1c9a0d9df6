"""The sweep file: its ``[sweep]`` table validated, the members listed, tolerances drawn.

:func:`parse_sweep` and :func:`load_sweep` turn a sweep mapping or TOML file (described in
:mod:`hertzchain.sweep`) into a :class:`SweepConfig`: the base run config and every member's
parameter values, with the seeded manufacturing tolerances that make each member's beads
(:meth:`SweepConfig.models`, or all members as one array ensemble: :func:`_member_ensemble`).
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Iterable, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from ..config import parse_path, set_path
from ..errors import ConfigError

#: Sections of a run config that members may not differ in: the batched engine shares them.
_SHARED = {"run.duration", "run.sample_interval", "run.integrator", "run.rtol", "run.steps_per_radian"}


# ------------------------------------------------------------------------------ schema
class _Section(BaseModel):
    # strict like the run config (hertzchain.config): no booleans or strings as numbers, no NaN
    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, allow_inf_nan=False)


#: Most members a sweep may have (a grid's product of list lengths, or random mode's n).
MAX_MEMBERS = 1_000_000
_SEED = Field(default=0, ge=0, le=2**63 - 1)


class Range(_Section):
    """A range to draw from in random mode: uniform in [low, high] (log-uniform with ``log``;
    integers low..high inclusive with ``integer``)."""

    low: float
    high: float
    log: bool = False
    integer: bool = False


class Tolerances(_Section):
    """Per-bead random deviations (manufacturing tolerances), seeded per member index."""

    diameter_rel: float = Field(default=0.0, ge=0, lt=0.1, description="relative diameter deviation (1 sigma)")
    offset_mm: float = Field(default=0.0, ge=0, le=1e3, description="perpendicular offset deviation, mm (1 sigma)")
    distribution: Literal["normal", "uniform"] = "normal"
    seed: int = _SEED


class SweepSection(_Section):
    """The ``[sweep]`` table (cross-field rules are checked in :func:`parse_sweep`)."""

    mode: Literal["grid", "random"] = "grid"
    parameters: dict[str, Any] = {}
    n: int | None = Field(default=None, ge=1, le=MAX_MEMBERS, description="members drawn in random mode")
    seed: int = _SEED
    chunk_size: int = Field(default=32, ge=1, le=MAX_MEMBERS, description="members per chunk file")
    tolerances: Tolerances | None = None
    store: Literal["wall", "probes"] = "wall"
    n_threads: int | None = Field(default=None, ge=1, le=4096)
    zip: list[list[str]] = Field(default=[], description="groups of parameters varied together (coupled)")


class _SweepFile(_Section):
    base: dict[str, Any]
    sweep: SweepSection


def _loc_name(loc: tuple[Any, ...]) -> str:
    out = ""
    for i, part in enumerate(loc):
        if isinstance(part, int):
            out += f"[{part}]"
        elif i > 0 and loc[i - 1] == "parameters":
            out += f'["{part}"]'  # parameter paths contain dots: quote them
        else:
            out += ("." if out else "") + str(part)
    return out


# ------------------------------------------------------------------------------ paths
def _set_path(cfg: dict, path: str, value: Any) -> None:
    """Set ``value`` at dotted ``path`` in ``cfg`` (tables are created when missing)."""
    set_path(cfg, parse_path(path), copy.deepcopy(value), f'sweep.parameters["{path}"]')


# ------------------------------------------------------------------------------ the sweep
@dataclass
class SweepConfig:
    """A validated sweep: the base config, the ``[sweep]`` table and every member's parameter values.

    Attributes
    ----------
    base:
        The base run config (a plain mapping, as in a run file).
    sweep:
        The validated ``[sweep]`` table.
    members:
        One ``{path: value}`` mapping per member, in member order.
    hash:
        SHA-256 of the normalised definition (base + sweep): two sweeps with the same hash have
        the same members, chunks and results.
    """

    base: dict
    sweep: SweepSection
    members: list[dict[str, Any]]
    hash: str
    _models: list | None = field(default=None, repr=False)

    @property
    def n_members(self) -> int:
        return len(self.members)

    @property
    def parameter_names(self) -> list[str]:
        return list(self.sweep.parameters)

    def chunks(self) -> list[range]:
        """Member indices of every chunk."""
        cs = self.sweep.chunk_size
        return [range(i, min(i + cs, self.n_members)) for i in range(0, self.n_members, cs)]

    def member_config(self, i: int) -> dict:
        """The run config (mapping) of member ``i``: the base with the member's values set."""
        cfg = copy.deepcopy(self.base)
        for path, value in self.members[i].items():
            _set_path(cfg, path, value)
        return cfg

    def definition(self) -> dict:
        """Plain-data definition (what the hash covers)."""
        return {"base": self.base, "sweep": self.sweep.model_dump(mode="json"),
                "parameter_order": self.parameter_names}

    def models(self) -> list:
        """Every member's :class:`~hertzchain.model.Model`, tolerances applied (built once, cached).

        Raises :class:`ConfigError` naming the field, with the member and its values, when a
        member's config is invalid (e.g. a swept value out of range).
        """
        if self._models is None:
            from ..config import build_model, parse_config

            out = []
            for i in range(self.n_members):
                try:
                    model = build_model(parse_config(self.member_config(i)))
                except ConfigError as exc:
                    raise _member_error(exc, i, self.members[i]) from None
                if self.sweep.tolerances is not None:
                    model = _apply_tolerances(model, self.sweep.tolerances, i)
                out.append(model)
            self._models = out
        return self._models


def _member_error(exc: ConfigError, index: int, values: dict[str, Any]) -> ConfigError:
    """A member's config error under the key the user wrote: ``sweep.parameters["PATH"]`` when the
    bad field is a swept value, ``base.FIELD`` otherwise (a base value the member's values made
    invalid, e.g. ``base.chain.taper.n`` when only ``chain.taper.q`` is swept)."""
    if exc.field.startswith("sweep."):  # already named in the sweep table (a path that does not fit the base)
        return ConfigError(exc.field, f"{exc.message} (sweep member {index}: {values})")
    swept = next((p for p in values if exc.field == p or exc.field.startswith((p + ".", p + "["))), None)
    field_name = f'sweep.parameters["{swept}"]' if swept is not None else f"base.{exc.field}"
    return ConfigError(field_name, f"{exc.field}: {exc.message} (sweep member {index}: {values})")


def _apply_tolerances(model, tol: Tolerances, index: int):
    """Perturb the beads of ``model`` with the seeded deviations of member ``index``."""
    from ..chain import Chain

    # One stream per (seed, member): a member's deviations do not depend on the others; both
    # rows are always drawn so that changing one tolerance leaves the other's draws alone.
    z = _tolerance_draws(tol, index, model.chain.n_beads)
    chain = model.chain
    diameters = chain.diameters * (1.0 + tol.diameter_rel * z[0])
    offsets = chain.offsets + tol.offset_mm * 1e-3 * z[1] if tol.offset_mm > 0 else chain.offsets
    try:
        return replace(model, chain=Chain(diameters, chain.materials, offsets))
    except ConfigError as exc:
        raise ConfigError("sweep.tolerances", f"member {index}: {exc.field}: {exc.message}") from None


def _tolerance_draws(tol: Tolerances, index: int, n: int) -> np.ndarray:
    """The (2, n) standard deviates of member ``index`` (diameters, offsets), as _apply_tolerances draws them."""
    rng = np.random.default_rng([tol.seed, index, 1])
    return rng.standard_normal((2, n)) if tol.distribution == "normal" else rng.uniform(-1.0, 1.0, (2, n))


def _member_ensemble(cfg: SweepConfig) -> tuple[Any, list]:
    """Every member as one :class:`~hertzchain.integrate.ensemble.Ensemble` (None when their layouts
    differ) and every member's ``run.dt``.

    Array code instead of a Model per member: one model is built per distinct set of parameter
    values (a tolerance Monte Carlo builds one), and the tolerances are applied to the stacked
    diameters and offsets; the members are those of :meth:`SweepConfig.models`, number for number.
    """
    from ..config import build_model, parse_config
    from ..integrate.ensemble import Ensemble, same_layout

    built: dict[str, tuple] = {}
    bases, dts = [], []
    for i, params in enumerate(cfg.members):
        key = json.dumps(params, sort_keys=True, default=str)
        hit = built.get(key)
        if hit is None:
            try:
                run_cfg = parse_config(cfg.member_config(i))
                hit = built[key] = (build_model(run_cfg), run_cfg.run.dt)
            except ConfigError as exc:
                raise ConfigError(exc.field, f"{exc.message} (sweep member {i}: {params})") from None
        bases.append(hit[0])
        dts.append(hit[1])
    if not same_layout(bases):
        return None, dts
    ens = Ensemble.from_models(bases)
    tol = cfg.sweep.tolerances
    if tol is not None:
        z = np.stack([_tolerance_draws(tol, i, ens.n_beads) for i in range(ens.n_members)])
        arrays = {"diameters": ens.diameters * (1.0 + tol.diameter_rel * z[:, 0])}
        if tol.offset_mm > 0:
            arrays["offsets"] = ens.offsets + tol.offset_mm * 1e-3 * z[:, 1]
        try:
            ens = ens.replace(**arrays)
        except ConfigError as exc:
            raise ConfigError("sweep.tolerances", f"{exc.field}: {exc.message}") from None
    return ens, dts


def _draw(spec: list | Range, rng: np.random.Generator) -> Any:
    if isinstance(spec, Range):
        if spec.integer:
            return int(rng.integers(math.ceil(spec.low), math.floor(spec.high) + 1))
        if spec.log:
            return float(math.exp(rng.uniform(math.log(spec.low), math.log(spec.high))))
        return float(rng.uniform(spec.low, spec.high))
    return copy.deepcopy(spec[int(rng.integers(len(spec)))])


def _allowed_keys(model: Any, loc: tuple) -> str:
    """Keys allowed where an unknown key was found (walks the nested sections of ``model``)."""
    for part in loc[:-1]:
        fld = getattr(model, "model_fields", {}).get(part) if isinstance(part, str) else None
        if fld is None:
            return ""
        args = (fld.annotation, *getattr(fld.annotation, "__args__", ()))
        model = next((a for a in args if isinstance(a, type) and issubclass(a, BaseModel)), None)
    return ", ".join(getattr(model, "model_fields", {}))


def _validate(model: type[BaseModel], data: Any, prefix: tuple) -> Any:
    """pydantic validation with the first problem raised as a ConfigError naming the field."""
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        err = exc.errors()[0]
        name = _loc_name(prefix + tuple(err["loc"]))
        if err["type"] == "missing":
            raise ConfigError(name, "is required") from None
        if err["type"] == "extra_forbidden":
            allowed = _allowed_keys(model, tuple(err["loc"]))
            raise ConfigError(name, "unknown key" + (f"; allowed keys here: {allowed}" if allowed else "")) from None
        msg = err["msg"].removeprefix("Value error, ")
        if not isinstance(err.get("input"), (dict, list)):
            msg += f" (got {err.get('input')!r})"
        raise ConfigError(name or "sweep", msg) from None


def parse_sweep(data: dict) -> SweepConfig:
    """Validate a sweep mapping (``{"base": ..., "sweep": ...}``) and list its members.

    Raises :class:`ConfigError` naming the first bad field (``sweep.chunk_size``,
    ``sweep.parameters["striker.velocity"]``, ``chain.taper.q`` for a bad base or member value).
    """
    from ..config import parse_config

    parsed = _validate(_SweepFile, data, ())
    sw = parsed.sweep
    base = parsed.base
    try:
        base_cfg = parse_config(base)
    except ConfigError as exc:
        raise ConfigError(f"base.{exc.field}", exc.message) from None
    if base_cfg.run.integrator != "verlet":
        raise ConfigError("base.run.integrator", "sweeps run on the batched Verlet engine; use 'verlet'")

    if sw.mode == "grid" and sw.n is not None:
        raise ConfigError("sweep.n", "is for mode = 'random'; a grid has one member per combination of values")
    if sw.mode == "random" and sw.n is None:
        raise ConfigError("sweep.n", "mode = 'random' needs n, the number of members to draw")
    if not sw.parameters and sw.tolerances is None:
        raise ConfigError("sweep.parameters", "is empty: give parameters to sweep (or tolerances for an ensemble)")
    specs: dict[str, list | Range] = {}
    for path, spec in sw.parameters.items():
        name = f'sweep.parameters["{path}"]'
        try:
            tokens = parse_path(path)
        except ValueError:
            raise ConfigError(name, "is not a dotted path into the base config (e.g. 'striker.velocity', "
                              "'chain.diameters_mm[3]')") from None
        if tokens[0] not in type(base_cfg).model_fields:
            raise ConfigError(name, f"'{tokens[0]}' is not a section of a run config "
                              f"({', '.join(type(base_cfg).model_fields)})")
        if ".".join(str(t) for t in tokens[:2]) in _SHARED:
            raise ConfigError(name, "all members share the duration, sample interval and integrator; "
                              "set it in [base.run]")
        if isinstance(spec, list):
            if not spec:
                raise ConfigError(name, "needs at least one value")
            specs[path] = spec
        elif isinstance(spec, dict) and sw.mode == "random":
            rng_spec = _validate(Range, spec, ("sweep", "parameters", path))
            if not (math.isfinite(rng_spec.low) and math.isfinite(rng_spec.high)):
                raise ConfigError(name, "low and high must be finite numbers")
            if rng_spec.high < rng_spec.low:
                raise ConfigError(f"{name}.high", f"must not be below low ({rng_spec.low!r}), got {rng_spec.high!r}")
            if rng_spec.log and rng_spec.low <= 0:
                raise ConfigError(f"{name}.low", f"a log range needs low > 0, got {rng_spec.low!r}")
            if rng_spec.integer and math.ceil(rng_spec.low) > math.floor(rng_spec.high):
                raise ConfigError(name, f"holds no integer between {rng_spec.low!r} and {rng_spec.high!r}")
            specs[path] = rng_spec
        elif sw.mode == "grid":
            raise ConfigError(name, f"a grid sweep needs a list of values, got {spec!r}")
        else:
            raise ConfigError(name, f"needs a list of values to choose from or a range "
                              f"{{low = , high = }}, got {spec!r}")

    names = list(sw.parameters)
    axes = _zip_axes(sw, specs)
    if sw.mode == "grid":
        # One grid axis per zipped group (its lists walked together) and per other parameter.
        size = math.prod(len(specs[ax[0]]) for ax in axes)
        if size > MAX_MEMBERS:
            raise ConfigError("sweep.parameters", f"the grid has {size:,} members (the product of the list "
                              f"lengths); at most {MAX_MEMBERS:,} are allowed: use fewer values or mode = 'random'")
        combos = itertools.product(*(range(len(specs[ax[0]])) for ax in axes)) if axes else [()]
        members = []
        for c in combos:
            member = {k: specs[k][i] for ax, i in zip(axes, c) for k in ax}
            members.append({k: member[k] for k in names})
    else:
        members = []
        for i in range(sw.n):
            rng = np.random.default_rng([sw.seed, i, 0])  # one stream per member: see module docstring
            member = {}
            for ax in axes:
                if len(ax) == 1:
                    member[ax[0]] = _draw(specs[ax[0]], rng)
                else:  # a zipped group: one draw picks the same position in every list
                    j = int(rng.integers(len(specs[ax[0]])))
                    member.update({k: copy.deepcopy(specs[k][j]) for k in ax})
            members.append({k: member[k] for k in names})

    definition = {"base": base, "sweep": sw.model_dump(mode="json"),
                  # sort_keys below loses the order of the parameters, which orders the grid
                  # and the random draws: keep it explicitly.
                  "parameter_order": names}
    digest = hashlib.sha256(json.dumps(definition, sort_keys=True, default=str).encode()).hexdigest()
    cfg = SweepConfig(base=base, sweep=sw, members=members, hash=digest)
    # Every member must be a valid run config: fail now, naming the field, not halfway through.
    for i in range(cfg.n_members):
        try:
            parse_config(cfg.member_config(i))
        except ConfigError as exc:
            raise _member_error(exc, i, members[i]) from None
    return cfg


def _zip_axes(sw: SweepSection, specs: dict[str, list | Range]) -> list[list[str]]:
    """Axes of the sweep: each ``zip`` group (coupled parameters) and each other parameter alone."""
    grouped: dict[str, int] = {}
    for g, group in enumerate(sw.zip):
        name = f"sweep.zip[{g}]"
        if len(group) < 2:
            raise ConfigError(name, f"a zipped group couples at least two parameters, got {group!r}")
        for path in group:
            if path not in specs:
                raise ConfigError(name, f"{path!r} is not one of sweep.parameters ({', '.join(specs)})")
            if path in grouped:
                raise ConfigError(name, f"{path!r} is already zipped in sweep.zip[{grouped[path]}]")
            if not isinstance(specs[path], list):
                raise ConfigError(f'sweep.parameters["{path}"]', "a zipped parameter needs a list of values, not a range")
            grouped[path] = g
        lengths = {p: len(specs[p]) for p in group}
        if len(set(lengths.values())) != 1:
            raise ConfigError(name, "zipped parameters need lists of equal length, got "
                              + ", ".join(f"{p}: {n}" for p, n in lengths.items()))
    axes: list[list[str]] = []
    for path in specs:
        if path in grouped:
            group = list(sw.zip[grouped[path]])
            if group not in axes:  # the group's axis sits where its first parameter is listed
                axes.append(group)
        else:
            axes.append([path])
    return axes


def load_sweep(path: str | Path, overrides: Iterable[str] = ()) -> SweepConfig:
    """Read and validate a TOML sweep file (see the module docstring).

    Parameters
    ----------
    path : str or pathlib.Path
        The sweep file: a ``[base]`` run config and a ``[sweep]`` table.
    overrides : iterable of str
        ``--set DOTTED.PATH=VALUE`` assignments relative to ``[base]``
        (:func:`hertzchain.config.apply_overrides`), in the keys' own units, validated like the file.

    Returns
    -------
    SweepConfig
        The validated sweep (members are drawn lazily).
    """
    from ..config import apply_overrides, read_toml

    return parse_sweep(apply_overrides(read_toml(path, "sweep file"), overrides, prefix="base"))
