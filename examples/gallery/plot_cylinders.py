"""
Cylinders in a chain of spheres
===============================

A cylinder lying across the chain touches its neighbours with its curved side: an elliptical
Hertz contact (Johnson, *Contact Mechanics*, Sec. 4.2), still F = kappa delta^(3/2) but with a
constant between the sphere-sphere and the sphere-flat ones; a cylinder along the chain touches
them with its flat ends. Its mass is rho pi phi^2 L / 4. Here bead 8 of 16 spheres of 20 mm is
replaced by a 20 mm cylinder, 40 mm long, crossed or aligned: heavier than the sphere it
replaces, it reflects part of the pulse.
"""

import matplotlib.pyplot as plt
import numpy as np

import hertzchain as hc
from hertzchain.elements import Element

chain = hc.Chain.uniform(16, 20e-3)
variants = {"all spheres": None,
            "bead 8 a crossed cylinder": Element("crossed", "cylinder", "crossed", 40e-3),
            "bead 8 an aligned cylinder": Element("aligned", "cylinder", "aligned", 40e-3)}
fig, ax = plt.subplots(figsize=(7, 4))
for label, element in variants.items():
    c = chain if element is None else chain.substitute(8, element=element)
    ds = hc.simulate(hc.Model(c, hc.Striker(20e-3, 0.2)), 1.5e-3, hc.Probes(sample_interval=1e-6))
    print(f"{label}: bead 8 {c.masses[7] * 1e3:.1f} g, kappa of contact 7 {float(ds.kappa[7]):.3e} N/m^1.5, "
          f"peak wall force {ds.attrs['peak_wall_force']:.1f} N")
    ax.plot(ds.time * 1e3, ds.contact_force.sel(contact=4), label=label)
ax.set_xlabel("time after impact [ms]")
ax.set_ylabel("force of contact 4 [N]")
ax.set_title("Pulses reflected by a cylinder (bead 8)")
ax.legend()
fig.tight_layout()
