"""Checks of drawn figures by their data (shared by the figure tests): text on curves, clipped data."""

from __future__ import annotations

import numpy as np


def _boxes(ax, renderer):
    """(label, window extent) of every text inside the axes: texts, legend, axes-anchored text."""
    out = [(t.get_text().replace("\n", " ")[:40], t.get_window_extent(renderer)) for t in ax.texts
           if t.get_visible() and t.get_text().strip()]
    legend = ax.get_legend()
    if legend is not None and legend.get_visible():
        out.append(("legend", legend.get_window_extent(renderer)))
    return out


def _points(ax):
    """Display coordinates of every drawn data point of the axes' lines inside its view limits."""
    pts = []
    x0, x1 = sorted(ax.get_xlim())
    y0, y1 = sorted(ax.get_ylim())
    for line in ax.get_lines():
        if not line.get_visible():
            continue
        x, y = (np.asarray(a, dtype=float) for a in line.get_data())
        if x.size == 0 or line.get_transform() != ax.transData:
            continue
        x, y = np.broadcast_arrays(x, y)
        inside = (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1) & np.isfinite(x) & np.isfinite(y)
        if not inside.any():
            continue
        p = ax.transData.transform(np.column_stack([x[inside], y[inside]]))
        if line.get_linestyle() not in ("None", "", " ") and 1 < len(p) < 2000:
            # sparse lines (markers joined by segments): sample the segments too
            s = np.linspace(0.0, 1.0, 12)[:, None, None]
            p = (p[:-1][None] * (1 - s) + p[1:][None] * s).reshape(-1, 2)
        pts.append(p)
    return np.concatenate(pts) if pts else np.empty((0, 2))


def text_overlaps(fig) -> list[str]:
    """Texts and legends that cover a drawn data point (panel tags included), as readable strings."""
    renderer = fig.canvas.get_renderer()
    fig.draw(renderer)
    bad = []
    for k, ax in enumerate(fig.axes):
        pts = _points(ax)
        if not pts.size:
            continue
        for label, box in _boxes(ax, renderer):
            hit = (pts[:, 0] > box.x0) & (pts[:, 0] < box.x1) & (pts[:, 1] > box.y0) & (pts[:, 1] < box.y1)
            if hit.any():
                bad.append(f"axes {k} ({ax.get_title() or ax.get_ylabel()}): {label!r} covers {int(hit.sum())} points")
    return bad


def uncovered(fig) -> list[str]:
    """Axes whose view limits cut off part of a drawn line (the axis range must cover the data)."""
    bad = []
    for k, ax in enumerate(fig.axes):
        y0, y1 = sorted(ax.get_ylim())
        x0, x1 = sorted(ax.get_xlim())
        for line in ax.get_lines():
            if line.get_transform() != ax.transData:
                continue
            x, y = (np.asarray(a, dtype=float) for a in line.get_data())
            if x.size == 0:
                continue
            x, y = np.broadcast_arrays(x, y)
            shown = (x >= x0) & (x <= x1) & np.isfinite(y)
            if ax.get_yscale() == "log":
                shown &= y > 0
            if shown.any() and (y[shown].max() > y1 or (ax.get_yscale() != "log" and y[shown].min() < y0)):
                bad.append(f"axes {k} ({ax.get_ylabel()}): {line.get_label()!r} spans "
                           f"{y[shown].min():.3g}..{y[shown].max():.3g} beyond {y0:.3g}..{y1:.3g}")
    return bad
