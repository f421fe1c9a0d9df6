"""Designing for a protected body: its objectives, the variables of the issue (``wall.stiffness``,
``striker.mass``, per-bead element types), and the body every candidate is measured against."""

from __future__ import annotations

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.design import parse_design, run_design, write_report
from hertzchain.runs.batch import simulate_batch

BODY = {"type": "body", "mass": 1.0, "stiffness": 1e7}
RUN = {"duration": 3e-3, "sample_interval": 1e-6}


def _design(**over) -> dict:
    d = {"base": {"chain": {"uniform": {"n": 4, "diameter_mm": 26.0}, "taper": {"n": 4, "q": 0.05}},
                  "striker": {"diameter_mm": 8.0, "velocity": 0.2}, "wall": dict(BODY), "run": dict(RUN)},
         "design": {"objective": "peak_body_force", "variables": {"chain.taper.q": [0.0, 0.12]},
                    "budget": 24, "seed": 2, "polish": False}}
    d["design"].update(over)
    return d


def test_body_objectives_are_what_a_run_reports(tmp_path):
    """The best candidate's objectives equal the attributes of the run of its best.toml; the report
    says which body every candidate was measured against."""
    prob = parse_design(_design(objective=["peak_body_force", "peak_body_acceleration", "energy_to_body"],
                                budget=60, population=8))
    res = run_design(prob, tmp_path)
    info = write_report(res, figures=False)
    ds = hc.run_config(tmp_path / "best.toml")
    best = info["best"]["objective"]
    assert best["peak_body_force"] == pytest.approx(ds.attrs["peak_body_force"], rel=1e-9)
    assert best["peak_body_acceleration"] == pytest.approx(ds.attrs["peak_body_acceleration"], rel=1e-9)
    assert best["energy_to_body"] == pytest.approx(ds.attrs["peak_body_energy"], rel=1e-9)
    assert info["measured_against"]["base"].startswith("a protected body of 1 kg on a mount of 1e+07 N/m")
    assert info["measured_against"]["varied_by"] == []


def test_body_objective_needs_a_body_and_body_designs_run():
    d = _design()
    d["base"]["wall"] = {"type": "flat"}
    with pytest.raises(hc.ConfigError, match="design.objective"):
        parse_design(d)
    d = _design()
    d["base"]["wall"] = {"type": "none"}
    with pytest.raises(hc.ConfigError, match="base.wall.type"):
        parse_design(d)


def test_issue_variables_stiffness_striker_mass_and_elements(tmp_path):
    """``wall.stiffness``, ``striker.mass`` and per-bead element types as design variables: each
    candidate's model carries them, and a softer mount lowers the peak force on the ground."""
    d = _design(variables={"wall.stiffness": [1e6, 1e8], "striker.mass": [1e-3, 1e-2],
                           "chain.elements[5:7]": ["sphere", "mim"]}, budget=40)
    d["base"]["elements"] = {"mim": {"resonator": {"mass_fraction": 0.3, "frequency": 5000.0}}}
    d["base"]["chain"]["elements"] = ["sphere"] * 8
    prob = parse_design(d)
    vals, cfg = prob.space.decode(np.array([0.0, 1.0, 0.9, 0.1]))
    model = hc.build_model(hc.parse_config(cfg))
    assert model.wall.stiffness == 1e6 and model.striker.mass == pytest.approx(1e-2)
    assert [el.name for el in model.chain.elements[5:7]] == ["mim", "sphere"]
    res = run_design(prob, tmp_path)
    assert res.best["variables"]["wall.stiffness"] < 1e7
    info = write_report(res, figures=False)
    assert info["measured_against"]["varied_by"] == ["wall.stiffness"]


def test_every_candidate_meets_the_same_wall():
    """Per-bead materials as design variables: the wall stays the base chain's first material (it
    is written into the base), not whichever material the last bead takes."""
    d = _design(objective="peak_wall_force", variables={"chain.materials[7]": ["AISI52100", "PTFE"]})
    d["base"]["wall"] = {"type": "flat"}
    d["base"]["chain"]["materials"] = ["AISI52100"] * 8
    prob = parse_design(d)
    assert prob.base["wall"]["material"] == "AISI52100"
    kappas = []
    for x in (0.0, 1.0):
        _, cfg = prob.space.decode(np.array([x]))
        model = hc.build_model(hc.parse_config(cfg))
        assert model.wall_material.name == "AISI52100"
        kappas.append(model.system().kappa[-1])
    # the wall contact changes only through the last bead's own material
    assert kappas[1] == pytest.approx(hc.hertz_constant(float(model.chain.radii[-1]), None, "PTFE", "AISI52100"))


def test_batched_body_metrics_match_single_runs():
    """member_metrics of a stacked batch with bodies (and one member without) against single runs."""
    from hertzchain.design.objectives import member_metrics

    chain = hc.Chain.uniform(6, 20e-3)
    models = [hc.Model(chain, hc.Striker(8e-3, 0.2), hc.Wall("body", mass=m, stiffness=1e6)) for m in (0.5, 2.0)]
    ds = simulate_batch(models, 2e-3)
    out = member_metrics(ds, ["peak_body_force", "peak_body_acceleration", "energy_to_body"])
    for i, m in enumerate(models):
        single = hc.simulate(m, 2e-3)
        assert out["peak_body_force"][i] == pytest.approx(single.attrs["peak_body_force"], rel=1e-12)
        assert out["energy_to_body"][i] == pytest.approx(single.attrs["peak_body_energy"], rel=1e-12)
    # a heavier body on the same mount is pushed to a smaller acceleration
    assert out["peak_body_acceleration"][1] < out["peak_body_acceleration"][0]


def test_a_body_objective_is_searched_with_gradients(tmp_path):
    """``peak_body_force`` over the mount's stiffness alone (a real variable the sensitivity engine
    differentiates) takes the gradient phase; a softer mount passes less force to the ground, so
    the search ends on the soft bound, and the reported value is the run of its best config."""
    d = _design(variables={"wall.stiffness": [1e6, 1e8]}, budget=24, population=6, polish=True)
    prob = parse_design(d)
    from hertzchain.design.gradient import gradient_support

    assert gradient_support(prob) is None
    res = run_design(prob, tmp_path)
    assert "gradient" in {r["phase"] for r in res.history}
    assert res.best["variables"]["wall.stiffness"] == pytest.approx(1e6, rel=1e-3)
    ds = hc.run_config(res.best["config"])
    assert res.best["objective"] == pytest.approx(ds.attrs["peak_body_force"], rel=1e-9)
