"""
Mass-in-mass beads: a band gap
==============================

A bead may hide an internal mass on a spring (``Element(resonator_fraction=..,
resonator_frequency=..)``, config ``[elements.NAME] resonator = { mass_fraction, frequency }``).
Linearised about a precompression F0 (contact stiffness K = (3/2) kappa^(2/3) F0^(1/3)), such a
chain obeys the dispersion relation

    m1 omega^2 + m2 omega^2 omega2^2 / (omega2^2 - omega^2) = 4 K sin^2(q / 2),

shell m1, internal mass m2, omega2^2 = k_in / m2: between the acoustic branch's top (q = pi) and
the optical branch's bottom omega2 sqrt(1 + m2/m1) no wave travels. A gentle tap shows it in the
spectrum of the force 35 beads down the chain.
"""

import math

import matplotlib.pyplot as plt
import numpy as np
from scipy.optimize import brentq

import hertzchain as hc
from hertzchain.elements import Element

n, f0, fraction, frequency = 40, 20.0, 0.4, 6000.0
chain = hc.Chain(np.full(n, 20e-3), "AISI52100", None, Element("mim", resonator_fraction=fraction,
                                                                 resonator_frequency=frequency))
model = hc.Model(chain, hc.Striker(8e-3, 1e-4), precompression=f0)
s = model.system()
m = float(chain.masses[0])
m1, m2 = (1 - fraction) * m, fraction * m
k = 1.5 * s.kappa[2] ** (2 / 3) * f0 ** (1 / 3)
w2 = 2 * math.pi * frequency

ds = hc.simulate(model, 20e-3, hc.Probes(sample_interval=2e-6, contacts=(35,)))
force = ds.contact_force.sel(contact=35).values
spectrum = np.abs(np.fft.rfft((force - force[0]) * np.hanning(force.size)))
freq = np.fft.rfftfreq(force.size, 2e-6)

# the analytic branches: omega(q) from the dispersion relation
q = np.linspace(1e-3, math.pi, 200)
rhs = 4 * k * np.sin(q / 2) ** 2


def branch(lo, hi):
    return np.array([brentq(lambda w: m1 * w * w + m2 * w * w * w2 * w2 / (w2 * w2 - w * w) - r, lo, hi) for r in rhs])


acoustic = branch(1e-3, w2 * (1 - 1e-12))
optical = branch(w2 * (1 + 1e-12), 1e7)
top, bottom = acoustic[-1] / (2 * math.pi), w2 * math.sqrt(1 + m2 / m1) / (2 * math.pi)
print(f"band gap {top:.0f} Hz - {bottom:.0f} Hz")

fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(9, 4), sharey=True)
ax1.plot(q, acoustic / (2 * math.pi) / 1e3, label="acoustic")
ax1.plot(q, optical / (2 * math.pi) / 1e3, label="optical")
ax1.axhspan(top / 1e3, bottom / 1e3, color="0.9")
ax1.set_xlabel("wavenumber q [rad per bead]")
ax1.set_ylabel("frequency [kHz]")
ax1.legend()
ax2.semilogx(spectrum / spectrum.max(), freq / 1e3)
ax2.axhspan(top / 1e3, bottom / 1e3, color="0.9", label="analytic gap")
ax2.set_xlim(1e-6, 2)
ax2.set_ylim(0, 14)
ax2.set_xlabel("spectrum 35 beads down (relative)")
ax2.legend()
fig.tight_layout()
