"""The schema of a run config: one pydantic model per TOML section, with the physical bounds of
every number (:data:`BOUNDS`); :func:`parse_config` validates a mapping against it and reports the
first problem as a :class:`~hertzchain.errors.ConfigError` naming the field as the user wrote it.

The documentation's table of config keys is generated from :class:`RunConfig` (docs/conf.py).
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal, NoReturn

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

# BOUNDS live beside the Python API (hertzchain.bounds), which applies them too; re-exported here
from ..bounds import BOUNDS
from ..errors import ConfigError
from ..laws import get_law, law_names


class _Section(BaseModel):
    # strict: TOML booleans and strings are not numbers, floats are not counts (issue: ``velocity =
    # true`` ran at 1 m/s); integers are still accepted where a float is expected.
    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, allow_inf_nan=False)

    def __deepcopy__(self, memo: dict | None = None) -> "_Section":
        # pydantic deep-copies a model default (WallConfig(), ProbesConfig(), ...) at every
        # validation, which was a third of parse_config's time (a design search parses
        # thousands); the sections are frozen, so a shallow copy is as good.
        return self.__copy__()


def _bounded(kind: str, *, open_low: bool = False, **kw: Any) -> Any:
    lo, hi = BOUNDS[kind]
    return Field(gt=lo, le=hi, **kw) if open_low else Field(ge=lo, le=hi, **kw)


def _law_field(law: str, name: str) -> Any:
    """A config field for parameter ``name`` of the registered law ``law``: its unit and bounds."""
    p = get_law(law).param(name)
    lo: dict[str, Any] = {"gt": p.low} if p.open_low else {"ge": p.low}
    hi: dict[str, Any] = {"lt": p.high} if p.open_high else {"le": p.high}
    return Field(default=None, description=f"{law}: {p.description}, {p.unit}", **lo, **hi)


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
    # 0: no chain, the striker hits the wall or the protected body (the reference of a protector)
    n: int = Field(ge=0, le=BOUNDS["beads"][1], description="number of beads (0: the striker hits the wall directly)")
    diameter_mm: _Diameter


class TaperBlock(_Section):
    n: _BeadNumber
    q: float = Field(ge=0, lt=1, description="tapering factor as a fraction (0.056 = 5.6 %)")


class Substitution(_Section):
    bead: _BeadNumber
    diameter_mm: _Diameter | None = None
    material: str | None = None
    element: str | None = None


class ResonatorConfig(_Section):
    """A mass-in-mass bead's internal mass: a fraction of the bead's mass on a linear spring."""

    mass_fraction: float = Field(gt=0, lt=1, description="internal mass / whole bead mass")
    frequency: float = _bounded("frequency", open_low=True,
                                description="Hz, sqrt(k_in / m_in) / (2 pi) with the shell held")


class ElementConfig(_Section):
    """A bead kind under ``[elements.NAME]``, used by name in ``chain.elements`` (a bead's diameter
    and material stay the chain's)."""

    shape: Literal["sphere", "cylinder"] = "sphere"
    orientation: Literal["crossed", "aligned"] = Field(
        default="crossed", description="cylinder axis across the chain (side contacts) or along it (flat ends)")
    length_mm: _Diameter | None = Field(default=None, description="cylinder length; absent: its diameter")
    axis_deg: float = Field(default=0.0, ge=-360, le=360, description="crossed cylinder's axis about the chain axis")
    mass: float | None = _bounded("mass", default=None, description="kg, a given bead mass")
    resonator: ResonatorConfig | None = None


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
    gravity: float | None = _bounded("gravity", default=None,
                                     description="m/s^2 along the chain towards the wall (absent: 0)")
    tilt_deg: float | None = Field(default=None, ge=0, le=90,
                                   description="track inclined by this angle, wall end down: gravity = "
                                               "9.80665 sin(tilt) (instead of gravity)")
    elements: list[str] | None = Field(default=None, description="one element name per bead ('sphere' or "
                                                                  "a name of [elements])")

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
        if self.gravity is not None and self.tilt_deg is not None:
            raise ValueError("give gravity or tilt_deg, not both")
        return self


class StrikerConfig(_Section):
    diameter_mm: _Diameter = 8.0
    velocity: float = _bounded("velocity", default=0.5, description="m/s towards the chain")
    # one rule in config and API (hc.Striker): the paper's steel ball unless given, whatever the
    # chain is made of (a config's striker used to take the chain's first material)
    material: str = Field(default="AISI52100", description="the striker's material (default: AISI 52100, as "
                                                            "hc.Striker's, whatever the chain's)")
    mass: float | None = _bounded("mass", default=None,
                                  description="kg; absent: the sphere's rho pi phi^3 / 6")
    shape: Literal["sphere", "flat"] = Field(default="sphere", description="its face: 'flat' meets bead 1 in a "
                                                                           "sphere-flat contact")
    radius_of_curvature_mm: _Diameter | None = Field(default=None, description="a curved face's radius; "
                                                                               "absent: diameter / 2")


class WallConfig(_Section):
    """``[wall]``: a flat, a free end, or a protected body (``type = "body"``: mass, mount)."""

    type: Literal["flat", "none", "body"] = "flat"
    material: str | None = None
    mass: float | None = _bounded("mass", default=None, description="kg, the protected body's")
    stiffness: float = _bounded("stiffness", default=0.0, description="N/m, its mount to the ground (0: free)")
    damping: float = _bounded("damping", default=0.0, description="N s/m, the mount's dashpot")
    shape: Literal["flat", "sphere"] = Field(default="flat", description="the body's face")
    radius_of_curvature_mm: _Diameter | None = Field(default=None, description="a spherical body face's radius")


class ContactConfig(_Section):
    """``[contact]``: law and either its parameter (A [s] or gamma [N s/m]) or a target ``eps``;
    ``elastoplastic`` (Thornton) takes an optional viscous A (default 0)."""

    law: str = Field(default="elastic", description="a registered law (hertzchain.laws): " + ", ".join(law_names()))
    # ge=MIN_EPS (hertzchain.dissipation): no law reaches a lower eps on its weak-damping branch, and
    # the calibration would otherwise search ever stronger damping (eps = 1e-300 ran for hours).
    eps: float | None = Field(default=None, ge=0.5, le=1, description="per-bead factor of the paper")
    A: float | None = _bounded("A", default=None, description="Kuwabara-Kono time constant, s "
                                  "(viscoelastic_scaled: between two beads like the chain's first)")
    limiting_pressure_factor: float | None = _bounded(
        "limiting_pressure_factor", default=None,
        description="elastoplastic: Thornton's limiting pressure p_y over the yield stress (default 1.5: yield "
                    "starts at the paper's F_Y)")
    gamma: float | None = _bounded("gamma", default=None, description="dashpot coefficient, N s/m "
                                   "(dashpot_scaled: between two beads like the chain's first)")
    # the generated laws' parameters: bounds and units declared once in hertzchain.laws
    exponent: float | None = _law_field("power", "exponent")
    stiffness: float | None = _law_field("power", "stiffness")
    restitution: float | None = _law_field("hunt_crossley", "restitution")
    parameters: dict[str, float] | None = Field(default=None, description="a user law's parameters by name "
                                                "(its own declaration bounds them)")

    @field_validator("law")
    @classmethod
    def _registered(cls, law: str) -> str:
        if law not in law_names():
            raise ValueError(f"unknown law {law!r}; registered laws: {', '.join(law_names())} (a law of your own: "
                             "hertzchain.register_law, or --laws FILE on the command line)")
        return law

    def law_parameters(self) -> dict:
        """The law's parameters by name (None where not given), as its declaration lists them."""
        spec = get_law(self.law)
        given = dict(self.parameters or {})
        return {p: given.get(p, getattr(self, p, None)) for p in spec.param_names}

    @model_validator(mode="after")
    def _parameter(self) -> "ContactConfig":
        spec = get_law(self.law)
        if spec.generated:  # a law declared in hertzchain.laws: its own parameters only, bounded there
            named = ("A", "gamma", "eps", "limiting_pressure_factor", "exponent", "stiffness", "restitution")
            stray = [f for f in named if getattr(self, f) is not None and f not in spec.param_names]
            stray += [f"parameters.{f}" for f in (self.parameters or {}) if f not in spec.param_names]
            if stray:
                raise ValueError(f"law {self.law!r} takes {', '.join(spec.param_names) or 'no parameters'}, "
                                 f"not {', '.join(stray)}")
            for name, value in self.law_parameters().items():
                try:
                    spec.param(name).check(value)
                except ConfigError as exc:
                    raise ValueError(str(exc)) from None
            assert spec.make is not None  # every registered law has its maker (laws.spec.attach_maker)
            try:  # the law's own checks across parameters (e.g. the power law's n = 1 needs a stiffness)
                spec.make(self.law_parameters())
            except ConfigError as exc:
                raise ValueError(str(exc)) from None
            return self
        if self.exponent is not None or self.stiffness is not None or self.restitution is not None or self.parameters:
            raise ValueError(f"law {self.law!r} takes no exponent, stiffness, restitution or parameters "
                             "(those of law = 'power', 'hunt_crossley' or a registered law)")
        if not spec.dissipative and (self.A is not None or self.gamma is not None or
                                      (self.eps is not None and self.eps != 1.0)):
            raise ValueError("the elastic law takes no A, gamma or eps < 1; set law = 'viscoelastic' or 'dashpot'")
        if not spec.plastic and self.limiting_pressure_factor is not None:
            raise ValueError("limiting_pressure_factor belongs to law = 'elastoplastic'")
        if spec.plastic:
            if self.gamma is not None or self.eps is not None:
                raise ValueError("law 'elastoplastic' takes an optional A (s, the viscous term on top of Thornton's "
                                 "plastic contact), not gamma or eps")
            return self
        own = spec.calibrated
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
                                    "(hertzchain.runs.simulation.auto_duration)")
    sample_interval: float = _bounded("sample_interval", default=1e-7, description="s")
    dt: float | None = _bounded("dt", default=None, description="s; automatic when absent")
    integrator: Literal["auto", "verlet", "rkn4", "dop853", "rk45"] = Field(
        default="auto", description="'auto': 'rkn4' where it integrates the model, else 'verlet' "
                                    "(hertzchain.engine_choice); or one of them by name")
    rtol: float | None = _bounded(
        "rtol", default=None,
        description="relative tolerance of 'dop853'/'rk45' (default 1e-10) or of the step control of 'rkn4' "
                    "(default 1e-6); unused by 'verlet'")
    steps_per_radian: float = _bounded(
        "steps_per_radian", default=400.0,
        description="adaptive Verlet step: omega dt <= 1 / steps_per_radian; peak error ~ (1/steps_per_radian)^2; "
                    "setting it makes integrator 'auto' pick 'verlet'")

    @property
    def verlet_steps_per_radian(self) -> float | None:
        """``steps_per_radian`` where the config sets it, else None (integrator 'auto' may pick 'rkn4')."""
        return self.steps_per_radian if "steps_per_radian" in self.model_fields_set else None
    threads: int | Literal["auto"] = Field(
        default="auto", description="'auto' (several only for a long chain on the Verlet, or on rkn4 with the "
                                    "elastic law, with cores free; hertzchain.engine_choice), or threads sharing one "
                                    "long chain (Verlet: every contact law, offsets too, no protected body or "
                                    "mass-in-mass beads; rkn4: aligned elastic chains; pays from ~1e4 beads)")

    @field_validator("threads", mode="before")
    @classmethod
    def _auto_or_count(cls, v: Any) -> Any:
        # Checked here in full, so that an error names run.threads (not a branch of the union).
        if v == "auto":
            return v
        lo, hi = BOUNDS["threads"]
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            raise ValueError(f"must be 'auto' or a whole number of threads from {lo} to {hi}")
        return v

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
    contacts: Literal["auto", "all"] | list[Annotated[int, Field(ge=0, le=BOUNDS["beads"][1])]] = Field(
        default="auto", description="'auto': every contact up to 256, else the wall's, the sensors' and 33 spread "
                                    "along the chain; 'all'; or contact numbers")
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


