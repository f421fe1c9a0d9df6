"""simulate()'s Python around the kernel, and what integrator/threads = "auto" picks.

Overhead: CPU time of ``hc.simulate(model, duration, probes)`` less that of the engine call it makes
(``run_rkn`` / ``run_verlet`` with the same arguments), on a short elastic chain with a short
record, so that the kernel is small and the Python around it shows. Each timing is the median of
``--repeat`` blocks of ``--calls`` calls, warm (kernels compiled first), CPU time
(``time.process_time``: the machine is shared, wall time is noisy); the load average is saved.

Auto: the CPU time per run of chain 1 (elastic and the reproduction's ``dashpot_scaled`` law) with
the defaults against each integrator named, the default probes.

Batch: ``simulate_batch`` end to end against the compiled batched loop it calls, CPU time, one
thread (:func:`batch_ratio`).

    .venv/bin/python benchmarks/overhead.py [--json benchmarks/results/overhead.json]
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
import warnings
from pathlib import Path

from _common import RESULTS, machine_info, save_json

import hertzchain as hc


def _cpu_per_call(fn, calls: int, repeat: int) -> float:
    """Median over ``repeat`` blocks of the CPU seconds per call of ``fn``."""
    fn()
    out = []
    for _ in range(repeat):
        t = time.process_time()
        for _ in range(calls):
            fn()
        out.append((time.process_time() - t) / calls)
    return statistics.median(out)


def overhead(calls: int, repeat: int) -> dict:
    from hertzchain.integrate.drivers.rkn import run_rkn
    from hertzchain.integrate.drivers.verlet import run_verlet

    model = hc.Model(hc.Chain.uniform(6, 20e-3), hc.Striker(8e-3, 0.2))
    probes = hc.Probes(sample_interval=1e-6, sensors=(3,))
    duration = 4e-4  # the pulse reaches the wall (no PulseNotReachedWarning in the timing)
    system = model.system()
    rec = probes.recorded_contacts(6, True)
    res = {}
    for name, engine in (("rkn4", lambda: run_rkn(system, duration, probes.sample_interval, contacts=rec)),
                         ("verlet", lambda: run_verlet(system, duration, probes.sample_interval, contacts=rec))):
        total = _cpu_per_call(lambda: hc.simulate(model, duration, probes, integrator=name, threads=1), calls, repeat)
        kernel = _cpu_per_call(engine, calls, repeat)
        res[name] = {"simulate_ms": total * 1e3, "engine_ms": kernel * 1e3, "overhead_ms": (total - kernel) * 1e3}
    return res


def auto_choice(repeat: int) -> dict:
    from hertzchain.config import build_model, load_config
    from hertzchain.engine_choice import choose_engine

    out = {}
    for label, path in (("chain1 elastic", "examples/chain1_elastic.toml"), ("chain1 dashpot_scaled", "examples/chain1.toml")):
        model = build_model(load_config(path, ()))
        row = {"auto_picks": choose_engine(model.system()).integrator}
        for name in ("auto", "verlet", "rkn4"):
            try:
                row[f"{name}_ms"] = 1e3 * _cpu_per_call(lambda: hc.simulate(model, 3e-3, integrator=name), 1, repeat)
            except hc.ConfigError:
                row[f"{name}_ms"] = None  # rkn4 refuses dissipative laws
        out[label] = row
    return out


def batch_ratio(members: int, repeat: int) -> dict:
    """``simulate_batch`` end to end against its engine: chain 1 elastic, ``members`` strikers at
    0.1-0.3 m/s (one layout: the array set-up), 3 ms, default probes, one thread. The engine's CPU
    time is that spent inside ``batch._engine`` (the compiled batched loop) in the same calls;
    the best of ``repeat`` calls. Target (issue 37): engine / end to end >= 0.85."""
    import numpy as np

    from hertzchain.config import build_model, load_config
    from hertzchain.runs import batch

    base = build_model(load_config("examples/chain1_elastic.toml", ()))
    models = [hc.Model(base.chain, hc.Striker(base.striker.diameter, float(v)), base.wall, base.law)
              for v in np.linspace(0.1, 0.3, members)]
    engine = batch._engine
    spent = [0.0]

    def timed(*args, **kwargs):  # the engine's options (integrator, ...) passed on
        t = time.process_time()
        try:
            return engine(*args, **kwargs)
        finally:
            spent[0] += time.process_time() - t

    batch._engine = timed
    try:
        hc.simulate_batch(models[:2], 3e-3, n_threads=1)  # compiled first
        rows = []
        for _ in range(repeat):
            spent[0] = 0.0
            t = time.process_time()
            hc.simulate_batch(models, 3e-3, n_threads=1)
            rows.append((time.process_time() - t, spent[0]))
    finally:
        batch._engine = engine
    total, kernel = min(rows)
    return {"members": members, "end_to_end_s": total, "engine_s": kernel, "engine_share": kernel / total}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", default=str(RESULTS / "overhead.json"))
    ap.add_argument("--calls", type=int, default=200)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--members", type=int, default=64, help="members of the simulate_batch timing")
    ap.add_argument("--overhead-only", action="store_true",
                    help="only the overhead (runs on versions before integrator 'auto', for a baseline)")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    os.chdir(os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
    load0 = os.getloadavg()
    res = {"overhead": overhead(args.calls, args.repeat),
           "auto": {} if args.overhead_only else auto_choice(args.repeat)}
    res["batch"] = None if args.overhead_only else batch_ratio(args.members, args.repeat)
    res["load_average"] = [load0, os.getloadavg()]
    for name, r in res["overhead"].items():
        print(f"simulate() {name}: {r['simulate_ms']:.3f} ms CPU, engine {r['engine_ms']:.3f} ms, "
              f"overhead {r['overhead_ms']:.3f} ms")
    for label, r in res["auto"].items():
        print(f"{label}: auto picks {r['auto_picks']}; CPU per run auto {r['auto_ms']:.2f} ms, verlet "
              f"{r['verlet_ms']:.2f} ms, rkn4 " + ("refused" if r["rkn4_ms"] is None else f"{r['rkn4_ms']:.2f} ms"))
    if res["batch"]:
        b = res["batch"]
        print(f"simulate_batch, {b['members']} members of chain 1: {b['end_to_end_s']:.3f} CPU-s end to end, engine "
              f"{b['engine_s']:.3f} CPU-s: engine share {b['engine_share']:.3f}")
    print(f"load average {res['load_average']}")
    save_json({"machine": machine_info(), **res}, Path(args.json))


if __name__ == "__main__":
    main()
