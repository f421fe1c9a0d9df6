"""
Laboratory data: read, compare, fit
===================================

``examples/scope_chain1_wall.csv`` is an oscilloscope record of the wall sensor of the paper's
chain 1 (a simulated 8-bit scope, in the layout a scope exports: time in s, sensor output in V).
We read it in newtons (the sensor's sensitivity, 112.40 mV/N), compare it with a simulation at a
first-guess striker speed of 0.2 m/s (the paper's protocol: cos^6 fits of both pulses, the
simulation shifted onto the scope's clock), then calibrate that speed by least squares on the
trace (:func:`hertzchain.fit_traces`, with the sensor gain and the trigger time free, as the
lab does with ``hertzchain fit``): the fitted model lies on the measured pulse.
"""

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import hertzchain as hc

# run from the repository root, or from examples/gallery as the documentation build does
examples = next(p for p in (Path("examples"), Path("..")) if (p / "lab_chain1.toml").exists())
measured = hc.read_trace(examples / "scope_chain1_wall.csv", sensor="pcb_208a11")   # volts -> newtons
first = hc.run_config(hc.load_config(examples / "lab_chain1.toml"))                  # 0.2 m/s: a first guess
before = hc.compare_traces(measured, first.wall_force)
fit = hc.fit_traces(examples / "lab_chain1.toml", [hc.Trace(measured)], ["striker.velocity", "gain", "time_offset"],
                    max_evaluations=30)
k = fit.names.index("striker.velocity")
print(f"striker velocity {fit.values[k]:.5f} +- {fit.stderr[k]:.5f} m/s "
      f"(first guess 0.2 m/s); before the fit: dF_m = {before.peak_force_diff:+.3f} N, dT = "
      f"{before.time_of_flight_diff * 1e6:+.1f} us (simulated - measured)")

tr = fit.traces[0]
fig, (ax, axr) = plt.subplots(2, 1, sharex=True, figsize=(7, 5), gridspec_kw={"height_ratios": [3, 1]})
ax.plot(before.time * 1e3, before.measured_force, ".", ms=2, color="0.4", label="scope record")
ax.plot(before.time * 1e3, before.simulated_force, color="C0", label="simulated, 0.2 m/s (T aligned)")
ax.plot(np.asarray(tr["time"]) * 1e3, tr["model"], color="C3", label=f"fitted: {fit.values[k]:.4f} m/s")
ax.set_ylabel("wall force [N]")
ax.legend(fontsize=8)
axr.plot(before.time * 1e3, before.residual, color="C0", lw=0.8)
axr.plot(np.asarray(tr["time"]) * 1e3, np.asarray(tr["model"]) - np.asarray(tr["data"]), color="C3", lw=0.8)
axr.set_ylabel("simulated -\nmeasured [N]")
axr.set_xlabel("t [ms]")
fig.tight_layout()
