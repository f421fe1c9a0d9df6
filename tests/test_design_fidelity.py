"""run.steps_per_radian (the adaptive step's accuracy) and the design's multi-fidelity search."""

from __future__ import annotations

import json
import tomllib

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

import hertzchain as hc
from hertzchain.cli.main import main
from hertzchain.config import build_model, parse_config
from hertzchain.design import parse_design, run_design
from hertzchain.design.objectives import (Fidelity, _records, _records_of_dataset, _Task, member_metrics, run_task,
                                         search_interval)
from hertzchain.design.problem import search_fidelity
from hertzchain.errors import ConfigError
from hertzchain.runs.batch import run_batch, simulate_batch

STRIKER = {"diameter_mm": 8.0, "velocity": 0.2}
RUN = {"duration": 2.0e-3, "sample_interval": 1e-6}


def _model(n: int = 4, q: float = 0.12) -> hc.Model:
    return hc.Model(hc.Chain.uniform(4, 26e-3).append_taper(n, q), hc.Striker(8e-3, 0.2), hc.Wall("flat"), hc.Elastic())


def _nq(**over) -> dict:
    d = {"base": {"chain": {"uniform": {"n": 4, "diameter_mm": 26.0}, "taper": {"n": 4, "q": 0.05}},
                  "striker": dict(STRIKER), "run": dict(RUN)},
         "design": {"variables": {"chain.taper.n": [2, 12], "chain.taper.q": [0.0, 0.15]},
                    "constraints": {"min_diameter_mm": 15.0}, "budget": 120, "seed": 2}}
    d["design"].update(over)
    return d


def test_peak_error_shrinks_as_the_square_of_the_step():
    """Verlet is second order: the peak wall force's error falls as (1 / steps_per_radian)^2. Reference:
    6400 steps per radian (within 2e-9 of DOP853 at rtol 1e-12, 40x below the smallest error fitted)."""
    model = _model()
    probes = hc.Probes(sample_interval=1e-6, contacts=())
    ref = hc.simulate(model, 2e-3, probes, steps_per_radian=6400).attrs["peak_wall_force"]
    dop = hc.simulate(model, 2e-3, probes, integrator="dop853", rtol=1e-12).attrs["peak_wall_force"]
    assert abs(ref - dop) / dop < 5e-9
    cs = np.array([100.0, 200.0, 400.0, 800.0])
    err = [abs(hc.simulate(model, 2e-3, probes, steps_per_radian=c).attrs["peak_wall_force"] - ref) / ref for c in cs]
    order = -np.polyfit(np.log(cs), np.log(err), 1)[0]
    assert 1.7 < order < 2.3  # measured 1.88
    assert np.all(np.diff(err) < 0)
    # The default is the calibrated 400 (bit for bit), and the config's field reaches the engine.
    default = hc.simulate(model, 2e-3, probes, integrator="verlet").attrs["peak_wall_force"]
    assert default == hc.simulate(model, 2e-3, probes, steps_per_radian=400).attrs["peak_wall_force"]
    cfg = {"chain": {"uniform": {"n": 4, "diameter_mm": 26.0}, "taper": {"n": 4, "q": 0.12}}, "striker": STRIKER,
           "probes": {"contacts": []}, "run": {**RUN, "steps_per_radian": 20.0}}
    # (the config's 26.0 mm x 1e-3 is one ulp away from the 26e-3 m of _model: the same chain is compared)
    coarse = hc.run_config(cfg).attrs["peak_wall_force"]
    assert coarse == hc.simulate(build_model(parse_config(cfg)), 2e-3, probes,
                                 steps_per_radian=20).attrs["peak_wall_force"]
    coarse = hc.simulate(model, 2e-3, probes, steps_per_radian=20).attrs["peak_wall_force"]
    assert abs(coarse - default) / default > 1e-6
    # The batched engine takes it too, bit-identical to single runs.
    ds = simulate_batch([model, _model(6, 0.05)], 2e-3, probes, steps_per_radian=20)
    assert ds["peak_wall_force"].values[0] == coarse


