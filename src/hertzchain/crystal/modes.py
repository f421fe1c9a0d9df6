"""Normal modes of a chain linearised about its static equilibrium, and its linear response to a drive.

About the equilibrium (:mod:`hertzchain.crystal.statics`) each loaded Hertz contact is a spring of
stiffness

    K_j = dF/d(delta) = (3/2) kappa_j delta_j^(1/2) = (3/2) kappa_j^(2/3) F_j^(1/3)

(paper eq. 1 differentiated at the static force F_j; a registry law's own dF/d(delta) there, from
its partials, e.g. n k delta^(n - 1) for the power law); a contact that carries no static force has
no linear stiffness (it opens or closes: the chain is not linear there). The degrees of freedom are
the beads (their shells for mass-in-mass beads), each internal mass of a mass-in-mass bead (a
spring k_in to its shell), a protected body (its mount k to the ground) and the striker when it
rests loaded on bead 1 (under gravity; a striker that only touches is left out). The mass matrix
M is diagonal; the modes solve K phi = omega^2 M phi (scipy.linalg.eigh, generalised symmetric),
shapes normalised to phi^T M phi = 1, frequencies f = omega / (2 pi) [Hz].

The linearised damping matrix C takes each contact's dashpot, c_j = gamma (dashpot law) or
c_j = kappa_j A delta_j^(1/2) (Kuwabara-Kono), and the mount's. :func:`linear_transmission` solves
(K - omega^2 M + i omega C) X = F for a drive on bead 1 and returns the ratio of the amplitude of
the last contact's force (the wall's) to the drive's force amplitude.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..laws import law_of_code
from ..integrate.core.primitives import LAW_DASHPOT, LAW_ELASTIC, LAW_ELASTOPLASTIC, LAW_VISCOELASTIC
from .statics import equilibrium

#: The law codes whose elastic part is Hertz's kappa delta^(3/2) (what the linearisation assumes).
HERTZ_LAWS = (LAW_ELASTIC, LAW_VISCOELASTIC, LAW_DASHPOT, LAW_ELASTOPLASTIC)

__all__ = ["Modes", "modes", "linear_matrices", "linear_transmission", "LinearChain"]


@dataclass(frozen=True)
class LinearChain:
    """The linearised chain: M, K, C [kg, N/m, N s/m] over the degrees of freedom ``labels``.

    ``index[i]`` is the row of body i (0 = striker, 1..N beads, N + 1 the protected body), -1 for
    a body that does not move (the wall, a striker left out, a driver); ``contact_stiffness`` and
    ``contact_damping`` are K_j and c_j of contacts 0..N.
    """

    mass: np.ndarray
    stiffness: np.ndarray
    damping: np.ndarray
    labels: list[str]
    index: np.ndarray
    contact_stiffness: np.ndarray
    contact_damping: np.ndarray


def linear_matrices(model) -> LinearChain:
    """Assemble M, K and C of ``model`` linearised about its equilibrium (module docstring)."""
    from .ends import driven_from_last, from_driven_end

    if driven_from_last(model):  # the chain read from bead N, its rows and contacts in the model's numbers
        return _to_model_numbers(linear_matrices(from_driven_end(model)), model.chain.n_beads)
    eq = equilibrium(model)
    system = model.system()
    spec = law_of_code(system.law)
    if system.law not in HERTZ_LAWS and not spec.generated:
        raise ConfigError("contact.law", f"the linearisation K = (3/2) kappa^(2/3) F^(1/3) is that of Hertz contacts "
                          f"(the elastic, viscoelastic, dashpot and elastoplastic laws); {model.law.name!r} is not one")
    n = system.n_beads
    d0 = eq.overlaps
    loaded = (eq.forces > 0) & (system.kappa > 0)
    if spec.generated:  # dF/d(delta) at rest from the law's partials (its state: a first touch at 1 m/s)
        kc = np.array([abs(spec.partials(d, 0.0, k, p, 1.0)[0]) if on else 0.0
                       for d, k, p, on in zip(d0, system.kappa, system.damping, loaded)])
    else:
        kc = np.where(loaded, 1.5 * system.kappa * np.sqrt(d0), 0.0)
    cc = np.where(loaded, system.damping_coefficients(d0), 0.0)
    index = np.full(n + 2, -1)
    labels: list[str] = []
    masses: list[float] = []
    if system.inv_mass[0] > 0 and loaded[0]:
        index[0] = 0
        labels.append("striker")
        masses.append(float(system.mass[0]))
    for i in range(1, n + 1):
        index[i] = len(labels)
        labels.append(f"bead {i}")
        masses.append(float(system.mass[i]))
    if system.body:
        index[n + 1] = len(labels)
        labels.append("body")
        masses.append(float(system.mass[n + 1]))
    inner = []
    if system.res_m is not None:
        for i in range(n + 2):
            if system.res_m[i] > 0 and index[i] >= 0:
                inner.append((i, len(labels)))
                labels.append(f"resonator {i}")
                masses.append(float(system.res_m[i]))
    size = len(labels)
    k = np.zeros((size, size))
    c = np.zeros((size, size))

    def spring(mat, a, b, value):
        for p, q, s in ((a, a, 1.0), (b, b, 1.0), (a, b, -1.0), (b, a, -1.0)):
            if p >= 0 and q >= 0:
                mat[p, q] += s * value

    for j in range(n + 1):
        spring(k, index[j], index[j + 1], kc[j])
        spring(c, index[j], index[j + 1], cc[j])
    if system.body:
        spring(k, index[n + 1], -1, system.mount_k)
        spring(c, index[n + 1], -1, system.mount_c)
    for body, row in inner:
        spring(k, index[body], row, system.res_k[body])
    return LinearChain(mass=np.diag(masses), stiffness=k, damping=c, labels=labels, index=index,
                       contact_stiffness=kc, contact_damping=cc)


def _to_model_numbers(lin: LinearChain, n: int) -> LinearChain:
    """``lin`` of the chain read from bead N (hertzchain.crystal.ends) with beads i -> N + 1 - i and
    contacts j -> N - j, rows ordered as the model's (beads 1..N, the body, the resonators)."""
    def renumbered(label: str) -> tuple[str, tuple]:
        kind, _, number = label.partition(" ")
        if kind in ("bead", "resonator"):
            i = n + 1 - int(number)
            return f"{kind} {i}", (0 if kind == "bead" else 2, i)
        return label, (1, 0)

    pairs = [renumbered(x) for x in lin.labels]
    order = sorted(range(len(pairs)), key=lambda r: pairs[r][1])
    row = np.empty(len(order), dtype=int)
    row[order] = np.arange(len(order))  # new row of each old row
    index = np.full(n + 2, -1)
    for body in range(n + 2):
        old = lin.index[n + 1 - body]
        index[body] = row[old] if old >= 0 else -1
    pick = np.ix_(order, order)
    return LinearChain(mass=lin.mass[pick], stiffness=lin.stiffness[pick], damping=lin.damping[pick],
                       labels=[pairs[r][0] for r in order], index=index,
                       contact_stiffness=lin.contact_stiffness[::-1].copy(),
                       contact_damping=lin.contact_damping[::-1].copy())


