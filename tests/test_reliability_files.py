"""No lost or corrupt files: special targets, full disk, permissions, concurrent writers, a killed
save, a damaged sweep chunk, a second sweep on the same folder (issue 10, part 4)."""

from __future__ import annotations

import errno
import hashlib
import json
import multiprocessing as mp
import os
import shutil
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import hertzchain as hc
from hertzchain import fileio
from hertzchain.cli.main import main
from hertzchain.errors import ConfigError

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
SMALL_RUN = '[chain]\nuniform = {n = 3, diameter_mm = 26.0}\n[striker]\nvelocity = 0.2\n[run]\nduration = 2e-4\nsample_interval = 1e-6\n'


def leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".tmp"))


# ---------------------------------------------------------------------------- special targets
@pytest.mark.parametrize("kind", ["symlink", "fifo", "folder"])
def test_special_target_is_refused_and_left_alone(tmp_path, kind):
    target = tmp_path / "out.nc"
    if kind == "symlink":
        (tmp_path / "elsewhere.nc").write_bytes(b"keep me")
        target.symlink_to(tmp_path / "elsewhere.nc")
    elif kind == "fifo":
        os.mkfifo(target)
    else:
        target.mkdir()
    words = {"symlink": "symbolic link", "fifo": "FIFO", "folder": "a folder"}[kind]
    with pytest.raises(ConfigError, match=words) as info:
        fileio.write_text(target, "new")
    assert info.value.field == str(target)
    assert os.path.lexists(target) and leftovers(tmp_path) == []
    if kind == "symlink":
        assert target.is_symlink() and (tmp_path / "elsewhere.nc").read_bytes() == b"keep me"


def test_device_target_is_refused(tmp_path):
    with pytest.raises(ConfigError, match="character device"):
        fileio.check_target("/dev/null")


