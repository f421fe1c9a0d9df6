"""Run configuration (TOML): schema, validation and translation into model objects.

Validation uses pydantic; every problem is reported as a :class:`~hertzchain.errors.ConfigError`
naming the field (``chain.diameters_mm[3]``), what was wrong and what is allowed. Keys that take
non-SI units say so in their name (``diameter_mm``); all others are SI.

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
    duration = 2.5e-3       # s
    sample_interval = 1e-7  # s
    [probes]
    sensors = [2]
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from collections.abc import Iterable
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from .errors import ConfigError

__all__ = ["RunConfig", "load_config", "parse_config", "build_model", "build_probes", "run_config"]


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class MaterialConfig(_Section):
    """A user material under ``[materials.NAME]`` (SI units)."""

    density: float = Field(gt=0, description="kg/m^3")
    young: float = Field(gt=0, description="Young's modulus, Pa")
    poisson: float = Field(gt=-1, lt=0.5)
    yield_stress: float | None = Field(default=None, gt=0, description="Pa")


class UniformBlock(_Section):
    n: int = Field(ge=1)
    diameter_mm: float = Field(gt=0)


class TaperBlock(_Section):
    n: int = Field(ge=1)
    q: float = Field(ge=0, lt=1, description="tapering factor as a fraction (0.056 = 5.6 %)")


class Substitution(_Section):
    bead: int = Field(ge=1)
    diameter_mm: float | None = Field(default=None, gt=0)
    material: str | None = None


class ChainConfig(_Section):
    """``[chain]``: give exactly one of ``diameters_mm``, ``preset`` or ``uniform`` (+ optional ``taper``)."""

    material: str = "AISI52100"
    materials: list[str] | None = None
    diameters_mm: list[float] | None = None
    preset: Literal["chain1", "chain2"] | None = None
    uniform: UniformBlock | None = None
    taper: TaperBlock | None = None
    truncate: int | None = Field(default=None, ge=1)
    substitutions: list[Substitution] = []
    offsets_mm: list[float] | None = None
    offsets_fraction: list[float] | None = None
    precompression: float = Field(default=0.0, ge=0, description="static force, N")

    @field_validator("diameters_mm")
    @classmethod
    def _finite_positive(cls, v: list[float] | None) -> list[float] | None:
        if v is not None:
            if not v:
                raise ValueError("must list at least one diameter")
            for i, d in enumerate(v):
                if not (math.isfinite(d) and d > 0):
                    raise ValueError(f"diameter of bead {i + 1} (item [{i}]) must be a positive finite number "
                                     f"in mm, got {d!r}")
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
    diameter_mm: float = Field(default=8.0, gt=0)
    velocity: float = Field(default=0.5, gt=0, description="m/s towards the chain")
    material: str | None = None


class WallConfig(_Section):
    type: Literal["flat", "none"] = "flat"
    material: str | None = None


class ContactConfig(_Section):
    """``[contact]``: law and either its parameter (A [s] or gamma [N s/m]) or a target ``eps``."""

    law: Literal["elastic", "viscoelastic", "dashpot"] = "elastic"
    eps: float | None = Field(default=None, gt=0, le=1, description="per-bead factor of the paper")
    A: float | None = Field(default=None, ge=0, description="Kuwabara-Kono time constant, s")
    gamma: float | None = Field(default=None, ge=0, description="dashpot coefficient, N s/m")

    @model_validator(mode="after")
    def _parameter(self) -> "ContactConfig":
        if self.law == "elastic" and (self.A is not None or self.gamma is not None or
                                      (self.eps is not None and self.eps != 1.0)):
            raise ValueError("the elastic law takes no A, gamma or eps < 1; set law = 'viscoelastic' or 'dashpot'")
        own = {"viscoelastic": "A", "dashpot": "gamma"}.get(self.law)
        if own is not None:
            other = "gamma" if own == "A" else "A"
            if getattr(self, other) is not None:
                raise ValueError(f"law '{self.law}' takes {own} (or eps), not {other}")
            if (getattr(self, own) is None) == (self.eps is None):
                raise ValueError(f"law '{self.law}' needs exactly one of {own} or eps")
        return self


class RunSection(_Section):
    duration: float = Field(default=2.5e-3, gt=0, description="s")
    sample_interval: float = Field(default=1e-7, gt=0, description="s")
    dt: float | None = Field(default=None, gt=0, description="s; automatic when absent")
    integrator: Literal["verlet", "dop853", "rk45"] = "verlet"
    rtol: float = Field(default=1e-10, gt=0, lt=1)

    @field_validator("duration", "sample_interval", "dt")
    @classmethod
    def _finite(cls, v: float | None) -> float | None:
        if v is not None and not math.isfinite(v):
            raise ValueError("must be finite")
        return v


class ProbesConfig(_Section):
    sensors: list[int] = []
    contacts: Literal["all"] | list[int] = "all"
    velocities: bool = False


class InstrumentChannel(_Section):
    """One measured channel: a sensor preset plus any :class:`hertzchain.instrument.Instrument` field."""

    preset: Literal["pcb_208a11", "pcb_200b02"] | None = None
    sensitivity_mV_per_N: float | None = None
    noise_rms_mV: float | None = None
    sample_rate: float | None = None
    record_length: int | None = None
    trigger_level_N: float | None = None
    pretrigger_fraction: float | None = None
    bits: int | None = None
    full_scale_V: float | None = None
    offset_V: float | None = None
    n_average: int | None = None
    trigger_jitter: bool | None = None
    seed: int | None = None


class InstrumentConfig(_Section):
    """``[instrument]``: the laboratory's measurement chain, off unless a channel is given."""

    trigger: Literal["self", "wall"] = "self"
    wall: InstrumentChannel | None = None
    sensors: InstrumentChannel | None = None


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
        err = exc.errors()[0]
        loc = tuple(err["loc"])
        name = _field_name(loc)
        if err["type"] == "extra_forbidden":
            allowed = _allowed_keys(loc)
            raise ConfigError(name, f"unknown key; allowed keys here: {allowed}") from None
        if err["type"] == "missing":
            raise ConfigError(name, "is required") from None
        msg = err["msg"].removeprefix("Value error, ")
        value = err.get("input")
        if not isinstance(value, (dict, list)):
            msg += f" (got {value!r})"
        raise ConfigError(name or "config", msg) from None


