"""Reference integrator: the same model through ``scipy.integrate.solve_ivp`` (DOP853 by default).

The right-hand side calls the very force functions of the compiled Verlet
(:mod:`hertzchain.integrate.core.kernels`, or the loop generated from a registry law without
per-contact state: :mod:`hertzchain.integrate.core.generated`), so the two integrators differ only
in how they step. The dissipated energy is integrated as one extra state component.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import minimize_scalar

from ...errors import SimulationDiverged
from ...model import System
from ..core import kernels
from ..core.generated import is_generated, law_kernels
from ..core.layout import pack
from .verlet import RawRun

__all__ = ["run_reference", "make_rhs"]

#: The elastic-plastic state arrays of ``kernels.forces_general``, unused by the laws solved here
#: (a history-dependent force has no place in an ODE right-hand side evaluated at trial points).
_NO_STATE = np.zeros(0)


def _check_law(system: System, method: str = "DOP853") -> None:
    """Refuse the elastic-plastic law (ConfigError naming ``run.integrator``, suggesting only the
    integrators that take the model: :mod:`hertzchain.integrate.drivers.refusals`)."""
    from .refusals import refuse

    refuse(method.lower(), system)


def _contact_forces(law: int, kappa, damping, d0, de, dx0, rsum, general: bool):
    """``forces(u, v, g) -> dissipated power [W]``: the axial contact forces into ``g`` as the
    Verlet computes them (the generated loop of a registry law, ``forces_general`` or the elastic
    loop), and ``energy(u, g, fext) -> stored energy [J]`` as its probes do."""
    if is_generated(law):
        forces_g, _, stored, _, _ = law_kernels(law)
        state = np.zeros(kappa.size)  # a law without per-contact state (refusals.py) leaves it as is

        def forces(u, v, g):
            return forces_g(u, v, kappa, damping, d0, de, dx0, rsum, g, state)

        def energy(u, g, fext):
            return stored(u, kappa, damping, d0, de, dx0, rsum, fext)
        return forces, energy

    def energy_hertz(u, g, fext):
        return kernels.potential_energy(u, g, kappa, d0, de, dx0, rsum, fext, False)

    if general:
        def forces_general(u, v, g):
            return kernels.forces_general(u, v, kappa, damping, d0, de, dx0, rsum, law, g, *(_NO_STATE,) * 4)
        return forces_general, energy_hertz

    def forces_elastic(u, v, g):
        kernels.forces_elastic(u, kappa, d0, g)
        return 0.0
    return forces_elastic, energy_hertz


def make_rhs(system: System) -> Callable[[float, np.ndarray], np.ndarray]:
    """dy/dt for y = [u_0..u_N, v_0..v_N, E_dissipated] (SI units); not for the elastic-plastic law. An
    extended system (a protected body, mass-in-mass beads: :func:`_make_rhs_extended`) has more
    components."""
    _check_law(system)
    if system.extended:
        return _make_rhs_extended(system)
    nb = system.n_beads + 1
    u = np.zeros(nb + 1)
    v = np.zeros(nb + 1)
    g = np.zeros(nb + 1)
    a = np.zeros(nb)
    s = system
    forces, _ = _contact_forces(s.law, s.kappa, s.damping, s.d0, s.de, s.dx0, s.rsum, s.general)

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        u[:nb] = y[:nb]
        v[:nb] = y[nb : 2 * nb]
        power = forces(u, v, g)
        kernels.accelerations(g, s.fext, s.inv_mass, a)
        return np.concatenate([v[:nb], a, [power]])

    return rhs


class _Extended:
    """The arrays of an extended system laid out as the kernels take them (``layout.pack``), and
    the state vector's parts: y = [u (nb), v (nb), w (nb), wv (nb), E_dissipated, W_body], nb the
    moving bodies (the protected body included), w and wv the internal masses' motion."""

    def __init__(self, system: System) -> None:
        w = pack(system)
        self.w = w
        self.nb = system.n_moving
        p = w.n_slots
        self.u = np.zeros(p + 1)
        self.v = np.zeros(p + 1)
        self.g = np.zeros(p + 1)
        self.a = np.zeros(p)
        self.wa = np.zeros(p)
        self.ext = w.ext.copy()
        self.contact_forces, self.stored = _contact_forces(system.law, w.kappa, w.damping, w.d0, w.de, w.dx0,
                                                           w.rsum, True)
        if not is_generated(system.law):  # the elastic-plastic state of forces_general (refused laws aside)
            def forces_general(u, v, g):
                return kernels.forces_general(u, v, w.kappa, w.damping, w.d0, w.de, w.dx0, w.rsum, system.law, g,
                                              w.dyield, w.dmax, w.dres, w.kres)
            self.contact_forces = forces_general

    def load(self, y: np.ndarray) -> None:
        nb, e = self.nb, self.ext
        self.u[:nb] = y[:nb]
        self.v[:nb] = y[nb:2 * nb]
        e[:nb, kernels.EXT_W] = y[2 * nb:3 * nb]
        e[:nb, kernels.EXT_WV] = y[3 * nb:4 * nb]

    def forces(self) -> float:
        power = self.contact_forces(self.u, self.v, self.g)
        return power + kernels.forces_linear(self.u, self.v, self.w.d0, self.ext, self.g)