@pytest.mark.parametrize("value", [5.0, 2e5, "fast", True])
def test_bad_steps_per_radian_names_the_field(value, tmp_path, capsys):
    with pytest.raises(ConfigError) as exc:
        parse_config({"chain": {"diameters_mm": [26.0] * 4}, "run": {"steps_per_radian": value}})
    assert exc.value.field == "run.steps_per_radian"
    if isinstance(value, float):
        f = tmp_path / "run.toml"
        f.write_text('[chain]\ndiameters_mm = [26.0, 26.0]\n')
        assert main(["run", str(f), "--out", str(tmp_path / "r.nc"), "--set", f"run.steps_per_radian={value}"]) == 2
        assert "run.steps_per_radian" in capsys.readouterr().err


@pytest.mark.parametrize("value", [5.0, "coarse", True])
def test_bad_search_steps_per_radian_names_the_field(value):
    with pytest.raises(ConfigError) as exc:
        parse_design(_nq(search_steps_per_radian=value))
    assert exc.value.field == "design.search_steps_per_radian"
    with pytest.raises(ConfigError) as exc:
        parse_design(_nq(verify_top=0))
    assert exc.value.field == "design.verify_top"


def test_a_budget_that_only_pays_for_the_verification_is_refused(tmp_path):
    with pytest.raises(ConfigError) as exc:
        run_design(parse_design(_nq(budget=4)), tmp_path)
    assert exc.value.field == "design.budget" and "verify_top" in exc.value.message


def test_search_fidelity_is_coarse_only_where_it_cannot_change_the_answer():
    p = parse_design(_nq())
    assert search_fidelity(p) == Fidelity("search", 20.0, True)
    # Objectives read off sampled records, sampled constraints: the base sampling.
    assert not search_fidelity(parse_design(_nq(objective="peak_contact_force"))).coarse_sampling
    assert not search_fidelity(parse_design(_nq(constraints={"max_force_over_yield": 1.0}))).coarse_sampling
    # "full", a fixed step, Pareto fronts: the search runs at the base config's accuracy.
    assert search_fidelity(parse_design(_nq(search_steps_per_radian="full"))) == Fidelity()
    fixed = _nq()
    fixed["base"]["run"]["dt"] = 2e-8
    assert search_fidelity(parse_design(fixed)) == Fidelity()
    assert search_fidelity(parse_design(_nq(objective=["peak_wall_force", "front_momentum_at_wall"]))) == Fidelity()


def test_coarse_sampling_keeps_the_wall_pulse_resolved():
    """A coarse search call samples every k base intervals, k leaving >= 10 samples in the shortest
    wall pulse its members can give (all the striker's energy in the last bead); the pulse-arrival
    check then judges every member as it does at the base sampling."""
    models = [_model(n, q) for n, q in ((2, 0.0), (4, 0.1285), (12, 0.0448), (12, 0.15))]
    probes = hc.Probes(sample_interval=1e-6, contacts=())
    assert search_interval(models[:3], 1e-6, 2e-3) == 5 * 1e-6  # last beads >= 15 mm
    assert search_interval(models, 1e-6, 2e-3) == 1e-6  # a 3.7 mm last bead: no room to coarsen
    from dataclasses import replace

    assert search_interval([replace(models[0], precompression=1.0)], 1e-6, 2e-3) == 1e-6  # faster waves
    interval = search_interval(models[:3], 1e-6, 2e-3)
    fine = simulate_batch(models[:3], 2e-3, probes)
    coarse = simulate_batch(models[:3], 2e-3, hc.Probes(sample_interval=interval, contacts=()), steps_per_radian=20)
    wall = fine["wall_force"].values
    for i in range(3):
        # the measured half-width of the wall pulse holds more than 10 coarse samples
        above = np.flatnonzero(wall[i] >= 0.5 * wall[i].max())
        assert (above[-1] - above[0]) * 1e-6 > 10 * interval
    task = _Task(models[:3], 2e-3, hc.Probes(sample_interval=interval, contacts=()), None, ["peak_wall_force"], None,
                 steps_per_radian=20)
    out = run_task(task)
    assert out["pulse_at_wall"].all() and out["energy_ok"].all()
    np.testing.assert_allclose(out["peak_wall_force"], fine["peak_wall_force"].values, rtol=1e-4)
    np.testing.assert_array_equal(out["peak_wall_force"], coarse["peak_wall_force"].values)


