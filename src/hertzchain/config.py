"""Run configuration (TOML): schema, validation and translation into model objects.

Validation uses pydantic in strict mode; every problem is reported as a
:class:`~hertzchain.errors.ConfigError` naming the field as the user wrote it
(``chain.diameters_mm[3]``, ``chain.uniform.diameter_mm``), what was wrong and what is allowed.
Types are strict (``true`` or ``"0.5"`` is not a number, ``1.0`` is not a bead count) and every
number has physical bounds (:data:`BOUNDS`), so values such as 1e300 or 1e-300 are refused before
they reach the engine. Keys that take non-SI units say so in their name (``diameter_mm``); all
others are SI.

A minimal config (the contract of the core-engine issue)::

    [chain]
    material = "AISI52100"
    diameters_mm = [26, 26, 26, 24, 23, 22]
    [striker]
    diameter_mm = 8.0
    velocity = 0.5          # m/s
    [wall]
    type = "flat"           # or "none"
    [run]
    duration = 2.5e-3       # s, or "auto" (the default)
    sample_interval = 1e-7  # s
    [probes]
    sensors = [2]
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Iterable
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any, Literal, NoReturn

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from .errors import ConfigError

__all__ = ["RunConfig", "load_config", "parse_config", "build_model", "build_probes", "run_config"]


class _Section(BaseModel):
    # strict: TOML booleans and strings are not numbers, floats are not counts (issue: ``velocity =
    # true`` ran at 1 m/s); integers are still accepted where a float is expected.
    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, allow_inf_nan=False)

    def __deepcopy__(self, memo: dict | None = None) -> "_Section":
        # pydantic deep-copies a model default (WallConfig(), ProbesConfig(), ...) at every
        # validation, which was a third of parse_config's time (a design search parses
        # thousands); the sections are frozen, so a shallow copy is as good.
        return self.__copy__()


#: Physical bounds of the config's numbers (inclusive unless said otherwise), generous enough for
#: any granular-chain experiment and tight enough that nothing reaches the engine as 0, inf or an
#: overflowing product (1e300 m/s, 1e-300 mm, 1e30 beads).
BOUNDS = {
    "diameter_mm": (1e-3, 1e4),       # 1 um .. 10 m
    "beads": (1, 10_000_000),         # bead counts and numbers (memory is checked separately)
    "velocity": (0.0, 1e3),           # m/s, > 0; far beyond yield already
    "density": (1.0, 1e5),            # kg/m^3
    "young": (1e3, 1e13),             # Pa
    "yield_stress": (1e3, 1e12),      # Pa
    "precompression": (0.0, 1e9),     # N (and the Hertz-range check on the static overlap)
    "offset_mm": (-1e4, 1e4),
    "A": (0.0, 1.0),                  # s (the paper's eps = 0.985 needs A ~ 4.5e-6 s)
    "gamma": (0.0, 1e9),              # N s/m
    "duration": (0.0, 100.0),         # s, > 0 (memory and run time are checked separately)
    "sample_interval": (1e-12, 1.0),  # s
    "dt": (1e-15, 1.0),               # s
    "rtol": (1e-14, 0.1),
    # adaptive Verlet accuracy, omega dt <= 1 / steps_per_radian: below ~10 the peak force is off
    # by more than ~3e-4 (error ~ (1 / steps_per_radian)^2) and Verlet nears its stability limit
    "steps_per_radian": (10.0, 1e5),
}


def _bounded(kind: str, *, open_low: bool = False, **kw: Any) -> Any:
    lo, hi = BOUNDS[kind]
    return Field(gt=lo, le=hi, **kw) if open_low else Field(ge=lo, le=hi, **kw)


_Diameter = Annotated[float, _bounded("diameter_mm")]
_BeadNumber = Annotated[int, _bounded("beads")]
_Offset = Annotated[float, _bounded("offset_mm")]


class MaterialConfig(_Section):
    """A user material under ``[materials.NAME]`` (SI units)."""

    density: float = _bounded("density", description="kg/m^3")
    young: float = _bounded("young", description="Young's modulus, Pa")
    poisson: float = Field(gt=-1, lt=0.5)
    yield_stress: float | None = _bounded("yield_stress", default=None, description="Pa")


class UniformBlock(_Section):
    n: _BeadNumber
    diameter_mm: _Diameter


class TaperBlock(_Section):
    n: _BeadNumber
    q: float = Field(ge=0, lt=1, description="tapering factor as a fraction (0.056 = 5.6 %)")


class Substitution(_Section):
    bead: _BeadNumber
    diameter_mm: _Diameter | None = None
    material: str | None = None


class ChainConfig(_Section):
    """``[chain]``: give exactly one of ``diameters_mm``, ``preset`` or ``uniform`` (+ optional ``taper``)."""

    material: str = "AISI52100"
    materials: list[str] | None = None
    diameters_mm: list[float] | None = None
    preset: Literal["chain1", "chain2"] | None = None
    uniform: UniformBlock | None = None
    taper: TaperBlock | None = None
    truncate: _BeadNumber | None = None
    substitutions: list[Substitution] = Field(default_factory=list)  # not deep-copied at every validation
    offsets_mm: list[_Offset] | None = None
    offsets_fraction: list[Annotated[float, Field(ge=-0.5, le=0.5)]] | None = None
    precompression: float = _bounded("precompression", default=0.0, description="static force, N")

    @field_validator("diameters_mm")
    @classmethod
    def _finite_positive(cls, v: list[float] | None) -> list[float] | None:
        if v is not None:
            if not v:
                raise ValueError("must list at least one diameter")
            if len(v) > BOUNDS["beads"][1]:
                raise ValueError(f"lists {len(v)} beads; at most {BOUNDS['beads'][1]} are allowed")
            lo, hi = BOUNDS["diameter_mm"]
            for i, d in enumerate(v):
                if not (math.isfinite(d) and lo <= d <= hi):
                    raise ValueError(f"diameter of bead {i + 1} (item [{i}]) must be a positive finite number "
                                     f"in mm, from {lo:g} to {hi:g}, got {d!r}")
        return v

    @model_validator(mode="after")
    def _one_source(self) -> "ChainConfig":
        given = [k for k in ("diameters_mm", "preset", "uniform") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError("give exactly one of diameters_mm, preset or uniform "
                             f"(got {', '.join(given) if given else 'none'})")
        if self.offsets_mm is not None and self.offsets_fraction is not None:
            raise ValueError("give offsets_mm or offsets_fraction, not both")
        return self


class StrikerConfig(_Section):
    diameter_mm: _Diameter = 8.0
    velocity: float = _bounded("velocity", open_low=True, default=0.5, description="m/s towards the chain")
    material: str | None = None


class WallConfig(_Section):
    type: Literal["flat", "none"] = "flat"
    material: str | None = None


class ContactConfig(_Section):
    """``[contact]``: law and either its parameter (A [s] or gamma [N s/m]) or a target ``eps``."""

    law: Literal["elastic", "viscoelastic", "viscoelastic_scaled", "dashpot"] = "elastic"
    eps: float | None = Field(default=None, gt=0, le=1, description="per-bead factor of the paper")
    A: float | None = _bounded("A", default=None, description="Kuwabara-Kono time constant, s "
                                  "(viscoelastic_scaled: between two beads like the chain's first)")
    gamma: float | None = _bounded("gamma", default=None, description="dashpot coefficient, N s/m")

    @model_validator(mode="after")
    def _parameter(self) -> "ContactConfig":
        if self.law == "elastic" and (self.A is not None or self.gamma is not None or
                                      (self.eps is not None and self.eps != 1.0)):
            raise ValueError("the elastic law takes no A, gamma or eps < 1; set law = 'viscoelastic' or 'dashpot'")
        own = {"viscoelastic": "A", "viscoelastic_scaled": "A", "dashpot": "gamma"}.get(self.law)
        if own is not None:
            other = "gamma" if own == "A" else "A"
            if getattr(self, other) is not None:
                raise ValueError(f"law '{self.law}' takes {own} (or eps), not {other}")
            if (getattr(self, own) is None) == (self.eps is None):
                raise ValueError(f"law '{self.law}' needs exactly one of {own} or eps")
        return self


class RunSection(_Section):
    duration: float | Literal["auto"] = Field(
        default="auto", description="s, or 'auto': until the front has crossed the chain and its tail passed "
                                    "(hertzchain.simulation.auto_duration)")
    sample_interval: float = _bounded("sample_interval", default=1e-7, description="s")
    dt: float | None = _bounded("dt", default=None, description="s; automatic when absent")
    integrator: Literal["verlet", "dop853", "rk45"] = "verlet"
    rtol: float = _bounded("rtol", default=1e-10)
    steps_per_radian: float = _bounded(
        "steps_per_radian", default=400.0,
        description="adaptive Verlet step: omega dt <= 1 / steps_per_radian; peak error ~ (1/steps_per_radian)^2")

    @field_validator("duration", mode="before")
    @classmethod
    def _auto_or_time(cls, v: Any) -> Any:
        # Checked here in full, so that an error names run.duration (not a branch of the union).
        if v == "auto":
            return v
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ValueError("must be a time in s (a number) or 'auto'")
        lo, hi = BOUNDS["duration"]
        if not (math.isfinite(v) and lo < v <= hi):
            raise ValueError(f"must be greater than {lo:g} and at most {hi:g} (a time in s), or 'auto'")
        return float(v)


class ProbesConfig(_Section):
    sensors: list[_BeadNumber] = []
    contacts: Literal["all"] | list[Annotated[int, Field(ge=0, le=BOUNDS["beads"][1])]] = "all"
    velocities: bool = False
    positions: bool = False


class InstrumentChannel(_Section):
    """One measured channel: a sensor preset plus any :class:`hertzchain.instrument.Instrument` field."""

    preset: Literal["pcb_208a11", "pcb_200b02"] | None = None
    sensitivity_mV_per_N: float | None = Field(default=None, gt=0, le=1e6)
    noise_rms_mV: float | None = Field(default=None, ge=0, le=1e6)
    sample_rate: float | None = Field(default=None, ge=1.0, le=1e12, description="Hz")
    record_length: int | None = Field(default=None, ge=2, le=100_000_000)
    trigger_level_N: float | None = Field(default=None, ge=-1e9, le=1e9)
    pretrigger_fraction: float | None = Field(default=None, ge=0, lt=1)
    bits: int | None = Field(default=None, ge=1, le=48)
    full_scale_V: float | None = Field(default=None, gt=0, le=1e4)
    offset_V: float | None = Field(default=None, ge=-1e4, le=1e4)
    n_average: int | None = Field(default=None, ge=1, le=1_000_000)
    trigger_jitter: bool | None = None
    seed: int | None = Field(default=None, ge=0, le=2**63 - 1)


class InstrumentConfig(_Section):
    """``[instrument]``: the laboratory's measurement chain, off unless a channel is given."""

    trigger: Literal["self", "wall"] = "self"
    wall: InstrumentChannel | None = None
    sensors: InstrumentChannel | None = None


