"""The derivative engines of a registry law run by the generated engines (:mod:`hertzchain.laws`):
its taped primal run, the tangent-linear model and the discrete adjoint, built from the law's
declared scalar functions (``force``, ``state``, ``partials`` and, for a law with state,
``state_partials``), once per law and process.

The primal is the generated run (:func:`hertzchain.integrate.core.generated.law_kernels`: its compiled
``forces`` and adaptive ``stride``, called here, so the taped run is ``simulate``'s bit for bit);
the steps follow the convention of :mod:`hertzchain.integrate.derivatives.tape`. Each contact j of a step
gives the partials of its axial force F_j and of its new state s'_j with respect to
w = u_j - u_{j+1}, the relative velocity the force sees, the System parameters kappa (the law's
k), damping (the law's p), d0, de, dx0, rsum, and the state s_j before the step
(:func:`contact_partials` below: the law's partials through the contact's geometry, aligned or
misaligned, and through its state update s' = state(delta, rate, k, p, s)):

    F' = dF/dw w' + dF/dv v' + sum dF/dtheta theta' + dF/ds s',    s'_new = ds'/dw w' + ... + ds'/ds s'

The tangent carries (u', v', a', s') per direction; the adjoint carries (u, v, a, s) adjoints
backwards, the state's from step to step and checkpoint group to group (checkpoints hold the
state: 4 P doubles; a replayed step stores positions, predicted velocities and the state before
it: 3 P). Non-smooth points are those of :mod:`hertzchain.integrate.derivatives.partials`: overlaps below
``kernels.DELTA_MIN`` count as zero (no delta-derivative), a force clipped at zero has no
partials (its state's still flow), and a branch of the state update (Hunt-Crossley's running
maximum) is held as the computed run took it. A protected body's mount and mass-in-mass beads
are the extension's, stepped and differentiated by the pieces the hand-written engines use
(:func:`partials.mount_partials`, ``tape.bodies_kick``, ``adjoint.inner_back``,
``tangent._inner_tangent``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .adjoint import _bodies_back, _clear_seeds, _take_seeds, group_starts, initial_bodies_back, inner_back
from ..core.extension import EXT_W, extension_stride, forces_linear
from ..core.kernels import DELTA_MIN, _adapt_stride
from ..core.primitives import _track_peak
from .partials import contact_geometry, has_mount, mount_partials
from .tangent import _seeded, tangent_drift, tangent_kick
from .tape import (bodies_kick, checkpoint, inner_accelerations, open_block, record_sample,
                   restore_inner)

#: Rows of a contact's partials (of F, and of the new state): w, v, then the System parameters in
#: the order of the gradient rows (kappa, damping, d0, de, dx0, rsum), then the state before, then
#: a protected body's mount (its spring k and dashpot c, on contact N + 1: ``extension.linear_force``).
ROWS = 11
_CACHE: dict = {}


@njit(cache=True, nogil=True)
def _no_state(d, rate, k, p, s):
    """A law without state: s' = s, and the force does not read it."""
    return 0.0, 0.0, 0.0, 0.0, 0.0, 1.0


def law_engines(code: int, inner: bool = False, mount: bool = False):
    """(tape_forward, replay_group, tangent_run, reverse_sweep, initial) for the generated law of
    engine code ``code`` (``inner``: for a model with mass-in-mass beads; ``mount``: with the
    extension, a protected body's mount among it), built on first use; a
    :class:`ConfigError` naming ``contact.law`` for a law with state that declares no
    ``state_partials``."""
    from ...errors import ConfigError
    from ...laws import law_of_code
    from ...laws.spec import compiled
    from ..core.generated import law_kernels

    spec = law_of_code(code)
    if spec.state_size and spec.state_partials is None:
        raise ConfigError("contact.law", f"law {spec.name!r} has a per-contact state but declares no state_partials "
                          "(dF/ds and the state update's partials): its sensitivities cannot be carried through "
                          "the state; add them to its LawSpec (docs/guide/laws.rst)")
    kernels = law_kernels(code)
    sp = compiled(spec.state_partials) if spec.state_partials is not None else _no_state
    key = (code, id(kernels[0]), id(sp), id(spec.partials), bool(inner), bool(mount))
    if key not in _CACHE:
        _CACHE[key] = _build(compiled(spec.force), compiled(spec.state), compiled(spec.partials), sp, kernels[0],
                             kernels[3], spec.state_size > 0, bool(inner), bool(mount))
    return _CACHE[key]


