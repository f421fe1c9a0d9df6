"""Laboratory data in: oscilloscope files, measured-vs-simulated comparison, model calibration.

- :mod:`.readers`: :func:`read_trace` reads a measured force record (delimited text in any
  of the usual spellings, Tektronix CSV and ``.isf``, PicoScope CSV/TXT, LeCroy ``.trc``, or a
  signal of a hertzchain result) into an :class:`xarray.DataArray` in SI units;
- :mod:`.compare`: :func:`compare_traces` aligns a measured and a simulated pulse and reports
  the differences of the paper's pulse parameters (Sec. III) and the residual;
- :mod:`.fit`: :func:`fit_traces` calibrates config fields (and the measurement's gain, time
  offset and baseline) by least squares on one or several traces, with the Jacobian of every
  iteration from one batched engine call.
"""

from __future__ import annotations

from .compare import Comparison, compare_traces
from .fit import FitResult, Trace, fit_traces
from .readers import SENSOR_PRESETS, read_trace

__all__ = ["read_trace", "SENSOR_PRESETS", "compare_traces", "Comparison", "fit_traces", "FitResult", "Trace"]
