"""Cost of the elastoplastic (Thornton) contact law against the elastic and viscous laws.

Usage::

    python benchmarks/plasticity.py [--json PATH] [--quick]

The paper's chain 1 (30 beads) hit by the 8 mm striker at 2 m/s (the striker contact and the
first beads yield), 2 ms at a fixed step of 5 ns (400,000 steps), default probes every 100 ns,
run with :func:`hertzchain.integrate.drivers.verlet.run_verlet` under four laws, each the best of several
calls after a warm-up (compilation excluded):

- ``elastic``: Hertz, the fused vectorised path (``kernels.step_elastic``);
- ``viscoelastic``: Kuwabara-Kono (A = 4.5 us), the general force loop: the baseline of the
  dissipative laws;
- ``elastoplastic``: Thornton's law with its per-contact state (general loop);
- ``elastoplastic_viscous``: Thornton plus the Kuwabara-Kono term (A = 4.5 us).

Prints and saves ns per bead-step (time / (steps x moving bodies)) and the ratios to the
elastic and viscoelastic laws, with machine info (default benchmarks/results/plasticity.json).
The time is the process's CPU time (``time.process_time``), best of the repetitions: on a shared
machine the wall time also counts the time other processes hold the core; the wall time is saved
beside it. Single core (``NUMBA_NUM_THREADS=1``). Takes ~15 s.
"""

from __future__ import annotations

import os

os.environ["NUMBA_NUM_THREADS"] = "1"  # one core, before numba is imported anywhere

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, best_of, machine_info, save_json, table  # noqa: E402

DURATION = 2e-3
DT = 5e-9
SAMPLE = 1e-7
VELOCITY = 2.0


def models() -> dict:
    import hertzchain as hc

    chain = hc.paper_chain("chain1")
    striker = hc.Striker(8e-3, VELOCITY)
    laws = {"elastic": hc.Elastic(), "viscoelastic": hc.Viscoelastic(4.5e-6), "elastoplastic": hc.Elastoplastic(),
            "elastoplastic_viscous": hc.Elastoplastic(A=4.5e-6)}
    return {name: hc.Model(chain, striker, hc.Wall("flat"), law) for name, law in laws.items()}


def runner(model, duration: float):
    from hertzchain.integrate.drivers.verlet import run_verlet

    system = model.system()
    return lambda: run_verlet(system, duration, SAMPLE, dt=DT)


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", type=Path, default=RESULTS / "plasticity.json", help="where to save the results")
    ap.add_argument("--quick", action="store_true", help="0.5 ms runs, 2 repetitions")
    args = ap.parse_args(argv)
    duration, repeat = (5e-4, 2) if args.quick else (DURATION, 5)
    rows = {}
    for name, model in models().items():
        t0 = time.perf_counter()
        runner(model, 2 * SAMPLE)()  # compile (or load the cache) and warm up
        warm = time.perf_counter() - t0
        run = runner(model, duration)
        best, times, raw = best_of(run, repeat)
        cpu = []
        for _ in range(repeat):
            c0 = time.process_time()
            run()
            cpu.append(time.process_time() - c0)
        bodies = model.chain.n_beads + 1
        rows[name] = {"steps": int(raw.n_steps), "bodies": bodies, "best_s": best, "times_s": times,
                      "best_cpu_s": min(cpu), "cpu_s": cpu, "warmup_s": warm,
                      "ns_per_bead_step": 1e9 * min(cpu) / (raw.n_steps * bodies),
                      "wall_ns_per_bead_step": 1e9 * best / (raw.n_steps * bodies),
                      "peak_wall_force": float(raw.peak_wall_force),
                      "plastic_work": None if raw.plastic_work is None else float(raw.plastic_work[-1])}
    ns = {k: r["ns_per_bead_step"] for k, r in rows.items()}
    ratios = {"elastoplastic/elastic": ns["elastoplastic"] / ns["elastic"],
              "elastoplastic/viscoelastic": ns["elastoplastic"] / ns["viscoelastic"],
              "elastoplastic_viscous/viscoelastic": ns["elastoplastic_viscous"] / ns["viscoelastic"]}
    print(table([(k, r["steps"], f"{r['best_cpu_s'] * 1e3:.1f}", f"{r['ns_per_bead_step']:.2f}",
                  f"{r['wall_ns_per_bead_step']:.2f}", f"{r['peak_wall_force']:.2f}") for k, r in rows.items()],
                ("law", "steps", "best CPU ms", "ns/bead-step", "(wall)", "peak wall N")))
    for k, v in ratios.items():
        print(f"{k}: {v:.2f} x")
    res = {"benchmark": "plasticity", "machine": machine_info(), "duration": duration, "dt": DT,
           "velocity": VELOCITY, "laws": rows, "ratios": ratios}
    save_json(res, args.json)
    print(f"saved {args.json}")
    return res


if __name__ == "__main__":
    main()
