"""The primal run of the derivative engines: velocity Verlet exactly as :func:`kernels._verlet_run`
steps it, with the step sequence and checkpoints recorded (the "tape").

A sensitivity is the derivative of the result the engine computes, on the step sequence it used:
the adaptive step (``kernels.required_stride``) is a discrete choice, so :func:`tape_forward`
records the number of steps ``ns`` of every block and the derivative engines
(:mod:`~hertzchain.integrate.derivatives.adjoint`, :mod:`~hertzchain.integrate.derivatives.tangent`) hold that sequence
fixed. The numbers are those of ``verlet_run`` bit for bit (the same compiled step functions in
the same order; tests/test_gradients_engine.py checks it), so ``Sensitivity.value`` is what
:func:`hertzchain.simulate` reports.

Memory. The reverse sweep needs the state of every step, read backwards. :func:`tape_forward`
keeps the state (u, v, a) at the start of every ``group``-th block (a checkpoint, 3 P doubles);
:func:`replay_group` runs a group again from its checkpoint and stores, per step, the positions
at which the forces are evaluated and the velocities the dissipative laws see (P doubles each).
The cost is one more primal run; the memory is 3 P / ``group`` doubles per block plus the steps
of one group.

Mass-in-mass beads (``ext``'s internal masses, ``extension.step_extended``): the internal masses
are stepped with the beads by the same kick-drift-kick (:func:`open_inner`, :func:`bodies_kick`,
the arithmetic of ``extension.body_accelerations``), their positions and velocities checkpointed
(two more rows) and their positions at every step stored by the replays (one more P).

Step convention (the KDK form of ``verlet_run``): step s, of length h, takes (u_s, v_s, a_s) to

    vh = v_s + h/2 a_s,  u_{s+1} = u_s + h vh,  vp_s = vh + h/2 a_s,
    F^(s) = F(u_{s+1}, vp_s),  a_{s+1} = (F^(s)_{i-1} - F^(s)_i + f_ext,i) / m_i,  v_{s+1} = vh + h/2 a_{s+1},

(paper eq. 1 for F). Steps are numbered over the whole run from 0; "step -1" is the state at
t = 0, whose forces F(u_0, v_0) are sample 0 of the records.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..core import kernels
from ..core.extension import EXT_IMIN, EXT_KIN, EXT_W, EXT_WV, body_accelerations, forces_linear, internal_acceleration


@njit(cache=True, nogil=True, inline="always")
def _store(dst, row, src):
    """dst[row, :] = src[:dst.shape[1]] as an element loop (a slice assignment costs ~100 ns a call)."""
    for i in range(dst.shape[1]):
        dst[row, i] = src[i]


@njit(cache=True, nogil=True, inline="always")
def open_inner(ext, wa, dt):
    """The internal masses' part of a block's opening half kick and drift (``extension.step_extended``)."""
    half = 0.5 * dt
    for i in range(wa.shape[0]):
        ext[i, EXT_WV] += half * wa[i]
        ext[i, EXT_W] += dt * ext[i, EXT_WV]


@njit(cache=True, nogil=True, inline="always")
def open_block(u, v, a, dt, ext, wa, inner):
    """A block's opening half kick and drift (:func:`_open_block`), the internal masses' too with
    ``inner`` (:func:`open_inner`)."""
    _open_block(u, v, a, dt)
    if inner:
        open_inner(ext, wa, dt)


@njit(cache=True, nogil=True, inline="always")
def inner_accelerations(u, ext, wa):
    """The internal masses' accelerations at the positions ``u`` (``extension.internal_acceleration``:
    a function of the positions, so a replay from a checkpoint finds them bit for bit)."""
    for i in range(wa.shape[0]):
        wa[i] = internal_acceleration(ext[i, EXT_KIN], ext[i, EXT_W], u[i], ext[i, EXT_IMIN])


@njit(cache=True, nogil=True, inline="always")
def bodies_kick(u, v, a, g, fext, inv_mass, dt, last, ext, wa, inner, xs):
    """A step's accelerations from its forces ``g``, then the kick v += dt a and the next drift
    u += dt v (a block's ``last`` step: only the closing half kick). With ``inner`` (mass-in-mass
    beads) the internal springs join the accelerations and the internal masses are kicked and
    drifted too (``extension.body_accelerations``, ``step_extended``: the same numbers), and ``xs``
    receives every spring's stretch w - u at the step (the derivative engines read it). The
    branches are taken outside the loops, so that LLVM vectorises the plain ones."""
    half = 0.5 * dt
    if inner:
        for i in range(a.shape[0]):
            xs[i] = ext[i, EXT_W] - u[i]
            a[i], wa[i] = body_accelerations(g[i], g[i + 1], fext[i], inv_mass[i], ext[i, EXT_KIN], ext[i, EXT_W], u[i],
                                             ext[i, EXT_IMIN])
            if last:
                v[i] += half * a[i]
                ext[i, EXT_WV] += half * wa[i]
            else:
                v[i] += dt * a[i]
                u[i] += dt * v[i]
                ext[i, EXT_WV] += dt * wa[i]
                ext[i, EXT_W] += dt * ext[i, EXT_WV]
    elif last:
        for i in range(a.shape[0]):
            a[i] = (g[i] - g[i + 1] + fext[i]) * inv_mass[i]
            v[i] += half * a[i]
    else:
        for i in range(a.shape[0]):
            a[i] = (g[i] - g[i + 1] + fext[i]) * inv_mass[i]
            v[i] += dt * a[i]
            u[i] += dt * v[i]


@njit(cache=True, nogil=True, inline="always")
def _general_block(u, v, a, g, vp, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, law, wall_slot, ns, dt, t0,
                   step, peak, kstar, store, stores, s0, state, extn):
    """One block of ``ns`` steps of length ``dt`` after :func:`_open_block`, as ``kernels._verlet_run`` steps it,
    with ``kernels.forces_general`` (dissipation, offsets), and with ``ext_on`` the linear mount of a
    protected body and the internal masses of mass-in-mass beads (``kernels.forces_linear``,
    :func:`bodies_kick`: ``kernels.step_extended``'s numbers). ``stores`` is (ustore, vpstore,
    hstore, pstore: the elastic-plastic state before each step, (3, steps, P), wstore: the internal
    masses' positions), ``state`` the elastic-plastic law's (dyield, dmax, dres, kres), ``extn``
    (ext, ext_on, inner: mass-in-mass beads, wa: their accelerations, xs: scratch): tuples, because a call
    with more than 30 arguments compiles to a star-args call, which Numba cannot inline."""
    ustore, vpstore, hstore, pstore, wstore = stores
    dyield, dmax, dres, kres = state
    ext, ext_on, inner, wa, xs = extn
    n = a.shape[0]
    half = 0.5 * dt
    plastic = store and law == kernels.LAW_ELASTOPLASTIC
    for s in range(ns):
        for i in range(n):
            vp[i] = v[i] + half * a[i]
        if store:
            _store(ustore, s0 + s, u)
            _store(vpstore, s0 + s, vp)
            hstore[s0 + s] = dt
        if store and inner:
            for i in range(n):
                wstore[s0 + s, i] = ext[i, EXT_W]
        if plastic:  # the elastic-plastic state the step's forces start from
            for i in range(n):
                pstore[0, s0 + s, i] = dmax[i]
                pstore[1, s0 + s, i] = dres[i]
                pstore[2, s0 + s, i] = kres[i]
        kernels.forces_general(u, vp, kappa, damping, d0, de, dx0, rsum, law, g, dyield, dmax, dres, kres)
        if ext_on:  # a protected body's mount (kernels.step_extended, without internal masses)
            forces_linear(u, vp, d0, ext, g)
        before = peak[0]
        kernels._track_peak(g[wall_slot + 1], t0 + (s + 1) * dt, dt, peak)
        if g[wall_slot + 1] > before:
            kstar[0] = step + s
        # the plain kicks written here rather than through bodies_kick: inlined, its code for the
        # internal masses (not taken) made the taped run of a protected body ~13 % slower
        if inner:
            bodies_kick(u, v, a, g, fext, inv_mass, dt, s == ns - 1, ext, wa, inner, xs)
        elif s < ns - 1:
            for i in range(n):
                a[i] = (g[i] - g[i + 1] + fext[i]) * inv_mass[i]
                v[i] += dt * a[i]
                u[i] += dt * v[i]
        else:
            for i in range(n):
                a[i] = (g[i] - g[i + 1] + fext[i]) * inv_mass[i]
                v[i] += half * a[i]


@njit(cache=True, nogil=True, inline="always")
def _dissipative_block(u, v, vp, a, g, inv_mass, kappa, damping, d0, fext, law, wall_slot, ns, dt, t0, step, peak,
                       kstar, store, ustore, vpstore, hstore, s0):
    """One block for an aligned viscoelastic or dashpot chain with the engine's fused step
    (``kernels.step_dissipative``, as ``kernels.dissipative_block``: the same numbers as
    :func:`_general_block`, in one pass; ``vp`` its P + 1 predicted velocities); with ``store``
    every step's positions and predicted velocities v + dt/2 a are stored (the velocities the
    forces see)."""
    half = 0.5 * dt
    n = a.shape[0]
    kernels.predict(v, a, half, vp)
    for s in range(ns):
        if store:
            _store(ustore, s0 + s, u)
            for i in range(n):
                vpstore[s0 + s, i] = vp[i]
            hstore[s0 + s] = dt
        kernels.step_dissipative(u, v, vp, a, g, kappa, damping, d0, fext, inv_mass, law, dt, half, s == ns - 1)
        before = peak[0]
        kernels._track_peak(g[wall_slot + 1], t0 + (s + 1) * dt, dt, peak)
        if g[wall_slot + 1] > before:
            kstar[0] = step + s


@njit(cache=True, nogil=True, inline="always")
def _elastic_block(u, v, a, g, inv_mass, kappa, d0, fext, wall_slot, ns, dt, block, t0, step, peak, kstar):
    """One block of ``ns`` steps for an aligned elastic chain (``kernels.step_elastic``)."""
    for s in range(ns - 1):
        kernels.step_elastic(u, v, a, g, kappa, d0, fext, inv_mass, dt)
        before = peak[0]
        kernels._track_peak(g[wall_slot + 1], t0 + (s + 1) * dt, dt, peak)
        if g[wall_slot + 1] > before:
            kstar[0] = step + s
    kernels.final_step_elastic(u, v, a, g, kappa, d0, fext, inv_mass, 0.5 * dt)
    before = peak[0]
    kernels._track_peak(g[wall_slot + 1], t0 + block, dt, peak)
    if g[wall_slot + 1] > before:
        kstar[0] = step + ns - 1


@njit(cache=True, nogil=True, inline="always")
def _elastic_block_stored(u, v, a, g, inv_mass, kappa, d0, fext, ns, dt, ustore, hstore, s0):
    """:func:`_elastic_block` storing every step's positions (no peak tracking: a replay)."""
    for s in range(ns - 1):
        _store(ustore, s0 + s, u)
        hstore[s0 + s] = dt
        kernels.step_elastic(u, v, a, g, kappa, d0, fext, inv_mass, dt)
    _store(ustore, s0 + ns - 1, u)
    hstore[s0 + ns - 1] = dt
    kernels.final_step_elastic(u, v, a, g, kappa, d0, fext, inv_mass, 0.5 * dt)


