"""The sweep file: its ``[sweep]`` table validated, the members listed, tolerances drawn.

:func:`parse_sweep` and :func:`load_sweep` turn a sweep mapping or TOML file (described in
:mod:`hertzchain.sweep`) into a :class:`SweepConfig`: the base run config and every member's
parameter values; :func:`chunk_members` builds the models of some members (a chunk), with the
seeded manufacturing tolerances of :mod:`hertzchain.sweep.tolerances` applied.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Literal, Sequence

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from ..config import parse_path, set_path
from ..errors import ConfigError
from .tolerances import Tolerances, apply_to_ensemble, apply_to_model

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


class SweepSection(_Section):
    """The ``[sweep]`` table (cross-field rules are checked in :func:`parse_sweep`)."""

    mode: Literal["grid", "random"] = "grid"
    parameters: dict[str, Any] = {}
    n: int | None = Field(default=None, ge=1, le=MAX_MEMBERS, description="members drawn in random mode")
    seed: int = _SEED
    chunk_size: int = Field(default=32, ge=1, le=MAX_MEMBERS, description="members per chunk file")
    tolerances: Tolerances | None = None
    store: Literal["wall", "probes", "metrics"] = "wall"
    traces: list[int] = Field(default=[], description="members whose records are kept (store = 'metrics')")
    n_threads: int | None = Field(default=None, ge=1, le=4096)
    zip: list[list[str]] = Field(default=[], description="groups of parameters varied together (coupled)")
    analysis: Literal["impact", "dispersion"] = Field(
        default="impact", description="what each member gives: its impact run's wall-pulse metrics, or its band "
                                      "gaps (the chain one period of a periodic chain under chain.precompression)")


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
        One ``{path: value}`` mapping per member, in member order (for a chunk's recipe,
        :meth:`subset`, a mapping by member index).
    hash:
        SHA-256 of the normalised definition (base + sweep): two sweeps with the same hash have
        the same members, chunks and results.
    """

    base: dict
    sweep: SweepSection
    members: list[dict[str, Any]] | dict[int, dict[str, Any]]
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

    def subset(self, members) -> "SweepConfig":
        """The sweep with only some members' values (a chunk's recipe, small enough to send to a
        worker); ``members`` is then a mapping by member index, and :func:`chunk_members` of
        those indices builds the same models as on the whole sweep."""
        return SweepConfig(base=self.base, sweep=self.sweep, members={m: self.members[m] for m in members},
                           hash=self.hash)

    def definition(self) -> dict:
        """Plain-data definition (what the hash covers)."""
        sweep = self.sweep.model_dump(mode="json")
        if sweep["analysis"] == "impact":  # the default left out: the hashes of earlier sweeps stay
            del sweep["analysis"]
        return {"base": self.base, "sweep": sweep, "parameter_order": self.parameter_names}

    def models(self) -> list:
        """Every member's :class:`~hertzchain.model.Model`, tolerances applied (built once, cached;
        for inspection: a sweep builds its members chunk by chunk, :func:`chunk_members`).

        Raises :class:`ConfigError` naming the field, with the member and its values, when a
        member's config is invalid (e.g. a swept value out of range).
        """
        if self._models is None:
            self._models = [self.member_model(i) for i in range(self.n_members)]
        return self._models

    def member_model(self, i: int):
        """The :class:`~hertzchain.model.Model` of member ``i``, tolerances applied, built alone
        (Model by Model: the reference the chunks' array set-up must match number for number)."""
        from ..config import build_model, parse_config

        try:
            model = build_model(parse_config(self.member_config(i)))
        except ConfigError as exc:
            raise _member_error(exc, i, self.members[i]) from None
        return model if self.sweep.tolerances is None else apply_to_model(model, self.sweep.tolerances, i)


