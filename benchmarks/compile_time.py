"""What a first run compiles: Numba's compilation time of a few first runs in fresh processes.

Usage::

    python benchmarks/compile_time.py [--json PATH] [--cases verlet_elastic,sweep,...]

Each case runs in a new process with an empty Numba cache (``NUMBA_CACHE_DIR`` a new folder, so
the package's own ``__pycache__`` is not touched) and records Numba's compile events
(``numba.core.event``, kind ``numba:compile``): the CPU seconds of the whole process, the seconds
spent compiling (the outermost compile events: a function compiled inside another's compilation
counts in its caller's), and the five functions whose own compilation took longest. The cases:

- ``verlet_elastic``: ``simulate`` of 3 elastic 10 mm beads with ``integrator="verlet"``;
- ``verlet_hunt_crossley``: the same with the Hunt-Crossley law (a registry law's generated loops);
- ``sweep``: an 8-member grid sweep of 3-4 beads (``run_sweep``; the batched engine and the pulse
  fits), as tests/test_sweep.py runs it;
- ``sensitivity``: the adjoint sensitivity of an elastic 8-bead taper's peak wall force to a
  diameter and the striker's speed (tests/test_gradients.py's chain).

Run it on another source tree to compare (``git archive REV src | tar -x -C /tmp/base``, then
``PYTHONPATH=/tmp/base/src python benchmarks/compile_time.py --json before.json``).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import RESULTS, machine_info, save_json, table

CASES = {
    "verlet_elastic": """
import hertzchain as hc
hc.simulate(hc.Model(hc.Chain.uniform(3, 10e-3), hc.Striker(8e-3, 0.2)), 2e-4, integrator="verlet")
""",
    "verlet_hunt_crossley": """
import hertzchain as hc
hc.simulate(hc.Model(hc.Chain.uniform(3, 10e-3), hc.Striker(8e-3, 0.2), law=hc.HuntCrossley(0.8)), 2e-4,
            integrator="verlet")
""",
    "sweep": """
import tempfile
from hertzchain.sweep import run_sweep
base = {"chain": {"uniform": {"n": 3, "diameter_mm": 10.0}}, "striker": {"diameter_mm": 8.0, "velocity": 0.2},
        "run": {"duration": 2e-4, "sample_interval": 1e-6}}
grid = {"mode": "grid", "chunk_size": 2,
        "parameters": {"striker.velocity": [0.1, 0.15, 0.2, 0.3], "chain.uniform.n": [3, 4]}}
with tempfile.TemporaryDirectory() as d:
    run_sweep({"base": base, "sweep": grid}, d + "/out")
""",
    "sensitivity": """
from hertzchain.gradients.api import sensitivity
cfg = {"chain": {"diameters_mm": [20.0, 19.0, 18.0, 17.0, 16.0, 15.0, 14.0, 13.0]},
       "striker": {"diameter_mm": 8.0, "velocity": 0.3}, "run": {"duration": "auto", "sample_interval": 1e-6}}
sensitivity(cfg, ["chain.diameters_mm[0]", "striker.velocity"])
""",
}

#: Runs a case's code under Numba's compile-event recorder; prints the events' totals as JSON.
WRAPPER = """
import collections, json, sys, time, warnings
warnings.simplefilter("ignore")
from numba.core import event
t0 = time.process_time()
with event.install_recorder("numba:compile") as rec:
    exec(sys.argv[1])
cpu = time.process_time() - t0
stack, own, outer = [], collections.Counter(), 0.0
for ts, ev in rec.buffer:
    d = ev.data.get("dispatcher")
    name = d.py_func.__module__ + "." + d.py_func.__qualname__ if d is not None else "?"
    if ev.is_start:
        stack.append([name, ts, 0.0])
        continue
    name, start, inner = stack.pop()
    own[name] += ts - start - inner
    if stack:
        stack[-1][2] += ts - start
    else:
        outer += ts - start
print(json.dumps({"cpu_s": cpu, "compile_s": outer, "functions_compiled": len(own),
                  "longest": [[n, round(s, 2)] for n, s in own.most_common(5)]}))
"""


def run_case(code: str) -> dict:
    with tempfile.TemporaryDirectory(prefix="hc-numba-cache-") as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t = time.perf_counter()
        out = subprocess.run([sys.executable, "-c", WRAPPER, code], env=env, capture_output=True, text=True)
        if out.returncode != 0:
            raise SystemExit(f"the case failed:\n{out.stderr[-3000:]}")
        wall = time.perf_counter() - t
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    res = json.loads(out.stdout.strip().splitlines()[-1])
    res["process_cpu_s"] = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    res["process_wall_s"] = wall
    return res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", type=Path, default=RESULTS / "compile_time.json", help="where to save the results")
    ap.add_argument("--cases", help=f"comma-separated cases (default: all of {', '.join(CASES)})")
    args = ap.parse_args()
    names = [c.strip() for c in args.cases.split(",")] if args.cases else list(CASES)
    unknown = [c for c in names if c not in CASES]
    if unknown:
        ap.error(f"--cases: unknown {unknown}; known: {', '.join(CASES)}")
    info = machine_info()
    print(f"first-run compilation, empty Numba cache — {info['cpu_model']}, load {info['load_average_at_start']}")
    rows = {name: run_case(CASES[name]) for name in names}
    print(table([(n, f"{r['process_cpu_s']:.1f}", f"{r['compile_s']:.1f}", r["functions_compiled"],
                  ", ".join(f"{f.rsplit('.', 1)[-1]} {s}" for f, s in r["longest"][:3])) for n, r in rows.items()],
                ("case", "process CPU-s", "compiling s", "functions", "longest own compilations (s)")))
    save_json({"benchmark": "compile_time", "machine": info, "cases": rows,
               "load_average_at_end": list(os.getloadavg())}, args.json)
    print(f"saved {args.json}")


if __name__ == "__main__":
    main()
