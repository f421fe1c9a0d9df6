"""The tangent-linear model of velocity Verlet: directional derivatives of the whole trajectory,
carried forward beside the primal run (forward-mode differentiation of the steps the engine took).

For D directions theta' (one per parameter of interest), each step propagates

    vh' = v' + h/2 a',  u'_{s+1} = u' + h vh',  vp' = vh' + h/2 a',
    F'_j = dF_j/dw (u'_j - u'_{j+1}) + dF_j/dvrel (vp'_j - vp'_{j+1}) + sum_theta dF_j/dtheta theta'_j,
    a'_{s+1,i} = (F'_{i-1} - F'_i + f_ext,i') / m_i + (1/m_i)' (net force)_i,  v'_{s+1} = vh' + h/2 a'_{s+1}

(step convention of :mod:`hertzchain.integrate.derivatives.tape`). The primal steps are those of
``kernels._verlet_run`` (the same adaptive choices and arithmetic), each step taking its contacts'
partials where it takes their forces, then every direction's step. Cost: about two runs plus one
per direction; it gives the derivative of every sample at once (the wall-force trace a fit
needs), where the adjoint (:mod:`hertzchain.integrate.derivatives.adjoint`) gives one scalar's gradient for
all parameters.

Mass-in-mass beads: each internal mass carries its tangents (w', wv', wa') by the same steps, the
spring's s' = k_in (w' - u') + k_in' (w - u) joining the body's acceleration and -(s / m_in)' the
internal mass's (:func:`_inner_tangent`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..core import kernels
from .adjoint import STATE_U, STATE_V
from ..core.extension import EXT_IMIN, EXT_KIN, EXT_W, forces_linear
from .partials import aligned_partials, contact_partials, has_mount, mount_partials, plastic_contact_adjoint
from .tape import bodies_kick, has_inner, inner_accelerations, open_block


@njit(cache=True, nogil=True, inline="always")
def _kick(u, v, i, ai, dt, last):
    """Body i's update after its acceleration ``ai`` (``kernels._verlet_run``'s step): the kick
    v += dt a then the drift u += dt v, or in a block's ``last`` step only the closing half kick."""
    if last:
        v[i] += 0.5 * dt * ai
    else:
        v[i] += dt * ai
        u[i] += dt * v[i]


@njit(cache=True, nogil=True, inline="always")
def _elastic_step(u, v, a, g, kappa, d0, fext, inv_mass, dt, last, gw, gk):
    """``kernels.step_elastic`` (the same arithmetic), or with ``last`` ``kernels.final_step_elastic``
    (a block's last step: the closing half kick), writing also each contact's partials at the
    positions the forces are taken at: gw = dF/dw = (3/2) kappa delta^(1/2), gk = dF/dkappa =
    delta^(3/2)."""
    fprev = 0.0
    for i in range(a.shape[0]):
        d = u[i] - u[i + 1] + d0[i]
        d = d if d > kernels.DELTA_MIN else 0.0
        sd = np.sqrt(d)
        f = kappa[i] * d * sd
        gw[i] = 1.5 * kappa[i] * sd
        gk[i] = d * sd
        g[i + 1] = f
        ai = (fprev - f + fext[i]) * inv_mass[i]
        a[i] = ai
        _kick(u, v, i, ai, dt, last)
        fprev = f


@njit(cache=True, nogil=True, inline="always")
def _general_partials(u, vv, kappa, damping, d0, de, dx0, rsum, law, g, gp, ext):
    """Every contact's force (``kernels.forces_general``'s, plus the mount's in ``ext``) into ``g``
    and its partials into the rows of ``gp`` (dF/dw, dF/dvrel, then kappa, damping, d0, de, dx0,
    rsum, the mount's k and c) at positions ``u`` and velocities ``vv``."""
    for j in range(kappa.shape[0] - 1):
        fj, gw, gv, gk, ga, g0, gdd, gx, gr = contact_partials(u[j], u[j + 1], vv[j], vv[j + 1], kappa[j], damping[j],
                                                               d0[j], de[j], dx0[j], rsum[j], law)
        if has_mount(ext, j):
            fl, kl, cl, gp[8, j], gp[9, j] = mount_partials(ext, j, u[j], u[j + 1], vv[j], vv[j + 1], d0[j])
            fj += fl
            gw += kl
            g0 += kl
            gv += cl
        g[j + 1] = fj
        gp[0, j] = gw
        gp[1, j] = gv
        gp[2, j] = gk
        gp[3, j] = ga
        gp[4, j] = g0
        gp[5, j] = gdd
        gp[6, j] = gx
        gp[7, j] = gr


