"""The dissipative laws' fused kernels against a bare loop of the same law.

Usage::

    python benchmarks/dissipative.py [--json PATH] [--quick]

For each law (Kuwabara-Kono ``viscoelastic``, ``dashpot``, ``elastoplastic``), on a uniform chain
of 30 beads of 26 mm AISI 52100 hit at 1 m/s (the elastoplastic chain yields at the striker), flat
wall, fixed step dt = 5 ns, one core (``NUMBA_NUM_THREADS=1``), best of N runs of 2.5 ms (500,000
steps: the impact, the pulse's transit and its reflection, as the paper's runs):

- **hertzchain**: ``run_verlet(Model(...).system(), ...)``, default probes (every contact force,
  the energies and the dissipated energy every 100 ns; the wall peak tracked every step);
- **bare loop** (the baseline, defined here): the minimal velocity-Verlet loop computing that
  law's forces and the leapfrog update, written as one writes it in Numba in ten minutes, compiled
  the same way (``@njit``, no fastmath): a kick-drift loop over the bodies, a loop over the
  contacts computing the force at the velocities predicted half a step ahead (v + dt/2 a, what
  keeps a velocity-dependent force second order; the elastoplastic loop calls the package's
  ``kernels.elastoplastic_force`` with its state), a loop for the accelerations and a closing
  half kick; no probes, no padding, no dissipated-energy integral, no peak tracking;
- **general two-pass loop**: what ``run_verlet`` ran before the fused kernels (a pass predicting
  velocities, ``kernels.forces_general``, a pass for the accelerations and the kick-drift), the
  same numbers, for reference.

``ratio_to_bare`` = hertzchain / bare throughput (target >= 0.85 for every law). Bead-steps/s
count the 30 beads. Timed in CPU time of the thread (``time.thread_time``), best of N, the three
alternated: on a shared machine wall-clock time also counts the time other work held the core
(the wall-clock rates are saved too).
"""

from __future__ import annotations

import os

os.environ["NUMBA_NUM_THREADS"] = "1"

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np
from numba import njit

from hertzchain.integrate.core.kernels import elastoplastic_force, forces_general

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, machine_info, quiet, save_json, table  # noqa: E402

DT = 5e-9
SAMPLE = 1e-7
DURATION = 2.5e-3
N_BEADS = 30
TARGET = 0.85
LAWS = ("viscoelastic", "dashpot", "elastoplastic")


@njit(nogil=True)
def bare_loop(u, v, a, f, kappa, damping, inv_m, law, dyield, dmax, dres, kres, dt, n_steps):
    """The bare loop (module docstring). Bodies 0..n-1 = striker, beads, wall (inv_m = 0)."""
    n = u.shape[0]
    h = 0.5 * dt
    for _ in range(n_steps):
        for i in range(n):
            v[i] += h * a[i]
            u[i] += dt * v[i]
        for j in range(n - 1):
            d = u[j] - u[j + 1]
            if d >= 0.0:
                rate = (v[j] + h * a[j]) - (v[j + 1] + h * a[j + 1])
                if law == 3:
                    f[j], _, dmax[j], dres[j], kres[j] = elastoplastic_force(d, rate, kappa[j], damping[j], dyield[j],
                                                                             dmax[j], dres[j], kres[j])
                else:
                    sd = math.sqrt(d)
                    x = kappa[j] * d * sd + (kappa[j] * damping[j] * sd * rate if law == 1 else damping[j] * rate)
                    f[j] = max(x, 0.0)
            else:
                f[j] = 0.0
        a[0] = -f[0] * inv_m[0]
        for i in range(1, n - 1):
            a[i] = (f[i - 1] - f[i]) * inv_m[i]
        for i in range(n):
            v[i] += h * a[i]


@njit(nogil=True)
def general_loop(u, v, a, g, vp, kappa, damping, d0, de, dx0, rsum, fext, inv_mass, law, dyield, dmax, dres, kres, dt,
                 n_steps):
    """What verlet_run ran for a dissipative law before the fused kernels (its general branch,
    without probes)."""
    n = a.shape[0]
    half = 0.5 * dt
    e = 0.0
    for i in range(n):
        v[i] += half * a[i]
        u[i] += dt * v[i]
    for _ in range(n_steps):
        for i in range(n):
            vp[i] = v[i] + half * a[i]
        e += forces_general(u, vp, kappa, damping, d0, de, dx0, rsum, law, g, dyield, dmax, dres, kres)
        for i in range(n):
            a[i] = (g[i] - g[i + 1] + fext[i]) * inv_mass[i]
            v[i] += dt * a[i]
            u[i] += dt * v[i]
    return e


def model(law: str):
    import hertzchain as hc

    laws = {"viscoelastic": hc.Viscoelastic(A=2e-6), "dashpot": hc.Dashpot(gamma=5.0),
            "elastoplastic": hc.Elastoplastic()}
    return hc.Model(hc.Chain.uniform(N_BEADS, 26e-3), hc.Striker(8e-3, 1.0), hc.Wall("flat"), law=laws[law])