def read_toml(path: str | Path, what: str = "config file") -> dict:
    """Read a TOML file; a missing file or bad TOML is a ConfigError naming the path."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ConfigError(str(path), f"cannot read the {what}: {exc.strerror}") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(str(path), f"is not valid TOML: {exc}") from None


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
    import re

    out = copy.deepcopy(data)
    for item in assignments:
        if "=" not in item:
            raise ConfigError("--set", f"{item!r} is not DOTTED.PATH=VALUE (e.g. striker.velocity=0.3)")
        path, raw = (part.strip() for part in item.split("=", 1))
        try:
            value = tomllib.loads(f"v = {raw}")["v"]
        except tomllib.TOMLDecodeError:
            value = raw  # a bare word such as elastic: a string
        keys = ([prefix] if prefix else []) + path.split(".")
        node: Any = out
        for depth, key in enumerate(keys):
            m = re.fullmatch(r"([A-Za-z_][A-Za-z0-9_]*)(?:\[(\d+)\])?", key)
            if not m:
                raise ConfigError(f"--set {path}", f"{key!r} is not a field name (letters, digits, _; list items as key[i])")
            name, index = m.group(1), m.group(2)
            last = depth == len(keys) - 1
            if not isinstance(node, dict):
                raise ConfigError(f"--set {path}", f"{'.'.join(keys[:depth])} is not a section")
            if index is None:
                if last:
                    node[name] = value
                else:
                    node = node.setdefault(name, {})
            else:
                seq = node.get(name)
                if not isinstance(seq, list) or int(index) >= len(seq):
                    raise ConfigError(f"--set {path}", f"{name} has no item {index} in this config")
                if last:
                    seq[int(index)] = value
                else:
                    node = seq[int(index)]
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


def build_chain(cfg: RunConfig):
    """The :class:`~hertzchain.chain.Chain` described by ``[chain]``."""
    import numpy as np

    from .chain import Chain, paper_chain

    c = cfg.chain
    _register_materials(cfg)
    _check_material_names(cfg)
    mats: Any = c.material
    if c.preset is not None:
        chain = paper_chain(c.preset, c.material)
    elif c.uniform is not None:
        chain = Chain.uniform(c.uniform.n, c.uniform.diameter_mm * 1e-3, c.material)
    else:
        chain = Chain.from_diameters(np.array(c.diameters_mm) * 1e-3, c.material)
    if c.taper is not None:
        chain = chain.append_taper(c.taper.n, c.taper.q)
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
    offsets = None
    if c.offsets_mm is not None:
        offsets = np.array(c.offsets_mm) * 1e-3
        name = "chain.offsets_mm"
    elif c.offsets_fraction is not None:
        offsets = np.array(c.offsets_fraction) * chain.diameters[: len(c.offsets_fraction)]
        name = "chain.offsets_fraction"
    if offsets is not None:
        if offsets.size != chain.n_beads:
            raise ConfigError(name, f"needs one value per bead ({chain.n_beads}), got {offsets.size}")
        chain = chain.with_offsets(offsets)
    return chain


def build_model(cfg: RunConfig):
    """The :class:`~hertzchain.model.Model` of a config (calibrating the law when ``eps`` is given).

    Parameters
    ----------
    cfg : RunConfig
        A validated config (:func:`load_config`, :func:`parse_config`); lengths in mm where the
        key says so (``diameter_mm``), everything else SI.

    Returns
    -------
    Model
        Chain, striker, wall and contact law in SI units (diameters [m], speeds [m/s]).
    """
    from .contact import Dashpot, Elastic, Viscoelastic
    from .model import Model, Striker, Wall

    chain = build_chain(cfg)
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
    else:
        law = Dashpot(k.gamma)
    return Model(chain, striker, wall, law, precompression=cfg.chain.precompression)


def build_probes(cfg: RunConfig):
    from .probes import Probes

    p = cfg.probes
    return Probes(sample_interval=cfg.run.sample_interval, sensors=tuple(p.sensors),
                  contacts=None if p.contacts == "all" else tuple(p.contacts), velocities=p.velocities)


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
    return out


def apply_instruments(ds, cfg: RunConfig):
    """Add the measured signals of ``[instrument]`` to a result (ideal signals are kept)."""
    instruments = build_instruments(cfg)
    if not instruments:
        return ds
    from .instrument import measure_dataset

    return measure_dataset(ds, wall=instruments.get("wall"), sensors=instruments.get("sensors"),
                           trigger=cfg.instrument.trigger)


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
    from .simulation import simulate

    if isinstance(cfg, (str, Path)):
        cfg = load_config(cfg)
    elif isinstance(cfg, dict):
        cfg = parse_config(cfg)
    model = build_model(cfg)
    build_instruments(cfg)  # fail on bad instrument settings before a long run
    ds = simulate(model, cfg.run.duration, build_probes(cfg), integrator=cfg.run.integrator, dt=cfg.run.dt,
                  rtol=cfg.run.rtol, progress=progress, config=cfg.model_dump(mode="json"))
    return apply_instruments(ds, cfg)
