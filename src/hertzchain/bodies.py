"""The parts of ``Model.system()`` beyond the paper's chain: the striker's face, beads that are not
plain spheres, the protected body behind the wall, and the static state under gravity.

:func:`extend` takes the arrays ``Model.system()`` computed for a chain of spheres and changes what
these models change:

- masses: a given striker or bead mass, a cylinder's rho pi phi^2 L / 4, and the shell
  (1 - f) m of a mass-in-mass bead, whose internal mass f m rides on a spring (``res_m``,
  ``res_k``); the protected body's mass M (body N + 1 moves);
- the Hertz constant and elastic limit of every contact whose faces are not two spheres or a
  sphere on a flat: a flat or curved striker face, cylinders, a spherical body face
  (:func:`hertzchain.elements.contact_constants`, Johnson's elliptical Hertz contact);
- the static state: every body of mass m feels m g along the chain (``gravity``), bead 1 is
  pushed by the precompression F0, and contact j carries what bodies 0..j weigh and are pushed
  with, S_j = sum_{i <= j} f_i, at the overlap (S_j / kappa_j)^(2/3) (paper eq. 1 inverted); the
  body's mount carries everything, k d = S_{N+1}.

Nothing here is used by the models of the paper (``Model.plain``), whose arrays stay those of the
array set-up of ensembles bit for bit.
"""

from __future__ import annotations

import numpy as np

from .elements import Face, contact_constants, face_of
from .errors import ConfigError
from .laws import spec_of

__all__ = ["extend", "STANDARD_GRAVITY", "mount_half_period", "MAX_BODY_DURATION"]

#: The longest run [s] the automatic duration makes for a protected body's swing (a slow mount's
#: half period is cut there; an explicit ``run.duration`` is never cut).
MAX_BODY_DURATION = 25e-3


def mount_half_period(mass: float, stiffness: float) -> float:
    """Half the period pi sqrt(M/k) [s] of a protected body swinging on its mount.

    Parameters
    ----------
    mass : float
        The body's mass M [kg].
    stiffness : float
        Its mount's stiffness k [N/m]; 0 (a free body) gives 0: nothing swings back.

    Returns
    -------
    float
        pi sqrt(M/k) [s]: the chain pushes the body, which then swings on its mount, so the force
        the mount passes to the ground peaks within about this time after the pulse arrives.
    """
    return float(np.pi * np.sqrt(float(mass) / float(stiffness))) if stiffness > 0 else 0.0

#: Standard acceleration of gravity [m/s^2] (CGPM 1901), for a track tilted by an angle.
STANDARD_GRAVITY = 9.80665


def _faces(model) -> tuple[Face | None, list[Face], Face | None]:
    """The striker's face, every bead's face and the wall's face (None: a flat wall's default)."""
    s = model.striker
    k = 0.0 if s.face_radius is None else 1.0 / s.face_radius
    striker = Face(k, k, 0.0, s.material, "the flat striker" if s.shape == "flat" else "the striker")
    chain = model.chain
    beads = [face_of(el, float(d), mat, f"bead {i + 1}")
             for i, (el, d, mat) in enumerate(zip(chain.elements, chain.diameters, chain.materials))]
    wall = None
    if model.wall.present:
        r = model.wall.face_radius
        kw = 0.0 if r is None else 1.0 / r
        wall = Face(kw, kw, 0.0, model.wall_material, "the body's face" if model.wall.is_body else "the wall")
    return striker, beads, wall


def _special_contacts(model) -> list[int]:
    """Contacts whose faces are not those of the sphere formulas of ``Model.system()``."""
    n = model.chain.n_beads
    out = set()
    s = model.striker
    if s.shape == "flat" or s.radius_of_curvature is not None:
        out.add(0)
    for i, el in enumerate(model.chain.elements):
        if el.shape != "sphere":
            out.update((i, i + 1))
    if model.wall.present and model.wall.face_radius is not None:
        out.add(n)
    if not model.wall.present:
        out.discard(n)
    return sorted(out)


