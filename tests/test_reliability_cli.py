"""One error path for the command line: every bad input or file gives its name and what is wrong,
exit 2, never a traceback; JSON output is valid JSON; NumPy warnings do not reach the user
(issue 10, parts 1 and 5)."""

from __future__ import annotations

import json
from pathlib import Path
import warnings

import numpy as np
import pytest
import xarray as xr

import hertzchain as hc
from hertzchain.cli.main import main
from hertzchain.config import parse_config

SMALL_RUN = ('[chain]\nuniform = {n = 3, diameter_mm = 26.0}\n[striker]\nvelocity = 0.2\n'
             '[run]\nduration = 3e-4\nsample_interval = 1e-6\n')


def run_error(capsys, argv) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "Traceback" not in err and "internal error" not in err
    assert "\n\n" not in err.strip()  # one paragraph
    return err


# ---------------------------------------------------------------------------- strict types, bounds
@pytest.mark.parametrize("section,key,value,field", [
    ("striker", "velocity", True, "striker.velocity"),            # issue: ran at 1 m/s
    ("striker", "velocity", "0.5", "striker.velocity"),           # issue: taken as a number
    ("chain", "diameters_mm", [True], "chain.diameters_mm[0]"),   # issue: built 1 mm beads
    ("chain", "uniform", {"n": 1e30, "diameter_mm": 26.0}, "chain.uniform.n"),
    ("chain", "uniform", {"n": 3, "diameter_mm": 1e300}, "chain.uniform.diameter_mm"),
    ("chain", "uniform", {"n": 3, "diameter_mm": 1e-300}, "chain.uniform.diameter_mm"),
    ("run", "duration", 1e300, "run.duration"),
    ("run", "sample_interval", 1e-300, "run.sample_interval"),
    ("contact", "gamma", 1e300, "contact.gamma"),
    ("probes", "sensors", [2.0], "probes.sensors[0]"),
    ("probes", "velocities", 1, "probes.velocities"),
    ("wall", "type", 1, "wall.type"),
])
def test_strict_types_and_bounds_name_the_field(section, key, value, field):
    data = {"chain": {"uniform": {"n": 3, "diameter_mm": 26.0}}, "contact": {"law": "dashpot", "gamma": 1.0}}
    data.setdefault(section, {})
    data[section] = {k: v for k, v in data[section].items() if k not in ("uniform", "diameters_mm")} \
        if key in ("uniform", "diameters_mm") else dict(data[section])
    data[section][key] = value
    with pytest.raises(hc.ConfigError) as info:
        parse_config(data)
    assert info.value.field == field


def test_model_errors_name_the_key_as_written():
    """Issue: a bad bead built from chain.uniform was reported as chain.diameters[0]."""
    from hertzchain.config import build_model

    with pytest.raises(hc.ConfigError, match=r"^chain\.taper: .* makes the last bead"):
        build_model(parse_config({"chain": {"uniform": {"n": 2, "diameter_mm": 26.0}, "taper": {"n": 900, "q": 0.9}}}))
    with pytest.raises(hc.ConfigError, match=r"^chain\.offsets_mm: needs one value per bead \(3\), got 5"):
        build_model(parse_config({"chain": {"uniform": {"n": 3, "diameter_mm": 26.0}, "offsets_mm": [0.0] * 5}}))
    with pytest.raises(hc.ConfigError, match=r"^chain\.offsets_fraction: needs one value per bead"):
        build_model(parse_config({"chain": {"uniform": {"n": 3, "diameter_mm": 26.0}, "offsets_fraction": [0.1] * 4}}))


# ---------------------------------------------------------------------------- bad files
def test_non_utf8_config_and_csv(tmp_path, capsys):
    cfg = tmp_path / "latin1.toml"
    cfg.write_bytes(SMALL_RUN.replace("[chain]", "# d\xe9j\xe0\n[chain]").encode("latin-1"))
    err = run_error(capsys, ["run", str(cfg), "--out", str(tmp_path / "r.nc")])
    assert f"error: {cfg}: is not UTF-8" in err
    csv = tmp_path / "scope.csv"
    csv.write_bytes("time,force\n0,0\n".encode() + b"\xff\xfe1,2\n")
    err = run_error(capsys, ["analyze", str(csv)])
    assert f"error: {csv}: is not UTF-8" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["latin1.toml", "scope.csv"]


