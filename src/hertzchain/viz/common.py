"""What every picture of a result needs: one member, a time window, a title, where the beads
and contacts are, the image format and an atomic save.

A result is the Dataset of :func:`hertzchain.simulate` (or a file written by
:func:`hertzchain.save`), a stacked batch of :func:`hertzchain.simulate_batch` or a sweep chunk
(``member`` dimension: pick one with ``member``), possibly with the instrument model's measured
signals (each on its own scope time axis).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Sequence

import numpy as np
import xarray as xr

from ..errors import ConfigError

__all__ = ["IMAGE_FORMATS", "image_format", "save_figure", "select_member", "time_window", "result_title",
           "bead_centres", "contact_positions"]

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
    from ..fileio import atomic_path

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


def result_title(ds: xr.Dataset, member: int | None = None) -> str:
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
    if "striker" in model and model["striker"] is None:  # a crystal built with striker=None
        title = f"{n} beads, no striker"
    if member is not None:
        title += f" (member {member}"
        if "parameters" in ds:
            title += f": {ds.parameters.values.item()}"
        title += ")"
    return title


def bead_centres(ds: xr.Dataset) -> np.ndarray:
    """Centre [m] of every bead along the chain at rest, bead 1's left side at 0.

    Consecutive centres are the axial distance of touching spheres apart,
    sqrt((R_n + R_{n+1})^2 - (e_{n+1} - e_n)^2) (equal to R_n + R_{n+1} for aligned beads).
    """
    phi = ds.diameter.values
    if not phi.size:  # no beads
        return np.zeros(0)
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
    if not phi.size:  # no beads: contact 0 is the striker on the wall, at 0
        return np.zeros(min(1, ds.sizes.get("contact_all", 1)))
    c = bead_centres(ds)
    between = c[:-1] + np.diff(c) * phi[:-1] / (phi[:-1] + phi[1:])
    x = np.concatenate([[0.0], between, [c[-1] + 0.5 * phi[-1]]])
    return x[: ds.sizes.get("contact_all", phi.size + 1)]
