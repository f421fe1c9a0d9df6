"""Compact summaries: ``repr`` of chains, models, materials and pulse fits on one readable line
(not every bead's full material), and an HTML table for Jupyter (``_repr_html_``)."""

from __future__ import annotations

import numpy as np
import pytest

import hertzchain as hc


def test_chain_repr_is_one_short_line_with_what_a_reader_checks():
    chain = hc.paper_chain("chain1")
    text = repr(chain)
    assert "\n" not in text and len(text) < 150  # was ~4,900 characters
    assert text.startswith("Chain(30 beads: 26 x 16, 24, 23") and text.endswith("12, 11 mm; AISI52100)")
    assert text.count("AISI52100") == 1
    mixed = hc.Chain.from_diameters([0.02] * 3 + [0.01] * 2, ["AISI52100"] * 3 + ["brass"] * 2)
    assert repr(mixed) == "Chain(5 beads: 20 x 3, 10 x 2 mm; AISI52100 x 3, brass x 2)"
    long = hc.Chain.uniform(1000, 0.01).append_taper(200, 0.002).with_offsets({3: 1e-4})
    assert "1200 beads" in repr(long) and "..." in repr(long) and "offsets up to 0.1 mm" in repr(long)
    assert len(repr(long)) < 200


def test_model_material_and_fit_reprs():
    model = hc.Model(hc.paper_chain("chain2"), hc.Striker(8e-3, 0.2), hc.Wall("flat", "brass"), hc.Viscoelastic(4.5e-6))
    text = repr(model)
    assert len(text) < 250 and "Striker(8 mm AISI52100 at 0.2 m/s)" in text and "Wall('flat', brass)" in text
    assert "Viscoelastic(A=4.5e-06)" in text and "28 beads" in text
    assert repr(hc.get_material("AISI52100")).startswith("Material('AISI52100': rho 7780 kg/m^3, Y 203 GPa")
    t = np.linspace(0.0, 1e-3, 2001)
    fit = hc.fit_pulse(t, 2.5 * np.cos(np.clip((t - 5e-4) / 6e-5, -np.pi / 2, np.pi / 2)) ** 6)
    assert repr(fit).startswith("PulseFit(F_m = 2.5 ± ") and "T = 0.5 ± " in repr(fit) and "tau = 60 ± " in repr(fit)


@pytest.mark.parametrize("make", [
    lambda: hc.paper_chain("chain1"),
    lambda: hc.Model(hc.Chain.uniform(4, 26e-3), hc.Striker(8e-3, 0.1), hc.Wall("none")),
    lambda: hc.fit_pulse(np.linspace(0, 1e-3, 1001), np.cos(np.clip((np.linspace(0, 1e-3, 1001) - 5e-4) / 5e-5,
                                                                    -np.pi / 2, np.pi / 2)) ** 6),
])
def test_html_repr_for_jupyter(make):
    from html.parser import HTMLParser

    page = make()._repr_html_()
    cells: list[str] = []

    class Cells(HTMLParser):
        def handle_data(self, data):
            cells.append(data)

    Cells().feed(page)
    assert page.startswith("<table>") and page.endswith("</table>") and len(cells) >= 6
    assert "AISI52100" in page or "F_m" in page


def test_design_result_repr_summarises_the_search(tmp_path):
    import tomllib
    from pathlib import Path

    data = tomllib.loads((Path(__file__).resolve().parents[1] / "examples" / "design_taper.toml").read_text())
    data["design"]["budget"] = 24
    result = hc.run_design(hc.parse_design(data), tmp_path)
    text = repr(result)
    assert len(text) < 400 and text.startswith("DesignResult(best peak_wall_force = ")  # was ~25,000 characters
    assert f"{result.n_evaluations} engine runs" in text and "chain.taper.q" in text