@dataclass(frozen=True)
class Modes:
    """Normal modes of a linearised chain.

    Attributes
    ----------
    frequencies : numpy.ndarray
        f_k [Hz], ascending.
    shapes : numpy.ndarray
        (degrees of freedom, modes): column k is mode k, normalised to phi^T M phi = 1 [kg^-1/2].
    participation : numpy.ndarray
        Effective mass fraction of each mode along the chain, (phi_k^T M 1)^2 / sum(M) (they add up to 1).
    labels : list of str
        The degree of freedom of each row ("bead 3", "resonator 3", "body", "striker").
    matrices : LinearChain
        M, K, C.
    """

    frequencies: np.ndarray
    shapes: np.ndarray
    participation: np.ndarray
    labels: list[str]
    matrices: LinearChain

    def __repr__(self) -> str:
        f = self.frequencies
        return f"Modes({f.size} modes, {f[0]:.4g}..{f[-1]:.4g} Hz)" if f.size else "Modes(none)"


def modes(model) -> Modes:
    """Normal modes of ``model`` (:class:`hertzchain.Model`) about its static equilibrium.

    Parameters
    ----------
    model : hertzchain.Model
        Chain, wall, law, ``precompression`` [N], ``gravity``, ``loads``: what holds the chain
        statically sets its linear stiffness (a chain without static forces has no linear modes
        beyond zero frequency).

    Returns
    -------
    Modes
        Frequencies [Hz] ascending, mass-normalised shapes, effective mass fractions.
    """
    from scipy.linalg import eigh

    lin = linear_matrices(model)
    w2, phi = eigh(lin.stiffness, lin.mass)
    w2 = np.maximum(w2, 0.0)  # rounding below zero for the rigid modes of a free chain
    m = np.diag(lin.mass)
    gamma = phi.T @ m
    part = gamma**2 / m.sum()
    return Modes(frequencies=np.sqrt(w2) / (2.0 * np.pi), shapes=phi, participation=part, labels=lin.labels,
                 matrices=lin)


