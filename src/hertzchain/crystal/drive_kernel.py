"""The compiled loop of a driven chain: velocity Verlet on a fixed step with the drive of
:mod:`hertzchain.crystal.drive` computed inside the loop from five scalars (no Python call per step).

It reuses the engine's force functions (``kernels.forces_general`` for the built-in laws, the
loops generated from a registry law's scalar functions, ``generated.law_kernels``, for every other
law, and the extension's linear springs and internal masses, ``extension.forces_linear`` /
``accelerations_extended``), so a driven run integrates the same contact laws as an impact; only
the stepping is its own: kick-drift-kick
with the velocity-dependent forces taken at the predicted velocities v + (dt/2) a (as the engine's
general path does), plus

- a force drive: s(t) added to bead 1's forces;
- a displacement drive: body 0 (massless, 1/m = 0) placed at u_0 = s(t) with velocity s'(t)
  before the forces of each step.

An aligned chain with a built-in law and no extension takes the engine's fused step
(``kernels.step_dissipative``: one pass over the bodies per step, the drive's force on bead 1
added to its external forces; the kicks of consecutive steps fused between samples, :func:`_fused_block`),
2.6 times faster than the general pass (forces, then accelerations, then kicks) that every other
model takes (6.2 against 16 ns per bead-step, 16 beads, one core).

The power the drive delivers, s(t) v_1 (force) or (F_0 - f_0) s'(t) (displacement: the contact
force on the driver beyond the static force f_0 it holds, whose work is the -f_0 u_0 term of the
potential energy), is integrated with the trapezoidal rule, as is the dissipated power: the energy
balance W_drive = Delta(E_kin + E_pot) + E_dissipated holds to the Verlet step's O(dt^2).

:func:`driven_batch` steps many members at once (one drive frequency or amplitude each, with its
own step, stride and state; the chain's arrays shared), one thread per member in turn
(``numba.prange``), each member by :func:`driven_run` itself: a member's arithmetic is that of
its run alone. :func:`kernels_for` gives the four functions for a law: the compiled ones here
(cached on disk) for the built-in laws, for a registry law the same Python functions compiled
again with the law's forces and stored energy in place of ``_forces`` and ``_stored`` (one source
for both; built once per law and process, as the generated engines are).
"""

from __future__ import annotations

import types

import numpy as np
from numba import njit, prange

from ..integrate.core.energies import kinetic_energy, potential_energy
from ..integrate.core.extension import (EXT_W, EXT_WV, accelerations_extended, energies_extended,
                                   forces_linear)
from ..integrate.core.generated import is_generated, law_kernels
from ..integrate.core.kernels import forces_general, predict, step_dissipative
from ..integrate.core.primitives import LAW_DASHPOT, LAW_ELASTIC, LAW_VISCOELASTIC

__all__ = ["drive_value", "driven_run", "driven_batch", "kernels_for"]

_BUILT: dict = {}


@njit(cache=True, nogil=True)
def drive_value(t, p, tt, vv):
    """(s(t), s'(t)) of the drive with scalars ``p`` = (A, f0, rate, T_sweep, T_ramp, history) and,
    for a history (p[5] = 1), its rows (``tt`` [s], ``vv``) interpolated linearly (drive.py)."""
    if p[5] > 0.0:
        if t >= tt[-1]:
            return vv[-1], 0.0
        i = np.searchsorted(tt, t, side="right") - 1
        slope = (vv[i + 1] - vv[i]) / (tt[i + 1] - tt[i])
        return vv[i] + slope * (t - tt[i]), slope
    amp, f0, rate, tsw, tr = p[0], p[1], p[2], p[3], p[4]
    if t <= tsw:
        phase = 2.0 * np.pi * (f0 * t + 0.5 * rate * t * t)
        freq = f0 + rate * t
    else:
        phase = 2.0 * np.pi * (f0 * tsw + 0.5 * rate * tsw * tsw + (f0 + rate * tsw) * (t - tsw))
        freq = f0 + rate * tsw
    sn, cs = np.sin(phase), np.cos(phase)
    if t < tr:
        x = 0.5 * np.pi * t / tr
        r = np.sin(x) ** 2
        dr = np.sin(2.0 * x) * 0.5 * np.pi / tr
    else:
        r, dr = 1.0, 0.0
    return amp * r * sn, amp * (dr * sn + r * cs * 2.0 * np.pi * freq)


@njit(cache=True, nogil=True)
def _forces(u, vp, g, kappa, damping, d0, de, dx0, rsum, law, dyield, dmax, dres, kres, ext, extended):
    p = forces_general(u, vp, kappa, damping, d0, de, dx0, rsum, law, g, dyield, dmax, dres, kres)
    if extended:
        p += forces_linear(u, vp, d0, ext, g)
    return p


@njit(cache=True, nogil=True)
def _stored(u, g, kappa, damping, d0, de, dx0, rsum, fext):
    """Hertz energy of the contacts minus the work of the static forces [J] (built-in laws)."""
    return potential_energy(u, g, kappa, d0, de, dx0, rsum, fext, False)


