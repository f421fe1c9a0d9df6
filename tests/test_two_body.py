"""Head-on impact of two Hertz spheres against the closed form (Johnson, Contact Mechanics, 11.3).

delta_m = (5 mu v^2 / (4 kappa))^(2/5), F_max = kappa delta_m^(3/2), contact time
t_c = 2.94328 delta_m / v, and the spheres separate with their velocities exchanged as in an
elastic collision (momentum and energy conserved).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import hertzchain as hc

T_C_FACTOR = 2 * 1.4716  # 2 * integral_0^1 dx / sqrt(1 - x^(5/2))


def _integral_factor() -> float:
    from scipy.integrate import quad

    return 2 * quad(lambda x: 1 / math.sqrt(1 - x**2.5), 0, 1, limit=200)[0]


def _two_body(striker_d, bead_d, v, striker_mat="AISI52100", bead_mat="AISI52100", dt_sample=1e-9):
    model = hc.Model(hc.Chain.uniform(1, bead_d, bead_mat), hc.Striker(striker_d, v, striker_mat), hc.Wall("none"))
    s = model.system()
    mu = 1 / (1 / s.mass[0] + 1 / s.mass[1])
    kappa = hc.hertz_constant(striker_d / 2, bead_d / 2, striker_mat, bead_mat)
    dm = (5 * mu * v**2 / (4 * kappa)) ** 0.4
    tc = _integral_factor() * dm / v
    ds = hc.simulate(model, 1.6 * tc, hc.Probes(sample_interval=dt_sample, velocities=True))
    return model, ds, kappa, dm, tc


@pytest.mark.parametrize("striker_d,bead_d,v,mats", [
    (26e-3, 26e-3, 0.3, ("AISI52100", "AISI52100")),
    (8e-3, 26e-3, 0.2, ("AISI52100", "AISI52100")),
    (10e-3, 20e-3, 0.005, ("brass", "aluminium")),
])
def test_peak_force_and_contact_time(striker_d, bead_d, v, mats):
    model, ds, kappa, dm, tc = _two_body(striker_d, bead_d, v, *mats)
    f = ds.contact_force.sel(contact=0).values
    assert f.max() == pytest.approx(kappa * dm**1.5, rel=1e-6)
    # Contact time from the samples: exact to one sample interval (1 ns here, t_c ~ 30-100 us).
    t_contact = np.count_nonzero(f > 0) * ds.attrs["sample_interval"]
    assert t_contact == pytest.approx(tc, abs=2 * ds.attrs["sample_interval"])


def test_integral_factor_is_johnsons_constant():
    assert _integral_factor() == pytest.approx(2.9432, abs=1e-4)


def test_velocities_after_elastic_collision():
    model, ds, *_ = _two_body(8e-3, 26e-3, 0.2)
    s = model.system()
    m1, m2, v = s.mass[0], s.mass[1], 0.2
    v_end = ds.velocity.isel(time=-1).values
    assert v_end[0] == pytest.approx((m1 - m2) / (m1 + m2) * v, rel=1e-6)
    assert v_end[1] == pytest.approx(2 * m1 / (m1 + m2) * v, rel=1e-6)
