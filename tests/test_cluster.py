"""Sweeps, ensembles, designs and fit bootstraps on a real Dask cluster of processes.

One cluster for the module, started as docs/guide/cluster.rst tells users to (the page's
commands, run as written on a free port): a ``dask scheduler`` and two ``dask worker`` processes
(``--nthreads 1``, no dashboard, a scratch folder in a temporary directory), then the README's
sweep through them. Every result is compared with the same job run here, bit for bit; the last
test kills a worker in the middle of a run. The fixture's finalizer stops every process it
started, by PID, whatever happened.
"""

from __future__ import annotations

import copy
import hashlib
import json
import os
import re
import shlex
import signal
import socket
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from hertzchain.cli.main import main
from hertzchain.sweep import run_sweep

distributed = pytest.importorskip("distributed")

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
PAGE = ROOT / "docs" / "guide" / "cluster.rst"


def _parent(pid: int) -> int:
    with open(f"/proc/{pid}/stat") as fh:
        return int(fh.read().rsplit(")", 1)[1].split()[1])


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def page_commands() -> list[str]:
    """The shell lines of the page's tested block (the first code block after the marker)."""
    text = PAGE.read_text()
    block = text[text.index(".. tested-commands:"):]
    block = block[block.index(".. code-block:: bash"):].split("\n\n", 2)[1]
    return [line.strip() for line in block.splitlines() if line.strip()]


class Cluster:
    """Processes started from the page's commands; ``stop`` ends each one by its PID."""

    def __init__(self, workdir: Path) -> None:
        self.workdir = workdir
        self.procs: list[subprocess.Popen] = []
        self.address = ""
        self.client = None

    def run_page(self, commands: list[str], port: int) -> None:
        self.address = f"tcp://127.0.0.1:{port}"
        for line in commands:
            line = line.replace("8786", str(port))
            background = line.endswith("&")
            argv = shlex.split(line.rstrip("&"))
            argv[0] = str(BIN / Path(argv[0]).name) if argv[0].startswith(".venv/bin/") else argv[0]
            if background:
                log = open(self.workdir / f"process{len(self.procs)}.log", "wb")
                self.procs.append(subprocess.Popen(argv, cwd=self.workdir, stdout=log, stderr=subprocess.STDOUT))
                log.close()
                self._wait_ready(argv)
            else:
                run = subprocess.run(argv, cwd=self.workdir, capture_output=True, text=True, timeout=300)
                assert run.returncode == 0, f"{line}\n{run.stdout}\n{run.stderr}"

    def _wait_ready(self, argv: list[str]) -> None:
        """What a user does between typing the lines: wait until the scheduler answers, then
        until each worker has joined it."""
        deadline = time.monotonic() + 120
        if argv[1] == "scheduler":
            port = int(self.address.rsplit(":", 1)[1])
            while socket.socket().connect_ex(("127.0.0.1", port)) != 0:
                assert time.monotonic() < deadline and self.procs[-1].poll() is None, "the scheduler did not start"
                time.sleep(0.1)
            self.client = distributed.Client(self.address, timeout="30s", set_as_default=False)
        else:
            workers = sum(1 for argv_ in self._argvs() if argv_[1] == "worker")
            self.client.wait_for_workers(workers, timeout=120)

    def _argvs(self) -> list[list[str]]:
        return [p.args for p in self.procs]

    def worker_pids(self) -> dict[str, int]:
        """Worker address -> PID of the worker process, for the workers this fixture started (each
        ``dask worker`` is a nanny process that runs the worker as its child, and restarts it)."""
        mine = {p.pid for p in self.procs}
        return {addr: pid for addr, pid in self.client.run(os.getpid).items() if _parent(pid) in mine}

    def stop(self) -> None:
        """SIGTERM to every process started (each nanny stops its worker), then SIGKILL to any
        still alive after 15 s; each one by its PID."""
        if self.client is not None:
            self.client.close()
        for p in reversed(self.procs):  # workers first, the scheduler last
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
        for p in self.procs:
            try:
                p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(timeout=15)


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    if not (BIN / "dask").exists():
        pytest.skip(f"no dask executable beside {sys.executable}")
    work = tmp_path_factory.mktemp("cluster")
    (work / "examples").symlink_to(ROOT / "examples")
    c = Cluster(work)
    try:
        c.run_page(page_commands(), _free_port())
        yield c
    finally:
        c.stop()


def _sha(folder: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.glob("*.nc"))}


