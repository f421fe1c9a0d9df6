"""Per-law cost per bead-step: the engine of each registered law against a bare Numba loop of it.

Usage::

    python benchmarks/laws.py [--json PATH] [--quick] [--before PATH] [--laws elastic,dashpot,...]

For every law (the built-in ones, the power law at n = 3/2 and n = 2, the values its generated
loop compiles as constants, and at n = 2.5, read per contact; Hunt-Crossley), on the
paper's chain 1 (30 beads, striker 8 mm at 0.2 m/s, flat wall) and on 300 uniform 26 mm beads,
fixed step dt = 20 ns, one core (``NUMBA_NUM_THREADS=1``), best of N, about 1.2e7 bead-steps a
run (400,000 steps on chain 1, 50,000 on 300 beads, so that the Python set-up of a run is
below 1 % of it):

- **hertzchain**: ``run_verlet(Model(...).system(), ...)`` as a run does it: the engine's own
  kernel and per-step work (the wall peak every step), its probes (every contact force and
  the energies) every 50 steps (1 us), sparse enough that they are not what is measured: the
  hand-written kernels for the built-in laws, the loop generated from the declaration
  (:mod:`hertzchain.integrate.core.generated`) for the power and Hunt-Crossley laws;
- **bare loop** (the baseline the issue names): symplectic Euler, one fused loop over the
  contacts then one over the bodies, v += dt a(u, v); u += dt v, with the law's own scalar
  ``force`` and ``state`` functions from its declaration (the elastic-plastic law:
  ``kernels.elastoplastic_force`` with its state), no probes, no padding, compiled with ``@njit``.

``--before PATH`` reads an earlier run's JSON (e.g. the code before a change) and adds its
engine times to the rows (``before_ns_per_bead_step``) and to the table.

``ratio_to_bare`` = hertzchain time / bare time per bead-step; ``ratio_to_elastic`` = a law's
hertzchain time over the elastic law's on the same chain. CPU time of the thread
(``time.thread_time``).
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from numba import njit  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, machine_info, quiet, save_json, table  # noqa: E402

from hertzchain.integrate.core.kernels import elastoplastic_force  # noqa: E402

DT = 2e-8
SAMPLE = 1e-6  # probes every 50 steps
BEAD_STEPS = 12_000_000  # per timed run


def _bare(force, update):
    @njit(nogil=True)
    def loop(u, v, kappa, damping, inv_m, state, dt, n_steps):
        n = u.shape[0]
        f = np.zeros(n)
        for _ in range(n_steps):
            for j in range(n - 1):
                d = u[j] - u[j + 1]
                rate = v[j] - v[j + 1]
                state[j] = update(d, rate, kappa[j], damping[j], state[j])
                if d >= 0.0:
                    x = force(d, rate, kappa[j], damping[j], state[j])
                    f[j] = x if x > 0.0 else 0.0
                else:
                    f[j] = 0.0
            v[0] -= dt * f[0] * inv_m[0]
            u[0] += dt * v[0]
            for i in range(1, n - 1):
                v[i] += dt * (f[i - 1] - f[i]) * inv_m[i]
                u[i] += dt * v[i]
    return loop


@njit(nogil=True)
def _bare_plastic(u, v, kappa, damping, inv_m, dyield, dt, n_steps):
    n = u.shape[0]
    f = np.zeros(n)
    dmax = np.zeros(n)
    dres = np.zeros(n)
    kres = kappa.copy()
    for _ in range(n_steps):
        for j in range(n - 1):
            d = u[j] - u[j + 1]
            if d >= 0.0:
                f[j], _, dmax[j], dres[j], kres[j] = elastoplastic_force(d, v[j] - v[j + 1], kappa[j], damping[j],
                                                                         dyield[j], dmax[j], dres[j], kres[j])
            else:
                f[j] = 0.0
        v[0] -= dt * f[0] * inv_m[0]
        u[0] += dt * v[0]
        for i in range(1, n - 1):
            v[i] += dt * (f[i - 1] - f[i]) * inv_m[i]
            u[i] += dt * v[i]


def _laws():
    import hertzchain as hc

    return {"elastic": hc.Elastic(), "viscoelastic": hc.Viscoelastic(2e-6), "dashpot": hc.Dashpot(5.0),
            "elastoplastic": hc.Elastoplastic(), "power n=1.5": hc.PowerLaw(1.5),
            "power n=2": hc.PowerLaw(2.0, 1e13), "power n=2.5": hc.PowerLaw(2.5, 1e14),
            "hunt_crossley": hc.HuntCrossley(0.9)}


def measure(chain_name: str, chain, label: str, law, repeat: int) -> dict:
    import hertzchain as hc
    from hertzchain.integrate.drivers.verlet import run_verlet
    from hertzchain.laws import spec_of
    from hertzchain.laws.spec import compiled

    system = hc.Model(chain, hc.Striker(8e-3, 0.2), hc.Wall("flat"), law=law).system()
    spec = spec_of(law)
    nb = system.n_beads + 1
    n_beads = system.n_beads

    steps = max(50_000, int(round(BEAD_STEPS / n_beads, -4)))

    def hc_run(steps):
        run_verlet(system, steps * DT, SAMPLE, dt=DT)

    bare_fn = _bare(compiled(spec.force), compiled(spec.state)) if spec.force is not None else None

    def bare(steps):
        u = np.zeros(nb + 1)
        v = np.zeros(nb + 1)
        v[:nb] = system.v0[:nb]
        inv_m = np.zeros(nb + 1)
        inv_m[:nb] = system.inv_mass[:nb]
        kappa = system.kappa[:nb].copy()
        damping = system.damping[:nb].copy()
        if spec.plastic:
            _bare_plastic(u, v, kappa, damping, inv_m, system.yield_overlap()[:nb].copy(), DT, steps)
        else:
            bare_fn(u, v, kappa, damping, inv_m, np.zeros(nb), DT, steps)

    fns = (("hertzchain", hc_run, round(SAMPLE / DT)), ("bare", bare, 1))
    for _, fn, st in fns:
        fn(10 * st)  # compile / warm
    cpu = {name: [] for name, _, _ in fns}
    for _ in range(repeat):
        for name, fn, _ in fns:
            c0 = time.thread_time()
            fn(steps)
            cpu[name].append(time.thread_time() - c0)
    out = {"chain": chain_name, "law": label, "steps": steps}
    for name, _, _ in fns:
        out[f"{name}_ns_per_bead_step"] = min(cpu[name]) / (steps * n_beads) * 1e9
    out["ratio_to_bare"] = out["hertzchain_ns_per_bead_step"] / out["bare_ns_per_bead_step"]
    return out


def main(argv: list[str] | None = None) -> dict:
    import hertzchain as hc

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", type=Path, default=RESULTS / "laws.json", help="where to save the results")
    ap.add_argument("--quick", action="store_true", help="fewer repetitions")
    ap.add_argument("--before", type=Path, help="an earlier run's JSON whose engine times the rows add")
    ap.add_argument("--laws", help="comma-separated labels of the laws to measure (default: all; the elastic "
                    "law is always measured, the others' ratios are to it)")
    args = ap.parse_args(argv)
    laws = _laws()
    if args.laws:
        wanted = {"elastic", *(x.strip() for x in args.laws.split(","))}
        unknown = wanted - set(laws)
        if unknown:
            ap.error(f"--laws: unknown {sorted(unknown)}; known: {', '.join(laws)}")
        laws = {k: v for k, v in laws.items() if k in wanted}
    before = {}
    if args.before is not None:
        old = json.loads(args.before.read_text())
        before = {(r["chain"], r["law"]): r["hertzchain_ns_per_bead_step"] for r in old["rows"]}
    quiet()
    repeat = 3 if args.quick else 7
    info = machine_info()
    print(f"per-law cost — {info['cpu_model']}, load {info['load_average_at_start']}, {info['date_utc']}")
    rows = []
    for chain_name, chain in (("chain1", hc.paper_chain("chain1")), ("uniform300", hc.Chain.uniform(300, 26e-3))):
        for label, law in laws.items():
            rows.append(measure(chain_name, chain, label, law, repeat))
        elastic = next(r for r in rows if r["chain"] == chain_name and r["law"] == "elastic")
        for r in rows:
            if r["chain"] == chain_name:
                r["ratio_to_elastic"] = r["hertzchain_ns_per_bead_step"] / elastic["hertzchain_ns_per_bead_step"]
    for r in rows:
        if (r["chain"], r["law"]) in before:
            r["before_ns_per_bead_step"] = before[r["chain"], r["law"]]
    print(table([(r["chain"], r["law"], f"{r['before_ns_per_bead_step']:.2f}" if "before_ns_per_bead_step" in r else "-",
                  f"{r['hertzchain_ns_per_bead_step']:.2f}", f"{r['bare_ns_per_bead_step']:.2f}",
                  f"{r['ratio_to_bare']:.2f}", f"{r['ratio_to_elastic']:.2f}") for r in rows],
                ("chain", "law", "before ns/bead-step", "hertzchain ns/bead-step", "bare ns/bead-step", "hc / bare",
                 "hc / elastic")))
    res = {"benchmark": "laws", "quick": args.quick, "machine": info, "dt": DT, "sample_interval": SAMPLE,
           "rows": rows, "before": str(args.before) if args.before else None,
           "load_average_at_end": list(os.getloadavg())}
    save_json(res, args.json)
    print(f"saved {args.json}")
    return res


if __name__ == "__main__":
    main()
