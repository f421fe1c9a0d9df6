"""The threaded long-chain engine for every contact law: one block of bodies per thread.

:func:`hertzchain.integrate.drivers.threaded.run_verlet_threaded` runs aligned elastic chains with the
hand-fused elastic steps of :mod:`hertzchain.integrate.drivers.threaded`; every other model it runs with
a thread function built here, once per law and process, from the law's one-contact function:

- the built-in laws (elastic with offsets, Kuwabara-Kono, dashpot, their size-scaled forms,
  Thornton's elastic-plastic law): :func:`hertzchain.integrate.core.kernels.contact_general`,
  the contact ``kernels.forces_general`` itself loops over;
- the laws declared in :mod:`hertzchain.laws` (power, Hunt-Crossley, a user's): the ``contact``
  that :func:`hertzchain.integrate.core.generated.law_kernels` builds from the law's ``force`` and
  ``state``, the contact of the generated single-thread loop.

A step is the single-thread general path's (``kernels._verlet_run``, ``generated``'s ``run``):
the forces at the drifted positions and at the velocities predicted half a step ahead,
v + (dt/2) a, then a = (F_{i-1} - F_i + f_ext) / m, the kick and the drift (the closing half kick
at a block's end); fused into one pass over a thread's bodies (as ``kernels.step_dissipative``),
which computes each contact's force from the same numbers in the same operations. The contact
on a block's left edge needs the left neighbour's last position and predicted velocity, the
last contact the right neighbour's first: each thread publishes both after it moves its bodies,
in one of two slots that alternate from step to step, and reads its neighbours' after one
barrier (one per step, :mod:`hertzchain.integrate.core.barrier`). The contact on the left edge is
computed by both threads from the same numbers; its per-contact state (elastic-plastic: the
largest overlap and the unloading curve; Hunt-Crossley: the approach speed) belongs to the
thread that owns the contact (the left one), the right one carries a private copy, updated by
the same arithmetic, so both see the same force.

So positions, velocities, forces, the per-contact state and the wall peak are those of one
thread bit for bit. The dissipated energy is each block's trapezoidal integral of its own
dissipated power, added over the blocks, and the kinetic and potential energies and the plastic
work are block sums added in block order: they round differently from the one-thread sums
(relative difference ~1e-15 x sqrt(N); tests/test_threaded_laws.py bounds it by 1e-12 of the
largest energy).
"""

from __future__ import annotations


import numpy as np
from numba import njit

from ..core import kernels
from ..core.barrier import barrier
from ..core.extension import EXT_COLUMNS
from ..core.primitives import _track_peak, _viscous_force, open_block
from .thread_blocks import agree_steps, column_sum, end_sample, kept_on_disk, move_body, record_block, thread_start

__all__ = ["law_thread_run"]

_CACHE: dict = {}


def _on_disk(dispatcher, *variant):
    """``dispatcher``, a closure built here over this package's functions only, cached on disk
    under ``variant`` (the law and geometry it was built for): :func:`.thread_blocks.kept_on_disk`."""
    return kept_on_disk(dispatcher, "drivers/threaded_laws.py", *variant)


def law_thread_run(code: int, aligned: bool):
    """The thread function (:func:`_build`) for the law of engine code ``code`` on an aligned chain
    (``aligned``: no offsets, the misaligned geometry compiled out) or one with offsets; compiled on
    first use in a process and cached on disk for a built-in law (:func:`_on_disk`: the next
    process loads it), in memory for a declared law (a closure over the law's own functions)."""
    from ..core.generated import is_generated, law_kernels

    if is_generated(code):
        _, _, energy, stride, contact = law_kernels(code)
        key: tuple = ("generated", int(code), bool(aligned), id(contact))
    else:
        key = ("builtin", int(code), bool(aligned))
    if key not in _CACHE:
        _CACHE[key] = (_generated(contact, stride, energy, aligned) if is_generated(code)
                       else _builtin(int(code), aligned))
    return _CACHE[key]