@njit(cache=True, nogil=True, inline="always")
def _general_step(u, v, a, g, vp, kappa, damping, d0, de, dx0, rsum, fext, inv_mass, law, dt, last, gp, ext, inn):
    """One step of ``tape._general_block`` (forces of ``kernels.forces_general``, and of
    ``kernels.forces_linear`` for a protected body's mount in ``ext``: the same numbers), writing also
    the contacts' partials into the rows of ``gp`` (rows 8, 9: by the mount's k and c); ``inn`` =
    (wa, inner, xs): mass-in-mass beads (``tape.bodies_kick``)."""
    n = a.shape[0]
    half = 0.5 * dt
    for i in range(n):
        vp[i] = v[i] + half * a[i]
    _general_partials(u, vp, kappa, damping, d0, de, dx0, rsum, law, g, gp, ext)
    wa, inner, xs = inn
    bodies_kick(u, v, a, g, fext, inv_mass, dt, last, ext, wa, inner, xs)


@njit(cache=True, nogil=True, inline="always")
def _aligned_step(u, v, a, g, kappa, damping, d0, fext, inv_mass, law, dt, last, gw, gv, gk, ga):
    """``kernels.step_dissipative`` (an aligned Kuwabara-Kono or dashpot chain: one fused pass, the
    same arithmetic in the same order), writing also each contact's partials (dF/dw = dF/dd0 in
    ``gw``, dF/drate, dF/dkappa, dF/ddamping). The padding slot's contact (kappa = 0) is left out."""
    n = a.shape[0]
    half = 0.5 * dt
    fprev = 0.0
    vq = v[0] + half * a[0]
    for i in range(n - 1):
        vq1 = v[i + 1] + half * a[i + 1]
        f, gw[i], gv[i], gk[i], ga[i] = aligned_partials(u[i] - u[i + 1] + d0[i], vq - vq1, kappa[i], damping[i],
                                                         law)
        g[i + 1] = f
        ai = (fprev - f + fext[i]) * inv_mass[i]
        a[i] = ai
        _kick(u, v, i, ai, dt, last)
        fprev = f
        vq = vq1
    i = n - 1
    f, _, _, _, _ = aligned_partials(u[i] - u[i + 1] + d0[i], vq, kappa[i], damping[i], law)
    g[i + 1] = f
    ai = (fprev - f + fext[i]) * inv_mass[i]
    a[i] = ai
    _kick(u, v, i, ai, dt, last)


@njit(cache=True, nogil=True, inline="always")
def _plastic_partials(u, vv, kappa, damping, d0, de, dx0, rsum, dyield, dmax, dres, kres, ext, gp, jac):
    """Every elastic-plastic contact's Jacobian at positions ``u`` and velocities ``vv``, from the
    state (dmax, dres, kres) a step starts from, into ``jac`` (3, 11, P): rows the force, the
    residual overlap and the unloading stiffness after the step; columns w, vrel, kappa, damping,
    d0, de, dx0, rsum, dyield, then the residual overlap and stiffness before. Each row is
    :func:`partials.plastic_contact_adjoint` (the law's reverse-mode derivative, the one the
    adjoint takes) seeded with that output's unit vector: the derivative is written once and read
    both ways. The mount's spring and dashpot (``ext``) join the force's row, their own partials
    ``gp`` rows 8, 9."""
    for j in range(kappa.shape[0] - 1):
        for r in range(3):
            out = plastic_contact_adjoint(u[j], u[j + 1], vv[j], vv[j + 1], kappa[j], damping[j], d0[j], de[j],
                                          dx0[j], rsum[j], dyield[j], dmax[j], dres[j], kres[j],
                                          1.0 if r == 0 else 0.0, 1.0 if r == 1 else 0.0, 1.0 if r == 2 else 0.0)
            for c in range(11):
                jac[r, c, j] = out[c + 1]
        if has_mount(ext, j):
            _, kl, cl, gp[8, j], gp[9, j] = mount_partials(ext, j, u[j], u[j + 1], vv[j], vv[j + 1], d0[j])
            jac[0, 0, j] += kl
            jac[0, 4, j] += kl
            jac[0, 1, j] += cl


