"""``"rkn4"`` on the registry's generated laws and the elastic-plastic law
(:mod:`hertzchain.integrate.drivers.rkn_laws`): convergence order 4 on a two-body impact and on
the paper's chain 1 for the power law (n = 1.5 and 2), Hunt-Crossley and Thornton's law; the
power law against DOP853 (an independent integrator on the same forces) and against the elastic
law; the elastic-plastic law against the Verlet at a small step (peak wall force, residual
overlaps, plastic work); Hunt-Crossley's restitution; the energy balance."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.integrate.drivers.rkn import run_rkn

PROBES = hc.Probes(sample_interval=1e-6, contacts=())
# (the power law at n = 3/2 without stiffness is the elastic law, which rkn4 runs with the elastic
# law's own engine: laws.hertz_equivalent; n = 1.7 takes the registry laws' method)
LAWS = {"power 1.7": (hc.PowerLaw(1.7, 2e11), 0.2), "power 2": (hc.PowerLaw(2.0, 2e9), 0.2),
        "hunt_crossley": (hc.HuntCrossley(0.7), 0.2), "elastoplastic": (hc.Elastoplastic(), 2.0)}
CHAIN5 = hc.Chain.from_diameters(np.random.default_rng(4).uniform(10e-3, 26e-3, size=5))


def _quiet(fn, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*args, **kwargs)


def _order(steps, errors) -> float:
    """Slope of log(error) against log(steps), negated: error ~ steps^(-order)."""
    return -float(np.polyfit(np.log(steps), np.log(errors), 1)[0])


@pytest.mark.parametrize("name", list(LAWS))
def test_two_body_impact_converges_with_order_4(name):
    """Both bodies' velocities after the impact (the contact closed, loaded, unloaded and opened,
    every branch change landed on) against the same integrator at rtol 1e-12: the error follows
    rtol (the local bound eps per step, a few steps around the impact carrying it: within 10x of
    rtol times the speed), and against the steps for rtol 1e-6 ... 1e-9 it falls with an order
    between 4 (errors accumulating over the steps) and 5.7 (the local error eps ~ h^5): a fourth-order method, no order lost at the contact's events."""
    law, v = LAWS[name]
    s = hc.Model(hc.Chain.uniform(1, 26e-3), hc.Striker(8e-3, v), hc.Wall("none"), law=law).system()
    duration = 2e-4
    ref = _quiet(run_rkn, s, duration, duration, rtol=1e-12, record_velocities=True)
    assert ref.integrator == "rkn4"
    steps, errors = [], []
    for rtol in (1e-6, 1e-7, 1e-8, 1e-9):
        run = _quiet(run_rkn, s, duration, duration, rtol=rtol, record_velocities=True)
        steps.append(run.n_steps)
        errors.append(float(np.abs(run.velocity[-1, :2] - ref.velocity[-1, :2]).max()) / v)
        assert errors[-1] < 10 * rtol
    assert 3.7 < _order(steps, errors) < 5.7


def test_power_law_against_dop853_and_the_elastic_law():
    """A stateless registry law: rkn4 at its default rtol within 1e-6 of DOP853 at rtol 1e-12 on
    the same forces; n = 3/2 without stiffness is the elastic law, within 1e-6 of the elastic law's
    rkn4 (its symplectic method and step control: not the same steps)."""
    model = hc.Model(CHAIN5, hc.Striker(8e-3, 0.2), law=hc.PowerLaw(2.0, 1e13))
    auto = _quiet(hc.simulate, model, 4e-4, PROBES, integrator="rkn4")
    ref = _quiet(hc.simulate, model, 4e-4, PROBES, integrator="dop853", rtol=1e-12)
    assert auto.attrs["integrator_used"] == "rkn4"
    assert ref.attrs["peak_wall_force"] > 1.0
    assert abs(auto.attrs["peak_wall_force"] / ref.attrs["peak_wall_force"] - 1) < 1e-6
    p15 = _quiet(hc.simulate, hc.Model(CHAIN5, hc.Striker(8e-3, 0.2), law=hc.PowerLaw(1.5)), 4e-4, PROBES,
                 integrator="rkn4")
    el = _quiet(hc.simulate, hc.Model(CHAIN5, hc.Striker(8e-3, 0.2)), 4e-4, PROBES)
    assert p15.attrs["integrator_used"] == el.attrs["integrator_used"] == "rkn4"
    assert abs(p15.attrs["peak_wall_force"] / el.attrs["peak_wall_force"] - 1) < 1e-6