def linear_transmission(model, frequencies, quantity: str | None = None) -> np.ndarray:
    """Transmission of a small drive on bead 1 through the linearised chain (module docstring).

    Parameters
    ----------
    model : hertzchain.Model
        The chain; its ``drive`` sets the quantity when ``quantity`` is None (a force when there is none).
    frequencies : array_like
        Drive frequencies [Hz].
    quantity : {"force", "displacement"}, optional
        A force on bead 1, or a driver displacement through contact 0.

    Returns
    -------
    numpy.ndarray
        abs(F_out) / abs(F_in) at each frequency: the last contact's (the wall's, else contact N - 1)
        force amplitude over the drive's force amplitude on bead 1.
    """
    from .ends import driven_from_last, from_driven_end

    if driven_from_last(model):  # bead N driven, contact 0 (the wall's) transmitting: the chain read from bead N
        return linear_transmission(from_driven_end(model), frequencies, quantity)
    lin = linear_matrices(model)
    n = model.chain.n_beads
    if quantity is None:
        quantity = "force" if model.drive is None else model.drive.quantity
    if quantity not in ("force", "displacement"):
        raise ConfigError("drive.quantity", f"must be 'force' or 'displacement', got {quantity!r}")
    out = n if model.wall.present else n - 1
    if out < 1 and not model.wall.present:
        raise ConfigError("chain", "a single bead with a free end has no contact to transmit through")
    idx = lin.index
    res = []
    for f in np.atleast_1d(np.asarray(frequencies, dtype=float)):
        w = 2.0 * np.pi * f
        dyn = lin.stiffness - w * w * lin.mass + 1j * w * lin.damping
        rhs = np.zeros(len(lin.labels), dtype=complex)
        z0 = lin.contact_stiffness[0] + 1j * w * lin.contact_damping[0]
        if quantity == "force":
            rhs[idx[1]] = 1.0
        else:  # a unit driver displacement pushes bead 1 through contact 0
            rhs[idx[1]] = z0
        x = np.linalg.solve(dyn, rhs)
        xb = lambda i: 0.0 if idx[i] < 0 else x[idx[i]]  # noqa: E731
        f_out = (lin.contact_stiffness[out] + 1j * w * lin.contact_damping[out]) * (xb(out) - xb(out + 1))
        f_in = 1.0 if quantity == "force" else z0 * (1.0 - xb(1))
        res.append(abs(f_out) / abs(f_in))
    return np.array(res)