def _builtin(law: int, aligned: bool):
    """The thread function of a built-in law (engine code ``law``: ``kernels.LAW_*``)."""
    plastic = law == kernels.LAW_ELASTOPLASTIC
    # aligned Kuwabara-Kono and dashpot chains: the one-thread loop's fused step
    # (kernels.step_dissipative), whose contact is _viscous_force; its power sum may be
    # reassociated (vectorised) as kernels.dissipative_block's
    fused = aligned and law in (kernels.LAW_VISCOELASTIC, kernels.LAW_DASHPOT)

    @njit(nogil=True, inline="always")
    def contact(ui, uj, vi, vj, kappa, damping, d0, de, dx0, rsum, dyield, s0, s1, s2):
        if fused:
            rate = vi - vj
            f, fel = _viscous_force(ui - uj + d0, rate, kappa, damping, law)
            return f, (f - fel) * rate, s0, s1, s2
        # the one-thread loop's own contact; on an aligned chain its offset branch is folded away
        # (computed, even untaken, it cost ~4x)
        return kernels.contact_general(ui, uj, vi, vj, kappa, damping, d0, de, dx0, rsum, law, dyield, s0, s1, s2,
                                       aligned)

    @njit(nogil=True)
    def stride(u, v, a, kappa, damping, d0, de, dx0, rsum, dcap, state, inv_mass, horizon, block, c_steps, ext):
        return kernels.required_stride(u, v, a, kappa, d0, de, dx0, rsum, dcap, inv_mass, horizon, block, c_steps,
                                       damping, law, ext, False)

    @njit(nogil=True)
    def energies(u, v, g, mass, kappa, damping, d0, de, dx0, rsum, fext, dyield, dmax, dres, kres):
        ke = kernels.kinetic_energy(v, mass)
        if plastic:
            pe = kernels.potential_energy_plastic(u, d0, de, dx0, rsum, fext, dres, kres)
            return ke, pe, kernels.plastic_work(kappa, dyield, dmax, dres)
        return ke, kernels.potential_energy(u, g, kappa, d0, de, dx0, rsum, fext, False), 0.0

    variant = ("builtin", law, aligned)
    return _build(contact, _on_disk(stride, *variant), _on_disk(energies, *variant), plastic, plastic, fused,
                  variant)


def _generated(law_contact, law_stride, law_energy, aligned: bool):
    """The thread function of a law run by the generated engines (its state in the ``dmax`` slots)."""

    @njit(nogil=True, inline="always")
    def contact(ui, uj, vi, vj, kappa, damping, d0, de, dx0, rsum, dyield, s0, s1, s2):
        if aligned:  # the offset branch folded away
            f, p, s0 = law_contact(ui, uj, vi, vj, kappa, damping, d0, 0.0, 0.0, 0.0, s0)
        else:
            f, p, s0 = law_contact(ui, uj, vi, vj, kappa, damping, d0, de, dx0, rsum, s0)
        return f, p, s0, s1, s2

    @njit(nogil=True)
    def stride(u, v, a, kappa, damping, d0, de, dx0, rsum, dcap, state, inv_mass, horizon, block, c_steps, ext):
        return law_stride(u, v, a, kappa, damping, d0, de, dx0, rsum, dcap, state, inv_mass, horizon, block, c_steps)

    @njit(nogil=True)
    def energies(u, v, g, mass, kappa, damping, d0, de, dx0, rsum, fext, dyield, dmax, dres, kres):
        return kernels.kinetic_energy(v, mass), law_energy(u, kappa, damping, d0, de, dx0, rsum, fext), 0.0

    return _build(contact, stride, energies, True, False, False, None)


@njit(nogil=True, inline="always")
def _publish(pub, par, tid, u, v, a, s, e, half):
    """The block's first and last positions and predicted velocities v + half a into the other
    parity's slots; returns that parity (a slot is written only after a barrier has followed every
    read of it)."""
    par = 1 - par
    pub[par, tid, 0] = u[s]
    pub[par, tid, 1] = v[s] + half * a[s]
    pub[par, tid, 2] = u[e - 1]
    pub[par, tid, 3] = v[e - 1] + half * a[e - 1]
    return par


