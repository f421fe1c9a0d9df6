"""The reproduction's dissipation and the restitution's trend with speed (issue 38 item 6, docs/guide/
plasticity.rst "Restitution that falls with speed"): every law calibrated to the paper's eps =
0.985 on chain 1's first bead and striker, then the striker's restitution on a 26 mm bead at
1e-4 .. 1 m/s.

- Kuwabara-Kono (one A, or A following the collision time) falls with speed as viscoelastic spheres
  do, 1 - e ~ v^(1/5), but gives the striker e < 0.93 at 0.2 m/s;
- the reproduction's ``dashpot_scaled`` keeps the striker's e = 0.958 but rises with speed;
- the catalogue's ``viscoelastic_sized`` (A_j ~ t_j^2, t the pair's collision time scale) does all
  three: eps = 0.985 +- 0.002, e >= 0.93 at 0.2 m/s and 1 - e ~ v^(1/5).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.chain import Chain
from hertzchain.contact import ScaledViscoelastic, SizedViscoelastic
from hertzchain.dissipation import calibrate_law, measure_eps
from hertzchain.laws import get_law
from hertzchain.model import Model

SPEEDS = np.array([1e-4, 1e-2, 0.2, 1.0])
STRIKER = hc.Striker(8e-3, 0.2)


def _striker_e(law) -> np.ndarray:
    return np.array([hc.restitution(v, law, 8e-3, "AISI52100", 26e-3, "AISI52100") for v in SPEEDS])


def _kk_exponent(e: np.ndarray) -> float:
    """d ln(1 - e) / d ln v between 1e-4 and 1e-2 m/s (Kuwabara-Kono: 1/5)."""
    return math.log((1 - e[1]) / (1 - e[0])) / math.log(SPEEDS[1] / SPEEDS[0])


@pytest.mark.parametrize("name", ["viscoelastic", "viscoelastic_scaled"])
def test_kuwabara_kono_falls_with_speed_but_the_striker_bounces_too_little(name):
    e = _striker_e(calibrate_law(name, 0.985, chain=hc.paper_chain("chain1"), striker=STRIKER))
    assert np.all(np.diff(e) < 0)
    assert _kk_exponent(e) == pytest.approx(0.2, abs=0.03)
    assert e[2] < 0.93


def test_the_reproductions_dashpot_rises_with_speed():
    law = calibrate_law("dashpot_scaled", 0.985, chain=hc.paper_chain("chain1"), striker=STRIKER)
    e = _striker_e(law)
    assert np.all(np.diff(e) > 0) and e[2] >= 0.95


def _log_slope(e: np.ndarray) -> float:
    """Least-squares slope of ln(1 - e) against ln v over every speed of SPEEDS."""
    return float(np.polyfit(np.log(SPEEDS), np.log(1 - e), 1)[0])


def test_the_catalogues_sized_law_does_all_three():
    """Calibrated through the registry (``calibrated = "A"``) like the other laws: the chain's eps
    measured back within 0.002 of 0.985, the striker's e >= 0.93 at 0.2 m/s, e falling with speed and
    1 - e growing like v^(1/5): the log-slope fitted over 1e-4 .. 1 m/s within 0.2 +- 0.03 (Kuwabara-
    Kono's quasi-static exponent; it bends down a little at 1 m/s, where 1 - e is no longer small)."""
    spec = get_law("viscoelastic_sized")
    assert spec.calibrated == "A" and spec.dissipative and not spec.generated
    law = calibrate_law("viscoelastic_sized", 0.985, chain=hc.paper_chain("chain1"), striker=STRIKER)
    assert isinstance(law, SizedViscoelastic) and law.diameter == pytest.approx(26e-3)
    assert measure_eps(law, 26e-3, "AISI52100", STRIKER).eps == pytest.approx(0.985, abs=0.002)
    e = _striker_e(law)
    assert np.all(np.diff(e) < 0) and e[2] >= 0.93
    assert _log_slope(e) == pytest.approx(0.2, abs=0.03)
    assert _kk_exponent(e) == pytest.approx(0.2, abs=0.03)


def test_the_sized_laws_A_follows_the_square_of_the_collision_time():
    """A_j = A (t_j / t_ref)^2, t = (mu / kappa)^(2/5): the reference value between two reference
    beads, a quarter of it between beads of half the size (t ~ R), the square of the scaled law's
    ratio everywhere (the wall's pair and the striker's included), and from a config."""
    a = 5e-6
    chain = Chain.from_diameters(np.array([26e-3, 26e-3, 13e-3, 13e-3]), "AISI52100")
    sized = Model(chain, hc.Striker(8e-3, 0.2), hc.Wall("flat"), SizedViscoelastic(a, 26e-3)).system()
    scaled = Model(chain, hc.Striker(8e-3, 0.2), hc.Wall("flat"), ScaledViscoelastic(a, 26e-3)).system()
    assert sized.law == scaled.law == 1  # the Kuwabara-Kono kernel, with a per-contact A
    assert sized.damping[1] == pytest.approx(a, rel=1e-12)
    assert sized.damping[3] == pytest.approx(a / 4, rel=1e-12)
    np.testing.assert_allclose(sized.damping, scaled.damping**2 / a, rtol=1e-12)
    cfg = hc.parse_config({"chain": {"diameters_mm": [26, 26, 13, 13]}, "striker": {"velocity": 0.2},
                           "contact": {"law": "viscoelastic_sized", "A": a}})
    model = hc.build_model(cfg)
    assert isinstance(model.law, SizedViscoelastic)
    assert model.describe()["contact"]["reference_diameter_mm"] == pytest.approx(26.0)
    np.testing.assert_allclose(model.system().damping, sized.damping, rtol=1e-12)


def test_the_gradients_set_up_differentiates_the_sized_law():
    """The sensitivity engines' set-up map reproduces the sized law's A_j (it is checked against
    Model.system()) and its derivatives: dA_j/dA = A_j / A, and by a bead's diameter the central
    difference of Model.system()."""
    from hertzchain.gradients.setup import setup_derivatives

    base = {"chain": {"diameters_mm": [26, 26, 13, 13]}, "striker": {"velocity": 0.2},
            "contact": {"law": "viscoelastic_sized", "A": 5e-6}}

    def damping(d2: float) -> np.ndarray:
        cfg = hc.parse_config({**base, "chain": {"diameters_mm": [26, 26, d2, 13]}})
        return hc.build_model(cfg).system().damping

    cfg = hc.parse_config(base)
    d = setup_derivatives(cfg, hc.build_model(cfg).system(), ["contact.A", "chain.diameters_mm[2]"])
    np.testing.assert_allclose(d.dense("contact.A", "damping"), d.values["damping"] / 5e-6, rtol=1e-12)
    h = 1e-4
    central = (damping(13 + h) - damping(13 - h)) / (2 * h)
    np.testing.assert_allclose(d.dense("chain.diameters_mm[2]", "damping"), central, rtol=1e-6, atol=1e-18)
