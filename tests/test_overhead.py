"""simulate()'s Python around the kernel: the Dataset built directly is the one xarray's public
constructor builds, and the checks read the same numbers."""

from __future__ import annotations

import numpy as np
import xarray as xr

import hertzchain as hc
from hertzchain.integrate.drivers.verlet import run_verlet
from hertzchain.result import fields_dataset, run_fields


def test_direct_dataset_is_the_public_constructors():
    model = hc.Model(hc.Chain.uniform(6, 20e-3), hc.Striker(8e-3, 0.2))
    probes = hc.Probes(sample_interval=1e-6, sensors=(3,), velocities=True, contacts=(0, 2))
    system = model.system()
    raw = run_verlet(system, 2e-4, probes.sample_interval, record_velocities=True,
                     contacts=probes.recorded_contacts(6, True))
    f = run_fields(raw, model, probes, duration=2e-4, system=system)
    fast = fields_dataset(f)
    public = xr.Dataset({n: xr.Variable(d, v, attrs=a) for n, (d, v, a) in f.data.items()}, coords=f.coords,
                        attrs=f.attrs)
    assert fast.identical(public)
    assert list(fast.variables) == list(public.variables)
    assert list(fast.sizes) == list(public.sizes)
    assert all(type(fast.xindexes[k]) is type(public.xindexes[k]) for k in public.xindexes)
    # selection by label works on the direct build's indexes
    t = float(public.time[100])
    assert float(fast.contact_force.sel(contact=2, time=t)) == float(public.contact_force.sel(contact=2, time=t))


def test_energy_gain_in_place_is_the_formula():
    from hertzchain.checks import energy_gain

    rng = np.random.default_rng(0)
    k, p, d = rng.random((3, 4, 50))
    k[2, 0] = p[2, 0] = 0.0  # a member with no energy at the start: gain 0
    total = k + p + d
    scale = np.abs(k[..., :1]) + np.abs(p[..., :1])
    with np.errstate(invalid="ignore", divide="ignore"):
        expected = np.where(scale > 0, (total - total[..., :1]) / scale, 0.0)
    assert np.array_equal(energy_gain(k, p, d), expected)
    assert np.array_equal(energy_gain(k[0], p[0], d[0]), expected[0])
