"""Tolerance ensembles: metrics-only recording, traces of chosen members, absolute and
lot-correlated tolerances (the statistical model of hertzchain.sweep.tolerances)."""

from __future__ import annotations

import copy

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from hertzchain.errors import ConfigError
from hertzchain.sweep import parse_sweep, run_sweep
from hertzchain.sweep.schema import chunk_members
from hertzchain.sweep.tolerances import Tolerances, perturb

# Tiny chains of 10 mm beads: 200 samples each, the wall pulse arrives before 1.5e-4 s.
BASE = {"chain": {"uniform": {"n": 3, "diameter_mm": 10.0}},
        "striker": {"diameter_mm": 8.0, "velocity": 0.2},
        "run": {"duration": 2e-4, "sample_interval": 1e-6}}


def ensemble(n: int = 40, chunk_size: int = 16, **sweep) -> dict:
    sw = {"mode": "random", "n": n, "chunk_size": chunk_size,
          "tolerances": {"diameter_rel": 2e-3, "offset_mm": 0.02, "seed": 5}, **sweep}
    return {"base": copy.deepcopy(BASE), "sweep": sw}


@pytest.fixture(scope="module")
def wall_run(tmp_path_factory):
    """The ensemble with every member's wall record kept (store = "wall", the default)."""
    return run_sweep(ensemble(), tmp_path_factory.mktemp("wall"))


def test_metrics_only_keeps_the_same_numbers_in_a_few_hundred_bytes_per_member(wall_run, tmp_path):
    spec = ensemble(store="metrics", traces=[5, 33])
    result = run_sweep(spec, tmp_path)
    # the metrics are those of the run that kept every record, number for number
    pd.testing.assert_frame_equal(result.metrics, wall_run.metrics, check_exact=True)
    chunks = sorted((tmp_path / "chunks").glob("chunk_*.nc"))
    with xr.open_dataset(chunks[0], engine="h5netcdf") as ds:
        assert "time" not in ds.dims and set(ds.dims) == {"member"}
        for name in ("F_m", "T", "tau", "Q_F", "Q_T", "peak_wall_force", "peak_wall_time", "kinetic_energy_end",
                     "potential_energy_end", "dissipated_energy_end", "force_over_yield"):
            assert ds[name].dims == ("member",) and ds[name].attrs["units"]
    # a few hundred bytes per member (what a member adds to a chunk file: chunk 0 holds 16 members,
    # chunk 2 the last 8; the file's headers, a few kB, are shared by a chunk's members)
    per_member = (chunks[0].stat().st_size - chunks[2].stat().st_size) / 8
    assert 100 < per_member < 300, per_member
    # the traced members' full records, in the chunk's traces file, as the wall store has them
    traces = {int(m): p for p in (tmp_path / "chunks").glob("traces_*.nc")
              for m in xr.open_dataset(p, engine="h5netcdf")["member"].values}
    assert sorted(traces) == [5, 33] and traces[5].name == "traces_00000.nc" and traces[33].name == "traces_00002.nc"
    with xr.open_dataset(traces[33], engine="h5netcdf") as tr, \
            xr.open_dataset(wall_run.out_dir / "chunks" / "chunk_00002.nc", engine="h5netcdf") as full:
        assert np.array_equal(tr["wall_force"].sel(member=33).values, full["wall_force"].sel(member=33).values)
        assert tr["F_m"].sel(member=33).item() == result.metrics.loc[33, "F_m"]
        assert "contact_force" in tr  # every probe of the base config (here: all contacts)


def test_a_chunk_whose_traces_file_is_lost_is_computed_again(tmp_path):
    spec = ensemble(store="metrics", traces=[5])
    first = run_sweep(spec, tmp_path)
    (tmp_path / "chunks" / "traces_00000.nc").unlink()
    again = run_sweep(spec, tmp_path)
    assert again.computed == [0] and again.skipped == [1, 2]
    pd.testing.assert_frame_equal(first.metrics, again.metrics, check_exact=True)


@pytest.mark.parametrize("changes, field", [
    ({"traces": [3]}, "sweep.traces"),  # only with store = "metrics"
    ({"store": "metrics", "traces": [40]}, "sweep.traces[0]"),
    ({"store": "metrics", "traces": [1, 1]}, "sweep.traces"),
    ({"tolerances": {"diameter_abs_mm": -0.1}}, "sweep.tolerances.diameter_abs_mm"),
    ({"tolerances": {"diameter_rel": [1e-3, 0.2, 0.0]}}, "sweep.tolerances.diameter_rel"),
    ({"tolerances": {"correlation": 1.5}}, "sweep.tolerances.correlation"),
    ({"tolerances": {"lot": "box"}}, "sweep.tolerances.lot"),
    ({"tolerances": {"velocity_abs": True}}, "sweep.tolerances.velocity_abs"),
])
def test_bad_ensemble_settings_name_the_field(changes, field):
    with pytest.raises(ConfigError) as e:
        parse_sweep(ensemble(**changes))
    assert e.value.field == field


