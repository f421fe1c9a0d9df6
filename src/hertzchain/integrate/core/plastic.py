"""The general path's contact and the elastic-plastic law's steps (Thornton 1997), compiled into
:mod:`hertzchain.integrate.core.kernels` (which re-exports them: ``kernels.elastoplastic_force``,
``kernels.contact_general``, ``kernels.plastic_block``).

:func:`elastoplastic_force` is plain Python with ``math``: its source is also the CUDA engine's
device function. :func:`contact_general` is one contact of ``kernels.forces_general`` for every
hand-written law (geometry, the d == 0 convention, the law's force); :func:`plastic_block`
steps an elastic-plastic chain, aligned chains with the branch-free pass :func:`plastic_pass`.
Unit-free SI floats, the packed layout of ``kernels``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .primitives import DELTA_MIN, FORCE_MIN, LAW_ELASTIC, LAW_ELASTOPLASTIC, LAW_VISCOELASTIC, _track_peak, kick, predict, total


@njit(cache=True, nogil=True, inline="always")
def elastoplastic_force(d, rate, kappa, damping, dyield, dmax, dres, kres):
    """Thornton's elastic-plastic contact force at overlap ``d`` >= 0 and its new state.

    Loading past the largest overlap so far (d > dmax): Hertz, kappa d^(3/2), up to the yield
    overlap dyield, then the line F_y + (3/2) kappa dyield^(1/2) (d - dyield) (slope pi p_y R*);
    the state moves to the unloading curve through (d, F): residual overlap
    dres = d - F / (kappa d^(1/2)) and stiffness kres = kappa (d / (d - dres))^(1/2) (Hertz with
    Thornton's enlarged radius R_p, see ``contact.thornton_unloading``). Otherwise (unloading or
    reloading below dmax): kres (d - dres)^(3/2), zero below dres. A viscous term
    damping kres (d - dres)^(1/2) d(delta)/dt is added (Kuwabara-Kono with the present elastic
    stiffness; ``damping`` = A [s], 0 for the plain law) and the sum is clipped at zero.

    Parameters are per-contact scalars (overlap [m], rate [m/s], kappa [N/m^1.5], A [s], yield
    overlap [m], state); returns (force [N], its elastic-plastic part [N], dmax, dres, kres), the
    caller stores the state. Elastic contacts (dmax <= dyield) have dres = 0 and kres = kappa.
    Plain Python with ``math``: its source is also the CUDA engine's device function
    (:mod:`hertzchain.integrate.cuda.kernels`; numba.cuda takes math.sqrt, not np.sqrt).
    """
    if d > dmax:
        dmax = d
        if d > dyield:
            sy = math.sqrt(dyield)
            fep = kappa * sy * (dyield + 1.5 * (d - dyield))  # F_y + (3/2) kappa dyield^(1/2) (d - dyield)
            sd = math.sqrt(d)
            x = fep / (kappa * sd)  # d - dres: the unloading stiffness at d is Hertz's (3/2) kappa d^(1/2)
            dres = d - x
            kres = kappa * sd / math.sqrt(x)
            sx = math.sqrt(x)
        else:
            sx = math.sqrt(d)
            fep = kappa * d * sx
    else:
        x = d - dres
        if x > DELTA_MIN:
            sx = math.sqrt(x)
            fep = kres * x * sx
        else:
            sx = 0.0
            fep = 0.0
    f = fep + damping * kres * sx * rate
    f = f if f > 0.0 else 0.0
    return f, fep, dmax, dres, kres


@njit(cache=True, nogil=True, inline="always")
def contact_general(ui, uj, vi, vj, kappa, damping, d0, de, dx0, rsum, law, dyield, dmax, dres, kres, aligned):
    """One contact of :func:`forces_general` (its body: bodies at ``ui``, ``uj`` [m] moving at
    ``vi``, ``vj`` [m/s], the contact's parameters and elastic-plastic state): (axial force [N],
    dissipated power [W], new dmax, dres, kres). With ``aligned`` (a constant in the caller: no
    offsets in the chain) the geometry branch is compiled out, with the same numbers for aligned
    pairs. Scalars in and out: inlined with the arrays as arguments, each call counted the
    arrays' references (~50 ns a contact)."""
    if not aligned and de != 0.0:
        dx = dx0 - (ui - uj)
        dist = np.sqrt(dx * dx + de * de)
        d = rsum - dist
        c = dx / dist
    else:
        d = ui - uj + d0
        c = 1.0
    # d == 0 is kept as a contact: at the impact instant (t = 0, striker just touching) the
    # dashpot force is already gamma d(delta)/dt = gamma v0 (the law jumps at closure); taking
    # 0 there instead made Verlet's first half kick miss an O(dt) impulse (first-order error).
    # The elastic part and the Kuwabara-Kono term (~ delta^(1/2)) vanish at d == 0 anyway.
    if d < 0.0:
        return 0.0, 0.0, dmax, dres, kres
    if d <= DELTA_MIN:
        d = 0.0
    if law == LAW_ELASTOPLASTIC:
        if kappa == 0.0:  # no contact (free end, padding)
            return 0.0, 0.0, dmax, dres, kres
        rate = c * (vi - vj)
        f, fep, dmax, dres, kres = elastoplastic_force(d, rate, kappa, damping, dyield, dmax, dres, kres)
        return c * f, (f - fep) * rate, dmax, dres, kres
    sd = np.sqrt(d)
    fel = kappa * d * sd
    if law == LAW_ELASTIC:
        return c * fel, 0.0, dmax, dres, kres
    rate = c * (vi - vj)  # d(delta)/dt
    if law == LAW_VISCOELASTIC:
        f = fel + kappa * damping * sd * rate
    else:
        f = fel + damping * rate
    f = f if f > FORCE_MIN else 0.0  # as primitives.damped_force
    return c * f, (f - fel) * rate, dmax, dres, kres  # F_diss * d(delta)/dt >= 0: power lost to dissipation