def measure_law(law: str, repeat: int) -> dict:
    from hertzchain.integrate.core.layout import pack
    from hertzchain.integrate.drivers.verlet import run_verlet

    system = model(law).system()
    stride = round(SAMPLE / DT)
    nb = system.n_beads + 1

    def hc_run(steps: int):
        return run_verlet(system, steps * DT, SAMPLE, dt=DT)

    def bare(steps: int):
        w = pack(system)
        u = np.zeros(nb + 1)
        v = np.zeros(nb + 1)
        v[:nb] = system.v0[:nb]
        inv_m = np.zeros(nb + 1)
        inv_m[:nb] = system.inv_mass[:nb]
        bare_loop(u, v, np.zeros(nb + 1), np.zeros(nb), w.kappa[:nb], w.damping[:nb], inv_m, system.law,
                  w.dyield[:nb].copy(), w.dmax[:nb].copy(), w.dres[:nb].copy(), w.kres[:nb].copy(), DT, steps)

    def general(steps: int):
        w = pack(system)
        p = w.n_slots
        general_loop(w.u, w.v, np.zeros(p), np.zeros(p + 1), np.zeros(p + 1), w.kappa, w.damping, w.d0, w.de, w.dx0,
                     w.rsum, w.fext, w.inv_mass, system.law, w.dyield, w.dmax, w.dres, w.kres, DT, steps)

    out = {"law": law}
    fns = (("hertzchain", hc_run, stride), ("bare", bare, 1), ("general_two_pass", general, 1))
    steps = {}
    for name, fn, st in fns:
        fn(10 * st)  # compile / warm
        # a run of the paper's length: the impact, the pulse's transit and its reflection (on
        # much longer runs the beads fly apart and a loop that skips open contacts gains)
        steps[name] = round(DURATION / DT / st) * st
    cpu = {name: [] for name, _, _ in fns}
    wall = {name: [] for name, _, _ in fns}
    for _ in range(repeat):  # alternated, so that a disturbance of the shared machine hits all alike
        for name, fn, _ in fns:
            t0, c0 = time.perf_counter(), time.thread_time()
            fn(steps[name])
            cpu[name].append(time.thread_time() - c0)
            wall[name].append(time.perf_counter() - t0)
    for name, _, _ in fns:
        best = min(cpu[name])
        out[name] = {"steps": steps[name], "best_cpu_s": best, "cpu_times_s": cpu[name], "wall_times_s": wall[name],
                     "bead_steps_per_s": N_BEADS * steps[name] / best,
                     "bead_steps_per_s_wall": N_BEADS * steps[name] / min(wall[name])}
    out["ratio_to_bare"] = out["hertzchain"]["bead_steps_per_s"] / out["bare"]["bead_steps_per_s"]
    out["speedup_vs_general_two_pass"] = (out["hertzchain"]["bead_steps_per_s"]
                                          / out["general_two_pass"]["bead_steps_per_s"])
    return out


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", type=Path, default=RESULTS / "dissipative.json", help="where to save the results")
    ap.add_argument("--quick", action="store_true", help="fewer, shorter repetitions")
    args = ap.parse_args(argv)
    quiet()
    repeat = 3 if args.quick else 9
    info = machine_info()
    print(f"dissipative kernels — {info['cpu_model']}, load {info['load_average_at_start']}, {info['date_utc']}")
    rows = {law: measure_law(law, repeat) for law in LAWS}
    res = {"benchmark": "dissipative", "quick": args.quick, "machine": info,
           "settings": {"chain": f"uniform {N_BEADS} x 26 mm AISI52100, striker 8 mm at 1 m/s, flat wall", "dt": DT,
                        "probes": "hertzchain: default (all contact forces + energies every 100 ns)"},
           "laws": rows, "load_average_at_end": list(os.getloadavg())}
    res["targets"] = {"ratio_to_bare": TARGET, "met": {law: bool(r["ratio_to_bare"] >= TARGET) for law, r in rows.items()}}
    print(table([(law, f"{r['hertzchain']['bead_steps_per_s']:.3g}", f"{r['bare']['bead_steps_per_s']:.3g}",
                  f"{r['general_two_pass']['bead_steps_per_s']:.3g}", f"{r['ratio_to_bare']:.2f}",
                  f"{r['speedup_vs_general_two_pass']:.2f}") for law, r in rows.items()],
                ("law", "hertzchain", "bare loop", "general 2-pass", "hc / bare", "hc / 2-pass")))
    print("\n>= %.2f of the bare loop: %s" % (TARGET, ", ".join(
        f"{law} {'MET' if ok else 'NOT MET'}" for law, ok in res["targets"]["met"].items())))
    save_json(res, args.json)
    print(f"saved {args.json}")
    return res


if __name__ == "__main__":
    main()
