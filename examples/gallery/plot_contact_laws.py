"""
Contact laws: a power law, Hunt-Crossley and a law of your own
==============================================================

The registry (:mod:`hertzchain.laws`) declares every contact law once; the engines are generated
from the declaration. Left: the wall force of one 20-bead chain with Hertz contacts (paper eq. 1),
a stiffer-than-Hertz power law (n = 2), Hunt-Crossley contacts with a restitution of 0.9, and
Tsuji's damped Hertz contact, a user's law registered from ``examples/laws/tsuji.py``. Right: the
two-body restitution Hunt-Crossley gives back against the e it was asked for, at three speeds
(Flores et al.'s closed form; the law is scale-free, so the speeds fall on one curve).
"""

import runpy
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import hertzchain as hc

here = Path(__file__).resolve().parent if "__file__" in globals() else Path("examples/gallery")
Tsuji = runpy.run_path(str(here.parent / "laws" / "tsuji.py"))["Tsuji"]

chain = hc.Chain.uniform(20, 10e-3)
laws = {"Hertz (elastic)": hc.Elastic(), "power law, n = 2": hc.PowerLaw(2.0, 1e13),
        "Hunt-Crossley, e = 0.9": hc.HuntCrossley(0.9), "Tsuji (user law), eta = 300": Tsuji(300.0)}
fig, (ax, bx) = plt.subplots(1, 2, figsize=(10, 4))
for label, law in laws.items():
    ds = hc.simulate(hc.Model(chain, hc.Striker(8e-3, 0.2), law=law), 6e-4, hc.Probes(sample_interval=2e-7))
    ax.plot(ds.time * 1e3, ds.wall_force, label=label)
ax.set(xlabel="time [ms]", ylabel="wall force [N]", title="20 beads of 10 mm, striker at 0.2 m/s")
ax.legend(fontsize=8)

asked = np.array([0.3, 0.5, 0.7, 0.9, 0.99])
for v, marker in ((0.02, "o"), (0.3, "s"), (4.0, "^")):
    got = [hc.restitution(v, hc.HuntCrossley(e), 8e-3, "AISI52100", 26e-3) for e in asked]
    bx.plot(asked, got, marker, fillstyle="none", label=f"{v:g} m/s")
bx.plot([0.25, 1], [0.25, 1], "k:", lw=0.8, label="e given")
bx.set(xlabel="restitution given, e", ylabel="restitution of the impact",
       title="Hunt-Crossley: 8 mm on 26 mm steel")
bx.legend(fontsize=8)
fig.tight_layout()
plt.show()