@njit(cache=True, nogil=True)
def _accelerations(u, g, fext, inv_mass, ext, extended, a, wa):
    if extended:
        accelerations_extended(u, g, fext, inv_mass, ext, a, wa)
    else:
        for i in range(a.shape[0]):
            a[i] = (g[i] - g[i + 1] + fext[i]) * inv_mass[i]


@njit(cache=True, nogil=True)
def _record(k, u, v, a, g, mass, kappa, damping, d0, de, dx0, rsum, fext, ext, extended, rec, out_f, out_e, fmax,
            acc, drive_f, drive_x, body_slot, out_b):
    for c in range(rec.shape[0]):
        out_f[k, c] = g[rec[c] + 1]
    for j in range(fmax.shape[0]):
        if g[j + 1] > fmax[j]:
            fmax[j] = g[j + 1]
    ke = kinetic_energy(v, mass)
    pe = _stored(u, g, kappa, damping, d0, de, dx0, rsum, fext)
    if extended:
        ke_in, pe_lin = energies_extended(u, d0, ext)
        ke += ke_in
        pe += pe_lin
    out_e[k, 0] = ke
    out_e[k, 1] = pe
    out_e[k, 2] = acc[0]  # dissipated [J]
    out_e[k, 3] = acc[2]  # work of the drive [J]
    out_e[k, 4] = drive_f
    out_e[k, 5] = drive_x
    if body_slot >= 0:
        out_b[k, 0] = u[body_slot]
        out_b[k, 1] = v[body_slot]
        out_b[k, 2] = a[body_slot]
        out_b[k, 3] = acc[5]


@njit(cache=True, nogil=True, fastmath={"reassoc"})
def _fused_block(u, v, vp, a, g, kappa, damping, d0, fext, inv_mass, law, dt, stride, p, tt, vv, displacement,
                 drive, acc):
    """The ``stride`` steps between two samples by the fused step (leapfrog: the closing half
    kick at the last), the drive computed at each step and its power and the dissipated power
    integrated (trapezoidal rule) into ``acc``. Each step is the engine's own fused step
    (``kernels.step_dissipative``) with ``drive`` as its external forces: the static ones ``fext``
    plus, on bead 1, the drive's force (the same sum as the engine's when fext[1] = 0, rounding
    otherwise), ``vp`` its P + 1 predicted velocities. A function of its own whose power sum may
    be reassociated (as the engine's ``kernels.dissipative_block``): the state does not depend on it."""
    half = 0.5 * dt
    for i in range(a.shape[0]):
        drive[i] = fext[i]
    for i in range(a.shape[0]):
        v[i] += half * a[i]
        u[i] += dt * v[i]
    predict(v, a, half, vp)
    for s in range(stride):
        acc[4] += 1.0
        x, xd = drive_value(acc[4] * dt, p, tt, vv)
        if displacement:  # the driver's place and speed; a[0] = 0 (1/m = 0): its prediction is xd
            u[0] = x
            v[0] = xd
            vp[0] = xd
        else:
            drive[1] = fext[1] + x
        last = s == stride - 1
        pd = step_dissipative(u, v, vp, a, g, kappa, damping, d0, drive, inv_mass, law, dt, half, last)
        acc[0] += half * (acc[1] + pd)
        acc[1] = pd
        # bead 1's velocity at the step's end: the closing half kick's, or the half-step one's
        pw = (g[1] - fext[0]) * xd if displacement else x * (v[1] if last else v[1] - half * a[1])
        acc[2] += half * (acc[3] + pw)
        acc[3] = pw


