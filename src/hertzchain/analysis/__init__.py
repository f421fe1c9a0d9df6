"""Analysis of force signals as in Melo et al., PRE 2006, Sec. III.

- :mod:`.pulse`: fit of the loading part of the first pulse with F_m cos^6[(t - T)/tau]
  (peak force, time of flight, duration) and the front/tail momenta;
- :mod:`.spectrum`: power spectra and the spectral centroid (Figs. 1h, 2h);
- :mod:`.timing`: local velocities, velocity-growth, time-of-flight and restitution fits,
  and the self-similar collapse of Fig. 4;
- :mod:`.io`: CSV records and batch analysis of simulation datasets.

All functions take plain numpy arrays in SI units (s, N, m).
"""

from __future__ import annotations

from .io import ROW_KEYS, analyze_signals, read_signal_csv
from .pulse import PulseFit, cos6_pulse, estimate_noise, fit_pulse, front_tail_momenta
from .spectrum import SpectraComparison, compare_spectra, power_spectrum, spectral_centroid
from .timing import (
    RestitutionFit,
    TimeOfFlightFit,
    VelocityGrowthFit,
    collapse,
    fit_restitution,
    fit_uniform_time_of_flight,
    fit_velocity_growth,
    local_velocity,
)

__all__ = [
    "PulseFit", "fit_pulse", "cos6_pulse", "estimate_noise", "front_tail_momenta",
    "power_spectrum", "spectral_centroid", "SpectraComparison", "compare_spectra",
    "local_velocity", "VelocityGrowthFit", "fit_velocity_growth", "TimeOfFlightFit",
    "fit_uniform_time_of_flight", "RestitutionFit", "fit_restitution", "collapse",
    "read_signal_csv", "analyze_signals", "ROW_KEYS",
]
