"""
Design: a Pareto front of two objectives
========================================

Two objectives at once give a front of non-dominated chains instead of one best chain (NSGA-II
from ``pymoo``, the ``[design]`` extra): here the peak wall force and the momentum the front
pulse delivers to the wall (Q_F of its cos^6 fit, paper Sec. III), over the same exponentially
tapered chains as the single-objective search (``examples/design_taper.toml``), 400 runs.
"""

import tempfile
import tomllib
from pathlib import Path

import matplotlib.pyplot as plt

import hertzchain as hc

# run from the repository root, or from examples/gallery as the documentation build does
examples = next(p for p in (Path("examples"), Path("..")) if (p / "lab_chain1.toml").exists())
data = tomllib.loads((examples / "design_taper.toml").read_text())
data["design"].update(objective=["peak_wall_force", "front_momentum_at_wall"], budget=400)
with tempfile.TemporaryDirectory() as out:
    result = hc.run_design(hc.parse_design(data), out)
feasible = [r for r in result.history if r["feasible"]]
front = sorted(result.pareto, key=lambda r: r["peak_wall_force"])
for r in front:
    print(f"n0 = {r['chain.uniform.n']:2d}, taper {r['chain.taper.n']:2d} beads, q = {r['chain.taper.q']:.3f}: "
          f"F = {r['peak_wall_force']:.3f} N, Q_F = {r['front_momentum_at_wall'] * 1e3:.4f} mN s")

fig, ax = plt.subplots(figsize=(6.5, 4))
ax.plot([r["peak_wall_force"] for r in feasible], [r["front_momentum_at_wall"] * 1e3 for r in feasible], ".",
        color="0.65", ms=4, label=f"feasible candidates ({len(feasible)})")
ax.plot([r["peak_wall_force"] for r in front], [r["front_momentum_at_wall"] * 1e3 for r in front], "o-",
        color="C3", label=f"Pareto front ({len(front)})")
ax.set_xlabel("peak wall force [N]")
ax.set_ylabel("front momentum at the wall $Q_F$ [mN s]")
ax.legend()
fig.tight_layout()
