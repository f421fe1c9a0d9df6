"""Compiled (Numba) contact forces and the velocity-Verlet stepping loop.

Everything here is unit-free SI floats. The arrays are the :class:`hertzchain.model.System`
arrays laid out for speed by :func:`hertzchain.integrate.layout.pack` (``P`` slots, a multiple
of 8, so the vector loops run without a scalar remainder on short chains):

- bodies 0..P-1: 0 striker, 1..N beads, N + 1 the immovable wall ghost, then dummies; ``u`` and
  ``v`` have one extra slot P so that contact P - 1 can read u[P];
- ``g`` (P + 1,) holds contact forces shifted by one: g[0] = 0 and g[j + 1] = F_j, so that the
  acceleration of body i is (g[i] - g[i + 1] + f_ext,i) / m_i with no special first body.

Padding bodies and contacts have 1/m = 0 and kappa = 0 and never move or push. The contact
forces are written once (:func:`forces_elastic`, branch-free so that LLVM vectorises it, and
:func:`forces_general` for dissipative laws and misaligned beads); the same functions serve the
Verlet loop and the scipy reference RHS, so both integrate the same equations (paper eq. 1).
Probes are sampled inside the loop every ``stride`` steps (no Python call per step).
"""

from __future__ import annotations

import numpy as np
from numba import njit

LAW_ELASTIC, LAW_VISCOELASTIC, LAW_DASHPOT = 0, 1, 2

#: Overlaps below this [m] count as zero (forces below ~1e-35 N). Without it the numerical
#: precursor ahead of a pulse decays into subnormal floats (~1e-300), which x86 handles ~30x
#: slower: 2.4 instead of 1.6 ns per bead-step while a pulse crosses a 30-bead chain.
DELTA_MIN = 1e-30


@njit(cache=True, nogil=True)
def forces_elastic(u, kappa, d0, g):
    """Aligned Hertz forces g[j+1] = kappa_j max(delta_j, 0)^(3/2), delta_j = u_j - u_{j+1} + d0_j (eq. 1)."""
    for j in range(kappa.shape[0]):
        d = u[j] - u[j + 1] + d0[j]
        d = d if d > DELTA_MIN else 0.0
        g[j + 1] = kappa[j] * d * np.sqrt(d)


@njit(cache=True, nogil=True)
def forces_general(u, v, kappa, damping, d0, de, dx0, rsum, law, g):
    """Axial contact forces with dissipation and/or misalignment; returns the dissipated power [W].

    For a misaligned pair (de_j != 0) the distance of centres is d = sqrt(dx^2 + de^2),
    delta = R_j + R_{j+1} - d and the axial force is F(delta) dx / d (DESIGN.md section 2).
    Kuwabara-Kono: F = kappa (delta^(3/2) + A delta^(1/2) ddelta/dt); dashpot:
    F = kappa delta^(3/2) + gamma ddelta/dt; both clipped at zero (never attractive).
    """
    power = 0.0
    for j in range(kappa.shape[0]):
        if de[j] != 0.0:
            dx = dx0[j] - (u[j] - u[j + 1])
            dist = np.sqrt(dx * dx + de[j] * de[j])
            d = rsum[j] - dist
            c = dx / dist
        else:
            d = u[j] - u[j + 1] + d0[j]
            c = 1.0
        # d == 0 is kept as a contact: at the impact instant (t = 0, striker just touching) the
        # dashpot force is already gamma d(delta)/dt = gamma v0 (the law jumps at closure); taking
        # 0 there instead made Verlet's first half kick miss an O(dt) impulse (first-order error).
        # The elastic part and the Kuwabara-Kono term (~ delta^(1/2)) vanish at d == 0 anyway.
        if d < 0.0:
            g[j + 1] = 0.0
            continue
        if d <= DELTA_MIN:
            d = 0.0
        sd = np.sqrt(d)
        fel = kappa[j] * d * sd
        if law == LAW_ELASTIC:
            g[j + 1] = c * fel
            continue
        rate = c * (v[j] - v[j + 1])  # d(delta)/dt
        if law == LAW_VISCOELASTIC:
            f = fel + kappa[j] * damping[j] * sd * rate
        else:
            f = fel + damping[j] * rate
        f = max(f, 0.0)
        power += (f - fel) * rate  # F_diss * d(delta)/dt >= 0: power lost to dissipation
        g[j + 1] = c * f
    return power


@njit(cache=True, nogil=True)
def accelerations(g, fext, inv_mass, a):
    """a_i = (F_{i-1} - F_i + f_ext,i) / m_i for every slot (1/m = 0 for the wall and padding)."""
    for i in range(a.shape[0]):
        a[i] = (g[i] - g[i + 1] + fext[i]) * inv_mass[i]


