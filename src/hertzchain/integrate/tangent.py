"""The tangent-linear model of velocity Verlet: directional derivatives of the whole trajectory,
carried forward beside the primal run (forward-mode differentiation of the steps the engine took).

For D directions theta' (one per parameter of interest), each step propagates

    vh' = v' + h/2 a',  u'_{s+1} = u' + h vh',  vp' = vh' + h/2 a',
    F'_j = dF_j/dw (u'_j - u'_{j+1}) + dF_j/dvrel (vp'_j - vp'_{j+1}) + sum_theta dF_j/dtheta theta'_j,
    a'_{s+1,i} = (F'_{i-1} - F'_i + f_ext,i') / m_i + (1/m_i)' (net force)_i,  v'_{s+1} = vh' + h/2 a'_{s+1}

(step convention of :mod:`hertzchain.integrate.tape`). The primal steps are those of
``kernels.verlet_run`` (same functions, same adaptive choices), each block run first and its
steps stored, then differentiated. Cost: one primal run plus about half a run per direction;
it gives the derivative of every sample at once (the wall-force trace a fit needs), where the
adjoint (:mod:`hertzchain.integrate.adjoint`) gives one scalar's gradient for all parameters.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from . import kernels
from .partials import contact_partials
from .tape import _elastic_block_stored, _general_block, _open_block


@njit(cache=True, nogil=True, inline="always")
def _partials(us, vps, s, inv_mass, kappa, damping, d0, de, dx0, rsum, law, general, f, gp):
    """Primal forces f (shifted: f[j + 1] = F_j) and partials of every contact at the state of row s
    of ``us`` (positions) and ``vps`` (velocities; unused by the aligned elastic law): gp rows dF/dw,
    dF/dvrel, then dF/dtheta for the parameters kappa, damping, d0, de, dx0, rsum."""
    n = inv_mass.shape[0]
    if general:
        for j in range(n - 1):
            fj, gw, gv, gk, ga, g0, gdd, gx, gr = contact_partials(us[s, j], us[s, j + 1], vps[s, j], vps[s, j + 1],
                                                                   kappa[j], damping[j], d0[j], de[j], dx0[j],
                                                                   rsum[j], law)
            f[j + 1] = fj
            gp[0, j] = gw
            gp[1, j] = gv
            gp[2, j] = gk
            gp[3, j] = ga
            gp[4, j] = g0
            gp[5, j] = gdd
            gp[6, j] = gx
            gp[7, j] = gr
    else:  # aligned elastic (kernels.step_elastic)
        for j in range(n - 1):
            d = us[s, j] - us[s, j + 1] + d0[j]
            d = d if d > kernels.DELTA_MIN else 0.0
            sd = np.sqrt(d)
            f[j + 1] = kappa[j] * d * sd
            gw = 1.5 * kappa[j] * sd
            gp[0, j] = gw
            gp[2, j] = d * sd
            gp[4, j] = gw


@njit(cache=True, nogil=True, inline="always")
def _parameter_forces(gp, th, pf, general):
    """pf[dd, j] = sum over parameters of dF_j/dtheta theta'_j along direction dd (fixed in a step)."""
    nd = th.shape[1]
    n = pf.shape[1]
    for dd in range(nd):
        if general:
            for j in range(n - 1):
                pf[dd, j] = (gp[2, j] * th[0, dd, j] + gp[3, j] * th[1, dd, j] + gp[4, j] * th[2, dd, j]
                             + gp[5, j] * th[3, dd, j] + gp[6, j] * th[4, dd, j] + gp[7, j] * th[5, dd, j])
        else:
            for j in range(n - 1):
                pf[dd, j] = gp[2, j] * th[0, dd, j] + gp[4, j] * th[2, dd, j]


@njit(cache=True, nogil=True, inline="always")
def _tangent_step(ut, vt, at, ft, vpt, gp, pf, f, th, dd, inv_mass, fext, h, general):
    """One step of direction ``dd`` (the step's partials in ``gp``, ``pf``). The directions' states
    are flat arrays (direction dd at offset dd (P + 1)), indexed rather than cut into views: a view
    costs two atomic reference counts, more than a short loop, and flat indices vectorise."""
    n = inv_mass.shape[0]
    o = dd * (n + 1)
    hh = 0.5 * h
    for i in range(n):
        vh = vt[o + i] + hh * at[o + i]
        ut[o + i] += h * vh
        vpt[i] = vh + hh * at[o + i]
        vt[o + i] = vh
    if general:
        for j in range(n - 1):
            ft[o + j + 1] = gp[0, j] * (ut[o + j] - ut[o + j + 1]) + gp[1, j] * (vpt[j] - vpt[j + 1]) + pf[dd, j]
    else:
        for j in range(n - 1):
            ft[o + j + 1] = gp[0, j] * (ut[o + j] - ut[o + j + 1]) + pf[dd, j]
    for i in range(n):
        at[o + i] = (inv_mass[i] * (ft[o + i] - ft[o + i + 1] + th[6, dd, i])
                     + th[7, dd, i] * (f[i] - f[i + 1] + fext[i]))
        vt[o + i] += hh * at[o + i]


