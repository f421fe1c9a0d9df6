"""
Strikers of any mass and face
=============================

The paper's striker is an 8 mm steel sphere. A drop hammer is heavier and flat-faced; an impactor
may have a curved face of any radius. ``Striker(mass=..., shape="flat")`` (config ``[striker]
mass``, ``shape = "flat"``) meets bead 1 in a sphere-flat Hertz contact (1/R' = 0 in paper eq. 1);
``radius_of_curvature`` sets a curved face. Three strikers of the same momentum hit 16 beads of
26 mm: the heavy, slow ones push a longer train of pulses into the chain instead of one solitary
wave.
"""

import matplotlib.pyplot as plt

import hertzchain as hc

chain = hc.Chain.uniform(16, 26e-3)
ball = hc.Striker(diameter=8e-3, velocity=0.2)
momentum = ball.mass * ball.velocity
strikers = {
    "8 mm sphere (the paper's)": ball,
    "flat hammer, 20 g": hc.Striker(velocity=momentum / 0.02, mass=0.02, shape="flat"),
    "hammer, 20 g, face R = 50 mm": hc.Striker(velocity=momentum / 0.02, mass=0.02, radius_of_curvature=50e-3),
}
fig, ax = plt.subplots(figsize=(7, 4))
for label, striker in strikers.items():
    ds = hc.simulate(hc.Model(chain, striker), 2.5e-3, hc.Probes(sample_interval=1e-6))
    print(f"{label}: kappa_0 = {float(ds.kappa[0]):.3e} N/m^1.5, peak wall force {ds.attrs['peak_wall_force']:.2f} N")
    ax.plot(ds.time * 1e3, ds.wall_force, label=label)
ax.set_xlabel("time after impact [ms]")
ax.set_ylabel("wall force [N]")
ax.set_title(f"Same momentum ({momentum * 1e3:.2f} mN s), three strikers")
ax.legend()
fig.tight_layout()
