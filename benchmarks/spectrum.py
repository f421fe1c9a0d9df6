"""A transmission spectrum one frequency after another against the batched driven engine.

Usage::

    python benchmarks/spectrum.py [--json PATH] [--points 20] [--settle-cycles 100] [--baseline-src DIR]

The chain of ``examples/dimer_driven.toml`` (eight 10 mm / 6 mm steel cells under 1 N, dashpot
contacts, a 1 mN force drive on bead 1), ``--points`` frequencies from 2 to 24 kHz (across its
band gap), ``--settle-cycles`` cycles after the ramp and 20 measured:

- **one at a time** (what ``hertzchain spectrum`` did before the batched engine): one
  :func:`hertzchain.simulate` per frequency and its lock-in (``transmission_run``);
- **batched**: :func:`hertzchain.transmission_spectrum` with ``batch`` frequencies per compiled
  call (one member per frequency, the members handed to the threads in turn), for batch = 4, 8 and
  all of them, and all of them on one thread (``numba.set_num_threads(1)``: what the batch saves
  besides the threads).

With ``--baseline-src DIR`` (the ``src`` folder of another version, e.g. ``git archive`` of the
commit before the batched engine) the one-at-a-time spectrum of that version runs too, in a
subprocess (its own JIT warmed first, its wall and CPU time measured inside it), the "before".

The driven step alone is timed too, in ns per bead-step (process CPU time over steps x beads): one
40 ms run of the same chain at 5 kHz on a 50 ns step, here and (with ``--baseline-src``) in the
other version: the fused pass of an aligned chain with a built-in law against the general pass.

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


#: One driven run of the example's chain, timed per bead-step (shared by this process and the baseline's).
KERNEL = """
def kernel_ns(model, repeat):
    import dataclasses, time
    import hertzchain as hc
    m = dataclasses.replace(model, drive=dataclasses.replace(model.drive, frequency=5000.0))
    hc.simulate(m, 1e-4, hc.Probes(6.25e-6, contacts=(16,)), dt=5e-8)
    best = float("inf")
    for _ in range(repeat):
        c0 = time.process_time()
        ds = hc.simulate(m, 4e-2, hc.Probes(6.25e-6, contacts=(16,)), dt=5e-8)
        best = min(best, (time.process_time() - c0) / ds.attrs["n_steps"] / m.chain.n_beads * 1e9)
    return best
"""
exec(KERNEL)

BASELINE = KERNEL + """
import json, sys, time, warnings
import numpy as np
import hertzchain as hc
from hertzchain.crystal.spectrum import SpectrumSettings, transmission_run
warnings.simplefilter("ignore")
config, points, settle, repeat = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4])
model = hc.build_model(hc.load_config(config))
freqs = np.linspace(2000.0, 24000.0, points)
settings = SpectrumSettings(settle_cycles=settle, measure_cycles=20)
transmission_run(model, float(freqs[0]), SpectrumSettings(settle_cycles=1, measure_cycles=1))
runs = []
for _ in range(repeat):
    w0, c0 = time.perf_counter(), time.process_time()
    t = [transmission_run(model, float(f), settings)[0] for f in freqs]
    runs.append((time.perf_counter() - w0, time.process_time() - c0))
print(json.dumps({"runs": runs, "transmission": t, "kernel_ns": kernel_ns(model, repeat)}))
"""


def baseline(src: Path, points: int, settle: float, repeat: int) -> dict:
    """The one-at-a-time spectrum of the version whose package is in ``src``, in a subprocess."""
    import json
    import subprocess

    env = {**os.environ, "PYTHONPATH": str(src)}
    run = subprocess.run([sys.executable, "-c", BASELINE, str(REPO / "examples" / "dimer_driven.toml"), str(points),
                          str(settle), str(repeat)], env=env, capture_output=True, text=True, check=True)
    out = json.loads(run.stdout.strip().splitlines()[-1])
    wall, cpu = min(out["runs"])
    return {"wall_s": wall, "cpu_s": cpu, "wall_all_s": [r[0] for r in out["runs"]],
            "cpu_all_s": [r[1] for r in out["runs"]], "transmission": out["transmission"], "src": str(src),
            "kernel_ns_per_bead_step": out["kernel_ns"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--json", type=Path, default=RESULTS / "spectrum.json")
    parser.add_argument("--points", type=int, default=20)
    parser.add_argument("--settle-cycles", type=float, default=100.0)
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--baseline-src", type=Path, default=None,
                        help="src folder of the version to compare with (its one-at-a-time spectrum)")
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
    if args.baseline_src is not None:
        before = baseline(args.baseline_src, args.points, args.settle_cycles, args.repeat)
        diff = float(np.max(np.abs(np.array(before.pop("transmission")) / reference - 1)))
        results = {"before (baseline src), one at a time": {**before, "largest_relative_difference": diff},
                   **results}
    base = next(iter(results.values()))
    kernel = {"now": kernel_ns(model, args.repeat)}  # noqa: F821 (defined by exec(KERNEL))
    if args.baseline_src is not None:
        kernel["before"] = results["before (baseline src), one at a time"]["kernel_ns_per_bead_step"]
    for r in results.values():
        r["wall_speedup"] = base["wall_s"] / r["wall_s"]
        r["cpu_ratio"] = r["cpu_s"] / base["cpu_s"]
    rows = [(k, f"{r['wall_s']:.2f}", f"{r['cpu_s']:.2f}", f"{r['wall_speedup']:.2f}", f"{r['cpu_ratio']:.2f}",
             r.get("equal_to_one_at_a_time", f"rel. diff {r.get('largest_relative_difference', 0):.1e}"))
            for k, r in results.items()]
    print(f"{args.points} frequencies 2-24 kHz, examples/dimer_driven.toml, {args.settle_cycles:g} settling + 20 "
          f"measured cycles; compile {compile_s['wall']:.1f} s; load {load_before[0]:.2f} -> {os.getloadavg()[0]:.2f}")
    print(table(rows, ("spectrum", "wall s", "CPU s", "wall speed-up", "CPU ratio", "equal")))
    print("driven step, ns per bead-step (CPU): " + ", ".join(f"{k} {v:.2f}" for k, v in kernel.items()))
    save_json({"machine": machine_info(), "points": args.points, "settle_cycles": args.settle_cycles,
               "measure_cycles": 20, "compile_s": compile_s, "load_before": load_before,
               "load_after": os.getloadavg(), "results": results, "kernel_ns_per_bead_step": kernel,
               "transmission": {"frequency_Hz": freqs.tolist(), "transmission": reference.tolist()}}, args.json)
    print(f"saved {args.json}")


if __name__ == "__main__":
    main()
