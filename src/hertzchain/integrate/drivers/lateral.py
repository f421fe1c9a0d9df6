"""Compiled two-dimensional path: beads that may move sideways in their track.

The one-dimensional kernels (:mod:`hertzchain.integrate.core.kernels`) hold misaligned beads rigidly on
their offset line and keep only the axial component of each contact force. Here every body
(striker and beads) has a second, transverse degree of freedom y (position across the track,
measured from the track's axis) besides the axial displacement u, and

- a contact between bodies j and j + 1 pushes along their line of centres: with
  dx = dx0_j - (u_j - u_{j+1}), ey = y_{j+1} - y_j, dist = sqrt(dx^2 + ey^2), the overlap is
  delta = R_j + R_{j+1} - dist and the force of the contact law F(delta, d(delta)/dt) (paper
  eq. 1, Kuwabara-Kono or dashpot as in 1D) acts as -F n on body j and +F n on body j + 1,
  n = (dx, ey) / dist, with d(delta)/dt = n . (v_j - v_{j+1}) (both components);
- the flat wall (contact N) pushes along the axis only (a frictionless plane);
- the track acts on the transverse motion of every body i: a restoring force -k_i (y_i - e_i)
  towards its rest line e_i (the bead's offset; k_i = m_i g / (R_g - R_i) for a round groove of
  radius R_g, plus an optional spring) and Coulomb friction -mu m_i g w / sqrt(w^2 + v_s^2)
  against the transverse velocity w (regularised below the slip speed v_s, so it can only
  remove energy: its power -mu m g w^2 / sqrt(w^2 + v_s^2) is never positive).

Axial motion along the track is free, as in the 1D model (beads roll along the groove).

A pair with ey == 0 (exactly) takes the very arithmetic of the 1D kernels' aligned branch, and
the stepping below is that of ``kernels._verlet_run``'s general path: an aligned chain (every
offset zero) never gets a transverse force, its y stays exactly 0, and the run repeats the 1D
engine's numbers bit for bit (tests/test_lateral.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from ...errors import SimulationDiverged
from ...model import System
from ..core import kernels
from ..core.layout import pack
from .verlet import RawRun, _dt_used, refine_peak, step_plan

__all__ = ["LateralArrays", "LateralRun", "forces_2d", "run_lateral", "run_lateral_reference"]

DELTA_MIN = kernels.DELTA_MIN


@dataclass(frozen=True)
class LateralArrays:
    """Transverse model of every body, (N+2,) arrays like :class:`~hertzchain.model.System`'s.

    ``stiffness`` [N/m] pulls body i back to ``rest`` [m] (its offset e_i); ``friction`` [N] is
    mu m_i g, the Coulomb force at full slip; ``slip_velocity`` [m/s] regularises it. The wall
    ghost (last entry) has zeros.
    """

    stiffness: np.ndarray
    friction: np.ndarray
    rest: np.ndarray
    slip_velocity: float


@dataclass
class LateralRun:
    """A 2D run: the 1D-style record plus the transverse motion and its energy.

    ``raw`` holds axial contact forces (the component a force sensor on the axis reads), the
    total kinetic energy (axial + transverse), the potential energy (Hertz + track) and the
    energy dissipated by the contact law and the track friction together.
    """

    raw: RawRun
    lateral_kinetic_energy: np.ndarray   # (K,) J
    friction_loss: np.ndarray            # (K,) J, cumulative work of the track friction
    contact_loss: np.ndarray             # (K,) J, cumulative work of the contact law's dissipation
    lateral_position: np.ndarray         # (K, N+1) m, y of bodies 0..N
    lateral_velocity: np.ndarray         # (K, N+1) m/s
    momentum: np.ndarray                 # (K, 2) kg m/s, total axial and transverse momentum


@njit(cache=True, nogil=True)
def forces_2d(u, v, y, w, kappa, damping, d0, dx0, rsum, flat, law, gx, gy):
    """Contact forces along the line of centres; returns the power dissipated by the law [W].

    ``gx[j + 1]``, ``gy[j + 1]`` receive the axial and transverse components F c, F s of contact
    j (c, s the direction cosines of the line of centres). ``flat[j]`` marks the wall (axial only).
    Aligned pairs (ey == 0) use the 1D kernels' arithmetic unchanged.
    """
    power = 0.0
    for j in range(kappa.shape[0]):
        ey = y[j + 1] - y[j]
        aligned = flat[j] or ey == 0.0
        if aligned:
            d = u[j] - u[j + 1] + d0[j]
            c = 1.0
            s = 0.0
        else:
            dx = dx0[j] - (u[j] - u[j + 1])
            dist = np.sqrt(dx * dx + ey * ey)
            d = rsum[j] - dist
            c = dx / dist
            s = ey / dist
        # as kernels.forces_general: d == 0 is a contact (the dashpot's jump at closure)
        if d < 0.0:
            gx[j + 1] = 0.0
            gy[j + 1] = 0.0
            continue
        if d <= DELTA_MIN:
            d = 0.0
        sd = np.sqrt(d)
        fel = kappa[j] * d * sd
        if law == kernels.LAW_ELASTIC:
            gx[j + 1] = c * fel
            gy[j + 1] = s * fel
            continue
        if aligned:
            rate = c * (v[j] - v[j + 1])
        else:
            rate = c * (v[j] - v[j + 1]) + s * (w[j] - w[j + 1])  # d(delta)/dt
        if law == kernels.LAW_VISCOELASTIC:
            f = fel + kappa[j] * damping[j] * sd * rate
        else:
            f = fel + damping[j] * rate
        f = max(f, 0.0)
        power += (f - fel) * rate
        gx[j + 1] = c * f
        gy[j + 1] = s * f
    return power


@njit(cache=True, nogil=True)
def _track_forces(y, w, stiffness, friction, rest, vslip, fy):
    """Transverse track force on every body (restoring + regularised Coulomb); returns the friction power lost [W]."""
    lost = 0.0
    for i in range(fy.shape[0]):
        ff = 0.0
        if friction[i] != 0.0:
            ff = friction[i] * w[i] / np.sqrt(w[i] * w[i] + vslip * vslip)
            lost += ff * w[i]
        fy[i] = -stiffness[i] * (y[i] - rest[i]) - ff
    return lost


@njit(cache=True, nogil=True)
def _potential_2d(u, y, kappa, d0, dx0, rsum, flat, stiffness, rest, n):
    """Hertz potential (2/5) kappa delta^(5/2) with the 2D overlaps plus the track's (1/2) k (y - e)^2 [J]."""
    e = 0.0
    for j in range(kappa.shape[0]):
        ey = y[j + 1] - y[j]
        if flat[j] or ey == 0.0:
            d = u[j] - u[j + 1] + d0[j]
        else:
            dx = dx0[j] - (u[j] - u[j + 1])
            d = rsum[j] - np.sqrt(dx * dx + ey * ey)
        if d > 0.0:
            e += 0.4 * kappa[j] * d * d * np.sqrt(d)
    for i in range(n):
        dy = y[i] - rest[i]
        e += 0.5 * stiffness[i] * dy * dy
    return e


