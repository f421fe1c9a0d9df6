"""
A vertical column under gravity
===============================

Stand the chain on its wall, bead 1 on top (``Model(gravity=9.81)``, config ``[chain]
gravity``, or ``tilt_deg`` for an inclined track): every contact carries the weight above it,
and the run starts from that static state, each overlap (W_j / kappa_j)^(2/3). The column is then
a chain under a gradient of precompression (the setting of Sen's and Hong's vertical columns),
and a pulse speeds up as it goes down. Here 30 beads of 26 mm are hit by the 8 mm striker at
0.05 m/s, horizontal and vertical.
"""

import matplotlib.pyplot as plt
import numpy as np

import hertzchain as hc

chain = hc.Chain.uniform(30, 26e-3)
striker = hc.Striker(diameter=8e-3, velocity=0.05)
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(9, 4))
for g, label in ((0.0, "horizontal"), (9.81, "vertical, g = 9.81 m/s^2")):
    model = hc.Model(chain, striker, gravity=g)
    ds = hc.simulate(model, 5e-3, hc.Probes(sample_interval=1e-6))
    static = model.system().static_forces()
    dynamic = ds.contact_force - static  # the impact's part of every contact force
    arrival = dynamic.time.values[np.argmax(dynamic.values > 0.5 * dynamic.max("time").values, axis=0)]
    ax1.plot(ds.contact.values[1:], arrival[1:] * 1e3, label=label)
    if g:
        ax2.plot(ds.contact.values, static, "o-", ms=3)
        weight = g * np.cumsum(np.concatenate([[striker.mass], chain.masses]))
        print(f"static force of the bottom contact {static[-1]:.3f} N = weight above it {weight[-1]:.3f} N")
ax1.set_xlabel("contact")
ax1.set_ylabel("pulse arrival [ms]")
ax1.legend()
ax2.set_xlabel("contact")
ax2.set_ylabel("static contact force [N]")
ax2.set_title("weight above each contact")
fig.tight_layout()
