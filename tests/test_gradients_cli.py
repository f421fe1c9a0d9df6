"""``hertzchain sensitivity`` and the sensitivity bar chart: outputs, plain data, and bad input
ending with exit status 2 and a message naming the field."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import tomli_w

import hertzchain as hc
from hertzchain.cli.main import main

RUN = {"chain": {"diameters_mm": [20.0, 19.0, 18.0, 17.0, 16.0, 15.0]},
       "striker": {"velocity": 0.3, "diameter_mm": 8.0},
       "run": {"duration": 5e-4, "sample_interval": 1e-7}}


@pytest.fixture
def config(tmp_path) -> Path:
    path = tmp_path / "run.toml"
    path.write_text(tomli_w.dumps(RUN))
    return path


def test_json_plot_and_table(config, tmp_path, capsys):
    out, png = tmp_path / "sens.json", tmp_path / "sens.png"
    assert main(["sensitivity", str(config), "--wrt", "chain.diameters_mm", "--wrt", "striker.velocity",
                 "--json", str(out), "--plot", str(png)]) == 0
    text = capsys.readouterr().out
    assert "matters most" in text and "N/mm" in text
    data = json.loads(out.read_text())
    api = hc.sensitivity(RUN, ["chain.diameters_mm", "striker.velocity"])
    assert data["value"] == api.value and data["objective"] == "peak_wall_force" and data["unit"] == "N"
    rows = {r["path"]: r for r in data["variables"]}
    assert len(rows) == 7 and rows["striker.velocity"]["derivative_unit"] == "N/(m/s)"
    for path, g in api.gradient.items():
        assert rows[path]["derivative"] == pytest.approx(g, rel=1e-12)
    assert png.stat().st_size > 5000 and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # --json alone prints the same data, nothing else
    assert main(["sensitivity", str(config), "--wrt", "striker.velocity", "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["variables"][0]["path"] == "striker.velocity"


@pytest.mark.parametrize("args, field", [
    (["--wrt", "chain.taper.n"], "chain.taper.n"),
    (["--wrt", "striker.velocity", "--objective", "loudness"], "objective"),
    (["--wrt", "chain.diameters_mm[3:40]"], "chain.diameters_mm[3:40]"),
    (["--wrt", "striker.velocity", "--plot", "x.csv"], "--plot"),
    (["--wrt", "striker.velocity", "--set", "contact.law='viscoelastic'", "--set", "contact.eps=0.98"], "contact.eps"),
    (["--wrt", "striker.velocity", "--set", "run.integrator='dop853'"], "run.integrator"),
])
def test_bad_input_is_exit_2_naming_the_field(config, capsys, args, field):
    assert main(["sensitivity", str(config), *args]) == 2
    err = capsys.readouterr().err
    assert field in err and "Traceback" not in err


def test_bar_chart_marks_the_bead_that_matters_most(tmp_path):
    from hertzchain.viz.sensitivity import per_bead, plot_sensitivity

    s = hc.sensitivity(RUN, ["chain.diameters_mm", "striker.velocity", "striker.diameter_mm"])
    lists, others = per_bead(s)
    beads = lists["chain.diameters_mm"]
    assert [b for b, _ in beads] == [1, 2, 3, 4, 5, 6]
    assert set(others) == {"striker.velocity", "striker.diameter_mm"}
    assert others["striker.velocity"] == pytest.approx(1.2, abs=2e-3)  # F ~ v^(6/5) (paper eq. 1 scaling)
    fig = plot_sensitivity(s)
    ax = fig.axes[0]
    heights = [p.get_height() for p in ax.patches]
    assert np.allclose(heights, [g for _, g in beads])
    top = max(beads, key=lambda r: abs(r[1]))[0]
    assert any(t.get_text() == f"bead {top}" for t in ax.texts)
