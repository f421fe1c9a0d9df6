"""A killed save leaves no temporary file for good, and SIGTERM is handled like Ctrl-C."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

from hertzchain.fileio import _host, remove_stale_temporaries, write_text

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _python(code: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], cwd=cwd, capture_output=True, text=True,
                          timeout=300)


def _dead_pid() -> int:
    """The id of a process that has ended (and was reaped)."""
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def test_sigkill_during_a_save_leaves_a_temporary_file_that_the_next_write_removes(tmp_path):
    target = tmp_path / "result.txt"
    killed = _python(f"""
        import os, signal
        from hertzchain.fileio import atomic_path
        with atomic_path({str(target)!r}) as tmp:
            tmp.write_text("half a file")
            os.kill(os.getpid(), signal.SIGKILL)
        """, tmp_path)
    assert killed.returncode == -signal.SIGKILL
    left = list(tmp_path.glob(".result.txt.*.tmp"))
    assert len(left) == 1 and not target.exists()  # what SIGKILL leaves: nothing can run on it
    write_text(target, "whole")
    assert target.read_text() == "whole"
    assert list(tmp_path.glob(".*.tmp")) == []


def test_temporary_files_of_live_writers_other_hosts_and_names_are_kept(tmp_path):
    target = tmp_path / "r.nc"
    live = tmp_path / f".r.nc.{_host()}-{os.getpid()}.abc123.tmp"       # this process: a write under way
    init = tmp_path / f".r.nc.{_host()}-1.abc123.tmp"                    # pid 1 is alive
    other_host = tmp_path / f".r.nc.elsewhere-{_dead_pid()}.abc123.tmp"  # a shared folder: not ours to judge
    other_name = tmp_path / f".s.nc.{_host()}-{_dead_pid()}.abc123.tmp"
    dead = tmp_path / f".r.nc.{_host()}-{_dead_pid()}.abc123.tmp"
    legacy_new = tmp_path / ".r.nc.k2j4h5g6.tmp"                         # an older hertzchain's, recent
    legacy_old = tmp_path / ".r.nc.q8w7e6r5.tmp"
    for p in (live, init, other_host, other_name, dead, legacy_new, legacy_old):
        p.write_text("x")
    os.utime(legacy_old, (1e9, 1e9))
    removed = remove_stale_temporaries(target)
    assert sorted(removed) == sorted([dead, legacy_old])
    assert all(p.exists() for p in (live, init, other_host, other_name, legacy_new))


def test_sigterm_during_a_save_is_handled_like_ctrl_c(tmp_path):
    """hertzchain run gets SIGTERM while it writes its result: exit 143, one line 'terminated', no
    result and no temporary file left."""
    out = tmp_path / "r.nc"
    done = _python(f"""
        import os, signal, sys, time
        import hertzchain.result as result
        from hertzchain.fileio import atomic_path

        def save(ds, path, **kw):
            with atomic_path(path) as tmp:
                tmp.write_bytes(b"partial")
                os.kill(os.getpid(), signal.SIGTERM)
                time.sleep(30)

        result.save = save
        from hertzchain.cli.main import main
        sys.exit(main(["run", {str(EXAMPLES / "chain1_elastic.toml")!r}, "--set", "run.duration=2e-4", "-o",
                       {str(out)!r}, "-q"]))
        """, tmp_path)
    assert done.returncode == 143, done.stderr
    assert done.stderr.strip().splitlines()[-1] == "terminated"
    assert "Traceback" not in done.stderr
    assert not out.exists() and list(tmp_path.glob(".*.tmp")) == []


def test_main_restores_the_previous_sigterm_handler():
    from hertzchain.cli.main import main

    before = signal.getsignal(signal.SIGTERM)
    assert main(["materials"]) == 0
    assert signal.getsignal(signal.SIGTERM) is before


def test_forked_figure_workers_stop_quietly_under_the_clis_sigterm_handler(tmp_path):
    """reproduce draws figures in a forked pool; the pool stops its workers with SIGTERM at its end.
    A fork inherits the CLI's SIGTERM handler (raise, as Ctrl-C), so each idle worker printed a
    traceback under a successful `hertzchain reproduce` (seen in the docs-commands check). With
    the pool's initializer the workers take SIGTERM's default and ignore SIGINT (the parent stops
    the pool on Ctrl-C): the pool's end prints nothing, whatever the workers were doing."""
    p = _python("""
        import signal, sys, time
        from hertzchain.cli.main import _on_sigterm
        from hertzchain.interrupts import forked_pool

        signal.signal(signal.SIGTERM, _on_sigterm)  # what the CLI installs
        for _ in range(5):
            with forked_pool(2) as pool:  # as reproduce starts its drawing processes
                assert pool.apply(signal.getsignal, (signal.SIGTERM,)) == signal.SIG_DFL
                assert pool.apply(signal.getsignal, (signal.SIGINT,)) == signal.SIG_IGN
                pool.map_async(time.sleep, [0.2, 0.2])  # busy workers, stopped by the with block
                time.sleep(0.05)
        print("done")
    """, tmp_path)
    assert p.returncode == 0 and p.stdout.strip() == "done", p.stderr
    assert "Traceback" not in p.stderr and "Terminated" not in p.stderr, p.stderr


def test_a_latched_block_in_another_thread_leaves_the_main_threads_alone(default_sigint):
    """A sweep running in a worker thread (inside ``latched``) while the main thread starts one:
    the main thread's block still installs the handler that remembers Ctrl-C (the worker's block
    counted as nesting, and the main thread's Ctrl-C could be swallowed)."""
    import threading

    from hertzchain import interrupts

    inside, release = threading.Event(), threading.Event()

    def worker() -> None:
        with interrupts.latched():
            inside.set()
            release.wait(10)

    thread = threading.Thread(target=worker)
    thread.start()
    try:
        assert inside.wait(10)
        with interrupts.latched():
            assert signal.getsignal(signal.SIGINT) is interrupts._handler
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    finally:
        release.set()
        thread.join(10)
    assert interrupts._state["depth"] == 0
