"""``hertzchain export`` and :func:`hertzchain.export`: the same numbers as the NetCDF result, in
CSV (units in the header), MATLAB (variables + a units struct) and parquet; ``run --out r.mat``."""

from __future__ import annotations

import sys

import numpy as np
import pandas as pd
import pytest
import scipy.io as sio

import hertzchain as hc
from hertzchain.cli.main import main


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    model = hc.Model(hc.Chain.uniform(6, 26e-3).append_taper(4, 0.06), hc.Striker(8e-3, 0.2))
    ds = hc.simulate(model, "auto", hc.Probes(sample_interval=1e-6, sensors=(3,), velocities=True))
    path = tmp_path_factory.mktemp("export") / "r.nc"
    hc.save(ds, path)
    return path, hc.load(path)


def test_mat_file_holds_time_and_wall_force_in_si_with_units(result, tmp_path):
    path, ds = result
    assert main(["export", str(path), "--out", str(tmp_path / "r.mat")]) == 0
    m = sio.loadmat(tmp_path / "r.mat", squeeze_me=True)
    np.testing.assert_array_equal(m["time"], ds.time.values)                   # s
    np.testing.assert_array_equal(m["wall_force"], ds.wall_force.values)       # N
    np.testing.assert_array_equal(m["contact_force"], ds.contact_force.values)  # time x contact
    np.testing.assert_array_equal(m["velocity"], ds.velocity.values)
    assert m["units"]["time"] == "s" and m["units"]["wall_force"] == "N" and m["units"]["velocity"] == "m s-1"
    assert float(m["attrs"]["peak_wall_force"]) == ds.attrs["peak_wall_force"]
    assert '"striker"' in str(m["attrs"]["config"])  # the run's config as JSON text


def test_csv_has_units_in_the_header_and_the_same_numbers(result, tmp_path):
    path, ds = result
    out = hc.export(ds, tmp_path / "r.csv")
    table = pd.read_csv(out, comment="#")  # the run's metadata is in # lines above the table
    assert list(table.columns[:3]) == ["time [s]", "wall_force [N]", "sensor_force[3] [N]"]
    assert "contact_force[0] [N]" in table and "velocity[0] [m s-1]" in table and "kinetic_energy [J]" in table
    np.testing.assert_allclose(table["wall_force [N]"], ds.wall_force.values, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(table["contact_force[4] [N]"], ds.contact_force.sel(contact=4).values, rtol=1e-9,
                               atol=1e-15)


def test_parquet_round_trip_and_a_clean_error_without_pyarrow(result, tmp_path, monkeypatch):
    pytest.importorskip("pyarrow")
    _, ds = result
    table = pd.read_parquet(hc.export(ds, tmp_path / "r.parquet"))
    np.testing.assert_array_equal(table["wall_force [N]"], ds.wall_force.values)
    monkeypatch.setitem(sys.modules, "pyarrow", None)  # as if the extra were not installed
    with pytest.raises(hc.ConfigError, match=r"hertzchain\[export\]"):
        hc.export(ds, tmp_path / "s.parquet")


def test_run_writes_mat_and_csv_directly(tmp_path):
    cfg = tmp_path / "c.toml"
    cfg.write_text('[chain]\nuniform = {n = 5, diameter_mm = 20.0}\n[striker]\nvelocity = 0.1\n'
                   '[run]\nsample_interval = 1e-6\n')
    assert main(["run", str(cfg), "--out", str(tmp_path / "r.nc"), "-q"]) == 0
    assert main(["run", str(cfg), "--out", str(tmp_path / "r.mat"), "-q"]) == 0
    assert main(["run", str(cfg), "--out", str(tmp_path / "r.csv"), "-q"]) == 0
    ds = hc.load(tmp_path / "r.nc")
    np.testing.assert_array_equal(sio.loadmat(tmp_path / "r.mat", squeeze_me=True)["wall_force"], ds.wall_force.values)
    assert pd.read_csv(tmp_path / "r.csv", comment="#")["wall_force [N]"].max() == pytest.approx(float(ds.wall_force.max()), rel=1e-9)


def test_refusals_name_the_option(result, tmp_path, capsys):
    path, ds = result
    assert main(["export", str(path), "--out", str(tmp_path / "r.xlsx")]) == 2
    err = capsys.readouterr().err
    assert "--out" in err and "*.csv" in err and "*.mat" in err and "Traceback" not in err
    batch = hc.simulate_batch([hc.Model(hc.Chain.uniform(3, 26e-3), hc.Striker(8e-3, v)) for v in (0.1, 0.2)],
                              2e-4, hc.Probes(sample_interval=1e-6))
    with pytest.raises(hc.ConfigError, match="member"):
        hc.export(batch, tmp_path / "b.csv")
