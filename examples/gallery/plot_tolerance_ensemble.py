"""
A tolerance ensemble
====================

Real beads are not exactly the size of the drawing. A sweep with ``tolerances`` and no swept
parameter runs many copies of one chain, each with its own random diameter deviations (here
0.5 % standard deviation) and perpendicular offsets (0.1 mm), seeded so every member can be
drawn again. We look at the spread of the wall pulse of a short tapered chain.
"""

import tempfile

import matplotlib.pyplot as plt

import hertzchain as hc

sweep = {
    "base": {
        "chain": {"uniform": {"n": 8, "diameter_mm": 26.0}, "taper": {"n": 6, "q": 0.056}},
        "striker": {"diameter_mm": 8.0, "velocity": 0.2},
        "run": {"duration": 2.0e-3, "sample_interval": 1e-7},
    },
    "sweep": {"mode": "random", "n": 24, "chunk_size": 12,
              "tolerances": {"diameter_rel": 0.005, "offset_mm": 0.1, "seed": 7}},
}
with tempfile.TemporaryDirectory() as out:
    result = hc.run_sweep(sweep, out)
    metrics = result.metrics

print(metrics[["F_m", "T", "tau"]].describe().loc[["mean", "std", "min", "max"]])

fig, axes = plt.subplots(1, 2, figsize=(8, 3.5))
axes[0].hist(metrics["F_m"], bins=10, color="C0")
axes[0].set_xlabel("peak wall force F$_m$ [N]")
axes[0].set_ylabel("members")
axes[1].plot(metrics["T"] * 1e3, metrics["tau"] * 1e6, "o", color="C1")
axes[1].set_xlabel("time of flight T [ms]")
axes[1].set_ylabel(r"duration $\tau$ [$\mu$s]")
fig.suptitle("24 chains within manufacturing tolerances")
fig.tight_layout()
