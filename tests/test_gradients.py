"""hertzchain.sensitivity: exact derivatives of results by config fields.

Checked against central finite differences of whole runs at a fixed small step (the same step
sequence on both sides, so the two must agree to the difference's own error) for every kind of
parameter, with and without dissipation, and against the similarity laws of Hertz chains (closed
forms): scaling every length by s scales forces by s^2, the Young modulus by l forces by l^(2/5),
densities by l forces by l^(3/5), the striker speed by l forces by l^(6/5) (paper eq. 1 made
dimensionless).
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.config import build_model, parse_config, parse_path
from hertzchain.errors import ConfigError
from hertzchain.gradients import OBJECTIVES, sensitivity
from hertzchain.gradients.objectives import read_objective
from hertzchain.integrate.derivatives import differentiate as D

MAT = {"mysteel": {"density": 7800.0, "young": 2.0e11, "poisson": 0.3, "yield_stress": 2e9}}
BASE = {"materials": MAT,
        "chain": {"diameters_mm": [20.0, 19.0, 18.0, 17.0, 16.0, 15.0, 14.0, 13.0], "material": "mysteel"},
        "striker": {"velocity": 0.3, "diameter_mm": 8.0, "material": "mysteel"},  # one material throughout
        "run": {"duration": 6e-4, "sample_interval": 1e-7, "dt": 2e-8}}  # the wall peak at ~4e-4 s
LAWS = {"elastic": {}, "viscoelastic": {"law": "viscoelastic", "A": 1e-6},
        "dashpot": {"law": "dashpot", "gamma": 20.0}}


def _with(base: dict, **sections) -> dict:
    cfg = copy.deepcopy(base)
    for key, value in sections.items():
        cfg[key] = {**cfg.get(key, {}), **value}
    return cfg


def _objective(cfg: dict, objective: str) -> float:
    c = parse_config(cfg)
    system = build_model(c).system()
    tape = D.record(system, c.run.duration, c.run.sample_interval, dt=c.run.dt, steps_per_radian=c.run.steps_per_radian)
    return read_objective(objective, tape).value


def central_difference(cfg: dict, path: str, objective: str = "peak_wall_force", rel: float = 1e-6) -> float:
    """(J(x + h) - J(x - h)) / 2h of a config field, h relative to its value."""
    out = []
    tokens = parse_path(path)
    for sign in (1, -1):
        c = copy.deepcopy(cfg)
        node = c
        for tok in tokens[:-1]:
            node = node[tok]
        x = node[tokens[-1]]
        h = rel * abs(x)
        node[tokens[-1]] = x + sign * h
        out.append(_objective(c, objective))
    return (out[0] - out[1]) / (2 * h)


def assert_matches(sens, cfg, paths, objective="peak_wall_force", rel=1e-6, tol=1e-4):
    for p in paths:
        fd = central_difference(cfg, p, objective, rel)
        assert sens.gradient[p] == pytest.approx(fd, rel=tol), p


@pytest.mark.parametrize("law", list(LAWS))
def test_every_kind_of_parameter_matches_finite_differences(law):
    cfg = _with(BASE, contact=LAWS[law]) if LAWS[law] else copy.deepcopy(BASE)
    paths = ["chain.diameters_mm[0]", "chain.diameters_mm[4]", "chain.diameters_mm[7]", "striker.velocity",
             "striker.diameter_mm", "materials.mysteel.young", "materials.mysteel.poisson",
             "materials.mysteel.density"] + (["contact.A"] if law == "viscoelastic" else []) + \
        (["contact.gamma"] if law == "dashpot" else [])
    s = sensitivity(cfg, paths)
    assert s.mode == "adjoint" and s.unit == "N"
    assert_matches(s, cfg, paths)


def test_precompression_and_the_size_scaled_law():
    cfg = _with(BASE, chain={"precompression": 5.0})
    assert_matches(sensitivity(cfg, ["chain.precompression", "chain.diameters_mm[3]"]), cfg,
                   ["chain.precompression", "chain.diameters_mm[3]"])
    cfg = _with(BASE, contact={"law": "viscoelastic_scaled", "A": 1e-6})  # A_j follows every contact's size
    paths = ["contact.A", "chain.diameters_mm[0]", "chain.diameters_mm[5]", "materials.mysteel.density"]
    assert_matches(sensitivity(cfg, paths), cfg, paths)


def test_offsets_of_a_misaligned_chain():
    """Offsets enter through d = R + R' - sqrt(dx^2 + de^2), which loses ~4 digits to cancellation
    (d ~ 1 um against R + R' ~ 20 mm): a difference step of 1e-6 would measure that rounding, so
    the step is 1e-3 (its truncation error ~1e-6 relative)."""
    cfg = _with(BASE, chain={"offsets_mm": [0.0, 0.5, 1.0, 0.2, 0.0, -0.3, 0.0, 0.1]},
                contact=LAWS["viscoelastic"])
    paths = ["chain.offsets_mm[2]", "chain.offsets_mm[5]", "chain.diameters_mm[4]"]
    assert_matches(sensitivity(cfg, paths), cfg, paths, rel=1e-3)


def test_a_protected_body_and_its_mount():
    """[wall] type = "body": a mass on a spring and a dashpot behind the last bead; the peak force on
    its face by the body's mass and its mount's stiffness and damping (the issue names the body's
    stiffness), a given striker mass, and the size-scaled dashpot whose gamma_j follows the body's
    reduced mass too."""
    cfg = _with(BASE, wall={"type": "body", "mass": 0.05, "stiffness": 2e5, "damping": 5.0},
                striker={"mass": 0.004}, contact={"law": "dashpot_scaled", "gamma": 20.0})
    paths = ["wall.stiffness", "wall.damping", "wall.mass", "striker.mass", "contact.gamma", "chain.diameters_mm[3]"]
    s = sensitivity(cfg, paths)
    assert s.units["wall.stiffness"] == "N/m" and s.units["wall.damping"] == "N s/m"
    # the mount's derivatives are small (the pulse is over before the mount moves much): a step of
    # 1e-4 keeps the difference above the run's rounding
    assert_matches(s, cfg, paths, rel=1e-4)


def test_fields_of_chains_given_by_builders():
    cfg = copy.deepcopy(BASE)
    cfg["chain"] = {"uniform": {"n": 4, "diameter_mm": 20.0}, "taper": {"n": 4, "q": 0.08},
                    "substitutions": [{"bead": 2, "diameter_mm": 18.0}], "material": "mysteel"}
    paths = ["chain.uniform.diameter_mm", "chain.taper.q", "chain.substitutions[0].diameter_mm"]
    assert_matches(sensitivity(cfg, paths), cfg, paths)
    # a bead of a chain that is no list: bead 6 as built (the derivative is the list item's)
    listed = copy.deepcopy(BASE)
    listed["chain"] = {"diameters_mm": list(build_model(parse_config(cfg)).chain.diameters * 1e3),
                       "material": "mysteel"}
    built = sensitivity(cfg, ["chain.diameters_mm[5]"], mode="adjoint").gradient["chain.diameters_mm[5]"]
    assert built == pytest.approx(sensitivity(listed, ["chain.diameters_mm[5]"]).gradient["chain.diameters_mm[5]"],
                                  rel=1e-6)
    # the substituted bead's list item no longer matters
    sub = copy.deepcopy(BASE)
    sub["chain"]["substitutions"] = [{"bead": 3, "diameter_mm": 15.0}]
    assert sensitivity(sub, ["chain.diameters_mm[2]"]).gradient["chain.diameters_mm[2]"] == 0.0


FITTED = ("time_of_flight", "pulse_duration", "front_momentum_at_wall")
#: Objectives of a protected body or of the elastic-plastic law (tests/test_gradients_objectives.py).
STATE_OBJECTIVES = ("peak_body_force", "peak_body_acceleration", "energy_to_body", "plastic_work",
                    "residual_overlap_max")


@pytest.mark.parametrize("objective", [o for o in OBJECTIVES if o not in FITTED + ("peak_wall_time",)
                                       and o not in STATE_OBJECTIVES]  # in test_gradients_objectives
                         + ["peak_contact_force[3]"])
def test_every_objective_matches_finite_differences(objective):
    cfg = _with(BASE, contact=LAWS["viscoelastic"])
    paths = ["chain.diameters_mm[4]", "striker.velocity"]
    s = sensitivity(cfg, paths, objective)
    assert s.value == pytest.approx(_objective(cfg, objective), rel=1e-14)
    assert_matches(s, cfg, paths, objective)


def _trend(cfg: dict, path: str, objective: str, span: float = 1e-2, n: int = 21) -> float:
    """Slope at x of a quadratic fitted to the objective over x (1 +- span): the trend through the
    small jumps of a quantity read off a fit whose window of samples moves with the pulse."""
    tokens = parse_path(path)
    xs, ys = [], []
    for f in np.linspace(-span, span, n):
        c = copy.deepcopy(cfg)
        node = c
        for tok in tokens[:-1]:
            node = node[tok]
        x0 = node[tokens[-1]]
        node[tokens[-1]] = x0 * (1 + f)
        xs.append(x0 * (1 + f))
        ys.append(_objective(c, objective))
    a2, a1, _ = np.polyfit(xs, ys, 2)
    return a1 + 2 * a2 * x0


@pytest.mark.parametrize("objective", FITTED)
def test_fitted_pulse_quantities_follow_the_trend(objective):
    """T, tau and Q_F come from the cos^6 fit of the loading part (paper Sec. III), over the samples
    with (t - T) / tau in (-1, 0]: each sample that enters or leaves that window as the pulse moves
    makes the values jump (~1e-4 relative here). The derivative is that of the fit with the window's
    ends moving continuously, the trend through the jumps: against the slope of a quadratic fitted
    over +-1 % (21 runs) it agrees to the scatter the jumps leave (< 0.5 %)."""
    cfg = _with(BASE, contact=LAWS["viscoelastic"])
    paths = ["chain.diameters_mm[4]", "striker.velocity"]
    s = sensitivity(cfg, paths, objective)
    assert s.value == pytest.approx(_objective(cfg, objective), rel=1e-14)
    for p in paths:
        assert s.gradient[p] == pytest.approx(_trend(cfg, p, objective), rel=1e-2), p


def test_fit_derivatives_on_a_cos6_pulse():
    """On an exact cos^6 record F_m cos^6((t - T0) / tau0) the fit returns T0 and tau0 whatever the
    window, and Q_F = F_m tau0 int_{-pi/2}^{1} cos^6: dT/dT0 = 1, dtau/dtau0 = 1, dQ_F/dtau0 = Q_F / tau0,
    dQ_F/dF_m = Q_F / F_m, dQ_F/dT0 = 0 (closed forms)."""
    from hertzchain.gradients.objectives import pulse_partials

    t = np.arange(0.0, 2e-3, 1e-7)
    fm, t0, tau0 = 8.0, 1.2e-3, 6e-5

    def record(fm, t0, tau0):
        phase = (t - t0) / tau0
        return np.where(np.abs(phase) < np.pi / 2, fm * np.cos(phase) ** 6, 0.0)

    def along(w, i, h=1e-6):
        p = np.array([fm, t0, tau0])
        e = np.zeros(3)
        e[i] = h * p[i]
        return w @ (record(*(p + e)) - record(*(p - e))) / (2 * e[i])

    _, w = pulse_partials(t, record(fm, t0, tau0), "time_of_flight")
    assert along(w, 1) == pytest.approx(1.0, abs=1e-7) and abs(along(w, 2)) < 1e-7
    _, w = pulse_partials(t, record(fm, t0, tau0), "pulse_duration")
    assert along(w, 2) == pytest.approx(1.0, abs=1e-7) and abs(along(w, 1)) < 1e-7
    q, w = pulse_partials(t, record(fm, t0, tau0), "front_momentum_at_wall")
    assert along(w, 2) == pytest.approx(q / tau0, rel=1e-6)  # Q_F by trapezoids: ~3e-7 off the integral
    assert along(w, 0) == pytest.approx(q / fm, rel=1e-7)
    assert abs(along(w, 1)) < 1e-6 * q / tau0


def test_peak_time_and_tangent_mode():
    cfg = copy.deepcopy(BASE)
    paths = ["chain.diameters_mm[2]", "striker.velocity"]
    s = sensitivity(cfg, paths, "peak_wall_time")
    assert 3e-4 < s.value < 5e-4
    assert_matches(s, cfg, paths, "peak_wall_time")
    t = sensitivity(cfg, paths, "peak_wall_time", mode="tangent")
    assert t.mode == "tangent"
    for p in paths:
        assert t.gradient[p] == pytest.approx(s.gradient[p], rel=1e-10)


@pytest.mark.parametrize("law", ["elastic", "viscoelastic"])
def test_adaptive_step_gradient_is_the_derivative_at_a_tight_step(law):
    """An adaptive run differentiated on its own step sequence, against central differences of
    runs at a fixed step finer than its smallest. Both converge to the derivative of the exact
    solution as the step shrinks; the Kuwabara-Kono rate term ~ delta^(1/2) d(delta)/dt is not
    smooth at closure, and its derivative converges at first order only (4e-9 s: 1.0e-4 off,
    2e-9 s: 5e-5, 1e-9 s: 3e-5), so the adaptive run is asked for 1600 steps per radian."""
    cfg = _with(BASE, contact=LAWS[law], run={"steps_per_radian": 1600.0}) if LAWS[law] else \
        _with(BASE, run={"steps_per_radian": 1600.0})
    del cfg["run"]["dt"]
    paths = ["chain.diameters_mm[3]", "striker.velocity"] + (["contact.A"] if law == "viscoelastic" else [])
    s = sensitivity(cfg, paths)
    assert s.value == hc.run_config(cfg).attrs["peak_wall_force"]  # the engine's own number
    assert_matches(s, _with(cfg, run={"dt": 1e-9}), paths, tol=1e-4)


def test_similarity_laws_of_hertz_chains():
    """Elasticities (x / F) dF/dx of the peak wall force of an elastic chain of one material:
    velocity 6/5, Young modulus 2/5, density 3/5, all diameters together (striker's included) 2."""
    cfg = copy.deepcopy(BASE)
    del cfg["run"]["dt"]
    cfg["run"].update(steps_per_radian=2000.0, duration=8e-4)  # the whole first pulse reaches the wall
    paths = ["striker.velocity", "materials.mysteel.young", "materials.mysteel.density", "chain.diameters_mm",
             "striker.diameter_mm"]
    e = sensitivity(cfg, paths).relative()
    assert e["striker.velocity"] == pytest.approx(1.2, abs=1e-4)
    assert e["materials.mysteel.young"] == pytest.approx(0.4, abs=1e-4)
    assert e["materials.mysteel.density"] == pytest.approx(0.6, abs=1e-4)
    sizes = sum(v for k, v in e.items() if "diameter" in k)
    assert sizes == pytest.approx(2.0, abs=1e-4)


def test_refusals_name_the_field():
    with pytest.raises(ConfigError, match="striker.colour"):
        sensitivity(BASE, ["striker.colour"])
    with pytest.raises(ConfigError, match="discrete"):
        sensitivity(_with(BASE, chain={"diameters_mm": None, "uniform": {"n": 8, "diameter_mm": 20.0}}),
                    ["chain.uniform.n"])
    with pytest.raises(ConfigError, match="objective"):
        sensitivity(BASE, ["striker.velocity"], "loudness")
    with pytest.raises(ConfigError, match="contact.eps"):
        sensitivity(_with(BASE, contact={"law": "viscoelastic", "eps": 0.98}), ["striker.velocity"])
    with pytest.raises(ConfigError, match="run.integrator"):
        sensitivity(_with(BASE, run={"integrator": "dop853"}), ["striker.velocity"])
    with pytest.raises(ConfigError, match="track"):
        sensitivity(_with(BASE, track={"spring": 10.0}), ["striker.velocity"])
    with pytest.raises(ConfigError, match="wall"):
        sensitivity(_with(BASE, wall={"type": "none"}), ["striker.velocity"], "peak_wall_force")
    with pytest.raises(ConfigError, match=r"chain.diameters_mm\[2:20\]"):
        sensitivity(BASE, ["chain.diameters_mm[2:20]"])


def test_ranges_units_and_plain_data(tmp_path):
    path = tmp_path / "run.toml"
    import tomli_w

    path.write_text(tomli_w.dumps(BASE))
    s = sensitivity(path, ["chain.diameters_mm[2:5]", "materials.mysteel.young", "striker.mass"])
    assert list(s.gradient) == ["chain.diameters_mm[2]", "chain.diameters_mm[3]", "chain.diameters_mm[4]",
                                "materials.mysteel.young", "striker.mass"]
    assert s.units["chain.diameters_mm[3]"] == "mm" and s.units["materials.mysteel.young"] == "Pa"
    assert s.values["chain.diameters_mm[3]"] == 17.0 and s.values["striker.mass"] > 0
    row = s.as_dict()["variables"][0]
    assert row["derivative_unit"] == "N/mm" and row["value"] == 18.0
    # per mm: a bead 1 um larger changes the force by a thousandth of the derivative
    mm = s.gradient["chain.diameters_mm[3]"]
    cfg = copy.deepcopy(BASE)
    cfg["chain"]["diameters_mm"][3] += 1e-3
    assert (_objective(cfg, "peak_wall_force") - s.value) == pytest.approx(1e-3 * mm, rel=1e-3)