def test_cli_run_refuses_a_fifo_out_before_simulating(tmp_path, capsys):
    cfg = tmp_path / "c.toml"
    cfg.write_text(SMALL_RUN)
    fifo = tmp_path / "pipe.nc"
    os.mkfifo(fifo)
    assert main(["run", str(cfg), "--out", str(fifo), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {fifo}: exists and is a FIFO") and "Traceback" not in err
    assert fifo.is_fifo()


# ---------------------------------------------------------------------------- disk full, permissions
@pytest.mark.parametrize("code,words", [(errno.ENOSPC, "no space left"), (errno.EACCES, "permission denied"),
                                        (errno.EBUSY, "busy or locked")])
def test_write_error_is_clean_and_removes_the_partial_file(tmp_path, monkeypatch, code, words):
    target = tmp_path / "r.nc"
    target.write_bytes(b"previous result")

    def failing_write(self, data):  # half the data reaches the temporary file, then the disk is full
        with open(self, "wb") as fh:
            fh.write(data[: len(data) // 2])
        raise OSError(code, os.strerror(code), str(self))

    monkeypatch.setattr(Path, "write_bytes", failing_write)
    with pytest.raises(ConfigError, match=words) as info:
        fileio.write_bytes(target, b"x" * 1000)
    assert info.value.field == str(target) and "partial file was removed" in info.value.message
    assert target.read_bytes() == b"previous result" and leftovers(tmp_path) == []


def test_save_on_a_full_disk_is_an_error_not_a_crash(tmp_path, monkeypatch, capsys):
    """Issue: a full disk during the save ended in a segmentation fault (HDF5 writing the file)."""
    cfg = tmp_path / "c.toml"
    cfg.write_text(SMALL_RUN)

    def full(fd, data):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(os, "fsync", lambda fd: full(fd, b""))
    assert main(["run", str(cfg), "--out", str(tmp_path / "r.nc"), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {tmp_path / 'r.nc'}: cannot be written: no space left on the device")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.toml"]


def test_new_files_get_ordinary_permissions(tmp_path):
    mask = os.umask(0o022)
    try:
        fileio.write_text(tmp_path / "a.txt", "x")
    finally:
        os.umask(mask)
    assert (tmp_path / "a.txt").stat().st_mode & 0o777 == 0o644


def test_json_text_writes_null_for_nan():
    text = fileio.json_text({"a": float("nan"), "b": [np.float64(np.inf), np.float32(1.5), 2], "c": np.int64(3)})
    assert json.loads(text) == {"a": None, "b": [None, 1.5, 2], "c": 3}
    assert "NaN" not in text and "Infinity" not in text


# ---------------------------------------------------------------------------- concurrent writers, killed save
def _writer(path: str, tag: int, n: int) -> None:
    for i in range(n):
        fileio.write_text(path, json.dumps({"writer": tag, "i": i, "pad": "x" * 50_000}))


def test_concurrent_writers_leave_one_whole_file(tmp_path):
    """Issue: two runs on the same --out shared a temporary name and left an unreadable file."""
    target = tmp_path / "shared.json"
    ctx = mp.get_context("fork")
    procs = [ctx.Process(target=_writer, args=(str(target), tag, 40)) for tag in range(3)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(60)
    assert [p.exitcode for p in procs] == [0, 0, 0]
    last = json.loads(target.read_text())
    assert last["i"] == 39 and len(last["pad"]) == 50_000
    assert leftovers(tmp_path) == []


def _cli_run(argv: list[str]) -> None:
    sys.exit(main(argv))


def test_two_cli_runs_on_the_same_out(tmp_path):
    """The issue's case: two `hertzchain run` writing one --out (forked: no second import)."""
    cfg = tmp_path / "c.toml"
    cfg.write_text(SMALL_RUN)
    out = tmp_path / "r.nc"
    main(["run", str(cfg), "--out", str(tmp_path / "warm.nc"), "-q"])  # compile before forking
    (tmp_path / "warm.nc").unlink()
    ctx = mp.get_context("fork")
    procs = [ctx.Process(target=_cli_run, args=(["run", str(cfg), "--out", str(out), "-q"],)) for _ in range(3)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(120)
    assert [p.exitcode for p in procs] == [0, 0, 0]
    ds = hc.load(out)  # one whole file from one of them
    assert ds.time.size == 201 and np.all(np.isfinite(ds.contact_force.values))
    assert leftovers(tmp_path) == []


def test_killed_save_leaves_the_previous_file(tmp_path):
    target = tmp_path / "big.bin"
    target.write_bytes(b"old")
    script = textwrap.dedent(f"""
        import os, sys
        from hertzchain import fileio
        with fileio.atomic_path({str(target)!r}) as tmp:
            with open(tmp, "wb") as fh:
                fh.write(b"x" * 1000)
                fh.flush()
                print("writing", flush=True)
                os.kill(os.getpid(), 9)
    """)
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert proc.returncode == -signal.SIGKILL and "writing" in proc.stdout
    assert target.read_bytes() == b"old"  # never half a file under the final name


# ---------------------------------------------------------------------------- sweeps
def small_sweep(velocities=(0.1, 0.2, 0.3, 0.4)) -> dict:
    return {"base": {"chain": {"uniform": {"n": 3, "diameter_mm": 26.0}},
                     "run": {"duration": 4e-4, "sample_interval": 1e-6}},
            "sweep": {"parameters": {"striker.velocity": list(velocities)}, "chunk_size": 2}}


def test_damaged_chunk_is_recomputed_on_resume(tmp_path):
    """Issue: a chunk damaged on disk was taken as finished and its numbers reached metrics.csv."""
    first = hc.run_sweep(small_sweep(), tmp_path)
    chunk = tmp_path / "chunks" / "chunk_00001.nc"
    recorded = (tmp_path / "chunks" / "chunk_00001.nc.sha256").read_text().strip()
    assert recorded == hashlib.sha256(chunk.read_bytes()).hexdigest()
    data = bytearray(chunk.read_bytes())
    data[len(data) // 2] ^= 0xFF  # one flipped byte (bit rot): the file may still open, its numbers are wrong
    chunk.write_bytes(bytes(data))
    again = hc.run_sweep(small_sweep(), tmp_path)
    assert again.skipped == [0] and again.computed == [1]
    pd.testing.assert_frame_equal(again.metrics, first.metrics, check_exact=True)
    assert hashlib.sha256(chunk.read_bytes()).hexdigest() == recorded  # deterministic: same bytes


def test_second_sweep_on_the_same_folder_is_refused(tmp_path, capsys):
    from hertzchain.sweep import SweepLocked, parse_sweep
    from hertzchain.sweep.storage import _folder_lock

    tmp_path.mkdir(exist_ok=True)
    with _folder_lock(tmp_path):
        code = subprocess.run([sys.executable, "-c", textwrap.dedent(f"""
            import sys, json
            from hertzchain.cli.main import main
            open({str(tmp_path / 's.toml')!r}, 'w').write('''
            [base]
            chain = {{uniform = {{n = 3, diameter_mm = 26.0}}}}
            run = {{duration = 4e-4, sample_interval = 1e-6}}
            [sweep]
            parameters = {{"striker.velocity" = [0.1]}}
            ''')
            sys.exit(main(['sweep', {str(tmp_path / 's.toml')!r}, '--out', {str(tmp_path)!r}, '-q']))
        """)], capture_output=True, text=True, timeout=120)
        assert code.returncode == 2, code.stderr
        assert "in use by another sweep" in code.stderr and str(os.getpid()) in code.stderr
        with pytest.raises(SweepLocked):
            hc.run_sweep(small_sweep(), tmp_path)
    assert not (tmp_path / "sweep.json").exists()
    hc.run_sweep(parse_sweep(small_sweep((0.1,))), tmp_path)  # lock released: the sweep runs


def test_invalid_sweep_writes_nothing(tmp_path):
    """Issue: an invalid sweep still wrote sweep.json, which then blocked the corrected sweep."""
    bad = small_sweep()
    bad["base"]["chain"]["truncate"] = 9  # valid schema, but only 3 beads: fails when models are built
    out = tmp_path / "out"
    with pytest.raises(ConfigError, match=r"chain\.truncate"):
        hc.run_sweep(bad, out)
    assert not out.exists()
    good = hc.run_sweep(small_sweep(), out)  # the corrected sweep is not blocked
    assert good.computed == [0, 1]


def test_missing_folder(tmp_path, capsys):
    with pytest.raises(ConfigError, match="its folder does not exist"):
        fileio.write_text(tmp_path / "nope" / "a.txt", "x")
    cfg = tmp_path / "c.toml"
    cfg.write_text(SMALL_RUN)
    # hertzchain run creates the result's folder, as before
    assert main(["run", str(cfg), "--out", str(tmp_path / "new" / "r.nc"), "-q"]) == 0
    assert hc.load(tmp_path / "new" / "r.nc").time.size == 201


def test_out_that_is_the_input_is_refused(tmp_path, capsys):
    cfg = tmp_path / "c.toml"
    cfg.write_text(SMALL_RUN)
    assert main(["run", str(cfg), "--out", str(cfg)]) == 2
    assert capsys.readouterr().err.startswith("error: --out: ") and cfg.read_text() == SMALL_RUN
    png = tmp_path / "r.png"
    png.write_bytes(b"\x89PNG not a result")
    assert main(["plot", str(png), "--out", str(png)]) == 2
    assert png.read_bytes() == b"\x89PNG not a result"


def test_real_write_limit_is_a_clean_error(tmp_path):
    """A real fault, not a monkeypatch: the file-size limit (RLIMIT_FSIZE) makes every write past
    64 kB fail with EFBIG, as a full disk would fail with ENOSPC."""
    import resource

    cfg = tmp_path / "c.toml"
    cfg.write_text(SMALL_RUN.replace("duration = 2e-4", "duration = 4e-3"))
    out = tmp_path / "r.nc"

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (64_000, 64_000))

    # the run's kernels compiled and cached first: with a cold Numba cache (a new CPU, an edited
    # kernel) the first write past the limit is a kernel's cache file, not the result
    warm = tmp_path / "warm"
    warm.mkdir()
    subprocess.run([sys.executable, "-m", "hertzchain.cli", "run", str(cfg), "--out", str(warm / "w.nc"), "-q"],
                   capture_output=True, text=True, timeout=300, check=True)
    shutil.rmtree(warm)
    proc = subprocess.run([sys.executable, "-m", "hertzchain.cli", "run", str(cfg), "--out", str(out), "-q"],
                          capture_output=True, text=True, timeout=120, preexec_fn=limit)
    assert proc.returncode == 2, proc.stderr
    assert f"error: {out}: cannot be written: the file is too large for the file system" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.toml"]


def test_full_numba_cache_names_its_folder(tmp_path):
    """Numba lets a failed write of its cache of compiled kernels (a full disk, a quota, here the
    file-size limit) through without a file name; the error names the cache's folder and what to
    do instead of "a file". A cold cache of its own, so that the kernels are written first."""
    import resource

    cfg = tmp_path / "c.toml"
    cfg.write_text(SMALL_RUN)
    cache = tmp_path / "numba_cache"
    cache.mkdir()

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (16_000, 16_000))

    proc = subprocess.run([sys.executable, "-m", "hertzchain.cli", "run", str(cfg), "--out", str(tmp_path / "r.nc"),
                           "-q"], capture_output=True, text=True, timeout=300, preexec_fn=limit,
                          env={**os.environ, "NUMBA_CACHE_DIR": str(cache)})
    assert proc.returncode == 2, proc.stderr
    assert f"error: Numba's cache of compiled kernels ({cache}" in proc.stderr, proc.stderr
    assert "File too large" in proc.stderr and "NUMBA_CACHE_DIR" in proc.stderr
    assert "Traceback" not in proc.stderr and not (tmp_path / "r.nc").exists()
