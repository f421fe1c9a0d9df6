"""Unit strings read from a scope's file, parsed by a strict grammar, never evaluated.

A unit is what an oscilloscope or its export writes beside a column or in a header field:
SI-prefixed base units (``s``, ``ms``, ``us``/``µs``, ``V``, ``mV``, ``N``, ``kN``, ``A``, ``Pa``,
``m``, ``g``, ``W``, ``Hz``, or their names: ``second``, ``millivolt`` ...) and simple products,
quotients and small integer powers of them (``mV/N``, ``N*m``, ``N m``, ``m/s^2``, ``s**-1``):

    unit  := term ( ("*" | "·" | "/" | blank) term )*
    term  := [prefix] base [ ("^" | "**") exponent ]
    exponent := a non-zero integer from -4 to 4

Numbers other than exponents (``10**10**10*s``, ``s/0``, ``1e-3 s``), a zero exponent (``s**0``),
parentheses and anything else are refused: a unit string from a received file is data, and
handing it to an expression evaluator (pint's parser did) gave ZeroDivisionError on ``s/0`` and
computed 10**(10**10) on ``10**10**10*s``.
"""

from __future__ import annotations

import re

__all__ = ["parse_unit", "UnitError", "MAX_UNIT_LENGTH", "MAX_EXPONENT"]

#: Longest unit string accepted [characters] (``mV/N`` is 4; a header's unit is short).
MAX_UNIT_LENGTH = 40
#: Largest |exponent| of a term (``m/s^2``; a scope writes no higher power).
MAX_EXPONENT = 4

#: SI prefixes and their factors (``u``, ``µ`` and ``μ`` are micro); ``da`` and ``h`` are not used
#: by scopes and would make ``h`` ambiguous.
_PREFIXES = {"Y": 1e24, "Z": 1e21, "E": 1e18, "P": 1e15, "T": 1e12, "G": 1e9, "M": 1e6, "k": 1e3,
             "c": 1e-2, "d": 1e-1, "m": 1e-3, "u": 1e-6, "µ": 1e-6, "μ": 1e-6, "n": 1e-9, "p": 1e-12,
             "f": 1e-15, "a": 1e-18, "z": 1e-21, "y": 1e-24}
_PREFIX_NAMES = {"yotta": 1e24, "zetta": 1e21, "exa": 1e18, "peta": 1e15, "tera": 1e12, "giga": 1e9,
                 "mega": 1e6, "kilo": 1e3, "centi": 1e-2, "deci": 1e-1, "milli": 1e-3, "micro": 1e-6,
                 "nano": 1e-9, "pico": 1e-12, "femto": 1e-15, "atto": 1e-18}
#: Base units: SI factor and dimension exponents (m, kg, s, A).
_BASES = {
    "s": (1.0, (0, 0, 1, 0)), "m": (1.0, (1, 0, 0, 0)), "g": (1e-3, (0, 1, 0, 0)), "A": (1.0, (0, 0, 0, 1)),
    "N": (1.0, (1, 1, -2, 0)), "Pa": (1.0, (-1, 1, -2, 0)), "V": (1.0, (2, 1, -3, -1)),
    "W": (1.0, (2, 1, -3, 0)), "Hz": (1.0, (0, 0, -1, 0)),
}
_BASE_NAMES = {"second": "s", "seconds": "s", "sec": "s", "secs": "s", "metre": "m", "meter": "m",
               "metres": "m", "meters": "m", "gram": "g", "grams": "g", "ampere": "A", "amperes": "A",
               "amp": "A", "amps": "A", "newton": "N", "newtons": "N", "pascal": "Pa", "pascals": "Pa",
               "volt": "V", "volts": "V", "watt": "W", "watts": "W", "hertz": "Hz"}
#: Whole strings some scopes write for a plain unit (LeCroy's ``S``, Tektronix's ``Volts``).
_ALIASES = {"S": "s", "Volts": "V", "Volt": "V"}