class TrackConfig(_Section):
    """``[track]``: lateral freedom (:func:`hertzchain.simulate_lateral`): the beads may leave the
    chain's axis, held by a groove, a spring and friction (:class:`hertzchain.Track`). Absent: the
    beads stay on their lines (the 1D engine)."""

    groove_radius_mm: float | None = Field(default=None, gt=0, le=BOUNDS["diameter_mm"][1],
                                           description="mm, radius of the groove's cross-section; absent: flat bed")
    spring: float = Field(default=0.0, ge=0, le=1e12, description="N/m, transverse spring per body")
    friction: float = Field(default=0.0, ge=0, le=10.0, description="Coulomb coefficient with the track")
    slip_velocity: float = Field(default=1e-5, gt=0, le=10.0, description="m/s, regularisation of the friction")
    gravity: float = Field(default=9.81, ge=0, le=1e3, description="m/s^2")


class RunConfig(_Section):
    """The whole run file."""

    materials: dict[str, MaterialConfig] = {}
    chain: ChainConfig
    striker: StrikerConfig = StrikerConfig()
    wall: WallConfig = WallConfig()
    contact: ContactConfig = ContactConfig()
    run: RunSection = RunSection()
    probes: ProbesConfig = ProbesConfig()
    instrument: InstrumentConfig = InstrumentConfig()
    track: TrackConfig | None = None