def test_engine_arrays_give_the_metrics_of_the_stacked_result():
    """The design reads the engine's arrays (run_batch) instead of a stacked Dataset: same numbers."""
    models = [_model(n, q) for n, q in ((2, 0.0), (5, 0.08), (9, 0.03))]
    probes = hc.Probes(sample_interval=1e-6, contacts=())
    names = ["peak_wall_force", "peak_contact_force", "max_force_over_yield", "front_momentum_at_wall",
             "energy_at_wall"]
    ds = simulate_batch(models, 2e-3, probes)
    runs, systems = run_batch(models, 2e-3, probes, return_systems=True)
    a = member_metrics(ds, names)
    task = _Task(models, 2e-3, probes, None, names, None)
    b = run_task(task)
    for k in a:
        np.testing.assert_array_equal(a[k], b[k])
    ra, rb = _records_of_dataset(ds), _records(runs, systems)
    for k in ("wall", "peak_wall_force", "kinetic", "potential", "dissipated", "kappa_wall"):
        np.testing.assert_array_equal(getattr(ra, k), getattr(rb, k))


def test_coarse_search_best_is_the_full_accuracy_value_of_best_toml(tmp_path):
    """The search runs coarse; the best few are run again at the base accuracy and design.json holds
    that value, which `hertzchain run best.toml` reproduces (best.toml carries no coarse setting)."""
    f = tmp_path / "d.toml"
    import tomli_w

    f.write_text(tomli_w.dumps(_nq()))
    out = tmp_path / "out"
    assert main(["design", str(f), "--out", str(out), "-q", "--no-html"]) == 0
    info = json.loads((out / "design.json").read_text())
    best_toml = tomllib.loads((out / "best.toml").read_text())
    assert best_toml["run"].get("steps_per_radian", 400.0) == 400.0
    assert main(["run", str(out / "best.toml"), "--out", str(tmp_path / "best.nc"), "-q"]) == 0
    import xarray as xr

    with xr.open_dataset(tmp_path / "best.nc") as ds:
        assert ds.attrs["peak_wall_force"] == pytest.approx(info["best"]["objective"], rel=1e-6)
    import pandas as pd

    hist = pd.read_csv(out / "history.csv")
    assert set(hist["fidelity"]) == {"search", "full"}
    full = hist[hist["fidelity"] == "full"]
    assert len(full) == 4 and set(full["phase"]) == {"verify"}  # design.verify_top
    # The verified rows are the four best distinct feasible search rows, and the coarse value differed.
    search = hist[(hist["fidelity"] == "search") & hist["feasible"]].drop_duplicates("chain.taper.q")
    top = search.nsmallest(4, "peak_wall_force")
    assert sorted(full["chain.taper.q"]) == sorted(top["chain.taper.q"])
    best = full.loc[full["peak_wall_force"].idxmin()]
    assert best["peak_wall_force"] == info["best"]["objective"]
    coarse = search[search["chain.taper.q"] == best["chain.taper.q"]]["peak_wall_force"].iloc[0]
    assert 0 < abs(coarse - best["peak_wall_force"]) / best["peak_wall_force"] < 1e-3
    assert info["n_evaluations"] <= 120


def test_a_candidate_infeasible_at_full_accuracy_is_dropped(tmp_path, monkeypatch):
    """A candidate that met a run constraint only at search accuracy never becomes the best."""
    import hertzchain.design.objectives as objectives

    real = objectives.run_task
    dropped = []

    def strict_full(task):
        out = real(task)
        if task.steps_per_radian == 400.0 and not dropped:  # the first full-accuracy call: its best fails
            i = int(np.argmin(out["peak_wall_force"]))
            out["pulse_at_wall"][i] = False
            dropped.append(float(out["peak_wall_force"][i]))
        return out

    monkeypatch.setattr(objectives, "run_task", strict_full)
    res = run_design(parse_design(_nq(verify_top=2)), tmp_path)
    full = [r for r in res.history if r["fidelity"] == "full"]
    assert len(full) == 2 and sum(not r["feasible"] for r in full) == 1
    assert res.best["feasible"] and res.best["objective"] > dropped[0]
    assert res.best["objective"] == min(r["peak_wall_force"] for r in full if r["feasible"])


