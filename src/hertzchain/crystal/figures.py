"""Figures of the granular-crystal analyses: mode shapes, band structure, transmission spectrum,
band-gap map over a swept parameter."""

from __future__ import annotations

import numpy as np

__all__ = ["plot_modes", "plot_dispersion", "plot_transmission", "plot_gap_map"]


def plot_modes(mds, count: int = 6):
    """The lowest ``count`` mode shapes (beads' amplitudes, mass-normalised) with their frequencies."""
    import matplotlib.pyplot as plt

    count = min(count, mds.frequencies.size)
    fig, ax = plt.subplots(figsize=(7, 4), constrained_layout=True)
    rows = [i for i, name in enumerate(mds.labels) if name.startswith("bead")]
    x = np.arange(1, len(rows) + 1)
    for k in range(count):
        shape = mds.shapes[rows, k]
        ax.plot(x, shape / np.max(np.abs(shape)), marker="o", label=f"{mds.frequencies[k]:.4g} Hz")
    ax.set_xlabel("bead")
    ax.set_ylabel("mode shape (normalised)")
    ax.legend(fontsize="small")
    return fig


def plot_dispersion(ds):
    """Branches f(q) [Hz] over q [rad per period], band gaps shaded."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4.5), constrained_layout=True)
    for b in ds.branch.values:
        ax.plot(ds.wavenumber.values, ds.frequency.sel(branch=b).values / 1e3, color="C0")
    for low, high in ds.attrs.get("gaps", []):
        ax.axhspan(low / 1e3, high / 1e3, color="0.85", zorder=0)
    ax.set_xlim(0, np.pi)
    ax.set_xlabel("wavenumber [rad per period]")
    ax.set_ylabel("frequency [kHz]")
    ax.set_title(f"band structure at F0 = {ds.attrs.get('precompression', float('nan')):.4g} N")
    return fig


def plot_transmission(ds, gaps=None):
    """Transmission abs(F_out) / abs(F_in) against frequency (log scale), band gaps shaded when given."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.5, 4), constrained_layout=True)
    ax.semilogy(ds.frequency.values / 1e3, ds.transmission.values, marker=".")
    for low, high in gaps or []:
        ax.axvspan(low / 1e3, high / 1e3, color="0.85", zorder=0)
    ax.set_xlabel("drive frequency [kHz]")
    ax.set_ylabel("transmission |F_out| / |F_in|")
    return fig


def plot_gap_map(metrics, parameter: str):
    """A band-gap map: each member's gaps [kHz] (a band-gap sweep's ``gaps_Hz``) shaded against the
    swept ``parameter`` (its values when numbers, else the member number), the top of the highest
    branch (``top_Hz``) drawn above them."""
    import json

    import matplotlib.pyplot as plt

    values = metrics[parameter].tolist()
    numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)
    x = np.asarray(values if numeric else metrics["member"].tolist(), dtype=float)
    order = np.argsort(x, kind="stable")
    x = x[order]
    gaps = [json.loads(metrics["gaps_Hz"].iloc[i]) for i in order]
    # each member's column runs half-way to its neighbours
    mid = (x[1:] + x[:-1]) / 2 if x.size > 1 else np.array([])
    step = float(np.diff(x).min()) if x.size > 1 and np.diff(x).min() > 0 else 1.0
    left = np.concatenate([[x[0] - step / 2], mid]) if x.size else x
    right = np.concatenate([mid, [x[-1] + step / 2]]) if x.size else x
    fig, ax = plt.subplots(figsize=(6.5, 4.5), constrained_layout=True)
    for lo, hi, g in zip(left, right, gaps):
        for low, high in g:
            ax.fill_between([lo, hi], low / 1e3, high / 1e3, color="0.7", linewidth=0)
    ax.plot(x, metrics["top_Hz"].to_numpy()[order] / 1e3, color="C0", label="top of the highest branch")
    ax.plot([], [], color="0.7", linewidth=8, label="band gap")
    ax.set_xlabel(parameter if numeric else "member")
    ax.set_ylabel("frequency [kHz]")
    ax.set_ylim(bottom=0)
    ax.legend(fontsize="small")
    return fig
