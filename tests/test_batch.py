"""Batched engine: bit-identical to single runs for a mixed batch, stacked layout, scheduling."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import assert_same_run

from hertzchain import Chain, Dashpot, Model, Probes, Striker, Viscoelastic, Wall, simulate
from hertzchain.errors import ConfigError, ElasticLimitWarning
from hertzchain.integrate.batch import engine as batch_engine
from hertzchain.runs.batch import run_batch, simulate_batch, simulate_many

DURATION = 2.5e-4  # s: short, but long enough for the pulse to hit the wall of every chain below
INTERVAL = 1e-6    # s


def mixed_models() -> list[Model]:
    """Different lengths, diameters, materials, strikers, laws, offsets and ends."""
    return [
        Model(Chain.uniform(4, 10e-3), Striker(8e-3, 0.2)),
        Model(Chain.uniform(3, 12e-3).append_taper(4, 0.08), Striker(6e-3, 0.3)),                  # taper
        Model(Chain.uniform(5, 8e-3, "brass"), Striker(8e-3, 0.15, "brass"), law=Viscoelastic(A=1e-6)),
        Model(Chain.uniform(6, 10e-3).with_offsets({2: 0.4e-3, 3: -0.2e-3}), Striker(8e-3, 0.1)),  # offsets
        Model(Chain.uniform(5, 10e-3), Striker(8e-3, 0.2), wall=Wall("none")),                      # free end
        Model(Chain.uniform(2, 10e-3), Striker(8e-3, 0.2), law=Dashpot(gamma=5.0)),
        Model(Chain.from_diameters([10e-3, 9e-3, 11e-3], ("AISI52100", "glass", "AISI52100")), Striker(8e-3, 0.1),
              wall=Wall("flat", "brass")),
    ]


def mixed_probes(models: list[Model]) -> list[Probes]:
    """Per-member probes sharing one sample interval: sensors, a contact subset, velocities."""
    out = [Probes(INTERVAL, sensors=(2,)) for _ in models]
    out[1] = Probes(INTERVAL, sensors=(3, 5), contacts=(0, 4))
    out[3] = Probes(INTERVAL, velocities=True)
    return out


def single_runs(models, probes, dts=None):
    dts = dts or [None] * len(models)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ElasticLimitWarning)
        return [simulate(m, DURATION, p, dt=dt, integrator="verlet") for m, p, dt in zip(models, probes, dts)]


@pytest.fixture(scope="module")
def mixed():
    models = mixed_models()
    probes = mixed_probes(models)
    # One member with a user time step, to check that per-member steps (and strides) mix.
    dts = [None, None, None, None, None, 1e-8, None]
    return models, probes, dts, single_runs(models, probes, dts)


def test_simulate_many_equals_single_runs_bit_for_bit(mixed):
    models, probes, dts, singles = mixed
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ElasticLimitWarning)
        many = simulate_many(models, DURATION, probes, dt=dts)
    # Guard against a vacuous comparison: members really differ in step and the pulses are there.
    assert len({ds.attrs["dt"] for ds in many}) > 2
    assert min(float(ds.wall_force.max()) for ds in many if "wall_force" in ds) > 1.0
    assert float(many[2].dissipated_energy[-1]) > 0 and float(many[5].dissipated_energy[-1]) > 0
    for single, other in zip(singles, many):
        assert_same_run(single, other)


def test_simulate_batch_stacks_members_exactly_with_nan_padding(mixed):
    models, probes, dts, singles = mixed
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ElasticLimitWarning)
        ds = simulate_batch(models, DURATION, probes, dt=dts)
    assert ds.sizes["member"] == len(models)
    stored = sorted(set().union(*(s["contact"].values.tolist() for s in singles)))
    assert ds["contact"].values.tolist() == stored
    for i, single in enumerate(singles):
        row = ds.isel(member=i)
        for name, var in single.data_vars.items():
            sel = {d: single[d].values for d in var.dims if d != "time"}
            assert np.array_equal(row[name].sel(sel).values, var.values), (i, name)
        for key in ("dt", "n_steps"):
            assert row[key].item() == single.attrs[key]
        n = models[i].chain.n_beads
        assert row["n_beads"].item() == n
        assert row["n_contacts"].item() == n + int(models[i].wall.present)
        # Beyond the member's own chain there is nothing: NaN, not zeros.
        assert np.all(np.isnan(row["diameter"].sel(bead=slice(n + 1, None)).values))
        assert np.all(np.isnan(row["contact_force"].sel(contact=slice(n + 1, None)).values))
        if models[i].wall.present:
            assert row["peak_wall_force"].item() == single.attrs["peak_wall_force"]
        else:
            assert np.isnan(row["peak_wall_force"].item()) and np.all(np.isnan(row["wall_force"].values))
            assert np.all(np.isnan(row["contact_force"].sel(contact=n).values))
    # Member 1 stores only contacts 0 and 4: the others are NaN although they exist.
    assert np.all(np.isnan(ds["contact_force"].isel(member=1).sel(contact=2).values))


def test_many_compiled_calls_and_one_thread_change_nothing(mixed, monkeypatch):
    models, probes, dts, singles = mixed
    calls = []
    # A tiny work budget per call splits the run into one compiled call per few samples.
    monkeypatch.setattr(batch_engine, "CHUNK_SLOT_STEPS", 2e3)
    runs = run_batch(models, DURATION, probes, dt=dts, n_threads=1, progress=lambda d, t: calls.append((d, t)))
    n = singles[0].sizes["time"] - 1
    assert len(calls) > 10 and calls[-1] == (n, n)
    assert all(b[0] > a[0] for a, b in zip(calls, calls[1:]))
    for raw, single in zip(runs, singles):
        cols = np.searchsorted(raw.contacts, single["contact"].values)
        assert np.array_equal(raw.contact_force[:, cols], single.contact_force.values)
        assert np.array_equal(raw.kinetic_energy, single.kinetic_energy.values)
        assert raw.peak_wall_time == single.attrs["peak_wall_time"]


def test_bad_batches_name_the_field():
    m = Model(Chain.uniform(3, 10e-3), Striker(8e-3, 0.1))
    with pytest.raises(ConfigError) as e:
        simulate_many([m, m], DURATION, [Probes(INTERVAL), Probes(2 * INTERVAL)])
    assert e.value.field == "probes[1].sample_interval"
    with pytest.raises(ConfigError) as e:
        simulate_many([m], DURATION, Probes(INTERVAL), n_threads=0)
    assert e.value.field == "n_threads"
    with pytest.raises(ConfigError) as e:
        simulate_many([m], DURATION, Probes(INTERVAL, sensors=(7,)))
    assert e.value.field == "probes.sensors[0]"
    with pytest.raises(ConfigError) as e:
        simulate_many([], DURATION)
    assert e.value.field == "models"
    with pytest.raises(ConfigError) as e:
        simulate_many([m, m], DURATION, dt=[None])
    assert e.value.field == "run.dt"


def test_elastic_limit_warning_names_the_member():
    slow = Model(Chain.uniform(3, 10e-3), Striker(8e-3, 0.05))
    fast = Model(Chain.uniform(3, 10e-3), Striker(8e-3, 3.0))
    with pytest.warns(ElasticLimitWarning, match="member 1"):
        ds = simulate_batch([slow, fast], 4e-5, Probes(INTERVAL))
    assert ds["elastic_limit_exceeded"].values.tolist() == [0, 1]
