"""Figures 1-6 of the paper and the reproduction report (hertzchain.paper.figures / .report).

Fast: the studies are built once (elastic contacts, 3.5 ms records) and every figure is drawn
once into a temporary folder; the tests check the files, the panels and their labels, and that
the report holds the comparison table and embeds every figure. The physics of the summary is
tested elsewhere.
"""

from __future__ import annotations

import base64
import html
import re
import struct

import numpy as np
import pytest

from hertzchain.paper import figures as figs
from hertzchain.paper import protocol
from hertzchain.paper.report import comparison_rows, figure_notes, write_report
from hertzchain.paper.values import PAPER

from figure_checks import text_overlaps, uncovered

#: name -> (number of panels, figure width [in]) expected for each figure.
EXPECTED = {"fig1": (8, 7.0), "fig2": (8, 7.0), "fig3": (6, 3.4), "fig4": (1, 3.4), "fig5": (8, 7.0),
            "fig6": (6, 7.0)}


@pytest.fixture(scope="module")
def settings():
    return protocol.Settings(elastic=True, duration=3.5e-3)


@pytest.fixture(scope="module")
def data(settings):
    """The runs behind the figures, made once for the module."""
    return {
        "chain1": protocol.run_chain_study("chain1", settings),
        "chain2": protocol.run_chain_study("chain2", settings),
        "misalignment": protocol.run_misalignment(settings),
        "substitutions": protocol.run_substitutions(settings),
    }


@pytest.fixture(scope="module")
def drawn(data, settings, tmp_path_factory):
    """{name: (Figure, png path)} for Figs. 1-6, saved once into a temporary folder."""
    out = tmp_path_factory.mktemp("figures")
    s1, s2 = data["chain1"], data["chain2"]
    made = {
        "fig1": figs.fig1(s1, settings),
        "fig2": figs.fig2(s2, settings),
        "fig3": figs.fig3(data["misalignment"], data["substitutions"], settings),
        "fig4": figs.fig4(s1, s2),
        "fig5": figs.fig5(s1, s2, settings),
        "fig6": figs.fig6(s1, s2, settings),
    }
    return {name: (fig, figs.save_figure(fig, out, name)) for name, fig in made.items()}


@pytest.fixture(scope="module")
def summary(data, settings):
    """A summary with the structure reproduce.py writes (speed check and wall ratio run for real)."""
    def chain(study):
        return {"q": study.q, "q_std": study.q_std, "Q_theory": study.Q_theory, "Q_fit": study.Q_fit,
                "Q_fit_err": study.Q_fit_err, "beads": [int(b) for b in study.truncations],
                **{key: [float(x) for x in study.series(key)] for key in
                   ("peak_force", "duration", "time_of_flight", "front_momentum", "tail_momentum")}}

    ratio = protocol.run_wall_chain_ratio(settings)
    speed = protocol.run_speed_check(settings)
    s1, s2 = data["chain1"], data["chain2"]
    return {
        "chain1": chain(s1), "chain2": chain(s2),
        "eps": s1.eps_measured, "eps_err": s1.eps_measured_err,
        "wall_to_chain_force_ratio": ratio["force_ratio"], "wall_to_chain_duration_ratio": ratio["duration_ratio"],
        "yield_force": 473.8, "yield_overlap": 11.6e-6,
        "speed_check": {k: speed[k] for k in ("velocities", "max_peak_norm_deviation", "max_duration_norm_deviation")},
        "paper": {"chain1": dict(PAPER["chain1"]), "chain2": dict(PAPER["chain2"]), "eps": PAPER["eps"],
                  "wall_to_chain_force_ratio": 1.94, "wall_to_chain_duration_ratio": 1.09,
                  "yield_force": 470.0, "yield_overlap": 11e-6},
        "settings": settings.describe(), "timing": {"simulation_s": 1.0},
        "figures": figs.figure_summary(s1, s2, data["misalignment"], data["substitutions"], settings),
    }


def _png_size(data: bytes) -> tuple[int, int]:
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    return struct.unpack(">II", data[16:24])


