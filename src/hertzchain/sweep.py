"""Parameter sweeps and tolerance ensembles, computed in resumable chunks by the batched engine.

A sweep file (TOML) has two tables::

    [base]                      # a normal run config (see hertzchain.config)
    chain = { uniform = { n = 16, diameter_mm = 26.0 }, taper = { n = 8, q = 0.05 } }
    striker = { velocity = 0.2 }
    run = { duration = 2.0e-3, sample_interval = 1e-7 }

    [sweep]
    mode = "grid"               # cartesian product of the lists; or "random"
    parameters = { "striker.velocity" = [0.1, 0.2, 0.4], "chain.taper.q" = [0.02, 0.05] }
    chunk_size = 16             # members per chunk file (the unit of resumption)
    tolerances = { diameter_rel = 0.001, offset_mm = 0.05, seed = 1 }

Parameters are dotted paths into the base config (``chain.taper.q``, ``chain.diameters_mm[3]``).
``zip = [["chain.taper.n", "chain.taper.q"]]`` couples parameters: their lists (of equal
length) are walked together, as one axis of the grid (or one draw in random mode), e.g. bead
count and tapering factor chosen so the last bead keeps its size. ``mode = "random"`` draws ``n`` members with ``seed``; each parameter is then a list to choose
from or a range ``{ low = 0.1, high = 0.4 }`` (options ``log = true``, ``integer = true``).
``tolerances`` perturbs every member's beads with seeded random deviations (manufacturing
tolerances): each diameter phi_n -> phi_n (1 + diameter_rel z) and each perpendicular offset
e_n -> e_n + offset_mm z' [mm], z, z' standard normal (``distribution = "uniform"``: uniform in
[-1, 1], so the values are half-widths). Random draws depend only on (seed, member index): a
member is the same whatever ``n`` or ``chunk_size`` is.

:func:`run_sweep` writes into ``out_dir``:

- ``sweep.json``: the sweep definition and its hash (a rerun with a different sweep is refused
  unless ``force``);
- ``chunks/chunk_00012.nc``: one file per finished chunk (the batched results stacked along
  ``member`` plus the pulse metrics), written through :mod:`hertzchain.fileio` (unique temporary
  name, fsync, rename), so a killed sweep never leaves a half chunk, and a rerun skips every
  chunk already on disk (resumption); beside it ``chunk_00012.nc.sha256``, the SHA-256 of the
  file, checked before a chunk is skipped: a chunk damaged on disk is computed again;
- ``.sweep.lock``: held (``flock``) while a sweep writes into the folder; a second sweep on the
  same folder is refused (:class:`SweepLocked`) instead of mixing files with the first;
- ``metrics.csv`` (and ``metrics.parquet`` when pyarrow is installed): one row per member, the
  swept parameter values and the wall-pulse metrics of the paper (Sec. III), SI units:
  ``F_m`` [N], ``T`` [s], ``tau`` [s], ``Q_F`` [N s], ``Q_T`` [N s].

Parallelism is passed in: locally each chunk already uses every core
(Numba ``prange``); with a Dask ``distributed.Client`` (or any executor with ``submit``, or
anything with ``map``) the chunks are farmed out and written as they finish.
"""

from __future__ import annotations

import copy
import datetime as _dt
import hashlib
import importlib.util
import itertools
import json
import math
import os
import warnings
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from .config import parse_path, set_path
from .errors import ConfigError, HertzchainError, SimulationDiverged

__all__ = ["SweepConfig", "SweepMismatch", "SweepLocked", "SweepResult", "load_sweep", "parse_sweep", "run_sweep",
           "compute_chunk", "METRIC_COLUMNS"]

#: Wall-pulse metrics of each member (paper Sec. III), in SI units, with their PulseFit attribute.
METRIC_COLUMNS = {"F_m": "peak_force", "T": "time_of_flight", "tau": "duration", "Q_F": "front_momentum",
                  "Q_T": "tail_momentum"}
_METRIC_UNITS = {"F_m": ("N", "peak wall force F_m of the cos^6 fit"),
                 "T": ("s", "time of flight T of the wall pulse"),
                 "tau": ("s", "duration tau of the wall pulse"),
                 "Q_F": ("N s", "front momentum Q_F (integral of F up to T + tau)"),
                 "Q_T": ("N s", "tail momentum Q_T (integral of F after T + tau)")}
