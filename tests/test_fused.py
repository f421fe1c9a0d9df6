"""The fused steps against the general path they replace (the predicted velocities,
kernels.forces_general, the update loops): the viscous laws' step of aligned chains
(kernels.step_dissipative) and the elastic and viscous steps of misaligned chains (integrate/core/fused.py):
positions, velocities, accelerations and forces bit for bit over a whole pulse; the dissipated
power, summed in a vectorised order (kernels.dissipative_block, fused.offset_dissipative_block),
within 1e-14 of the contact-order sum; the energies of the probes of a misaligned chain
(fused.energies_offset) within rounding of kernels.potential_energy's. (The elastic-plastic law
keeps the general path's two passes: faster than a fused scalar pass, benchmarks/dissipative.py.)"""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

import hertzchain as hc
from hertzchain.integrate.core import fused as FU
from hertzchain.integrate.core import kernels as K
from hertzchain.integrate.core.layout import pack
from hertzchain.integrate.core.primitives import open_block

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
    vp = np.zeros(u.shape[0])
    K.predict(v, a, half, vp)
    for s in range(n_steps):
        powers[s] = K.step_dissipative(u, v, vp, a, g, kappa, damping, d0, fext, inv_mass, law, dt, half,
                                       s == n_steps - 1)


def _block_start(s):
    """A system's packed arrays, forces and accelerations at t = 0, after a block's opening half kick
    and drift (dt = 10 ns, as verlet_run), and room for the powers of 60,000 steps (0.6 ms: the
    pulse through the chain and off the wall)."""
    w = pack(s)
    p = w.n_slots
    a = np.zeros(p)
    g = np.zeros(p + 1)
    K.forces_general(w.u, w.v, w.kappa, w.damping, w.d0, w.de, w.dx0, w.rsum, s.law, g, w.dyield, w.dmax, w.dres,
                     w.kres)
    K.accelerations(g, w.fext, w.inv_mass, a)
    for i in range(p):
        w.v[i] += 0.5e-8 * a[i]
        w.u[i] += 1e-8 * w.v[i]
    return w, a, g, np.zeros(60_000)


@pytest.mark.parametrize("law", [hc.Viscoelastic(A=2e-6), hc.Dashpot(gamma=20.0)], ids=["viscoelastic", "dashpot"])
@pytest.mark.parametrize("precompression", [0.0, 20.0])
def test_fused_step_is_the_general_path(law, precompression):
    model = hc.Model(hc.Chain.from_diameters(np.r_[np.full(12, 26e-3), np.geomspace(26e-3, 14e-3, 9)]),
                     hc.Striker(8e-3, 1.0), law=law, precompression=precompression)
    s = model.system()
    runs = []
    for fused in (False, True):
        w, a, g, powers = _block_start(s)
        p = w.n_slots
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


@njit
def _fused_offset(u, v, a, g, e, kappa, damping, d0, de, dx0, rsum, fext, inv_mass, law, dt, n_steps, powers):
    half = 0.5 * dt
    for s in range(n_steps):
        last = s == n_steps - 1
        if law == K.LAW_ELASTIC:
            FU.step_offset_elastic(u, v, a, g, e, kappa, d0, de, dx0, rsum, fext, inv_mass, dt, half, last)
        else:
            powers[s] = FU.step_offset_dissipative(u, v, a, g, e, kappa, damping, d0, de, dx0, rsum, fext, inv_mass,
                                                   law, dt, half, last)


#: Offsets [m] of a tapered chain's beads: misaligned pairs, an aligned pair (beads 8 and 9 share
#: an offset) and an aligned end (the last bead on the axis, then the wall).
OFFSETS = {1: 2e-5, 2: -1e-5, 4: 3e-5, 5: 1e-5, 8: -2e-5, 9: -2e-5, 13: 1.5e-5}


@pytest.mark.parametrize("law", [None, hc.Viscoelastic(A=2e-6), hc.Dashpot(gamma=20.0)],
                         ids=["elastic", "viscoelastic", "dashpot"])
@pytest.mark.parametrize("wall", ["flat", "none"])
def test_fused_offset_step_is_the_general_path(law, wall):
    chain = hc.Chain.from_diameters(np.r_[np.full(12, 26e-3), np.geomspace(26e-3, 14e-3, 9)]).with_offsets(OFFSETS)
    kw = {} if law is None else {"law": law}
    s = hc.Model(chain, hc.Striker(8e-3, 1.0), wall=hc.Wall(wall), **kw).system()
    assert s.misaligned and np.any(s.de == 0.0) and np.any(s.de != 0.0)
    runs = []
    for fused in (False, True):
        w, a, g, powers = _block_start(s)
        p = w.n_slots
        e = np.zeros(p)
        if fused:
            _fused_offset(w.u, w.v, a, g, e, w.kappa, w.damping, w.d0, w.de, w.dx0, w.rsum, w.fext, w.inv_mass, s.law,
                          1e-8, powers.size, powers)
        else:
            _general(w.u, w.v, a, g, np.zeros(p + 1), w.kappa, w.damping, w.d0, w.de, w.dx0, w.rsum, w.fext,
                     w.inv_mass, s.law, w.dyield, w.dmax, w.dres, w.kres, 1e-8, powers.size, powers)
        runs.append((w, a, g, e, powers))
    (wg, ag, gg, _, pg), (wf, af, gf, ef, pf) = runs
    for name, x, y in (("u", wg.u, wf.u), ("v", wg.v, wf.v), ("a", ag, af), ("g", gg, gf)):
        assert np.array_equal(x, y), name
    assert np.max(gg) > 1.0  # forces acted
    if law is not None:
        assert np.max(pg) > 0.0  # energy was dissipated
        assert np.abs(pg - pf).max() <= POWER_REL * np.abs(pg).max()
    # the probes' energies from the contact energies the last step stored
    ke, pe = FU.energies_offset(wf.u, wf.v, wf.mass, wf.fext, ef)
    pe_ref = K.potential_energy(wf.u, gf, wf.kappa, wf.d0, wf.de, wf.dx0, wf.rsum, wf.fext, False)
    assert ke == pytest.approx(K.kinetic_energy(wf.v, wf.mass), rel=1e-14)
    assert pe == pytest.approx(pe_ref, rel=1e-13, abs=1e-14 * ke)


