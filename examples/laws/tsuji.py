"""A user's contact law: Tsuji et al.'s damped Hertz contact (Powder Technol. 71, 1992).

F = kappa delta^(3/2) + eta delta^(1/4) d(delta)/dt, clipped at zero (the engines clip every
law), kappa the pair's Hertz constant (paper eq. 1), eta [N s / m^(5/4)] the law's parameter. In
the units of a two-body impact (delta* = (mu v^2 / kappa)^(2/5), t* = delta* / v) the damping
term is eta / sqrt(kappa mu) times the elastic one whatever the speed: the restitution depends
on the pair, not on the impact speed. Use it with

    hertzchain run mychain.toml --laws examples/laws/tsuji.py

and ``[contact] law = "tsuji"``, ``parameters = {eta = 300.0}``; in Python, import or run this
file once (``runpy.run_path``), then ``hertzchain.Model(..., law=Tsuji(300.0))``.
"""

import math
from dataclasses import dataclass

from numba import njit

import hertzchain as hc


@njit
def force(d, rate, k, eta, s):
    """kappa d^(3/2) + eta d^(1/4) rate [N]."""
    return k * d * math.sqrt(d) + eta * math.sqrt(math.sqrt(d)) * rate


@njit
def state(d, rate, k, eta, s):
    return s  # no per-contact state


@njit
def energy(d, k, eta):
    """The elastic part's stored energy (2/5) kappa d^(5/2) [J]."""
    return 0.4 * k * d * d * math.sqrt(d)


@njit
def partials(d, rate, k, eta, s):
    """(dF/d delta, dF/d rate, dF/d kappa, dF/d eta)."""
    q = math.sqrt(math.sqrt(d))
    ddd = 1.5 * k * math.sqrt(d) + (0.25 * eta * rate * q / d if d > 0.0 else 0.0)
    return ddd, eta * q, d * math.sqrt(d), q * rate


@dataclass(frozen=True)
class Tsuji:
    """Tsuji's damped Hertz contact with coefficient ``eta`` [N s / m^(5/4)]."""

    eta: float
    name = "tsuji"

    def __post_init__(self):
        object.__setattr__(self, "eta", SPEC.param("eta").check(self.eta))

    @property
    def parameter(self) -> float:  # the per-contact number the engines pass as p
        return self.eta


SPEC = hc.register_law(hc.LawSpec(
    name="tsuji", title="Tsuji et al. (1992): kappa delta^(3/2) + eta delta^(1/4) d(delta)/dt",
    force=force, state=state, energy=energy, partials=partials, dissipative=True,
    params=(hc.Param("eta", "N s/m^(5/4)", "damping coefficient", 0.0, 1e9),),
    make=lambda params, chain=None: Tsuji(params["eta"])), replace=True)
