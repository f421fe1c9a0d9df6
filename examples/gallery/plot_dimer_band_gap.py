"""
A dimer chain's band gap
========================

Alternating 10 mm and 6 mm steel beads pressed by F0 = 1 N form a granular crystal whose
contacts are springs K = (3/2) kappa^(2/3) F0^(1/3). :func:`hertzchain.dispersion` gives the Bloch
band structure of one period (left): an acoustic and an optical branch with a gap between
sqrt(2K/m_heavy) and sqrt(2K/m_light). A finite chain of eight cells driven on bead 1 by a small
harmonic force transmits in the pass bands and only its evanescent tail in the gap (right): the
linearised chain's transmission (:func:`hertzchain.linear_transmission`, line) and the steady
state of driven runs (:func:`hertzchain.transmission_spectrum`, dots). Where the linear tail falls
below ~1e-6 (21 kHz, above the optical band) the runs level off there: what is left of the start-up
transient at the drive frequency after 100 cycles (it is the same at a tenth of the amplitude and
with four times finer steps, and falls with longer settling).
"""

import matplotlib.pyplot as plt
import numpy as np

import hertzchain as hc
from hertzchain.crystal.spectrum import SpectrumSettings

cell = hc.Chain([10e-3, 6e-3])
bands = hc.dispersion(cell, 1.0)
(low, high), = bands.attrs["gaps"]

chain = cell
for _ in range(7):
    chain = chain.concat(cell)
model = hc.Model(chain, law=hc.Dashpot(5.0), precompression=1.0,
                 drive=hc.Drive(amplitude=1e-3, frequency=5000.0, ramp_cycles=10))
f_line = np.linspace(1e3, 24e3, 400)
f_runs = np.linspace(3e3, 21e3, 7)
spec = hc.transmission_spectrum(model, f_runs, settings=SpectrumSettings(settle_cycles=100, measure_cycles=10))

fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4), constrained_layout=True)
for b in bands.branch.values:
    ax1.plot(bands.wavenumber, bands.frequency.sel(branch=b) / 1e3, color="C0")
ax1.axhspan(low / 1e3, high / 1e3, color="0.85")
ax1.set(xlabel="wavenumber [rad per period]", ylabel="frequency [kHz]", xlim=(0, np.pi), title="band structure")
ax2.semilogy(f_line / 1e3, hc.linear_transmission(model, f_line), color="C0", label="linearised chain")
ax2.semilogy(spec.frequency / 1e3, spec.transmission, "o", color="C3", label="driven runs (steady state)")
ax2.axvspan(low / 1e3, high / 1e3, color="0.85")
ax2.set(xlabel="drive frequency [kHz]", ylabel="|F_wall| / |F_drive|", title="eight cells, 1e-3 N drive")
ax2.legend()
plt.show()
