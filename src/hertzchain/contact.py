"""Contact laws between two bodies: Hertz elastic force (paper eq. 1) and dissipative variants.

Geometry helpers here are plain Python (used to build a model and by :mod:`hertzchain.theory`);
the compiled force evaluations live in :mod:`hertzchain.integrate.core.kernels`. The elastic-plastic
law (Thornton 1997) and its closed forms are in :mod:`hertzchain.plasticity`.

Conventions (docs/conventions.rst): overlap delta > 0 in compression, force
F = kappa * delta^(3/2) for delta > 0 and 0 otherwise (never attractive), with
1/kappa = (theta + theta') * sqrt(1/R + 1/R'), theta = 3 (1 - nu^2) / (4 Y), 1/R' = 0 for a flat.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .errors import ConfigError
from .laws.spec import attach_maker, get_law
from .materials import Material, get_material
from .strict import real

__all__ = [
    "hertz_constant", "effective_radius", "effective_modulus", "yield_force", "Elastic",
    "Viscoelastic", "ScaledViscoelastic", "SizedViscoelastic", "Dashpot", "ScaledDashpot", "ContactLaw", "LAW_CODES",
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
# Integer codes select the compiled force function (see integrate/core/kernels.py).
# The size-scaled Kuwabara-Kono law is the Kuwabara-Kono force with a per-contact A (code 1).
# The size-scaled dashpot is the dashpot force with a per-contact gamma (code 2).
LAW_CODES = {"elastic": 0, "viscoelastic": 1, "dashpot": 2, "viscoelastic_scaled": 1, "viscoelastic_sized": 1,
             "dashpot_scaled": 2, "elastoplastic": 3}


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
        object.__setattr__(self, "A", real(self.A, "contact.A", unit="s"))
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
        object.__setattr__(self, "gamma", real(self.gamma, "contact.gamma", unit="N s/m"))
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


class _ReferencePair:
    """What the size-scaled laws share: their parameter (the field ``_field`` names, with its unit),
    checked with the reference pair's diameter [m] on construction, and the reference pair of
    beads (``diameter``, ``material``) their per-contact values are scaled from."""

    _field: tuple[str, str]
    diameter: float
    material: Material | str

    def __post_init__(self) -> None:
        name, unit = self._field
        value = real(getattr(self, name), f"contact.{name}", unit=unit)
        if not (math.isfinite(value) and value >= 0):
            raise ConfigError(f"contact.{name}", f"must be a finite number >= 0 ({unit}), got {value!r}")
        if not (math.isfinite(self.diameter) and self.diameter > 0):
            raise ConfigError("contact.diameter", f"must be a positive reference diameter (m), got {self.diameter!r}")
        object.__setattr__(self, name, value)
        object.__setattr__(self, "material", get_material(self.material))

    @property
    def parameter(self) -> float:
        return float(getattr(self, self._field[0]))

    def reference(self) -> tuple[float, float]:
        """Reduced mass [kg] and Hertz constant [N/m^1.5] of two reference beads.

        Returns
        -------
        tuple of float
            (mu_ref = m / 2, kappa_ref of paper eq. 1 for two beads of the reference diameter and
            material).
        """
        assert isinstance(self.material, Material)  # (__post_init__)
        r = self.diameter / 2
        mu = 0.5 * self.material.density * math.pi * self.diameter**3 / 6.0
        return mu, hertz_constant(r, r, self.material, self.material)


@dataclass(frozen=True)
class ScaledViscoelastic(_ReferencePair):
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
    _field = ("A", "s")

    def reference_time_scale(self) -> float:
        """Collision time scale of two reference beads.

        Returns
        -------
        float
            (mu / kappa)^(2/5) with mu = m / 2 and kappa of paper eq. 1 for two beads of the
            reference diameter and material.
        """
        return collision_time_scale(*self.reference())

    @property
    def size_exponent(self) -> float:
        """The power p of A_j = A (t_j / t_ref)^p [-]: 1 here, declared with the law in
        :mod:`hertzchain.laws.builtin` (``extra["size_exponent"]``, read by the gradients too)."""
        return float(get_law(self.name).extra.get("size_exponent", 1.0))

    def contact_damping(self, mu, kappa):
        """Per-contact time constants A_j = A (t_j / t_ref)^p, p = :attr:`size_exponent`.

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
        ratio = collision_time_scale(mu, safe) / self.reference_time_scale()
        return np.where(kappa > 0, self.A * ratio**self.size_exponent, 0.0)


