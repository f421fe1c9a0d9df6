"""Design checkpoints are data: a planted pickle runs no code, a damaged file is named and kept aside,
and a resumed search replays to the state it was saved in (CMA-ES and NSGA-II) and ends as an
uninterrupted one."""

from __future__ import annotations

import io
import json
import pickle
import warnings

import numpy as np
import pytest

from hertzchain.cli.main import main
from hertzchain.design import parse_design, run_design
from hertzchain.design.checkpoint import _CHECKPOINT, _load, _read
from hertzchain.errors import CheckpointWarning

RUN = {"duration": 2.0e-3, "sample_interval": 1e-6}


def _design(**over) -> dict:
    d = {"base": {"chain": {"uniform": {"n": 4, "diameter_mm": 26.0}, "taper": {"n": 4, "q": 0.05}},
                  "striker": {"diameter_mm": 8.0, "velocity": 0.2}, "run": dict(RUN)},
         "design": {"objective": "peak_wall_force",
                    "variables": {"chain.taper.n": [2, 12], "chain.taper.q": [0.0, 0.15]},
                    "constraints": {"min_diameter_mm": 15.0}, "budget": 60, "seed": 3}}
    d["design"].update(over)
    return d


class _Payload:
    """What an attacker plants: unpickling it runs ``code`` (through NumPy's own helper that
    executes a string, which the allow-list of the pickle checkpoint let through)."""

    def __init__(self, code: str):
        self.code = code

    def __reduce__(self):
        from numpy.testing._private.utils import runstring

        return runstring, (self.code, {})


def _touch(marker) -> str:
    return f"open({str(marker)!r}, 'w').write('ran')"


def _killed(out, design: dict, after: int = 3) -> None:
    """Run the design in ``out`` and stop it (as Ctrl-C would) after ``after`` engine calls."""
    calls = []

    def killer(done, total):
        calls.append(done)
        if len(calls) == after:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_design(parse_design(design), out, progress=killer, checkpoint_interval=0)


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """An uninterrupted search and the checkpoint of the same search killed after 3 engine calls."""
    base = tmp_path_factory.mktemp("ref")
    ref = run_design(parse_design(_design()), base / "ref")
    _killed(base / "killed", _design())
    return ref, (base / "killed" / _CHECKPOINT).read_bytes()


