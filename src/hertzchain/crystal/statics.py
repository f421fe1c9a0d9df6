"""Static equilibrium of a chain under precompression, gravity (or a tilt), a protected body on its
mount and static forces on chosen beads (``[load]``).

Conventions (docs/guide/crystals.rst): contact j joins body j and body j + 1 (contact 0 =
striker-bead 1, contact N = bead N-wall); every external force f_i [N] points along the chain
towards the wall. A chain is statically determinate: body i is balanced when
F_{i-1} - F_i + f_i = 0, so contact j carries what bodies 0..j are pushed with,

    S_j = sum_{i <= j} f_i,

and its overlap is the Hertz law inverted, delta_j = (S_j / kappa_j)^(2/3) (paper eq. 1; along
Thornton's loading line past the elastic limit for the elastic-plastic law; a registry law's force
at rest inverted by root finding, hertzchain.laws.solve). A protected body's
mount carries everything, k d = S_{N+1}. Contacts cannot pull: S_j < 0 means that bodies 0..j are
pulled off the chain and there is no equilibrium (refused, naming ``load.forces``). The solution
is exact, so no iterative solver is needed; :func:`equilibrium` reports the residual of the force
balance evaluated with the contact law at the computed overlaps as a check.

Uniform precompression F0 gives delta_0 = (F0 / kappa)^(2/3) in every contact of the chain
(the striker only touches bead 1: contact 0 carries the striker's weight under gravity, else 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..laws import spec_of

__all__ = ["Equilibrium", "equilibrium", "held_forces", "static_overlaps"]


def held_forces(fext: np.ndarray, kappa: np.ndarray, n_beads: int) -> np.ndarray:
    """Force S_j [N] every contact j = 0..N + 1 must carry at rest (N + 2,): S_j = sum_{i <= j} f_i.

    Parameters
    ----------
    fext : numpy.ndarray
        External static force on every body 0..N + 1 [N], towards the wall (weights, the
        precompression on bead 1, loads).
    kappa : numpy.ndarray
        Hertz constants of contacts 0..N [N/m^1.5] (0 where there is no contact).
    n_beads : int
        N.

    Raises
    ------
    ConfigError
        ``load.forces`` when a contact would have to pull (bodies 0..j pulled away from the wall).
    """
    held = np.cumsum(fext)
    scale = max(float(np.max(np.abs(np.cumsum(np.abs(fext))))), 1e-300)
    pulled = np.flatnonzero(held[: n_beads + 1] < -1e-12 * scale)
    if pulled.size:
        j = int(pulled[0])
        raise ConfigError("load.forces", f"the static forces pull bodies 0..{j} away from the wall "
                          f"(contact {j} would have to pull with {-held[j]:.4g} N): contacts cannot pull, so "
                          "there is no equilibrium; make the forces on beads 1..n add up to >= 0 for every n")
    return np.where(held > 0, held, 0.0)


def static_overlaps(held: np.ndarray, kappa: np.ndarray, yield_force: np.ndarray | None = None) -> np.ndarray:
    """Overlap [m] of every contact 0..N carrying ``held[j]`` (paper eq. 1 inverted).

    Parameters
    ----------
    held : numpy.ndarray
        Static force of contacts 0..N [N] (:func:`held_forces`, its first N + 1 entries).
    kappa : numpy.ndarray
        Hertz constants [N/m^1.5].
    yield_force : numpy.ndarray, optional
        Thornton's F_y of every contact [N] for the elastic-plastic law: past it the contact is
        loaded along F_y + (3/2) kappa delta_y^(1/2) (delta - delta_y) (Thornton 1997); None: Hertz.

    Returns
    -------
    numpy.ndarray
        (S_j / kappa_j)^(2/3), 0 where there is no contact or no force.
    """
    held = np.asarray(held, dtype=float)[: kappa.size]
    d0 = np.zeros(kappa.size)
    loaded = (held > 0) & (kappa > 0)
    d0[loaded] = (held[loaded] / kappa[loaded]) ** (2.0 / 3.0)
    if yield_force is not None:
        with np.errstate(invalid="ignore", divide="ignore"):
            dy = (yield_force / np.where(kappa > 0, kappa, 1.0)) ** (2.0 / 3.0)
            over = loaded & (held > yield_force)
            plastic = dy + (held - yield_force) / (1.5 * kappa * np.sqrt(dy))
        d0 = np.where(over, plastic, d0)
    return d0


@dataclass(frozen=True)
class Equilibrium:
    """The static state of a model (see the module docstring).

    Attributes
    ----------
    overlaps : numpy.ndarray
        Overlap of every contact 0..N [m] (contact 0 = striker-bead 1, N = bead N-wall).
    forces : numpy.ndarray
        Force every contact 0..N carries [N].
    displacements : numpy.ndarray
        Static displacement of bodies 0..N (striker, beads) [m], towards the wall, from the chain
        whose neighbours just touch with the wall (or the unloaded body's face) in place.
    positions : numpy.ndarray
        Centre positions of bodies 0..N [m] along the chain: bead 1's centre is at 0 in the
        touching chain, and each centre is moved by its displacement.
    mount_deflection : float
        A protected body's displacement on its mount [m] (0 for a flat wall or a free end).
    external : numpy.ndarray
        External static force on bodies 0..N + 1 [N] (weights, precompression, loads).
    residual : float
        Largest force imbalance of a body [N], the contact law evaluated at ``overlaps``.
    """

    overlaps: np.ndarray
    forces: np.ndarray
    displacements: np.ndarray
    positions: np.ndarray
    mount_deflection: float
    external: np.ndarray
    residual: float

    def __repr__(self) -> str:
        return (f"Equilibrium({self.forces.size} contacts, forces {np.min(self.forces):.4g}..{np.max(self.forces):.4g} N, "
                f"overlaps up to {np.max(self.overlaps):.4g} m, residual {self.residual:.2g} N)")


def equilibrium(model) -> Equilibrium:
    """Static equilibrium of ``model`` (:class:`hertzchain.Model`); every run starts from it.

    Parameters
    ----------
    model : hertzchain.Model
        Chain, striker, wall (a protected body on its mount included), contact law,
        ``precompression`` [N], ``gravity`` [m/s^2] and ``loads`` (static forces [N] on beads).

    Returns
    -------
    Equilibrium
        Overlaps [m] and forces [N] of contacts 0..N, displacements and positions [m].
    """
    from .ends import driven_from_last, equilibrium_to_model_numbers, from_driven_end

    if driven_from_last(model):  # the chain read from bead N (hertzchain.crystal.ends)
        return equilibrium_to_model_numbers(equilibrium(from_driven_end(model)), model)
    system = model.system()
    n = system.n_beads
    fext = system.fext
    held = held_forces(fext, system.kappa, n)[: n + 1]
    held = np.where(system.kappa > 0, held, 0.0)
    d0 = np.where(system.kappa > 0, system.d0, 0.0)
    # residual: the contact law at the overlaps (Hertz; Thornton's loading line when plastic; a
    # generated law's own force at rest)
    spec = spec_of(model.law)
    if spec.plastic:
        f_law = held.copy()
    elif spec.generated:
        assert spec.force is not None  # a generated law has all its functions (register_law)
        f_law = np.array([spec.force(d, 0.0, k, p, 0.0) if k > 0 else 0.0
                          for d, k, p in zip(d0, system.kappa, system.damping)])
    else:
        f_law = system.kappa * d0**1.5
    g = np.concatenate([[0.0], f_law, [0.0]])[: n + 2]  # g[i] = F_{i-1}
    balance = g[: n + 1] - g[1 : n + 2] + fext[: n + 1]
    u = np.zeros(n + 2)
    u[n + 1] = system.mount_d0
    for j in range(n, -1, -1):
        u[j] = u[j + 1] + d0[j]
    # no striker: body 0 is a point at bead 1's face (a displacement drive's flat driver)
    r = np.concatenate([[0.0 if model.striker is None else model.striker.diameter / 2], model.chain.radii])
    x = np.concatenate([[-(r[0] + r[1])], np.cumsum(np.concatenate([[0.0], r[1:-1] + r[2:]]))])
    return Equilibrium(overlaps=d0, forces=held, displacements=u[: n + 1], positions=x + u[: n + 1],
                       mount_deflection=float(system.mount_d0), external=fext.copy(),
                       residual=float(np.max(np.abs(balance))) if balance.size else 0.0)