@dataclass(frozen=True)
class SizedViscoelastic(ScaledViscoelastic):
    """Kuwabara-Kono contact whose time constant follows the square of each contact's collision time.

    F_j = kappa_j (delta^(3/2) + A_j delta^(1/2) d(delta)/dt), clipped at zero, with
    A_j = A (t_j / t_ref)^2 and t = (mu / kappa)^(2/5) (:func:`collision_time_scale`). In the units
    of :func:`collision_time_scale` the Kuwabara-Kono loss is set by A_j / t*, t* = t v^(-1/5), so
    every pair keeps the viscoelastic spheres' trend 1 - e ~ A_j v^(1/5) / t_j (restitution
    falling with impact speed), and a pair whose collision time scale is shorter than the
    reference beads' (the 8 mm striker on a 26 mm bead: t / t_ref = 0.37) loses less at the same
    speed, by the factor t_j / t_ref. Calibrated to the paper's eps = 0.985 on its 26 mm beads
    (A = 4.36 us with the paper's 8 mm striker at 0.2 m/s) it gives that striker a two-body
    restitution of 0.947 at 0.2 m/s, where :class:`ScaledViscoelastic` (A_j ~ t_j) gives 0.864;
    see the user guide's plasticity page. Between equal beads of one material t ~ R, so A_j ~ R^2;
    geometrically similar chains then no longer share one eps (smaller beads lose less per bead).
    The square is the smallest whole power that keeps the striker's e >= 0.93 (t^1.5 gives 0.915);
    no measurement of the paper fixes it.

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

    name = "viscoelastic_sized"


@dataclass(frozen=True)
class ScaledDashpot(_ReferencePair):
    """Hertz contact with a linear dashpot whose coefficient follows each contact pair.

    F_j = kappa_j delta^(3/2) + gamma_j d(delta)/dt, clipped at zero, with
    gamma_j = gamma (kappa_j / kappa_ref)^(2/5) (mu_j / mu_ref)^(3/5) (mu the pair's reduced
    mass; the reference is two beads of ``diameter`` and ``material``). In the units of
    :func:`collision_time_scale` the dashpot force reads x^(3/2) + G x' with
    G = gamma v^(-1/5) / (kappa^(2/5) mu^(3/5)): this scaling gives every pair, whatever its sizes
    and materials, the same restitution at the same impact speed, and that restitution rises with
    speed (1 - e ~ v^(-1/5)): the loss is largest at the small amplitudes of a travelling pulse
    and smaller at the striker's impact. Calibrated to the paper's eps = 0.985 in the 26 mm
    chain it gives the 8 mm striker a two-body restitution of ~0.96 at 0.2 m/s, in the range of
    steel balls, where the Kuwabara-Kono laws give 0.68 (constant A) or 0.86 (size-scaled A).

    Parameters
    ----------
    gamma : float
        Damping coefficient [N s/m] of a contact between two beads of the reference
        ``diameter`` and ``material``.
    diameter : float
        Reference bead diameter [m] (a calibration's uniform chain, e.g. 26 mm).
    material : Material or str
        Reference bead material.
    """

    gamma: float
    diameter: float
    material: Material | str = "AISI52100"
    name = "dashpot_scaled"
    _field = ("gamma", "N s/m")

    def contact_damping(self, mu, kappa):
        """Per-contact coefficients gamma_j = gamma (kappa_j / kappa_ref)^(2/5) (mu_j / mu_ref)^(3/5).

        Parameters
        ----------
        mu : numpy.ndarray
            Reduced mass of every contact [kg].
        kappa : numpy.ndarray
            Hertz constant of every contact [N/m^1.5]; 0 where there is no contact.

        Returns
        -------
        numpy.ndarray
            gamma_j [N s/m], 0 where kappa = 0.
        """
        import numpy as np

        mu = np.asarray(mu, dtype=float)
        kappa = np.asarray(kappa, dtype=float)
        mu_ref, k_ref = self.reference()
        safe = np.where(kappa > 0, kappa, k_ref)
        return np.where(kappa > 0, self.gamma * (safe / k_ref) ** 0.4 * (mu / mu_ref) ** 0.6, 0.0)


#: The laws of this module (the elastic-plastic one is :class:`hertzchain.plasticity.Elastoplastic`).
ContactLaw = Elastic | Viscoelastic | ScaledViscoelastic | SizedViscoelastic | Dashpot | ScaledDashpot


def _attach_makers() -> None:
    """The registry's constructors of this module's laws (hertzchain.laws declares their parameters)."""
    attach_maker("elastic", lambda params, chain=None: Elastic())
    attach_maker("viscoelastic", lambda params, chain=None: Viscoelastic(params["A"]))
    attach_maker("dashpot", lambda params, chain=None: Dashpot(params["gamma"]))
    attach_maker("viscoelastic_scaled", lambda params, chain=None: ScaledViscoelastic(
        params["A"], float(chain.diameters[0]), chain.materials[0]))
    attach_maker("viscoelastic_sized", lambda params, chain=None: SizedViscoelastic(
        params["A"], float(chain.diameters[0]), chain.materials[0]))
    attach_maker("dashpot_scaled", lambda params, chain=None: ScaledDashpot(
        params["gamma"], float(chain.diameters[0]), chain.materials[0]))


_attach_makers()
