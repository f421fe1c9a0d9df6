"""The first ``hc.simulate`` of a fresh process: cold (an empty Numba cache: everything compiles) and
warm (a second process on the cache the first filled), and what the warm one still compiles.

Each case is a new process; its CPU seconds (user + system, ``resource.getrusage(RUSAGE_CHILDREN)``:
steadier than the wall clock on a shared machine) and wall seconds are saved, with the load
average. ``NUMBA_CACHE_DIR`` points at a new folder for the cold run, so the package's own
``__pycache__`` is not touched. The warm run also counts the kernels Numba compiled instead of
loading them (``numba.core.dispatcher``'s compile events: each dispatcher's ``stats.cache_misses``).
"Cold" is a fresh installation (nothing compiled yet); "warm" a new process of an installation that
ran it once (Numba's cache: compile once per installation). ``build_model`` is timed apart: for a
calibrated law (``chain1.toml``'s ``dashpot_scaled``) its calibration runs compile the law's engine,
so the first simulate after it only loads it; the first run's cost is their sum.

    .venv/bin/python benchmarks/cold_start.py [--json benchmarks/results/cold_start.json] [--integrator verlet]
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

from _common import RESULTS, machine_info, save_json

#: The first simulate after import, then the dispatchers that compiled instead of loading.
FIRST = """
import json, sys, time, warnings
warnings.simplefilter("ignore")
t0 = time.process_time()
import hertzchain as hc
from hertzchain.config import build_model, load_config
ta = time.process_time()
model = build_model(load_config(sys.argv[1], ()))  # a calibrated law's runs compile its engine here
t1 = time.process_time()
ds = hc.simulate(model, integrator=sys.argv[2])
t2 = time.process_time()
from numba.core.registry import CPUDispatcher
import gc
misses = {}
for obj in gc.get_objects():
    if isinstance(obj, CPUDispatcher):
        n = sum(obj.stats.cache_misses.values())
        if n:
            misses[obj.py_func.__module__ + "." + obj.py_func.__qualname__] = n
print(json.dumps({"import_cpu_s": ta - t0, "build_model_cpu_s": t1 - ta, "simulate_cpu_s": t2 - t1,
                  "build_and_simulate_cpu_s": t2 - ta, "integrator": ds.attrs["integrator_used"],
                  "compiled": misses}))
"""


def _child(config: str, integrator: str, env: dict) -> dict:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", FIRST, config, integrator], env=env, capture_output=True, text=True,
                         check=True)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"process_cpu_s": cpu, "process_wall_s": wall, **json.loads(out.stdout.strip().splitlines()[-1])}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", default=str(RESULTS / "cold_start.json"))
    ap.add_argument("--configs", nargs="+", default=["examples/chain1_elastic.toml", "examples/chain1.toml"])
    ap.add_argument("--integrator", default="auto",
                    help="the integrator of the first simulate (default: auto, what a user gets); e.g. verlet")
    args = ap.parse_args()
    repo = Path(__file__).resolve().parents[1]
    res = {"load_average_before": os.getloadavg()}
    for config in args.configs:
        with tempfile.TemporaryDirectory(prefix="hc-numba-cache-") as cache:
            env = {**os.environ, "NUMBA_CACHE_DIR": cache}
            cold = _child(str(repo / config), args.integrator, env)
            warm = _child(str(repo / config), args.integrator, env)
        res[config] = {"cold": cold, "warm": warm, "integrator_asked": args.integrator}
        for label, r in (("cold", cold), ("warm", warm)):
            print(f"{config} {label}: process {r['process_cpu_s']:.2f} CPU-s ({r['process_wall_s']:.2f} s wall), "
                  f"build_model {r['build_model_cpu_s']:.2f} + first simulate {r['simulate_cpu_s']:.2f} CPU-s "
                  f"({r['integrator']}), "
                  f"{len(r['compiled'])} kernels compiled")
        if warm["compiled"]:
            print("  compiled again in the warm process:", ", ".join(sorted(warm["compiled"])))
    res["load_average_after"] = os.getloadavg()
    print(f"load average {res['load_average_before']} -> {res['load_average_after']}")
    save_json({"machine": machine_info(), **res}, Path(args.json))


if __name__ == "__main__":
    main()
