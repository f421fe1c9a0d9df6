"""Power spectra of force signals (Melo et al., PRE 2006, Figs. 1h and 2h).

The paper compares the spectrum of the incident solitary wave with that of the wave leaving the
tapered chain and sees "a clear cascade of energy from low to high frequencies". Here the
spectra are periodograms (the definition of :func:`scipy.signal.periodogram`) and the cascade is
summarised by the spectral centroid, the power-weighted mean frequency, which must be higher for
the outgoing wave.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ConfigError

__all__ = ["power_spectrum", "spectral_centroid", "SpectraComparison", "compare_spectra"]


def _sampling_rate(time: np.ndarray) -> float:
    """Sampling frequency [Hz] of a uniformly sampled time axis [s]."""
    if time.ndim != 1 or time.size < 4:
        raise ConfigError("time", "must be a 1-D array of at least 4 samples")
    dt = np.diff(time)
    if np.any(dt <= 0):
        raise ConfigError("time", "must be strictly increasing")
    mean_dt = (time[-1] - time[0]) / (time.size - 1)
    # an FFT needs uniform sampling; allow round-off in the stored time axis only
    if np.max(np.abs(dt - mean_dt)) > 1e-6 * mean_dt + 1e-12 * abs(time).max():
        raise ConfigError("time", "must be uniformly sampled for a power spectrum "
                          "(resample first, e.g. with numpy.interp)")
    return 1.0 / mean_dt


def power_spectrum(time: ArrayLike, force: ArrayLike, *, nfft: int | None = None, window: str = "hann",
                   detrend: str | bool = False) -> tuple[np.ndarray, np.ndarray]:
    """One-sided power spectral density of a uniformly sampled force record.

    The periodogram of :func:`scipy.signal.periodogram` with ``scaling="density"`` (equal to
    it to rounding): ``P(f_k) = c abs(sum_n w_n F_n exp(-2 pi i k n / nfft))^2 / (fs sum_n w_n^2)``
    with c = 2 except at 0 Hz and the Nyquist frequency (one-sided density). It is computed
    with :func:`numpy.fft.rfft` so that importing :mod:`hertzchain.analysis` does not load
    :mod:`scipy.signal` (~0.45 s, most of it scipy.stats); windows other than "hann" and
    "boxcar" and linear detrending are taken from scipy.signal when asked for.

    Parameters
    ----------
    time
        Sample times [s], uniformly spaced.
    force
        Force [N]. Remove any baseline first (e.g. ``PulseFit.baseline``): the mean of a pulse
        is part of its spectrum, so no detrending is done by default.
    nfft
        FFT length (zero padding refines the frequency grid); default: the record length.
    window
        scipy window name. "hann" suppresses the leakage of a record cut inside the pulse tail
        (as in the paper's high-rate records); "boxcar" keeps Parseval's relation exact for a
        pulse that fits entirely in the record.
    detrend
        "constant" (remove the mean), "linear" (remove the least-squares line) or False.

    Returns
    -------
    (frequency [Hz], power [N^2/Hz])
    """
    t = np.asarray(time, dtype=float)
    f = np.asarray(force, dtype=float)
    if f.shape != t.shape:
        raise ConfigError("time/force", f"must have equal shapes, got {t.shape} and {f.shape}")
    if not np.all(np.isfinite(f)):
        raise ConfigError("force", "contains NaN or infinite values")
    fs = _sampling_rate(t)
    if nfft is not None and nfft < f.size:
        raise ConfigError("nfft", f"must be at least the record length ({f.size}), got {nfft}")
    n = f.size
    nfft = n if nfft is None else int(nfft)
    f = _detrended(f, detrend)
    w = _window(window, n)
    power = np.abs(np.fft.rfft(f * w, nfft)) ** 2 / (fs * np.sum(w * w))
    # one-sided: the negative frequencies' power folded onto the positive ones (not 0 Hz, nor
    # the Nyquist bin of an even-length transform, which have no mirror image)
    power[1: None if nfft % 2 else -1] *= 2
    return np.fft.rfftfreq(nfft, 1.0 / fs), power


def _window(name: str, n: int) -> np.ndarray:
    """Window of ``n`` samples, periodic (DFT-even) as :func:`scipy.signal.get_window` gives it."""
    if name == "hann":
        return 0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(n) / n)
    if name == "boxcar":
        return np.ones(n)
    from scipy.signal import get_window  # any other scipy window, loaded only when used

    try:
        return get_window(name, n)
    except ValueError as exc:
        raise ConfigError("window", f"{name!r} is not a scipy window name ({exc})") from None


def _detrended(f: np.ndarray, detrend: str | bool) -> np.ndarray:
    """``f`` without its mean ("constant") or its least-squares line ("linear"), as scipy detrends."""
    if detrend is False or detrend is None:
        return f
    if detrend == "constant":
        return f - f.mean()
    if detrend == "linear":
        from scipy.signal import detrend as linear

        return linear(f, type="linear")
    raise ConfigError("detrend", f"must be 'constant', 'linear' or False, got {detrend!r}")


def spectral_centroid(freq: ArrayLike, power: ArrayLike, *, fmin: float = 0.0, fmax: float | None = None) -> float:
    """Power-weighted mean frequency [Hz], int f P df / int P df, over [fmin, fmax].

    Parameters
    ----------
    freq:
        Frequencies [Hz], increasing.
    power:
        Power spectral density (any unit; only its shape matters).
    fmin, fmax:
        Frequency band [Hz]; default the whole spectrum.
    """
    fr = np.asarray(freq, dtype=float)
    pw = np.asarray(power, dtype=float)
    if fr.shape != pw.shape or fr.ndim != 1:
        raise ConfigError("freq/power", "must be 1-D arrays of equal length")
    band = fr >= fmin
    if fmax is not None:
        band &= fr <= fmax
    if np.count_nonzero(band) < 2:
        raise ConfigError("fmin/fmax", "the band holds fewer than two frequencies")
    weight = np.trapezoid(pw[band], fr[band])
    if not weight > 0:
        raise ConfigError("power", "has no positive power in the band")
    return float(np.trapezoid(fr[band] * pw[band], fr[band]) / weight)


@dataclass(frozen=True)
class SpectraComparison:
    """Incoming and outgoing spectra, normalised for comparison (paper Figs. 1h, 2h).

    Attributes
    ----------
    freq_in, freq_out:
        Frequencies [Hz].
    power_in, power_out:
        Power spectra normalised as requested (dimensionless, "arbitrary units").
    centroid_in, centroid_out:
        Spectral centroids [Hz]; the paper's energy cascade means centroid_out > centroid_in.
    """

    freq_in: np.ndarray
    power_in: np.ndarray
    freq_out: np.ndarray
    power_out: np.ndarray
    centroid_in: float
    centroid_out: float

    @property
    def centroid_ratio(self) -> float:
        """centroid_out / centroid_in (> 1 when energy moved to higher frequencies)."""
        return self.centroid_out / self.centroid_in


def compare_spectra(time_in: ArrayLike, force_in: ArrayLike, time_out: ArrayLike,
                    force_out: ArrayLike, *, nfft: int | None = None,
                    window: str = "hann", normalize: str = "max",
                    fmax: float | None = None) -> SpectraComparison:
    """Spectra of the incoming and outgoing pulses, normalised, with their centroids.

    Parameters
    ----------
    time_in, force_in:
        Incoming pulse (e.g. the sensor in the uniform part) [s], [N].
    time_out, force_out:
        Outgoing pulse (e.g. the wall force at the end of the tapered chain) [s], [N].
    nfft:
        Common FFT length; default the longer record, so that equal sampling rates give the same
        frequency grid.
    window:
        scipy window name (see :func:`power_spectrum`).
    normalize:
        "max": each spectrum divided by its maximum (the paper's arbitrary units; both start near
        1 at low frequency for a positive pulse); "area": divided by its integral, so the curves
        are distributions of power over frequency; "none": raw N^2/Hz.
    fmax:
        Upper frequency [Hz] of the centroids (default: Nyquist), to keep a noise floor out.
    """
    if normalize not in ("max", "area", "none"):
        raise ConfigError("normalize", f"must be 'max', 'area' or 'none', got {normalize!r}")
    if nfft is None:
        nfft = max(np.size(force_in), np.size(force_out))
    spectra = []
    for t, f in ((time_in, force_in), (time_out, force_out)):
        freq, power = power_spectrum(t, f, nfft=nfft, window=window)
        if normalize == "max":
            power = power / power.max()
        elif normalize == "area":
            power = power / np.trapezoid(power, freq)
        spectra.append((freq, power, spectral_centroid(freq, power, fmax=fmax)))
    (f_in, p_in, c_in), (f_out, p_out, c_out) = spectra
    return SpectraComparison(f_in, p_in, f_out, p_out, c_in, c_out)