def _make_rhs_extended(system: System) -> Callable[[float, np.ndarray], np.ndarray]:
    """dy/dt of an extended system (see :class:`_Extended`)."""
    x = _Extended(system)
    nb, b = x.nb, x.w.body_slot

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        x.load(y)
        power = x.forces()
        kernels.accelerations_extended(x.u, x.g, x.w.fext, x.w.inv_mass, x.ext, x.a, x.wa)
        work = x.g[b] * x.v[b] if b >= 0 else 0.0
        return np.concatenate([x.v[:nb], x.a[:nb], x.ext[:nb, kernels.EXT_WV], x.wa[:nb], [power, work]])

    return rhs


def _wall_force(system: System, forces: Callable, y: np.ndarray) -> float:
    """The wall contact's force in state ``y``, by the recorded forces' function (a dissipative
    law's includes the rate term the wall sensor reads)."""
    nb = system.n_beads + 1
    u = np.zeros(nb + 1)
    v = np.zeros(nb + 1)
    g = np.zeros(nb + 1)
    u[:nb] = y[:nb]
    v[:nb] = y[nb : 2 * nb]
    forces(u, v, g)
    return float(g[nb])


def run_reference(system: System, duration: float, sample_interval: float, method: str = "DOP853",
                  rtol: float = 1e-10, atol_scale: float | None = None,
                  record_velocities: bool = False, record_positions: bool = False) -> RawRun:
    """Integrate with ``solve_ivp(method=method, rtol=rtol)`` and sample like :func:`run_verlet`.

    ``atol`` is set per component from ``rtol`` and natural scales (overlap of the striker
    contact, striker speed, striker energy) so that a tolerance means the same for every chain.
    The peak wall force is refined on the dense output. The elastic-plastic law is refused
    (ConfigError naming ``run.integrator``).
    """
    _check_law(system, method)
    if system.extended:
        return _run_reference_extended(system, duration, sample_interval, method, rtol, atol_scale,
                                       record_velocities, record_positions)
    nb = system.n_beads + 1
    n_samples = int(math.floor(duration / sample_interval + 1e-9)) + 1
    time = np.arange(n_samples) * sample_interval
    y0 = np.concatenate([system.u0[:nb], system.v0[:nb], [0.0]])
    v_scale = max(abs(system.v0).max(), 1e-12)
    energy = 0.5 * system.mass[0] * system.v0[0] ** 2
    d_scale = (2.5 * energy / system.kappa[0]) ** 0.4 if system.kappa[0] > 0 else 1e-6
    if atol_scale is None:
        atol_scale = rtol
    atol = np.concatenate([np.full(nb, atol_scale * d_scale), np.full(nb, atol_scale * v_scale), [atol_scale * energy]])
    sol = solve_ivp(make_rhs(system), (0.0, time[-1]), y0, method=method, rtol=rtol, atol=atol, t_eval=time,
                    dense_output=True)
    if not sol.success or not np.all(np.isfinite(sol.y)):
        raise SimulationDiverged(f"solve_ivp({method}) failed: {sol.message}")
    u = np.zeros((n_samples, nb + 1))
    u[:, :nb] = sol.y[:nb].T
    vel = sol.y[nb : 2 * nb].T
    nc = system.n_contacts
    forces = np.empty((n_samples, nc))
    g = np.zeros(nb + 1)
    ke = 0.5 * (vel**2 * system.mass[:nb]).sum(axis=1)
    pe = np.empty(n_samples)
    vv = np.zeros(nb + 1)
    s = system
    contact_forces, stored = _contact_forces(s.law, s.kappa, s.damping, s.d0, s.de, s.dx0, s.rsum, s.general)
    for k in range(n_samples):
        vv[:nb] = vel[k]
        contact_forces(u[k], vv, g)
        forces[k] = g[1 : nc + 1]
        pe[k] = stored(u[k], g, system.fext)
    peak_f, peak_t = 0.0, 0.0
    if system.has_wall:
        k = int(np.argmax(forces[:, -1]))
        lo, hi = time[max(k - 1, 0)], time[min(k + 1, n_samples - 1)]
        if hi > lo:
            res = minimize_scalar(lambda t: -_wall_force(system, contact_forces, sol.sol(t)), bounds=(lo, hi),
                                  method="bounded",
                                  options={"xatol": 1e-13})
            peak_f, peak_t = -float(res.fun), float(res.x)
        peak_f = max(peak_f, float(forces[k, -1]))
    return RawRun(time=time, contact_force=forces, kinetic_energy=ke, potential_energy=pe, max_force=forces.max(axis=0),
                  dissipated_energy=sol.y[-1].copy(), velocity=vel if record_velocities else None,
                  peak_wall_force=peak_f, peak_wall_time=peak_t, dt=0.0,
                  integrator=f"scipy.solve_ivp({method}, rtol={rtol:g})", n_steps=int(sol.nfev), contacts=np.arange(nc),
                  displacement=u[:, :nb].copy() if record_positions else None)


