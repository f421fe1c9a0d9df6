"""Sensitivities of a registry law (hertzchain.laws: the power law, Hunt-Crossley) against a
protected body: the derivative engines generated from the law's declarations step the body's
mount (its spring and dashpot, in parallel with the law on the last contact) as the generated run
does, and differentiate it by the mount's own parameters too. Checked against central finite
differences of whole runs at a fixed small step, and the tangent model against the adjoint (two
differentiations of the same steps: equal to rounding)."""

from __future__ import annotations

import pytest

import hertzchain as hc
from hertzchain.errors import ConfigError
from hertzchain.gradients import sensitivity

from test_gradients import BASE, _with, assert_matches

BODY = {"type": "body", "mass": 0.05, "stiffness": 2e5, "damping": 5.0}
LAWS = {"hunt_crossley": {"law": "hunt_crossley", "restitution": 0.8},
        "power": {"law": "power", "exponent": 1.8, "stiffness": 6e11}}


@pytest.mark.parametrize("law", ["hunt_crossley", pytest.param("power", marks=pytest.mark.slow)])
def test_registry_law_with_a_protected_body(law):
    cfg = _with(BASE, contact=LAWS[law], wall=BODY)
    paths = ["striker.velocity", "wall.mass", "chain.diameters_mm[4]", "wall.damping"]
    own = ["contact.restitution"] if law == "hunt_crossley" else ["contact.exponent"]
    a = sensitivity(cfg, paths + own + ["wall.stiffness"], mode="adjoint")
    t = sensitivity(cfg, paths + own + ["wall.stiffness"], mode="tangent")
    assert a.value == hc.run_config(cfg).attrs["peak_wall_force"]  # the taped run is the engine's, bit for bit
    for p in a.gradient:
        assert t.gradient[p] == pytest.approx(a.gradient[p], rel=1e-10), p
    assert_matches(a, cfg, paths + own, tol=1e-5)
    assert_matches(a, cfg, ["wall.stiffness"], rel=1e-4, tol=1e-5)  # small: a larger step keeps it above rounding


def test_mass_in_mass_refusal_names_the_field():
    cfg = _with(BASE, contact=LAWS["hunt_crossley"],
                elements={"res": {"shape": "sphere", "resonator": {"mass_fraction": 0.2, "frequency": 5000.0}}},
                chain={"elements": ["res"] * 8})
    with pytest.raises(ConfigError, match="chain.elements"):
        sensitivity(cfg, ["striker.velocity"])
