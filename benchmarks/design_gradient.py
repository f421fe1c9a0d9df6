"""Per-bead design with gradients against CMA-ES and differential evolution driving ``simulate``.

    python benchmarks/design_gradient.py [--json PATH] [--quick] [--budget N] [--seeds K]

Problems: a chain of n = 10, 20 and 50 beads whose every diameter is free in [8, 26] mm and kept
decreasing away from the impact end (``chain.diameters_mm[0:n]``, ``monotone = true``), hit by
the paper's 8 mm striker at 0.2 m/s, elastic contacts, flat wall, samples every 1 us, the run's
duration resolved by the design (``"auto"``: the slowest corner of the space); objective: the
peak wall force. The same budget of engine runs for every method (default 2000):

- ``hertzchain design`` (``run_design``): a Latin-hypercube sample, then L-BFGS-B local searches
  on exact gradients (each value and gradient charged 3 engine runs), at the search accuracy
  (20 steps per radian), its best candidates run again at full accuracy (their value is the one
  reported, and the one compared);
- CMA-ES (``cma``, population 4 + 3 ln n, sigma 0.3 from the centre of the box) and scipy's
  ``differential_evolution`` (defaults: population 15 n, no polish), each calling
  :func:`hertzchain.simulate` once per candidate at its default (full) accuracy, the candidate's
  coordinates sorted into a decreasing profile as the design does; a candidate whose wall pulse
  does not arrive and pass within the run is infeasible (ranked by a penalty), as in the design.

Reported per problem and seed: the final value at equal engine budget; the value each method had
when the time hertzchain's whole run took had passed (equal wall time); the time each method
needed to reach its own final value; hertzchain "reaches it in less time" when its whole run
(verification at full accuracy included) ends before the better of the two others first reached
its final value. Seeds: 1..K (default 3).
The machine is shared (2 cores, other engineers' tests): the load average is recorded before
and after every run and printed. Saves JSON (default benchmarks/results/design_gradient.json)
with machine info. ~10 min with the defaults.
"""

from __future__ import annotations

import argparse
import copy
import math
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, machine_info, quiet, save_json, table  # noqa: E402

LOW, HIGH = 8.0, 26.0
#: Columns: final values at equal budget; the others' best at hertzchain's end (equal wall time);
#: hertzchain's whole run, its time to the better other's final value (verified at full accuracy),
#: and the time that other took to reach it.
HEAD = ("n", "seed", "hertzchain N", "CMA-ES N", "DE N", "CMA @hz end", "DE @hz end", "hz run s",
        "hz to leader s", "leader to own s", "load before/after")
STRIKER = {"diameter_mm": 8.0, "velocity": 0.2}


def design(n: int, budget: int, seed: int) -> dict:
    return {"base": {"chain": {"diameters_mm": [HIGH] * n}, "striker": dict(STRIKER), "run": {"sample_interval": 1e-6}},
            "design": {"variables": {f"chain.diameters_mm[0:{n}]": {"low": LOW, "high": HIGH, "monotone": True}},
                       "budget": budget, "seed": seed}}


class _Spent(Exception):
    """The budget is spent."""


class Simulator:
    """``simulate`` of a candidate (unit-cube point, sorted into a decreasing profile), with the
    trajectory (elapsed time, best feasible value so far) and a budget."""

    def __init__(self, base: dict, budget: int):
        import hertzchain as hc
        from hertzchain.config import build_model, parse_config

        self.hc, self.build_model, self.parse_config = hc, build_model, parse_config
        self.base, self.budget = base, budget
        self.n = 0
        self.best = math.inf
        self.trace: list[tuple[float, float]] = []
        self.t0 = time.perf_counter()

    def __call__(self, x) -> float:
        from hertzchain.design.objectives import _pulses_passed

        if self.n >= self.budget:
            raise _Spent
        self.n += 1
        d = LOW + np.sort(np.clip(np.asarray(x, float), 0.0, 1.0))[::-1] * (HIGH - LOW)
        cfg = copy.deepcopy(self.base)
        cfg["chain"]["diameters_mm"] = [float(v) for v in d]
        c = self.parse_config(cfg)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ds = self.hc.simulate(self.build_model(c), c.run.duration,
                                  self.hc.Probes(sample_interval=c.run.sample_interval, contacts=()))
        value = float(ds.attrs["peak_wall_force"])
        if not _pulses_passed(ds["wall_force"].values[None, :])[0]:
            return 1e3 + value  # infeasible: the pulse has not passed the wall within the run
        if value < self.best:
            self.best = value
            self.trace.append((time.perf_counter() - self.t0, value))
        return value


def run_cma(base: dict, n: int, budget: int, seed: int) -> Simulator:
    import cma

    sim = Simulator(base, budget)
    es = cma.CMAEvolutionStrategy(np.full(n, 0.5), 0.3, {"bounds": [0.0, 1.0], "seed": seed, "verbose": -9,
                                                          "verb_log": 0, "verb_disp": 0})
    try:
        while not es.stop():
            xs = es.ask()
            es.tell(xs, [sim(x) for x in xs])
    except _Spent:
        pass
    return sim


def run_de(base: dict, n: int, budget: int, seed: int) -> Simulator:
    from scipy.optimize import differential_evolution

    sim = Simulator(base, budget)
    try:
        differential_evolution(sim, [(0.0, 1.0)] * n, seed=seed, maxiter=100_000, tol=0.0, polish=False)
    except _Spent:
        pass
    return sim


