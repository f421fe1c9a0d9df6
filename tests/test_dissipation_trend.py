"""The measured trade-off behind the reproduction's dissipation (issue 38 item 6, docs/guide/
plasticity.rst "Restitution that falls with speed"): every law calibrated to the paper's eps =
0.985 on chain 1's first bead and striker, then the striker's restitution on a 26 mm bead at
1e-4 .. 1 m/s.

- Kuwabara-Kono (one A, or A following the collision time) falls with speed as viscoelastic spheres
  do, 1 - e ~ v^(1/5), but gives the striker e < 0.93 at 0.2 m/s;
- the reproduction's ``dashpot_scaled`` keeps the striker's e = 0.958 but rises with speed;
- only a size dependence stronger than the collision time's (A ~ t^2, not a catalogue law) does all
  three, with no measurement of the paper behind it.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.optimize import brentq

import hertzchain as hc
from hertzchain.contact import ScaledViscoelastic, collision_time_scale
from hertzchain.dissipation import calibrate_law, measure_eps

SPEEDS = np.array([1e-4, 1e-2, 0.2, 1.0])
STRIKER = hc.Striker(8e-3, 0.2)


@dataclasses.dataclass(frozen=True)
class _PowerScaled(ScaledViscoelastic):
    """Kuwabara-Kono with A_j = A (t_j / t_ref)^p (p = 1: ScaledViscoelastic), for this comparison."""

    p: float = 1.0

    def contact_damping(self, mu, kappa):
        kappa = np.asarray(kappa, float)
        safe = np.where(kappa > 0, kappa, 1.0)
        scale = collision_time_scale(mu, safe) / self.reference_time_scale()
        return np.where(kappa > 0, self.A * scale**self.p, 0.0)


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


def test_a_size_law_stronger_than_the_collision_time_does_all_three():
    def eps_error(log_a: float, p: float) -> float:
        return measure_eps(_PowerScaled(math.exp(log_a), 26e-3, "AISI52100", p=p), 26e-3, "AISI52100", STRIKER).eps - 0.985

    law = _PowerScaled(math.exp(brentq(eps_error, math.log(1e-7), math.log(1e-4), args=(2.0,), xtol=1e-4)),
                       26e-3, "AISI52100", p=2.0)
    assert measure_eps(law, 26e-3, "AISI52100", STRIKER).eps == pytest.approx(0.985, abs=0.002)
    e = _striker_e(law)
    assert np.all(np.diff(e) < 0) and _kk_exponent(e) == pytest.approx(0.2, abs=0.03)
    assert e[2] >= 0.93
