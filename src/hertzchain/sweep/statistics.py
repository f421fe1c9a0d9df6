"""Statistics of a sweep's or an ensemble's metrics: what ``hertzchain summary`` prints and what
the ensemble pictures (:mod:`hertzchain.viz.ensemble`) write on their panels.

:func:`read_metrics` reads ``metrics.csv`` (a sweep's output folder or the file itself, checked
as data: the columns :func:`~hertzchain.sweep.run_sweep` writes); :func:`summarize` gives, per
metric, the number of members with a value, the mean, the standard deviation (n - 1), the
extremes and the quantiles :data:`QUANTILES`, in SI units; :func:`display_unit` picks the unit
(with an SI prefix) in which a metric's values read best.
"""

from __future__ import annotations

import csv
import io
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ConfigError
from .storage import COLUMN_UNITS

__all__ = ["read_metrics", "metric_columns", "summarize", "display_unit", "past_elastic_limit", "QUANTILES"]

#: Quantiles reported for every metric (5 %, median, 95 %: the central 90 % of the members).
QUANTILES = (0.05, 0.5, 0.95)

#: Metrics that are not statistics of interest (the step is an input).
_SKIP = {"dt", "elastic_limit_exceeded", "fit_error"}

_PREFIXES = [(1e-9, "n"), (1e-6, "u"), (1e-3, "m"), (1.0, ""), (1e3, "k")]


def read_metrics(path: str | Path):
    """The metrics table of a sweep: ``DIR/metrics.csv`` of an output folder, or the file itself.

    Parameters
    ----------
    path : str or pathlib.Path
        The sweep's output folder or its ``metrics.csv``.

    Returns
    -------
    pandas.DataFrame
        One row per member.

    Raises
    ------
    ConfigError
        (naming the file) when it is missing, unreadable or not a sweep's metrics table.
    """
    import pandas as pd

    from ..received import open_received

    path = Path(path)
    folder = path if path.is_dir() else None
    if folder is not None:
        path = path / "metrics.csv"
    if not os.path.lexists(path):
        raise ConfigError(str(path), "no such file; give a sweep's output folder (it holds metrics.csv) or the "
                          "metrics.csv itself")
    try:
        # A regular file only (a FIFO would hang the read; a link out of the folder is refused).
        with open_received(path, folder) as fh:
            text = fh.read().decode("utf-8")
        lines = _row_lines(text)
        _check_widths(lines, str(path))
        df = pd.read_csv(io.StringIO(text), keep_default_na=False, na_values=list(_NA))
    except (OSError, ValueError, UnicodeDecodeError, csv.Error) as exc:
        raise ConfigError(str(path), f"cannot be read as a metrics table: {exc}") from None
    need = ["member", "chunk", "dt", "F_m"]
    missing = [c for c in need if c not in df.columns]
    if missing:
        raise ConfigError(str(path), f"is not a sweep's metrics.csv: no column {', '.join(missing)} (hertzchain "
                          "sweep writes member, chunk, the swept parameters, dt and the metrics)")
    _check_rows(df, lines, str(path))
    return df


#: The cells a metrics table may hold for a missing number.
_NA = ("", "nan", "NaN")


def _row_lines(text: str) -> list[tuple[int, int]]:
    """(line number in the file, number of fields) of the header, then of each data row (csv:
    quoted cells may hold separators and line breaks)."""
    reader = csv.reader(io.StringIO(text))
    out, start = [], 1
    for row in reader:
        out.append((start, len(row)))
        start = reader.line_num + 1
    return out


def _refuse(where: str, damaged: list[tuple[int, str]]) -> None:
    """Refuse a damaged table (ConfigError), naming its first damaged lines and what is wrong."""
    if damaged:
        damaged.sort()
        first = "; ".join(f"line {line}: {why}" for line, why in damaged[:3])
        more = f" (and {len(damaged) - 3} more)" if len(damaged) > 3 else ""
        raise ConfigError(where, f"is damaged: {first}{more}; the table is refused rather than summarised without "
                          "those members: rerun the sweep into its folder (hertzchain sweep FILE --out DIR), "
                          "which rewrites metrics.csv from its chunks")


def _check_widths(lines: list[tuple[int, int]], where: str) -> None:
    """Every data row has as many fields as the header (a ragged line is no member)."""
    if lines:
        width = lines[0][1]
        _refuse(where, [(line, f"{n} fields, the header has {width}") for line, n in lines[1:] if n != width])


