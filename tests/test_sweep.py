"""Sweeps: design (grid / random / tolerances), chunked resumable runs, Dask, errors, CLI."""

from __future__ import annotations

import concurrent.futures as cf
import copy
import json
import os
import sys

import numpy as np
import pandas as pd
import pytest

from hertzchain.sweep import runner as sweep_runner
from hertzchain.errors import ConfigError, HertzchainError
from hertzchain.sweep import SweepMismatch, load_sweep, parse_sweep, run_sweep

# Tiny chains of 10 mm beads: 200 samples each, the wall pulse arrives before 1.5e-4 s.
BASE = {"chain": {"uniform": {"n": 3, "diameter_mm": 10.0}},
        "striker": {"diameter_mm": 8.0, "velocity": 0.2},
        "run": {"duration": 2e-4, "sample_interval": 1e-6}}
GRID = {"mode": "grid", "chunk_size": 2,
        "parameters": {"striker.velocity": [0.1, 0.15, 0.2, 0.3], "chain.uniform.n": [3, 4]}}


def grid_sweep(**changes) -> dict:
    sw = copy.deepcopy(GRID)
    sw.update(changes)
    return {"base": copy.deepcopy(BASE), "sweep": sw}


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """An uninterrupted local run of the grid sweep (8 members, 4 chunks)."""
    out = tmp_path_factory.mktemp("reference")
    return run_sweep(grid_sweep(), out)


def test_grid_sweep_table_and_files(reference):
    df = reference.metrics
    cfg = parse_sweep(grid_sweep())
    assert cfg.n_members == 8 and len(cfg.chunks()) == 4
    # Cartesian product, last parameter fastest, each member's config carries its values.
    assert cfg.members[1] == {"striker.velocity": 0.1, "chain.uniform.n": 4}
    assert cfg.member_config(5)["striker"]["velocity"] == 0.2 and cfg.member_config(5)["chain"]["uniform"]["n"] == 4
    assert df["member"].tolist() == list(range(8))
    assert df["striker.velocity"].tolist() == [0.1, 0.1, 0.15, 0.15, 0.2, 0.2, 0.3, 0.3]
    assert df["chain.uniform.n"].tolist() == [3, 4] * 4
    assert (df["fit_error"] == "").all()
    # Physics: the fitted wall peak is the integrator's peak within the cos^6 fit error, and it
    # grows with the striker speed (F_m ~ V^(6/5) for a Hertzian impact).
    assert np.allclose(df["F_m"], df["peak_wall_force"], rtol=0.03)
    for n in (3, 4):
        f = df.loc[df["chain.uniform.n"] == n, "F_m"].to_numpy()
        assert np.all(np.diff(f) > 0)
        ratio = f[-1] / f[0]
        assert 0.7 * 3.0 ** 1.2 < ratio < 1.3 * 3.0 ** 1.2
    assert (df["T"] > 0).all() and (df["tau"] > 0).all() and (df["Q_F"] > 0).all()
    # Files: one chunk file per chunk, the definition and its hash, and the table on disk.
    files = sorted(p.name for p in (reference.out_dir / "chunks").iterdir())
    assert files == sorted([f"chunk_{i:05d}.nc" for i in range(4)] + [f"chunk_{i:05d}.nc.sha256" for i in range(4)])
    meta = json.loads((reference.out_dir / "sweep.json").read_text())
    assert meta["hash"] == cfg.hash and meta["n_members"] == 8
    on_disk = pd.read_csv(reference.metrics_path, keep_default_na=False, na_values=[""])
    assert np.array_equal(on_disk["F_m"].to_numpy(), df["F_m"].to_numpy())
    # Parquet only when pyarrow is there (it is not a dependency).
    import importlib.util
    assert (reference.out_dir / "metrics.parquet").exists() == (importlib.util.find_spec("pyarrow") is not None)


class Killed(Exception):
    pass


