"""Cost of exact sensitivities (``hertzchain.sensitivity``) against one simulation, warm.

Usage::

    python benchmarks/gradient.py [--json PATH] [--quick] [--laws]

The issue's target: a full gradient for 30 variables costs at most 5 x one simulation. Measured on
the paper's chain 1 (30 beads, 8 mm striker at 0.2 m/s, 2.5-3 ms, adaptive step) with the 30 bead
diameters as variables, for the elastic and the Kuwabara-Kono law (A = 4.5 us), at the default
accuracy (400 steps per radian) and at the design search's (20), and for the elastic-plastic law
(Thornton, A = 4.5 us, chain 1 made of brass, sigma_Y = 200 MPa: every contact yields, 4 ms) at
the default accuracy:

- one simulation: :func:`hertzchain.run_config` (``simulate``: the run, its checks and its
  Dataset) and the engine alone (``integrate.verlet.run_verlet``);
- the gradient by the adjoint: the whole :func:`hertzchain.sensitivity` call (validation, set-up
  derivatives, taped run, reverse sweep, chain rule) for all 30 diameters, and its parts;
- the tangent model with 1 and 4 variables (forward mode: one run plus ~half a run per variable;
  the elastic-plastic law's takes each contact's Jacobian from its reverse-mode partials, three
  per contact and step, so ``auto`` gives that law to the adjoint);
- the finite-difference gradient it replaces: 31 members (the base and one step per diameter) in
  one batched call (:func:`hertzchain.simulate_batch`, all cores), as ``fit`` did.

``--laws``: the registry laws instead, differentiated by the engines generated from their
declarations (``integrate/derivatives/law_derivatives.py``): chain 1 with the power law at n = 3/2 (Hertz's
constant: the elastic problem, on the generated engines) and with Hunt-Crossley (e = 0.8, a law
with state), at the default accuracy (saved to benchmarks/results/gradient_laws.json).

Every timing is the best of N warm calls (the JIT compiled first); the machine's load average is
saved beside them (2 shared cores: other work inflates everything, the ratios hold better).
Saves JSON (default benchmarks/results/gradient.json) with machine info. ~30 s.
"""

from __future__ import annotations

import argparse
import copy
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, best_of, machine_info, quiet, save_json, table  # noqa: E402

REPO = Path(__file__).resolve().parent.parent


def configs() -> dict[str, dict]:
    from hertzchain.config import read_toml

    elastic = read_toml(REPO / "examples" / "chain1_elastic.toml")
    elastic.pop("probes", None)
    visco = copy.deepcopy(elastic)
    visco["contact"] = {"law": "viscoelastic", "A": 4.5e-6}
    visco["run"]["duration"] = 3.0e-3
    plastic = copy.deepcopy(visco)
    plastic["contact"] = {"law": "elastoplastic", "A": 4.5e-6}
    plastic["chain"]["material"] = plastic["striker"]["material"] = "brass"
    plastic["run"]["duration"] = 4.0e-3
    out = {}
    for name, cfg in (("chain1 elastic", elastic), ("chain1 Kuwabara-Kono", visco)):
        for spr in (400.0, 20.0):
            c = copy.deepcopy(cfg)
            c["run"]["steps_per_radian"] = spr
            out[f"{name}, {spr:g} steps/rad"] = c
    plastic["run"]["steps_per_radian"] = 400.0
    out["chain1 elastic-plastic, 400 steps/rad"] = plastic
    return out


def law_configs() -> dict[str, dict]:
    """Chain 1 with the registry laws (``--laws``), at the default accuracy."""
    from hertzchain.config import read_toml

    base = read_toml(REPO / "examples" / "chain1_elastic.toml")
    base.pop("probes", None)
    base["run"]["steps_per_radian"] = 400.0
    out = {}
    for name, contact, duration in (("chain1 power n = 1.5", {"law": "power", "exponent": 1.5}, None),
                                    ("chain1 hunt_crossley e = 0.8", {"law": "hunt_crossley", "restitution": 0.8},
                                     3.0e-3)):
        c = copy.deepcopy(base)
        c["contact"] = contact
        if duration is not None:
            c["run"]["duration"] = duration
        out[name] = c
    return out


