"""What a bead can be besides a sphere, and the Hertz constant of any two faces that meet.

An :class:`Element` says what body sits at a place of the chain: a sphere (the default), a
cylinder lying across the chain (``orientation="crossed"``: its neighbours touch its curved
side) or along it (``"aligned"``: they touch its flat end faces), a body of a given mass, and a
mass-in-mass bead (an internal mass on a linear spring inside the bead). Its diameter is the
chain's diameter of that bead.

Contacts between curved faces follow Hertz's theory of elliptical contact (Johnson, *Contact
Mechanics*, Cambridge University Press 1985, Sec. 4.2 with the elliptical pressure distribution
of Sec. 3.5). Each face near the contact point has two principal curvatures (1/R_1', 1/R_1''),
the first along a direction at angle ``theta`` about the chain axis. The gap between two faces is
A x^2 + B y^2 with (Johnson Sec. 4.2)

    A + B = (1/R_1' + 1/R_1'' + 1/R_2' + 1/R_2'') / 2,
    B - A = sqrt((1/R_1' - 1/R_1'')^2 + (1/R_2' - 1/R_2'')^2
                 + 2 (1/R_1' - 1/R_1'') (1/R_2' - 1/R_2'') cos 2 alpha) / 2,

alpha the angle between the two first directions. The contact ellipse (semi-axes a >= b,
eccentricity e = sqrt(1 - b^2/a^2)) carries the pressure p_0 sqrt(1 - x^2/a^2 - y^2/b^2), and
with the complete elliptic integrals K(e), E(e) (Johnson Sec. 3.5)

    B / A = (E(e) / (1 - e^2) - K(e)) / (K(e) - E(e)),
    A = p_0 b (K(e) - E(e)) / (E* e^2 a^2),     delta = p_0 b K(e) / E*,     P = (2/3) pi p_0 a b,

so that P = kappa delta^(3/2) with

    kappa = (2 pi / 3) E* sqrt(K(e) - E(e)) / (e sqrt(A) K(e)^(3/2)),

the elliptical form of paper eq. 1: for A = B = 1/(2R) (two spheres, a sphere on a flat) it is
kappa = (4/3) E* sqrt(R), the circular Hertz constant. A sphere of radius R_1 on the side of a
crossed cylinder of radius R_2 has B/A = 1 + R_1 / R_2; two equal cylinders crossed at right
angles meet like a sphere on a flat. Parallel cylinders, or a cylinder's side on a flat, touch
along a line (A = 0): that contact is not Hertz's point contact and is refused, as is a flat on a
flat.

The elastic limit follows the paper's criterion (Sec. II) on the ellipse: the mean pressure
P / (pi a b) reaches sigma_Y.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from .bounds import BOUNDS, check_bound
from .errors import ConfigError
from .materials import Material

__all__ = ["Element", "SPHERE", "Face", "face_of", "contact_constants", "relative_curvatures",
           "elliptic_hertz", "ellipse_parameter", "curvature_ratio", "shape_factors"]


@dataclass(frozen=True)
class Element:
    """What one bead of a chain is (its diameter is the chain's diameter of that bead).

    Parameters
    ----------
    name : str
        Name in the config (``[elements.NAME]``) and in the result's description.
    shape : {"sphere", "cylinder"}
        A sphere of the bead's diameter, or a circular cylinder of that diameter.
    orientation : {"crossed", "aligned"}
        A cylinder's axis across the chain (its neighbours touch its curved side) or along the
        chain (they touch its flat end faces). Unused for a sphere.
    length : float or None
        Cylinder length [m]; None: as long as its diameter.
    axis_angle : float
        Angle [deg] of a crossed cylinder's axis about the chain axis (two neighbouring crossed
        cylinders meet at the difference of their angles; equal angles would be a line contact).
    mass : float or None
        Given total mass [kg] of the bead; None: rho pi phi^3 / 6 for a sphere, rho pi phi^2 L / 4
        for a cylinder.
    resonator_fraction : float
        Mass-in-mass bead: fraction f (0 <= f < 1) of the bead's mass m that is an internal mass
        m_in = f m on a linear spring; the outer shell keeps (1 - f) m. 0: a plain bead.
    resonator_frequency : float
        Natural frequency [Hz] of the internal mass on its spring with the shell held,
        sqrt(k_in / m_in) / (2 pi); needed when ``resonator_fraction`` > 0.
    """

    name: str = "sphere"
    shape: Literal["sphere", "cylinder"] = "sphere"
    orientation: Literal["crossed", "aligned"] = "crossed"
    length: float | None = None
    axis_angle: float = 0.0
    mass: float | None = None
    resonator_fraction: float = 0.0
    resonator_frequency: float = 0.0

    def __post_init__(self) -> None:
        where = f"elements.{self.name}"
        if self.shape not in ("sphere", "cylinder"):
            raise ConfigError(f"{where}.shape", f"must be 'sphere' or 'cylinder', got {self.shape!r}")
        if self.orientation not in ("crossed", "aligned"):
            raise ConfigError(f"{where}.orientation", f"must be 'crossed' or 'aligned', got {self.orientation!r}")
        if self.length is not None and not (math.isfinite(self.length) and self.length > 0):
            raise ConfigError(f"{where}.length_mm", f"must be a positive length, got {self.length!r} m")
        if not math.isfinite(self.axis_angle):
            raise ConfigError(f"{where}.axis_deg", f"must be a finite angle, got {self.axis_angle!r}")
        check_bound(self.mass, "mass", f"{where}.mass", "kg", allow_none=True)
        f = self.resonator_fraction
        if not (math.isfinite(f) and 0.0 <= f < 1.0):
            raise ConfigError(f"{where}.resonator.mass_fraction", f"must lie in [0, 1), got {f!r}")
        nu = self.resonator_frequency
        if f > 0 and not (math.isfinite(nu) and 0 < nu <= BOUNDS["frequency"][1]):
            raise ConfigError(f"{where}.resonator.frequency", f"must be a positive frequency up to "
                              f"{BOUNDS['frequency'][1]:g} Hz, got {nu!r}")

    @property
    def plain(self) -> bool:
        """True for an ordinary sphere (the mass rho pi phi^3 / 6, no resonator)."""
        return self.shape == "sphere" and self.mass is None and self.resonator_fraction == 0.0

    def total_mass(self, diameter: float, material: Material) -> float:
        """Mass of the whole bead [kg] (shell and internal mass).

        Parameters
        ----------
        diameter : float
            The bead's diameter phi [m].
        material : Material
            Its material (density rho [kg/m^3]).

        Returns
        -------
        float
            The given mass, else rho pi phi^3 / 6 (sphere) or rho pi phi^2 L / 4 (cylinder).
        """
        if self.mass is not None:
            return self.mass
        if self.shape == "sphere":
            return material.density * math.pi * diameter**3 / 6.0
        length = diameter if self.length is None else self.length
        return material.density * math.pi * diameter**2 * length / 4.0

    def resonator(self, total_mass: float) -> tuple[float, float]:
        """Internal mass [kg] and spring [N/m] of a mass-in-mass bead ((0, 0) for a plain one).

        Parameters
        ----------
        total_mass : float
            The bead's whole mass m [kg].

        Returns
        -------
        tuple of float
            (m_in = f m, k_in = m_in (2 pi nu)^2).
        """
        if self.resonator_fraction == 0.0:
            return 0.0, 0.0
        m_in = self.resonator_fraction * total_mass
        return m_in, m_in * (2.0 * math.pi * self.resonator_frequency) ** 2

    def describe(self) -> dict:
        """Plain-data description (stored in result attributes)."""
        out: dict = {"name": self.name, "shape": self.shape}
        if self.shape == "cylinder":
            out.update(orientation=self.orientation, length_mm=None if self.length is None else self.length * 1e3,
                       axis_deg=self.axis_angle)
        if self.mass is not None:
            out["mass"] = self.mass
        if self.resonator_fraction > 0:
            out["resonator"] = {"mass_fraction": self.resonator_fraction, "frequency": self.resonator_frequency}
        return out


#: The default element: a plain sphere.
SPHERE = Element()


@dataclass(frozen=True)
class Face:
    """The face a body presents to a contact: principal curvatures [1/m], the first along the
    direction at ``angle`` [deg] about the chain axis, and its material."""

    k1: float
    k2: float
    angle: float
    material: Material
    what: str

    @property
    def flat(self) -> bool:
        return self.k1 == 0.0 and self.k2 == 0.0


def face_of(element: Element, diameter: float, material: Material, what: str) -> Face:
    """The face a bead presents to either neighbour.

    Parameters
    ----------
    element : Element
        The bead's element.
    diameter : float
        Its diameter [m].
    material : Material
        Its material.
    what : str
        How errors name it (``"bead 3"``).

    Returns
    -------
    Face
        A sphere: curvature 2/phi both ways; a crossed cylinder: 0 along its axis and 2/phi across
        it; an aligned cylinder: its flat end (0, 0).
    """
    k = 2.0 / diameter
    if element.shape == "sphere":
        return Face(k, k, 0.0, material, what)
    if element.orientation == "aligned":
        return Face(0.0, 0.0, 0.0, material, what)
    return Face(0.0, k, element.axis_angle, material, what)


def relative_curvatures(f1: Face, f2: Face) -> tuple[float, float]:
    """Johnson's (A, B), A <= B [1/m], of two faces (see the module docstring)."""
    s = 0.5 * (f1.k1 + f1.k2 + f2.k1 + f2.k2)
    d1, d2 = f1.k1 - f1.k2, f2.k1 - f2.k2
    alpha = math.radians(f1.angle - f2.angle)
    diff = 0.5 * math.sqrt(max(d1 * d1 + d2 * d2 + 2.0 * d1 * d2 * math.cos(2.0 * alpha), 0.0))
    return 0.5 * (s - diff), 0.5 * (s + diff)