def test_killed_sweep_resumes_without_recomputing(tmp_path, reference, monkeypatch):
    out = tmp_path / "run"

    def kill_after_two_chunks(done, total):
        if done >= 4:  # chunk_size 2: the second chunk file has just been written
            raise Killed

    with pytest.raises(Killed):
        run_sweep(grid_sweep(), out, progress=kill_after_two_chunks)
    chunks = out / "chunks"
    assert sorted(p.name for p in chunks.iterdir()) == ["chunk_00000.nc", "chunk_00000.nc.sha256",
                                                        "chunk_00001.nc", "chunk_00001.nc.sha256"]
    assert not (out / "metrics.csv").exists()
    stamps = {p.name: p.stat().st_mtime_ns for p in chunks.iterdir()}
    # What a kill can leave behind: a half-written temporary file and, worse, an unreadable file
    # under a final name (e.g. copied in by hand): neither may be taken for a finished chunk.
    (chunks / ".chunk_00002.nc.999.tmp").write_bytes(b"half a chunk")
    (chunks / "chunk_00003.nc").write_bytes(b"not netcdf")

    computed = []
    real = sweep_runner.compute_chunk

    def counting(task):
        computed.append(task.index)
        return real(task)

    monkeypatch.setattr(sweep_runner, "compute_chunk", counting)
    seen = []
    result = run_sweep(grid_sweep(), out, progress=lambda d, t: seen.append(d))
    assert computed == [2, 3]
    assert result.skipped == [0, 1] and result.computed == [2, 3]
    assert seen == [4, 6, 8]  # the resumed members count as done from the start
    assert {p.name: p.stat().st_mtime_ns for p in chunks.iterdir() if p.name in stamps} == stamps
    assert not list(chunks.glob("*.tmp"))
    pd.testing.assert_frame_equal(result.metrics, reference.metrics, check_exact=True)


def test_other_sweep_in_the_same_folder_needs_force(tmp_path):
    small = grid_sweep(parameters={"striker.velocity": [0.2]})
    run_sweep(small, tmp_path)
    other = grid_sweep(parameters={"striker.velocity": [0.3]})
    with pytest.raises(SweepMismatch, match="--force"):
        run_sweep(other, tmp_path)
    assert isinstance(SweepMismatch("x"), HertzchainError)  # the CLI turns it into exit status 2
    result = run_sweep(other, tmp_path, force=True)
    assert result.computed == [0] and result.metrics["striker.velocity"].tolist() == [0.3]
    assert json.loads((tmp_path / "sweep.json").read_text())["hash"] == parse_sweep(other).hash
    # The order of the parameters orders the members: another order is another sweep.
    swapped = grid_sweep(parameters=dict(reversed(list(GRID["parameters"].items()))))
    assert parse_sweep(swapped).members[1] == {"chain.uniform.n": 3, "striker.velocity": 0.15}
    assert parse_sweep(swapped).hash != parse_sweep(grid_sweep()).hash


def test_dask_local_cluster_gives_the_same_metrics(tmp_path, reference):
    distributed = pytest.importorskip("distributed")
    from click.testing import CliRunner

    from hertzchain.cli.sweep import sweep

    toml = tmp_path / "grid.toml"
    toml.write_text(to_toml(grid_sweep()))
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:
            done = []
            result = run_sweep(grid_sweep(), tmp_path / "api", client=client, progress=lambda d, t: done.append(d))
        # The command line connects to the scheduler by its address.
        res = CliRunner().invoke(sweep, [str(toml), "--out", str(tmp_path / "cli"), "--quiet",
                                         "--scheduler", cluster.scheduler_address])
        assert res.exit_code == 0, res.output
    assert sorted(result.computed) == [0, 1, 2, 3] and done[-1] == 8
    assert len(list((tmp_path / "api" / "chunks").glob("chunk_*.nc"))) == 4
    pd.testing.assert_frame_equal(result.metrics, reference.metrics, check_exact=True)
    cli = pd.read_csv(tmp_path / "cli" / "metrics.csv")
    assert np.array_equal(cli["F_m"].to_numpy(), reference.metrics["F_m"].to_numpy())


def to_toml(d: dict) -> str:
    """A sweep mapping as TOML (the few value types used here)."""
    def value(v):
        if isinstance(v, dict):
            return "{ " + ", ".join(f"{json.dumps(k)} = {value(x)}" for k, x in v.items()) + " }"
        if isinstance(v, list):
            return "[" + ", ".join(value(x) for x in v) + "]"
        return json.dumps(v) if isinstance(v, str) else repr(v)
    return "".join(f"[{table}]\n" + "".join(f"{json.dumps(k)} = {value(v)}\n" for k, v in body.items())
                   for table, body in d.items())


