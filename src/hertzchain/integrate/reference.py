"""Reference integrator: the same model through ``scipy.integrate.solve_ivp`` (DOP853 by default).

The right-hand side calls the very force functions of the compiled Verlet
(:mod:`hertzchain.integrate.kernels`), so the two integrators differ only in how they step.
The dissipated energy is integrated as one extra state component.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import minimize_scalar

from ..errors import ConfigError, SimulationDiverged
from ..model import System
from . import kernels
from .verlet import RawRun

__all__ = ["run_reference", "make_rhs"]

#: The elastic-plastic state arrays of ``kernels.forces_general``, unused by the laws solved here
#: (a history-dependent force has no place in an ODE right-hand side evaluated at trial points).
_NO_STATE = np.zeros(0)


def _check_law(system: System) -> None:
    """Refuse the elastic-plastic law (ConfigError naming ``run.integrator``)."""
    if system.law == kernels.LAW_ELASTOPLASTIC:
        raise ConfigError("run.integrator", "the elastoplastic contact law keeps a history per contact (its largest "
                          "overlap), which the scipy integrators cannot carry between their trial steps; use "
                          "integrator = 'verlet'")


def make_rhs(system: System) -> Callable[[float, np.ndarray], np.ndarray]:
    """dy/dt for y = [u_0..u_N, v_0..v_N, E_dissipated] (SI units); not for the elastic-plastic law."""
    _check_law(system)
    nb = system.n_beads + 1
    u = np.zeros(nb + 1)
    v = np.zeros(nb + 1)
    g = np.zeros(nb + 1)
    a = np.zeros(nb)
    s = system

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        u[:nb] = y[:nb]
        v[:nb] = y[nb : 2 * nb]
        if s.general:
            power = kernels.forces_general(u, v, s.kappa, s.damping, s.d0, s.de, s.dx0, s.rsum, s.law, g,
                                           *(_NO_STATE,) * 4)
        else:
            kernels.forces_elastic(u, s.kappa, s.d0, g)
            power = 0.0
        kernels.accelerations(g, s.fext, s.inv_mass, a)
        return np.concatenate([v[:nb], a, [power]])

    return rhs


def _wall_force(system: System, y: np.ndarray) -> float:
    nb = system.n_beads + 1
    if system.general:
        # Dissipative laws: the wall force includes the rate term, so use the same kernel as the
        # recorded forces (the elastic part alone is not the force the wall sensor reads).
        u = np.zeros(nb + 1)
        v = np.zeros(nb + 1)
        g = np.zeros(nb + 1)
        u[:nb] = y[:nb]
        v[:nb] = y[nb : 2 * nb]
        kernels.forces_general(u, v, system.kappa, system.damping, system.d0, system.de, system.dx0, system.rsum,
                               system.law, g, *(_NO_STATE,) * 4)
        return float(g[nb])
    d = y[nb - 1] + system.d0[-1]
    return float(system.kappa[-1] * max(d, 0.0) ** 1.5)


def run_reference(system: System, duration: float, sample_interval: float, method: str = "DOP853",
                  rtol: float = 1e-10, atol_scale: float | None = None,
                  record_velocities: bool = False, record_positions: bool = False) -> RawRun:
    """Integrate with ``solve_ivp(method=method, rtol=rtol)`` and sample like :func:`run_verlet`.

    ``atol`` is set per component from ``rtol`` and natural scales (overlap of the striker
    contact, striker speed, striker energy) so that a tolerance means the same for every chain.
    The peak wall force is refined on the dense output. The elastic-plastic law is refused
    (ConfigError naming ``run.integrator``).
    """
    _check_law(system)
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
    for k in range(n_samples):
        vv[:nb] = vel[k]
        if system.general:
            kernels.forces_general(u[k], vv, system.kappa, system.damping, system.d0, system.de, system.dx0,
                                   system.rsum, system.law, g, *(_NO_STATE,) * 4)
        else:
            kernels.forces_elastic(u[k], system.kappa, system.d0, g)
        forces[k] = g[1 : nc + 1]
        pe[k] = kernels.potential_energy(u[k], g, system.kappa, system.d0, system.de, system.dx0, system.rsum,
                                         system.fext, False)
    peak_f, peak_t = 0.0, 0.0
    if system.has_wall:
        k = int(np.argmax(forces[:, -1]))
        lo, hi = time[max(k - 1, 0)], time[min(k + 1, n_samples - 1)]
        if hi > lo:
            res = minimize_scalar(lambda t: -_wall_force(system, sol.sol(t)), bounds=(lo, hi), method="bounded",
                                  options={"xatol": 1e-13})
            peak_f, peak_t = -float(res.fun), float(res.x)
        peak_f = max(peak_f, float(forces[k, -1]))
    return RawRun(time=time, contact_force=forces, kinetic_energy=ke, potential_energy=pe, max_force=forces.max(axis=0),
                  dissipated_energy=sol.y[-1].copy(), velocity=vel if record_velocities else None,
                  peak_wall_force=peak_f, peak_wall_time=peak_t, dt=0.0,
                  integrator=f"scipy.solve_ivp({method}, rtol={rtol:g})", n_steps=int(sol.nfev), contacts=np.arange(nc),
                  displacement=u[:, :nb].copy() if record_positions else None)
