"""A large tolerance ensemble of the paper's chain 1, metrics only: memory, speed, and the cost of Dask.

The ensemble is ``examples/tolerance_ensemble.toml`` (chain 1 at 0.2 m/s, 3 ms at 100 ns, 0.1 %
diameter and 0.02 mm offset tolerances) with ``store = "metrics"``, run as a user runs it:

1. ``hertzchain sweep`` here (the local engine: each chunk across every core), in a fresh
   process: wall time, members per second, the process's peak resident memory (``os.wait4``)
   against the sweep's estimate, and the bytes each member leaves on disk;
2. the Dask overhead: the same sweep of ``--dask-members`` members through a local cluster of
   processes started as ``docs/guide/cluster.rst`` says (a ``dask scheduler``, two ``dask worker
   --nthreads 1``; warmed by a small sweep first), against the local engine on the same members
   in the same conditions; the metrics of both are checked to be identical.

The CPU time per member is the robust figure on a shared machine (the wall time carries whatever
else runs on the cores). A sweep of one chunk runs first, so that the process's fixed cost
(imports, loading the compiled kernels, planning: a few CPU-seconds) is separated from the
marginal cost per member, which is what a million members multiply; ``--stages`` members are then
timed stage by stage in this process on one thread (steps, samples, fit). ``--rtol`` sets the
members' ``run.rtol`` (recorded as not the default) to measure the step tolerance's share.

    .venv/bin/python benchmarks/ensemble_scale.py                                  # 1e6 members (hours on 2 cores)
    .venv/bin/python benchmarks/ensemble_scale.py --members 100000 --dask-members 10000

Prints the numbers and saves ``benchmarks/results/ensemble_scale.json`` with the machine's
description and its load average before and after (the machine may be shared). When
``--members`` is below 1e6 the JSON and the printout also give the extrapolation to 1e6 members,
labelled as such: the time scales with the members (chunks are independent; the marginal CPU
time per member times 1e6 plus the fixed cost once, on the idle cores), the peak memory
with the chunk (and, at the end, with the metrics table of every member).
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np
import tomli_w

from _common import REPO, RESULTS, machine_info, save_json

BIN = Path(sys.executable).parent


def sweep_file(folder: Path, members: int, chunk_size: int, rtol: float | None = None) -> Path:
    data = tomllib.loads((REPO / "examples" / "tolerance_ensemble.toml").read_text())
    data["sweep"].update(n=members, chunk_size=chunk_size, store="metrics")
    if rtol is not None:  # not the default: the step tolerance of every member's rkn4 run
        data["base"]["run"]["rtol"] = rtol
    path = folder / f"ensemble_{members}.toml"
    path.write_text(tomli_w.dumps(data))
    return path


def timed(argv: list[str]) -> dict:
    """Run ``argv``; wall time [s], CPU time [s] and peak resident memory [bytes] (os.wait4), exit status."""
    t0 = time.perf_counter()
    with tempfile.TemporaryFile() as err:
        proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=err, cwd=REPO)
        _, status, usage = os.wait4(proc.pid, 0)
        seconds = time.perf_counter() - t0
        err.seek(0)
        tail = err.read().decode(errors="replace")[-800:]
    code = os.waitstatus_to_exitcode(status)
    if code != 0:
        raise SystemExit(f"{' '.join(argv)}: exit status {code}\n{tail}")
    return {"seconds": seconds, "cpu_seconds": usage.ru_utime + usage.ru_stime, "peak_rss_bytes": usage.ru_maxrss * 1024}


def local_run(path: Path, out: Path) -> dict:
    from hertzchain.sweep import load_sweep
    from hertzchain.sweep.runner import estimate_sweep

    from dataclasses import replace

    from hertzchain.checks import RUNTIME_BYTES

    cfg = load_sweep(path)
    est = replace(estimate_sweep(cfg), process_bytes=RUNTIME_BYTES)  # as the sweep's fresh process makes it
    r = timed([str(BIN / "hertzchain"), "sweep", str(path), "--out", str(out), "-q"])
    chunk_bytes = sum(p.stat().st_size for p in (out / "chunks").glob("chunk_*.nc"))
    r.update(members=cfg.n_members, members_per_s=cfg.n_members / r["seconds"],
             cpu_ms_per_member=1e3 * r["cpu_seconds"] / cfg.n_members, estimate_peak_bytes=est.peak_bytes,
             peak_over_estimate=r["peak_rss_bytes"] / est.peak_bytes, chunk_bytes_per_member=chunk_bytes / cfg.n_members,
             metrics_csv_bytes=(out / "metrics.csv").stat().st_size)
    return r


class LocalProcessCluster:
    """A scheduler and two workers as the cluster page starts them; stopped by PID."""

    def __init__(self, folder: Path) -> None:
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            self.port = s.getsockname()[1]
        self.address = f"tcp://127.0.0.1:{self.port}"
        dask = str(BIN / "dask")
        self.procs = [subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", str(self.port),
                                        "--no-dashboard"], cwd=folder, stdout=subprocess.DEVNULL,
                                       stderr=subprocess.DEVNULL)]
        from distributed import Client

        self.client = Client(self.address, timeout="60s", set_as_default=False)
        for _ in range(2):
            self.procs.append(subprocess.Popen([dask, "worker", self.address, "--nthreads", "1", "--no-dashboard",
                                                "--local-directory", str(folder / "dask-scratch")], cwd=folder,
                                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        self.client.wait_for_workers(2, timeout=120)

    def worker_peak_rss(self) -> list[int]:
        import resource

        return [v * 1024 for v in self.client.run(lambda: resource.getrusage(resource.RUSAGE_SELF).ru_maxrss).values()]

    def stop(self) -> None:
        self.client.close()
        for p in reversed(self.procs):
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
        for p in self.procs:
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                p.kill()


def dask_comparison(folder: Path, members: int, chunk_size: int) -> dict:
    import pandas as pd

    path = sweep_file(folder, members, chunk_size)
    local = local_run(path, folder / "dask_local")
    cluster = LocalProcessCluster(folder)
    try:
        warm = sweep_file(folder, 4 * 2, 2)  # every worker imports hertzchain and loads the compiled kernels
        timed([str(BIN / "hertzchain"), "sweep", str(warm), "--out", str(folder / "warm"), "-q", "--scheduler",
               cluster.address])
        there = timed([str(BIN / "hertzchain"), "sweep", str(path), "--out", str(folder / "dask_cluster"), "-q",
                       "--scheduler", cluster.address])
        workers = cluster.worker_peak_rss()
    finally:
        cluster.stop()
    a = pd.read_csv(folder / "dask_local" / "metrics.csv")
    b = pd.read_csv(folder / "dask_cluster" / "metrics.csv")
    identical = bool(a.equals(b))
    return {"members": members, "chunk_size": chunk_size, "local_seconds": local["seconds"],
            "cluster_seconds": there["seconds"], "cluster_over_local": there["seconds"] / local["seconds"],
            "local_members_per_s": members / local["seconds"], "cluster_members_per_s": members / there["seconds"],
            "client_peak_rss_bytes": there["peak_rss_bytes"], "worker_peak_rss_bytes": workers,
            "metrics_identical": identical}


def stages(members: int, rtol: float | None) -> dict:
    """Where one batch's CPU time goes, in this process on one thread (CPU-ms per member, the best of
    three): the batched rkn4 steps alone (samples 1/10 of the run apart), the steps with the
    sweep's samples (the difference: interpolating the wall force and the energies at them), and
    the compiled fit of the wall pulses, as a metrics-only chunk runs them."""
    import warnings

    import numba

    from hertzchain import Probes
    from hertzchain.analysis.pulse_batch import fit_pulses
    from hertzchain.runs.batch import simulate_batch
    from hertzchain.sweep import parse_sweep
    from hertzchain.sweep.runner import F_M_REFINE
    from hertzchain.sweep.schema import chunk_members

    data = tomllib.loads((REPO / "examples" / "tolerance_ensemble.toml").read_text())
    data["sweep"].update(n=members, chunk_size=members, store="metrics")
    cfg = parse_sweep(data)
    run = data["base"]["run"]
    models, _ = chunk_members(cfg, list(range(members)))
    threads = numba.get_num_threads()
    numba.set_num_threads(1)

    def best(fn) -> float:
        fn()  # loads the compiled code
        times = []
        for _ in range(3):
            c0 = time.process_time()
            fn()
            times.append(time.process_time() - c0)
        return 1e3 * min(times) / members

    def batch(interval: float):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return simulate_batch(models, run["duration"], Probes(sample_interval=interval, contacts=()),
                                  integrator="auto", max_force="run", rtol=rtol)

    try:
        steps = best(lambda: batch(run["duration"] / 10))
        sampled = best(lambda: batch(run["sample_interval"]))
        ds = batch(run["sample_interval"])
        t, wall = ds["time"].values, ds["wall_force"].values
        fit = best(lambda: fit_pulses(t, wall, refine=F_M_REFINE))
    finally:
        numba.set_num_threads(threads)
    return {"members": members, "threads": 1, "steps_per_member": float(ds["n_steps"].mean()),
            "steps_cpu_ms": steps, "samples_cpu_ms": sampled - steps, "fit_cpu_ms": fit,
            "note": "simulate_batch end to end (steps alone: samples 1/10 of the run apart); CPU-ms per member"}


def load() -> list[float]:
    return list(os.getloadavg())


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--members", type=int, default=1_000_000, help="members of the local run (default 1e6)")
    ap.add_argument("--dask-members", type=int, default=10_000, help="members of the Dask comparison (0: none)")
    ap.add_argument("--chunk-size", type=int, default=500, help="members per chunk")
    ap.add_argument("--rtol", type=float, default=None,
                    help="run.rtol of the members (default: the config's, i.e. rkn4's default; a non-default "
                         "value is recorded as such)")
    ap.add_argument("--stages", type=int, default=1000,
                    help="members of the per-stage timing on one thread, in this process (0: none)")
    ap.add_argument("--json", type=Path, default=RESULTS / "ensemble_scale.json", help="where to save the results")
    args = ap.parse_args()
    info = {"machine": machine_info(), "load_before": load(), "members": args.members, "chunk_size": args.chunk_size,
            "ensemble": "examples/tolerance_ensemble.toml, store = 'metrics'"
                        + ("" if args.rtol is None else f", run.rtol = {args.rtol:g} (NOT the default)")}
    with tempfile.TemporaryDirectory(prefix="ensemble_scale_") as tmp:
        folder = Path(tmp)
        print(f"load average {info['load_before']}; {args.members} members, chunks of {args.chunk_size}"
              + ("" if args.rtol is None else f"; run.rtol = {args.rtol:g} (not the default)"), flush=True)
        # One chunk alone first: the process's fixed cost (imports, loading the compiled kernels,
        # planning), so that the CPU time per member can be given without it (the marginal cost,
        # what a million members multiply) and the extrapolation adds it once. A small sweep
        # before it fills Numba's cache: a chunk that compiled the engine would count the
        # compilation as fixed cost, which a million members pay once per installation, and
        # understate the marginal cost by ~1 CPU-ms a member.
        local_run(sweep_file(folder, 16, 16, args.rtol), folder / "warm")
        shutil.rmtree(folder / "warm")
        one = local_run(sweep_file(folder, args.chunk_size, args.chunk_size, args.rtol), folder / "one")
        shutil.rmtree(folder / "one")
        r = local_run(sweep_file(folder, args.members, args.chunk_size, args.rtol), folder / "local")
        shutil.rmtree(folder / "local")
        extra = args.members - args.chunk_size
        if extra > 0:
            r["marginal_cpu_ms_per_member"] = 1e3 * (r["cpu_seconds"] - one["cpu_seconds"]) / extra
            r["fixed_cpu_seconds"] = one["cpu_seconds"] - 1e-3 * r["marginal_cpu_ms_per_member"] * args.chunk_size
        info["one_chunk"] = one
        info["local"] = r
        print(f"local engine: {r['seconds']:.0f} s, {r['members_per_s']:.1f} members/s "
              f"({r['cpu_ms_per_member']:.2f} CPU-ms per member, compilation included), peak RSS "
              f"{r['peak_rss_bytes'] / 2**20:.0f} MiB (estimate {r['estimate_peak_bytes'] / 2**20:.0f} MiB, ratio "
              f"{r['peak_over_estimate']:.2f}), {r['chunk_bytes_per_member']:.0f} bytes/member on disk", flush=True)
        if "marginal_cpu_ms_per_member" in r:
            print(f"  marginal {r['marginal_cpu_ms_per_member']:.2f} CPU-ms per member (against one chunk of "
                  f"{args.chunk_size}: {one['cpu_seconds']:.1f} CPU-s), fixed cost {r['fixed_cpu_seconds']:.1f} CPU-s",
                  flush=True)
        if args.members < 1_000_000:
            from hertzchain.sweep import load_sweep
            from hertzchain.sweep.runner import estimate_sweep

            import warnings

            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # the LongRunWarning of a sweep that is not run
                est = estimate_sweep(load_sweep(sweep_file(folder, 1_000_000, args.chunk_size, args.rtol)))
            cores = len(os.sched_getaffinity(0))
            per_member = r.get("marginal_cpu_ms_per_member", r["cpu_ms_per_member"])
            fixed = r.get("fixed_cpu_seconds", 0.0)
            info["extrapolated_1e6"] = {
                "note": f"EXTRAPOLATED from {args.members} members, not measured",
                "seconds": 1_000_000 / r["members_per_s"],
                # what the CPU time per member gives on this machine's cores when nothing else runs
                # (the wall time above carries the load of whatever shares the cores)
                # (the marginal CPU time per member times a million, plus the fixed cost once)
                "seconds_on_idle_cores": (1e-3 * per_member * 1_000_000 + fixed) / cores, "cores": cores,
                "estimate_peak_rss_bytes": est.peak_bytes,
                "disk_bytes": 1_000_000 * r["chunk_bytes_per_member"]}
            x = info["extrapolated_1e6"]
            print(f"EXTRAPOLATED to 1e6 members (not measured): {x['seconds'] / 3600:.2f} h at this load, "
                  f"{x['seconds_on_idle_cores'] / 60:.0f} min from the CPU time on {cores} idle cores; peak RSS "
                  f"~{x['estimate_peak_rss_bytes'] / 2**20:.0f} MiB (the sweep's estimate), "
                  f"{x['disk_bytes'] / 2**20:.0f} MiB of chunks", flush=True)
        if args.stages:
            st = info["stages"] = stages(args.stages, args.rtol)
            print(f"one batch of {st['members']} members on 1 thread, CPU-ms per member: steps "
                  f"{st['steps_cpu_ms']:.2f} ({st['steps_per_member']:.0f} steps), samples {st['samples_cpu_ms']:.2f}, "
                  f"fit {st['fit_cpu_ms']:.2f}", flush=True)
        if args.dask_members:
            d = dask_comparison(folder, args.dask_members, args.chunk_size)
            info["dask"] = d
            print(f"Dask, local process cluster (2 workers x 1 thread) vs local engine, {d['members']} members: "
                  f"{d['cluster_seconds']:.0f} s vs {d['local_seconds']:.0f} s (x{d['cluster_over_local']:.2f}); "
                  f"client peak RSS {d['client_peak_rss_bytes'] / 2**20:.0f} MiB, workers "
                  f"{', '.join(f'{w / 2**20:.0f}' for w in d['worker_peak_rss_bytes'])} MiB; metrics identical: "
                  f"{d['metrics_identical']}", flush=True)
    info["load_after"] = load()
    print(f"load average after: {info['load_after']}")
    save_json(info, args.json)
    print(f"saved {args.json}")
    return 0


if __name__ == "__main__":
    np.seterr(all="ignore")
    sys.exit(main())
