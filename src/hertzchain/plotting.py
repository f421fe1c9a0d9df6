"""Figures of any hertzchain result: signals against time, the space-time map, the energies.

A result is the Dataset of :func:`hertzchain.simulate` (or a file written by
:func:`hertzchain.save`), a stacked batch of :func:`hertzchain.simulate_batch` or a sweep chunk
(``member`` dimension: pick one with ``member``), possibly with the instrument model's measured
signals (each on its own scope time axis). Every function returns the
:class:`matplotlib.figure.Figure` (Agg canvas, no pyplot state) so that callers and tests can
read back what was drawn; :func:`save_figure` writes it atomically.

Display units: time in ms, force in N, energy in mJ, positions along the chain in mm.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Sequence

import numpy as np
import xarray as xr

from .errors import ConfigError

__all__ = ["plot_signals", "plot_spacetime", "plot_energy", "signal_list", "select_member", "time_window",
           "contact_positions", "bead_centres", "save_figure", "image_format", "IMAGE_FORMATS", "SIGNALS", "KINDS"]

#: Time dimensions of a result: the simulation's and the instrument model's scope records.
TIME_DIMS = ("time", "wall_scope_time", "sensor_scope_time")
#: Signals of a result that ``plot --kind signals`` draws (each in its own panel).
SIGNALS = ("wall_force", "sensor_force", "contact_force", "measured_wall_force", "measured_sensor_force",
           "velocity", "displacement")
#: What ``hertzchain plot --kind`` draws.
KINDS = ("signals", "spacetime", "energy")
#: Rows of a space-time map beyond which time is binned (the largest force of each bin is kept,
#: so no peak is lost); a screen has fewer pixels than this anyway.
MAX_MAP_ROWS = 4000

_LABELS = {"wall_force": "wall force", "measured_wall_force": "wall force as measured",
           "velocity": "velocity", "displacement": "displacement"}
_DISPLAY = {"N": ("F [N]", 1.0), "m s-1": ("v [m/s]", 1.0), "m": ("u [µm]", 1e6)}


def _figure(width: float, height: float):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


#: Image formats the figures can be written in (by file suffix).
IMAGE_FORMATS = ("png", "pdf", "svg", "jpg", "jpeg", "eps", "ps", "tif", "tiff", "webp")


def image_format(out: str | Path, option: str = "--out") -> str:
    """The image format of ``out`` from its suffix.

    Parameters
    ----------
    out : str or pathlib.Path
        Target file name.
    option : str
        The option named in the error (``--out``).

    Returns
    -------
    str
        The format (``"png"``, ``"pdf"``, ...); a ConfigError naming ``option`` when the suffix
        is not one of IMAGE_FORMATS.
    """
    fmt = Path(out).suffix.lower().lstrip(".")
    if fmt not in IMAGE_FORMATS:
        raise ConfigError(option, f"{str(out)!r} has no image suffix Matplotlib can write; "
                          f"use one of {', '.join('.' + f for f in IMAGE_FORMATS)}")
    return fmt


def save_figure(fig, out: str | Path, dpi: int = 150) -> Path:
    """Write ``fig`` to ``out`` atomically; the format follows the suffix (:func:`image_format`).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    out : str or pathlib.Path
        Target file; its folder is created.
    dpi : int
        Resolution of raster formats [dots per inch].

    Returns
    -------
    pathlib.Path
        ``out``.
    """
    from .fileio import atomic_path

    out = Path(out)
    fmt = image_format(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(out) as tmp:
        fig.savefig(tmp, format=fmt, dpi=dpi)
    return out


def select_member(ds: xr.Dataset, member: int | None = None) -> xr.Dataset:
    """One run of a result: the result itself, or member ``member`` of a batch or sweep chunk.

    Parameters
    ----------
    ds : xarray.Dataset
        A result, or a stacked batch / sweep chunk (``member`` dimension).
    member : int or None
        Member number as stored in the file (sweep chunks keep the sweep's member numbers, the
        rows of ``metrics.csv``). Required when the file holds several members.

    Returns
    -------
    xarray.Dataset
        The chosen run, without the ``member`` dimension.
    """
    if "time" not in ds.coords:
        raise ConfigError("RESULT", "is not a hertzchain result (no time axis); give a file written by "
                          "hertzchain run, sweep or hertzchain.save")
    if "member" not in ds.dims:
        if member is not None:
            raise ConfigError("--member", "this result holds a single run; leave --member out")
        return ds
    members = [int(m) for m in ds.member.values]
    listed = f"{members[0]}..{members[-1]}" if members == list(range(members[0], members[-1] + 1)) else str(members)
    if member is None:
        if len(members) == 1:
            member = members[0]
        else:
            raise ConfigError("--member", f"the file holds {len(members)} runs (members {listed}); choose one "
                              "with --member N")
    if member not in members:
        raise ConfigError("--member", f"member {member} is not in this file (it holds members {listed})")
    return ds.sel(member=member)


def time_window(window: Sequence[float] | None, t: np.ndarray) -> np.ndarray:
    """Boolean mask of the samples of ``t`` [s] inside ``window`` = (t0, t1) [s] (all when None)."""
    if window is None:
        return np.ones(t.size, dtype=bool)
    t0, t1 = float(window[0]), float(window[1])
    if not (t1 > t0):
        raise ConfigError("--window", f"needs T0 < T1, got {t0 * 1e3:g},{t1 * 1e3:g} ms")
    sel = (t >= t0) & (t <= t1)
    if sel.sum() < 2:
        raise ConfigError("--window", f"{t0 * 1e3:g},{t1 * 1e3:g} ms holds fewer than 2 samples; the record "
                          f"spans {t[0] * 1e3:g}..{t[-1] * 1e3:g} ms")
    return sel


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
        Names from ``SIGNALS``; default: the wall and sensor forces, and their measured
        versions when the instrument model was on (else the contact forces).
    contacts : sequence of int or None
        Contacts drawn for ``contact_force`` (default: about six spread along the chain).

    Returns
    -------
    list of tuple
        (label, units, time dimension, time [s], values); time is the signal's own axis (the
        scope's for measured signals, relative to its trigger).
    """
    if not signals:
        signals = [s for s in ("wall_force", "sensor_force", "measured_wall_force", "measured_sensor_force")
                   if s in ds] or ["contact_force"]
    out: list[tuple[str, str, str, np.ndarray, np.ndarray]] = []
    recorded = [s for s in SIGNALS if s in ds and (s != "contact_force" or ds.sizes.get("contact", 0) > 0)]
    for name in signals:
        if name not in SIGNALS:
            raise ConfigError("--signal", f"unknown signal {name!r}; choose from {', '.join(SIGNALS)}")
        if name not in recorded:
            raise ConfigError("--signal", f"the result has no {name!r} (recorded: {', '.join(recorded) or 'none'})")
        var = ds[name]
        tdim = _time_dim(var)
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


