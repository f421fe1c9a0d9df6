"""Tests of the measurement chain (sensor, noise, oscilloscope sampling, trigger, ADC, averaging)."""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
import pytest

from hertzchain.errors import ConfigError
from hertzchain.instrument import (
    PCB_200B02_MV_PER_N,
    PCB_208A11_MV_PER_N,
    Acquisition,
    Instrument,
    InstrumentWarning,
)

# An instrument with no measurement error worth speaking of: used as the base of most tests.
IDEAL = dict(noise_rms_mV=0.0, bits=48, trigger_jitter=False, n_average=1)


def gaussian(t, t0=1.0e-3, width=50e-6, amplitude=20.0):
    """A smooth positive pulse [N]."""
    return amplitude * np.exp(-0.5 * ((t - t0) / width) ** 2)


def gaussian_crossing(level, t0=1.0e-3, width=50e-6, amplitude=20.0):
    """Exact time of the first upward crossing of ``level`` by :func:`gaussian` [s]."""
    return t0 - width * math.sqrt(2.0 * math.log(amplitude / level))


# --- settings and presets ----------------------------------------------------------------------

def test_presets_carry_the_paper_sensitivities_and_accept_overrides():
    wall = Instrument.pcb_208a11()
    chain = Instrument.pcb_200b02(n_average=9, bits=12)
    assert wall.sensitivity_mV_per_N == PCB_208A11_MV_PER_N == 112.40
    assert chain.sensitivity_mV_per_N == PCB_200B02_MV_PER_N == 11.24
    assert (chain.n_average, chain.bits) == (9, 12)
    # TDS340 defaults
    assert (wall.record_length, wall.bits) == (1000, 8)
    with pytest.raises(ConfigError) as err:
        Instrument.pcb_208a11(volts_per_division=1.0)
    assert err.value.field == "instrument.volts_per_division"


def test_instrument_is_frozen_and_replace_revalidates():
    inst = Instrument()
    with pytest.raises(dataclasses.FrozenInstanceError):
        inst.bits = 12  # type: ignore[misc]
    assert inst.replace(bits=12).bits == 12
    with pytest.raises(ConfigError):
        inst.replace(bits=0)


def test_quantisation_step_and_range():
    inst = Instrument(sensitivity_mV_per_N=100.0, full_scale_V=8.0, offset_V=1.0, bits=8)
    assert inst.quantisation_step_V == pytest.approx(8.0 / 256)
    assert inst.quantisation_step_N == pytest.approx(8.0 / 256 / 0.1)
    lo, hi = inst.range_V
    assert lo == pytest.approx(1.0 - 4.0)
    assert hi == pytest.approx(1.0 + 4.0 - 8.0 / 256)
    assert inst.range_N == pytest.approx((lo / 0.1, hi / 0.1))
    assert inst.volts_per_div == pytest.approx(1.0)
    # The paper's wall channel on the default +-5 V window: ~0.35 N per level.
    assert Instrument.pcb_208a11().quantisation_step_N == pytest.approx(10.0 / 256 / 0.1124)


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("sensitivity_mV_per_N", 0.0),
        ("sensitivity_mV_per_N", -11.24),
        ("sensitivity_mV_per_N", float("nan")),
        ("noise_rms_mV", -1.0),
        ("noise_rms_mV", float("inf")),
        ("sample_rate", 0.0),
        ("sample_rate", "1e6"),
        ("record_length", 1),
        ("record_length", 1000.0),
        ("trigger_level_N", float("nan")),
        ("pretrigger_fraction", -0.1),
        ("pretrigger_fraction", 1.0),
        ("bits", 0),
        ("bits", 49),
        ("bits", 8.5),
        ("bits", True),
        ("full_scale_V", 0.0),
        ("offset_V", float("inf")),
        ("n_average", 0),
        ("n_average", 2.0),
        ("trigger_jitter", "yes"),
        ("seed", -1),
        ("seed", 1.5),
    ],
)
def test_bad_settings_raise_config_error_naming_the_field(name, value):
    with pytest.raises(ConfigError) as err:
        Instrument(**{name: value})
    assert err.value.field == f"instrument.{name}"
    assert isinstance(err.value, ValueError)


def test_numpy_integers_are_accepted():
    inst = Instrument(bits=np.int64(10), record_length=np.int32(500), seed=np.uint8(3))
    assert inst.bits == 10


