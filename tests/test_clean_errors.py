"""Issue 23's crashes, hangs and silent coercions: each one is now a clean error (exit 2, the field
named), a warning before the work, or a correct result."""

from __future__ import annotations

import math

import json
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
import tomli_w

import hertzchain as hc
from hertzchain.cli.main import main
from hertzchain.errors import ConfigError, ElasticLimitWarning, LongRunWarning

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
RUN = {"duration": 2.0e-3, "sample_interval": 1e-6}


def _error(capsys, argv: list[str]) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "internal error" not in err
    return err.strip().splitlines()[-1]


def _design(**over) -> dict:
    d = {"base": {"chain": {"uniform": {"n": 4, "diameter_mm": 26.0}, "taper": {"n": 4, "q": 0.05}},
                  "striker": {"diameter_mm": 8.0, "velocity": 0.2}, "run": dict(RUN)},
         "design": {"objective": "peak_wall_force",
                    "variables": {"chain.taper.n": [2, 12], "chain.taper.q": [0.0, 0.15]}, "budget": 60, "seed": 3}}
    d["design"].update(over)
    return d


def _write(path: Path, data: dict) -> Path:
    path.write_text(tomli_w.dumps(data))
    return path


# ------------------------------------------------------------------------------------------
# silent long runs and hangs: the pre-flight
# ------------------------------------------------------------------------------------------
def test_run_with_a_tiny_dt_says_how_long_before_it_starts(monkeypatch, tmp_path, capsys):
    """run.dt = 1e-15: the 'about 32 h' warning came only after the run; now before, naming run.dt."""
    import hertzchain.config as config

    seen = {}

    def stop(*args, **kwargs):
        seen["err"] = capsys.readouterr().err  # what the user saw before the run started
        raise KeyboardInterrupt

    monkeypatch.setattr(config, "simulate_config", stop)
    assert main(["run", str(EXAMPLES / "chain1_elastic.toml"), "--set", "run.dt=1e-15", "-o",
                 str(tmp_path / "r.nc")]) == 130
    assert "warning: this run is projected to take about" in seen["err"] and " h (" in seen["err"]
    assert "run.dt = 1e-15 s sets the number of steps" in seen["err"]


def test_tiny_eps_is_refused_at_once(capsys):
    """contact.eps = 1e-300 made the calibration search ever stronger damping for hours."""
    t0 = time.perf_counter()
    err = _error(capsys, ["run", str(EXAMPLES / "chain1.toml"), "--set", "contact.eps=1e-300", "-o", "x.nc"])
    assert err.startswith("error: contact.eps") and "0.5" in err
    assert time.perf_counter() - t0 < 10
    with pytest.raises(ConfigError, match=r"contact.eps: must lie in \[0.5, 1\]"):
        hc.calibrate_law("viscoelastic", 1e-300, hc.paper_chain("chain1"))


def test_calibration_refuses_an_unreachable_eps_without_searching_ever_stronger_damping():
    """An eps above the floor but below what the law can give: the search stops at a damping time of
    a few pulse durations (MAX_DAMPING_DURATIONS) with the smallest eps it found."""
    t0 = time.perf_counter()
    with pytest.raises(ConfigError, match=r"cannot give eps = 0.6 .* smallest eps found is 0\.9"):
        hc.calibrate_law("viscoelastic", 0.6, hc.paper_chain("chain1"), hc.Striker(8e-3, 0.2))
    assert time.perf_counter() - t0 < 60


def test_design_population_beyond_the_budget_is_refused_before_any_candidate(tmp_path, capsys):
    """design.population = 1e6 ran with no estimate (building a million candidates)."""
    f = _write(tmp_path / "d.toml", _design(population=1_000_000, budget=600))
    t0 = time.perf_counter()
    err = _error(capsys, ["design", str(f), "--out", str(tmp_path / "o"), "-q"])
    assert err.startswith("error: design.population: a generation of 1,000,000 candidates")
    assert time.perf_counter() - t0 < 20 and not (tmp_path / "o").exists()


def test_design_generation_beyond_memory_is_refused_by_the_preflight(monkeypatch):
    from hertzchain import checks
    from hertzchain.design import parse_design
    from hertzchain.design.search import preflight

    monkeypatch.setattr(checks, "available_memory", lambda: 2**30)
    with pytest.raises(ConfigError, match=r"design.population: .* x 200,000 members, about .* GiB, more than"):
        preflight(parse_design(_design(population=200_000, budget=10_000_000)))