@njit(cache=True, nogil=True, inline="always")
def _open_block(u, v, a, dt):
    """The opening half kick and drift of a block: v += dt/2 a, u += dt v."""
    half = 0.5 * dt
    for i in range(a.shape[0]):
        v[i] += half * a[i]
        u[i] += dt * v[i]


@njit(cache=True, nogil=True, inline="always")
def record_sample(k, g, v, rec, out_f, fmax, fmax_k):
    """Sample ``k`` of a taped run: the forces of the contacts ``rec`` into ``out_f[k]``, every
    contact's largest sampled force ``fmax`` and the sample ``fmax_k`` it came from; returns True
    when the state is no longer finite."""
    for j in range(rec.shape[0]):
        out_f[k, j] = g[rec[j] + 1]
    g1 = g[1:]
    for j in range(fmax.shape[0]):  # selects, not branches: LLVM vectorises them
        x = g1[j]
        up = x > fmax[j]
        fmax_k[j] = k if up else fmax_k[j]
        fmax[j] = x if up else fmax[j]
    return not np.isfinite(g[1]) or not np.isfinite(v[0])


@njit(cache=True, nogil=True)
def has_inner(ext):
    """Whether the extension ``ext`` holds internal masses (mass-in-mass beads)."""
    for i in range(ext.shape[0]):
        if ext[i, EXT_KIN] != 0.0:
            return True
    return False


