"""
Wall force against chain force
==============================

A sensor at the wall does not read the force travelling in the chain: the pulse is reflected by
the flat, immovable wall and the last contact is squeezed by the incoming and the reflected
wave at once. The paper quotes F_wall = 1.94 F_chain and tau_wall = 1.09 tau_chain for a
uniform elastic chain. We measure both ratios on 16 beads of 26 mm.
"""

import matplotlib.pyplot as plt

import hertzchain as hc

chain = hc.Chain.uniform(16, 26e-3)
model = hc.Model(chain, hc.Striker(diameter=8e-3, velocity=0.2), hc.Wall("flat"))
ds = hc.simulate(model, duration=2.0e-3, probes=hc.Probes(sample_interval=2.5e-8, contacts=(12,)))

t = ds.time.values
wall = hc.fit_pulse(t, ds.wall_force.values)
inner = hc.fit_pulse(t, ds.contact_force.sel(contact=12).values)
print(f"F_wall / F_chain = {wall.peak_force / inner.peak_force:.3f} (paper 1.94), "
      f"tau_wall / tau_chain = {wall.duration / inner.duration:.3f} (paper 1.09)")

fig, ax = plt.subplots(figsize=(7, 4))
ax.plot(t * 1e3, ds.contact_force.sel(contact=12), label="contact 12 (in the chain)")
ax.plot(t * 1e3, ds.wall_force, label="contact 16 (wall sensor)")
ax.set_xlim(0.6, 1.6)
ax.set_xlabel("time after impact [ms]")
ax.set_ylabel("force [N]")
ax.set_title(f"Wall/chain peak-force ratio {wall.peak_force / inner.peak_force:.2f}")
ax.legend()
fig.tight_layout()
