"""
A localized defect mode
=======================

Twenty-one 10 mm steel (AISI 52100) beads pressed against the wall by F0 = 1 N are, linearised about
their static equilibrium, a row of equal springs K = (3/2) kappa^(2/3) F0^(1/3) [N/m] (the Hertz
contact's tangent stiffness at the static force; here K = 5.7e6 N/m). A uniform chain passes
frequencies up to the monatomic cut-off f_c = 2 sqrt(K/m) / (2 pi) = 11.9 kHz (the top of its
dispersion branch, omega = 2 sqrt(K/m) abs(sin(q/2)), q the wavenumber in rad per bead). Replace the
middle bead by a lighter 6 mm one: the defect's own vibration sits above f_c, where no wave can
carry it away, so :func:`hertzchain.modes` finds one mode above the band edge whose shape decays
exponentially on both sides of the defect (Theocharis et al., Phys. Rev. E 82, 056604, 2010). Left:
every mode frequency of the uniform and the defect chain against f_c (from
:func:`hertzchain.dispersion` of one bead); right: the defect mode's shape next to an in-band
mode's. The defect mode (18.3 kHz, neighbouring beads moving in opposite directions) carries over 99.9 %
of its kinetic energy on the five beads around the defect; the in-band mode spreads over
the whole chain.
"""

import matplotlib.pyplot as plt
import numpy as np

import hertzchain as hc

n, defect, f0 = 21, 10, 1.0  # defect: the 11th bead (index 10)
uniform = hc.Chain(np.full(n, 10e-3))
beads = np.full(n, 10e-3)
beads[defect] = 6e-3
with_defect = hc.Chain(beads)

bands = hc.dispersion(hc.Chain([10e-3]), f0)
f_cut = float(bands.frequency.max())  # 2 sqrt(K/m) / (2 pi)
k = float(np.atleast_1d(bands.attrs["stiffness"])[0])
m = float(uniform.masses[0])
print(f"K = {k:.4g} N/m, cut-off 2 sqrt(K/m)/(2 pi) = {2 * np.sqrt(k / m) / (2 * np.pi):.1f} Hz "
      f"(dispersion: {f_cut:.1f} Hz)")

plain = hc.modes(hc.Model(uniform, precompression=f0))
mds = hc.modes(hc.Model(with_defect, precompression=f0))
above = np.flatnonzero(mds.frequencies > f_cut)
print(f"highest uniform mode {plain.frequencies[-1]:.1f} Hz; defect chain modes above the cut-off: "
      + ", ".join(f"{f:.1f} Hz" for f in mds.frequencies[above]))
local = mds.shapes[:n, above[-1]]
inband = mds.shapes[:n, n // 2]
share = local[defect - 2:defect + 3] ** 2 * with_defect.masses[defect - 2:defect + 3]
print(f"share of the defect mode's kinetic energy on beads {defect - 1}..{defect + 3}: {share.sum():.3f}")

fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4), constrained_layout=True)
ax1.plot(np.arange(1, n + 1), plain.frequencies / 1e3, "o", mfc="none", label="uniform chain")
ax1.plot(np.arange(1, n + 1), mds.frequencies / 1e3, ".", color="C3", label="6 mm bead at 11")
ax1.axhline(f_cut / 1e3, color="k", lw=0.8, ls="--", label="cut-off 2 sqrt(K/m) / 2 pi")
ax1.set(xlabel="mode number", ylabel="frequency [kHz]", title="normal modes, F0 = 1 N")
ax1.legend()
bead = np.arange(1, n + 1)
ax2.plot(bead, local / np.abs(local).max(), "o-", color="C3", label=f"defect mode, {mds.frequencies[above[-1]] / 1e3:.2f} kHz")
ax2.plot(bead, inband / np.abs(inband).max(), ".-", color="0.5", label=f"in-band mode, {mds.frequencies[n // 2] / 1e3:.2f} kHz")
ax2.axvline(defect + 1, color="k", lw=0.5)
ax2.set(xlabel="bead", ylabel="displacement (normalised)", title="mode shapes")
ax2.legend()
plt.show()
