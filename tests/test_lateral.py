"""Lateral freedom (2D path): conservation, a DOP853 reference, the 1D limit, friction."""

from __future__ import annotations

import numpy as np
import pytest

import hertzchain as hc
from conftest import assert_sums_agree
from hertzchain.chain import Chain, paper_chain
from hertzchain.model import Model, Striker, Wall
from hertzchain.runs.track import Track, lateral_arrays, simulate_lateral


def _oblique_pair(law=None) -> Model:
    """8 mm striker at 0.2 m/s on a free 26 mm bead whose centre is 5 mm off the axis."""
    chain = Chain.uniform(1, 26e-3).with_offsets({1: 5e-3})
    return Model(chain, Striker(8e-3, 0.2), Wall("none"), law or hc.Elastic())


def _offset_chain(law) -> Model:
    """Six tapered beads against the wall, bead 3 offset by 10 % of its diameter."""
    chain = Chain.from_diameters(np.array([26, 24, 22, 20, 18, 16]) * 1e-3)
    chain = chain.with_offsets({3: 0.1 * chain.diameters[2]})
    return Model(chain, Striker(8e-3, 0.2), Wall("flat"), law)


def test_two_body_oblique_impact_conserves_momentum_and_energy():
    ds = simulate_lateral(_oblique_pair(), Track(), 2e-4, hc.Probes(1e-6))
    p = ds.momentum.values
    p0 = p[0, 0]
    assert np.max(np.abs(p[:, 0] / p0 - 1)) < 1e-6
    assert np.max(np.abs(p[:, 1])) / p0 < 1e-6
    energy = (ds.kinetic_energy + ds.potential_energy).values
    assert np.max(np.abs(energy / energy[0] - 1)) < 1e-6
    # the impact is oblique: the bead leaves with a transverse velocity, balanced by the striker's
    # (centres at distance R + R' with a 5 mm offset: direction cosine s = 5 / 17)
    assert ds.lateral_kinetic_energy.values[-1] > 0.05 * energy[0]
    y_end = ds.lateral_displacement.values[-1]
    assert y_end[0] * y_end[1] < 0  # pushed apart across the axis


@pytest.mark.parametrize("case", ["pair", "chain"])
def test_verlet_matches_dop853_of_the_same_2d_equations(case):
    if case == "pair":
        model, track, duration = _oblique_pair(), Track(), 2e-4
    else:
        model, track, duration = _offset_chain(hc.Viscoelastic(4.4e-6)), Track(0.02, 20.0, 0.2), 8e-4
    probes = hc.Probes(2e-6)
    a = simulate_lateral(model, track, duration, probes)
    b = simulate_lateral(model, track, duration, probes, integrator="dop853", rtol=1e-12)
    fa, fb = a.contact_force.values, b.contact_force.values
    assert np.max(np.abs(fa - fb)) < 1e-5 * np.max(np.abs(fb))
    ya, yb = a.lateral_displacement.values, b.lateral_displacement.values
    assert np.max(np.abs(ya - yb)) < 1e-5 * np.max(np.abs(yb))
    assert np.max(np.abs(a.lateral_kinetic_energy.values - b.lateral_kinetic_energy.values)) < \
        1e-5 * np.max(b.lateral_kinetic_energy.values)
    if case == "chain":
        assert a.friction_loss.values[-1] == pytest.approx(b.friction_loss.values[-1], rel=1e-5)
        assert a.contact_loss.values[-1] == pytest.approx(b.contact_loss.values[-1], rel=1e-5)


@pytest.mark.parametrize("law", [hc.Elastic(), hc.Viscoelastic(4.4e-6)], ids=["elastic", "viscoelastic"])
def test_zero_offset_repeats_the_1d_engine_bit_for_bit(law):
    model = Model(paper_chain("chain2").truncated(20), Striker(8e-3, 0.2), Wall("flat"), law)
    probes = hc.Probes(1e-6, sensors=(8,))
    one = hc.simulate(model, 2.5e-3, probes, integrator="verlet")  # the lateral path steps the Verlet
    two = simulate_lateral(model, Track(0.02, 5.0, 0.2), 2.5e-3, probes)
    assert one.attrs["peak_wall_force"] > 0  # the pulse reached the wall
    assert np.array_equal(one.contact_force.values, two.contact_force.values)
    assert np.array_equal(one.sensor_force.values, two.sensor_force.values)
    assert one.attrs["n_steps"] == two.attrs["n_steps"]
    assert one.attrs["peak_wall_force"] == two.attrs["peak_wall_force"]
    # Energies are sums over the beads (and, dissipated, over the steps) that each engine's kernel
    # vectorises for the host CPU: equal to a few ulp of the total energy (conftest.assert_sums_agree).
    total = float(one.kinetic_energy[0])
    assert_sums_agree(one.kinetic_energy.values, two.kinetic_energy.values, total, model.chain.n_beads + 1)
    assert_sums_agree(one.dissipated_energy.values, two.dissipated_energy.values, total, one.attrs["n_steps"] * model.chain.n_beads)
    # the 1D potential energy is summed in a vectorised order: equal to rounding
    np.testing.assert_allclose(one.potential_energy.values, two.potential_energy.values, rtol=1e-13, atol=1e-20)
    assert not np.any(two.lateral_displacement.values) and not np.any(two.friction_loss.values)


