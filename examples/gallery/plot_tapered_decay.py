"""
Pulse decay in a tapered chain
==============================

The paper's chain 1 (Table I): 16 beads of 26 mm, then 14 beads shrinking by q = 5.6 % each.
The peak force of the pulse falls bead by bead in the tapered part. We compare the simulated
peak force of every contact with the ballistic approximation (paper eq. 7), for elastic contacts
and for the paper's dissipation as the reproduction models it (a dashpot following each contact
pair, calibrated to eps = 0.985).

Both fall faster than eq. 7 predicts: the pulse does not fully re-form a solitary wave at every
bead, and part of its momentum stays in a growing tail (see the user guide's "Reproducing the
paper"). Note also the first beads: the pulse leaving
the light striker needs about ten beads to settle.
"""

import matplotlib.pyplot as plt
import numpy as np

import hertzchain as hc

chain = hc.paper_chain("chain1")
striker = hc.Striker(diameter=8e-3, velocity=0.2)
laws = {1.0: hc.Elastic(), 0.985: hc.calibrate_law("dashpot_scaled", 0.985, chain=chain, striker=striker)}

fig, ax = plt.subplots(figsize=(7, 4))
for (eps, law), color in zip(laws.items(), ("C0", "C3")):
    # No wall: every contact's largest force is the front pulse's, not a reflection.
    model = hc.Model(chain, striker, hc.Wall("none"), law)
    ds = hc.simulate(model, duration=3e-3)
    beads = np.arange(1, chain.n_beads)                    # contact n: right contact of bead n
    peak = ds.max_contact_force.sel(contact_all=beads).values
    # Eq. 7 bead by bead with the Table I diameters, anchored at the last uniform bead (16).
    theory = hc.predict_chain(chain.diameters, "AISI52100", 1.0, eps=eps).peak_force
    theory = theory / theory[15] * peak[15]
    ax.plot(beads, peak, "o", color=color, ms=4, label=f"simulated, eps = {eps}")
    ax.plot(beads[15:], theory[15:29], "-", color=color, label=f"eq. 7, eps = {eps}")
ax.axvline(16.5, color="0.6", lw=0.8)
ax.text(17, ax.get_ylim()[1] * 0.95, "tapered part", va="top")
ax.set_xlabel("bead n (contact between bead n and n + 1)")
ax.set_ylabel("peak contact force [N]")
ax.set_title("Chain 1: peak force along the chain")
ax.legend()
fig.tight_layout()