def _edit_meta(good: bytes, edit) -> bytes:
    """The checkpoint ``good`` with its JSON document changed by ``edit(meta)`` (which may return
    raw bytes to store instead)."""
    with np.load(io.BytesIO(good), allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    meta = json.loads(arrays["meta"].tobytes())
    text = edit(meta)
    arrays["meta"] = np.frombuffer(text if text is not None else json.dumps(meta).encode(), np.uint8)
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def _plant(tmp_path, data: bytes):
    """A design folder holding the checkpoint ``data``."""
    out = tmp_path / "d"
    out.mkdir()
    (out / _CHECKPOINT).write_bytes(data)
    return out


def _same_search(a, b) -> None:
    assert [r["x"] for r in a.history] == [r["x"] for r in b.history]
    assert a.best["variables"] == b.best["variables"] and a.best["objective"] == b.best["objective"]
    assert a.n_evaluations == b.n_evaluations and a.generations == b.generations


@pytest.mark.parametrize("name", ["checkpoint.pkl", "checkpoint.npz"])
def test_a_planted_pickle_runs_no_code_and_the_user_is_told(tmp_path, reference, name):
    """The payload would create a file when unpickled: no code runs, a warning names the file, which is
    kept aside (renamed), and the search starts afresh and ends as an uninterrupted one."""
    ref, _ = reference
    marker = tmp_path / "ran"
    out = tmp_path / "d"
    out.mkdir()
    (out / name).write_bytes(pickle.dumps(_Payload(_touch(marker))))
    with pytest.warns(CheckpointWarning, match=name) as seen:
        res = run_design(parse_design(_design()), out)
    assert not marker.exists()
    assert "starts afresh" in str(seen[0].message)
    assert not res.resumed
    _same_search(res, ref)
    kept = list(out.glob(f"{name}.unreadable-*"))
    assert len(kept) == 1 and kept[0].read_bytes() == pickle.dumps(_Payload(_touch(marker)))


def test_an_npz_with_a_pickled_object_array_is_not_unpickled(tmp_path):
    """An archive whose arrays hold Python objects (np.save pickles them) is refused unread."""
    marker = tmp_path / "ran"
    out = tmp_path / "d"
    out.mkdir()
    buf = io.BytesIO()
    np.savez(buf, meta=np.array([_Payload(_touch(marker))], dtype=object))
    (out / _CHECKPOINT).write_bytes(buf.getvalue())
    problem = parse_design(_design())
    with pytest.warns(CheckpointWarning, match="not a NumPy .npz archive of plain arrays"):
        assert _load(out, problem, force=False) is None
    assert not marker.exists() and not (out / _CHECKPOINT).exists()


def test_cli_tells_about_a_planted_checkpoint_and_exits_0(tmp_path, capsys):
    import tomli_w

    marker = tmp_path / "ran"
    f = tmp_path / "d.toml"
    f.write_text(tomli_w.dumps(_design(polish=False)))
    out = tmp_path / "out"
    out.mkdir()
    (out / "checkpoint.pkl").write_bytes(pickle.dumps(_Payload(_touch(marker))))
    assert main(["design", str(f), "--out", str(out), "-q", "--no-html"]) == 0
    err = capsys.readouterr().err
    assert "warning:" in err and "checkpoint.pkl" in err and "never reads" in err
    assert not marker.exists()


@pytest.mark.parametrize("damage", ["truncated", "empty", "text", "bad-json", "wrong-type", "other-schema"])
def test_a_damaged_checkpoint_is_named_kept_aside_and_the_search_restarts(tmp_path, reference, damage):
    ref, good = reference
    data = {"truncated": lambda: good[: len(good) // 2], "empty": lambda: b"", "text": lambda: b"not a checkpoint\n",
            "bad-json": lambda: _edit_meta(good, lambda m: b"{" + json.dumps(m).encode()[:40]),
            "wrong-type": lambda: _edit_meta(good, lambda m: m["history"][0].update(x="0.5")),
            "other-schema": lambda: _edit_meta(good, lambda m: m.update(schema=99))}[damage]()
    out = _plant(tmp_path, data)
    with pytest.warns(CheckpointWarning, match=r"checkpoint\.npz: is damaged or not a design checkpoint"):
        res = run_design(parse_design(_design()), out)
    assert not res.resumed
    _same_search(res, ref)
    assert [p.read_bytes() for p in out.glob("checkpoint.npz.unreadable-*")] == [data]


def test_resumed_search_replays_to_the_saved_state_and_ends_as_uninterrupted(tmp_path, reference):
    """CMA-ES: the replay asks for the saved candidates, reaches the saved mean, sigma, covariance,
    counters and random streams (no CheckpointWarning), and goes on to the uninterrupted result."""
    ref, good = reference
    out = _plant(tmp_path, good)
    saved = _read(out / _CHECKPOINT, parse_design(_design()))
    assert saved.scalars["optimiser"] == "cma-es" and saved.generation >= 1
    assert {"cma_mean", "cma_C", "cma_pc", "cma_ps"} <= set(saved.arrays)
    assert "numpy_random_key" not in saved.arrays  # global state: not what defines the search
    with warnings.catch_warnings():
        warnings.simplefilter("error", CheckpointWarning)
        res = run_design(parse_design(_design()), out)
    assert res.resumed
    _same_search(res, ref)
    # The replay of a finished search's checkpoint is the whole search: the same result again.
    with warnings.catch_warnings():
        warnings.simplefilter("error", CheckpointWarning)
        again = run_design(parse_design(_design()), out)
    assert again.resumed
    _same_search(again, ref)


def test_a_checkpoint_that_replays_elsewhere_is_set_aside(tmp_path, reference):
    """A well-formed checkpoint whose candidates are not those the search asks for (an edited file, or
    one of another version) is reported and the search starts from its seed."""
    ref, good = reference
    out = _plant(tmp_path, _edit_meta(good, lambda m: m["history"][-1]["x"].__setitem__(0, 0.123456789)))
    with pytest.warns(CheckpointWarning, match="does not replay to the search it was saved from"):
        res = run_design(parse_design(_design()), out)
    assert not res.resumed
    _same_search(res, ref)


def test_replay_checks_the_optimiser_state(tmp_path, reference):
    """The saved CMA-ES state is compared with the replayed one: a sigma changed in its last digit is
    caught, reported and the search restarts."""
    ref, good = reference
    out = _plant(tmp_path, _edit_meta(good, lambda m: m["state"]["cma"].update(sigma=m["state"]["cma"]["sigma"]
                                                                                * (1.0 + 1e-12))))
    with pytest.warns(CheckpointWarning, match="replayed optimiser differs from the saved one in cma"):
        res = run_design(parse_design(_design()), out)
    assert not res.resumed
    _same_search(res, ref)


def test_nsga2_resumes_by_replay_to_its_saved_population(tmp_path):
    """Several objectives (NSGA-II, pymoo): the replay reaches the saved generation and population."""
    pytest.importorskip("pymoo")
    design = _design(objective=["peak_wall_force", "front_momentum_at_wall"], budget=40, population=8)
    ref = run_design(parse_design(design), tmp_path / "a")
    _killed(tmp_path / "b", design, after=3)
    saved = _read(tmp_path / "b" / _CHECKPOINT, parse_design(design))
    assert saved.scalars["optimiser"] == "nsga-ii" and "nsga_X" in saved.arrays
    with warnings.catch_warnings():
        warnings.simplefilter("error", CheckpointWarning)
        res = run_design(parse_design(design), tmp_path / "b")
    assert res.resumed
    assert [r["x"] for r in res.history] == [r["x"] for r in ref.history]
    def timeless(rows):
        return [{k: v for k, v in r.items() if k != "elapsed_s"} for r in rows]

    assert timeless(res.pareto) == timeless(ref.pareto)


#: Loaded at the start of a ``hertzchain design`` subprocess (``sitecustomize``): every engine call
#: appends the module that made it and its engine runs to the file HC_TEST_ENGINE_LOG, then waits
#: HC_TEST_ENGINE_DELAY seconds, so that a kill lands between generations, not after the end.
_HOOK = '''
import os, sys, time
if os.environ.get("HC_TEST_ENGINE_LOG"):
    from hertzchain.design import objectives as _objectives
    _evaluate = _objectives.Evaluator.evaluate

    def _counted(self, keys, configs):
        evs = _evaluate(self, keys, configs)
        with open(os.environ["HC_TEST_ENGINE_LOG"], "a") as log:
            caller = os.path.basename(sys._getframe(1).f_code.co_filename)
            log.write(f"{caller} {sum(ev.engine_runs for ev in evs)}\\n")
        time.sleep(float(os.environ.get("HC_TEST_ENGINE_DELAY", "0")))
        return evs

    _objectives.Evaluator.evaluate = _counted
'''


def _design_process(tmp_path, design_file, out, log: str, delay: float = 0.0):
    import os
    import subprocess
    import sys
    from pathlib import Path

    import hertzchain

    hook = tmp_path / "hook"
    hook.mkdir(exist_ok=True)
    (hook / "sitecustomize.py").write_text(_HOOK)
    src = str(Path(hertzchain.__file__).parents[1])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(hook), src, os.environ.get("PYTHONPATH", "")]),
           "HC_TEST_ENGINE_LOG": str(tmp_path / log), "HC_TEST_ENGINE_DELAY": str(delay)}
    return subprocess.Popen([sys.executable, "-m", "hertzchain.cli", "design", str(design_file), "--out", str(out),
                             "--no-html"], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _engine_runs(path) -> int:
    """The engine runs of the search logged by _HOOK (the report's comparison runs left out)."""
    rows = [line.split() for line in path.read_text().splitlines()] if path.exists() else []
    return sum(int(n) for caller, n in rows if caller != "report.py")


def test_a_killed_design_process_resumes_and_a_finished_one_replays_without_engine_runs(tmp_path, reference):
    """A real ``hertzchain design`` process, killed (SIGKILL) once its checkpoint is on disk, then
    rerun into the same --out by a new process: it continues the search (no warning, only the
    engine runs the killed one had not done, the uninterrupted search's result); rerun again, the
    finished search replays with no engine run at all."""
    import signal
    import time

    import tomli_w

    ref, _ = reference
    design_file = tmp_path / "d.toml"
    design_file.write_text(tomli_w.dumps(_design()))
    out = tmp_path / "out"
    proc = _design_process(tmp_path, design_file, out, "killed.log", delay=0.25)
    deadline = time.monotonic() + 120
    while not (out / _CHECKPOINT).exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=30)
    assert proc.returncode == -signal.SIGKILL  # killed, not finished
    saved = _read(out / _CHECKPOINT, parse_design(_design()))
    assert saved.phase != "done" and 1 <= saved.generation and 0 < saved.n_evaluations < ref.n_evaluations
    assert _engine_runs(tmp_path / "killed.log") >= saved.n_evaluations

    # The rerun, a new process: it replays what the killed one saved and computes only the rest.
    proc = _design_process(tmp_path, design_file, out, "resumed.log")
    stdout, stderr = proc.communicate(timeout=300)
    assert proc.returncode == 0, stderr
    assert "warning" not in stderr.lower() and "afresh" not in stderr, stderr
    assert "resumed" in " ".join(stdout.split())
    assert _engine_runs(tmp_path / "resumed.log") == ref.n_evaluations - saved.n_evaluations
    info = json.loads((out / "design.json").read_text())
    assert info["best"]["variables"] == ref.best["variables"] and info["best"]["objective"] == ref.best["objective"]
    assert info["n_evaluations"] == ref.n_evaluations
    # Once more (here, to count the engine runs): the finished search replays with none.
    from hertzchain.design import search

    runs = []
    real = search.Evaluator.evaluate

    def counted(self, keys, configs):
        evs = real(self, keys, configs)
        runs.append(sum(ev.engine_runs for ev in evs))
        return evs

    with pytest.MonkeyPatch.context() as mp, warnings.catch_warnings():
        warnings.simplefilter("error", CheckpointWarning)
        mp.setattr(search.Evaluator, "evaluate", counted)
        res = run_design(parse_design(_design()), out)
    assert res.resumed and sum(runs) == 0
    _same_search(res, ref)
    assert not list(out.glob("checkpoint.npz.unreadable-*"))


