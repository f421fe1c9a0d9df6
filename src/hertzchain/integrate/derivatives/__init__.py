"""Derivatives of a run: the taped primal run, the tangent-linear and the adjoint models."""
