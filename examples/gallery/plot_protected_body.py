"""
A protected body behind the chain
=================================

The paper's wall is immovable: everything the chain delivers goes straight into the ground. A
shock absorber exists for a body, though, with its own mass and mount. Here chain 1 of the
paper ends on a 1 kg body held by a 1e6 N/m spring (``Wall("body", ...)``, config
``[wall] type = "body"``). The chain presses on the body's face (``wall_force``); the body
passes ``body_force`` = k x + c v on to its ground. A body this heavy on so soft a mount is
pushed by the pulse train as a whole and swings slowly (a period of 6.3 ms): the ground sees a
fraction of the peak force the rigid wall takes.
"""

import matplotlib.pyplot as plt

import hertzchain as hc

chain = hc.paper_chain("chain1")
striker = hc.Striker(diameter=8e-3, velocity=0.2)
probes = hc.Probes(sample_interval=1e-6)
rigid = hc.simulate(hc.Model(chain, striker), 12e-3, probes)
body = hc.simulate(hc.Model(chain, striker, hc.Wall("body", mass=1.0, stiffness=1e6)), 12e-3, probes)

f_rigid = rigid.attrs["peak_wall_force"]
f_ground = body.attrs["peak_body_force"]
print(f"peak force on the rigid wall {f_rigid:.3f} N; on the body's face {body.attrs['peak_wall_force']:.3f} N; "
      f"passed to the ground by the mount {f_ground:.3f} N ({f_ground / f_rigid:.1%} of the rigid wall's)")
print(f"energy delivered to the body at most {body.attrs['peak_body_energy'] * 1e6:.2f} uJ "
      f"(striker {0.5 * striker.mass * striker.velocity ** 2 * 1e6:.1f} uJ)")

fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(7, 5.5), sharex=True)
t = body.time.values * 1e3
ax1.plot(t, rigid.wall_force, label="rigid wall")
ax1.plot(t, body.wall_force, label="face of the 1 kg body", alpha=0.8)
ax1.set_ylabel("contact force [N]")
ax1.legend()
ax2.plot(t, body.body_force, color="C2", label="body -> ground, k x")
ax2.set_ylabel("force on the ground [N]")
ax2.set_xlabel("time after impact [ms]")
ax2.legend()
fig.suptitle("Chain 1 against a 1 kg body on a 1e6 N/m mount")
fig.tight_layout()