def _npz(members: dict[str, bytes]) -> bytes:
    """A zip archive of the raw ``members`` (stored, as np.savez writes them)."""
    import zipfile

    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_STORED) as z:
        for name, data in members.items():
            z.writestr(name, data)
    return buf.getvalue()


def _npy_declaring(shape, data: bytes) -> bytes:
    """A .npy member whose header declares ``shape`` float64 values, followed by ``data``."""
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": "<f8", "fortran_order": False, "shape": shape})
    return buf.getvalue() + data


def _members(good: bytes) -> dict[str, bytes]:
    import zipfile

    with zipfile.ZipFile(io.BytesIO(good)) as z:
        return {name: z.read(name) for name in z.namelist()}


@pytest.mark.parametrize("damage, why", [
    ("huge-shape", r"member 'cma_mean\.npy'.* declares shape \(1000000000000,\)"),
    ("non-array", r"member 'notes\.txt' is not a \.npy array"),
    ("object-array", r"member 'cma_C\.npy'.* holds object values"),
    ("short-array", r"member 'cma_mean\.npy'.* declares shape \(4,\)"),
])
def test_a_checkpoint_member_is_checked_before_it_is_allocated(tmp_path, reference, damage, why):
    """A member declaring 10**12 values (8 TB) in a few bytes, a member that is no .npy array, a
    pickled object array or a header that promises more than the member holds: set aside with a
    warning naming the member (not an internal error, not an allocation, not a blamed run.duration)."""
    _, good = reference
    members = _members(good)
    if damage == "huge-shape":
        members["cma_mean.npy"] = _npy_declaring((10**12,), b"\0" * 16)
    elif damage == "non-array":
        members["notes.txt"] = b"hello"
    elif damage == "object-array":
        buf = io.BytesIO()
        np.lib.format.write_array_header_1_0(buf, {"descr": "|O", "fortran_order": False, "shape": (1,)})
        members["cma_C.npy"] = buf.getvalue() + pickle.dumps([1])
    else:
        members["cma_mean.npy"] = _npy_declaring((4,), b"\0" * 16)
    data = _npz(members)
    out = _plant(tmp_path, data)
    with pytest.warns(CheckpointWarning, match="checkpoint.npz: is damaged or not a design checkpoint") as rec:
        assert _load(out, parse_design(_design()), force=False) is None
    assert any(__import__("re").search(why, str(w.message)) for w in rec), [str(w.message) for w in rec]
    assert [p.read_bytes() for p in out.glob("checkpoint.npz.unreadable-*")] == [data]


