"""Strict types at the Python API's door: the rules a config file already follows.

A number is an ``int``, a ``float`` or a NumPy integer or floating scalar (``np.float32`` is a
number) and never a ``bool`` or a string (``True`` and ``"0.3"`` are refused, not read as 1 and
0.3); a count is an integer, never a float (``2.7`` beads is refused, not truncated to 2, and
``12.0`` is refused as in a config). Values come back as plain Python ``float`` / ``int``, so that
NumPy scalars travel into results and JSON like any number. The errors are the config's
:class:`~hertzchain.errors.ConfigError` naming the field as a config spells it.

The bounds are the config schema's (:data:`hertzchain.config.schema.BOUNDS`): a keyword of
:func:`hertzchain.simulate` or :func:`hertzchain.simulate_batch` is held to what the same field
of a config file may be (:func:`bounded`, :func:`run_options`), so that the Python API neither
crashes on ``steps_per_radian=0`` nor starts a run of ``dt=nan`` or ``threads=10**6``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .errors import ConfigError

__all__ = ["real", "count", "real_array", "bounded", "run_options"]


def _kind(value: Any) -> str:
    return f"{value!r} ({type(value).__name__})"


def real(value: Any, field: str, *, low: float | None = None, open_low: bool = False, unit: str = "") -> float:
    """``value`` as a finite float, or a ConfigError naming ``field``.

    Parameters
    ----------
    value : Any
        What the caller gave.
    field : str
        The field's name (``striker.velocity``).
    low : float, optional
        Smallest value allowed (``open_low``: excluded).
    open_low : bool
        ``low`` itself is not allowed.
    unit : str
        Unit for the message (``m/s``).

    Returns
    -------
    float
        The value.
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ConfigError(field, f"must be a number{f' in {unit}' if unit else ''}, got {_kind(value)}")
    x = float(value)
    if not math.isfinite(x):
        raise ConfigError(field, f"must be a finite number{f' in {unit}' if unit else ''}, got {value!r}")
    if low is not None and (x < low or (open_low and x == low)):
        bound = f"> {low:g}" if open_low else f">= {low:g}"
        raise ConfigError(field, f"must be {bound}{f' {unit}' if unit else ''}, got {value!r}")
    return x


def count(value: Any, field: str, *, low: int = 1) -> int:
    """``value`` as an int >= ``low``, or a ConfigError naming ``field`` (a float is not a count).

    Parameters
    ----------
    value : Any
        What the caller gave.
    field : str
        The field's name (``chain.n``).
    low : int
        Smallest value allowed.

    Returns
    -------
    int
        The value.
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise ConfigError(field, f"must be a whole number (an int), got {_kind(value)}")
    if value < low:
        raise ConfigError(field, f"must be at least {low}, got {value!r}")
    return int(value)


def real_array(values: Any, field: str) -> np.ndarray:
    """``values`` as a float array, refusing booleans, strings and objects (``np.asarray(['0.02'],
    float)`` would read the string).

    Parameters
    ----------
    values : Any
        A sequence or array of numbers.
    field : str
        The field's name (``chain.diameters``).

    Returns
    -------
    numpy.ndarray
        A new float64 array.
    """
    if isinstance(values, np.ndarray) and values.dtype.kind in "iuf":
        return np.array(values, dtype=float)
    try:
        items = np.ravel(np.asarray(values, dtype=object))  # the caller's own objects, unconverted
    except (TypeError, ValueError):
        raise ConfigError(field, f"must be a sequence of numbers, got {type(values).__name__}") from None
    for v in items:
        if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.integer, np.floating)):
            raise ConfigError(field, f"must hold numbers only, got {_kind(v)}")
    return np.array(items.tolist() if items.size else [], dtype=float).reshape(np.shape(values))


def bounded(value: Any, field: str, kind: str, *, unit: str = "", whole: bool = False) -> float | int:
    """``value`` within the config schema's bounds ``BOUNDS[kind]``, or a ConfigError naming ``field``.

    Parameters
    ----------
    value : Any
        What the caller gave.
    field : str
        The field's name as a config spells it (``run.steps_per_radian``).
    kind : str
        The key of :data:`hertzchain.config.schema.BOUNDS` (``steps_per_radian``).
    unit : str
        Unit for the message (``s``).
    whole : bool
        A count (:func:`count`) rather than a real number (:func:`real`).

    Returns
    -------
    float or int
        The value.
    """
    from .bounds import BOUNDS  # the schema's own table (config.schema re-exports it), below this module

    lo, hi = BOUNDS[kind]
    x = count(value, field, low=int(lo)) if whole else real(value, field, low=lo, unit=unit)
    if x > hi:
        raise ConfigError(field, f"must be <= {hi:g}{f' {unit}' if unit else ''}, got {value!r}")
    return x


def run_options(*, dt: Any = None, rtol: Any = None, steps_per_radian: Any = None, threads: Any = None,
                threads_field: str = "run.threads", threads_max: int | None = None) -> tuple:
    """The run keywords of the Python API checked as the config's ``[run]`` fields (None: absent).

    Parameters
    ----------
    dt : float, sequence of float or None, or None
        Fixed time step [s] (a sequence: one per batch member, None for an adaptive member).
    rtol : float or None
        Relative tolerance of the rkn4 / SciPy integrators.
    steps_per_radian : float or None
        Accuracy of the adaptive Verlet step.
    threads : int or None
        Threads of one run (``run.threads``) or of a batch (``n_threads``).
    threads_field : str
        How the caller names ``threads`` (for the message).
    threads_max : int or None
        The most threads allowed (None: ``run.threads``'s bound).

    Returns
    -------
    tuple
        ``(dt, rtol, steps_per_radian, threads)``, checked.
    """
    if isinstance(dt, (list, tuple, np.ndarray)):
        dt = [None if d is None else bounded(d, f"run.dt[{i}]", "dt", unit="s") for i, d in enumerate(dt)]
    elif dt is not None:
        dt = bounded(dt, "run.dt", "dt", unit="s")
    rtol = None if rtol is None else bounded(rtol, "run.rtol", "rtol")
    if steps_per_radian is not None:
        steps_per_radian = bounded(steps_per_radian, "run.steps_per_radian", "steps_per_radian")
    if threads is not None:
        threads = bounded(threads, threads_field, "threads", whole=True) if threads_max is None else \
            count(threads, threads_field)
        if threads_max is not None and threads > threads_max:
            raise ConfigError(threads_field, f"must be <= {threads_max}, got {threads!r}")
    return dt, rtol, steps_per_radian, threads
