"""``hertzchain.sensitivity``: exact derivatives of a run's results with respect to config fields.

One call = one taped primal run (:func:`hertzchain.integrate.derivatives.differentiate.record`), the
objective's value and partials (:mod:`hertzchain.gradients.objectives`), then either one reverse
sweep (adjoint: the whole gradient for about two more runs, whatever the number of variables) or
one tangent run (about half a run more per variable: cheaper for one or two), and the chain rule
through the set-up map (:mod:`hertzchain.gradients.setup`, exact by complex step).

:func:`trace_sensitivity` gives the derivative of a whole sampled signal (the wall force, or an
embedded sensor's) by a few config fields, by the tangent model: the Jacobian of a fit.
"""

from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal, Sequence

import numpy as np

from ..errors import ConfigError

__all__ = ["Sensitivity", "TraceSensitivity", "sensitivity", "trace_sensitivity", "variable_unit", "memory_estimate"]

#: With at most this many variables ``mode="auto"`` uses the tangent model (but for the
#: elastic-plastic law, whose tangent costs more than its adjoint: ``differentiate.TANGENT_LAWS``),
#: else the adjoint. On chain 1 (benchmarks/gradient.py) the whole call costs ~2.8-3.3 runs
#: with the adjoint whatever the number of variables, ~1.6 plus ~0.7 per variable with the tangent:
#: the tangent wins for one variable only, and serves whole signals (:func:`trace_sensitivity`).
TANGENT_MAX_VARIABLES = 1


def variable_unit(path: str) -> str:
    """The config unit of a variable (what its derivative is per).

    Parameters
    ----------
    path : str
        A dotted config path.

    Returns
    -------
    str
        ``"mm"``, ``"m/s"``, ``"Pa"``, ...
    """
    if path.endswith("_mm") or "_mm[" in path:
        return "mm"
    tail = path.rsplit(".", 1)[-1]
    if path in ("wall.damping",):
        return "N s/m"
    if path.startswith("contact."):  # a law's parameter: the unit its registry entry declares
        from ..laws import get_law, law_names

        for name in law_names():
            spec = get_law(name)
            if tail in spec.param_names:
                unit = spec.param(tail).unit
                return "1" if unit == "-" else unit
    return {"velocity": "m/s", "q": "1", "precompression": "N", "mass": "kg", "A": "s", "gamma": "N s/m",
            "stiffness": "N/m",
            "density": "kg/m^3", "young": "Pa", "poisson": "1", "yield_stress": "Pa", "frequency": "Hz",
            "mass_fraction": "1"}.get(tail.split("[")[0], "1")


