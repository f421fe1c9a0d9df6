"""Set-up of mixed-layout batches: array code per layout group against member by member.

Usage::

    python benchmarks/batch_setup.py [--json PATH] [--quick]

A design search's generation is one ``run_batch`` call on chains of different bead counts. On
the design's generation-0-like batch (the n-q problem of benchmarks/design.py: 32 chains of
4 x 26 mm then an exponential taper of n in 2..12 beads, q drawn in [0, 0.15] with no bead under
15 mm; striker 8 mm at 0.2 m/s, flat wall, 2 ms, samples every 5 us, no contact forces
recorded but the wall's, adaptive step at 20 steps per radian), after a JIT warm-up, measured
alternately in the same run (best of N; the machine may be shared):

1. ``setup_s_per_member``: the set-up (Model -> engine buffers, step plans, initial state) with
   array code (``batch_pack._setup_groups``: here one ragged group, every chain on a wall with the
   elastic law, padded to the longest), against the
   member-by-member set-up (``Model.system()``, ``step_plan``, ``layout.pack``, ``initialise``
   per member: ``batch_pack._setup_members``, the path of batches with a size-scaled law).
2. ``run_batch_s``: ``run_batch(..., return_systems=True)`` end to end (what the design calls),
   the engine alone on the same packed batch, and the same call with the member-by-member
   set-up (``old_run_batch_s``: that set-up, the same engine, the same RawRuns). Target: <= 5 ms.
3. ``ensemble_setup_s_per_member``: a 1e4-member single-layout ensemble (30 beads of 26 mm,
   0.1 % diameter tolerances) set up with ``batch_pack._pack_ensemble``, per member: the one-group
   case of the grouped set-up must not be slower than before it (see benchmarks/README.md).
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, best_of, machine_info, quiet, save_json, table  # noqa: E402

import hertzchain as hc  # noqa: E402
from hertzchain.errors import ElasticLimitWarning  # noqa: E402
from hertzchain.runs import batch, batch_results
from hertzchain.integrate.batch import engine as batch_engine, pack as batch_pack  # noqa: E402
from hertzchain.integrate.batch.ensemble import Ensemble  # noqa: E402

DURATION = 2e-3           # s
INTERVAL = 5e-6           # s
STEPS_PER_RADIAN = 20.0   # the design's coarse search accuracy
MEMBERS = 32
TARGET_RUN_BATCH = 5e-3   # s per call on the gen-0-like batch


def generation0(seed: int = 0, members: int = MEMBERS) -> list[hc.Model]:
    """The design's first generation on the n-q problem: random (n, q), no bead under 15 mm."""
    rng = np.random.default_rng(seed)
    models = []
    for _ in range(members):
        n = int(rng.integers(2, 13))
        q = rng.uniform(0.0, min(0.15, 1.0 - (15.0 / 26.0) ** (1.0 / n)))
        chain = hc.Chain.uniform(4, 26e-3).append_taper(n, q)
        models.append(hc.Model(chain, hc.Striker(8e-3, 0.2), hc.Wall("flat"), hc.Elastic()))
    return models


