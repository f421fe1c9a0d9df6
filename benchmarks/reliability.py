"""What the reliability checks cost, and how the damped step bound does on dissipative runs.

Usage::

    python benchmarks/reliability.py [--json PATH] [--repeat N]

1. Overhead of the checks (``hertzchain.checks``: resources before the run, energy balance,
   Hertz range and pulse arrival after it): ``simulate`` on the paper's chain 1 with the checks
   against the same call with them replaced by no-ops, best of N, in the same run.
2. Cost of the safe save (``hertzchain.save``: the file built in memory, a unique temporary file,
   fsync, atomic rename) against ``Dataset.to_netcdf`` straight to the target, same encoding.
3. The step bound with damping on dissipative runs: steps, largest relative gain of kinetic +
   elastic + dissipated energy, and the peak wall force against DOP853 at rtol = 1e-12, for the
   laws calibrated to the paper's eps = 0.985 and a strong dashpot (gamma = 1e5 N s/m, which the
   elastic-only bound let gain energy).

Saves JSON (default benchmarks/results/reliability.json) with machine info. Takes ~15 s.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, best_of, machine_info, quiet, save_json, table  # noqa: E402


def checks_overhead(repeat: int) -> dict:
    import hertzchain as hc
    from hertzchain.runs import simulation

    model = hc.Model(hc.paper_chain("chain1"), hc.Striker(8e-3, 0.2), hc.Wall("flat"))
    run = lambda: hc.simulate(model, 3e-3)  # noqa: E731
    run()  # JIT warm-up
    with_checks, spread_with, _ = best_of(run, repeat)
    saved = simulation.check_before_run, simulation.check_after_run
    simulation.check_before_run = lambda *a, **k: None
    simulation.check_after_run = lambda *a, **k: None
    try:
        without, spread_without, _ = best_of(run, repeat)
    finally:
        simulation.check_before_run, simulation.check_after_run = saved
    return {"case": "chain1, 0.2 m/s, 3 ms, adaptive step", "with_checks_s": with_checks,
            "without_checks_s": without, "overhead": with_checks / without - 1,
            "times_with_s": spread_with, "times_without_s": spread_without}


def save_cost(repeat: int) -> dict:
    import hertzchain as hc
    from hertzchain.result import ENGINE

    ds = hc.simulate(hc.Model(hc.paper_chain("chain1"), hc.Striker(8e-3, 0.2)), 3e-3)
    encoding = {n: {"compression": "gzip", "compression_opts": 4, "shuffle": True}
                for n, v in ds.data_vars.items() if v.size > 1000}
    with tempfile.TemporaryDirectory() as tmp:
        safe, spread_safe, _ = best_of(lambda: hc.save(ds, Path(tmp) / "safe.nc"), repeat)
        direct, spread_direct, _ = best_of(lambda: ds.to_netcdf(Path(tmp) / "direct.nc", engine=ENGINE,
                                                                 encoding=encoding), repeat)
        size = (Path(tmp) / "safe.nc").stat().st_size
    return {"case": "chain1 result, 30001 samples x 31 contacts", "file_bytes": size, "safe_save_s": safe,
            "direct_to_netcdf_s": direct, "ratio": safe / direct, "times_safe_s": spread_safe,
            "times_direct_s": spread_direct}


def damped_case(name: str, model, duration: float) -> dict:
    import hertzchain as hc

    ref = hc.simulate(model, duration, integrator="dop853", rtol=1e-12)
    ds = hc.simulate(model, duration)
    e = (ds.kinetic_energy + ds.potential_energy + ds.dissipated_energy).values
    return {"case": name, "max_frequency": model.system().max_frequency(),
            "elastic_max_frequency": hc.Model(model.chain, model.striker, model.wall).system().max_frequency(),
            "n_steps": int(ds.attrs["n_steps"]), "dt_min": float(ds.attrs["dt"]), "dt_max": float(ds.attrs["dt_max"]),
            "energy_gain": float(np.max(e / e[0] - 1)), "energy_rel_error": float(np.abs(e / e[0] - 1).max()),
            "peak_rel_error": abs(ds.attrs["peak_wall_force"] / ref.attrs["peak_wall_force"] - 1)}


def damped_cases() -> list[dict]:
    import hertzchain as hc

    chain, striker = hc.paper_chain("chain1"), hc.Striker(8e-3, 0.2)
    rows = []
    for law in ("viscoelastic", "dashpot"):
        calibrated = hc.calibrate_law(law, 0.985, chain=chain, striker=striker)
        rows.append(damped_case(f"chain1 {law} eps=0.985", hc.Model(chain, striker, hc.Wall("flat"), calibrated), 3e-3))
    strong = hc.Model(hc.Chain.uniform(5, 26e-3), striker, hc.Wall("flat"), hc.Dashpot(1e5))
    rows.append(damped_case("5 x 26 mm dashpot gamma=1e5", strong, 3e-4))
    return rows


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", type=Path, default=RESULTS / "reliability.json", help="where to save the results")
    ap.add_argument("--repeat", type=int, default=5, help="repetitions of each timing (best of)")
    args = ap.parse_args(argv)
    quiet()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        overhead = checks_overhead(args.repeat)
        save = save_cost(args.repeat)
        damped = damped_cases()
    print(f"checks: {overhead['with_checks_s'] * 1e3:.1f} ms with, {overhead['without_checks_s'] * 1e3:.1f} ms without "
          f"({overhead['overhead'] * 100:+.1f} %)")
    print(f"save: {save['safe_save_s'] * 1e3:.1f} ms safe, {save['direct_to_netcdf_s'] * 1e3:.1f} ms direct "
          f"(x{save['ratio']:.2f}, {save['file_bytes'] / 1e6:.2f} MB)")
    print(table([(r["case"], f"{r['max_frequency'] / r['elastic_max_frequency']:.3f}", r["n_steps"],
                  f"{r['energy_gain']:.1e}", f"{r['peak_rel_error']:.1e}") for r in damped],
                ("case", "omega/elastic", "steps", "energy gain", "peak err")))
    res = {"benchmark": "reliability", "machine": machine_info(), "checks_overhead": overhead, "save": save,
           "damped": damped}
    save_json(res, args.json)
    print(f"saved {args.json}")
    return res


if __name__ == "__main__":
    main()
