"""hertzchain design: known optima found by brute force, constraints, resumption, seeds, errors, physics."""

from __future__ import annotations

import copy
import itertools
import json
import os

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.cli.main import main
from hertzchain.design import parse_design, run_design, write_report
from hertzchain.runs.batch import simulate_batch

STRIKER = {"diameter_mm": 8.0, "velocity": 0.2}
# Sampling every 1 us: the engine refines the wall peak between samples, so the objective does
# not depend on it, and the pulse (~50 us wide) is still resolved for the arrival check.
RUN = {"duration": 2.0e-3, "sample_interval": 1e-6}


def _nq_design(**over) -> dict:
    d = {"base": {"chain": {"uniform": {"n": 4, "diameter_mm": 26.0}, "taper": {"n": 4, "q": 0.05}},
                  "striker": dict(STRIKER), "run": dict(RUN)},
         "design": {"objective": "peak_wall_force",
                    "variables": {"chain.taper.n": [2, 12], "chain.taper.q": [0.0, 0.15]},
                    "constraints": {"min_diameter_mm": 15.0}, "budget": 260, "seed": 3}}
    d["design"].update(over)
    return d


def _peaks(chains: list) -> np.ndarray:
    models = [hc.Model(c, hc.Striker(8e-3, 0.2), hc.Wall("flat"), hc.Elastic()) for c in chains]
    ds = simulate_batch(models, RUN["duration"], hc.Probes(sample_interval=RUN["sample_interval"], contacts=()))
    # Every grid chain's wall pulse has come and gone within the run (else its peak would be cut short).
    wall = ds["wall_force"].values
    assert np.all(wall[:, -1] < 0.5 * wall.max(axis=1))
    return ds["peak_wall_force"].values


def test_nq_grid_with_min_diameter_matches_brute_force(tmp_path):
    """Exponential taper (n, q) under phi_min >= 15 mm: the search is within 1 % of a brute-force grid
    that includes, for every n, the largest admissible q (where the optimum of each n lies)."""
    grid = []
    for n in range(2, 13):
        q_max = min(0.15, 1.0 - (15.0 / 26.0) ** (1.0 / n))  # 26 (1 - q)^n >= 15 mm
        grid += [(n, q) for q in np.linspace(0.0, q_max, 9)]
    chains = [hc.Chain.uniform(4, 26e-3).append_taper(n, q) for n, q in grid]
    brute = float(_peaks(chains).min())

    res = run_design(parse_design(_nq_design()), tmp_path)
    assert res.best["feasible"]
    assert res.best["objective"] <= 1.01 * brute
    assert res.n_evaluations <= 260
    # Constraints are never violated by the best, and every row called feasible meets them.
    assert res.best["metrics"]["min_diameter_mm"] >= 15.0
    assert all(r["min_diameter_mm"] >= 15.0 for r in res.history if r["feasible"])
    n, q = res.best["variables"]["chain.taper.n"], res.best["variables"]["chain.taper.q"]
    assert isinstance(n, int) and 26.0 * (1 - q) ** n >= 15.0


def test_three_bead_catalogue_matches_brute_force(tmp_path):
    """Free-form 3-bead chain from a catalogue of sizes, total length <= 60 mm: the exhaustive optimum.

    The peak wall force of so short a chain is a rugged function of the diameters (the striker and
    the beads collide several times and the reflected pulses interfere), so the known answer is
    the exhaustive one over a coarse catalogue rather than a grid approximation of a continuum."""
    sizes = [10.0, 14.0, 18.0, 22.0, 26.0, 30.0]
    run = {"duration": 1.0e-3, "sample_interval": 1e-6}
    combos = [c for c in itertools.product(sizes, repeat=3) if sum(c) <= 60.0]
    models = [hc.Model(hc.Chain.from_diameters(np.array(c) * 1e-3), hc.Striker(8e-3, 0.2), hc.Wall("flat"),
                       hc.Elastic()) for c in combos]
    ds = simulate_batch(models, run["duration"], hc.Probes(sample_interval=run["sample_interval"], contacts=()))
    best_i = int(np.argmin(ds["peak_wall_force"].values))
    brute = float(ds["peak_wall_force"].values[best_i])

    design = {"base": {"chain": {"diameters_mm": [20.0, 20.0, 20.0]}, "striker": dict(STRIKER), "run": run},
              "design": {"variables": {"chain.diameters_mm[0:3]": {"low": 10.0, "high": 30.0, "catalogue": sizes}},
                         "constraints": {"max_length_mm": 60.0}, "budget": 100, "seed": 2}}
    res = run_design(parse_design(design), tmp_path)
    assert res.best["feasible"]
    assert res.best["objective"] <= 1.01 * brute
    chosen = res.best["variables"]["chain.diameters_mm[0:3]"]
    assert all(d in sizes for d in chosen) and sum(chosen) <= 60.0 + 1e-9
    assert all(r["length_mm"] <= 60.0 + 1e-9 for r in res.history if r["feasible"])


