"""From a validated config to objects and runs: the chain, the model (calibrating the contact law
when ``eps`` is given), the probes, the instruments of ``[instrument]``, the track of ``[track]``,
and :func:`run_config`, which simulates a config end to end.
"""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from ..errors import ConfigError
from .loading import load_config
from .schema import BOUNDS, ChainConfig, RunConfig, RunSection, _raise_config_error, parse_config


def _register_materials(cfg: RunConfig) -> None:
    from ..materials import Material, register_material

    for name, m in cfg.materials.items():
        register_material(Material(name, m.density, m.young, m.poisson, m.yield_stress, "config"))


def _check_material_names(cfg: RunConfig) -> None:
    """Name the field of an unknown material (rather than a bare 'material')."""
    from ..materials import get_material

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
    """The :class:`~hertzchain.chain.Chain` described by ``[chain]`` (with the bead kinds of
    ``[elements]``)."""
    _register_materials(cfg)
    _check_material_names(cfg)
    return _chain(cfg.chain, _element_table(cfg))


def _element_table(cfg: RunConfig) -> dict:
    """``{name: Element}`` of ``[elements]``, plus the plain ``"sphere"``."""
    from ..elements import SPHERE, Element

    table = {"sphere": SPHERE}
    for name, e in cfg.elements.items():
        if name == "sphere":
            raise ConfigError("elements.sphere", "'sphere' is the plain bead's name; give your element another one")
        r = e.resonator
        table[name] = Element(name, e.shape, e.orientation, None if e.length_mm is None else e.length_mm * 1e-3,
                              e.axis_deg, e.mass, 0.0 if r is None else r.mass_fraction,
                              0.0 if r is None else r.frequency)
    return table


def _element(table: dict, name: str, field_name: str):
    try:
        return table[name]
    except KeyError:
        raise ConfigError(field_name, f"unknown element {name!r}; known: {', '.join(sorted(table))} "
                          "(define others under [elements.NAME])") from None


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
    if "materials" in data or "elements" in data or not isinstance(data.get("chain"), dict):
        cfg = parse_config(data)
        return cfg.chain, build_chain(cfg)
    try:
        section = ChainConfig.model_validate(data["chain"])
    except ValidationError as exc:
        _raise_config_error(exc, ("chain",))
    return section, _chain(section)


def _chain(c: ChainConfig, elements: dict | None = None):
    """The Chain of a validated ``[chain]`` (its materials registered; ``elements``: the bead kinds
    by name, :func:`_element_table`)."""
    import numpy as np

    from ..chain import TABLE_I_MM, Chain

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
        if d.size == 0:
            raise ConfigError("chain.taper", "a taper continues the beads before it; chain.uniform.n = 0 has none")
        if d.size + c.taper.n > n_max:
            raise ConfigError("chain.taper.n", f"makes a chain of {d.size + c.taper.n} beads; "
                              f"at most {n_max} are allowed")
        smallest_mm = d[-1] * 1e3 * (1.0 - c.taper.q) ** c.taper.n
        if smallest_mm < BOUNDS["diameter_mm"][0]:
            raise ConfigError("chain.taper", f"q = {c.taper.q:g} over n = {c.taper.n} beads makes the last bead "
                              f"{smallest_mm:.3g} mm; beads must be at least {BOUNDS['diameter_mm'][0]:g} mm")
        d = np.concatenate([d, d[-1] * (1.0 - c.taper.q) ** np.arange(1, c.taper.n + 1)])  # Chain.append_taper
    chain = Chain.from_diameters(d, c.material)
    if c.truncate is not None:
        if c.truncate > chain.n_beads:
            raise ConfigError("chain.truncate", f"must be at most the number of beads ({chain.n_beads}), got {c.truncate}")
        chain = chain.truncated(c.truncate)
    if c.materials is not None:
        if len(c.materials) != chain.n_beads:
            raise ConfigError("chain.materials", f"needs one material per bead ({chain.n_beads}), got {len(c.materials)}")
        mats = c.materials
        chain = Chain(chain.diameters, tuple(mats), chain.offsets)
    if elements is None:  # a [chain] validated alone: only the plain sphere is known
        from ..elements import SPHERE

        elements = {"sphere": SPHERE}
    if c.elements is not None:
        if len(c.elements) != chain.n_beads:
            raise ConfigError("chain.elements", f"needs one element per bead ({chain.n_beads}), got {len(c.elements)}")
        els = tuple(_element(elements, name, f"chain.elements[{i}]") for i, name in enumerate(c.elements))
        chain = Chain(chain.diameters, chain.materials, chain.offsets, els)
    for i, sub in enumerate(c.substitutions):
        if sub.bead > chain.n_beads:
            raise ConfigError(f"chain.substitutions[{i}].bead", f"bead {sub.bead} does not exist (1..{chain.n_beads})")
        el = None if sub.element is None else _element(elements, sub.element, f"chain.substitutions[{i}].element")
        chain = chain.substitute(sub.bead, None if sub.diameter_mm is None else sub.diameter_mm * 1e-3, sub.material,
                                 el)
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