def _panels(fig):
    return [ax for ax in fig.axes if ax.get_label() != "<colorbar>"]


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_figure_files_and_panels(drawn, name):
    fig, png = drawn[name]
    n_panels, width = EXPECTED[name]
    # files: a 200-dpi PNG of the figure's size and a vector PDF beside it
    data = png.read_bytes()
    w_px, h_px = _png_size(data)
    assert len(data) > 20_000
    assert abs(w_px - 200 * fig.get_figwidth()) <= 2 and abs(h_px - 200 * fig.get_figheight()) <= 2
    pdf = png.with_suffix(".pdf")
    assert pdf.read_bytes()[:5] == b"%PDF-" and pdf.stat().st_size > 10_000
    # layout: the paper's panels at its column widths
    assert fig.get_figwidth() == pytest.approx(width)
    panels = _panels(fig)
    assert len(panels) == n_panels
    for ax in panels:
        assert ax.get_ylabel().strip(), f"{name}: a panel has no y label"
        assert ax.has_data()
        # an x label on the panel or on a panel sharing its x axis (columns label the bottom row)
        siblings = ax.get_shared_x_axes().get_siblings(ax)
        assert any(a.get_xlabel().strip() for a in siblings), f"{name}: a panel has no x label"
        assert "[" in ax.get_ylabel() or "/" in ax.get_ylabel(), "y label without unit or normalisation"


def test_figure_text_uses_paper_symbols(drawn):
    """Axes carry the paper's symbols and units (F [N], t - T [ms], phi_n [mm], tau [us], ...)."""
    labels = {name: " ".join(ax.get_xlabel() + " " + ax.get_ylabel() for ax in _panels(fig))
              for name, (fig, _) in drawn.items()}
    assert "F [N]" in labels["fig1"] and "t - T [ms]" in labels["fig1"] and "f [kHz]" in labels["fig1"]
    assert "F [N]" in labels["fig3"] and "t - T [ms]" in labels["fig3"]
    assert "F / $F_m$" in labels["fig4"] and "(t - T) / $\\tau$" in labels["fig4"]
    for token in ("$\\phi_n$ [mm]", "$F_m$ [N]", "$\\tau$ [$\\mu$s]", "[mN s]", "bead n"):
        assert token in labels["fig5"]
    for token in ("T [ms]", "v [m/s]", "[$\\mu$s]"):
        assert token in labels["fig6"]


def test_fig3_legends_give_offsets_in_mm(drawn):
    fig, _ = drawn["fig3"]
    a, _, b, _, c, _ = _panels(fig)
    for ax in (a, b):
        texts = [t.get_text() for t in ax.get_legend().get_texts()]
        assert len(texts) == 3 and all(re.match(r"e = \d+\.\d\d mm", t) for t in texts)
    texts = [t.get_text() for t in c.get_legend().get_texts()]
    assert texts[0] == "reference" and any("+1" in t for t in texts) and any("-1" in t for t in texts)


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_figures_checked_by_data(drawn, name):
    """No text box or legend covers a drawn data point; every axis range covers its curves."""
    fig, _ = drawn[name]
    assert text_overlaps(fig) == []
    assert uncovered(fig) == []


def test_fig1h_spectrum_axis_is_used_and_centroids_apart(drawn, data):
    for name, study in (("fig1", data["chain1"]), ("fig2", data["chain2"])):
        fig, _ = drawn[name]
        ax = _panels(fig)[7]
        renderer = fig.canvas.get_renderer()
        fig.draw(renderer)
        # the outgoing spectrum reaches the bottom (1e-8) in the right part of the frequency axis
        out = [l for l in ax.get_lines() if l.get_label().startswith("out")][0]
        f, p = out.get_data()
        last = f[p >= 1e-8][-1]
        lo, hi = ax.get_xlim()
        assert 0.6 < np.log(last / lo) / np.log(hi / lo) <= 1.0
        # the two centroid lines are at least 5 points apart on the page
        spec = figs.figure_summary(data["chain1"], data["chain2"])["spectra"][study.name]
        xs = ax.transData.transform([[spec["centroid_in_hz"] * 1e-3, 1.0], [spec["centroid_out_hz"] * 1e-3, 1.0]])
        assert abs(xs[1, 0] - xs[0, 0]) > 5 * fig.dpi / 72


def test_fig3_shows_the_misalignment_difference(drawn, data):
    """(a'): F(10 % offset) - F(aligned) on its own scale, sample by sample."""
    from hertzchain import analysis

    fig, _ = drawn["fig3"]
    diff = _panels(fig)[1]
    ref, big = data["misalignment"][(22, 0.0)], data["misalignment"][(22, 0.1)]
    t = ref.time.values
    x = (t - analysis.fit_pulse(t, ref.wall_force.values).time_of_flight) * 1e3
    sel = (x >= figs.PULSE_WINDOW_MS[0]) & (x <= figs.PULSE_WINDOW_MS[1])
    line = [l for l in diff.get_lines() if len(l.get_xdata()) > 2][-1]
    assert np.allclose(line.get_xdata(), x[sel])
    assert np.allclose(line.get_ydata(), (big.wall_force.values - ref.wall_force.values)[sel] * 1e3)
    lo, hi = diff.get_ylim()
    y = line.get_ydata()
    # its own scale: a few times the largest difference, far below the force scale of (a)
    assert lo <= y.min() and y.max() <= hi and (hi - lo) < 4 * np.ptp(y)


