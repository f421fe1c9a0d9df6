"""``Model.system()`` vectorised over the members of an ensemble: the batched engines' set-up.

:func:`systems` applies the formulas of ``Model.system()`` (Hertz constants, paper eq. 1;
masses; precompression; offsets) along a leading member axis, operation for operation, so that
every member's numbers are bit for bit those of ``Model.system()`` of that member alone, for an
:class:`~hertzchain.integrate.batch.ensemble.Ensemble` (one layout) or a
:class:`~hertzchain.integrate.batch.ragged.Ragged` set (any bead counts).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ...contact import LAW_CODES
from ...laws import get_law

if TYPE_CHECKING:
    from .ensemble import Ensemble
    from .ragged import Ragged

__all__ = ["Systems", "systems"]


@dataclass
class Systems:
    """``System`` arrays of every member, stacked along a leading member axis.

    Row i of each array is exactly the corresponding array of ``ensemble.model(i).system()``.
    Shapes: (M, N + 2) for bodies, (M, N + 1) for contact slots, (M,) per member.
    """

    mass: np.ndarray
    inv_mass: np.ndarray
    kappa: np.ndarray
    damping: np.ndarray
    d0: np.ndarray
    de: np.ndarray
    dx0: np.ndarray
    rsum: np.ndarray
    fext: np.ndarray
    u0: np.ndarray
    v0: np.ndarray
    yield_force: np.ndarray
    law: int
    misaligned: np.ndarray   # (M,) bool
    has_wall: bool
    bead_mass: np.ndarray    # (M, N) kg, Chain.masses of every member
    max_overlap: np.ndarray  # (M, N + 1) m, System.max_overlap()
    max_frequency: np.ndarray  # (M,) rad/s, System.max_frequency()

    @property
    def general(self) -> np.ndarray:
        """(M,) True where the general force loop is needed (dissipation or offsets)."""
        return (self.law != 0) | self.misaligned


def _scalar_map(fn, x: np.ndarray) -> np.ndarray:
    """``fn`` applied with Python float arithmetic to every distinct value of ``x``.

    Scalar powers (``x ** 2``, ``x ** 3`` on a Python float or NumPy scalar) go through the C
    library's pow, while NumPy's array power may use a vector routine that differs in the last
    bit; where Model.system() computes on scalars, so does this, once per distinct value.
    """
    if x.size <= _SMALL:  # a few members: sorting out the distinct values costs more than fn
        return np.array([fn(v) for v in x.ravel().tolist()], dtype=float).reshape(x.shape)
    vals, inv = np.unique(x, return_inverse=True)
    return np.array([fn(float(v)) for v in vals], dtype=float)[inv.reshape(x.shape)]


#: Up to this many values, :func:`_scalar_map` calls ``fn`` on each (np.unique's ~10 us would
#: cost more); the values are the same either way.
_SMALL = 32


def systems(ens: Ensemble | Ragged, start: int = 0, stop: int | None = None) -> Systems:
    """The engine's arrays of every member: ``Model.system()`` vectorised over the members.

    Parameters
    ----------
    ens:
        The members: one layout (:class:`Ensemble`), or any numbers of beads (:class:`Ragged`:
        then row i holds member i's arrays in its first N_i + 1 contact slots and bodies, and
        ``max_frequency`` is over its bodies 0..N_i).
    start, stop:
        The range of members to compute (default: all). The batched engine computes blocks of
        a few thousand members, whose arrays stay in the caches.

    Returns
    -------
    Systems
        Per-member arrays, bit for bit those of each member's ``Model.system()`` (same
        operations in the same order: Hertz constants kappa = 1 / (theta_sum sqrt(1/R + 1/R'))
        of paper eq. 1, masses rho pi phi^3 / 6, the precompression overlaps, the offsets'
        geometry), plus ``max_overlap`` and ``max_frequency`` (the step's bounds).
    """
    sel = slice(start, stop)
    d = ens.diameters[sel]
    m, n = d.shape
    bead_material, striker_material = ens.bead_material[sel], ens.striker_material[sel]
    wall_material, striker_diameter = ens.wall_material[sel], ens.striker_diameter[sel]
    striker_velocity, precompression = ens.striker_velocity[sel], ens.precompression[sel]
    law_parameter = ens.law_parameter[sel]
    # Ragged members (:class:`Ragged`): member i has n_each[i] beads, its arrays padded to n; the
    # few slots where a shorter chain differs (its wall contact, the slots past its end) are set
    # after the array code, which is element for element the same as for one layout.
    nn = getattr(ens, "n_each", None)
    if nn is not None:
        nn = nn[sel]
        every = np.arange(m)
    mats = ens.materials
    rho_t = np.array([x.density for x in mats])
    theta_t = np.array([x.theta for x in mats])
    sigma_t = np.array([np.nan if x.yield_stress is None else x.yield_stress for x in mats])

    # Material columns once when every member has the same materials (the usual ensemble): rows
    # of shape (1, ...) then broadcast against the members' geometry, same numbers.
    if nn is None and (bead_material.strides[0] == 0 or bool(np.all(bead_material == bead_material[:1]))) and \
            bool(np.all(striker_material == striker_material[0])) and bool(np.all(wall_material == wall_material[0])):
        bead_mat, striker_mat, wall_mat = bead_material[:1], striker_material[:1], wall_material[:1]
    else:
        bead_mat, striker_mat, wall_mat = bead_material, striker_material, wall_material
    mm = striker_mat.size

    # masses: the striker's with scalar arithmetic (Striker.mass), the beads' as Chain.masses
    striker_mass = np.empty(m)
    for k in (striker_mat.tolist() if mm == 1 else np.unique(striker_material).tolist()):
        rows = slice(None) if mm == 1 else striker_material == k
        rho = float(rho_t[k])
        striker_mass[rows] = _scalar_map(lambda dia: rho * math.pi * dia**3 / 6.0, striker_diameter[rows])
    bead_mass = np.ascontiguousarray(rho_t[bead_mat]) * math.pi * np.ascontiguousarray(d) ** 3 / 6.0
    mass = np.empty((m, n + 2))
    mass[:, 0] = striker_mass
    mass[:, 1:n + 1] = bead_mass
    mass[:, n + 1] = np.inf
    inv_mass = np.zeros((m, n + 2))
    inv_mass[:, :n + 1] = 1.0 / mass[:, :n + 1]

    r = np.empty((m, n + 1))
    r[:, 0] = striker_diameter / 2
    r[:, 1:] = d / 2.0
    theta = np.empty((mm, n + 1))
    theta[:, 0] = theta_t[striker_mat]
    theta[:, 1:] = theta_t[bead_mat]
    sigma = np.empty((mm, n + 1))
    sigma[:, 0] = sigma_t[striker_mat]
    sigma[:, 1:] = sigma_t[bead_mat]
    nk = n + 1 if ens.has_wall else n
    inv_r = (np.empty if nn is None else np.ones)((m, nk))  # ragged: finite in every padding slot
    t_sum = (np.empty if nn is None else np.ones)((mm, nk))
    s_min = (np.empty if nn is None else np.ones)((mm, nk))
    inv_r[:, :n] = 1.0 / r[:, :-1] + 1.0 / r[:, 1:]
    t_sum[:, :n] = theta[:, :-1] + theta[:, 1:]
    s_min[:, :n] = np.fmin(sigma[:, :-1], sigma[:, 1:])
    if ens.has_wall and nn is None:
        inv_r[:, n] = 1.0 / r[:, -1]
        t_sum[:, n] = theta[:, -1] + theta_t[wall_mat]
        s_min[:, n] = np.fmin(sigma[:, -1], sigma_t[wall_mat])
    elif ens.has_wall:  # contact N_i of every member, the same operations
        inv_r[every, nn] = 1.0 / r[every, nn]
        t_sum[every, nn] = theta[every, nn] + theta_t[wall_mat]
        s_min[every, nn] = np.fmin(sigma[every, nn], sigma_t[wall_mat])
    kappa = np.zeros((m, n + 1))
    fy = np.full((m, n + 1), np.inf)
    kappa[:, :nk] = 1.0 / (t_sum * np.sqrt(inv_r))
    c = 3.0 * (1.0 / inv_r) / (4.0 * (0.75 / t_sum))
    with np.errstate(invalid="ignore"):
        fy[:, :nk] = np.where(np.isnan(s_min), np.inf, (math.pi * s_min) ** 3 * c**2)
    if nn is not None:  # no contact past a member's chain (nor at a free end): kappa 0, no limit
        past = np.arange(n + 1) >= (nn + (1 if ens.has_wall else 0))[:, None]
        kappa[past] = 0.0
        fy[past] = np.inf

    damping = np.where(kappa > 0, law_parameter[:, None], 0.0)
    d0 = np.zeros((m, n + 1))
    fext = np.zeros((m, n + 2))
    pushed = np.flatnonzero(precompression > 0)
    if pushed.size and nn is None:
        f0 = precompression[pushed]
        # row by row, as Model.system() does (a contiguous (N,) array to the power 2/3)
        for row, i in zip(f0[:, None] / np.ascontiguousarray(kappa[pushed, 1:]), pushed):
            d0[i, 1:] = np.ascontiguousarray(row) ** (2.0 / 3.0)
        fext[pushed, 1] = precompression[pushed]
    elif pushed.size:
        for i in pushed.tolist():
            end = int(nn[i]) + 1
            d0[i, 1:end] = (precompression[i] / np.ascontiguousarray(kappa[i, 1:end])) ** (2.0 / 3.0)
        fext[pushed, 1] = precompression[pushed]

    e = np.zeros((m, n + 2))
    e[:, 1:n + 1] = ens.offsets[sel]
    de = e[:, 1:] - e[:, :-1]  # np.diff's own arithmetic
    de[:, n] = 0.0
    r2 = np.zeros((m, n + 2))
    r2[:, :n + 1] = r
    if nn is not None:
        de[every, nn] = 0.0  # a flat wall is unaffected by the last bead's offset
        r2[every, nn + 1] = 0.0  # the wall ghost's radius, as in System.rsum
    rsum = r2[:, :-1] + r2[:, 1:]
    dx0 = np.sqrt(np.maximum(rsum**2 - de**2, 0.0))
    v0 = np.zeros((m, n + 2))
    v0[:, 0] = striker_velocity

    # System.max_overlap and System.max_frequency, per member
    energy = 0.5 * mass[:, 0] * _scalar_map(lambda v: v**2, striker_velocity)
    if pushed.size and nn is None:
        energy = energy + np.sum(0.4 * kappa * d0**2.5, axis=1)
    elif pushed.size:
        stored = np.zeros(m)  # each member's sum over its own N_i + 1 slots (the same pairwise sum)
        pe = 0.4 * kappa * d0**2.5
        for i in pushed.tolist():
            stored[i] = np.sum(pe[i, :int(nn[i]) + 1])
        energy = energy + stored
    else:
        energy = energy + 0.0
    with np.errstate(divide="ignore"):
        dcap = np.where(kappa > 0, (2.5 * energy[:, None] / np.where(kappa > 0, kappa, 1.0)) ** 0.4, 0.0) + d0
    # System.max_frequency: Gershgorin bounds of stiffness and damping (System.damping_coefficients)
    k = 1.5 * kappa * np.sqrt(dcap)
    k_left = np.zeros((m, n + 1))
    k_left[:, 1:] = k[:, :n]
    omega2 = 2.0 * (k_left + k[:, :n + 1]) * inv_mass[:, :n + 1]
    if not get_law(ens.law_name).dissipative:
        # beta = 0: sqrt(omega2 + 0.0) + 0.0 is sqrt(omega2) (omega2 >= 0), the same numbers
        bound = np.sqrt(omega2)
    else:
        if get_law(ens.law_name).calibrated == "gamma":
            c = np.where(kappa > 0, damping, 0.0)
        else:
            c = kappa * damping * np.sqrt(np.maximum(dcap, 0.0))
        c_left = np.zeros((m, n + 1))
        c_left[:, 1:] = c[:, :n]
        beta = 2.0 * (c_left + c[:, :n + 1]) * inv_mass[:, :n + 1]
        bound = np.sqrt(omega2 + 0.25 * beta**2) + 0.5 * beta
    if nn is not None:  # bodies 0..N_i only (the bounds are >= 0)
        bound = np.where(np.arange(n + 1) <= nn[:, None], bound, 0.0)
    w = np.max(bound, axis=1)
    return Systems(mass=mass, inv_mass=inv_mass, kappa=kappa, damping=damping, d0=d0, de=de, dx0=dx0, rsum=rsum,
                   fext=fext, u0=np.zeros((m, n + 2)), v0=v0, yield_force=fy, law=LAW_CODES[ens.law_name],
                   misaligned=np.any(de != 0.0, axis=1), has_wall=ens.has_wall, bead_mass=bead_mass,
                   max_overlap=dcap, max_frequency=w)