def test_a_candidate_past_a_geometric_constraint_moves_onto_its_boundary():
    """Root finding on the geometry alone: from a feasible taper (n = 4, q = 0.05) towards one whose
    last bead is below 15 mm, the point found meets the constraint and lies within 2^-steps of the
    exact boundary q* = 1 - (15/26)^(1/4) (26 (1 - q)^4 = 15 mm) or within the boundary slack
    (last bead under 15 mm x (1 + slack)); it takes fewer geometry checks than bisection."""
    from hertzchain.design.boundary import _BOUNDARY_SLACK, _to_boundary
    from hertzchain.design.objectives import Evaluator

    p = parse_design(_nq())
    ev = Evaluator(p.objectives, p.section.constraints)
    n_bin = (4 - 2 + 0.5) / 11  # unit coordinate of the integer bin n = 4 (2..12)
    good, bad = np.array([n_bin, 0.05 / 0.15]), np.array([n_bin, 1.0])
    steps = 12
    x = _to_boundary(p, ev, good, bad, steps)
    checks = ev.candidates  # one chain built per distinct point checked
    vals = p.space.values(x)
    q_star = 1 - (15 / 26) ** 0.25
    last = 26 * (1 - vals["chain.taper.q"]) ** 4
    assert vals["chain.taper.n"] == 4
    assert last >= 15.0
    assert q_star - (0.15 - 0.05) * 2.0 ** -steps <= vals["chain.taper.q"] <= q_star or last <= 15.0 * (1 + _BOUNDARY_SLACK)
    assert len(checks) < 2 + steps  # the two ends and fewer than bisection's steps


@settings(max_examples=150, deadline=None)
@given(st.floats(0, 1), st.floats(0, 1), st.floats(0, 1), st.floats(0, 1))
def test_the_boundary_search_ends_on_the_feasible_side_within_its_check_budget(n_good, q_good, n_bad, q_bad):
    """Property, on any segment of the n-q space from a point that meets the 15 mm limit to one
    that breaks it (across bead counts too, where the margin jumps): the boundary search
    (Chandrupatla's method) returns a point that meets the limit, after at most 2 (steps + 1)
    geometry checks; on a segment within one bead count, within the accepted band or 2^-steps
    of the segment from the exact boundary q*(n) = 1 - (15/26)^(1/n)."""
    from hertzchain.design.objectives import Evaluator
    from hertzchain.design.search import _BOUNDARY_SLACK, _margin, _to_boundary

    p = parse_design(_nq())
    ev = Evaluator(p.objectives, p.section.constraints)
    good, bad = np.array([n_good, q_good]), np.array([n_bad, q_bad])
    f_good, f_bad = _margin(p, ev, good), _margin(p, ev, bad)
    assume(f_good >= 0 > f_bad)
    before = len(ev.candidates)  # the ends are checked: every new entry is one check of the search
    steps = 6
    y = _to_boundary(p, ev, good, bad, steps, f_good, f_bad)
    assert len(ev.candidates) - before <= 2 * (steps + 1)
    margin = _margin(p, Evaluator(p.objectives, p.section.constraints), y)
    assert margin >= 0
    vals = [p.space.values(x) for x in (good, bad, y)]
    n = vals[0]["chain.taper.n"]
    if vals[1]["chain.taper.n"] == n:
        q_star = 1 - (15 / 26) ** (1 / n)
        span = abs(vals[1]["chain.taper.q"] - vals[0]["chain.taper.q"])
        assert margin <= _BOUNDARY_SLACK or q_star - vals[2]["chain.taper.q"] <= span * 2.0 ** -steps


