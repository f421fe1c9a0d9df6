"""Contact laws between two bodies: Hertz elastic force (paper eq. 1) and dissipative variants.

Geometry helpers here are plain Python (used to build a model and by :mod:`hertzchain.theory`);
the compiled force evaluations live in :mod:`hertzchain.integrate.kernels`.

Conventions (docs/conventions.rst): overlap delta > 0 in compression, force
F = kappa * delta^(3/2) for delta > 0 and 0 otherwise (never attractive), with
1/kappa = (theta + theta') * sqrt(1/R + 1/R'), theta = 3 (1 - nu^2) / (4 Y), 1/R' = 0 for a flat.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .errors import ConfigError
from .materials import Material, get_material

__all__ = [
    "hertz_constant", "effective_radius", "effective_modulus", "yield_force", "Elastic",
    "Viscoelastic", "ScaledViscoelastic", "Dashpot", "Elastoplastic", "ContactLaw", "LAW_CODES",
    "LIMITING_PRESSURE_FACTOR", "limiting_pressure", "thornton_loading_force", "thornton_loading_overlap",
    "thornton_loading_work", "thornton_unloading", "thornton_restitution", "yield_velocity",
]


def effective_radius(radius1: float, radius2: float | None) -> float:
    """Reduced radius R* = 1 / (1/R + 1/R') [m]; ``radius2=None`` (or inf) is a flat."""
    inv = 1.0 / radius1 + (0.0 if radius2 is None or math.isinf(radius2) else 1.0 / radius2)
    return 1.0 / inv


def effective_modulus(mat1: str | Material, mat2: str | Material) -> float:
    """Contact modulus E* with 1/E* = (1-nu^2)/Y + (1-nu'^2)/Y' [Pa] (so that E* = 3/(4(theta+theta')))."""
    m1, m2 = get_material(mat1), get_material(mat2)
    return 0.75 / (m1.theta + m2.theta)


def hertz_constant(radius1: float, radius2: float | None, mat1: str | Material, mat2: str | Material) -> float:
    """Hertz stiffness kappa [N/m^1.5] of paper eq. 1: 1/kappa = (theta + theta') sqrt(1/R + 1/R').

    Parameters
    ----------
    radius1, radius2 : float
        Radii of curvature [m] of the two bodies; ``radius2=None`` is a flat (wall cap).
    mat1, mat2 : str or Material
        Materials (catalogue names or :class:`Material`; Young's modulus [Pa], Poisson ratio [-]).

    Returns
    -------
    float
        kappa [N/m^1.5], so that F = kappa delta^(3/2) with the overlap delta [m].
    """
    m1, m2 = get_material(mat1), get_material(mat2)
    inv_r = 1.0 / radius1 + (0.0 if radius2 is None or math.isinf(radius2) else 1.0 / radius2)
    return 1.0 / ((m1.theta + m2.theta) * math.sqrt(inv_r))


def yield_force(radius1: float, radius2: float | None, mat1: str | Material, mat2: str | Material) -> tuple[float, float]:
    """Elastic limit of a contact as estimated in the paper (Sec. II): (F_Y [N], delta_Y [m]).

    Yield is taken when the mean contact pressure F / (pi a^2) reaches sigma_Y, with the Hertz
    contact radius a^3 = 3 F R* / (4 E*) (a^3 = theta R F for two equal spheres, as in the paper).
    Solving gives F_Y = (pi sigma_Y)^3 (3 R* / (4 E*))^2 and delta_Y = a_Y^2 / R*. The weaker of
    the two materials sets sigma_Y.

    Parameters
    ----------
    radius1, radius2 : float
        Radii of curvature [m] of the two bodies; ``radius2=None`` is a flat (wall cap).
    mat1, mat2 : str or Material
        Materials (catalogue names or :class:`Material`); their ``yield_stress`` [Pa] sets sigma_Y.

    Returns
    -------
    tuple of float
        (F_Y [N], delta_Y [m]); (inf, inf) when neither material has a yield stress.
    """
    m1, m2 = get_material(mat1), get_material(mat2)
    stresses = [s for s in (m1.yield_stress, m2.yield_stress) if s is not None]
    if not stresses:
        return math.inf, math.inf
    sigma = min(stresses)
    r_eff = effective_radius(radius1, radius2)
    e_eff = effective_modulus(m1, m2)
    c = 3.0 * r_eff / (4.0 * e_eff)
    force = (math.pi * sigma) ** 3 * c**2
    a = (c * force) ** (1.0 / 3.0)
    return force, a * a / r_eff


# --- dissipative laws ------------------------------------------------------------------------
# Integer codes select the compiled force function (see integrate/kernels.py).
# The size-scaled Kuwabara-Kono law is the Kuwabara-Kono force with a per-contact A (code 1).
LAW_CODES = {"elastic": 0, "viscoelastic": 1, "dashpot": 2, "viscoelastic_scaled": 1, "elastoplastic": 3}


@dataclass(frozen=True)
class Elastic:
    """Pure Hertz contact, paper eq. 1: F = kappa delta^(3/2)."""

    name = "elastic"

    @property
    def parameter(self) -> float:
        return 0.0


@dataclass(frozen=True)
class Viscoelastic:
    """Kuwabara-Kono viscoelastic Hertz contact: F = kappa (delta^(3/2) + A delta^(1/2) d(delta)/dt).

    Clipped at zero while unloading (never attractive).

    Parameters
    ----------
    A
        Dissipative time constant [s] (same for every contact of the run).
    """

    A: float
    name = "viscoelastic"

    def __post_init__(self) -> None:
        if not (math.isfinite(self.A) and self.A >= 0):
            raise ConfigError("contact.A", f"must be a finite number >= 0 (s), got {self.A!r}")

    @property
    def parameter(self) -> float:
        return self.A


@dataclass(frozen=True)
class Dashpot:
    """Hertz contact with a linear dashpot: F = kappa delta^(3/2) + gamma d(delta)/dt, clipped at zero.

    Parameters
    ----------
    gamma
        Damping coefficient [N s/m] (same for every contact of the run).
    """

    gamma: float
    name = "dashpot"

    def __post_init__(self) -> None:
        if not (math.isfinite(self.gamma) and self.gamma >= 0):
            raise ConfigError("contact.gamma", f"must be a finite number >= 0 (N s/m), got {self.gamma!r}")

    @property
    def parameter(self) -> float:
        return self.gamma


def collision_time_scale(mu, kappa):
    """Time scale (mu / kappa)^(2/5) [s m^(1/5)] of a Hertz contact of reduced mass ``mu`` [kg] and stiffness ``kappa``.

    A two-body Hertz collision at speed v lasts t_c ~ (mu / kappa)^(2/5) v^(-1/5) (paper eq. 1
    made dimensionless with delta* = (mu v^2 / kappa)^(2/5) and t* = delta* / v). In these units
    the Kuwabara-Kono force reads x^(3/2) + (A / t*) x^(1/2) dx/ds, so the restitution of a pair
    depends on A only through A / t*.

    Parameters
    ----------
    mu : float or numpy.ndarray
        Reduced mass m m' / (m + m') [kg] (m for a bead against an immovable wall).
    kappa : float or numpy.ndarray
        Hertz constant [N/m^1.5] (paper eq. 1).

    Returns
    -------
    float or numpy.ndarray
        (mu / kappa)^(2/5).
    """
    return (mu / kappa) ** 0.4


@dataclass(frozen=True)
class ScaledViscoelastic:
    """Kuwabara-Kono contact whose time constant follows each contact's collision time.

    F_j = kappa_j (delta^(3/2) + A_j delta^(1/2) d(delta)/dt), clipped at zero, with
    A_j = A t_j / t_ref and t = (mu / kappa)^(2/5) (:func:`collision_time_scale`; mu the pair's
    reduced mass): every pair then has the same two-body restitution at a given impact speed, and
    a geometrically similar chain hit at the same speed (all lengths times s) has every time and
    every A_j times s, hence exactly the same per-bead factor eps. This is the size-independent
    eps that the paper's eq. 6 assumes; a constant A (:class:`Viscoelastic`, a material constant
    in Kuwabara and Kono's theory) loses more per bead as beads and pulses get smaller. Between
    equal beads of one material t ~ R, so A_j ~ R.

    Parameters
    ----------
    A : float
        Time constant [s] of a contact between two beads of the reference ``diameter`` and
        ``material``.
    diameter : float
        Reference bead diameter [m] (a calibration's uniform chain, e.g. 26 mm).
    material : Material or str
        Reference bead material.
    """

    A: float
    diameter: float
    material: Material | str = "AISI52100"
    name = "viscoelastic_scaled"

    def __post_init__(self) -> None:
        if not (math.isfinite(self.A) and self.A >= 0):
            raise ConfigError("contact.A", f"must be a finite number >= 0 (s), got {self.A!r}")
        if not (math.isfinite(self.diameter) and self.diameter > 0):
            raise ConfigError("contact.diameter", f"must be a positive reference diameter (m), got {self.diameter!r}")
        object.__setattr__(self, "material", get_material(self.material))

    @property
    def parameter(self) -> float:
        return self.A

    def reference_time_scale(self) -> float:
        """Collision time scale of two reference beads.

        Returns
        -------
        float
            (mu / kappa)^(2/5) with mu = m / 2 and kappa of paper eq. 1 for two beads of the
            reference diameter and material.
        """
        r = self.diameter / 2
        mu = 0.5 * self.material.density * math.pi * self.diameter**3 / 6.0
        return collision_time_scale(mu, hertz_constant(r, r, self.material, self.material))

    def contact_damping(self, mu, kappa):
        """Per-contact time constants A_j = A t_j / t_ref.

        Parameters
        ----------
        mu : numpy.ndarray
            Reduced mass of every contact [kg].
        kappa : numpy.ndarray
            Hertz constant of every contact [N/m^1.5]; 0 where there is no contact.

        Returns
        -------
        numpy.ndarray
            A_j [s], 0 where kappa = 0.
        """
        import numpy as np

        mu = np.asarray(mu, dtype=float)
        kappa = np.asarray(kappa, dtype=float)
        safe = np.where(kappa > 0, kappa, 1.0)
        return np.where(kappa > 0, self.A * collision_time_scale(mu, safe) / self.reference_time_scale(), 0.0)


# --- elastic-plastic contact (Thornton 1997) -------------------------------------------------
#: Thornton's limiting contact pressure p_y in units of the weaker material's yield stress. With
#: p_y = 1.5 sigma_Y the largest Hertz pressure p0 = 3F / (2 pi a^2) reaches p_y exactly when the
#: mean pressure F / (pi a^2) reaches sigma_Y: Thornton's F_y is then the paper's elastic limit
#: F_Y (:func:`yield_force`, paper Sec. II) and ``max_force_over_yield`` keeps its meaning.
#: (Johnson's first yield under a sphere, von Mises with nu = 0.3, is p0 = 1.6 sigma_Y.)
LIMITING_PRESSURE_FACTOR = 1.5


def limiting_pressure(mat1: str | Material, mat2: str | Material | None = None) -> float:
    """Thornton's limiting contact pressure p_y = LIMITING_PRESSURE_FACTOR sigma_Y [Pa].

    Parameters
    ----------
    mat1, mat2 : str or Material
        The two materials (``mat2=None``: the same as ``mat1``); the weaker yield stress
        sigma_Y [Pa] sets p_y.

    Returns
    -------
    float
        p_y [Pa]; inf when neither material has a yield stress (the contact stays elastic).
    """
    m1, m2 = get_material(mat1), get_material(mat1 if mat2 is None else mat2)
    stresses = [s for s in (m1.yield_stress, m2.yield_stress) if s is not None]
    return LIMITING_PRESSURE_FACTOR * min(stresses) if stresses else math.inf


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

    Parameters
    ----------
    A : float
        Viscous time constant [s] (0: plastic dissipation only).
    diameter : float or None
        Reference bead diameter [m] of a size-scaled A (None: the same A at every contact).
    material : Material or str
        Reference bead material of a size-scaled A.
    """

    A: float = 0.0
    diameter: float | None = None
    material: Material | str = "AISI52100"
    name = "elastoplastic"

    def __post_init__(self) -> None:
        if not (isinstance(self.A, (int, float)) and math.isfinite(self.A) and self.A >= 0):
            raise ConfigError("contact.A", f"must be a finite number >= 0 (s), got {self.A!r}")
        if self.diameter is not None and not (math.isfinite(self.diameter) and self.diameter > 0):
            raise ConfigError("contact.diameter", f"must be a positive reference diameter (m), got {self.diameter!r}")
        object.__setattr__(self, "material", get_material(self.material))

    @property
    def parameter(self) -> float:
        return self.A

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


ContactLaw = Elastic | Viscoelastic | ScaledViscoelastic | Dashpot | Elastoplastic