def test_killed_design_resumes_to_the_same_result_and_seed_reproduces(tmp_path):
    problem = parse_design(_nq_design(budget=120))
    ref = run_design(problem, tmp_path / "a")

    calls = []

    def killer(done, total):
        calls.append(done)
        if len(calls) == 4:  # after the third generation's checkpoint
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_design(parse_design(_nq_design(budget=120)), tmp_path / "b", progress=killer, checkpoint_interval=0)
    assert (tmp_path / "b" / "checkpoint.npz").exists()
    resumed = run_design(parse_design(_nq_design(budget=120)), tmp_path / "b")
    assert resumed.resumed
    assert resumed.best["variables"] == ref.best["variables"]
    assert resumed.best["objective"] == ref.best["objective"]
    assert resumed.n_evaluations == ref.n_evaluations
    assert [r["x"] for r in resumed.history] == [r["x"] for r in ref.history]
    other = run_design(parse_design(_nq_design(budget=120, seed=4)), tmp_path / "c")
    assert [r["x"] for r in other.history] != [r["x"] for r in ref.history]


def _write_design(path, data: dict) -> None:
    import tomli_w

    path.write_text(tomli_w.dumps(data))


def test_cli_outputs_and_best_toml_reproduces_the_objective(tmp_path):
    f = tmp_path / "d.toml"
    _write_design(f, _nq_design(budget=80, polish=False))
    out = tmp_path / "out"
    assert main(["design", str(f), "--out", str(out), "-q"]) == 0
    info = json.loads((out / "design.json").read_text())
    assert info["objective_name"] == "peak_wall_force"
    assert set(info["best"]) >= {"objective", "variables"}
    assert set(info["best"]["variables"]) == {"chain.taper.n", "chain.taper.q"}
    assert 0 < info["n_evaluations"] <= 80
    for name in ("best.toml", "history.csv", "design.html"):
        assert (out / name).stat().st_size > 0
    ds = hc.run_config(out / "best.toml")
    assert ds.attrs["peak_wall_force"] == pytest.approx(info["best"]["objective"], rel=1e-6)
    # A rerun of a finished design resumes from its checkpoint and reports the same best.
    assert main(["design", str(f), "--out", str(out), "-q"]) == 0
    assert json.loads((out / "design.json").read_text())["best"] == info["best"]