@njit(cache=True, nogil=True)
def _stride_2d(u, v, a, y, kappa, d0, de_now, dx0, rsum, flat, dcap, inv_mass, stiffness, horizon, block, c_steps,
               damping, law):
    """kernels.required_stride on the present transverse geometry (contact damping included), and
    at least enough steps for the stiffest track spring (omega^2 = k / m)."""
    for j in range(kappa.shape[0]):
        de_now[j] = 0.0 if flat[j] else y[j + 1] - y[j]
    ns = kernels.required_stride(u, v, a, kappa, d0, de_now, dx0, rsum, dcap, inv_mass, horizon, block, c_steps,
                                 damping, law, np.zeros((0, kernels.EXT_COLUMNS)), False)
    w2 = 0.0
    for i in range(stiffness.shape[0]):
        w2 = max(w2, stiffness[i] * inv_mass[i])
    if w2 > 0.0:
        ns = max(ns, int(np.ceil(block * c_steps * np.sqrt(w2) - 1e-9)))
    return ns


@njit(cache=True, nogil=True)
def lateral_run(u, v, a, g, y, w, ay, gy, fy, mass, inv_mass, kappa, damping, d0, dx0, rsum, flat, fext, dcap,
                stiffness, friction, rest, vslip, law, wall_slot, interval, stride, n_sub, n_eval, c_steps, relax,
                k_start, k_stop, rec, out_f, out_ke, out_pe, out_ed, out_kl, out_fl, out_y, out_w, out_p, fmax, peak,
                acc):
    """Advance samples ``k_start`` .. ``k_stop`` - 1 with velocity Verlet on (u, y); see ``kernels._verlet_run``.

    The stepping (blocks, adaptive step, leapfrog with fused half kicks, predicted velocities for
    the rate-dependent forces, wall-peak tracking) is that of ``verlet_run``'s general path, with
    the transverse coordinates stepped alongside. ``acc`` = [contact-law loss (J), its last power,
    step count, current ns, relax count, largest ns in the relax window, largest ns used,
    smallest ns used, friction loss (J), its last power]. Returns 0, or 1 if the state became
    non-finite.
    """
    n = a.shape[0]
    nout = rec.shape[0]
    block = interval / n_sub
    adaptive = stride == 0
    ns = stride if not adaptive else int(acc[3])
    vp = np.zeros_like(v)
    wp = np.zeros_like(w)
    de_now = np.zeros(kappa.shape[0])
    step = int(acc[2])
    for k in range(k_start, k_stop):
        for b in range(n_sub):
            if adaptive and ((k - 1) * n_sub + b) % n_eval == 0:
                req = _stride_2d(u, v, a, y, kappa, d0, de_now, dx0, rsum, flat, dcap, inv_mass, stiffness,
                                 n_eval * block, block, c_steps, damping, law)
                ns = kernels._adapt_stride(req, ns, relax, acc)
            dt = block / ns
            half = 0.5 * dt
            t0 = (k - 1) * interval + b * block
            for i in range(n):
                v[i] += half * a[i]
                u[i] += dt * v[i]
                w[i] += half * ay[i]
                y[i] += dt * w[i]
            for s in range(ns):
                for i in range(n):
                    vp[i] = v[i] + half * a[i]
                    wp[i] = w[i] + half * ay[i]
                p = forces_2d(u, vp, y, wp, kappa, damping, d0, dx0, rsum, flat, law, g, gy)
                pf = _track_forces(y, wp, stiffness, friction, rest, vslip, fy)
                acc[0] += half * (acc[1] + p)  # trapezoidal integrals of the dissipated powers
                acc[1] = p
                acc[8] += half * (acc[9] + pf)
                acc[9] = pf
                kernels._track_peak(g[wall_slot + 1], t0 + (s + 1) * dt, dt, peak)
                kick = dt if s < ns - 1 else half
                for i in range(n):
                    a[i] = (g[i] - g[i + 1] + fext[i]) * inv_mass[i]
                    v[i] += kick * a[i]
                    ay[i] = (gy[i] - gy[i + 1] + fy[i]) * inv_mass[i]
                    w[i] += kick * ay[i]
                if s < ns - 1:
                    for i in range(n):
                        u[i] += dt * v[i]
                        y[i] += dt * w[i]
            step += ns
        for j in range(nout):
            out_f[k, j] = g[rec[j] + 1]
        for j in range(fmax.shape[0]):
            x = g[j + 1]
            fmax[j] = x if x > fmax[j] else fmax[j]
        kl = kernels.kinetic_energy(w, mass)
        out_ke[k] = kernels.kinetic_energy(v, mass) + kl
        out_kl[k] = kl
        out_pe[k] = _potential_2d(u, y, kappa, d0, dx0, rsum, flat, stiffness, rest, n)
        out_ed[k] = acc[0]
        out_fl[k] = acc[8]
        px = 0.0
        py = 0.0
        for i in range(out_y.shape[1]):
            out_y[k, i] = y[i]
            out_w[k, i] = w[i]
            px += mass[i] * v[i]
            py += mass[i] * w[i]
        out_p[k, 0] = px
        out_p[k, 1] = py
        if not np.isfinite(out_ke[k]) or not np.isfinite(g[1]):
            acc[2] = step
            return 1
    acc[2] = step
    return 0