#: Sections of a run config that members may not differ in: the batched engine shares them.
_SHARED = {"run.duration", "run.sample_interval", "run.integrator", "run.rtol", "run.steps_per_radian"}
_CHUNK_NAME = "chunk_{:05d}.nc"


class SweepMismatch(HertzchainError):
    """``out_dir`` already holds the results of a different sweep."""


class SweepLocked(HertzchainError):
    """Another sweep is writing into ``out_dir`` now."""


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
            from .config import build_model, parse_config

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
    from .chain import Chain

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
    from .config import build_model, parse_config
    from .integrate.ensemble import Ensemble, same_layout

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
    from .config import parse_config

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
    from .config import apply_overrides, read_toml

    return parse_sweep(apply_overrides(read_toml(path, "sweep file"), overrides, prefix="base"))


# ------------------------------------------------------------------------------ computing chunks
@dataclass
class _ChunkTask:
    """Everything a worker needs for one chunk (picklable; no file access on the worker)."""

    index: int
    members: list[int]
    models: Any  # the members: a list of Models, or an Ensemble (array set-up) when they share a layout
    params: list[dict]
    duration: float
    probes: Any
    dt: float | None
    n_threads: int | None
    sweep_hash: str
    device: str = "auto"
    steps_per_radian: float | None = None


def _wall_metrics(time: np.ndarray, force: np.ndarray) -> dict[str, float]:
    """Wall-pulse metrics F_m [N], T [s], tau [s], Q_F [N s], Q_T [N s] by :func:`hertzchain.analysis.fit_pulse`.

    Raises :class:`hertzchain.errors.PulseNotFound` when the record holds no pulse.
    """
    from .analysis import fit_pulse

    fit = fit_pulse(time, force)
    return {col: float(getattr(fit, attr)) for col, attr in METRIC_COLUMNS.items()}


def compute_chunk(task: _ChunkTask):
    """Simulate one chunk with the batched engine and fit the wall pulses; returns its Dataset.

    Runs wherever it is sent (locally, a Dask worker): it only needs the task. Elastic-limit
    warnings are not raised per member (a sweep would print thousands); the
    ``elastic_limit_exceeded`` variable and the metrics table carry them.
    """
    import xarray as xr

    from .errors import ElasticLimitWarning, PulseNotFound, PulseNotReachedWarning
    from .integrate.batch import simulate_batch

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ElasticLimitWarning)
        warnings.simplefilter("ignore", PulseNotReachedWarning)  # fit_error says "no pulse" per member
        ds = simulate_batch(task.models, task.duration, task.probes, dt=task.dt, n_threads=task.n_threads,
                            configs=None, device=task.device, steps_per_radian=task.steps_per_radian)
    ds = ds.assign_coords(member=("member", np.asarray(task.members, dtype=np.int64), ds["member"].attrs))
    _check_members_energy(ds, task)
    values = {k: np.full(len(task.members), np.nan) for k in METRIC_COLUMNS}
    errors = [""] * len(task.members)
    time = ds["time"].values
    for i in range(len(task.members)):
        if not ds["has_wall"].values[i]:
            errors[i] = "no wall: no wall pulse"
            continue
        try:
            m = _wall_metrics(time, ds["wall_force"].values[i])
        except PulseNotFound as exc:
            errors[i] = f"no pulse: {exc}"
            continue
        for k in METRIC_COLUMNS:
            values[k][i] = m[k]
    for k, (units, long_name) in _METRIC_UNITS.items():
        ds[k] = xr.Variable(("member",), values[k], attrs={"units": units, "long_name": long_name})
    ds["fit_error"] = xr.Variable(("member",), np.array(errors, dtype=object),
                                  attrs={"long_name": "why the wall pulse has no metrics (empty when fitted)"})
    ds["parameters"] = xr.Variable(("member",), np.array([json.dumps(p) for p in task.params], dtype=object),
                                   attrs={"long_name": "swept parameter values of the member (JSON)"})
    ds.attrs.update(sweep_hash=task.sweep_hash, chunk=task.index, title="hertzchain sweep chunk")
    # A chunk is a function of the sweep and its index: no creation time (sweep.json has the
    # sweep's), so that a recomputed chunk has the same bytes and checksum as the first one.
    ds.attrs.pop("created_utc", None)
    return ds


