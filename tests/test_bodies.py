"""What a protector protects and what hits it: the protected body behind the wall, strikers of any
mass and face, gravity along the chain and its static state."""

from __future__ import annotations

import math

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.runs.batch import simulate_batch, simulate_many
from hertzchain.integrate.drivers.reference import run_reference
from hertzchain.integrate.drivers.verlet import run_verlet

from conftest import assert_same_run

CHAIN = hc.Chain.uniform(8, 26e-3)


# ------------------------------------------------------------------ the protected body
def test_huge_stiff_body_is_the_immovable_wall():
    """A body of 1e6 kg on a 1e15 N/m mount barely moves (its displacement ~ 1e-13 m against
    overlaps of ~1e-6 m): the wall force is the rigid wall's to 1e-6."""
    model = hc.Model(CHAIN, hc.Striker(8e-3, 0.2))
    rigid = hc.simulate(model, 1e-3, integrator="verlet")  # the engine the body runs on
    body = hc.simulate(hc.Model(CHAIN, hc.Striker(8e-3, 0.2), hc.Wall("body", mass=1e6, stiffness=1e15)), 1e-3)
    peak = rigid.attrs["peak_wall_force"]
    assert peak > 1.0
    assert body.attrs["peak_wall_force"] == pytest.approx(peak, rel=1e-6)
    assert np.max(np.abs(body.wall_force.values - rigid.wall_force.values)) < 1e-6 * peak
    # the body's mount passes on what it is pushed with, at most twice (a stiff spring rings)
    assert 0 < body.attrs["peak_body_force"] < 2.01 * peak


@pytest.mark.parametrize("mass, stiffness", [(1.0, 1e6), (0.5, 2e6), (1.0, 1e4)])
def test_automatic_duration_holds_the_mounts_peak(mass, stiffness):
    """The force a mount passes to the ground peaks as the body swings, after the pulse: the
    automatic duration runs half the mount's period pi sqrt(M/k) past the pulse's own (at most
    25 ms in all), so the automatic run's peak body force is that of a run long enough to see
    the body turn back (1 kg on 1e6 N/m behind chain 1: 1.444 N at 4.4 ms, where the pulse alone
    would stop the record at 3.6 ms and report 1.142 N). A slow mount (1 kg on 1e4 N/m, half
    period 31 ms) is cut at 25 ms and the record says so by its length."""
    from hertzchain.bodies import MAX_BODY_DURATION, mount_half_period

    body = hc.Wall("body", mass=mass, stiffness=stiffness)
    model = hc.Model(hc.paper_chain("chain1"), hc.Striker(8e-3, 0.2), body)
    pulse_only = hc.auto_duration(hc.Model(hc.paper_chain("chain1"), hc.Striker(8e-3, 0.2)))
    half = mount_half_period(mass, stiffness)
    assert half == pytest.approx(math.pi * math.sqrt(mass / stiffness), rel=1e-15)
    auto = hc.auto_duration(model)
    assert auto == pytest.approx(min(pulse_only + half, MAX_BODY_DURATION), rel=1e-12)
    if pulse_only + half > MAX_BODY_DURATION:
        return
    probes = hc.Probes(1e-6)
    short = hc.simulate(model, "auto", probes)
    long = hc.simulate(model, pulse_only + 3 * half, probes)
    assert int(np.argmax(short.body_force.values)) < short.time.size - 10  # a peak, not the record's end
    assert short.attrs["peak_body_force"] == pytest.approx(long.attrs["peak_body_force"], rel=1e-9)
    # a free body (no mount) has nothing to swing back: the pulse's duration
    assert hc.auto_duration(hc.Model(hc.paper_chain("chain1"), hc.Striker(8e-3, 0.2), hc.Wall("body", mass=1.0))) \
        == pulse_only


