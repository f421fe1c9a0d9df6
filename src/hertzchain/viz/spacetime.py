"""``hertzchain plot --kind spacetime``: the space-time map of the contact forces.

Each recorded contact j is a column, time runs upwards, colour is F_j(t) [N] (paper eq. 1): the
front's slope is the pulse speed; reflections and the tail show as further streaks.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Sequence

from dataclasses import dataclass

import numpy as np
import xarray as xr

from ..errors import ConfigError
from .common import contact_positions, result_title, save_figure, select_member, time_window

__all__ = ["MAX_MAP_ROWS", "SpacetimeGrid", "spacetime_grid", "robust_vmax", "plot_spacetime"]

#: Rows of a space-time map beyond which time is binned (the largest force of each bin is kept,
#: so no peak is lost); a screen has fewer pixels than this anyway.
MAX_MAP_ROWS = 4000


def _edges(x: np.ndarray) -> np.ndarray:
    mid = 0.5 * (x[1:] + x[:-1])
    first = x[0] - (mid[0] - x[0]) if x.size > 1 else x[0] - 0.5
    last = x[-1] + (x[-1] - mid[-1]) if x.size > 1 else x[-1] + 0.5
    return np.concatenate([[first], mid, [last]])


@dataclass
class SpacetimeGrid:
    """The numbers of a space-time map (what :func:`plot_spacetime` and the explorer draw).

    Attributes
    ----------
    x : numpy.ndarray
        (C,) column positions: contact numbers, or positions along the chain at rest [mm].
    time : numpy.ndarray
        (R,) row times [s] (binned beyond ``max_rows`` samples: the first time of each bin).
    force : numpy.ndarray
        (R, C) contact forces [N] (each bin's largest, so no peak is lost).
    contacts : numpy.ndarray
        (C,) contact numbers of the columns.
    xlabel : str
        What ``x`` is, with its unit.
    """

    x: np.ndarray
    time: np.ndarray
    force: np.ndarray
    contacts: np.ndarray
    xlabel: str


def spacetime_grid(run: xr.Dataset, *, to_scale: bool = False, window: Sequence[float] | None = None,
                   max_rows: int = MAX_MAP_ROWS) -> SpacetimeGrid:
    """Contact forces of one run on a (time, contact) grid, binned in time to at most ``max_rows`` rows.

    Parameters
    ----------
    run : xarray.Dataset
        One run that stored contact forces (see :func:`~hertzchain.viz.common.select_member`).
    to_scale : bool
        Columns at the contacts' positions along the chain at rest [mm] instead of their numbers.
    window : (float, float) or None
        Time range [s] (default: the whole record).
    max_rows : int
        Rows beyond which time is binned, keeping each bin's largest force.

    Returns
    -------
    SpacetimeGrid
        Columns, rows and forces [N].
    """
    if "contact_force" not in run or run.sizes.get("contact", 0) == 0:
        raise ConfigError("--kind spacetime", "the result stores no contact forces (a sweep with "
                          "store = 'wall' keeps only the wall; use store = 'probes', or hertzchain run)")
    t = run.time.values
    sel = time_window(window, t)
    f = run.contact_force.values[sel]
    t = t[sel]
    if t.size > max_rows:
        k = math.ceil(t.size / max_rows)
        rows = t.size // k
        f = f[: rows * k].reshape(rows, k, -1).max(axis=1)
        t = t[: rows * k].reshape(rows, k)[:, 0]
    contacts = run.contact.values
    if to_scale:
        x = contact_positions(run)[contacts] * 1e3
        xlabel = "position along the chain at rest [mm] (contact points)"
    else:
        x = contacts.astype(float)
        xlabel = "contact j (0 = striker-bead 1)"
    return SpacetimeGrid(x=x, time=t, force=f, contacts=contacts, xlabel=xlabel)


def robust_vmax(grid: SpacetimeGrid) -> float:
    """Top of the linear colour scale: the largest force of the chain's own contacts (j >= 1).

    The striker contact (j = 0) carries a short, much larger force (31 N against 8.5 N for the
    paper's chain 1 at 0.2 m/s): scaled to it, the pulse in the chain fades to the colour of
    zero. It is drawn saturated instead (the colour bar says so with its arrow). The largest
    force of all when only the striker contact was recorded.

    Parameters
    ----------
    grid : SpacetimeGrid
        The map's numbers.

    Returns
    -------
    float
        The force [N] at the top of the colour scale (0 when nothing carries a force).
    """
    chain = grid.force[:, grid.contacts >= 1]
    f = chain if chain.size and np.isfinite(chain).any() and np.nanmax(chain) > 0 else grid.force
    return float(np.nanmax(f)) if np.isfinite(f).any() else 0.0


def plot_spacetime(ds: xr.Dataset, out: str | Path | None = None, *, scale: str = "linear",
                   to_scale: bool = False, window: Sequence[float] | None = None, member: int | None = None,
                   floor: float = 1e-4, vmax: float | str | None = "auto"):
    """Space-time map of the contact forces: contact (or position along the chain) against time.

    The field's standard picture of a pulse in a chain: each recorded contact j is a column,
    time runs upwards, colour is F_j(t) [N] (paper eq. 1). The front's slope is the pulse
    speed; reflections and the tail show as further streaks.

    Parameters
    ----------
    ds : xarray.Dataset
        A result that stored contact forces (batches and sweep chunks: give ``member``).
    out : str or pathlib.Path or None
        Image file to write; nothing is written when None.
    scale : {"linear", "log"}
        Colour scale; ``"log"`` spans ``floor`` times the largest force up to it (forces
        below are drawn blank), which shows the tail and the precursor.
    to_scale : bool
        Place the contacts at their positions along the chain at rest [mm] (:func:`contact_positions`)
        instead of at their numbers.
    window : (float, float) or None
        Time range [s] (default: the whole record).
    member : int or None
        Member of a batch or sweep chunk.
    floor : float
        Lower end of the log scale, as a fraction of the largest force.
    vmax : float or "auto" or None
        Top of the colour scale [N]; larger forces are drawn in its colour (the colour bar's
        arrow says so). ``"auto"`` (linear scale): the largest force in the chain, leaving out
        the short, much larger striker contact (:func:`robust_vmax`); ``None``: the largest
        force of all. The log scale always spans ``floor`` up to its top.

    Returns
    -------
    matplotlib.figure.Figure
        The map is ``fig.axes[0].collections[0]``; its array is the (time, contact) forces [N]
        drawn (binned in time, keeping each bin's largest force, beyond ``MAX_MAP_ROWS`` samples).
    """
    from matplotlib.colors import LogNorm, Normalize

    from .style import agg_figure

    run = select_member(ds, member)
    if scale not in ("linear", "log"):
        raise ConfigError("--scale", f"must be 'linear' or 'log', got {scale!r}")
    grid = spacetime_grid(run, to_scale=to_scale, window=window)
    f = grid.force
    fmax = float(np.nanmax(f)) if np.isfinite(f).any() else 0.0
    if not fmax > 0:
        raise ConfigError("--window", "no contact carries any force in this time range")
    if isinstance(vmax, str):
        if vmax != "auto":
            raise ConfigError("--vmax", f"must be a force in N or 'auto', got {vmax!r}")
        top = robust_vmax(grid) if scale == "linear" else fmax
    else:
        top = fmax if vmax is None else float(vmax)
    if not (math.isfinite(top) and top > 0):
        raise ConfigError("--vmax", f"must be a positive force in N, got {vmax!r}")
    norm = LogNorm(floor * top, top) if scale == "log" else Normalize(0.0, top)
    data = np.ma.masked_less_equal(f, floor * top) if scale == "log" else f
    fig = agg_figure(6.0, 4.8)
    ax = fig.subplots()
    mesh = ax.pcolormesh(_edges(grid.x), _edges(grid.time * 1e3), data, norm=norm, cmap="magma_r", shading="flat",
                         rasterized=True)
    cb = fig.colorbar(mesh, ax=ax, pad=0.01, extend="max" if fmax > top else "neither")
    cb.set_label("contact force F [N]" + (" (log scale)" if scale == "log" else ""))
    ax.set_xlabel(grid.xlabel)
    ax.set_ylabel("t [ms]")
    ax.set_title(result_title(run, member if "member" in ds.dims else None), fontsize=9)
    if out is not None:
        save_figure(fig, out)
    return fig
