"""read_trace on every supported layout (fixtures written from the vendors' documentation), the
analyze command's new options, and clear errors on bad files."""

from __future__ import annotations

import json

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.analysis import cos6_pulse
from hertzchain.cli.main import main
from hertzchain.errors import ConfigError
from hertzchain.lab import read_trace

from lab_files import (isf_values, trc_values, write_isf, write_mso_csv, write_picoscope, write_tds_csv,
                       write_trc)

SENS = 112.40  # mV/N, PCB 208A11


@pytest.fixture(scope="module")
def pulse():
    """A cos^6 pulse (paper eq. 4 in time) on a 2.5 MS/s, 1000-point record, in volts."""
    t = (np.arange(1000) - 100) * 4e-7
    force = cos6_pulse(t, 5.0, 1.2e-4, 3.0e-5)
    return t, force * SENS * 1e-3


def _same(da, t, volts, atol_v):
    assert da.attrs["units"] == "N" and da["time"].attrs["units"] == "s"
    np.testing.assert_allclose(da["time"].values, t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(da.values, volts / (SENS * 1e-3), rtol=0, atol=atol_v / (SENS * 1e-3))


def test_tektronix_tds_csv(tmp_path, pulse):
    t, v = pulse
    da = read_trace(write_tds_csv(tmp_path / "F0000CH1.CSV", t, v), sensor="pcb_208a11", baseline=False)
    assert da.attrs["format"] == "tektronix-csv" and da.name == "CH1"
    _same(da, t, v, 0.5e-5)  # written with 5 decimals of a volt


def test_tektronix_mso_csv(tmp_path, pulse):
    t, v = pulse
    da = read_trace(write_mso_csv(tmp_path / "mso.csv", t, v), sensitivity=SENS, baseline=False)
    assert da.attrs["raw_unit"] == "V"
    _same(da, t, v, 1e-6 * np.abs(v).max())


@pytest.mark.parametrize("width", [1, 2])
def test_tektronix_isf(tmp_path, pulse, width):
    t, v = pulse
    da = read_trace(write_isf(tmp_path / "TEK00000.ISF", t, v, width), sensor="pcb_208a11", baseline=False)
    assert da.attrs["format"] == "tektronix-isf" and da.name == "Ch1"
    np.testing.assert_allclose(da.values, isf_values(t, v, width) / (SENS * 1e-3), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(da["time"].values, t, atol=1e-12)


def test_lecroy_trc(tmp_path, pulse):
    t, v = pulse
    da = read_trace(write_trc(tmp_path / "C1Trace00000.trc", t, v), sensitivity=SENS, baseline=False)
    assert da.attrs["format"] == "lecroy-trc" and da.attrs["time_unit"] == "S"
    np.testing.assert_allclose(da.values, trc_values(v) / (SENS * 1e-3), rtol=1e-6, atol=1e-9)
    # HORIZ_OFFSET + i HORIZ_INTERVAL (float32 interval): the points are not spread over count x interval.
    np.testing.assert_allclose(da["time"].values, t[0] + np.arange(t.size) * np.float32(t[1] - t[0]), rtol=1e-12)


@pytest.mark.parametrize("sep,suffix", [(",", ".csv"), ("\t", ".txt")])
def test_picoscope(tmp_path, pulse, sep, suffix):
    t, v = pulse
    path = write_picoscope(tmp_path / f"pico{suffix}", t, v, sep)
    da = read_trace(path, "Channel A", sensor="pcb_208a11", baseline=False)
    assert da.attrs["raw_unit"] == "mV" and da.attrs["time_unit"] == "us"
    _same(da, t, v, 1e-8)
    assert read_trace(path, 1, sensor="pcb_208a11", baseline=False).name == "Channel A"


def test_delimited_variants(tmp_path, pulse):
    t, v = pulse
    f = v / (SENS * 1e-3)
    rows_ms = [(f"{a * 1e3:.7f}", f"{b:.8f}") for a, b in zip(t, f)]
    # Excel: sep=; line, decimal comma, a units row, a BOM.
    text = "sep=;\nZeit;Kraft\n(ms);(N)\n" + "\n".join(f"{a};{b}".replace(".", ",") for a, b in rows_ms)
    (tmp_path / "excel.csv").write_text(text, encoding="utf-8-sig")
    da = read_trace(tmp_path / "excel.csv", baseline=False)
    _same(da, t, v, 1e-8 * SENS)
    # Comments, a unit in the header, kN; then the same without a header (SI assumed).
    text = "# bench 3\n# 2026-11-23\ntime [us]\tforce [kN]\n" + "\n".join(
        f"{a * 1e6:.5f}\t{b * 1e-3:.11f}" for a, b in zip(t, f))
    (tmp_path / "c.txt").write_text(text)
    _same(read_trace(tmp_path / "c.txt", baseline=False), t, v, 1e-8 * SENS)
    (tmp_path / "bare.dat").write_text("\n".join(f"{a:.10e} {b:.10e}" for a, b in zip(t, f)))
    _same(read_trace(tmp_path / "bare.dat", baseline=False), t, v, 1e-9 * SENS)
    # A plain 'time' header in ms: refused as implausible, read with --time-unit ms.
    (tmp_path / "ms.csv").write_text("time,force\n" + "\n".join(f"{a},{b}" for a, b in rows_ms))
    with pytest.raises(ConfigError, match="--time-unit ms"):
        read_trace(tmp_path / "ms.csv")
    _same(read_trace(tmp_path / "ms.csv", time_unit="ms", baseline=False), t, v, 1e-8 * SENS)
    # An option that contradicts the file, or a sensitivity for a column already in newtons: refused.
    with pytest.raises(ConfigError, match="--time-unit us contradicts"):
        read_trace(tmp_path / "excel.csv", time_unit="us")
    with pytest.raises(ConfigError, match="--sensitivity.*already a force"):
        read_trace(tmp_path / "excel.csv", sensitivity=SENS)


def test_baseline_removed(tmp_path, pulse):
    t, v = pulse
    path = write_mso_csv(tmp_path / "off.csv", t, v + 0.05)
    da = read_trace(path, sensitivity=SENS)
    assert da.attrs["baseline"] == pytest.approx(0.05 / (SENS * 1e-3), rel=1e-6)
    _same(da, t, v, 1e-6)


def test_result_signals(tmp_path):
    ds = hc.run_config({"chain": {"uniform": {"n": 8, "diameter_mm": 26}}, "striker": {"velocity": 0.3},
                        "run": {"duration": 1.2e-3}, "probes": {"sensors": [4]},
                        "instrument": {"wall": {"sample_rate": 2.5e6, "trigger_level_N": 0.5}}})
    path = tmp_path / "r.nc"
    hc.save(ds, path)
    da = read_trace(path, "measured_wall_force", baseline=False)
    np.testing.assert_allclose(da.values, ds.measured_wall_force.values)
    sensor = read_trace(path, "sensor_force:4", baseline=False)
    np.testing.assert_allclose(sensor.values, ds.sensor_force.sel(sensor=4).values)


@pytest.mark.parametrize("content,match", [
    ("", "is empty"),
    ("time,force\n" + "\n".join(f"{i * 1e-6},{i}" for i in range(20)) + "\n2e-5,abc\n", "line 22.*'abc' is not a number"),
    ("time,force\n" + "\n".join(f"{(i if i != 12 else 5) * 1e-6},{i % 7}" for i in range(30)), "line 14: time does not increase"),
    ("time,force\n" + "\n".join(f"{i * 1e-6},0.25" for i in range(30)), "constant"),
    ("force\n" + "\n".join(f"{i % 3}" for i in range(30)), "single column"),
    ("time,force\n" + "\n".join(f"{i * 1e-6},{i % 5}" + (",7" if i == 15 else "") for i in range(40)),
     "line 17 has 3 field"),
    ("time,force\n" + "\n".join(f"{i * 1e-3},{i % 5}" for i in range(30)), "needs a spacing"),
    ("time (ms),volts (V)\n" + "\n".join(f"{i * 1e-3},{i % 5}" for i in range(30)), "--sensitivity"),
    ("time (blorp),force\n" + "\n".join(f"{i * 1e-3},{i % 5}" for i in range(30)), "unknown unit"),
])
def test_bad_files(tmp_path, capsys, content, match):
    path = tmp_path / "bad.csv"
    path.write_text(content)
    with pytest.raises(ConfigError, match=match):
        read_trace(path)
    capsys.readouterr()
    assert main(["analyze", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_analyze_cli_on_scope_file(tmp_path, pulse, capsys):
    t, v = pulse
    path = write_picoscope(tmp_path / "pico.csv", t, v)
    out = tmp_path / "rows.json"
    assert main(["analyze", str(path), "--column", "Channel A", "--sensitivity", "112.40", "--time-unit", "us",
                 "--json", str(out)]) == 0
    (row,) = json.loads(out.read_text())
    # The exact cos^6 pulse: the paper's fit returns its parameters.
    assert row["peak_force"] == pytest.approx(5.0, rel=1e-6)
    assert row["time_of_flight"] == pytest.approx(1.2e-4, abs=1e-9)
    assert row["duration"] == pytest.approx(3.0e-5, rel=1e-5)
    # --tail-end: Q_T stops there, so Q_F + Q_T is the integral up to it.
    assert main(["analyze", str(path), "--column", "1", "--sensor", "pcb_208a11", "--tail-end", "1.3e-4",
                 "--json", str(out)]) == 0
    (cut,) = json.loads(out.read_text())
    f = v / (SENS * 1e-3)
    keep = t <= 1.3e-4
    assert cut["front_momentum"] + cut["tail_momentum"] == pytest.approx(np.trapezoid(f[keep], t[keep]), rel=1e-9)
    capsys.readouterr()
    assert main(["analyze", str(path), "--column", "Channel C", "--sensor", "pcb_208a11"]) == 2
    assert "--column" in capsys.readouterr().err


def test_analyze_cli_measured_signal(tmp_path, capsys):
    ds = hc.run_config({"chain": {"uniform": {"n": 8, "diameter_mm": 26}}, "striker": {"velocity": 0.3},
                        "run": {"duration": 1.2e-3},
                        "instrument": {"wall": {"sample_rate": 2.5e6, "trigger_level_N": 0.5, "bits": 16}}})
    path = tmp_path / "r.nc"
    hc.save(ds, path)
    capsys.readouterr()
    assert main(["analyze", str(path), "--signal", "wall_force", "--signal", "measured_wall_force", "--json"]) == 0
    ideal, measured = json.loads(capsys.readouterr().out)
    assert measured["signal"] == "measured_wall_force" and measured["error"] is None
    # Same pulse seen through a 16-bit scope: F_m and tau agree, T is on the trigger's clock.
    assert measured["peak_force"] == pytest.approx(ideal["peak_force"], rel=2e-3)
    assert measured["duration"] == pytest.approx(ideal["duration"], rel=1e-2)
    trig = ds.measured_wall_force.attrs["trigger_time"]
    assert measured["time_of_flight"] + trig == pytest.approx(ideal["time_of_flight"], abs=4e-7)


@pytest.mark.parametrize("reader", ["read_trace", "analyze_signals"])
def test_a_fifo_given_as_a_record_is_refused_at_once(tmp_path, reader):
    """A FIFO (named pipe) given as a scope record or a CSV of signals: opening it for reading
    would wait for a writer forever; it is refused at once, naming it (run in a thread joined with
    a timeout, so that a hang fails the test instead of stopping the suite)."""
    import os
    import threading

    from hertzchain.analysis import analyze_signals

    fifo = tmp_path / "record.csv"
    os.mkfifo(fifo)
    call = {"read_trace": lambda: read_trace(fifo), "analyze_signals": lambda: analyze_signals(fifo)}[reader]
    caught: list[BaseException] = []

    def target():
        try:
            call()
        except BaseException as exc:  # noqa: BLE001 - handed to the test below
            caught.append(exc)

    worker = threading.Thread(target=target, daemon=True)
    worker.start()
    worker.join(timeout=30)
    assert not worker.is_alive(), "reading the FIFO hangs"
    assert len(caught) == 1 and isinstance(caught[0], ConfigError)
    assert "a FIFO (named pipe), not a regular file" in caught[0].message and str(fifo) in str(caught[0])