@pytest.mark.parametrize("seed", [1, 2, 3, 4, 5])
def test_the_first_generation_holds_the_boundary_point_of_every_bead_count_it_samples(seed):
    """Known answer: with no bead below 15 mm, the steepest taper of n beads after 26 mm beads is
    q*(n) = 1 - (15/26)^(1/n) (q* < 0.15, the box's edge, from n = 4 on). The first generation
    (Latin hypercube, repair, and the choices' boundary points) holds, for every bead count it
    samples, a point that meets the limit within the repair's resolution (2^-6 of the q range
    or the boundary slack) at q*(n), or at the box's edge q = 0.15 where the whole range is
    allowed, and only one such point per bead count (no near-copies to pay runs for); and no
    point breaks the limit."""
    from scipy.stats import qmc

    from hertzchain.design.boundary import _BOUNDARY_SLACK, _REPAIR_STEPS, _repair_initial
    from hertzchain.design.objectives import Evaluator
    from hertzchain.design.search import _initial_sample

    p = parse_design(_nq(seed=seed))
    ev = Evaluator(p.objectives, p.section.constraints)
    xs = list(qmc.LatinHypercube(d=2, seed=np.random.default_rng([seed, 11])).random(_initial_sample(p)))
    points = [p.space.values(x) for x in _repair_initial(p, ev, xs)]
    sampled = {p.space.values(x)["chain.taper.n"] for x in xs}
    for n in sampled:
        q_star = min(1 - (15 / 26) ** (1 / n), 0.15)
        qs = np.array([v["chain.taper.q"] for v in points if v["chain.taper.n"] == n])
        last = 26 * (1 - qs) ** n
        assert np.all(last >= 15.0)
        near = (qs >= q_star - 0.15 * 2.0 ** -_REPAIR_STEPS) | (last <= 15.0 * (1 + _BOUNDARY_SLACK))
        assert near.any(), (n, q_star, qs)
        # One real coordinate: a choice's boundary point is found once and shared, so the points
        # that are not sampled ones (repaired or added) hold one q per bead count, no near-copies.
        moved = {v["chain.taper.q"] for v in points if v["chain.taper.n"] == n} - {
            v["chain.taper.q"] for v in (p.space.values(x) for x in xs) if v["chain.taper.n"] == n}
        assert len(moved) <= 1, (n, moved)


def test_sweeps_run_at_the_base_steps_per_radian_and_refuse_to_vary_it(tmp_path):
    """run.steps_per_radian is a shared run setting of a sweep (one batched engine call per chunk)."""
    import xarray as xr

    from hertzchain.sweep import parse_sweep, run_sweep

    base = {"chain": {"uniform": {"n": 3, "diameter_mm": 10.0}}, "striker": {"diameter_mm": 8.0, "velocity": 0.2},
            "run": {"duration": 2e-4, "sample_interval": 1e-6, "steps_per_radian": 20.0}}
    sweep = {"mode": "grid", "chunk_size": 4, "parameters": {"striker.velocity": [0.1, 0.3]}}
    res = run_sweep({"base": base, "sweep": sweep}, tmp_path / "s")
    with xr.open_mfdataset(sorted((res.out_dir / "chunks").glob("*.nc")), combine="by_coords") as ds:
        peaks = ds["peak_wall_force"].values
    for v, peak in zip((0.1, 0.3), peaks):
        model = hc.Model(hc.Chain.uniform(3, 10e-3), hc.Striker(8e-3, v), hc.Wall("flat"), hc.Elastic())
        ref = hc.simulate(model, 2e-4, hc.Probes(sample_interval=1e-6), steps_per_radian=20)
        assert peak == ref.attrs["peak_wall_force"]
        assert peak != hc.simulate(model, 2e-4, hc.Probes(sample_interval=1e-6)).attrs["peak_wall_force"]
    with pytest.raises(ConfigError) as exc:
        parse_sweep({"base": base, "sweep": {**sweep, "parameters": {"run.steps_per_radian": [20.0, 40.0]}}})
    assert "run.steps_per_radian" in exc.value.field
