"""``hertzchain plot --kind spacetime``: the space-time map of the contact forces.

Each recorded contact j is a column, time runs upwards, colour is F_j(t) [N] (paper eq. 1): the
front's slope is the pulse speed; reflections and the tail show as further streaks.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Sequence

import numpy as np
import xarray as xr

from ..errors import ConfigError
from .common import contact_positions, result_title, save_figure, select_member, time_window

__all__ = ["MAX_MAP_ROWS", "plot_spacetime"]

#: Rows of a space-time map beyond which time is binned (the largest force of each bin is kept,
#: so no peak is lost); a screen has fewer pixels than this anyway.
MAX_MAP_ROWS = 4000


def _edges(x: np.ndarray) -> np.ndarray:
    mid = 0.5 * (x[1:] + x[:-1])
    first = x[0] - (mid[0] - x[0]) if x.size > 1 else x[0] - 0.5
    last = x[-1] + (x[-1] - mid[-1]) if x.size > 1 else x[-1] + 0.5
    return np.concatenate([[first], mid, [last]])


def plot_spacetime(ds: xr.Dataset, out: str | Path | None = None, *, scale: str = "linear",
                   to_scale: bool = False, window: Sequence[float] | None = None, member: int | None = None,
                   floor: float = 1e-4):
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

    Returns
    -------
    matplotlib.figure.Figure
        The map is ``fig.axes[0].collections[0]``; its array is the (time, contact) forces [N]
        drawn (binned in time, keeping each bin's largest force, beyond ``MAX_MAP_ROWS`` samples).
    """
    from matplotlib.colors import LogNorm, Normalize

    from .style import agg_figure

    run = select_member(ds, member)
    if "contact_force" not in run or run.sizes.get("contact", 0) == 0:
        raise ConfigError("--kind spacetime", "the result stores no contact forces (a sweep with "
                          "store = 'wall' keeps only the wall; use store = 'probes', or hertzchain run)")
    if scale not in ("linear", "log"):
        raise ConfigError("--scale", f"must be 'linear' or 'log', got {scale!r}")
    t = run.time.values
    sel = time_window(window, t)
    f = run.contact_force.values[sel]
    t = t[sel]
    if t.size > MAX_MAP_ROWS:
        k = math.ceil(t.size / MAX_MAP_ROWS)
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
    fmax = float(np.nanmax(f)) if np.isfinite(f).any() else 0.0
    if not fmax > 0:
        raise ConfigError("--window", "no contact carries any force in this time range")
    norm = LogNorm(floor * fmax, fmax) if scale == "log" else Normalize(0.0, fmax)
    data = np.ma.masked_less_equal(f, floor * fmax) if scale == "log" else f
    fig = agg_figure(6.0, 4.8)
    ax = fig.subplots()
    mesh = ax.pcolormesh(_edges(x), _edges(t * 1e3), data, norm=norm, cmap="magma_r", shading="flat",
                         rasterized=True)
    cb = fig.colorbar(mesh, ax=ax, pad=0.01)
    cb.set_label("contact force F [N]" + (" (log scale)" if scale == "log" else ""))
    ax.set_xlabel(xlabel)
    ax.set_ylabel("t [ms]")
    ax.set_title(result_title(run, member if "member" in ds.dims else None), fontsize=9)
    if out is not None:
        save_figure(fig, out)
    return fig