def test_result_without_expected_content_under_plot_and_analyze(tmp_path, capsys):
    foreign = tmp_path / "foreign.nc"
    xr.Dataset({"x": ("n", np.arange(5.0))}).to_netcdf(foreign, engine="h5netcdf")
    for argv in (["plot", str(foreign), "--out", str(tmp_path / "p.png")], ["analyze", str(foreign)]):
        err = run_error(capsys, argv)
        assert f"error: {foreign}: is not a hertzchain result" in err
    garbage = tmp_path / "garbage.nc"
    garbage.write_bytes(b"\x89HDF\r\n" + b"\x00" * 100)
    err = run_error(capsys, ["plot", str(garbage), "--out", str(tmp_path / "p.png")])
    assert f"error: {garbage}: is not a hertzchain NetCDF result" in err
    assert not (tmp_path / "p.png").exists()


def test_plot_without_model_attributes_and_unknown_suffix(tmp_path, capsys):
    cfg = tmp_path / "c.toml"
    cfg.write_text(SMALL_RUN)
    out = tmp_path / "r.nc"
    assert main(["run", str(cfg), "--out", str(out), "-q"]) == 0
    ds = hc.load(out)
    del ds.attrs["model"]
    bare = tmp_path / "bare.nc"
    hc.save(ds, bare)
    assert main(["plot", str(bare), "--out", str(tmp_path / "b.png")]) == 0
    assert (tmp_path / "b.png").read_bytes()[:4] == b"\x89PNG"
    err = run_error(capsys, ["plot", str(out), "--out", str(tmp_path / "r.xyz")])
    assert "error: --out: " in err and ".png" in err
    assert not (tmp_path / "r.xyz").exists()


def test_damaged_data_under_reproduce_from_data(tmp_path, capsys):
    from hertzchain.paper.protocol import Settings

    err = run_error(capsys, ["reproduce", "--out", str(tmp_path), "--from-data"])
    assert "summary.json" in err
    (tmp_path / "summary.json").write_text("{not json")
    assert "summary.json: cannot read it" in run_error(capsys, ["reproduce", "--out", str(tmp_path), "--from-data"])
    (tmp_path / "summary.json").write_text("{}")
    assert "summary.json: is not the summary" in run_error(capsys, ["reproduce", "--out", str(tmp_path), "--from-data"])
    (tmp_path / "summary.json").write_text(json.dumps({"settings": Settings().describe()}))
    data = tmp_path / "data"
    data.mkdir()
    (data / "chain1_truncated_16.nc").write_bytes(b"truncated")
    err = run_error(capsys, ["reproduce", "--out", str(tmp_path), "--from-data"])
    assert f"{data / 'chain1_truncated_16.nc'}: is damaged" in err


def test_analyze_json_is_valid_json_with_null(tmp_path, capsys):
    """Issue: a failed fit wrote bare NaN, which no JSON parser reads."""
    # A record of noise alone: it reads, but holds no pulse to fit (a constant record is refused
    # by the reader itself, exit 2, issue 11).
    csv = tmp_path / "noise.csv"
    noise = np.random.default_rng(0).normal(0.0, 0.01, 50)
    csv.write_text("time,force\n" + "".join(f"{i * 1e-6},{f}\n" for i, f in enumerate(noise)))
    # Every row failed: the rows are still printed, and the exit status says so (issue 23).
    assert main(["analyze", str(csv), "--json"]) == 2
    text = capsys.readouterr().out
    rows = json.loads(text, parse_constant=lambda c: pytest.fail(f"bare {c} in JSON"))
    assert rows[0]["error"] and rows[0]["peak_force"] is None


def test_numpy_warnings_do_not_reach_the_user(capsys):
    import hertzchain.cli.main as cli_mod

    @cli_mod.cli.command("noisy")
    def noisy():
        np.log(np.zeros(1))  # RuntimeWarning: divide by zero
        warnings.warn(hc.ElasticLimitWarning("ours"))

    try:
        assert main(["noisy"]) == 0
    finally:
        cli_mod.cli.commands.pop("noisy")
    err = capsys.readouterr().err
    assert err == "warning: ours\n"