def _build(force, update, partials, state_partials, gforces, gstride, stateful, inner, mount):
    """The engines of one law; ``stateful`` (the law has a state), ``inner`` (mass-in-mass beads) and
    ``mount`` (the extension's linear springs) are constants of the closures: Numba prunes the
    branches not taken (the extension's, taken at run time, made the runs ~1.2x slower)."""
    nrows = ROWS if mount else ROWS - 2  # columns of a contact's partials written (the mount's last)
    @njit(nogil=True, inline="always")
    def contact_partials(uj, uj1, vj, vj1, k, p, d0, de, dx0, rsum, s, cf, ch, j):
        """Axial force F of contact j (as the generated ``forces`` computes it) at state ``s`` before
        the step; writes its partials into row j of ``cf`` and those of the new state into ``ch``
        (columns: :data:`ROWS`). ``stateful`` (a constant of the closure: the branch not taken is
        not compiled) leaves a law without state its one carried state."""
        for r in range(nrows):
            cf[j, r] = 0.0
            ch[j, r] = 0.0
        ch[j, 8] = 1.0
        if k == 0.0:  # no contact: the state is carried
            return 0.0
        d, c, dx, dist = contact_geometry(uj, uj1, d0, de, dx0, rsum)
        if de != 0.0:  # misaligned: delta = rsum - dist(dx), c = dx / dist, F = c f(delta, c vrel)
            inv3 = 1.0 / (dist * dist * dist)
            c_w = -de * de * inv3  # dc/dw; dc/ddx0 = -dc/dw
            c_de = -dx * de * inv3
            d_w, d_0, d_de, d_dx0, d_rs = c, 0.0, -de / dist, -c, 1.0
        else:
            c_w, c_de = 0.0, 0.0
            d_w, d_0, d_de, d_dx0, d_rs = 1.0, 1.0, 0.0, 0.0, 0.0
        vrel = vj - vj1
        rate = c * vrel
        s1 = update(d, rate, k, p, s)
        ss = 1.0
        if stateful:
            _, sd, sr, sk, sp, ss = state_partials(d, rate, k, p, s)
            ch[j, 0] = sd * d_w + sr * vrel * c_w
            ch[j, 1] = sr * c
            ch[j, 2] = sk
            ch[j, 3] = sp
            ch[j, 4] = sd * d_0
            ch[j, 5] = sd * d_de + sr * vrel * c_de
            ch[j, 6] = sd * d_dx0 - sr * vrel * c_w
            ch[j, 7] = sd * d_rs
            ch[j, 8] = ss
        if d < 0.0:
            return 0.0
        on = d > DELTA_MIN
        dd = d if on else 0.0
        f = force(dd, rate, k, p, s1)
        if not f > 0.0:  # clipped (never attractive): no partials
            return 0.0
        fd, fr, fk, fp = partials(dd, rate, k, p, s1)
        fd = fd if on else 0.0
        fs = state_partials(dd, rate, k, p, s1)[0] if stateful else 0.0
        cf[j, 0] = c_w * f + c * (fd * d_w + fr * vrel * c_w + fs * ch[j, 0])
        cf[j, 1] = c * (fr * c + fs * ch[j, 1])
        cf[j, 2] = c * (fk + fs * ch[j, 2])
        cf[j, 3] = c * (fp + fs * ch[j, 3])
        cf[j, 4] = c * (fd * d_0 + fs * ch[j, 4])
        cf[j, 5] = c_de * f + c * (fd * d_de + fr * vrel * c_de + fs * ch[j, 5])
        cf[j, 6] = -c_w * f + c * (fd * d_dx0 - fr * vrel * c_w + fs * ch[j, 6])
        cf[j, 7] = c * (fd * d_rs + fs * ch[j, 7])
        cf[j, 8] = c * fs * ss
        return c * f

    @njit(nogil=True, inline="always")
    def partials_ext(uj, uj1, vj, vj1, k, p, d0, de, dx0, rsum, s, cf, ch, j, ext):
        """:func:`contact_partials` with the mount's spring and dashpot of contact slot j in ``ext``
        (empty: none), in parallel with the law as the generated run adds them
        (``extension.forces_linear``): the axial force and its partials, columns 9, 10 by k and c."""
        f = contact_partials(uj, uj1, vj, vj1, k, p, d0, de, dx0, rsum, s, cf, ch, j)
        if mount and has_mount(ext, j):
            fl, kl, cl, cf[j, 9], cf[j, 10] = mount_partials(ext, j, uj, uj1, vj, vj1, d0)
            cf[j, 0] += kl
            cf[j, 4] += kl
            cf[j, 1] += cl
            f += fl
        return f

    # The forces of a step are the law's (``gforces``), then, with ``mount``, the mount's
    # (``extension.forces_linear``), called in the loops themselves: a wrapper around the two, even
    # inlined, cost the taped run ~12 %.
    if mount:
        @njit(nogil=True, inline="always")
        def step_stride(u, v, a, kappa, damping, d0, de, dx0, rsum, dcap, state, inv_mass, horizon, block, c_steps,
                        ext):
            """The steps per block the generated run takes: the law's bound, plus the extension's."""
            return (gstride(u, v, a, kappa, damping, d0, de, dx0, rsum, dcap, state, inv_mass, horizon, block, c_steps)
                    + extension_stride(ext, inv_mass, block, c_steps))
    else:
        @njit(nogil=True, inline="always")
        def step_stride(u, v, a, kappa, damping, d0, de, dx0, rsum, dcap, state, inv_mass, horizon, block, c_steps,
                        ext):
            """The steps per block the generated run takes (no extension)."""
            return gstride(u, v, a, kappa, damping, d0, de, dx0, rsum, dcap, state, inv_mass, horizon, block, c_steps)

    @njit(nogil=True)
    def tape_forward(u, v, a, g, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, dcap, dyield, dmax, dres, kres, law,
                     general, wall_slot, interval, stride, n_sub, n_eval, c_steps, relax, n_samples, rec, out_f, fmax,
                     fmax_k, peak, kstar, acc, ns_log, step_end, ckpt, group, ext, ext_on):
        """``tape.tape_forward`` for the generated law (the arguments alike; ``dmax`` holds the
        law's state, checkpointed as row 3; mass-in-mass beads' internal masses as the last two): the
        generated run's steps, taped."""
        n = a.shape[0]
        block = interval / n_sub
        adaptive = stride == 0
        ns = stride if not adaptive else int(acc[3])
        vp = np.zeros_like(v)
        wa = np.zeros(n)
        xs = np.zeros(n)
        if inner:
            inner_accelerations(u, ext, wa)
        step = 0
        step_end[0] = 0
        for k in range(1, n_samples):
            for b in range(n_sub):
                bi = (k - 1) * n_sub + b
                if adaptive and bi % n_eval == 0:
                    req = step_stride(u, v, a, kappa, damping, d0, de, dx0, rsum, dcap, dmax, inv_mass, n_eval * block,
                                      block, c_steps, ext)
                    ns = _adapt_stride(req, ns, relax, acc)
                if bi % group == 0:
                    c = bi // group
                    checkpoint(ckpt[c], u, v, a, ext, inner)
                    for i in range(n):
                        ckpt[c, 3, i] = dmax[i]
                ns_log[bi] = ns
                dt = block / ns
                half = 0.5 * dt
                t0 = (k - 1) * interval + b * block
                open_block(u, v, a, dt, ext, wa, inner)
                for s in range(ns):
                    for i in range(n):
                        vp[i] = v[i] + half * a[i]
                    gforces(u, vp, kappa, damping, d0, de, dx0, rsum, g, dmax)
                    if mount:
                        forces_linear(u, vp, d0, ext, g)
                    before = peak[0]
                    _track_peak(g[wall_slot + 1], t0 + (s + 1) * dt, dt, peak)
                    if g[wall_slot + 1] > before:
                        kstar[0] = step + s
                    bodies_kick(u, v, a, g, fext, inv_mass, dt, s == ns - 1, ext, wa, inner, xs)
                step += ns
            step_end[k] = step
            if record_sample(k, g, v, rec, out_f, fmax, fmax_k):
                acc[2] = step
                return 1
        acc[2] = step
        return 0

    @njit(nogil=True)
    def replay_group(ckpt_g, u, v, a, g, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, law, general, wall_slot,
                     ns_log, b0, b1, block, stores, dyield, dmax, dres, kres, ext, ext_on):
        """``tape.replay_group`` for the generated law: ``stores`` = (ustore, vpstore, hstore, pstore,
        wstore), pstore[0] the state each step started from, wstore the internal masses' positions."""
        ustore, vpstore, hstore, pstore, wstore = stores
        n = a.shape[0]
        for i in range(n):
            u[i] = ckpt_g[0, i]
            v[i] = ckpt_g[1, i]
            a[i] = ckpt_g[2, i]
            dmax[i] = ckpt_g[3, i]
        wa = np.zeros(n)
        xs = np.zeros(n)
        if inner:
            restore_inner(ckpt_g, u, ext, wa)
        vp = np.zeros_like(v)
        s0 = 0
        for b in range(b0, b1):
            ns = ns_log[b]
            dt = block / ns
            half = 0.5 * dt
            open_block(u, v, a, dt, ext, wa, inner)
            for s in range(ns):
                for i in range(n):
                    vp[i] = v[i] + half * a[i]
                    ustore[s0 + s, i] = u[i]
                    vpstore[s0 + s, i] = vp[i]
                    pstore[0, s0 + s, i] = dmax[i]
                if inner:
                    for i in range(n):
                        wstore[s0 + s, i] = ext[i, EXT_W]
                hstore[s0 + s] = dt
                gforces(u, vp, kappa, damping, d0, de, dx0, rsum, g, dmax)
                if mount:
                    forces_linear(u, vp, d0, ext, g)
                bodies_kick(u, v, a, g, fext, inv_mass, dt, s == ns - 1, ext, wa, inner, xs)
            s0 += ns
        return s0

    @njit(nogil=True)
    def tangent_run(u, v, a, g, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, dcap, state, interval, stride, n_sub,
                    n_eval, c_steps, relax, n_samples, acc, th, v0t, rec, out_f, out_ft, seed_step, seed_contact,
                    seed_w, dj, ext):
        """``tangent.tangent_run`` for the generated law (``state``: the law's state after t = 0, as
        ``verlet.initialise`` leaves it; the state before t = 0 is zero): the generated run with D
        tangents, the state's among them."""
        n = a.shape[0]
        nd = th.shape[1]
        block = interval / n_sub
        adaptive = stride == 0
        ns = stride if not adaptive else int(acc[3])
        m = nd * (n + 1)
        ut, vt, at, ft, st = np.zeros(m), np.zeros(m), np.zeros(m), np.zeros(m), np.zeros(m)
        pf, ph, thf, thm = np.zeros(m), np.zeros(m), np.zeros(m), np.zeros(m)
        vpt = np.zeros(n + 1)
        vp = np.zeros_like(v)
        cf = np.zeros((n, ROWS))
        ch = np.zeros((n, ROWS))
        for dd in range(nd):
            for i in range(n):
                thf[dd * (n + 1) + i] = th[6, dd, i]
                thm[dd * (n + 1) + i] = th[7, dd, i]
        wa, xs = np.zeros(n), np.zeros(n)
        inn_t = (np.zeros(m if inner else 1), np.zeros(m if inner else 1), np.zeros(m if inner else 1))
        if inner:
            inner_accelerations(u, ext, wa)
            for i in range(n):
                xs[i] = ext[i, EXT_W] - u[i]
        for j in range(n - 1):  # t = 0: F(u_0, v_0) from the state 0
            partials_ext(u[j], u[j + 1], v[j], v[j + 1], kappa[j], damping[j], d0[j], de[j], dx0[j], rsum[j], 0.0, cf,
                         ch, j, ext)
        _parameter_forces(cf, ch, th, pf, ph, mount)
        for dd in range(nd):
            o = dd * (n + 1)
            for i in range(n):
                vt[o + i] = v0t[dd, i]
                vpt[i] = vt[o + i]
            _contact_tangents(cf, ch, ut, vpt, ft, st, pf, ph, o, n)
            tangent_kick(ut, vt, at, ft, g, thf, thm, th, dd, o, inv_mass, fext, 0.0, inner, inn_t, xs, ext)
            for r in range(rec.shape[0]):
                out_ft[dd, 0, r] = ft[o + rec[r] + 1]
        p = _seeded(-1, 0, seed_step, seed_contact, seed_w, ft, ut, vt, nd, n, dj)
        step = 0
        for k in range(1, n_samples):
            for b in range(n_sub):
                bi = (k - 1) * n_sub + b
                if adaptive and bi % n_eval == 0:
                    req = step_stride(u, v, a, kappa, damping, d0, de, dx0, rsum, dcap, state, inv_mass,
                                      n_eval * block, block, c_steps, ext)
                    ns = _adapt_stride(req, ns, relax, acc)
                dt = block / ns
                hh = 0.5 * dt
                open_block(u, v, a, dt, ext, wa, inner)
                for s in range(ns):
                    for i in range(n):
                        vp[i] = v[i] + hh * a[i]
                    for j in range(n - 1):  # partials at the state before the step, then the step
                        partials_ext(u[j], u[j + 1], vp[j], vp[j + 1], kappa[j], damping[j], d0[j], de[j], dx0[j],
                                     rsum[j], state[j], cf, ch, j, ext)
                    gforces(u, vp, kappa, damping, d0, de, dx0, rsum, g, state)
                    if mount:
                        forces_linear(u, vp, d0, ext, g)
                    bodies_kick(u, v, a, g, fext, inv_mass, dt, s == ns - 1, ext, wa, inner, xs)
                    _parameter_forces(cf, ch, th, pf, ph, mount)
                    for dd in range(nd):
                        o = dd * (n + 1)
                        tangent_drift(ut, vt, at, vpt, o, dt, n, inner, inn_t)
                        _contact_tangents(cf, ch, ut, vpt, ft, st, pf, ph, o, n)
                        tangent_kick(ut, vt, at, ft, g, thf, thm, th, dd, o, inv_mass, fext, dt, inner, inn_t, xs, ext)
                    p = _seeded(step + s, p, seed_step, seed_contact, seed_w, ft, ut, vt, nd, n, dj)
                step += ns
            for r in range(rec.shape[0]):
                out_f[k, r] = g[rec[r] + 1]
                for dd in range(nd):
                    out_ft[dd, k, r] = ft[dd * (n + 1) + rec[r] + 1]
            if not np.isfinite(g[1]) or not np.isfinite(v[0]):
                return 1
        return 0

    @njit(nogil=True)
    def steps(nsteps, ustore, vpstore, hstore, pstore, step0, ub, vb, ab, sb, fb, fs, wb, rb, inv_mass, kappa,
              damping, d0, de, dx0, rsum, fext, seed_step, seed_contact, seed_w, ptr, grad, cf, ch, ext, inn):
        """Steps ``step0 + nsteps - 1`` down to ``step0`` in reverse (``adjoint._steps_general`` with
        the law's partials; ``sb`` the adjoints of the state after the step, carried backwards;
        ``inn`` = (wstore, wub, wvb, wab, inner): mass-in-mass beads, ``adjoint.inner_back``)."""
        n = ab.shape[0]
        p = ptr
        wstore, wub, wvb, wab, inner = inn
        fs1, wb1, rb1 = fs[1:], wb[1:], rb[1:]
        for sl in range(nsteps - 1, -1, -1):
            h = hstore[sl]
            hh = 0.5 * h
            q = _take_seeds(step0 + sl, p, fb, ub, vb, seed_step, seed_contact, seed_w)
            for j in range(n - 1):
                f = partials_ext(ustore[sl, j], ustore[sl, j + 1], vpstore[sl, j], vpstore[sl, j + 1], kappa[j],
                                 damping[j], d0[j], de[j], dx0[j], rsum[j], pstore[0, sl, j], cf, ch, j, ext)
                fbar = fb[j] + inv_mass[j + 1] * (ab[j + 1] + hh * vb[j + 1]) - inv_mass[j] * (ab[j] + hh * vb[j])
                _contact_adjoint(j, f, fbar, cf, ch, sb, fs, wb, rb, grad, mount)
            if inner:
                inner_back(h, ustore, wstore, sl, ub, vb, ab, wub, wvb, wab, inv_mass, ext, grad)
            _bodies_back(h, ub, vb, ab, fs, fs1, wb, wb1, rb, rb1, inv_mass, fext, grad[7], grad[6], True, True)
            _clear_seeds(p, q, fb, seed_contact)
            p = q
        return p

    @njit(nogil=True)
    def initial(u0, v0, ub, vb, ab, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, seed_step, seed_contact,
                seed_w, ptr, grad, sb, ext, inn):
        """``adjoint._adjoint_initial`` for the generated law: the forces at t = 0 from the state 0
        (``inn`` = (w0, wub, wvb, wab, inner), as there)."""
        n = ab.shape[0]
        fb = np.zeros(n)
        p = _take_seeds(-1, ptr, fb, ub, vb, seed_step, seed_contact, seed_w)
        fs, wb, rb = np.zeros(n + 1), np.zeros(n + 1), np.zeros(n + 1)
        cf = np.zeros((n, ROWS))
        ch = np.zeros((n, ROWS))
        for j in range(n - 1):
            f = partials_ext(u0[j], u0[j + 1], v0[j], v0[j + 1], kappa[j], damping[j], d0[j], de[j], dx0[j],
                             rsum[j], 0.0, cf, ch, j, ext)
            fbar = fb[j] + inv_mass[j + 1] * ab[j + 1] - inv_mass[j] * ab[j]
            _contact_adjoint(j, f, fbar, cf, ch, sb, fs, wb, rb, grad, mount)
        initial_bodies_back(u0, ub, vb, ab, fs, wb, rb, inv_mass, fext, grad, ext, inn)
        return p

    @njit(nogil=True)
    def reverse_sweep(ckpt, ns_log, group, n_blocks, block, u0, v0, ub, vb, ab, inv_mass, kappa, damping, d0, de, dx0,
                      rsum, fext, law, general, wall_slot, seed_step, seed_contact, seed_w, grad, max_rows, ext, dyield,
                      sb, w0):
        """``adjoint._reverse_sweep`` for the generated law (the arguments alike; ``sb[0]``: the
        adjoints of the law's state, zero on entry)."""
        n = ab.shape[0]
        u, v, a, g = np.zeros(n + 1), np.zeros(n + 1), np.zeros(n), np.zeros(n + 1)
        state = np.zeros(n)
        stores = (np.zeros((max_rows, n)), np.zeros((max_rows, n)), np.zeros(max_rows), np.zeros((1, max_rows, n)),
                  np.zeros((max_rows if inner else 1, n)))
        wub, wvb, wab = np.zeros(n), np.zeros(n), np.zeros(n)
        fb, fs, wb, rb = np.zeros(n), np.zeros(n + 1), np.zeros(n + 1), np.zeros(n + 1)
        cf = np.zeros((n, ROWS))
        ch = np.zeros((n, ROWS))
        sbar = sb[0]
        n_groups = (n_blocks + group - 1) // group
        starts = group_starts(ns_log, group, n_blocks)
        p = seed_step.shape[0]
        for gi in range(n_groups - 1, -1, -1):
            b0 = gi * group
            b1 = min(b0 + group, n_blocks)
            rows = replay_group(ckpt[gi], u, v, a, g, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, law, general,
                                wall_slot, ns_log, b0, b1, block, stores, dyield, state, state, state, ext,
                                ext.shape[0] > 0)
            p = steps(rows, stores[0], stores[1], stores[2], stores[3], starts[gi], ub, vb, ab, sbar, fb, fs, wb, rb,
                      inv_mass, kappa, damping, d0, de, dx0, rsum, fext, seed_step, seed_contact, seed_w, p, grad, cf,
                      ch, ext, (stores[4], wub, wvb, wab, inner))
        return initial(u0, v0, ub, vb, ab, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, seed_step, seed_contact,
                       seed_w, p, grad, sbar, ext, (w0, wub, wvb, wab, inner))

    return tape_forward, replay_group, tangent_run, reverse_sweep, initial


