"""Ensembles at scale: the vectorised set-up, end-to-end batch throughput, and the CUDA engine.

Usage::

    python benchmarks/ensemble.py [--json PATH] [--quick]

Measures, after a JIT warm-up, on chains of 30 beads of 26 mm AISI 52100 (diameters perturbed
by 0.1 % tolerances, 1 sigma, a different draw per member), striker 8 mm at 0.5 m/s, flat wall:

1. ``setup_s_per_member``: set-up of 1e5 members on the CPU, per member: building the
   :class:`~hertzchain.integrate.batch.ensemble.Ensemble` from the (member, bead) diameters, every
   member's System arrays, step plans, packing into the engine's buffers and the initial state
   (everything ``simulate_batch`` does before the engine runs). Also from a list of 1e5 Models
   (``Ensemble.from_models``), and, as the baseline, the member-by-member set-up
   (``Model.system()`` + pack + initialise per member) on 2,000 of them.
2. ``end_to_end_over_engine``: 1e4 members for 1 ms (adaptive step, probes: striker and wall
   contact forces and the energies every 1 us): the engine alone (compiled calls on the packed
   batch) over ``simulate_batch`` end to end (set-up, engine, stacked Dataset). Target >= 0.85.
   ``cpu_bead_steps_per_s`` is the engine's throughput there (beads x steps / s, all cores).
3. With a usable CUDA GPU: ``gpu_bead_steps_per_s`` of the CUDA engine (fixed dt = 5 ns, 0.1 ms,
   transfers included; the engine's kernel choice: the register kernel for these aligned elastic
   chains) at 1e3, 1e4, 1e5 and 1e6 members, each kernel alone too (register; the general kernel
   with one thread per member; one warp per member up to 1e5 members: where those two cross sets
   ``cuda.WARP_PER_MEMBER_BELOW``), and ``gpu_max_rel_diff_vs_cpu``: the
   largest difference GPU vs CPU engine, relative to each member's largest value, of the peak
   wall force and the sampled contact forces, over an elastic and a viscoelastic misaligned
   ensemble. Without a GPU these keys are absent and ``gpu`` says why.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, best_of, machine_info, quiet, save_json, table  # noqa: E402

from hertzchain import Chain, Model, Probes, Striker, Viscoelastic  # noqa: E402
from hertzchain.errors import ElasticLimitWarning  # noqa: E402
from hertzchain.runs import batch
from hertzchain.integrate.batch import engine as batch_engine, pack as batch_pack
from hertzchain.integrate.cuda import launch as cuda, kernels as cuda_kernels  # noqa: E402
from hertzchain.integrate.drivers.verlet import step_plan  # noqa: E402
from hertzchain.integrate.batch.ensemble import Ensemble  # noqa: E402

N_BEADS = 30
DIAMETER = 26e-3
TOLERANCE = 1e-3
TARGET_SETUP = 10e-6     # s per member, 1e5 members (issue 13)
TARGET_RATIO = 0.85      # end to end over engine alone, 1e4 members
TARGET_GPU_1E5 = 3e11    # bead-steps/s at 1e5 chains on an H100
GPU_DT = 5e-9            # s


def base_model() -> Model:
    return Model(Chain.uniform(N_BEADS, DIAMETER), Striker(8e-3, 0.5))


def perturbed(m: int, seed: int = 0) -> np.ndarray:
    return DIAMETER * (1 + TOLERANCE * np.random.default_rng(seed).standard_normal((m, N_BEADS)))


# ----------------------------------------------------------------------------- 1. set-up
def measure_setup(m: int, repeat: int, n_baseline: int) -> dict:
    base = base_model()
    d = perturbed(m)
    probes = Probes(1e-6, contacts=(0,))
    dts = batch_pack._ensemble_dts(None, m)

    def vectorised():
        ens = Ensemble(base, diameters=d)
        return batch_pack._pack_ensemble(ens, probes, dts, 1e-6, 11)

    vectorised()  # compiled initialise: load / compile
    best, times, _ = best_of(vectorised, repeat)
    models = [Model(Chain(d[i], base.chain.materials), base.striker) for i in range(m)]
    best_models, times_models, _ = best_of(
        lambda: batch_pack._pack_ensemble(Ensemble.from_models(models), probes, dts, 1e-6, 11), repeat)

    def per_member():
        members = []
        for model in models[:n_baseline]:
            system = model.system()
            members.append(batch_pack._Member(system, probes.recorded_contacts(N_BEADS, True),
                                              step_plan(system, 1e-6, None), False))
        return batch_pack._pack_models(members, 1e-6, 11)

    best_old, times_old, _ = best_of(per_member, max(1, repeat - 1))
    return {"members": m, "setup_s_per_member": best / m, "times_s": times,
            "from_models_s_per_member": best_models / m, "from_models_times_s": times_models,
            "member_by_member_s_per_member": best_old / n_baseline, "member_by_member_members": n_baseline,
            "speedup_vs_member_by_member": (best_old / n_baseline) / (best / m)}


# ----------------------------------------------------------------------------- 2. end to end
def measure_end_to_end(m: int, duration: float, repeat: int) -> dict:
    ens = Ensemble(base_model(), diameters=perturbed(m, 1))
    probes = Probes(1e-6, contacts=(0,))
    dts = batch_pack._ensemble_dts(None, m)
    n_samples = int(round(duration / 1e-6)) + 1

    def engine():
        pk, _ = batch_pack._pack_ensemble(ens, probes, dts, 1e-6, n_samples)
        t0 = time.perf_counter()
        batch_engine._engine(pk, None, None)
        return time.perf_counter() - t0, pk

    def end_to_end():
        return batch.simulate_batch(ens, duration, probes, device="cpu")

    # Warm-up at full size: the JIT, and the process's memory (on a VM the first touch of fresh
    # memory cost ~17 us per page here, 0.8 us later: it would fall on whichever call came first).
    t_first, _, _ = best_of(end_to_end, 1)
    eng, times_e2e = [], []
    for _ in range(repeat):  # alternated, so that both see the same machine load
        eng.append(engine())
        t0 = time.perf_counter()
        ds = end_to_end()
        times_e2e.append(time.perf_counter() - t0)
    t_engine = min(t for t, _ in eng)
    t_e2e = min(times_e2e)
    steps = float(np.sum(eng[0][1].acc[:, 2]))
    assert float(np.sum(ds["n_steps"].values)) == steps  # same work in both
    rate = N_BEADS * steps / t_engine
    return {"members": m, "duration_s": duration, "first_call_s": t_first, "engine_s": t_engine,
            "engine_times_s": [t for t, _ in eng],
            "end_to_end_s": t_e2e, "end_to_end_times_s": times_e2e, "total_steps": steps,
            "end_to_end_over_engine": t_engine / t_e2e, "cpu_bead_steps_per_s": rate,
            "end_to_end_bead_steps_per_s": N_BEADS * steps / t_e2e}


# ----------------------------------------------------------------------------- 3. GPU
def measure_gpu(sizes: list[int], repeat: int, warp_up_to: int) -> dict:
    """GPU throughput with the engine's own kernel choice (``bead_steps_per_s``: the register
    kernel for these aligned elastic chains), and each kernel alone: ``register``,
    ``thread_per_member``, ``warp_per_member`` (up to ``warp_up_to`` members)."""
    base = base_model()
    probes = Probes(1e-5, contacts=(0,))
    duration = 1e-4
    out: dict = {"dt_s": GPU_DT, "duration_s": duration, "warp_per_member_below": cuda.WARP_PER_MEMBER_BELOW,
                 "bead_steps_per_s": {}, "register": {}, "thread_per_member": {}, "warp_per_member": {},
                 "times_s": {}}
    saved = cuda.WARP_PER_MEMBER_BELOW, cuda.USE_REGISTER_KERNEL
    settings = {"dispatch": saved, "register": (saved[0], True), "thread": (0, False), "warp": (10**12, False)}

    def run(m: int, kernel: str) -> tuple[float, list[float]]:
        cuda.WARP_PER_MEMBER_BELOW, cuda.USE_REGISTER_KERNEL = settings[kernel]
        ens = Ensemble(base, diameters=perturbed(m, 2))
        times = []
        for _ in range(repeat):
            pk, _ = batch_pack._pack_ensemble(ens, probes, np.full(m, GPU_DT), 1e-5, 11)
            t0 = time.perf_counter()
            cuda.run_packed(pk)
            times.append(time.perf_counter() - t0)
        return N_BEADS * float(np.sum(pk.acc[:, 2])) / min(times), times

    try:
        t0 = time.perf_counter()
        for kernel in ("register", "thread", "warp"):
            run(32, kernel)
        out["first_call_s"] = time.perf_counter() - t0  # compiles the three kernels
        for m in sizes:
            rate, out["times_s"][str(m)] = run(m, "dispatch")
            out["bead_steps_per_s"][str(m)] = rate
            out["register"][str(m)] = run(m, "register")[0]
            out["thread_per_member"][str(m)] = run(m, "thread")[0]
            if m <= warp_up_to:
                out["warp_per_member"][str(m)] = run(m, "warp")[0]
        # the register kernel's block size (its shared memory holds slots x threads parameters)
        tpb = cuda_kernels.REGISTER_THREADS
        out["register_threads_per_block"] = {}
        m = min(100_000, max(sizes))
        for threads in (32, 64):
            cuda_kernels.REGISTER_THREADS = threads
            cuda_kernels._register_kernel.cache_clear()
            run(32, "register")
            out["register_threads_per_block"][str(threads)] = run(m, "register")[0]
        cuda_kernels.REGISTER_THREADS = tpb
        cuda_kernels._register_kernel.cache_clear()
    finally:
        cuda.WARP_PER_MEMBER_BELOW, cuda.USE_REGISTER_KERNEL = saved
    return out


def gpu_vs_cpu(m: int) -> dict:
    """Largest relative difference GPU vs CPU engine: peak wall force and sampled contact forces."""
    rng = np.random.default_rng(3)
    visco = Model(Chain.uniform(N_BEADS, DIAMETER), Striker(8e-3, 0.5), law=Viscoelastic(A=1e-6))
    cases = {"elastic": Ensemble(base_model(), diameters=perturbed(m, 4)),
             "viscoelastic_misaligned": Ensemble(visco, diameters=perturbed(m, 5),
                                                 offsets=0.1e-3 * rng.standard_normal((m, N_BEADS)))}
    out = {}
    for name, ens in cases.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ElasticLimitWarning)
            a = batch.simulate_batch(ens, 1e-3, Probes(1e-6), device="cpu")
            b = batch.simulate_batch(ens, 1e-3, Probes(1e-6), device="cuda")
        diffs = {}
        for v in ("peak_wall_force", "contact_force"):
            x = a[v].values.reshape(m, -1)
            y = b[v].values.reshape(m, -1)
            scale = np.max(np.abs(x), axis=1, keepdims=True)
            diffs[v] = float(np.max(np.abs(x - y) / np.where(scale > 0, scale, 1.0)))
        diffs["same_steps"] = bool(np.array_equal(a["n_steps"].values, b["n_steps"].values))
        out[name] = diffs
    out["max"] = max(max(d["peak_wall_force"], d["contact_force"]) for d in out.values())
    return out


# ----------------------------------------------------------------------------- main
def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", type=Path, default=RESULTS / "ensemble.json", help="where to save the results")
    ap.add_argument("--quick", action="store_true", help="smaller batches and one repetition (a smoke run)")
    args = ap.parse_args(argv)
    quiet()
    info = machine_info()
    print(f"hertzchain ensemble benchmark — {info['cpu_model']}, {info['usable_cores']} usable cores, "
          f"numba {info['numba']}, {info['date_utc']}")
    repeat = 1 if args.quick else 3
    gpu = cuda.gpu_usable()  # asked once (imports numba.cuda, ~1 s), before any timing
    setup = measure_setup(10_000 if args.quick else 100_000, repeat, 500 if args.quick else 2_000)
    e2e = measure_end_to_end(1_000 if args.quick else 10_000, 2e-4 if args.quick else 1e-3, 1 if args.quick else 2)
    res = {"benchmark": "ensemble", "quick": args.quick, "machine": info, "setup": setup, "end_to_end": e2e,
           "setup_s_per_member": setup["setup_s_per_member"],
           "end_to_end_over_engine": e2e["end_to_end_over_engine"],
           "cpu_bead_steps_per_s": e2e["cpu_bead_steps_per_s"]}
    if gpu:
        from numba import cuda as nc

        res["gpu"] = {"device": nc.get_current_device().name.decode() if isinstance(
            nc.get_current_device().name, bytes) else str(nc.get_current_device().name)}
        sizes = [1_000, 10_000] if args.quick else [1_000, 10_000, 100_000, 1_000_000]
        res["gpu"].update(measure_gpu(sizes, repeat, 10_000 if args.quick else 100_000))
        res["gpu_bead_steps_per_s"] = res["gpu"]["bead_steps_per_s"]
        res["gpu"]["vs_cpu"] = gpu_vs_cpu(256 if args.quick else 2_000)
        res["gpu_max_rel_diff_vs_cpu"] = res["gpu"]["vs_cpu"]["max"]
    else:
        res["gpu"] = {"skipped": "no usable CUDA GPU (numba-cuda missing, no driver or no device)"}
    res["targets"] = {
        "setup_s_per_member": TARGET_SETUP, "setup_met": bool(res["setup_s_per_member"] <= TARGET_SETUP),
        "end_to_end_over_engine": TARGET_RATIO, "end_to_end_met": bool(res["end_to_end_over_engine"] >= TARGET_RATIO)}
    if "gpu_bead_steps_per_s" in res and "100000" in res["gpu_bead_steps_per_s"]:
        res["targets"]["gpu_bead_steps_per_s_1e5"] = TARGET_GPU_1E5
        res["targets"]["gpu_met"] = bool(res["gpu_bead_steps_per_s"]["100000"] >= TARGET_GPU_1E5)
        res["targets"]["gpu_max_rel_diff_met"] = bool(res["gpu_max_rel_diff_vs_cpu"] <= 1e-12)
    report(res)
    save_json(res, args.json)
    print(f"\nsaved {args.json}")
    return res


def report(res: dict) -> None:
    s, e = res["setup"], res["end_to_end"]
    rows = [
        (f"set-up, {s['members']:,} members (Ensemble from arrays)", f"{s['setup_s_per_member'] * 1e6:.2f} us/member"),
        ("set-up from a list of Models (Ensemble.from_models)", f"{s['from_models_s_per_member'] * 1e6:.2f} us/member"),
        (f"member-by-member set-up ({s['member_by_member_members']:,} members)",
         f"{s['member_by_member_s_per_member'] * 1e6:.1f} us/member ({s['speedup_vs_member_by_member']:.0f}x slower)"),
        (f"engine alone, {e['members']:,} members x {e['duration_s'] * 1e3:g} ms", f"{e['engine_s']:.2f} s "
         f"({e['cpu_bead_steps_per_s']:.3g} bead-steps/s)"),
        ("simulate_batch end to end",
         f"{e['end_to_end_s']:.2f} s ({e['end_to_end_bead_steps_per_s']:.3g} bead-steps/s)"),
        ("end_to_end_over_engine", f"{e['end_to_end_over_engine']:.3f}"),
    ]
    for m, r in res.get("gpu_bead_steps_per_s", {}).items():
        g = res["gpu"]
        alone = f"register {g['register'][m]:.3g}, thread/member {g['thread_per_member'][m]:.3g}"
        if m in g["warp_per_member"]:
            alone += f", warp/member {g['warp_per_member'][m]:.3g}"
        rows.append((f"GPU, {int(m):,} chains", f"{r:.3g} bead-steps/s ({alone})"))
    if "gpu_max_rel_diff_vs_cpu" in res:
        rows.append(("GPU vs CPU, max relative difference", f"{res['gpu_max_rel_diff_vs_cpu']:.2e}"))
    elif "skipped" in res["gpu"]:
        rows.append(("GPU", res["gpu"]["skipped"]))
    print(table(rows, ("quantity", "value")))
    print("targets:", res["targets"])


if __name__ == "__main__":
    main()
