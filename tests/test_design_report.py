"""design.html and the headline: each objective's own record is drawn (the body's force for
``peak_body_force``, not its face's), and references that break the design's constraints are
said to, in the headline, the table and the CLI line."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.design import parse_design, run_design, write_report
from hertzchain.design.objectives import member_metrics
from hertzchain.design.report import compare_with_references, headline_sentence, objective_signal
from hertzchain.runs.batch import simulate_batch

#: 4 x 26 mm then a taper of 4 beads (q = 0.05: 195.6 mm long) on a 1 kg body on a 1e7 N/m mount;
#: no chain longer than 190 mm allowed, which the base and the uniform chain of 8 x 26 mm break.
DESIGN = {"base": {"chain": {"uniform": {"n": 4, "diameter_mm": 26.0}, "taper": {"n": 4, "q": 0.05}},
                   "striker": {"diameter_mm": 8.0, "velocity": 0.2},
                   "wall": {"type": "body", "mass": 1.0, "stiffness": 1e7},
                   "run": {"duration": 3e-3, "sample_interval": 1e-6}},
          "design": {"objective": "peak_body_force", "variables": {"chain.taper.q": [0.0, 0.12]},
                     "constraints": {"max_length_mm": 190.0}, "budget": 24, "seed": 2, "polish": False}}


@pytest.fixture(scope="module")
def designed(tmp_path_factory):
    out = tmp_path_factory.mktemp("design")
    res = run_design(parse_design(DESIGN), out)
    return res, write_report(res), out


def test_design_html_draws_the_objectives_own_signal(designed):
    res, info, out = designed
    _, ds = compare_with_references(res)
    label, _, _, y = objective_signal("peak_body_force", ds)
    assert "body_force" in label
    # the drawn record is the one the objective is read from: its peak is each chain's objective
    for i, name in enumerate(("best", "base", "uniform")):
        assert np.max(y[i]) == pytest.approx(info["comparison"][name]["peak_body_force"], rel=1e-12)
        # ... and not the force on the body's face, which is several times larger
        assert np.max(ds["wall_force"].values[i]) > 2 * np.max(y[i])
    page = (out / "design.html").read_text()
    titles = re.findall(r"<h2>([^<]*)</h2>", page)
    assert "peak_body_force: the |body_force| of the protected body" in titles
    assert titles.index("peak_body_force: the |body_force| of the protected body") < titles.index(
        "The force on the wall (or the body&#x27;s face), for reference")


def test_references_breaking_the_constraints_are_marked(designed):
    res, info, out = designed
    cmp = info["comparison"]
    assert info["best"]["feasible"] and cmp["best"]["breaks"] == []
    length = float(hc.build_model(hc.parse_config(DESIGN["base"])).chain.diameters.sum()) * 1e3
    assert 190 < length < 200
    assert cmp["base"]["breaks"] == [f"design.constraints.max_length_mm = 190 (it has {length:.4g})"]
    assert cmp["uniform"]["breaks"] == ["design.constraints.max_length_mm = 190 (it has 208)"]
    assert not cmp["base"]["feasible"] and not cmp["uniform"]["feasible"]
    headline = headline_sentence(info)
    assert headline.count("which breaks the constraints: design.constraints.max_length_mm = 190") == 2
    page = (out / "design.html").read_text()
    assert "<p id='headline'>" in page and page.count("<b>no</b>: breaks design.constraints.max_length_mm") == 2
    assert page.count("(against a chain that breaks the constraints)") == 2
    # ... and the line `hertzchain design` prints
    from hertzchain.cli.design import _improvement

    for ref in ("base", "uniform"):
        assert "% (which breaks the constraints: design.constraints.max_length_mm = 190" in _improvement(info, ref)


def test_energy_and_plastic_signals_peak_at_their_objectives():
    """energy_at_wall is the largest (2/5) F^(5/3) / kappa^(2/3) of the wall contact (paper eq. 1),
    plastic_work the last value of its record: the drawn signals give the objectives' values."""
    cfg = hc.parse_config({"chain": {"uniform": {"n": 5, "diameter_mm": 20.0}}, "striker": {"diameter_mm": 8.0,
                           "velocity": 3.0}, "contact": {"law": "elastoplastic"}})
    model = hc.build_model(cfg)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ds = simulate_batch([model], 1e-3, hc.Probes(1e-6, contacts=None))
    names = ["energy_at_wall", "plastic_work", "residual_overlap_max"]
    metrics = member_metrics(ds, names)
    for name in names:
        _, _, _, y = objective_signal(name, ds)
        assert np.max(y, axis=1) == pytest.approx(metrics[name], rel=1e-12)
    assert metrics["plastic_work"].min() > 0  # the law yielded: the test is not of zeros
