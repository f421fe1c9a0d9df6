"""Speed of the compiled single-chain Verlet, and time-to-solution against scipy.

Usage::

    python benchmarks/kernel.py [--json PATH] [--quick]

Measures, after a JIT warm-up (compile / cache-load time is reported apart from run time):

1. Throughput, in bead-steps per second (beads N x Verlet steps / wall-clock seconds), of
   :func:`hertzchain.integrate.drivers.verlet.run_verlet` on ``Model(...).system()`` for uniform chains
   of 30 and 10,000 beads of 26 mm AISI 52100 hit by the paper's 8 mm striker at 0.5 m/s, flat
   wall, dt = 5 ns, default probes (every contact force, kinetic and potential energy every
   100 ns; wall-force peak tracked every step). Best of several repetitions, each long enough
   (>= 0.3 s). A minimal Hertz-chain Verlet loop written inline here in Numba (no probes, no
   padding) is timed in the same run as the baseline. For 30 beads the first 0.25 ms (the pulse
   crossing the chain) is also timed apart: it runs slower (subnormal floats, see README).
2. Time-to-solution on the contract chain (16 x 26 mm then 24, 23, 22 mm, striker 8 mm at
   0.5 m/s, flat wall, 2.5 ms): wall-clock time to get the peak wall force within 1e-6
   (relative) of a tight reference (DOP853, rtol = 1e-12). hertzchain: ``simulate(model, 2.5e-3)``
   with its automatic (adaptive) step, default probes, Dataset included. scipy: ``solve_ivp`` RK45 and DOP853 with rtol = 1e-4, 1e-5, ...
   (atol scaled alike) until the peak reaches 1e-6, with a plain vectorised NumPy right-hand side
   and, as a stronger baseline, with hertzchain's compiled one.

Single core: ``NUMBA_NUM_THREADS=1`` is set before Numba loads (the single-chain kernel is serial
anyway). Targets stated in the output: >= 5e8 bead-steps/s and >= 10x the faster scipy solver.
"""

from __future__ import annotations

import os

os.environ["NUMBA_NUM_THREADS"] = "1"  # one core, before numba is imported anywhere

import argparse
import json
import math
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from numba import njit

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import (RESULTS, best_of, calibrate, contract_model, machine_info, measure, quiet,  # noqa: E402
                     save_json, table, time_to_solution, time_to_solution_rows, uniform_model)

TARGET_BEAD_STEPS = 5e8
TARGET_SPEEDUP = 10.0
DT = 5e-9                # s, the time step of the throughput measurements
SAMPLE = 1e-7            # s, the default probe interval (100 ns)
DURATION = 2.5e-3        # s, the contract run
TOLERANCE = 1e-6         # relative error required on the peak wall force


# ----------------------------------------------------------------------------- bare baseline
@njit(nogil=True)
def bare_hertz_chain(u, v, a, f, kappa, inv_m, dt, n_steps):
    """Minimal velocity Verlet of a Hertz chain: what one writes in ten minutes with Numba.

    Bodies 0..n-1 = striker, beads, wall (inv_m = 0 so it never moves); f[j] is the force of
    contact j between bodies j and j + 1, F = kappa max(u_j - u_{j+1}, 0)^(3/2) (paper eq. 1).
    No probes, no padding, no peak tracking.
    """
    n = u.shape[0]
    h = 0.5 * dt
    for _ in range(n_steps):
        for i in range(n):
            v[i] += h * a[i]
            u[i] += dt * v[i]
        for j in range(n - 1):
            d = max(u[j] - u[j + 1], 0.0)
            f[j] = kappa[j] * d * math.sqrt(d)
        a[0] = -f[0] * inv_m[0]
        for i in range(1, n - 1):
            a[i] = (f[i - 1] - f[i]) * inv_m[i]
        for i in range(n):
            v[i] += h * a[i]


def bare_state(system):
    """Arrays for :func:`bare_hertz_chain` from a System (striker, beads, wall ghost)."""
    nb = system.n_beads + 1
    u = np.zeros(nb + 1)
    v = np.zeros(nb + 1)
    v[:nb] = system.v0[:nb]
    inv_m = np.zeros(nb + 1)
    inv_m[:nb] = system.inv_mass[:nb]
    return u, v, np.zeros(nb + 1), np.zeros(nb), np.array(system.kappa, dtype=float), inv_m