def ellipse_parameter(ratio: float) -> float:
    """m = e^2 of the contact ellipse whose relative curvatures have B / A = ``ratio`` >= 1 (module
    docstring: the root of B/A = (3 R_F / R_D - 1) / (1 - m), R_F, R_D Carlson's integrals at
    (0, 1 - m, 1)); 0 for a circle."""
    from scipy.optimize import brentq

    if not ratio > 1.0:
        return 0.0

    def excess(m: float) -> float:
        return float(curvature_ratio(m)) - ratio

    # B/A grows from 1 (m = 0) without bound (m -> 1), roughly as (a/b)^(3/2) (Greenwood 1985)
    return 0.0 if excess(0.0) >= 0.0 else brentq(excess, 0.0, 1.0 - 1e-16, xtol=1e-17, rtol=1e-15, maxiter=500)


def curvature_ratio(m):
    """B / A of the contact ellipse of parameter m = e^2 (float or complex: an analytic function).

    Carlson's forms K = R_F(0, 1 - m, 1) and K - E = (m / 3) R_D(0, 1 - m, 1) turn Johnson's
    expression (module docstring) into one without the cancellation of K - E at small e:
    B/A = (3 R_F / R_D - 1) / (1 - m)."""
    from scipy.special import elliprd, elliprf

    return (3.0 * elliprf(0.0, 1.0 - m, 1.0) / elliprd(0.0, 1.0 - m, 1.0) - 1.0) / (1.0 - m)


