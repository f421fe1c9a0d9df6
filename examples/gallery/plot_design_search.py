"""
Design: the exponential taper that transmits the least force
============================================================

``examples/design_taper.toml`` asks which chain of a uniform block of 26 mm beads followed by an
exponential taper (phi_(n+1) = (1 - q) phi_n, the paper's shape), no longer than the paper's chain 1
(660.65 mm) and with no bead smaller than its smallest (11 mm), gives the least peak force on
the wall. :func:`hertzchain.run_design` searches the number of uniform beads, the number of
tapered beads and q (CMA-ES on the batched engine); here with a budget of 200 runs.
"""

import tempfile
import tomllib
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import hertzchain as hc

# run from the repository root, or from examples/gallery as the documentation build does
examples = next(p for p in (Path("examples"), Path("..")) if (p / "lab_chain1.toml").exists())
data = tomllib.loads((examples / "design_taper.toml").read_text())
data["design"]["budget"] = 200
with tempfile.TemporaryDirectory() as out:
    result = hc.run_design(hc.parse_design(data), out)
best = result.best
print("best:", best["variables"], f"peak wall force {best['objective']:.3f} N")

# Every candidate's peak wall force (feasible ones), and the best so far, against engine runs.
runs = np.cumsum([r["engine_runs"] for r in result.history])
value = np.array([r["peak_wall_force"] if r["feasible"] else np.nan for r in result.history])
chain1 = hc.simulate(hc.Model(hc.paper_chain("chain1"), hc.Striker(8e-3, 0.2)), 3e-3, hc.Probes(sample_interval=1e-6))
fig, (ax, bx) = plt.subplots(1, 2, figsize=(9, 3.6))
ax.plot(runs, value, ".", color="0.6", ms=4, label="candidates (feasible)")
ax.plot(runs, np.fmin.accumulate(np.nan_to_num(value, nan=np.inf)), color="C3", label="best so far")
ax.axhline(chain1.attrs["peak_wall_force"], color="C0", ls="--", label="the paper's chain 1")
ax.set_xlabel("engine runs")
ax.set_ylabel("peak wall force [N]")
ax.legend(fontsize=8)
designed = hc.build_model(hc.parse_config(best["config"])).chain
bx.plot(np.arange(1, 31), hc.paper_chain("chain1").diameters * 1e3, "o-", ms=3, label="chain 1 (Table I)")
bx.plot(np.arange(1, designed.n_beads + 1), designed.diameters * 1e3, "s-", ms=3, color="C3", label="designed")
bx.axhline(11, color="0.5", lw=0.8, ls=":")
bx.set_xlabel("bead n")
bx.set_ylabel("diameter [mm]")
bx.legend(fontsize=8)
fig.tight_layout()
