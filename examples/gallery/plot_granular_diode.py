"""
A granular diode: asymmetric transmission
=========================================

Ten cells of 10 mm and 6 mm steel beads under F0 = 1 N, the third bead made a 4 mm defect, the
chain ended by the wall (Boechler et al., Nat. Mater. 10, 665, 2011). Linearised (contact springs
K = (3/2) kappa^(2/3) F0^(1/3)), the dimer has a band gap between sqrt(2K/m_heavy) and
sqrt(2K/m_light) (divided by 2 pi: 8.04 to 17.29 kHz), and the defect adds localized modes inside
it (:func:`hertzchain.modes`). A harmonic force on bead 1 just below the lowest of them (0.98 x its
frequency, 12.37 kHz) is applied at bead 1, the defect at the driven end ("defect first"), or at
bead 20 with ``end = "last"`` (the same chain resting with bead 1 on the wall: "defect last", the
defect next to the wall, a 6 mm bead driven; the transmitted force is then the wall's at bead 1).
Transmission is the steady-state ratio of the wall force's amplitude at the drive frequency to the
drive's (:func:`hertzchain.transmission_against_amplitude`, 150 settling cycles after a 20-cycle
ramp, 20 measured, a light dashpot law). At small amplitudes each direction transmits what the
linearised chain does (:func:`hertzchain.linear_transmission`, dashed): 1.0e-5 and 5.7e-5, an
evanescent tail through the gap; the two differ (ratio 0.17) because the output is the wall force
of two different chains, not a reciprocal pair. Above a threshold the one-sided Hertz contacts open
and the response leaves the linear one: the "defect last" chain from between 0.12 and 0.26 N
(1.1e-3 at 0.26 N, 17 times its linear value), the "defect first" chain only above 0.59 N. In
between the chain is a diode: at 0.59 N "defect last" transmits 5.4e-3 and "defect first" 1.2e-5,
470 times less (ratio 0.0021); at 3 N both transmit and the ratio is back to 0.08 (above ~1 N the
driven chain bifurcates: there the numbers move with rounding-level changes of the step).
Left: the defect chain's modes (two inside the gap, at 12.62 and 17.09 kHz) and the drive;
right: transmission against the drive amplitude [N] from both ends.
"""

import warnings

import matplotlib.pyplot as plt
import numpy as np

import hertzchain as hc
from hertzchain.crystal.spectrum import SpectrumSettings

beads = [10e-3, 6e-3] * 10
beads[2] = 4e-3
chain = hc.Chain(beads)
ends = {"defect first": "first", "defect last": "last"}
law, f0 = hc.Dashpot(3.0), 1.0
mds = hc.modes(hc.Model(chain, striker=None, law=law, precompression=f0))
(low, high), = hc.dispersion(hc.Chain([10e-3, 6e-3]), f0).attrs["gaps"]
in_gap = mds.frequencies[(mds.frequencies > low) & (mds.frequencies < high)]
f = 0.98 * in_gap[0]
print(f"gap {low:.0f} - {high:.0f} Hz; defect modes in the gap: " + ", ".join(f"{x:.0f} Hz" for x in in_gap)
      + f"; drive at {f:.0f} Hz")

amplitudes = np.geomspace(0.01, 3.0, 8)
settings = SpectrumSettings(settle_cycles=150, measure_cycles=20)
curves, linear = {}, {}
with warnings.catch_warnings():
    warnings.simplefilter("ignore", hc.ElasticLimitWarning)
    for name, end in ends.items():
        model = hc.Model(chain, striker=None, law=law, precompression=f0,
                         drive=hc.Drive(amplitude=0.01, frequency=f, ramp_cycles=20, end=end))
        curves[name] = hc.transmission_against_amplitude(model, f, amplitudes, settings=settings).transmission.values
        linear[name] = float(hc.linear_transmission(model, [f])[0])
print("linear chain: " + ", ".join(f"{k} {v:.2e}" for k, v in linear.items()))
ratio = curves["defect first"] / curves["defect last"]
for a, t1, t2, r in zip(amplitudes, curves["defect first"], curves["defect last"], ratio):
    print(f"{a:7.3f} N: defect first {t1:.2e}, defect last {t2:.2e}, ratio {r:.3g}")

fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4), constrained_layout=True)
ax1.plot(np.arange(1, mds.frequencies.size + 1), mds.frequencies / 1e3, ".", color="C0")
ax1.axhspan(low / 1e3, high / 1e3, color="0.85", label="dimer band gap")
ax1.axhline(f / 1e3, color="C3", lw=0.8, label="drive frequency")
ax1.set(xlabel="mode number", ylabel="frequency [kHz]", title="modes of the defect chain, F0 = 1 N")
ax1.legend()
for (name, marker), color in zip((("defect first", "o-"), ("defect last", "s-")), ("C0", "C1")):
    ax2.loglog(amplitudes, curves[name], marker, color=color, label=name)
    ax2.axhline(linear[name], color=color, ls="--", lw=0.8)
ax2.set(xlabel="drive force amplitude [N]", ylabel="|F_wall| / |F_drive| at the drive frequency",
        title=f"driven at {f / 1e3:.2f} kHz (in the gap)")
ax2.legend()
plt.show()
