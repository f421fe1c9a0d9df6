"""The granular-crystal commands: modes, dispersion and spectrum (tables, JSON, files, resuming)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.cli.main import main

DIMER = """
[chain]
diameters_mm = [10.0, 6.0]
precompression = 10.0
"""

DRIVEN = """
[chain]
uniform = {n = 3, diameter_mm = 10.0}
precompression = 10.0
[contact]
law = "dashpot"
gamma = 20.0
[drive]
type = "harmonic"
quantity = "force"
amplitude = 0.001
frequency = 1000.0
ramp_cycles = 5
"""


def test_dispersion_command_reports_the_dimer_gap(tmp_path, capsys):
    cfg = tmp_path / "dimer.toml"
    cfg.write_text(DIMER)
    assert main(["dispersion", str(cfg), "--points", "21", "--json", str(tmp_path / "d.json"),
                 "--out", str(tmp_path / "out")]) == 0
    data = json.loads((tmp_path / "d.json").read_text())
    ds = hc.dispersion(hc.Chain([10e-3, 6e-3]), 10.0, points=21)
    np.testing.assert_allclose(data["gaps_Hz"], ds.attrs["gaps"], rtol=1e-12)
    import xarray as xr

    with xr.open_dataset(tmp_path / "out" / "dispersion.nc") as nc:
        np.testing.assert_allclose(json.loads(nc.attrs["gaps"]), ds.attrs["gaps"], rtol=1e-12)
        np.testing.assert_allclose(nc.frequency.values, ds.frequency.values)
    assert (tmp_path / "out" / "dispersion.png").stat().st_size > 1000
    assert "gaps:" in capsys.readouterr().out


def test_modes_command_json(tmp_path):
    cfg = tmp_path / "dimer.toml"
    cfg.write_text(DIMER)
    assert main(["modes", str(cfg), "--json", str(tmp_path / "m.json")]) == 0
    data = json.loads((tmp_path / "m.json").read_text())
    model = hc.build_model(hc.load_config(cfg))
    np.testing.assert_allclose(data["frequencies_Hz"], hc.modes(model).frequencies, rtol=1e-12)
    assert data["labels"] == ["bead 1", "bead 2"]
    # dispersion without precompression: a clean error naming the field
    cfg.write_text(DIMER.replace("precompression = 10.0", ""))
    assert main(["dispersion", str(cfg)]) == 2


def test_spectrum_command_writes_and_resumes(tmp_path, capsys):
    """The table matches the linear response (small drive) to 1e-3, and a rerun with more
    frequencies runs only the new ones (the rows already there are kept as they were)."""
    cfg = tmp_path / "driven.toml"
    cfg.write_text(DRIVEN)
    out = tmp_path / "spec"
    args = ["spectrum", str(cfg), "--out", str(out), "--fmin", "4000", "--fmax", "12000", "--points", "2",
            "--settle-cycles", "150", "--measure-cycles", "10", "--quiet"]
    assert main(args) == 0
    lines = (out / "transmission.csv").read_text().splitlines()
    assert lines[0].startswith("frequency_Hz,transmission")
    rows = [list(map(float, x.split(","))) for x in lines[1:]]
    model = hc.build_model(hc.load_config(cfg))
    for f, t, *_ in rows:
        assert t == pytest.approx(hc.linear_transmission(model, [f])[0], rel=1e-3)
    (out / "transmission.csv").write_text("\n".join([lines[0], lines[1].replace(lines[1].split(",")[1], "0.5")])
                                           + "\n")
    assert main(args[:9] + ["3"] + args[10:]) == 0  # 4000, 8000, 12000 Hz: 4000 Hz is kept as written
    again = [list(map(float, x.split(","))) for x in (out / "transmission.csv").read_text().splitlines()[1:]]
    assert [r[0] for r in again] == [4000.0, 8000.0, 12000.0]
    assert again[0][1] == 0.5 and again[2][1] == pytest.approx(rows[1][1], rel=1e-12)
    assert (out / "transmission.nc").exists() and (out / "transmission.png").exists()
    # another model in the same folder is refused, naming --out
    cfg.write_text(DRIVEN.replace("gamma = 20.0", "gamma = 10.0"))
    assert main(args) == 2
    assert "--out" in capsys.readouterr().err
    assert math.isfinite(again[1][1])


def test_band_gap_map_through_sweep(tmp_path, capsys):
    """``[sweep] analysis = "dispersion"`` (examples/dimer_gap_map.toml): each member's band gap over
    the light bead's diameter equals the diatomic closed form, from sqrt(2K/m_heavy) to
    sqrt(2K/m_light) over 2 pi (K = (3/2) kappa^(2/3) F0^(1/3), both contacts heavy-light), to 1e-9;
    equal beads have none; the map and gaps.nc are written; a member without precompression is
    refused naming the field and the member."""
    from pathlib import Path

    import pandas as pd
    import xarray as xr

    example = Path(__file__).resolve().parents[1] / "examples" / "dimer_gap_map.toml"
    out = tmp_path / "map"
    assert main(["sweep", str(example), "--out", str(out), "--quiet"]) == 0
    df = pd.read_csv(out / "metrics.csv")
    theta = hc.get_material("AISI52100").theta
    mat = hc.get_material("AISI52100")
    for d_mm, low, high, count in zip(df["chain.diameters_mm[1]"], df["gap_low_Hz"], df["gap_high_Hz"],
                                      df["gap_count"]):
        r_h, r_l = 5e-3, d_mm * 0.5e-3
        kappa = 1.0 / (2 * theta * math.sqrt(1 / r_h + 1 / r_l))  # paper eq. 1, two steel spheres
        k = 1.5 * kappa ** (2 / 3) * 1.0 ** (1 / 3)
        m_h, m_l = (mat.density * math.pi * (2 * r) ** 3 / 6 for r in (r_h, r_l))
        if d_mm == 10.0:
            assert count == 0 and math.isnan(low)
            continue
        assert count == 1
        assert low == pytest.approx(math.sqrt(2 * k / m_h) / (2 * math.pi), rel=1e-9)
        assert high == pytest.approx(math.sqrt(2 * k / m_l) / (2 * math.pi), rel=1e-9)
    assert (out / "gap_map.png").stat().st_size > 0
    with xr.open_dataset(out / "gaps.nc") as ds:
        np.testing.assert_allclose(ds.gap_low.values[:, 0], df["gap_low_Hz"].to_numpy(), rtol=1e-15)
    text = example.read_text().replace("precompression = 1.0", "precompression = 0.0")
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    assert main(["sweep", str(bad), "--out", str(tmp_path / "bad"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "chain.precompression" in err and "sweep member 0" in err