@njit(cache=True, nogil=True, inline="always")
def checkpoint(ck, u, v, a, ext, inner):
    """The state (u, v, a) into rows 0-2 of checkpoint ``ck`` (element loops: a slice assignment per
    block cost as much as the block) and, with ``inner``, the internal masses' positions and
    velocities into its last two rows (a law's state goes between: the caller's)."""
    for i in range(ck.shape[1]):
        ck[0, i] = u[i]
        ck[1, i] = v[i]
        ck[2, i] = a[i]
    if inner:
        r = ck.shape[0] - 2
        for i in range(ck.shape[1]):
            ck[r, i] = ext[i, EXT_W]
            ck[r + 1, i] = ext[i, EXT_WV]


@njit(cache=True, nogil=True, inline="always")
def restore_inner(ck, u, ext, wa):
    """The internal masses' state from checkpoint ``ck`` (:func:`checkpoint`), their
    accelerations from the positions (``u`` restored first)."""
    r = ck.shape[0] - 2
    for i in range(ck.shape[1]):
        ext[i, EXT_W] = ck[r, i]
        ext[i, EXT_WV] = ck[r + 1, i]
    inner_accelerations(u, ext, wa)


@njit(cache=True, nogil=True)
def _fused(general, law, de, ext_on):
    """Whether ``kernels._verlet_run`` steps this system with its fused dissipative step: an
    aligned viscoelastic or dashpot chain without a protected body."""
    aligned = True
    for i in range(de.shape[0]):
        aligned = aligned and de[i] == 0.0
    return general and aligned and not ext_on and (law == kernels.LAW_VISCOELASTIC or law == kernels.LAW_DASHPOT)


