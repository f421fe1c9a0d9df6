"""The GPU kernels of hertzchain.integrate.cuda.lanes: to run on a machine with an NVIDIA GPU.

Usage::

    python benchmarks/gpu_kernels.py [--json PATH] [--quick]

NOT MEASURED YET: the kernels were prepared without a GPU (checked against the CPU engine through
Numba's CUDA simulator and compiled to PTX for sm_90, tests/test_cuda_lanes.py). Without a usable
GPU this script says so, saves that in the JSON and exits.

With one (float64, transfers included, after a warm-up launch; best of N):

1. **Batch** (the issue's target: >= 3e11 bead-steps/s at 1e5 chains of 30 beads on an H100):
   30 beads of 26 mm AISI 52100 with 0.1 % diameter tolerances (a draw per chain), striker 8 mm
   at 0.5 m/s, flat wall, fixed dt = 5 ns for 0.1 ms, probes of the striker and wall contacts
   every 1 us; ``simulate_batch(..., device="cuda")`` with the register kernel (the default) and
   with the lanes-per-chain kernel (``cuda.USE_LANES_KERNEL = True``), at 1e3 ... 1e6 chains; and
   the largest difference of the lanes kernel from the CPU engine on 2,000 chains (relative to
   each chain's largest value; the documented bound is eps x steps).
2. **Bodies**: the general kernels on 30-bead mass-in-mass chains (a resonator of 30 % of each
   bead's mass at 40 kHz) pressing a protected 10 g body on a 2e6 N/m, 20 N s/m mount, striker at
   0.5 m/s for 0.1 ms, automatic step (set up member by member), at 1e3 and 1e4 chains (the warp
   kernel below ``WARP_PER_MEMBER_BELOW``), and their largest difference from the CPU engine on
   200 chains, the body's force included.
3. **Long chain**: the tile kernel (``cuda_lanes.tile_kernel``, HALO steps per launch) on one
   uniform chain of 1e5 and 1e6 beads at dt = 5 ns, in bead-steps/s, against one CPU thread
   (``run_verlet``'s lean loop) on the same machine.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, machine_info, quiet, save_json, table, uniform_model  # noqa: E402

DT = 5e-9
TARGET = 3e11


def batch(sizes, repeat: int) -> dict:
    import hertzchain as hc
    from hertzchain.integrate.cuda import launch as hc_cuda
    from hertzchain.runs.batch import simulate_batch

    base = uniform_model(30)
    probes = hc.Probes(1e-6, contacts=(0,))
    duration = 1e-4
    steps = round(duration / DT)
    rows = []
    for m in sizes:
        ens = hc.Ensemble(base, diameters=base.chain.diameters * (1 + 1e-3 * np.random.default_rng(0).standard_normal(
            (m, 30))))
        row = {"chains": m}
        for kernel, lanes in (("register", False), ("lanes", True)):
            hc_cuda.USE_LANES_KERNEL = lanes
            simulate_batch(ens, 2e-6, probes, dt=DT, device="cuda")  # compile, warm
            times = []
            for _ in range(repeat):
                t0 = time.perf_counter()
                simulate_batch(ens, duration, probes, dt=DT, device="cuda")
                times.append(time.perf_counter() - t0)
            row[kernel] = {"best_s": min(times), "bead_steps_per_s": 30 * steps * m / min(times)}
        hc_cuda.USE_LANES_KERNEL = False
        rows.append(row)
    # the lanes kernel against the CPU engine
    ens = hc.Ensemble(base, diameters=base.chain.diameters * (1 + 1e-3 * np.random.default_rng(1).standard_normal(
        (2000, 30))))
    cpu = simulate_batch(ens, 1e-3, probes, dt=DT, device="cpu")
    hc_cuda.USE_LANES_KERNEL = True
    try:
        gpu = simulate_batch(ens, 1e-3, probes, dt=DT, device="cuda")
    finally:
        hc_cuda.USE_LANES_KERNEL = False
    diff = {}
    for v in ("peak_wall_force", "contact_force", "kinetic_energy", "max_contact_force"):
        a, b = cpu[v].values.reshape(2000, -1), gpu[v].values.reshape(2000, -1)
        scale = np.nanmax(np.abs(a), axis=1, keepdims=True)
        diff[v] = float(np.nanmax(np.abs(a - b) / np.where(scale > 0, scale, 1.0)))
    return {"rows": rows, "lanes_vs_cpu_max_rel_diff": diff, "steps_in_comparison": round(1e-3 / DT)}


def bodies(sizes, repeat: int) -> dict:
    import hertzchain as hc
    from hertzchain.elements import Element
    from hertzchain.runs.batch import simulate_batch

    chain = hc.Chain(np.full(30, 26e-3), "AISI52100", None,
                     Element("mim", resonator_fraction=0.3, resonator_frequency=40e3))
    wall = hc.Wall("body", mass=0.01, stiffness=2e6, damping=20.0)
    probes = hc.Probes(1e-6, contacts=(0,))
    duration = 1e-4

    def models(m: int, seed: int) -> list:
        v = 0.5 * (1 + 1e-3 * np.random.default_rng(seed).standard_normal(m))
        return [hc.Model(chain, hc.Striker(8e-3, float(x)), wall) for x in v]

    rows = []
    for m in sizes:
        batch_ = models(m, 0)
        simulate_batch(batch_[:64], 2e-6, probes, device="cuda")  # compile, warm
        times = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            ds = simulate_batch(batch_, duration, probes, device="cuda")
            times.append(time.perf_counter() - t0)
        steps = float(ds["n_steps"].values.mean())
        rows.append({"chains": m, "best_s": min(times), "bead_steps_per_s": 30 * steps * m / min(times)})
    small = models(200, 1)
    cpu = simulate_batch(small, duration, probes, device="cpu")
    gpu = simulate_batch(small, duration, probes, device="cuda")
    diff = {}
    for v in ("peak_wall_force", "contact_force", "body_force", "peak_body_force", "kinetic_energy"):
        a, b = cpu[v].values.reshape(200, -1), gpu[v].values.reshape(200, -1)
        scale = np.nanmax(np.abs(a), axis=1, keepdims=True)
        diff[v] = float(np.nanmax(np.abs(a - b) / np.where(scale > 0, scale, 1.0)))
    return {"rows": rows, "vs_cpu_max_rel_diff": diff, "steps": int(cpu["n_steps"].values.max())}


def long_chain(sizes, repeat: int) -> dict:
    from hertzchain.integrate.cuda.device import _cuda
    from hertzchain.integrate.cuda.lanes import HALO, TILE, tile_kernel
    from hertzchain.integrate.core.layout import pack
    from hertzchain.integrate.drivers.verlet import run_verlet

    cuda = _cuda()
    kernel, width = tile_kernel()
    rows = []
    for n in sizes:
        system = uniform_model(n).system()
        w = pack(system)
        p = w.n_slots
        launches = 200
        du, dv = cuda.to_device(w.u), cuda.to_device(w.v)
        ou, ov = cuda.to_device(w.u.copy()), cuda.to_device(w.v.copy())
        kap, inv = cuda.to_device(w.kappa), cuda.to_device(w.inv_mass)
        fw = cuda.to_device(np.zeros(HALO))
        grid = -(-p // TILE)
        kernel[grid, width](du, dv, ou, ov, kap, inv, DT, HALO, n, fw)
        cuda.synchronize()
        times = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            for _ in range(launches):
                kernel[grid, width](du, dv, ou, ov, kap, inv, DT, HALO, n, fw)
                du, ou = ou, du
                dv, ov = ov, dv
            cuda.synchronize()
            times.append(time.perf_counter() - t0)
        gpu_rate = n * launches * HALO / min(times)
        t0 = time.perf_counter()
        run_verlet(system, 2000 * DT, 1e-6, dt=DT, contacts=np.array([0, n]))
        cpu_rate = n * 2000 / (time.perf_counter() - t0)
        rows.append({"beads": n, "gpu_bead_steps_per_s": gpu_rate, "cpu_one_thread_bead_steps_per_s": cpu_rate,
                     "speedup": gpu_rate / cpu_rate})
    return {"rows": rows, "tile": TILE, "halo": HALO}


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", type=Path, default=RESULTS / "gpu_kernels.json", help="where to save the results")
    ap.add_argument("--quick", action="store_true", help="1e3-1e5 chains, 1e5 beads, one repetition")
    args = ap.parse_args(argv)
    quiet()
    from hertzchain.integrate.cuda.device import gpu_usable

    info = machine_info()
    res = {"benchmark": "gpu_kernels", "machine": info}
    if not gpu_usable():
        res["measured"] = False
        res["note"] = "no usable CUDA GPU on this machine: nothing measured (the kernels are checked by tests/test_cuda_lanes.py)"
        print(res["note"])
        save_json(res, args.json)
        return res
    from numba import cuda

    res["gpu"] = cuda.get_current_device().name.decode() if isinstance(cuda.get_current_device().name, bytes) \
        else str(cuda.get_current_device().name)
    repeat = 1 if args.quick else 3
    res["measured"] = True
    res["batch"] = batch((1000, 10_000, 100_000) if args.quick else (1000, 10_000, 100_000, 1_000_000), repeat)
    res["bodies"] = bodies((1000,) if args.quick else (1000, 10_000), repeat)
    res["long_chain"] = long_chain((100_000,) if args.quick else (100_000, 1_000_000), repeat)
    at = next(r for r in res["batch"]["rows"] if r["chains"] == 100_000)
    best = max(at["register"]["bead_steps_per_s"], at["lanes"]["bead_steps_per_s"])
    res["targets"] = {"bead_steps_per_s_1e5_chains": TARGET, "measured": best, "met": bool(best >= TARGET)}
    print(table([(f"{r['chains']:,}", f"{r['register']['bead_steps_per_s']:.3g}", f"{r['lanes']['bead_steps_per_s']:.3g}")
                 for r in res["batch"]["rows"]], ("chains x 30 beads", "register kernel", "lanes kernel")))
    print("lanes vs CPU engine:", res["batch"]["lanes_vs_cpu_max_rel_diff"])
    print(table([(f"{r['chains']:,}", f"{r['bead_steps_per_s']:.3g}") for r in res["bodies"]["rows"]],
                ("chains x 30 mass-in-mass beads + body", "general kernels")))
    print("bodies vs CPU engine:", res["bodies"]["vs_cpu_max_rel_diff"])
    print(table([(f"{r['beads']:,}", f"{r['gpu_bead_steps_per_s']:.3g}", f"{r['cpu_one_thread_bead_steps_per_s']:.3g}",
                  f"{r['speedup']:.0f}") for r in res["long_chain"]["rows"]],
                ("one chain, beads", "tile kernel", "CPU 1 thread", "x")))
    print(f">= {TARGET:.0e} bead-steps/s at 1e5 chains: {best:.3g} -> {'MET' if res['targets']['met'] else 'NOT MET'}")
    save_json(res, args.json)
    return res


if __name__ == "__main__":
    main()