def test_a_per_bead_list_of_the_wrong_length_names_the_field(tmp_path):
    with pytest.raises(ConfigError) as e:
        run_sweep(ensemble(tolerances={"diameter_abs_mm": [0.01, 0.02]}), tmp_path / "never")
    assert e.value.field == "sweep.tolerances.diameter_abs_mm" and "3 beads" in e.value.message
    assert not (tmp_path / "never").exists()


def _deviations(tol: dict, nominal_mm: np.ndarray, members: int = 4000) -> np.ndarray:
    """Diameter deviations [mm], shape (members, beads), of a chain of the given nominal sizes."""
    d = np.broadcast_to(nominal_mm * 1e-3, (members, nominal_mm.size))
    out = perturb(Tolerances(**tol), range(members), d, np.zeros_like(d), np.zeros(d.shape, dtype=np.int64),
                  np.full(members, 0.2))
    return (out["diameters"] - d) * 1e3


def test_relative_and_absolute_parts_add_as_independent_errors():
    nominal = np.array([26.0] * 4 + [13.0] * 4)
    rel = _deviations({"diameter_rel": 1e-3, "seed": 2}, nominal)
    assert np.allclose(rel.std(axis=0), nominal * 1e-3, rtol=0.05)
    both = _deviations({"diameter_rel": 1e-3, "diameter_abs_mm": 0.02, "seed": 2}, nominal)
    assert np.allclose(both.std(axis=0), np.hypot(nominal * 1e-3, 0.02), rtol=0.05)
    assert np.allclose(both.mean(axis=0), 0, atol=4 * 0.03 / np.sqrt(4000))
    # one value per bead: each bead its own spread
    per_bead = _deviations({"diameter_abs_mm": [0.01, 0.02, 0.03, 0.04, 0, 0, 0, 0.05]}, nominal)
    assert np.allclose(per_bead.std(axis=0), [0.01, 0.02, 0.03, 0.04, 0, 0, 0, 0.05], rtol=0.05, atol=1e-12)
    # uniform: the values are half-widths
    uni = _deviations({"diameter_abs_mm": 0.03, "distribution": "uniform"}, nominal)
    assert np.abs(uni).max() <= 0.03 and np.allclose(uni.std(axis=0), 0.03 / np.sqrt(3), rtol=0.05)


def test_beads_of_one_lot_correlate_by_the_given_coefficient():
    nominal = np.array([26.0] * 6 + [24.0, 22.0, 20.0])
    for lot in ("size", "chain"):
        dev = _deviations({"diameter_abs_mm": 0.02, "correlation": 0.6, "lot": lot}, nominal)
        c = np.corrcoef(dev.T)
        same_size = c[np.triu_indices(6, 1)]  # the 26 mm beads: one lot either way
        assert np.allclose(same_size, 0.6, atol=0.05), same_size
        other = c[0, 6:]  # a 26 mm bead and the tapered ones: one lot only with lot = "chain"
        assert np.allclose(other, 0.6 if lot == "chain" else 0.0, atol=0.05), (lot, other)
        assert np.allclose(dev.std(axis=0), 0.02, rtol=0.05)  # each bead keeps its spread
    independent = np.corrcoef(_deviations({"diameter_abs_mm": 0.02}, nominal).T)
    assert np.abs(independent[np.triu_indices(9, 1)]).max() < 0.06


def test_the_velocity_tolerance_and_the_array_set_up_match_the_models():
    tol = {"diameter_rel": 1e-3, "diameter_abs_mm": 0.01, "correlation": 0.3, "offset_mm": [0.01, 0.02, 0.0],
           "velocity_rel": 0.01, "velocity_abs": 0.002, "seed": 9}
    cfg = parse_sweep(ensemble(n=400, tolerances=tol))
    ens, _ = chunk_members(cfg, range(400))
    v = ens.striker_velocity
    assert v.std() == pytest.approx(np.hypot(0.01 * 0.2, 0.002), rel=0.1) and abs(v.mean() - 0.2) < 5e-4
    for i in (0, 7, 399):  # member by member (one Model each) and as arrays: the same numbers
        m = cfg.member_model(i)
        assert np.array_equal(m.chain.diameters, ens.diameters[i]) and np.array_equal(m.chain.offsets, ens.offsets[i])
        assert m.striker.velocity == ens.striker_velocity[i]
    assert np.all(ens.offsets[:, 2] == 0) and ens.offsets[:, 1].std() > ens.offsets[:, 0].std()


def test_relative_only_draws_are_those_documented():
    """diameter_rel alone: phi (1 + rel z), z from numpy's default_rng([seed, member, 1]) (the
    draws of earlier versions: an ensemble keeps its members)."""
    cfg = parse_sweep(ensemble(n=3, tolerances={"diameter_rel": 1e-3, "offset_mm": 0.02, "seed": 5}))
    ens, _ = chunk_members(cfg, range(3))
    for i in range(3):
        z = np.random.default_rng([5, i, 1]).standard_normal((2, 3))
        assert np.array_equal(ens.diameters[i], np.full(3, 10e-3) * (1.0 + 1e-3 * z[0]))
        assert np.array_equal(ens.offsets[i], np.zeros(3) + 0.02 * 1e-3 * z[1])


