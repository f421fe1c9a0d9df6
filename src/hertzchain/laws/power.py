"""The power law F = k delta^n (cones, o-rings, non-Hertz contacts), written as a user writes a law.
Without a stiffness, k is the pair's Hertz constant (paper eq. 1) and n = 3/2 is the elastic law,
with its arithmetic (k delta sqrt(delta)): the runs agree to rounding."""

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from .spec import LawSpec, Param, jit, register_law


@jit
def force(d, rate, k, n, s):
    """F = k d^n [N] at overlap d >= 0 [m]."""
    return k * d * math.sqrt(d) if n == 1.5 else k * d**n


state = jit(lambda d, rate, k, n, s: s)  # no per-contact state


@jit
def energy(d, k, n):
    """Stored energy k d^(n+1) / (n+1) [J]."""
    return 0.4 * k * d * d * math.sqrt(d) if n == 1.5 else k * d ** (n + 1.0) / (n + 1.0)


@jit
def overlap_at_energy(e, k, n):
    """The overlap [m] storing the energy e [J]: ((n+1) e / k)^(1/(n+1))."""
    return (2.5 * e / k) ** 0.4 if n == 1.5 else ((n + 1.0) * e / k) ** (1.0 / (n + 1.0))


@jit
def partials(d, rate, k, n, s):
    """(dF/d delta, dF/d rate, dF/dk, dF/dn)."""
    if d <= 0.0:
        return (k if n == 1.0 else 0.0), 0.0, 0.0, 0.0
    dn = d * math.sqrt(d) if n == 1.5 else d**n
    return (1.5 * k * math.sqrt(d) if n == 1.5 else n * k * dn / d), 0.0, dn, k * dn * math.log(d)


@dataclass(frozen=True)
class PowerLaw:
    """F = k delta^n for delta > 0, else 0 (never attractive).

    Parameters
    ----------
    exponent : float
        n [-], > 1 (1, a linear spring, only with ``stiffness``).
    stiffness : float, optional
        k [N/m^n]; None: each pair's Hertz constant (paper eq. 1).
    """

    exponent: float
    stiffness: float | None = None
    name = "power"

    def __post_init__(self) -> None:
        for p in SPEC.params:
            object.__setattr__(self, p.name, p.check(getattr(self, p.name)))
        if self.exponent == 1.0 and self.stiffness is None:
            raise ConfigError("contact.exponent", "n = 1 (a linear spring) needs an explicit contact.stiffness (N/m)")

    @property
    def parameter(self) -> float:
        return self.exponent

    def contact_stiffness(self, kappa):
        """k of every contact: the stiffness given, or Hertz's kappa_j; 0 where there is no contact."""
        return kappa if self.stiffness is None else np.where(kappa > 0, self.stiffness, 0.0)


SPEC = register_law(LawSpec(
    name="power", title="power law F = k delta^n", force=force, state=state, energy=energy, partials=partials,
    overlap_at_energy=overlap_at_energy, exponent=None, constant_parameters=(1.5, 2.0), hertz_parameter=1.5, code=4, make=lambda p, chain=None: PowerLaw(**p),
    params=(Param("exponent", "-", "n, the power of the overlap", 1.0, 10.0),
            Param("stiffness", "N/m^n", "k (default: the pair's Hertz constant)", 0.0, 1e30, open_low=True,
                  optional=True))))