@njit(cache=True, nogil=True)
def tape_forward(u, v, a, g, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, dcap, dyield, dmax, dres, kres, law,
                 general, wall_slot, interval, stride, n_sub, n_eval, c_steps, relax, n_samples, rec, out_f, fmax,
                 fmax_k, peak, kstar, acc, ns_log, step_end, ckpt, group, ext, ext_on):
    """The primal run from t = 0 to sample ``n_samples - 1``, taped.

    State on entry as :func:`hertzchain.integrate.drivers.verlet.initialise` leaves it (sample 0 of
    ``out_f``, ``fmax``, ``peak`` and ``acc`` written). Writes, per block b (``n_sub`` per sample
    interval): ``ns_log[b]`` its number of steps, and the state (u, v, a) at its start into
    ``ckpt[b // group]`` when b is a multiple of ``group``; per sample k: ``step_end[k]`` the
    number of steps made up to it (the forces of sample k are those of step
    ``step_end[k] - 1``), ``out_f[k]`` the forces of the contacts ``rec``, and every contact's
    largest sampled force ``fmax`` with the sample ``fmax_k`` it came from. Returns 0, or 1 when
    the state became non-finite. The elastic-plastic law's state (``dmax``, ``dres``, ``kres``:
    ``kernels.elastoplastic_force``) is carried in place, and checkpointed too when ``ckpt`` has
    rows for it (6 rows: u, v, a, dmax, dres, kres), and so are the internal masses of mass-in-mass
    beads (their positions and velocities, the two rows after those).
    """
    n = a.shape[0]
    plastic_rows = law == kernels.LAW_ELASTOPLASTIC
    inner = has_inner(ext)
    wa = np.zeros(n)
    xs = np.zeros(n)
    if inner:
        inner_accelerations(u, ext, wa)
    block = interval / n_sub
    adaptive = stride == 0
    ns = stride if not adaptive else int(acc[3])
    vp = np.zeros_like(v)
    fused = _fused(general, law, de, ext_on)
    dummy = np.zeros((1, 1))
    dummy_h = np.zeros(1)
    dummy_p = np.zeros((3, 1, 1))
    step = 0
    step_end[0] = 0
    for k in range(1, n_samples):
        for b in range(n_sub):
            bi = (k - 1) * n_sub + b
            if adaptive and bi % n_eval == 0:
                req = kernels.required_stride(u, v, a, kappa, d0, de, dx0, rsum, dcap, inv_mass, n_eval * block,
                                              block, c_steps, damping, law, ext, ext_on)
                ns = kernels._adapt_stride(req, ns, relax, acc)
            if bi % group == 0:
                c = bi // group
                checkpoint(ckpt[c], u, v, a, ext, inner)
                if plastic_rows:
                    for i in range(n):
                        ckpt[c, 3, i] = dmax[i]
                        ckpt[c, 4, i] = dres[i]
                        ckpt[c, 5, i] = kres[i]
            ns_log[bi] = ns
            # The two paths are called apart (not through one function holding both): LLVM then
            # vectorises the elastic step as in verlet_run (~2.5x faster).
            dt = block / ns
            t0 = (k - 1) * interval + b * block
            open_block(u, v, a, dt, ext, wa, inner)
            if fused:
                _dissipative_block(u, v, vp, a, g, inv_mass, kappa, damping, d0, fext, law, wall_slot, ns, dt, t0,
                                   step, peak, kstar, False, dummy, dummy, dummy_h, 0)
            elif general:
                _general_block(u, v, a, g, vp, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, law, wall_slot, ns,
                               dt, t0, step, peak, kstar, False, (dummy, dummy, dummy_h, dummy_p, dummy), 0,
                               (dyield, dmax, dres, kres), (ext, ext_on, inner, wa, xs))
            else:
                _elastic_block(u, v, a, g, inv_mass, kappa, d0, fext, wall_slot, ns, dt, block, t0, step, peak, kstar)
            step += ns
        step_end[k] = step
        if record_sample(k, g, v, rec, out_f, fmax, fmax_k):
            acc[2] = step
            return 1
    acc[2] = step
    return 0