def test_design_search_projected_long_warns_before_it_starts(monkeypatch):
    from hertzchain import checks
    from hertzchain.design import parse_design
    from hertzchain.design.search import preflight

    monkeypatch.setattr(checks, "NS_PER_BEAD_STEP", {"elastic": 1e-3, "general": 1e-3})
    with pytest.warns(LongRunWarning, match="lower design.budget"):
        est = preflight(parse_design(_design()))
    assert est.seconds > checks.LONG_RUN_S


def test_batch_too_large_for_memory_is_refused_before_any_allocation():
    """simulate_batch of 10k members with default probes died with a raw MemoryError (69 GiB)."""
    base = hc.Model(hc.paper_chain("chain1"), hc.Striker(8e-3, 0.2))
    ens = hc.Ensemble(base, striker_velocity=np.full(10_000, 0.2))
    t0 = time.perf_counter()
    with pytest.raises(ConfigError, match=r"probes.contacts: .* x 10,000 members, about [\d.]+ GiB.*split the 10,000 "
                                          r"members \(models\)"):
        hc.simulate_batch(ens, 2.5e-3)
    with pytest.raises(ConfigError, match="probes.contacts"):
        hc.simulate_many([base] * 10_000, 2.5e-3)
    assert time.perf_counter() - t0 < 30


def test_batch_projected_long_warns_before_it_starts(monkeypatch):
    from hertzchain import checks

    monkeypatch.setattr(checks, "NS_PER_BEAD_STEP", {"elastic": 1e-2, "general": 1e-2})
    base = hc.Model(hc.Chain.uniform(5, 26e-3), hc.Striker(8e-3, 0.2))

    def boom(*args, **kwargs):
        raise AssertionError("the engine ran before the warning")

    monkeypatch.setattr("hertzchain.runs.batch._pack_ensemble", boom)
    with pytest.warns(LongRunWarning, match=r"split the 3 members \(models\) into smaller batches"), \
            pytest.raises(AssertionError):
        hc.simulate_batch([base] * 3, 1e-3)


# ------------------------------------------------------------------------------------------
# crashes
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("constraint,key", [({"min_diameter_mm": 30.0}, "min_diameter_mm"),
                                            ({"max_length_mm": 10.0}, "max_length_mm"),
                                            ({"max_mass_kg": 0.001}, "max_mass_kg"),
                                            ({"min_beads": 200}, "min_beads"), ({"max_beads": 3}, "max_beads")])
def test_design_whose_geometric_constraints_no_candidate_meets(tmp_path, capsys, constraint, key):
    """A ZeroDivisionError in the boundary search (4 cases); now exit 2 naming the constraint."""
    f = _write(tmp_path / "d.toml", _design(constraints=constraint, budget=200))
    err = _error(capsys, ["design", str(f), "--out", str(tmp_path / "o"), "-q", "--no-html"])
    assert err.startswith("error: design.constraints: no candidate of the design space meets the geometric")
    assert f"design.constraints.{key} = " in err


def test_design_that_only_some_candidates_meet_still_runs_from_an_infeasible_start(tmp_path):
    """The boundary search starts only from a point inside the constraints (the crash's cause):
    a constraint most of the space breaks still ends on a feasible best."""
    from hertzchain.design import parse_design, run_design

    res = run_design(parse_design(_design(constraints={"min_diameter_mm": 25.0}, budget=120)), tmp_path)
    assert res.best["feasible"] and res.best["metrics"]["min_diameter_mm"] >= 25.0


@pytest.mark.parametrize("seed,field", [(-1, "design.seed"), (2**32, "design.seed")])
def test_design_seed_out_of_range(tmp_path, capsys, seed, field):
    f = _write(tmp_path / "d.toml", _design(seed=seed))
    assert _error(capsys, ["design", str(f), "--out", str(tmp_path / "o"), "-q"]).startswith(f"error: {field}")


def test_tiny_striker_velocity_is_refused_naming_the_field(tmp_path, capsys):
    """striker.velocity = 1e-300: a ZeroDivisionError (no motion to take a step from)."""
    err = _error(capsys, ["run", str(EXAMPLES / "chain1_elastic.toml"), "--set", "striker.velocity=1e-300", "-o",
                          str(tmp_path / "r.nc")])
    assert err.startswith("error: striker.velocity") and "1e-06" in err


@pytest.mark.parametrize("value", ["0.3\n[run]\nduration = 9", "0.3\nduration = 9", "AISI\n52100"])
def test_set_takes_exactly_one_toml_value(tmp_path, capsys, value):
    """--set 'x=0.3\\n[run]\\nduration=9' silently dropped the rest."""
    err = _error(capsys, ["run", str(EXAMPLES / "chain1_elastic.toml"), "--set", f"striker.velocity={value}", "-o",
                          str(tmp_path / "r.nc")])
    assert err.startswith("error: --set striker.velocity: takes exactly one TOML value")


