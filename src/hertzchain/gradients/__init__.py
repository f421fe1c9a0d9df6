"""Sensitivities: exact derivatives of a run's results with respect to its config fields.

:func:`sensitivity` differentiates one result (the peak wall force by default) with respect to any
number of continuous config fields (bead diameters, materials, striker, law constants, offsets,
precompression), by the discrete adjoint (or tangent) of the velocity-Verlet steps the engine
takes (:mod:`hertzchain.integrate.derivatives.tape`, ``adjoint``, ``tangent``) and the exact derivatives of the
set-up (:mod:`~hertzchain.gradients.setup`); :func:`trace_sensitivity` differentiates a whole
sampled signal (a fit's Jacobian). The results it knows: :data:`OBJECTIVES`.
"""

from __future__ import annotations

from .api import Sensitivity, TraceSensitivity, memory_estimate, sensitivity, trace_sensitivity, variable_unit
from .objectives import OBJECTIVES

__all__ = ["sensitivity", "Sensitivity", "trace_sensitivity", "TraceSensitivity", "OBJECTIVES", "variable_unit",
           "memory_estimate"]
