"""Conservation laws of the elastic chain (docs/validation.rst)."""

from __future__ import annotations

import numpy as np
import pytest

import hertzchain as hc


def test_energy_drift_below_1e6_at_default_step(gentle_contract_model):
    ds = hc.simulate(gentle_contract_model, 2.5e-3)
    e = (ds.kinetic_energy + ds.potential_energy).values
    drift = np.abs(e / e[0] - 1).max()
    assert drift < 1e-6
    assert ds.dissipated_energy.values.max() == 0.0


def test_energy_error_shrinks_as_dt_squared(gentle_contract_model):
    # Verlet's energy error is bounded and O(dt^2): halving dt divides it by ~4.
    errs = []
    for dt in (2e-8, 1e-8):
        ds = hc.simulate(gentle_contract_model, 2e-3, dt=dt)
        e = (ds.kinetic_energy + ds.potential_energy).values
        errs.append(np.abs(e / e[0] - 1).max())
    assert errs[0] / errs[1] == pytest.approx(4.0, rel=0.15)


def test_momentum_conserved_without_wall():
    chain = hc.paper_chain("chain2")
    model = hc.Model(chain, hc.Striker(8e-3, 0.3), hc.Wall("none"))
    ds = hc.simulate(model, 2.5e-3, hc.Probes(velocities=True))
    masses = model.system().mass[: chain.n_beads + 1]
    p = ds.velocity.values @ masses
    # Contact forces cancel pairwise in every kick: momentum is conserved to round-off.
    assert np.abs(p / p[0] - 1).max() < 1e-12


def test_momentum_reverses_at_wall():
    # With a wall the chain's momentum is not conserved: the wall pushes it back.
    chain = hc.Chain.uniform(5, 26e-3)
    model = hc.Model(chain, hc.Striker(26e-3, 0.1), hc.Wall("flat"))
    ds = hc.simulate(model, 1.5e-3, hc.Probes(velocities=True))
    p = ds.velocity.values @ model.system().mass[:6]
    assert p[-1] < -0.5 * p[0]
    # and the impulse the wall gave equals the change of momentum
    impulse = np.trapezoid(ds.wall_force.values, ds.time.values)
    assert p[0] - p[-1] == pytest.approx(impulse, rel=1e-4)
