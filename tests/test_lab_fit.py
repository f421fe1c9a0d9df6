"""hertzchain fit / compare on synthetic laboratory data with known answers.

The records are made from the model with hidden parameters (striker speed, sensor gain, a DC
offset, the trigger time), passed through white noise, an 8-bit scope window and a scope clock
25 times coarser than the simulation with a random phase (tests/lab_files.py), and written in
each supported vendor format. The fit must find every hidden value within 3 standard errors, and
its standard errors must be honest: over many noise seeds the 1-sigma intervals cover the truth
about 68 % of the time.
"""

from __future__ import annotations

import json
import tomllib

import numpy as np
import pytest
from scipy.stats import chi2

import hertzchain as hc
from hertzchain.cli.main import main
from hertzchain.errors import ConfigError
from hertzchain.lab import Trace, fit_traces, read_trace
from hertzchain.lab.fit_checks import check_identifiable

from lab_files import (START, TRUTH, lab_record, truth_signal, write_isf, write_mso_csv, write_picoscope,
                       write_tds_csv, write_trc)

SENS_V = 112.40e-3  # V/N, nominal PCB 208A11
FREE = ["striker.velocity", "gain", "time_offset", "baseline"]
WRITERS = {"tds.csv": write_tds_csv, "scope.isf": write_isf, "scope.trc": write_trc, "pico.csv": write_picoscope,
           "mso.csv": write_mso_csv}


@pytest.fixture(scope="module")
def signal():
    return truth_signal()


def _fit_record(tmp_path, signal, seed: int, name: str = "mso.csv"):
    t, volts, tau = lab_record(signal, seed)
    path = WRITERS[name](tmp_path / f"{seed}_{name}", t, volts)
    da = read_trace(path, "Channel A" if name == "pico.csv" else None, sensor="pcb_208a11")
    result = fit_traces(START, [Trace(da, name=name)], FREE)
    # read_trace removed the pre-pulse median; what is left of the DC offset is the baseline.
    truth = np.array([TRUTH["velocity"], TRUTH["gain"], tau, TRUTH["offset_V"] / SENS_V - da.attrs["baseline"]])
    return result, truth


@pytest.mark.parametrize("name", list(WRITERS)[:4])
def test_fit_recovers_hidden_parameters(tmp_path, signal, name):
    seed = list(WRITERS).index(name) + 100
    result, truth = _fit_record(tmp_path, signal, seed, name)
    assert result.converged and result.names == FREE
    z = (result.values - truth) / result.stderr
    print(f"{name}: (fit - truth)/stderr " + ", ".join(f"{n} {v:+.2f}" for n, v in zip(FREE, z)))
    assert np.all(np.abs(z) < 3), dict(zip(FREE, z))
    # The errors are a real measurement, not a formality: the speed to ~1-2 %, the clock to ~10 us.
    assert result.stderr[0] / TRUTH["velocity"] < 0.03 and result.stderr[2] < 1e-5
    # Residuals are the noise: s^2 (weighted by the robust noise estimate) is of order one.
    assert 0.3 < result.residual_variance < 4
    # One engine call per evaluation; the Jacobian's only free config field adds one member.
    assert result.n_members <= 2 * result.n_evaluations


def test_standard_errors_are_honest_few_seeds(tmp_path, signal):
    """The fast version of the coverage test: for each parameter, the sum over seeds of
    ((fit - truth)/stderr)^2 follows chi^2(n_seeds) when the errors are honest."""
    seeds = range(6)
    z = np.array([(lambda r, t: (r.values - t) / r.stderr)(*_fit_record(tmp_path, signal, s)) for s in seeds])
    stat = (z**2).sum(axis=0)
    p = chi2.cdf(stat, len(seeds))
    assert np.all((p > 1e-3) & (p < 1 - 1e-3)), dict(zip(FREE, stat))


@pytest.mark.slow
def test_coverage_over_40_seeds(tmp_path, signal):
    """Over 40 seeds the 1-sigma intervals of the 4 parameters (160 intervals) cover the truth in
    60-76 % of cases (68.3 % expected; binomial sd 3.7 %)."""
    z = np.array([(lambda r, t: (r.values - t) / r.stderr)(*_fit_record(tmp_path, signal, s)) for s in range(40)])
    coverage = float(np.mean(np.abs(z) < 1))
    print(f"1-sigma coverage over {z.shape[0]} seeds x {z.shape[1]} parameters: {coverage:.3f}; per parameter "
          + ", ".join(f"{n} {c:.3f}" for n, c in zip(FREE, np.mean(np.abs(z) < 1, axis=0))))
    assert 0.60 <= coverage <= 0.76, coverage


