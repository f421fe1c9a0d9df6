"""Compiled pieces of the engine's extension: a protected body's mount and mass-in-mass beads.

A model with a protected body or mass-in-mass beads (``System.extended``) carries, besides the
arrays of :mod:`hertzchain.integrate.core.kernels`, an extension array ``ext`` of shape
(P, EXT_COLUMNS) (built by ``layout.extension``):

- per contact slot j, a linear spring (EXT_KLIN [N/m]) and dashpot (EXT_CLIN [N s/m]) acting on
  the overlap u_j - u_{j+1} + d0_j in parallel with the contact law; they pull as well as push.
  The protected body's mount is contact N + 1, between the body (slot N + 1) and the immovable
  ghost N + 2;
- per body slot i, an internal mass (EXT_MIN [kg], its inverse EXT_IMIN) on a spring (EXT_KIN
  [N/m]) inside the body, its displacement EXT_W [m] and velocity EXT_WV [m/s] (state, measured
  from the place where its spring is relaxed);
- column EXT_ACC: row 0 the work [J] contact N has done on a protected body so far, row 1 that
  power [W] at the last step (the trapezoidal rule's memory, carried from chunk to chunk).

The stepping itself is ``kernels.step_extended``; the functions here are its forces, accelerations
and energies, also used by ``verlet.initialise`` and the scipy reference.
"""

from __future__ import annotations

from numba import njit

__all__ = ["EXT_KLIN", "EXT_CLIN", "EXT_KIN", "EXT_MIN", "EXT_IMIN", "EXT_W", "EXT_WV", "EXT_ACC", "EXT_COLUMNS",
           "forces_linear", "accelerations_extended", "energies_extended"]

#: Columns of the extension array ``ext`` (see the module docstring).
EXT_KLIN, EXT_CLIN, EXT_KIN, EXT_MIN, EXT_IMIN, EXT_W, EXT_WV, EXT_ACC = range(8)
EXT_COLUMNS = 8


@njit(cache=True, nogil=True)
def forces_linear(u, v, d0, ext, g):
    """Add the linear springs and dashpots of ``ext`` to the contact forces ``g`` (g[j + 1] +=
    k_j delta_j + c_j d(delta_j)/dt, delta_j = u_j - u_{j+1} + d0_j); returns their dissipated power [W]."""
    power = 0.0
    for j in range(ext.shape[0]):
        k = ext[j, EXT_KLIN]
        c = ext[j, EXT_CLIN]
        if k != 0.0 or c != 0.0:
            rate = v[j] - v[j + 1]
            g[j + 1] += k * (u[j] - u[j + 1] + d0[j]) + c * rate
            power += c * rate * rate
    return power


@njit(cache=True, nogil=True)
def accelerations_extended(u, g, fext, inv_mass, ext, a, wa):
    """``kernels.accelerations`` with the internal springs: a_i = (F_{i-1} - F_i + f_ext,i + k_in (w_i - u_i)) / m_i
    and the internal masses' wa_i = k_in (u_i - w_i) / m_in (mass-in-mass beads)."""
    for i in range(a.shape[0]):
        s = ext[i, EXT_KIN] * (ext[i, EXT_W] - u[i])
        a[i] = (g[i] - g[i + 1] + fext[i] + s) * inv_mass[i]
        wa[i] = -s * ext[i, EXT_IMIN]


@njit(cache=True, nogil=True, fastmath={"reassoc"})
def energies_extended(u, d0, ext):
    """(kinetic energy of the internal masses, elastic energy of the linear and internal springs) [J]."""
    ke = 0.0
    pe = 0.0
    for i in range(ext.shape[0]):
        wv = ext[i, EXT_WV]
        x = ext[i, EXT_W] - u[i]
        d = u[i] - u[i + 1] + d0[i]
        ke += 0.5 * ext[i, EXT_MIN] * wv * wv
        pe += 0.5 * (ext[i, EXT_KIN] * x * x + ext[i, EXT_KLIN] * d * d)
    return ke, pe