def test_elastoplastic_against_the_verlet_at_a_small_step():
    """Thornton's law at 2 m/s (every contact yields): rkn4 at its default rtol against the Verlet at a
    2 ns step (its error ~1e-8 here): peak wall force, every residual overlap and the plastic work
    within 1e-6 (measured ~1e-8); KE + PE + viscous + plastic work = the striker's energy within
    1e-6 (measured 2e-8)."""
    model = hc.Model(CHAIN5, hc.Striker(8e-3, 2.0), law=hc.Elastoplastic())
    r = _quiet(hc.simulate, model, 4e-4, PROBES, integrator="rkn4")
    v = _quiet(hc.simulate, model, 4e-4, PROBES, integrator="verlet", dt=2e-9)
    assert r.attrs["integrator_used"] == "rkn4"
    assert abs(r.attrs["peak_wall_force"] / v.attrs["peak_wall_force"] - 1) < 1e-6
    assert float(v["plastic_work"][-1]) > 1e-2 * float(v["kinetic_energy"][0])
    assert abs(float(r["plastic_work"][-1]) / float(v["plastic_work"][-1]) - 1) < 1e-6
    res, res_v = r["residual_overlap"].values, v["residual_overlap"].values
    assert res_v.max() > 0
    np.testing.assert_allclose(res, res_v, rtol=0, atol=1e-6 * res_v.max())
    total = r["kinetic_energy"] + r["potential_energy"] + r["dissipated_energy"] + r["plastic_work"]
    assert float(np.max(np.abs(total - total[0]))) < 1e-6 * float(total[0])


def test_hunt_crossley_restitution_and_energy_balance():
    """Hunt-Crossley's two-body restitution is the e the law is given, short by at most the
    documented 0.03 for e >= 0.5 and never above it; a chain run on rkn4 keeps KE + PE + dissipated
    the striker's energy within 1e-6 (measured 7e-8)."""
    for e in (0.5, 0.9):
        got = _quiet(hc.restitution, 0.3, hc.HuntCrossley(e), 0.02, "AISI52100", 0.02, "AISI52100")
        assert e - 0.03 < got <= e + 1e-9
    r = _quiet(hc.simulate, hc.Model(CHAIN5, hc.Striker(8e-3, 0.2), law=hc.HuntCrossley(0.7)), 4e-4, PROBES,
               integrator="rkn4")
    assert r.attrs["integrator_used"] == "rkn4"
    total = r["kinetic_energy"] + r["potential_energy"] + r["dissipated_energy"]
    assert float(r["dissipated_energy"][-1]) > 0.05 * float(total[0])
    assert float(np.max(np.abs(total - total[0]))) < 1e-6 * float(total[0])


@pytest.fixture(scope="module")
def chain1():
    from pathlib import Path

    from hertzchain.config.build import build_model
    from hertzchain.config.loading import read_toml
    from hertzchain.config.schema import parse_config

    cfg = parse_config(read_toml(Path(__file__).resolve().parents[1] / "examples" / "chain1.toml"))
    return build_model(cfg)


@pytest.mark.slow
@pytest.mark.parametrize("name", list(LAWS))
def test_chain1_converges_with_order_4(chain1, name):
    """The paper's chain 1 with each law (the elastic-plastic one at 2 m/s): every body's velocity
    at every microsecond of 1 ms against rtol 1e-11; the error for rtol 1e-6 ... 1e-9 (where the
    accuracy, not the stability bound, sets the steps: at 1e-5 Hunt-Crossley took 302 steps, at
    1e-6 334) falls with order 4 (3.5 to 5.7; Hunt-Crossley measured 4.2 on 1e-6 ... 1e-8)."""
    law, v = LAWS[name]
    s = hc.Model(chain1.chain, hc.Striker(chain1.striker.diameter, v), chain1.wall, law=law).system()
    ref = _quiet(run_rkn, s, 1e-3, 1e-6, rtol=1e-11, record_velocities=True)
    steps, errors = [], []
    for rtol in (1e-6, 1e-7, 1e-8, 1e-9):
        run = _quiet(run_rkn, s, 1e-3, 1e-6, rtol=rtol, record_velocities=True)
        steps.append(run.n_steps)
        errors.append(float(np.abs(run.velocity - ref.velocity).max()) / v)
        assert errors[-1] < rtol  # the global error follows rtol (measured 0.03 ... 0.2 rtol)
    assert 3.5 < _order(steps, errors) < 5.7


@pytest.mark.parametrize("law", [hc.Dashpot(gamma=8.0), hc.HuntCrossley(0.7)], ids=["damped", "registry"])
def test_peak_wall_force_is_the_run_s_own_when_it_ends_on_the_rise(law):
    """A run that ends while the wall force still rises (both rkn4 kernels: the damped laws' and the
    registry laws'): its peak is the force at its last sample, at its end, never a value the last
    step (which may pass the end) reached after it."""
    model = hc.Model(CHAIN5, hc.Striker(8e-3, 0.2), law=law)
    probes = hc.Probes(sample_interval=1e-6)
    full = _quiet(hc.simulate, model, 4e-4, probes, integrator="rkn4")
    t_peak = float(full.attrs["peak_wall_time"])
    duration = round(0.97 * t_peak * 1e6) * 1e-6  # on the rise, a sample at the end
    cut = _quiet(hc.simulate, model, duration, probes, integrator="rkn4")
    wall = cut["wall_force"].values
    assert 0 < wall[-2] < wall[-1] < float(full.attrs["peak_wall_force"])
    assert float(cut.attrs["peak_wall_time"]) <= duration * (1 + 1e-12)
    assert float(cut.attrs["peak_wall_force"]) == pytest.approx(wall[-1], rel=1e-9, abs=0)
