"""simulate_batch builds its stacked Dataset straight from the engine's arrays: it must be exactly
stack_results(simulate_many(...)) (same variables, dimensions, coordinates, dtypes, attributes
and NaN padding), for mixed batches (the per-member fill) and uniform ones (the engine's buffers
used without a copy), with the same elastic-limit warnings."""

from __future__ import annotations

import re

import warnings

import numpy as np
import pytest

from hertzchain import Chain, Dashpot, Model, Probes, Striker, Viscoelastic, Wall
from hertzchain.errors import ElasticLimitWarning, PulseNotReachedWarning
from hertzchain.runs.batch import simulate_batch, simulate_many, stack_results
from hertzchain.result import build_dataset, run_fields

DURATION = 1.2e-4  # s
INTERVAL = 1e-6    # s


def _run_both(models, probes, dt=None, configs=None, duration=DURATION):
    """(simulate_batch, stack_results(simulate_many)) and the warnings each raised."""
    out, caught = [], []
    for fn in (lambda: simulate_batch(models, duration, probes, dt=dt, configs=configs),
               lambda: stack_results(simulate_many(models, duration, probes, dt=dt, configs=configs))):
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            out.append(fn())
        caught.append([(x.category, str(x.message)) for x in w])
    return out[0], out[1], caught[0], caught[1]


def assert_identical(fast, slow):
    """xarray-identical once created_utc is dropped, in the same order, with NaN in the same places."""
    fast, slow = fast.copy(), slow.copy()
    assert fast.attrs.pop("created_utc") and slow.attrs.pop("created_utc")
    assert fast.identical(slow)
    assert list(fast.variables) == list(slow.variables)
    assert list(fast.dims) == list(slow.dims) and dict(fast.sizes) == dict(slow.sizes)
    for name in slow.variables:
        a, b = fast[name], slow[name]
        assert a.dtype == b.dtype and a.dims == b.dims and a.attrs == b.attrs, name
        if a.dtype.kind == "f":
            assert np.array_equal(np.isnan(a.values), np.isnan(b.values)), name
            assert np.array_equal(a.values, b.values, equal_nan=True), name
        else:
            assert np.array_equal(a.values, b.values), name


def test_mixed_batch_equals_stacked_single_datasets():
    models = [
        Model(Chain.uniform(4, 10e-3), Striker(8e-3, 0.2)),
        Model(Chain.uniform(3, 12e-3).append_taper(4, 0.08), Striker(6e-3, 0.3)),
        Model(Chain.uniform(5, 8e-3, "brass"), Striker(8e-3, 0.15, "brass"), law=Viscoelastic(A=1e-6)),
        Model(Chain.uniform(6, 10e-3).with_offsets({2: 0.4e-3, 3: -0.2e-3}), Striker(8e-3, 0.1)),
        Model(Chain.uniform(5, 10e-3), Striker(8e-3, 0.2), wall=Wall("none")),          # no wall
        Model(Chain.uniform(2, 10e-3), Striker(8e-3, 2.0), law=Dashpot(gamma=5.0)),      # over the limit
        Model(Chain.uniform(3, 10e-3), Striker(8e-3, 3.0)),                              # over the limit
    ]
    probes = [Probes(INTERVAL, sensors=(2,)), Probes(INTERVAL, sensors=(3, 5), contacts=(0, 4)),
              Probes(INTERVAL), Probes(INTERVAL, velocities=True),
              Probes(INTERVAL, velocities=True, contacts=(1, 3)), Probes(INTERVAL, sensors=(1,)),
              Probes(INTERVAL, contacts=())]
    dts = [None, None, None, None, 1e-8, 1e-8, None]  # fixed and automatic steps
    configs = [None, {"name": "taper"}, None, None, {"x": [1, 2]}, None, None]
    fast, slow, w_fast, w_slow = _run_both(models, probes, dts, configs)
    assert_identical(fast, slow)
    # Not a vacuous comparison: padding, dissipation, both kinds of step, both walls, warnings.
    assert np.isnan(fast["contact_force"].values).any() and np.isnan(fast["velocity"].values).any()
    assert np.isnan(fast["wall_force"].sel(member=4)).all() and np.isnan(fast["peak_wall_force"][4])
    assert float(fast["dissipated_energy"][2, -1]) > 0 and float(fast["dissipated_energy"][5, -1]) > 0
    assert {"sensor", "body", "contact_all"} <= set(fast.dims)
    assert fast["contact_force"].sel(member=6).sizes["contact"] > 0
    assert len(set(fast["dt"].values.tolist())) > 3
    # simulate_batch also names, in one warning, the members whose record ended before the pulse
    # reached the wall (simulate_many leaves that to the caller)
    pulse = [m for c, m in w_fast if c is PulseNotReachedWarning]
    w_fast = [(c, m) for c, m in w_fast if c is not PulseNotReachedWarning]
    # ONE elastic-limit warning for the batch, naming the members past the limit (issue 23: not one line
    # per member, 10,000 for a 10k ensemble)
    assert w_fast == w_slow and len(w_fast) == 1 and w_fast[0][0] is ElasticLimitWarning
    assert re.search(r"\d+ of 7 members \(member [\d, ]*5, 6\) pass the elastic limit; worst: member \d+:",
                     w_fast[0][1]), w_fast[0][1]
    # the single-run check's criterion: the wall contact never carried 1e-6 of the member's largest force
    fmax = np.nanmax(fast["max_contact_force"].values, axis=1)
    missed = [i for i in range(len(models))
              if models[i].wall.present and fast["peak_wall_force"].values[i] <= 1e-6 * fmax[i]]
    assert missed and len(pulse) == 1
    assert pulse[0].startswith(f"{len(missed)} of {len(models)} members (member {', '.join(map(str, missed))})")