def test_friction_dissipates_and_never_adds_energy():
    model = _offset_chain(hc.Elastic())
    probes = hc.Probes(1e-6)
    free = simulate_lateral(model, Track(0.02), 1.5e-3, probes)
    rough = simulate_lateral(model, Track(0.02, friction=0.3), 1.5e-3, probes)
    loss = rough.friction_loss.values
    assert np.all(np.diff(loss) >= 0.0) and loss[-1] > 0
    # energy balance: mechanical energy + friction loss is the striker's energy (elastic contacts)
    e0 = float(free.kinetic_energy[0])
    for ds in (free, rough):
        total = (ds.kinetic_energy + ds.potential_energy + ds.dissipated_energy).values
        assert np.max(np.abs(total / e0 - 1)) < 1e-6
    mech = lambda ds: (ds.kinetic_energy + ds.potential_energy).values  # noqa: E731
    assert np.all(mech(rough) <= mech(free) + 1e-6 * e0)
    assert mech(rough)[-1] < mech(free)[-1]
    assert rough.lateral_kinetic_energy.values.max() < free.lateral_kinetic_energy.values.max()


def test_track_restoring_force_from_the_groove_and_the_spring():
    model = _offset_chain(hc.Elastic())
    lat = lateral_arrays(model, Track(groove_radius=0.02, spring=3.0, friction=0.1))
    m = model.chain.masses
    r = model.chain.radii
    np.testing.assert_allclose(lat.stiffness[1:-1], m * 9.81 / (0.02 - r) + 3.0, rtol=1e-12)
    np.testing.assert_allclose(lat.friction[1:-1], 0.1 * m * 9.81, rtol=1e-12)
    assert lat.rest[3] == pytest.approx(2.2e-3) and lat.stiffness[-1] == 0.0
    with pytest.raises(hc.ConfigError):
        lateral_arrays(model, Track(groove_radius=0.01))


def test_a_stiff_track_spring_recovers_the_rigid_1d_offset_model():
    """The 1D model holds the offset bead on its line: the limit of an infinitely stiff spring.
    The difference falls ~1/k (the transverse give of the bead under the pulse)."""
    model = _offset_chain(hc.Elastic())
    probes = hc.Probes(1e-6)
    rigid = hc.simulate(model, 8e-4, probes)
    f1 = rigid.wall_force.values
    errs = []
    for k in (1e8, 1e10):
        ds = simulate_lateral(model, Track(spring=k), 8e-4, probes)
        errs.append(np.max(np.abs(ds.wall_force.values - f1)) / f1.max())
    free = simulate_lateral(model, Track(), 8e-4, probes)
    assert np.max(np.abs(free.wall_force.values - f1)) / f1.max() > 0.01  # free: a different chain
    assert errs[1] < 1e-4 and errs[1] < errs[0] / 30


def test_track_section_of_a_run_config(tmp_path, capsys):
    """``[track]`` in a run file runs the 2D path: the same numbers as simulate_lateral called with
    the Track it describes, the config stored, and field-named errors (exit 2 from the CLI)."""
    from hertzchain.cli.main import main
    from hertzchain.config import parse_config, run_config
    from hertzchain.errors import ConfigError

    data = {"chain": {"diameters_mm": [26.0] * 5, "offsets_mm": [0.0, 0.0, 1.0, 0.0, 0.0]},
            "striker": {"diameter_mm": 8.0, "velocity": 0.25},
            "run": {"duration": 6e-4, "sample_interval": 1e-6},
            "track": {"groove_radius_mm": 15.0, "friction": 0.2}}
    ds = run_config(data)
    mm = 1e-3  # the config's unit conversion (26 mm -> 26 * 1e-3 m, not the literal 26e-3)
    model = Model(Chain([26.0 * mm] * 5, offsets=[0.0, 0.0, 1.0 * mm, 0.0, 0.0]), Striker(8.0 * mm, 0.25), Wall("flat"))
    ref = simulate_lateral(model, Track(groove_radius=15.0 * mm, friction=0.2), 6e-4, hc.Probes(1e-6))
    assert ds.attrs["lateral_freedom"] == 1 and "track" in ds.attrs["config"]
    for v in ("contact_force", "lateral_displacement", "friction_loss"):
        np.testing.assert_array_equal(ds[v].values, ref[v].values)
    assert float(ds.friction_loss[-1]) > 0
    # without [track], the 1D engine
    assert "lateral_freedom" not in run_config({k: v for k, v in data.items() if k != "track"}).attrs
    with pytest.raises(ConfigError) as e:
        run_config({**data, "track": {"groove_radius_mm": 5.0}})  # narrower than the 13 mm beads
    assert e.value.field == "track.groove_radius_mm" and "13 mm" in str(e.value)
    with pytest.raises(ConfigError) as e:
        parse_config({**data, "track": {"friction": -0.1}})
    assert e.value.field == "track.friction"
    cfg = tmp_path / "run.toml"
    cfg.write_text('[chain]\ndiameters_mm = [26, 26, 26]\n[run]\nduration = 3e-4\n[track]\nspring = 1e3\n')
    capsys.readouterr()
    assert main(["run", str(cfg), "--out", str(tmp_path / "r.nc"), "--set", "track.sprung=1"]) == 2
    err = capsys.readouterr().err
    assert "track.sprung" in err and "Traceback" not in err
    assert main(["run", str(cfg), "--out", str(tmp_path / "r.nc"), "--quiet"]) == 0
    assert hc.load(tmp_path / "r.nc").attrs["lateral_freedom"] == 1
