"""Figures of the granular-crystal analyses: mode shapes, band structure, transmission spectrum."""

from __future__ import annotations

import numpy as np

__all__ = ["plot_modes", "plot_dispersion", "plot_transmission"]


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