def _contact_field(model, j: int) -> str:
    n = model.chain.n_beads
    if j == 0 and (n == 0 or model.chain.elements[0].shape == "sphere"):  # n = 0: the striker meets the wall
        return "striker.shape"
    if j == n and model.chain.elements[-1].shape == "sphere":
        return "wall.shape"
    return "chain.elements"


def extend(model, parts: dict) -> dict:
    """The System fields of a model that is not the paper's kind (see the module docstring).

    Parameters
    ----------
    model : hertzchain.Model
        The model.
    parts : dict
        The System fields ``Model.system()`` computed for a chain of spheres (changed in place
        and completed).

    Returns
    -------
    dict
        Every field of :class:`hertzchain.model.System`.
    """
    chain, wall, n = model.chain, model.wall, model.chain.n_beads
    mass, inv_mass, kappa, fy = parts["mass"], parts["inv_mass"], parts["kappa"], parts["yield_force"]
    total = chain.masses  # whole bead masses (shell and internal mass)
    res_m = res_k = None
    if any(el.resonator_fraction > 0 for el in chain.elements):
        res_m, res_k = np.zeros(n + 2), np.zeros(n + 2)
        for i, (el, m) in enumerate(zip(chain.elements, total)):
            res_m[i + 1], res_k[i + 1] = el.resonator(float(m))
        mass[1:n + 1] = total - res_m[1:n + 1]
        inv_mass[1:n + 1] = 1.0 / mass[1:n + 1]
    if wall.is_body:
        mass[n + 1] = wall.mass
        inv_mass[n + 1] = 1.0 / wall.mass

    striker_face, bead_faces, wall_face = _faces(model)
    faces = [striker_face, *bead_faces, wall_face]
    for j in _special_contacts(model):
        kappa[j], fy[j] = contact_constants(faces[j], faces[j + 1], _contact_field(model, j))

    law = model.law
    parts["damping"] = np.where(kappa > 0, float(law.parameter), 0.0)
    if hasattr(law, "contact_damping"):  # size-scaled law: the pair's reduced mass, the body's included
        parts["damping"] = law.contact_damping(1.0 / (inv_mass[: n + 1] + inv_mass[1:]), kappa)

    # The static state: weights (gravity along the chain) and the precompression push on bead 1;
    # contact j holds bodies 0..j (the striker rests on bead 1).
    g = model.gravity
    fext = np.zeros(n + 2)
    if g > 0:
        fext[0] = model.striker.mass * g
        fext[1:n + 1] = total * g
        if wall.is_body:
            fext[n + 1] = wall.mass * g
    fext[1] += model.precompression
    held = np.cumsum(fext)
    d0 = np.zeros(n + 1)
    loaded = (held[: n + 1] > 0) & (kappa > 0)
    d0[loaded] = (held[: n + 1][loaded] / kappa[loaded]) ** (2.0 / 3.0)
    if spec_of(law).plastic:
        # loaded past F_Y: along Thornton's loading line F_y + (3/2) kappa delta_y^(1/2) (delta - delta_y)
        with np.errstate(invalid="ignore", divide="ignore"):
            dy = (fy / np.where(kappa > 0, kappa, 1.0)) ** (2.0 / 3.0)
            over = loaded & (held[: n + 1] > fy)
            plastic = dy + (held[: n + 1] - fy) / (1.5 * kappa * np.sqrt(dy))
        d0 = np.where(over, plastic, d0)
    mount_d0 = 0.0
    if wall.is_body and held[n + 1] > 0:
        if wall.stiffness == 0:  # Model refuses this before; kept as a guard for direct callers
            raise ConfigError("wall.stiffness", "a free body cannot hold a static load")
        mount_d0 = float(held[n + 1]) / wall.stiffness
    parts.update(mass=mass, inv_mass=inv_mass, kappa=kappa, yield_force=fy, fext=fext, d0=d0, body=wall.is_body,
                 mount_k=float(wall.stiffness), mount_c=float(wall.damping), mount_d0=mount_d0, res_m=res_m,
                 res_k=res_k)
    return parts
