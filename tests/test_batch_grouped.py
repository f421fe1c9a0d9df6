"""Batched engine: mixed-layout batches set up with array code, one group of members sharing the
end, contact law kind and Probes at a time (an Ensemble when they share the bead count too, else
ragged: padded to the longest chain).

Every member's results must be bit for bit those of :func:`hertzchain.simulate` run on it alone,
whatever the order of the members and however the groups interleave.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import assert_same_run

from hertzchain import Chain, Dashpot, Model, Probes, Striker, Viscoelastic, Wall, simulate
from hertzchain.contact import ScaledViscoelastic
from hertzchain.errors import ConfigError, ElasticLimitWarning
from hertzchain.runs import batch
from hertzchain.integrate.batch import pack as batch_pack
from hertzchain.runs.batch import run_batch, simulate_batch, simulate_many
from hertzchain.integrate.batch.ensemble import Ensemble, layout_key, same_layout
from hertzchain.integrate.batch.ragged import Ragged

DURATION = 2.5e-4  # s: the pulse reaches the wall of every chain below
INTERVAL = 1e-6    # s


def grouped_models() -> list[Model]:
    """Bead counts 3 to 6, a free end and a wall, three laws, two materials, offsets, precompression;
    several members per end and law, shuffled so that the groups interleave."""
    visco = Viscoelastic(A=1e-6)
    models = [
        Model(Chain.uniform(4, 10e-3), Striker(8e-3, 0.2)),
        Model(Chain.uniform(2, 12e-3).append_taper(3, 0.08), Striker(6e-3, 0.3)),
        Model(Chain.uniform(4, 10e-3), Striker(8e-3, 0.2), precompression=2.0),
        Model(Chain.uniform(4, 9e-3, "brass"), Striker(8e-3, 0.15, "brass")),
        Model(Chain.uniform(4, 10e-3).with_offsets({2: 0.3e-3}), Striker(8e-3, 0.1)),
        Model(Chain.uniform(6, 10e-3), Striker(8e-3, 0.2), law=visco),
        Model(Chain.uniform(6, 8e-3, "brass"), Striker(8e-3, 0.25), law=visco, precompression=1.0),
        Model(Chain.uniform(5, 11e-3).with_offsets({3: -0.2e-3}), Striker(7e-3, 0.2), law=visco),
        Model(Chain.uniform(5, 10e-3), Striker(8e-3, 0.2), wall=Wall("none")),
        Model(Chain.uniform(3, 9e-3), Striker(8e-3, 0.3), wall=Wall("none")),
        Model(Chain.uniform(3, 10e-3), Striker(8e-3, 0.2), law=Dashpot(gamma=5.0)),
        Model(Chain.uniform(3, 9e-3, "brass"), Striker(8e-3, 0.2), law=Dashpot(gamma=2.0)),
        Model(Chain.from_diameters([10e-3, 9e-3, 11e-3, 10e-3], ("AISI52100", "brass", "AISI52100", "brass")),
              Striker(8e-3, 0.1), wall=Wall("flat", "brass")),
    ]
    order = np.random.default_rng(3).permutation(len(models))
    return [models[i] for i in order]


def singles(models, probes):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ElasticLimitWarning)
        return [simulate(m, DURATION, probes, integrator="verlet") for m in models]


@pytest.fixture(scope="module")
def grouped():
    models = grouped_models()
    probes = Probes(INTERVAL, sensors=(2,))
    return models, probes, singles(models, probes)


def test_groups_interleave_and_hold_several_members(grouped):
    models, probes, _ = grouped
    groups = batch_pack._groups(models, [probes] * len(models))
    rows = np.concatenate([g.rows for g in groups])
    assert sorted(rows.tolist()) == list(range(len(models)))
    assert len(groups) == 4 and max(g.ens.n_members for g in groups) == 6
    assert sum(isinstance(g.ens, Ragged) for g in groups) == 3
    assert not all(np.array_equal(g.rows, np.arange(g.rows[0], g.rows[0] + g.rows.size)) for g in groups)
    for g in groups:  # one end and law per group, its members in the batch's order
        members = [models[i] for i in g.rows]
        assert len({layout_key(m)[1:] for m in members}) == 1 and np.all(np.diff(g.rows) > 0)
        assert isinstance(g.ens, Ragged) != same_layout(members)


def test_mixed_layouts_equal_single_runs_bit_for_bit(grouped, monkeypatch):
    models, probes, alone = grouped

    def refuse(*args, **kwargs):
        raise AssertionError("this batch must be set up with array code")

    monkeypatch.setattr(batch, "_setup_members", refuse)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ElasticLimitWarning)
        many = simulate_many(models, DURATION, probes)
    # not vacuous: pulses at the walls, dissipation, precompression, distinct steps
    assert len({ds.attrs["dt"] for ds in many}) > 5
    assert all(float(ds.wall_force.max()) > 1.0 for ds in many if "wall_force" in ds)
    assert any(float(ds.dissipated_energy[-1]) > 0 for ds in many)
    assert any(ds.potential_energy.values[0] > 0 for ds in many)  # precompressed at t = 0
    for single, other in zip(alone, many):
        assert_same_run(single, other)


def test_grouped_engine_arrays_and_member_systems(grouped):
    """run_batch's RawRuns equal the single runs'; its MemberSystems hold Model.system()'s rows."""
    models, probes, alone = grouped
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ElasticLimitWarning)
        runs, systems = run_batch(models, DURATION, probes, return_systems=True)
    for raw, single, sy, model in zip(runs, alone, systems, models):
        ref = model.system()
        assert sy.n_beads == ref.n_beads and sy.n_contacts == ref.n_contacts and sy.has_wall == ref.has_wall
        assert np.array_equal(sy.kappa, ref.kappa) and np.array_equal(sy.yield_force, ref.yield_force)
        cols = np.searchsorted(raw.contacts, single["contact"].values)
        assert np.array_equal(raw.contact_force[:, cols], single.contact_force.values)
        assert np.array_equal(raw.max_force, single.max_contact_force.values)
        assert np.array_equal(raw.dissipated_energy, single.dissipated_energy.values)
        assert raw.dt == single.attrs["dt"] and raw.n_steps == single.attrs["n_steps"]
        if model.wall.present:
            assert raw.peak_wall_force == single.attrs["peak_wall_force"]


