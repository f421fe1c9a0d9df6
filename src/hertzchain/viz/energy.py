"""``hertzchain plot --kind energy``: kinetic, potential and dissipated energy and their sum."""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np
import xarray as xr

from ..errors import ConfigError
from .common import result_title, save_figure, select_member, time_window

__all__ = ["plot_energy"]


def plot_energy(ds: xr.Dataset, out: str | Path | None = None, *, window: Sequence[float] | None = None,
                member: int | None = None):
    """Kinetic, Hertz potential and dissipated energy and their sum against time.

    The sum is the striker's initial kinetic energy (plus precompression work) when the run
    conserves energy; its drift is the integrator's error.

    Parameters
    ----------
    ds : xarray.Dataset
        A result (batches and sweep chunks: give ``member``).
    out : str or pathlib.Path or None
        Image file to write; nothing is written when None.
    window : (float, float) or None
        Time range [s].
    member : int or None
        Member of a batch or sweep chunk.

    Returns
    -------
    matplotlib.figure.Figure
        One axes; lines labelled "kinetic", "potential", "dissipated", "total" [mJ].
    """
    from .style import agg_figure

    run = select_member(ds, member)
    parts = [(lab, name) for lab, name in (("kinetic", "kinetic_energy"), ("potential", "potential_energy"),
                                           ("dissipated", "dissipated_energy")) if name in run]
    if not parts:
        raise ConfigError("--kind energy", "the result holds no energies")
    t = run.time.values
    sel = time_window(window, t)
    fig = agg_figure(6.5, 3.4)
    ax = fig.subplots()
    total = np.zeros(int(sel.sum()))
    for lab, name in parts:
        e = run[name].values[sel] * 1e3
        total = total + e
        ax.plot(t[sel] * 1e3, e, lw=1.0, label=lab)
    ax.plot(t[sel] * 1e3, total, lw=1.2, color="k", label="total")
    ax.set_xlim(t[sel][0] * 1e3, t[sel][-1] * 1e3)
    top = float(np.nanmax(total)) if np.isfinite(total).any() else 0.0
    ax.set_ylim(0, 1.05 * top if top > 0 else 1.0)
    ax.set_xlabel("t [ms]")
    ax.set_ylabel("energy [mJ]")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0))  # outside the axes: never on the data
    ax.grid(alpha=0.3)
    ax.set_title(result_title(run, member if "member" in ds.dims else None), fontsize=9)
    if out is not None:
        save_figure(fig, out)
    return fig
