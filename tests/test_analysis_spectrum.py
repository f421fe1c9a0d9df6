"""Power spectra of hertzchain.analysis.spectrum (paper Figs. 1h, 2h: energy cascade)."""

from __future__ import annotations

import numpy as np
import pytest

from hertzchain.analysis import compare_spectra, cos6_pulse, power_spectrum, spectral_centroid
from hertzchain.errors import ConfigError

FS = 1e6  # Hz, 1 us sampling
TIME = np.arange(0, 4096) / FS


def test_sine_peak_at_its_frequency():
    f0 = 12_500.0  # between bins: 4096 samples at 1 MHz give 244.14 Hz bins, 12500 Hz is bin 51.2
    force = 3.0 * np.sin(2 * np.pi * f0 * TIME)
    freq, power = power_spectrum(TIME, force)
    df = freq[1] - freq[0]
    assert df == pytest.approx(FS / TIME.size)
    assert abs(freq[np.argmax(power)] - f0) <= df / 2
    # zero padding refines the grid and the peak
    freq, power = power_spectrum(TIME, force, nfft=16 * TIME.size)
    assert abs(freq[np.argmax(power)] - f0) <= (freq[1] - freq[0])


def test_parseval_with_boxcar_window():
    force = cos6_pulse(TIME, 100.0, 2e-3, 50e-6)
    freq, power = power_spectrum(TIME, force, window="boxcar")
    # one-sided density: int P df = mean(F^2)
    assert np.sum(power) * (freq[1] - freq[0]) == pytest.approx(np.mean(force**2), rel=1e-10)


def test_narrower_pulse_has_higher_centroid():
    wide = cos6_pulse(TIME, 100.0, 2e-3, 80e-6)
    narrow = cos6_pulse(TIME, 100.0, 2e-3, 40e-6)
    c_wide = spectral_centroid(*power_spectrum(TIME, wide))
    c_narrow = spectral_centroid(*power_spectrum(TIME, narrow))
    # the spectrum of F(t / tau) scales as 1/tau in frequency: the centroid doubles
    assert c_narrow == pytest.approx(2 * c_wide, rel=0.02)


def test_spectral_centroid_band():
    freq = np.linspace(0, 10, 101)
    power = np.ones_like(freq)
    assert spectral_centroid(freq, power) == pytest.approx(5.0)
    assert spectral_centroid(freq, power, fmin=2, fmax=4) == pytest.approx(3.0)
    with pytest.raises(ConfigError):
        spectral_centroid(freq, np.zeros_like(freq))


def test_compare_spectra_energy_cascade():
    # incoming: the solitary wave of the uniform part; outgoing: a weaker, narrower front
    # followed by an oscillating tail (paper Figs. 1, 2)
    incoming = cos6_pulse(TIME, 100.0, 1e-3, 90e-6)
    outgoing = cos6_pulse(TIME, 60.0, 1e-3, 40e-6)
    for k in range(1, 6):
        outgoing += cos6_pulse(TIME, 25.0 / k, 1e-3 + k * 90e-6, 30e-6)
    cmp = compare_spectra(TIME, incoming, TIME, outgoing)
    assert cmp.centroid_out > 1.5 * cmp.centroid_in
    assert cmp.centroid_ratio == pytest.approx(cmp.centroid_out / cmp.centroid_in)
    assert cmp.power_in.max() == pytest.approx(1.0) and cmp.power_out.max() == pytest.approx(1.0)
    np.testing.assert_array_equal(cmp.freq_in, cmp.freq_out)
    area = compare_spectra(TIME, incoming, TIME, outgoing, normalize="area")
    assert np.trapezoid(area.power_out, area.freq_out) == pytest.approx(1.0)
    assert area.centroid_in == pytest.approx(cmp.centroid_in)  # normalisation does not move it


def test_power_spectrum_rejects_uneven_sampling():
    t = np.sort(np.random.default_rng(0).uniform(0, 1e-3, 500))
    with pytest.raises(ConfigError, match="uniformly"):
        power_spectrum(t, np.ones_like(t))


@pytest.mark.parametrize("n, nfft", [(4096, None), (1001, None), (1001, 4096), (1000, 3001)])
@pytest.mark.parametrize("window", ["hann", "boxcar", "hamming"])
@pytest.mark.parametrize("detrend", [False, "constant", "linear"])
def test_power_spectrum_is_scipys_periodogram(n, nfft, window, detrend):
    """The numpy periodogram equals scipy.signal.periodogram (the independent reference) for
    even and odd lengths and transforms, zero padding, scipy windows and every detrending."""
    from scipy.signal import periodogram

    rng = np.random.default_rng(n + (nfft or 0))
    t = np.arange(n) / FS
    force = cos6_pulse(t, 100.0, t[n // 3], 50e-6) + 0.3 + 2e3 * t + rng.normal(0.0, 0.5, n)
    freq, power = power_spectrum(t, force, nfft=nfft, window=window, detrend=detrend)
    ref_freq, ref_power = periodogram(force, fs=FS, window=window, nfft=nfft, detrend=detrend,
                                      scaling="density", return_onesided=True)
    np.testing.assert_allclose(freq, ref_freq, rtol=1e-12)
    np.testing.assert_allclose(power, ref_power, rtol=1e-9, atol=1e-12 * ref_power.max())


def test_importing_analysis_leaves_scipy_signal_unloaded():
    """scipy.signal (~0.45 s to import) is loaded only for a window or detrending it provides."""
    import subprocess
    import sys

    code = ("import sys, numpy as np; import hertzchain.analysis as a; t = np.arange(64) * 1e-6; "
            "a.power_spectrum(t, np.sin(t * 1e5)); a.power_spectrum(t, np.sin(t * 1e5), window='boxcar'); "
            "print(int('scipy.signal' in sys.modules))")
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip() == "0"


def test_power_spectrum_rejects_unknown_window_and_detrend():
    force = np.sin(2 * np.pi * 1e4 * TIME)
    with pytest.raises(ConfigError, match="window"):
        power_spectrum(TIME, force, window="no-such-window")
    with pytest.raises(ConfigError, match="detrend"):
        power_spectrum(TIME, force, detrend="quadratic")