def test_simulate_uses_the_fused_steps_for_misaligned_chains():
    """A misaligned run agrees with DOP853 (the fused steps are the general path's arithmetic) and
    its energy balance holds at every sample (the probes read the energies the steps stored)."""
    chain = hc.Chain.uniform(10, 20e-3).with_offsets({3: 2e-4, 4: -1e-4, 7: 3e-4})
    for law in (None, hc.Viscoelastic(A=2e-6)):
        model = hc.Model(chain, hc.Striker(8e-3, 0.3), **({} if law is None else {"law": law}))
        ds = hc.simulate(model, 1e-3)
        ref = hc.simulate(model, 1e-3, integrator="dop853", rtol=1e-11)
        assert ds.attrs["peak_wall_force"] == pytest.approx(ref.attrs["peak_wall_force"], rel=1e-5)
        total = ds.kinetic_energy.values + ds.potential_energy.values + ds.dissipated_energy.values
        assert np.abs(total - total[0]).max() < 1e-4 * total[0]
        assert ds.potential_energy.values.max() > 0.1 * total[0]  # the contacts stored energy


@pytest.mark.parametrize("fused_first", [True, False], ids=["fused-first", "two-pass"])
@pytest.mark.parametrize("A", [0.0, 2e-6], ids=["plain", "damped"])
def test_vectorised_plastic_pass_is_the_general_path(A, fused_first):
    """kernels.plastic_block's branch-free pass (the unloading curve for every contact, the yield
    branch redone only for the contacts loaded past dmax and dyield) gives the general path's
    positions, velocities, forces and elastic-plastic state bit for bit over a pulse that yields
    contacts (a bead-sized striker at 3 m/s, well above the yield velocity) and separates them; the viscous power
    within the documented bound. So do its fused steps (plastic.plastic_step, tried first on a block
    after one without yield, ``fused_first``), with the blocks in which a contact yields stepped
    again from the checkpoint: both cases happen in the run (else every block takes the two passes)."""
    model = hc.Model(hc.Chain.from_diameters(np.r_[np.full(12, 26e-3), np.geomspace(26e-3, 14e-3, 9)]),
                     hc.Striker(26e-3, 3.0), law=hc.Elastoplastic(A=A))
    s = model.system()
    runs = []
    for vector in (False, True):
        w, a, g, powers = _block_start(s)
        p = w.n_slots
        vp = np.zeros(p + 1)
        if vector:
            acc = np.zeros(8)
            ck = np.zeros((K.CHECKPOINT_ROWS, max(p + 1, K.CHECKPOINT_MIN_COLUMNS)))
            outcomes = set()
            for k in range(powers.size // 100):  # blocks of 100 steps, the last one's closing half kick
                if k > 0:
                    open_block(w.u, w.v, a, 1e-8, 0.5e-8)
                if not fused_first:
                    ck[4, 10] = 1.0  # as after a block with a yielding contact: the two passes
                tried = ck[4, 10] == 0.0
                K.plastic_block(w.u, w.v, vp, a, g, np.zeros(p), w.kappa, w.damping, w.d0, w.de, w.dx0, w.rsum, w.fext,
                                w.inv_mass, w.dyield, w.dmax, w.dres, w.kres, True, 100, 1e-8, 0.0, 0, np.zeros(8), acc,
                                ck)
                outcomes.add((tried, ck[4, 10] == 0.0))
                powers[k] = acc[1]
            if fused_first:
                assert {(True, True), (True, False)} <= outcomes  # fused blocks, and fused blocks stepped again
        else:
            for k in range(powers.size // 100):
                if k > 0:
                    open_block(w.u, w.v, a, 1e-8, 0.5e-8)
                _general(w.u, w.v, a, g, vp, w.kappa, w.damping, w.d0, w.de, w.dx0, w.rsum, w.fext, w.inv_mass,
                         s.law, w.dyield, w.dmax, w.dres, w.kres, 1e-8, 100, powers[100 * k:100 * k + 100])
                powers[k] = powers[100 * k + 99]
        runs.append((w.u, w.v, a, g, w.dmax, w.dres, w.kres, powers[:powers.size // 100]))
    general, vector = runs
    for name, x, y in zip(("u", "v", "a", "g", "dmax", "dres", "kres"), general, vector):
        assert np.array_equal(x, y), name
    assert np.sum(general[4] > w.dyield) >= 5  # contacts yielded
    assert np.max(general[3]) > 1.0
    if A > 0.0:
        assert np.max(general[-1]) > 0.0
        assert np.abs(general[-1] - vector[-1]).max() <= POWER_REL * np.abs(general[-1]).max()
