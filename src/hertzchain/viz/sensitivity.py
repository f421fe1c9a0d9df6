"""Pictures of sensitivities (:func:`hertzchain.sensitivity`): which bead, which constant matters.

Per-bead variables (``chain.diameters_mm[i]``, ``chain.offsets_mm[i]``, ...) are drawn as bars
against the bead number, one panel per list, in the objective's unit per the variable's unit (the
question "which bead matters most for the wall force?"). The other variables share one panel of
horizontal bars of their elasticities (x / J) dJ/dx, dimensionless, so that a velocity and a
Young modulus can be compared. Every bar's value is printed at its end, and a bar of ~0 (below
:data:`NEAR_ZERO` of its panel's largest) gets a marker on the zero line: a zero-height bar
is otherwise invisible. An undefined elasticity (zero variable or objective) is printed as such.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

__all__ = ["plot_sensitivity", "per_bead", "NEAR_ZERO"]

_ITEM = re.compile(r"^(?P<list>chain\.\w+)\[(?P<i>\d+)\]$")

#: A bar shorter than this fraction of its panel's longest is drawn with a marker at 0 (a bar of
#: zero height is invisible, and "no effect" is an answer worth seeing).
NEAR_ZERO = 1e-3


def _near_zero(vals: list[float]) -> list[bool]:
    """Which values are ~0 against the largest magnitude of their panel (all of them when it is 0)."""
    finite = [abs(v) for v in vals if math.isfinite(v)]
    scale = max(finite, default=0.0)
    return [math.isfinite(v) and abs(v) <= NEAR_ZERO * scale for v in vals]


def _label(v: float) -> str:
    return "undefined" if not math.isfinite(v) else f"{v:.3g}"


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
        bars = ax.bar(beads, vals, color=colors, width=0.8)
        ax.axhline(0.0, color="0.3", lw=0.6)
        # every bar's value printed at its end; ~0 ones get a visible marker on the zero line
        ax.bar_label(bars, labels=[_label(v) for v in vals], fontsize=5, rotation=90, padding=5)
        zero = [b for b, z in zip(beads, _near_zero(vals)) if z]
        if zero:
            ax.plot(zero, [0.0] * len(zero), "D", mfc="white", mec="0.2", ms=4, ls="none", clip_on=False,
                    label=f"~0 (below {NEAR_ZERO:g} of the largest)")
            ax.legend(fontsize=6, loc="best")
        top = max(range(len(vals)), key=lambda k: abs(vals[k]))
        # beyond the printed value of that bar
        ax.annotate(f"bead {beads[top]}", (beads[top], vals[top]), textcoords="offset points",
                    xytext=(0, 32 if vals[top] > 0 else -40), ha="center", fontsize=7)
        ax.use_sticky_edges = False
        ax.margins(y=0.65)  # room for the labels inside the frame
        ax.set_xlabel("bead")
        ax.set_ylabel(f"derivative [{sens.unit}/{unit}]")
        ax.set_title(f"by {name} (one bar per bead)", fontsize=8)
    if others:
        ax = axes[-1]
        names = list(others)
        raw = [others[n] for n in names]
        vals = [v if math.isfinite(v) else 0.0 for v in raw]  # an undefined elasticity: no bar, said in words
        bars = ax.barh(range(len(names)), vals, color=["#d62728" if v > 0 else "#1f77b4" for v in vals])
        ax.bar_label(bars, labels=[_label(v) for v in raw], fontsize=6, padding=5)
        ax.set_yticks(range(len(names)), names)
        ax.axvline(0.0, color="0.3", lw=0.6)
        zero = [i for i, z in enumerate(_near_zero(raw)) if z]
        if zero:
            ax.plot([0.0] * len(zero), zero, "D", mfc="white", mec="0.2", ms=4, ls="none", clip_on=False,
                    label=f"~0 (below {NEAR_ZERO:g} of the largest)")
            ax.legend(fontsize=6, loc="best")
        ax.use_sticky_edges = False
        ax.margins(x=0.2)  # room for the printed values and the zero markers
        ax.invert_yaxis()
        ax.set_xlabel("elasticity (x / J) dJ/dx  [1]")
    fig.suptitle(title or f"sensitivities of J = {sens.objective} = {sens.value:.5g} {sens.unit}", fontsize=9)
    if out is not None:
        from .common import save_figure

        save_figure(fig, out)
    return fig
