"""Elastic-plastic contacts: Thornton's (1997) law and its closed forms.

Thornton, C. (1997), "Coefficient of restitution for collinear collisions of elastic-perfectly
plastic spheres", J. Appl. Mech. 64, 383-386. Hertz (paper eq. 1) until the largest contact
pressure reaches a limiting value p_y; then the force grows linearly with the overlap; unloading
is Hertzian with an enlarged radius of curvature, down to a residual (permanent) overlap. The
compiled force is :func:`hertzchain.integrate.core.kernels.elastoplastic_force`; the functions here
are the same law in closed form (loading curve, its work and inverse, the unloading curve, the
yield velocity and Thornton's restitution), used to size the time step, by the tests and by
:func:`hertzchain.restitution`'s users. Overlaps [m], forces [N], stiffnesses kappa [N/m^1.5].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .bounds import check_bound
from .contact import ScaledViscoelastic
from .errors import ConfigError
from .laws.spec import attach_maker
from .materials import Material, get_material

__all__ = ["LIMITING_PRESSURE_FACTOR", "limiting_pressure", "thornton_loading_force", "thornton_loading_work",
           "thornton_loading_overlap", "thornton_unloading", "yield_velocity", "thornton_restitution",
           "Elastoplastic"]


#: Thornton's limiting contact pressure p_y in units of the weaker material's yield stress. With
#: p_y = 1.5 sigma_Y the largest Hertz pressure p0 = 3F / (2 pi a^2) reaches p_y exactly when the
#: mean pressure F / (pi a^2) reaches sigma_Y: Thornton's F_y is then the paper's elastic limit
#: F_Y (:func:`yield_force`, paper Sec. II) and ``max_force_over_yield`` keeps its meaning.
#: (Johnson's first yield under a sphere, von Mises with nu = 0.3, is p0 = 1.6 sigma_Y.)
LIMITING_PRESSURE_FACTOR = 1.5


def limiting_pressure(mat1: str | Material, mat2: str | Material | None = None,
                      factor: float = LIMITING_PRESSURE_FACTOR) -> float:
    """Thornton's limiting contact pressure p_y = factor x sigma_Y [Pa].

    Parameters
    ----------
    mat1, mat2 : str or Material
        The two materials (``mat2=None``: the same as ``mat1``); the weaker yield stress
        sigma_Y [Pa] sets p_y.
    factor : float
        p_y / sigma_Y (default LIMITING_PRESSURE_FACTOR = 1.5: yield starts at the paper's F_Y).

    Returns
    -------
    float
        p_y [Pa]; inf when neither material has a yield stress (the contact stays elastic).
    """
    m1, m2 = get_material(mat1), get_material(mat1 if mat2 is None else mat2)
    stresses = [s for s in (m1.yield_stress, m2.yield_stress) if s is not None]
    return factor * min(stresses) if stresses else math.inf


def thornton_loading_force(delta, kappa, delta_y):
    """Force [N] on Thornton's loading curve at overlap ``delta`` [m] (Thornton 1997).

    Hertz, F = kappa delta^(3/2), up to the yield overlap delta_y, then the straight line
    F = F_y + (3/2) kappa delta_y^(1/2) (delta - delta_y), with F_y = kappa delta_y^(3/2): the
    slope (3/2) kappa delta_y^(1/2) = pi p_y R* continues Hertz's tangent at delta_y.

    Parameters
    ----------
    delta : float or numpy.ndarray
        Overlap [m] (>= 0).
    kappa : float or numpy.ndarray
        Hertz constant (4/3) E* sqrt(R*) [N/m^1.5] (paper eq. 1).
    delta_y : float or numpy.ndarray
        Yield overlap (pi p_y / (2 E*))^2 R* [m] (inf: always elastic).

    Returns
    -------
    float or numpy.ndarray
        The force [N].
    """
    import numpy as np

    d = np.maximum(np.asarray(delta, dtype=float), 0.0)
    dy = np.asarray(delta_y, dtype=float)
    with np.errstate(invalid="ignore"):
        plastic = kappa * dy * np.sqrt(dy) + 1.5 * kappa * np.sqrt(dy) * (d - dy)
    out = np.where(d <= dy, kappa * d * np.sqrt(d), plastic)
    return float(out) if out.ndim == 0 else out


def thornton_loading_work(delta, kappa, delta_y):
    """Work [J] done along Thornton's loading curve from 0 to overlap ``delta`` [m].

    (2/5) kappa delta^(5/2) below delta_y; above it (2/5) F_y delta_y + F_y (delta - delta_y)
    + (3/4) kappa delta_y^(1/2) (delta - delta_y)^2.

    Parameters
    ----------
    delta, kappa, delta_y : float or numpy.ndarray
        As :func:`thornton_loading_force`.

    Returns
    -------
    float or numpy.ndarray
        The work [J].
    """
    import numpy as np

    d = np.maximum(np.asarray(delta, dtype=float), 0.0)
    dy = np.asarray(delta_y, dtype=float)
    with np.errstate(invalid="ignore"):
        fy = kappa * dy * np.sqrt(dy)
        x = d - dy
        plastic = 0.4 * fy * dy + fy * x + 0.75 * kappa * np.sqrt(dy) * x * x
    out = np.where(d <= dy, 0.4 * kappa * d * d * np.sqrt(d), plastic)
    return float(out) if out.ndim == 0 else out


def thornton_loading_overlap(work, kappa, delta_y):
    """Overlap [m] at which the work along Thornton's loading curve reaches ``work`` [J]
    (the inverse of :func:`thornton_loading_work`).

    Parameters
    ----------
    work : float or numpy.ndarray
        Work [J] (>= 0).
    kappa, delta_y : float or numpy.ndarray
        As :func:`thornton_loading_force`.

    Returns
    -------
    float or numpy.ndarray
        The overlap [m].
    """
    import numpy as np

    w = np.maximum(np.asarray(work, dtype=float), 0.0)
    kap = np.asarray(kappa, dtype=float)
    dy = np.asarray(delta_y, dtype=float)
    safe = np.where(kap > 0, kap, 1.0)
    with np.errstate(invalid="ignore", over="ignore"):
        fy = safe * dy * np.sqrt(dy)
        wy = 0.4 * fy * dy
        slope = 1.5 * safe * np.sqrt(dy)
        x = 2.0 * (w - wy) / (fy + np.sqrt(fy * fy + 2.0 * slope * (w - wy)))  # root of fy x + slope x^2 / 2
        out = np.where(w <= wy, (2.5 * w / safe) ** 0.4, dy + x)
    out = np.where(kap > 0, out, 0.0)
    return float(out) if out.ndim == 0 else out


def thornton_unloading(delta_max, kappa, delta_y):
    """Unloading curve after loading to ``delta_max`` [m]: (residual overlap delta_p [m],
    unloading stiffness kappa_p [N/m^1.5]), F = kappa_p (delta - delta_p)^(3/2).

    Thornton (1997): Hertz with the enlarged radius of curvature
    R_p = (4 E* / (3 F_max)) ((2 F_max + F_y) / (2 pi p_y))^(3/2), i.e. kappa_p = (4/3) E* sqrt(R_p)
    = kappa sqrt(R_p / R*), through (delta_max, F_max):
    delta_p = delta_max - (F_max / kappa_p)^(2/3). The contact radius at F_max is
    a_p^2 = (2 F_max + F_y) / (2 pi p_y) = R* delta_max, so the unloading stiffness at delta_max,
    2 E* a_p, equals Hertz's (3/2) kappa delta_max^(1/2): delta_max - delta_p =
    F_max / (kappa delta_max^(1/2)), and kappa_p = kappa (delta_max / (delta_max - delta_p))^(1/2).
    Below delta_y the contact is elastic: (0, kappa).

    Parameters
    ----------
    delta_max : float or numpy.ndarray
        Largest overlap reached [m].
    kappa, delta_y : float or numpy.ndarray
        As :func:`thornton_loading_force`.

    Returns
    -------
    tuple
        (delta_p [m], kappa_p [N/m^1.5]).
    """
    import numpy as np

    dm = np.asarray(delta_max, dtype=float)
    fmax = thornton_loading_force(dm, kappa, delta_y)
    with np.errstate(invalid="ignore", divide="ignore"):
        x = fmax / (kappa * np.sqrt(dm))
        dp = np.where(dm > delta_y, dm - x, 0.0)
        kp = np.where(dm > delta_y, kappa * np.sqrt(dm / x), kappa)
    if dp.ndim == 0:
        return float(dp), float(kp)
    return dp, kp


def yield_velocity(kappa: float, delta_y: float, mu: float) -> float:
    """Relative impact speed v_y [m/s] below which a two-body collision stays elastic.

    The kinetic energy mu v_y^2 / 2 equals the Hertz energy (2/5) F_y delta_y stored up to the
    yield overlap, so v_y = (4 F_y delta_y / (5 mu))^(1/2). For a sphere of radius R, density
    rho on a rigid flat (R* = R, mu = m) this is Thornton's (1997)
    v_y = 1.56 (p_y^5 / (E*^4 rho))^(1/2); two equal spheres (R* = R/2, mu = m/2) meet at half
    that relative speed.

    Parameters
    ----------
    kappa : float
        Hertz constant [N/m^1.5].
    delta_y : float
        Yield overlap [m].
    mu : float
        Reduced mass [kg] (the sphere's mass against an immovable flat).

    Returns
    -------
    float
        v_y [m/s] (inf for a contact that never yields).
    """
    if not math.isfinite(delta_y):
        return math.inf
    return math.sqrt(0.8 * kappa * delta_y**2.5 / mu)


def thornton_restitution(velocity, v_y):
    """Thornton's (1997) closed-form coefficient of restitution of his elastic-plastic
    contact at relative impact speed ``velocity`` [m/s].

    e = 1 for v <= v_y; above, with x = v_y / v,
    e = (6 sqrt(3) / 5)^(1/2) (1 - x^2 / 6)^(1/2) (x / (x + 2 (6/5 - x^2 / 5)^(1/2)))^(1/4),
    which falls as v^(-1/4) at high speed. It is the exact energy balance of the law: rebound
    energy (2/5) F_max (delta_max - delta_p) over impact energy.

    Parameters
    ----------
    velocity : float or numpy.ndarray
        Relative impact speed [m/s] (> 0).
    v_y : float
        Yield velocity [m/s] (:func:`yield_velocity`).

    Returns
    -------
    float or numpy.ndarray
        e [-].
    """
    import numpy as np

    v = np.asarray(velocity, dtype=float)
    x = np.minimum(v_y / v, 1.0)
    e = (np.sqrt(6.0 * math.sqrt(3.0) / 5.0) * np.sqrt(1.0 - x * x / 6.0)
         * (x / (x + 2.0 * np.sqrt(1.2 - 0.2 * x * x))) ** 0.25)
    out = np.where(v <= v_y, 1.0, e)
    return float(out) if out.ndim == 0 else out


@dataclass(frozen=True)
class Elastoplastic:
    """Thornton's (1997) elastic-perfectly-plastic contact, optionally with Kuwabara-Kono damping.

    Loading: Hertz (paper eq. 1) until the largest contact pressure reaches the limiting pressure
    p_y (:func:`limiting_pressure`: 1.5 sigma_Y of the weaker material, so that yield starts at
    the paper's F_Y), then the straight line F = F_y + pi p_y R* (delta - delta_y). Unloading and
    reloading: Hertz with the enlarged radius of curvature R_p, F = kappa_p (delta - delta_p)^(3/2),
    down to the residual (permanent) overlap delta_p (:func:`thornton_unloading`). Every contact
    keeps its largest overlap over the whole run, so a pair that separates and meets again
    reloads on its unloading curve. The energy lost, the plastic work, is the work along the
    loading curve minus what the unloading curve gives back.

    With ``A`` > 0 a viscous force A kappa_p (delta - delta_p)^(1/2) d(delta)/dt is added (the
    Kuwabara-Kono term of :class:`Viscoelastic`, with the contact's present elastic stiffness: it
    equals kappa A delta^(1/2) d(delta)/dt while loading and vanishes when the surfaces part);
    the sum is clipped at zero (never attractive). With ``diameter`` the time constant is scaled
    per contact as in :class:`ScaledViscoelastic` (A_j = A t_j / t_ref).

    ``limiting_pressure_factor`` sets p_y = factor x sigma_Y. The default 1.5 makes Thornton's
    onset of yield the paper's F_Y; about 3 (the fully plastic mean pressure of an indentation,
    Tabor's hardness ~ 2.8-3 sigma_Y) stiffens the plastic branch towards what work-hardened metal
    balls show at speeds far above v_y (see the user guide's plasticity page). F_Y, and with it
    ``max_force_over_yield``, stays the paper's elastic limit whatever the factor.

    Parameters
    ----------
    A : float
        Viscous time constant [s] (0: plastic dissipation only).
    diameter : float or None
        Reference bead diameter [m] of a size-scaled A (None: the same A at every contact).
    material : Material or str
        Reference bead material of a size-scaled A.
    limiting_pressure_factor : float
        p_y over the weaker material's yield stress sigma_Y [-] (default LIMITING_PRESSURE_FACTOR).
    """

    A: float = 0.0
    diameter: float | None = None
    material: Material | str = "AISI52100"
    limiting_pressure_factor: float = LIMITING_PRESSURE_FACTOR
    name = "elastoplastic"

    def __post_init__(self) -> None:
        if not (isinstance(self.A, (int, float)) and math.isfinite(self.A) and self.A >= 0):
            raise ConfigError("contact.A", f"must be a finite number >= 0 (s), got {self.A!r}")
        if self.diameter is not None and not (math.isfinite(self.diameter) and self.diameter > 0):
            raise ConfigError("contact.diameter", f"must be a positive reference diameter (m), got {self.diameter!r}")
        check_bound(self.limiting_pressure_factor, "limiting_pressure_factor", "contact.limiting_pressure_factor",
                    "(p_y / sigma_Y)")
        object.__setattr__(self, "material", get_material(self.material))

    @property
    def parameter(self) -> float:
        return self.A

    @property
    def pressure_ratio(self) -> float:
        """p_y over the paper-consistent 1.5 sigma_Y: F_y = F_Y ratio^3, delta_y = delta_Y ratio^2."""
        return self.limiting_pressure_factor / LIMITING_PRESSURE_FACTOR

    def contact_damping(self, mu, kappa):
        """Per-contact viscous time constants A_j [s] (see :meth:`ScaledViscoelastic.contact_damping`).

        Parameters
        ----------
        mu : numpy.ndarray
            Reduced mass of every contact [kg].
        kappa : numpy.ndarray
            Hertz constant of every contact [N/m^1.5]; 0 where there is no contact.

        Returns
        -------
        numpy.ndarray
            A_j [s]: A everywhere (or scaled with the collision time when ``diameter`` is set),
            0 where kappa = 0.
        """
        import numpy as np

        kappa = np.asarray(kappa, dtype=float)
        if self.diameter is None:
            return np.where(kappa > 0, float(self.A), 0.0)
        return ScaledViscoelastic(self.A, self.diameter, self.material).contact_damping(mu, kappa)


# the registry's constructor of this law (hertzchain.laws declares its parameters)
attach_maker("elastoplastic", lambda params, chain=None: Elastoplastic(
    params["A"] or 0.0, limiting_pressure_factor=params["limiting_pressure_factor"] or 1.5))