@pytest.mark.parametrize("changes,field", [
    ({"seed": -1}, "sweep.seed"),                               # numpy refused it with a traceback
    ({"chunk_size": True}, "sweep.chunk_size"),
    ({"chunk_size": 2.0}, "sweep.chunk_size"),
    ({"tolerances": {"diameter_rel": 1e-3, "seed": -5}}, "sweep.tolerances.seed"),
    ({"tolerances": {"offset_mm": 1e300}}, "sweep.tolerances.offset_mm"),
    ({"mode": "random", "n": 10**12, "parameters": {"striker.velocity": [0.1]}}, "sweep.n"),
    ({"parameters": {"striker.velocity": [0.1] * 1000, "striker.diameter_mm": [8.0] * 1001}}, "sweep.parameters"),
    ({"parameters": {"striker.velocity": [0.1, "0.2"]}}, 'sweep.parameters["striker.velocity"]'),
])
def test_sweep_table_is_strict_and_bounded(changes, field):
    from hertzchain.sweep import parse_sweep

    data = {"base": {"chain": {"uniform": {"n": 3, "diameter_mm": 26.0}}},
            "sweep": {"parameters": {"striker.velocity": [0.1]}, **changes}}
    with pytest.raises(hc.ConfigError) as info:
        parse_sweep(data)
    assert info.value.field == field


@pytest.fixture(scope="module")
def small_result():
    model = hc.Model(hc.Chain.uniform(4, 26e-3), hc.Striker(8e-3, 0.2))
    return hc.simulate(model, 4e-4, hc.Probes(sample_interval=1e-6, sensors=(2,)))


DAMAGE = {
    "no time": lambda ds: ds.drop_vars("time"),
    "no contact axis": lambda ds: ds.drop_vars("contact"),
    "no sensor axis": lambda ds: ds.drop_vars("sensor"),
    "no wall force": lambda ds: ds.drop_vars("wall_force"),
    "no forces": lambda ds: ds.drop_vars(["wall_force", "sensor_force", "contact_force"]),
    "NaN wall force": lambda ds: ds.assign(wall_force=ds.wall_force * np.nan),
    "no attributes": lambda ds: ds.assign_attrs({k: "" for k in ds.attrs}),
    "model attribute not JSON": lambda ds: ds.assign_attrs(model="{not json"),
    "model attribute a list": lambda ds: ds.assign_attrs(model="[1, 2]"),
    "one sample": lambda ds: ds.isel(time=slice(0, 1)),
}


@pytest.mark.parametrize("damage", DAMAGE)
def test_results_with_missing_or_odd_content(small_result, damage, tmp_path, capsys):
    """Issue: 5 of 19 plot cases (results without the expected attributes...) were internal errors."""
    path = tmp_path / "r.nc"
    DAMAGE[damage](small_result).to_netcdf(path, engine="h5netcdf")
    for argv in (["plot", str(path), "--out", str(tmp_path / "p.png")], ["analyze", str(path), "--json"]):
        code = main(argv)
        captured = capsys.readouterr()
        assert code in (0, 2) and "internal error" not in captured.err, captured.err
        if code == 2:
            assert captured.err.startswith(f"error: {path}") or captured.err.startswith("error: --"), captured.err
        elif argv[0] == "analyze":
            json.loads(captured.out, parse_constant=lambda c: pytest.fail(f"bare {c}"))


