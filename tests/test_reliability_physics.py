"""No silent wrong physics: the step bound with damping, the energy balance, geometry, Hertz range,
resources and the record that ends before the pulse arrives (issue 10, part 3 and 2)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import hertzchain as hc
from hertzchain import checks
from hertzchain.config import build_model, parse_config
from hertzchain.errors import HertzRangeWarning, LongRunWarning, PulseNotReachedWarning, SimulationDiverged


def total_energy(ds):
    return (ds.kinetic_energy + ds.potential_energy + ds.dissipated_energy).values


def dashpot_model(gamma, n=5, velocity=0.2):
    return hc.Model(hc.Chain.uniform(n, 26e-3), hc.Striker(8e-3, velocity), hc.Wall("flat"), hc.Dashpot(gamma))


def test_step_bound_of_a_damped_contact_is_the_closed_form():
    """One bead between striker and wall: max_frequency is max_i sqrt(w_i^2 + b_i^2/4) + b_i/2 with
    Gershgorin's w_i^2 = 2 (k_l + k_r)/m_i, b_i = 2 (c_l + c_r)/m_i, which gives 2 m / gamma alone."""
    gamma = 3e4
    model = dashpot_model(gamma, n=1)
    s = model.system()
    d = s.max_overlap()
    k = 1.5 * s.kappa * np.sqrt(d)
    m = s.mass[:2]
    w2 = np.array([2 * k[0] / m[0], 2 * (k[0] + k[1]) / m[1]])
    b = np.array([2 * gamma / m[0], 2 * (2 * gamma) / m[1]])
    expected = np.max(np.sqrt(w2 + b**2 / 4) + b / 2)
    assert s.max_frequency() == pytest.approx(expected, rel=1e-12)
    # Dashpots alone (kappa -> 0): omega_max -> b, the stable step 2 / omega_max = m / (c_l + c_r).
    assert np.max(b) >= 2 * gamma / m.max()
    elastic = hc.Model(model.chain, model.striker, model.wall).system().max_frequency()
    assert elastic == pytest.approx(np.sqrt(w2.max()), rel=1e-12)  # no damping: unchanged bound


@pytest.mark.parametrize("gamma", [1e4, 1e5])
def test_strong_dashpot_keeps_the_energy_balance(gamma):
    """Issue: gamma = 1e5 gained 1.8 % (and 1e25 x at larger gamma) with the elastic step bound.
    With the damping in the bound, kinetic + elastic + dissipated stays constant to 1e-6."""
    model = dashpot_model(gamma)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", hc.ElasticLimitWarning)
        ds = hc.simulate(model, 3e-4, hc.Probes(sample_interval=1e-6))
    e = total_energy(ds)
    assert np.all(np.isfinite(e))
    assert np.max(np.abs(e - e[0])) < 1e-6 * e[0]
    # Strong damping dissipates almost everything, and the wall force stays below the force that
    # would stop the striker's whole momentum within one damping time m_bead / gamma (the issue's
    # run reported 1e17 N).
    assert ds.dissipated_energy.values[-1] > 0.99 * e[0]
    momentum = model.striker.mass * model.striker.velocity
    assert 0 < ds.wall_force.max() < momentum * gamma / model.chain.masses[0]


def test_fixed_step_must_respect_the_damping_bound():
    model = dashpot_model(1e5)
    w = model.system().max_frequency()
    elastic_w = hc.Model(model.chain, model.striker, model.wall).system().max_frequency()
    assert w > 10 * elastic_w  # the damping, not the stiffness, sets the bound here
    with pytest.raises(hc.ConfigError, match=r"run\.dt"):
        hc.simulate(model, 2e-5, hc.Probes(sample_interval=1e-6), dt=1.0 / w)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", hc.ElasticLimitWarning)
        ds = hc.simulate(model, 2e-5, hc.Probes(sample_interval=1e-6), dt=0.45 / w)
    e = total_energy(ds)
    assert np.max(e - e[0]) < 1e-3 * e[0]


