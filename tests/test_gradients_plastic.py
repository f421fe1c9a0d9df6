"""Sensitivities of the elastic-plastic (Thornton) law: the reverse sweep carries the adjoints of
every contact's state (residual overlap, unloading stiffness) backwards, and the yield overlaps
are parameters of their own. Checked against central finite differences of whole runs at a fixed
small step, on runs where the contacts yield (the plastic branch is exercised)."""

from __future__ import annotations

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.gradients import sensitivity, trace_sensitivity

from test_gradients import BASE, _with, assert_matches

# A soft steel (sigma_Y = 200 MPa): at 0.3 m/s every contact the pulse reaches yields.
MAT = {"mysteel": {"density": 7800.0, "young": 2.0e11, "poisson": 0.3, "yield_stress": 2e8}}
PLASTIC = _with(BASE, materials=MAT, contact={"law": "elastoplastic", "A": 1e-6})
PATHS = ["striker.velocity", "chain.diameters_mm[0]", "chain.diameters_mm[5]", "chain.diameters_mm[7]",
         "contact.A", "materials.mysteel.yield_stress", "materials.mysteel.young", "striker.diameter_mm"]


def test_the_contacts_yield():
    r = hc.run_config(PLASTIC)
    dy = hc.build_model(hc.parse_config(PLASTIC)).system().yield_overlap()[:9]
    assert np.all(r["max_overlap"].values > 3 * dy)  # every contact, the wall's included, went plastic


@pytest.mark.parametrize("objective", ["peak_wall_force", "peak_contact_force[0]", "energy_at_wall",
                                       "max_force_over_yield"])
def test_plastic_gradients_match_finite_differences(objective):
    s = sensitivity(PLASTIC, PATHS, objective)
    assert s.mode == "adjoint"
    assert_matches(s, PLASTIC, [p for p in PATHS if s.gradient[p] != 0.0], objective)


def test_limiting_pressure_without_viscosity_and_a_protected_body():
    cfg = _with(PLASTIC, contact={"law": "elastoplastic", "A": 0.0, "limiting_pressure_factor": 2.5},
                wall={"type": "body", "mass": 0.05, "stiffness": 2e5, "damping": 5.0})
    paths = ["contact.limiting_pressure_factor", "materials.mysteel.yield_stress", "chain.diameters_mm[4]",
             "wall.mass", "striker.velocity"]
    s = sensitivity(cfg, paths + ["wall.stiffness"])
    assert_matches(s, cfg, paths)
    assert_matches(s, cfg, ["wall.stiffness"], rel=1e-4)  # small: a larger step keeps it above rounding


def test_precompression_past_yield():
    """A static load past the elastic limit: the chain starts on Thornton's loading line with every
    contact's largest overlap equal to its static one, exactly on the switch between loading and
    unloading, so rounding decides the branch of the first small motions. The derivative is the
    one-sided one of the branches taken; differences agree to ~1e-4 (differences of a field that
    moves the switch itself, the yield stress, are noisy at the 3e-4 level whatever their step)."""
    cfg = _with(PLASTIC, chain={"precompression": 5.0})
    system = hc.build_model(hc.parse_config(cfg)).system()
    assert np.all(system.d0[1:8] > 5 * system.yield_overlap()[1:8])
    paths = ["chain.precompression", "striker.velocity", "chain.diameters_mm[3]"]
    assert_matches(sensitivity(cfg, paths), cfg, paths, tol=2e-4)
    s = sensitivity(cfg, ["materials.mysteel.yield_stress"])
    assert_matches(s, cfg, ["materials.mysteel.yield_stress"], rel=1e-7, tol=1e-3)


@pytest.mark.parametrize("objective", ["peak_wall_force", "plastic_work"])
def test_tangent_equals_adjoint(objective):
    """Forward mode (each contact's Jacobian from the law's reverse-mode partials, the state's
    tangents carried step to step) and the reverse sweep are two differentiations of the same
    steps: equal to rounding, a result read from the final state (the plastic work) included."""
    paths = ["striker.velocity", "contact.A", "materials.mysteel.yield_stress", "chain.diameters_mm[5]"]
    a = sensitivity(PLASTIC, paths, objective)
    t = sensitivity(PLASTIC, paths, objective, mode="tangent")
    assert (a.mode, t.mode) == ("adjoint", "tangent") and t.value == a.value
    for p in paths:
        assert t.gradient[p] == pytest.approx(a.gradient[p], rel=1e-10), p


@pytest.mark.slow  # ~35 s: five whole runs and the trace's tangent compiled
def test_trace_matches_finite_differences():
    """d(wall force at every sample)/d(field) of a yielding chain by the tangent model against
    central differences of the whole trace (the samples where the force is above 1 % of its peak)."""
    paths = ["striker.velocity", "materials.mysteel.yield_stress"]
    tr = trace_sensitivity(PLASTIC, paths)
    for i, p in enumerate(paths):
        x = hc.parse_config(PLASTIC)
        base = float(x.striker.velocity if p == "striker.velocity" else 2e8)
        h = 1e-6 * base
        traces = []
        for sign in (1, -1):
            cfg = _with(PLASTIC, striker={"velocity": base + sign * h}) if p == "striker.velocity" else \
                _with(PLASTIC, materials={"mysteel": {**MAT["mysteel"], "yield_stress": base + sign * h}})
            traces.append(hc.run_config(cfg)["wall_force"].values)
        fd = (traces[0] - traces[1]) / (2 * h)
        live = np.abs(tr.value) > 0.01 * np.abs(tr.value).max()
        assert np.all(tr.value[live] == pytest.approx(hc.run_config(PLASTIC)["wall_force"].values[live], rel=1e-12))
        scale = np.abs(fd[live]).max()
        assert np.abs(tr.jacobian[i][live] - fd[live]).max() < 1e-5 * scale, p
