"""
Where the striker's energy goes
===============================

:func:`hertzchain.plot_energy` draws the kinetic energy, the Hertz potential energy and the
energy dissipated by the contact law, and their sum. With elastic contacts the sum stays the
striker's initial kinetic energy (its drift is the integrator's error); with the paper's
dissipation (Kuwabara-Kono law calibrated to eps = 0.985, Sec. III) the dissipated share grows
as the pulse crosses the chain.
"""

import numpy as np

import hertzchain as hc

chain = hc.paper_chain("chain1")
striker = hc.Striker(8e-3, 0.2)
law = hc.calibrate_law("viscoelastic", 0.985, chain=chain, striker=striker)
elastic = hc.simulate(hc.Model(chain, striker), 3e-3, hc.Probes(sample_interval=1e-6))
damped = hc.simulate(hc.Model(chain, striker, law=law), 3e-3, hc.Probes(sample_interval=1e-6))
e0 = 0.5 * striker.mass * striker.velocity**2
total = (elastic.kinetic_energy + elastic.potential_energy).values
print(f"striker energy {e0 * 1e3:.4f} mJ; elastic run: total drifts by {np.ptp(total) / e0:.1e} of it; "
      f"damped run dissipates {damped.dissipated_energy.values[-1] / e0:.1%} by 3 ms")
fig_elastic = hc.plot_energy(elastic)
fig_damped = hc.plot_energy(damped)
