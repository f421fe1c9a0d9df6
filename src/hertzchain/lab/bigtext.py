"""A delimited-text record larger than :data:`hertzchain.lab.readers.TEXT_HEAD`, read with bounded memory.

Its layout (separator, decimal mark, header, first data row) comes from its first 64 KiB, as for a
small file (:func:`hertzchain.lab.readers._layout`). Before a number is parsed its rows are
counted from its size and the length of the first data lines, and a record of more rows than
:func:`~hertzchain.lab.formats.check_samples` allows is refused; a file whose last bytes hold NUL
bytes (a binary file, or a sparse one) too. The numbers are then parsed by :func:`pandas.read_csv`
straight from the file, as floats: the memory is that of the table returned (and of a trailing
empty column, when the lines end with a separator). A line pandas cannot read is then found by reading the file line by line, and named.
"""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError
from .formats import _Table, check_samples
from .textlayout import _cells, _layout, _number

__all__ = ["read_big_text"]

#: Bytes of the file's start whose lines give its layout (a scope's header is < 2 KiB; the rest
#: are the first data lines, which give the separator and the bytes a row).
LAYOUT_BYTES = 1 << 16
#: Bytes of the file's end checked for NUL bytes (a binary or sparse file) before anything is parsed.
TAIL_BYTES = 1 << 12
#: Bytes a Tektronix TDS CSV line may take (name, value, blank, time, value).
_TDS_LINE = 128
#: Bytes counted at a time when the data lines are numbered.
_CHUNK = 1 << 24


def read_big_text(path, fh, head: bytes, size: int) -> _Table | None:
    """The table of a large delimited text (see the module docstring).

    Parameters
    ----------
    path : pathlib.Path
        The file (for messages).
    fh : binary file
        The open file (a received regular file), positioned anywhere.
    head : bytes
        Its first bytes (:data:`~hertzchain.lab.readers.TEXT_HEAD` of them).
    size : int
        Its size [bytes].

    Returns
    -------
    _Table or None
        The columns, as :func:`hertzchain.lab.readers._read_text` gives them; None for a Tektronix
        TDS CSV whose Record Length (checked here, with the file's size) bounds it: the caller
        reads it whole.
    """
    where = str(path)
    fh.seek(max(0, size - TAIL_BYTES))
    if b"\x00" in fh.read(TAIL_BYTES) or b"\x00" in head:
        raise ConfigError(where, "is a binary file, not text (NUL bytes); hertzchain reads Tektronix .isf, LeCroy "
                          ".trc and delimited text (.csv, .txt)")
    cut = head.rfind(b"\n", 0, LAYOUT_BYTES) + 1
    if not cut:
        raise ConfigError(where, f"its first line is longer than {LAYOUT_BYTES} bytes: not a scope's text export")
    lay = _layout(where, head[:cut])
    if lay.tds:
        cells = lay.numbered[0][1].split(",")
        try:
            n = int(cells[1])
        except (IndexError, ValueError):
            raise ConfigError(where, f"Record Length is {cells[1:2]!r}, not a whole number") from None
        check_samples(n, "Record Length", where)
        if size > n * _TDS_LINE + len(head):
            raise ConfigError(where, f"holds {size} bytes, far more than its Record Length of {n} points can fill "
                              f"(at most {_TDS_LINE} bytes a line)")
        return None
    first_line = lay.numbered[lay.start][0]
    raw_lines = head[:cut].split(b"\n")
    offset = sum(len(ln) + 1 for ln in raw_lines[:first_line - 1])
    data_lines = cut - offset
    per_row = data_lines / max(1, len(raw_lines) - first_line)
    rows_est = int((size - offset) / per_row)
    check_samples(rows_est, f"its size ({size} bytes, rows of ~{per_row:.0f} bytes)", where)
    sep = lay.sep if lay.sep is not None else r"\s+"
    sample = [ln for _, ln in lay.numbered[lay.start:lay.start + 50]]
    ncols = max(len(ln.split(lay.sep)) if lay.sep else len(ln.split()) for ln in sample)
    import pandas as pd  # after the checks: a refused file costs no import

    fh.seek(offset)
    try:
        # every column (not usecols: pandas then lets a line of more fields pass), floats only
        frame = pd.read_csv(fh, sep=sep, decimal=lay.decimal, header=None, names=range(ncols), dtype=float,
                            skip_blank_lines=True, comment="#", skipinitialspace=True, encoding="utf-8")
        data = frame.iloc[:, :lay.width].to_numpy(dtype=float)
        del frame
        if np.isnan(data).any():
            raise ValueError("an empty cell")
    except (pd.errors.ParserError, ValueError, UnicodeDecodeError) as exc:
        _name_the_bad_line(where, fh, offset, first_line, lay)
        raise ConfigError(where, f"cannot read the numbers below line {first_line} ({exc})") from None
    lines = np.zeros(len(data), dtype=int)
    if _line_count(fh, offset) == len(data):  # no blank or comment line among the data: lines are known
        lines = first_line + np.arange(len(data))
    columns = lay.names if lay.names is not None else [str(j) for j in range(lay.width)]
    return _Table(columns, data, lay.units, lines, lay.meta, "text")


def _line_count(fh, offset: int) -> int:
    """Lines from byte ``offset`` to the end (a last line without its newline counted)."""
    fh.seek(offset)
    count, last = 0, b"\n"
    while chunk := fh.read(_CHUNK):
        count += chunk.count(b"\n")
        last = chunk[-1:]
    return count + (last != b"\n")


def _name_the_bad_line(where: str, fh, offset: int, first_line: int, lay) -> None:
    """Raise the small file's error for the first data line that is not ``width`` numbers (read
    one line at a time); return when every line is (the caller then says what pandas said)."""
    fh.seek(offset)
    for no, raw in enumerate(fh, start=first_line):
        text = raw.decode("utf-8", "replace")
        if not text.strip() or text.lstrip().startswith(("#", "%")):
            continue
        cells = _cells(text.rstrip("\r\n"), lay.sep)
        if len(cells) != lay.width:
            raise ConfigError(where, f"line {no} has {len(cells)} field(s) where the data above has {lay.width}: "
                              f"{' '.join(cells)[:60]!r}")
        for j, cell in enumerate(cells):
            if _number(cell.strip('"'), lay.decimal) is None:
                label = lay.names[j] if lay.names else f"{j}"
                what = "an empty cell" if cell == "" else f"{cell!r} is not a number"
                raise ConfigError(where, f"line {no}, column {label!r}: {what}")