@dataclass
class Sensitivity:
    """What :func:`sensitivity` computed.

    Attributes
    ----------
    objective : str
        The objective's name; ``unit`` its unit.
    value : float
        Its value for the config (what :func:`hertzchain.simulate` of the config gives).
    gradient : dict
        ``{variable path: d value / d variable}``, in the objective's unit per the variable's config
        unit (``chain.diameters_mm[3]``: per mm).
    values : dict
        ``{variable path: the variable's value in the config}`` (config units).
    units : dict
        ``{variable path: its config unit}``.
    mode : str
        ``"adjoint"`` or ``"tangent"``.
    n_steps : int
        Verlet steps of the run.
    elapsed_s : float
        Wall time of the whole computation [s].
    notes : list of str
        What the derivative holds fixed (the adaptive step's sequence).
    records : dict
        What the run recorded: ``time`` [s] and ``wall_force`` [N] at every sample (absent
        without a wall), every contact's largest sampled force ``max_contact_force`` [N] and
        elastic limit ``yield_force`` [N] (the design search's feasibility checks read them).
    smooth_value : float or None
        With ``smoothing``: the soft maximum whose gradient ``gradient`` is.
    """

    objective: str
    unit: str
    value: float
    gradient: dict[str, float]
    values: dict[str, float]
    units: dict[str, str]
    mode: str
    n_steps: int
    elapsed_s: float = 0.0
    notes: list[str] = field(default_factory=list)
    records: dict = field(default_factory=dict, repr=False)
    smooth_value: float | None = None

    def relative(self) -> dict[str, float]:
        """Elasticities (x / J) dJ/dx: the relative change of the objective per relative change of each
        variable (dimensionless; NaN where the variable or the objective is zero).

        Returns
        -------
        dict
            ``{variable path: elasticity}``.
        """
        out = {}
        for k, g in self.gradient.items():
            x = self.values.get(k, math.nan)
            out[k] = g * x / self.value if self.value and x else math.nan
        return out

    def as_dict(self) -> dict:
        """The result as plain data (what ``hertzchain sensitivity --json`` writes).

        Returns
        -------
        dict
            objective, unit, value, mode, n_steps, elapsed_s, notes and one row per variable
            (path, value, unit, derivative, derivative unit, elasticity).
        """
        rel = self.relative()
        return {"objective": self.objective, "unit": self.unit, "value": self.value, "mode": self.mode,
                "n_steps": self.n_steps, "elapsed_s": self.elapsed_s, "notes": list(self.notes),
                "variables": [{"path": k, "value": self.values.get(k), "unit": self.units[k], "derivative": g,
                               "derivative_unit": _per(self.unit, self.units[k]),
                               "elasticity": None if math.isnan(rel[k]) else rel[k]}
                              for k, g in self.gradient.items()]}


def _per(unit: str, per: str) -> str:
    """``N`` per ``m/s`` -> ``N/(m/s)``; per ``mm`` -> ``N/mm``."""
    if per == "1":
        return unit
    return f"{unit}/({per})" if any(c in per for c in "/ ^") else f"{unit}/{per}"


def _config(config):
    """A validated RunConfig from a path, a mapping or a RunConfig."""
    from ..config import load_config, parse_config
    from ..config.schema import RunConfig

    if isinstance(config, RunConfig):
        return config
    if isinstance(config, (str, Path)):
        return load_config(config)
    if isinstance(config, dict):
        return parse_config(config)
    raise ConfigError("config", f"must be a run-config path or mapping, got {type(config).__name__}")


def _prepare(cfg):
    """Model, System and run settings of a config, refusing what the derivative engines do not cover."""
    from ..checks import check_before_run
    from ..config import build_model
    from ..integrate.derivatives import differentiate as D
    from ..probes import Probes
    from ..runs.simulation import auto_duration

    if cfg.track is not None:
        raise ConfigError("track", "gradients follow the 1D engine; a run with [track] (beads leaving the axis) "
                          "has no sensitivity: leave [track] out")
    if cfg.run.integrator not in ("verlet", "auto"):
        raise ConfigError("run.integrator", f"gradients differentiate the Verlet engine's steps; got "
                          f"'{cfg.run.integrator}': use 'auto' (the default) or 'verlet'")
    model = build_model(cfg)
    system = model.system()
    D.check_law(system)
    duration = auto_duration(model) if cfg.run.duration == "auto" else float(cfg.run.duration)
    # what the taped run records: the wall's force (the config's probes are not written), so the
    # run's own memory check is not that of recording every contact
    probes = Probes(sample_interval=cfg.run.sample_interval, contacts=(system.n_beads,) if system.has_wall else ())
    check_before_run(model, system, duration, probes, dt=cfg.run.dt, integrator="verlet")
    return model, system, duration


def _parameter_gradient(sd, engine: dict[str, np.ndarray], direct: dict[str, np.ndarray]) -> dict[str, float]:
    """Chain rule: dJ/dx = sum over System arrays of (dJ/d array) . (d array / dx)."""
    grads = dict(engine)
    for name, g in direct.items():  # an objective's own partials on an array the engines also give
        grads[name] = g if name not in grads else _add(grads[name], g)
    return {path: sd.dot(path, grads) for path in sd.derivatives}