@njit(nogil=True, inline="always")
def _parameter_forces(cf, ch, th, pf, ph, mount):
    """pf[dd (P + 1) + j] = sum over the System parameters of dF_j/dtheta theta'_j along direction
    dd (rows kappa .. rsum of ``th``, and the mount's k and c, rows 8, 9), ph the same for the new
    state (which the mount does not move)."""
    nd = th.shape[1]
    n = th.shape[2]
    for dd in range(nd):
        o = dd * (n + 1)
        for j in range(n - 1):
            x = 0.0
            y = 0.0
            for r in range(6):
                x += cf[j, r + 2] * th[r, dd, j]
                y += ch[j, r + 2] * th[r, dd, j]
            pf[o + j] = x + cf[j, 9] * th[8, dd, j] + cf[j, 10] * th[9, dd, j] if mount else x
            ph[o + j] = y


@njit(nogil=True, inline="always")
def _contact_tangents(cf, ch, ut, vpt, ft, st, pf, ph, o, n):
    """Every contact's force tangent F' and new state tangent of direction offset ``o``."""
    for j in range(n - 1):
        dw = ut[o + j] - ut[o + j + 1]
        dv = vpt[j] - vpt[j + 1]
        sj = st[o + j]
        ft[o + j + 1] = cf[j, 0] * dw + cf[j, 1] * dv + cf[j, 8] * sj + pf[o + j]
        st[o + j] = ch[j, 0] * dw + ch[j, 1] * dv + ch[j, 8] * sj + ph[o + j]


@njit(nogil=True, inline="always")
def _contact_adjoint(j, f, fbar, cf, ch, sb, fs, wb, rb, grad, mount):
    """Contact j's adjoint: ``fbar`` on its force and ``sb[j]`` on its new state to those of w, the
    relative velocity, the parameters (``grad`` rows 0-5; the mount's k and c, rows 8, 9) and the
    state before (into ``sb[j]``)."""
    sbar = sb[j]
    fs[j + 1] = f
    wb[j + 1] = fbar * cf[j, 0] + sbar * ch[j, 0]
    rb[j + 1] = fbar * cf[j, 1] + sbar * ch[j, 1]
    for r in range(6):
        grad[r, j] += fbar * cf[j, r + 2] + sbar * ch[j, r + 2]
    if mount:  # a constant at every call: the branch is dropped without the extension
        grad[8, j] += fbar * cf[j, 9]
        grad[9, j] += fbar * cf[j, 10]
    sb[j] = fbar * cf[j, 8] + sbar * ch[j, 8]