def test_oscilloscope_work_is_bounded_before_the_run():
    from hertzchain.config import MAX_SCOPE_SAMPLES, build_instruments

    data = {"chain": {"preset": "chain1"}, "instrument": {"wall": {"record_length": 10_000_000, "n_average": 1000}}}
    with pytest.raises(hc.ConfigError, match=r"^instrument\.wall\.n_average: 1000 acquisitions"):
        build_instruments(parse_config(data))
    data["instrument"]["wall"]["n_average"] = int(MAX_SCOPE_SAMPLES // 10_000_000)
    assert build_instruments(parse_config(data))["wall"].n_average == 10


def test_run_refuses_an_out_name_that_is_not_a_result_format(tmp_path, capsys):
    """A result is NetCDF (or CSV / MATLAB / parquet, as export writes them): --out result.png is
    refused before the run, naming --out and the formats, nothing written."""
    out = tmp_path / "result.png"
    examples = Path(__file__).resolve().parents[1] / "examples"
    assert main(["run", str(examples / "contract.toml"), "--out", str(out), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --out:") and "*.nc" in err and "*.mat" in err
    assert not out.exists()


@pytest.mark.parametrize("where, reason", [
    ("a-file/result.nc", "a part of its folder path is not a folder"),
    ("a-file/sub/result.nc", "a part of its folder path is not a folder"),
    ("read-only/result.nc", "permission denied"),
    ("read-only/new/result.nc", "permission denied"),
])
def test_run_refuses_an_out_it_cannot_write_before_simulating(tmp_path, capsys, monkeypatch, where, reason):
    """--out under a file, or in a folder it may not write (or create): refused before the
    simulation (which ran to its end first, before), naming the file and why; exit 2."""
    import os

    import hertzchain.config as config

    if where.startswith("read-only"):
        if os.geteuid() == 0:
            pytest.skip("the administrator may write into a read-only folder")
        (tmp_path / "read-only").mkdir(mode=0o500)
    (tmp_path / "a-file").write_text("x")
    ran = []
    monkeypatch.setattr(config, "simulate_config", lambda *a, **k: ran.append(1))
    examples = Path(__file__).resolve().parents[1] / "examples"
    out = tmp_path / where
    assert main(["run", str(examples / "contract.toml"), "--out", str(out), "-q"]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert err.startswith(f"error: {out}: cannot be written: {reason}") and ran == []


def test_reproduce_from_data_reads_only_regular_files_of_its_folder(tmp_path, capsys):
    """--from-data on a received folder: a trace linking out of data/, a FIFO named summary.json or
    like a trace (reading one would wait forever: run in a subprocess, so that a hang fails by its
    timeout): refused at once, naming the file; exit 2."""
    import os
    import subprocess
    import sys
    import textwrap

    from hertzchain.paper.protocol import Settings

    def folder(name: str, plant: str):
        out = tmp_path / name
        data = out / "data"
        data.mkdir(parents=True)
        summary, trace = out / "summary.json", data / "chain1_truncated_16.nc"
        if plant == "fifo-summary":
            os.mkfifo(summary)
        else:
            summary.write_text(json.dumps({"settings": Settings().describe()}))
        if plant == "fifo-trace":
            os.mkfifo(trace)
        elif plant == "link-trace":
            outside = tmp_path / "outside.nc"
            outside.write_bytes(b"\x89HDF\r\n\x1a\n")
            trace.symlink_to(outside)
        return out

    linked = folder("link", "link-trace")
    err = " ".join(run_error(capsys, ["reproduce", "--out", str(linked), "--from-data"]).split())
    assert "chain1_truncated_16.nc: is a symbolic link to" in err and "outside" in err
    fifos = [folder("fifo-summary", "fifo-summary"), folder("fifo-trace", "fifo-trace")]
    script = textwrap.dedent(f"""
        from hertzchain.cli.main import main
        for out in {[str(f) for f in fifos]!r}:
            print(main(["reproduce", "--out", out, "--from-data"]))
    """)
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert proc.stdout.split() == ["2", "2"], proc.stderr
    err = " ".join(proc.stderr.split())
    assert "summary.json: is a FIFO (named pipe), not a regular file" in err
    assert "chain1_truncated_16.nc: is a FIFO (named pipe), not a regular file" in err
    assert "Traceback" not in err


def test_a_received_trace_declaring_a_huge_variable_is_refused_before_it_is_allocated(tmp_path):
    """A trace of a reproduction's data/ whose wall_force declares 10**13 samples (an HDF5 file of
    a few kB, the data never written): refused naming the file and the variable, nothing allocated."""
    import h5py

    from hertzchain.paper.reproduce import load_trace

    path = tmp_path / "trace.nc"
    with h5py.File(path, "w") as f:
        f.create_dataset("wall_force", shape=(10**13,), dtype="f8", chunks=(4096,))
    # (--from-data's reader wraps it in a ConfigError naming the file: "is damaged or not a
    # hertzchain result (ValueError: ...)")
    with pytest.raises(ValueError, match=r"'wall_force' declares shape \(10000000000000,\)"):
        load_trace(path)
