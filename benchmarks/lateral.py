"""Cost of the 2D path (lateral freedom) against the 1D kernels on the same chain.

Usage::

    python benchmarks/lateral.py [--json PATH] [--quick]

Chain 2 of the paper (28 beads) hit by the 8 mm striker at 0.2 m/s, bead 22 offset by 10 % of its
diameter, Kuwabara-Kono contacts (A = 4.4 us), 3 ms at a fixed step of 20 ns (150,000 steps), in
three ways, each the best of several calls after a warm-up (compilation excluded):

- ``1d_aligned_elastic``: the same chain aligned and elastic (the fused, vectorised fast path);
- ``1d_general``: the 1D general path (offset bead held on its line, dissipative law);
- ``2d_lateral``: the 2D path (bead free across the axis in a 15 mm groove, friction 0.2).

Prints and saves ns per bead-step (wall time / (steps x moving bodies)) and the 2D/1D-general
ratio, with machine info (default benchmarks/results/lateral.json). Takes ~20 s.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, best_of, machine_info, save_json, table  # noqa: E402

DURATION = 3e-3
DT = 2e-8
SAMPLE = 1e-6


def models():
    import hertzchain as hc
    from hertzchain.runs.track import Track

    chain = hc.paper_chain("chain2")
    law = hc.Viscoelastic(4.4e-6)
    striker = hc.Striker(8e-3, 0.2)
    offset = chain.with_offsets({22: 0.1 * chain.diameters[21]})
    return {"1d_aligned_elastic": (hc.Model(chain, striker, hc.Wall("flat"), hc.Elastic()), None),
            "1d_general": (hc.Model(offset, striker, hc.Wall("flat"), law), None),
            "2d_lateral": (hc.Model(offset, striker, hc.Wall("flat"), law), Track(15e-3, friction=0.2))}


def runner(model, track, duration):
    from hertzchain.integrate.drivers.lateral import run_lateral
    from hertzchain.integrate.drivers.verlet import run_verlet
    from hertzchain.runs.track import lateral_arrays

    system = model.system()
    n = model.chain.n_beads
    if track is None:
        return lambda: run_verlet(system, duration, SAMPLE, dt=DT, contacts=[n])
    lat = lateral_arrays(model, track)
    return lambda: run_lateral(system, lat, duration, SAMPLE, dt=DT, contacts=[n]).raw


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", type=Path, default=RESULTS / "lateral.json", help="where to save the results")
    ap.add_argument("--quick", action="store_true", help="1 ms runs, 2 repetitions")
    args = ap.parse_args(argv)
    duration, repeat = (1e-3, 2) if args.quick else (DURATION, 5)
    rows = {}
    for name, (model, track) in models().items():
        t0 = time.perf_counter()
        runner(model, track, 2 * SAMPLE)()  # compile (or load the cache) and warm up
        warm = time.perf_counter() - t0
        best, times, raw = best_of(runner(model, track, duration), repeat)
        bodies = model.chain.n_beads + 1
        rows[name] = {"steps": int(raw.n_steps), "bodies": bodies, "best_s": best, "times_s": times,
                      "warmup_s": warm, "ns_per_bead_step": 1e9 * best / (raw.n_steps * bodies),
                      "peak_wall_force": float(raw.peak_wall_force)}
    ratio = rows["2d_lateral"]["ns_per_bead_step"] / rows["1d_general"]["ns_per_bead_step"]
    print(table([(k, r["steps"], f"{r['best_s'] * 1e3:.1f}", f"{r['ns_per_bead_step']:.2f}") for k, r in rows.items()],
                ("path", "steps", "best ms", "ns/bead-step")))
    print(f"2D path / 1D general path: {ratio:.2f} x")
    res = {"benchmark": "lateral", "machine": machine_info(), "duration": duration, "dt": DT, "paths": rows,
           "ratio_2d_to_1d_general": ratio}
    save_json(res, args.json)
    print(f"saved {args.json}")
    return res


if __name__ == "__main__":
    main()