def measure_mixed(repeat: int) -> dict:
    models = generation0()
    probes = hc.Probes(sample_interval=INTERVAL, contacts=())
    plist, dts = [probes] * len(models), [None] * len(models)
    n_samples = int(round(DURATION / INTERVAL)) + 1

    def grouped():
        return batch_pack._setup_groups(models, plist, dts, INTERVAL, n_samples, STEPS_PER_RADIAN)

    def members():
        return batch_pack._setup_members(models, plist, dts, INTERVAL, n_samples, STEPS_PER_RADIAN)

    def run_new():
        return batch.run_batch(models, DURATION, probes, steps_per_radian=STEPS_PER_RADIAN, return_systems=True)

    def run_old():
        pk, systems = members()
        batch_engine._engine(pk, None, None)
        return batch_results._member_runs(pk), systems

    def engine():
        pk, _ = grouped()
        t0 = time.perf_counter()
        batch_engine._engine(pk, None, None)
        return time.perf_counter() - t0

    # Same numbers both ways (the point of the array set-up), checked once.
    new_runs, old_runs = run_new()[0], run_old()[0]
    assert all(np.array_equal(a.contact_force, b.contact_force) and a.n_steps == b.n_steps
               for a, b in zip(new_runs, old_runs))
    times = {k: [] for k in ("grouped", "members", "run_new", "run_old", "engine")}
    for _ in range(repeat):  # alternated, so that every variant sees the same machine load
        for key, fn in (("grouped", grouped), ("members", members), ("run_new", run_new), ("run_old", run_old)):
            times[key].append(best_of(fn, 5)[0])
        times["engine"].append(min(engine() for _ in range(5)))
    best = {k: min(v) for k, v in times.items()}
    m = len(models)
    return {"members": m, "bead_counts": sorted({mdl.chain.n_beads for mdl in models}),
            "setup_groups": len(batch_pack._groups(models, plist)), "duration_s": DURATION,
            "sample_interval_s": INTERVAL,
            "steps_per_radian": STEPS_PER_RADIAN,
            "setup_s_per_member": best["grouped"] / m, "member_by_member_setup_s_per_member": best["members"] / m,
            "setup_speedup": best["members"] / best["grouped"],
            "run_batch_s": best["run_new"], "old_run_batch_s": best["run_old"], "engine_s": best["engine"],
            "times_s": times, "target_run_batch_s": TARGET_RUN_BATCH,
            "run_batch_met": bool(best["run_new"] <= TARGET_RUN_BATCH)}


def measure_ensemble(m: int, repeat: int) -> dict:
    """The one-group case: a single-layout ensemble of ``m`` members (as benchmarks/ensemble.py)."""
    base = hc.Model(hc.Chain.uniform(30, 26e-3), hc.Striker(8e-3, 0.5))
    d = 26e-3 * (1 + 1e-3 * np.random.default_rng(0).standard_normal((m, 30)))
    probes = hc.Probes(1e-6, contacts=(0,))
    dts = batch_pack._ensemble_dts(None, m)

    def setup():
        return batch_pack._pack_ensemble(Ensemble(base, diameters=d), probes, dts, 1e-6, 11)

    setup()
    best, times, _ = best_of(setup, repeat)
    return {"members": m, "setup_s_per_member": best / m, "times_s": times}


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", type=Path, default=RESULTS / "batch_setup.json", help="where to save the results")
    ap.add_argument("--quick", action="store_true", help="fewer repetitions (a smoke run)")
    args = ap.parse_args(argv)
    quiet()
    warnings.simplefilter("ignore", ElasticLimitWarning)
    info = machine_info()
    print(f"hertzchain batch set-up benchmark — {info['cpu_model']}, {info['usable_cores']} usable cores, "
          f"numba {info['numba']}, {info['date_utc']}")
    mixed = measure_mixed(3 if args.quick else 10)
    ens = measure_ensemble(10_000, 3 if args.quick else 7)
    res = {"benchmark": "batch_setup", "quick": args.quick, "machine": info, "mixed": mixed, "ensemble": ens,
           "setup_s_per_member": mixed["setup_s_per_member"], "run_batch_s": mixed["run_batch_s"],
           "ensemble_setup_s_per_member": ens["setup_s_per_member"]}
    rows = [
        (f"set-up per member, {mixed['members']} chains of {len(mixed['bead_counts'])} bead counts, array code "
         f"({mixed['setup_groups']} group)",
         f"{mixed['setup_s_per_member'] * 1e6:.1f} us"),
        ("set-up per member, member by member (Model.system, pack, initialise)",
         f"{mixed['member_by_member_setup_s_per_member'] * 1e6:.1f} us"),
        ("run_batch(return_systems=True), grouped set-up", f"{mixed['run_batch_s'] * 1e3:.2f} ms"),
        ("  same call, member-by-member set-up", f"{mixed['old_run_batch_s'] * 1e3:.2f} ms"),
        ("  engine alone (compiled calls)", f"{mixed['engine_s'] * 1e3:.2f} ms"),
        (f"single-layout ensemble set-up, {ens['members']:,} members", f"{ens['setup_s_per_member'] * 1e6:.2f} us/member"),
    ]
    print(table(rows, ("measure", "value")))
    print(f"run_batch target <= {TARGET_RUN_BATCH * 1e3:.0f} ms: {'met' if mixed['run_batch_met'] else 'NOT met'}")
    save_json(res, args.json)
    print(f"\nsaved {args.json}")
    return res


if __name__ == "__main__":
    main()
