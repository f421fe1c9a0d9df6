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
- no striker (``Model.striker = None``, or a ``Model.drive`` without one,
  :mod:`hertzchain.crystal.drive`): no striker body (mass 0, at rest); no contact 0 (with no drive
  or a force drive), the massless driver's contact for a displacement drive (the driver then
  applies the precompression; with ``striker = None`` its face is a flat of bead 1's material);
- the static state: every body of mass m feels m g along the chain (``gravity``), bead 1 is
  pushed by the precompression F0, the beads of ``Model.loads`` by their static forces, and contact
  j carries what bodies 0..j weigh and are pushed with, S_j = sum_{i <= j} f_i, at the overlap
  (S_j / kappa_j)^(2/3) (paper eq. 1 inverted; :mod:`hertzchain.crystal.statics`); the body's
  mount carries everything, k d = S_{N+1}.

Nothing here is used by the models of the paper (``Model.plain``), whose arrays stay those of the
array set-up of ensembles bit for bit.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from .elements import Face, contact_constants, face_of
from .errors import ConfigError
from .laws import spec_of
from .strict import real

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


def _faces(model) -> tuple[Face, list[Face], Face | None]:
    """The striker's face, every bead's face and the wall's face (None: no wall)."""
    s = model.body0
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
    s = model.body0
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
    special = _special_contacts(model)
    for j in special:
        a, b = faces[j], faces[j + 1]
        assert a is not None and b is not None  # (contact N is special only with a wall)
        kappa[j], fy[j] = contact_constants(a, b, _contact_field(model, j))
    if special and hasattr(model.law, "contact_stiffness"):  # a law's own k (the power law's) where redone here
        kappa[special] = model.law.contact_stiffness(kappa[special])

    drive = model.drive
    no_striker = model.striker is None or (drive is not None and not drive.striker)
    driver = no_striker and drive is not None and drive.quantity == "displacement"
    if no_striker:
        # no striker: a force drive has no contact 0; a displacement drive's massless driver (an
        # immovable body whose position the drive prescribes) takes the striker's place
        mass[0], inv_mass[0] = 0.0, 0.0
        parts["v0"][0] = 0.0
        if not driver:
            kappa[0], fy[0] = 0.0, np.inf
    law = model.law
    spec = spec_of(law)
    parts["damping"] = np.where(kappa > 0, float(law.parameter), 0.0)
    if hasattr(law, "contact_damping"):  # size-scaled law: the pair's reduced mass, the body's included
        parts["damping"] = law.contact_damping(1.0 / (inv_mass[: n + 1] + inv_mass[1:]), kappa)

    # The static state (hertzchain.crystal.statics): weights (gravity along the chain), the
    # precompression push on bead 1 and the loads on chosen beads; contact j holds bodies 0..j
    # (the striker rests on bead 1).
    from .crystal.statics import held_forces, static_overlaps

    g = model.gravity
    fext = np.zeros(n + 2)
    if g > 0:
        fext[0] = mass[0] * g  # the striker (0 for a massless driver)
        fext[1:n + 1] = total * g
        if wall.is_body:
            fext[n + 1] = wall.mass * g
    fext[1] += model.precompression
    for bead, force in model.loads:
        fext[bead] += force
    if driver:  # the driver is massless: it applies the precompression through contact 0
        fext[0], fext[1] = model.precompression, fext[1] - model.precompression
    held = held_forces(fext, kappa, n)
    # loaded past F_Y (elastic-plastic): along Thornton's loading line F_y + (3/2) kappa delta_y^(1/2) (delta - delta_y)
    # (Thornton's F_y at the law's limiting pressure: p_y^3, as Model.system and the engines' yield overlap)
    d0 = static_overlaps(held[: n + 1], kappa, fy * getattr(law, "pressure_ratio", 1.0) ** 3 if spec.plastic else None)
    if spec.generated:  # where the law's force at rest is the held force (laws/solve.py)
        from .laws.solve import static_overlap

        d0 = np.array([static_overlap(spec, s, k, p) if s > 0 and k > 0 else 0.0
                       for s, k, p in zip(held[: n + 1], kappa, parts["damping"])])
    mount_d0 = 0.0
    if wall.is_body and held[n + 1] > 0:
        if wall.stiffness == 0:  # Model refuses this before; kept as a guard for direct callers
            raise ConfigError("wall.stiffness", "a free body cannot hold a static load")
        mount_d0 = float(held[n + 1]) / wall.stiffness
    parts.update(mass=mass, inv_mass=inv_mass, kappa=kappa, yield_force=fy, fext=fext, d0=d0, body=wall.is_body,
                 mount_k=float(wall.stiffness), mount_c=float(wall.damping), mount_d0=mount_d0, res_m=res_m,
                 res_k=res_k)
    return parts


def checked_loads(items, chain, wall) -> tuple:
    """Static loads ``[load]`` as a tuple of (bead number 1..N, finite force in N) pairs, checked
    against the chain and the wall (ConfigError naming ``load``, ``load.beads`` or ``load.forces``)."""
    n = chain.n_beads
    loads = []
    for item in items:
        if not (isinstance(item, (tuple, list)) and len(item) == 2):
            raise ConfigError("load", f"each load is a pair (bead number, force in N), got {item!r}")
        bead, force = item
        if isinstance(bead, bool) or not isinstance(bead, numbers.Integral) or not 1 <= int(bead) <= n:
            raise ConfigError("load.beads", f"must be bead numbers from 1 to {n}, got {bead!r}")
        force = real(force, "load.forces", unit="N")
        if not math.isfinite(force):
            raise ConfigError("load.forces", f"must be finite forces in N, got {force!r}")
        loads.append((int(bead), force))
    if loads and not wall.present:
        raise ConfigError("load", "static loads need a wall (or a body) to push against; wall.type = 'none' "
                          "has no static equilibrium under them")
    if loads and not chain.is_aligned:
        raise ConfigError("load", "static loads together with bead offsets are not supported")
    if loads and wall.is_body and wall.stiffness == 0:
        raise ConfigError("wall.stiffness", "a free body (stiffness 0) cannot hold the static loads: give its "
                          "mount a stiffness in N/m")
    return tuple(loads)
