"""Compiled energies of the probes: kinetic, Hertz potential (elastic and elastic-plastic), plastic
work. Called by the Verlet loop of :mod:`hertzchain.integrate.core.kernels` (which re-exports them),
the batched engines and the scipy reference; arrays as laid out there (``layout.pack``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: The energy sums may be reassociated, so that LLVM vectorises them: a strict left-to-right sum
#: of ~30 terms is a chain of dependent additions, and it made the probes ~4x slower than the step.
_SUMS = {"reassoc"}


@njit(cache=True, nogil=True, fastmath=_SUMS)
def potential_energy(u, g, kappa, d0, de, dx0, rsum, fext, aligned_elastic):
    """Hertz potential sum (2/5) kappa delta^(5/2) (paper Sec. III) minus the work of f_ext [J].

    For an aligned elastic chain U_j = (2/5) F_j delta_j reuses the forces (no extra sqrt).
    """
    e = 0.0
    if aligned_elastic:
        # Shifted views instead of u[j + 1], g[j + 1]: with the +1 in the index LLVM left this sum
        # scalar (~14 ns for 24 contacts instead of ~5). g = 0 wherever d <= 0, so no max().
        u1 = u[1:]
        g1 = g[1:]
        for j in range(kappa.shape[0]):
            e += g1[j] * (u[j] - u1[j] + d0[j])
        e *= 0.4
    else:
        for j in range(kappa.shape[0]):
            if de[j] != 0.0:
                dx = dx0[j] - (u[j] - u[j + 1])
                d = rsum[j] - np.sqrt(dx * dx + de[j] * de[j])
            else:
                d = u[j] - u[j + 1] + d0[j]
            if d > 0.0:
                e += 0.4 * kappa[j] * d * d * np.sqrt(d)
    for i in range(fext.shape[0]):
        e -= fext[i] * u[i]
    return e


@njit(cache=True, nogil=True, fastmath=_SUMS)
def potential_energy_plastic(u, d0, de, dx0, rsum, fext, dres, kres):
    """Elastic energy stored in elastic-plastic contacts minus the work of f_ext [J]: what each
    contact's unloading curve gives back, (2/5) kres (delta - dres)^(5/2) (Hertz's
    (2/5) kappa delta^(5/2) for a contact that never yielded: dres = 0, kres = kappa)."""
    e = 0.0
    for j in range(kres.shape[0]):
        if de[j] != 0.0:
            dx = dx0[j] - (u[j] - u[j + 1])
            d = rsum[j] - np.sqrt(dx * dx + de[j] * de[j])
        else:
            d = u[j] - u[j + 1] + d0[j]
        e += unloading_energy(d - dres[j], kres[j])
    for i in range(fext.shape[0]):
        e -= fext[i] * u[i]
    return e


@njit(cache=True, nogil=True, fastmath=_SUMS)
def plastic_work(kappa, dyield, dmax, dres):
    """Plastic work [J] done in all contacts so far, from each one's largest overlap alone.

    The work along Thornton's loading curve up to dmax, (2/5) F_y dyield + F_y (dmax - dyield)
    + (3/4) kappa dyield^(1/2) (dmax - dyield)^2, minus what its unloading curve stores,
    (2/5) F_max (dmax - dres); 0 for a contact that never passed dyield.
    """
    w = 0.0
    for j in range(kappa.shape[0]):
        w += contact_plastic_work(kappa[j], dyield[j], dmax[j], dres[j])
    return w


# The per-contact terms of the two sums above, plain Python with ``math``: their source is also
# the CUDA engine's device functions (hertzchain.integrate.cuda.kernels), so both engines record
# one definition of the elastic-plastic energies.

@njit(cache=True, nogil=True, inline="always")
def unloading_energy(x, kres):
    """Energy [J] an elastic-plastic contact gives back along its unloading curve at x = delta -
    dres [m]: (2/5) kres x^(5/2), 0 for x <= 0 (``kres`` [N/m^1.5])."""
    return 0.4 * kres * x * x * math.sqrt(x) if x > 0.0 else 0.0


@njit(cache=True, nogil=True, inline="always")
def contact_plastic_work(kappa, dyield, dmax, dres):
    """Plastic work [J] one contact has done (one term of :func:`plastic_work`): kappa
    [N/m^1.5], yield overlap, largest overlap and residual overlap [m]."""
    if dmax > dyield:
        sy = math.sqrt(dyield)
        fy = kappa * dyield * sy
        x = dmax - dyield
        fmax = fy + 1.5 * kappa * sy * x
        return 0.4 * fy * dyield + fy * x + 0.75 * kappa * sy * x * x - 0.4 * fmax * (dmax - dres)
    return 0.0


@njit(cache=True, nogil=True, fastmath=_SUMS)
def energies_elastic(u, v, g, mass, d0, fext):
    """(kinetic, potential) energy [J] of an aligned elastic chain, as :func:`kinetic_energy` and
    :func:`potential_energy` give them, in one vectorised pass (~20 ns a sample for 24 slots,
    against ~60 ns for the two separate sums)."""
    u1 = u[1:]
    g1 = g[1:]
    ke = 0.0
    pe = 0.0
    for i in range(mass.shape[0]):
        ke += mass[i] * v[i] * v[i]
        pe += 0.4 * g1[i] * (u[i] - u1[i] + d0[i]) - fext[i] * u[i]
    return 0.5 * ke, pe


@njit(cache=True, nogil=True, fastmath=_SUMS)
def kinetic_energy(v, mass):
    """Sum of m v^2 / 2 over the slots [J] (mass = 0 for the wall and padding)."""
    e = 0.0
    for i in range(mass.shape[0]):
        e += 0.5 * mass[i] * v[i] * v[i]
    return e