def measure(cfg: dict, repeat: int) -> dict:
    import hertzchain as hc
    from hertzchain.config import build_model, parse_config
    from hertzchain.gradients.objectives import read_objective
    from hertzchain.integrate.derivatives import differentiate as D
    from hertzchain.integrate.drivers.verlet import run_verlet

    run_cfg = parse_config(cfg)
    model = build_model(run_cfg)
    system = model.system()
    dur, si, spr = run_cfg.run.duration, run_cfg.run.sample_interval, run_cfg.run.steps_per_radian
    diam = ["chain.diameters_mm"]

    def fd_batch():
        base = model.chain.diameters
        models = [model]
        for i in range(base.size):
            d = base.copy()
            d[i] *= 1 + 1e-4
            models.append(hc.Model(hc.Chain(d, model.chain.materials), model.striker, model.wall, model.law))
        return hc.simulate_batch(models, dur, hc.Probes(sample_interval=si, contacts=()), steps_per_radian=spr)

    calls = {
        "simulate": lambda: hc.run_config(run_cfg),
        "engine": lambda: run_verlet(system, dur, si, steps_per_radian=spr),
        "adjoint_30": lambda: hc.sensitivity(cfg, diam, mode="adjoint"),
        "tangent_1": lambda: hc.sensitivity(cfg, ["chain.diameters_mm[29]"], mode="tangent"),
        "tangent_4": lambda: hc.sensitivity(cfg, ["chain.diameters_mm[26:30]"], mode="tangent"),
        "fd_batch_31": fd_batch,
    }
    for fn in calls.values():  # compile everything first
        fn()
    out = {}
    for key, fn in calls.items():
        best, times, _ = best_of(fn, repeat)
        out[key] = {"best_s": best, "times_s": times}
    # the adjoint's parts
    tape_best, _, tape = best_of(lambda: D.record(system, dur, si, steps_per_radian=spr), repeat)
    reading = read_objective("peak_wall_force", tape)
    seeds = D.Seeds.build(list(reading.steps))
    sweep_best, _, _ = best_of(lambda: D.gradient(tape, seeds), repeat)
    out["taped_run"] = {"best_s": tape_best}
    out["reverse_sweep"] = {"best_s": sweep_best}
    out["n_steps"] = tape.n_steps
    out["checkpoint_groups"] = int(tape.ckpt.shape[0])
    out["checkpoint_bytes"] = int(tape.ckpt.nbytes)
    s = hc.sensitivity(cfg, diam, mode="adjoint")
    out["value_N"] = s.value
    out["most_influential_bead"] = int(np.argmax(np.abs(list(s.gradient.values())))) + 1
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", type=Path, default=RESULTS / "gradient.json")
    ap.add_argument("--quick", action="store_true", help="3 repetitions instead of 7")
    ap.add_argument("--laws", action="store_true", help="the registry laws (generated engines) instead")
    args = ap.parse_args()
    if args.laws and args.json == RESULTS / "gradient.json":
        args.json = RESULTS / "gradient_laws.json"
    quiet()
    repeat = 3 if args.quick else 7
    info = machine_info()
    t0 = time.perf_counter()
    results = {}
    rows = []
    for name, cfg in (law_configs() if args.laws else configs()).items():
        r = measure(cfg, repeat)
        results[name] = r
        sim, eng, adj = r["simulate"]["best_s"], r["engine"]["best_s"], r["adjoint_30"]["best_s"]
        rows.append((name, r["n_steps"], f"{sim * 1e3:.1f}", f"{eng * 1e3:.1f}", f"{adj * 1e3:.1f}",
                     f"{adj / sim:.2f}", f"{adj / eng:.2f}", *(f"{r[k]['best_s'] / sim:.2f}" if k in r else "-"
                                                              for k in ("tangent_1", "tangent_4")),
                     f"{r['fd_batch_31']['best_s'] / sim:.2f}"))
    import os

    info["load_average_at_end"] = list(os.getloadavg())
    print(table(rows, ("problem", "steps", "simulate ms", "engine ms", "adjoint-30 ms", "adj/sim", "adj/engine",
                       "tan-1/sim", "tan-4/sim", "FD-31 batch/sim")))
    print(f"load average: start {info['load_average_at_start']}, end {info['load_average_at_end']} "
          f"({info['usable_cores']} usable cores); {time.perf_counter() - t0:.0f} s")
    save_json({"machine": info, "repeat": repeat, "results": results,
               "target": "full gradient of 30 variables <= 5 x one simulation"}, args.json)
    print(f"saved {args.json}")


if __name__ == "__main__":
    main()
