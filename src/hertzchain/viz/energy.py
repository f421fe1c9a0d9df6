"""``hertzchain plot --kind energy``: kinetic, potential and dissipated energy and their sum."""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np
import xarray as xr

from ..errors import ConfigError
from .common import result_title, save_figure, select_member, time_window

__all__ = ["energy_curves", "plot_energy"]


def energy_curves(run: xr.Dataset, window: Sequence[float] | None = None) -> tuple[np.ndarray, list[tuple[str, np.ndarray]]]:
    """The energies of one run: kinetic, Hertz potential, dissipated (those recorded) and their total.

    Parameters
    ----------
    run : xarray.Dataset
        One run (see :func:`~hertzchain.viz.common.select_member`).
    window : (float, float) or None
        Time range [s] (default: the whole record).

    Returns
    -------
    time : numpy.ndarray
        Sample times [s].
    curves : list of (str, numpy.ndarray)
        ("kinetic" | "potential" | "dissipated" | "plastic" | "total", energy [J]); "total" last.
        "plastic" is the work of the elastoplastic law (Thornton), recorded apart from the
        viscous dissipation.
    """
    parts = [(lab, name) for lab, name in (("kinetic", "kinetic_energy"), ("potential", "potential_energy"),
                                           ("dissipated", "dissipated_energy"), ("plastic", "plastic_work"))
             if name in run and run[name].dims == ("time",)]
    if not parts:
        raise ConfigError("--kind energy", "the result holds no energies")
    t = run.time.values
    sel = time_window(window, t)
    curves = [(lab, run[name].values[sel]) for lab, name in parts]
    curves.append(("total", np.sum([e for _, e in curves], axis=0)))
    return t[sel], curves


def plot_energy(ds: xr.Dataset, out: str | Path | None = None, *, window: Sequence[float] | None = None,
                member: int | None = None):
    """Kinetic, Hertz potential, dissipated (and plastic) energy and their sum against time.

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
    t, curves = energy_curves(run, window)
    fig = agg_figure(6.5, 3.4)
    ax = fig.subplots()
    for lab, e in curves:
        is_total = lab == "total"
        ax.plot(t * 1e3, e * 1e3, lw=1.2 if is_total else 1.0, label=lab, color="k" if is_total else None)
    total = curves[-1][1] * 1e3
    ax.set_xlim(t[0] * 1e3, t[-1] * 1e3)
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