def test_set_still_takes_tables_lists_and_bare_words():
    from hertzchain.config import apply_overrides

    out = apply_overrides({}, ["chain.taper={n = 30, q = 0.05}", "probes.sensors=[8, 12]", "contact.law=elastic"])
    assert out == {"chain": {"taper": {"n": 30, "q": 0.05}}, "probes": {"sensors": [8, 12]},
                   "contact": {"law": "elastic"}}


# ------------------------------------------------------------------------------------------
# strict types in the Python API
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("make,field", [
    (lambda: hc.Chain.uniform(2.7, 26e-3), "chain.n"),                 # gave 2 beads
    (lambda: hc.Chain.uniform(True, 26e-3), "chain.n"),
    (lambda: hc.Chain.uniform(3, "0.026"), "chain.diameter"),
    (lambda: hc.Chain.from_diameters(["0.02", "0.03"]), "chain.diameters"),
    (lambda: hc.Chain.from_diameters([True, 0.02]), "chain.diameters"),
    (lambda: hc.Chain.uniform(3, 26e-3).append_taper(2.5, 0.05), "chain.taper.n"),
    (lambda: hc.Chain.uniform(3, 26e-3).append_taper(2, "0.05"), "chain.taper.q"),
    (lambda: hc.Striker(velocity=True), "striker.velocity"),           # ran at 1 m/s
    (lambda: hc.Striker(velocity="0.3"), "striker.velocity"),          # crashed in math.isfinite
    (lambda: hc.Striker(diameter="8e-3"), "striker.diameter"),
    (lambda: hc.Viscoelastic("1e-6"), "contact.A"),
    (lambda: hc.Dashpot(True), "contact.gamma"),
    (lambda: hc.Probes(sample_interval="1e-7"), "run.sample_interval"),
    (lambda: hc.Probes(sensors=[2.5]), "probes.sensors[0]"),
    (lambda: hc.simulate(hc.Model(hc.Chain.uniform(3, 2e-2)), True), "run.duration"),
    (lambda: hc.simulate_batch([hc.Model(hc.Chain.uniform(3, 2e-2))] * 2, "1e-3"), "run.duration"),
])
def test_api_refuses_what_a_config_refuses(make, field):
    with pytest.raises(ConfigError) as e:
        make()
    assert e.value.field == field


_TWO = [hc.Model(hc.Chain.uniform(3, 2e-2))] * 2


@pytest.mark.parametrize("make, field, why", [
    (lambda: hc.simulate(_TWO[0], 1e-4, steps_per_radian=0), "run.steps_per_radian", ">= 10"),   # crashed
    (lambda: hc.simulate(_TWO[0], 1e-4, steps_per_radian=1e9), "run.steps_per_radian", "<= 100000"),
    (lambda: hc.simulate(_TWO[0], 1e-4, integrator="rkn4", rtol=0), "run.rtol", ">= 1e-14"),    # ran for minutes
    (lambda: hc.simulate(_TWO[0], 1e-4, integrator="dop853", rtol=0.5), "run.rtol", "<= 0.1"),
    (lambda: hc.simulate(_TWO[0], 1e-4, dt=math.nan), "run.dt", "finite"),
    (lambda: hc.simulate(_TWO[0], 1e-4, threads=10**6), "run.threads", "<= 1024"),
    (lambda: hc.simulate(_TWO[0], 1e-4, threads=2.0), "run.threads", "whole number"),
    (lambda: hc.simulate_batch(_TWO, 1e-4, dt=math.nan), "run.dt", "finite"),                  # was accepted
    (lambda: hc.simulate_batch(_TWO, 1e-4, dt=[1e-8, -1.0]), "run.dt[1]", ">= 1e-15"),
    (lambda: hc.simulate_batch(_TWO, 1e-4, n_threads=10**6), "n_threads", "<= 4096"),          # was accepted
    (lambda: hc.simulate_batch(_TWO, 1e-4, steps_per_radian=0), "run.steps_per_radian", ">= 10"),
    (lambda: hc.restitution(0.2, hc.Dashpot(1e9), 8e-3, "AISI52100", 26e-3), "law", "overdamped"),  # minutes
])
def test_api_run_keywords_are_held_to_the_config_bounds(make, field, why):
    """The keywords of simulate / simulate_batch / restitution are checked at the door as the same
    fields of a config are (the schema's BOUNDS), before any work; a collision whose damping would
    make it take ~1e13 steps is refused naming the law."""
    with pytest.raises(ConfigError) as e:
        make()
    assert e.value.field == field and why in e.value.message, e.value.message