def _flat_mask(system: System, size: int) -> np.ndarray:
    flat = np.zeros(size, dtype=np.bool_)
    if system.has_wall:
        flat[system.n_beads] = True
    return flat


def _pad(x: np.ndarray, size: int) -> np.ndarray:
    out = np.zeros(size)
    out[: min(x.size, size)] = x[:size]
    return out


def run_lateral(system: System, lateral: LateralArrays, duration: float, sample_interval: float,
                dt: float | None = None, contacts: np.ndarray | None = None, chunk_steps: int = 2_000_000,
                progress=None) -> LateralRun:
    """Integrate ``system`` with transverse freedom ``lateral`` for ``duration`` [s] (compiled Verlet).

    Same step choice as :func:`hertzchain.integrate.drivers.verlet.run_verlet` (``dt`` [s] fixed, or the
    adaptive step when None, also bounded by the track springs), same samples every
    ``sample_interval`` [s]. ``contacts`` lists the contacts whose axial force is recorded.
    """
    if np.any(system.d0 != 0) or np.any(system.fext != 0):
        from ...errors import ConfigError

        raise ConfigError("chain.precompression", "is not supported with lateral freedom")
    plan = step_plan(system, sample_interval, dt)
    if dt is not None:
        w_lat = math.sqrt(float(np.max(lateral.stiffness[: system.n_beads + 1] * system.inv_mass[: system.n_beads + 1])))
        if w_lat * plan.dt > 0.5:
            from ...errors import ConfigError

            raise ConfigError("run.dt", f"time step {plan.dt:.3g} s is too large for the track spring "
                              f"(omega = {w_lat:.3g} rad/s); leave it out for the automatic step")
    n_samples = int(math.floor(duration / sample_interval + 1e-9)) + 1
    nc = system.n_contacts
    nb = system.n_beads + 1
    pk = pack(system)
    p = pk.n_slots
    u, v = pk.u, pk.v
    g = np.zeros(p + 1)
    a = np.zeros(p)
    y = _pad(lateral.rest, p + 1)       # bodies start on their rest lines, at rest
    w = np.zeros(p + 1)
    gy = np.zeros(p + 1)
    ay = np.zeros(p)
    fy = np.zeros(p)
    stiffness = _pad(lateral.stiffness[:nb], p)
    friction = _pad(lateral.friction[:nb], p)
    rest = _pad(lateral.rest[:nb], p)
    flat = _flat_mask(system, p)
    rec = np.arange(nc) if contacts is None else np.asarray(contacts, dtype=np.int64)
    out_f = np.empty((n_samples, rec.size))
    out_ke, out_pe, out_ed = np.empty(n_samples), np.empty(n_samples), np.empty(n_samples)
    out_kl, out_fl = np.zeros(n_samples), np.zeros(n_samples)
    out_y, out_w = np.empty((n_samples, nb)), np.zeros((n_samples, nb))
    out_p = np.empty((n_samples, 2))
    fmax = np.empty(nc)
    peak = np.empty(8)
    acc = np.zeros(10)
    # t = 0 (bodies on their rest lines, at rest but the striker; every pair touches along its
    # line of centres, so only a dashpot pushes yet): the forces on the 2D geometry, sample 0, and the
    # wall-peak tracker and accumulators as verlet.initialise starts them (peak: the wall force and
    # its neighbours; acc[1]: the dissipated power, acc[7]: the smallest ns so far). Not
    # verlet.initialise itself: it computes the 1D forces with kernels.forces_general, whose
    # compilation (~1 CPU-s with the 1D energy) a cold lateral run would add for numbers it overwrites.
    acc[1] = forces_2d(u, v, y, w, pk.kappa, pk.damping, pk.d0, pk.dx0, pk.rsum, flat, system.law, g, gy)
    acc[7] = np.inf
    acc[9] = _track_forces(y, w, stiffness, friction, rest, float(lateral.slip_velocity), fy)
    kernels.accelerations(g, pk.fext, pk.inv_mass, a)
    kernels.accelerations(gy, fy, pk.inv_mass, ay)
    fw0 = g[pk.wall_slot + 1]
    peak[:] = (fw0, 0.0, 0.0, 0.0, 0.0, fw0, 0.0, 0.0)
    out_f[0] = g[rec + 1]
    fmax[:] = g[1:nc + 1]
    out_ke[0] = kernels.kinetic_energy(v, pk.mass)
    out_pe[0] = _potential_2d(u, y, pk.kappa, pk.d0, pk.dx0, pk.rsum, flat, stiffness, rest, p)
    out_ed[0] = 0.0
    out_y[0] = y[:nb]
    out_p[0] = (float(np.dot(pk.mass, v[:p])), 0.0)
    samples_per_chunk = max(1, round(chunk_steps * plan.dt / sample_interval))
    k = 1
    while k < n_samples:
        k_stop = min(n_samples, k + samples_per_chunk)
        status = lateral_run(u, v, a, g, y, w, ay, gy, fy, pk.mass, pk.inv_mass, pk.kappa, pk.damping, pk.d0, pk.dx0,
                             pk.rsum, flat, pk.fext, pk.dcap, stiffness, friction, rest, float(lateral.slip_velocity),
                             system.law, pk.wall_slot, sample_interval, plan.stride, plan.n_sub, plan.n_eval,
                             plan.c_steps, plan.relax, k, k_stop, rec, out_f, out_ke, out_pe, out_ed, out_kl, out_fl,
                             out_y, out_w, out_p, fmax, peak, acc)
        if status != 0:
            raise SimulationDiverged(f"the 2D integration diverged before t = {k_stop * sample_interval:.4g} s")
        k = k_stop
        if progress is not None:
            progress(k - 1, n_samples - 1)
    fpk, t_pk = refine_peak(peak)
    dt_min, dt_max = _dt_used(plan, acc, sample_interval)
    raw = RawRun(time=np.arange(n_samples) * sample_interval, contact_force=out_f, kinetic_energy=out_ke,
                 potential_energy=out_pe, dissipated_energy=out_ed + out_fl, velocity=None, max_force=fmax,
                 peak_wall_force=fpk, peak_wall_time=t_pk, dt=dt_min, integrator="verlet", n_steps=int(acc[2]),
                 contacts=rec, dt_max=dt_max, adaptive=plan.adaptive)
    return LateralRun(raw=raw, lateral_kinetic_energy=out_kl, friction_loss=out_fl, contact_loss=out_ed,
                      lateral_position=out_y, lateral_velocity=out_w, momentum=out_p)


