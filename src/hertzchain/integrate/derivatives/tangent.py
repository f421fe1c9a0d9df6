"""The tangent-linear model of velocity Verlet: directional derivatives of the whole trajectory,
carried forward beside the primal run (forward-mode differentiation of the steps the engine took).

For D directions theta' (one per parameter of interest), each step propagates

    vh' = v' + h/2 a',  u'_{s+1} = u' + h vh',  vp' = vh' + h/2 a',
    F'_j = dF_j/dw (u'_j - u'_{j+1}) + dF_j/dvrel (vp'_j - vp'_{j+1}) + sum_theta dF_j/dtheta theta'_j,
    a'_{s+1,i} = (F'_{i-1} - F'_i + f_ext,i') / m_i + (1/m_i)' (net force)_i,  v'_{s+1} = vh' + h/2 a'_{s+1}

(step convention of :mod:`hertzchain.integrate.derivatives.tape`). The primal steps are those of
``kernels.verlet_run`` (the same adaptive choices and arithmetic), each step taking its contacts'
partials where it takes their forces, then every direction's step. Cost: about two runs plus one
per direction; it gives the derivative of every sample at once (the wall-force trace a fit
needs), where the adjoint (:mod:`hertzchain.integrate.derivatives.adjoint`) gives one scalar's gradient for
all parameters.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..core import kernels
from .adjoint import STATE_U, STATE_V
from ..core.extension import EXT_CLIN, EXT_KLIN
from .partials import aligned_partials, contact_partials
from .tape import _open_block


@njit(cache=True, nogil=True, inline="always")
def _kick(u, v, i, ai, dt, last):
    """Body i's update after its acceleration ``ai`` (``kernels.verlet_run``'s step): the kick
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
def _general_step(u, v, a, g, vp, kappa, damping, d0, de, dx0, rsum, fext, inv_mass, law, dt, last, gp, ext):
    """One step of ``tape._general_block`` (forces of ``kernels.forces_general``, and of
    ``kernels.forces_linear`` for a protected body's mount in ``ext``: the same numbers), writing also
    the contacts' partials into the rows of ``gp`` (rows 8, 9: by the mount's k and c)."""
    n = a.shape[0]
    half = 0.5 * dt
    for i in range(n):
        vp[i] = v[i] + half * a[i]
    for j in range(n - 1):
        fj, gw, gv, gk, ga, g0, gdd, gx, gr = contact_partials(u[j], u[j + 1], vp[j], vp[j + 1], kappa[j], damping[j],
                                                               d0[j], de[j], dx0[j], rsum[j], law)
        g[j + 1] = fj
        if ext.shape[0] > 0 and (ext[j, EXT_KLIN] != 0.0 or ext[j, EXT_CLIN] != 0.0):
            dl = u[j] - u[j + 1] + d0[j]
            rl = vp[j] - vp[j + 1]
            g[j + 1] += ext[j, EXT_KLIN] * dl + ext[j, EXT_CLIN] * rl
            gw += ext[j, EXT_KLIN]
            g0 += ext[j, EXT_KLIN]
            gv += ext[j, EXT_CLIN]
            gp[8, j] = dl
            gp[9, j] = rl
        gp[0, j] = gw
        gp[1, j] = gv
        gp[2, j] = gk
        gp[3, j] = ga
        gp[4, j] = g0
        gp[5, j] = gdd
        gp[6, j] = gx
        gp[7, j] = gr
    for i in range(n):
        a[i] = (g[i] - g[i + 1] + fext[i]) * inv_mass[i]
        _kick(u, v, i, a[i], dt, last)


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
def _tangent_step(ut, vt, at, ft, vpt, gw, gv, pf, g, thf, thm, dd, inv_mass, fext, h):
    """One step of direction ``dd`` (the step's partials dF/dw in ``gw``, dF/dvrel in ``gv``, its
    parameter forces in ``pf``, its primal forces in ``g``; ``thf``, ``thm`` the tangents of f_ext
    and 1/m). Every per-direction array is flat (direction dd at offset dd (P + 1)) and indexed
    rather than cut into views: a view costs two atomic reference counts, more than a short loop."""
    n = inv_mass.shape[0]
    o = dd * (n + 1)
    hh = 0.5 * h
    for i in range(n):
        vh = vt[o + i] + hh * at[o + i]
        ut[o + i] += h * vh
        vpt[i] = vh + hh * at[o + i]
        vt[o + i] = vh
    for j in range(n - 1):  # gv = 0 for the elastic law: one loop, no branch
        ft[o + j + 1] = gw[j] * (ut[o + j] - ut[o + j + 1]) + gv[j] * (vpt[j] - vpt[j + 1]) + pf[o + j]
    for i in range(n):
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