@njit(cache=True, nogil=True, inline="always")
def _plastic_step(u, v, a, g, vp, kappa, damping, d0, de, dx0, rsum, fext, inv_mass, dt, last, gp, ext, state, jac,
                  inn):
    """One step of ``tape._general_block`` for the elastic-plastic law (``kernels.forces_general``
    and the mount's ``forces_linear``: the same numbers, the state ``state`` = (dyield, dmax, dres,
    kres) carried in place), its contacts' Jacobians taken first, at the state the step starts from
    (:func:`_plastic_partials`); ``inn`` as for :func:`_general_step`."""
    dyield, dmax, dres, kres = state
    n = a.shape[0]
    half = 0.5 * dt
    for i in range(n):
        vp[i] = v[i] + half * a[i]
    _plastic_partials(u, vp, kappa, damping, d0, de, dx0, rsum, dyield, dmax, dres, kres, ext, gp, jac)
    kernels.forces_general(u, vp, kappa, damping, d0, de, dx0, rsum, kernels.LAW_ELASTOPLASTIC, g, dyield, dmax, dres,
                           kres)
    if ext.shape[0] > 0:
        forces_linear(u, vp, d0, ext, g)
    wa, inner, xs = inn
    bodies_kick(u, v, a, g, fext, inv_mass, dt, last, ext, wa, inner, xs)


@njit(cache=True, nogil=True, inline="always")
def _plastic_tangents(jac, st, th, gp, ut, vpt, ft, o, dd, n):
    """Direction dd's force tangents F'_j and state tangents (``st``: residual overlap', stiffness',
    updated in place) of every elastic-plastic contact: the step's Jacobian ``jac``
    (:func:`_plastic_partials`) times (w', vrel', the parameters' tangents, the state's), plus the
    mount's spring and dashpot (``gp`` rows 8, 9)."""
    for j in range(n - 1):
        x0 = ut[o + j] - ut[o + j + 1]
        x1 = vpt[j] - vpt[j + 1]
        sr = st[0, o + j]
        sk = st[1, o + j]
        for r in range(3):
            y = (jac[r, 0, j] * x0 + jac[r, 1, j] * x1 + jac[r, 2, j] * th[0, dd, j] + jac[r, 3, j] * th[1, dd, j]
                 + jac[r, 4, j] * th[2, dd, j] + jac[r, 5, j] * th[3, dd, j] + jac[r, 6, j] * th[4, dd, j]
                 + jac[r, 7, j] * th[5, dd, j] + jac[r, 8, j] * th[10, dd, j] + jac[r, 9, j] * sr
                 + jac[r, 10, j] * sk)
            if r == 0:
                ft[o + j + 1] = y + gp[8, j] * th[8, dd, j] + gp[9, j] * th[9, dd, j]
            else:
                st[r - 1, o + j] = y


@njit(cache=True, nogil=True, inline="always")
def _parameter_forces(gp, gw, gk, th, pf, general, aligned):
    """pf[dd (P + 1) + j] = sum over parameters of dF_j/dtheta theta'_j along direction dd (a step's):
    all rows (general), kappa, damping and d0 (aligned dissipative: dF/dd0 = dF/dw, in ``gw``), or
    kappa and d0 (elastic)."""
    nd = th.shape[1]
    n = th.shape[2]
    for dd in range(nd):
        o = dd * (n + 1)
        if general and aligned:
            for j in range(n - 1):
                pf[o + j] = gp[2, j] * th[0, dd, j] + gp[3, j] * th[1, dd, j] + gw[j] * th[2, dd, j]
        elif general:
            for j in range(n - 1):
                pf[o + j] = (gp[2, j] * th[0, dd, j] + gp[3, j] * th[1, dd, j] + gp[4, j] * th[2, dd, j]
                             + gp[5, j] * th[3, dd, j] + gp[6, j] * th[4, dd, j] + gp[7, j] * th[5, dd, j]
                             + gp[8, j] * th[8, dd, j] + gp[9, j] * th[9, dd, j])
        else:
            for j in range(n - 1):
                pf[o + j] = gk[j] * th[0, dd, j] + gw[j] * th[2, dd, j]