def run_hertzchain(problem: dict) -> dict:
    from hertzchain.design import parse_design, run_design

    t0 = time.perf_counter()
    prob = parse_design(problem)
    with tempfile.TemporaryDirectory() as tmp:
        res = run_design(prob, Path(tmp) / "design")
    wall = time.perf_counter() - t0
    phases = {}
    for r in res.history:
        phases[r["phase"]] = phases.get(r["phase"], 0) + r["engine_runs"]
    # the search's trajectory: (time since the call [s], value at the search's accuracy, config)
    offset = wall - res.elapsed_s  # parsing and set-up before the search clock starts
    obj = prob.objectives[0]
    trace, best = [], math.inf
    for r in res.history:
        if r["feasible"] and r[obj] < best:
            best = r[obj]
            trace.append((offset + r["elapsed_s"], best, prob.space.config(prob.space.values(np.asarray(r["x"])))))
    return {"value": float(res.best["objective"]), "feasible": bool(res.best["feasible"]), "wall_s": wall,
            "engine_runs": res.n_evaluations, "runs_by_phase": phases,
            "diameters_mm": [round(float(v), 3) for v in next(iter(res.best["variables"].values()))],
            "base": prob.base, "trace": trace}


def hertzchain_time_to(trace: list, target: float) -> tuple[float, float | None]:
    """When hertzchain's search first held a candidate whose FULL-accuracy value is <= ``target``:
    the search ranks at its own (coarse) accuracy, so every earlier best is run again at full
    accuracy (outside the timed run) and the first that qualifies counts. Returns (time [s], its
    full-accuracy value); (inf, None) when none qualifies."""
    import hertzchain as hc

    for t, value, cfg in trace:
        if value > target * 1.01:  # far above: its full-accuracy value cannot qualify (the accuracies differ ~1e-4)
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            full = float(hc.run_config(cfg).attrs["peak_wall_force"])
        if full <= target:
            return t, full
    return math.inf, None


def at_time(trace: list[tuple[float, float]], t: float) -> float:
    """Best value reached by time ``t`` [s] (inf before the first feasible one)."""
    vals = [v for s, v in trace if s <= t]
    return min(vals) if vals else math.inf


def time_to(trace: list[tuple[float, float]], target: float) -> float:
    """First time [s] the best value was <= ``target`` (inf: never)."""
    return next((s for s, v in trace if v <= target * (1 + 1e-12)), math.inf)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", type=Path, default=RESULTS / "design_gradient.json")
    ap.add_argument("--budget", type=int, default=2000)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--sizes", type=int, nargs="+", default=[10, 20, 50])
    ap.add_argument("--quick", action="store_true", help="one seed, budget 600")
    args = ap.parse_args()
    if args.quick:
        args.seeds, args.budget = 1, 600
    quiet()
    info = machine_info()
    # warm-up: compile (or load) the engine, the derivative kernels and the batched engine
    run_hertzchain(design(6, 200, 0))
    results, rows = [], []
    for n in args.sizes:
        for seed in range(1, args.seeds + 1):
            load0 = os.getloadavg()[0]
            hz = run_hertzchain(design(n, args.budget, seed))
            base = hz.pop("base")
            trace = hz.pop("trace")
            cm = run_cma(base, n, args.budget, seed)
            de = run_de(base, n, args.budget, seed)
            load1 = os.getloadavg()[0]
            entry = {"n": n, "seed": seed, "budget": args.budget, "load_average_before": load0,
                     "load_average_after": load1, "hertzchain": hz}
            for name, sim in (("cma", cm), ("de", de)):
                entry[name] = {"value": sim.best, "simulations": sim.n, "value_at_hertzchain_time": at_time(sim.trace, hz["wall_s"]),
                               "time_to_own_best_s": sim.trace[-1][0] if sim.trace else math.inf,
                               "time_to_hertzchain_value_s": time_to(sim.trace, hz["value"]),
                               "trace": sim.trace}
            # The best of the two others, and the time it took to reach its final value; hertzchain's
            # time to its (better or equal) value is bounded by its whole run, verification included.
            leader = min(("cma", "de"), key=lambda k: entry[k]["value"])
            entry["best_other"] = leader
            entry["hertzchain_at_least_as_good"] = hz["value"] <= entry[leader]["value"]
            t_hit, v_hit = hertzchain_time_to(trace, entry[leader]["value"])
            hz["time_to_best_other_s"], hz["value_at_that_time"] = t_hit, v_hit
            entry["hertzchain_faster"] = t_hit < entry[leader]["time_to_own_best_s"]
            results.append(entry)
            rows.append((n, seed, f"{hz['value']:.4f}", f"{entry['cma']['value']:.4f}", f"{entry['de']['value']:.4f}",
                         f"{entry['cma']['value_at_hertzchain_time']:.4f}", f"{entry['de']['value_at_hertzchain_time']:.4f}",
                         f"{hz['wall_s']:.1f}", f"{t_hit:.1f}", f"{entry[leader]['time_to_own_best_s']:.1f}",
                         f"{load0:.1f}/{load1:.1f}"))
            print(table(rows[-1:], HEAD), flush=True)
    print()
    print(f"equal engine budget ({args.budget} runs; hertzchain charges a value-and-gradient 3 runs), final peak "
          "wall force [N] at full accuracy; equal wall time: the others' best when hertzchain's whole run had ended")
    print(table(rows, HEAD))
    ok = all(r["hertzchain_at_least_as_good"] and r["hertzchain_faster"] for r in results)
    print(f"hertzchain at least as good as the best of CMA-ES and DE, and sooner, on every problem and seed: {ok}")
    info["load_average_at_end"] = list(os.getloadavg())
    save_json({"benchmark": "design_gradient", "machine": info, "budget": args.budget, "seeds": args.seeds,
               "results": results, "all_at_least_as_good_and_sooner": ok}, args.json)
    print(f"saved {args.json}")


if __name__ == "__main__":
    main()
