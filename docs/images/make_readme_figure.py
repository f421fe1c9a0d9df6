"""Draw docs/images/taper_vs_uniform.png, the picture at the top of the README.

Run from the repository root: ``.venv/bin/python docs/images/make_readme_figure.py``.
Left: the space-time map of the contact forces of the paper's chain 1 (16 uniform 26 mm beads,
then a 5.6 % taper), elastic contacts, 8 mm striker at 0.2 m/s. Right: the force on the wall
for that chain and for 30 uniform 26 mm beads hit the same way.
"""

from pathlib import Path

import numpy as np

import hertzchain as hc
from hertzchain.viz.style import agg_figure

OUT = Path(__file__).with_name("taper_vs_uniform.png")

striker = hc.Striker(8e-3, 0.2)
probes = hc.Probes(sample_interval=2e-6)
taper = hc.simulate(hc.Model(hc.paper_chain("chain1"), striker), 3e-3, probes=probes)
uniform = hc.simulate(hc.Model(hc.Chain.uniform(30, 26e-3), striker), 3e-3, probes=probes)

fig = agg_figure(9.0, 3.4)
left, right = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.1, 1]})
f = taper.contact_force.values  # (time, contact) [N]
mesh = left.pcolormesh(taper.contact.values, taper.time.values * 1e3, f, shading="nearest",
                       cmap="magma", vmax=np.quantile(f, 0.999), rasterized=True)
fig.colorbar(mesh, ax=left, label="contact force [N]")
left.axvline(16.5, color="w", lw=0.8, ls="--")
left.text(17.2, 0.15, "taper begins", color="w", va="bottom")
left.set(xlabel="contact j (0 = striker, 30 = wall)", ylabel="time [ms]",
         title="(a) a pulse crossing chain 1")
for ds, label, colour in ((uniform, "30 uniform beads", "0.5"), (taper, "chain 1 (taper q = 5.6 %)", "C3")):
    right.plot(ds.time.values * 1e3, ds.wall_force.values, color=colour,
               label=f"{label}: peak {ds.attrs['peak_wall_force']:.2f} N")
right.set(xlabel="time [ms]", ylabel="wall force [N]", title="(b) what reaches the wall", xlim=(0.5, 3.0))
right.legend(loc="upper left", frameon=False)
fig.savefig(OUT, dpi=110)
print(f"wrote {OUT}")
