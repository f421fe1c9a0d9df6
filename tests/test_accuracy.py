"""Accuracy of the compiled Verlet: order 2, agreement with scipy DOP853, automatic step."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.errors import ElasticLimitWarning


@pytest.fixture(scope="module")
def dop853_contract(contract_model):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ElasticLimitWarning)
        return hc.simulate(contract_model, 2.5e-3, integrator="dop853", rtol=1e-12)


def test_verlet_converges_with_order_2(gentle_contract_model):
    # Error of the state at a fixed time against a 16x finer run; slope of log(error) vs log(dt).
    dts = np.array([2e-8, 1e-8, 5e-9])  # divide the 100 ns sample interval exactly
    ref = hc.simulate(gentle_contract_model, 1.2e-3, dt=dts[-1] / 16).contact_force.values
    errs = [np.abs(hc.simulate(gentle_contract_model, 1.2e-3, dt=dt).contact_force.values - ref).max() for dt in dts]
    slope = np.polyfit(np.log(dts), np.log(errs), 1)[0]
    assert slope == pytest.approx(2.0, abs=0.1)


def test_verlet_agrees_with_dop853_on_peak_wall_force(contract_model, dop853_contract):
    with pytest.warns(ElasticLimitWarning):
        ds = hc.simulate(contract_model, 2.5e-3)  # automatic step
    ref = dop853_contract
    # The issue asks for 1e-5; the automatic step is designed to deliver 1e-6.
    assert ds.attrs["peak_wall_force"] == pytest.approx(ref.attrs["peak_wall_force"], rel=1e-6, abs=0)
    assert ds.attrs["peak_wall_time"] == pytest.approx(ref.attrs["peak_wall_time"], rel=1e-6, abs=0)
    # Whole signals agree too (relative to the pulse height).
    diff = np.abs(ds.wall_force.values - ref.wall_force.values).max()
    assert diff < 1e-5 * ref.attrs["peak_wall_force"]


@pytest.mark.parametrize("name,velocity", [("chain1", 0.2), ("chain2", 0.1)])
def test_automatic_step_delivers_1e6_on_paper_chains(name, velocity):
    model = hc.Model(hc.paper_chain(name), hc.Striker(8e-3, velocity))
    ds = hc.simulate(model, 3e-3)
    ref = hc.simulate(model, 3e-3, integrator="dop853", rtol=1e-12)
    # The pulse must have reached the wall (a ~0 N "peak" would compare nothing).
    assert ref.attrs["peak_wall_force"] > 1.0
    assert ds.attrs["peak_wall_force"] == pytest.approx(ref.attrs["peak_wall_force"], rel=1e-6, abs=0)


def test_dop853_reference_is_converged(gentle_contract_model):
    # The rtol=1e-12 reference must be far more accurate than the 1e-6 the Verlet is held to:
    # it agrees with a 100x looser run to ~2e-8, so its own error is well below 1e-7.
    a = hc.simulate(gentle_contract_model, 2.5e-3, integrator="dop853", rtol=1e-10)
    b = hc.simulate(gentle_contract_model, 2.5e-3, integrator="dop853", rtol=1e-12)
    assert a.attrs["peak_wall_force"] == pytest.approx(b.attrs["peak_wall_force"], rel=1e-7)


def test_uniform_chain_wall_to_chain_force_ratio():
    # Job et al. 2005 (quoted in the paper, Sec. II): F_wall ~ 1.94 F_chain in a uniform chain.
    model = hc.Model(hc.Chain.uniform(20, 26e-3), hc.Striker(8e-3, 0.2))
    ds = hc.simulate(model, 2.5e-3, hc.Probes(sample_interval=2e-8))
    chain_peak = ds.contact_force.sel(contact=slice(10, 18)).max("time").mean().item()
    assert ds.wall_force.max().item() / chain_peak == pytest.approx(1.94, abs=0.02)


def test_diverging_run_raises(monkeypatch):
    from hertzchain.integrate.drivers import verlet

    # A precompressed chain stepped far beyond Verlet's stability limit (omega dt = 30 > 2) blows
    # up; the user gets an error, not a file of NaNs. The guard that refuses such a dt is lifted.
    model = hc.Model(hc.Chain.uniform(10, 26e-3), hc.Striker(8e-3, 0.1), precompression=50.0)
    dt = 30.0 / model.system().max_frequency()
    monkeypatch.setattr(verlet, "MAX_OMEGA_DT", 100.0)
    with pytest.raises(hc.SimulationDiverged, match="diverged"):
        hc.simulate(model, 1e-2, hc.Probes(sample_interval=dt), dt=dt)


def test_too_large_step_is_refused():
    model = hc.Model(hc.Chain.uniform(10, 26e-3), hc.Striker(8e-3, 0.1))
    with pytest.raises(hc.ConfigError, match="run.dt"):
        hc.simulate(model, 1e-3, hc.Probes(sample_interval=1e-5), dt=1e-5)
