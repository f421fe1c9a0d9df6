"""Pictures of a sweep's ``metrics.csv``: a wall-pulse metric against one or two swept parameters.

``metrics.csv`` (written by :func:`hertzchain.run_sweep`) has one row per member: ``member``,
``chunk``, one column per swept parameter (named by its dotted path), then ``dt`` and the
metrics (``peak_wall_force``, ``F_m``, ``T``, ``tau``, ``Q_F``, ``Q_T``, SI units). Against one
parameter the metric is drawn as a line (one line per combination of the other parameters);
against two as a colour map, one cell per pair of swept values (mean over the other parameters),
or for random draws one coloured point per member.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # Matplotlib loads when a figure is drawn
    from matplotlib.collections import PathCollection, QuadMesh

__all__ = ["plot_metrics", "metrics_figure", "swept_parameters", "MAX_TICK_LABELS"]

#: Most labelled cells along each axis of a sweep map; beyond, every k-th cell is labelled
#: (40 swept values labelled one by one overlapped into a black bar).
MAX_TICK_LABELS = {"x": 10, "y": 15}


def _cell_ticks(n: int, most: int):
    """Centres of the cells to label among n: every k-th, k the smallest that keeps at most ``most``."""
    import math

    import numpy as np

    step = max(1, math.ceil(n / most))
    return np.arange(0, n, step)


_UNITS = {"peak_wall_force": "N", "F_m": "N", "T": "s", "tau": "s", "Q_F": "N s", "Q_T": "N s", "dt": "s",
          "peak_wall_time": "s"}


def swept_parameters(df) -> list[str]:
    """The swept parameter columns of a metrics table (between ``chunk`` and ``dt``)."""
    cols = list(df.columns)
    if "chunk" not in cols or "dt" not in cols:
        return []
    return cols[cols.index("chunk") + 1:cols.index("dt")]


def metrics_figure(path: str | Path, metric: str = "F_m", x: str | None = None, y: str | None = None):
    """The figure of :func:`plot_metrics`, not written.

    Parameters
    ----------
    path : str or Path
        The sweep's ``metrics.csv``.
    metric, x, y : str or None
        As for :func:`plot_metrics`.

    Returns
    -------
    matplotlib.figure.Figure
        One axes (and its colour bar for a map); a map labels at most ``MAX_TICK_LABELS`` cells
        per axis.
    """
    import numpy as np

    from ..errors import ConfigError
    from ..sweep.statistics import read_metrics

    path = Path(path)
    df = read_metrics(path)  # checked row by row: a damaged line is named, never plotted
    params = swept_parameters(df)
    if not params:
        raise ConfigError(str(path), "is not a sweep's metrics.csv (needs the columns member, chunk, "
                          "<swept parameters>, dt, ...)")
    metrics = [c for c in df.columns[df.columns.get_loc("dt"):] if df[c].dtype.kind == "f"]
    if metric not in df.columns or metric in params:
        raise ConfigError("--signal", f"unknown metric {metric!r}; this table has {', '.join(metrics)}")
    x = x or params[0]
    if y is None and len(params) == 2:
        y = params[1] if params[1] != x else params[0]
    for name, value in (("x", x), ("y", y)):
        if value is not None and value not in params:
            raise ConfigError(name, f"{value!r} is not a swept parameter; swept: {', '.join(params)}")
    if y == x:
        raise ConfigError("y", "must differ from x")
    for p in (x, y):
        if p is not None and df[p].dtype.kind not in "fiu":
            raise ConfigError(p, "is not a numeric parameter; plot numeric parameters only")

    from .style import agg_figure

    unit = _UNITS.get(metric, "")
    label = f"{metric} [{unit}]" if unit else metric
    fig = agg_figure(6.5, 4.2, layout=None)  # cropped to its content by bbox_inches="tight" below
    ax = fig.subplots()
    if y is None:
        others = [p for p in params if p != x]
        groups = df.groupby(others, sort=True) if others else [((), df)]
        for key, g in groups:
            g = g.sort_values(x)
            key = key if isinstance(key, tuple) else (key,)
            ax.plot(g[x], g[metric], "o-", ms=3, label=", ".join(f"{p} = {v}" for p, v in zip(others, key)) or None)
        ax.set_xlabel(x)
        ax.set_ylabel(label)
        if others:
            ax.legend(fontsize=7)
    else:
        table = df.pivot_table(index=y, columns=x, values=metric, aggfunc="mean")
        if table.size <= 4 * len(df):
            # A grid: one cell per pair of values, labelled with them (swept values are rarely evenly spaced).
            mesh: QuadMesh | PathCollection = ax.pcolormesh(
                np.arange(table.shape[1] + 1), np.arange(table.shape[0] + 1), np.ma.masked_invalid(table.values))
            cols = _cell_ticks(table.shape[1], MAX_TICK_LABELS["x"])
            rows = _cell_ticks(table.shape[0], MAX_TICK_LABELS["y"])
            ax.set_xticks(cols + 0.5, [f"{v:.4g}" for v in table.columns.values[cols]],
                          rotation=45 if cols.size > 6 else 0, ha="right" if cols.size > 6 else "center")
            ax.set_yticks(rows + 0.5, [f"{v:.4g}" for v in table.index.values[rows]])
        else:  # random draws: one coloured point per member
            mesh = ax.scatter(df[x], df[y], c=df[metric], s=18)
        fig.colorbar(mesh, ax=ax, label=label)
        ax.set_xlabel(x)
        ax.set_ylabel(y)
    ax.set_title(f"{metric} of {path.name}")
    return fig


def plot_metrics(path: str | Path, out: str | Path, metric: str = "F_m", x: str | None = None,
                 y: str | None = None) -> Path:
    """Draw ``metric`` of a sweep's ``metrics.csv`` against one or two swept parameters.

    Parameters
    ----------
    path : str or Path
        The sweep's ``metrics.csv``.
    out : str or Path
        Image file (PNG, PDF or SVG), written atomically.
    metric : str
        Column to draw: ``F_m`` [N] (default), ``peak_wall_force`` [N], ``T`` [s], ``tau`` [s],
        ``Q_F`` [N s], ``Q_T`` [N s].
    x : str or None
        Swept parameter on the horizontal axis (default: the first one).
    y : str or None
        Second swept parameter (a colour map); default: the second one when exactly two were
        swept, else none (lines, one per combination of the others).

    Returns
    -------
    Path
        The image written.

    Raises
    ------
    ConfigError
        Unknown metric or parameter, or a table that is not a sweep's metrics.csv.
    """
    from ..fileio import atomic_path
    from .common import image_format

    out = Path(out)
    fmt = image_format(out)
    fig = metrics_figure(path, metric, x, y)
    with atomic_path(out) as tmp:
        fig.savefig(tmp, format=fmt, dpi=120, bbox_inches="tight")
    return out