def build_model(cfg: RunConfig, chain=None, preflight=None):
    """The :class:`~hertzchain.model.Model` of a config (calibrating the law when ``eps`` is given).

    Parameters
    ----------
    cfg : RunConfig
        A validated config (:func:`load_config`, :func:`parse_config`); lengths in mm where the
        key says so (``diameter_mm``), everything else SI.
    chain : Chain, optional
        The chain of ``cfg.chain`` when it was built already (:func:`chain_parts`: a design
        search builds it to check the geometry before it runs the candidate); else built here.
    preflight : callable, optional
        ``preflight(model)``, called before a calibration with the model whose law is not
        calibrated yet (its parameter 0, the same law otherwise): the caller's checks of the run
        (:func:`preflight_run`) refuse a bad config before the calibration, whose runs compile the
        law's engine in a fresh installation (~8 CPU-s).

    Returns
    -------
    Model
        Chain, striker, wall and contact law in SI units (diameters [m], speeds [m/s]).
    """
    from ..laws import get_law
    from ..model import Model, Striker, Wall

    if chain is None:
        chain = build_chain(cfg)
    else:
        _register_materials(cfg)
        _check_material_names(cfg)
    s = cfg.striker
    striker = Striker(s.diameter_mm * 1e-3, s.velocity, s.material, mass=s.mass, shape=s.shape,
                      radius_of_curvature=None if s.radius_of_curvature_mm is None else s.radius_of_curvature_mm * 1e-3)
    w = cfg.wall
    # the wall's default material is the chain's (its first bead's); with no beads, chain.material
    wall = Wall(w.type, w.material or (None if chain.n_beads else cfg.chain.material), w.mass, w.stiffness, w.damping,
                w.shape, None if w.radius_of_curvature_mm is None else w.radius_of_curvature_mm * 1e-3)
    k = cfg.contact
    # the beads a calibration (eps) and a size-scaled law refer to: the chain's first; with zero beads
    # (chain.uniform.n = 0, the striker onto the wall) the uniform block's diameter, as in its chain
    ref = chain
    if not chain.n_beads:
        from ..chain import Chain

        assert cfg.chain.uniform is not None  # zero beads: chain.uniform.n = 0 (an empty list is refused)
        ref = Chain.uniform(1, cfg.chain.uniform.diameter_mm * 1e-3, cfg.chain.material)
    spec = get_law(k.law)
    loads = () if cfg.load is None else tuple(zip(cfg.load.beads, cfg.load.forces))
    drive = None
    if cfg.drive is not None:
        from ..crystal.drive import Drive

        drive = Drive(**{k: v for k, v in cfg.drive.model_dump().items() if v is not None})

    def model(law) -> Model:
        with _as_written("chain.offsets", _offsets_key(cfg)):
            return Model(chain, striker, wall, law, precompression=cfg.chain.precompression,
                         gravity=chain_gravity(cfg.chain), loads=loads, drive=drive)

    assert spec.make is not None  # every registered law has its maker (laws.spec.attach_maker)
    if k.eps is not None and spec.calibrated:
        # the model's own checks, and the caller's, before the calibration's runs (and its imports)
        provisional = model(spec.make({p: 0.0 if p == spec.calibrated else None for p in spec.param_names}, ref))
        if preflight is not None:
            preflight(provisional)
        from ..dissipation import calibrate_law

        law: Any = calibrate_law(k.law, k.eps, chain=ref, striker=striker)
    else:  # the law's own constructor from its declared parameters (hertzchain.laws)
        law = spec.make(k.law_parameters(), ref)
    return model(law)