def _check_members_energy(ds, task: _ChunkTask) -> None:
    """The energy balance of every member (hertzchain.checks), which the batched engine does not
    check itself: a member that gains energy stops the sweep, naming the member and the cause."""
    from .checks import check_energy_balance, energy_cause, energy_tolerance

    time = ds["time"].values
    ke, pe, ed = (ds[v].values for v in ("kinetic_energy", "potential_energy", "dissipated_energy"))
    for i, model in enumerate(task.models):
        dt = task.dt[i] if isinstance(task.dt, list) else task.dt
        # the adaptive step's largest step is not stored per member: the minimum allowance then
        tol = energy_tolerance(model.system(), dt) if dt is not None else energy_tolerance(model.system(), 0.0)
        try:
            check_energy_balance(time, ke[i], pe[i], ed[i], tolerance=tol, cause=energy_cause(model, dt))
        except SimulationDiverged as exc:
            raise SimulationDiverged(f"sweep member {task.members[i]} ({task.params[i]}): {exc}") from None


def _write_chunk(ds, path: Path) -> None:
    """Write a chunk (hertzchain.fileio: never a half file under ``path``) and its SHA-256 beside it.

    The file is built in memory so that the checksum is that of the bytes written; the checksum
    file comes second, so a chunk without one (killed in between) is simply computed again.
    """
    from .fileio import write_bytes, write_text
    from .result import ENGINE

    # Force records are mostly zeros before the pulse arrives: gzip shrinks them ~5-10x, losslessly.
    encoding = {name: {"compression": "gzip", "compression_opts": 4, "shuffle": True}
                for name, var in ds.data_vars.items() if var.dtype.kind == "f" and var.size > 1000}
    data = bytes(ds.to_netcdf(None, engine=ENGINE, encoding=encoding))
    write_bytes(path, data)
    write_text(_checksum_path(path), hashlib.sha256(data).hexdigest() + "\n")


def _checksum_path(path: Path) -> Path:
    return path.with_name(path.name + ".sha256")


def _checksum_ok(path: Path) -> bool:
    """True when ``path`` has the SHA-256 recorded beside it (a damaged or unrecorded chunk: False)."""
    try:
        recorded = _checksum_path(path).read_text(encoding="ascii").strip()
        digest = hashlib.sha256()
        with open(path, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                digest.update(block)
    except (OSError, ValueError):
        return False
    return digest.hexdigest() == recorded


def _chunk_is_done(path: Path, sweep_hash: str, members: range) -> bool:
    """True when ``path`` is a complete, undamaged chunk of this sweep holding exactly ``members``."""
    import h5netcdf

    if not path.exists() or not _checksum_ok(path):
        return False
    try:
        # h5netcdf directly: ~10x faster than xarray.open_dataset, which decodes every variable.
        with h5netcdf.File(path, "r") as f:
            return (_text(f.attrs.get("sweep_hash")) == sweep_hash
                    and np.array_equal(f.variables["member"][...], np.asarray(members)))
    except (OSError, ValueError, KeyError):  # unreadable or foreign: recompute it
        return False


def _text(x: Any) -> Any:
    return x.decode() if isinstance(x, bytes) else x


def _results(client, fn: Callable, tasks: list) -> Iterator:
    """Yield ``fn(task)`` for every task, each as soon as it is available.

    ``client``: None (here, in order), a Dask ``distributed.Client`` (``submit`` +
    ``as_completed``), a ``concurrent.futures.Executor``, anything with ``submit`` and ``gather``,
    or anything with ``map`` (results taken as the iterator yields them).
    """
    if client is None:
        for t in tasks:
            yield fn(t)
        return
    try:
        import distributed
    except ImportError:  # pragma: no cover - a dependency, but keep the generic paths usable
        distributed = None
    import concurrent.futures as cf

    if distributed is not None and isinstance(client, distributed.Client):
        futures = [client.submit(fn, t, pure=False) for t in tasks]
        try:
            for fut in distributed.as_completed(futures):
                yield fut.result()
                fut.release()
        finally:  # stopped early (error, kill): do not leave work running on the cluster
            client.cancel([f for f in futures if not f.done()])
    elif isinstance(client, cf.Executor):
        futures = [client.submit(fn, t) for t in tasks]
        try:
            for fut in cf.as_completed(futures):
                yield fut.result()
        finally:
            for f in futures:
                f.cancel()
    elif hasattr(client, "submit") and hasattr(client, "gather"):
        futures = [client.submit(fn, t) for t in tasks]
        for fut in futures:
            yield client.gather(fut)
    elif hasattr(client, "map"):
        yield from client.map(fn, tasks)
    else:
        raise ConfigError("client", f"must have submit/gather or map (a Dask client, an executor), "
                          f"got {type(client).__name__}")


@dataclass
class SweepResult:
    """What :func:`run_sweep` did.

    Attributes
    ----------
    metrics:
        One row per member (pandas DataFrame, see :func:`run_sweep`).
    out_dir:
        The output folder.
    computed, skipped:
        Indices of the chunks computed by this call and of those found finished on disk.
    """

    metrics: Any
    out_dir: Path
    computed: list[int]
    skipped: list[int]

    @property
    def metrics_path(self) -> Path:
        return self.out_dir / "metrics.csv"


def _sweep_json(cfg: SweepConfig) -> dict:
    from . import __version__

    return {"hash": cfg.hash, "n_members": cfg.n_members, "n_chunks": len(cfg.chunks()),
            "chunk_size": cfg.sweep.chunk_size, "parameters": cfg.parameter_names,
            "definition": cfg.definition(), "hertzchain_version": __version__,
            "created_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")}


