"""The elastoplastic law through the many-run tools: sweeps, designs, fits (known answers)."""

from __future__ import annotations

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.design import parse_design, run_design
from hertzchain.errors import ConfigError
from hertzchain.lab import Trace, fit_traces, read_trace
from hertzchain.sweep import run_sweep

from lab_files import write_tds_csv

# Short brass chains (brass yields early: sigma_Y = 200 MPa, v_y ~ 7 mm/s for an 8 mm striker).
BASE = {"chain": {"uniform": {"n": 4, "diameter_mm": 12.0}, "material": "brass"},
        "striker": {"diameter_mm": 8.0, "velocity": 0.2, "material": "brass"},
        "contact": {"law": "elastoplastic"},
        "run": {"duration": 4e-4, "sample_interval": 1e-6}}


def test_sweep_table_has_the_plastic_metrics_of_single_runs(tmp_path):
    speeds = [0.002, 0.1, 0.4]
    res = run_sweep({"base": BASE, "sweep": {"mode": "grid", "chunk_size": 2,
                                             "parameters": {"striker.velocity": speeds}}}, tmp_path)
    df = res.metrics
    # (on the sweep's integrator: a batch steps the elastic-plastic law with the Verlet, a single
    # run's auto takes rkn4)
    single = [hc.run_config({**BASE, "striker": {**BASE["striker"], "velocity": v},
                             "run": {**BASE.get("run", {}), "integrator": "verlet"}}) for v in speeds]
    assert df["plastic_work"].tolist() == [ds.attrs["plastic_work"] for ds in single]
    assert df["residual_overlap_max"].tolist() == [ds.attrs["residual_overlap_max"] for ds in single]
    # below the yield velocity nothing yields; above, the loss grows with the impact energy
    assert df["plastic_work"][0] == 0.0 and df["residual_overlap_max"][0] == 0.0
    assert 0 < df["plastic_work"][1] < df["plastic_work"][2]
    # an elastic sweep has no such columns
    elastic = {**BASE, "contact": {"law": "elastic"}}
    res = run_sweep({"base": elastic, "sweep": {"mode": "grid", "parameters": {"striker.velocity": [0.1]}}},
                    tmp_path / "elastic")
    assert "plastic_work" not in res.metrics


def _design(objective, constraints=None, law="elastoplastic"):
    base = {**BASE, "contact": {"law": law}, "run": {"duration": 6e-4, "sample_interval": 1e-6},
            "chain": {"uniform": {"n": 3, "diameter_mm": 12.0}, "taper": {"n": 3, "q": 0.08}, "material": "brass"}}
    return {"base": base, "design": {"objective": objective, "variables": {"chain.uniform.diameter_mm": [8.0, 14.0]},
                                     "constraints": constraints or {}, "budget": 40, "seed": 1}}


def _brute(diameters):
    """Plastic work [J], largest residual overlap [m] and peak wall force [N] of the design's chains."""
    base = _design("plastic_work")["base"]
    models = [hc.build_model(hc.parse_config({**base, "chain": {**base["chain"], "uniform": {
        "n": 3, "diameter_mm": float(d)}}})) for d in diameters]
    ds = hc.simulate_batch(models, base["run"]["duration"], hc.Probes(sample_interval=1e-6, contacts=()))
    return {"plastic_work": ds["plastic_work"].values[:, -1],
            "residual_overlap_max": np.nanmax(ds["residual_overlap"].values, axis=1),
            "peak_wall_force": ds["peak_wall_force"].values}


GRID = np.linspace(8.0, 14.0, 31)


@pytest.fixture(scope="module")
def brute():
    return _brute(GRID)


@pytest.mark.parametrize("objective", ["plastic_work", "residual_overlap_max"])
def test_design_minimises_the_plastic_metrics_as_a_grid_does(tmp_path, brute, objective):
    # larger first beads take the striker's blow with less plastic work, smaller ones with a
    # shallower dent: the two objectives pull to opposite ends of the range
    assert np.ptp(brute[objective]) > 0.02 * brute[objective].max()
    res = run_design(parse_design(_design(objective)), tmp_path)
    assert res.best["feasible"]
    assert res.best["objective"] <= brute[objective].min() * 1.001
    d = res.best["variables"]["chain.uniform.diameter_mm"]
    assert res.best["objective"] == pytest.approx(_brute([d])[objective][0], rel=1e-6)


def test_design_plastic_constraint_holds_for_the_best(tmp_path, brute):
    """Peak wall force grows with the first beads' size: unconstrained, the smallest beads win;
    capping the plastic work just below theirs moves the best to where the cap binds."""
    limit = 0.999 * float(brute["plastic_work"][0])
    feasible = brute["plastic_work"] <= limit
    res = run_design(parse_design(_design("peak_wall_force", {"max_plastic_work": limit})), tmp_path)
    assert res.best["feasible"] and res.best["metrics"]["plastic_work_worst"] <= limit
    assert all(r["plastic_work_worst"] <= limit for r in res.history if r["feasible"])
    assert res.best["objective"] <= brute["peak_wall_force"][feasible].min() * 1.001
    assert res.best["objective"] > brute["peak_wall_force"].min()  # the cap costs wall force


def test_plastic_objectives_need_the_elastoplastic_law():
    with pytest.raises(ConfigError, match="design.objective"):
        parse_design(_design("plastic_work", law="elastic"))
    with pytest.raises(ConfigError, match="design.constraints.max_residual_overlap"):
        parse_design(_design("peak_wall_force", {"max_residual_overlap": 1e-6}, law="elastic"))


def test_fit_recovers_a_yield_stress(tmp_path):
    """The elastoplastic law's yield stress is a free field like any other: synthetic scope data
    of a chain whose contacts yield, fitted from a wrong start, give it back within 3 standard
    errors (and to better than 0.1 %: the plastic branch shapes the whole pulse)."""
    mat = {"density": 8530.0, "young": 1.1e11, "poisson": 0.35, "yield_stress": 2.0e8}
    cfg = {"materials": {"mybrass": mat}, "chain": {"uniform": {"n": 8, "diameter_mm": 20}, "material": "mybrass"},
           "striker": {"velocity": 0.3}, "contact": {"law": "elastoplastic"}, "run": {"duration": 1.0e-3}}
    true = {**cfg, "materials": {"mybrass": {**mat, "yield_stress": 2.5e8}}}
    ds = hc.run_config(true)
    assert ds.attrs["plastic_work"] > 0
    acq = hc.Instrument.pcb_208a11(sample_rate=2.5e6, noise_rms_mV=5.0, bits=12, trigger_level_N=0.5,
                                   seed=3).acquire(ds.time.values, ds.wall_force.values)
    da = read_trace(write_tds_csv(tmp_path / "y.csv", acq.time, acq.volts), sensor="pcb_208a11")
    result = fit_traces(cfg, [Trace(da)], ["materials.mybrass.yield_stress", "time_offset"])
    assert result.converged
    z = (result.values - [2.5e8, acq.trigger_time + acq.jitter[0]]) / result.stderr
    assert np.all(np.abs(z) < 3), z
    assert result.stderr[0] / 2.5e8 < 1e-3