def test_the_page_runs_the_readme_sweep_on_two_worker_processes_bit_for_bit(cluster, tmp_path):
    commands = page_commands()
    assert [c.split()[:2] for c in commands[:3]] == [[".venv/bin/dask", "scheduler"]] + [[".venv/bin/dask", "worker"]] * 2
    assert "examples/sweep_taper.toml" in commands[3] and "--scheduler" in commands[3]
    # both workers took part (the tasks are spread) ...
    assert len(cluster.worker_pids()) == 2
    # ... and the chunk files are those of the same sweep run here, byte for byte
    assert main(["sweep", "examples/sweep_taper.toml", "--out", str(tmp_path / "here"), "-q"]) == 0
    there = cluster.workdir / "sweep_taper"
    assert _sha(there / "chunks") == _sha(tmp_path / "here" / "chunks") and len(_sha(there / "chunks")) == 3
    assert (there / "metrics.csv").read_bytes() == (tmp_path / "here" / "metrics.csv").read_bytes()


def ensemble(n: int = 6, chunk_size: int = 2) -> dict:
    """The shipped tolerance ensemble (chain 1), smaller, metrics only, every kind of tolerance."""
    d = tomllib.loads((ROOT / "examples" / "tolerance_ensemble.toml").read_text())
    d["sweep"].update(n=n, chunk_size=chunk_size, store="metrics", traces=[3],
                      tolerances={"diameter_rel": 0.001, "diameter_abs_mm": 0.005, "correlation": 0.5,
                                  "offset_mm": 0.02, "velocity_abs": 0.002, "seed": 1})
    return d


def test_tolerance_ensemble_through_the_cluster_is_bit_identical(cluster, tmp_path):
    here = run_sweep(ensemble(), tmp_path / "here")
    there = run_sweep(ensemble(), tmp_path / "there", client=cluster.client)
    pd.testing.assert_frame_equal(here.metrics, there.metrics, check_exact=True)
    assert _sha(tmp_path / "here" / "chunks") == _sha(tmp_path / "there" / "chunks")
    assert (tmp_path / "there" / "chunks" / "traces_00001.nc").exists()
    assert np.isfinite(there.metrics["F_m"]).all() and there.metrics["F_m"].std() > 0


def test_design_generations_through_the_cluster_give_the_same_search(cluster, tmp_path):
    design = tomllib.loads((ROOT / "examples" / "design_taper.toml").read_text())
    design["design"].update(budget=48, population=8, chunk_size=4)
    f = tmp_path / "d.toml"
    f.write_text(_toml(design))
    assert main(["design", str(f), "--out", str(tmp_path / "here"), "-q", "--no-html"]) == 0
    assert main(["design", str(f), "--out", str(tmp_path / "there"), "-q", "--no-html",
                 "--scheduler", cluster.address]) == 0
    a, b = (json.loads((tmp_path / w / "design.json").read_text()) for w in ("here", "there"))
    assert a["best"] == b["best"] and a["n_evaluations"] == b["n_evaluations"] >= 8
    ha, hb = (pd.read_csv(tmp_path / w / "history.csv") for w in ("here", "there"))
    timing = [c for c in ha.columns if c.startswith("elapsed")]
    pd.testing.assert_frame_equal(ha.drop(columns=timing), hb.drop(columns=timing), check_exact=True)


def test_fit_bootstrap_refits_run_on_the_cluster_with_the_same_numbers(cluster, tmp_path):
    args = ["fit", "examples/lab_chain1.toml", "examples/scope_chain1_wall.csv", "--sensor", "pcb_208a11",
            "--free", "striker.velocity", "--free", "gain", "--free", "time_offset", "--bootstrap", "2", "-q"]
    assert main(args + ["--out", str(tmp_path / "here")]) == 0
    assert main(args + ["--out", str(tmp_path / "there"), "--scheduler", cluster.address]) == 0
    a, b = (json.loads((tmp_path / w / "fit.json").read_text()) for w in ("here", "there"))
    assert a["parameters"] == b["parameters"] and a["parameters"]["gain"]["bootstrap"]["refits"] == 2
    assert a["n_evaluations"] == b["n_evaluations"]