def _field_name(loc: tuple[Any, ...]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out


def _allowed_keys(loc: tuple[Any, ...]) -> str:
    model: Any = RunConfig
    for part in loc[:-1]:
        if isinstance(part, int) or model is None:
            continue
        fld = getattr(model, "model_fields", {}).get(part)
        if fld is None:
            return ""
        ann = fld.annotation
        args = getattr(ann, "__args__", ())
        candidates = [ann, *args] + [a for x in args for a in getattr(x, "__args__", ())]
        model = next((c for c in candidates if isinstance(c, type) and issubclass(c, BaseModel)), None)
    if model is None:
        return ""
    return ", ".join(model.model_fields)


def parse_config(data: dict) -> RunConfig:
    """Validate a config mapping; raise :class:`ConfigError` naming the first bad field.

    Parameters
    ----------
    data : dict
        The mapping as read from a TOML run file (keys in the units their names say, else SI).

    Returns
    -------
    RunConfig
        The validated, immutable config.
    """
    try:
        return RunConfig.model_validate(data)
    except ValidationError as exc:
        _raise_config_error(exc)


def _raise_config_error(exc: ValidationError, prefix: tuple[str, ...] = ()) -> NoReturn:
    """Turn pydantic's first error into a ConfigError naming the field as written (under ``prefix``:
    the section that was validated on its own)."""
    err = exc.errors()[0]
    loc = prefix + tuple(err["loc"])
    name = _field_name(loc)
    if err["type"] == "extra_forbidden":
        allowed = _allowed_keys(loc)
        raise ConfigError(name, f"unknown key; allowed keys here: {allowed}") from None
    if err["type"] == "missing":
        raise ConfigError(name, "is required") from None
    msg = err["msg"].removeprefix("Value error, ").replace("Input should be", "must be")
    value = err.get("input")
    if not isinstance(value, (dict, list)):
        msg += f" (got {value!r})"
    if err["type"] in ("float_type", "int_type", "int_from_float", "bool_type", "string_type"):
        msg += "; write it as a TOML " + {"float_type": "number such as 0.5 (not true or a quoted string)",
                                           "int_type": "whole number such as 12 (not 12.0 or a quoted string)",
                                           "int_from_float": "whole number such as 12 (not 12.0)",
                                           "bool_type": "boolean, true or false",
                                           "string_type": "quoted string"}[err["type"]]
    raise ConfigError(name or "config", msg) from None


def read_toml(path: str | Path, what: str = "config file") -> dict:
    """Read a TOML file; a missing file or bad TOML is a ConfigError naming the path."""
    path = Path(path)
    try:
        text = path.read_bytes().decode("utf-8")
    except OSError as exc:
        raise ConfigError(str(path), f"cannot read the {what}: {exc.strerror}") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(str(path), f"is not UTF-8 text (byte {exc.start} cannot be decoded); "
                          f"a {what} is a TOML text file saved as UTF-8") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(str(path), f"is not valid TOML: {exc}") from None


_TOKEN = re.compile(r"([^.\[\]]+)|\[(\d+)\]")


def parse_path(path: str) -> list[str | int]:
    """``"chain.diameters_mm[3]"`` -> ``["chain", "diameters_mm", 3]``; ValueError when malformed."""
    tokens: list[str | int] = []
    pos = 0
    for m in _TOKEN.finditer(path):
        gap = path[pos:m.start()]
        if gap not in ("", "."):
            raise ValueError
        tokens.append(m.group(1) if m.group(1) is not None else int(m.group(2)))
        pos = m.end()
    if pos != len(path) or not tokens or not isinstance(tokens[0], str) or path.endswith("."):
        raise ValueError
    return tokens


def set_path(cfg: dict, tokens: list[str | int], value: Any, name: str) -> None:
    """Set ``value`` at ``tokens`` (from a dotted path) in ``cfg``; missing tables are created.

    Shared by sweeps and the design search; a path that does not fit the base config is a
    ConfigError naming ``name`` (the field as the user wrote it).
    """
    node: Any = cfg
    for tok, nxt in zip(tokens[:-1], tokens[1:]):
        if isinstance(tok, int):
            if not isinstance(node, list) or tok >= len(node):
                raise ConfigError(name, f"index [{tok}] is outside the base list")
            node = node[tok]
        else:
            if not isinstance(node, dict):
                raise ConfigError(name, f"'{tok}' is not inside a table of the base config")
            if tok not in node:
                if isinstance(nxt, int):
                    raise ConfigError(name, f"the base config has no list '{tok}' to index")
                node[tok] = {}
            node = node[tok]
    last = tokens[-1]
    if isinstance(last, int):
        if not isinstance(node, list) or last >= len(node):
            raise ConfigError(name, f"index [{last}] is outside the base list")
    elif not isinstance(node, dict):
        raise ConfigError(name, f"'{last}' is not inside a table of the base config")
    node[last] = value


def apply_overrides(data: dict, assignments: Iterable[str], prefix: str = "") -> dict:
    """Apply ``--set DOTTED.PATH=VALUE`` assignments to a config mapping read from TOML.

    Parameters
    ----------
    data : dict
        The mapping as read from the TOML file (left unchanged; a changed copy is returned).
    assignments : iterable of str
        ``"striker.velocity=0.3"``, ``"chain.taper={n = 30, q = 0.05}"``, ``"probes.sensors=[8, 12]"``.
        VALUE is read as a TOML value (so ``0.3`` is a number, ``"elastic"`` or a bare word a
        string); list items are addressed as ``key[i]``.
    prefix : str
        Section the paths are relative to (``"base"`` for sweep and design files).

    Returns
    -------
    dict
        The new mapping, to be validated by the same schema as the file itself.
    """
    import copy

    out = copy.deepcopy(data)
    for item in assignments:
        if "=" not in item:
            raise ConfigError("--set", f"{item!r} is not DOTTED.PATH=VALUE (e.g. striker.velocity=0.3)")
        path, raw = (part.strip() for part in item.split("=", 1))
        try:
            value = tomllib.loads(f"v = {raw}")["v"]
        except tomllib.TOMLDecodeError:
            value = raw  # a bare word such as elastic: a string
        try:
            tokens = parse_path(path)
        except ValueError:
            raise ConfigError(f"--set {path}", "is not a dotted field path (names joined by '.', list items "
                              "as key[i])") from None
        set_path(out, ([prefix] if prefix else []) + tokens, value, f"--set {path}")
    return out


def load_config(path: str | Path, overrides: Iterable[str] = ()) -> RunConfig:
    """Read and validate a TOML run file, after applying ``--set`` overrides (:func:`apply_overrides`).

    Parameters
    ----------
    path : str or pathlib.Path
        The TOML run file (sections and keys: the user guide's "Configuration files" page).
    overrides : iterable of str
        ``DOTTED.PATH=VALUE`` assignments applied before validation (``"striker.velocity=0.3"``,
        value in the key's own unit).

    Returns
    -------
    RunConfig
        The validated config.

    Raises
    ------
    ConfigError
        Naming the first bad field (``chain.diameters_mm[3]``), what was wrong and what is allowed.
    """
    return parse_config(apply_overrides(read_toml(path), overrides))


def _register_materials(cfg: RunConfig) -> None:
    from .materials import Material, register_material

    for name, m in cfg.materials.items():
        register_material(Material(name, m.density, m.young, m.poisson, m.yield_stress, "config"))


def _check_material_names(cfg: RunConfig) -> None:
    """Name the field of an unknown material (rather than a bare 'material')."""
    from .materials import get_material

    names = [("chain.material", cfg.chain.material), ("striker.material", cfg.striker.material),
             ("wall.material", cfg.wall.material)]
    names += [(f"chain.materials[{i}]", m) for i, m in enumerate(cfg.chain.materials or [])]
    names += [(f"chain.substitutions[{i}].material", s.material) for i, s in enumerate(cfg.chain.substitutions)]
    for field_name, name in names:
        if name is None:
            continue
        try:
            get_material(name)
        except ConfigError as exc:
            raise ConfigError(field_name, exc.message) from None


@contextmanager
def _as_written(internal: str, written: str):
    """Report a model-level ConfigError on ``internal`` (``chain.offsets``) under the key the user
    wrote (``chain.offsets_mm``), so that every message names a field of the input."""
    try:
        yield
    except ConfigError as exc:
        if exc.field == internal or exc.field.startswith(internal + "["):
            raise ConfigError(written + exc.field[len(internal):], exc.message) from None
        raise


def build_chain(cfg: RunConfig):
    """The :class:`~hertzchain.chain.Chain` described by ``[chain]``."""
    _register_materials(cfg)
    _check_material_names(cfg)
    return _chain(cfg.chain)


def chain_of(data: dict):
    """The :class:`~hertzchain.chain.Chain` of a config mapping, validating ``[chain]`` alone.

    What :func:`build_chain` of :func:`parse_config` gives, with the same schema and the same
    field-named errors, at a third of the cost: a design search checks the geometry of thousands
    of candidates whose other sections are validated once, when they are run. A mapping with its
    own ``[materials]`` goes the whole way.

    Parameters
    ----------
    data : dict
        A run config mapping (as read from TOML).

    Returns
    -------
    Chain
        The beads, diameters in m.
    """
    return chain_parts(data)[1]


def chain_parts(data: dict) -> tuple[ChainConfig, Any]:
    """``(validated [chain] section, Chain)`` of a config mapping: :func:`chain_of` with the section,
    so that a model can later be built from it without validating ``[chain]`` again
    (:func:`build_model` with ``chain=``)."""
    if "materials" in data or not isinstance(data.get("chain"), dict):
        cfg = parse_config(data)
        return cfg.chain, build_chain(cfg)
    try:
        section = ChainConfig.model_validate(data["chain"])
    except ValidationError as exc:
        _raise_config_error(exc, ("chain",))
    return section, _chain(section)


def _chain(c: ChainConfig):
    """The Chain of a validated ``[chain]`` (its materials registered)."""
    import numpy as np

    from .chain import TABLE_I_MM, Chain

    mats: Any = c.material
    n_max = BOUNDS["beads"][1]
    # The diameters first, then one Chain (each Chain validates itself; a design search builds
    # thousands): the same numbers as Chain.uniform(...).append_taper(...).
    if c.preset is not None:
        d = np.array(TABLE_I_MM[c.preset]) * 1e-3
    elif c.uniform is not None:
        d = np.full(c.uniform.n, c.uniform.diameter_mm * 1e-3)
    else:
        d = np.array(c.diameters_mm) * 1e-3
    if c.taper is not None:
        if d.size + c.taper.n > n_max:
            raise ConfigError("chain.taper.n", f"makes a chain of {d.size + c.taper.n} beads; "
                              f"at most {n_max} are allowed")
        smallest_mm = d[-1] * 1e3 * (1.0 - c.taper.q) ** c.taper.n
        if smallest_mm < BOUNDS["diameter_mm"][0]:
            raise ConfigError("chain.taper", f"q = {c.taper.q:g} over n = {c.taper.n} beads makes the last bead "
                              f"{smallest_mm:.3g} mm; beads must be at least {BOUNDS['diameter_mm'][0]:g} mm")
        d = np.concatenate([d, d[-1] * (1.0 - c.taper.q) ** np.arange(1, c.taper.n + 1)])  # Chain.append_taper
    chain = Chain(d, c.material)
    if c.truncate is not None:
        if c.truncate > chain.n_beads:
            raise ConfigError("chain.truncate", f"must be at most the number of beads ({chain.n_beads}), got {c.truncate}")
        chain = chain.truncated(c.truncate)
    if c.materials is not None:
        if len(c.materials) != chain.n_beads:
            raise ConfigError("chain.materials", f"needs one material per bead ({chain.n_beads}), got {len(c.materials)}")
        mats = c.materials
        chain = Chain(chain.diameters, tuple(mats), chain.offsets)
    for i, sub in enumerate(c.substitutions):
        if sub.bead > chain.n_beads:
            raise ConfigError(f"chain.substitutions[{i}].bead", f"bead {sub.bead} does not exist (1..{chain.n_beads})")
        chain = chain.substitute(sub.bead, None if sub.diameter_mm is None else sub.diameter_mm * 1e-3, sub.material)
    name, values = ("chain.offsets_mm", c.offsets_mm) if c.offsets_mm is not None else \
        ("chain.offsets_fraction", c.offsets_fraction)
    if values is not None:
        if len(values) != chain.n_beads:
            raise ConfigError(name, f"needs one value per bead ({chain.n_beads}), got {len(values)}")
        scale = 1e-3 if name == "chain.offsets_mm" else chain.diameters
        with _as_written("chain.offsets", name):
            chain = chain.with_offsets(np.asarray(values, dtype=float) * scale)
    return chain


def _offsets_key(cfg: RunConfig) -> str:
    return "chain.offsets_fraction" if cfg.chain.offsets_fraction is not None else "chain.offsets_mm"


def build_model(cfg: RunConfig, chain=None):
    """The :class:`~hertzchain.model.Model` of a config (calibrating the law when ``eps`` is given).

    Parameters
    ----------
    cfg : RunConfig
        A validated config (:func:`load_config`, :func:`parse_config`); lengths in mm where the
        key says so (``diameter_mm``), everything else SI.
    chain : Chain, optional
        The chain of ``cfg.chain`` when it was built already (:func:`chain_parts`: a design
        search builds it to check the geometry before it runs the candidate); else built here.

    Returns
    -------
    Model
        Chain, striker, wall and contact law in SI units (diameters [m], speeds [m/s]).
    """
    from .contact import Dashpot, Elastic, ScaledViscoelastic, Viscoelastic
    from .model import Model, Striker, Wall

    if chain is None:
        chain = build_chain(cfg)
    else:
        _register_materials(cfg)
        _check_material_names(cfg)
    s = cfg.striker
    striker = Striker(s.diameter_mm * 1e-3, s.velocity, s.material or chain.materials[0])
    wall = Wall(cfg.wall.type, cfg.wall.material)
    k = cfg.contact
    if k.law == "elastic":
        law: Any = Elastic()
    elif k.eps is not None:
        from .dissipation import calibrate_law

        law = calibrate_law(k.law, k.eps, chain=chain, striker=striker)
    elif k.law == "viscoelastic":
        law = Viscoelastic(k.A)
    elif k.law == "viscoelastic_scaled":
        law = ScaledViscoelastic(k.A, float(chain.diameters[0]), chain.materials[0])
    else:
        law = Dashpot(k.gamma)
    with _as_written("chain.offsets", _offsets_key(cfg)):
        return Model(chain, striker, wall, law, precompression=cfg.chain.precompression)


def build_probes(cfg: RunConfig):
    from .probes import Probes

    p = cfg.probes
    return Probes(sample_interval=cfg.run.sample_interval, sensors=tuple(p.sensors),
                  contacts=None if p.contacts == "all" else tuple(p.contacts), velocities=p.velocities,
                  positions=p.positions)


#: Most oscilloscope samples (record_length x n_average) a measured channel may draw.
MAX_SCOPE_SAMPLES = 1e8


def build_instruments(cfg: RunConfig) -> dict:
    """Instrument objects of ``[instrument]`` (``{}`` when the measurement chain is off)."""
    from .instrument import Instrument

    out = {}
    for channel in ("wall", "sensors"):
        ch = getattr(cfg.instrument, channel)
        if ch is None:
            continue
        fields = {k: v for k, v in ch.model_dump().items() if v is not None and k != "preset"}
        default = "pcb_208a11" if channel == "wall" else "pcb_200b02"
        try:
            out[channel] = getattr(Instrument, ch.preset or default)(**fields)
        except ConfigError as exc:
            raise ConfigError(exc.field.replace("instrument.", f"instrument.{channel}.", 1), exc.message) from None
        # Resources before any work (as hertzchain.checks does for the run): every averaged
        # acquisition draws record_length samples of noise and digitises them.
        inst = out[channel]
        drawn = inst.record_length * inst.n_average
        if drawn > MAX_SCOPE_SAMPLES:
            raise ConfigError(f"instrument.{channel}.n_average", f"{inst.n_average} acquisitions of record_length = "
                              f"{inst.record_length} points are {drawn:.3g} samples; at most {MAX_SCOPE_SAMPLES:.0e} "
                              "(the oscilloscope of the paper records 1000 points)")
    return out


def apply_instruments(ds, cfg: RunConfig):
    """Add the measured signals of ``[instrument]`` to a result (ideal signals are kept)."""
    instruments = build_instruments(cfg)
    if not instruments:
        return ds
    from .instrument import measure_dataset

    return measure_dataset(ds, wall=instruments.get("wall"), sensors=instruments.get("sensors"),
                           trigger=cfg.instrument.trigger)


def build_track(cfg: RunConfig):
    """The :class:`hertzchain.Track` of ``[track]``, or None when the config has none (1D engine)."""
    if cfg.track is None:
        return None
    from .track import Track

    t = cfg.track
    with _as_written("track.groove_radius", "track.groove_radius_mm"):
        return Track(groove_radius=None if t.groove_radius_mm is None else t.groove_radius_mm * 1e-3,
                     spring=t.spring, friction=t.friction, slip_velocity=t.slip_velocity, gravity=t.gravity)


def simulate_config(cfg: RunConfig, model=None, probes=None, progress=None):
    """Simulate a validated config: :func:`hertzchain.simulate`, or with ``[track]``
    :func:`hertzchain.simulate_lateral` (no instrument model applied here).

    Parameters
    ----------
    cfg : RunConfig
        The validated config.
    model, probes : optional
        Already built from ``cfg`` (built here when None).
    progress : callable, optional
        ``progress(done, total)`` during a 1D Verlet run.

    Returns
    -------
    xarray.Dataset
        The result, SI units, with the config in its ``config`` attribute.
    """
    model = build_model(cfg) if model is None else model
    probes = build_probes(cfg) if probes is None else probes
    config = cfg.model_dump(mode="json")
    if cfg.track is None:
        from .simulation import simulate

        return simulate(model, cfg.run.duration, probes, integrator=cfg.run.integrator, dt=cfg.run.dt,
                        rtol=cfg.run.rtol, progress=progress, config=config,
                        steps_per_radian=cfg.run.steps_per_radian)
    if cfg.run.steps_per_radian != RunSection.model_fields["steps_per_radian"].default:
        raise ConfigError("run.steps_per_radian", "is a setting of the 1D engine's adaptive step; the lateral "
                          "(2D) path of [track] has its own: leave it out")
    from .simulation import auto_duration
    from .track import simulate_lateral

    auto = cfg.run.duration == "auto"
    track = build_track(cfg)
    with _as_written("track.groove_radius", "track.groove_radius_mm"):
        ds = simulate_lateral(model, track, auto_duration(model) if auto else cfg.run.duration, probes,
                              integrator=cfg.run.integrator, dt=cfg.run.dt, rtol=cfg.run.rtol, config=config)
    if auto:
        ds.attrs["duration_mode"] = "auto"
    return ds


def run_config(cfg: RunConfig | dict | str | Path, progress=None):
    """Build and simulate a config; returns the result :class:`xarray.Dataset`.

    Parameters
    ----------
    cfg : RunConfig, dict, str or pathlib.Path
        A validated config, a mapping as read from TOML, or the path of a TOML file.
    progress : callable, optional
        Called as ``progress(done, total)`` during a Verlet run.

    Returns
    -------
    xarray.Dataset
        The result (SI units), with the measured signals of ``[instrument]`` when configured.
    """
    if isinstance(cfg, (str, Path)):
        cfg = load_config(cfg)
    elif isinstance(cfg, dict):
        cfg = parse_config(cfg)
    model = build_model(cfg)
    build_instruments(cfg)  # fail on bad instrument settings before a long run
    return apply_instruments(simulate_config(cfg, model, progress=progress), cfg)
