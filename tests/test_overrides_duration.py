"""--set overrides on run and sweep, duration = "auto", the elastic-limit message, lazy imports."""

from __future__ import annotations

import json
import subprocess
import sys
import tomllib
import warnings
from pathlib import Path

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.cli.main import main
from hertzchain.runs.simulation import auto_duration, elastic_limit_message

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _flatten(d: dict, prefix: str = "") -> dict:
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flatten(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def test_set_changes_exactly_the_named_field(tmp_path):
    base, changed = tmp_path / "base.nc", tmp_path / "changed.nc"
    short = ["--set", "run.duration=4e-4", "-q"]
    assert main(["run", str(EXAMPLES / "contract.toml"), "--out", str(base), *short]) == 0
    assert main(["run", str(EXAMPLES / "contract.toml"), "--out", str(changed), *short,
                 "--set", "striker.velocity=0.3", "--set", "probes.sensors=[5]"]) == 0
    a = _flatten(json.loads(hc.load(base).attrs["config"]))
    b = _flatten(json.loads(hc.load(changed).attrs["config"]))
    diff = {k for k in a.keys() | b.keys() if a.get(k) != b.get(k)}
    assert diff == {"striker.velocity", "probes.sensors"}
    assert b["striker.velocity"] == 0.3 and b["probes.sensors"] == [5]
    assert list(hc.load(changed).sensor.values) == [5]


@pytest.mark.parametrize("assignment, field", [("striker.speed=1", "striker.speed"),
                                               ("striker.velocity=-1", "striker.velocity"),
                                               ("velocity", "--set")])
def test_set_rejects_unknown_or_bad_fields(tmp_path, capsys, assignment, field):
    out = tmp_path / "r.nc"
    assert main(["run", str(EXAMPLES / "contract.toml"), "--out", str(out), "--set", assignment]) == 2
    err = capsys.readouterr().err
    assert field in err and "Traceback" not in err
    assert not out.exists()


def test_sweep_set_is_relative_to_base(tmp_path, capsys):
    from hertzchain.sweep import load_sweep

    plain = load_sweep(EXAMPLES / "sweep_taper.toml")
    cfg = load_sweep(EXAMPLES / "sweep_taper.toml", ["striker.diameter_mm=10", "run.duration=1e-3"])
    a, b = _flatten(plain.base), _flatten(cfg.base)
    assert {k for k in a.keys() | b.keys() if a.get(k) != b.get(k)} == {"striker.diameter_mm", "run.duration"}
    assert cfg.members == plain.members
    assert main(["sweep", str(EXAMPLES / "sweep_taper.toml"), "--out", str(tmp_path / "s"),
                 "--set", "chain.tapper.q=0.1"]) == 2
    assert "chain.tapper" in capsys.readouterr().err


def test_duration_defaults_to_auto():
    cfg = hc.parse_config(tomllib.loads('[chain]\npreset = "chain1"\n'))
    assert cfg.run.duration == "auto"
    with pytest.raises(hc.ConfigError, match="run.duration"):
        hc.parse_config({"chain": {"preset": "chain1"}, "run": {"duration": "long"}})


def _wall_pulse_captured(model, sample_interval):
    """Auto run against a run twice as long: the same wall peak, and the pulse's front momentum."""
    probes = hc.Probes(sample_interval=sample_interval, contacts=())
    auto = hc.simulate(model, "auto", probes)
    assert auto.attrs["duration_mode"] == "auto"
    assert auto.attrs["duration"] == pytest.approx(auto_duration(model))
    long = hc.simulate(model, 2 * auto.attrs["duration"], probes)
    assert "duration_mode" not in long.attrs
    # the wall pulse of the long run lies inside the auto run: same peak, same time, same fit
    assert auto.attrs["peak_wall_force"] == pytest.approx(long.attrs["peak_wall_force"], rel=1e-9)
    assert auto.attrs["peak_wall_time"] == pytest.approx(long.attrs["peak_wall_time"], rel=1e-9)
    fit = hc.fit_pulse(auto.time.values, auto.wall_force.values)
    assert fit.time_of_flight + 3 * fit.duration < auto.attrs["duration"]
    return auto, fit


def test_auto_duration_slow_striker_chain1():
    """Chain 1 at 0.05 m/s: the old fixed 2.5 ms saw no wall pulse at all; "auto" sees all of it."""
    model = hc.Model(hc.paper_chain("chain1"), hc.Striker(8e-3, 0.05), hc.Wall("flat"), hc.Elastic())
    from hertzchain.errors import PulseNotReachedWarning

    with pytest.warns(PulseNotReachedWarning):
        old = hc.simulate(model, 2.5e-3, hc.Probes(sample_interval=1e-6, contacts=()))
    auto, fit = _wall_pulse_captured(model, 1e-6)
    assert old.attrs["peak_wall_force"] < 1e-3 * auto.attrs["peak_wall_force"]
    # not wastefully long either: the front arrives in the second half of the record
    assert fit.time_of_flight > 0.5 * auto.attrs["duration"]


def test_auto_duration_200_bead_chain():
    model = hc.Model(hc.Chain.uniform(200, 26e-3), hc.Striker(8e-3, 0.2), hc.Wall("flat"), hc.Elastic())
    auto, fit = _wall_pulse_captured(model, 2e-6)
    assert fit.time_of_flight > 0.5 * auto.attrs["duration"]


def test_elastic_limit_message_names_worst_contact_and_range():
    model = hc.Model(hc.Chain.uniform(100, 26e-3), hc.Striker(26e-3, 3.0), hc.Wall("flat"), hc.Elastic())
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ds = hc.simulate(model, 1.5e-3, hc.Probes(sample_interval=1e-6, contacts=()))
    msgs = [str(w.message) for w in caught if issubclass(w.category, hc.ElasticLimitWarning)]
    assert len(msgs) == 1 and msgs[0] == elastic_limit_message(ds)
    ratio = ds.max_contact_force.values / ds.yield_force.values
    over = np.flatnonzero(ratio > 1)
    worst = int(np.argmax(ratio))
    assert f"contact {worst} " in msgs[0] and f"{ratio[worst]:.2f} x F_Y" in msgs[0]
    # the over-limit contacts are contiguous here: one range, not 60 numbers
    assert np.array_equal(over, np.arange(over[0], over[-1] + 1))
    assert f"({over[0]}-{over[-1]})" in msgs[0] and f"{over.size} of {ratio.size} contacts" in msgs[0]
    assert len(msgs[0]) < 300


def test_simulate_loads_no_scipy_integrate_for_verlet():
    code = ("import sys, hertzchain as hc\n"
            "assert 'numba' not in sys.modules\n"
            "m = hc.Model(hc.Chain.uniform(5, 26e-3), hc.Striker(8e-3, 0.2), hc.Wall('flat'), hc.Elastic())\n"
            "hc.simulate(m, 2e-4)\n"
            "assert 'numba' in sys.modules\n"
            "print(sorted(k for k in sys.modules if k.startswith('scipy.integrate')))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"