def test_a_run_that_gains_energy_is_stopped_naming_the_cause(monkeypatch):
    """Bypass the step check: a fixed step beyond 2 m / gamma gains energy, and the balance check
    stops the run naming run.dt (never exit 0 with 1e17 N)."""
    from hertzchain.integrate.drivers import verlet

    monkeypatch.setattr(verlet, "check_time_step", lambda system, dt: None)
    model = dashpot_model(1e5)
    w = model.system().max_frequency()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        # Gershgorin's bound is ~2x the striker's true damping rate: 6 / omega_max is ~1.5x past
        # the stable 2 m / gamma. Forces never pull, so the error stays finite: only the balance sees it.
        with pytest.raises(SimulationDiverged, match=r"gains energy: .* grew by .*Cause: the time step run\.dt"):
            hc.simulate(model, 2e-5, hc.Probes(sample_interval=1e-5), dt=6.0 / w)


def test_energy_balance_check_on_known_series():
    t = np.linspace(0, 1, 5)
    ke = np.array([1.0, 0.5, 0.2, 0.1, 0.1])
    pe = np.array([0.0, 0.4, 0.5, 0.3, 0.2])
    ed = 1.0 - ke - pe  # exact balance: passes
    checks.check_energy_balance(t, ke, pe, ed, tolerance=1e-9, cause="x")
    with pytest.raises(SimulationDiverged, match=r"grew by 0\.01 .*t = 0\.75.*Cause: contact\.gamma"):
        checks.check_energy_balance(t, ke, pe, ed + np.array([0, 0, 0, 0.01, 0.0]), tolerance=1e-3,
                                    cause="contact.gamma")
    with pytest.raises(SimulationDiverged, match="non-finite"):
        checks.check_energy_balance(t, ke, pe, ed + np.array([0, 0, np.inf, 0, 0]), tolerance=1e-3, cause="x")


def test_striker_must_hit_bead_one():
    """Issue: a bead-1 offset past the two radii let the striker miss the chain (0 N, exit 0)."""
    base = {"chain": {"uniform": {"n": 3, "diameter_mm": 26.0}}, "striker": {"diameter_mm": 8.0}}
    for key, value in (("offsets_mm", [17.5, 17.5, 17.5]), ("offsets_fraction", [0.4, 0.4, 0.4])):
        cfg = parse_config({**base, "chain": {**base["chain"], key: value}})
        with pytest.raises(hc.ConfigError, match=rf"^chain\.{key}: bead 1 is offset .* striker"):
            build_model(cfg)
    # Just inside (R_s + R_1) / 2 = 8.5 mm is a valid misaligned impact.
    build_model(parse_config({**base, "chain": {**base["chain"], "offsets_mm": [8.4, 8.4, 8.4]}}))


def test_static_overlap_beyond_hertz_range_is_refused():
    """Issue: 1e9 N of precompression on glass overlapped 37 radii without a word."""
    cfg = parse_config({"chain": {"uniform": {"n": 4, "diameter_mm": 26.0}, "material": "glass",
                                  "precompression": 1e9}})
    with pytest.raises(hc.ConfigError, match=r"^chain\.precompression: .* times the smaller bead radius"):
        hc.simulate(build_model(cfg), 1e-4)
    # The static overlap is the Hertz law inverted, delta0 = (F0 / kappa)^(2/3): 10 N is far inside.
    model = build_model(parse_config({"chain": {"uniform": {"n": 4, "diameter_mm": 26.0}, "precompression": 10.0}}))
    d0 = model.system().d0[1]
    assert d0 == pytest.approx((10.0 / model.system().kappa[1]) ** (2 / 3))
    assert d0 < checks.HERTZ_MAX_OVERLAP * 13e-3


def test_dynamic_overlap_beyond_hertz_range_warns():
    model = hc.Model(hc.Chain.uniform(2, 1e-3, "PTFE"), hc.Striker(20e-3, 300.0, "AISI52100"))
    with pytest.warns(HertzRangeWarning, match=r"striker\.velocity"):
        warnings.simplefilter("ignore", hc.ElasticLimitWarning)
        hc.simulate(model, 2e-6, hc.Probes(sample_interval=1e-8))