def test_fit_cli_on_shipped_example(tmp_path, capsys):
    """The README's fit: examples/scope_chain1_wall.csv was made with v = 0.25 m/s, a sensor at
    0.970 of its nominal sensitivity (examples/make_scope_example.py)."""
    out = tmp_path / "fit"
    assert main(["fit", "examples/lab_chain1.toml", "examples/scope_chain1_wall.csv", "--sensor", "pcb_208a11",
                 "--free", "striker.velocity", "--free", "gain", "--free", "time_offset", "--bootstrap", "3",
                 "--out", str(out), "-q"]) == 0
    report = json.loads((out / "fit.json").read_text())
    assert report["parameters"]["gain"]["bootstrap"]["refits"] == 3
    assert report["converged"] and report["n_evaluations"] >= 1 and report["cost"] > 0
    pars = report["parameters"]
    for key, truth in (("striker.velocity", 0.25), ("gain", 109.0 / 112.40)):
        assert abs(pars[key]["value"] - truth) < 3 * pars[key]["stderr"], (key, pars[key])
    # calibrated.toml is a valid run config carrying the fitted speed, and runs as is.
    calibrated = tomllib.loads((out / "calibrated.toml").read_text())
    assert calibrated["striker"]["velocity"] == pytest.approx(pars["striker.velocity"]["value"], rel=1e-12)
    assert main(["run", str(out / "calibrated.toml"), "--out", str(tmp_path / "c.nc"), "-q"]) == 0
    page = (out / "fit.html").read_text()
    assert (out / "fit.png").stat().st_size > 10_000 and "<table>" in page and "bootstrap 68 % interval" in page


def test_series_with_per_trace_settings(tmp_path, capsys):
    """Two wall traces of chain 1 truncated after beads 20 and 30 (the paper's protocol) and the
    sensor embedded in bead 12, each read with its own sensitivity: one speed shared, one gain
    per sensor kind, one time offset per trace (noise-free records: exact recovery)."""
    data = {**START, "striker": {"diameter_mm": 8.0, "velocity": 0.23}}
    args = []
    for n in (20, 30):
        ds = hc.run_config({**data, "chain": {"preset": "chain1", "truncate": n},
                            "instrument": {"wall": {"sample_rate": 2.5e6, "bits": 24, "trigger_level_N": 0.5,
                                                    "sensitivity_mV_per_N": 112.40 * 1.04, "trigger_jitter": False}}})
        path = write_tds_csv(tmp_path / f"n{n}.csv", ds.wall_scope_time.values,
                             ds.measured_wall_force.values * 112.40e-3 * 1.04)
        args.append(f"{path}@chain.truncate={n}")
    ds = hc.run_config({**data, "chain": {"preset": "chain1"}, "probes": {"sensors": [12]},
                        "instrument": {"sensors": {"sample_rate": 2.5e6, "bits": 24, "trigger_level_N": 0.5,
                                                   "sensitivity_mV_per_N": 11.24 * 0.95, "trigger_jitter": False}}})
    path = write_picoscope(tmp_path / "bead12.csv", ds.sensor_scope_time.values,
                           ds.measured_sensor_force.sel(sensor=12).values * 11.24e-3 * 0.95)
    args.append(f"{path}@signal=sensor:12@sensor=pcb_200b02@column=Channel A")
    out = tmp_path / "series"
    assert main(["fit", "examples/lab_chain1.toml", *args, "--sensor", "pcb_208a11", "--free", "striker.velocity",
                 "--free", "gain", "--free", "time_offset", "--set", "contact.A=2e-6", "--out", str(out), "-q"]) == 0
    pars = json.loads((out / "fit.json").read_text())["parameters"]
    assert set(pars) == {"striker.velocity", "gain[sensor]", "gain[wall]", "time_offset[0]", "time_offset[1]",
                         "time_offset[2]"}
    assert pars["striker.velocity"]["value"] == pytest.approx(0.23, rel=2e-4)
    assert pars["gain[wall]"]["value"] == pytest.approx(1.04, rel=2e-4)
    assert pars["gain[sensor]"]["value"] == pytest.approx(0.95, rel=2e-4)


