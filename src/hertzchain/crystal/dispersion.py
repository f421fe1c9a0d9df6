"""Bloch band structure of a periodic chain under a uniform precompression.

A unit cell of n beads (an :class:`hertzchain.Chain` holding one period: any diameters,
materials, elements, mass-in-mass beads) repeats without end; every contact carries the static
force F0 and is the spring K_j = (3/2) kappa_j^(2/3) F0^(1/3) (the linearised Hertz stiffness).
With u_{i + n} = u_i e^{i q} (q the wavenumber in radians per period, 0..pi) the cell's equations
become the Hermitian eigenproblem K(q) phi = omega^2 M phi: within the cell K_j couples beads j and
j + 1; the closing contact couples bead n with bead 1 of the next cell, with the phase e^{i q}.
Internal masses of mass-in-mass beads are degrees of freedom of their own (a spring k_in to their
shell). Branches are sorted by frequency at each q; a gap lies between the highest frequency of a
branch and the lowest of the next one, when the second is above the first.

Closed forms (the tests): a monatomic chain has f = (1/pi) sqrt(K/m) abs(sin(q/2)), cut-off
2 sqrt(K/m) (angular); a diatomic chain (masses m_h > m_l, the same contact both ways) has its
gap between sqrt(2K/m_h) and sqrt(2K/m_l) (angular, at q = pi).
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from ..errors import ConfigError

__all__ = ["dispersion", "band_gaps"]


def _cell_arrays(cell, precompression: float):
    """Masses, internal masses/springs and the n contact stiffnesses [N/m] of a cell under F0."""
    from ..model import Model

    two = cell.concat(cell)
    system = Model(two, precompression=precompression).system()
    n = cell.n_beads
    kappa = system.kappa[1 : n + 1]  # contact j joins beads j and j + 1; contact n, bead n and the next cell's bead 1
    k = 1.5 * kappa ** (2.0 / 3.0) * precompression ** (1.0 / 3.0)
    mass = system.mass[1 : n + 1].copy()
    res_m = np.zeros(n) if system.res_m is None else system.res_m[1 : n + 1].copy()
    res_k = np.zeros(n) if system.res_k is None else system.res_k[1 : n + 1].copy()
    return mass, res_m, res_k, k


def band_gaps(frequency: np.ndarray, rel_tol: float = 1e-9) -> list[list[float]]:
    """Gaps [[low, high], ...] [Hz] of branches ``frequency`` (wavenumber, branch), sorted."""
    gaps = []
    for b in range(frequency.shape[1] - 1):
        low, high = float(np.max(frequency[:, b])), float(np.min(frequency[:, b + 1]))
        if high > low * (1.0 + rel_tol):
            gaps.append([low, high])
    return gaps


def dispersion(cell, precompression: float, points: int = 201) -> xr.Dataset:
    """Band structure of the periodic chain whose one period is ``cell`` (module docstring).

    Parameters
    ----------
    cell : hertzchain.Chain
        One period (any number of beads, diameters, materials, elements), aligned.
    precompression : float
        The static force F0 [N] every contact carries, > 0.
    points : int
        Wavenumbers from 0 to pi (both included).

    Returns
    -------
    xarray.Dataset
        ``frequency`` [Hz] over ``wavenumber`` [rad per period] and ``branch`` (0 = the lowest);
        attribute ``gaps``: a list of [low, high] [Hz] (empty when the branches overlap),
        ``precompression`` [N] and ``stiffness`` (the cell's K_j [N/m]).
    """
    from scipy.linalg import eigh

    if isinstance(precompression, bool) or not (np.isfinite(precompression) and precompression > 0):
        raise ConfigError("chain.precompression", f"a band structure needs a static force > 0 in N (the "
                          f"linearised stiffness vanishes without it), got {precompression!r}")
    if not (isinstance(points, (int, np.integer)) and points >= 2):
        raise ConfigError("points", f"must be a whole number of wavenumbers >= 2, got {points!r}")
    if not cell.is_aligned:
        raise ConfigError("chain.offsets", "a band structure needs an aligned cell")
    mass, res_m, res_k, k = _cell_arrays(cell, float(precompression))
    n = mass.size
    inner = np.flatnonzero(res_m > 0)
    size = n + inner.size
    m_diag = np.concatenate([mass, res_m[inner]])
    q = np.linspace(0.0, np.pi, int(points))
    freq = np.empty((q.size, size))
    for iq, qq in enumerate(q):
        kq = np.zeros((size, size), dtype=complex)
        for j in range(n):
            a, b = j, (j + 1) % n
            phase = np.exp(1j * qq) if j == n - 1 else 1.0
            kq[a, a] += k[j]
            kq[b, b] += k[j]
            kq[a, b] -= k[j] * phase
            kq[b, a] -= k[j] * np.conj(phase)
        for r, i in enumerate(inner):
            kq[i, i] += res_k[i]
            kq[n + r, n + r] += res_k[i]
            kq[i, n + r] -= res_k[i]
            kq[n + r, i] -= res_k[i]
        w2 = eigh(kq, np.diag(m_diag), eigvals_only=True)
        freq[iq] = np.sqrt(np.maximum(w2, 0.0)) / (2.0 * np.pi)
    ds = xr.Dataset(
        {"frequency": (("wavenumber", "branch"), freq, {"units": "Hz", "long_name": "frequency"})},
        coords={"wavenumber": ("wavenumber", q, {"units": "rad", "long_name": "wavenumber per period"}),
                "branch": ("branch", np.arange(size), {"long_name": "branch, from the lowest"})},
    )
    ds.attrs.update(gaps=band_gaps(freq), precompression=float(precompression), stiffness=k.tolist(),
                    beads_per_cell=n)
    return ds
