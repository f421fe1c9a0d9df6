"""Pictures of an ensemble's metrics: histograms and a corner plot, with their statistics written on.

An ensemble (a tolerance Monte Carlo, or any sweep) leaves one row per member in ``metrics.csv``.
:func:`histogram_figure` draws one histogram per metric, with the mean (solid line), the 5 % and
95 % quantiles (dashed) and the median (dotted), and the mean, standard deviation and quantiles
written in the panel; :func:`corner_figure` draws every pair of metrics as a 2-D histogram
(lower triangle) with their correlation coefficient (upper triangle) and each metric's histogram
on the diagonal. Both bin the values (no marker per member), so a million members draw as fast as
a hundred. :func:`plot_ensemble` writes either to a file. The statistics are those of
:func:`hertzchain.sweep.statistics.summarize`, in the units :func:`~hertzchain.sweep.statistics.display_unit`
chooses.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["plot_ensemble", "histogram_figure", "corner_figure", "DEFAULT_CORNER"]

#: Metrics of the corner plot when none are named: the wall pulse of the paper (Sec. III).
DEFAULT_CORNER = ("peak_wall_force", "T", "tau", "Q_F", "Q_T")
#: The histograms' default metric: the wall force's peak refined between the engine's steps,
#: free of the sampling comb that the cos^6 fit's F_m shows on coarse samples (issue 36); F_m
#: when a table has no such column.
DEFAULT_HISTOGRAM = "peak_wall_force"


def _values(df, metric: str) -> np.ndarray:
    x = df[metric].to_numpy(dtype=float)
    return x[np.isfinite(x)]


def _label(metric: str, unit: str) -> str:
    return f"{metric} [{unit}]" if unit and unit != "1" else metric


def _fmt(v: float) -> str:
    return f"{v:.4g}"


def _histogram(ax, df, metric: str, stats: dict, bins: int, annotate: bool = True) -> None:
    from ..sweep.statistics import display_unit
    from .style import C1, CK

    x = _values(df, metric)
    unit, k = display_unit(stats["units"], x)
    ax.hist(x * k, bins=bins, color=C1, alpha=0.75)
    if not x.size:
        ax.text(0.5, 0.5, "no values", transform=ax.transAxes, ha="center")
        return
    q = stats["quantiles"]
    ax.axvline(stats["mean"] * k, color=CK, lw=1.2)
    for p, style in (("0.05", "--"), ("0.5", ":"), ("0.95", "--")):
        ax.axvline(q[p] * k, color=CK, lw=0.9, ls=style)
    ax.set_xlabel(_label(metric, unit))
    if annotate:
        u = "" if unit in ("", "1") else f" {unit}"
        text = (f"n = {stats['n']}\nmean = {_fmt(stats['mean'] * k)}{u}\nstd = {_fmt(stats['std'] * k)}{u}\n"
                f"5 % = {_fmt(q['0.05'] * k)}\nmedian = {_fmt(q['0.5'] * k)}\n95 % = {_fmt(q['0.95'] * k)}")
        ax.text(0.98, 0.97, text, transform=ax.transAxes, ha="right", va="top", fontsize=7, family="monospace",
                bbox={"facecolor": "white", "alpha": 0.8, "edgecolor": "0.8", "pad": 2})


def histogram_figure(df, metrics, bins: int | None = None):
    """One histogram per metric, the statistics written on each (mean, std, 5 %, median, 95 %).

    Parameters
    ----------
    df : pandas.DataFrame
        A metrics table (:func:`hertzchain.sweep.statistics.read_metrics`).
    metrics : sequence of str
        The metric columns to draw.
    bins : int or None
        Bins per histogram (default: about sqrt(members), between 10 and 100).

    Returns
    -------
    matplotlib.figure.Figure
        The figure (one row of panels, up to three per row).
    """
    from ..sweep.statistics import summarize
    from .style import agg_figure

    metrics = list(metrics)
    summary = summarize(df, metrics)["metrics"]
    bins = bins or _bins(len(df))
    cols = min(3, len(metrics))
    rows = -(-len(metrics) // cols)
    fig = agg_figure(3.6 * cols, 2.9 * rows)
    axes = np.atleast_1d(fig.subplots(rows, cols)).ravel()
    for ax, m in zip(axes, metrics):
        _histogram(ax, df, m, summary[m], bins)
        ax.set_ylabel("members")
    for ax in axes[len(metrics):]:
        ax.set_visible(False)
    fig.suptitle(f"{len(df)} members", fontsize=9)
    return fig


def corner_figure(df, metrics, bins: int | None = None):
    """The corner plot of ``metrics``: 2-D histograms of every pair, correlations, histograms.

    Parameters
    ----------
    df : pandas.DataFrame
        A metrics table.
    metrics : sequence of str
        At least two metric columns.
    bins : int or None
        Bins per axis (default: about sqrt(members), between 10 and 60).

    Returns
    -------
    matplotlib.figure.Figure
        A k x k grid: histograms with their statistics on the diagonal, 2-D histograms below it,
        Pearson's correlation coefficient r of each pair above it.
    """
    from ..errors import ConfigError
    from ..sweep.statistics import display_unit, summarize
    from .style import agg_figure

    metrics = list(metrics)
    if len(metrics) < 2:
        raise ConfigError("--signal", "a corner plot needs at least two metrics")
    summary = summarize(df, metrics)["metrics"]
    bins = min(bins or _bins(len(df)), 60)
    k = len(metrics)
    fig = agg_figure(2.2 * k, 2.2 * k)
    axes = fig.subplots(k, k, squeeze=False)
    data = df[metrics].to_numpy(dtype=float)
    ok = np.all(np.isfinite(data), axis=1)
    scaled = []
    for j, m in enumerate(metrics):
        unit, f = display_unit(summary[m]["units"], data[ok, j])
        scaled.append((data[ok, j] * f, unit))
    for i in range(k):
        for j in range(k):
            ax = axes[i, j]
            if i == j:
                _histogram(ax, df, metrics[i], summary[metrics[i]], bins, annotate=True)
                ax.set_yticks([])
            elif i > j:
                x, y = scaled[j][0], scaled[i][0]
                if x.size:
                    h, xe, ye = np.histogram2d(x, y, bins=bins)
                    ax.pcolormesh(xe, ye, np.ma.masked_equal(h.T, 0), cmap="Blues")
            else:
                x, y = scaled[j][0], scaled[i][0]
                r = np.corrcoef(x, y)[0, 1] if x.size > 1 and x.std() > 0 and y.std() > 0 else np.nan
                ax.text(0.5, 0.5, f"r = {r:.2f}", transform=ax.transAxes, ha="center", va="center", fontsize=9)
                ax.set_axis_off()
            if i == k - 1:
                ax.set_xlabel(_label(metrics[j], scaled[j][1]))
            elif i >= j:
                ax.tick_params(labelbottom=False)
            if j == 0 and i > 0:
                ax.set_ylabel(_label(metrics[i], scaled[i][1]))
            elif i >= j:
                ax.tick_params(labelleft=False)
    fig.suptitle(f"{int(ok.sum())} members with every metric", fontsize=9)
    return fig


def _bins(n: int) -> int:
    return int(np.clip(round(np.sqrt(max(n, 1))), 10, 100))


def plot_ensemble(path: str | Path, out: str | Path, metrics=None, kind: str = "histogram",
                  bins: int | None = None) -> Path:
    """Draw the histograms or the corner plot of a sweep's metrics into an image file.

    Parameters
    ----------
    path : str or pathlib.Path
        The sweep's output folder or its ``metrics.csv``.
    out : str or pathlib.Path
        Image file (PNG, PDF or SVG), written atomically.
    metrics : sequence of str or None
        Metric columns (default: :data:`DEFAULT_HISTOGRAM`, ``peak_wall_force``, for histograms,
        ``F_m`` when the table lacks it; :data:`DEFAULT_CORNER` for a corner plot).
    kind : str
        ``"histogram"`` or ``"corner"``.
    bins : int or None
        Bins per histogram (default: about sqrt(members)).

    Returns
    -------
    pathlib.Path
        The image written.

    Raises
    ------
    ConfigError
        An unreadable table, an unknown metric (``--signal``) or kind.
    """
    from ..errors import ConfigError
    from ..fileio import atomic_path
    from ..sweep.statistics import read_metrics, summarize
    from .common import image_format

    out = Path(out)
    fmt = image_format(out)
    df = read_metrics(path)
    default = DEFAULT_HISTOGRAM if DEFAULT_HISTOGRAM in df and np.isfinite(df[DEFAULT_HISTOGRAM].to_numpy(float)).any() \
        else "F_m"
    if kind == "histogram":
        metrics = list(metrics or [default])
        summarize(df, metrics)  # unknown metrics are refused here, naming them
        fig = histogram_figure(df, metrics, bins)
    elif kind == "corner":
        metrics = list(metrics or [default if m == DEFAULT_HISTOGRAM else m for m in DEFAULT_CORNER])
        summarize(df, metrics)
        fig = corner_figure(df, metrics, bins)
    else:
        raise ConfigError("--kind", f"{kind!r} is not a picture of metrics; use histogram or corner")
    with atomic_path(out) as tmp:
        fig.savefig(tmp, format=fmt, dpi=120)
    return out