def _tangent_loop(general: bool, aligned: bool):
    """The tangent run, compiled on its own for the aligned elastic steps, the aligned dissipative
    ones and the general ones (one function holding them all made LLVM's code for the elastic
    steps ~1.6x slower): ``general`` and ``aligned`` are constants of the closure, and Numba
    prunes the branches not taken."""

    @njit(cache=True, nogil=True)
    def run(u, v, a, g, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, dcap, law, interval, stride, n_sub, n_eval,
            c_steps, relax, n_samples, acc, th, v0t, rec, out_f, out_ft, seed_step, seed_contact, seed_w, dj, ext):
        """The primal run from t = 0 (state as ``verlet.initialise`` leaves it) with D tangents.

        ``th`` (10, D, P): parameter tangents, rows kappa, damping, d0, de, dx0, rsum, fext, inv_mass,
        the linear spring and dashpot of every contact (``ext``: a protected body's mount);
        ``v0t`` (D, P): tangent of the initial velocities. Records, at every sample k, the primal
        forces ``out_f[k]`` and tangent forces ``out_ft[:, k]`` of the contacts ``rec``; accumulates
        dj[dd] += seed_w F'^(seed_step)_(seed_contact) (seeds sorted by step; step -1: t = 0).
        Every step is the engine's (``kernels.verlet_run``: the same adaptive choices and arithmetic),
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
        p = 0
        # t = 0: a_0 from F(u_0, v_0) (the aligned elastic law reads no velocity)
        for j in range(n - 1):
            fj, gw0, gv0, gk0, ga0, g00, gdd0, gx0, gr0 = contact_partials(u[j], u[j + 1], v[j], v[j + 1], kappa[j],
                                                                           damping[j], d0[j], de[j], dx0[j], rsum[j], lw)
            gp[0, j] = gw0
            gp[1, j] = gv0
            gp[2, j] = gk0
            gp[3, j] = ga0
            gp[4, j] = g00
            gp[5, j] = gdd0
            gp[6, j] = gx0
            gp[7, j] = gr0
            if ext_on and (ext[j, EXT_KLIN] != 0.0 or ext[j, EXT_CLIN] != 0.0):  # the mount at t = 0
                gp[0, j] += ext[j, EXT_KLIN]
                gp[4, j] += ext[j, EXT_KLIN]
                gp[1, j] += ext[j, EXT_CLIN]
                gp[8, j] = u[j] - u[j + 1] + d0[j]
                gp[9, j] = v[j] - v[j + 1]
        _parameter_forces(gp, gw, gk, th, pf, True, False)
        for dd in range(nd):
            o = dd * (n + 1)
            for i in range(n):
                vt[o + i] = v0t[dd, i]
            for j in range(n - 1):
                ft[o + j + 1] = gw[j] * (ut[o + j] - ut[o + j + 1]) + gv[j] * (vt[o + j] - vt[o + j + 1]) + pf[o + j]
            for i in range(n):
                at[o + i] = inv_mass[i] * (ft[o + i] - ft[o + i + 1] + thf[o + i]) + thm[o + i] * (g[i] - g[i + 1] + fext[i])
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
                _open_block(u, v, a, dt)
                for s in range(ns):
                    # the primal step (forces at u_{s+1}, partials there), then the tangents' step s;
                    # ``general`` is a constant of the closure: the branch not taken is not compiled
                    if general and aligned:
                        _aligned_step(u, v, a, g, kappa, damping, d0, fext, inv_mass, law, dt, s == ns - 1, gw, gv, gk,
                                      ga)
                    elif general:
                        _general_step(u, v, a, g, vp, kappa, damping, d0, de, dx0, rsum, fext, inv_mass, law, dt,
                                      s == ns - 1, gp, ext)
                    else:
                        _elastic_step(u, v, a, g, kappa, d0, fext, inv_mass, dt, s == ns - 1, gw, gk)
                    if params:
                        _parameter_forces(gp, gw, gk, th, pf, general, aligned)
                    for dd in range(nd):
                        _tangent_step(ut, vt, at, ft, vpt, gw, gv, pf, g, thf, thm, dd, inv_mass, fext, dt)
                    p = _seeded(step + s, p, seed_step, seed_contact, seed_w, ft, ut, vt, nd, n, dj)
                step += ns
            for r in range(rec.shape[0]):
                out_f[k, r] = g[rec[r] + 1]
                for dd in range(nd):
                    out_ft[dd, k, r] = ft[dd * (n + 1) + rec[r] + 1]
            if not np.isfinite(g[1]) or not np.isfinite(v[0]):
                return 1
        return 0

    return run


#: The tangent runs: aligned elastic, aligned dissipative (Kuwabara-Kono, dashpot), general (offsets).
_TANGENT_RUNS = {"elastic": _tangent_loop(False, True), "aligned": _tangent_loop(True, True),
                 "general": _tangent_loop(True, False)}


def tangent_run(u, v, a, g, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, dcap, law, general, wall_slot,
                interval, stride, n_sub, n_eval, c_steps, relax, n_samples, acc, th, v0t, rec, out_f, out_ft,
                seed_step, seed_contact, seed_w, dj, ext):
    """The primal run from t = 0 (state as ``verlet.initialise`` leaves it) with D tangents (see the
    loop's docstring above); ``general``, the law, the offsets and the extension ``ext`` (a
    protected body's mount) choose the compiled run."""
    if not general:
        kind = "elastic"
    elif law in (kernels.LAW_VISCOELASTIC, kernels.LAW_DASHPOT) and not np.any(de) and ext.shape[0] == 0:
        kind = "aligned"
    else:
        kind = "general"
    return _TANGENT_RUNS[kind](u, v, a, g, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, dcap, law,
                                             interval, stride, n_sub, n_eval, c_steps, relax, n_samples, acc, th, v0t,
                                             rec, out_f, out_ft, seed_step, seed_contact, seed_w, dj, ext)