def test_bad_arrays_raise_config_error_naming_the_argument():
    t = np.linspace(0.0, 2e-3, 2001)
    f = gaussian(t)
    inst = Instrument(**IDEAL)
    with pytest.raises(ConfigError) as err:
        inst.acquire(t[::-1], f)
    assert err.value.field == "acquire.time"
    with pytest.raises(ConfigError) as err:
        inst.acquire(t, f[:-1])
    assert err.value.field == "acquire.force"
    with pytest.raises(ConfigError) as err:
        inst.acquire(t, f, trigger_signal=f[:10])
    assert err.value.field == "acquire.trigger_signal"
    bad = f.copy()
    bad[5] = np.nan
    with pytest.raises(ConfigError) as err:
        inst.acquire(t, bad)
    assert err.value.field == "acquire.force"


def test_trigger_that_never_fires_names_the_level():
    t = np.linspace(0.0, 2e-3, 2001)
    with pytest.raises(ConfigError) as err:
        Instrument(trigger_level_N=50.0, **IDEAL).acquire(t, gaussian(t))
    assert err.value.field == "instrument.trigger_level_N"


# --- quantisation and clipping -----------------------------------------------------------------

def test_quantisation_error_is_at_most_half_a_step_and_output_is_on_the_grid():
    # A ramp spanning most of the window, sampled exactly (linear interpolation of a line is exact).
    inst = Instrument(sensitivity_mV_per_N=100.0, full_scale_V=4.0, offset_V=0.5, bits=8,
                      sample_rate=1e6, record_length=1000, pretrigger_fraction=0.0,
                      trigger_level_N=-10.0, noise_rms_mV=0.0, trigger_jitter=False)
    t = np.linspace(0.0, 1.2e-3, 12001)
    slope = 30.0 / 1e-3                                   # N/s: -15 N -> +21 N over the record
    f = -15.0 + slope * t
    with warnings.catch_warnings():
        warnings.simplefilter("error")                    # no clipping, no coarse-grid warning
        acq = inst.acquire(t, f)
    assert isinstance(acq, Acquisition)
    ideal = -15.0 + slope * acq.absolute_time
    q = inst.quantisation_step_V
    err_V = acq.volts - ideal * inst.volts_per_N
    assert np.max(np.abs(err_V)) <= 0.5 * q * (1 + 1e-9)
    # The error really uses the whole half step (not trivially zero).
    assert np.max(np.abs(err_V)) > 0.4 * q
    codes = (acq.volts - inst.offset_V) / q
    np.testing.assert_allclose(codes, np.rint(codes), atol=1e-9)
    # Many distinct levels visited, and force is volts / sensitivity.
    assert np.unique(np.rint(codes)).size > 100
    np.testing.assert_allclose(acq.force, acq.volts / 0.1)
    assert acq.n_clipped == 0


def test_quantise_rounds_to_nearest_level():
    inst = Instrument(full_scale_V=8.0, bits=3)           # step 1 V, codes -4..3
    out, clipped = inst.quantise(np.array([0.2, 0.7, -1.3, 2.49, -3.6]))
    np.testing.assert_array_equal(out, [0.0, 1.0, -1.0, 2.0, -4.0])
    assert clipped == 0


def test_clipping_at_full_scale():
    inst = Instrument(sensitivity_mV_per_N=100.0, full_scale_V=2.0, offset_V=0.0, bits=8,
                      trigger_level_N=0.5, trigger_jitter=False)
    t = np.linspace(0.0, 2e-3, 20001)
    f = 30.0 * np.sin(2 * np.pi * 2e3 * t)                # +-3 V, the window is +-1 V
    with pytest.warns(InstrumentWarning, match="clipped"):
        acq = inst.acquire(t, f)
    lo, hi = inst.range_V
    assert acq.volts.max() == pytest.approx(hi) and hi == pytest.approx(1.0 - 2.0 / 256)
    assert acq.volts.min() == pytest.approx(lo) and lo == pytest.approx(-1.0)
    assert acq.n_clipped > 0
    # Clipped samples are exactly where the ideal signal leaves the window.
    # (the record starts before t = 0, where the first value, 0, is held)
    ideal_V = np.interp(acq.absolute_time, t, f) * 0.1
    outside = (ideal_V > hi + inst.quantisation_step_V / 2) | (ideal_V < lo - inst.quantisation_step_V / 2)
    assert acq.n_clipped == np.count_nonzero(outside)
    np.testing.assert_allclose(acq.volts[ideal_V > hi + 0.01], hi)


# --- sampling and trigger ----------------------------------------------------------------------

