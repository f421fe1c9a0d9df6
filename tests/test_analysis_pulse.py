"""Pulse fitting (paper Sec. III: cos^6 fit of the loading part) and batch analysis of records.

Covers hertzchain.analysis.pulse and hertzchain.analysis.io."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hertzchain.analysis import (
    ROW_KEYS, analyze_signals, cos6_pulse, fit_pulse, front_tail_momenta, read_signal_csv,
)
from hertzchain.errors import ConfigError, PulseNotFound

F_M, T_OF, TAU = 120.0, 1.0e-3, 50e-6  # N, s, s: the scale of the paper's wall pulses
DT = 1e-6  # 50 samples on the rise
TIME = np.arange(0.0, 3e-3, DT)
CLEAN = cos6_pulse(TIME, F_M, T_OF, TAU)
EXACT_AREA = F_M * TAU * 5 * math.pi / 16  # integral of cos^6 over one hump

# Noisy cases: sigma = 2 % of F_m with 50 samples on the rise. A Monte Carlo over 300 seeds gave
# a scatter of 1.1 % on F_m, 1.4 % of tau on T and 2.1 % on tau, and reported standard errors
# that match that scatter (normalised deviations of std 1.07). Tolerances below are ~4 standard
# deviations of the scatter, and the deviation must also lie within 4 reported standard errors.
NOISE_TOL = {"peak_force": 0.05 * F_M, "time_of_flight": 0.06 * TAU, "duration": 0.08 * TAU}


def assert_clean_fit(fit, F=F_M, T=T_OF, tau=TAU, rel=1e-6):
    assert fit.peak_force == pytest.approx(F, rel=rel)
    assert fit.time_of_flight == pytest.approx(T, abs=rel * tau)
    assert fit.duration == pytest.approx(tau, rel=rel)


def assert_noisy_fit(fit, F=F_M, T=T_OF, tau=TAU):
    for name, true in (("peak_force", F), ("time_of_flight", T), ("duration", tau)):
        value, err = getattr(fit, name), getattr(fit, name + "_err")
        assert abs(value - true) < NOISE_TOL[name], name
        assert abs(value - true) < 4 * err, name
        assert 0 < err < NOISE_TOL[name] / 2, name  # the error bar is meaningful, not huge


def test_clean_pulse_exact():
    fit = fit_pulse(TIME, CLEAN)
    assert_clean_fit(fit, rel=1e-9)
    assert fit.baseline == 0.0
    assert fit.peak_force_err < 1e-9 and fit.duration_err < 1e-12
    # the final window is the loading part -tau < t - T <= 0 (paper Sec. III)
    assert fit.window[0] > T_OF - TAU and fit.window[1] <= T_OF
    assert 49 <= fit.n_points <= 50  # 50 samples per tau; the end points sit on the window edges
    assert fit.residual_rms < 1e-9
    np.testing.assert_allclose(fit.model(TIME), CLEAN, atol=1e-8)


def test_clean_pulse_momenta():
    fit = fit_pulse(TIME, CLEAN)
    # the hump ends at T + (pi/2) tau, so the front (up to T + tau) holds almost all of it
    split = T_OF + TAU
    assert fit.front_momentum + fit.tail_momentum == pytest.approx(np.trapezoid(CLEAN, TIME), rel=1e-13)
    assert fit.total_momentum == pytest.approx(EXACT_AREA, rel=1e-6)
    tail_exact = F_M * TAU * (5 * math.pi / 32 - quad_cos6(1.0))
    # trapezoid rule with 50 samples per tau on the steep falling edge: ~0.4 % on this small tail
    assert fit.tail_momentum == pytest.approx(tail_exact, rel=1e-2)
    assert fit.front_momentum == pytest.approx(EXACT_AREA - tail_exact, rel=2e-5)  # same rule error
    front, tail = front_tail_momenta(TIME, CLEAN, split)
    assert (front, tail) == (fit.front_momentum, fit.tail_momentum)


def quad_cos6(x):
    """int_0^x cos^6 u du (closed form)."""
    return 5 * x / 16 + 15 * math.sin(2 * x) / 64 + 3 * math.sin(4 * x) / 64 + math.sin(6 * x) / 192


def test_noisy_pulse():
    rng = np.random.default_rng(12345)
    fit = fit_pulse(TIME, CLEAN + rng.normal(0.0, 0.02 * F_M, TIME.size))
    assert_noisy_fit(fit)
    assert fit.noise == pytest.approx(0.02 * F_M, rel=0.25)


def test_baseline_offset_clean_and_noisy():
    fit = fit_pulse(TIME, CLEAN + 7.5)
    assert fit.baseline == pytest.approx(7.5, abs=1e-12)
    assert_clean_fit(fit, rel=1e-9)
    # momenta are integrals of the baseline-corrected force
    assert fit.total_momentum == pytest.approx(EXACT_AREA, rel=1e-6)

    rng = np.random.default_rng(7)
    noisy = CLEAN - 12.0 + rng.normal(0.0, 0.02 * F_M, TIME.size)
    fit = fit_pulse(TIME, noisy)
    # median of ~900 pre-pulse samples: standard error ~ 1.25 sigma / 30 = 0.1 N
    assert fit.baseline == pytest.approx(-12.0, abs=0.5)
    assert_noisy_fit(fit)
    assert fit.front_momentum + fit.tail_momentum == pytest.approx(np.trapezoid(noisy - fit.baseline, TIME), rel=1e-12)


def test_given_baseline_is_used():
    fit = fit_pulse(TIME, CLEAN + 3.0, baseline=3.0)
    assert fit.baseline == 3.0
    assert_clean_fit(fit, rel=1e-9)


@pytest.mark.parametrize("points_on_rise, phase", [(6, 0.0), (6, 0.37), (5, 0.81), (8, 0.5)])
def test_coarse_sampling(points_on_rise, phase):
    dt = TAU / points_on_rise
    t = np.arange(phase * dt, 2.5e-3, dt)
    fit = fit_pulse(t, cos6_pulse(t, F_M, T_OF, TAU))
    # noise-free samples of the exact model: the fit is exact however few points there are
    assert_clean_fit(fit, rel=1e-7)
    assert fit.n_points in (points_on_rise, points_on_rise - 1, points_on_rise + 1)


def test_larger_later_pulse_is_ignored():
    # a reflection 2.5 times larger arrives 5 tau later
    signal = CLEAN + cos6_pulse(TIME, 2.5 * F_M, T_OF + 5 * TAU, 1.2 * TAU)
    fit = fit_pulse(TIME, signal)
    assert_clean_fit(fit, rel=1e-9)
    # the later pulse is in the tail momentum
    assert fit.tail_momentum > 2.5 * EXACT_AREA
    assert fit.front_momentum + fit.tail_momentum == pytest.approx(np.trapezoid(signal, TIME), rel=1e-13)


def test_larger_overlapping_pulse_with_noise():
    # a secondary wave twice as large starting before the first pulse has ended
    rng = np.random.default_rng(99)
    signal = CLEAN + cos6_pulse(TIME, 2.0 * F_M, T_OF + 2.5 * TAU, TAU) + rng.normal(0, 0.02 * F_M, TIME.size)
    assert_noisy_fit(fit_pulse(TIME, signal))


def test_scaled_amplitude_and_shifted_time_origin():
    # any units of amplitude / time origin: fit in scaled variables internally
    t = TIME + 123.456
    fit = fit_pulse(t, 1e-3 * CLEAN)
    assert_clean_fit(fit, F=1e-3 * F_M, T=T_OF + 123.456, rel=1e-6)


def test_signal_starting_at_the_pulse():
    # a simulated contact force recorded from rest at t = 0: no pre-pulse part -> baseline 0
    t = np.arange(0, 1e-3, DT)
    fit = fit_pulse(t, cos6_pulse(t, F_M, 1.6 * TAU, TAU))
    assert fit.baseline == 0.0
    assert_clean_fit(fit, T=1.6 * TAU, rel=1e-9)


@pytest.mark.parametrize("signal", [
    np.zeros(TIME.size),
    np.full(TIME.size, 4.2),
    np.random.default_rng(3).normal(0.0, 1.0, TIME.size),
    np.random.default_rng(4).normal(5.0, 1.0, TIME.size),
], ids=["zero", "constant", "noise", "noise+offset"])
def test_no_pulse_raises(signal):
    with pytest.raises(PulseNotFound, match="no pulse"):
        fit_pulse(TIME, signal)


def test_too_few_samples_and_truncated_records():
    with pytest.raises(PulseNotFound, match="samples"):
        fit_pulse(TIME[:5], CLEAN[:5])
    with pytest.raises(PulseNotFound, match="too coarsely"):  # 2 samples on the rise
        t = np.arange(0.0, 3e-3, TAU / 2)
        fit_pulse(t, cos6_pulse(t, F_M, T_OF + 0.3 * TAU, TAU))
    with pytest.raises(PulseNotFound, match="ends before"):  # the record stops on the rise
        cut = TIME < T_OF - 0.2 * TAU
        fit_pulse(TIME[cut], CLEAN[cut])
    with pytest.raises(PulseNotFound, match="starts during the rise"):
        cut = TIME > T_OF - 0.2 * TAU
        fit_pulse(TIME[cut], CLEAN[cut])


def test_bad_input():
    with pytest.raises(ConfigError):
        fit_pulse(TIME, CLEAN[:-1])
    with pytest.raises(ConfigError):
        fit_pulse(TIME[::-1], CLEAN)
    bad = CLEAN.copy()
    bad[3] = np.nan
    with pytest.raises(ConfigError):
        fit_pulse(TIME, bad)


# --- reading records and batch analysis (hertzchain.analysis.io) -------------------------------
@pytest.mark.parametrize("header, t_scale, f_scale, sep", [
    ("time,force", 1.0, 1.0, ","),
    ("t_ms;F_kN", 1e3, 1e-3, ";"),
    ("time [us]\tforce (N)", 1e6, 1.0, "\t"),
    ("time_s wall_force", 1.0, 1.0, " "),
    (None, 1.0, 1.0, ","),
])
def test_read_signal_csv_units_and_layouts(tmp_path, header, t_scale, f_scale, sep):
    path = tmp_path / "signal.csv"
    lines = ["# oscilloscope export"] + ([header] if header else [])
    lines += [f"{t * t_scale:.17g}{sep}{f * f_scale:.17g}" for t, f in zip(TIME[::10], CLEAN[::10])]
    path.write_text("\n".join(lines) + "\n")
    t, f = read_signal_csv(path)
    np.testing.assert_allclose(t, TIME[::10], rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(f, CLEAN[::10], rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("text, message", [
    ("a,b\n1,2\n2,3\n", "no time column"),
    ("time,x\n1,2\n2,3\n", "no force column"),
    ("time,wall_force,sensor_force\n1,2,3\n2,3,4\n", "several force columns"),
    ("time [fortnight],force\n1,2\n2,3\n", "unknown unit"),
    ("1,2,3\n2,3,4\n", "no header line and 3 columns"),
    ("time,force\n1,2\n1,3\n", "not strictly increasing"),
    ("time,force\n1,2\n2,oops\n", "line 3"),
    ("# nothing\n", "no data"),
])
def test_read_signal_csv_errors(tmp_path, text, message):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(ConfigError, match=message):
        read_signal_csv(path)
    with pytest.raises(ConfigError, match="cannot read"):
        read_signal_csv(tmp_path / "missing.csv")


def test_read_signal_csv_explicit_column(tmp_path):
    path = tmp_path / "two.csv"
    path.write_text("time,wall_force,sensor_force\n0,1,5\n1,2,6\n")
    t, f = read_signal_csv(path, force_column="sensor_force")
    np.testing.assert_array_equal(f, [5.0, 6.0])


def _dataset():
    import xarray as xr

    sensors = [8, 12]
    sensor = np.stack([cos6_pulse(TIME, 60.0, 0.6e-3, 90e-6), np.zeros(TIME.size)], axis=1)
    contact = np.stack([cos6_pulse(TIME, 50.0 + 10 * j, 0.2e-3 + j * 0.1e-3, 90e-6) for j in range(3)], axis=1)
    return xr.Dataset(
        {"wall_force": ("time", 2 * CLEAN, {"units": "N"}),
         "sensor_force": (("time", "sensor"), sensor, {"units": "N"}),
         "contact_force": (("time", "contact"), contact, {"units": "N"})},
        coords={"time": ("time", TIME, {"units": "s"}), "sensor": sensors, "contact": [0, 1, 2]},
    )


def test_analyze_signals_dataset():
    ds = _dataset()
    rows = analyze_signals(ds, signals=("wall_force", "sensor_force", "contact_force"))
    assert [(r["signal"], r["index"]) for r in rows] == [
        ("wall_force", None), ("sensor_force", 8), ("sensor_force", 12),
        ("contact_force", 0), ("contact_force", 1), ("contact_force", 2)]
    assert all(tuple(r) == ROW_KEYS for r in rows)
    wall = rows[0]
    assert wall["error"] is None
    assert wall["peak_force"] == pytest.approx(2 * F_M, rel=1e-9)
    assert wall["time_of_flight"] == pytest.approx(T_OF, abs=1e-12)
    assert wall["duration"] == pytest.approx(TAU, rel=1e-9)
    assert wall["front_momentum"] + wall["tail_momentum"] == pytest.approx(2 * EXACT_AREA, rel=1e-6)
    assert rows[1]["time_of_flight"] == pytest.approx(0.6e-3, abs=1e-12)
    # the sensor that saw nothing gives a row with an error message, not an exception
    assert "no pulse" in rows[2]["error"] and np.isnan(rows[2]["peak_force"])
    assert [r["peak_force"] for r in rows[3:]] == pytest.approx([50.0, 60.0, 70.0], rel=1e-9)
    with pytest.raises(ConfigError, match="not a variable"):
        analyze_signals(ds, signals=("bead_velocity",))


def test_analyze_signals_files(tmp_path):
    ds = _dataset()
    nc = tmp_path / "run.nc"
    ds.to_netcdf(nc)
    rows = analyze_signals(nc, signals="sensor_force")
    assert [r["index"] for r in rows] == [8, 12]
    assert rows[0]["peak_force"] == pytest.approx(60.0, rel=1e-9)
    assert rows[0]["time_of_flight"] == pytest.approx(0.6e-3, abs=1e-12)

    csv_path = tmp_path / "wall.csv"
    csv_path.write_text("time_ms,force_N\n" + "\n".join(
        f"{t * 1e3:.17g},{f:.17g}" for t, f in zip(TIME, CLEAN + 1.0)))
    (row,) = analyze_signals(csv_path)
    assert row["signal"] == "force" and row["index"] is None and row["error"] is None
    assert row["baseline"] == pytest.approx(1.0, abs=1e-9)
    assert row["peak_force"] == pytest.approx(F_M, rel=1e-9)


@pytest.mark.parametrize("offset_mm", [0.0, 0.02, 0.05])
def test_compiled_window_updates_give_the_scipy_loops_fit(offset_mm):
    """The window's fixed point found by compiled Gauss-Newton steps (analysis/window_fit.py), then
    one scipy fit, is the fit of the scipy-only loop: same window, same number of window updates,
    parameters equal to the LM solver's own convergence (~1e-9 relative on a noise-free pulse
    whose cos^6 is not exact), on simulated wall pulses of chain 1, straight and misaligned (whose
    window may cycle between two sample sets until max_iter)."""
    import hertzchain as hc

    rng = np.random.default_rng(3)
    chain = hc.paper_chain("chain1")
    if offset_mm:
        chain = hc.Chain(chain.diameters, chain.materials, offsets=rng.normal(0.0, offset_mm * 1e-3, chain.diameters.size))
    ds = hc.simulate(hc.Model(chain, hc.Striker(8e-3, 0.2)), 3e-3, hc.Probes(1e-7))
    t, f = ds.time.values, ds.wall_force.values
    fast = fit_pulse(t, f, compiled=True)
    slow = fit_pulse(t, f)
    assert (fast.window, fast.n_points, fast.iterations) == (slow.window, slow.n_points, slow.iterations)
    for name in ("peak_force", "time_of_flight", "duration", "front_momentum"):
        assert getattr(fast, name) == pytest.approx(getattr(slow, name), rel=1e-8), name