def run_lateral_reference(system: System, lateral: LateralArrays, duration: float, sample_interval: float,
                          rtol: float = 1e-12, atol_scale: float | None = None) -> LateralRun:
    """The same 2D equations through ``scipy.integrate.solve_ivp(method="DOP853")``.

    State [u, v, y, w, contact-law loss, friction loss] of bodies 0..N; the right-hand side calls
    the compiled :func:`forces_2d` and the track forces of the Verlet path.
    """
    from scipy.integrate import solve_ivp

    nb = system.n_beads + 1
    s = system
    flat = _flat_mask(s, s.kappa.size)
    stiffness, friction, rest = lateral.stiffness[:nb].copy(), lateral.friction[:nb].copy(), lateral.rest[:nb].copy()
    uu, vv, yy, ww = (np.zeros(nb + 1) for _ in range(4))
    gx, gy = np.zeros(nb + 1), np.zeros(nb + 1)
    fy = np.zeros(nb)

    def rhs(t, z):
        uu[:nb], vv[:nb], yy[:nb], ww[:nb] = z[:nb], z[nb:2 * nb], z[2 * nb:3 * nb], z[3 * nb:4 * nb]
        yy[nb] = yy[nb - 1]  # the wall ghost: a flat, its y is never read (flat contact)
        p = forces_2d(uu, vv, yy, ww, s.kappa, s.damping, s.d0, s.dx0, s.rsum, flat, s.law, gx, gy)
        pf = _track_forces(yy[:nb], ww[:nb], stiffness, friction, rest, lateral.slip_velocity, fy)
        ax = (gx[:nb] - gx[1:] + s.fext[:nb]) * s.inv_mass[:nb]
        ayy = (gy[:nb] - gy[1:] + fy) * s.inv_mass[:nb]
        return np.concatenate([vv[:nb], ax, ww[:nb], ayy, [p, pf]])

    n_samples = int(math.floor(duration / sample_interval + 1e-9)) + 1
    time = np.arange(n_samples) * sample_interval
    z0 = np.concatenate([s.u0[:nb], s.v0[:nb], rest, np.zeros(nb), [0.0, 0.0]])
    energy = 0.5 * s.mass[0] * s.v0[0] ** 2
    d_scale = (2.5 * energy / s.kappa[0]) ** 0.4
    v_scale = abs(s.v0).max()
    atol_scale = rtol if atol_scale is None else atol_scale
    atol = atol_scale * np.concatenate([np.full(nb, d_scale), np.full(nb, v_scale), np.full(nb, d_scale),
                                        np.full(nb, v_scale), [energy, energy]])
    sol = solve_ivp(rhs, (0.0, time[-1]), z0, method="DOP853", rtol=rtol, atol=atol, t_eval=time)
    if not sol.success:
        raise SimulationDiverged(f"solve_ivp(DOP853) failed: {sol.message}")
    nc = s.n_contacts
    forces = np.empty((n_samples, nc))
    ke, kl, pe = np.empty(n_samples), np.empty(n_samples), np.empty(n_samples)
    for k in range(n_samples):
        z = sol.y[:, k]
        uu[:nb], vv[:nb], yy[:nb], ww[:nb] = z[:nb], z[nb:2 * nb], z[2 * nb:3 * nb], z[3 * nb:4 * nb]
        yy[nb] = yy[nb - 1]
        forces_2d(uu, vv, yy, ww, s.kappa, s.damping, s.d0, s.dx0, s.rsum, flat, s.law, gx, gy)
        forces[k] = gx[1:nc + 1]
        kl[k] = 0.5 * float(np.sum(s.mass[:nb] * ww[:nb] ** 2))
        ke[k] = 0.5 * float(np.sum(s.mass[:nb] * vv[:nb] ** 2)) + kl[k]
        pe[k] = _potential_2d(uu, yy, s.kappa, s.d0, s.dx0, s.rsum, flat, stiffness, rest, nb)
    m = s.mass[:nb]
    vel, lat_v = sol.y[nb:2 * nb].T, sol.y[3 * nb:4 * nb].T
    momentum = np.stack([vel @ m, lat_v @ m], axis=1)
    raw = RawRun(time=time, contact_force=forces, kinetic_energy=ke, potential_energy=pe,
                 dissipated_energy=sol.y[-2] + sol.y[-1], velocity=vel, max_force=forces.max(axis=0),
                 peak_wall_force=float(forces[:, -1].max()) if s.has_wall else 0.0, peak_wall_time=0.0, dt=0.0,
                 integrator=f"scipy.solve_ivp(DOP853, rtol={rtol:g})", n_steps=int(sol.nfev),
                 contacts=np.arange(nc))
    return LateralRun(raw=raw, lateral_kinetic_energy=kl, friction_loss=sol.y[-1].copy(), contact_loss=sol.y[-2].copy(),
                      lateral_position=sol.y[2 * nb:3 * nb].T.copy(), lateral_velocity=lat_v.copy(), momentum=momentum)