def test_mixed_stacked_batch_equals_stacked_single_runs(grouped):
    models, probes, alone = grouped
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ElasticLimitWarning)
        ds = simulate_batch(models, DURATION, probes)
    for i, single in enumerate(alone):
        row = ds.isel(member=i)
        for name, var in single.data_vars.items():
            sel = {d: single[d].values for d in var.dims if d != "time"}
            assert np.array_equal(row[name].sel(sel).values, var.values), (i, name)


def test_user_steps_per_member_in_a_mixed_batch(grouped):
    models, probes, alone = grouped
    dts = [1e-8 if i % 3 == 0 else None for i in range(len(models))]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ElasticLimitWarning)
        many = simulate_many(models, DURATION, probes, dt=dts)
        for model, dt, other in zip(models, dts, many):
            if dt is not None:
                assert_same_run(simulate(model, DURATION, probes, dt=dt, integrator="verlet"), other)
        with pytest.raises(ConfigError, match="member 4: time step"):
            simulate_many(models, DURATION, probes, dt=[None] * 4 + [1e-3] + [None] * (len(models) - 5))


def scaled_models() -> list[Model]:
    law = ScaledViscoelastic(A=1e-6, diameter=26e-3)
    return [Model(Chain.uniform(5, d), Striker(8e-3, 0.2), law=law) for d in (20e-3, 26e-3)]


def test_size_scaled_law_is_set_up_member_by_member():
    """Its damping depends on each contact's masses, which the array set-up does not compute:
    such batches (one layout or mixed) go member by member and stay identical to single runs."""
    models = scaled_models()
    assert not same_layout(models)
    with pytest.raises(ConfigError, match="contact.law"):
        Ensemble(models[0])
    probes = Probes(INTERVAL)
    alone = singles(models, probes)
    mixed = models + [Model(Chain.uniform(3, 10e-3), Striker(8e-3, 0.2))]
    assert batch_pack._groups(mixed, [probes] * 3) is None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ElasticLimitWarning)
        ds = simulate_batch(models, DURATION, probes)
        many = simulate_many(mixed, DURATION, probes)
    assert float(ds.dissipated_energy[0, -1]) > 0
    for i, single in enumerate(alone):
        assert np.array_equal(ds.contact_force.values[i], single.contact_force.values)
        assert_same_run(single, many[i])
