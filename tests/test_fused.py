"""The viscous laws' fused step (kernels.step_dissipative) against the general path it replaces
for aligned chains (the predicted velocities, kernels.forces_general, the update loops):
positions, velocities, accelerations and forces bit for bit over a whole pulse; the dissipated
power, summed in a vectorised order (kernels.dissipative_block), within 1e-14 of the
contact-order sum. (The elastic-plastic law keeps the general path's two passes: faster than a
fused scalar pass, benchmarks/dissipative.py.)"""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

import hertzchain as hc
from hertzchain.integrate import kernels as K
from hertzchain.integrate.layout import pack

#: The documented bound on the dissipated power of the viscous laws (relative to its largest value).
POWER_REL = 1e-14


@njit
def _general(u, v, a, g, vp, kappa, damping, d0, de, dx0, rsum, fext, inv_mass, law, dyield, dmax, dres, kres, dt,
             n_steps, powers):
    """verlet_run's general branch, step by step (the last step of a block: the closing half kick)."""
    n = a.shape[0]
    half = 0.5 * dt
    for s in range(n_steps):
        for i in range(n):
            vp[i] = v[i] + half * a[i]
        powers[s] = K.forces_general(u, vp, kappa, damping, d0, de, dx0, rsum, law, g, dyield, dmax, dres, kres)
        last = s == n_steps - 1
        for i in range(n):
            a[i] = (g[i] - g[i + 1] + fext[i]) * inv_mass[i]
            if last:
                v[i] += half * a[i]
            else:
                v[i] += dt * a[i]
                u[i] += dt * v[i]


@njit
def _fused(u, v, a, g, kappa, damping, d0, fext, inv_mass, law, dt, n_steps, powers):
    half = 0.5 * dt
    for s in range(n_steps):
        powers[s] = K.step_dissipative(u, v, a, g, kappa, damping, d0, fext, inv_mass, law, dt, half,
                                       s == n_steps - 1)


@pytest.mark.parametrize("law", [hc.Viscoelastic(A=2e-6), hc.Dashpot(gamma=20.0)], ids=["viscoelastic", "dashpot"])
@pytest.mark.parametrize("precompression", [0.0, 20.0])
def test_fused_step_is_the_general_path(law, precompression):
    model = hc.Model(hc.Chain.from_diameters(np.r_[np.full(12, 26e-3), np.geomspace(26e-3, 14e-3, 9)]),
                     hc.Striker(8e-3, 1.0), law=law, precompression=precompression)
    s = model.system()
    runs = []
    for fused in (False, True):
        w = pack(s)
        p = w.n_slots
        a = np.zeros(p)
        g = np.zeros(p + 1)
        K.forces_general(w.u, w.v, w.kappa, w.damping, w.d0, w.de, w.dx0, w.rsum, s.law, g, w.dyield, w.dmax, w.dres,
                         w.kres)
        K.accelerations(g, w.fext, w.inv_mass, a)
        for i in range(p):  # a block's opening half kick and drift, as verlet_run
            w.v[i] += 0.5e-8 * a[i]
            w.u[i] += 1e-8 * w.v[i]
        powers = np.zeros(60_000)  # 0.6 ms at 10 ns: the pulse through the chain and off the wall
        if fused:
            _fused(w.u, w.v, a, g, w.kappa, w.damping, w.d0, w.fext, w.inv_mass, s.law, 1e-8, powers.size, powers)
        else:
            _general(w.u, w.v, a, g, np.zeros(p + 1), w.kappa, w.damping, w.d0, w.de, w.dx0, w.rsum, w.fext,
                     w.inv_mass, s.law, w.dyield, w.dmax, w.dres, w.kres, 1e-8, powers.size, powers)
        runs.append((w.u, w.v, a, g, w.dmax, w.dres, w.kres, powers))
    general, fused = runs
    for name, x, y in zip(("u", "v", "a", "g", "dmax", "dres", "kres"), general, fused):
        assert np.array_equal(x, y), name
    assert np.max(general[3]) > 1.0 and np.max(general[-1]) > 0.0  # forces acted, energy was dissipated
    assert np.abs(general[-1] - fused[-1]).max() <= POWER_REL * np.abs(general[-1]).max()


def test_simulate_uses_the_fused_steps_for_aligned_dissipative_chains():
    """The default path of a dissipative run agrees with DOP853 as before (the fused steps are the
    general path's arithmetic; tests/test_dissipation.py checks the physics)."""
    model = hc.Model(hc.Chain.uniform(10, 20e-3), hc.Striker(8e-3, 0.3), law=hc.Viscoelastic(A=2e-6))
    ds = hc.simulate(model, 1e-3)
    ref = hc.simulate(model, 1e-3, integrator="dop853", rtol=1e-11)
    assert ds.attrs["peak_wall_force"] == pytest.approx(ref.attrs["peak_wall_force"], rel=1e-5)
    assert ds.dissipated_energy.values[-1] == pytest.approx(ref.dissipated_energy.values[-1], rel=1e-4)