def _title(ds: xr.Dataset, member: int | None = None) -> str:
    """'N beads, striker D mm at V m/s' from the result's ``model`` (attribute, or per-member
    variable of a batch), '?' where a result written elsewhere lacks it or holds something else;
    with the member and its swept parameters when a member was chosen."""
    def table(x) -> dict:
        return x if isinstance(x, dict) else {}

    def num(x) -> str:
        return f"{x:g}" if isinstance(x, (int, float)) and not isinstance(x, bool) else "?"

    raw = ds["model"].values.item() if "model" in ds.data_vars else ds.attrs.get("model", "{}")
    try:
        model = table(json.loads(raw))
    except (TypeError, ValueError):
        model = {}
    diameters = table(model.get("chain")).get("diameters_mm")
    s = table(model.get("striker"))
    n = len(diameters) if isinstance(diameters, list) else "?"
    title = f"{n} beads, striker {num(s.get('diameter_mm'))} mm at {num(s.get('velocity'))} m/s"
    if member is not None:
        title += f" (member {member}"
        if "parameters" in ds:
            title += f": {ds.parameters.values.item()}"
        title += ")"
    return title


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
    run = select_member(ds, member)
    panels = signal_list(run, signals, contacts)
    fig = _figure(6.5, 1.0 + 1.7 * len(panels))
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
    fig.suptitle(title or _title(run, member if "member" in ds.dims else None), fontsize=10)
    if out is not None:
        save_figure(fig, out)
    return fig


def bead_centres(ds: xr.Dataset) -> np.ndarray:
    """Centre [m] of every bead along the chain at rest, bead 1's left side at 0.

    Consecutive centres are the axial distance of touching spheres apart,
    sqrt((R_n + R_{n+1})^2 - (e_{n+1} - e_n)^2) (equal to R_n + R_{n+1} for aligned beads).
    """
    phi = ds.diameter.values
    e = ds.offset.values if "offset" in ds else np.zeros_like(phi)
    dx = np.sqrt(np.maximum((0.5 * (phi[:-1] + phi[1:])) ** 2 - np.diff(e) ** 2, 0.0))
    return 0.5 * phi[0] + np.concatenate([[0.0], np.cumsum(dx)])


def contact_positions(ds: xr.Dataset) -> np.ndarray:
    """Position [m] along the chain of every contact of ``ds.contact_all`` at rest.

    Contact 0 (striker-bead 1) is at 0; contact j between beads j and j + 1 is their touching
    point, R_j / (R_j + R_{j+1}) of the way between their centres (the sum of the diameters of
    beads 1..j for an aligned chain); contact N (bead N-wall) is the wall.
    """
    phi = ds.diameter.values
    c = bead_centres(ds)
    between = c[:-1] + np.diff(c) * phi[:-1] / (phi[:-1] + phi[1:])
    x = np.concatenate([[0.0], between, [c[-1] + 0.5 * phi[-1]]])
    return x[: ds.sizes.get("contact_all", phi.size + 1)]


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
    fig = _figure(6.0, 4.8)
    ax = fig.subplots()
    mesh = ax.pcolormesh(_edges(x), _edges(t * 1e3), data, norm=norm, cmap="magma_r", shading="flat",
                         rasterized=True)
    cb = fig.colorbar(mesh, ax=ax, pad=0.01)
    cb.set_label("contact force F [N]" + (" (log scale)" if scale == "log" else ""))
    ax.set_xlabel(xlabel)
    ax.set_ylabel("t [ms]")
    ax.set_title(_title(run, member if "member" in ds.dims else None), fontsize=9)
    if out is not None:
        save_figure(fig, out)
    return fig


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
    run = select_member(ds, member)
    parts = [(lab, name) for lab, name in (("kinetic", "kinetic_energy"), ("potential", "potential_energy"),
                                           ("dissipated", "dissipated_energy")) if name in run]
    if not parts:
        raise ConfigError("--kind energy", "the result holds no energies")
    t = run.time.values
    sel = time_window(window, t)
    fig = _figure(6.5, 3.4)
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
    ax.set_title(_title(run, member if "member" in ds.dims else None), fontsize=9)
    if out is not None:
        save_figure(fig, out)
    return fig
