"""hertzchain.restitution: two-body collisions of any law, against closed forms and scaling laws."""

from __future__ import annotations

import math

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.contact import collision_time_scale, hertz_constant
from hertzchain.errors import ConfigError
from hertzchain.plasticity import thornton_restitution, yield_velocity

STEEL = hc.get_material("AISI52100")


def _mass(d, mat=STEEL):
    return mat.density * math.pi * d**3 / 6


def test_the_contract_signature_and_hertz():
    assert hc.restitution(0.2, "elastic", 8e-3, "AISI52100", 26e-3) == pytest.approx(1.0, abs=1e-6)
    assert hc.restitution(0.2, hc.Elastic(), 8e-3, "AISI52100") == pytest.approx(1.0, abs=1e-6)  # on a flat
    assert hc.restitution(velocity=0.3, law="elastoplastic", diameter_a=8e-3, material_a="brass", diameter_b=None,
                          material_b="AISI52100") < 1.0


@pytest.mark.parametrize("diameter_b,material_b", [(26e-3, "AISI52100"), (None, "AISI52100"), (20e-3, "brass"),
                                                    (None, "aluminium")])
def test_thornton_on_spheres_and_flats(diameter_b, material_b):
    """Above the pair's yield velocity (reduced mass, weaker material, flat: R' = inf, mu = m_a)
    the simulated e is Thornton's closed form."""
    da = 8e-3
    mb = hc.get_material(material_b)
    ra, rb = da / 2, (None if diameter_b is None else diameter_b / 2)
    kappa = hertz_constant(ra, rb, STEEL, mb)
    fy = hc.yield_force(ra, rb, STEEL, mb)[0]
    dy = (fy / kappa) ** (2 / 3)
    mu = _mass(da) if diameter_b is None else 1 / (1 / _mass(da) + 1 / _mass(diameter_b, mb))
    v_y = yield_velocity(kappa, dy, mu)
    for ratio in (0.5, 3.0, 12.0):
        e = hc.restitution(ratio * v_y, "elastoplastic", da, STEEL, diameter_b, material_b)
        assert e == pytest.approx(thornton_restitution(ratio * v_y, v_y), rel=1e-5, abs=1e-6)


def test_kuwabara_kono_depends_on_a_over_the_collision_time():
    """In collision units the Kuwabara-Kono restitution depends on A / t* only, t* = (mu/kappa)^(2/5)
    v^(-1/5): two pairs with the same A / t* bounce alike, and 1 - e grows as v^(1/5) for weak damping."""
    law = hc.Viscoelastic(2e-6)
    e1 = hc.restitution(0.2, law, 8e-3, "AISI52100", 26e-3)
    mu1 = 1 / (1 / _mass(8e-3) + 1 / _mass(26e-3))
    t1 = collision_time_scale(mu1, hertz_constant(4e-3, 13e-3, STEEL, STEEL)) * 0.2 ** -0.2
    mu2 = _mass(20e-3) / 2
    t2 = collision_time_scale(mu2, hertz_constant(10e-3, 10e-3, STEEL, STEEL)) * 0.2 ** -0.2
    e2 = hc.restitution(0.2, hc.Viscoelastic(2e-6 * t2 / t1), 20e-3, "AISI52100", 20e-3)
    assert e2 == pytest.approx(e1, rel=1e-6)
    weak = hc.Viscoelastic(2e-8)
    loss = [1 - hc.restitution(v, weak, 8e-3, "AISI52100", 26e-3) for v in (0.05, 1.6)]
    assert math.log(loss[1] / loss[0]) / math.log(32) == pytest.approx(0.2, abs=0.01)


def test_scaled_dashpot_gives_every_pair_the_same_bounce_rising_with_speed():
    law = hc.ScaledDashpot(25.0, 26e-3)
    pairs = [(8e-3, "AISI52100", 26e-3, "AISI52100"), (26e-3, "AISI52100", 26e-3, "AISI52100"),
             (11e-3, "AISI52100", None, "AISI52100"), (12e-3, "brass", 9e-3, "brass")]
    e = [hc.restitution(0.2, law, *p) for p in pairs]
    assert np.allclose(e, e[0], rtol=1e-6)
    # weak damping: 1 - e ~ G ~ v^(-1/5)
    weak = hc.ScaledDashpot(0.1, 26e-3)
    loss = [1 - hc.restitution(v, weak, 8e-3, "AISI52100", 26e-3) for v in (0.05, 1.6)]
    assert math.log(loss[1] / loss[0]) / math.log(32) == pytest.approx(-0.2, abs=0.01)
    # with the reference beads it is the plain dashpot
    assert hc.restitution(0.2, law, 26e-3, "AISI52100", 26e-3) == hc.restitution(0.2, hc.Dashpot(25.0), 26e-3,
                                                                                  "AISI52100", 26e-3)


def test_bad_inputs_name_the_field():
    with pytest.raises(ConfigError, match="velocity"):
        hc.restitution(-1.0, "elastic", 8e-3, "AISI52100")
    with pytest.raises(ConfigError, match="diameter_a"):
        hc.restitution(0.2, "elastic", 0.0, "AISI52100")
    with pytest.raises(ConfigError, match="diameter_b"):
        hc.restitution(0.2, "elastic", 8e-3, "AISI52100", float("nan"))
    with pytest.raises(ConfigError, match="needs its parameter"):
        hc.restitution(0.2, "viscoelastic", 8e-3, "AISI52100")
    with pytest.raises(ConfigError, match="unknown contact law"):
        hc.restitution(0.2, "plastic", 8e-3, "AISI52100")
    with pytest.raises(ConfigError, match="material"):
        hc.restitution(0.2, "elastic", 8e-3, "unobtainium")