def _segment(contact, stateful, fused, last):
    """One step over a block's bodies: ``last`` (a constant, so that the loop has no branch on it
    and vectorises where the contact allows) the block's closing half kick, else kick and drift."""

    @njit(nogil=True, fastmath={"reassoc"} if fused else False)
    def segment(u, v, a, g, kappa, damping, d0, de, dx0, rsum, fext, inv_mass, dyield, dmax, dres, kres, dt, half,
                fprev, ur, vr):
        """The step on a block's bodies, given as views from its first body (``u``, ``g`` one slot
        longer): ``fprev`` the force of the contact on its left, ``ur``, ``vr`` the right
        neighbour's position and predicted velocity. Returns the block's dissipated power [W].
        Views from 0, so that the indices are known to be non-negative (from the block's first
        slot, Numba wraps every access for negative indices)."""
        n = inv_mass.shape[0]
        vq = v[0] + half * a[0]
        power = 0.0
        for i in range(n - 1):
            vq1 = v[i + 1] + half * a[i + 1]
            f, p, x0, x1, x2 = contact(u[i], u[i + 1], vq, vq1, kappa[i], damping[i], d0[i], de[i], dx0[i], rsum[i],
                                       dyield[i], dmax[i], dres[i], kres[i])
            if stateful:
                dmax[i] = x0
                dres[i] = x1
                kres[i] = x2
            power += p
            move_body(u, v, a, g, i, f, fprev, fext[i], inv_mass[i], dt, half, last)
            fprev = f
            vq = vq1
        i = n - 1
        f, p, x0, x1, x2 = contact(u[i], ur, vq, vr, kappa[i], damping[i], d0[i], de[i], dx0[i], rsum[i], dyield[i],
                                   dmax[i], dres[i], kres[i])
        if stateful:
            dmax[i] = x0
            dres[i] = x1
            kres[i] = x2
        move_body(u, v, a, g, i, f, fprev, fext[i], inv_mass[i], dt, half, last)
        return power + p

    return segment