def test_api_takes_numpy_scalars_as_numbers():
    """np.float32 velocities crashed (float32 is not JSON serialisable) when the result was built."""
    m = hc.Model(hc.Chain.uniform(np.int64(8), np.float32(26e-3)), hc.Striker(np.float64(8e-3), np.float32(0.2)),
                 law=hc.Viscoelastic(np.float32(1e-6)))
    assert type(m.striker.velocity) is float and m.striker.velocity == float(np.float32(0.2))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", hc.PulseNotReachedWarning)
        # the Verlet, as the batch runs it (integrator "auto" picks rkn4 for this law)
        ds = hc.simulate(m, np.float32(6e-4), hc.Probes(sample_interval=np.float64(1e-6)), integrator="verlet")
        batch = hc.simulate_batch([m, m], np.float32(6e-4), hc.Probes(sample_interval=1e-6))
    assert json.loads(ds.attrs["model"])["striker"]["velocity"] == pytest.approx(0.2, rel=1e-7)
    assert np.array_equal(batch["wall_force"].values[0], ds["wall_force"].values)


def test_batch_warns_once_per_kind_naming_the_members():
    """A batch printed one ElasticLimitWarning per member (10,000 lines for a 10k ensemble)."""
    base = hc.Model(hc.Chain.uniform(10, 26e-3), hc.Striker(8e-3, 0.2))
    speeds = np.where(np.arange(40) % 4 == 0, 3.0, 0.2)  # every fourth member past the elastic limit
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        hc.simulate_batch(hc.Ensemble(base, striker_velocity=speeds), 1e-3, hc.Probes(sample_interval=1e-6))
        hc.simulate_many([hc.Model(base.chain, hc.Striker(8e-3, float(v))) for v in speeds], 1e-3,
                         hc.Probes(sample_interval=1e-6))
    limits = [str(w.message) for w in caught if issubclass(w.category, ElasticLimitWarning)]
    assert len(limits) == 2
    for msg in limits:
        assert msg.startswith("10 of 40 members (member 0, 4, 8, 12, 16, 20, 24, 28, ...) pass the elastic limit; "
                              "worst: member ")


# ------------------------------------------------------------------------------------------
# misreadings: units in every table and JSON
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("columns", ["40", "80", "200"])
def test_analyze_table_headers_carry_units_in_every_width(monkeypatch, capsys, columns):
    """In a pipe or a narrow terminal the headers lost their units ('[ms]' read as a Rich style, then
    cut with an ellipsis) under a caption saying 'shown in SI'."""
    monkeypatch.setenv("COLUMNS", columns)
    assert main(["analyze", str(EXAMPLES / "scope_chain1_wall.csv"), "--sensor", "pcb_208a11"]) == 0
    out = capsys.readouterr().out
    for header in ("F_m [N]", "T [ms]", "tau [us]", "Q_F [mN s]", "Q_T [mN s]"):
        assert header in out, (columns, out)
    assert "…" not in out and "shown in SI" not in out
    assert max(len(line) for line in out.splitlines()) <= int(columns)


def test_compare_table_and_json_carry_units(monkeypatch, tmp_path, capsys):
    monkeypatch.setenv("COLUMNS", "40")
    js = tmp_path / "c.json"
    assert main(["compare", str(EXAMPLES / "scope_chain1_wall.csv"), str(EXAMPLES / "lab_chain1.toml"), "--sensor",
                 "pcb_208a11", "--out", str(tmp_path / "c.png"), "--json", str(js)]) == 0
    out = capsys.readouterr().out
    assert all(h in out for h in ("F_m [N]", "T [ms]", "tau [us]")) and "…" not in out
    units = json.loads(js.read_text())["units"]
    assert units["peak_force_diff"] == "N" and units["shift"] == "s" and units["time_of_flight"] == "s"


def test_analyze_json_rows_carry_units(capsys):
    assert main(["analyze", str(EXAMPLES / "scope_chain1_wall.csv"), "--sensor", "pcb_208a11", "--json"]) == 0
    row = json.loads(capsys.readouterr().out)[0]
    assert row["units"] == {"peak_force": "N", "peak_force_err": "N", "time_of_flight": "s",
                            "time_of_flight_err": "s", "duration": "s", "duration_err": "s",
                            "front_momentum": "N s", "tail_momentum": "N s", "baseline": "N"}
