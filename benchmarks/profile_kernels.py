"""Where a run's CPU time goes, by compiled function: Linux ``perf`` samples attributed to Numba's
functions.

A profiler of Python frames (py-spy, cProfile) sees one opaque call into a compiled kernel, and
``perf`` alone sees anonymous JIT addresses. This script runs a workload in a child process with an
empty Numba cache (so that every kernel is compiled there and Numba still holds its LLVM module),
has the child write the address of every function of every compiled library, samples the child
with ``perf record -p`` while it repeats the workload, and gives each sample to the function
whose code starts last before its address (exclusive time: a function LLVM inlined counts in its
caller). Samples outside the JIT are grouped by shared library (libpython: Python around the
kernels). Needs ``perf`` (Debian's ``linux-perf``) and permission to trace one's own processes.

Cases:

- ``ensemble``: ``simulate_batch`` of the metrics-only tolerance ensemble of chain 1
  (``examples/tolerance_ensemble.toml``, misaligned beads, the batched ``rkn4`` path), 300 members
  a call, one thread, samples every 100 ns as the sweep records them;
- ``simulate``: ``hc.simulate(model, 3 ms)`` with the defaults, chain 1 with an 8 mm striker at
  0.2 m/s and the law ``--law`` (as ``time_to_accuracy.py --laws`` runs it).

Usage::

    python benchmarks/profile_kernels.py --case ensemble            # ~1 min (compiling included)
    python benchmarks/profile_kernels.py --case simulate --law hunt_crossley

Measured 2026-11-29 (AMD EPYC, 2 cores; results/profile_*.json): ``--case ensemble`` spends 46 %
in ``damped_run`` (the stepping logic, the samples and ``end_data``, which LLVM inlines into it),
21 % in ``step`` (three of a step's four force passes), 11 % in ``next_step``; ``--case simulate
--law hunt_crossley`` ~35 % in ``run`` and 9 % in ``step_paths`` (the samples: every loaded
contact's force at every sample, for the largest contact forces), 16 % in Python around the
kernel.
"""

from __future__ import annotations

import argparse
import bisect
import collections
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import REPO, RESULTS, machine_info, save_json, table

LAWS = ("elastic", "viscoelastic", "dashpot", "elastoplastic", "hunt_crossley", "power")

#: The child: set up the case, run it once (compiling), write the symbols, then repeat it until killed.
CHILD = r"""
import gc, json, os, sys, time, warnings
warnings.simplefilter("ignore")
case, law_name, symbols, ready = sys.argv[1:5]
sys.path.insert(0, os.path.join({repo!r}, "benchmarks"))
import hertzchain as hc
if case == "ensemble":
    import tomllib, numba
    from hertzchain.runs.batch import simulate_batch
    from hertzchain.sweep import parse_sweep
    from hertzchain.sweep.schema import chunk_members
    numba.set_num_threads(1)
    data = tomllib.loads(open(os.path.join({repo!r}, "examples", "tolerance_ensemble.toml")).read())
    data["sweep"].update(n=300, chunk_size=300, store="metrics")
    models, _ = chunk_members(parse_sweep(data), list(range(300)))
    run = data["base"]["run"]
    work = lambda: simulate_batch(models, run["duration"], hc.Probes(sample_interval=run["sample_interval"],
                                  contacts=()), integrator="auto", max_force="run")
else:
    from time_to_accuracy import chain1_dashpot_model
    laws = dict(elastic=hc.Elastic(), viscoelastic=hc.Viscoelastic(A=2e-6), dashpot=hc.Dashpot(gamma=8.0),
                elastoplastic=hc.Elastoplastic(), hunt_crossley=hc.HuntCrossley(0.9), power=hc.PowerLaw(2.0, 1e13))
    base = chain1_dashpot_model()
    model = hc.Model(base.chain, base.striker, base.wall, law=laws[law_name])
    work = lambda: hc.simulate(model, 3e-3)
work()
from numba.core.registry import CPUDispatcher
found = set()
for o in gc.get_objects():
    if isinstance(o, CPUDispatcher):
        for cres in o.overloads.values():
            module = getattr(cres.library, "_final_module", None)
            for fn in (module.functions if module is not None else ()):
                if not fn.is_declaration:
                    try:
                        address = cres.library.get_pointer_to_function(fn.name)
                    except Exception:
                        continue
                    if address:
                        found.add((address, fn.name))
json.dump(sorted(found), open(symbols, "w"))
open(ready, "w").write("1")
calls, t0 = 0, time.perf_counter()
while True:
    work()
    calls += 1
    open(ready, "w").write(f"{{calls}} {{time.perf_counter() - t0}}")
"""


