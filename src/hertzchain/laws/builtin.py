"""The built-in laws as registry entries.

Hertz (paper eq. 1), Kuwabara-Kono and the linear dashpot, their size-scaled forms (``extra``:
``scaled``, and ``size_exponent`` p of Kuwabara-Kono's A_j = A (t_j / t_ref)^p, 1 unless given) and Thornton's
elastic-plastic law run on the hand-written engines (``generated=False``; codes 0..3 are the
kernels' ``LAW_*``); the power law and Hunt-Crossley are written the way a user writes a law
(:mod:`hertzchain.laws.power`, :mod:`hertzchain.laws.hunt_crossley`) and run on the generated
engines. Bounds: those of the config schema (``config.schema.BOUNDS``: A in [0, 1] s, gamma in
[0, 1e9] N s/m). Their classes live in :mod:`hertzchain.contact` and :mod:`hertzchain.plasticity`,
which attach each law's constructor (:func:`~hertzchain.laws.spec.attach_maker`): this package
imports none of the modules above it.
"""

from __future__ import annotations

import numpy as np

from .spec import LawSpec, Param, jit, register_law

_A = Param("A", "s", "Kuwabara-Kono time constant", 0.0, 1.0)
_GAMMA = Param("gamma", "N s/m", "dashpot coefficient", 0.0, 1e9)
_A_PLASTIC = Param("A", "s", "viscous time constant on top of Thornton's contact", 0.0, 1.0, default=0.0)
_P_Y = Param("limiting_pressure_factor", "-", "Thornton's limiting pressure over the yield stress", 0.0, 10.0,
             open_low=True, default=1.5)


@jit
def _hertz(d, rate, k, p, s):
    """Hertz, paper eq. 1: k d^(3/2)."""
    return k * d * np.sqrt(d)


@jit
def _kuwabara_kono(d, rate, k, p, s):
    """k (d^(3/2) + A d^(1/2) rate), p = A [s]."""
    sd = np.sqrt(d)
    return k * (d * sd + p * sd * rate)


@jit
def _dashpot(d, rate, k, p, s):
    """k d^(3/2) + gamma rate, p = gamma [N s/m]."""
    return k * d * np.sqrt(d) + p * rate


@jit
def _keep(d, rate, k, p, s):
    return s


@jit
def _hertz_energy(d, k, p):
    return 0.4 * k * d * d * np.sqrt(d)


@jit
def _hertz_partials(d, rate, k, p, s):
    return 1.5 * k * np.sqrt(d), 0.0, d * np.sqrt(d), 0.0


@jit
def _kk_partials(d, rate, k, p, s):
    sd = np.sqrt(d)
    ddd = 1.5 * k * sd + (0.5 * k * p * rate / sd if d > 0.0 else 0.0)
    return ddd, k * p * sd, d * sd + p * sd * rate, k * sd * rate


@jit
def _dashpot_partials(d, rate, k, p, s):
    return 1.5 * k * np.sqrt(d), p, d * np.sqrt(d), rate


def _builtin(name, title, code, params=(), force=_hertz, partials=_hertz_partials, **kw):
    return register_law(LawSpec(name=name, title=title, params=params, force=force, state=_keep,
                                energy=_hertz_energy, partials=partials, generated=False,
                                code=code, **kw))


ELASTIC = _builtin("elastic", "Hertz, paper eq. 1: F = kappa delta^(3/2)", 0)
VISCOELASTIC = _builtin("viscoelastic", "Kuwabara-Kono: F = kappa (delta^(3/2) + A delta^(1/2) d(delta)/dt)", 1,
                        (_A,), _kuwabara_kono, _kk_partials, dissipative=True, calibrated="A")
DASHPOT = _builtin("dashpot", "Hertz with a linear dashpot: F = kappa delta^(3/2) + gamma d(delta)/dt", 2,
                   (_GAMMA,), _dashpot, _dashpot_partials, dissipative=True, calibrated="gamma")
VISCOELASTIC_SCALED = _builtin("viscoelastic_scaled", "Kuwabara-Kono with A_j following each contact's collision "
                               "time", 1, (_A,), _kuwabara_kono, _kk_partials, dissipative=True, calibrated="A",
                               extra={"scaled": True})
#: A_j = A (t_j / t_ref)^2: the restitution falls with speed as Kuwabara-Kono's (1 - e ~ v^(1/5)) while
#: a light striker's short contact loses less than the chain's (docs/guide/plasticity.rst).
VISCOELASTIC_SIZED = _builtin("viscoelastic_sized", "Kuwabara-Kono with A_j following the square of each contact's "
                              "collision time", 1, (_A,), _kuwabara_kono, _kk_partials, dissipative=True,
                              calibrated="A", extra={"scaled": True, "size_exponent": 2.0})
DASHPOT_SCALED = _builtin("dashpot_scaled", "dashpot with gamma_j ~ kappa_j^(2/5) mu_j^(3/5)", 2, (_GAMMA,),
                          _dashpot, _dashpot_partials, dissipative=True, calibrated="gamma", extra={"scaled": True})
ELASTOPLASTIC = _builtin("elastoplastic", "Thornton (1997) elastic-plastic, optional viscous A", 3,
                         (_A_PLASTIC, _P_Y), dissipative=True, plastic=True, state_size=3)

# the laws written the way a user writes one (imported for their registration)
from . import hunt_crossley, power  # noqa: E402,F401