@njit(cache=True, nogil=True, inline="always")
def _inner_tangent(i, o, dd, ut, wt, wat, at, th, thm, xs, ext, inv_mass):
    """Body i's internal mass in direction dd (offset ``o``): the spring's tangent s' = k_in (w' - u')
    + k_in' x (x = ``xs[i]``, its stretch w - u at the step) added to the body's acceleration tangent
    (with (1/m)' k_in x), and the internal mass's wa' = -(s' / m_in + (1/m_in)' k_in x)."""
    k = ext[i, EXT_KIN]
    x = xs[i]
    sp = k * (wt[o + i] - ut[o + i]) + th[11, dd, i] * x
    at[o + i] += inv_mass[i] * sp + thm[o + i] * k * x
    wat[o + i] = -(ext[i, EXT_IMIN] * sp + th[12, dd, i] * k * x)


@njit(cache=True, nogil=True, inline="always")
def _tangent_step(ut, vt, at, ft, vpt, gw, gv, pf, g, thf, thm, dd, inv_mass, fext, h, plastic, jac, st, th, gp,
                  inner, inn_t, xs, ext):
    """One step of direction ``dd`` (the step's partials dF/dw in ``gw``, dF/dvrel in ``gv``, its
    parameter forces in ``pf``, its primal forces in ``g``; ``thf``, ``thm`` the tangents of f_ext
    and 1/m; with ``plastic`` the elastic-plastic contacts' Jacobians ``jac`` and state tangents
    ``st``, :func:`_plastic_tangents`; with ``inner`` the internal masses' tangents ``inn_t`` =
    (w', wv', wa'), :func:`_inner_tangent`): :func:`tangent_drift`, the contacts' force tangents,
    :func:`tangent_kick`."""
    n = inv_mass.shape[0]
    o = dd * (n + 1)
    tangent_drift(ut, vt, at, vpt, o, h, n, inner, inn_t)
    if plastic:  # a constant at every call: the branch not taken is dropped
        _plastic_tangents(jac, st, th, gp, ut, vpt, ft, o, dd, n)
    else:
        for j in range(n - 1):  # gv = 0 for the elastic law: one loop, no branch
            ft[o + j + 1] = gw[j] * (ut[o + j] - ut[o + j + 1]) + gv[j] * (vpt[j] - vpt[j + 1]) + pf[o + j]
    tangent_kick(ut, vt, at, ft, g, thf, thm, th, dd, o, inv_mass, fext, h, inner, inn_t, xs, ext)


@njit(cache=True, nogil=True, inline="always")
def tangent_drift(ut, vt, at, vpt, o, h, n, inner, inn_t):
    """The first half kick and the drift of a step of length ``h`` for the direction at offset ``o``
    (vh' = v' + h/2 a', u' += h vh', the predicted vp' = vh' + h/2 a' into ``vpt``), the internal
    masses' too with ``inner``. Every per-direction array is flat (direction dd at offset dd (P + 1))
    and indexed rather than cut into views: a view costs two atomic reference counts, more than a
    short loop."""
    hh = 0.5 * h
    for i in range(n):
        vh = vt[o + i] + hh * at[o + i]
        ut[o + i] += h * vh
        vpt[i] = vh + hh * at[o + i]
        vt[o + i] = vh
    if inner:
        wt, wvt, wat = inn_t
        for i in range(n):
            wvh = wvt[o + i] + hh * wat[o + i]
            wt[o + i] += h * wvh
            wvt[o + i] = wvh


