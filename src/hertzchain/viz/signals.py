"""``hertzchain plot --kind signals``: each recorded signal in its own panel against time.

Forces at the wall and in sensor beads, contact forces, the instrument model's measured signals
(each on its own scope time axis), velocities and displacements; display units on the axes.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np
import xarray as xr

from ..errors import ConfigError
from .common import result_title, save_figure, select_member, time_window

__all__ = ["SIGNALS", "signal_list", "plot_signals"]

#: Time dimensions of a result: the simulation's and the instrument model's scope records.
TIME_DIMS = ("time", "wall_scope_time", "sensor_scope_time")
#: Signals of a result that ``plot --kind signals`` draws (each in its own panel).
SIGNALS = ("wall_force", "sensor_force", "contact_force", "measured_wall_force", "measured_sensor_force",
           "velocity", "displacement", "body_force", "body_displacement")

_LABELS = {"wall_force": "wall force", "measured_wall_force": "wall force as measured",
           "velocity": "velocity", "displacement": "displacement", "body_force": "body -> ground",
           "body_displacement": "body displacement"}
_DISPLAY = {"N": ("F [N]", 1.0), "m s-1": ("v [m/s]", 1.0), "m": ("u [µm]", 1e6)}


def _time_dim(var: xr.DataArray) -> str | None:
    return next((d for d in var.dims if d in TIME_DIMS), None)


def signal_list(ds: xr.Dataset, signals: Sequence[str] | None = None,
                contacts: Sequence[int] | None = None) -> list[tuple[str, str, str, np.ndarray, np.ndarray]]:
    """The panels of :func:`plot_signals`: (label, units, time [s], values) per signal.

    Parameters
    ----------
    ds : xarray.Dataset
        One run (see :func:`select_member`).
    signals : sequence of str or None
        Names from ``SIGNALS``; default: the wall and sensor forces, a protected body's force on
        the ground, and the measured versions when the instrument model was on (else the contact
        forces).
    contacts : sequence of int or None
        Contacts drawn for ``contact_force`` (default: about six spread along the chain).

    Returns
    -------
    list of tuple
        (label, units, time dimension, time [s], values); time is the signal's own axis (the
        scope's for measured signals, relative to its trigger).
    """
    if not signals:
        signals = [s for s in ("wall_force", "sensor_force", "body_force", "measured_wall_force",
                               "measured_sensor_force") if s in ds] or ["contact_force"]
    out: list[tuple[str, str, str, np.ndarray, np.ndarray]] = []
    recorded = [s for s in SIGNALS if s in ds and (s != "contact_force" or ds.sizes.get("contact", 0) > 0)]
    for name in signals:
        if name not in SIGNALS:
            raise ConfigError("--signal", f"unknown signal {name!r}; choose from {', '.join(SIGNALS)}")
        if name not in recorded:
            raise ConfigError("--signal", f"the result has no {name!r} (recorded: {', '.join(recorded) or 'none'})")
        var = ds[name]
        tdim = _time_dim(var)
        assert tdim is not None  # (every one of SIGNALS is a record along a time dimension)
        t = ds[tdim].values
        units = var.attrs.get("units", "")
        other = [d for d in var.dims if d != tdim]
        if not other:
            out.append((_LABELS.get(name, name.replace("_", " ")), units, tdim, t, var.values))
            continue
        dim = other[0]
        if name == "contact_force":
            values = ds.contact.values
            chosen = list(contacts) if contacts else list(values[:: max(1, values.size // 6)])
            for c in chosen:
                if c not in values:
                    raise ConfigError("--contact", f"contact {c} was not recorded (recorded: {values[0]}..{values[-1]})")
                out.append((f"contact {int(c)}", units, tdim, t, var.sel(contact=c).values))
        else:
            prefix = "measured " if name.startswith("measured") else ""
            for k in ds[dim].values:
                what = f"{prefix}sensor in bead {int(k)}" if dim == "sensor" else f"{_LABELS[name]} of body {int(k)}"
                out.append((what, units, tdim, t, var.sel({dim: k}).values))
    return out


def _ylim(ax, values: np.ndarray) -> None:
    """Axis range covering every drawn value, with a margin (no clipped peak)."""
    finite = values[np.isfinite(values)]
    if finite.size == 0:  # nothing to draw (a damaged or foreign result): Matplotlib's default
        return
    lo, hi = float(finite.min()), float(finite.max())
    pad = 0.06 * (hi - lo) if hi > lo else max(abs(hi), 1e-30) * 0.1
    ax.set_ylim(lo - pad, hi + pad)


def plot_signals(ds: xr.Dataset, out: str | Path | None = None, signals: Sequence[str] | None = None,
                 contacts: Sequence[int] | None = None, title: str | None = None,
                 window: Sequence[float] | None = None, member: int | None = None):
    """Each signal in its own panel against time, on its own time axis.

    Parameters
    ----------
    ds : xarray.Dataset
        A result (batches and sweep chunks: give ``member``).
    out : str or pathlib.Path or None
        Image file to write (PNG, PDF, SVG); nothing is written when None.
    signals, contacts : sequence or None
        What to draw (see :func:`signal_list`).
    title : str or None
        Figure title (default: chain and striker).
    window : (float, float) or None
        Time range [s] shown (default: the whole record).
    member : int or None
        Member of a batch or sweep chunk (see :func:`select_member`).

    Returns
    -------
    matplotlib.figure.Figure
        One axes per panel; each panel's label is its title, above the data.
    """
    from .style import agg_figure

    run = select_member(ds, member)
    panels = signal_list(run, signals, contacts)
    fig = agg_figure(6.5, 1.0 + 1.7 * len(panels))
    axes = fig.subplots(len(panels), 1, squeeze=False)[:, 0]
    for ax, (label, units, tdim, t, values) in zip(axes, panels):
        sel = time_window(window, t)
        ylabel, scale = _DISPLAY.get(units, (f"[{units}]", 1.0))
        y = values[sel] * scale
        ax.plot(t[sel] * 1e3, y, lw=0.9)
        ax.set_xlim(t[sel][0] * 1e3, t[sel][-1] * 1e3)
        _ylim(ax, y)
        ax.set_ylabel(ylabel)
        ax.set_title(label, loc="left", fontsize=9)  # above the axes: never on the data
        ax.grid(alpha=0.3)
        ax.set_xlabel("t [ms]" if tdim == "time" else "t - trigger [ms] (scope record)")
    fig.suptitle(title or result_title(run, member if "member" in ds.dims else None), fontsize=10)
    if out is not None:
        save_figure(fig, out)
    return fig