@njit(cache=True, nogil=True, inline="always")
def plastic_pass(u, vp, g, pw, kappa, damping, d0, dyield, dmax, dres, kres, viscous):
    """Every aligned contact's elastic-plastic force as :func:`contact_general` computes it, but
    for the contacts loaded past both their largest overlap and the yield overlap (the only case
    that moves a contact onto a new unloading curve), in one branch-free pass that LLVM
    vectorises: the unloading curve kres (delta - dres)^(3/2) plus its damping term, which is
    also, bit for bit, the Hertz force of a contact that never yielded (dres = 0, kres = kappa
    exactly) and so of elastic loading; dmax = max(dmax, delta) but on yielding contacts.
    Forces into g[j + 1], viscous powers into pw[j]. Returns the first and last index of the
    yielding contacts (n, -1: none), whose force and state :func:`plastic_yield` redoes with the
    state left as it was. Computing the yield branch in the pass too (two more square roots and
    two divisions per contact) cost more than the pass: benchmarks/laws.py."""
    n = kappa.shape[0]
    lo = n
    hi = -1
    for j in range(n):
        d = u[j] - u[j + 1] + d0[j]
        dd = d if d > DELTA_MIN else 0.0
        x = dd - dres[j]
        x = x if x > DELTA_MIN else 0.0
        sx = np.sqrt(x)
        kr = kres[j]
        fep = kr * x * sx
        on = (d >= 0.0) & (kappa[j] != 0.0)
        if viscous:
            rate = vp[j] - vp[j + 1]
            f = fep + damping[j] * kr * sx * rate
            f = f if f > 0.0 else 0.0
            g[j + 1] = f if on else 0.0
            pw[j] = (f - fep) * rate if on else 0.0
        else:  # every A = 0 (a compile-time constant): the damping term is +-0, fep + -0 = fep, no power
            g[j + 1] = fep if on else 0.0
        dm = dmax[j]
        up = on & (dd > dm)
        yl = up & (dd > dyield[j])
        dmax[j] = dd if up & ~yl else dm
        # min and max of (j or a sentinel) as ternaries: LLVM vectorises these reductions, not
        # "the last j where yl" (hi = j if yl else hi kept the pass scalar)
        t = j if yl else n
        lo = lo if lo < t else t
        t = j if yl else -1
        hi = hi if hi > t else t
    return lo, hi


@njit(cache=True, nogil=True, inline="always")
def plastic_yield(u, vp, g, pw, kappa, damping, d0, de, dx0, rsum, dyield, dmax, dres, kres, lo, hi):
    """The yielding contacts lo..hi that :func:`plastic_pass` left (its state unchanged there):
    :func:`contact_general`'s force and new state for those loaded past dmax and dyield."""
    for j in range(lo, hi + 1):
        d = u[j] - u[j + 1] + d0[j]
        dd = d if d > DELTA_MIN else 0.0
        if d >= 0.0 and kappa[j] != 0.0 and dd > dmax[j] and dd > dyield[j]:
            g[j + 1], pw[j], dmax[j], dres[j], kres[j] = contact_general(
                u[j], u[j + 1], vp[j], vp[j + 1], kappa[j], damping[j], d0[j], de[j], dx0[j], rsum[j],
                LAW_ELASTOPLASTIC, dyield[j], dmax[j], dres[j], kres[j], True)