class MapOnly:
    """The smallest 'client': only ``map`` (like multiprocessing.Pool.imap)."""

    def map(self, fn, items):
        return (fn(x) for x in items)


class SubmitGather:
    """A 'client' with submit and gather only (futures resolved on gather)."""

    def submit(self, fn, x):
        return (fn, x)

    def gather(self, future):
        fn, x = future
        return fn(x)


@pytest.mark.parametrize("make_client", [lambda: cf.ThreadPoolExecutor(2), MapOnly, SubmitGather],
                         ids=["executor", "map", "submit-gather"])
def test_other_clients_give_the_same_metrics(tmp_path, reference, make_client):
    client = make_client()
    try:
        result = run_sweep(grid_sweep(), tmp_path, client=client)
    finally:
        if hasattr(client, "shutdown"):
            client.shutdown()
    pd.testing.assert_frame_equal(result.metrics, reference.metrics, check_exact=True)


def random_sweep(n=6, seed=7, **tol) -> dict:
    sw = {"mode": "random", "n": n, "seed": seed, "chunk_size": 4,
          "parameters": {"striker.velocity": {"low": 0.1, "high": 0.4},
                         "striker.diameter_mm": {"low": 4.0, "high": 12.0, "log": True},
                         "chain.uniform.n": {"low": 2, "high": 5, "integer": True},
                         "striker.material": ["AISI52100", "brass"]}}
    if tol:
        sw["tolerances"] = tol
    return {"base": copy.deepcopy(BASE), "sweep": sw}


def test_random_design_is_reproducible_from_the_seed():
    a = parse_sweep(random_sweep())
    b = parse_sweep(random_sweep())
    assert a.members == b.members and a.hash == b.hash
    c = parse_sweep(random_sweep(seed=8))
    assert c.members != a.members and c.hash != a.hash
    # A member depends only on (seed, index): drawing more members keeps the first ones.
    assert parse_sweep(random_sweep(n=10)).members[:6] == a.members
    for m in parse_sweep(random_sweep(n=40)).members:
        assert 0.1 <= m["striker.velocity"] <= 0.4
        assert 4.0 <= m["striker.diameter_mm"] <= 12.0
        assert isinstance(m["chain.uniform.n"], int) and 2 <= m["chain.uniform.n"] <= 5
        assert m["striker.material"] in ("AISI52100", "brass")
    many = parse_sweep(random_sweep(n=40)).members
    assert len({m["chain.uniform.n"] for m in many}) == 4 and len({m["striker.material"] for m in many}) == 2


def test_tolerances_are_seeded_per_member_and_have_the_requested_size():
    def tol_sweep(n, seed=1):
        d = grid_sweep(parameters={"striker.velocity": [0.2] * n},
                       tolerances={"diameter_rel": 1e-3, "offset_mm": 0.05, "seed": seed})
        d["base"]["chain"]["uniform"]["n"] = 60
        return parse_sweep(d)

    models = tol_sweep(4).models()
    again = tol_sweep(6).models()
    for m, r in zip(models, again[:4]):  # same seed: same beads, whatever the number of members
        assert np.array_equal(m.chain.diameters, r.chain.diameters)
        assert np.array_equal(m.chain.offsets, r.chain.offsets)
    assert not np.array_equal(models[0].chain.diameters, models[1].chain.diameters)
    assert not np.array_equal(tol_sweep(1, seed=2).models()[0].chain.diameters, models[0].chain.diameters)
    rel = np.concatenate([m.chain.diameters / 10e-3 - 1 for m in models])
    off = np.concatenate([m.chain.offsets for m in models])
    assert 0.8e-3 < rel.std() < 1.2e-3 and abs(rel.mean()) < 3e-4
    assert 0.04e-3 < off.std() < 0.06e-3
    assert models[0].striker.diameter == 8e-3  # only the beads are perturbed


