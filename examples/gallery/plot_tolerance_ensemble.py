"""
A tolerance ensemble
====================

Real beads are not exactly the size of the drawing. A sweep with ``tolerances`` and no swept
parameter runs many copies of one chain, each with its own random diameter deviations (here
0.5 % standard deviation) and perpendicular offsets (0.1 mm), seeded so every member can be
drawn again. With ``store = "metrics"`` a member keeps only its metrics (a few hundred bytes on
disk), so the same file scales to a million members. We look at the spread of the wall pulse of
a short tapered chain: the histograms of ``hertzchain plot DIR`` (mean, standard deviation and
quantiles written on each), then the corner plot of ``hertzchain plot DIR --kind corner``.
"""

import tempfile
from pathlib import Path

import hertzchain as hc
from hertzchain.viz.ensemble import corner_figure, histogram_figure

sweep = {
    "base": {
        "chain": {"uniform": {"n": 8, "diameter_mm": 26.0}, "taper": {"n": 6, "q": 0.056}},
        "striker": {"diameter_mm": 8.0, "velocity": 0.2},
        "run": {"duration": 2.0e-3, "sample_interval": 1e-7},
    },
    "sweep": {"mode": "random", "n": 48, "chunk_size": 24, "store": "metrics",
              "tolerances": {"diameter_rel": 0.005, "offset_mm": 0.1, "seed": 7}},
}
with tempfile.TemporaryDirectory() as out:
    result = hc.run_sweep(sweep, out)
    metrics = result.metrics
    hc.plot_ensemble(out, Path(out) / "ensemble.png")  # what `hertzchain plot DIR` writes

print(metrics[["F_m", "T", "tau"]].describe().loc[["mean", "std", "min", "max"]])
histograms = histogram_figure(metrics, ["F_m", "T", "tau"])
corner = corner_figure(metrics, ["F_m", "T", "tau"])