@njit(cache=True, nogil=True, inline="always")
def plastic_step(u, v, vp, a, g, pw, kappa, damping, d0, fext, inv_mass, dyield, dmax, dres, kres, viscous, dt, half,
                 last):
    """One step of an aligned elastic-plastic chain in one pass, right when no contact yields in it
    (as ``kernels.step_elastic`` fuses the elastic step): each contact's force as
    :func:`plastic_pass` computes it (the unloading curve, which is the Hertz force of a contact
    that never yielded; dmax = max(dmax, delta)), then the kick of the body on its left
    (:func:`~.primitives.kick`'s numbers, the left contact's force carried in ``fprev``).
    Iteration i reads u[i + 1] before iteration i + 1 writes it. Without a viscous term
    (``viscous`` False, a compile-time constant) there is no power and the predictions ``vp``
    are neither read nor written (only a viscous term reads them).

    Returns the number of contacts loaded past both their largest overlap and their yield overlap
    (:func:`plastic_pass`'s yielding contacts): where it is not 0 the step is wrong and
    :func:`plastic_block` redoes the block (an integer sum in the loop costs nothing; a test
    pass before the step, or copies of the state in it, cost 40-70 % of the step)."""
    fprev = 0.0
    hits = 0
    for i in range(a.shape[0]):
        d = u[i] - u[i + 1] + d0[i]
        dd = d if d > DELTA_MIN else 0.0
        x = dd - dres[i]
        x = x if x > DELTA_MIN else 0.0
        sx = np.sqrt(x)
        kr = kres[i]
        fep = kr * x * sx
        if viscous:
            on = (d >= 0.0) & (kappa[i] != 0.0)
            rate = vp[i] - vp[i + 1]
            f = fep + damping[i] * kr * sx * rate
            f = f if f > 0.0 else 0.0
            f = f if on else 0.0
            pw[i] = (f - fep) * rate if on else 0.0
        else:
            # plastic_pass's select on ``on`` left out: an open contact (d < 0: dd = 0, x <= 0 -> 0)
            # and a slot without contact (kres = kappa = 0) already give fep = +0
            f = fep
        dm = dmax[i]
        # d >= 0 is implied by dd > dm >= 0
        up = (kappa[i] != 0.0) & (dd > dm)
        hits += 1 if up & (dd > dyield[i]) else 0
        dmax[i] = dd if up else dm
        g[i + 1] = f
        ai = (fprev - f + fext[i]) * inv_mass[i]
        a[i] = ai
        if last:
            v[i] += half * ai
        else:
            vi = v[i] + dt * ai
            v[i] = vi
            if viscous:
                vp[i] = vi + half * ai
            u[i] += dt * vi
        fprev = f
    return hits


@njit(cache=True, nogil=True, inline="always")
def _fused_steps(u, v, vp, a, g, pw, kappa, damping, d0, fext, inv_mass, dyield, dmax, dres, kres, viscous, ns, dt,
                 t0, wall_slot, peak, acc):
    """The ``ns`` steps of a block by :func:`plastic_step` (``viscous`` a constant), stopping at
    the first step in which a contact yields; returns whether one did."""
    half = 0.5 * dt
    for s in range(ns):
        if s < ns - 1:
            hits = plastic_step(u, v, vp, a, g, pw, kappa, damping, d0, fext, inv_mass, dyield, dmax, dres, kres,
                                viscous, dt, half, False)
        else:
            hits = plastic_step(u, v, vp, a, g, pw, kappa, damping, d0, fext, inv_mass, dyield, dmax, dres, kres,
                                viscous, dt, half, True)
        if hits > 0:
            return True
        p = total(pw) if viscous else 0.0
        acc[0] += half * (acc[1] + p)  # trapezoidal integral of the dissipated power
        acc[1] = p
        _track_peak(g[wall_slot + 1], t0 + (s + 1) * dt, dt, peak)
    return False


@njit(cache=True, nogil=True, inline="always")
def _checkpoint(u, v, a, dmax, peak, acc, ck, save):
    """Copy the state a block changes (positions, velocities, accelerations, dmax, the wall-peak
    tracker, the dissipated energy's accumulators) into ``ck`` (``save``) or back from it. Loops,
    not slice assignments: each of those compiled Numba's formatted shape-error message (~1.5
    CPU-s of every new process's first Verlet run, issue 37)."""
    n = a.shape[0]
    _move(ck[0, :n + 1], u, save)
    _move(ck[1, :n + 1], v, save)
    _move(ck[2, :n], a, save)
    _move(ck[3, :n], dmax, save)
    _move(ck[4, :8], peak, save)
    _move(ck[4, 8:10], acc, save)