def test_a_worker_killed_mid_run_costs_only_its_task(cluster, tmp_path):
    """Kill (SIGKILL) a worker process while it holds a task: the scheduler gives the task to
    another worker (the other one, or the one its nanny restarts), and the sweep ends with the
    results of an uninterrupted local run."""
    import threading

    spec = ensemble(n=24, chunk_size=4)
    spec["sweep"].update(traces=[])
    first_back = threading.Event()
    out: dict = {}

    def sweep() -> None:
        try:
            out["result"] = run_sweep(spec, tmp_path / "there", client=cluster.client,
                                      progress=lambda done, total: done and first_back.set())
        except BaseException as exc:  # noqa: BLE001 - reported by the test thread
            out["error"] = exc
        first_back.set()

    thread = threading.Thread(target=sweep)
    thread.start()
    killed = []
    first_back.wait(timeout=120)  # some chunks are on disk: the kill must not cost them
    deadline = time.monotonic() + 30
    while not killed and thread.is_alive() and time.monotonic() < deadline:
        pids = cluster.worker_pids()
        busy = [addr for addr, keys in cluster.client.processing().items() if keys and addr in pids]
        if busy:
            os.kill(pids[busy[0]], signal.SIGKILL)
            killed.append(pids[busy[0]])
        time.sleep(0.01)
    thread.join(timeout=300)
    assert "error" not in out, out.get("error")
    assert killed, "no worker held a task after the first chunk came back"
    there = out["result"]
    assert sorted(there.computed) == list(range(6))
    here = run_sweep(spec, tmp_path / "here")
    pd.testing.assert_frame_equal(here.metrics, there.metrics, check_exact=True)
    assert _sha(tmp_path / "here" / "chunks") == _sha(tmp_path / "there" / "chunks")
    assert killed[0] not in cluster.worker_pids().values()


def _toml(d: dict) -> str:
    """A design mapping as TOML (the value types its files use)."""
    import tomli_w

    return tomli_w.dumps(copy.deepcopy(d))


def test_page_block_is_the_one_documented():
    """The marker sits right above the local-process block (a reordered page would test another)."""
    text = PAGE.read_text()
    assert re.search(r"\.\. tested-commands:.*\n\n\.\. code-block:: bash\n\n   \.venv/bin/dask scheduler", text)


def test_no_scheduler_at_the_address_is_a_clean_error():
    from hertzchain.errors import ConfigError
    from hertzchain.parallel import connect

    with pytest.raises(ConfigError) as e:
        connect(f"tcp://127.0.0.1:{_free_port()}", timeout="1s")
    assert e.value.field == "--scheduler" and "dask scheduler" in e.value.message


@pytest.mark.parametrize("address, why", [
    ("tls://127.0.0.1:1", "tls:// is not supported (TLS needs certificates"),
    ("ucx://127.0.0.1:1", "ucx:// is not supported (UCX needs"),
    ("ws://127.0.0.1:1", "ws:// is not supported (an unknown scheme)"),
    ("127.0.0.1:99999", "a port from 1 to 65535"),
    ("tcp://127.0.0.1", "is not a scheduler address"),
])
def test_an_unsupported_scheduler_address_is_refused_at_once(tmp_path, capsys, address, why):
    """TLS, UCX and other schemes (an internal TypeError, or a 40 s stall, before), a port out of
    range, no port: refused before anything is tried, naming --scheduler (exit 2 in the CLI)."""
    from hertzchain.errors import ConfigError
    from hertzchain.parallel import connect

    start = time.monotonic()
    with pytest.raises(ConfigError) as e:
        connect(address)
    assert e.value.field == "--scheduler" and why in e.value.message
    assert time.monotonic() - start < 2.0  # nothing was tried: no connection timeout
    assert main(["sweep", str(ROOT / "examples" / "sweep_taper.toml"), "--out", str(tmp_path / "o"),
                 "--scheduler", address]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert "--scheduler" in err and why in err and "internal error" not in err


def test_no_scheduler_answering_is_an_error_within_the_connection_timeout():
    """Nothing listens at the address: the error comes after the short connection timeout
    (CONNECT_TIMEOUT_S, 10 s), not after Dask's 20-40 s."""
    from hertzchain.errors import ConfigError
    from hertzchain.parallel import CONNECT_TIMEOUT_S, connect

    start = time.monotonic()
    with pytest.raises(ConfigError, match="cannot connect to the Dask scheduler"):
        connect(f"tcp://127.0.0.1:{_free_port()}", timeout=1.0)
    assert time.monotonic() - start < 1.0 + 5.0 and CONNECT_TIMEOUT_S <= 10.0


def test_a_cluster_without_workers_is_waited_for_a_bounded_time_then_refused(tmp_path):
    """A scheduler with no worker (started as the guide says, without its workers): the wait is
    announced, bounded, and ends in a clean error naming --scheduler (it waited forever before)."""
    from hertzchain.errors import ConfigError
    from hertzchain.parallel import connect

    if not (BIN / "dask").exists():
        pytest.skip(f"no dask executable beside {sys.executable}")
    lonely = Cluster(tmp_path)
    try:
        lonely.run_page([line for line in page_commands() if " scheduler" in line][:1], _free_port())
        said: list[str] = []
        start = time.monotonic()
        with pytest.raises(ConfigError) as e:
            connect(lonely.address, worker_wait=1.0, notify=said.append)
        assert time.monotonic() - start < 10.0
        assert e.value.field == "--scheduler" and "no worker joined" in e.value.message
        assert len(said) == 1 and "has no worker; waiting up to 1 s" in said[0]
    finally:
        lonely.stop()
