"""Fused Verlet steps of misaligned chains (bead centres off the axis): one vectorisable pass per step.

Called by :func:`hertzchain.integrate.core.kernels._verlet_run` for the blocks of a chain with offsets and
the elastic, Kuwabara-Kono or dashpot law (the elastic-plastic law keeps the general path's two
passes). Arrays and layout as in :mod:`hertzchain.integrate.core.kernels`.

A step is the general path's arithmetic (``kernels.forces_general`` at the velocities predicted half
a step ahead, then the accelerations and the kick-drift loop), fused as
:func:`~hertzchain.integrate.core.kernels.step_elastic` fuses the aligned elastic step: the force of the
contact on a body's left is carried from the previous iteration (a first-order recurrence LLVM
vectorises), and every contact computes both the misaligned overlap
delta = R_j + R_{j+1} - sqrt(dx^2 + e_j^2), dx = dx0_j - (u_j - u_{j+1}), with its direction cosine
dx / sqrt(dx^2 + e_j^2) (docs/conventions.rst, misalignment) and the aligned one
u_j - u_{j+1} + d0_j, and selects by e_j != 0 instead of branching (a branch per contact kept the
loop scalar). The same operations in the same order per contact: positions, velocities,
accelerations, forces and the wall peak are those of the general path bit for bit; the dissipated
power of the viscous laws is summed in a vectorised order (its last bits may differ, within 1e-14
of its largest value; tests/test_fused.py).

The selects compute the misaligned branch on aligned slots too, padding included, where
dx = e = 0 gives 0 / 0: the functions use NumPy's error model (a NaN, discarded by the select)
instead of Python's (a ZeroDivisionError check per contact, which would also keep the loop scalar).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .primitives import DELTA_MIN, _track_peak, _viscous_force


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _offset_overlap(ui, uj, d0, de, dx0, rsum):
    """Overlap delta [m] and direction cosine of one contact, as ``kernels.forces_general`` computes
    them (misaligned when ``de`` != 0, else aligned with cosine 1), by selects."""
    dx = dx0 - (ui - uj)
    dist = np.sqrt(dx * dx + de * de)
    off = de != 0.0
    d = rsum - dist if off else ui - uj + d0
    c = dx / dist if off else 1.0
    return d, c


@njit(cache=True, nogil=True, inline="always")
def _advance(u, v, a, g, e, i, f, ei, fprev, fext, inv_mass, dt, half, last):
    """Store contact i's axial force ``f`` and Hertz energy ``ei``, then body i's acceleration
    (F_{i-1} - F_i + f_ext,i) / m_i (``fprev`` = F_{i-1}) and its kick and drift, v += dt a,
    u += dt v (or, when ``last``, the closing half kick v += half a), as the general path's loops."""
    g[i + 1] = f
    ai = (fprev - f + fext) * inv_mass
    a[i] = ai
    e[i] = ei  # every step: a store in the last step's branch alone kept the loop scalar
    if last:
        v[i] += half * ai
    else:
        v[i] += dt * ai
        u[i] += dt * v[i]


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def step_offset_elastic(u, v, a, g, e, kappa, d0, de, dx0, rsum, fext, inv_mass, dt, half, last):
    """One step of a misaligned elastic chain in one pass: the axial forces c kappa delta^(3/2)
    (paper eq. 1 along the line of centres), then v += dt a, u += dt v (or, when ``last``, the
    closing half kick v += half a); each contact's Hertz energy (2/5) kappa delta^(5/2) goes to
    ``e`` (for the probes after a block's last step). Iteration i reads u[i + 1] before iteration
    i + 1 writes it."""
    fprev = 0.0
    for i in range(a.shape[0]):
        d, c = _offset_overlap(u[i], u[i + 1], d0[i], de[i], dx0[i], rsum[i])
        dd = d if d > DELTA_MIN else 0.0
        fel = kappa[i] * dd * np.sqrt(dd)
        f = c * fel
        f = f if d >= 0.0 else 0.0
        _advance(u, v, a, g, e, i, f, 0.4 * fel * dd, fprev, fext[i], inv_mass[i], dt, half, last)
        fprev = f


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _offset_viscous(ui, uj, vq, vq1, kappa, damping, d0, de, dx0, rsum, law):
    """Axial viscoelastic or dashpot force of one contact [N] at the predicted velocities ``vq``,
    ``vq1`` of its bodies, the power it dissipates [W] and its Hertz energy (2/5) kappa
    delta^(5/2) [J], as ``kernels.forces_general``: closing rate c (v_j - v_{j+1}), force
    F(delta, rate) along the line of centres, axial part c F."""
    d, c = _offset_overlap(ui, uj, d0, de, dx0, rsum)
    rate = c * (vq - vq1)
    f, fel = _viscous_force(d, rate, kappa, damping, law)  # 0 for an open contact (d < 0)
    # c f, not a select of 0 for d < 0 (the force already is 0; a second select there kept the loop
    # scalar): the same number as forces_general's 0, but for its sign when c < 0 (a pair whose
    # centres passed each other along the axis, with no contact anyway)
    return c * f, (f - fel) * rate, 0.4 * fel * (d if d > DELTA_MIN else 0.0)


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def step_offset_dissipative(u, v, a, g, e, kappa, damping, d0, de, dx0, rsum, fext, inv_mass, law, dt, half, last):
    """One step of a misaligned viscoelastic or dashpot chain in one pass, as
    ``kernels.step_dissipative`` for an aligned one: the forces of :func:`_offset_viscous` at the
    velocities predicted half a step ahead, v + (dt/2) a (carried from body to body), then the kick
    and drift (or the closing half kick); the contacts' Hertz energies go to ``e``. Returns the
    dissipated power [W]. The last slot (padding) is peeled off: its right neighbour's prediction
    is 0, as in ``forces_general``."""
    n = a.shape[0]
    power = 0.0
    fprev = 0.0
    vq = v[0] + half * a[0]
    for i in range(n - 1):
        vq1 = v[i + 1] + half * a[i + 1]
        f, p, ei = _offset_viscous(u[i], u[i + 1], vq, vq1, kappa[i], damping[i], d0[i], de[i], dx0[i], rsum[i],
                                   law)
        power += p
        _advance(u, v, a, g, e, i, f, ei, fprev, fext[i], inv_mass[i], dt, half, last)
        fprev = f
        vq = vq1
    i = n - 1
    f, p, ei = _offset_viscous(u[i], u[i + 1], vq, 0.0, kappa[i], damping[i], d0[i], de[i], dx0[i], rsum[i], law)
    _advance(u, v, a, g, e, i, f, ei, fprev, fext[i], inv_mass[i], dt, half, last)
    return power + p


