"""Peak memory of ``hertzchain sensitivity --wrt chain.diameters_mm`` against the chain's length.

Usage::

    python benchmarks/sensitivity_memory.py [--json PATH] [--beads 1000 2000 4000]

Every bead's diameter is a variable (N variables for N beads): the set-up's derivatives are per
bead, so the memory must grow like N, not N^2 (issue 38: 0.57 GB at 1,000 beads, 1.5 GB at
2,000, > 6 GB at 4,000 before). Each size runs in a fresh subprocess (a uniform chain of 20 mm
steel beads, 8 mm striker at 0.3 m/s, ``peak_contact_force[2]`` over 0.3 ms, so the run itself is
short and the same for every N), whose peak resident set size (``resource.getrusage``,
RUSAGE_CHILDREN) is reported beside the estimate :func:`hertzchain.gradients.memory_estimate`
makes before the run and the memory of a plain ``hertzchain run``-like process that imports the
package and simulates the same config (the baseline the sensitivity adds to). Saves JSON
(default benchmarks/results/sensitivity_memory.json) with machine info.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, fmt, machine_info, save_json, table  # noqa: E402

CHILD = r"""
import json, resource, sys
import hertzchain as hc
n, what = int(sys.argv[1]), sys.argv[2]
cfg = {"chain": {"uniform": {"n": n, "diameter_mm": 20.0}}, "striker": {"velocity": 0.3, "diameter_mm": 8.0},
       "run": {"duration": 3e-4, "sample_interval": 1e-6}, "probes": {"contacts": [0]}}
out = {}
if what == "sensitivity":
    try:
        from hertzchain.gradients import memory_estimate
        out["estimate_bytes"] = memory_estimate(cfg, ["chain.diameters_mm"])
    except ImportError:  # before the estimate existed
        out["estimate_bytes"] = None
    s = hc.sensitivity(cfg, ["chain.diameters_mm"], "peak_contact_force[2]")
    out["variables"] = len(s.gradient)
else:
    hc.run_config(cfg)
out["maxrss_bytes"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
print(json.dumps(out))
"""


def measure(n: int, what: str) -> dict:
    """Run one size in a fresh interpreter; its own peak RSS and what it printed."""
    res = subprocess.run([sys.executable, "-c", CHILD, str(n), what], capture_output=True, text=True, check=True)
    return json.loads(res.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--json", type=Path, default=RESULTS / "sensitivity_memory.json")
    ap.add_argument("--beads", type=int, nargs="+", default=[1000, 2000, 4000])
    args = ap.parse_args()
    rows = []
    for n in args.beads:
        base = measure(n, "run")
        sens = measure(n, "sensitivity")
        rows.append({"beads": n, "variables": sens["variables"], "run_rss_mib": base["maxrss_bytes"] / 2**20,
                     "sensitivity_rss_mib": sens["maxrss_bytes"] / 2**20,
                     "added_mib": (sens["maxrss_bytes"] - base["maxrss_bytes"]) / 2**20,
                     "estimate_mib": None if sens["estimate_bytes"] is None else sens["estimate_bytes"] / 2**20})
        print(json.dumps(rows[-1]), flush=True)
    keys = ("beads", "variables", "run_rss_mib", "sensitivity_rss_mib", "added_mib", "estimate_mib")
    print(table([tuple(fmt(r[k], 4) if isinstance(r[k], float) else r[k] for k in keys) for r in rows], keys))
    save_json({"machine": machine_info(), "rows": rows}, args.json)


if __name__ == "__main__":
    main()