BAD = [
    ({"mode": "foo"}, "sweep.mode"),
    ({"chunk_size": 0}, "sweep.chunk_size"),
    ({"colour": 1}, "sweep.colour"),
    ({"parameters": {"striker..velocity": [0.1]}}, 'sweep.parameters["striker..velocity"]'),
    ({"parameters": {"wheel.size": [0.1]}}, 'sweep.parameters["wheel.size"]'),
    ({"parameters": {"striker.velocity": {"low": 0.1, "high": 0.2}}}, 'sweep.parameters["striker.velocity"]'),
    ({"parameters": {"striker.velocity": []}}, 'sweep.parameters["striker.velocity"]'),
    ({"parameters": {"run.duration": [1e-4]}}, 'sweep.parameters["run.duration"]'),
    ({"parameters": {"striker.velocity": [0.1, -0.2]}}, 'sweep.parameters["striker.velocity"]'),
    ({"parameters": {"chain.uniform.n": [3, -1]}}, 'sweep.parameters["chain.uniform.n"]'),  # 0: no chain, valid
    ({"parameters": {"chain.taper.q": [0.05]}}, "base.chain.taper.n"),
    ({"parameters": {"chain.diameters_mm[2]": [9.0]}}, 'sweep.parameters["chain.diameters_mm[2]"]'),
    ({"parameters": {}}, "sweep.parameters"),
    ({"tolerances": {"diameter_rel": -1e-3}}, "sweep.tolerances.diameter_rel"),
    ({"tolerances": {"offset": 0.1}}, "sweep.tolerances.offset"),
    ({"mode": "random"}, "sweep.n"),
    ({"n": 3}, "sweep.n"),
    ({"mode": "random", "n": 3, "parameters": {"striker.velocity": {"low": 0.3, "high": 0.2}}},
     'sweep.parameters["striker.velocity"].high'),
    ({"mode": "random", "n": 3, "parameters": {"striker.velocity": {"low": 0.3}}},
     'sweep.parameters["striker.velocity"].high'),
    ({"mode": "random", "n": 3, "parameters": {"striker.velocity": {"low": 0.0, "high": 0.2, "log": True}}},
     'sweep.parameters["striker.velocity"].low'),
]


@pytest.mark.parametrize("changes, field", BAD, ids=[f for _, f in BAD])
def test_bad_sweep_names_the_field(changes, field):
    with pytest.raises(ConfigError) as e:
        parse_sweep(grid_sweep(**changes))
    assert e.value.field == field


def test_bad_base_and_missing_tables_name_the_field(tmp_path):
    d = grid_sweep()
    d["base"]["striker"]["velocity"] = "fast"
    with pytest.raises(ConfigError) as e:
        parse_sweep(d)
    assert e.value.field == "base.striker.velocity"
    with pytest.raises(ConfigError) as e:
        parse_sweep({"base": BASE})
    assert e.value.field == "sweep"
    path = tmp_path / "broken.toml"
    path.write_text("[sweep\nmode = 'grid'")
    with pytest.raises(ConfigError, match="not valid TOML") as e:
        load_sweep(path)
    assert e.value.field == str(path)


def test_example_sweep_file_is_valid():
    here = os.path.dirname(__file__)
    cfg = load_sweep(os.path.join(here, "..", "examples", "sweep_taper.toml"))
    assert cfg.n_members == 12 and cfg.parameter_names == ["striker.velocity", "chain.taper.q"]
    assert [m.chain.n_beads for m in cfg.models()] == [24] * 12


