"""Compiled pieces every CPU stepping kernel shares: the contact-law codes, the overlap floor, the
viscous force of one contact and the wall-peak tracker.

They live below both :mod:`hertzchain.integrate.core.kernels` (the Verlet loop, which re-exports them)
and :mod:`hertzchain.integrate.core.fused` (the fused steps of misaligned chains), so that neither
imports the other's callers. Unit-free SI floats, as in ``kernels``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

LAW_ELASTIC, LAW_VISCOELASTIC, LAW_DASHPOT, LAW_ELASTOPLASTIC = 0, 1, 2, 3

#: Overlaps below this [m] count as zero (forces below ~1e-35 N). Without it the numerical
#: precursor ahead of a pulse decays into subnormal floats (~1e-300), which x86 handles ~30x
#: slower: 2.4 instead of 1.6 ns per bead-step while a pulse crosses a 30-bead chain.
DELTA_MIN = 1e-30


#: Viscous contact forces at or below this [N] count as zero (the dissipative laws' counterpart of
#: DELTA_MIN). A dashpot pushes at zero overlap (gamma d(delta)/dt, the d == 0 convention of
#: ``plastic.contact_general``), so in an uncompressed chain its precursor ran ahead of the pulse
#: through touching beads, decaying into subnormal velocities and forces (~1e-320): 300 beads,
#: 1.2 instead of 0.9 ns per bead-step (benchmarks/laws.py). At 1e-100 N the precursor's
#: velocities (~1e-110 m/s) and the products of the dissipated power (~1e-210 W) stay normal
#: floats, and every Hertz force is above it (kappa DELTA_MIN^(3/2) = kappa 1e-45 N), so that
#: A = 0 and gamma = 0 still give the elastic law's forces bit for bit.
FORCE_MIN = 1e-100


@njit(cache=True, nogil=True, inline="always")
def damped_force(d, rate, kappa, c, visco):
    """The viscoelastic (``visco``) or dashpot force at overlap d [m] and rate [m/s] (along the line
    of centres), with the law's damping as a per-contact constant ``c``: kappa A [N s/m^1.5]
    (Kuwabara-Kono, F = kappa delta^(3/2) + kappa A delta^(1/2) d(delta)/dt) or gamma [N s/m]
    (dashpot); returns (force, elastic part). Forces at or below FORCE_MIN and open contacts give
    0 through selects (vectorised). ``c`` = kappa A computed once (:func:`damping_constants`)
    is the product that kappa A delta^(1/2) rate evaluates first: the same numbers, one
    multiplication less per contact and step. An open Kuwabara-Kono contact (d < 0) has
    delta^(1/2) = 0 and so F = +-0, which the floor already selects to 0: only the dashpot, whose
    rate term pushes at any overlap, needs the select on d."""
    dd = d if d > DELTA_MIN else 0.0
    return damped_force_sd(d, dd, np.sqrt(dd), rate, kappa, c, visco)


@njit(cache=True, nogil=True, inline="always")
def damped_force_sd(d, dd, sd, rate, kappa, c, visco):
    """:func:`damped_force` given its clamped overlap ``dd`` (d where d > DELTA_MIN, else 0) and
    ``sd`` = sqrt(dd), for callers that need the square root again."""
    fel = kappa * dd * sd
    if visco:
        f = fel + c * sd * rate
        return (f if f > FORCE_MIN else 0.0), fel
    f = fel + c * rate
    return (f if (f > FORCE_MIN) & (d >= 0.0) else 0.0), fel


@njit(cache=True, nogil=True, inline="always")
def _viscous_force(d, rate, kappa, damping, law):
    """``kernels.forces_general``'s viscoelastic or dashpot force at overlap d and rate (along the
    line of centres), ``damping`` the law's parameter (A or gamma); returns (force, elastic part):
    :func:`damped_force`."""
    visco = law == LAW_VISCOELASTIC
    return damped_force(d, rate, kappa, kappa * damping if visco else damping, visco)


@njit(cache=True, nogil=True)
def damping_constants(kappa, damping, law, c):
    """c_j = kappa_j A_j (Kuwabara-Kono) or gamma_j (dashpot), the per-contact constant of
    :func:`damped_force`, written into ``c``."""
    visco = law == LAW_VISCOELASTIC
    for j in range(kappa.shape[0]):
        c[j] = kappa[j] * damping[j] if visco else damping[j]


@njit(cache=True, nogil=True, inline="always")
def predict(v, a, half, vp):
    """vp_i = v_i + (dt/2) a_i for every body slot and vp[P] = 0 (no body beyond the last slot):
    the predicted velocities the dissipative forces see at a step's positions, which the fused
    viscous steps (``kernels.step_dissipative``) read on entry and leave for their next step."""
    n = a.shape[0]
    for i in range(n):
        vp[i] = v[i] + half * a[i]
    vp[n] = 0.0


@njit(cache=True, nogil=True, fastmath={"reassoc"})
def total(x):
    """The sum of ``x`` in any order (vectorised): the contacts' dissipated powers, whose sum in
    contact order (a chain of dependent additions) set the pace of a scalar step (~2x slower);
    only the dissipated energy's last bits depend on the order."""
    t = 0.0
    for j in range(x.shape[0]):
        t += x[j]
    return t


@njit(cache=True, nogil=True, inline="always")
def kick(u, v, vp, a, g, fext, inv_mass, dt, half, last):
    """The bodies' accelerations a_i = (F_{i-1} - F_i + f_ext,i) / m_i from the forces ``g``, then
    v += dt a, u += dt v with the next step's predicted velocities vp = v + (dt/2) a (or, when
    ``last``, the closing half kick v += half a): the numbers of the update loops of
    ``kernels._verlet_run``."""
    for i in range(a.shape[0]):
        ai = (g[i] - g[i + 1] + fext[i]) * inv_mass[i]
        a[i] = ai
        if last:
            v[i] += half * ai
        else:
            vi = v[i] + dt * ai
            v[i] = vi
            vp[i] = vi + half * ai
            u[i] += dt * vi


@njit(cache=True, nogil=True)
def _track_peak(fw, t, dt, peak):
    """Running maximum of the wall force with its neighbours (see ``kernels._verlet_run``)."""
    if fw > peak[0]:
        peak[0] = fw
        peak[1] = t
        peak[2] = peak[5]
        peak[6] = dt
        peak[4] = 1.0
    elif peak[4] != 0.0:
        peak[3] = fw
        peak[7] = dt
        peak[4] = 0.0
    peak[5] = fw


@njit(cache=True, nogil=True)
def running_max(fmax, g):
    """fmax = max(fmax, g) element by element (every contact's largest sampled force), on views of
    a thread's contacts (from index 0 the loop vectorises; from a block's first slot it did not)."""
    for j in range(fmax.shape[0]):
        x = g[j]
        fmax[j] = x if x > fmax[j] else fmax[j]


@njit(cache=True, nogil=True)
def open_block(u, v, a, dt, half):
    """A block's opening half kick and drift, v += (dt/2) a, u += dt v, on views of a thread's
    bodies (from index 0 the loop vectorises; from a block's first slot Numba kept it scalar)."""
    for i in range(a.shape[0]):
        v[i] += half * a[i]
        u[i] += dt * v[i]