@pytest.mark.parametrize("change, field", [
    (lambda d: d["design"].update(budget=0), "design.budget"),
    (lambda d: d["design"].update(objective="peak_force"), "design.objective"),
    (lambda d: d["design"].update(variables={"chain.taper.q": [0.3, 0.1]}), 'design.variables["chain.taper.q"]'),
    (lambda d: d["design"].update(variables={"chain.taper..q": [0.0, 0.1]}), 'design.variables["chain.taper..q"]'),
    (lambda d: d["design"].update(variables={"chain.diameters_mm[0:3]": [10.0, 20.0]}),
     'design.variables["chain.diameters_mm[0:3]"]'),
    (lambda d: d["design"].update(constraints={"min_diameter": 10.0}), "design.constraints.min_diameter"),
    (lambda d: d["design"].update(colour="red"), "design.colour"),
    (lambda d: d["base"]["chain"]["taper"].update(q=1.5), "base.chain.taper.q"),
    (lambda d: d["design"].update(variables={"chain.taper.q": [0.0, 1.2]}), "chain.taper.q"),
])
def test_bad_design_files_name_the_field_and_exit_2(tmp_path, capsys, change, field):
    data = copy.deepcopy(_nq_design())
    change(data)
    f = tmp_path / "bad.toml"
    _write_design(f, data)
    assert main(["design", str(f), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert field in err and "Traceback" not in err


def test_infeasible_candidates_never_win_and_pulse_must_reach_the_wall(tmp_path):
    """A run too short for the pulse makes every design infeasible (no wall pulse = no free win)."""
    data = _nq_design(budget=40, polish=False, population=8)
    data["base"]["run"]["duration"] = 2e-4
    res = run_design(parse_design(data), tmp_path)
    assert not res.best["feasible"]
    assert not any(r["feasible"] for r in res.history)
    assert all(not r["pulse_at_wall"] for r in res.history if "pulse_at_wall" in r)


def test_best_taper_of_the_paper_length_beats_its_base_and_a_uniform_chain(tmp_path):
    """Physics: an exponentially tapered chain no longer than chain 1 (660.65 mm) and with no bead below
    its smallest (11 mm) transmits a smaller peak force to the wall than the design's base chain
    (16 x 26 mm, then 14 beads tapered with q = 0.05) and than a uniform chain of as many beads.
    The references are like for like: the base configuration itself, and the uniform chain with
    the best design's bead count, the base chain's first diameter and material, the same run."""
    length_chain1 = sum(hc.TABLE_I_MM["chain1"])
    design = {"base": {"chain": {"uniform": {"n": 16, "diameter_mm": 26.0}, "taper": {"n": 14, "q": 0.05}},
                       "striker": dict(STRIKER), "run": {"duration": 3.0e-3, "sample_interval": 1e-6}},
              "design": {"variables": {"chain.uniform.n": [8, 24], "chain.taper.n": [2, 22],
                                       "chain.taper.q": [0.0, 0.2]},
                         "constraints": {"min_diameter_mm": 11.0, "max_length_mm": length_chain1},
                         "budget": 300, "seed": 1}}
    res = run_design(parse_design(design), tmp_path)
    assert res.best["feasible"] and res.best["metrics"]["length_mm"] <= length_chain1 + 1e-9
    info = write_report(res, figures=False)
    cmp = info["comparison"]
    assert set(cmp) == {"best", "base", "uniform", "no_chain", "improvement_percent"}
    # no chain (the striker onto the wall, issue 36): the two-body Hertz impact, far above any chain's
    assert cmp["no_chain"]["n_beads"] == 0 and cmp["no_chain"]["peak_wall_force"] > cmp["uniform"]["peak_wall_force"]
    assert info["comparison"]["improvement_percent"]["no_chain"]["peak_wall_force"] > 80.0
    assert cmp["uniform"]["n_beads"] == cmp["best"]["n_beads"] and cmp["base"]["n_beads"] == 30
    assert cmp["best"]["peak_wall_force"] < cmp["base"]["peak_wall_force"] < cmp["uniform"]["peak_wall_force"]
    imp = info["comparison"]["improvement_percent"]
    assert imp["base"]["peak_wall_force"] == pytest.approx(
        100 * (1 - cmp["best"]["peak_wall_force"] / cmp["base"]["peak_wall_force"]))
    assert imp["base"]["peak_wall_force"] > 5.0 and imp["uniform"]["peak_wall_force"] > 20.0
    # The base reference is what hertzchain.simulate gives for the base config itself, on the
    # design's engine (the Verlet; integrator "auto" would pick rkn4 for this elastic chain)
    verlet = {**design["base"].get("run", {}), "integrator": "verlet"}
    alone = hc.run_config({**design["base"], "run": verlet})
    assert cmp["base"]["peak_wall_force"] == pytest.approx(alone.attrs["peak_wall_force"], rel=1e-12)
    uni = hc.run_config({**design["base"], "chain": {"uniform": {"n": cmp["best"]["n_beads"], "diameter_mm": 26.0}},
                         "run": verlet})
    assert cmp["uniform"]["peak_wall_force"] == pytest.approx(uni.attrs["peak_wall_force"], rel=1e-12)
    assert info["objective_label"] == "peak_wall_force"


def test_other_design_in_the_same_folder_needs_force(tmp_path, capsys):
    f = tmp_path / "d.toml"
    _write_design(f, _nq_design(budget=40, polish=False, population=8))
    out = tmp_path / "out"
    assert main(["design", str(f), "--out", str(out), "-q", "--no-html"]) == 0
    _write_design(f, _nq_design(budget=40, polish=False, population=8, seed=9))
    assert main(["design", str(f), "--out", str(out), "-q", "--no-html"]) == 2
    assert "different design" in capsys.readouterr().err
    assert main(["design", str(f), "--out", str(out), "-q", "--no-html", "--force"]) == 0
    assert json.loads((out / "design.json").read_text())["seed"] == 9


def test_a_folder_in_use_by_another_search_is_refused(tmp_path, capsys):
    from hertzchain.design.search import DesignLocked
    from hertzchain.sweep.storage import _folder_lock

    f = tmp_path / "d.toml"
    _write_design(f, _nq_design(budget=40, polish=False, population=8))
    out = tmp_path / "out"
    out.mkdir()
    with _folder_lock(out, "design", DesignLocked):  # as another process's search would hold it
        assert main(["design", str(f), "--out", str(out), "-q", "--no-html"]) == 2
        assert "in use by another design" in capsys.readouterr().err
    assert main(["design", str(f), "--out", str(out), "-q", "--no-html"]) == 0


@pytest.mark.slow
def test_dask_scheduler_spreads_generations_with_the_same_result(tmp_path):
    distributed = pytest.importorskip("distributed")
    f = tmp_path / "d.toml"
    _write_design(f, _nq_design(budget=60, population=12, chunk_size=4))
    assert main(["design", str(f), "--out", str(tmp_path / "here"), "-q", "--no-html"]) == 0
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cl:
        assert main(["design", str(f), "--out", str(tmp_path / "dask"), "-q", "--no-html",
                     "--scheduler", cl.scheduler_address]) == 0
    a = json.loads((tmp_path / "here" / "design.json").read_text())
    b = json.loads((tmp_path / "dask" / "design.json").read_text())
    assert a["best"] == b["best"] and a["n_evaluations"] == b["n_evaluations"]


def test_a_generation_too_large_for_memory_is_refused_naming_the_population(tmp_path, capsys, monkeypatch):
    import hertzchain.checks as checks

    # 2 MB: 200 members of 2 ms sampled every 5 us (the coarse search of this problem) need ~3 MB
    monkeypatch.setattr(checks, "available_memory", lambda: 2_000_000)
    f = tmp_path / "d.toml"
    _write_design(f, _nq_design(budget=400, population=200))
    assert main(["design", str(f), "--out", str(tmp_path / "out"), "-q", "--no-html"]) == 2
    assert "design.population" in capsys.readouterr().err


def test_device_option_reaches_the_engine(tmp_path, capsys):
    from hertzchain.integrate.cuda import launch as cuda

    f = tmp_path / "d.toml"
    _write_design(f, _nq_design(budget=40, polish=False, population=8))
    assert main(["design", str(f), "--out", str(tmp_path / "cpu"), "-q", "--no-html", "--device", "cpu"]) == 0
    if not cuda.gpu_usable():
        assert main(["design", str(f), "--out", str(tmp_path / "gpu"), "-q", "--no-html", "--device", "cuda"]) == 2
        assert "--device" in capsys.readouterr().err


@pytest.mark.parametrize("robust, label", [
    (None, "peak_wall_force"),
    ({"velocities": [0.2, 0.3], "draws": 2, "tolerances": {"diameter_rel": 0.001, "seed": 1},
      "statistic": "mean+ksigma", "k": 2.0}, "peak_wall_force, mean + 2 sigma over 4 scenarios"),
    ({"velocities": [0.2, 0.3], "statistic": "worst"}, "peak_wall_force, worst case over 2 scenarios"),
])
def test_the_printed_objective_says_how_scenarios_are_summarised(robust, label):
    from hertzchain.design.report import objective_label

    data = _nq_design(budget=40, polish=False, population=8)
    if robust is not None:
        data["design"]["robust"] = robust
    assert objective_label(parse_design(data)) == label