def test_fig4_curves_peak_at_one(drawn):
    fig, _ = drawn["fig4"]
    ax = _panels(fig)[0]
    curves = [l.get_ydata() for l in ax.get_lines() if len(l.get_ydata()) > 100]
    assert len(curves) == 16  # 15 pulses and cos^6
    for y in curves:
        assert abs(np.max(y) - 1.0) < 2e-3


def test_fig3_has_no_text_between_panels_and_y_ranges_fit_the_peaks(drawn):
    """The changes of the fits are the difference panels' keys (no text block between panels),
    and each force panel's y range is the data's (a 2.6 N peak is not drawn on a 4.4 N axis)."""
    fig, _ = drawn["fig3"]
    panels = _panels(fig)
    assert not fig.texts
    for ax in panels:
        assert "\n" not in ax.get_title()  # one line: the panel's subject, nothing else
    for force, diff in zip(panels[0::2], panels[1::2]):
        peak = max(np.max(line.get_ydata()) for line in force.get_lines())
        assert force.get_ylim()[1] <= 1.15 * peak
        keys = [t.get_text() for t in diff.get_legend().get_texts()]
        assert keys and all("$\\Delta F_m$" in k and "$\\Delta T$" in k for k in keys)


def test_fig6_time_of_flight_axis_starts_at_the_impact(drawn):
    fig, _ = drawn["fig6"]
    for ax in _panels(fig)[:2]:  # (a1), (a2): T [ms]
        assert ax.get_ylabel() == "T [ms]" and ax.get_ylim()[0] == 0.0


def test_fig6_legend_quotes_q(drawn, data):
    fig, _ = drawn["fig6"]
    legend = " ".join(t.get_text() for ax in _panels(fig) if ax.get_legend()
                      for t in ax.get_legend().get_texts())
    assert f"{data['chain1'].Q_fit:.3f}" in legend and f"{data['chain2'].Q_theory:.3f}" in legend


def test_figure_summary_numbers(summary):
    f = summary["figures"]
    for chain in ("chain1", "chain2"):
        spec = f["spectra"][chain]
        assert spec["centroid_in_hz"] > 0 and spec["bandwidth_out_hz"] > 0
    assert 0 <= f["collapse_rms"] < 1 and f["collapse_pulses"] == 15
    assert len(f["misalignment"]) == 6 and set(f["substitutions"]) == {"reference", "dq/q = +1", "dq/q = -1"}


def test_report_md_and_html(drawn, summary, settings, tmp_path):
    paths = {name: png for name, (_, png) in drawn.items()}
    out = write_report(tmp_path, summary, paths, settings.describe())
    md, page = out["md"].read_text(encoding="utf-8"), out["html"].read_text(encoding="utf-8")
    # the comparison table
    for row in ("tapering factor q1", "standard deviation of q1", "tapering factor q2", "standard deviation of q2",
                "Q1 (fit", "Q2 (fit", "$Q_1^{th}$", "$Q_2^{th}$", "$\\varepsilon$ measured back",
                "wall/chain peak-force ratio", "wall/chain duration ratio", "yield force", "yield overlap"):
        assert row in md, row
        parts = re.split(r"\$([^$]+)\$", row)  # text, formula, text...: formulas drawn as SVG in the page
        for i, part in enumerate(parts):
            assert (f'data-tex="{html.escape(part)}"' if i % 2 else html.escape(part)) in page, row
    assert "| quantity | simulated | paper | relative difference | verdict |" in md
    assert "the paper's error bar 1.025 ± 0.016" in md
    assert re.search(r"\$Q_\{fit\}\$ = 1\.\d{3} ± 0\.\d{3} lies (inside|outside) the paper's error bar", md)
    # maths as maths: no ASCII formula left in the notes; drawn as inline SVG in the page
    assert 'data-tex="F_m"><svg' in page and "$F_m$" in md and 'data-tex="\\tau"' in page
    assert "\\(" not in page and "$" not in re.sub(r"<svg.*?</svg>", "", page, flags=re.S)
    notes = md.split("## Parameters")[0]
    for ascii_formula in (r"F_m\^\(n\+1\)", r"Q\^\(n-n'\)", r" tau ", r"T\(eps", r"(?<!\\)cos\^6"):
        assert not re.search(ascii_formula, notes), ascii_formula
    # the two-speed check and the run's parameters
    assert "do not depend on the striker speed" in md or "DEPEND on the striker speed" in md
    assert "striker_velocity" in md and "0.2 m/s" in md and "sample_interval" in page
    # every figure linked (md) and embedded byte for byte (html), nothing external
    for name, png in paths.items():
        assert re.search(rf'<img src="[^"]*{png.name}"', md)
        notes = figure_notes(summary, settings.describe())[name]
        assert notes[0] and notes[1]
    embedded = re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', page)
    assert len(embedded) == len(paths)
    assert {base64.b64decode(e) for e in embedded} == {p.read_bytes() for p in paths.values()}
    # nothing external, no script at all: the page reads the same offline
    external = re.findall(r'(?:src|href)="((?:https?:)?//[^"]+)"', page)
    assert external == [] and "<link" not in page and "<script" not in page
    # one scale: each figure shown at its size in inches (a one-column figure at 3.4/7 of the page)
    widths = {name: float(w) for name, w in re.findall(r'<h3 id="(fig\d)">.*?style="width: ([\d.]+)%"', page,
                                                      flags=re.S)}
    for name, (fig, _) in drawn.items():
        assert widths[name] == pytest.approx(100 * fig.get_figwidth() / 7.0, abs=0.2)


