"""Compiled (Numba) contact forces and the velocity-Verlet stepping loop.

Everything here is unit-free SI floats. The arrays are the :class:`hertzchain.model.System`
arrays laid out for speed by :func:`hertzchain.integrate.core.layout.pack` (``P`` slots, a multiple
of 8, so the vector loops run without a scalar remainder on short chains):

- bodies 0..P-1: 0 striker, 1..N beads, N + 1 the immovable wall ghost, then dummies; ``u`` and
  ``v`` have one extra slot P so that contact P - 1 can read u[P];
- ``g`` (P + 1,) holds contact forces shifted by one: g[0] = 0 and g[j + 1] = F_j, so that the
  acceleration of body i is (g[i] - g[i + 1] + f_ext,i) / m_i with no special first body.

Padding bodies and contacts have 1/m = 0 and kappa = 0 and never move or push. The
elastic-plastic law (Thornton 1997, :func:`elastoplastic_force`) also takes, per contact slot,
its yield overlap ``dyield`` and a state that lives as long as the run: the largest overlap
reached ``dmax``, and the unloading curve it implies, residual overlap ``dres`` and stiffness
``kres`` (``layout.pack`` starts them at 0, 0, kappa). A model with a protected body or
mass-in-mass beads (``System.extended``) also has an extension array ``ext`` (P, EXT_COLUMNS):
linear springs and dashpots in parallel with the contact law of a contact slot (the body's mount,
contact N + 1, to the immovable ghost N + 2), and an internal mass on a spring per body slot,
whose displacement and velocity are state (:func:`step_extended`). The contact
forces are written once (:func:`forces_elastic`, branch-free so that LLVM vectorises it, and
:func:`forces_general` for dissipative laws and misaligned beads); the same functions serve the
Verlet loop and the scipy reference RHS, so both integrate the same equations (paper eq. 1). The
Verlet loop's fused steps (one pass per step) compute the same numbers: :func:`step_elastic`,
:func:`step_dissipative` here, those of misaligned chains in :mod:`hertzchain.integrate.core.fused`.
Probes are sampled inside the loop every ``stride`` steps (no Python call per step).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numba import njit

# the energies of the probes (re-exported: kernels.potential_energy & co. are used throughout)
from .energies import (energies_elastic, kinetic_energy, plastic_work, potential_energy,  # noqa: F401
                       potential_energy_plastic)
from .extension import (EXT_ACC, EXT_CLIN, EXT_COLUMNS, EXT_IMIN, EXT_KIN, EXT_KLIN, EXT_W, EXT_WV,  # noqa: F401
                        accelerations_extended, energies_extended, extended_bound, extended_steps, forces_linear,
                        close_sample, internal_acceleration)

from .fused import energies_offset, offset_dissipative_block, offset_elastic_block
# the general path's contact and the elastic-plastic law (re-exported: kernels.elastoplastic_force & co.)
from .plastic import (CHECKPOINT_MIN_COLUMNS, CHECKPOINT_ROWS, contact_general, elastoplastic_force,  # noqa: F401
                      plastic_block)
# the law codes, the overlap floor and the helpers the fused steps share (re-exported: kernels.DELTA_MIN & co.)
from .primitives import (DELTA_MIN, FORCE_MIN, LAW_DASHPOT, LAW_ELASTIC, LAW_ELASTOPLASTIC,  # noqa: F401
                         LAW_VISCOELASTIC, _track_peak, _viscous_force, damped_force, damping_constants, kick, predict,
                         total)


@njit(cache=True, nogil=True)
def forces_elastic(u, kappa, d0, g):
    """Aligned Hertz forces g[j+1] = kappa_j max(delta_j, 0)^(3/2), delta_j = u_j - u_{j+1} + d0_j (eq. 1)."""
    for j in range(kappa.shape[0]):
        d = u[j] - u[j + 1] + d0[j]
        d = d if d > DELTA_MIN else 0.0
        g[j + 1] = kappa[j] * d * np.sqrt(d)


#: From this many slots on, steps use :func:`step_elastic_lean` (long chains are limited by memory
#: traffic); shorter chains keep :func:`step_elastic`, faster there (1.17 vs 1.48 ns per
#: bead-step on 30 beads). Both give the same numbers.
LEAN_SLOTS = 4096


@njit(cache=True, nogil=True, inline="always")
def step_elastic(u, v, a, g, kappa, d0, fext, inv_mass, dt):
    """One fused pass of the aligned elastic leapfrog: forces at u, then v += dt a, u += dt v.

    Same arithmetic as :func:`forces_elastic` followed by a loop over the bodies, in one loop: the
    force of the contact on a body's left is carried from the previous iteration (``fprev``),
    which LLVM vectorises as a first-order recurrence (a register shuffle). Two loops exchange the
    shifted forces and positions through memory instead, and a vector load that straddles two
    just-written vectors cannot be forwarded from the store buffer: that stall made a step of a
    30-bead chain ~25 % slower (10,000 beads: ~55 %). Iteration i reads u[i + 1] before
    iteration i + 1 writes it, so the order is that of two loops.
    Inlined by Numba (``inline="always"``): called through LLVM instead, the loop was not
    vectorised and a step took ~2.8x longer.
    """
    fprev = 0.0
    for i in range(a.shape[0]):
        d = u[i] - u[i + 1] + d0[i]
        d = d if d > DELTA_MIN else 0.0
        f = kappa[i] * d * np.sqrt(d)
        g[i + 1] = f
        ai = (fprev - f + fext[i]) * inv_mass[i]
        a[i] = ai
        v[i] += dt * ai
        u[i] += dt * v[i]
        fprev = f


@njit(cache=True, nogil=True, inline="always")
def step_elastic_lean(u, v, kappa, inv_mass, dt):
    """:func:`step_elastic` for a chain without precompression (d0 = fext = 0), storing neither
    forces nor accelerations (only a block's last step needs them, :func:`final_step_elastic`).

    Same numbers; ~50 instead of ~110 bytes of memory traffic per bead-step, which is what limits
    chains too long for the caches: 1e6 beads 3.3 -> 2.1 ns per bead-step, 1e4 beads 1.05 -> 0.66.
    """
    fprev = 0.0
    for i in range(inv_mass.shape[0]):
        d = u[i] - u[i + 1]
        d = d if d > DELTA_MIN else 0.0
        f = kappa[i] * d * np.sqrt(d)
        v[i] += dt * ((fprev - f) * inv_mass[i])
        u[i] += dt * v[i]
        fprev = f


@njit(cache=True, nogil=True, inline="always")
def contact_force(u, kappa, d0, j):
    """Force of aligned elastic contact j [N], exactly as :func:`step_elastic` computes it."""
    d = u[j] - u[j + 1] + d0[j]
    d = d if d > DELTA_MIN else 0.0
    return kappa[j] * d * np.sqrt(d)


@njit(cache=True, nogil=True, inline="always")
def final_step_elastic(u, v, a, g, kappa, d0, fext, inv_mass, half):
    """:func:`step_elastic` without the drift: forces at u, then the closing half kick v += half a.

    u is not written, so the probes that follow read positions that are not in flight in the
    store buffer (a vector load straddling two pending stores waits for them: ~40 ns a sample).
    """
    fprev = 0.0
    for i in range(a.shape[0]):
        d = u[i] - u[i + 1] + d0[i]
        d = d if d > DELTA_MIN else 0.0
        f = kappa[i] * d * np.sqrt(d)
        g[i + 1] = f
        ai = (fprev - f + fext[i]) * inv_mass[i]
        a[i] = ai
        v[i] += half * ai
        fprev = f


@njit(cache=True, nogil=True)
def forces_general(u, v, kappa, damping, d0, de, dx0, rsum, law, g, dyield, dmax, dres, kres):
    """Axial contact forces with dissipation and/or misalignment; returns the dissipated power [W].

    For a misaligned pair (de_j != 0) the distance of centres is d = sqrt(dx^2 + de^2),
    delta = R_j + R_{j+1} - d and the axial force is F(delta) dx / d (docs/conventions.rst, misalignment).
    Kuwabara-Kono: F = kappa (delta^(3/2) + A delta^(1/2) ddelta/dt); dashpot:
    F = kappa delta^(3/2) + gamma ddelta/dt; both clipped at zero (never attractive).
    Elastic-plastic (Thornton): :func:`elastoplastic_force`, whose state (``dmax``, ``dres``,
    ``kres``; unused by the other laws, which may pass empty arrays) is updated in place; the
    dissipated power returned is the viscous part's only (the plastic work follows from the
    state, :func:`plastic_work`). Each contact: :func:`contact_general`.
    """
    power = 0.0
    plastic = law == LAW_ELASTOPLASTIC
    for j in range(kappa.shape[0]):
        if plastic:
            g[j + 1], p, dmax[j], dres[j], kres[j] = contact_general(
                u[j], u[j + 1], v[j], v[j + 1], kappa[j], damping[j], d0[j], de[j], dx0[j], rsum[j], law, dyield[j],
                dmax[j], dres[j], kres[j], False)
        else:
            g[j + 1], p, _, _, _ = contact_general(u[j], u[j + 1], v[j], v[j + 1], kappa[j], damping[j], d0[j], de[j],
                                                   dx0[j], rsum[j], law, 0.0, 0.0, 0.0, 0.0, False)
        power += p
    return power


@njit(cache=True, nogil=True, inline="always")
def step_dissipative(u, v, vp, a, g, kappa, damping, d0, fext, inv_mass, law, dt, half, last):
    """One step of an aligned chain with the viscoelastic or dashpot law, fused into one pass (as
    :func:`step_elastic`): the forces of :func:`forces_general` at the velocities predicted half a
    step ahead, ``vp`` = v + (dt/2) a (P + 1 slots, vp[P] = 0; set by
    :func:`~hertzchain.integrate.core.primitives.predict` before a block's first step), then the kick
    and drift (or, when ``last``, the closing half kick); returns the dissipated power [W].

    The kick leaves the next step's predictions in ``vp`` (v + dt a + (dt/2) a, the numbers the
    next step would compute from v and a), so the pass covers every slot, the padding slot P - 1
    included (its right neighbour's prediction is vp[P] = 0, as in forces_general): a loop over
    P - 1 slots left LLVM's vectorised loop a long scalar remainder, and predicting at the start
    of the pass (a load straddling the vectors just stored) stalled on the store buffer; either
    cost ~2x. The same operations per contact in the same order as forces_general and the
    update loops of :func:`verlet_run` (the same forces, positions and velocities); the power is
    summed by :func:`dissipative_block` in a vectorised order (its last bits may differ)."""
    power = 0.0
    fprev = 0.0
    for i in range(a.shape[0]):
        rate = vp[i] - vp[i + 1]
        f, fel = _viscous_force(u[i] - u[i + 1] + d0[i], rate, kappa[i], damping[i], law)
        power += (f - fel) * rate
        g[i + 1] = f
        ai = (fprev - f + fext[i]) * inv_mass[i]
        a[i] = ai
        if last:
            v[i] += half * ai
        else:
            vi = v[i] + dt * ai
            v[i] = vi
            vp[i] = vi + half * ai
            u[i] += dt * vi
        fprev = f
    return power


@njit(cache=True, nogil=True, inline="always")
def step_damped(u, v, vp, a, g, kappa, c, d0, fext, inv_mass, visco, unloaded, dt, half, last):
    """:func:`step_dissipative` as the engine runs it: the same numbers, with the law's damping as
    the per-contact constants ``c`` (:func:`~.primitives.damping_constants`), the law
    (``visco``: Kuwabara-Kono, else the dashpot) and ``unloaded`` (every d0 and f_ext zero: the
    additions of zeros left out, as :func:`step_elastic_lean` does) compile-time constants of
    the caller: four to six floating-point operations fewer per contact than the general step's
    ~28, on a loop whose pace they set (300 beads: ~1.2 -> ~0.85 ns per bead-step with
    FORCE_MIN; benchmarks/laws.py). Adding a zero changes no number but the sign of a zero."""
    power = 0.0
    fprev = 0.0
    for i in range(a.shape[0]):
        rate = vp[i] - vp[i + 1]
        d = u[i] - u[i + 1] if unloaded else u[i] - u[i + 1] + d0[i]
        f, fel = damped_force(d, rate, kappa[i], c[i], visco)
        power += (f - fel) * rate
        g[i + 1] = f
        ai = (fprev - f) * inv_mass[i] if unloaded else (fprev - f + fext[i]) * inv_mass[i]
        a[i] = ai
        if last:
            v[i] += half * ai
        else:
            vi = v[i] + dt * ai
            v[i] = vi
            vp[i] = vi + half * ai
            u[i] += dt * vi
        fprev = f
    return power


@njit(cache=True, nogil=True, inline="always")
def _damped_steps(u, v, vp, a, g, kappa, c, d0, fext, inv_mass, visco, unloaded, ns, dt, t0, wall_slot, peak, acc):
    """The ``ns`` steps of :func:`dissipative_block` (``visco`` and ``unloaded`` constants)."""
    half = 0.5 * dt
    predict(v, a, half, vp)
    for s in range(ns):
        if s < ns - 1:
            p = step_damped(u, v, vp, a, g, kappa, c, d0, fext, inv_mass, visco, unloaded, dt, half, False)
        else:
            p = step_damped(u, v, vp, a, g, kappa, c, d0, fext, inv_mass, visco, unloaded, dt, half, True)
        acc[0] += half * (acc[1] + p)  # trapezoidal integral of the dissipated power
        acc[1] = p
        _track_peak(g[wall_slot + 1], t0 + (s + 1) * dt, dt, peak)


# One compiled block per law and loading (constants folded into the loop, no branch in it): a
# single block branching between the four loops inside its step loop was ~1.4x slower on chain 1.
@njit(cache=True, nogil=True, fastmath={"reassoc"})
def _kk_block(u, v, vp, a, g, kappa, c, d0, fext, inv_mass, ns, dt, t0, wall_slot, peak, acc):
    _damped_steps(u, v, vp, a, g, kappa, c, d0, fext, inv_mass, True, False, ns, dt, t0, wall_slot, peak, acc)


@njit(cache=True, nogil=True, fastmath={"reassoc"})
def _kk_block_unloaded(u, v, vp, a, g, kappa, c, d0, fext, inv_mass, ns, dt, t0, wall_slot, peak, acc):
    _damped_steps(u, v, vp, a, g, kappa, c, d0, fext, inv_mass, True, True, ns, dt, t0, wall_slot, peak, acc)


@njit(cache=True, nogil=True, fastmath={"reassoc"})
def _dashpot_block(u, v, vp, a, g, kappa, c, d0, fext, inv_mass, ns, dt, t0, wall_slot, peak, acc):
    _damped_steps(u, v, vp, a, g, kappa, c, d0, fext, inv_mass, False, False, ns, dt, t0, wall_slot, peak, acc)


@njit(cache=True, nogil=True, fastmath={"reassoc"})
def _dashpot_block_unloaded(u, v, vp, a, g, kappa, c, d0, fext, inv_mass, ns, dt, t0, wall_slot, peak, acc):
    _damped_steps(u, v, vp, a, g, kappa, c, d0, fext, inv_mass, False, True, ns, dt, t0, wall_slot, peak, acc)


@njit(cache=True, nogil=True)
def dissipative_block(u, v, vp, a, g, kappa, c, d0, fext, inv_mass, law, unloaded, ns, dt, t0, wall_slot, peak,
                      acc):
    """The ``ns`` steps of a block of :func:`verlet_run` for an aligned viscoelastic or dashpot
    chain (:func:`step_damped`, ``vp`` its P + 1 predicted velocities, ``c`` the damping constants
    of :func:`~.primitives.damping_constants`, ``unloaded``: every d0 and f_ext zero), with the
    dissipated energy's trapezoidal integral in acc[0:2] and the wall peak; functions of their own,
    called once per block (inlined into verlet_run's large body, LLVM left the fused loop scalar),
    whose power sum may be reassociated: in contact order it held the loop scalar (~1.8x slower);
    the forces, positions and velocities do not depend on it (tests/test_fused.py)."""
    if law == LAW_VISCOELASTIC and unloaded:
        _kk_block_unloaded(u, v, vp, a, g, kappa, c, d0, fext, inv_mass, ns, dt, t0, wall_slot, peak, acc)
    elif law == LAW_VISCOELASTIC:
        _kk_block(u, v, vp, a, g, kappa, c, d0, fext, inv_mass, ns, dt, t0, wall_slot, peak, acc)
    elif unloaded:
        _dashpot_block_unloaded(u, v, vp, a, g, kappa, c, d0, fext, inv_mass, ns, dt, t0, wall_slot, peak, acc)
    else:
        _dashpot_block(u, v, vp, a, g, kappa, c, d0, fext, inv_mass, ns, dt, t0, wall_slot, peak, acc)


@njit(cache=True, nogil=True)
def accelerations(g, fext, inv_mass, a):
    """a_i = (F_{i-1} - F_i + f_ext,i) / m_i for every slot (1/m = 0 for the wall and padding)."""
    for i in range(a.shape[0]):
        a[i] = (g[i] - g[i + 1] + fext[i]) * inv_mass[i]


#: One block of ``ns`` steps of the general path with the extension (see :func:`verlet_run` and
#: :func:`~.extension.extended_steps`, which writes it once for every law's force pass).
step_extended = extended_steps(forces_general)


@njit(cache=True, nogil=True)
def required_stride(u, v, a, kappa, d0, de, dx0, rsum, dcap, inv_mass, horizon, block, c_steps, damping, law,
                    ext, ext_on):
    """Steps needed in a block of ``block`` seconds so that omega dt <= 1 / c_steps over the next ``horizon``.

    omega is a Gershgorin bound (omega^2 <= max_i 2 (k_left + k_right) / m_i) on the linearised
    chain with tangent stiffnesses k_j = (3/2) kappa_j delta_j^(1/2) at an upper estimate of each
    overlap, the larger of

    - the Taylor estimate over the horizon h, delta + 2 (max(d(delta)/dt, 0) h +
      max(d2(delta)/dt2, 0) h^2 / 2) (twice the increments: contacts that close or are pushed
      within the horizon);
    - the overlap at which the pair's present elastic energy plus the kinetic energy of its
      closing motion, (2/5) kappa delta^(5/2) + mu (d(delta)/dt)^2 / 2 (mu the reduced mass), is
      all stored in the contact: a closing contact gets the step of its whole compression at
      once, instead of a step shrinking as it compresses (each change of step shifts Verlet's
      conserved shadow energy, and such shifts would add up over a compression);

    never above the run's bound ``dcap`` (System.max_overlap). State at a synchronised time
    (u, v, a of the same instant).

    Dissipative laws add their damping coefficients c_j (dashpot: gamma; Kuwabara-Kono:
    kappa A delta^(1/2) = (2/3) A k_j) bounded the same way, beta_i = 2 (c_left + c_right) / m_i,
    and omega becomes sqrt(omega_i^2 + beta_i^2 / 4) + beta_i / 2, the frequency whose stable
    step 2 / omega is that of the explicitly damped oscillator (System.max_frequency).

    With the extension (``ext_on``) a contact slot's linear spring and dashpot add to its k_j and
    c_j, a body's internal spring to its row, and an internal mass brings its own row
    2 k_in / m_in, as in System.max_frequency.
    """
    kprev = 0.0
    cprev = 0.0
    w2 = 0.0
    weff = 0.0
    hh = 0.5 * horizon * horizon
    for j in range(kappa.shape[0]):
        if kappa[j] == 0.0:
            k = 0.0
        else:
            if de[j] != 0.0:
                dx = dx0[j] - (u[j] - u[j + 1])
                d = rsum[j] - np.sqrt(dx * dx + de[j] * de[j])
            else:
                d = u[j] - u[j + 1] + d0[j]
            rate = v[j] - v[j + 1]
            q = a[j] - a[j + 1]
            dt_ = d + 2.0 * (q if q > 0.0 else 0.0) * hh
            if rate > 0.0 and d + 2.0 * rate * horizon > 0.0:  # closing, touching within the horizon
                dp = d if d > 0.0 else 0.0
                e = 0.4 * kappa[j] * dp * dp * np.sqrt(dp) + 0.5 * rate * rate / (inv_mass[j] + inv_mass[j + 1])
                de_ = (2.5 * e / kappa[j]) ** 0.4
                dt_ = de_ if de_ > dt_ else dt_
            dt_ = dt_ if dt_ < dcap[j] else dcap[j]
            k = 1.5 * kappa[j] * np.sqrt(dt_) if dt_ > 0.0 else 0.0
        if ext_on:
            w, k, cprev = extended_bound(kprev, k, cprev, damping[j], law, ext[j, EXT_KLIN], ext[j, EXT_CLIN],
                                         ext[j, EXT_KIN], ext[j, EXT_IMIN], inv_mass[j])
            weff = max(weff, w)
        elif law == LAW_ELASTIC:
            w2 = max(w2, (kprev + k) * inv_mass[j])
        else:
            c = damping[j] if law == LAW_DASHPOT else (2.0 / 3.0) * damping[j] * k
            om2 = 2.0 * (kprev + k) * inv_mass[j]
            beta = 2.0 * (cprev + c) * inv_mass[j]
            weff = max(weff, np.sqrt(om2 + 0.25 * beta * beta) + 0.5 * beta)
            cprev = c
        kprev = k
    w = np.sqrt(2.0 * w2) if law == LAW_ELASTIC and not ext_on else weff
    return max(1, int(np.ceil(block * c_steps * w - 1e-9)))


@njit(cache=True, nogil=True, inline="always")
def _adapt_stride(req, ns, relax, acc):
    """Next steps per block from the required ``req`` and the current ``ns`` (see verlet_run).

    A larger requirement is taken at once (stability); a smaller one only after ``relax``
    evaluations in a row all asked for less, then the largest of them, so that the step does
    not flicker. Updates the controller state acc[3:8] (ns, count, largest smaller request,
    largest and smallest ns used) and returns the new ns. Shared with the 2D kernel of
    :mod:`hertzchain.integrate.drivers.lateral`.
    """
    if req > ns:
        ns = req
        acc[4] = 0.0
        acc[5] = 0.0
    elif req < ns:
        acc[4] += 1.0
        acc[5] = max(acc[5], req)
        if acc[4] >= relax:
            ns = int(acc[5])
            acc[4] = 0.0
            acc[5] = 0.0
    else:
        acc[4] = 0.0
        acc[5] = 0.0
    acc[3] = ns
    acc[6] = max(acc[6], ns)
    acc[7] = min(acc[7], ns)
    return ns


#: What a compiled Verlet run steps (``kind``, a compile-time constant of each, :func:`run_kind`):
#: aligned elastic chains; the general force loop (the viscous laws, offsets); the elastic-plastic
#: law; an extension (a protected body, mass-in-mass beads). One function held every path and a
#: first run of any model compiled them all (30 CPU-s; an elastic chain now compiles its own, 5).
RUN_ELASTIC, RUN_GENERAL, RUN_PLASTIC, RUN_EXTENDED = 0, 1, 2, 3


def run_kind(law: int, general: bool, extended: bool) -> int:
    """The ``kind`` of Verlet run a system needs (``System.general``, ``System.extended``)."""
    if extended:
        return RUN_EXTENDED
    if not general:
        return RUN_ELASTIC
    return RUN_PLASTIC if law == LAW_ELASTOPLASTIC else RUN_GENERAL


@njit(cache=True, nogil=True, inline="always")
def _verlet_run(kind, state, chain, contacts, extension, probes, control, law, general, k_start, k_stop):
    """Advance from sample ``k_start`` to ``k_stop`` (samples ``interval`` seconds apart) with velocity Verlet.

    Inlined with ``kind`` (:func:`run_kind`) a constant into :func:`verlet_run_elastic`,
    :func:`verlet_run_general`, :func:`verlet_run_plastic` and :func:`verlet_run_extended`
    (:func:`verlet_run_of`): Numba drops the branches of the other kinds before it types them,
    so each compiles only its own steps. A run of another kind than its arguments is refused.

    ``state`` (:class:`~.structures.VerletState`), ``chain`` (:class:`~.structures.ChainArrays`),
    ``contacts`` (:class:`~.structures.ContactArrays`), ``extension``
    (:class:`~.structures.Extension`), ``probes`` (:class:`~.structures.VerletProbes`, positions
    not recorded) and ``control`` (:class:`~.structures.VerletControl`) carry the arrays and
    numbers named below; ``law`` is the law's code, ``general`` whether the general force loop is
    needed (``System.general``: dissipation, offsets, an extension).

    On entry and exit ``u, v, a, g`` hold positions, synchronised velocities, accelerations and
    forces at a sample time, so a run can be split into chunks (progress bars, checkpoints).

    Time step. Every sample interval is cut into ``n_sub`` blocks; a block of length
    B = interval / n_sub is crossed in ``ns`` equal steps dt = B / ns. Fixed step: ``stride`` > 0
    is ns (``n_sub`` = 1). Adaptive step (``stride`` == 0): every ``n_eval`` blocks ns is
    recomputed by :func:`required_stride` (omega dt <= 1 / ``c_steps`` over the next ``n_eval``
    blocks); it grows at once when needed, and shrinks only after ``relax`` evaluations in a row
    allowed it (to the largest of them): every change of dt shifts Verlet's conserved shadow
    energy, so few changes keep the energy error at the level of a fixed step. Each block is a
    sequence of symmetric kick-drift-kick steps, so the scheme stays time-reversible and
    second order.

    Between block ends the half kicks of consecutive steps are fused (leapfrog form); a step is
    one pass (aligned chains: :func:`step_elastic`, :func:`step_dissipative` for the viscoelastic
    and dashpot laws; offset beads: the steps of :mod:`hertzchain.integrate.core.fused`, whose probes
    read the contact energies the last step stored), but for the elastic-plastic law: one pass
    over the contacts and one over the bodies. ``acc`` holds [dissipated energy (J),
    last dissipated power (W), step count, current ns, relax count, largest ns allowed in the
    relax window, largest ns used, smallest ns used]. ``peak`` tracks contact ``wall_slot`` (the
    wall): [max force, its time, force one step before, force one step after, waiting flag,
    previous force, step before, step after]; the parabola through the three points gives the
    peak between steps. Sample k of ``out_f`` receives the forces of the contacts listed in
    ``rec``; ``fmax`` keeps every contact's largest sampled force, stored or not, for the
    elastic-limit check. The elastic-plastic law's per-contact state (``dmax``, ``dres``,
    ``kres``, see :func:`elastoplastic_force`) is carried in place from chunk to chunk, and
    ``out_wp`` receives its plastic work (:func:`plastic_work`) at every sample (other laws leave
    it alone). Returns 0, or 1 when the state became non-finite.

    A model with the extension (``ext_on``: a protected body, mass-in-mass beads) steps with
    :func:`step_extended` and its energies include the internal masses and the linear springs;
    with a protected body (``body_slot`` = N + 1, else -1) sample k of ``out_b`` receives its
    displacement [m], velocity [m/s], acceleration [m/s^2] and the work done on it so far [J].

    Velocities used by the dissipative forces at t + dt are predicted as v(t + dt/2) + a(t) dt/2;
    the error is O(dt^2) per step, so the scheme stays second order.
    """
    u, v, a, g, acc = state
    mass, inv_mass, kappa, damping, d0, fext, wall_slot = chain
    de, dx0, rsum, dcap, dyield, dmax, dres, kres = contacts
    ext, ext_on, body_slot = extension
    rec, out_f, _, _, _, out_wp, _, _, _, _, fmax, peak, _ = probes
    interval, stride, n_sub, n_eval, c_steps, relax = control
    expected = RUN_EXTENDED if ext_on else (RUN_ELASTIC if not general else (
        RUN_PLASTIC if law == LAW_ELASTOPLASTIC else RUN_GENERAL))
    if expected != kind:
        raise ValueError("verlet_run: this compiled run steps another kind of model (kernels.run_kind)")
    n = a.shape[0]
    nout = rec.shape[0]
    block = interval / n_sub
    adaptive = stride == 0
    ns = stride if not adaptive else int(acc[3])
    vp = np.zeros_like(v)
    wa = np.zeros(n)
    pw = np.zeros(n)  # the contacts' dissipated powers (plastic_block)
    # plastic_block's checkpoint (its fused steps are tried again in each chunk)
    ck = np.zeros((CHECKPOINT_ROWS, max(n + 1, CHECKPOINT_MIN_COLUMNS)) if law == LAW_ELASTOPLASTIC else (1, 1))
    ec = np.zeros(n)  # contact energies at a block's end (offset chains' fused steps, their probes)
    if ext_on:  # the internal masses' accelerations: a function of the positions, not state
        for i in range(n):
            wa[i] = internal_acceleration(ext[i, EXT_KIN], ext[i, EXT_W], u[i], ext[i, EXT_IMIN])
    step = int(acc[2])
    lean = n >= LEAN_SLOTS  # long chain without precompression (d0 = fext = 0): step_elastic_lean
    # Both flags start as a bool that is not the constant True (n >= 0): with ``= True`` Numba
    # compiled plastic_block and dissipative_block twice, for the literal True and for a bool
    # (~13 CPU-s more for a first run, issue 37).
    aligned = n >= 0  # no offsets: the dissipative laws' fused steps (step_damped)
    unloaded = n >= 0  # no precompression, no external force
    for i in range(n):
        unloaded = unloaded and d0[i] == 0.0 and fext[i] == 0.0
        aligned = aligned and de[i] == 0.0
    lean = lean and unloaded
    cd = np.zeros(n)  # the viscous laws' damping constants (step_damped)
    if general and law != LAW_ELASTIC and law != LAW_ELASTOPLASTIC:
        damping_constants(kappa, damping, law, cd)
    # Recorded contacts r0, r0 + 1, ... (the default: all of them) are copied as one slice.
    contiguous = nout > 0
    for j in range(1, nout):
        contiguous = contiguous and rec[j] == rec[j - 1] + 1
    grec = g[rec[0] + 1:rec[0] + 1 + nout] if contiguous else g[:0]
    for k in range(k_start, k_stop):
        for b in range(n_sub):
            if adaptive and ((k - 1) * n_sub + b) % n_eval == 0:
                req = required_stride(u, v, a, kappa, d0, de, dx0, rsum, dcap, inv_mass, n_eval * block, block,
                                      c_steps, damping, law, ext, ext_on)
                ns = _adapt_stride(req, ns, relax, acc)
            dt = block / ns
            half = 0.5 * dt
            t0 = (k - 1) * interval + b * block
            if kind == RUN_EXTENDED:
                step_extended(u, v, vp, a, wa, g, kappa, damping, d0, de, dx0, rsum, fext, inv_mass, law, dyield, dmax,
                              dres, kres, ext, body_slot, wall_slot, t0, dt, ns, peak, acc)
                step += ns
                continue
            for i in range(n):
                v[i] += half * a[i]
                u[i] += dt * v[i]
            if kind == RUN_GENERAL and aligned:
                # aligned viscous chains: one fused pass per step, the same numbers as the general
                # path (the elastic-plastic law's fused steps, while no contact yields: plastic_block)
                dissipative_block(u, v, vp, a, g, kappa, cd, d0, fext, inv_mass, law, unloaded, ns, dt, t0, wall_slot,
                                  peak, acc)
            elif kind == RUN_GENERAL and law == LAW_ELASTIC:  # offsets: the fused steps of fused.py, the same numbers
                offset_elastic_block(u, v, a, g, ec, kappa, d0, de, dx0, rsum, fext, inv_mass, ns, dt, t0, wall_slot,
                                     peak)
            elif kind == RUN_GENERAL:
                offset_dissipative_block(u, v, a, g, ec, kappa, damping, d0, de, dx0, rsum, fext, inv_mass, law, ns,
                                         dt, t0, wall_slot, peak, acc)
            elif kind == RUN_PLASTIC:
                plastic_block(u, v, vp, a, g, pw, kappa, damping, d0, de, dx0, rsum, fext, inv_mass, dyield, dmax, dres,
                              kres, aligned, ns, dt, t0, wall_slot, peak, acc, ck)
            else:
                if lean:
                    for s in range(ns - 1):
                        # the wall force this step computes (at the positions it starts from)
                        _track_peak(contact_force(u, kappa, d0, wall_slot), t0 + (s + 1) * dt, dt, peak)
                        step_elastic_lean(u, v, kappa, inv_mass, dt)
                else:
                    for s in range(ns - 1):
                        step_elastic(u, v, a, g, kappa, d0, fext, inv_mass, dt)
                        _track_peak(g[wall_slot + 1], t0 + (s + 1) * dt, dt, peak)
                final_step_elastic(u, v, a, g, kappa, d0, fext, inv_mass, half)
                _track_peak(g[wall_slot + 1], t0 + block, dt, peak)
            step += ns
        # --- probes, sampled inside the compiled loop
        if contiguous:
            out_f[k, :] = grec
        else:
            for j in range(nout):
                out_f[k, j] = g[rec[j] + 1]
        g1 = g[1:]
        for j in range(fmax.shape[0]):
            x = g1[j]
            fmax[j] = x if x > fmax[j] else fmax[j]  # a ternary vectorises; Numba's max() does not
        if kind != RUN_ELASTIC and law == LAW_ELASTOPLASTIC:
            ke = kinetic_energy(v, mass)
            pe = potential_energy_plastic(u, d0, de, dx0, rsum, fext, dres, kres)
            out_wp[k] = plastic_work(kappa, dyield, dmax, dres)
        elif kind == RUN_GENERAL and not aligned:  # the contact energies the fused steps left in ec
            ke, pe = energies_offset(u, v, mass, fext, ec)
        elif kind != RUN_ELASTIC:
            ke = kinetic_energy(v, mass)
            pe = potential_energy(u, g, kappa, d0, de, dx0, rsum, fext, False)
        else:
            ke, pe = energies_elastic(u, v, g, mass, d0, fext)
        if close_sample(k, ke, pe, u, v, a, g, d0, extension, probes, acc, step):
            return 1
    acc[2] = step
    return 0


@njit(cache=True, nogil=True)
def verlet_run_elastic(state, chain, contacts, extension, probes, control, law, general, k_start, k_stop):
    """:func:`_verlet_run` of an aligned elastic chain (``RUN_ELASTIC``)."""
    return _verlet_run(RUN_ELASTIC, state, chain, contacts, extension, probes, control, law, general, k_start, k_stop)


@njit(cache=True, nogil=True)
def verlet_run_general(state, chain, contacts, extension, probes, control, law, general, k_start, k_stop):
    """:func:`_verlet_run` of the general force loop (``RUN_GENERAL``)."""
    return _verlet_run(RUN_GENERAL, state, chain, contacts, extension, probes, control, law, general, k_start, k_stop)


@njit(cache=True, nogil=True)
def verlet_run_plastic(state, chain, contacts, extension, probes, control, law, general, k_start, k_stop):
    """:func:`_verlet_run` of the elastic-plastic law (``RUN_PLASTIC``)."""
    return _verlet_run(RUN_PLASTIC, state, chain, contacts, extension, probes, control, law, general, k_start, k_stop)


@njit(cache=True, nogil=True)
def verlet_run_extended(state, chain, contacts, extension, probes, control, law, general, k_start, k_stop):
    """:func:`_verlet_run` of a model with the extension (``RUN_EXTENDED``)."""
    return _verlet_run(RUN_EXTENDED, state, chain, contacts, extension, probes, control, law, general, k_start,
                       k_stop)


def verlet_run_of(kind: int):
    """The compiled Verlet run of ``kind`` (:func:`run_kind`)."""
    return (verlet_run_elastic, verlet_run_general, verlet_run_plastic, verlet_run_extended)[kind]


def flush_stale_cache(*kernels_using: Any, also: tuple[str | Path, ...] = ()) -> None:
    """Drop the on-disk cache of these compiled functions when this module (or ``extension.py``,
    ``energies.py``, ``primitives.py``, ``fused.py`` or ``plastic.py``, whose functions it compiles in,
    or a file in ``also``) is newer than it.

    Numba's cache only checks the source file of the cached function itself, not of the
    functions it calls; the batched engine's loops (``batch_engine._batch_kernel``,
    ``batch_pack._init_kernel``) compile the functions of this module into themselves, so an
    edit of ``kernels.py`` would otherwise leave the batched engine running the old kernel.

    Parameters
    ----------
    *kernels_using
        Numba dispatchers (``@njit(cache=True)``) that call functions of this module.
    also
        Other source files they compile in (the rkn4 kernels' interpolants, :mod:`..drivers.rkn_samples`).
    """
    # what the kernels compile in
    sources = [Path(__file__).with_name(name) for name in ("kernels.py", "extension.py", "energies.py",
                                                            "primitives.py", "fused.py", "plastic.py")]
    sources += [Path(p) for p in also]
    newest = max(p.stat().st_mtime for p in sources)
    for fn in kernels_using:
        try:
            index = Path(fn._cache._cache_file._index_path)
            if index.exists() and index.stat().st_mtime < newest:
                fn._cache.flush()
        except (AttributeError, OSError):  # private Numba API moved or no cache: nothing to protect
            pass


# The stepping loop (and forces_general: plastic.contact_general, primitives.FORCE_MIN) compiles the functions of
# extension.py, primitives.py, fused.py and plastic.py into itself:
# an edit there must recompile it too (Numba's cache only checks the file of the function it caches).
flush_stale_cache(forces_general, dissipative_block, _kk_block, _kk_block_unloaded, _dashpot_block,
                  _dashpot_block_unloaded, plastic_block, offset_elastic_block, offset_dissipative_block,
                  verlet_run_elastic, verlet_run_general, verlet_run_plastic, verlet_run_extended)