_TOKEN = re.compile(r"\s*(?:(?P<pow>\*\*|\^)|(?P<op>[*/·⋅])|(?P<name>[A-Za-zµμ]+)|(?P<int>[+-]?\d+)|(?P<bad>\S))")

#: Dimensions of the kinds a record's column can hold.
KINDS: dict[tuple[int, ...], str] = {(0, 0, 1, 0): "time", (1, 1, -2, 0): "force", (2, 1, -3, -1): "voltage"}


class UnitError(ValueError):
    """A unit string outside the grammar (the message says which part)."""


def _atom(name: str) -> tuple[float, tuple[int, ...]]:
    """Factor and dimensions of one prefixed unit name (``ms``, ``kN``, ``millivolt``)."""
    word = name.lower()
    if name in _BASES:  # an exact base first: ``m`` is the metre, ``Pa`` the pascal
        return _BASES[name]
    if word in _BASE_NAMES:
        return _BASES[_BASE_NAMES[word]]
    for prefix, factor in _PREFIX_NAMES.items():
        if word.startswith(prefix) and word[len(prefix):] in _BASE_NAMES:
            f, dims = _BASES[_BASE_NAMES[word[len(prefix):]]]
            return factor * f, dims
    if len(name) > 1 and name[0] in _PREFIXES and name[1:] in _BASES:
        f, dims = _BASES[name[1:]]
        return _PREFIXES[name[0]] * f, dims
    raise UnitError(f"{name!r} is not a unit (known: s, V, A, N, Pa, m, g, W, Hz with an SI prefix)")


def parse_unit(text: str) -> tuple[float, tuple[int, ...]]:
    """SI factor and dimensions of a unit string, by the module's grammar.

    Parameters
    ----------
    text : str
        The unit as the file wrote it (``"ms"``, ``"mV/N"``, ``"m/s^2"``).

    Returns
    -------
    tuple of (float, tuple of int)
        The factor to SI (``ms`` -> 1e-3) and the exponents of (m, kg, s, A).

    Raises
    ------
    UnitError
        The string is not a unit of the grammar (saying which part).
    """
    text = _ALIASES.get(text.strip(), text.strip())
    if not text:
        raise UnitError("empty unit")
    if len(text) > MAX_UNIT_LENGTH:
        raise UnitError(f"longer than {MAX_UNIT_LENGTH} characters")
    factor, dims = 1.0, [0, 0, 0, 0]
    pos, sign, expect_term = 0, 1, True
    pending: tuple[float, tuple[int, ...]] | None = None

    def close(term, power: int) -> None:
        nonlocal factor
        f, d = term
        factor *= f ** (sign * power)
        for i in range(4):
            dims[i] += sign * power * d[i]

    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if m is None:  # only trailing blanks are left
            break
        pos = m.end()
        kind = m.lastgroup
        if kind == "name":
            if not expect_term:  # "N m": a blank multiplies
                if pending is not None:
                    close(pending, 1)
                sign = 1
            pending, expect_term = _atom(m.group("name")), False
        elif kind == "pow":
            e = _TOKEN.match(text, pos)
            if pending is None or e is None or e.lastgroup != "int":
                raise UnitError(f"{m.group('pow')!r} must follow a unit and precede an integer exponent")
            power = int(e.group("int"))
            if power == 0 or abs(power) > MAX_EXPONENT:
                raise UnitError(f"exponent {power} is not allowed (non-zero, at most {MAX_EXPONENT} in size)")
            pos = e.end()
            close(pending, power)
            pending = None
        elif kind == "op":
            if expect_term:
                raise UnitError(f"{m.group('op')!r} must stand between two units")
            if pending is not None:
                close(pending, 1)
                pending = None
            sign, expect_term = (-1 if m.group("op") == "/" else 1), True
        else:
            what = m.group(kind or 0)
            raise UnitError(f"{what!r} is not allowed in a unit (no numbers, brackets or other operators)")
    if expect_term:
        raise UnitError("ends without a unit")
    if pending is not None:
        close(pending, 1)
    return factor, tuple(dims)
