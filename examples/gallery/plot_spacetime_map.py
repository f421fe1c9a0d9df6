"""
The space-time map of a pulse
=============================

Each contact is a column, time runs upwards, colour is the contact force (paper eq. 1): the
slope of the front is the pulse speed, which grows in the tapered part (paper eq. 8), and the
wall's reflection comes back as a second streak. On the linear scale the striker's contact, a
short and several times larger force, is drawn saturated (the colour bar's arrow) so that the
pulse in the chain keeps its colours; the log scale shows the tail behind the front. With
``to_scale=True`` the columns sit at the contacts' places along the chain.
"""

import hertzchain as hc

model = hc.Model(hc.paper_chain("chain1"), hc.Striker(8e-3, 0.2))
ds = hc.simulate(model, 3e-3, hc.Probes(sample_interval=1e-6))
linear = hc.plot_spacetime(ds)                                       # striker contact saturated
log_scale = hc.plot_spacetime(ds, scale="log", to_scale=True, floor=1e-3)   # three decades, in mm