def test_non_identifiable_and_bad_start(tmp_path, signal, capsys):
    t, volts, tau = lab_record(signal, 7)
    path = write_mso_csv(tmp_path / "r.csv", t, volts)
    da = read_trace(path, sensor="pcb_208a11")
    # Stopped early: said so, in the result and in fit.json.
    early = fit_traces(START, [Trace(da)], ["striker.velocity", "gain", "time_offset"], max_evaluations=2)
    assert not early.converged and "not converged" in early.as_json()["warnings"][0]
    with pytest.raises(ConfigError, match=r"r.csv@signal: sensor:31 names no bead.*1..30"):
        fit_traces(START, [Trace(da, signal="sensor:31", name="r.csv")], ["gain"])
    # run.rtol is not used by the Verlet engine: the traces cannot tell anything about it (given a
    # number: its default, None, means the integrator's own and is not a field to fit).
    with_rtol = {**START, "run": {**START["run"], "rtol": 1e-10}}
    with pytest.raises(ConfigError, match="run.rtol.*do not change"):
        fit_traces(with_rtol, [Trace(da)], ["run.rtol", "gain", "time_offset"])
    # Two parameters that act the same way: named together, with the combination.
    J = np.random.default_rng(0).standard_normal((200, 3))
    J[:, 2] = -2.0 * J[:, 0]
    with pytest.raises(ConfigError, match=r"--free a: cannot be separated from c"):
        check_identifiable(["a", "b", "c"], J, "at the start")
    # Without a time offset the record (times from its trigger) lies before the simulated pulse.
    capsys.readouterr()
    assert main(["fit", "examples/lab_chain1.toml", str(path), "--sensor", "pcb_208a11", "--free", "gain",
                 "--out", str(tmp_path / "f"), "-q"]) == 2
    err = capsys.readouterr().err
    assert "bad start" in err and "Traceback" not in err
    assert main(["fit", "examples/lab_chain1.toml", str(path), "--sensor", "pcb_208a11", "--free", "chain.preset",
                 "--out", str(tmp_path / "f"), "-q"]) == 2
    assert "not a numeric field" in capsys.readouterr().err


def test_compare_cli(tmp_path, capsys):
    """A record of the model through a fine scope compared with the model: the paper's pulse
    parameters agree within their errors, the residual is the noise."""
    cfg = {"chain": {"uniform": {"n": 8, "diameter_mm": 26}}, "striker": {"velocity": 0.3}, "run": {"duration": 1.2e-3}}
    ds = hc.run_config(cfg)
    sim = tmp_path / "sim.nc"
    hc.save(ds, sim)
    scope = hc.Instrument.pcb_208a11(sample_rate=2.5e6, noise_rms_mV=2.0, bits=16, trigger_level_N=0.5, seed=4)
    acq = scope.acquire(ds.time.values, ds.wall_force.values)
    meas = write_tds_csv(tmp_path / "m.csv", acq.time, acq.volts)
    out, js = tmp_path / "cmp.png", tmp_path / "cmp.json"
    assert main(["compare", str(meas), str(sim), "--out", str(out), "--json", str(js), "--sensor", "pcb_208a11"]) == 0
    r = json.loads(js.read_text())
    m, s = r["measured"], r["simulated"]
    assert abs(r["peak_force_diff"]) < 3 * np.hypot(m["peak_force_err"], s["peak_force_err"]) + 2e-3 * s["peak_force"]
    assert abs(r["duration_diff"]) < 3 * np.hypot(m["duration_err"], s["duration_err"]) + 4e-7
    # The record's clock starts at the trigger (+ the sample-clock phase): T differs by that much.
    assert r["time_of_flight_diff"] == pytest.approx(acq.trigger_time + acq.jitter[0], abs=3 * m["time_of_flight_err"] + 2e-7)
    noise_n = 2.0e-3 / SENS_V
    assert noise_n * 0.8 < r["rms_residual"] < noise_n * 1.5
    assert out.stat().st_size > 10_000
    # The same against the run config itself (simulated on the fly), aligned by cross-correlation.
    (tmp_path / "c.toml").write_text('[chain]\nuniform = {n = 8, diameter_mm = 26}\n[striker]\nvelocity = 0.3\n'
                                     '[run]\nduration = 1.2e-3\n')
    assert main(["compare", str(meas), str(tmp_path / "c.toml"), "--out", str(out), "--json", str(js),
                 "--sensor", "pcb_208a11", "--align", "xcorr"]) == 0
    assert json.loads(js.read_text())["rms_residual"] < noise_n * 1.5