# ----------------------------------------------------------------------------- throughput
def measure_verlet(n_beads: int, min_time: float, repeat: int) -> dict:
    """Bead-steps/s of run_verlet (dt = 5 ns, default probes) and of the bare loop."""
    from hertzchain.integrate.drivers.verlet import run_verlet

    system = uniform_model(n_beads).system()
    stride = round(SAMPLE / DT)

    def verlet(steps: int):
        return run_verlet(system, steps * DT, SAMPLE, dt=DT)

    def bare(steps: int):
        st = bare_state(system)
        bare_hertz_chain(*st, DT, steps)
        return st

    steps, best, times, raw = measure(verlet, calibrate(verlet, n_beads, stride, min_time), stride, repeat, min_time)
    assert raw.n_steps == steps, (raw.n_steps, steps)
    rate = n_beads * steps / best
    bsteps, bbest, btimes, _ = measure(bare, calibrate(bare, n_beads, 1, min_time), 1, repeat, min_time)
    brate = n_beads * bsteps / bbest
    out = {"n_beads": n_beads, "dt": DT, "steps": steps, "simulated_time_s": steps * DT, "run_time_s": best,
           "times_s": times, "bead_steps_per_s": rate, "ns_per_bead_step": 1e9 / rate,
           "bare_steps": bsteps, "bare_run_time_s": bbest, "bare_times_s": btimes,
           "bare_bead_steps_per_s": brate, "ratio_to_bare": rate / brate}
    if n_beads <= 100:
        # The first 0.25 ms, while the pulse crosses the chain: the precursor ahead of a Hertzian
        # pulse decays super-exponentially (paper Sec. III), so some overlaps, forces and speeds at
        # its edge pass through the subnormal float range, which x86 handles in slow microcode.
        # The long run above is mostly after the pulse has filled the chain.
        k = round(2.5e-4 / DT)
        tt, _, _ = best_of(lambda: verlet(k), 3 * repeat)
        out["transit"] = {"steps": k, "simulated_time_s": k * DT, "run_time_s": tt,
                          "bead_steps_per_s": n_beads * k / tt, "ns_per_bead_step": tt / (n_beads * k) * 1e9}
    return out


def first_call_times() -> dict:
    """JIT warm-up: first (compile or cache load) and second call of run_verlet and of the bare loop."""
    from hertzchain.integrate.drivers.verlet import run_verlet

    system = uniform_model(30).system()
    t_first, _, _ = best_of(lambda: run_verlet(system, 1e-6, SAMPLE, dt=DT), 1)
    t_second, _, _ = best_of(lambda: run_verlet(system, 1e-6, SAMPLE, dt=DT), 1)
    st = bare_state(system)
    b_first, _, _ = best_of(lambda: bare_hertz_chain(*st, DT, 200), 1)
    b_second, _, _ = best_of(lambda: bare_hertz_chain(*st, DT, 200), 1)
    return {"run_verlet_first_call_s": t_first, "run_verlet_second_call_s": t_second,
            "run_verlet_jit_overhead_s": t_first - t_second,
            "bare_loop_compile_s": b_first - b_second,
            "note": "run_verlet's kernels are cached on disk (cache=True): its first call loads the cache "
                    "unless the source changed; cold_compile_s is a fresh compile in an empty cache dir"}


_COLD_SNIPPET = r"""
import json, time
t0 = time.perf_counter()
import hertzchain as hc
from hertzchain.integrate.drivers.verlet import run_verlet
s = hc.Model(hc.Chain.uniform(30, 26e-3), hc.Striker(8e-3, 0.5)).system()
t1 = time.perf_counter(); run_verlet(s, 1e-6, 1e-7, dt=5e-9)
t2 = time.perf_counter(); run_verlet(s, 1e-6, 1e-7, dt=5e-9)
t3 = time.perf_counter()
print(json.dumps({"import_s": t1 - t0, "first_call_s": t2 - t1, "second_call_s": t3 - t2}))
"""