def _build(contact, stride, energies, stateful, plastic, fused, variant):
    """The thread function over ``contact`` (one contact: (axial force, dissipated power, state)),
    ``stride`` (the adaptive step's bound over a range of contacts) and ``energies`` (a block's
    kinetic and potential energies and plastic work); ``stateful``: the contacts carry state;
    ``plastic``: the plastic work is recorded (``out_wp``); ``fused``: the block's power sum may be
    reassociated (``kernels.dissipative_block``'s flag, for its contact only); ``variant``: what
    the built-in law's closures were built for (:func:`_on_disk`), None to keep them in memory."""

    def kept(dispatcher, *part):
        return dispatcher if variant is None else _on_disk(dispatcher, *variant, *part)

    kick_drift = kept(_segment(contact, stateful, fused, False), "kick_drift")
    half_kick = kept(_segment(contact, stateful, fused, True), "half_kick")

    @njit(nogil=True)
    def thread_run(tid, team, state, chain, contacts, probes, control, k_start, k_stop):
        """Thread ``tid``'s share of the single-thread general loop from sample ``k_start`` to
        ``k_stop``: bodies and contacts of its block of :class:`~.thread_blocks.ThreadTeam`
        ``team``, whose ``pub`` (2, nthr, 4) holds the first and last position and predicted
        velocity of each block, by parity, ``energy`` (nthr, 3) the blocks' kinetic, potential
        energies and plastic work, ``edacc`` (nthr, 2) their dissipated energy and last
        dissipated power (kept from call to call); the other structures are
        ``kernels._verlet_run``'s. Thread 0 keeps ``acc`` (the others a copy: the same numbers).
        Returns 1 when the state is not finite (every thread sees the same sums), else 0."""
        u, v, a, g, acc = state
        mass, inv_mass, kappa, damping, d0, fext, ws = chain
        de, dx0, rsum, dcap, dyield, dmax, dres, kres = contacts
        out_ke, out_pe, out_ed, out_wp, peak = probes.out_ke, probes.out_pe, probes.out_ed, probes.out_wp, probes.peak
        interval, stride_, n_sub, n_eval, c_steps, relax = control
        nthr, bar, pub, energy, edacc = team.nthr, team.bar, team.pub, team.energy, team.edacc
        s, e, owns_wall, left, right, my, block, ns, step = thread_start(team, tid, acc, ws, control)
        adaptive = stride_ == 0
        no_ext = np.zeros((0, EXT_COLUMNS))
        sense = 0
        par = 0
        j0 = s - 1 if left else 0
        # the contact on the block's left: its parameters and a private copy of its owner's state
        kl, cl, d0l, del_, dxl, rl, dyl = kappa[j0], damping[j0], d0[j0], de[j0], dx0[j0], rsum[j0], dyield[j0]
        gs0, gs1, gs2 = dmax[j0], dres[j0], kres[j0]
        ed = edacc[tid, 0]
        pprev = edacc[tid, 1]
        for k in range(k_start, k_stop):
            for b in range(n_sub):
                if adaptive and ((k - 1) * n_sub + b) % n_eval == 0:
                    # a maximum over bodies of a bound from their contacts: the largest of the
                    # blocks' values (each with its left contact) is the chain's
                    sense = barrier(bar, nthr, sense)
                    req = stride(u[j0:e + 1], v[j0:e + 1], a[j0:e + 1], kappa[j0:e], damping[j0:e], d0[j0:e],
                                 de[j0:e], dx0[j0:e], rsum[j0:e], dcap[j0:e], dmax[j0:e], inv_mass[j0:e + 1],
                                 n_eval * block, block, c_steps, no_ext)
                    ns, sense = agree_steps(team, tid, sense, req, ns, relax, my)
                dt = block / ns
                half = 0.5 * dt
                t0 = (k - 1) * interval + b * block
                open_block(u[s:e], v[s:e], a[s:e], dt, half)
                par = _publish(pub, par, tid, u, v, a, s, e, half)
                sense = barrier(bar, nthr, sense)
                for st in range(ns):
                    last = st == ns - 1
                    if right:
                        ur = pub[par, tid + 1, 0]
                        vr = pub[par, tid + 1, 1]
                    else:  # the slot past the last (padding): at rest, as the one-thread loop's
                        ur = u[e]
                        vr = 0.0
                    vq = v[s] + half * a[s]
                    fprev = 0.0
                    if left:
                        fprev, _, gs0, gs1, gs2 = contact(pub[par, tid - 1, 2], u[s], pub[par, tid - 1, 3], vq, kl, cl,
                                                          d0l, del_, dxl, rl, dyl, gs0, gs1, gs2)
                    if last:
                        power = half_kick(u[s:e + 1], v[s:e], a[s:e], g[s:e + 1], kappa[s:e], damping[s:e], d0[s:e],
                                          de[s:e], dx0[s:e], rsum[s:e], fext[s:e], inv_mass[s:e], dyield[s:e],
                                          dmax[s:e], dres[s:e], kres[s:e], dt, half, fprev, ur, vr)
                    else:
                        power = kick_drift(u[s:e + 1], v[s:e], a[s:e], g[s:e + 1], kappa[s:e], damping[s:e], d0[s:e],
                                           de[s:e], dx0[s:e], rsum[s:e], fext[s:e], inv_mass[s:e], dyield[s:e],
                                           dmax[s:e], dres[s:e], kres[s:e], dt, half, fprev, ur, vr)
                    ed += half * (pprev + power)  # the block's trapezoidal integral of its dissipated power
                    pprev = power
                    if owns_wall:
                        _track_peak(g[ws + 1], t0 + (st + 1) * dt, dt, peak)
                    if not last:
                        par = _publish(pub, par, tid, u, v, a, s, e, half)
                        sense = barrier(bar, nthr, sense)
                step += ns
            # --- probes: each thread its own contacts and bodies, energies as block sums
            record_block(team, tid, k, s, e, u, v, g, probes)
            energy[tid, 0], energy[tid, 1], energy[tid, 2] = energies(
                u[s:e + 1], v[s:e], g[s:e + 1], mass[s:e], kappa[s:e], damping[s:e], d0[s:e], de[s:e], dx0[s:e], rsum[s:e],
                fext[s:e], dyield[s:e], dmax[s:e], dres[s:e], kres[s:e])
            edacc[tid, 0] = ed
            edacc[tid, 1] = pprev
            sense = barrier(bar, nthr, sense)
            ke = column_sum(energy, 0)
            pe = column_sum(energy, 1)
            wp = column_sum(energy, 2)
            edk = column_sum(edacc, 0)
            pk = column_sum(edacc, 1)
            if tid == 0:
                out_ke[k] = ke
                out_pe[k] = pe
                out_ed[k] = edk
                if plastic:
                    out_wp[k] = wp
                my[0] = edk
                my[1] = pk
            sense, finite = end_sample(team, sense, ke, g)
            if not finite:
                my[2] = step
                return 1
        my[2] = step
        return 0

    return kept(thread_run, "thread_run")