@pytest.mark.slow
@pytest.mark.parametrize("store", ["metrics", "wall"])
def test_peak_memory_of_a_sweep_is_within_its_estimate(tmp_path, store):
    """The sweep's estimate (hertzchain.sweep.runner.estimate_sweep) against the peak resident
    memory of the process that runs it (os.wait4), on chunks whose records dominate: 120 short
    chains recorded for 2e5 samples (~90 MB of records a chunk). benchmarks/memory_estimates.py
    does the same for every documented example."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    import tomli_w

    from hertzchain.sweep.runner import estimate_sweep

    spec = ensemble(n=240, chunk_size=120, store=store)
    spec["base"]["run"] = {"duration": 2e-2, "sample_interval": 1e-7}
    f = tmp_path / "s.toml"
    f.write_text(tomli_w.dumps(spec))
    est = estimate_sweep(parse_sweep(spec))
    assert est.memory_bytes > 80e6  # the records, not the interpreter, decide
    proc = subprocess.Popen([str(Path(sys.executable).parent / "hertzchain"), "sweep", str(f), "--out",
                             str(tmp_path / "out"), "-q"], stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    assert os.waitstatus_to_exitcode(status) == 0, proc.stderr.read()
    # the estimate the sweep's own (fresh) process makes: its job on top of the engine's runtime
    from hertzchain.checks import RUNTIME_BYTES

    ratio = usage.ru_maxrss * 1024 / (est.memory_bytes + RUNTIME_BYTES)
    assert 1 / 1.3 <= ratio <= 1.3, (ratio, usage.ru_maxrss * 1024, est)


def test_metrics_only_keeps_the_elastoplastic_and_body_metrics(tmp_path):
    """Members of the elastoplastic law at 2 m/s (past yield) hitting a protected body: the
    metrics-only chunks keep their plastic work, permanent overlap and body peaks, as the wall
    store's chunks have them."""
    base = {"chain": {"uniform": {"n": 4, "diameter_mm": 20.0}}, "striker": {"velocity": 2.0},
            "contact": {"law": "elastoplastic"}, "wall": {"type": "body", "mass": 1.0, "stiffness": 1e6},
            "run": {"duration": 4e-4, "sample_interval": 1e-6}}
    runs = {store: run_sweep({"base": base, "sweep": {"mode": "random", "n": 4, "chunk_size": 2, "store": store,
                                                      "tolerances": {"velocity_rel": 0.05, "seed": 2}}},
                             tmp_path / store).metrics for store in ("wall", "metrics")}
    pd.testing.assert_frame_equal(runs["wall"], runs["metrics"], check_exact=True)
    m = runs["metrics"]
    assert (m["plastic_work"] > 0).all() and (m["residual_overlap_max"] > 0).all() and (m["force_over_yield"] > 1).all()
    assert (m["peak_body_force"] > 0).all() and m["plastic_work"].std() > 0


def test_a_long_sweep_is_projected_on_the_cores_that_run_it(monkeypatch, tmp_path):
    """The time a sweep is projected to take, warned before it starts, is the members' one-core
    time shared by the cores the local engine runs each chunk on (sweep.n_threads, or every
    usable core); through a cluster, whose size is not known here, it is quoted for one core.
    The warning says on how many cores and what would be faster."""
    import hertzchain.checks as checks
    from hertzchain.errors import LongRunWarning
    from hertzchain.sweep import runner

    monkeypatch.setattr(checks, "NS_PER_BEAD_STEP", {"elastic": 1.0, "general": 1.0, "rkn4": 1.0, "rkn4_general": 1.0})
    cfg = parse_sweep(ensemble(n=8, chunk_size=4, n_threads=3, store="metrics"))
    projected = []
    real_check = checks.check_resources

    def record(est, **kwargs):
        projected.append(est.seconds)
        real_check(est, **kwargs)

    monkeypatch.setattr(checks, "check_resources", record)
    with pytest.warns(LongRunWarning, match=r"that is on 3 cores; fewer members \(sweep.n\)"):
        runner._plan(cfg, "auto", cores=3)
    on_three = projected[-1]
    with pytest.warns(LongRunWarning) as caught:
        runner._plan(cfg, "auto", cores=1)
    assert not any("cores" in str(w.message) for w in caught)
    assert projected[-1] == pytest.approx(3 * on_three, rel=1e-12)
    # run_sweep shares the time by sweep.n_threads when it runs locally
    monkeypatch.setattr(runner, "_plan", lambda cfg, device, cores=1, advice=None: (_ for _ in ()).throw(AssertionError(cores)))
    with pytest.raises(AssertionError, match="^3$"):
        run_sweep(cfg, tmp_path / "local", progress=None)
