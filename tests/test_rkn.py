"""The fourth-order integrator ``"rkn4"``: convergence order (two-body impact, paper chain 1),
agreement with DOP853, interpolated probes that do not depend on the sample interval, chunking,
conservation, and what it refuses."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.errors import ElasticLimitWarning, PulseNotReachedWarning
from hertzchain.integrate.drivers.rkn import RKN_RTOL, run_rkn

REF_RTOL = 1e-12


def _quiet():
    warnings.simplefilter("ignore", ElasticLimitWarning)
    warnings.simplefilter("ignore", PulseNotReachedWarning)  # runs cut before the wall, on purpose


def _order(steps, errors) -> float:
    """Slope of log(error) against log(steps), negated: error ~ steps^(-order)."""
    return -float(np.polyfit(np.log(steps), np.log(errors), 1)[0])


@pytest.fixture(scope="module")
def chain1():
    return hc.Model(hc.paper_chain("chain1"), hc.Striker(8e-3, 0.5), hc.Wall("flat"))


def test_two_body_impact_converges_with_order_4():
    """Striker on one free bead (Johnson 11.3): the rebound velocity is (m1 - m2) / (m1 + m2) v.

    The contact's force is not smooth where it closes and opens (its second derivative is
    infinite there); the contact-aware step shrinks there, and the error falls as steps^-4."""
    v = 0.2
    model = hc.Model(hc.Chain.uniform(1, 26e-3), hc.Striker(8e-3, v), hc.Wall("none"))
    s = model.system()
    m1, m2 = s.mass[0], s.mass[1]
    mu = 1 / (1 / m1 + 1 / m2)
    dm = (5 * mu * v**2 / (4 * s.kappa[0])) ** 0.4
    duration = 1.6 * 2.9432 * dm / v  # contact time 2.9432 delta_m / v, then apart
    exact = (m1 - m2) / (m1 + m2) * v
    steps, errors = [], []
    for rtol in (1e-5, 1e-6, 1e-7, 1e-8, 1e-9):
        run = run_rkn(s, duration, duration / 50, rtol=rtol, record_velocities=True)
        steps.append(run.n_steps)
        errors.append(abs(run.velocity[-1, 0] / exact - 1))
    assert errors[-1] < 1e-10
    assert _order(steps, errors) > 3.5
    # the closed form's peak force, at half the contact time (a sample lands there: the force is
    # interpolated between steps ~100x longer than the sample interval)
    half = 0.5 * 2.9432752 * dm / v  # Johnson's 2 int_0^1 dx / sqrt(1 - x^(5/2)) (tests/test_two_body.py)
    run = run_rkn(s, 2 * half, half / 1000)
    assert run.max_force[0] == pytest.approx(s.kappa[0] * dm**1.5, rel=1e-9)
    assert run.contact_force[1000, 0] == run.max_force[0]


def test_chain1_converges_with_order_4(chain1):
    """Paper chain 1: velocities of every body against a much finer run. Contacts close and open
    all along the run (the striker's rebound, gaps behind the pulse); with the steps that follow
    them the measured order is
    ~4 (a fixed step gives ~2, erratically: benchmarks/time_to_accuracy.py)."""
    s = chain1.system()
    ref = run_rkn(s, 2.5e-3, 1e-6, rtol=1e-13, record_velocities=True)
    steps, errors = [], []
    for rtol in (1e-6, 1e-7, 1e-8, 1e-9):
        run = run_rkn(s, 2.5e-3, 1e-6, rtol=rtol, record_velocities=True)
        steps.append(run.n_steps)
        errors.append(np.abs(run.velocity - ref.velocity).max())
    assert _order(steps, errors) > 3.5
    assert errors[-1] < 1e-9 * 0.5


@pytest.mark.parametrize("name,velocity,precompression", [("chain1", 0.5, 0.0), ("chain2", 1.0, 0.0),
                                                          ("chain1", 0.2, 20.0)])
def test_agrees_with_dop853(name, velocity, precompression):
    _quiet()
    model = hc.Model(hc.paper_chain(name), hc.Striker(8e-3, velocity), precompression=precompression)
    ref = hc.simulate(model, 3e-3, integrator="dop853", rtol=REF_RTOL)
    ds = hc.simulate(model, 3e-3, integrator="rkn4")
    assert ds.attrs["integrator"] == "rkn4" and ds.attrs["time_step"] == "adaptive"
    assert ref.attrs["peak_wall_force"] > 1.0
    assert ds.attrs["peak_wall_force"] == pytest.approx(ref.attrs["peak_wall_force"], rel=1e-7, abs=0)
    assert ds.attrs["peak_wall_time"] == pytest.approx(ref.attrs["peak_wall_time"], rel=1e-7, abs=0)
    # every sampled force, interpolated between steps ~20x longer than the sample interval
    scale = float(ref.contact_force.max())
    assert np.abs(ds.contact_force.values - ref.contact_force.values).max() < 1e-6 * scale
    assert np.abs(ds.max_contact_force.values - ref.max_contact_force.values).max() < 1e-6 * scale
    assert ds.attrs["dt_max"] > 10 * ds.attrs["sample_interval"]
    e = (ds.kinetic_energy + ds.potential_energy).values
    assert np.abs(e / e[0] - 1).max() < 1e-8


def test_velocities_and_positions_are_interpolated_accurately(chain1):
    _quiet()
    probes = hc.Probes(sample_interval=1e-6, velocities=True, positions=True)
    ref = hc.simulate(chain1, 1.5e-3, probes, integrator="dop853", rtol=REF_RTOL)
    ds = hc.simulate(chain1, 1.5e-3, probes, integrator="rkn4")
    assert np.abs(ds.velocity.values - ref.velocity.values).max() < 1e-6 * 0.5
    assert np.abs(ds.displacement.values - ref.displacement.values).max() < 1e-6 * np.abs(
        ref.displacement.values).max()


def test_steps_do_not_depend_on_the_sample_interval(chain1):
    """The step never lands on sample times: the run is the same whatever is recorded, and so is
    its peak (refined on the wall contact's own interpolant)."""
    s = chain1.system()
    runs = [run_rkn(s, 2e-3, interval) for interval in (1e-8, 1e-7, 2e-3)]
    assert len({r.n_steps for r in runs}) == 1
    assert len({(r.peak_wall_force, r.peak_wall_time, r.dt, r.dt_max) for r in runs}) == 1
    # the coarse record's samples are the fine record's (every 10th / 200,000th), to rounding
    fine, mid = runs[0], runs[1]
    np.testing.assert_allclose(fine.contact_force[::10], mid.contact_force, rtol=0, atol=1e-9)


def test_chunked_run_is_bit_identical(chain1):
    s = chain1.system()
    one = run_rkn(s, 1e-3, 1e-7)
    many = run_rkn(s, 1e-3, 1e-7, chunk_steps=7)  # a compiled call every sample
    for name in ("contact_force", "kinetic_energy", "potential_energy", "max_force"):
        assert np.array_equal(getattr(one, name), getattr(many, name)), name
    assert (one.peak_wall_force, one.n_steps, one.dt, one.dt_max) == (many.peak_wall_force, many.n_steps, many.dt,
                                                                      many.dt_max)


def test_momentum_conserved_without_wall():
    """Internal forces in equal and opposite pairs: every kick conserves the total momentum."""
    model = hc.Model(hc.Chain.uniform(10, 20e-3), hc.Striker(8e-3, 0.3), hc.Wall("none"))
    s = model.system()
    run = run_rkn(s, 5e-4, 1e-5, record_velocities=True)
    p = run.velocity @ s.mass[: s.n_beads + 1]
    assert np.abs(p / p[0] - 1).max() < 1e-13


def test_fixed_step(chain1):
    _quiet()
    ds = hc.simulate(chain1, 1e-3, integrator="rkn4", dt=2e-7)
    assert ds.attrs["time_step"] == "fixed" and ds.attrs["dt"] == ds.attrs["dt_max"] == 2e-7
    assert ds.attrs["n_steps"] == 5000
    with pytest.raises(hc.ConfigError, match="run.dt"):
        hc.simulate(chain1, 1e-3, integrator="rkn4", dt=1e-5)


def test_refuses_the_elastoplastic_law_bodies_and_bad_rtol():
    """Kuwabara-Kono, the dashpot and offsets run (tests/test_rkn_dissipative.py), the elastic-plastic
    and registry laws too (tests/test_rkn_laws.py); a protected body is refused naming run.integrator."""
    for model in (hc.Model(hc.Chain.uniform(5, 10e-3), hc.Striker(8e-3, 0.2), hc.Wall("body", mass=0.5, stiffness=1e6)),):
        with pytest.raises(hc.ConfigError, match="run.integrator"):
            hc.simulate(model, 1e-4, integrator="rkn4")
    model = hc.Model(hc.Chain.uniform(5, 10e-3), hc.Striker(8e-3, 0.2))
    with pytest.raises(hc.ConfigError, match="run.rtol"):
        hc.simulate(model, 1e-4, integrator="rkn4", rtol=-1.0)


def test_config_key_runs_rkn4(tmp_path):
    from hertzchain.config import load_config
    from hertzchain.config.build import simulate_config

    path = tmp_path / "run.toml"
    path.write_text('[chain]\ndiameters_mm = [26, 26, 26, 20]\n[striker]\ndiameter_mm = 8\nvelocity = 0.2\n'
                    '[run]\nduration = 5e-4\nintegrator = "rkn4"\n')
    ds = simulate_config(load_config(path))
    assert ds.attrs["integrator"] == "rkn4"
    model = hc.Model(hc.Chain.from_diameters(np.array([26.0, 26, 26, 20]) * 1e-3), hc.Striker(8e-3, 0.2))
    ref = hc.simulate(model, 5e-4, integrator="rkn4", rtol=RKN_RTOL)
    assert ds.attrs["peak_wall_force"] == ref.attrs["peak_wall_force"] > 0
