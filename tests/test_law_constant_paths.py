"""The generated loop's loops compiled for a constant parameter (``LawSpec.constant_parameters``:
the power law's n = 3/2 and n = 2, hertzchain.integrate.core.generated) against the contact-by-contact
loop with the parameter read per contact (the threaded engine's, drivers/threaded_laws): at
n = 3/2 the same arithmetic (d sqrt(d)), so forces and velocities bit for bit; at n = 2 the
constant folds d**2 into d d where the general loop calls pow, so the two agree to rounding
(relative 1e-9 over a whole pulse: pow's last bit, carried through ~10^4 steps)."""

from __future__ import annotations

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.integrate.drivers import threaded
from hertzchain.integrate.drivers.verlet import run_verlet


@pytest.mark.parametrize("law, rel", [(hc.PowerLaw(1.5), 0.0), (hc.PowerLaw(2.0, 1e13), 1e-9)], ids=["n=1.5", "n=2"])
def test_constant_parameter_loop_is_the_general_loop(law, rel, monkeypatch):
    monkeypatch.setattr(threaded, "MIN_SLOTS_PER_THREAD", 8)
    model = hc.Model(hc.Chain.uniform(30, 10e-3), hc.Striker(8e-3, 0.5), hc.Wall(), law=law)
    s = model.system()
    kw = dict(record_velocities=True)
    duration = hc.auto_duration(model)
    one = run_verlet(s, duration, 1e-6, **kw)
    many = threaded.run_verlet_threaded(s, duration, 1e-6, 2, **kw)
    assert one.contact_force.max() > 10.0 and one.max_force[-1] > 0.05 * one.max_force[1]  # the pulse crossed
    for name in ("contact_force", "velocity"):
        x, y = getattr(one, name), getattr(many, name)
        if rel == 0.0:
            assert np.array_equal(x, y), name
        else:
            assert np.abs(x - y).max() <= rel * np.abs(x).max(), name
    assert one.n_steps == many.n_steps