def cold_compile_time() -> dict:
    """Compile time of the Verlet kernels from scratch (subprocess, empty NUMBA_CACHE_DIR)."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        out = subprocess.run([sys.executable, "-c", _COLD_SNIPPET], env=env, capture_output=True, text=True,
                             timeout=600)
    if out.returncode != 0:
        return {"error": out.stderr[-2000:]}
    d = json.loads(out.stdout.strip().splitlines()[-1])
    d["cold_compile_s"] = d["first_call_s"] - d["second_call_s"]
    return d


# ----------------------------------------------------------------------------- time to solution
def contract_time_to_solution(repeat: int, repeat_scipy: int) -> dict:
    """:func:`_common.time_to_solution` on the contract chain, plus the fixed-step error scan."""
    import hertzchain as hc
    from hertzchain.integrate.drivers.verlet import auto_time_step, run_verlet

    model = contract_model()
    system = model.system()
    out = time_to_solution(model, DURATION, TOLERANCE, repeat, repeat_scipy)
    ref = out["reference"]["peak_wall_force"]
    t_np = out["hertzchain"]["time_s"] * out["speedup_vs_scipy"]

    # For comparison: the fixed automatic step (one dt for the whole run, set by the stiffest moment).
    dt_fixed = auto_time_step(system, SAMPLE)
    t_fix, _, ds_fix = best_of(lambda: hc.simulate(model, DURATION, dt=dt_fixed), repeat)
    out["fixed_auto_step"] = {"dt": dt_fixed, "n_steps": int(ds_fix.attrs["n_steps"]), "simulate_time_s": t_fix,
                              "rel_error": abs(float(ds_fix.attrs["peak_wall_force"]) / ref - 1),
                              "speedup_vs_scipy": t_np / t_fix}
    # How the peak error of a fixed step grows with dt (Verlet is second order).
    scan = []
    for dt in (5e-9, 1e-8, 2e-8, 2.5e-8, 1e-7 / 3, 5e-8, 1e-7):
        t, _, raw = best_of(lambda: run_verlet(system, DURATION, SAMPLE, dt=dt), max(1, repeat // 2))
        scan.append({"dt": dt, "run_verlet_time_s": t, "peak_wall_force": raw.peak_wall_force,
                     "rel_error": abs(raw.peak_wall_force / ref - 1)})
    out["verlet_error_vs_dt"] = scan
    return out


# ----------------------------------------------------------------------------- main
def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", type=Path, default=RESULTS / "kernel.json", help="where to save the results")
    ap.add_argument("--quick", action="store_true", help="fewer repetitions, shorter runs, no cold compile")
    args = ap.parse_args(argv)
    quiet()
    repeat, min_time, repeat_scipy = (3, 0.1, 1) if args.quick else (7, 0.3, 3)

    info = machine_info()
    print(f"hertzchain kernel benchmark — {info['cpu_model']}, {info['usable_cores']} usable cores, "
          f"numba {info['numba']} (NUMBA_NUM_THREADS={info['numba_num_threads']}), {info['date_utc']}")
    compile_info = first_call_times()
    if not args.quick:
        compile_info["cold"] = cold_compile_time()
    throughput = {n: measure_verlet(n, min_time, repeat) for n in (30, 10_000)}
    tts = contract_time_to_solution(repeat, repeat_scipy)

    res = {"benchmark": "kernel", "quick": args.quick, "machine": info,
           "settings": {"dt": DT, "sample_interval": SAMPLE, "repeat": repeat, "min_run_time_s": min_time,
                        "chain": "uniform 26 mm AISI52100, striker 8 mm at 0.5 m/s, flat wall",
                        "probes": "default: all contact forces + energies every 100 ns"},
           "compile": compile_info, "throughput": {str(k): v for k, v in throughput.items()}}
    for n, r in throughput.items():
        res[f"bead_steps_per_s_{n}"] = r["bead_steps_per_s"]
        res[f"bare_numba_bead_steps_per_s_{n}"] = r["bare_bead_steps_per_s"]
        res[f"ratio_to_bare_numba_{n}"] = r["ratio_to_bare"]
    res["time_to_solution"] = tts
    res["speedup_vs_scipy"] = tts["speedup_vs_scipy"]
    res["speedup_vs_scipy_compiled_rhs"] = tts["speedup_vs_scipy_compiled_rhs"]
    res["targets"] = {
        "bead_steps_per_s": TARGET_BEAD_STEPS,
        "bead_steps_per_s_met": bool(res["bead_steps_per_s_30"] >= TARGET_BEAD_STEPS),
        "speedup_vs_scipy": TARGET_SPEEDUP,
        "speedup_vs_scipy_met": bool(res["speedup_vs_scipy"] >= TARGET_SPEEDUP),
    }
    report(res)
    save_json(res, args.json)
    print(f"\nsaved {args.json}")
    return res


def report(res: dict) -> None:
    c = res["compile"]
    print("\nJIT warm-up (not included in any run time below)")
    print(f"  run_verlet first call {c['run_verlet_first_call_s']:.3f} s (cache load or compile), "
          f"second {c['run_verlet_second_call_s'] * 1e3:.2f} ms; bare loop compile {c['bare_loop_compile_s']:.3f} s")
    if "cold" in c:
        cc = c["cold"]
        print("  cold compile of the Verlet kernels (empty cache): "
              + (f"{cc['cold_compile_s']:.2f} s (import {cc['import_s']:.2f} s)" if "cold_compile_s" in cc
                 else f"failed: {cc['error']}"))

    print("\nThroughput, dt = 5 ns, default probes (best of %d, >= %.1f s each)"
          % (res["settings"]["repeat"], res["settings"]["min_run_time_s"]))
    rows = []
    for n, r in res["throughput"].items():
        rows.append((f"{n} beads", f"{r['bead_steps_per_s']:.3g}", f"{r['ns_per_bead_step']:.2f}",
                     f"{r['bare_bead_steps_per_s']:.3g}", f"{r['ratio_to_bare']:.2f}", f"{r['run_time_s']:.2f}"))
    print(table(rows, ("chain", "bead-steps/s", "ns/bead-step", "bare Numba", "hc/bare", "run s")))
    tr = res["throughput"]["30"].get("transit")
    if tr:
        print(f"  30 beads during the first 0.25 ms (pulse in transit): {tr['bead_steps_per_s']:.3g} bead-steps/s "
              f"({tr['ns_per_bead_step']:.2f} ns/bead-step; subnormal floats in the pulse's precursor)")

    t = res["time_to_solution"]
    h = t["hertzchain"]
    print(f"\nTime to solution: contract chain, 2.5 ms, peak wall force within {TOLERANCE:g} of DOP853 rtol=1e-12 "
          f"({t['reference']['peak_wall_force']:.10g} N)")
    print(table(time_to_solution_rows(t, TOLERANCE), ("solver", "rtol", "time ms", "peak rel err", "<= 1e-6",
                                                       "x slower")))
    print(f"  hertzchain time = simulate() incl. Dataset: run_verlet {h['run_verlet_only_time_s'] * 1e3:.2f} ms "
          f"+ outside it {h['simulate_outside_run_verlet_s'] * 1e3:.2f} ms")
    f = t["fixed_auto_step"]
    print(f"  the fixed automatic step instead (dt = {f['dt'] * 1e9:.3g} ns, {f['n_steps']} steps): "
          f"{f['simulate_time_s'] * 1e3:.2f} ms, error {f['rel_error']:.1e} ({f['speedup_vs_scipy']:.1f}x scipy)")
    print("  fixed-step error vs dt: " + ", ".join(f"{s['dt'] * 1e9:.3g} ns: {s['rel_error']:.1e}"
                                                  for s in t["verlet_error_vs_dt"]))

    g = res["targets"]
    print("\nTargets")
    print(f"  >= {g['bead_steps_per_s']:.0e} bead-steps/s on one core (30 beads): "
          f"{res['bead_steps_per_s_30']:.3g} -> {'MET' if g['bead_steps_per_s_met'] else 'NOT MET'}")
    print(f"  >= {g['speedup_vs_scipy']:.0f}x the faster scipy solver (NumPy RHS): {res['speedup_vs_scipy']:.1f}x "
          f"-> {'MET' if g['speedup_vs_scipy_met'] else 'NOT MET'}  "
          f"(vs scipy with hertzchain's compiled RHS: {res['speedup_vs_scipy_compiled_rhs']:.1f}x)")


if __name__ == "__main__":
    main()
