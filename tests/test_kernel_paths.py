"""The compiled kernel's two elastic step loops (short and long chains) give the same numbers."""

from __future__ import annotations

import numpy as np

import hertzchain as hc
from hertzchain.integrate.core import kernels
from hertzchain.integrate.core.layout import pack


def test_long_chain_lean_loop_matches_short_chain_loop():
    # A chain of >= LEAN_SLOTS slots steps with step_elastic_lean (no stored forces, no d0/fext),
    # a short one with step_elastic. Before the pulse's precursor reaches the short chain's end
    # (its last contacts are still exactly 0 N), the first contacts of both must agree bit for bit.
    n_long = kernels.LEAN_SLOTS + 10
    short = hc.Model(hc.Chain.uniform(40, 26e-3), hc.Striker(8e-3, 0.4))
    long_ = hc.Model(hc.Chain.uniform(n_long, 26e-3), hc.Striker(8e-3, 0.4))
    assert pack(long_.system()).n_slots >= kernels.LEAN_SLOTS > pack(short.system()).n_slots
    probes = hc.Probes(contacts=tuple(range(30)))
    for dt in (None, 5e-9):  # adaptive and fixed step
        a = hc.simulate(short, 2e-4, probes, dt=dt)
        b = hc.simulate(long_, 2e-4, probes, dt=dt)
        assert a.contact_force.sel(contact=slice(25, 29)).values.max() == 0.0  # precursor not there yet
        assert a.contact_force.values.max() > 10.0  # a real pulse
        np.testing.assert_array_equal(a.contact_force.values, b.contact_force.values)
        assert a.attrs["n_steps"] == b.attrs["n_steps"]
