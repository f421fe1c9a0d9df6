"""One long chain on several cores: ``simulate(model, threads=T)`` against one thread.

Usage::

    python benchmarks/long_chain.py [--json PATH] [--quick] [--threads T]
    python benchmarks/long_chain.py --laws [--json PATH] [--threads T] [--beads N]
    python benchmarks/long_chain.py --defaults [--json PATH] [--threads T] [--beads N] [--law NAME]

Uniform chains of 26 mm AISI 52100 beads (1e4, 1e5 and, without ``--quick``, 1e6), the paper's
striker at 0.5 m/s, flat wall, the automatic (adaptive) step, probes of the striker and wall
contacts and the energies every 100 ns (every contact of a 1e5-bead chain every 100 ns would be
~20 GB): ``hertzchain.integrate.drivers.verlet.run_verlet`` (one thread) and
``hertzchain.integrate.drivers.threaded.run_verlet_threaded`` with T threads (default: every core),
alternated, best of N, each run >= 0.3 s. Throughput in bead-steps per second; the speed-up is
the ratio of the two in the same run. Every timed pair is checked bit for bit (forces, steps).
The load average is recorded before and after every measurement: the target (>= 1.7x on 2 cores
at 1e5 beads) is meant for a quiet machine, and other work on the cores stalls the threads at
every barrier (one per step).

``--laws``: the same comparison for every built-in contact law (elastic, Kuwabara-Kono, dashpot,
their size-scaled forms, Thornton's elastic-plastic law, the power law with n = 1.7,
Hunt-Crossley) on one chain of ``--beads`` beads (default 1e5), the striker at 0.5 m/s (2 m/s
for the elastic-plastic law, whose contacts then yield), saved to
``results/long_chain_laws.json``. Each row checks the forces and steps bit for bit. Runs of
>= 2 s (several compiled calls of ~0.2-0.4 s), so that the run's own fallback to one thread on
shared cores (``threaded.Pace``) can act: each row records how many calls ran on how many
threads, and the CPU time of the threaded loop on one block against the one-thread loop (the
per-thread cost, little changed by other work on the cores).

``--defaults``: what a user gets without options. For every law of ``--laws``, the default call
``hc.simulate(model, DEFAULTS_DURATION)`` (integrator and threads "auto") against the Verlet on one
thread and on T threads, and the default integrator on T threads against one (``threads=T`` and
``threads=1``: ``rkn4``'s threads, :mod:`hertzchain.integrate.drivers.rkn_threaded`, on aligned elastic
chains; the Verlet's for the laws rkn4 runs on one thread), alternated, best of 3, with the default
probes; the integrator auto chose, the ratios in one run, the threaded calls' count on 1 and T
threads (the fallback on shared cores) and the forces' difference from one thread, saved to
``results/long_chain_defaults.json``. ``--law NAME`` (repeatable) runs only those laws.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, machine_info, quiet, save_json, table, uniform_model  # noqa: E402

TARGET_SPEEDUP = 1.7
SAMPLE = 1e-7
#: Simulated time of a ``--defaults`` row [s] (the wave crosses a few beads; every bead is stepped).
DEFAULTS_DURATION = 2e-4


def law_models(n_beads: int) -> dict:
    """Every built-in law on a uniform chain of ``n_beads`` beads (the ``--laws`` rows)."""
    import hertzchain as hc

    base = uniform_model(n_beads)
    laws = {"elastic": None, "viscoelastic": hc.Viscoelastic(A=2e-6), "dashpot": hc.Dashpot(gamma=20.0),
            "viscoelastic_scaled": hc.ScaledViscoelastic(5e-6, 26e-3), "dashpot_scaled": hc.ScaledDashpot(25.0, 26e-3),
            "elastoplastic": hc.Elastoplastic(), "power_n1.7": hc.PowerLaw(1.7, 2e11),
            "hunt_crossley": hc.HuntCrossley(0.8)}
    out = {}
    for name, law in laws.items():
        striker = hc.Striker(base.striker.diameter, 2.0) if name == "elastoplastic" else base.striker
        out[name] = base if law is None else hc.Model(base.chain, striker, base.wall, law)
    return out


def measure(n_beads: int, threads: int, repeat: int, min_time: float, model=None) -> dict:
    """Bead-steps/s of one thread and of ``threads`` threads on a chain of ``n_beads`` beads
    (``model``: that chain with another law; default the elastic uniform chain)."""
    from hertzchain.integrate.drivers.threaded import run_verlet_threaded
    from hertzchain.integrate.drivers.verlet import run_verlet

    system = (model or uniform_model(n_beads)).system()
    run_verlet(system, 2 * SAMPLE, SAMPLE, contacts=np.array([0, n_beads]))  # compile both (a registry law's
    run_verlet_threaded(system, 2 * SAMPLE, SAMPLE, threads, contacts=np.array([0, n_beads]))  # loops: per process)
    rec = np.array([0, n_beads])
    # calibrate the duration on one thread: >= min_time per run
    duration = 2e-6
    while True:
        t0 = time.perf_counter()
        run_verlet(system, duration, SAMPLE, contacts=rec)
        if time.perf_counter() - t0 >= min_time:
            break
        duration *= 2
    one_t, many_t, loads = [], [], []
    one = many = None
    for _ in range(repeat):
        loads.append(os.getloadavg()[0])
        t0 = time.perf_counter()
        one = run_verlet(system, duration, SAMPLE, contacts=rec)
        one_t.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        many = run_verlet_threaded(system, duration, SAMPLE, threads, contacts=rec)
        many_t.append(time.perf_counter() - t0)
    loads.append(os.getloadavg()[0])
    same = bool(np.array_equal(one.contact_force, many.contact_force) and one.n_steps == many.n_steps
                and one.peak_wall_force == many.peak_wall_force)
    # the threaded loop on one block against the one-thread loop, in CPU time (no barrier waits:
    # what other work on the cores does not change much)
    cpu_one, cpu_block = [], []
    for _ in range(repeat):
        t0 = time.thread_time()
        run_verlet(system, duration, SAMPLE, contacts=rec)
        cpu_one.append(time.thread_time() - t0)
        t0 = time.thread_time()
        run_verlet_threaded(system, duration, SAMPLE, 1, contacts=rec)
        cpu_block.append(time.thread_time() - t0)
    work = n_beads * one.n_steps
    return {"n_beads": n_beads, "threads": threads, "duration_s": duration, "steps": one.n_steps,
            "one_thread_s": min(one_t), "threads_s": min(many_t), "one_thread_times_s": one_t, "threads_times_s": many_t,
            "one_thread_bead_steps_per_s": work / min(one_t), "threads_bead_steps_per_s": work / min(many_t),
            "speedup": min(one_t) / min(many_t), "bit_identical_forces_and_steps": same,
            "one_block_over_one_thread_cpu": min(cpu_block) / min(cpu_one),
            "load_average_1min": loads}


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", type=Path, default=RESULTS / "long_chain.json", help="where to save the results")
    ap.add_argument("--quick", action="store_true", help="1e4 and 1e5 beads, fewer repetitions")
    ap.add_argument("--threads", type=int, default=os.cpu_count(), help="threads of the split chain")
    ap.add_argument("--laws", action="store_true", help="every built-in contact law on one chain (--beads)")
    ap.add_argument("--beads", type=int, default=100_000, help="beads of the --laws / --defaults chain")
    ap.add_argument("--defaults", action="store_true", help="the default call against the Verlet on 1 and T threads")
    ap.add_argument("--law", action="append", help="--defaults: only this law (repeatable; default: every law)")
    args = ap.parse_args(argv)
    quiet()
    if args.laws:
        return main_laws(args)
    if args.defaults:
        return main_defaults(args)
    repeat, min_time = (3, 0.2) if args.quick else (5, 0.3)
    sizes = (10_000, 100_000) if args.quick else (10_000, 100_000, 1_000_000)
    info = machine_info()
    print(f"long chains — {info['cpu_model']}, {info['usable_cores']} usable cores, load {info['load_average_at_start']}")
    # warm the JIT (and its cache) on a chain long enough to be split
    from hertzchain.integrate.drivers.threaded import run_verlet_threaded

    run_verlet_threaded(uniform_model(5000).system(), 1e-6, SAMPLE, args.threads)
    rows = [measure(n, args.threads, repeat, min_time) for n in sizes]
    res = {"benchmark": "long_chain", "quick": args.quick, "machine": info, "rows": rows,
           "load_average_at_end": list(os.getloadavg())}
    at_1e5 = next(r for r in rows if r["n_beads"] == 100_000)
    res["speedup_1e5"] = at_1e5["speedup"]
    res["targets"] = {"speedup_1e5_on_2_cores": TARGET_SPEEDUP,
                      "met": bool(at_1e5["speedup"] >= TARGET_SPEEDUP and args.threads == 2)}
    print(table([(f"{r['n_beads']:,}", r["steps"], f"{r['one_thread_bead_steps_per_s']:.3g}",
                  f"{r['threads_bead_steps_per_s']:.3g}", f"{r['speedup']:.2f}",
                  "yes" if r["bit_identical_forces_and_steps"] else "NO",
                  " ".join(f"{x:.1f}" for x in r["load_average_1min"])) for r in rows],
                ("beads", "steps", "1 thread", f"{args.threads} threads", "speed-up", "bit-identical",
                 "load (1 min) during")))
    print(f"\n>= {TARGET_SPEEDUP}x on 2 cores at 1e5 beads: {res['speedup_1e5']:.2f}x with {args.threads} threads -> "
          f"{'MET' if res['targets']['met'] else 'NOT MET'} (load at the end {res['load_average_at_end'][0]:.1f})")
    save_json(res, args.json)
    print(f"saved {args.json}")
    return res


def main_laws(args) -> dict:
    """The ``--laws`` comparison (module docstring)."""
    json_path = RESULTS / "long_chain_laws.json" if args.json == RESULTS / "long_chain.json" else args.json
    info = machine_info()
    print(f"one chain of {args.beads:,} beads, every law, 1 vs {args.threads} threads — {info['cpu_model']}, "
          f"{info['usable_cores']} usable cores, load {info['load_average_at_start']}")
    from hertzchain.integrate.drivers import threaded

    calls: list[int] = []
    record = threaded.Pace.record

    def spy(self, n, *rest):  # the thread count of every compiled call of a run asked for several
        if self.threads > 1:
            calls.append(n)
        record(self, n, *rest)

    threaded.Pace.record = spy
    rows = []
    for name, model in law_models(args.beads).items():
        calls.clear()
        r = measure(args.beads, args.threads, 2, 2.0, model)
        r["law"] = name
        r["calls_by_threads"] = {str(n): calls.count(n) for n in sorted(set(calls))}
        rows.append(r)
        print(f"  {name}: {r['speedup']:.2f}x (load {r['load_average_1min'][-1]:.1f})", flush=True)
    end_load = list(os.getloadavg())
    res = {"benchmark": "long_chain_laws", "machine": info, "rows": rows, "load_average_at_end": end_load,
           "clean": bool(max(max(r["load_average_1min"]) for r in rows) < 0.5),
           "targets": {"speedup_on_2_idle_cores": TARGET_SPEEDUP,
                       "met": bool(all(r["speedup"] >= TARGET_SPEEDUP for r in rows) and args.threads == 2)}}
    print(table([(r["law"], r["steps"], f"{r['one_thread_bead_steps_per_s']:.3g}",
                  f"{r['threads_bead_steps_per_s']:.3g}", f"{r['speedup']:.2f}",
                  f"{r['one_block_over_one_thread_cpu']:.2f}",
                  "yes" if r["bit_identical_forces_and_steps"] else "NO",
                  " ".join(f"{x:.1f}" for x in r["load_average_1min"]),
                  " ".join(f"{k}:{v}" for k, v in r["calls_by_threads"].items())) for r in rows],
                ("law", "steps", "1 thread", f"{args.threads} threads", "speed-up", "1 block / 1 thread CPU",
                 "bit-identical", "load (1 min) during", "calls on n threads")))
    if not res["clean"]:
        print("\nthe load average was >= 0.5 during the runs: other work shared the cores, the speed-ups are not a "
              f"clean measurement of the threads (target: >= {TARGET_SPEEDUP}x on 2 idle cores)")
    save_json(res, json_path)
    print(f"saved {json_path}")
    return res


def main_defaults(args) -> dict:
    """The ``--defaults`` comparison (module docstring)."""
    import hertzchain as hc

    json_path = RESULTS / "long_chain_defaults.json" if args.json == RESULTS / "long_chain.json" else args.json
    info = machine_info()
    print(f"one chain of {args.beads:,} beads, the default call against the Verlet on 1 and {args.threads} threads "
          f"— {info['cpu_model']}, {info['usable_cores']} usable cores, load {info['load_average_at_start']}")
    many = f"default, {args.threads} threads"
    calls = {"default": {}, "verlet, 1 thread": {"integrator": "verlet", "threads": 1},
             f"verlet, {args.threads} threads": {"integrator": "verlet", "threads": args.threads},
             "default, 1 thread": {"threads": 1}, many: {"threads": args.threads}}
    from hertzchain.integrate.drivers import threaded

    paced: list[int] = []
    record = threaded.Pace.record

    def spy(self, n, *rest):  # the thread count of every compiled call of a run asked for several
        if self.threads > 1:
            paced.append(n)
        record(self, n, *rest)

    threaded.Pace.record = spy
    rows = []
    for name, model in law_models(args.beads).items():
        if args.law and name not in args.law:
            continue
        for kw in calls.values():
            hc.simulate(model, 2 * SAMPLE, **kw)  # compile
        best = dict.fromkeys(calls, np.inf)
        attrs = {}
        load = [os.getloadavg()[0]]
        forces = {}
        calls_by_threads: dict[str, int] = {}
        for _ in range(3):
            for label, kw in calls.items():
                paced.clear()
                t0 = time.perf_counter()
                ds = hc.simulate(model, DEFAULTS_DURATION, **kw)
                best[label] = min(best[label], time.perf_counter() - t0)
                attrs[label] = (ds.attrs.get("integrator_used"), int(ds.attrs.get("threads_used", 1)))
                forces[label] = ds.contact_force.values
                if label == many:
                    for n in paced:
                        calls_by_threads[str(n)] = calls_by_threads.get(str(n), 0) + 1
        load.append(os.getloadavg()[0])
        one, two = forces["default, 1 thread"], forces[many]
        row = {"law": name, "seconds": best, "engines": attrs, "load_average_1min": load,
               "default_over_verlet_threads": best[list(calls)[2]] / best["default"],
               "default_over_verlet_1": best["verlet, 1 thread"] / best["default"],
               # the default integrator on T threads against one (rkn4's threads: aligned elastic
               # chains; for the other laws "auto" with T threads takes the Verlet), the calls its
               # runs made on 1 and T threads (the fallback on shared cores), its forces' largest
               # difference from one thread's relative to the largest force
               "default_threads_speedup": best["default, 1 thread"] / best[many],
               "default_threads_calls_by_threads": calls_by_threads,
               "default_threads_force_rel_diff": float(np.abs(one - two).max() / max(np.abs(one).max(), 1e-300))}
        rows.append(row)
        print(f"  {name}: default {best['default']:.3f} s ({attrs['default'][0]}, {attrs['default'][1]} thread(s)); "
              f"verlet 1 thread {best['verlet, 1 thread']:.3f} s; verlet {args.threads} threads "
              f"{best[list(calls)[2]]:.3f} s; default on {args.threads} threads "
              f"({attrs[many][0]}) {row['default_threads_speedup']:.2f}x one (load {load[-1]:.1f})", flush=True)
    res = {"benchmark": "long_chain_defaults", "machine": info, "n_beads": args.beads, "duration_s": DEFAULTS_DURATION,
           "rows": rows, "load_average_at_end": list(os.getloadavg()),
           "clean": bool(max(max(r["load_average_1min"]) for r in rows) < 0.5),
           "targets": {"default_threads_speedup_on_2_idle_cores": TARGET_SPEEDUP,
                       "met": bool(all(r["default_threads_speedup"] >= TARGET_SPEEDUP for r in rows)
                                   and args.threads == 2)}}
    print(table([(r["law"], r["engines"]["default"][0], f"{r['engines']['default'][1]}", f"{r['seconds']['default']:.3f}",
                  f"{r['default_over_verlet_1']:.2f}", f"{r['default_over_verlet_threads']:.2f}",
                  f"{r['engines'][many][0]}", f"{r['default_threads_speedup']:.2f}",
                  " ".join(f"{k}:{v}" for k, v in r["default_threads_calls_by_threads"].items()),
                  f"{r['default_threads_force_rel_diff']:.1e}") for r in rows],
                ("law", "default engine", "threads", "default [s]", "verlet 1 thread / default",
                 f"verlet {args.threads} threads / default", f"{args.threads}-thread engine",
                 f"default {args.threads} threads / 1", "calls on n threads", "force diff")))
    if not res["clean"]:
        print(f"load average up to {max(max(r['load_average_1min']) for r in rows):.1f}: the cores were shared, not a "
              f"clean measurement of the threads (target: >= {TARGET_SPEEDUP}x on 2 idle cores)")
    save_json(res, json_path)
    print(f"saved {json_path}")
    return res


if __name__ == "__main__":
    main()