def _check_rows(df, lines: list[tuple[int, int]], where: str) -> None:
    """Every row of a metrics table as a sweep writes it (its width checked by :func:`_check_widths`):
    a number (or an empty / NaN cell) in every numeric column, true or false in ``elastic_limit_exceeded``;
    else the table is refused (ConfigError), naming the first damaged lines, their column and
    cell: a summary that silently dropped a metric, or counted half a line as a member, would
    report numbers the sweep never produced."""
    import pandas as pd

    lines = lines[1:]  # the data rows
    damaged: list[tuple[int, str]] = []
    numeric = [c for c in df.columns if c in ("member", "chunk") or (c in COLUMN_UNITS and c not in
                                                                      ("fit_error", "elastic_limit_exceeded"))]
    for c in numeric:
        if df[c].dtype.kind in "fiu":
            continue
        cells = df[c].astype(str)
        bad = pd.to_numeric(df[c], errors="coerce").isna() & ~df[c].isna() & ~cells.isin(_NA)
        damaged += [(lines[i][0] if i < len(lines) else i + 2, f"column {c} holds {cells.iloc[i]!r}, not a number")
                    for i in np.flatnonzero(bad.to_numpy())[:5]]
    if "elastic_limit_exceeded" in df and df["elastic_limit_exceeded"].dtype.kind != "b":
        cells = df["elastic_limit_exceeded"].astype(str)
        bad = ~cells.isin(["True", "False", "true", "false", "0", "1"])
        damaged += [(lines[i][0] if i < len(lines) else i + 2, f"column elastic_limit_exceeded holds "
                     f"{cells.iloc[i]!r}, not true or false") for i in np.flatnonzero(bad.to_numpy())[:5]]
    _refuse(where, damaged)


def metric_columns(df) -> list[str]:
    """The numeric metric columns of a metrics table (after ``dt``), in table order."""
    cols = list(df.columns)
    start = cols.index("dt") + 1 if "dt" in cols else 0
    return [c for c in cols[start:] if c not in _SKIP and df[c].dtype.kind in "fiu"]


def past_elastic_limit(df) -> int:
    """Members whose contacts passed the elastic limit under a law that does not model yield.

    A member of the elastoplastic law (its ``plastic_work`` column has a value) passes the limit
    by design: its contacts yield, and the law models it, so it is not counted (the docs promise
    no warning for it).

    Parameters
    ----------
    df : pandas.DataFrame
        A metrics table.

    Returns
    -------
    int
        The count (0 when the table has no ``elastic_limit_exceeded`` column).
    """
    if "elastic_limit_exceeded" not in df:
        return 0
    over = np.array(df["elastic_limit_exceeded"].astype(bool), dtype=bool)
    if "plastic_work" in df:
        over &= ~np.isfinite(df["plastic_work"].to_numpy(dtype=float))
    return int(over.sum())


def summarize(df, metrics: list[str] | None = None) -> dict[str, Any]:
    """Per metric: members with a value, mean, standard deviation, extremes and quantiles (SI units).

    Parameters
    ----------
    df : pandas.DataFrame
        A metrics table (:func:`read_metrics`).
    metrics : list of str or None
        The columns to summarise (default: :func:`metric_columns`).

    Returns
    -------
    dict
        ``n_members``, ``fit_failures`` (members without a fitted wall pulse),
        ``elastic_limit_exceeded`` (members past the elastic limit under a law that does not
        model yield, :func:`past_elastic_limit`) and ``metrics``:
        ``{name: {units, n, mean, std, min, max, quantiles: {"0.05": ..., "0.5": ..., "0.95": ...}}}``
        (NaN-free members only; ``std`` with n - 1, NaN for fewer than two).

    Raises
    ------
    ConfigError
        (``--signal``) naming a metric the table does not have.
    """
    available = metric_columns(df)
    metrics = available if metrics is None else list(metrics)
    for m in metrics:
        if m not in available:
            raise ConfigError("--signal", f"unknown metric {m!r}; this table has {', '.join(available)}")
    out: dict[str, Any] = {"n_members": int(len(df))}
    if "fit_error" in df:
        errors = df["fit_error"]  # read back, an empty cell is NaN (and an all-empty column float)
        out["fit_failures"] = int((errors.notna() & (errors.astype(str) != "")).sum())
    if "elastic_limit_exceeded" in df:
        out["elastic_limit_exceeded"] = past_elastic_limit(df)
    stats = {}
    for m in metrics:
        x = df[m].to_numpy(dtype=float)
        x = x[np.isfinite(x)]
        entry: dict[str, Any] = {"units": COLUMN_UNITS.get(m, ""), "n": int(x.size)}
        if x.size:
            q = np.quantile(x, QUANTILES)
            entry.update(mean=float(x.mean()), std=float(x.std(ddof=1)) if x.size > 1 else math.nan,
                         min=float(x.min()), max=float(x.max()),
                         quantiles={f"{p:g}": float(v) for p, v in zip(QUANTILES, q)})
        else:
            entry.update(mean=math.nan, std=math.nan, min=math.nan, max=math.nan,
                         quantiles={f"{p:g}": math.nan for p in QUANTILES})
        stats[m] = entry
    out["metrics"] = stats
    return out


def display_unit(unit: str, values) -> tuple[str, float]:
    """The unit with an SI prefix in which ``values`` read best, and the factor to multiply them by.

    Parameters
    ----------
    unit : str
        The SI unit (``N``, ``s``, ``N s``, ``J``; ``1`` or empty for numbers without one).
    values : array_like
        Values in ``unit``.

    Returns
    -------
    (str, float)
        E.g. ``("ms", 1e3)`` for times of a few milliseconds; ``(unit, 1.0)`` when no prefix helps.
    """
    if unit in ("", "1"):
        return unit, 1.0
    x = np.asarray(values, dtype=float)
    x = np.abs(x[np.isfinite(x) & (x != 0)])
    if not x.size:
        return unit, 1.0
    typical = float(np.median(x))
    factor, prefix = max((p for p in _PREFIXES if p[0] <= typical), default=_PREFIXES[0])
    return prefix + unit, 1.0 / factor