@njit(cache=True, nogil=True)
def _move(row, x, save):
    """``row`` (a slice of the checkpoint) from the first values of ``x`` (``save``), or back."""
    for i in range(row.shape[0]):
        if save:
            row[i] = x[i]
        else:
            x[i] = row[i]


#: Rows and columns beyond the chain's slots of :func:`plastic_block`'s scratch ``ck``: 5 rows,
#: max(P + 1, 11) columns; ck[4, 10] is 1 while the last block had a yielding contact.
CHECKPOINT_ROWS = 5
CHECKPOINT_MIN_COLUMNS = 11


@njit(cache=True, nogil=True)
def plastic_block(u, v, vp, a, g, pw, kappa, damping, d0, de, dx0, rsum, fext, inv_mass, dyield, dmax, dres, kres,
                  aligned, ns, dt, t0, wall_slot, peak, acc, ck):
    """The ``ns`` steps of a block of :func:`verlet_run` for the elastic-plastic law (its opening
    half kick and drift done by the caller): every contact's force (:func:`contact_general`,
    inlined, without the geometry branch when ``aligned``) at the predicted velocities ``vp``
    (P + 1 slots, vp[P] = 0), their powers in ``pw`` summed by
    :func:`~hertzchain.integrate.core.primitives.total` (the dissipated energy's trapezoidal integral
    in acc[0:2]), the wall peak, then the kick (:func:`~hertzchain.integrate.core.primitives.kick`),
    which leaves the next step's predictions in ``vp``. The numbers of forces_general and the
    update loops, but for the last bits of the dissipated energy (the power summed in another
    order). One function for the block: a call of forces_general per step cost as much as its
    pass on short chains, and the power summed in contact order (a chain of dependent additions)
    set the pace of the step.

    An aligned chain whose previous block had no yielding contact (ck[4, 10] == 0) first tries
    the block in fused steps (:func:`plastic_step`: one pass per step, 300 beads ~1.5 -> ~0.9 ns
    per bead-step, benchmarks/laws.py) from a checkpoint of its state in ``ck``; at the first
    step in which a contact yields, the state goes back to the checkpoint and the block is
    stepped as below (two passes, the yielding contacts' fix-up :func:`plastic_yield`), as are
    the blocks after it until one has no yield: the same numbers either way."""
    half = 0.5 * dt
    n = a.shape[0]
    viscous = False
    for j in range(n):
        viscous = viscous or damping[j] != 0.0
    if aligned and ck[4, 10] == 0.0:
        _checkpoint(u, v, a, dmax, peak, acc, ck, True)
        predict(v, a, half, vp)
        if viscous:
            again = _fused_steps(u, v, vp, a, g, pw, kappa, damping, d0, fext, inv_mass, dyield, dmax, dres, kres,
                                 True, ns, dt, t0, wall_slot, peak, acc)
        else:
            again = _fused_steps(u, v, vp, a, g, pw, kappa, damping, d0, fext, inv_mass, dyield, dmax, dres, kres,
                                 False, ns, dt, t0, wall_slot, peak, acc)
        if not again:
            return
        _checkpoint(u, v, a, dmax, peak, acc, ck, False)
    predict(v, a, half, vp)
    yielded = False
    for s in range(ns):
        if aligned:
            if viscous:
                lo, hi = plastic_pass(u, vp, g, pw, kappa, damping, d0, dyield, dmax, dres, kres, True)
            else:
                lo, hi = plastic_pass(u, vp, g, pw, kappa, damping, d0, dyield, dmax, dres, kres, False)
            if hi >= 0:
                yielded = True
                plastic_yield(u, vp, g, pw, kappa, damping, d0, de, dx0, rsum, dyield, dmax, dres, kres, lo, hi)
        else:
            for j in range(n):
                g[j + 1], pw[j], dmax[j], dres[j], kres[j] = contact_general(
                    u[j], u[j + 1], vp[j], vp[j + 1], kappa[j], damping[j], d0[j], de[j], dx0[j], rsum[j],
                    LAW_ELASTOPLASTIC, dyield[j], dmax[j], dres[j], kres[j], False)
        p = total(pw) if viscous or not aligned else 0.0  # without a viscous term the powers are 0
        acc[0] += half * (acc[1] + p)  # trapezoidal integral of the dissipated power
        acc[1] = p
        _track_peak(g[wall_slot + 1], t0 + (s + 1) * dt, dt, peak)
        kick(u, v, vp, a, g, fext, inv_mass, dt, half, s == ns - 1)
    ck[4, 10] = 1.0 if yielded else 0.0
