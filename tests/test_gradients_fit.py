"""``hertzchain fit`` with the exact Jacobian: the tangent model's columns against forward
differences, the same optimum, and the fallback to differences where the engine does not apply."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import xarray as xr

import hertzchain as hc
from hertzchain.lab import Trace, fit_traces
from hertzchain.lab.fit import _Problem

CONFIG = {"chain": {"diameters_mm": [26.0] * 6 + [22.0, 19.0, 16.0]},
          "striker": {"diameter_mm": 8.0, "velocity": 0.22},
          "contact": {"law": "viscoelastic", "A": 4.5e-6},
          "run": {"duration": 1.2e-3, "sample_interval": 1e-7}}
TRUTH = {"velocity": 0.25, "A": 3.0e-6}


@pytest.fixture(scope="module")
def record():
    """A noise-free wall record of the chain at the true values, on a coarser clock (0.4 us)."""
    cfg = copy.deepcopy(CONFIG)
    cfg["striker"]["velocity"] = TRUTH["velocity"]
    cfg["contact"]["A"] = TRUTH["A"]
    ds = hc.run_config(cfg)
    t = ds.time.values[::4]
    return xr.DataArray(ds.wall_force.values[::4], dims="time", coords={"time": t}, attrs={"units": "N"})


def test_exact_jacobian_matches_forward_differences(record):
    free = ["striker.velocity", "contact.A", "gain"]
    prob = _Problem(CONFIG, [Trace(record, name="wall")], free, 1e-6, None)
    x = np.array([0.22, 4.5e-6, 1.0])
    exact = prob.jacobian(x)
    assert prob.jacobian_kind == "exact" and prob.n_tangent_runs == 1
    prob.jacobian_kind = "finite differences"
    fd = prob.jacobian(x)
    for j in range(2):
        scale = np.abs(exact[:, j]).max()
        assert scale > 0
        # forward differences at a relative step of 1e-6: error ~1e-5 of the column's scale
        assert np.allclose(exact[:, j], fd[:, j], atol=2e-4 * scale), free[j]
    assert np.array_equal(exact[:, 2], fd[:, 2])  # the gain's column is the simulated signal either way


def test_exact_fit_recovers_the_truth_in_fewer_evaluations(record):
    free = ["striker.velocity", "contact.A"]
    exact = fit_traces(CONFIG, [Trace(record)], free)
    fd = fit_traces(CONFIG, [Trace(record)], free, jacobian="finite differences")
    assert exact.jacobian == "exact" and fd.jacobian == "finite differences"
    for r in (exact, fd):
        assert r.values == pytest.approx([TRUTH["velocity"], TRUTH["A"]], rel=1e-4)
    assert exact.cost <= fd.cost * (1 + 1e-6)
    assert exact.n_evaluations <= fd.n_evaluations


def test_falls_back_to_differences_where_the_engine_does_not_apply(record):
    cfg = copy.deepcopy(CONFIG)
    cfg["contact"] = {"law": "viscoelastic", "eps": 0.99}  # A comes out of a calibration run
    result = fit_traces(cfg, [Trace(record)], ["striker.velocity", "gain", "time_offset"])
    assert result.jacobian.startswith("finite differences (contact.eps") and result.n_tangent_runs == 0
    assert result.converged


def test_cli_chooses_the_jacobian(tmp_path):
    """``hertzchain fit --jacobian differences`` (what fit did before) against the default exact
    Jacobian on the README's fit: the same optimum, in fewer evaluations with the exact one."""
    import json

    from hertzchain.cli.main import main

    reports = {}
    for kind in ("exact", "differences"):
        out = tmp_path / kind
        assert main(["fit", "examples/lab_chain1.toml", "examples/scope_chain1_wall.csv", "--sensor", "pcb_208a11",
                     "--free", "striker.velocity", "--free", "gain", "--free", "time_offset", "--jacobian", kind,
                     "--out", str(out), "-q"]) == 0
        reports[kind] = json.loads((out / "fit.json").read_text())
    exact, fd = reports["exact"], reports["differences"]
    assert exact["jacobian"] == "exact" and fd["jacobian"] == "finite differences"
    assert exact["n_evaluations"] < fd["n_evaluations"]
    # the differences stop a little early (xtol) in the valley along which speed and gain trade
    # off: a higher cost, ~0.15 standard errors away
    assert exact["cost"] <= fd["cost"]
    for key in ("striker.velocity", "gain", "time_offset"):
        a, b = exact["parameters"][key], fd["parameters"][key]
        assert abs(a["value"] - b["value"]) < 0.3 * a["stderr"], key