@njit(cache=True, nogil=True, inline="always")
def tangent_kick(ut, vt, at, ft, g, thf, thm, th, dd, o, inv_mass, fext, h, inner, inn_t, xs, ext):
    """The accelerations' tangents of direction dd (offset ``o``) from the force tangents ``ft``,
    a'_i = (F'_{i-1} - F'_i + f_ext,i') / m_i + (1/m_i)' (net force)_i (the internal springs' with
    ``inner``, :func:`_inner_tangent`), then the closing half kick (h = 0: the state at t = 0).
    The branch is taken outside the loop, so that LLVM vectorises the plain one."""
    hh = 0.5 * h
    if inner:
        wt, wvt, wat = inn_t
        for i in range(inv_mass.shape[0]):
            at[o + i] = inv_mass[i] * (ft[o + i] - ft[o + i + 1] + thf[o + i]) + thm[o + i] * (g[i] - g[i + 1] + fext[i])
            _inner_tangent(i, o, dd, ut, wt, wat, at, th, thm, xs, ext, inv_mass)
            wvt[o + i] += hh * wat[o + i]
            vt[o + i] += hh * at[o + i]
    else:
        for i in range(inv_mass.shape[0]):
            at[o + i] = inv_mass[i] * (ft[o + i] - ft[o + i + 1] + thf[o + i]) + thm[o + i] * (g[i] - g[i + 1] + fext[i])
            vt[o + i] += hh * at[o + i]


@njit(cache=True, nogil=True, inline="always")
def _seeded(step, p, seed_step, seed_contact, seed_w, ft, ut, vt, nd, n, dj):
    """dj[dd] += seed_w x the tangent the seeds of ``step`` read: a force's, or the position's or
    velocity's after the step (contact numbers from ``adjoint.STATE_U`` / ``STATE_V`` on); returns
    the pointer past them."""
    while p < seed_step.shape[0] and seed_step[p] == step:
        c = seed_contact[p]
        for dd in range(nd):
            o = dd * (n + 1)
            if c >= STATE_V:
                dj[dd] += seed_w[p] * vt[o + c - STATE_V]
            elif c >= STATE_U:
                dj[dd] += seed_w[p] * ut[o + c - STATE_U]
            else:
                dj[dd] += seed_w[p] * ft[o + c + 1]
        p += 1
    return p


