"""Sensitivities with the engine's extension: mass-in-mass beads (an internal mass on a spring
inside a bead) and a protected body's mount, for the built-in laws and the registry laws
(hertzchain.laws: Hunt-Crossley, the power law). The derivative engines step the internal masses
and the mount as ``extension.step_extended`` does (the taped value is the engine's, bit for bit),
and differentiate by the internal springs and masses too (a bead's size and density move them, and so
do the element's own ``resonator.mass_fraction`` and ``frequency``, variables of their own).
Checked against central finite differences of whole runs at a fixed small step, and the tangent
model against the adjoint (two differentiations of the same steps: equal to rounding)."""

from __future__ import annotations

import pytest

import hertzchain as hc
from hertzchain.gradients import sensitivity

from test_gradients import BASE, _with, assert_matches

BODY = {"type": "body", "mass": 0.05, "stiffness": 2e5, "damping": 5.0}
LAWS = {"hunt_crossley": {"law": "hunt_crossley", "restitution": 0.8},
        "power": {"law": "power", "exponent": 1.8, "stiffness": 6e11},
        "viscoelastic": {"law": "viscoelastic", "A": 1e-6},
        "elastoplastic": {"law": "elastoplastic", "A": 1e-6}}
# beads 3 and 5 mass-in-mass: 30 % of their mass inside, at 20 kHz (its period ~ the contact time)
MIM = {"elements": {"mim": {"resonator": {"mass_fraction": 0.3, "frequency": 20000.0}}},
       "chain": {"elements": ["sphere", "sphere", "mim", "sphere", "mim", "sphere", "sphere", "sphere"]}}
SOFT = {"mysteel": {"density": 7800.0, "young": 2.0e11, "poisson": 0.3, "yield_stress": 2e8}}  # it yields


def _config(law: str, inner: bool, body: bool) -> dict:
    cfg = _with(BASE, contact=LAWS[law], **({"wall": BODY} if body else {}))
    if inner:
        cfg = _with(cfg, **MIM)
    return _with(cfg, materials=SOFT) if law == "elastoplastic" else cfg


@pytest.mark.parametrize("law, inner, body", [
    ("viscoelastic", True, True),
    ("hunt_crossley", True, True),
    pytest.param("power", False, True, marks=pytest.mark.slow),
    pytest.param("hunt_crossley", True, False, marks=pytest.mark.slow),
    pytest.param("elastoplastic", True, False, marks=pytest.mark.slow)])
def test_extension_gradients_match_differences(law, inner, body):
    cfg = _config(law, inner, body)
    paths = ["striker.velocity", "chain.diameters_mm[2]", "materials.mysteel.density"] + \
        (["elements.mim.resonator.frequency", "elements.mim.resonator.mass_fraction"] if inner else []) + \
        (["wall.mass"] if body else []) + \
        (["contact.restitution"] if law == "hunt_crossley" else ["contact.exponent"] if law == "power" else [])
    extra = ["wall.stiffness", "wall.damping"] if body else []
    a = sensitivity(cfg, paths + extra, mode="adjoint")
    t = sensitivity(cfg, paths + extra, mode="tangent")
    assert a.value == hc.run_config(cfg).attrs["peak_wall_force"]  # the taped run is the engine's, bit for bit
    for p in a.gradient:
        assert t.gradient[p] == pytest.approx(a.gradient[p], rel=1e-10), p
    assert_matches(a, cfg, paths, tol=1e-5)
    # the mount's spring and dashpot move the peak little (~1e-4 relative for the whole of either):
    # a larger step keeps the difference above rounding
    assert_matches(a, cfg, extra, rel=1e-4, tol=1e-5)