def test_bootstrap_agrees_with_covariance(tmp_path):
    """Where the model is close to linear over the error bars, the residual bootstrap's spread
    matches the covariance's standard errors (20 refits: the spread is known to ~16 %, so a
    ratio in [0.5, 1.5] is 3 sigma)."""
    cfg = {"chain": {"uniform": {"n": 8, "diameter_mm": 26}}, "striker": {"velocity": 0.3}, "run": {"duration": 1.0e-3}}
    ds = hc.run_config(cfg)
    scope = hc.Instrument.pcb_208a11(sample_rate=2.5e6, noise_rms_mV=20.0, bits=16, trigger_level_N=0.5,
                                     trigger_jitter=False, seed=11)
    acq = scope.acquire(ds.time.values, ds.wall_force.values)
    da = read_trace(write_tds_csv(tmp_path / "b.csv", acq.time, acq.volts), sensor="pcb_208a11")
    start = {**cfg, "striker": {"velocity": 0.27}}
    result = fit_traces(start, [Trace(da)], ["striker.velocity", "gain", "time_offset"], bootstrap=20, seed=3)
    assert result.bootstrap.shape == (20, 3)
    ratio = result.bootstrap.std(axis=0, ddof=1) / result.stderr
    assert np.all((ratio > 0.5) & (ratio < 1.5)), ratio
    boot = result.as_json()["parameters"]["striker.velocity"]["bootstrap"]
    assert boot["refits"] == 20 and boot["interval_68"][0] < result.values[0] < boot["interval_68"][1]
    with pytest.raises(ConfigError, match="--bootstrap"):
        fit_traces(start, [Trace(da)], ["gain"], bootstrap=1)


def test_fit_a_custom_materials_modulus(tmp_path):
    """Young's modulus of a [materials.NAME] chain is a free field like any other (its column of
    J is ~1e-11 of a time offset's in SI: judged in natural units, it is well determined)."""
    cfg = {"materials": {"mysteel": {"density": 7780.0, "young": 2.0e11, "poisson": 0.3}},
           "chain": {"uniform": {"n": 8, "diameter_mm": 26}, "material": "mysteel"}, "striker": {"velocity": 0.3},
           "run": {"duration": 1.0e-3}}
    true = {**cfg, "materials": {"mysteel": {"density": 7780.0, "young": 2.1e11, "poisson": 0.3}}}
    ds = hc.run_config(true)
    acq = hc.Instrument.pcb_208a11(sample_rate=2.5e6, noise_rms_mV=5.0, bits=12, trigger_level_N=0.5,
                                   seed=3).acquire(ds.time.values, ds.wall_force.values)
    da = read_trace(write_tds_csv(tmp_path / "y.csv", acq.time, acq.volts), sensor="pcb_208a11")
    result = fit_traces(cfg, [Trace(da)], ["materials.mysteel.young", "striker.velocity", "time_offset"])
    z = (result.values - [2.1e11, 0.3, acq.trigger_time + acq.jitter[0]]) / result.stderr
    assert np.all(np.abs(z) < 3), z
    assert result.stderr[0] / 2.1e11 < 0.01


def test_compare_residual_has_the_sign_of_the_differences():
    """simulated - measured everywhere: a simulation 10 % above the measurement gives dF_m > 0 and a
    positive residual at the peak (the residual used to be measured - simulated, against its numbers)."""
    import xarray as xr

    from hertzchain.lab import compare_traces

    t = np.linspace(0.0, 1e-3, 2001)
    x = np.clip((t - 5e-4) / 5e-5, -np.pi / 2, np.pi / 2)
    measured = xr.DataArray(2.0 * np.cos(x) ** 6, coords={"time": t}, dims="time")
    comp = compare_traces(measured, 1.1 * measured)
    assert comp.peak_force_diff == pytest.approx(0.2, rel=1e-3)
    peak = np.argmax(comp.measured_force)
    assert comp.residual[peak] == pytest.approx(0.2, rel=1e-3)
    np.testing.assert_allclose(comp.residual, comp.simulated_force - comp.measured_force)


def test_the_start_runs_a_config_left_at_the_automatic_duration(signal):
    """run.duration left out ("auto", the schema's default): the starting model runs over the
    model's automatic duration (hertzchain.auto_duration), exactly as with that duration written
    in the config, and finds the record's own gain (1) and time offset (0) (the start compared the
    string "auto" with a number and failed with a TypeError before)."""
    import copy

    import xarray as xr

    from hertzchain.config import build_model, parse_config
    from hertzchain.lab.fit import FD_STEP, _Problem

    t, f = signal
    noise = np.random.default_rng(7).normal(0.0, 1e-3 * f.max(), t[::25].size)
    da = xr.DataArray(f[::25] + noise, dims="time", coords={"time": t[::25]}, attrs={"units": "N"})
    auto = copy.deepcopy(START)
    auto["striker"]["velocity"] = TRUTH["velocity"]
    del auto["run"]["duration"]
    given = copy.deepcopy(auto)
    given["run"]["duration"] = hc.auto_duration(build_model(parse_config(auto)))
    starts = [_Problem(data, [Trace(da)], ["gain", "time_offset"], FD_STEP, 1).start() for data in (auto, given)]
    np.testing.assert_array_equal(starts[0], starts[1])
    assert abs(starts[0][0] - 1.0) < 1e-2 and abs(starts[0][1]) < 2 * (t[1] - t[0])
