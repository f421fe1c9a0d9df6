"""Overlaps from a law's functions by root finding (for laws that declare no closed-form inverse).

Both invert a function that increases with the overlap from 0 at d = 0: bracket by doubling from
1 nm, then Brent's method to a few ulp. Used by :class:`hertzchain.model.Model` for the stored
energy of precompressed contacts and the static overlap of a generated law under a force.
"""

from __future__ import annotations

import numpy as np


def _increasing_root(fn, target: float) -> float:
    """The d >= 0 [m] with ``fn(d) == target`` for ``fn`` increasing in d."""
    from scipy.optimize import brentq

    hi = 1e-9
    while fn(hi) < target and hi < 1.0:
        hi *= 2.0
    return float(brentq(lambda d: fn(d) - target, 0.0, hi, xtol=1e-300, rtol=4 * np.finfo(float).eps))


def overlap_at_energy(energy, e: float, k: float, p: float) -> float:
    """The overlap [m] at which a law's stored ``energy(d, k, p)`` is ``e`` [J]."""
    return _increasing_root(lambda d: energy(d, k, p), e)


def static_overlap(spec, force: float, k: float, p: float) -> float:
    """The overlap [m] at which a law's force at rest (rate 0, no state) is ``force`` [N]."""
    return _increasing_root(lambda d: spec.force(d, 0.0, k, p, 0.0), force)