def test_cli_runs_resumes_and_reports_user_errors(tmp_path):
    from click.testing import CliRunner

    from hertzchain.cli.sweep import sweep

    toml = tmp_path / "s.toml"
    toml.write_text(
        "[base]\nchain = { uniform = { n = 3, diameter_mm = 10.0 } }\nstriker = { velocity = 0.2 }\n"
        "run = { duration = 2e-4, sample_interval = 1e-6 }\n"
        "[sweep]\nchunk_size = 1\nparameters = { \"striker.velocity\" = [0.1, 0.2] }\n")
    out = tmp_path / "out"
    runner = CliRunner()
    res = runner.invoke(sweep, [str(toml), "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert "2 chunks computed, 0 resumed" in res.output
    assert len(pd.read_csv(out / "metrics.csv")) == 2
    res = runner.invoke(sweep, [str(toml), "--out", str(out), "--quiet"])
    assert res.exit_code == 0 and res.output == ""
    toml.write_text(toml.read_text().replace("chunk_size = 1", "chunk_size = 0"))
    res = runner.invoke(sweep, [str(toml), "--out", str(out)])
    assert isinstance(res.exception, ConfigError) and res.exception.field == "sweep.chunk_size"


def test_chunk_tasks_and_results_survive_pickling(tmp_path):
    """What a Dask worker in another process receives and sends back (processes=True pickles)."""
    import pickle

    cfg = parse_sweep(grid_sweep(parameters={"striker.velocity": [0.1, 0.2]},
                                 tolerances={"diameter_rel": 1e-3, "offset_mm": 0.02, "seed": 3}))
    captured = []
    real = sweep_runner.compute_chunk

    class Recorder:
        def map(self, fn, tasks):
            for t in tasks:
                captured.append(t)
                yield pickle.loads(pickle.dumps(real(pickle.loads(pickle.dumps(t)))))

    result = run_sweep(cfg, tmp_path / "pickled", client=Recorder())
    direct = run_sweep(cfg, tmp_path / "direct")
    assert len(captured) == 1 and captured[0].members == [0, 1]
    pd.testing.assert_frame_equal(result.metrics, direct.metrics, check_exact=True)
    # The tolerances reached the simulation: the stored beads are the perturbed ones.
    import xarray as xr
    with xr.open_dataset(tmp_path / "pickled" / "chunks" / "chunk_00000.nc", engine="h5netcdf") as ds:
        assert np.array_equal(ds["diameter"].values[0], cfg.models()[0].chain.diameters)
        assert np.array_equal(ds["offset"].values[1], cfg.models()[1].chain.offsets)
        assert not np.all(ds["offset"].values == 0)


def test_a_ctrl_c_swallowed_by_a_weakref_callback_still_stops_the_sweep(tmp_path, monkeypatch, default_sigint):
    """SIGINT handled while a weakref callback runs (as when the arrays of an engine call are
    freed): Python prints "Exception ignored" and drops that KeyboardInterrupt; one Ctrl-C in
    four to a sweep was lost that way and the sweep ran on. It must stop it all the same."""
    import signal
    import weakref

    class Freed:
        pass

    def interrupt_inside_a_callback(done: int, total: int) -> None:
        if done:  # after the first chunk is on disk
            obj = Freed()
            ref = weakref.ref(obj, lambda _: signal.raise_signal(signal.SIGINT))
            del obj  # the callback runs now; the handler raises inside it, where it is swallowed
            assert ref() is None

    swallowed = []  # what Python reports as "Exception ignored in ..."
    monkeypatch.setattr(sys, "unraisablehook", lambda u: swallowed.append(u.exc_type))
    with pytest.raises(KeyboardInterrupt):
        run_sweep(grid_sweep(), tmp_path, progress=interrupt_inside_a_callback)
    assert swallowed == [KeyboardInterrupt]  # it was swallowed once, as described
    assert sorted(p.name for p in (tmp_path / "chunks").glob("chunk_*.nc")) == ["chunk_00000.nc"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # the handler is put back
    again = run_sweep(grid_sweep(), tmp_path)  # and the sweep resumes where it stopped
    assert again.skipped == [0] and again.computed == [1, 2, 3]


def test_a_forced_sweep_killed_midway_keeps_the_old_results(tmp_path):
    """--force onto another sweep's folder, killed after its first chunk: the old sweep's results
    are whole (set aside, not deleted); the new sweep, forced again, resumes its finished chunk and,
    once complete, leaves no copy of the replaced results; forcing the old sweep back instead
    restores them without computing a chunk."""
    old_cfg = grid_sweep(parameters={"striker.velocity": [0.2]})
    new_cfg = grid_sweep(parameters={"striker.velocity": [0.2, 0.3]}, chunk_size=1)
    old = run_sweep(old_cfg, tmp_path)
    old_table = (tmp_path / "metrics.csv").read_bytes()
    calls = []

    def killer(done, total):
        calls.append(done)
        if len(calls) == 2:  # after the first chunk is on disk
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_sweep(new_cfg, tmp_path, force=True, progress=killer)
    kept = list(tmp_path.glob(".replaced-*"))
    assert len(kept) == 1 and (kept[0] / "metrics.csv").read_bytes() == old_table
    assert json.loads((kept[0] / "sweep.json").read_text())["hash"] == parse_sweep(old_cfg).hash
    assert len(list((kept[0] / "chunks").glob("chunk_*.nc"))) == 1
    new = run_sweep(new_cfg, tmp_path, force=True)
    assert new.skipped == [0] and new.computed == [1]
    assert not list(tmp_path.glob(".replaced-*"))
    # Killed again at the start of a forced run of the old sweep: forcing the new one back takes
    # its results back; forcing the old one completes it from its set-aside chunks.
    with pytest.raises(KeyboardInterrupt):
        run_sweep(old_cfg, tmp_path, force=True, progress=lambda d, t: (_ for _ in ()).throw(KeyboardInterrupt))
    assert len(list(tmp_path.glob(".replaced-*"))) == 1
    back = run_sweep(new_cfg, tmp_path, force=True)
    assert back.computed == [] and back.skipped == [0, 1]
    pd.testing.assert_frame_equal(back.metrics, new.metrics, check_exact=True)
    assert not list(tmp_path.glob(".replaced-*"))
    assert old.computed == [0]


def test_a_fifo_or_an_outside_link_among_the_chunks_is_never_read(tmp_path):
    """A received sweep folder whose chunk is a FIFO (reading it would wait forever: checked in a
    subprocess, so that a hang fails by its timeout) or a symbolic link out of the folder: the
    resumed sweep reads neither; the chunk is to be computed again, and replacing what is not a
    regular file is refused, naming it (exit 2 in the CLI)."""
    import shutil
    import subprocess
    import textwrap

    from hertzchain.errors import ConfigError

    small = grid_sweep(parameters={"striker.velocity": [0.2]})
    run_sweep(small, tmp_path / "a")
    shutil.copytree(tmp_path / "a", tmp_path / "b")
    fifo = tmp_path / "a" / "chunks" / "chunk_00000.nc"
    fifo.unlink()
    os.mkfifo(fifo)
    script = textwrap.dedent(f"""
        from pathlib import Path
        from hertzchain.sweep import parse_sweep
        from hertzchain.sweep.storage import _chunk_is_done
        cfg = parse_sweep({small!r})
        print(_chunk_is_done(Path({str(fifo)!r}), cfg.hash, cfg.chunks()[0]))
    """)
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0 and proc.stdout.strip() == "False", proc.stderr
    with pytest.raises(ConfigError, match=r"chunk_00000\.nc: exists and is a FIFO \(named pipe\)"):
        run_sweep(small, tmp_path / "a")
    link = tmp_path / "b" / "chunks" / "chunk_00000.nc"
    outside = tmp_path / "outside.nc"
    os.replace(link, outside)
    link.symlink_to(outside)  # the genuine chunk, with its genuine checksum beside the link
    with pytest.raises(ConfigError, match=r"chunk_00000\.nc: exists and is a symbolic link"):
        run_sweep(small, tmp_path / "b")


@pytest.mark.parametrize("damage", ["wrong-shape", "huge-declared", "text-metric"])
def test_a_chunk_with_a_valid_checksum_but_foreign_content_is_computed_again(tmp_path, damage):
    """A received chunk whose checksum was made to match (so it passes the SHA-256 check) but whose
    per-member variables are not the chunk's (F_m of another length, a member list declaring 10**12
    members, a metric of text): its declarations are checked before anything is read, and the chunk
    is computed again; the table is the uninterrupted sweep's."""
    import hashlib

    import h5py

    small = grid_sweep(parameters={"striker.velocity": [0.2, 0.3]})
    first = run_sweep(small, tmp_path)
    chunk = tmp_path / "chunks" / "chunk_00000.nc"
    with h5py.File(chunk, "r+") as f:
        if damage == "wrong-shape":
            del f["F_m"]
            f["F_m"] = np.ones(5)
        elif damage == "huge-declared":
            del f["member"]
            f.create_dataset("member", shape=(10**12,), dtype="i8", chunks=(1024,))
        else:
            del f["T"]
            f["T"] = np.array([b"abc", b"def"])
    (tmp_path / "chunks" / "chunk_00000.nc.sha256").write_text(hashlib.sha256(chunk.read_bytes()).hexdigest() + "\n")
    again = run_sweep(small, tmp_path)
    assert again.computed == [0]
    pd.testing.assert_frame_equal(again.metrics, first.metrics, check_exact=True)
