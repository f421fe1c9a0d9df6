"""
A band-gap map over the dimer's size ratio
==========================================

A dimer cell of a 10 mm steel bead and a smaller one of diameter d pressed by F0 = 1 N has one
contact stiffness K = (3/2) kappa^(2/3) F0^(1/3) [N/m] (both its contacts join a heavy and a light
bead). Its Bloch band structure (:func:`hertzchain.dispersion`) has an acoustic branch topped at
sqrt(2K/m_heavy) and an optical branch from sqrt(2K/m_light) to sqrt(2K (1/m_heavy + 1/m_light))
(angular frequencies; divide by 2 pi for Hz), the gap between them (Herbold et al., Acta Mech.
205, 85, 2009). Sweeping d from 3 to 10 mm maps the gap: the shaded band is what
:func:`hertzchain.dispersion` reports in its ``gaps`` attribute for each d, the lines the closed
forms. The gap closes as the two masses become equal (d = 10 mm: the monatomic chain, one branch
up to 2 sqrt(K/m)), and widens as the light bead shrinks: its optical band climbs because m_light
falls as d^3 faster than K (which softens as the contact's effective radius shrinks).
At d = 6 mm the gap runs from 8.04 to 17.29 kHz; the
edges :func:`hertzchain.dispersion` finds agree with the closed forms to rounding (2e-16).
"""

import matplotlib.pyplot as plt
import numpy as np

import hertzchain as hc

heavy, f0 = 10e-3, 1.0
diameters = np.linspace(3e-3, 10e-3, 36)
rows = []
for d in diameters:
    cell = hc.Chain([heavy, d])
    bands = hc.dispersion(cell, f0, points=51)
    k = float(np.atleast_1d(bands.attrs["stiffness"])[0])
    m_heavy, m_light = (float(m) for m in cell.masses)
    gap = bands.attrs["gaps"][0] if bands.attrs["gaps"] else [np.nan, np.nan]
    rows.append((*gap, float(bands.frequency.max()), k, m_heavy, m_light))
low, high, top, k, m_heavy, m_light = np.array(rows).T
closed_low = np.sqrt(2 * k / m_heavy) / (2 * np.pi)
closed_high = np.sqrt(2 * k / m_light) / (2 * np.pi)
closed_top = np.sqrt(2 * k * (1 / m_heavy + 1 / m_light)) / (2 * np.pi)
ok = np.isfinite(low)
print(f"largest relative difference, gap edges from dispersion vs closed forms: "
      f"{np.nanmax(np.abs(low / closed_low - 1)):.1e} (low), {np.nanmax(np.abs(high / closed_high - 1)):.1e} (high)")
i = np.argmin(np.abs(diameters - 6e-3))
print(f"d = 6 mm: gap {low[i]:.0f} - {high[i]:.0f} Hz")

fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
mm = diameters * 1e3
ax.fill_between(mm, 0, top / 1e3, color="C0", alpha=0.25, lw=0, label="pass bands (dispersion)")
ax.fill_between(mm[ok], low[ok] / 1e3, high[ok] / 1e3, color="0.8", lw=0, label="band gap (dispersion)")
ax.plot(mm, closed_low / 1e3, "k--", lw=1, label="sqrt(2K/m_heavy) / 2 pi")
ax.plot(mm, closed_high / 1e3, "k:", lw=1.2, label="sqrt(2K/m_light) / 2 pi")
ax.plot(mm, closed_top / 1e3, "k-", lw=0.8, label="sqrt(2K (1/m_h + 1/m_l)) / 2 pi")
ax.set(xlabel="light bead diameter d [mm] (heavy bead 10 mm)", ylabel="frequency [kHz]",
       title="steel dimer under F0 = 1 N", xlim=(mm[0], mm[-1]), ylim=(0, None))
ax.legend(loc="upper right")
plt.show()
