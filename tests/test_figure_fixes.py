"""Figures that say what they show: fig5_laws' legend clear of the data and its q = 0 duration
curve labelled for what it is; sensitivity bars with their values printed and ~0 ones visible."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hertzchain import theory
from hertzchain.paper.law_figure import fig_laws


def _numbers() -> dict:
    """Law numbers shaped like summary["fidelity"]["laws"]: F_m and tau falling along each chain."""
    out = {}
    for j, law in enumerate(("elastic", "viscoelastic", "viscoelastic_scaled", "dashpot_scaled")):
        row = {}
        for chain in ("chain1", "chain2"):
            beads = np.arange(16, len(theory.PAPER_CHAINS[chain]) + 1)
            x = (beads - 16) / (beads[-1] - 16)
            row[chain] = {"beads": beads.tolist(), "peak_force": (8.9 * (1 - (0.35 + 0.05 * j) * x)).tolist(),
                          "duration": (180e-6 * (1 - 0.6 * x)).tolist()}
        out[law] = row
    return out


def test_fig5_laws_legend_covers_no_data_marker():
    fig = fig_laws(_numbers(), 0.985)
    fig.canvas.draw()
    boxes = [leg.get_window_extent() for leg in fig.legends]
    boxes += [ax.get_legend().get_window_extent() for ax in fig.axes if ax.get_legend() is not None]
    assert boxes
    markers = 0
    for ax in fig.axes:
        for line in ax.get_lines():
            if line.get_marker() in (None, "None", "", " "):
                continue
            xy = ax.transData.transform(np.column_stack([line.get_xdata(), line.get_ydata()]))
            markers += len(xy)
            for box in boxes:
                assert not any(box.contains(x, y) for x, y in xy), line.get_label()
    assert markers == 4 * 2 * (15 + 13)  # every law's points, F_m and tau of both chains, were checked


def test_fig5_laws_q0_duration_curve_is_what_its_label_says():
    """The dashed duration curve is tau_n = (phi_n/2) sqrt(10)/v_n with the chain's real phi_n and the
    speeds of eq. 8 with q = 0 (not a uniform chain, whose ratio would not fall with phi_n): the
    legend says exactly that."""
    eps = 0.985
    fig = fig_laws(_numbers(), eps)
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert any("eq. 8: the speeds of q = 0 with the real diameters" in t for t in labels)
    ax = fig.axes[2]  # chain 1, duration
    dashed = [ln for ln in ax.get_lines() if ln.get_linestyle() == "--"]
    assert len(dashed) == 1
    beads = np.arange(16, 31)
    phi = np.asarray(theory.PAPER_CHAINS["chain1"], float)[beads - 1]
    expected = phi / phi[0] / theory.ballistic_ratios(0.0, eps).speed ** (beads - 16)
    assert dashed[0].get_ydata() == pytest.approx(expected, rel=1e-12)
    assert dashed[0].get_ydata()[-1] < 0.5  # it falls with the diameters, as no uniform chain's would


def _sensitivity():
    from hertzchain.gradients.api import Sensitivity

    g = {f"chain.diameters_mm[{i}]": v for i, v in enumerate([-0.12, 0.0, 1e-7, 0.31, -0.02])}
    g.update({"striker.velocity": 30.0, "striker.diameter_mm": 1e-9, "wall.damping": 0.4})
    values = {k: 26.0 for k in g} | {"striker.velocity": 0.2, "striker.diameter_mm": 8.0, "wall.damping": 0.0}
    units = {k: "mm" for k in g} | {"striker.velocity": "m/s", "wall.damping": "N s/m"}
    return Sensitivity("peak_wall_force", "N", 5.0, g, values, units, "adjoint", 1000)


def test_sensitivity_bars_print_their_values_and_mark_zero():
    from hertzchain.viz.sensitivity import plot_sensitivity

    s = _sensitivity()
    fig = plot_sensitivity(s)
    beads, others = fig.axes[0], fig.axes[1]
    texts = [t.get_text() for t in beads.texts]
    assert texts[:5] == ["-0.12", "0", "1e-07", "0.31", "-0.02"] and "bead 4" in texts
    # beads 2 and 3 (0 and 1e-7 against 0.31) are marked on the zero line
    (marks,) = [ln for ln in beads.get_lines() if ln.get_marker() == "D"]
    assert list(marks.get_xdata()) == [2, 3] and list(marks.get_ydata()) == [0.0, 0.0]
    rel = s.relative()
    texts = [t.get_text() for t in others.texts]
    assert texts == [f"{rel['striker.velocity']:.3g}", f"{rel['striker.diameter_mm']:.3g}", "undefined"]
    assert math.isnan(rel["wall.damping"])  # a zero variable: no elasticity, said in words, not drawn as 0
    (marks,) = [ln for ln in others.get_lines() if ln.get_marker() == "D"]
    assert list(marks.get_ydata()) == [1]  # striker.diameter_mm's 1.6e-9 is ~0
    # the marker is visible: inside the axes, not on its edge
    fig.canvas.draw()
    x, y = others.transData.transform((0.0, 1))
    box = others.get_window_extent()
    assert box.x0 + 5 < x < box.x1 - 5 and box.y0 < y < box.y1