def _run_reference_extended(system: System, duration: float, sample_interval: float, method: str, rtol: float,
                            atol_scale: float | None, record_velocities: bool, record_positions: bool) -> RawRun:
    """:func:`run_reference` of an extended system (a protected body, mass-in-mass beads)."""
    x = _Extended(system)
    nb, n, b = x.nb, system.n_beads, x.w.body_slot
    n_samples = int(math.floor(duration / sample_interval + 1e-9)) + 1
    time = np.arange(n_samples) * sample_interval
    y0 = np.concatenate([system.u0[:nb], system.v0[:nb], np.zeros(2 * nb + 2)])
    v_scale = max(abs(system.v0).max(), 1e-12)
    energy = 0.5 * system.mass[0] * system.v0[0] ** 2
    d_scale = (2.5 * energy / system.kappa[0]) ** 0.4 if system.kappa[0] > 0 else 1e-6
    tol = rtol if atol_scale is None else atol_scale
    atol = np.concatenate([np.full(nb, tol * d_scale), np.full(nb, tol * v_scale), np.full(nb, tol * d_scale),
                           np.full(nb, tol * v_scale), [tol * energy, tol * energy]])
    sol = solve_ivp(make_rhs(system), (0.0, time[-1]), y0, method=method, rtol=rtol, atol=atol, t_eval=time,
                    dense_output=True)
    if not sol.success or not np.all(np.isfinite(sol.y)):
        raise SimulationDiverged(f"solve_ivp({method}) failed: {sol.message}")
    nc = system.n_contacts
    forces = np.empty((n_samples, nc))
    ke, pe = np.empty(n_samples), np.empty(n_samples)
    body = np.empty((n_samples, 4)) if b >= 0 else None
    w = x.w
    for k in range(n_samples):
        x.load(sol.y[:, k])
        x.forces()
        kernels.accelerations_extended(x.u, x.g, w.fext, w.inv_mass, x.ext, x.a, x.wa)
        forces[k] = x.g[1:nc + 1]
        ke_in, pe_lin = kernels.energies_extended(x.u, w.d0, x.ext)
        ke[k] = kernels.kinetic_energy(x.v, w.mass) + ke_in
        pe[k] = x.stored(x.u, x.g, w.fext) + pe_lin
        if body is not None:
            body[k] = (x.u[b], x.v[b], x.a[b], sol.y[-1, k])

    def wall_force(t: float) -> float:
        x.load(sol.sol(t))
        x.forces()
        return float(x.g[n + 1])

    peak_f, peak_t = 0.0, 0.0
    if system.has_wall:
        k = int(np.argmax(forces[:, -1]))
        lo, hi = time[max(k - 1, 0)], time[min(k + 1, n_samples - 1)]
        if hi > lo:
            res = minimize_scalar(lambda t: -wall_force(t), bounds=(lo, hi), method="bounded", options={"xatol": 1e-13})
            peak_f, peak_t = -float(res.fun), float(res.x)
        peak_f = max(peak_f, float(forces[k, -1]))
    return RawRun(time=time, contact_force=forces, kinetic_energy=ke, potential_energy=pe, max_force=forces.max(axis=0),
                  dissipated_energy=sol.y[-2].copy(), velocity=sol.y[nb:nb + n + 1].T.copy() if record_velocities else None,
                  peak_wall_force=peak_f, peak_wall_time=peak_t, dt=0.0,
                  integrator=f"scipy.solve_ivp({method}, rtol={rtol:g})", n_steps=int(sol.nfev), contacts=np.arange(nc),
                  displacement=sol.y[:n + 1].T.copy() if record_positions else None, body=body)