@njit(cache=True, nogil=True, error_model="numpy")
def offset_elastic_block(u, v, a, g, e, kappa, d0, de, dx0, rsum, fext, inv_mass, ns, dt, t0, wall_slot, peak):
    """The ``ns`` steps of a block of ``kernels._verlet_run`` for a misaligned elastic chain
    (:func:`step_offset_elastic`; the block's opening half kick and drift done by the caller), with
    the wall peak; ``e`` receives the contacts' Hertz energies at the block's end
    (:func:`energies_offset`). No power: the elastic law dissipates nothing (the general path adds
    zeros)."""
    half = 0.5 * dt
    for s in range(ns):
        if s < ns - 1:
            step_offset_elastic(u, v, a, g, e, kappa, d0, de, dx0, rsum, fext, inv_mass, dt, half, False)
        else:
            step_offset_elastic(u, v, a, g, e, kappa, d0, de, dx0, rsum, fext, inv_mass, dt, half, True)
        _track_peak(g[wall_slot + 1], t0 + (s + 1) * dt, dt, peak)


@njit(cache=True, nogil=True, error_model="numpy", fastmath={"reassoc"})
def offset_dissipative_block(u, v, a, g, e, kappa, damping, d0, de, dx0, rsum, fext, inv_mass, law, ns, dt, t0,
                             wall_slot, peak, acc):
    """The ``ns`` steps of a block of ``kernels._verlet_run`` for a misaligned viscoelastic or
    dashpot chain (:func:`step_offset_dissipative`), with the dissipated energy's trapezoidal
    integral in acc[0:2], the wall peak and the contacts' Hertz energies at the block's end in
    ``e``; as ``kernels.dissipative_block``, whose power sum may be reassociated (the forces,
    positions and velocities do not depend on it)."""
    half = 0.5 * dt
    for s in range(ns):
        if s < ns - 1:
            p = step_offset_dissipative(u, v, a, g, e, kappa, damping, d0, de, dx0, rsum, fext, inv_mass, law, dt,
                                        half, False)
        else:
            p = step_offset_dissipative(u, v, a, g, e, kappa, damping, d0, de, dx0, rsum, fext, inv_mass, law, dt,
                                        half, True)
        acc[0] += half * (acc[1] + p)  # trapezoidal integral of the dissipated power
        acc[1] = p
        _track_peak(g[wall_slot + 1], t0 + (s + 1) * dt, dt, peak)


@njit(cache=True, nogil=True, fastmath={"reassoc"})
def energies_offset(u, v, mass, fext, e):
    """(kinetic, potential) energy [J] at a block's end from the contact energies ``e`` its last
    step stored: the sum of m v^2 / 2, and of (2/5) kappa delta^(5/2) minus the work of f_ext, in
    one vectorised pass without a square root (``kernels.kinetic_energy`` and
    ``kernels.potential_energy``'s numbers up to rounding: ~10 instead of ~65 ns a sample for
    32 slots). The sums may be reassociated, as the energies of ``energies.py``."""
    ke = 0.0
    pe = 0.0
    for i in range(mass.shape[0]):
        ke += mass[i] * v[i] * v[i]
        pe += e[i] - fext[i] * u[i]
    return 0.5 * ke, pe
