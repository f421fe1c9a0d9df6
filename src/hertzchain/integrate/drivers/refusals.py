"""Which integrator takes which model: one check per integrator, used both to refuse a model and
to suggest the integrators that would run it, so that a refusal never suggests one that refuses
in turn (an ``rkn4`` refusal on an elastic-plastic model once suggested ``dop853``).

Each check returns why the integrator does not integrate the model (None: it does):

- ``verlet``: every model;
- ``rkn4`` (:mod:`hertzchain.integrate.drivers.rkn`): chains (paper eq. 1, with or without
  precompression, aligned or with beads offset from the axis) with the elastic law, Kuwabara-Kono's
  or the dashpot (and their size-scaled forms: :mod:`hertzchain.integrate.drivers.rkn_damped`), the
  elastic-plastic law and every registry law, with or without per-contact state
  (:mod:`hertzchain.integrate.drivers.rkn_laws`); no protected body nor mass-in-mass beads;
- ``dop853``, ``rk45`` (:mod:`hertzchain.integrate.drivers.reference`, ``scipy.integrate.solve_ivp``):
  every law without a per-contact history, which a right-hand side evaluated at trial points cannot
  carry: not the elastic-plastic law (the largest overlap) nor a registry law with state
  (Hunt-Crossley's approach speed); the power law and a user's law without state run.
"""

from __future__ import annotations

from typing import Callable

from ...errors import ConfigError

__all__ = ["INTEGRATORS", "why_not", "accepted_integrators", "refuse"]

#: The integrators ``run.integrator`` names (besides ``"auto"``, the default, which picks one of them).
INTEGRATORS = ("verlet", "rkn4", "dop853", "rk45")


def _rkn4(system) -> str | None:
    if system.extended:
        return "'rkn4' integrates chains of beads; this model has a protected body or mass-in-mass beads"
    return None


def _scipy(name: str) -> Callable:
    def check(system) -> str | None:
        from ...laws import law_of_code
        from ..core.generated import is_generated
        from ..core.kernels import LAW_ELASTOPLASTIC

        if is_generated(system.law) and law_of_code(system.law).state_size:
            spec = law_of_code(system.law)
            return (f"'{name}' cannot run the contact law {spec.name!r}: it keeps a state per contact, which the scipy "
                    "integrators cannot carry between their trial steps")
        if system.law == LAW_ELASTOPLASTIC:
            return (f"'{name}' cannot run the elastoplastic contact law: it keeps a history per contact (its largest "
                    "overlap), which the scipy integrators cannot carry between their trial steps")
        return None

    return check


_CHECKS: dict[str, Callable] = {"verlet": lambda system: None, "rkn4": _rkn4, "dop853": _scipy("dop853"),
                                "rk45": _scipy("rk45")}


def why_not(integrator: str, system) -> str | None:
    """Why ``integrator`` does not integrate ``system`` (None: it does).

    Parameters
    ----------
    integrator : str
        One of :data:`INTEGRATORS`.
    system : hertzchain.model.System
        The model's arrays.

    Returns
    -------
    str or None
        The reason, in words.
    """
    return _CHECKS[integrator](system)


def accepted_integrators(system) -> list[str]:
    """The integrators that integrate ``system``, in :data:`INTEGRATORS` order (``verlet`` always)."""
    return [name for name in INTEGRATORS if why_not(name, system) is None]


def refuse(integrator: str, system) -> None:
    """Raise a ConfigError naming ``run.integrator`` when ``integrator`` does not integrate ``system``,
    suggesting only the integrators that do.

    Parameters
    ----------
    integrator : str
        One of :data:`INTEGRATORS`.
    system : hertzchain.model.System
        The model's arrays.
    """
    reason = why_not(integrator, system)
    if reason is None:
        return
    # 'auto' (the default, hertzchain.engine_choice) picks one of those that take the model
    others = ["'auto' (the default)"] + [f"'{name}'" for name in accepted_integrators(system) if name != integrator]
    raise ConfigError("run.integrator", f"{reason}: use integrator {' or '.join(others)}")