def test_free_body_conserves_momentum_and_energy():
    """Stiffness 0: nothing holds the system, so the striker's momentum ends up shared by beads and
    body to 1e-9 and the energy stays constant to 1e-6; in the end the body carries it away."""
    model = hc.Model(CHAIN, hc.Striker(26e-3, 0.2), hc.Wall("body", mass=0.3))
    ds = hc.simulate(model, 2e-3, hc.Probes(velocities=True))
    s = model.system()
    p = ds.velocity.values @ s.mass[:CHAIN.n_beads + 1] + 0.3 * ds.body_velocity.values
    assert np.max(np.abs(p - p[0])) < 1e-9 * abs(p[0])
    e = (ds.kinetic_energy + ds.potential_energy + ds.dissipated_energy).values
    assert np.max(np.abs(e - e[0])) < 1e-6 * e[0]
    # the work done on the body is its kinetic energy (no mount to store or dissipate any)
    ke_body = 0.5 * 0.3 * ds.body_velocity.values ** 2
    assert np.allclose(ds.body_energy.values, ke_body, rtol=1e-5, atol=1e-9 * e[0])
    assert ds.body_energy.values[-1] > 0.5 * e[0]


def test_mounted_body_balance_and_reference():
    """A damped mount: kinetic + elastic (Hertz, mount spring) + dissipated energy is constant; the
    force to the ground is k x + c v; Verlet agrees with DOP853 on the body's signals."""
    k, c, mass = 1e6, 20.0, 0.5
    model = hc.Model(CHAIN, hc.Striker(8e-3, 0.3), hc.Wall("body", mass=mass, stiffness=k, damping=c))
    ds = hc.simulate(model, 2e-3)
    e = (ds.kinetic_energy + ds.potential_energy + ds.dissipated_energy).values
    assert np.max(np.abs(e - e[0])) < 1e-6 * e[0]
    assert ds.dissipated_energy.values[-1] > 0  # the dashpot took some
    assert np.allclose(ds.body_force.values, k * ds.body_displacement.values + c * ds.body_velocity.values)
    # Newton for the body: M a = F_N - (k x + c v)
    assert np.allclose(mass * ds.body_acceleration.values, ds.wall_force.values - ds.body_force.values,
                       atol=1e-9 * float(ds.wall_force.max()))
    s = model.system()
    ref = run_reference(s, 2e-3, 1e-7, rtol=1e-11)
    ver = run_verlet(s, 2e-3, 1e-7)
    scale = np.abs(ref.body[:, :3]).max(axis=0)
    assert np.max(np.abs(ver.body[:, :3] - ref.body[:, :3]) / scale) < 1e-5
    assert ver.body[-1, 3] == pytest.approx(ref.body[-1, 3], rel=1e-5)


def test_body_in_the_batched_engine_is_bit_identical():
    models = [hc.Model(CHAIN, hc.Striker(8e-3, v), hc.Wall("body", mass=0.5, stiffness=1e6, damping=5.0))
              for v in (0.1, 0.2)] + [hc.Model(CHAIN, hc.Striker(8e-3, 0.2))]
    singles = [hc.simulate(m, 1e-3, integrator="verlet") for m in models]
    for single, other in zip(singles, simulate_many(models, 1e-3)):
        assert_same_run(single, other)
    stacked = simulate_batch(models, 1e-3)
    assert np.array_equal(stacked.body_force.values[0], singles[0].body_force.values)
    assert np.isnan(stacked.peak_body_force.values[2]) and stacked.peak_body_force.values[1] > 0


def test_body_errors_name_the_field():
    with pytest.raises(hc.ConfigError, match="wall.mass"):
        hc.Wall("body")
    with pytest.raises(hc.ConfigError, match="wall.stiffness"):
        hc.Wall("body", mass=1.0, stiffness=-1.0)
    with pytest.raises(hc.ConfigError, match="wall.mass"):
        hc.Wall("flat", mass=1.0)
    with pytest.raises(hc.ConfigError, match="wall.radius_of_curvature_mm"):
        hc.Wall("body", mass=1.0, shape="sphere")
    # a free body cannot hold a static load
    with pytest.raises(hc.ConfigError, match="wall.stiffness"):
        hc.Model(CHAIN, wall=hc.Wall("body", mass=1.0), precompression=5.0)