@pytest.mark.parametrize("probes", [Probes(INTERVAL, contacts=(0,)),                  # wall + contact 0
                                    Probes(INTERVAL, velocities=True),                # every contact
                                    Probes(INTERVAL, contacts=(0, 4), sensors=(2,)),  # columns 0 and 3 of 5
                                    Probes(INTERVAL, contacts=(1, 2))])
def test_uniform_batch_uses_the_engine_buffers_and_stays_identical(probes):
    # Same layout for every member (different strikers): the engine's buffers are the result.
    models = [Model(Chain.uniform(6, 10e-3), Striker(8e-3, v)) for v in (0.1, 0.2, 0.3, 0.4)]
    fast, slow, w_fast, w_slow = _run_both(models, probes, dt=[None, 1e-8, None, 1e-8])
    assert_identical(fast, slow)
    assert w_fast == w_slow
    assert not np.isnan(fast["contact_force"].values).any()
    if probes.contacts == (0,):  # contact 0 and the wall are the two recorded columns: no copy at all
        assert np.may_share_memory(fast["contact_force"].values, fast["wall_force"].values)


@pytest.mark.parametrize("reverse", [False, True])
def test_same_recorded_contacts_but_different_layouts_are_padded(reverse):
    # Both members record contacts (0, 5), but one stores both and has no wall, the other stores
    # contact 0 and a wall force: the engine's buffer is not the stacked layout; padding is needed.
    models = [Model(Chain.uniform(6, 10e-3), Striker(8e-3, 0.2), wall=Wall("none")),
              Model(Chain.uniform(5, 10e-3), Striker(8e-3, 0.2))]
    probes = [Probes(INTERVAL, contacts=(0, 5)), Probes(INTERVAL, contacts=(0,))]
    if reverse:
        models, probes = models[::-1], probes[::-1]
    fast, slow, _, _ = _run_both(models, probes)
    assert_identical(fast, slow)
    assert np.isnan(fast["contact_force"].values).any() and np.isnan(fast["wall_force"].values).any()


def test_one_member_warns_without_a_member_prefix():
    models = [Model(Chain.uniform(3, 10e-3), Striker(8e-3, 3.0))]
    fast, slow, w_fast, w_slow = _run_both(models, Probes(INTERVAL), duration=4e-5)
    assert_identical(fast, slow)
    assert w_fast == w_slow and len(w_fast) == 1 and w_fast[0][1].startswith("contact forces pass")


def test_stack_results_of_other_datasets_and_member_numbers():
    models = [Model(Chain.uniform(n, 10e-3), Striker(8e-3, 0.2)) for n in (3, 5)]
    many = simulate_many(models, 4e-5, Probes(INTERVAL, sensors=(2,)))
    ds = stack_results(many[::-1], member=[7, 3])
    assert ds["member"].values.tolist() == [7, 3]
    assert ds["n_beads"].values.tolist() == [5, 3]
    assert np.array_equal(ds["contact_force"].sel(member=3, contact=[0, 1, 2, 3]).values,
                          many[0]["contact_force"].values)


def test_build_dataset_is_run_fields_wrapped():
    model = Model(Chain.uniform(4, 10e-3), Striker(8e-3, 0.2))
    probes = Probes(INTERVAL, sensors=(2,), velocities=True)
    from hertzchain.integrate.drivers.verlet import run_verlet

    raw = run_verlet(model.system(), 2e-5, INTERVAL, record_velocities=True,
                     contacts=probes.recorded_contacts(4, True))
    ds = build_dataset(raw, model, probes, duration=2e-5)
    f = run_fields(raw, model, probes, duration=2e-5)
    assert list(ds.data_vars) == list(f.data) and set(ds.coords) == set(f.coords)
    for name, (dims, values, attrs) in f.data.items():
        assert ds[name].dims == dims and ds[name].attrs == attrs and np.array_equal(ds[name].values, values)
    for key in ("units", "long_name"):
        assert all(key in ds[name].attrs for name in ds.data_vars)
