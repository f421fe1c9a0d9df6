"""A new Dask worker's first chunk: does it compile what the installation has compiled?

A real ``dask scheduler`` and ``dask worker`` (one process, one thread, no nanny) run a small
``hertzchain sweep`` of ``examples/tolerance_ensemble.toml`` (``--scheduler``). Twice, each time
with a new worker process and a new, empty Numba cache folder (``NUMBA_CACHE_DIR``):

- ``empty``: the worker starts on the empty cache (an installation that never ran anything);
- ``installed``: the cache was first filled by one local run of the same sweep (what an
  installation that ran it once holds), then a new worker runs it.

Saved per case: the worker process's CPU seconds over the sweep (user + system, psutil: its first
chunk and the fit), the functions it compiled instead of loading (each dispatcher's
``stats.cache_misses``, read in the worker with ``client.run``), and the load average.

    .venv/bin/python benchmarks/dask_worker_cold.py [--members 20] [--json benchmarks/results/dask_worker_cold.json]
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import RESULTS, machine_info, save_json

REPO = Path(__file__).resolve().parents[1]

#: Run in the worker: the compiled functions it compiled (cache misses) and loaded (hits).
STATS = """
import gc, json
from numba.core.registry import CPUDispatcher
def stats():
    miss, hit = {}, {}
    for d in gc.get_objects():
        if isinstance(d, CPUDispatcher):
            name = d.py_func.__module__ + "." + d.py_func.__qualname__
            if sum(d.stats.cache_misses.values()):
                miss[name] = sum(d.stats.cache_misses.values())
            if sum(d.stats.cache_hits.values()):
                hit[name] = sum(d.stats.cache_hits.values())
    return {"compiled": miss, "loaded": hit}
"""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_for(address: str, timeout: float = 120.0, workers: int = 0) -> None:
    from distributed import Client

    t0 = time.monotonic()
    with Client(address, timeout=timeout) as client:
        while len(client.scheduler_info()["workers"]) < workers:
            if time.monotonic() - t0 > timeout:
                raise TimeoutError("no Dask worker joined")
            time.sleep(0.2)


def _sweep(args: list[str], env: dict) -> None:
    exe = Path(sys.executable).with_name("hertzchain")
    cli = [str(exe)] if exe.exists() else [sys.executable, "-m", "hertzchain.cli"]
    subprocess.run([*cli, "sweep", *args], env=env, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


def case(label: str, members: int, prefill: bool) -> dict:
    import psutil
    from distributed import Client

    with tempfile.TemporaryDirectory(prefix="hc-dask-") as work:
        work = Path(work)
        env = {**os.environ, "NUMBA_CACHE_DIR": str(work / "numba_cache"),
               "PYTHONPATH": os.pathsep.join([str(REPO / "src"), os.environ.get("PYTHONPATH", "")])}
        text = (REPO / "examples" / "tolerance_ensemble.toml").read_text()
        text = text.replace("n = 200", f"n = {members}").replace("chunk_size = 100", f"chunk_size = {members}")
        (work / "sweep.toml").write_text(text)
        sweep = [str(work / "sweep.toml")]
        if prefill:  # the installation ran the sweep once, here (its own process)
            _sweep([*sweep, "--out", str(work / "local")], env)
        port = _free_port()
        address = f"tcp://127.0.0.1:{port}"
        dask = Path(sys.executable).with_name("dask")
        sched = subprocess.Popen([str(dask), "scheduler", "--port", str(port), "--no-dashboard"], env=env,
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=work)
        worker = None
        try:
            _wait_for(address)
            worker = subprocess.Popen([str(dask), "worker", address, "--nthreads", "1", "--no-nanny",
                                       "--no-dashboard"], env=env, stdout=subprocess.DEVNULL,
                                      stderr=subprocess.DEVNULL, cwd=work)
            _wait_for(address, workers=1)
            proc = psutil.Process(worker.pid)
            before = proc.cpu_times()
            t0 = time.perf_counter()
            _sweep([*sweep, "--out", str(work / "remote"), "--scheduler", address], env)
            wall = time.perf_counter() - t0
            after = proc.cpu_times()
            with Client(address) as client:
                namespace: dict = {}
                exec(STATS, namespace)
                seen = next(iter(client.run(namespace["stats"]).values()))
        finally:
            for p in (worker, sched):
                if p is not None:
                    p.terminate()
                    p.wait(timeout=30)
    cpu = (after.user - before.user) + (after.system - before.system)
    print(f"{label}: the worker's sweep {cpu:.2f} CPU-s ({wall:.1f} s wall of the sweep command), "
          f"{len(seen['compiled'])} functions compiled, {len(seen['loaded'])} loaded from the cache")
    if seen["compiled"]:
        print("  compiled:", ", ".join(sorted(seen["compiled"])))
    return {"worker_cpu_s": cpu, "sweep_wall_s": wall, **seen}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--members", type=int, default=20, help="members of the sweep (one chunk)")
    ap.add_argument("--json", default=str(RESULTS / "dask_worker_cold.json"))
    args = ap.parse_args()
    os.chdir(REPO)
    res: dict = {"load_average_before": os.getloadavg(), "members": args.members}
    res["empty"] = case("new worker, empty cache", args.members, prefill=False)
    res["installed"] = case("new worker, cache filled by one local run", args.members, prefill=True)
    res["load_average_after"] = os.getloadavg()
    print(f"load average {res['load_average_before']} -> {res['load_average_after']}")
    save_json({"machine": machine_info(), **res}, Path(args.json))


if __name__ == "__main__":
    main()
