"""Offset beads on the dissipative ``rkn4`` engine: what a misaligned chain costs against the aligned one.

Chain 1 of the paper with its calibrated law (``dashpot_scaled``, the reproduction's), the 8 mm
striker at 0.2 m/s, 3 ms sampled every 100 ns, with the defaults:

- ``single``: ``hc.simulate`` of the aligned chain and of the same chain with every bead off the
  axis (normal, 0.02 mm: the tolerance ensemble's spread), median of 25 alternated calls;
- ``batch``: ``simulate_batch`` of 60 such members each (metrics only, ``max_force="run"``, as the
  tolerance ensemble runs them), one thread, CPU-ms per member, median of 5 calls.

Each version runs in its own processes (``--processes`` each, alternated) with its own Numba
cache, compiled before it is timed; a hash of the records checks that both versions give the
same numbers. ``--baseline-src DIR`` times another version's ``src`` beside this one, e.g. the
version before a change::

    git archive COMMIT src | tar -x -C /tmp/base
    .venv/bin/python benchmarks/offsets.py --baseline-src /tmp/base/src     # ~2 min

Prints and saves ``benchmarks/results/offsets.json`` with the machine's description.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from _common import REPO, RESULTS, machine_info, save_json, table

#: One process's measurement: prints a JSON line.
CHILD = r"""
import hashlib, json, sys, time, warnings
import numpy as np
warnings.simplefilter("ignore")
import hertzchain as hc
from hertzchain.runs.batch import simulate_batch
from hertzchain.config import build_model, load_config
base = build_model(load_config(sys.argv[1], ()))
model = hc.Model(base.chain, hc.Striker(8e-3, 0.2), base.wall, law=base.law)
rng = np.random.default_rng(1)
n = len(model.chain.diameters)

def off():
    return hc.Model(model.chain.with_offsets({i + 1: float(x) for i, x in enumerate(rng.normal(0, 2e-5, n))}),
                    model.striker, model.wall, law=model.law)

single = {"aligned": model, "misaligned": off()}
out, digest = {}, hashlib.sha1()
for name, m in single.items():
    ds = hc.simulate(m, 3e-3)
    digest.update(ds.contact_force.values.tobytes() + ds.dissipated_energy.values.tobytes())
ts = {name: [] for name in single}
for _ in range(25):
    for name, m in single.items():
        t = time.perf_counter(); hc.simulate(m, 3e-3); ts[name].append(time.perf_counter() - t)
for name, t in ts.items():
    out[f"single_{name}_ms"] = 1e3 * float(np.median(t))
probes = hc.Probes(sample_interval=1e-7, contacts=())
for name, members in (("aligned", [model] * 60), ("misaligned", [off() for _ in range(60)])):
    ds = simulate_batch(members, 3e-3, probes, integrator="auto", max_force="run")
    digest.update(ds.wall_force.values.tobytes())
    t = []
    for _ in range(5):
        c = time.process_time(); simulate_batch(members, 3e-3, probes, integrator="auto", max_force="run")
        t.append(time.process_time() - c)
    out[f"batch_{name}_cpu_ms_per_member"] = 1e3 * float(np.median(t)) / len(members)
out["hash"] = digest.hexdigest()[:12]
print(json.dumps(out))
"""


def measure(src: Path, cache: Path) -> dict:
    env = {**os.environ, "PYTHONPATH": str(src), "NUMBA_CACHE_DIR": str(cache), "NUMBA_NUM_THREADS": "1"}
    run = subprocess.run([sys.executable, "-c", CHILD, str(REPO / "examples" / "chain1.toml")], env=env,
                         capture_output=True, text=True, check=True)
    return json.loads(run.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline-src", type=Path, help="src folder of another version, timed alternately")
    ap.add_argument("--processes", type=int, default=3, help="processes per version (default 3)")
    ap.add_argument("--json", type=Path, default=RESULTS / "offsets.json", help="where to save the results")
    args = ap.parse_args(argv)
    versions = {"this": REPO / "src"}
    if args.baseline_src is not None:
        versions["baseline"] = args.baseline_src.resolve()
    runs: dict[str, list[dict]] = {v: [] for v in versions}
    with tempfile.TemporaryDirectory(prefix="offsets_") as tmp:
        for v, src in versions.items():  # compile each version into its own cache first
            measure(src, Path(tmp) / v)
        for _ in range(args.processes):
            for v, src in versions.items():
                runs[v].append(measure(src, Path(tmp) / v))
    keys = [k for k in runs["this"][0] if k != "hash"]
    summary = {v: {k: statistics.median(r[k] for r in rs) for k in keys} | {"hash": rs[0]["hash"]}
               for v, rs in runs.items()}
    rows = [(k, *(f"{summary[v][k]:.3f}" for v in versions)) for k in keys]
    print(table(rows, ("median of the processes", *versions)))
    if "baseline" in summary:
        same = summary["this"]["hash"] == summary["baseline"]["hash"]
        print("records bit for bit the same as the baseline's:", same)
    result = {"machine": machine_info(), "versions": {v: str(s) for v, s in versions.items()}, "runs": runs,
              "median": summary}
    save_json(result, args.json)
    print(f"saved {args.json}")
    return result


if __name__ == "__main__":
    main()
