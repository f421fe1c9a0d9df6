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
and energies, also used by ``verlet.initialise`` and the scipy reference. The law of the extension
is written once, as scalar functions of one contact or one body (:func:`linear_force`,
:func:`body_accelerations`, :func:`internal_acceleration`, :func:`body_energies`,
:func:`extended_bound`): the array loops here
and in ``kernels`` call them, and the CUDA engine compiles their Python source as device functions
(:mod:`hertzchain.integrate.cuda.extension`), so both integrate the same arithmetic.
"""

from __future__ import annotations

import math

from numba import njit

from .primitives import LAW_DASHPOT, LAW_ELASTIC

__all__ = ["EXT_KLIN", "EXT_CLIN", "EXT_KIN", "EXT_MIN", "EXT_IMIN", "EXT_W", "EXT_WV", "EXT_ACC", "EXT_COLUMNS",
           "linear_force", "body_accelerations", "internal_acceleration", "body_energies", "extended_bound",
           "forces_linear", "accelerations_extended", "energies_extended"]

#: Columns of the extension array ``ext`` (see the module docstring).
EXT_KLIN, EXT_CLIN, EXT_KIN, EXT_MIN, EXT_IMIN, EXT_W, EXT_WV, EXT_ACC = range(8)
EXT_COLUMNS = 8


@njit(cache=True, nogil=True, inline="always")
def linear_force(k, c, d, rate):
    """A contact slot's linear spring k [N/m] and dashpot c [N s/m] at overlap d [m] closing at
    ``rate`` [m/s]: (force k d + c rate [N], dissipated power c rate^2 [W])."""
    return k * d + c * rate, c * rate * rate


@njit(cache=True, nogil=True, inline="always")
def body_accelerations(fl, fr, fext, inv_mass, k_in, w, u, inv_m_in):
    """Body at ``u`` [m] between contact forces ``fl`` (left) and ``fr`` (right) [N], external force
    ``fext`` [N], with an internal mass (1/m_in = ``inv_m_in``) at ``w`` [m] on a spring ``k_in`` [N/m]:
    (a = (F_l - F_r + f_ext + k_in (w - u)) / m, the internal mass's k_in (u - w) / m_in) [m/s^2]."""
    s = k_in * (w - u)
    return (fl - fr + fext + s) * inv_mass, -s * inv_m_in


@njit(cache=True, nogil=True, inline="always")
def internal_acceleration(k_in, w, u, inv_m_in):
    """Acceleration [m/s^2] of an internal mass (1/m_in = ``inv_m_in``) at ``w`` [m] on a spring
    ``k_in`` [N/m] to its body at ``u`` [m]: k_in (u - w) / m_in, a function of the positions (the
    state a run starts from; :func:`body_accelerations` gives it with the body's)."""
    return k_in * (u - w) * inv_m_in


@njit(cache=True, nogil=True, inline="always")
def body_energies(m_in, wv, k_in, x, k_lin, d):
    """Body slot i's extension energies [J]: (kinetic 0.5 m_in wv^2 of its internal mass, elastic
    0.5 (k_in x^2 + k_lin d^2) of its internal spring, stretched by x, and of contact i's linear
    spring, at overlap d)."""
    return 0.5 * m_in * wv * wv, 0.5 * (k_in * x * x + k_lin * d * d)


@njit(cache=True, nogil=True, inline="always")
def extended_bound(kprev, k, cprev, damping, law, k_lin, c_lin, k_in, inv_m_in, inv_mass):
    """``kernels.required_stride``'s row of body j with the extension: contact j's tangent stiffness
    ``k`` [N/m] plus its linear spring, its damping (the law's, dashpot: gamma; Kuwabara-Kono:
    (2/3) A k; plus the linear dashpot), the left contact's ``kprev``, ``cprev``, the internal
    spring; returns (omega_eff [rad/s] of the body's row and of its internal mass's row 2 k_in / m_in,
    contact j's total stiffness, its total damping), as in System.max_frequency."""
    k += k_lin
    c = 0.0 if law == LAW_ELASTIC else (damping if law == LAW_DASHPOT else (2.0 / 3.0) * damping * k)
    c += c_lin
    om2 = 2.0 * (kprev + k + k_in) * inv_mass
    beta = 2.0 * (cprev + c) * inv_mass
    return max(math.sqrt(om2 + 0.25 * beta * beta) + 0.5 * beta, math.sqrt(2.0 * k_in * inv_m_in)), k, c


@njit(cache=True, nogil=True)
def forces_linear(u, v, d0, ext, g):
    """Add the linear springs and dashpots of ``ext`` to the contact forces ``g`` (g[j + 1] +=
    k_j delta_j + c_j d(delta_j)/dt, delta_j = u_j - u_{j+1} + d0_j); returns their dissipated power [W]."""
    power = 0.0
    for j in range(ext.shape[0]):
        k = ext[j, EXT_KLIN]
        c = ext[j, EXT_CLIN]
        if k != 0.0 or c != 0.0:
            f, p = linear_force(k, c, u[j] - u[j + 1] + d0[j], v[j] - v[j + 1])
            g[j + 1] += f
            power += p
    return power


@njit(cache=True, nogil=True)
def accelerations_extended(u, g, fext, inv_mass, ext, a, wa):
    """``kernels.accelerations`` with the internal springs: a_i = (F_{i-1} - F_i + f_ext,i + k_in (w_i - u_i)) / m_i
    and the internal masses' wa_i = k_in (u_i - w_i) / m_in (mass-in-mass beads)."""
    for i in range(a.shape[0]):
        a[i], wa[i] = body_accelerations(g[i], g[i + 1], fext[i], inv_mass[i], ext[i, EXT_KIN], ext[i, EXT_W], u[i],
                                         ext[i, EXT_IMIN])


@njit(cache=True, nogil=True, fastmath={"reassoc"})
def energies_extended(u, d0, ext):
    """(kinetic energy of the internal masses, elastic energy of the linear and internal springs) [J]."""
    ke = 0.0
    pe = 0.0
    for i in range(ext.shape[0]):
        k, p = body_energies(ext[i, EXT_MIN], ext[i, EXT_WV], ext[i, EXT_KIN], ext[i, EXT_W] - u[i], ext[i, EXT_KLIN],
                             u[i] - u[i + 1] + d0[i])
        ke += k
        pe += p
    return ke, pe