def test_wall_material_is_the_first_beads():
    """The default wall is of the chain's first material, whatever the last bead is made of: per-bead
    materials as design variables then measure every candidate against the same body."""
    steel_end = hc.Chain.from_diameters([26e-3] * 3, ["AISI52100", "PTFE", "AISI52100"])
    ptfe_end = hc.Chain.from_diameters([26e-3] * 3, ["AISI52100", "AISI52100", "PTFE"])
    for chain in (steel_end, ptfe_end):
        assert hc.Model(chain).wall_material.name == "AISI52100"
    k_ptfe_end = hc.Model(ptfe_end).system().kappa[-1]
    expected = hc.hertz_constant(13e-3, None, "PTFE", "AISI52100")
    assert k_ptfe_end == pytest.approx(expected, rel=1e-12)


def test_spherical_body_face():
    """A body face curved like a 26 mm bead meets bead N like another bead (two equal spheres)."""
    model = hc.Model(CHAIN, wall=hc.Wall("body", mass=1.0, stiffness=1e6, shape="sphere", radius_of_curvature=13e-3))
    s = model.system()
    assert s.kappa[-1] == pytest.approx(s.kappa[3], rel=1e-12)


# ------------------------------------------------------------------ strikers
def test_flat_striker_peak_force_is_sphere_flat_hertz():
    """A flat-faced striker of given mass hitting one free bead: the head-on Hertz impact with the
    sphere-flat constant kappa = (4/3) E* sqrt(R) (1/R' = 0, paper eq. 1): peak force
    kappa delta_m^(3/2), delta_m = (5 mu v^2 / (4 kappa))^(2/5) (Johnson)."""
    bead = hc.Chain.uniform(1, 20e-3)
    v, ms = 0.3, 0.05
    model = hc.Model(bead, hc.Striker(8e-3, v, mass=ms, shape="flat"), hc.Wall("none"))
    steel = hc.get_material("AISI52100")
    e_star = steel.young / (2 * (1 - steel.poisson ** 2))
    kappa = 4 / 3 * e_star * math.sqrt(10e-3)
    s = model.system()
    assert s.kappa[0] == pytest.approx(kappa, rel=1e-12)
    assert s.mass[0] == ms
    m1 = float(bead.masses[0])
    mu = ms * m1 / (ms + m1)
    dm = (5 * mu * v * v / (4 * kappa)) ** 0.4
    ds = hc.simulate(model, 40e-6, hc.Probes(sample_interval=2e-9), steps_per_radian=2000)
    assert float(ds.contact_force.sel(contact=0).max()) == pytest.approx(kappa * dm ** 1.5, rel=1e-5)


def test_curved_striker_face_and_given_mass():
    chain = hc.Chain.uniform(2, 26e-3)
    hammer = hc.Striker(8e-3, 0.2, mass=2.0, radius_of_curvature=13e-3)
    s = hc.Model(chain, hammer).system()
    assert s.mass[0] == 2.0 and s.kappa[0] == pytest.approx(s.kappa[1], rel=1e-12)
    assert hc.Striker(8e-3, 0.2).mass == pytest.approx(7780 * math.pi * 8e-3 ** 3 / 6)
    with pytest.raises(hc.ConfigError, match="striker.radius_of_curvature_mm"):
        hc.Striker(shape="flat", radius_of_curvature=1e-2)
    with pytest.raises(hc.ConfigError, match="striker.mass"):
        hc.Striker(mass=0.0)


