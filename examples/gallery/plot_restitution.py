"""
Restitution against impact speed
================================

Two-body coefficient of restitution e(v) by simulation (:func:`hertzchain.restitution`): an
8 mm sphere hitting a free 26 mm sphere of the same material, with Thornton's elastic-plastic
contact (``"elastoplastic"``, p_y = 1.5 sigma_Y) for the catalogue's AISI 52100 steel, brass,
aluminium and PTFE (points), against Thornton's closed form (lines): e = 1 below the yield
velocity v_y, then e ~ v^(-1/4).

Right: the 8 mm steel striker on a 26 mm steel bead under the dissipative laws calibrated to the
paper's eps = 0.985 in the chain. Kuwabara-Kono's loss grows with the speed (and, with one A, as
bodies shrink): the striker bounces far less than a steel ball (e >= 0.95 at 0.2 m/s). The
dashpot that follows each contact pair loses least at high speed: the reproduction's law.
"""

import math

import matplotlib.pyplot as plt
import numpy as np

import hertzchain as hc
from hertzchain.contact import hertz_constant, yield_force
from hertzchain.plasticity import thornton_restitution, yield_velocity

speeds = np.geomspace(2e-3, 5.0, 25)
fig, (ax, bx) = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
for name, color in zip(("AISI52100", "brass", "aluminium", "PTFE"), ("C0", "C1", "C2", "C3")):
    mat = hc.get_material(name)
    kappa = hertz_constant(4e-3, 13e-3, mat, mat)
    d_y = (yield_force(4e-3, 13e-3, mat, mat)[0] / kappa) ** (2 / 3)
    m_a, m_b = (mat.density * math.pi * d**3 / 6 for d in (8e-3, 26e-3))
    v_y = yield_velocity(kappa, d_y, m_a * m_b / (m_a + m_b))
    e = [hc.restitution(v, "elastoplastic", 8e-3, mat, 26e-3) for v in speeds]
    ax.plot(speeds, thornton_restitution(speeds, v_y), "-", color=color, lw=1)
    ax.plot(speeds, e, "o", color=color, ms=3, label=f"{name} (v_y = {v_y:.3g} m/s)")
ax.set_xscale("log")
ax.set_xlabel("impact speed v [m/s]")
ax.set_ylabel("coefficient of restitution e")
ax.set_title("Thornton, 8 mm on 26 mm, same material")
ax.legend(fontsize=8)

chain, striker = hc.paper_chain("chain1"), hc.Striker(8e-3, 0.2)
speeds = np.geomspace(0.01, 2.0, 12)
for kind, color in zip(("viscoelastic", "viscoelastic_scaled", "dashpot_scaled"), ("C4", "C5", "C2")):
    law = hc.calibrate_law(kind, 0.985, chain=chain, striker=striker)
    bx.plot(speeds, [hc.restitution(v, law, 8e-3, "AISI52100", 26e-3) for v in speeds], "o-", color=color,
            ms=3, label=kind)
bx.axhspan(0.95, 1.0, color="0.9", zorder=0)
bx.axvline(0.2, color="0.6", lw=0.8)
bx.set_xscale("log")
bx.set_xlabel("striker speed [m/s]")
bx.set_title("8 mm steel striker, laws calibrated to eps = 0.985")
bx.legend(fontsize=8)
fig.tight_layout()
plt.show()