def readable(symbol: str) -> str:
    """The qualified name inside an Itanium-mangled Numba symbol (module path dropped)."""
    start = symbol.find("_ZN")
    s = symbol[start + 3:] if start >= 0 else symbol
    parts, i = [], 0
    while i < len(s) and s[i].isdigit():
        j = i
        while s[j].isdigit():
            j += 1
        n = int(s[i:j])
        parts.append(s[j:j + n])
        i = j + n
    names = [p for p in parts if p not in ("_3clocals_3e",)]
    return names[-1] if names else symbol[:60]


def profile(case: str, law: str, seconds: float) -> dict:
    if shutil.which("perf") is None:
        raise SystemExit("perf not found: install Debian's linux-perf (or your distribution's perf)")
    with tempfile.TemporaryDirectory(prefix="profile_kernels_") as tmp:
        tmp = Path(tmp)
        script = tmp / "child.py"
        script.write_text(CHILD.format(repo=str(REPO)))
        symbols, ready, data = tmp / "symbols.json", tmp / "ready", tmp / "perf.data"
        env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp / "numba_cache"),
               "PYTHONPATH": os.pathsep.join([str(REPO / "src"), os.environ.get("PYTHONPATH", "")])}
        child = subprocess.Popen([sys.executable, str(script), case, law, str(symbols), str(ready)], env=env)
        try:
            t0 = time.perf_counter()
            while not ready.exists():
                if child.poll() is not None:
                    raise SystemExit(f"the workload failed (exit {child.returncode})")
                time.sleep(0.2)
            compile_s = time.perf_counter() - t0
            print(f"compiled and ran once in {compile_s:.1f} s; sampling {seconds:g} s", flush=True)
            subprocess.run(["perf", "record", "-q", "-F", "2000", "-p", str(child.pid), "-o", str(data), "--",
                            "sleep", str(seconds)], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            calls, elapsed = (float(x) for x in (ready.read_text().split() + ["0", "0"])[:2])
            out = subprocess.run(["perf", "script", "-i", str(data), "-F", "ip,dso"], capture_output=True, text=True,
                                 check=True).stdout
        finally:
            child.kill()
            child.wait()
        syms = [(int(a), readable(n)) for a, n in json.loads(symbols.read_text())]
    syms.sort()
    starts = [a for a, _ in syms]
    counts: collections.Counter = collections.Counter()
    for line in out.splitlines():
        fields = line.split()
        if len(fields) < 2:
            continue
        ip, dso = int(fields[0], 16), fields[1].strip("()")
        if "perf-" in dso or dso == "[unknown]":  # JIT code
            k = bisect.bisect_right(starts, ip) - 1
            counts[syms[k][1] if k >= 0 else "JIT (unknown)"] += 1
        else:
            counts[Path(dso).name] += 1
    total = sum(counts.values())
    rows = [{"where": k, "share": v / total, "samples": v} for k, v in counts.most_common()]
    return {"case": case, "law": law if case == "simulate" else None, "seconds_sampled": seconds,
            "samples": total, "calls": calls, "ms_per_call": 1e3 * elapsed / calls if calls else None,
            "compile_and_first_call_s": compile_s, "rows": rows}


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", choices=("ensemble", "simulate"), default="ensemble")
    ap.add_argument("--law", choices=LAWS, default="hunt_crossley", help="the law of --case simulate")
    ap.add_argument("--seconds", type=float, default=15.0, help="how long to sample (default 15 s)")
    ap.add_argument("--top", type=int, default=15, help="rows printed")
    ap.add_argument("--json", type=Path, help="where to save (default results/profile_<case>[_<law>].json)")
    args = ap.parse_args(argv)
    res = profile(args.case, args.law, args.seconds)
    res["machine"] = machine_info()
    print(table([(r["where"], f"{100 * r['share']:.1f} %", r["samples"]) for r in res["rows"][:args.top]],
                ("function or library", "share", "samples")))
    if res["ms_per_call"]:
        print(f"{res['calls']:.0f} calls, {res['ms_per_call']:.2f} ms a call (perf running)")
    path = args.json or RESULTS / (f"profile_{args.case}" + (f"_{args.law}" if args.case == "simulate" else "")
                                   + ".json")
    save_json(res, path)
    print(f"saved {path}")
    return res


if __name__ == "__main__":
    main()