class LoadConfig(_Section):
    """``[load]``: static forces on chosen beads (the run starts from the static equilibrium)."""

    beads: list[_BeadNumber] = Field(description="bead numbers 1..N")
    forces: list[Annotated[float, Field(ge=-BOUNDS["precompression"][1], le=BOUNDS["precompression"][1])]] = Field(
        description="N along the chain, > 0 towards the wall; one per bead")

    @model_validator(mode="after")
    def _pairs(self) -> "LoadConfig":
        if len(self.beads) != len(self.forces):
            raise ValueError(f"beads ({len(self.beads)}) and forces ({len(self.forces)}) must have the same length")
        return self


class DriveConfig(_Section):
    """``[drive]``: a harmonic or chirped force on bead 1, or the position of a massless driver
    touching bead 1 (:class:`hertzchain.Drive`)."""

    type: Literal["harmonic", "chirp", "history"] = "harmonic"
    quantity: Literal["force", "displacement"] = "force"
    amplitude: float | None = Field(default=None, gt=0, le=1e9, description="N (force) or m (displacement); "
                                                                            "harmonic and chirp")
    frequency: float | None = _bounded("frequency", open_low=True, default=None,
                                       description="Hz (a chirp's start); harmonic and chirp")
    ramp_cycles: float = Field(default=5.0, ge=0, le=1e6, description="cycles of the sin^2 ramp-up")
    frequency_end: float | None = _bounded("frequency", open_low=True, default=None, description="Hz, a chirp's end")
    sweep_time: float | None = Field(default=None, gt=0, le=BOUNDS["duration"][1], description="s, a chirp's sweep")
    end: Literal["first", "last"] = Field(default="first", description="where the drive enters: bead 1, or "
                                                                    "bead N (bead 1 then rests on the wall)")
    striker: bool = Field(default=False, description="keep the striker (force drive only)")
    file: str | None = Field(default=None, description="a history's CSV (time_s,value), relative to the "
                                                       "working folder")

    @model_validator(mode="after")
    def _needs(self) -> "DriveConfig":
        if self.type != "history":
            missing = [k for k in ("amplitude", "frequency") if getattr(self, k) is None]
            if missing:
                raise ValueError(f"a {self.type} drive needs {' and '.join(missing)}")
        elif self.amplitude is not None or self.frequency is not None:
            raise ValueError("a history drive takes its values from its file: leave amplitude and frequency out")
        return self


class RunConfig(_Section):
    """The whole run file."""

    materials: dict[str, MaterialConfig] = {}
    elements: dict[str, ElementConfig] = {}
    chain: ChainConfig
    striker: StrikerConfig = StrikerConfig()
    wall: WallConfig = WallConfig()
    contact: ContactConfig = ContactConfig()
    run: RunSection = RunSection()
    probes: ProbesConfig = ProbesConfig()
    instrument: InstrumentConfig = InstrumentConfig()
    track: TrackConfig | None = None
    load: LoadConfig | None = None
    drive: DriveConfig | None = None


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
    bound = {"greater_than_equal": ("ge", "at least"), "greater_than": ("gt", "greater than"),
             "less_than_equal": ("le", "at most"), "less_than": ("lt", "less than")}.get(err["type"])
    if bound is not None and isinstance(err.get("ctx", {}).get(bound[0]), (int, float)):
        msg = f"must be {bound[1]} {err['ctx'][bound[0]]:g}"  # 1e-15, not 0.000000000000001
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