def _member_error(exc: ConfigError, index: int, values: dict[str, Any]) -> ConfigError:
    """A member's config error under the key the user wrote: ``sweep.parameters["PATH"]`` when the
    bad field is a swept value, ``base.FIELD`` otherwise (a base value the member's values made
    invalid, e.g. ``base.chain.taper.n`` when only ``chain.taper.q`` is swept)."""
    if exc.field.startswith("sweep."):  # already named in the sweep table (a path that does not fit the base)
        return ConfigError(exc.field, f"{exc.message} (sweep member {index}: {values})")
    swept = next((p for p in values if exc.field == p or exc.field.startswith((p + ".", p + "["))), None)
    field_name = f'sweep.parameters["{swept}"]' if swept is not None else f"base.{exc.field}"
    return ConfigError(field_name, f"{exc.field}: {exc.message} (sweep member {index}: {values})")


def chunk_members(cfg: SweepConfig, members: Sequence[int], built: dict | None = None) -> tuple[Any, list]:
    """The models of some members, tolerances applied, and their ``run.dt``.

    One model is built per distinct set of parameter values (``built`` caches them across calls:
    a tolerance Monte Carlo builds one for the whole sweep); members that share a layout come back
    as one :class:`~hertzchain.integrate.batch.ensemble.Ensemble` (array code, microseconds per member),
    others as a list of Models. Either way member r is, number for number, the model of member
    ``members[r]``: its draws depend on (seed, member index) alone, so a chunk built here, on a
    Dask worker or as part of the whole sweep is the same.

    Parameters
    ----------
    cfg : SweepConfig
        The sweep.
    members : sequence of int
        Member indices.
    built : dict or None
        Cache of nominal models by parameter values (filled here).

    Returns
    -------
    (Ensemble or list of Model, list of float or None)
        The members and their fixed time steps [s] (None: automatic).

    Raises
    ------
    ConfigError
        Naming the field and the member when a member's model or its deviations are invalid.
    """
    from ..config import build_model, parse_config
    from ..integrate.batch.ensemble import Ensemble, same_layout

    built = {} if built is None else built
    bases, dts = [], []
    for i in members:
        params = cfg.members[i]
        key = json.dumps(params, sort_keys=True, default=str)
        hit = built.get(key)
        if hit is None:
            try:
                run_cfg = parse_config(cfg.member_config(i))
                hit = built[key] = (build_model(run_cfg), run_cfg.run.dt)
            except ConfigError as exc:
                raise _member_error(exc, i, params) from None
        bases.append(hit[0])
        dts.append(hit[1])
    tol = cfg.sweep.tolerances
    if not same_layout(bases):
        return [b if tol is None else apply_to_model(b, tol, i) for b, i in zip(bases, members)], dts
    ens = Ensemble.from_models(bases)
    return (ens if tol is None else apply_to_ensemble(ens, tol, list(members))), dts


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
    if base_cfg.run.integrator not in ("verlet", "auto"):
        raise ConfigError("base.run.integrator", "sweeps run on the batched Verlet engine; use 'auto' (the default) or 'verlet'")

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
    elif not axes:  # an ensemble: n copies of the base, made different by their tolerances alone
        members = [{}] * sw.n  # one empty mapping, shared (members are read, never changed): 8 bytes each
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

    cfg = SweepConfig(base=base, sweep=sw, members=members, hash="")
    # the hash of its definition (the parameters' order kept: sort_keys loses it, and it orders the
    # grid and the random draws)
    cfg.hash = hashlib.sha256(json.dumps(cfg.definition(), sort_keys=True, default=str).encode()).hexdigest()
    # Every member must be a valid run config: fail now, naming the field, not halfway through
    # (each distinct set of values once: an ensemble's million members are one config).
    seen = set()
    for i in range(cfg.n_members):
        key = json.dumps(members[i], sort_keys=True, default=str)
        if key in seen:
            continue
        seen.add(key)
        try:
            parse_config(cfg.member_config(i))
        except ConfigError as exc:
            raise _member_error(exc, i, members[i]) from None
    for k, m in enumerate(sw.traces):
        if sw.store != "metrics":
            raise ConfigError("sweep.traces", f"goes with store = 'metrics' (store = '{sw.store}' keeps every "
                              "member's records already)")
        if not 0 <= m < cfg.n_members:
            raise ConfigError(f"sweep.traces[{k}]", f"member {m} is not in the sweep (members 0..{cfg.n_members - 1})")
    if len(set(sw.traces)) != len(sw.traces):
        raise ConfigError("sweep.traces", "lists a member twice")
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
