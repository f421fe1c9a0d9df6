"""Is the pulse of a record clipped (a saturated sensor or scope)?

A scope that is overdriven writes its largest code for every sample above its range, and an
overloaded amplifier holds its largest output: the top of the pulse is cut flat. The paper's
fit (Sec. III) of such a record still converges, with small error bars, on a pulse as high as
the cut (a 35 N pulse clipped at 3.5 N gives F_m = 3.66 N), so a clipped record must be refused.

:func:`find_clipping` tells, from the samples alone,

1. a record whose pulse reaches the scope's full scale (``valid_max``: the largest code of the
   file's sample format, or the instrument model's range), and
2. a flat top at the record's maximum: more samples exactly equal to the maximum than a smooth
   peak can give. Around its maximum a pulse is a parabola (cos^6 ~ 1 - 3 u^2, u = (t - T) /
   tau), so quantised with a step q it stays on its top code for at most
   2 sqrt(q / (3 h)) tau of its height h, that is 2 sqrt(q / (3 h)) / 0.943 of its width at
   half height; noise only makes that top code rarer. The record is clipped when the samples
   on its maximum exceed 1.5 times that (and two more): a cut at 90 % of the true peak is found
   on a record of 50 samples per tau, a cut at half the peak on one of 10; no unclipped record
   of 4000 drawn (3-300 samples per tau, 10-4000 codes per pulse, noise 0-10 codes) was taken for
   a clipped one.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["find_clipping"]

#: Width at half height of cos^6 in units of tau: 2 arccos(2^(-1/6)).
_HALF_WIDTH_TAU = 0.943


def find_clipping(time: np.ndarray, force: np.ndarray, *, valid_max: float | None = None) -> str | None:
    """Why the pulse of a record is clipped, or None when it is not.

    Parameters
    ----------
    time : numpy.ndarray
        Sample times [s].
    force : numpy.ndarray
        The record [N] (any offset; the pulse is positive).
    valid_max : float, optional
        The largest value the scope can record [N] (its full scale, the largest code of the
        file's sample format); None when the file does not say.

    Returns
    -------
    str or None
        A sentence naming the samples at the limit or on the flat top, and their value [N].
    """
    t = np.asarray(time, float)
    y = np.asarray(force, float)
    if y.size < 5 or not np.all(np.isfinite(y)):
        return None
    i = int(np.argmax(y))
    top = float(y[i])
    base = float(np.percentile(y, 10))
    if not top > base:
        return None
    if valid_max is not None and math.isfinite(valid_max):
        at_limit = int(np.count_nonzero(y >= valid_max - 1e-9 * max(abs(valid_max), top - base)))
        if at_limit:
            return (f"{at_limit} sample(s) at the scope's full scale ({valid_max:.4g} N, from t = "
                    f"{t[int(np.argmax(y >= valid_max - 1e-9 * max(abs(valid_max), top - base)))]:.6g} s): the "
                    "pulse went beyond the vertical range; record again with a wider range")
    # The pulse's part above half its height, around its maximum.
    half = base + 0.5 * (top - base)
    above = y > half
    a = i - int(np.argmin(above[i::-1])) + 1 if not above[: i + 1].all() else 0
    b = i + int(np.argmin(above[i:])) - 1 if not above[i:].all() else y.size - 1
    on_top = int(np.count_nonzero(y[a:b + 1] == top))
    if on_top < 3:  # a smooth record (a simulation) has one sample on its maximum: no sort needed
        return None
    values = np.unique(y)
    q = float(np.min(np.diff(values))) if values.size > 1 else 0.0
    expected = 2.0 + 1.5 * (b - a + 1) / _HALF_WIDTH_TAU * 2.0 * math.sqrt(q / (3.0 * (top - base)))
    if on_top > expected + 1.0:
        first = a + int(np.argmax(y[a:b + 1] == top))
        return (f"its top is cut flat: {on_top} samples equal its maximum {top:.4g} N (from t = {t[first]:.6g} s), "
                f"where a smooth peak gives at most {expected:.0f}; the sensor or the scope saturated, so the "
                "pulse's height and width would be wrong; record again with a wider vertical range")
    return None