@contextmanager
def _folder_lock(out: Path, kind: str = "sweep", error: type[HertzchainError] | None = None) -> Iterator[None]:
    """Hold ``out/.{kind}.lock`` (``flock``, released by the system even if the process is killed);
    refuse with ``error`` (:class:`SweepLocked`) when another run of that kind holds it. Also used
    by ``hertzchain design`` (``kind="design"``)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX: no lock
        yield
        return
    path = out / f".{kind}.lock"
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        raise ConfigError(str(out), f"cannot create the {kind} lock file: {exc.strerror}") from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            holder = os.pread(fd, 64, 0).decode("ascii", "replace").strip() or "?"
            raise (error or SweepLocked)(f"{out} is in use by another {kind} (process {holder}); wait for it to "
                                         "finish (rerunning afterwards resumes it) or choose another --out") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, str(os.getpid()).encode(), 0)
        yield
    finally:
        os.close(fd)  # closing releases the lock


def _prepare_out_dir(cfg: SweepConfig, out: Path, force: bool) -> Path:
    """Create ``out``'s chunk folder; refuse (or, with ``force``, clear) the results of a different sweep.
    Called with the folder lock held."""
    from .fileio import write_text

    chunks = out / "chunks"
    meta = out / "sweep.json"
    if meta.exists():
        old = _recorded_hash(meta)
        if old != cfg.hash:
            if not force:
                raise SweepMismatch(f"{out} holds the results of a different sweep (hash {str(old)[:12]}, this one "
                                    f"{cfg.hash[:12]}); choose another output folder or use --force to replace them")
            for p in [*chunks.glob("chunk_*.nc"), *chunks.glob("chunk_*.nc.sha256"),
                      out / "metrics.csv", out / "metrics.parquet"]:
                p.unlink(missing_ok=True)
    elif chunks.exists() and any(chunks.glob("chunk_*.nc")) and not force:
        raise SweepMismatch(f"{chunks} holds chunk files but no sweep.json; use --force to replace them")
    chunks.mkdir(parents=True, exist_ok=True)
    # Temporary files left by a killed run (never a finished file); safe to remove under the lock.
    for p in [*chunks.glob(".chunk_*.tmp"), *out.glob(".metrics.*.tmp"), *out.glob(".sweep.json.*.tmp")]:
        p.unlink(missing_ok=True)
    if not meta.exists() or _recorded_hash(meta) != cfg.hash:  # a resumed sweep keeps its original record
        write_text(meta, json.dumps(_sweep_json(cfg), indent=2, default=str))
    return chunks


def _recorded_hash(meta: Path) -> str | None:
    """The hash recorded in ``sweep.json`` (None when unreadable)."""
    try:
        return json.loads(meta.read_bytes().decode("utf-8")).get("hash")
    except (OSError, ValueError, AttributeError):
        return None


def _metrics_table(cfg: SweepConfig, chunks_dir: Path):
    """Collect the per-member metrics of every chunk file into one DataFrame (ordered by member)."""
    import h5netcdf
    import pandas as pd

    cols = ["dt", "peak_wall_force", "peak_wall_time", "elastic_limit_exceeded", *METRIC_COLUMNS, "fit_error"]
    rows: dict[str, list] = {"member": [], "chunk": [], **{c: [] for c in cols}}
    for index in range(len(cfg.chunks())):
        # Only these small per-member variables are read (h5netcdf directly: see _chunk_is_done).
        with h5netcdf.File(chunks_dir / _CHUNK_NAME.format(index), "r") as f:
            members = f.variables["member"][...]
            rows["member"] += members.tolist()
            rows["chunk"] += [index] * members.size
            for c in cols:
                rows[c] += [_text(x) for x in f.variables[c][...].tolist()]
    table = {"member": rows.pop("member"), "chunk": rows.pop("chunk")}
    for name in cfg.parameter_names:
        vals = [cfg.members[m][name] for m in table["member"]]
        table[name] = [json.dumps(v) if isinstance(v, (list, dict)) else v for v in vals]
    table.update(rows)
    df = pd.DataFrame(table)
    df["elastic_limit_exceeded"] = df["elastic_limit_exceeded"].astype(bool)
    df["fit_error"] = df["fit_error"].fillna("").astype(str)
    return df


def run_sweep(sweep_cfg: SweepConfig | dict | str | Path, out_dir: str | Path, *, client=None,
              progress: Callable[[int, int], None] | None = None, force: bool = False,
              device: str = "auto") -> SweepResult:
    """Run (or resume) a sweep; every finished chunk is on disk at once.

    Parameters
    ----------
    sweep_cfg
        A :class:`SweepConfig`, a sweep mapping, or the path of a TOML sweep file.
    out_dir
        Output folder (see the module docstring for its content).
    client
        None: chunks are computed here, one after the other, each across all cores. A Dask
        ``distributed.Client``, a ``concurrent.futures.Executor``, anything with ``submit`` +
        ``gather`` or with ``map``: chunks are sent to it and written here as they come back (the
        workers need no access to ``out_dir``).
    progress
        Called as ``progress(done_members, total_members)`` after each chunk file is written
        (and once at the start with the members found finished on disk).
    force
        Replace the results of a different sweep found in ``out_dir`` instead of refusing.
    device:
        Where the chunks run: ``"cpu"``, ``"cuda"`` (the GPU engine; an error without a usable
        GPU) or ``"auto"`` (the GPU for chunks large enough to gain, when one is usable); see
        :func:`hertzchain.simulate_batch`.

    Returns
    -------
    SweepResult
        With ``metrics``: one row per member: ``member``, ``chunk``, one column per swept
        parameter (named by its path), ``dt`` [s], ``peak_wall_force`` [N] and ``peak_wall_time``
        [s] (integrator), ``elastic_limit_exceeded``, the wall-pulse metrics ``F_m`` [N], ``T``
        [s], ``tau`` [s], ``Q_F`` [N s], ``Q_T`` [N s] (NaN with ``fit_error`` saying why when the
        member has no wall or no fitted pulse). Also written to ``metrics.csv`` (and
        ``metrics.parquet`` when pyarrow is installed).

    Raises
    ------
    ConfigError
        Invalid sweep (naming the field), or a chunk that cannot fit in memory
        (``sweep.chunk_size``); nothing is written then.
    SweepMismatch
        ``out_dir`` holds another sweep.
    SweepLocked
        Another sweep is writing into ``out_dir``.
    """
    from .config import build_probes, parse_config
    from .probes import Probes

    if isinstance(sweep_cfg, (str, Path)):
        cfg = load_sweep(sweep_cfg)
    elif isinstance(sweep_cfg, dict):
        cfg = parse_sweep(sweep_cfg)
    else:
        cfg = sweep_cfg
    out = Path(out_dir)
    from .integrate.cuda import check_device

    check_device(device)
    # Everything is validated (every member's model, the memory a chunk needs) before anything is
    # written: an invalid sweep leaves no sweep.json behind to block the corrected one. Members
    # that share a layout are built as one array ensemble (microseconds per member), others as
    # one Model each.
    ensemble, member_dts = _member_ensemble(cfg)
    models = ensemble if ensemble is not None else cfg.models()
    run_cfg = parse_config(cfg.base)
    base_probes = build_probes(run_cfg)
    if cfg.sweep.store == "wall":
        # The wall force (always recorded with contacts=()), the sensors and the energies only:
        # every contact of every member would be ~N times larger and the metrics do not need it.
        probes: Any = Probes(sample_interval=base_probes.sample_interval, sensors=base_probes.sensors, contacts=())
    else:
        probes = base_probes
    duration = run_cfg.run.duration
    if duration == "auto":
        from .simulation import auto_duration

        # Members share one time axis (the batched engine): the slowest member's duration.
        duration = max(auto_duration(m) for m in models)
    _check_sweep_resources(cfg, models, duration, probes, member_dts)

    if out.exists() and not out.is_dir():
        raise ConfigError(str(out), "exists and is not a folder; --out names the sweep's output folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(str(out), f"cannot create the output folder: {exc.strerror}") from None
    with _folder_lock(out):
        chunks_dir = _prepare_out_dir(cfg, out, force)
        return _run_chunks(cfg, out, chunks_dir, models, duration, probes, member_dts, client, progress, device)


def _check_sweep_resources(cfg: SweepConfig, models, duration: float, probes, member_dts: list) -> None:
    """Refuse a chunk that cannot fit in memory (naming sweep.chunk_size); warn on a long sweep.

    ``models``: a list of Models, or an Ensemble (members of one length: member 0 stands for all).
    """
    from dataclasses import replace as _replace

    from .checks import check_resources, estimate_resources

    if isinstance(models, list):
        largest = max(range(len(models)), key=lambda i: models[i].chain.n_beads)
        model = models[largest]
    else:
        largest, model = 0, models.model(0)
    members = min(cfg.sweep.chunk_size, cfg.n_members)
    est = estimate_resources(model.system(), duration, probes, dt=member_dts[largest], members=members)
    check_resources(_replace(est, seconds=0.0), memory_field="sweep.chunk_size")
    total = _replace(est, members=cfg.n_members, memory_bytes=0, seconds=est.seconds / members * cfg.n_members)
    check_resources(total)


def _run_chunks(cfg: SweepConfig, out: Path, chunks_dir: Path, models, duration: float, probes,
                member_dts: list, client, progress, device: str = "auto") -> SweepResult:
    """Compute the chunks not yet on disk and write the metrics table (folder lock held).

    ``models``: a list of Models, or an Ensemble whose rows are the members; ``device`` as in
    :func:`run_sweep`.
    """
    from .config import parse_config
    from .fileio import atomic_path

    steps_per_radian = parse_config(cfg.base).run.steps_per_radian  # shared by every member (_SHARED)

    total = cfg.n_members
    done_members = 0
    skipped, todo = [], []
    for index, members in enumerate(cfg.chunks()):
        if _chunk_is_done(chunks_dir / _CHUNK_NAME.format(index), cfg.hash, members):
            skipped.append(index)
            done_members += len(members)
        else:
            chunk_models = [models[m] for m in members] if isinstance(models, list) else models.subset(members)
            todo.append(_ChunkTask(index=index, members=list(members), models=chunk_models,
                                   params=[cfg.members[m] for m in members], duration=duration,
                                   probes=probes, dt=[member_dts[m] for m in members],
                                   n_threads=cfg.sweep.n_threads, sweep_hash=cfg.hash, device=device,
                                   steps_per_radian=steps_per_radian))
    if progress is not None:
        progress(done_members, total)

    computed = []
    for ds in _results(client, compute_chunk, todo):
        index = int(ds.attrs["chunk"])
        _write_chunk(ds, chunks_dir / _CHUNK_NAME.format(index))
        computed.append(index)
        done_members += ds.sizes["member"]
        if progress is not None:
            progress(done_members, total)

    df = _metrics_table(cfg, chunks_dir)
    with atomic_path(out / "metrics.csv") as tmp:
        df.to_csv(tmp, index=False)
    if importlib.util.find_spec("pyarrow") is not None:
        with atomic_path(out / "metrics.parquet") as tmp:
            df.to_parquet(tmp, index=False)
    return SweepResult(metrics=df, out_dir=out, computed=sorted(computed), skipped=skipped)
