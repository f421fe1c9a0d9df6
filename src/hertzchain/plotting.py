"""Quick-look figures of a result: force signals against time, one panel per signal."""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np
import xarray as xr

from .fileio import atomic_path

__all__ = ["plot_signals", "signal_list", "image_format"]

SIGNALS = ("wall_force", "sensor_force", "contact_force")


def signal_list(ds: xr.Dataset, signals: Sequence[str] | None = None,
                contacts: Sequence[int] | None = None) -> list[tuple[str, np.ndarray]]:
    """(label, force array) pairs to draw: the wall and sensors by default."""
    from .errors import ConfigError

    if not signals:
        signals = [s for s in ("wall_force", "sensor_force") if s in ds] or ["contact_force"]
    out: list[tuple[str, np.ndarray]] = []
    for name in signals:
        if name not in SIGNALS:
            raise ConfigError("--signal", f"unknown signal {name!r}; choose from {', '.join(SIGNALS)}")
        if name not in ds:
            raise ConfigError("--signal", f"the result has no {name!r} (recorded: "
                              f"{', '.join(s for s in SIGNALS if s in ds)})")
        if name == "wall_force":
            out.append(("wall force", ds.wall_force.values))
        elif name == "sensor_force":
            for s in ds.sensor.values:
                out.append((f"sensor in bead {int(s)}", ds.sensor_force.sel(sensor=s).values))
        else:
            chosen = list(contacts) if contacts else list(ds.contact.values[:: max(1, ds.contact.size // 6)])
            for c in chosen:
                if c not in ds.contact.values:
                    raise ConfigError("--contact", f"contact {c} was not recorded")
                out.append((f"contact {int(c)}", ds.contact_force.sel(contact=c).values))
    return out


#: Image formats the figures can be written in (by file suffix).
IMAGE_FORMATS = ("png", "pdf", "svg", "jpg", "jpeg", "eps", "ps", "tif", "tiff", "webp")


def image_format(out: str | Path, option: str = "--out") -> str:
    """The image format of ``out`` from its suffix (ConfigError naming ``option`` when unknown)."""
    from .errors import ConfigError

    fmt = Path(out).suffix.lower().lstrip(".")
    if fmt not in IMAGE_FORMATS:
        raise ConfigError(option, f"{str(out)!r} has no image suffix Matplotlib can write; "
                          f"use one of {', '.join('.' + f for f in IMAGE_FORMATS)}")
    return fmt


def _title(ds: xr.Dataset) -> str:
    """'N beads, striker D mm at V m/s' from the result's ``model`` attribute ('?' where a result
    written elsewhere lacks it or holds something else)."""
    import json

    def table(x) -> dict:
        return x if isinstance(x, dict) else {}

    def num(x) -> str:
        return f"{x:g}" if isinstance(x, (int, float)) and not isinstance(x, bool) else "?"

    try:
        model = table(json.loads(ds.attrs.get("model", "{}")))
    except (TypeError, ValueError):
        model = {}
    diameters = table(model.get("chain")).get("diameters_mm")
    s = table(model.get("striker"))
    n = len(diameters) if isinstance(diameters, list) else "?"
    return f"{n} beads, striker {num(s.get('diameter_mm'))} mm at {num(s.get('velocity'))} m/s"


def plot_signals(ds: xr.Dataset, out: str | Path, signals: Sequence[str] | None = None,
                 contacts: Sequence[int] | None = None, title: str | None = None) -> Path:
    """Draw each signal in its own panel (force [N] against time [ms]) and save to ``out``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fmt = image_format(out)
    panels = signal_list(ds, signals, contacts)
    t_ms = ds.time.values * 1e3
    fig, axes = plt.subplots(len(panels), 1, sharex=True, figsize=(6.5, 1.2 + 1.6 * len(panels)), squeeze=False)
    for ax, (label, force) in zip(axes[:, 0], panels):
        ax.plot(t_ms, force, lw=0.9)
        ax.set_ylabel("F [N]")
        ax.text(0.99, 0.9, label, transform=ax.transAxes, ha="right", va="top")
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("t [ms]")
    if title is None:
        title = _title(ds)
    axes[0, 0].set_title(title)
    fig.tight_layout()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    try:
        with atomic_path(out) as tmp:  # unique temporary file, fsync, atomic rename (hertzchain.fileio)
            fig.savefig(tmp, dpi=150, format=fmt)
    finally:
        plt.close(fig)
    return out
