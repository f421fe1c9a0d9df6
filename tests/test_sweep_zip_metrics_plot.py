"""Sweeps with zipped (coupled) parameters, and `hertzchain plot` on a sweep's metrics.csv."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from hertzchain.cli.main import main
from hertzchain.errors import ConfigError
from hertzchain.viz.metrics import plot_metrics
from hertzchain.sweep import parse_sweep, run_sweep


def _sweep(**sw) -> dict:
    return {"base": {"chain": {"uniform": {"n": 4, "diameter_mm": 26.0}, "taper": {"n": 4, "q": 0.05}},
                     "striker": {"velocity": 0.2}, "run": {"duration": 1.5e-3, "sample_interval": 1e-6}},
            "sweep": {"mode": "grid", "chunk_size": 8, **sw}}


def test_zipped_parameters_walk_together_and_cross_the_others():
    # n and q coupled so that the last bead stays 26 (1 - q)^n = 15 mm; crossed with two speeds.
    ns = [2, 4, 8]
    qs = [1 - (15 / 26) ** (1 / n) for n in ns]
    cfg = parse_sweep(_sweep(parameters={"chain.taper.n": ns, "striker.velocity": [0.1, 0.2], "chain.taper.q": qs},
                             zip=[["chain.taper.n", "chain.taper.q"]]))
    assert cfg.n_members == 6
    pairs = [(m["chain.taper.n"], m["chain.taper.q"]) for m in cfg.members]
    assert set(pairs) == set(zip(ns, qs))
    assert sorted(m["striker.velocity"] for m in cfg.members) == [0.1, 0.1, 0.1, 0.2, 0.2, 0.2]
    for m in cfg.models():
        assert m.chain.diameters[-1] == pytest.approx(15e-3, rel=1e-12)
    rnd = parse_sweep({"base": _sweep()["base"],
                       "sweep": {"mode": "random", "n": 5, "seed": 3, "parameters": {"chain.taper.n": ns,
                                 "chain.taper.q": qs}, "zip": [["chain.taper.n", "chain.taper.q"]]}})
    assert all((m["chain.taper.n"], m["chain.taper.q"]) in set(zip(ns, qs)) for m in rnd.members)


@pytest.mark.parametrize("zipped, field", [
    ([["chain.taper.n", "chain.taper.q"]], "sweep.zip[0]"),          # unequal lengths
    ([["chain.taper.n", "striker.diameter_mm"]], "sweep.zip[0]"),    # not a swept parameter
    ([["chain.taper.n"]], "sweep.zip[0]"),                           # a group of one
])
def test_bad_zip_names_the_group(zipped, field):
    with pytest.raises(ConfigError) as exc:
        parse_sweep(_sweep(parameters={"chain.taper.n": [2, 4, 8], "chain.taper.q": [0.01, 0.02]}, zip=zipped))
    assert exc.value.field == field


def test_plot_metrics_one_and_two_parameters(tmp_path):
    res = run_sweep(_sweep(parameters={"chain.taper.q": [0.0, 0.05, 0.1], "striker.velocity": [0.1, 0.2]}),
                    tmp_path / "sw")
    csv = res.metrics_path
    df = pd.read_csv(csv)
    # Physics on the way: a steeper taper lowers the wall force at each speed (paper Fig. 4 trend).
    for _, g in df.groupby("striker.velocity"):
        assert list(g.sort_values("chain.taper.q")["F_m"]) == sorted(g["F_m"], reverse=True)
    two = plot_metrics(csv, tmp_path / "map.png")
    one = plot_metrics(csv, tmp_path / "line.png", metric="Q_F", x="chain.taper.q", y=None)
    for p in (two, one):
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # A library call leaves the session's Matplotlib backend as it was (its own Agg canvas, no pyplot).
    import matplotlib

    before = matplotlib.get_backend()
    matplotlib.use("svg")
    try:
        plot_metrics(csv, tmp_path / "again.png")
        assert matplotlib.get_backend() == "svg"
    finally:
        matplotlib.use(before)
    assert main(["plot", str(csv), "--out", str(tmp_path / "cli.png"), "--signal", "tau"]) == 0
    assert (tmp_path / "cli.png").stat().st_size > 0
    assert main(["plot", str(csv), "--out", str(tmp_path / "bad.png"), "--signal", "nope"]) == 2
    # Random draws (not a grid) are drawn as points.
    rnd = run_sweep({**_sweep(), "sweep": {"mode": "random", "n": 6, "seed": 1, "chunk_size": 8, "parameters": {
        "chain.taper.q": {"low": 0.0, "high": 0.1}, "striker.velocity": {"low": 0.1, "high": 0.3}}}},
        tmp_path / "rnd")
    assert plot_metrics(rnd.metrics_path, tmp_path / "rnd.png").stat().st_size > 0


def test_sweep_map_tick_labels_do_not_overlap(tmp_path):
    """40 swept values along y (and 12 along x): every k-th cell labelled, no two labels touching."""
    import itertools

    import pandas as pd

    from hertzchain.viz.metrics import MAX_TICK_LABELS, metrics_figure

    qs, vs = np.linspace(0.0, 0.117, 40), np.linspace(0.1, 1.2, 12)
    rows = [{"member": k, "chunk": 0, "chain.taper.q": q, "striker.velocity": v, "dt": 1e-8, "F_m": v * (1 - q)}
            for k, (v, q) in enumerate(itertools.product(vs, qs))]
    csv = tmp_path / "metrics.csv"
    pd.DataFrame(rows).to_csv(csv, index=False)
    fig = metrics_figure(csv, "F_m", x="striker.velocity", y="chain.taper.q")
    ax = fig.axes[0]
    renderer = fig.canvas.get_renderer()
    fig.draw(renderer)
    for axis, most in ((ax.yaxis, MAX_TICK_LABELS["y"]), (ax.xaxis, MAX_TICK_LABELS["x"])):
        labels = [t for t in axis.get_ticklabels() if t.get_text()]
        assert 2 <= len(labels) <= most
        boxes = [t.get_window_extent(renderer) for t in labels]
        assert not any(a.overlaps(b) for a, b in itertools.combinations(boxes, 2))
    # the labels name the cells they sit on: the first and every k-th swept value
    assert float(ax.yaxis.get_ticklabels()[0].get_text()) == 0.0
    assert float(ax.yaxis.get_ticklabels()[1].get_text()) == pytest.approx(qs[3], rel=1e-3)
