"""Bead sizes one can buy: named catalogues of precision (grade) ball diameters [mm].

A design variable restricted to a catalogue only takes the catalogue's sizes inside its
``[low, high]`` range. The series are the common stock sizes of bearing-steel grade balls
(ISO 3290-1 / ANSI-ABMA Std 10 nominal diameters): whole and half millimetres for the metric
series, fractions of an inch for the inch series (converted to mm, 1 in = 25.4 mm exactly).
"""

from __future__ import annotations

from fractions import Fraction

from ..errors import ConfigError

__all__ = ["CATALOGUES", "catalogue_sizes"]

_METRIC_MM = (1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0, 5.5, 6.0, 6.5, 7.0, 7.5, 8.0, 8.5, 9.0, 9.5, 10.0,
              11.0, 12.0, 13.0, 14.0, 15.0, 16.0, 17.0, 18.0, 19.0, 20.0, 21.0, 22.0, 23.0, 24.0, 25.0, 26.0,
              28.0, 30.0, 32.0, 35.0, 38.0, 40.0, 45.0, 50.0)
# Inch series in 1/32 in steps up to 1 in, then 1/8 in steps up to 2 in.
_INCH = ([Fraction(k, 32) for k in range(2, 33)] + [Fraction(1) + Fraction(k, 8) for k in range(1, 9)])

#: Named catalogues: sorted ball diameters [mm].
CATALOGUES: dict[str, tuple[float, ...]] = {
    "metric": _METRIC_MM,
    "inch": tuple(round(float(f) * 25.4, 4) for f in _INCH),
}


def catalogue_sizes(spec: str | list, low: float, high: float, field: str) -> tuple[float, ...]:
    """Catalogue sizes [mm] in ``[low, high]``, sorted.

    Parameters
    ----------
    spec : str or list of float
        A catalogue name (``"metric"``, ``"inch"``) or an explicit list of sizes [mm].
    low, high : float
        The variable's range [mm].
    field : str
        Field name used in error messages.

    Returns
    -------
    tuple of float
        The sizes [mm] one may choose from (at least one).
    """
    if isinstance(spec, str):
        if spec not in CATALOGUES:
            raise ConfigError(field, f"unknown catalogue {spec!r}; known: {', '.join(CATALOGUES)} (or a list of sizes in mm)")
        sizes = CATALOGUES[spec]
    else:
        try:
            sizes = tuple(sorted(float(x) for x in spec))
        except (TypeError, ValueError):
            raise ConfigError(field, f"must be a catalogue name or a list of sizes in mm, got {spec!r}") from None
        if not sizes or sizes[0] <= 0:
            raise ConfigError(field, "a list of sizes needs at least one positive size in mm")
    inside = tuple(s for s in sizes if low - 1e-9 <= s <= high + 1e-9)
    if not inside:
        raise ConfigError(field, f"holds no size between {low!r} and {high!r} mm")
    return inside