# ------------------------------------------------------------------ gravity
def test_vertical_column_is_at_rest():
    """A column of 10 beads standing on the wall under gravity, touched by a striker at 1e-6 m/s (the
    config's smallest speed, as the docs' example):
    no bead moves faster than the striker (a column released with its beads barely touching
    falls onto the wall at ~1e-2 m/s), and every contact starts at the overlap of the weight above
    it, delta_j = (W_j / kappa_j)^(2/3), W_j = (m_s + m_1 + ... + m_j) g (the striker rests on
    bead 1)."""
    g = 9.81
    chain = hc.Chain.uniform(10, 26e-3).append_taper(4, 0.1)
    model = hc.Model(chain, hc.Striker(8e-3, 1e-6), hc.Wall("flat"), gravity=g)
    s = model.system()
    weights = g * np.cumsum(np.concatenate([[model.striker.mass], chain.masses]))
    assert np.allclose(s.d0, (weights / s.kappa) ** (2 / 3), rtol=1e-12)
    assert np.allclose(s.static_forces(), weights, rtol=1e-12)
    ds = hc.simulate(model, 2e-3, hc.Probes(velocities=True))
    assert np.allclose(ds.contact_force.values[0], weights, rtol=1e-9)
    assert np.max(np.abs(ds.velocity.values[:, 1:])) < 1e-6
    # the same column without its static state: released barely touching, it falls
    import dataclasses

    raw = run_verlet(dataclasses.replace(s, d0=np.zeros_like(s.d0)), 2e-3, 1e-7, record_velocities=True)
    assert np.max(np.abs(raw.velocity[:, 1:])) > 1e-3


def test_gravity_on_a_body_and_tilt():
    """The body's mount carries the whole column: k x = (m_s + sum m_n + M) g; a tilted track
    feels g sin(tilt)."""
    g, k, mass = 9.81, 1e6, 0.2
    model = hc.Model(CHAIN, hc.Striker(8e-3, 1e-7), hc.Wall("body", mass=mass, stiffness=k), gravity=g)
    s = model.system()
    total = model.striker.mass + CHAIN.masses.sum() + mass
    assert s.mount_d0 * k == pytest.approx(total * g, rel=1e-12)
    ds = hc.simulate(model, 1e-3)
    assert float(ds.body_force[0]) == pytest.approx(total * g, rel=1e-12)
    assert np.max(np.abs(ds.body_velocity.values)) < 1e-8
    cfg = hc.parse_config({"chain": {"uniform": {"n": 3, "diameter_mm": 20.0}, "tilt_deg": 30.0}})
    assert hc.build_model(cfg).gravity == pytest.approx(9.80665 * 0.5)
    with pytest.raises(hc.ConfigError, match="chain"):
        hc.parse_config({"chain": {"uniform": {"n": 3, "diameter_mm": 20.0}, "tilt_deg": 30.0, "gravity": 1.0}})
    with pytest.raises(hc.ConfigError, match="chain.gravity"):
        hc.Model(CHAIN, wall=hc.Wall("none"), gravity=9.81)


def test_config_keys_build_the_model():
    cfg = hc.parse_config({
        "chain": {"uniform": {"n": 4, "diameter_mm": 26.0}, "gravity": 9.81},
        "striker": {"mass": 0.5, "shape": "flat", "velocity": 0.1},
        "wall": {"type": "body", "mass": 1.0, "stiffness": 1e6, "damping": 2.0},
    })
    model = hc.build_model(cfg)
    assert model.striker.mass == 0.5 and model.striker.shape == "flat"
    assert model.wall.is_body and model.wall.stiffness == 1e6 and model.wall.damping == 2.0
    assert model.gravity == 9.81
    ds = hc.run_config(cfg)
    assert {"body_force", "body_displacement", "wall_force"} <= set(ds.data_vars)
    with pytest.raises(hc.ConfigError, match="wall.mass"):
        hc.run_config({"chain": {"uniform": {"n": 4, "diameter_mm": 26.0}}, "wall": {"type": "body"}})


def test_wall_sensor_as_a_spring_mass():
    """The paper's wall sensor as a cap of a few grams on its 1.9 kN/um stack (Sec. II): the force
    through the stack follows the contact force (the paper neglects the coupling since k_s is much
    larger than the Hertz stiffness) and the instrument measures that force."""
    from hertzchain.instrument import SENSOR_STIFFNESS, Instrument, measure_dataset, sensor_wall

    assert SENSOR_STIFFNESS == 1.9e9
    model = hc.Model(CHAIN, hc.Striker(8e-3, 0.2))
    rigid = hc.simulate(model, 1e-3, integrator="verlet")  # the engine the body runs on
    ds = hc.simulate(hc.Model(CHAIN, hc.Striker(8e-3, 0.2), sensor_wall(3e-3)), 1e-3)
    peak = rigid.attrs["peak_wall_force"]
    assert ds.attrs["peak_wall_force"] == pytest.approx(peak, rel=1e-2)
    assert ds.attrs["peak_body_force"] == pytest.approx(peak, rel=1e-2)
    inst = Instrument(sample_rate=1e6, record_length=200, trigger_level_N=0.5, pretrigger_fraction=0.2, bits=48)
    measured = measure_dataset(ds, wall=inst)
    direct = inst.acquire(ds.time.values, ds.body_force.values)
    assert np.array_equal(measured.measured_wall_force.values, direct.force)