@njit(cache=True, nogil=True)
def potential_energy(u, g, kappa, d0, de, dx0, rsum, fext, aligned_elastic):
    """Hertz potential sum (2/5) kappa delta^(5/2) (paper Sec. III) minus the work of f_ext [J].

    For an aligned elastic chain U_j = (2/5) F_j delta_j reuses the forces (no extra sqrt).
    """
    e = 0.0
    if aligned_elastic:
        for j in range(kappa.shape[0]):
            d = u[j] - u[j + 1] + d0[j]
            e += 0.4 * g[j + 1] * max(d, 0.0)
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


@njit(cache=True, nogil=True)
def kinetic_energy(v, mass):
    """Sum of m v^2 / 2 over the slots [J] (mass = 0 for the wall and padding)."""
    e = 0.0
    for i in range(mass.shape[0]):
        e += 0.5 * mass[i] * v[i] * v[i]
    return e


@njit(cache=True, nogil=True)
def _track_peak(fw, step, peak):
    """Running maximum of the wall force with its neighbours (see verlet_run)."""
    if fw > peak[0]:
        peak[0] = fw
        peak[1] = step
        peak[2] = peak[5]
        peak[4] = 1.0
    elif peak[4] != 0.0:
        peak[3] = fw
        peak[4] = 0.0
    peak[5] = fw


@njit(cache=True, nogil=True)
def verlet_run(u, v, a, g, mass, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, law, general,
               wall_slot, dt, stride, k_start, k_stop, rec, out_f, out_ke, out_pe, out_ed, out_v, record_v,
               fmax, peak, acc):
    """Advance ``(k_stop - k_start) * stride`` velocity-Verlet steps, sampling after every stride.

    On entry and exit ``u, v, a, g`` hold positions, synchronised velocities, accelerations and
    forces at a sample time, so a run can be split into chunks (progress bars, checkpoints).
    Between samples the half kicks of consecutive steps are fused (leapfrog form): one pass over
    the contacts and one over the bodies per step. ``acc`` holds [dissipated energy (J), last
    dissipated power (W), global step count]. ``peak`` tracks contact ``wall_slot`` (the wall):
    [max force, step of max, force one step before, force one step after, waiting flag, previous
    force]; the parabola through the three gives the peak between steps. Sample k of ``out_f``
    receives the forces of the contacts listed in ``rec``; ``fmax`` keeps every contact's largest
    sampled force, stored or not, for the elastic-limit check. Returns 0, or 1 when the state
    became non-finite.

    Velocities used by the dissipative forces at t + dt are predicted as v(t + dt/2) + a(t) dt/2;
    the error is O(dt^2) per step, so the scheme stays second order.
    """
    n = a.shape[0]
    nout = rec.shape[0]
    half = 0.5 * dt
    vp = np.zeros_like(v)
    step = int(acc[2])
    for k in range(k_start, k_stop):
        for i in range(n):
            v[i] += half * a[i]
            u[i] += dt * v[i]
        for s in range(stride):
            if general:
                for i in range(n):
                    vp[i] = v[i] + half * a[i]
                p = forces_general(u, vp, kappa, damping, d0, de, dx0, rsum, law, g)
                acc[0] += half * (acc[1] + p)  # trapezoidal integral of the dissipated power
                acc[1] = p
            else:
                forces_elastic(u, kappa, d0, g)
            step += 1
            _track_peak(g[wall_slot + 1], step, peak)
            if s < stride - 1:
                for i in range(n):
                    a[i] = (g[i] - g[i + 1] + fext[i]) * inv_mass[i]
                    v[i] += dt * a[i]
                    u[i] += dt * v[i]
            else:
                for i in range(n):
                    a[i] = (g[i] - g[i + 1] + fext[i]) * inv_mass[i]
                    v[i] += half * a[i]
        # --- probes, sampled inside the compiled loop
        for j in range(nout):
            out_f[k, j] = g[rec[j] + 1]
        for j in range(fmax.shape[0]):
            fmax[j] = max(fmax[j], g[j + 1])
        ke = kinetic_energy(v, mass)
        out_ke[k] = ke
        out_pe[k] = potential_energy(u, g, kappa, d0, de, dx0, rsum, fext, not general)
        out_ed[k] = acc[0]
        if record_v:
            for i in range(out_v.shape[1]):
                out_v[k, i] = v[i]
        if not np.isfinite(ke) or not np.isfinite(g[1]):
            acc[2] = step
            return 1
    acc[2] = step
    return 0