def _tangent_loop(general: bool, aligned: bool, plastic: bool = False, inner: bool = False):
    """The tangent run, compiled on its own for the aligned elastic steps, the aligned dissipative
    ones, the general ones and the elastic-plastic law's, with or without mass-in-mass beads (one
    function holding them all made LLVM's code for the elastic steps ~1.6x slower; the internal
    masses' branches, taken at run time, ~1.3x): ``general``, ``aligned``, ``plastic`` and
    ``inner`` are constants of the closure, and Numba prunes the branches not taken."""

    @njit(cache=True, nogil=True)
    def run(u, v, a, g, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, dcap, law, interval, stride, n_sub, n_eval,
            c_steps, relax, n_samples, acc, th, v0t, rec, out_f, out_ft, seed_step, seed_contact, seed_w, dj, ext,
            state, fdres):
        """The primal run from t = 0 (state as ``verlet.initialise`` leaves it) with D tangents.

        ``th`` (11, D, P): parameter tangents, rows kappa, damping, d0, de, dx0, rsum, fext, inv_mass,
        the linear spring and dashpot of every contact (``ext``: a protected body's mount), the
        elastic-plastic law's yield overlaps; ``state``: that law's (dyield, dmax, dres, kres), as
        ``verlet.initialise`` leaves it (the state before t = 0 is (0, 0, kappa)), carried in place
        with its tangents; ``fdres`` the seeds dJ/d(residual overlap at the end) of a result that
        reads it (the plastic work: dj += fdres . dres');
        ``v0t`` (D, P): tangent of the initial velocities. Records, at every sample k, the primal
        forces ``out_f[k]`` and tangent forces ``out_ft[:, k]`` of the contacts ``rec``; accumulates
        dj[dd] += seed_w F'^(seed_step)_(seed_contact) (seeds sorted by step; step -1: t = 0).
        Every step is the engine's (``kernels._verlet_run``: the same adaptive choices and arithmetic),
        taking each contact's partials where it takes its force. Returns 0, or 1 when the state
        became non-finite.
        """
        n = a.shape[0]
        nd = th.shape[1]
        lw = law if general else 0
        ext_on = ext.shape[0] > 0
        block = interval / n_sub
        adaptive = stride == 0
        ns = stride if not adaptive else int(acc[3])
        ut = np.zeros(nd * (n + 1))  # direction dd at offset dd (n + 1)
        vt = np.zeros(nd * (n + 1))
        at = np.zeros(nd * (n + 1))
        ft = np.zeros(nd * (n + 1))
        vpt = np.zeros(n + 1)
        vp = np.zeros_like(v)
        gp = np.zeros((10, n))  # partials: dF/dw, dF/dvrel, then kappa, damping, d0, de, dx0, rsum, k, c
        gw, gv, gk, ga = gp[0], gp[1], gp[2], gp[3]
        params = False  # any parameter tangent (else pf stays zero: only v0 moves)
        for r in range(th.shape[0]):
            for dd in range(nd):
                for i in range(n):
                    params = params or th[r, dd, i] != 0.0
        pf = np.zeros(nd * (n + 1))
        thf = np.zeros(nd * (n + 1))  # tangents of f_ext and 1/m, flat like the states
        thm = np.zeros(nd * (n + 1))
        for dd in range(nd):
            for i in range(n):
                thf[dd * (n + 1) + i] = th[6, dd, i]
                thm[dd * (n + 1) + i] = th[7, dd, i]
        wa = np.zeros(n)  # mass-in-mass beads: their accelerations, stretches and tangents
        xs = np.zeros(n)
        inn_t = (np.zeros(nd * (n + 1) if inner else 1), np.zeros(nd * (n + 1) if inner else 1),
                 np.zeros(nd * (n + 1) if inner else 1))
        if inner:
            inner_accelerations(u, ext, wa)
            for i in range(n):
                xs[i] = ext[i, EXT_W] - u[i]
        p = 0
        jac = np.zeros((3, 11, n) if plastic else (1, 1, 1))  # the elastic-plastic contacts' Jacobians
        st = np.zeros((2, nd * (n + 1) if plastic else 1))  # and their state's tangents (dres', kres')
        if plastic:  # t = 0: from the state (0, 0, kappa), the stiffness's tangent kappa's
            _plastic_partials(u, v, kappa, damping, d0, de, dx0, rsum, state[0], np.zeros(n), np.zeros(n), kappa, ext,
                              gp, jac)
            for dd in range(nd):
                for j in range(n):
                    st[1, dd * (n + 1) + j] = th[0, dd, j]
        # t = 0: a_0 from F(u_0, v_0) (the aligned elastic law reads no velocity): the partials (into
        # scratch forces: g holds those ``verlet.initialise`` took)
        if not plastic:
            _general_partials(u, v, kappa, damping, d0, de, dx0, rsum, lw, np.zeros(n + 1), gp, ext)
        _parameter_forces(gp, gw, gk, th, pf, True, False)
        for dd in range(nd):
            o = dd * (n + 1)
            for i in range(n):
                vt[o + i] = v0t[dd, i]
                vpt[i] = vt[o + i]
            if plastic:
                _plastic_tangents(jac, st, th, gp, ut, vpt, ft, o, dd, n)
            for j in range(n - 1 if not plastic else 0):
                ft[o + j + 1] = gw[j] * (ut[o + j] - ut[o + j + 1]) + gv[j] * (vt[o + j] - vt[o + j + 1]) + pf[o + j]
            tangent_kick(ut, vt, at, ft, g, thf, thm, th, dd, o, inv_mass, fext, 0.0, inner, inn_t, xs, ext)
            for r in range(rec.shape[0]):
                out_ft[dd, 0, r] = ft[o + rec[r] + 1]
        p = _seeded(-1, p, seed_step, seed_contact, seed_w, ft, ut, vt, nd, n, dj)
        step = 0
        for k in range(1, n_samples):
            for b in range(n_sub):
                bi = (k - 1) * n_sub + b
                if adaptive and bi % n_eval == 0:
                    req = kernels.required_stride(u, v, a, kappa, d0, de, dx0, rsum, dcap, inv_mass, n_eval * block,
                                                  block, c_steps, damping, law, ext, ext_on)
                    ns = kernels._adapt_stride(req, ns, relax, acc)
                dt = block / ns
                open_block(u, v, a, dt, ext, wa, inner)
                for s in range(ns):
                    # the primal step (forces at u_{s+1}, partials there), then the tangents' step s;
                    # ``general`` is a constant of the closure: the branch not taken is not compiled
                    if plastic:
                        _plastic_step(u, v, a, g, vp, kappa, damping, d0, de, dx0, rsum, fext, inv_mass, dt,
                                      s == ns - 1, gp, ext, state, jac, (wa, inner, xs))
                    elif general and aligned:
                        _aligned_step(u, v, a, g, kappa, damping, d0, fext, inv_mass, law, dt, s == ns - 1, gw, gv, gk,
                                      ga)
                    elif general:
                        _general_step(u, v, a, g, vp, kappa, damping, d0, de, dx0, rsum, fext, inv_mass, law, dt,
                                      s == ns - 1, gp, ext, (wa, inner, xs))
                    else:
                        _elastic_step(u, v, a, g, kappa, d0, fext, inv_mass, dt, s == ns - 1, gw, gk)
                    if params and not plastic:
                        _parameter_forces(gp, gw, gk, th, pf, general, aligned)
                    for dd in range(nd):
                        _tangent_step(ut, vt, at, ft, vpt, gw, gv, pf, g, thf, thm, dd, inv_mass, fext, dt, plastic,
                                      jac, st, th, gp, inner, inn_t, xs, ext)
                    p = _seeded(step + s, p, seed_step, seed_contact, seed_w, ft, ut, vt, nd, n, dj)
                step += ns
            for r in range(rec.shape[0]):
                out_f[k, r] = g[rec[r] + 1]
                for dd in range(nd):
                    out_ft[dd, k, r] = ft[dd * (n + 1) + rec[r] + 1]
            if not np.isfinite(g[1]) or not np.isfinite(v[0]):
                return 1
        if plastic:  # a result reading the final residual overlaps
            for dd in range(nd):
                for j in range(min(fdres.shape[0], n)):
                    dj[dd] += fdres[j] * st[0, dd * (n + 1) + j]
        return 0

    return run


