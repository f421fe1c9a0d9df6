"""Sensitivity objectives of the design search (issue 36 item 3: a protected body's peaks, the
energy delivered to it, the plastic work), striker faces, and the time of a yielded wall peak
(issue 38): each derivative against central differences of whole runs at a fixed small step (the
same step sequence on both sides, 1e-5 relative), each value against what the run reports.

- ``peak_body_force`` (|k x + c v| of the mount), ``peak_body_acceleration`` and
  ``energy_to_body`` (the trapezoids of F_N v_body the engine sums) read the body's state and the
  forces on it: the engines seed positions and velocities (state seeds) as well as forces;
  checked on a short chain ending on a protected body, struck by a flat-faced striker.
- ``plastic_work`` and ``residual_overlap_max`` read every contact's final elastic-plastic state.
- a flat striker face (1/R' = 0), a curved one (its radius a variable) and a body's spherical face.
- ``peak_wall_time`` where the wall contact yields without viscosity (Thornton): the force's
  curvature jumps at the peak; the time where the overlap stops growing is smooth, so its
  derivative matches differences of 1e-7 (to 1e-5) and the trend of differences 1e-3 wide (to
  1e-3: the vertex of three steps still moves by a sliver of a step as the peak crosses steps,
  ~2e-4 of the slope); the three-force parabola's derivative was ~7 % off that trend here.
"""

from __future__ import annotations

import numpy as np
import pytest
import test_gradients as tg
from test_gradients import BASE, _with

import hertzchain as hc
from hertzchain.config import build_model, parse_config
from hertzchain.errors import ConfigError
from hertzchain.gradients import sensitivity
from hertzchain.gradients.objectives import contacts_needed, read_objective
from hertzchain.integrate.derivatives import differentiate as D

BODY = _with(BASE, wall={"type": "body", "mass": 0.05, "stiffness": 2e5, "damping": 5.0},
             striker={"shape": "flat", "mass": 0.004}, run={"duration": 1.2e-3})
SOFT = {"mysteel": {"density": 7800.0, "young": 2.0e11, "poisson": 0.3, "yield_stress": 2e8}}


def _objective(cfg: dict, objective: str) -> float:
    c = parse_config(cfg)
    system = build_model(c).system()
    tape = D.record(system, c.run.duration, c.run.sample_interval, dt=c.run.dt,
                    contacts=contacts_needed(objective, system))
    return read_objective(objective, tape).value


@pytest.fixture(autouse=True)
def _records_what_the_objective_reads(monkeypatch):
    monkeypatch.setattr(tg, "_objective", _objective)


@pytest.mark.parametrize("objective, record", [("peak_body_force", "body_force"),
                                               ("peak_body_acceleration", "body_acceleration"),
                                               ("energy_to_body", "body_energy")])
def test_body_objectives_are_the_runs_and_match_differences(objective, record):
    paths = ["striker.velocity", "striker.mass", "chain.diameters_mm[7]", "wall.mass", "wall.stiffness", "wall.damping"]
    s = sensitivity(BODY, paths, objective)
    assert s.mode == "adjoint"
    assert s.value == pytest.approx(float(np.max(np.abs(hc.run_config(BODY)[record].values))), rel=1e-12)
    tg.assert_matches(s, BODY, paths, objective, rel=1e-6, tol=1e-5)
    # forward mode seeds the same state: the same numbers
    t = sensitivity(BODY, ["wall.stiffness"], objective, mode="tangent")
    assert t.gradient["wall.stiffness"] == pytest.approx(s.gradient["wall.stiffness"], rel=1e-9)


@pytest.mark.parametrize("face, paths", [
    ({"striker": {"shape": "flat", "mass": 0.004}}, ["striker.velocity", "striker.mass", "chain.diameters_mm[0]"]),
    ({"striker": {"radius_of_curvature_mm": 30.0}}, ["striker.radius_of_curvature_mm", "striker.diameter_mm",
                                                     "chain.diameters_mm[0]"]),
    ({"wall": {"type": "body", "mass": 0.05, "stiffness": 2e5, "shape": "sphere", "radius_of_curvature_mm": 50.0}},
     ["wall.radius_of_curvature_mm", "chain.diameters_mm[7]"]),
])
def test_flat_and_curved_faces(face, paths):
    cfg = _with(BASE, **face)
    tg.assert_matches(sensitivity(cfg, paths), cfg, paths, tol=1e-5)


def test_the_time_of_a_yielded_wall_peak_follows_the_trend():
    cfg = _with(BASE, materials=SOFT, contact={"law": "elastoplastic", "A": 0.0})
    system = build_model(parse_config(cfg)).system()
    assert hc.run_config(cfg)["max_overlap"].values[-1] > 3 * system.yield_overlap()[system.n_beads]
    paths = ["striker.velocity", "chain.diameters_mm[7]", "materials.mysteel.yield_stress"]
    s = sensitivity(cfg, paths, "peak_wall_time")
    assert s.value == pytest.approx(hc.run_config(cfg).attrs["peak_wall_time"], abs=2e-8)  # within a step
    tg.assert_matches(s, cfg, paths, "peak_wall_time", rel=1e-7, tol=1e-5)
    tg.assert_matches(s, cfg, paths, "peak_wall_time", rel=1e-3, tol=1e-3)  # the trend, not a sawtooth's slope


@pytest.mark.parametrize("objective, record", [("plastic_work", "plastic_work"),
                                               ("residual_overlap_max", "residual_overlap")])
