"""Hunt-Crossley contact whose damping is set by a coefficient of restitution e.

F = k delta^(3/2) (1 + (3/2) alpha d(delta)/dt), clipped at zero, k the pair's Hertz constant
(paper eq. 1). The damping follows Flores et al. (Mech. Mach. Theory 46, 2011):
(3/2) alpha = 8 (1 - e) / (5 e v_in), derived for every e in (0, 1] (where Lankarani-Nikravesh's
3 (1 - e^2) / (4 v_in) holds only for e near 1). The two-body restitution it gives falls short
of e by at most 0.007 for e >= 0.9, 0.03 for e >= 0.5 and 0.05 for e >= 0.3 (measured with
:func:`hertzchain.restitution`, tests/test_laws.py) and does not depend on the impact speed (the
law is scale-free in delta* = (mu v^2 / k)^(2/5)). v_in, the approach speed at first touch, is
the contact's state: the largest d(delta)/dt since the contact last closed (the approach speed
at touch in a two-body impact, where it only falls while compressed; for contacts that start
touching at rest in a chain, the largest closing speed the pulse brings), 0 when open.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .spec import LawSpec, Param, jit, register_law


def damping_factor(e: float) -> float:
    """chi = 8 (1 - e) / (5 e) [-], so that (3/2) alpha = chi / v_in (Flores et al. 2011)."""
    return 8.0 * (1.0 - e) / (5.0 * e)


@jit
def force(d, rate, k, chi, vin):
    """k d^(3/2) (1 + chi rate / v_in) [N]; the elastic part alone before the state is set.
    chi / v_in is one quotient, the same in the engines' second call at rate 0 (the elastic part
    of the dissipated power), which the compiler then shares: one division a contact, not two."""
    fel = k * d * math.sqrt(d)
    b = chi / vin if vin > 0.0 else 0.0
    return fel + fel * b * rate


@jit
def state(d, rate, k, chi, vin):
    """v_in: the largest closing speed since the contact closed; 0 while open."""
    if d < 0.0:
        return 0.0
    return rate if rate > vin else vin


@jit
def energy(d, k, chi):
    return 0.4 * k * d * d * math.sqrt(d)


@jit
def overlap_at_energy(e, k, chi):
    return (2.5 * e / k) ** 0.4


@jit
def partials(d, rate, k, chi, vin):
    """(dF/d delta, dF/d rate, dF/dk, dF/d chi) at fixed v_in."""
    sd = math.sqrt(d)
    b = chi / vin if vin > 0.0 else 0.0
    return 1.5 * k * sd * (1.0 + b * rate), k * d * sd * b, d * sd * (1.0 + b * rate), \
        (k * d * sd * rate / vin if vin > 0.0 else 0.0)


@jit
def state_partials(d, rate, k, chi, vin):
    """(dF/d v_in at v_in, then d v_in'/d(delta, rate, k, chi, v_in)): v_in' is the rate where it
    exceeds v_in, else v_in (0 while open)."""
    fs = -k * d * math.sqrt(d) * chi * rate / (vin * vin) if vin > 0.0 else 0.0
    if d < 0.0:
        return fs, 0.0, 0.0, 0.0, 0.0, 0.0
    if rate > vin:
        return fs, 0.0, 1.0, 0.0, 0.0, 0.0
    return fs, 0.0, 0.0, 0.0, 0.0, 1.0


@dataclass(frozen=True)
class HuntCrossley:
    """Hunt-Crossley contact whose damping gives a two-body impact the restitution e.

    Parameters
    ----------
    restitution : float
        e [-], in (0, 1] (1: no damping).
    """

    restitution: float
    name = "hunt_crossley"

    def __post_init__(self) -> None:
        object.__setattr__(self, "restitution", SPEC.param("restitution").check(self.restitution))

    @property
    def parameter(self) -> float:
        return damping_factor(self.restitution)


SPEC = register_law(LawSpec(
    name="hunt_crossley", title="Hunt-Crossley, damping set by a restitution e (Flores et al. 2011)",
    force=force, state=state, energy=energy, partials=partials, overlap_at_energy=overlap_at_energy,
    state_partials=state_partials, state_size=1, dissipative=True,
    params=(Param("restitution", "-", "two-body coefficient of restitution e", 0.0, 1.0, open_low=True),),
    make=lambda params, chain=None: HuntCrossley(params["restitution"]), code=5))