def test_sine_sampled_at_scope_rate_reproduces_its_values():
    fs, n = 250e3, 1000
    inst = Instrument(sample_rate=fs, record_length=n, pretrigger_fraction=0.25,
                      trigger_level_N=0.0, full_scale_V=40.0, sensitivity_mV_per_N=1000.0, **IDEAL)
    amp, freq, t0 = 10.0, 3.1e3, 1.0e-3
    t = np.arange(0.0, 6e-3, 1e-7)                        # simulation 40x finer than the scope
    sine = lambda x: amp * np.sin(2 * np.pi * freq * (x - t0))  # noqa: E731
    f = np.where(t < t0, -1.0, sine(t))                   # at rest (below the level) until t0
    acq = inst.acquire(t, f)
    assert acq.time.shape == (n,)
    np.testing.assert_allclose(np.diff(acq.time), 1.0 / fs, rtol=1e-9)
    assert acq.trigger_time == pytest.approx(t0, abs=1e-7)
    after = acq.absolute_time >= t0 + 1e-7
    # Linear interpolation of the fine grid: error <= amp (2 pi f dt_sim)^2 / 8 ~ 5e-7 N.
    np.testing.assert_allclose(acq.force[after], sine(acq.absolute_time[after]), atol=1e-5)
    assert acq.covered.all()


def test_trigger_puts_first_crossing_at_the_pretrigger_index():
    level = 5.0
    inst = Instrument(trigger_level_N=level, pretrigger_fraction=0.2, record_length=500,
                      sample_rate=2e6, **IDEAL)
    t = np.arange(0.0, 3e-3, 5e-8)
    f = gaussian(t) + gaussian(t, t0=2.0e-3)              # second pulse must not re-trigger
    acq = inst.acquire(t, f)
    t_c = gaussian_crossing(level)
    assert acq.trigger_index == 100
    assert acq.time[100] == 0.0
    assert acq.trigger_time == pytest.approx(t_c, abs=1e-10)
    assert acq.absolute_time[0] == pytest.approx(t_c - 100 / 2e6)
    assert acq.force[100] == pytest.approx(level, rel=1e-5)
    assert np.all(acq.force[:100] < level)
    assert acq.force[101] > level


def test_trigger_on_a_separate_signal():
    # As in the paper: record one sensor, trigger with the other (which sees the pulse earlier).
    t = np.arange(0.0, 3e-3, 1e-7)
    trigger = gaussian(t, t0=0.8e-3, amplitude=50.0)
    recorded = gaussian(t, t0=1.1e-3, amplitude=20.0)
    inst = Instrument(trigger_level_N=10.0, pretrigger_fraction=0.1, **IDEAL)
    acq = inst.acquire(t, recorded, trigger_signal=trigger)
    t_c = gaussian_crossing(10.0, t0=0.8e-3, amplitude=50.0)
    assert acq.trigger_time == pytest.approx(t_c, abs=1e-10)
    np.testing.assert_allclose(acq.force, gaussian(acq.absolute_time, t0=1.1e-3), atol=1e-5)
    # The recorded pulse peaks ~ (1.1 - t_c) ms after the trigger.
    assert acq.time[np.argmax(acq.force)] == pytest.approx(1.1e-3 - t_c, abs=1e-6)


def test_trigger_jitter_delays_the_sample_clock_by_less_than_one_interval():
    level = 5.0
    fs = 1e6
    inst = Instrument(trigger_level_N=level, sample_rate=fs, bits=48, n_average=50, trigger_jitter=True)
    t = np.arange(0.0, 3e-3, 2e-8)
    acq = inst.acquire(t, gaussian(t))
    assert acq.jitter.shape == (50,)
    assert np.all((acq.jitter >= 0) & (acq.jitter < 1 / fs))
    assert np.ptp(acq.jitter) > 0.5 / fs                   # really random (50 draws)
    # Each acquisition sees the signal between its values at t_c and t_c + dt.
    t_c = gaussian_crossing(level)
    assert gaussian(np.array([t_c]))[0] <= acq.force[acq.trigger_index] <= gaussian(np.array([t_c + 1 / fs]))[0]
    # Same seed, same record; another generator, another jitter.
    np.testing.assert_array_equal(inst.acquire(t, gaussian(t)).jitter, acq.jitter)
    assert not np.array_equal(inst.acquire(t, gaussian(t), rng=np.random.default_rng(7)).jitter, acq.jitter)


# --- noise and averaging -----------------------------------------------------------------------

