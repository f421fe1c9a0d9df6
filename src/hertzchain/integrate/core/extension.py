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

The stepping itself is a block of steps built here for a contact-force pass
(:func:`extended_steps`: ``kernels.step_extended`` for the hand-written laws, the generated
engines' own for a registry law, :mod:`hertzchain.integrate.core.generated`); the functions here
are its forces, accelerations and energies, also used by ``verlet.initialise`` and the scipy reference. The law of the extension
is written once, as scalar functions of one contact or one body (:func:`linear_force`,
:func:`body_accelerations`, :func:`internal_acceleration`, :func:`body_energies`,
:func:`extended_bound`): the array loops here
and in ``kernels`` call them, and the CUDA engine compiles their Python source as device functions
(:mod:`hertzchain.integrate.cuda.extension`), so both integrate the same arithmetic.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .primitives import LAW_DASHPOT, LAW_ELASTIC, _track_peak

__all__ = ["EXT_KLIN", "EXT_CLIN", "EXT_KIN", "EXT_MIN", "EXT_IMIN", "EXT_W", "EXT_WV", "EXT_ACC", "EXT_COLUMNS",
           "linear_force", "body_accelerations", "internal_acceleration", "body_energies", "extended_bound",
           "forces_linear", "accelerations_extended", "energies_extended", "extended_steps", "extension_stride",
           "sample_extension", "close_sample"]

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


@njit(cache=True, nogil=True)
def sample_extension(k, u, v, a, d0, ext, body_slot, out_b):
    """At sample ``k``: the protected body's record (``body_slot`` >= 0: out_b[k] = displacement [m],
    velocity [m/s], acceleration [m/s^2], work done on it so far [J]); returns the extension's
    (kinetic energy of the internal masses, elastic energy of the linear and internal springs) [J]."""
    if body_slot >= 0:
        out_b[k, 0] = u[body_slot]
        out_b[k, 1] = v[body_slot]
        out_b[k, 2] = a[body_slot]
        out_b[k, 3] = ext[0, EXT_ACC]
    return energies_extended(u, d0, ext)


@njit(cache=True, nogil=True)
def extension_stride(ext, inv_mass, block, c_steps):
    """Steps per block that the extension alone needs (omega dt <= 1 / c_steps, the Gershgorin rows
    of :func:`extended_bound` with the contact law left out): a law's own bound plus this one bounds
    the whole system's, since sqrt(om2 + beta^2 / 4) + beta / 2 is subadditive in (om2, beta)."""
    weff = 0.0
    kprev = 0.0
    cprev = 0.0
    for i in range(ext.shape[0]):
        w, kprev, cprev = extended_bound(kprev, 0.0, cprev, 0.0, LAW_ELASTIC, ext[i, EXT_KLIN], ext[i, EXT_CLIN],
                                         ext[i, EXT_KIN], ext[i, EXT_IMIN], inv_mass[i])
        weff = max(weff, w)
    return int(math.ceil(block * c_steps * weff - 1e-9))


def extended_steps(forces):
    """The block of ``ns`` steps of a model with the extension, for the contact-force pass ``forces``
    (the signature of ``kernels.forces_general``: positions, predicted velocities, the contact
    arrays, the law's code, the forces ``g`` it writes and the per-contact state; returns the
    contacts' dissipated power [W]). Written once for every law: the hand-written laws'
    ``kernels.step_extended`` and a registry law's generated run (:mod:`.generated`) are this
    block around their own force pass.

    The same kick-drift-kick as the general path, the internal masses (``ext``) stepped with the
    beads; the mount's dashpot uses the predicted velocities, as the dissipative contacts do, and
    its power joins the dissipated energy. With a protected body (``body_slot`` >= 0) the power
    F_N v_body that contact N delivers to it is integrated (trapezoidal) into ext[0, EXT_ACC].
    """
    @njit(nogil=True)
    def step_extended(u, v, vp, a, wa, g, kappa, damping, d0, de, dx0, rsum, fext, inv_mass, law, dyield, dmax, dres,
                      kres, ext, body_slot, wall_slot, t0, dt, ns, peak, acc):
        n = a.shape[0]
        half = 0.5 * dt
        for i in range(n):
            v[i] += half * a[i]
            u[i] += dt * v[i]
            ext[i, EXT_WV] += half * wa[i]
            ext[i, EXT_W] += dt * ext[i, EXT_WV]
        for s in range(ns):
            for i in range(n):
                vp[i] = v[i] + half * a[i]
            p = forces(u, vp, kappa, damping, d0, de, dx0, rsum, law, g, dyield, dmax, dres, kres)
            p += forces_linear(u, vp, d0, ext, g)
            acc[0] += half * (acc[1] + p)  # trapezoidal integral of the dissipated power
            acc[1] = p
            if body_slot >= 0:
                pb = g[body_slot] * vp[body_slot]  # contact N (g[N + 1]) pushing body N + 1
                ext[0, EXT_ACC] += half * (ext[1, EXT_ACC] + pb)
                ext[1, EXT_ACC] = pb
            _track_peak(g[wall_slot + 1], t0 + (s + 1) * dt, dt, peak)
            accelerations_extended(u, g, fext, inv_mass, ext, a, wa)
            if s < ns - 1:
                for i in range(n):
                    v[i] += dt * a[i]
                    u[i] += dt * v[i]
                    ext[i, EXT_WV] += dt * wa[i]
                    ext[i, EXT_W] += dt * ext[i, EXT_WV]
            else:
                for i in range(n):
                    v[i] += half * a[i]
                    ext[i, EXT_WV] += half * wa[i]
    return step_extended


@njit(cache=True, nogil=True, inline="always")
def close_sample(k, ke, pe, u, v, a, g, d0, extension, probes, acc, step):
    """The end of sample ``k`` that every Verlet loop shares (``kernels._verlet_run`` and a registry
    law's generated run): the extension's energies added to the kinetic ``ke`` and potential ``pe``
    energies [J] and its body recorded (``extension``: :class:`~.structures.Extension`), then the
    energies, the dissipated energy acc[0] and the velocities (when recorded) written to ``probes``
    (:class:`~.structures.VerletProbes`). Returns 1 when the state (the energy, the first contact's
    force g[1]) is no longer finite (acc[2] then holds ``step``, the steps taken), else 0."""
    ext, ext_on, body_slot = extension
    _, _, out_ke, out_pe, out_ed, _, out_v, record_v, _, _, _, _, out_b = probes
    if ext_on:
        ke_in, pe_lin = sample_extension(k, u, v, a, d0, ext, body_slot, out_b)
        ke += ke_in
        pe += pe_lin
    out_ke[k] = ke
    out_pe[k] = pe
    out_ed[k] = acc[0]
    if record_v:
        for i in range(out_v.shape[1]):
            out_v[k, i] = v[i]
    if not np.isfinite(ke) or not np.isfinite(g[1]):
        acc[2] = step
        return 1
    return 0