def test_plastic_objectives_are_the_runs_and_match_differences(objective, record):
    """The plastic work at the end of the run: partials on every contact's largest overlap (the
    positions of the step that reached it), its final residual overlap (carried back by the reverse
    sweep), kappa and the yield overlaps; the largest residual overlap (the dent kept)."""
    cfg = _with(BASE, materials=SOFT, contact={"law": "elastoplastic", "A": 1e-6})
    paths = ["striker.velocity", "chain.diameters_mm[0]", "chain.diameters_mm[5]", "contact.A",
             "materials.mysteel.yield_stress", "materials.mysteel.young"]
    s = sensitivity(cfg, paths, objective)
    run = hc.run_config(cfg)[record].values
    assert s.value == pytest.approx(float(run[-1] if objective == "plastic_work" else run.max()), rel=1e-12)
    tg.assert_matches(s, cfg, paths, objective, rel=1e-6, tol=1e-5)


def test_body_objectives_need_a_body():
    with pytest.raises(ConfigError, match="type = 'body'"):
        sensitivity(BASE, ["striker.velocity"], "peak_body_force")
    with pytest.raises(ConfigError, match="elastoplastic"):
        sensitivity(BASE, ["striker.velocity"], "plastic_work")
    # a chain that stays elastic does no plastic work: refused, not a gradient of zeros
    with pytest.raises(ConfigError, match="yield overlap"):
        sensitivity(_with(BASE, contact={"law": "elastoplastic"}), ["striker.velocity"], "plastic_work")


@pytest.mark.parametrize("law", [{}, pytest.param({"law": "dashpot", "gamma": 20.0}, marks=pytest.mark.slow),
                                 pytest.param({"law": "power", "exponent": 1.8, "stiffness": 6e11},
                                              marks=pytest.mark.slow)])
def test_gravity_and_loads_static_state_matches_differences(law):
    """A column standing on the wall under gravity (plus a load on one bead), struck from above: the
    static state (every contact's overlap under the weights it holds, paper eq. 1 inverted, or the
    law's static force) moves with the masses, sizes and stiffnesses, and the gradient carries it
    (against central differences of whole runs). Strong gravity (2000 m/s^2) makes the static
    overlaps matter for the peak."""
    cfg = _with(BASE, chain={"gravity": 2000.0}, load={"beads": [3], "forces": [2.0]}, contact=law,
                run={"duration": 1.2e-3})
    paths = ["striker.velocity", "striker.diameter_mm", "chain.diameters_mm[0]", "chain.diameters_mm[5]",
             "materials.mysteel.density"]
    s = sensitivity(cfg, paths)
    assert s.value == pytest.approx(hc.run_config(cfg).attrs["peak_wall_force"], rel=1e-12)
    tg.assert_matches(s, cfg, paths, rel=1e-6, tol=1e-5)
    # the static state is what the gradient adds: without it the density's derivative changes
    flat = sensitivity(_with(cfg, chain={"gravity": 0.0}, load={"forces": [0.0]}), ["materials.mysteel.density"])
    assert abs(flat.gradient["materials.mysteel.density"] - s.gradient["materials.mysteel.density"]) > \
        1e-3 * abs(s.gradient["materials.mysteel.density"])


def test_cylinders_and_given_masses_match_differences():
    """Bead 3 a crossed cylinder (elliptical Hertz contacts with its neighbours: the ellipse's
    parameter by the implicit function theorem, gradients.faces), bead 5 a cylinder along the
    chain (its flat ends: sphere-on-flat contacts) and bead 7 of a given mass: the gradient by their
    diameters, the striker's and the material against central differences of whole runs."""
    cfg = _with(BASE, chain={"elements": ["sphere", "sphere", "rod", "sphere", "peg", "sphere", "heavy", "sphere"]},
                elements={"rod": {"shape": "cylinder", "orientation": "crossed", "length_mm": 25.0},
                          "peg": {"shape": "cylinder", "orientation": "aligned", "length_mm": 12.0},
                          "heavy": {"mass": 0.02}})
    paths = ["striker.velocity", "chain.diameters_mm[1]", "chain.diameters_mm[2]", "chain.diameters_mm[4]",
             "chain.diameters_mm[6]", "materials.mysteel.young", "materials.mysteel.density"]
    s = sensitivity(cfg, paths)
    assert s.value == pytest.approx(hc.run_config(cfg).attrs["peak_wall_force"], rel=1e-12)
    tg.assert_matches(s, cfg, paths, rel=1e-6, tol=1e-5)


@pytest.mark.parametrize("objective", ["peak_wall_force", "plastic_work"])
def test_elastoplastic_offset_chain_matches_differences(objective):
    """Offset beads with Thornton's law: each yielding contact's overlap and force direction come
    from the offsets' geometry (partials.plastic_contact_adjoint), its state carried back through
    the reverse sweep; against central differences of whole runs, offsets among the variables."""
    cfg = _with(BASE, materials=SOFT, contact={"law": "elastoplastic", "A": 1e-6},
                chain={"offsets_mm": [0.0, 0.4, -0.3, 0.5, 0.0, -0.2, 0.3, 0.0]})
    paths = ["striker.velocity", "chain.diameters_mm[2]", "materials.mysteel.yield_stress"]
    offsets = ["chain.offsets_mm[1]", "chain.offsets_mm[3]"]
    s = sensitivity(cfg, paths + offsets, objective)
    tg.assert_matches(s, cfg, paths, objective, rel=1e-6, tol=1e-5)
    # The peak barely moves with an offset (~1e-4 N/mm on ~10 N): differences 1e-6 wide sink in the
    # runs' rounding (the viscoelastic law's, differentiated by the general path, scatter as much),
    # so they are taken 1e-4 wide, where their truncation error is ~1e-5.
    tg.assert_matches(s, cfg, offsets, objective, rel=1e-4, tol=1e-4)