def test_sweep_over_the_mount_reports_the_body(tmp_path):
    """A sweep over wall.stiffness and striker.mass: each member's body peaks in the metrics table,
    equal to the single run's; a softer mount passes less force to the ground."""
    sweep = {"base": {"chain": {"uniform": {"n": 6, "diameter_mm": 20.0}}, "striker": {"velocity": 0.2},
                      "wall": {"type": "body", "mass": 1.0, "stiffness": 1e7},
                      "run": {"duration": 1.5e-3, "sample_interval": 1e-6}},
             "sweep": {"mode": "grid", "chunk_size": 2,
                       "parameters": {"wall.stiffness": [1e6, 1e8], "striker.mass": [2e-3]}}}
    res = hc.run_sweep(sweep, tmp_path)
    df = res.metrics
    assert df["peak_body_force"].iloc[0] < df["peak_body_force"].iloc[1]
    single = hc.simulate(hc.Model(hc.Chain.uniform(6, 20e-3), hc.Striker(velocity=0.2, mass=2e-3),
                                  hc.Wall("body", mass=1.0, stiffness=1e6)), 1.5e-3, hc.Probes(sample_interval=1e-6))
    assert df["peak_body_force"].iloc[0] == pytest.approx(single.attrs["peak_body_force"], rel=1e-12)


def test_body_and_gravity_with_the_elastoplastic_law():
    """The protected body and gravity combine with Thornton's elastoplastic law: kinetic + elastic
    (Hertz and unloading curves, the mount) + viscous + plastic work stays constant to 1e-6 in a hit
    hard enough to yield."""
    model = hc.Model(hc.Chain.uniform(6, 20e-3), hc.Striker(20e-3, 2.0),
                     hc.Wall("body", mass=0.5, stiffness=1e6, damping=3.0), law=hc.Elastoplastic(), gravity=9.81)
    ds = hc.simulate(model, 1e-3)
    e = (ds.kinetic_energy + ds.potential_energy + ds.dissipated_energy + ds.plastic_work).values
    assert ds.attrs["plastic_work"] > 1e-3 * e[0]
    assert np.max(np.abs(e - e[0])) < 1e-6 * e[0]


def test_static_state_past_yield_is_the_same_with_a_body_or_a_wall():
    """Precompression past the elastic limit at a limiting pressure other than Thornton's 1.5 sigma_Y:
    the static overlaps follow the loading line from F_y = F_Y (p_y / 1.5 sigma_Y)^3, whether the
    chain ends on a flat wall (the plain set-up) or on a protected body (the extended one)."""
    soft = hc.Material("soft", 7800.0, 2.0e11, 0.3, 2e8)
    chain = hc.Chain(np.full(4, 10e-3), soft)
    law = hc.Elastoplastic(limiting_pressure_factor=1.2)
    wall = hc.Model(chain, hc.Striker(8e-3, 0.2, material=soft), hc.Wall("flat", material=soft), law=law,
                    precompression=50.0).system()
    body = hc.Model(chain, hc.Striker(8e-3, 0.2, material=soft), hc.Wall("body", mass=1.0, stiffness=1e7,
                                                                             material=soft),
                    law=law, precompression=50.0).system()
    assert 50.0 > wall.yield_force[1] * law.pressure_ratio ** 3  # past yield: the loading line
    np.testing.assert_allclose(body.d0[1:], wall.d0[1:], rtol=1e-12)