def preflight_run(cfg: RunConfig, model, probes) -> None:
    """The checks a run of ``cfg`` makes before it allocates or compiles anything, on ``model``
    (its law's parameter may be provisional: :func:`build_model`'s ``preflight``): the run's
    duration and probes against the chain, the engine the options ask for (or the lateral path's
    refusals with ``[track]``), the static overlaps and the memory of the records. A law's damping
    only raises the frequencies the step follows, so a refusal on the provisional model holds for
    the calibrated one; the time a run is projected to take is said once, for the calibrated model
    (LongRunWarning ignored here)."""
    import warnings

    from ..checks import check_before_run
    from ..errors import LongRunWarning

    duration = cfg.run.duration
    if duration == "auto":
        from ..runs.simulation import auto_duration

        duration = auto_duration(model)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LongRunWarning)
        if cfg.track is not None:
            from ..runs.track import check_lateral

            check_track_options(cfg)
            check_lateral(model, duration, probes, integrator="verlet" if cfg.run.integrator == "auto"
                          else cfg.run.integrator, dt=cfg.run.dt)
            return
        from ..engine_choice import choose_engine

        if probes.sample_interval > duration:  # (as simulate says it)
            raise ConfigError("run.sample_interval",
                              f"({probes.sample_interval:g} s) is longer than run.duration ({duration:g} s)")
        probes.validate(model.chain.n_beads, model.wall.present)
        system = model.system()
        choice = choose_engine(system, cfg.run.integrator, cfg.run.threads,
                               steps_per_radian=cfg.run.verlet_steps_per_radian, dt=cfg.run.dt)
        check_before_run(model, system, duration, probes, dt=cfg.run.dt, integrator=choice.integrator)


def check_track_options(cfg: RunConfig) -> None:
    """Refuse the run options the lateral (2D) path of ``[track]`` does not take (ConfigError)."""
    if cfg.drive is not None:
        raise ConfigError("drive", "a driven chain runs on the 1D engine; [track] (the lateral path) takes no drive")
    if cfg.run.threads not in (1, "auto"):
        raise ConfigError("run.threads", "the lateral (2D) path of [track] runs on one thread: leave it out")
    if cfg.run.steps_per_radian != RunSection.model_fields["steps_per_radian"].default:
        raise ConfigError("run.steps_per_radian", "is a setting of the 1D engine's adaptive step; the lateral "
                          "(2D) path of [track] has its own: leave it out")


def chain_gravity(c: ChainConfig) -> float:
    """Gravity along the chain [m/s^2] of ``[chain]``: ``gravity``, or 9.80665 sin(``tilt_deg``)
    for a track inclined by that angle with the wall end down (0 when neither is given)."""
    import math

    from ..bodies import STANDARD_GRAVITY

    if c.tilt_deg is not None:
        return STANDARD_GRAVITY * math.sin(math.radians(c.tilt_deg))
    return 0.0 if c.gravity is None else float(c.gravity)


def build_probes(cfg: RunConfig):
    from ..probes import Probes

    p = cfg.probes
    return Probes(sample_interval=cfg.run.sample_interval, sensors=tuple(p.sensors),
                  contacts=None if p.contacts == "all" else p.contacts if p.contacts == "auto" else tuple(p.contacts), velocities=p.velocities,
                  positions=p.positions)


#: Most oscilloscope samples (record_length x n_average) a measured channel may draw.
MAX_SCOPE_SAMPLES = 1e8


def build_instruments(cfg: RunConfig) -> dict:
    """Instrument objects of ``[instrument]`` (``{}`` when the measurement chain is off)."""
    from ..instrument import Instrument

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
    from ..instrument import measure_dataset

    return measure_dataset(ds, wall=instruments.get("wall"), sensors=instruments.get("sensors"),
                           trigger=cfg.instrument.trigger)


def build_track(cfg: RunConfig):
    """The :class:`hertzchain.Track` of ``[track]``, or None when the config has none (1D engine)."""
    if cfg.track is None:
        return None
    from ..runs.track import Track

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
        from ..runs.simulation import simulate

        return simulate(model, cfg.run.duration, probes, integrator=cfg.run.integrator, dt=cfg.run.dt,
                        rtol=cfg.run.rtol, progress=progress, config=config,
                        steps_per_radian=cfg.run.verlet_steps_per_radian, threads=cfg.run.threads)
    check_track_options(cfg)
    from ..runs.simulation import SCIPY_RTOL, auto_duration
    from ..runs.track import simulate_lateral

    auto = cfg.run.duration == "auto"
    duration = auto_duration(model) if isinstance(cfg.run.duration, str) else cfg.run.duration
    track = build_track(cfg)
    with _as_written("track.groove_radius", "track.groove_radius_mm"):
        ds = simulate_lateral(model, track, duration, probes,
                              integrator="verlet" if cfg.run.integrator == "auto" else cfg.run.integrator,
                              dt=cfg.run.dt,
                              rtol=SCIPY_RTOL if cfg.run.rtol is None else cfg.run.rtol, config=config)
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
