"""The engine's viscous steps (kernels.dissipative_block: the damping constants per contact, the law
and an unloaded chain as compile-time constants) against the general step they specialise
(kernels.step_dissipative), and the viscous force floor (primitives.FORCE_MIN): a dashpot's
precursor through an uncompressed chain stops at it instead of decaying into subnormal floats."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

import hertzchain as hc
from hertzchain.integrate.core import kernels as K
from hertzchain.integrate.core.layout import pack
from hertzchain.integrate.core.primitives import FORCE_MIN, open_block
from hertzchain.integrate.drivers.verlet import run_verlet

#: The smallest normal double: below it, x86 arithmetic slows ~30x (kernels.DELTA_MIN, FORCE_MIN).
TINY = np.finfo(float).tiny


@njit
def _general_blocks(u, v, vp, a, g, kappa, damping, d0, fext, inv_mass, law, dt, n_blocks, ns):
    half = 0.5 * dt
    for k in range(n_blocks):
        if k > 0:
            for i in range(a.shape[0]):
                v[i] += half * a[i]
                u[i] += dt * v[i]
        K.predict(v, a, half, vp)
        for s in range(ns):
            K.step_dissipative(u, v, vp, a, g, kappa, damping, d0, fext, inv_mass, law, dt, half, s == ns - 1)


def _start(law, precompression):
    model = hc.Model(hc.Chain.from_diameters(np.r_[np.full(12, 26e-3), np.geomspace(26e-3, 14e-3, 9)]),
                     hc.Striker(8e-3, 1.0), law=law, precompression=precompression)
    s = model.system()
    w = pack(s)
    a = np.zeros(w.n_slots)
    g = np.zeros(w.n_slots + 1)
    K.forces_general(w.u, w.v, w.kappa, w.damping, w.d0, w.de, w.dx0, w.rsum, s.law, g, w.dyield, w.dmax, w.dres,
                     w.kres)
    K.accelerations(g, w.fext, w.inv_mass, a)
    open_block(w.u, w.v, a, 1e-8, 0.5e-8)
    return s, w, a, g


@pytest.mark.parametrize("law", [hc.Viscoelastic(A=2e-6), hc.Dashpot(gamma=20.0)], ids=["viscoelastic", "dashpot"])
@pytest.mark.parametrize("precompression", [0.0, 20.0], ids=["unloaded", "precompressed"])
def test_engine_viscous_blocks_are_the_general_step(law, precompression):
    """Over a pulse through the chain and off the wall (300 blocks of 200 steps), the engine's
    blocks give the positions, velocities, accelerations and forces of the general step bit for
    bit (unloaded: the additions of zero left out change at most the sign of a zero, which
    array_equal ignores), and the dissipated energy within the documented 1e-14 of the
    contact-order sum (tests/test_fused.py)."""
    runs = []
    for engine in (False, True):
        s, w, a, g = _start(law, precompression)
        vp = np.zeros(w.n_slots + 1)
        if engine:
            c = np.zeros(w.n_slots)
            K.damping_constants(w.kappa, w.damping, s.law, c)
            unloaded = bool(np.all(w.d0 == 0.0) and np.all(w.fext == 0.0))
            assert unloaded == (precompression == 0.0)
            acc = np.zeros(8)
            for k in range(300):
                if k > 0:
                    open_block(w.u, w.v, a, 1e-8, 0.5e-8)
                K.dissipative_block(w.u, w.v, vp, a, g, w.kappa, c, w.d0, w.fext, w.inv_mass, s.law, unloaded, 200,
                                    1e-8, 0.0, w.wall_slot, np.zeros(8), acc)
        else:
            _general_blocks(w.u, w.v, vp, a, g, w.kappa, w.damping, w.d0, w.fext, w.inv_mass, s.law, 1e-8, 300, 200)
        runs.append((w.u, w.v, a, g))
    for name, x, y in zip(("u", "v", "a", "g"), *runs):
        assert np.array_equal(x, y), name
    assert np.max(runs[0][3]) > 1.0  # forces acted
    assert acc[0] > 0.0


def test_dashpot_precursor_stops_at_the_force_floor():
    """A dashpot pushes at zero overlap (the d == 0 convention), so its precursor runs ahead of the
    pulse through an uncompressed chain's touching beads, one bead a step. Without a floor it
    decayed into subnormal velocities and forces (~1e-320, x86's slow path); with FORCE_MIN no
    recorded force is in (0, FORCE_MIN] and no velocity is subnormal, while the pulse itself is
    unchanged: the peak force and the energy balance as the DOP853 reference gives them."""
    model = hc.Model(hc.Chain.uniform(300, 26e-3), hc.Striker(8e-3, 0.2), hc.Wall("flat"), law=hc.Dashpot(5.0))
    s = model.system()
    run = run_verlet(s, 4e-5, 2e-7, dt=2e-8, record_velocities=True)  # 2000 steps: the precursor crosses the chain
    f = run.contact_force
    assert not np.any((f > 0.0) & (f <= FORCE_MIN))
    v = run.velocity
    assert not np.any((v != 0.0) & (np.abs(v) < TINY))
    assert np.count_nonzero(f[-1]) > 20  # a precursor ran ahead of the pulse, down to the floor
    short = hc.Model(hc.Chain.uniform(20, 26e-3), hc.Striker(8e-3, 0.2), hc.Wall("flat"), law=hc.Dashpot(5.0))
    ds = hc.simulate(short, 2e-3, dt=2e-8)
    ref = hc.simulate(short, 2e-3, integrator="dop853", rtol=1e-11)
    assert ref.attrs["peak_wall_force"] > 1.0  # the pulse reached the wall
    assert ds.attrs["peak_wall_force"] == pytest.approx(ref.attrs["peak_wall_force"], rel=1e-5)
    total = ds.kinetic_energy.values + ds.potential_energy.values + ds.dissipated_energy.values
    assert np.abs(total - total[0]).max() < 1e-5 * total[0]
