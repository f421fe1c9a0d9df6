"""The set-up derivatives of beads that are not spheres (cylinders, beads of a given mass): their
masses and the elliptical Hertz contacts they make, in the complex arithmetic of
:mod:`hertzchain.gradients.setup` (the complex step).

The formulas are those of ``Model.system()`` for elements (:mod:`hertzchain.elements`,
:mod:`hertzchain.bodies`): a cylinder's mass rho pi phi^2 L / 4 (a given mass is a constant),
each face's principal curvatures, Johnson's relative curvatures (A, B) and the elliptical Hertz
constant kappa = E* c(m, A) with the ellipse's parameter m = e^2 the root of
B/A = ratio(m) (``elements.curvature_ratio``). The root is found on the real numbers; its
complex-step part follows from the implicit function theorem, m' = (B/A)' / ratio'(m), with
ratio'(m) itself taken by a complex step of the analytic ``curvature_ratio`` (SciPy's Carlson
integrals take complex arguments): exact to rounding, as the rest of the set-up.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..elements import curvature_ratio, ellipse_parameter, shape_factors

__all__ = ["element_masses", "element_contacts"]

#: The complex step of ratio'(m) (any h far below m's scale: no subtraction is made).
_STEP = 1e-30


def element_masses(elements, mass: np.ndarray, rho: np.ndarray, phi: np.ndarray) -> None:
    """Bead masses (rows, N + 1, body 0 the striker) of ``elements`` (one per bead), in place: a
    given mass, or a cylinder's rho pi phi^2 L / 4 (L the element's length, else its diameter)."""
    for i, el in enumerate(elements):
        b = i + 1
        if el.mass is not None:
            mass[:, b] = el.mass
        elif el.shape == "cylinder":
            length = phi[:, b] if el.length is None else el.length
            mass[:, b] = rho[:, b] * math.pi * phi[:, b] ** 2 * length / 4.0


def element_resonators(elements, mass: np.ndarray, res_k: np.ndarray, res_inv_mass: np.ndarray, read) -> None:
    """Mass-in-mass beads (``Element.resonator``, ``bodies.extend``), in place: of a bead's whole
    mass m (``mass``, rows, N + 1) the internal mass f m rides on a spring f m (2 pi nu)^2 (into
    ``res_k`` and ``res_inv_mass`` = 1 / (f m)), and ``mass`` keeps the shell's (1 - f) m. The
    fraction f and the frequency nu [Hz] are read through ``read`` (``setup._Reader``) as the fields
    ``elements.NAME.resonator.mass_fraction`` and ``.frequency``: variables of their own."""
    for i, el in enumerate(elements):
        if el.resonator_fraction > 0:
            b = i + 1
            where = f"elements.{el.name}.resonator"
            m_in = read(f"{where}.mass_fraction", el.resonator_fraction)[:, 0] * mass[:, b]
            res_k[:, b] = m_in * (2.0 * math.pi * read(f"{where}.frequency", el.resonator_frequency)[:, 0]) ** 2
            res_inv_mass[:, b] = 1.0 / m_in
            mass[:, b] = mass[:, b] - m_in


def _face(el, phi) -> tuple[Any, Any, float]:
    """(k1, k2, angle) of a bead's face: elements.face_of in complex arithmetic."""
    k = 2.0 / phi
    if el.shape == "sphere":
        return k, k, 0.0
    if el.orientation == "aligned":
        return 0.0 * k, 0.0 * k, 0.0
    return 0.0 * k, k, el.axis_angle


def _elliptic(fa, fb, e_star, s_min) -> tuple[np.ndarray, np.ndarray]:
    """(kappa, F_Y) of two faces (rows,) complex: elements.contact_constants."""
    (a1, a2, ta), (b1, b2, tb) = fa, fb
    s = 0.5 * (a1 + a2 + b1 + b2)
    d1, d2 = a1 - a2, b1 - b2
    alpha = math.radians(ta - tb)
    q = d1 * d1 + d2 * d2 + 2.0 * d1 * d2 * math.cos(2.0 * alpha)
    diff = 0.5 * np.sqrt(np.where(np.real(q) > 0.0, q, 0.0))
    a_curv, b_curv = 0.5 * (s - diff), 0.5 * (s + diff)
    ratio = b_curv / a_curv
    m = ellipse_parameter(float(np.real(ratio[0])))
    slope = float(np.imag(curvature_ratio(m + 1j * _STEP))) / _STEP
    m = m + 1j * np.imag(ratio) / slope
    c, p = shape_factors(m, a_curv)
    kappa = e_star * c
    with np.errstate(invalid="ignore"):
        delta_y = (s_min / (p * kappa)) ** 2
    return kappa, np.where(np.isnan(np.real(s_min)), np.inf, kappa * delta_y**1.5)


def element_contacts(elements, n: int, phi: np.ndarray, striker_face, wall_face, t_sum: np.ndarray,
                     s_min: np.ndarray, kappa: np.ndarray, fy: np.ndarray) -> None:
    """Every contact that touches a bead of ``elements`` other than a sphere gets its elliptical
    Hertz constant and elastic limit (rows, N + 1 contacts), in place.

    ``phi`` (rows, N + 1): the striker's and the beads' diameters [m]; ``striker_face`` and
    ``wall_face``: (k1, k2) of the striker's face and the wall's (None: no wall) [1/m];
    ``t_sum``, ``s_min``: each contact's theta + theta' and weaker yield stress (NaN: none)."""
    special = sorted({j for i, el in enumerate(elements) if el.shape != "sphere" for j in (i, i + 1)
                      if j < n or wall_face is not None})
    for j in special:
        if j == 0:
            fa = (*striker_face, 0.0)
        else:
            fa = _face(elements[j - 1], phi[:, j])
        fb = _face(elements[j], phi[:, j + 1]) if j < n else (*wall_face, 0.0)
        kappa[:, j], fy[:, j] = _elliptic(fa, fb, 0.75 / t_sum[:, j], s_min[:, j])