def test_batches_warn_once_for_the_members_past_the_hertz_range():
    """simulate_batch gives one HertzRangeWarning naming the members that simulate would warn
    about, with the same worst ratio; both batch paths (one layout: array code; mixed layouts)."""
    def ratio(message: str) -> float:
        return float(message.split(" times the smaller")[0].split()[-1])

    fine = hc.Model(hc.Chain.uniform(5, 10e-3), hc.Striker(8e-3, 0.2))
    crushed = hc.Model(hc.Chain.uniform(5, 10e-3), hc.Striker(8e-3, 600.0))
    short = hc.Model(hc.Chain.uniform(3, 10e-3), hc.Striker(8e-3, 600.0))
    with warnings.catch_warnings(record=True) as single:
        warnings.simplefilter("always")
        warnings.simplefilter("ignore", hc.ElasticLimitWarning)
        hc.simulate(crushed, 1e-4)
    expected = ratio(str(next(w.message for w in single if w.category is HertzRangeWarning)))
    for members, named in (([fine, crushed, fine], "1 of 3 members (member 1)"),
                           ([fine, crushed, short], "2 of 3 members (member 1, 2)")):
        with warnings.catch_warnings(record=True) as rec:
            warnings.simplefilter("always")
            warnings.simplefilter("ignore", hc.ElasticLimitWarning)
            hc.simulate_batch(members, 1e-4)
        hertz = [str(w.message) for w in rec if w.category is HertzRangeWarning]
        assert len(hertz) == 1 and hertz[0].startswith(named)
        assert ratio(hertz[0]) == pytest.approx(expected, rel=1e-3)
    with warnings.catch_warnings():
        warnings.simplefilter("error", HertzRangeWarning)
        hc.simulate_batch([fine, fine], 1e-4)


def test_record_ending_before_the_pulse_reaches_the_wall_warns():
    """Issue: too short a run reported 'peak wall force 0 N', exit 0."""
    model = hc.Model(hc.Chain.uniform(20, 26e-3), hc.Striker(8e-3, 0.2))
    with pytest.warns(PulseNotReachedWarning, match=r"run\.duration") as rec:
        ds = hc.simulate(model, 1e-4)
    assert ds.wall_force.max() == 0.0
    # the estimate extrapolates the front's progress: the wall lies farther than the record
    arrival = float(str(rec[0].message).split("near t = ")[1].split(" s")[0])
    assert arrival > 1e-4
    with warnings.catch_warnings():
        warnings.simplefilter("error", PulseNotReachedWarning)
        warnings.simplefilter("ignore", hc.ElasticLimitWarning)
        hc.simulate(model, 3e-3)  # long enough: no warning
    # A precompressed chain carries F0 at the wall from the start: only the impact's part counts.
    squeezed = hc.Model(model.chain, model.striker, precompression=5.0)
    with pytest.warns(PulseNotReachedWarning):
        hc.simulate(squeezed, 1e-4)


def test_records_that_cannot_fit_in_memory_are_refused_before_allocation():
    model = hc.Model(hc.Chain.uniform(16, 26e-3))
    probes = hc.Probes(sample_interval=1e-7)
    est = checks.estimate_resources(model.system(), 12.0, probes)
    # samples x (contacts, the wall's among them, + 3 energies) x 12 bytes (the record and its compressed file)
    assert est.samples == 120_000_001 and est.signals == 17 + 3
    assert est.memory_bytes == checks.BYTES_PER_VALUE * est.samples * est.signals == 12 * est.samples * est.signals
    # the peak: the process as it is (at least the runtime's own) plus the job
    assert est.peak_bytes == est.memory_bytes + est.process_bytes and est.process_bytes >= checks.RUNTIME_BYTES
    with pytest.raises(hc.ConfigError, match=r"^run\.duration: .*GiB.*more than"):
        checks.check_resources(est, available=2**30)
    checks.check_resources(checks.estimate_resources(model.system(), 1e-3, probes), available=2**30)


