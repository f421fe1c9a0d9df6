"""Time to calibrate the model on laboratory traces (``hertzchain fit``), and engine calls.

Usage::

    python benchmarks/fit.py [--json PATH] [--quick]

Two problems on synthetic records of the paper's chain 1 (Kuwabara-Kono contacts, A = 4.5 us),
made from the model with hidden values (striker 0.25 m/s, sensor gain 0.97) through a PCB 208A11
wall sensor and an 8-bit 2.5 MS/s scope (5 mV noise, random clock phase, 1000 points):

- ``single``: one wall trace, 3 free parameters (striker.velocity, gain, time_offset);
  target < 5 s on the 2-core machine;
- ``series``: the chain-1 protocol of the paper, the wall trace of the chain truncated after
  each bead n = 16..30 (15 traces), striker.velocity and gain shared, one time_offset per trace
  (17 parameters); target < 60 s.

Each fit starts from 0.2 m/s. Reported, for the exact Jacobian (the tangent model, the default)
and for forward differences (``jacobian="finite differences"``, what the fit did before) in the
same run: wall time (best of 3 for the single trace, after a warm-up that compiles the engine),
evaluations, chains simulated by the batched engine, tangent runs, the cost reached and the
recovered values in standard errors from the truth. Baseline in the same run: the Jacobian members of one
series iteration (15 chains) simulated one by one with :func:`hertzchain.simulate`, against the
one batched call the fit makes. Saves JSON (default benchmarks/results/fit.json) with machine
info. Takes ~1 min on a quiet 2-core machine.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, best_of, machine_info, quiet, save_json, table  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
CONFIG = REPO / "examples" / "lab_chain1.toml"
TRUTH = {"striker.velocity": 0.25, "gain": 0.97}
SENS_MV = 112.40
SERIES = range(16, 31)


def records(truncations, seed: int = 0):
    """One synthetic wall record per truncation (time [s], force [N] read with the nominal
    sensitivity) and the true time offsets [s]."""
    import xarray as xr

    import hertzchain as hc
    from hertzchain.config import build_model, load_config
    from hertzchain.instrument import Instrument

    cfgs = [load_config(CONFIG, [f"striker.velocity={TRUTH['striker.velocity']}"]
                        + ([f"chain.truncate={n}"] if n else [])) for n in truncations]
    ds = hc.simulate_batch([build_model(c) for c in cfgs], cfgs[0].run.duration,
                           hc.Probes(sample_interval=cfgs[0].run.sample_interval, contacts=()))
    out = []
    for i, n in enumerate(truncations):
        scope = Instrument(sensitivity_mV_per_N=SENS_MV * TRUTH["gain"], noise_rms_mV=5.0, sample_rate=2.5e6,
                           record_length=1000, trigger_level_N=0.5, pretrigger_fraction=0.15, bits=8,
                           full_scale_V=2.0, offset_V=0.6, trigger_jitter=True, seed=seed + i)
        acq = scope.acquire(ds.time.values, ds.wall_force.values[i])
        da = xr.DataArray(acq.volts / (SENS_MV * 1e-3), dims="time", coords={"time": acq.time}, attrs={"units": "N"})
        out.append((n, da, acq.trigger_time + float(acq.jitter[0])))
    return out


def run_fit(recs, jacobian: str = "exact"):
    from hertzchain.lab import Trace, fit_traces

    traces = [Trace(da, overrides=(f"chain.truncate={n}",) if n else (), name=f"n={n or 30}") for n, da, _ in recs]
    return fit_traces(CONFIG, traces, ["striker.velocity", "gain", "time_offset"], jacobian=jacobian)


def summary(result, recs) -> dict:
    truth = dict(TRUTH)
    offsets = [tau for _, _, tau in recs]
    for k, tau in enumerate(offsets):
        truth["time_offset" if len(offsets) == 1 else f"time_offset[{k}]"] = tau
    z = {n: (v - truth[n]) / e for n, v, e in zip(result.names, result.values, result.stderr)}
    return {"elapsed_s": result.elapsed, "n_evaluations": result.n_evaluations, "n_members": result.n_members,
            "jacobian": result.jacobian, "n_tangent_runs": result.n_tangent_runs, "cost": result.cost,
            "n_parameters": len(result.names), "n_points": result.n_points, "converged": result.converged,
            "values": dict(zip(result.names, result.values.tolist())),
            "stderr": dict(zip(result.names, result.stderr.tolist())),
            "z_from_truth": z, "max_abs_z": max(abs(v) for v in z.values())}


def batch_vs_serial(recs, repeat: int) -> dict:
    """One series Jacobian call (15 members) batched against the same chains one by one."""
    import hertzchain as hc
    from hertzchain.config import build_model, load_config

    cfgs = [load_config(CONFIG, [f"chain.truncate={n}", "striker.velocity=0.2002"]) for n, _, _ in recs]
    models = [build_model(c) for c in cfgs]
    probes = hc.Probes(sample_interval=cfgs[0].run.sample_interval, contacts=())
    duration = 2.9e-3
    batched, _, _ = best_of(lambda: hc.simulate_batch(models, duration, probes), repeat)
    serial, _, _ = best_of(lambda: [hc.simulate(m, duration, probes) for m in models], repeat)
    return {"members": len(models), "batched_s": batched, "serial_s": serial, "speedup": serial / batched}


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", type=Path, default=RESULTS / "fit.json", help="where to save the results")
    ap.add_argument("--quick", action="store_true", help="one repetition of the single-trace fit")
    args = ap.parse_args(argv)
    quiet()
    t0 = time.perf_counter()
    single = records([None])
    run_fit(single)  # warm-up: compiles (or loads) the engine and the tangent model, imports scipy.optimize
    run_fit(single, "finite differences")
    warm_s = time.perf_counter() - t0
    series = records(list(SERIES), seed=100)
    out = {}
    rows = []
    for kind in ("exact", "finite differences"):  # after (the exact Jacobian) and before, in the same run
        best, times, result = best_of(lambda: run_fit(single, kind), 1 if args.quick else 3)
        one = summary(result, single) | {"best_s": best, "times_s": times}
        t1 = time.perf_counter()
        result = run_fit(series, kind)
        many = summary(result, series) | {"best_s": time.perf_counter() - t1, "n_traces": len(series)}
        out[kind] = {"single": one, "series": many}
        for name, r, target in (("single trace, 3 parameters", one, "< 5"),
                                (f"series of {len(series)} traces, {many['n_parameters']} parameters", many, "< 60")):
            rows.append((f"{name}; Jacobian {kind}", f"{r['best_s']:.2f}", target, r["n_evaluations"], r["n_members"],
                         r["n_tangent_runs"], f"{r['cost']:.6g}", f"{r['max_abs_z']:.2f}"))
    one, many = out["exact"]["single"], out["exact"]["series"]
    base = batch_vs_serial(series, 1 if args.quick else 3)
    print(table(rows, ("fit", "time s", "target s", "evaluations", "batched chains", "tangent runs", "cost",
                       "max |z|")))
    print(f"one series Jacobian by differences ({base['members']} chains): batched {base['batched_s']:.3f} s, one by "
          f"one {base['serial_s']:.3f} s ({base['speedup']:.2f}x)")
    import os

    print(f"load average at start {machine_info()['load_average_at_start']}, now {list(os.getloadavg())}")
    res = {"benchmark": "fit", "machine": machine_info(), "warmup_s": warm_s, "single": one, "series": many,
           "finite_differences": out["finite differences"], "jacobian_batch_vs_serial": base,
           "targets_s": {"single": 5.0, "series": 60.0},
           "meets_targets": {"single": one["best_s"] < 5.0, "series": many["best_s"] < 60.0}}
    save_json(res, args.json)
    print(f"saved {args.json}")
    return res


if __name__ == "__main__":
    main()