def _add(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a + b over the longer of the two (the shorter covers the first entries)."""
    out = np.zeros(max(a.size, b.size))
    out[:a.size] += a
    out[:b.size] += b
    return out


def _values(cfg, paths: list[str], sd) -> dict[str, float]:
    """The variables' values in the config (config units), for the elasticities."""
    from ..config import parse_path

    data = cfg.model_dump(mode="json")
    out = {}
    for p in paths:
        try:
            node = data
            for tok in parse_path(p):
                node = node[tok]
            out[p] = float(node)
        except (KeyError, IndexError, TypeError, ValueError):
            out[p] = _derived_value(p, sd)
    return out


def _derived_value(path: str, sd) -> float:
    """Values of variables that are no literal config field (a bead as built, a catalogue material)."""
    import re

    from ..materials import get_material

    m = re.fullmatch(r"chain\.(diameters|offsets)_mm\[(\d+)\]", path)
    if m:
        return float(1e3 * sd.values["diameter" if m.group(1) == "diameters" else "offset"][int(m.group(2))])
    m = re.fullmatch(r"materials\.([^.]+)\.(\w+)", path)
    if m:
        v = getattr(get_material(m.group(1)), m.group(2))
        return math.nan if v is None else float(v)
    if path == "striker.mass":
        return float(sd.values["mass"][0])
    if path == "contact.limiting_pressure_factor":  # the elastic-plastic law's default
        from ..plasticity import LIMITING_PRESSURE_FACTOR

        return float(LIMITING_PRESSURE_FACTOR)
    return math.nan


def sensitivity(config, variables: str | Sequence[str], objective: str = "peak_wall_force", *,
                mode: Literal["auto", "adjoint", "tangent"] = "auto",
                window: tuple[float, float] | None = None, smoothing: float | None = None) -> Sensitivity:
    """Exact derivatives of a run's result with respect to config fields.

    Parameters
    ----------
    config : str, pathlib.Path, dict or RunConfig
        A run-config file, or the mapping :func:`hertzchain.parse_config` takes.
    variables : str or sequence of str
        Dotted config paths, as in design files: ``"chain.diameters_mm[20]"``, ``"striker.velocity"``,
        ``"contact.A"``, ``"materials.AISI52100.young"``; a list field without an index
        (``"chain.diameters_mm"``) or with a range (``"chain.diameters_mm[16:30]"``) means each of its
        items. See :mod:`hertzchain.gradients.setup` for the fields known.
    objective : str
        One of :data:`hertzchain.gradients.OBJECTIVES` (default the refined peak wall force [N]), or
        ``"peak_contact_force[j]"``.
    mode : {"auto", "adjoint", "tangent"}
        Reverse mode (one sweep for any number of variables) or forward mode (one tangent per
        variable); ``"auto"``: the tangent for one variable, the adjoint for more (and for the
        elastic-plastic law, whose tangent costs more: ``benchmarks/gradient.py``).
    window : (float, float), optional
        Time window [s] of ``energy_at_wall``.
    smoothing : float, optional
        With ``peak_wall_force``: differentiate the soft maximum of the sampled wall force,
        mu log sum exp(F_k / mu), mu = ``smoothing`` [N] (:func:`hertzchain.gradients.objectives.soft_peak`:
        smooth where the peak has kinks, as where two pulses are equally high); ``.value`` stays
        the peak itself, ``.smooth_value`` is the soft maximum.

    Returns
    -------
    Sensitivity
        ``.value`` (float, the objective's unit) and ``.gradient`` ({path: derivative}, in the
        objective's unit per the variable's config unit).

    Raises
    ------
    ConfigError
        A bad config, an unknown objective, a variable that is no continuous field of the model, or
        a feature the derivative engines do not cover ([track], a scipy integrator, a law given by
        eps), each naming the field.

    Notes
    -----
    The derivative is that of the result the engine computes, on the step sequence it used (the
    adaptive step is held fixed); finite differences with the adaptive step see small jumps where a
    change of a parameter changes the sequence. Contact closures, the clipping of dissipative
    forces and the choice of the sample or step of a maximum are held fixed likewise: where they
    switch, the result has a kink or a jump, and the gradient is that of the branch the run is on.
    """
    from ..integrate.derivatives import differentiate as D
    from .memory import check_memory, estimate_memory
    from .objectives import (
        check_objective,
        contacts_needed,
        objective_unit,
        read_objective,
        soft_peak,
    )
    from .setup import expand_paths, setup_derivatives

    t0 = _time.perf_counter()
    if mode not in ("auto", "adjoint", "tangent"):
        raise ConfigError("mode", f"must be 'auto', 'adjoint' or 'tangent', got {mode!r}")
    cfg = _config(config)
    model, system, duration = _prepare(cfg)
    if not model.chain.n_beads:  # the derivative set-up is per bead; one contact has a closed form
        raise ConfigError("chain.uniform.n", "sensitivities need at least one bead; with none, the striker's impact "
                          "on the wall is the two-body Hertz impact of hertzchain.theory.two_body_impact")
    check_objective(objective, system)
    paths = expand_paths(cfg, variables)
    use_tangent = mode == "tangent" or (mode == "auto" and len(paths) <= TANGENT_MAX_VARIABLES
                                        and D.tangent_covers(system.law))
    check_memory(estimate_memory(cfg, system, duration, paths, use_tangent, objective))
    sd = setup_derivatives(cfg, system, paths)
    tape = D.record(system, duration, cfg.run.sample_interval, dt=cfg.run.dt,
                    steps_per_radian=cfg.run.steps_per_radian, contacts=contacts_needed(objective, system))
    reading = read_objective(objective, tape, window)
    value = reading.value
    if smoothing is not None:
        if objective != "peak_wall_force" or not smoothing > 0:
            raise ConfigError("smoothing", "is a width > 0 [N] of the soft maximum of peak_wall_force")
        reading = soft_peak(tape, float(smoothing))
    seeds = D.Seeds.build([(tape.sample_step(k), j, w) for k, j, w in reading.samples] + list(reading.steps),
                          reading.arrays)
    if use_tangent:
        dirs = {name: np.array([sd.dense(p, name) for p in paths]) for name in D.PARAMETERS}
        _, _, _, dj = D.tangents(system, dirs, duration, cfg.run.sample_interval, dt=cfg.run.dt,
                                 steps_per_radian=cfg.run.steps_per_radian, seeds=seeds, final_dres=reading.final_dres)
        grad = {p: float(dj[i]) + sd.dot(p, reading.direct) for i, p in enumerate(paths)}
    else:
        grad = _parameter_gradient(sd, D.gradient(tape, seeds, reading.final_dres), reading.direct)
    records = {"time": tape.time, "max_contact_force": tape.max_force,
               "yield_force": system.yield_force[:system.n_contacts]}
    if system.has_wall:
        records["wall_force"] = tape.forces[:, int(np.searchsorted(tape.contacts, system.n_beads))]
    notes = []
    if tape.plan.adaptive:
        notes.append("adaptive step: the derivative holds the run's step sequence fixed (see the docs, Sensitivities)")
    return Sensitivity(objective=objective, unit=objective_unit(objective), value=float(value),
                       gradient=grad, values=_values(cfg, paths, sd), units={p: variable_unit(p) for p in paths},
                       mode="tangent" if use_tangent else "adjoint", n_steps=tape.n_steps,
                       elapsed_s=_time.perf_counter() - t0, notes=notes, records=records,
                       smooth_value=float(reading.value) if smoothing is not None else None)


def memory_estimate(config, variables: str | Sequence[str], *, mode: Literal["auto", "adjoint", "tangent"] = "auto"
                    ) -> int:
    """The memory [bytes] :func:`sensitivity` will take for these variables, before anything runs
    (:mod:`hertzchain.gradients.memory`: linear in the beads, the variables and the samples).

    Parameters
    ----------
    config : str, pathlib.Path, dict or RunConfig
        The run config.
    variables : str or sequence of str
        As for :func:`sensitivity`.
    mode : {"auto", "adjoint", "tangent"}
        As for :func:`sensitivity`.

    Returns
    -------
    int
        The estimate [bytes] beyond the model and the imported package.
    """
    from ..integrate.derivatives import differentiate as D
    from .memory import estimate_memory
    from .setup import expand_paths

    cfg = _config(config)
    _, system, duration = _prepare(cfg)
    paths = expand_paths(cfg, variables)
    tangent = mode == "tangent" or (mode == "auto" and len(paths) <= TANGENT_MAX_VARIABLES
                                    and D.tangent_covers(system.law))
    return estimate_memory(cfg, system, duration, paths, tangent).total


@dataclass
class TraceSensitivity:
    """A sampled signal and its derivatives (:func:`trace_sensitivity`).

    Attributes
    ----------
    time : numpy.ndarray
        Sample times [s], (K,).
    value : numpy.ndarray
        The signal [N], (K,).
    jacobian : numpy.ndarray
        (P, K): d signal / d variable, per the variable's config unit.
    variables : list of str
        The P variable paths.
    """

    time: np.ndarray
    value: np.ndarray
    jacobian: np.ndarray
    variables: list[str]


def trace_sensitivity(config, variables: str | Sequence[str], signal: str = "wall",
                      duration: float | None = None) -> TraceSensitivity:
    """The derivative of a whole sampled force signal by a few config fields (tangent model).

    Parameters
    ----------
    config : str, pathlib.Path, dict or RunConfig
        The run config.
    variables : str or sequence of str
        Dotted config paths (as for :func:`sensitivity`).
    signal : str
        ``"wall"`` (contact N) or ``"sensor:n"`` (the sensor embedded in bead n, (F_{n-1} + F_n) / 2).
    duration : float, optional
        Run length [s] (default: the config's).

    Returns
    -------
    TraceSensitivity
        Times, the signal and its Jacobian.
    """
    from ..integrate.derivatives import differentiate as D
    from .memory import check_memory, estimate_memory
    from .setup import expand_paths, setup_derivatives

    cfg = _config(config)
    model, system, dur = _prepare(cfg)
    if duration is not None:
        dur = float(duration)
    paths = expand_paths(cfg, variables)
    check_memory(estimate_memory(cfg, system, dur, paths, tangent=True))
    sd = setup_derivatives(cfg, system, paths)
    if signal == "wall":
        if not system.has_wall:
            raise ConfigError("signal", "a wall signal needs a wall (wall.type = 'flat')")
        contacts = [system.n_beads]
    else:
        kind, _, bead = signal.partition(":")
        if kind != "sensor" or not bead.strip().isdigit() or not 1 <= int(bead) <= system.n_beads:
            raise ConfigError("signal", f"must be 'wall' or 'sensor:n' with n a bead (1..{system.n_beads}), "
                              f"got {signal!r}")
        contacts = [int(bead) - 1, int(bead)]
    dirs = {name: np.array([sd.dense(p, name) for p in paths]) for name in D.PARAMETERS}
    rec, f, ft, _ = D.tangents(system, dirs, dur, cfg.run.sample_interval, dt=cfg.run.dt,
                               steps_per_radian=cfg.run.steps_per_radian, contacts=contacts)
    if len(contacts) == 1:
        value, jac = f[:, 0], ft[:, :, 0]
    else:
        value, jac = 0.5 * (f[:, 0] + f[:, 1]), 0.5 * (ft[:, :, 0] + ft[:, :, 1])
    return TraceSensitivity(np.arange(f.shape[0]) * cfg.run.sample_interval, value, jac, paths)