@njit(cache=True, nogil=True)
def replay_group(ckpt_g, u, v, a, g, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, law, general, wall_slot,
                 ns_log, b0, b1, block, stores, dyield, dmax, dres, kres, ext, ext_on):
    """Run blocks ``b0`` to ``b1 - 1`` again from their group's checkpoint ``ckpt_g`` with the taped
    step counts, storing every step's force-evaluation state into ``stores`` = (ustore, vpstore,
    hstore, pstore, wstore) (:func:`_general_block`; ``pstore``: the elastic-plastic state before each
    step; ``wstore``: the internal masses' positions); returns the number of steps stored. ``u, v, a, g`` (and the elastic-plastic state) are scratch."""
    n = a.shape[0]
    for i in range(n):
        u[i] = ckpt_g[0, i]
        v[i] = ckpt_g[1, i]
        a[i] = ckpt_g[2, i]
    if law == kernels.LAW_ELASTOPLASTIC:
        for i in range(n):
            dmax[i] = ckpt_g[3, i]
            dres[i] = ckpt_g[4, i]
            kres[i] = ckpt_g[5, i]
    inner = has_inner(ext)
    wa = np.zeros(n)
    if inner:
        restore_inner(ckpt_g, u, ext, wa)
    vp = np.zeros_like(v)
    fused = _fused(general, law, de, ext_on)
    peak = np.zeros(8)
    kstar = np.zeros(1, dtype=np.int64)
    s0 = 0
    for b in range(b0, b1):
        ns = ns_log[b]
        dt = block / ns
        open_block(u, v, a, dt, ext, wa, inner)
        if fused:
            _dissipative_block(u, v, vp, a, g, inv_mass, kappa, damping, d0, fext, law, wall_slot, ns, dt, 0.0, 0,
                               peak, kstar, True, stores[0], stores[1], stores[2], s0)
        elif general:
            _general_block(u, v, a, g, vp, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, law, wall_slot, ns, dt,
                           0.0, 0, peak, kstar, True, stores, s0, (dyield, dmax, dres, kres),
                           (ext, ext_on, inner, wa, wa.copy()))
        else:
            _elastic_block_stored(u, v, a, g, inv_mass, kappa, d0, fext, ns, dt, stores[0], stores[2], s0)
        s0 += ns
    return s0