def test_report_without_optional_keys(tmp_path):
    """A bare summary still gives both documents, with n/a entries instead of errors."""
    out = write_report(tmp_path / "bare", {}, {}, None)
    md = out["md"].read_text(encoding="utf-8")
    assert "n/a" in md and "The two-speed check was not run." in md
    assert out["html"].read_text(encoding="utf-8").startswith("<!DOCTYPE html>")


def test_comparison_rows_verdicts():
    rows = comparison_rows({"chain1": {"Q_fit": 1.021, "Q_fit_err": 0.001}, "chain2": {"Q_fit": 1.20}},
                           {"eps_target": 0.985, "law": "viscoelastic"})
    by_name = {r.quantity.split(" (")[0]: r for r in rows}
    assert by_name["chain 1: Q1"].verdict.startswith("inside the paper's error bar")
    assert by_name["chain 2: Q2"].verdict.startswith("outside the paper's error bar")
    assert np.isclose(by_name["chain 1: Q1"].rel, 1.021 / 1.025 - 1)


def test_save_figure_draws_the_pdf_once_with_the_pngs_layout(data, tmp_path, monkeypatch):
    """The constrained layout is computed for the PNG and kept for the PDF, which is drawn once:
    a leftover layout engine (even the placeholder of "none") makes savefig run a dry-run draw
    on a renderer of its own first, 40 % of the PDF's time."""
    from matplotlib.backends.backend_agg import RendererAgg
    from matplotlib.figure import Figure

    fig = figs.fig4(data["chain1"], data["chain2"])
    draws = []
    real_draw = Figure.draw
    monkeypatch.setattr(Figure, "draw", lambda self, renderer: (draws.append(renderer), real_draw(self, renderer))[1])
    png = figs.save_figure(fig, tmp_path, "fig4")
    assert len([r for r in draws if not isinstance(r, RendererAgg)]) == 1  # the PDF: one draw
    assert fig.get_layout_engine() is None
    positions = [ax.get_position().bounds for ax in fig.axes]
    fig.draw(draws[-2])  # drawing again (the PNG's renderer) moves nothing: the layout is fixed
    assert [ax.get_position().bounds for ax in fig.axes] == positions
    assert png.with_suffix(".pdf").read_bytes()[:5] == b"%PDF-"


def test_fig3_lateral_has_a_letter_on_every_panel_and_no_text_on_the_curves():
    """Synthetic cos^6 wall pulses (the figure only draws them): a letter (a)..(f) per panel."""
    import xarray as xr

    from hertzchain.paper.fidelity import TRACKS, fig3_lateral

    t = np.linspace(0.0, 3e-3, 3001)

    def pulse(scale: float):
        x = np.clip((t - 2e-3) / 8e-5, -np.pi / 2, np.pi / 2)
        return xr.Dataset({"wall_force": ("time", scale * 2.6 * np.cos(x) ** 6)}, coords={"time": t})

    rigid = {(b, fr): pulse(1 - fr) for b in (22, 28) for fr in (0.0, 0.05, 0.1)}
    lateral = {(v, b, fr): pulse(1 - 2 * fr) for v in TRACKS for b in (22, 28) for fr in (0.05, 0.1)}
    fig = fig3_lateral(rigid, lateral)
    tags = sorted(t.get_text() for ax in fig.axes for t in ax.texts if re.fullmatch(r"\([a-z]\)", t.get_text()))
    assert tags == ["(a)", "(b)", "(c)", "(d)", "(e)", "(f)"]
    assert text_overlaps(fig) == []
