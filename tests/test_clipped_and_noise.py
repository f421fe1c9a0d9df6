"""Clipped and noise-only records are refused by analyze, compare and fit; a fit whose model pulse
leaves the record, or hardly stands above the noise, is flagged."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w
import xarray as xr

from hertzchain.analysis import cos6_pulse, fit_pulse
from hertzchain.analysis.saturation import find_clipping
from hertzchain.cli.main import main
from hertzchain.errors import PulseClipped
from hertzchain.lab import Trace, fit_traces

from lab_files import START, isf_bytes, lab_record, truth_signal, write_mso_csv

SENS_V = 112.40e-3  # V/N, PCB 208A11
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
FREE = ["--free", "striker.velocity", "--free", "gain", "--free", "time_offset", "--free", "baseline"]


def _scope(force: np.ndarray, *, noise_v: float = 4e-3, clip_v: float | None = None, seed: int = 0) -> np.ndarray:
    """Volts through a PCB 208A11, white noise, an 8-bit 2 V window and, if given, a clip."""
    rng = np.random.default_rng(seed)
    volts = force * SENS_V + rng.normal(0.0, noise_v, force.size)
    if clip_v is not None:
        volts = np.minimum(volts, clip_v)
    q = 2.0 / 256
    return np.round(volts / q) * q


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    """The issue's case: a 35 N pulse clipped at 3.5 N (an MSO CSV, no full scale in the file); the
    same pulse at an .isf file's largest code; and a record of noise alone."""
    folder = tmp_path_factory.mktemp("records")
    t = (np.arange(1000) - 150) * 4e-7
    pulse = cos6_pulse(t, 35.0, 1.2e-4, 3.0e-5)
    clipped = write_mso_csv(folder / "clipped.csv", t, _scope(pulse, clip_v=3.5 * SENS_V, noise_v=2e-3))
    codes = np.minimum(np.round(pulse * SENS_V / 2e-3), 127).astype(np.int8)  # 8-bit codes of 2 mV
    isf = folder / "clipped.isf"
    isf.write_bytes(isf_bytes(codes, fmt="RI", width=1, ymult=2e-3, xincr=4e-7, xzero=float(t[0])))
    noise = write_mso_csv(folder / "noise.csv", t, _scope(np.zeros_like(t), noise_v=8e-3))
    return {"clipped": clipped, "isf": isf, "noise": noise}


def test_the_detector_finds_the_flat_top_and_the_full_scale_and_spares_a_clean_pulse():
    t = (np.arange(1000) - 150) * 4e-7
    pulse = cos6_pulse(t, 35.0, 1.2e-4, 3.0e-5)
    assert find_clipping(t, _scope(pulse) / SENS_V) is None                  # 8-bit, unclipped
    assert find_clipping(t, pulse) is None                                  # a simulation
    assert "cut flat" in find_clipping(t, _scope(pulse, clip_v=3.5 * SENS_V) / SENS_V)
    assert "cut flat" in find_clipping(t, _scope(pulse, clip_v=0.9 * 35 * SENS_V) / SENS_V)  # 10 % cut
    assert "full scale" in find_clipping(t, np.minimum(pulse, 30.0), valid_max=30.0)
    with pytest.raises(PulseClipped, match="clipped"):
        fit_pulse(t, _scope(pulse, clip_v=3.5 * SENS_V) / SENS_V)
    # ... where the clipped record's fit used to give F_m = 3.66 N with small error bars.


@pytest.mark.parametrize("name,message", [("clipped", "cut flat"), ("isf", "full scale"),
                                          ("noise", "no pulse")])
def test_analyze_refuses_clipped_and_noise_only_records_and_exits_2(records, capsys, name, message):
    assert main(["analyze", str(records[name]), "--sensor", "pcb_208a11"]) == 2
    out = capsys.readouterr()
    # (a narrow terminal wraps the table's reasons at spaces: read the words, not the lines)
    assert message in " ".join(out.out.split())
    assert "error:" in out.err and "no pulse could be fitted" in " ".join(out.err.split())


@pytest.mark.parametrize("name,message", [("clipped", "cannot be compared: the pulse is clipped"),
                                          ("isf", "full scale"), ("noise", "no pulse found to compare")])
def test_compare_refuses_clipped_and_noise_only_records(records, tmp_path, capsys, name, message):
    code = main(["compare", str(records[name]), str(EXAMPLES / "chain1_elastic.toml"), "--sensor", "pcb_208a11",
                 "--out", str(tmp_path / "c.png")])
    assert code == 2
    err = capsys.readouterr().err
    assert err.startswith("error: MEASURED:") and message in err
    assert not (tmp_path / "c.png").exists()


@pytest.mark.parametrize("name,message", [("clipped", "is clipped"), ("isf", "full scale"),
                                          ("noise", "holds no significant pulse")])
def test_fit_refuses_clipped_and_noise_only_records_before_any_run(records, tmp_path, capsys, name, message):
    """fit on noise used to report converged: true, v = 0.149 +- 0.0025 m/s, without a warning."""
    code = main(["fit", str(EXAMPLES / "lab_chain1.toml"), str(records[name]), "--sensor", "pcb_208a11", *FREE,
                 "--out", str(tmp_path / "fit"), "-q"])
    assert code == 2
    err = capsys.readouterr().err
    assert f"error: {records[name].name}:" in err and message in err


@pytest.fixture(scope="module")
def truth_record():
    t, volts, _ = lab_record(truth_signal(), 100)
    force = volts / SENS_V
    return t, force - np.median(force[:100])


def _fit(t, f, name):
    da = xr.DataArray(f, dims="time", coords={"time": t}, attrs={"units": "N"})
    return fit_traces(START, [Trace(da, name=name)], ["striker.velocity", "gain", "time_offset", "baseline"])


def test_fit_flags_a_model_pulse_that_leaves_the_record_window(truth_record):
    t, f = truth_record
    ip = int(np.argmax(f))
    whole = _fit(t, f, "whole")
    assert whole.warnings == []
    cut_end = _fit(t[: ip - 3], f[: ip - 3], "cut-end")
    assert any("cut-end: the model's pulse leaves the record window" in w and "at the record's end" in w
               for w in cut_end.warnings)
    cut_start = _fit(t[ip + 15:], f[ip + 15:], "cut-start")
    assert any("before the record starts" in w for w in cut_start.warnings)


def test_fit_flags_a_fitted_pulse_not_above_the_noise(truth_record, tmp_path):
    """A record whose pulse stands out (so it is fitted) but whose fitted model is tiny: the baseline
    jump of a noisy record late in its window is fitted by a pulse hardly above the noise."""
    from hertzchain.lab.fit_checks import fit_doubts

    class Sol:
        status, nfev, message = 1, 5, "ok"

    t = np.linspace(0, 1e-3, 200)
    f = np.zeros(200)
    doubts = fit_doubts(Sol(), 1.0, ["weak"], [t], np.array([1.0]), np.array([0.0]), np.array([1.0]),
                        [(t, 3.0 * np.exp(-((t - 5e-4) / 5e-5) ** 2), 3.0 * np.exp(-((t - 5e-4) / 5e-5) ** 2), f)])
    assert doubts == ["weak: the fitted pulse is 3 times the noise (1 N) in the record, less than 8: the record "
                      "hardly constrains the fit"]


def test_fit_config_of_the_examples_is_unchanged():
    """The example the docs fit (a sanity anchor for the flags above: no doubts on a good record)."""
    data = tomllib.loads((EXAMPLES / "lab_chain1.toml").read_text())
    assert tomli_w.dumps(data)