@njit(cache=True, nogil=True)
def driven_run(u, v, a, wa, vp, g, mass, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, dyield, dmax, dres, kres,
               law, ext, extended, p, tt, vv, displacement, dt, stride, k_start, k_stop, rec, out_f, out_e, fmax, acc,
               body_slot, out_b):
    """Samples ``k_start``..``k_stop - 1`` of a driven run, ``stride`` steps of ``dt`` [s] apart.

    State (u, v, a, wa, ext, the elastic-plastic state) is carried between calls; ``acc`` holds
    (dissipated energy [J], last dissipated power [W], drive work [J], last drive power [W],
    steps taken, work of contact N on a protected body [J] and its last power [W]). With a protected
    body (``body_slot`` >= 0) ``out_b`` receives its displacement, velocity, acceleration and that
    work, as the engine's body record. ``wa`` holds the internal masses' accelerations (with the
    extension), or on the fused path (no extension) the external forces of each step (fext plus the drive on
    bead 1). ``out_e`` columns: kinetic, potential energy, dissipated, drive work [J], drive
    force on bead 1 [N], drive displacement [m] (force drive: bead 1's displacement). Returns 1
    when the state became non-finite, else 0.
    """
    half = 0.5 * dt
    n = a.shape[0]
    fused = not extended and (law == LAW_ELASTIC or law == LAW_VISCOELASTIC or law == LAW_DASHPOT)
    for i in range(n):
        fused = fused and de[i] == 0.0
    for k in range(k_start, k_stop):
        if fused:  # wa (the extension's, unused here) carries each step's external forces
            _fused_block(u, v, vp, a, g, kappa, damping, d0, fext, inv_mass, law, dt, stride, p, tt, vv, displacement,
                         wa, acc)
        for _ in range(stride if not fused else 0):
            for i in range(n):
                v[i] += half * a[i]
                u[i] += dt * v[i]
            if extended:
                for i in range(n):
                    ext[i, EXT_WV] += half * wa[i]
                    ext[i, EXT_W] += dt * ext[i, EXT_WV]
            acc[4] += 1.0
            t = acc[4] * dt  # from the step count: a sum of steps would drift the drive's phase
            x, xd = drive_value(t, p, tt, vv)
            for i in range(n):
                vp[i] = v[i] + half * a[i]
            if displacement:
                u[0] = x
                v[0] = xd
                vp[0] = xd
            pd = _forces(u, vp, g, kappa, damping, d0, de, dx0, rsum, law, dyield, dmax, dres, kres, ext, extended)
            acc[0] += half * (acc[1] + pd)
            acc[1] = pd
            _accelerations(u, g, fext, inv_mass, ext, extended, a, wa)
            if not displacement:
                a[1] += x * inv_mass[1]
            for i in range(n):
                v[i] += half * a[i]
            if extended:
                for i in range(n):
                    ext[i, EXT_WV] += half * wa[i]
            pw = (g[1] - fext[0]) * xd if displacement else x * v[1]
            acc[2] += half * (acc[3] + pw)
            acc[3] = pw
            if body_slot >= 0:
                pb = g[body_slot] * v[body_slot]  # contact N pushing body N + 1
                acc[5] += half * (acc[6] + pb)
                acc[6] = pb
        if not np.isfinite(u[1]) or not np.isfinite(v[1]):
            return 1
        x, xd = drive_value(acc[4] * dt, p, tt, vv)
        _record(k, u, v, a, g, mass, kappa, damping, d0, de, dx0, rsum, fext, ext, extended, rec, out_f, out_e, fmax,
                acc, g[1] if displacement else x, x if displacement else u[1], body_slot, out_b)
    return 0


@njit(cache=True, nogil=True, parallel=True)
def driven_batch(u, v, a, wa, vp, g, mass, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, dyield, dmax, dres, kres,
                 law, ext, extended, p, tt, vv, displacement, dt, stride, k_start, k_stop, rec, out_f, out_e, fmax, acc,
                 body_slot, out_b, status):
    """:func:`driven_run` for every member m (first axis of ``u``, ``v``, ``a``, ``wa``, ``vp``, ``g``,
    ``dmax`` (the law's state), ``ext``, ``p``, ``dt``, ``stride``, ``out_f``, ``out_e``, ``fmax``,
    ``acc``, ``out_b``; the chain's arrays shared), samples ``k_start``..``k_stop - 1``;
    ``status[m]`` its return value."""
    for m in prange(u.shape[0]):
        status[m] = driven_run(u[m], v[m], a[m], wa[m], vp[m], g[m], mass, inv_mass, kappa, damping, d0, de, dx0, rsum,
                               fext, dyield, dmax[m], dres, kres, law, ext[m], extended, p[m], tt, vv, displacement,
                               dt[m], stride[m], k_start, k_stop, rec, out_f[m], out_e[m], fmax[m], acc[m], body_slot,
                               out_b[m])


def _recompiled(fn, parallel: bool = False, **names):
    """``fn``'s Python source compiled again with the globals ``names`` replaced (not cached on disk:
    it closes over a law's functions)."""
    py = fn.py_func
    scope = dict(py.__globals__)
    scope.update(names)
    return njit(nogil=True, parallel=parallel)(types.FunctionType(py.__code__, scope, py.__name__, py.__defaults__))


def kernels_for(code: int):
    """(forces, record, run, batch) of the driven loop for the law of engine code ``code``
    (module docstring)."""
    if not is_generated(code):
        return _forces, _record, driven_run, driven_batch
    if code not in _BUILT:
        law_forces, _, law_energy = law_kernels(code)[:3]

        @njit(nogil=True)
        def forces(u, vp, g, kappa, damping, d0, de, dx0, rsum, law, dyield, dmax, dres, kres, ext, extended):
            p = law_forces(u, vp, kappa, damping, d0, de, dx0, rsum, g, dmax)  # the law's state in dmax
            if extended:
                p += forces_linear(u, vp, d0, ext, g)
            return p

        @njit(nogil=True)
        def stored(u, g, kappa, damping, d0, de, dx0, rsum, fext):
            return law_energy(u, kappa, damping, d0, de, dx0, rsum, fext)

        record = _recompiled(_record, _stored=stored)
        run = _recompiled(driven_run, _forces=forces, _record=record)
        _BUILT[code] = (forces, record, run, _recompiled(driven_batch, parallel=True, driven_run=run))
    return _BUILT[code]
