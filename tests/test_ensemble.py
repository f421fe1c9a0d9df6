"""Vectorised set-up (Ensemble): members built with array code give exactly the results of
simulate() on each member alone, and of the member-by-member batch (stacked Dataset identical)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import assert_same_run
from test_batch_stacking import assert_identical

from hertzchain import Chain, Dashpot, Model, Probes, Striker, Viscoelastic, Wall, simulate
from hertzchain.errors import ConfigError, ElasticLimitWarning
from hertzchain.runs.batch import simulate_batch, simulate_many, stack_results
from hertzchain.integrate.batch.ensemble import Ensemble, same_layout
from hertzchain.integrate.batch.systems import systems

DURATION = 2.5e-4  # s: the pulse reaches the wall of every member below
INTERVAL = 1e-6    # s
M = 4


def _perturbed(base: Model, seed: int, offsets: bool = False) -> dict:
    """Per-member arrays: tolerance-perturbed diameters (and offsets), several impact velocities."""
    rng = np.random.default_rng(seed)
    n = base.chain.n_beads
    out = {"diameters": base.chain.diameters * (1 + 2e-3 * rng.standard_normal((M, n))),
           "striker_velocity": rng.uniform(0.1, 0.4, M)}
    if offsets:
        out["offsets"] = 0.2e-3 * rng.standard_normal((M, n))
    return out


def ensembles() -> dict[str, Ensemble]:
    """One ensemble per feature the engine supports (each shares a layout across members)."""
    taper = Chain.uniform(4, 12e-3).append_taper(4, 0.06)
    mixed = Chain.from_diameters([10e-3, 9e-3, 11e-3, 10e-3], ("AISI52100", "glass", "brass", "AISI52100"))
    return {
        "elastic": Ensemble(Model(taper, Striker(8e-3, 0.3)), **_perturbed(Model(taper), 1)),
        "precompression": Ensemble(Model(Chain.uniform(5, 10e-3), Striker(8e-3, 0.2), precompression=2.0),
                                   precompression=[0.5, 1.0, 2.0, 4.0], striker_velocity=[0.1, 0.2, 0.3, 0.2]),
        "misaligned": Ensemble(Model(Chain.uniform(6, 10e-3), Striker(8e-3, 0.1)),
                               **_perturbed(Model(Chain.uniform(6, 10e-3)), 2, offsets=True)),
        "viscoelastic": Ensemble(Model(Chain.uniform(5, 8e-3, "brass"), Striker(8e-3, 0.15, "brass"),
                                       law=Viscoelastic(A=1e-6)), law_parameter=[0.0, 1e-7, 1e-6, 3e-6]),
        "dashpot_free_end": Ensemble(Model(Chain.uniform(3, 10e-3), Striker(8e-3, 0.2), wall=Wall("none"),
                                           law=Dashpot(gamma=5.0)), law_parameter=[1.0, 2.0, 5.0, 10.0],
                                     striker_diameter=[6e-3, 8e-3, 8e-3, 10e-3]),
        "materials_wall": Ensemble(Model(mixed, Striker(8e-3, 0.1, "stainless_steel"), wall=Wall("flat", "brass")),
                                   **_perturbed(Model(mixed), 3)),
        "materials_per_member": Ensemble.from_models([   # materials differ between members
            Model(Chain.uniform(4, 10e-3, "brass"), Striker(8e-3, 0.1, "brass")),
            Model(mixed, Striker(8e-3, 0.1), wall=Wall("flat", "glass")),
            Model(Chain.uniform(4, 10e-3), Striker(6e-3, 0.2, "stainless_steel")),
            Model(mixed.substitute(2, material="PTFE"), Striker(8e-3, 0.05))]),
    }


@pytest.fixture(scope="module", params=list(ensembles().items()), ids=lambda kv: kv[0])
def case(request):
    return request.param[1]


def test_systems_rows_are_model_system_bit_for_bit(case):
    sy = systems(case)
    for i in range(case.n_members):
        ref = case.model(i).system()
        for name in ("mass", "inv_mass", "kappa", "damping", "d0", "de", "dx0", "rsum", "fext", "v0", "yield_force"):
            assert np.array_equal(getattr(sy, name)[i], getattr(ref, name)), name
        assert np.array_equal(sy.max_overlap[i], ref.max_overlap())
        assert sy.max_frequency[i] == ref.max_frequency()
        assert bool(sy.general[i]) == ref.general


def test_ensemble_batch_equals_single_runs_and_member_by_member_stack(case):
    probes = Probes(INTERVAL, sensors=(2,), contacts=(0, 1)) if case.has_wall else Probes(INTERVAL, velocities=True)
    models = [case.model(i) for i in range(case.n_members)]
    dts = [None, None, 2e-9, None]  # one member on a fixed user step
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ElasticLimitWarning)
        fast = simulate_batch(case, DURATION, probes, dt=dts)
        slow = stack_results(simulate_many(models, DURATION, probes, dt=dts))
        singles = [simulate(m, DURATION, probes, dt=dt, integrator="verlet") for m, dt in zip(models, dts)]
        alone = [simulate_many([m], DURATION, probes, dt=dt)[0] for m, dt in zip(models, dts)]
    assert_identical(fast, slow)
    # the members really differ, and the pulse got somewhere
    assert len(set(fast["dt"].values.tolist())) > 1
    assert float(np.nanmax(fast["contact_force"].values)) > 1.0
    if case.has_wall:
        assert float(np.min(fast["peak_wall_force"].values)) > 0.1
    for i, single in enumerate(singles):
        assert_same_run(single, alone[i])
        assert np.array_equal(fast["kinetic_energy"].values[i], single["kinetic_energy"].values)
        assert fast["n_steps"].values[i] == single.attrs["n_steps"]


def test_list_of_models_of_one_layout_takes_the_array_path_with_same_result():
    ens = ensembles()["elastic"]
    models = [ens.model(i) for i in range(M)]
    assert same_layout(models) and not same_layout(models + [Model(Chain.uniform(3, 10e-3))])
    from_list = Ensemble.from_models(models)
    for name in ("diameters", "offsets", "striker_velocity", "striker_diameter", "precompression"):
        assert np.array_equal(getattr(from_list, name), getattr(ens, name)), name
    assert from_list.describe() == ens.describe()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ElasticLimitWarning)
        a = simulate_batch(models, DURATION, [Probes(INTERVAL)] * M)
        b = simulate_batch(ens, DURATION, Probes(INTERVAL))
    a.attrs.pop("created_utc"), b.attrs.pop("created_utc")
    assert a.identical(b)


def test_elastic_limit_warnings_name_the_member():
    base = Model(Chain.uniform(3, 10e-3), Striker(8e-3, 0.05))
    with pytest.warns(ElasticLimitWarning, match="member 1"):
        ds = simulate_batch(Ensemble(base, striker_velocity=[0.05, 3.0]), 4e-5, Probes(INTERVAL))
    assert ds["elastic_limit_exceeded"].values.tolist() == [0, 1]


def test_bad_member_values_name_the_field_and_member():
    base = Model(Chain.uniform(3, 10e-3), Striker(8e-3, 0.1))
    cases = [
        (dict(diameters=[[10e-3, 10e-3, 10e-3], [10e-3, -1.0, 10e-3]]), "chain.diameters[1]", "member 1"),
        (dict(striker_velocity=[0.1, 0.0, 0.2]), "striker.velocity", "member 1"),
        (dict(offsets=[[0, 0, 0], [0, 6e-3, 0]]), "chain.offsets", "member 1"),
        (dict(precompression=[1.0, -1.0]), "chain.precompression", "member 1"),
        (dict(law_parameter=[1.0, 2.0]), "contact.law", "elastic"),
        (dict(diameters=np.full((2, 4), 1e-2)), "chain.diameters", "shape"),
        (dict(striker_velocity=[0.1, 0.2], precompression=[1.0, 2.0, 3.0]), "n_members", "disagree"),
    ]
    for kwargs, field, text in cases:
        with pytest.raises(ConfigError) as e:
            Ensemble(base, **kwargs)
        assert e.value.field == field and text in str(e.value), (kwargs, e.value)
    with pytest.raises(ConfigError) as e:
        simulate_batch(Ensemble(base, striker_velocity=[0.1, 0.2]), DURATION, dt=[1e-3, None])
    assert e.value.field == "run.dt" and "member 0" in str(e.value)
    with pytest.raises(ConfigError) as e:
        simulate_batch(Ensemble(base, n_members=2), DURATION, Probes(INTERVAL, sensors=(5,)))
    assert e.value.field == "probes.sensors[0]"


def test_an_ensemble_with_different_probes_per_member_is_refused_naming_probes():
    """An Ensemble's members share one Probes: a list of different ones is a ConfigError naming
    ``probes`` (an AttributeError on None inside the run before; found by mypy). A list of equal
    ones is the one Probes."""
    model = Model(Chain.uniform(3, 10e-3), Striker(8e-3, 0.1))
    ens = Ensemble.from_models([model, model])
    with pytest.raises(ConfigError) as err:
        simulate_batch(ens, 2e-5, [Probes(1e-6), Probes(2e-6)])
    assert err.value.field == "probes" and "Ensemble" in err.value.message
    same = simulate_batch(ens, 2e-5, [Probes(1e-6), Probes(1e-6)])
    one = simulate_batch(ens, 2e-5, Probes(1e-6))
    np.testing.assert_array_equal(same.contact_force.values, one.contact_force.values)


def _tolerance_sweep(n: int = 6, **tol) -> dict:
    return {"base": {"chain": {"uniform": {"n": 5, "diameter_mm": 10.0}}, "striker": {"velocity": 0.2},
                     "run": {"duration": 1e-4, "sample_interval": 1e-6}},
            "sweep": {"mode": "grid", "chunk_size": 4, "parameters": {"striker.velocity": [0.1, 0.2] * (n // 2)},
                      "tolerances": {"diameter_rel": 1e-3, "offset_mm": 0.05, "seed": 4, **tol}}}


def test_sweep_members_as_one_ensemble_are_the_models_number_for_number():
    from hertzchain.integrate.batch.ensemble import Ensemble
    from hertzchain.sweep import parse_sweep
    from hertzchain.sweep.schema import chunk_members

    cfg = parse_sweep(_tolerance_sweep())
    ens, dts = chunk_members(cfg, range(6))
    models = [cfg.member_model(i) for i in range(6)]
    assert isinstance(ens, Ensemble) and len(ens) == len(models) == 6 and dts == [None] * 6
    assert ens.describe() == [__import__("json").dumps(m.describe()) for m in models]
    sy = systems(ens)
    for i, m in enumerate(models):
        ref = m.system()
        for name in ("mass", "kappa", "de", "dx0", "rsum", "v0", "yield_force"):
            assert np.array_equal(getattr(sy, name)[i], getattr(ref, name)), (i, name)
    # A chunk is built from its members alone: the same numbers as in the whole sweep.
    part, _ = chunk_members(cfg.subset([3, 4]), [3, 4])
    assert np.array_equal(part.diameters, ens.diameters[3:5]) and np.array_equal(part.offsets, ens.offsets[3:5])
    # members of different lengths cannot share arrays: the sweep then builds one Model per member
    mixed = _tolerance_sweep()
    mixed["sweep"]["parameters"] = {"chain.uniform.n": [3, 4]}
    assert isinstance(chunk_members(parse_sweep(mixed), range(2))[0], list)


def test_sweep_tolerances_out_of_range_name_the_field():
    from hertzchain.sweep import run_sweep

    with pytest.raises(ConfigError) as e:  # offsets of 6 mm (1 sigma) on 10 mm beads: not head-on contacts
        run_sweep(_tolerance_sweep(offset_mm=6.0), "/nonexistent/never-written")
    assert e.value.field == "sweep.tolerances" and "member" in str(e.value)


def test_cli_device_option(tmp_path, capsys):
    """--device is accepted; 'cuda' without a GPU is a user error naming the option (exit 2)."""
    from hertzchain.cli.main import main
    from hertzchain.integrate.cuda.launch import gpu_usable

    sweep = tmp_path / "s.toml"
    sweep.write_text('[base]\nchain = { uniform = { n = 3, diameter_mm = 10.0 } }\n'
                     'run = { duration = 1e-4, sample_interval = 1e-6 }\n'
                     '[sweep]\nparameters = { "striker.velocity" = [0.1, 0.2] }\n')
    assert main(["sweep", str(sweep), "--out", str(tmp_path / "cpu"), "--device", "cpu", "-q"]) in (0, None)
    assert (tmp_path / "cpu" / "metrics.csv").exists()
    if not gpu_usable():
        capsys.readouterr()
        assert main(["sweep", str(sweep), "--out", str(tmp_path / "gpu"), "--device", "cuda", "-q"]) == 2
        err = capsys.readouterr().err
        assert "--device" in err and "Traceback" not in err


@pytest.mark.filterwarnings("ignore::hertzchain.errors.ElasticLimitWarning")
def test_configs_and_the_member_by_member_fallback_give_the_same_dataset(monkeypatch):
    """Per-member configs are stored as given; a variable the array path does not know (one
    added to run_fields later) makes it stack member by member, with the same result."""
    from hertzchain.runs import batch_results

    ens = ensembles()["viscoelastic"]
    models = [ens.model(i) for i in range(M)]
    configs = [{"member": i, "note": "x" * i} for i in range(M)]
    probes = Probes(INTERVAL, sensors=(3,))
    fast = simulate_batch(ens, DURATION, probes, configs=configs)
    slow = stack_results(simulate_many(models, DURATION, probes, configs=configs))
    assert_identical(fast, slow)
    monkeypatch.setattr(batch_results, "_KNOWN", batch_results._KNOWN - {"sensor_force"})
    fallback = simulate_batch(ens, DURATION, probes, configs=configs)
    assert_identical(fallback, slow)


def test_ensemble_copies_inputs_and_subsets_by_index_slice_or_mask():
    base = Model(Chain.uniform(3, 10e-3), Striker(8e-3, 0.1))
    d = np.full((4, 3), 10e-3)
    v = np.array([0.1, 0.2, 0.3, 0.4])
    ens = Ensemble(base, diameters=d, striker_velocity=v)
    d[0, 0] = 5e-3  # the caller's arrays stay writable and are not shared
    assert d.flags.writeable and ens.diameters[0, 0] == 10e-3 and not ens.diameters.flags.writeable
    for rows, want in (([3, 0], [0.4, 0.1]), (slice(1, 3), [0.2, 0.3]), (v > 0.25, [0.3, 0.4])):
        sub = ens.subset(rows)
        assert sub.striker_velocity.tolist() == want and [m.striker.velocity for m in sub] == want
    listed = Ensemble.from_models([base, Model(Chain.uniform(3, 11e-3), Striker(8e-3, 0.1))])
    assert listed.subset(np.array([False, True])).model(0).chain.diameters.tolist() == [11e-3] * 3
