"""A transmission spectrum one frequency after another against the batched driven engine.

Usage::

    python benchmarks/spectrum.py [--json PATH] [--points 20] [--settle-cycles 100]

The chain of ``examples/dimer_driven.toml`` (eight 10 mm / 6 mm steel cells under 1 N, dashpot
contacts, a 1 mN force drive on bead 1), ``--points`` frequencies from 2 to 24 kHz (across its
band gap), ``--settle-cycles`` cycles after the ramp and 20 measured:

- **one at a time** (what ``hertzchain spectrum`` did before the batched engine): one
  :func:`hertzchain.simulate` per frequency and its lock-in (``transmission_run``);
- **batched**: :func:`hertzchain.transmission_spectrum` with ``batch`` frequencies per compiled
  call (one member per frequency, the members handed to the threads in turn), for batch = 4, 8 and
  all of them, and all of them on one thread (``numba.set_num_threads(1)``: what the batch saves
  besides the threads).

The JIT is warmed first (a two-frequency batch and one single run, short). Wall-clock and process
CPU time (all threads, ``time.process_time``) are measured in the same run, best of ``--repeat``
(the machine is shared: the load average before and after is saved). The transmissions of every
batched run are checked equal to the one-at-a-time ones (bit for bit: each member's run is its
own).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numba
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import REPO, RESULTS, machine_info, quiet, save_json, table  # noqa: E402

import hertzchain as hc  # noqa: E402
from hertzchain.crystal.spectrum import SpectrumSettings, transmission_run  # noqa: E402


def timed(fn):
    """(wall [s], CPU [s] of the process, all threads, result)."""
    w0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return time.perf_counter() - w0, time.process_time() - c0, out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--json", type=Path, default=RESULTS / "spectrum.json")
    parser.add_argument("--points", type=int, default=20)
    parser.add_argument("--settle-cycles", type=float, default=100.0)
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()
    quiet()
    model = hc.build_model(hc.load_config(REPO / "examples" / "dimer_driven.toml"))
    freqs = np.linspace(2000.0, 24000.0, args.points)
    settings = SpectrumSettings(settle_cycles=args.settle_cycles, measure_cycles=20)
    warm = SpectrumSettings(settle_cycles=1, measure_cycles=1)
    w0, c0 = time.perf_counter(), time.process_time()
    hc.transmission_spectrum(model, freqs[:2], settings=warm, batch=2)
    transmission_run(model, float(freqs[0]), warm)
    compile_s = {"wall": time.perf_counter() - w0, "cpu": time.process_time() - c0}
    load_before = os.getloadavg()

    def one_at_a_time():
        return np.array([transmission_run(model, float(f), settings)[0] for f in freqs])

    def batched(b, threads):
        def fn():
            numba.set_num_threads(threads)
            try:
                return hc.transmission_spectrum(model, freqs, settings=settings, batch=b).transmission.values
            finally:
                numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        return fn

    cores = numba.config.NUMBA_NUM_THREADS
    results: dict = {}
    reference = None
    cases = [("one at a time", one_at_a_time)]
    cases += [(f"batched, {b} per call, {cores} threads", batched(b, cores)) for b in (4, 8, args.points)]
    cases += [(f"batched, {args.points} per call, 1 thread", batched(args.points, 1))]
    for name, fn in cases:
        runs = [timed(fn) for _ in range(args.repeat)]
        best = min(runs, key=lambda r: r[0])
        values = best[2]
        if reference is None:
            reference = values
        results[name] = {"wall_s": best[0], "cpu_s": best[1], "wall_all_s": [r[0] for r in runs],
                         "cpu_all_s": [r[1] for r in runs], "equal_to_one_at_a_time": bool(np.array_equal(values, reference))}
    base = results["one at a time"]
    for r in results.values():
        r["wall_speedup"] = base["wall_s"] / r["wall_s"]
        r["cpu_ratio"] = r["cpu_s"] / base["cpu_s"]
    rows = [(k, f"{r['wall_s']:.2f}", f"{r['cpu_s']:.2f}", f"{r['wall_speedup']:.2f}", f"{r['cpu_ratio']:.2f}",
             r["equal_to_one_at_a_time"]) for k, r in results.items()]
    print(f"{args.points} frequencies 2-24 kHz, examples/dimer_driven.toml, {args.settle_cycles:g} settling + 20 "
          f"measured cycles; compile {compile_s['wall']:.1f} s; load {load_before[0]:.2f} -> {os.getloadavg()[0]:.2f}")
    print(table(rows, ("spectrum", "wall s", "CPU s", "wall speed-up", "CPU / one at a time", "equal")))
    save_json({"machine": machine_info(), "points": args.points, "settle_cycles": args.settle_cycles,
               "measure_cycles": 20, "compile_s": compile_s, "load_before": load_before,
               "load_after": os.getloadavg(), "results": results,
               "transmission": {"frequency_Hz": freqs.tolist(), "transmission": reference.tolist()}}, args.json)
    print(f"saved {args.json}")


if __name__ == "__main__":
    main()