def test_averaging_reduces_noise_rms_by_sqrt_n():
    # Zero force on the recorded channel, triggered by a separate ramp; resolution ~1e-13 V so the
    # ADC adds nothing. With M = 20000 independent samples, the relative standard error of an rms
    # estimate is 1/sqrt(2M) = 0.5 % (0.7 % for the ratio of two); the 5 % (7 %) tolerances are
    # 10 standard errors wide (over 300 seeds the worst deviations seen were 1.7 % and 2.2 %).
    m, sigma_mV = 20000, 2.0
    t = np.linspace(0.0, 0.1, 200001)                      # 0.5 us steps, scope 1 us
    inst = Instrument(noise_rms_mV=sigma_mV, record_length=m, sample_rate=1e6, bits=48,
                      trigger_level_N=1.0, trigger_jitter=True, seed=123)
    zero = np.zeros_like(t)
    ramp = 1e3 * t
    rms = {}
    for n in (1, 9):
        acq = inst.replace(n_average=n).acquire(t, zero, trigger_signal=ramp)
        rms[n] = float(np.sqrt(np.mean(acq.volts**2))) * 1e3
    assert rms[1] == pytest.approx(sigma_mV, rel=0.05)
    assert rms[9] == pytest.approx(sigma_mV / 3.0, rel=0.05)
    assert rms[1] / rms[9] == pytest.approx(3.0, rel=0.07)


def test_noise_is_reproducible_with_the_seed_and_can_be_varied():
    t = np.arange(0.0, 3e-3, 1e-7)
    inst = Instrument(noise_rms_mV=50.0, trigger_level_N=5.0)
    a, b = inst.acquire(t, gaussian(t)), inst.acquire(t, gaussian(t))
    np.testing.assert_array_equal(a.volts, b.volts)
    c = inst.replace(seed=1).acquire(t, gaussian(t))
    assert not np.array_equal(a.volts, c.volts)


def test_inputs_are_not_modified():
    t = np.arange(0.0, 3e-3, 1e-7)
    f = gaussian(t)
    t0, f0 = t.copy(), f.copy()
    Instrument(noise_rms_mV=10.0, n_average=3, trigger_level_N=5.0).acquire(t, f)
    np.testing.assert_array_equal(t, t0)
    np.testing.assert_array_equal(f, f0)


# --- the ideal limit and warnings --------------------------------------------------------------

@pytest.mark.parametrize("jitter", [False, True])
def test_ideal_signal_is_recovered_without_noise_fine_adc_and_fast_sampling(jitter):
    t = np.arange(0.0, 3e-3, 2e-8)
    inst = Instrument(sample_rate=50e6, record_length=20000, trigger_level_N=1.0, bits=48,
                      noise_rms_mV=0.0, trigger_jitter=jitter, n_average=4)
    acq = inst.acquire(t, gaussian(t))
    # With jitter the sample clock lags by < dt, so the error is bounded by max|dF/dt| x dt
    # (= 20 N e^-1/2 / 50 us x 20 ns ~ 5e-3 N); without it only the ~1e-7 N interpolation error.
    max_slope = 20.0 * math.exp(-0.5) / 50e-6
    tol = 1.05 * max_slope / 50e6 if jitter else 1e-5
    np.testing.assert_allclose(acq.force, gaussian(acq.absolute_time), atol=tol)
    assert acq.force.max() == pytest.approx(20.0, rel=1e-3)


def test_record_held_before_start_and_warned_after_end():
    t = np.arange(0.0, 0.8e-3, 1e-7)
    f = 0.3 + gaussian(t, t0=0.1e-3, width=20e-6) + 1.5 * (t > 0.5e-3)   # static preload, late step
    inst = Instrument(trigger_level_N=1.0, pretrigger_fraction=0.5, record_length=2000, **IDEAL)
    with pytest.warns(InstrumentWarning, match="past the end"):
        acq = inst.acquire(t, f)
    # Record covers [t_c - 1 ms, t_c + 1 ms]: its start lies before t = 0, held at f[0].
    before = acq.absolute_time < 0
    after = acq.absolute_time > t[-1]
    assert before.any() and after.any()
    np.testing.assert_array_equal(acq.covered, ~(before | after))
    np.testing.assert_allclose(acq.force[before], f[0], rtol=1e-9)
    np.testing.assert_allclose(acq.force[after], f[-1], rtol=1e-9)
    assert (f[0], f[-1]) == (pytest.approx(0.3, abs=1e-3), pytest.approx(1.8))


def test_coarse_simulation_grid_warns():
    t = np.arange(0.0, 3e-3, 2e-6)                         # 2 us steps, scope 1 us
    with pytest.warns(InstrumentWarning, match="coarser"):
        Instrument(trigger_level_N=1.0, **IDEAL).acquire(t, gaussian(t))
