"""Short text and HTML summaries of the package's objects: ``repr(chain)`` on one line, a small
table in Jupyter (``_repr_html_``).

A chain of 30 beads printed its 30 diameters as a NumPy array and each bead's full material,
5,000 characters; the summaries here say what a reader checks first (how many beads, which
diameters, which material) in one line. Pure formatting: nothing of the package is imported.
"""

from __future__ import annotations

import html
from typing import Iterable, Sequence

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["diameters_text", "counts_text", "html_table", "value_text"]


def _mm(x: float) -> str:
    return f"{x * 1e3:.4g}"


def diameters_text(diameters: ArrayLike, most: int = 16) -> str:
    """Bead diameters [m] as 'N beads: 26 mm x 16, 24, 23, ..., 11 mm', runs of equal beads grouped.

    Parameters
    ----------
    diameters : sequence of float
        phi_1..phi_N [m].
    most : int
        Most groups written; the middle ones are elided (``...``) beyond.

    Returns
    -------
    str
        The summary.
    """
    d = np.asarray(diameters, dtype=float)
    groups: list[tuple[float, int]] = []
    for x in d:
        if groups and groups[-1][0] == x:
            groups[-1] = (x, groups[-1][1] + 1)
        else:
            groups.append((float(x), 1))
    parts = [_mm(x) + (f" x {n}" if n > 1 else "") for x, n in groups]
    if len(parts) > most:
        parts = parts[: most - 3] + ["..."] + parts[-2:]
    return f"{d.size} bead{'s' if d.size != 1 else ''}: {', '.join(parts)} mm"


def counts_text(names: Iterable[str]) -> str:
    """'AISI52100' for one name throughout, else 'AISI52100 x 28, brass x 2' in order of first use.

    Parameters
    ----------
    names : iterable of str
        One name per item.

    Returns
    -------
    str
        The summary.
    """
    counts: dict[str, int] = {}
    for name in names:
        counts[name] = counts.get(name, 0) + 1
    if len(counts) == 1:
        return next(iter(counts))
    return ", ".join(f"{k} x {n}" for k, n in counts.items())


def value_text(value: float, error: float | None, unit: str, scale: float = 1.0) -> str:
    """'2.612 ± 0.003 N' (the value in ``unit`` after multiplying by ``scale``).

    Parameters
    ----------
    value, error : float
        The number and its standard error (None: none), SI.
    unit : str
        Display unit.
    scale : float
        Factor from SI to the display unit (1e3 for ms, 1e6 for µs).

    Returns
    -------
    str
        The formatted value.
    """
    text = f"{value * scale:.4g}"
    if error is not None and np.isfinite(error):
        text += f" ± {error * scale:.2g}"
    return f"{text} {unit}"


def html_table(title: str, rows: Sequence[tuple[str, str]]) -> str:
    """A two-column HTML table with a caption: what ``_repr_html_`` shows in Jupyter.

    Parameters
    ----------
    title : str
        Caption (the object's class).
    rows : sequence of (str, str)
        (what, value) lines, plain text (escaped here).

    Returns
    -------
    str
        The HTML.
    """
    body = "".join(f"<tr><th style='text-align:left'>{html.escape(k)}</th><td style='text-align:left'>"
                   f"{html.escape(v)}</td></tr>" for k, v in rows)
    return f"<table><caption style='text-align:left'><b>{html.escape(title)}</b></caption>{body}</table>"
