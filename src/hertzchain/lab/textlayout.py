"""The layout of a delimited text record: separator, decimal mark, header, units and data block.

Shared by the whole-file reader (:mod:`hertzchain.lab.readers`) and the large-file one
(:mod:`hertzchain.lab.bigtext`), which reads it from a file's first bytes only.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

from ..errors import ConfigError

__all__: list[str] = []

_INF = {"∞": math.inf, "+∞": math.inf, "-∞": -math.inf, "inf": math.inf, "-inf": -math.inf}


def _cells(line: str, sep: str | None) -> list[str]:
    cells = line.split() if sep is None else [c.strip().strip('"').strip() for c in line.split(sep)]
    while cells and cells[-1] == "":
        cells.pop()  # Tektronix and PicoScope end lines with a separator
    return cells


def _number(cell: str, decimal: str) -> float | None:
    cell = cell.strip()
    if cell in _INF:
        return _INF[cell]
    if decimal == ",":
        cell = cell.replace(",", ".")
    try:
        return float(cell)
    except ValueError:
        return None


def _numeric_row(cells: list[str], decimal: str) -> bool:
    return bool(cells) and all(_number(c, decimal) is not None for c in cells if c != "")


def _sniff(lines: list[str]) -> tuple[str | None, str]:
    """Separator and decimal mark of the data lines (the last lines of the file)."""
    from collections import Counter

    sample = [ln for ln in lines[-50:] if ln.strip()]
    for sep in (";", "\t", ","):
        # The separator splits nearly every data line the same way (a ragged line is then
        # reported by its number, not taken for another layout).
        count, n = Counter(ln.count(sep) for ln in sample).most_common(1)[0]
        if count >= 1 and n >= 0.9 * len(sample):
            break
    else:
        sep = None
    # A decimal comma: ';' / tab / blank separated numbers with commas between digits.
    decimal = "," if sep != "," and any(re.search(r"\d,\d", ln) for ln in sample) else "."
    return sep, decimal


@dataclass
class _Layout:
    """Where a delimited text's numbers are: its non-comment lines (file line number, text), the
    separator and decimal mark, the index of the first data row among those lines, the number of
    columns, and the names, units and metadata of the header above."""

    numbered: list[tuple[int, str]]
    sep: str | None = None
    decimal: str = "."
    start: int = 0
    width: int = 0
    names: list[str] | None = None
    units: list[str | None] = field(default_factory=list)
    meta: dict = field(default_factory=dict)
    tds: bool = False
    rows: list = field(default_factory=list)     # (file line, cells) of ``numbered``


def _layout(where: str, raw: bytes) -> _Layout:
    """The layout of a delimited text (all of a small file, or a large file's first lines)."""
    if b"\x00" in raw:
        raise ConfigError(where, "is a binary file, not text; hertzchain reads Tektronix .isf, LeCroy .trc "
                          "and delimited text (.csv, .txt)")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        # One rule for every text file hertzchain reads (configs, CSV): UTF-8, no guessing.
        raise ConfigError(where, f"is not UTF-8 text (byte {exc.start} cannot be decoded); save the file "
                          "as UTF-8 (plain ASCII numbers are fine)") from None
    lines = text.splitlines()
    sep_forced = None
    if lines and lines[0].strip().lower().startswith("sep="):
        sep_forced = lines[0].strip()[4:5] or ","
        lines[0] = ""
    numbered = [(i + 1, ln) for i, ln in enumerate(lines)
                if ln.strip() and not ln.lstrip().startswith(("#", "%"))]
    if not numbered:
        raise ConfigError(where, "holds no data (the file is empty or only comments)")
    first = numbered[0][1].split(",")[0].strip().strip('"')
    if first == "Record Length":
        return _Layout(numbered, tds=True)
    sep, decimal = _sniff([ln for _, ln in numbered])
    if sep_forced is not None:
        sep = sep_forced
        decimal = "," if sep != "," and decimal == "," else "."
    # The data block: the first run of three numeric rows of one width; the header above it.
    rows = [(no, _cells(ln, sep)) for no, ln in numbered]
    start = None
    for k in range(len(rows)):
        window = rows[k:k + 3]
        if all(_numeric_row(c, decimal) for _, c in window) and len({len(c) for _, c in window}) == 1:
            start = k
            break
    if start is None:
        bad_no, bad = next(((no, c) for no, c in rows[1:] if not _numeric_row(c, decimal)), rows[0])
        raise ConfigError(where, f"no block of numbers found (line {bad_no}: {' '.join(bad)[:60]!r} is not "
                          "numbers); expected a time column and a signal column")
    width = len(rows[start][1])
    head = rows[:start]
    units: list[str | None] = [None] * width
    names: list[str] | None = None
    unit_cell = re.compile(r"^\s*[\[(].*[\])]\s*$|^$")
    if head and len(head[-1][1]) >= width - 1 and all(unit_cell.match(c) for c in head[-1][1]) \
            and any(c for c in head[-1][1]):
        units = [c.strip("()[] ") or None for c in head[-1][1]] + [None] * (width - len(head[-1][1]))
        head = head[:-1]
    if head and len(head[-1][1]) == width:
        names = head[-1][1]
        head = head[:-1]
    meta = {c[0]: c[1] for _, c in head if len(c) >= 2}
    return _Layout(numbered, sep, decimal, start, width, names, units, meta, rows=rows)
