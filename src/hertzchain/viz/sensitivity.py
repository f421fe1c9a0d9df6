"""Pictures of sensitivities (:func:`hertzchain.sensitivity`): which bead, which constant matters.

Per-bead variables (``chain.diameters_mm[i]``, ``chain.offsets_mm[i]``, ...) are drawn as bars
against the bead number, one panel per list, in the objective's unit per the variable's unit (the
question "which bead matters most for the wall force?"). The other variables share one panel of
horizontal bars of their elasticities (x / J) dJ/dx, dimensionless, so that a velocity and a
Young modulus can be compared.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

__all__ = ["plot_sensitivity", "per_bead"]

_ITEM = re.compile(r"^(?P<list>chain\.\w+)\[(?P<i>\d+)\]$")


def per_bead(sens) -> tuple[dict[str, list[tuple[int, float]]], dict[str, float]]:
    """Split a sensitivity into per-bead lists and the other variables.

    Parameters
    ----------
    sens : Sensitivity
        A result of :func:`hertzchain.sensitivity`.

    Returns
    -------
    (dict, dict)
        ``{list path: [(bead number, derivative), ...]}`` (bead = item + 1) and ``{path: elasticity}``
        of the other variables.
    """
    lists: dict[str, list[tuple[int, float]]] = {}
    rel = sens.relative()
    others = {}
    for path, g in sens.gradient.items():
        m = _ITEM.match(path)
        if m:
            lists.setdefault(m.group("list"), []).append((int(m.group("i")) + 1, g))
        else:
            others[path] = rel[path]
    return lists, others


def plot_sensitivity(sens, out: str | Path | None = None, title: str | None = None):
    """Bar chart of a sensitivity: per-bead bars for list variables, elasticities for the others.

    Parameters
    ----------
    sens : Sensitivity
        A result of :func:`hertzchain.sensitivity`.
    out : str or Path, optional
        Image file to write (PNG, PDF, SVG...), atomically; None: only return the figure.
    title : str, optional
        Figure title (default: the objective and its value).

    Returns
    -------
    matplotlib.figure.Figure
        The figure (on its own Agg canvas).
    """
    from .style import agg_figure

    lists, others = per_bead(sens)
    panels = len(lists) + (1 if others else 0)
    fig = agg_figure(6.8, 2.6 * max(panels, 1))
    axes = fig.subplots(max(panels, 1), 1, squeeze=False)[:, 0]
    for ax, (name, rows) in zip(axes, lists.items()):
        beads = [b for b, _ in rows]
        vals = [g for _, g in rows]
        unit = sens.units[f"{name}[{beads[0] - 1}]"]
        colors = ["#d62728" if v > 0 else "#1f77b4" for v in vals]
        ax.bar(beads, vals, color=colors, width=0.8)
        ax.axhline(0.0, color="0.3", lw=0.6)
        top = max(range(len(vals)), key=lambda k: abs(vals[k]))
        ax.annotate(f"bead {beads[top]}", (beads[top], vals[top]), textcoords="offset points",
                    xytext=(0, 4 if vals[top] > 0 else -10), ha="center", fontsize=7)
        ax.margins(y=0.15)  # room for the label inside the frame
        ax.set_xlabel("bead")
        ax.set_ylabel(f"derivative [{sens.unit}/{unit}]")
        ax.set_title(f"by {name} (one bar per bead)", fontsize=8)
    if others:
        ax = axes[-1]
        names = list(others)
        vals = [0.0 if math.isnan(others[n]) else others[n] for n in names]
        ax.barh(range(len(names)), vals, color=["#d62728" if v > 0 else "#1f77b4" for v in vals])
        ax.set_yticks(range(len(names)), names)
        ax.axvline(0.0, color="0.3", lw=0.6)
        ax.invert_yaxis()
        ax.set_xlabel("elasticity (x / J) dJ/dx  [1]")
    fig.suptitle(title or f"sensitivities of J = {sens.objective} = {sens.value:.5g} {sens.unit}", fontsize=9)
    if out is not None:
        from .common import save_figure

        save_figure(fig, out)
    return fig