def shape_factors(m, a_curv):
    """:func:`elliptic_hertz`'s (c, p) from the ellipse's parameter m = e^2 and A [1/m], in NumPy
    arithmetic (so complex numbers too: the sensitivity's complex step through the set-up)."""
    import numpy as np
    from scipy.special import elliprd, elliprf

    rf, rd = elliprf(0.0, 1.0 - m, 1.0), elliprd(0.0, 1.0 - m, 1.0)
    # kappa / E* = (2 pi / 3) sqrt(R_D / 3) / (sqrt(A) R_F^(3/2)); the mean pressure P / (pi a b)
    # with a^2 = delta (K - E) / (A e^2 K), b = a sqrt(1 - e^2)
    c = 2.0 * math.pi / 3.0 * np.sqrt(rd / 3.0) / (np.sqrt(a_curv) * rf**1.5)
    p = 3.0 * a_curv * rf / (math.pi * np.sqrt(1.0 - m) * rd)
    return c, p


def elliptic_hertz(a_curv: float, b_curv: float) -> tuple[float, float]:
    """Shape factors of an elliptical Hertz contact: (kappa / E*, mean-pressure factor).

    Parameters
    ----------
    a_curv, b_curv : float
        Johnson's relative curvatures A <= B [1/m], A > 0.

    Returns
    -------
    tuple of float
        ``c`` [m^(1/2)] with kappa = E* c (module docstring), and ``p`` [1/m] with the mean
        contact pressure P / (pi a b) = p kappa delta^(1/2) (for the elastic limit).
    """
    c, p = shape_factors(ellipse_parameter(b_curv / a_curv), a_curv)
    return float(c), float(p)


def contact_constants(f1: Face, f2: Face, field: str) -> tuple[float, float]:
    """Hertz constant kappa [N/m^1.5] and elastic limit F_Y [N] of two faces in contact.

    Parameters
    ----------
    f1, f2 : Face
        The two faces (curvatures, materials).
    field : str
        The config field an impossible pair is reported under.

    Returns
    -------
    tuple of float
        kappa (P = kappa delta^(3/2), elliptical Hertz; paper eq. 1 for circular contacts) and
        F_Y, the force at which the mean pressure reaches the weaker material's yield stress
        (paper Sec. II; inf when neither material gives one).

    Raises
    ------
    ConfigError
        For a flat on a flat or a line contact (parallel cylinders, a cylinder's side on a flat).
    """
    a_curv, b_curv = relative_curvatures(f1, f2)
    if b_curv <= 0.0:
        raise ConfigError(field, f"{f1.what} and {f2.what} would meet flat on flat: that is not a Hertz contact "
                          "(make one face curved: a sphere, a crossed cylinder, a curved face)")
    if a_curv <= 1e-9 * b_curv:
        raise ConfigError(field, f"{f1.what} and {f2.what} would touch along a line (parallel cylinders, or a "
                          "cylinder's side on a flat): a line contact is not Hertz's point contact and is not "
                          "modelled; cross the cylinders (axis_deg) or align one with the chain")
    e_star = 0.75 / (f1.material.theta + f2.material.theta)
    c, p = elliptic_hertz(a_curv, b_curv)
    kappa = e_star * c
    stresses = [s for s in (f1.material.yield_stress, f2.material.yield_stress) if s is not None]
    if not stresses:
        return kappa, math.inf
    # p_mean = p kappa delta^(1/2) = sigma_Y
    delta_y = (min(stresses) / (p * kappa)) ** 2
    return kappa, kappa * delta_y**1.5