#: The tangent runs: aligned elastic, aligned dissipative (Kuwabara-Kono, dashpot), general (offsets),
#: elastic-plastic.
_TANGENT_RUNS = {"elastic": _tangent_loop(False, True), "aligned": _tangent_loop(True, True),
                 "general": _tangent_loop(True, False), "plastic": _tangent_loop(True, False, True),
                 "general inner": _tangent_loop(True, False, False, True),
                 "plastic inner": _tangent_loop(True, False, True, True)}


def tangent_run(u, v, a, g, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, dcap, law, general, wall_slot,
                interval, stride, n_sub, n_eval, c_steps, relax, n_samples, acc, th, v0t, rec, out_f, out_ft,
                seed_step, seed_contact, seed_w, dj, ext, state, fdres):
    """The primal run from t = 0 (state as ``verlet.initialise`` leaves it) with D tangents (see the
    loop's docstring above); ``general``, the law, the offsets and the extension ``ext`` (a
    protected body's mount) choose the compiled run."""
    if ext.shape[0] and has_inner(ext):  # mass-in-mass beads (an extended model: general)
        kind = "plastic inner" if law == kernels.LAW_ELASTOPLASTIC else "general inner"
    elif not general:
        kind = "elastic"
    elif law == kernels.LAW_ELASTOPLASTIC:
        kind = "plastic"
    elif law in (kernels.LAW_VISCOELASTIC, kernels.LAW_DASHPOT) and not np.any(de) and ext.shape[0] == 0:
        kind = "aligned"
    else:
        kind = "general"
    return _TANGENT_RUNS[kind](u, v, a, g, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, dcap, law,
                                             interval, stride, n_sub, n_eval, c_steps, relax, n_samples, acc, th, v0t,
                                             rec, out_f, out_ft, seed_step, seed_contact, seed_w, dj, ext, state,
                                             fdres)