def test_a_checkpoint_that_links_out_of_its_folder_is_set_aside(tmp_path, reference):
    """checkpoint.npz, a symbolic link to a (valid) checkpoint outside the folder: not followed;
    the link is set aside with a warning, its target left alone."""
    _, good = reference
    outside = tmp_path / "elsewhere.npz"
    outside.write_bytes(good)
    out = tmp_path / "d"
    out.mkdir()
    (out / _CHECKPOINT).symlink_to(outside)
    with pytest.warns(CheckpointWarning, match=r"symbolic link to .*elsewhere\.npz, outside"):
        assert _load(out, parse_design(_design()), force=False) is None
    assert outside.read_bytes() == good
    assert [p.is_symlink() for p in out.glob("checkpoint.npz.unreadable-*")] == [True]


def test_a_fifo_named_checkpoint_is_set_aside_within_seconds(tmp_path):
    """A FIFO (named pipe) named checkpoint.npz: a reader that opened it would wait for a writer
    forever; it is refused at once (a subprocess, so that a hang fails the test by its timeout)."""
    import os
    import subprocess
    import sys
    import textwrap

    out = tmp_path / "d"
    out.mkdir()
    os.mkfifo(out / _CHECKPOINT)
    script = textwrap.dedent(f"""
        import warnings
        from hertzchain.design import parse_design
        from hertzchain.design.checkpoint import _load
        with warnings.catch_warnings(record=True) as rec:
            warnings.simplefilter("always")
            print(_load(__import__("pathlib").Path({str(out)!r}), parse_design({_design()!r}), False))
        print("|".join(str(w.message) for w in rec))
    """)
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("None") and "a FIFO (named pipe), not a regular file" in proc.stdout
    kept = list(out.glob("checkpoint.npz.unreadable-*"))
    assert len(kept) == 1 and __import__("stat").S_ISFIFO(os.lstat(kept[0]).st_mode)