def test_long_run_is_allowed_with_a_warning_and_the_estimate():
    model = hc.Model(hc.Chain.uniform(1000, 26e-3))
    from hertzchain.integrate.drivers.verlet import step_plan

    est = checks.estimate_resources(model.system(), 10.0, hc.Probes(sample_interval=1e-3))
    # steps at the smallest adaptive step (an upper estimate) x moving bodies x cost of a bead-step
    assert est.steps == pytest.approx(10.0 / step_plan(model.system(), 1e-3, None).dt)
    assert est.seconds == pytest.approx(est.steps * 1001 * checks.NS_PER_BEAD_STEP["elastic"])
    assert est.seconds > checks.LONG_RUN_S
    with pytest.warns(LongRunWarning, match=r"about \d+ min"):
        checks.check_resources(est, available=2**40)


def test_cli_refuses_a_run_too_large_for_memory(tmp_path, capsys):
    """Issue: duration = 12 was killed by the kernel after two minutes with no message."""
    from hertzchain.cli.main import main

    cfg = tmp_path / "long.toml"
    cfg.write_text('[chain]\npreset = "chain1"\n[run]\nduration = 12.0\nsample_interval = 1e-9\n')
    assert main(["run", str(cfg), "--out", str(tmp_path / "x.nc")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: run.duration") and "GiB" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["long.toml"]


def test_divergence_message_names_run_dt_only_when_it_was_given(monkeypatch):
    """Issue: the divergence message asked for a smaller run.dt when none was given."""
    from hertzchain.integrate.core import kernels

    monkeypatch.setattr(kernels, "verlet_run_of", lambda kind: lambda *args: 1)  # the kernel reports a non-finite state
    model = hc.Model(hc.Chain.uniform(3, 26e-3), hc.Striker(8e-3, 0.2))
    with pytest.raises(SimulationDiverged) as auto:
        hc.simulate(model, 1e-4, integrator="verlet")  # the Verlet kernel patched above
    assert "automatic step" in str(auto.value) and "run.dt" not in str(auto.value)
    with pytest.raises(SimulationDiverged, match=r"with run\.dt = 1e-08 s; use a smaller run\.dt"):
        hc.simulate(model, 1e-4, dt=1e-8)


def test_sweep_member_that_gains_energy_stops_the_sweep(tmp_path, monkeypatch):
    """The batched engine has no balance check of its own: compute_chunk checks every member."""
    from hertzchain.integrate.drivers import verlet

    monkeypatch.setattr(verlet, "check_time_step", lambda system, dt: None)
    w = dashpot_model(1e5).system().max_frequency()
    sweep = {"base": {"chain": {"uniform": {"n": 5, "diameter_mm": 26.0}}, "striker": {"velocity": 0.2},
                      "contact": {"law": "dashpot", "gamma": 1e5},
                      "run": {"duration": 2e-5, "sample_interval": 1e-5, "dt": 6.0 / w}},
             "sweep": {"parameters": {"striker.diameter_mm": [8.0]}}}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(SimulationDiverged, match=r"sweep member 0 .*gains energy.*run\.dt"):
            hc.run_sweep(sweep, tmp_path / "out")
    assert not list((tmp_path / "out" / "chunks").glob("chunk_*.nc"))


def test_estimate_counts_every_recorded_signal():
    system = hc.Model(hc.Chain.uniform(10, 26e-3)).system()
    base = checks.estimate_resources(system, 1e-3, hc.Probes(sample_interval=1e-6, contacts=()))
    assert base.samples == 1001 and base.signals == 1 + 3  # the wall contact, 3 energies
    both = checks.estimate_resources(system, 1e-3, hc.Probes(sample_interval=1e-6, contacts=(), sensors=(3,),
                                                             velocities=True, positions=True))
    assert both.signals == base.signals + 2 + 1 + 2 * 11  # sensor's contacts, its force, bodies 0..10 twice