@njit(cache=True, nogil=True)
def tangent_run(u, v, a, g, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, dcap, law, general, wall_slot,
                interval, stride, n_sub, n_eval, c_steps, relax, n_samples, acc, th, v0t, rec, out_f, out_ft,
                seed_step, seed_contact, seed_w, dj, max_rows):
    """The primal run from t = 0 (state as ``verlet.initialise`` leaves it) with D tangents.

    ``th`` (8, D, P): parameter tangents, rows kappa, damping, d0, de, dx0, rsum, fext, inv_mass;
    ``v0t`` (D, P): tangent of the initial velocities. Records, at every sample k, the primal
    forces ``out_f[k]`` and tangent forces ``out_ft[:, k]`` of the contacts ``rec``; accumulates
    dj[dd] += seed_w F'^(seed_step)_(seed_contact) (seeds sorted by step; step -1: t = 0).
    ``max_rows`` bounds the steps of one block. Returns 0, or 1 when the state became non-finite.
    """
    n = a.shape[0]
    nd = th.shape[1]
    lw = law if general else 0
    block = interval / n_sub
    adaptive = stride == 0
    ns = stride if not adaptive else int(acc[3])
    ut = np.zeros(nd * (n + 1))  # direction dd at offset dd (n + 1)
    vt = np.zeros(nd * (n + 1))
    at = np.zeros(nd * (n + 1))
    ft = np.zeros(nd * (n + 1))
    vpt = np.zeros(n + 1)
    f = np.zeros(n + 1)  # primal forces, shifted
    vp = np.zeros_like(v)
    ustore = np.zeros((max_rows, n))
    vpstore = np.zeros((max_rows if general else 1, n))
    hstore = np.zeros(max_rows)
    peak = np.zeros(8)
    kstar = np.zeros(1, dtype=np.int64)
    ns_seed = seed_step.shape[0]
    p = 0
    gp = np.zeros((8, n))
    pf = np.zeros((nd, n))
    # t = 0: a_0 from F(u_0, v_0); the elastic path reads no velocity
    _partials(u.reshape((1, u.size)), v.reshape((1, v.size)), 0, inv_mass, kappa, damping, d0, de, dx0, rsum, lw,
              general, f, gp)
    _parameter_forces(gp, th, pf, general)
    for dd in range(nd):
        o = dd * (n + 1)
        for i in range(n):
            vt[o + i] = v0t[dd, i]
        for j in range(n - 1):
            ft[o + j + 1] = gp[0, j] * (ut[o + j] - ut[o + j + 1]) + gp[1, j] * (vt[o + j] - vt[o + j + 1]) + pf[dd, j]
        for i in range(n):
            at[o + i] = (inv_mass[i] * (ft[o + i] - ft[o + i + 1] + th[6, dd, i])
                         + th[7, dd, i] * (f[i] - f[i + 1] + fext[i]))
        for r in range(rec.shape[0]):
            out_ft[dd, 0, r] = ft[o + rec[r] + 1]
    while p < ns_seed and seed_step[p] == -1:
        for dd in range(nd):
            dj[dd] += seed_w[p] * ft[dd * (n + 1) + seed_contact[p] + 1]
        p += 1
    step = 0
    for k in range(1, n_samples):
        for b in range(n_sub):
            bi = (k - 1) * n_sub + b
            if adaptive and bi % n_eval == 0:
                req = kernels.required_stride(u, v, a, kappa, d0, de, dx0, rsum, dcap, inv_mass, n_eval * block,
                                              block, c_steps, damping, law)
                ns = kernels._adapt_stride(req, ns, relax, acc)
            if ns > max_rows:  # cannot happen (ns <= the bound of System.max_frequency); never write past the store
                return 2
            dt = block / ns
            _open_block(u, v, a, dt)
            if general:
                _general_block(u, v, a, g, vp, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, law, wall_slot, ns,
                               dt, 0.0, 0, peak, kstar, True, ustore, vpstore, hstore, 0)
            else:
                _elastic_block_stored(u, v, a, g, inv_mass, kappa, d0, fext, ns, dt, ustore, hstore, 0)
            for s in range(ns):
                _partials(ustore, vpstore if general else ustore, s, inv_mass, kappa, damping, d0, de, dx0, rsum, lw,
                          general, f, gp)
                _parameter_forces(gp, th, pf, general)
                for dd in range(nd):
                    _tangent_step(ut, vt, at, ft, vpt, gp, pf, f, th, dd, inv_mass, fext, hstore[s], general)
                while p < ns_seed and seed_step[p] == step + s:
                    for dd in range(nd):
                        dj[dd] += seed_w[p] * ft[dd * (n + 1) + seed_contact[p] + 1]
                    p += 1
            step += ns
        for r in range(rec.shape[0]):
            out_f[k, r] = g[rec[r] + 1]
            for dd in range(nd):
                out_ft[dd, k, r] = ft[dd * (n + 1) + rec[r] + 1]
        if not np.isfinite(g[1]) or not np.isfinite(v[0]):
            return 1
    return 0
