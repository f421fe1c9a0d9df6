"""CPU engine vs CUDA engine on small ensembles covering every feature the batch engine supports.

Used by tests/test_cuda.py in-process on a GPU, and as a script under Numba's CUDA simulator
(``NUMBA_ENABLE_CUDASIM=1 python tests/cuda_compare.py``), printing the comparison as JSON;
``python tests/cuda_compare.py ptx`` compiles the general kernels to PTX instead (no GPU needed).
"""

from __future__ import annotations

import json
import warnings

import numpy as np

from hertzchain import Chain, Dashpot, Elastoplastic, Model, Probes, Striker, Viscoelastic, Wall
from hertzchain.elements import Element
from hertzchain.errors import ElasticLimitWarning
from hertzchain.runs.batch import simulate_batch
from hertzchain.integrate.batch.ensemble import Ensemble

INTERVAL = 1e-6  # s
#: The protected body's variables (runs.batch_results), compared where a batch has them.
BODY = ("body_force", "body_displacement", "body_velocity", "body_acceleration", "body_energy", "peak_body_force",
        "peak_body_acceleration", "peak_body_energy")


def cases(members: int = 3, beads: int = 3) -> dict[str, tuple[Ensemble, Probes, list, float]]:
    """(ensemble, probes, per-member dt, duration [s]) for each feature group.

    ``members`` >= 3; the first three members carry the special features, the rest are
    tolerance-perturbed copies of the base.
    """
    rng = np.random.default_rng(7)
    # long enough for the wall to see the pulse: ~26 us a 10 mm bead at 0.1 m/s (0.79 ms for 30)
    span = 6e-5 * max(1.0, beads / 3) * (1.0 if beads <= 3 else 2.0)

    def diam(base: Model) -> np.ndarray:
        return base.chain.diameters * (1 + 2e-3 * rng.standard_normal((members, base.chain.n_beads)))

    elastic = Model(Chain.uniform(beads, 10e-3), Striker(8e-3, 0.2))
    pre = np.zeros(members)
    pre[0] = 1.0                              # member 0: precompressed
    off = np.zeros((members, beads))
    off[1, 1] = 0.3e-3                        # member 1: a misaligned bead (general force loop)
    dts = [None] * members
    # member 2: a fixed user step, near the automatic one for longer chains (5 ns there would take
    # 240,000 steps, and the GPU's fused multiply-adds would drift from the CPU's sums by ~1e-12)
    dts[2] = 5e-9 if beads <= 3 else 4e-8
    visco = Model(Chain.uniform(beads, 8e-3, "brass"), Striker(8e-3, 0.15, "brass"), law=Viscoelastic(A=1e-6))
    voff = np.zeros((members, beads))
    voff[0, 2] = -0.2e-3
    dash = Model(Chain.uniform(beads, 10e-3), Striker(8e-3, 0.2), wall=Wall("none"), law=Dashpot(gamma=5.0))
    return {
        "elastic_precompression_offsets_fixed_dt": (
            Ensemble(elastic, diameters=diam(elastic), precompression=pre, offsets=off,
                     striker_velocity=rng.uniform(0.1, 0.3, members)),
            Probes(INTERVAL, sensors=(2,), contacts=(0, 1)), dts, span),
        "viscoelastic_misaligned": (
            Ensemble(visco, diameters=diam(visco), offsets=voff, law_parameter=rng.uniform(0, 2e-6, members)),
            Probes(INTERVAL), [None] * members, span),
        "dashpot_free_end_velocities": (
            Ensemble(dash, diameters=diam(dash), law_parameter=rng.uniform(1, 10, members)),
            Probes(INTERVAL, velocities=True), [None] * members, span / 2),
    }


def register_cases(members: int = 3, beads: int = 3) -> dict[str, tuple[Ensemble, Probes, list, float]]:
    """Aligned elastic ensembles, the register kernel's domain: with precompression (its d0 and
    end-force variant) and a fixed-step member, and without (adaptive step, wall peak tracked)."""
    rng = np.random.default_rng(8)
    span = 6e-5 * max(1.0, beads / 3) * (1.0 if beads <= 3 else 2.0)
    base = Model(Chain.uniform(beads, 10e-3), Striker(8e-3, 0.2))
    diam = base.chain.diameters * (1 + 2e-3 * rng.standard_normal((members, beads)))
    pre = np.zeros(members)
    pre[0] = 1.0
    dts = [None] * members
    dts[1] = 5e-9 if beads <= 3 else 4e-8
    return {
        "register_elastic_precompression_fixed_dt": (
            Ensemble(base, diameters=diam, precompression=pre, striker_velocity=rng.uniform(0.1, 0.3, members)),
            Probes(INTERVAL, sensors=(2,), contacts=(0, 1)), dts, span),
        "register_elastic": (
            Ensemble(base, diameters=diam, striker_velocity=rng.uniform(0.1, 0.3, members)),
            Probes(INTERVAL, velocities=True), [None] * members, span),
    }


def warp_cases() -> dict[str, tuple[Ensemble, Probes, list, float]]:
    """Short cases for the warp-per-member kernel under the simulator (every lane is a Python
    thread there and every barrier costs milliseconds): the elastic fast path (adaptive, with
    precompression on a fixed step) and the general one (offsets, a dashpot), 3 samples each."""
    elastic = Model(Chain.uniform(3, 10e-3), Striker(8e-3, 0.2))
    dash = Model(Chain.uniform(3, 10e-3), Striker(8e-3, 0.2), law=Dashpot(gamma=3.0))
    return {
        "warp_elastic_precompression_offsets": (
            Ensemble(elastic, striker_velocity=[0.1, 0.2, 0.3], offsets=[[0, 0, 0], [0, 1e-4, 0], [0, 0, 0]],
                     precompression=[0.0, 0.0, 1.0]), Probes(INTERVAL, sensors=(2,)), [None, None, 5e-8], 3e-6),
        "warp_dashpot_misaligned": (
            Ensemble(dash, striker_velocity=[0.1, 0.3], offsets=[[0, 1e-4, 0], [0, 0, 0]]),
            Probes(INTERVAL, velocities=True), [None, None], 3e-6),
    }


def plastic_cases(warp: bool = False, long: bool = False) -> dict[str, tuple[list, Probes, list, float]]:
    """Elastic-plastic members (Thornton's law) fast enough to yield, as a list of models (the
    law is set up member by member), 3 beads: the plain law on the adaptive step; with a viscous
    term (A > 0) and a misaligned bead; with a viscous term on a fixed step. 5 us (every member's
    striker contact has yielded; ~25 s in the simulator, at ~25 ms a member-step),
    or with ``long`` 30 us (the pulse reaches the wall; ~170 s: the slow set); ``warp``: the
    viscous misaligned member alone, 3 us (every barrier costs milliseconds under the simulator)."""
    def model(velocity: float, A: float, offset: float = 0.0) -> Model:
        return Model(Chain(np.full(3, 10e-3), offsets=np.array([0.0, offset, 0.0])), Striker(8e-3, velocity),
                     law=Elastoplastic(A))

    models = [model(2.0, 0.0), model(2.5, 1e-6, 0.2e-3), model(1.5, 2e-6)]
    if warp:
        return {"warp_elastoplastic_misaligned": (models[1:2], Probes(INTERVAL, velocities=True), [None], 3e-6)}
    return {"elastoplastic_misaligned_fixed_dt": (models, Probes(INTERVAL, velocities=True), [None, None, 2e-8],
                                                  3e-5 if long else 5e-6)}


def body_cases(warp: bool = False, long: bool = False) -> dict[str, tuple[list, Probes, list, float]]:
    """Protected bodies and mass-in-mass beads (the engine's extension) in one batch of models (set
    up member by member) on a 1-bead chain struck at 0.7-1.5 m/s, 35 us (the body's face force has
    peaked, ~30 us; ~10 s in the simulator): (a) a protected body on a mount spring and dashpot
    (elastic law, adaptive step, a bead 0.2 mm off the axis); (b) mass-in-mass beads on a flat
    wall, on a fixed step; (c) both, with the Kuwabara-Kono law, and with Thornton's elastic-plastic
    law under gravity; (d) a plain member (no extension, in the same batch). ``long``: 3-bead chains for 80 us (the slow set); ``warp``: (c)
    alone, 4 us (every barrier of the warp kernel costs milliseconds under the simulator)."""
    n = 3 if long else 1
    mim = Element("mim", resonator_fraction=0.3, resonator_frequency=40e3)
    resonant = Chain(np.full(n, 10e-3), "AISI52100", None, mim)
    body = Wall("body", mass=0.01, stiffness=2e6, damping=20.0)
    offset = np.zeros(n)
    offset[0] = 0.2e-3
    both = Model(resonant, Striker(8e-3, 1.0), body, law=Viscoelastic(A=1e-6))
    if warp:
        return {"warp_mass_in_mass_body_viscoelastic": ([both], Probes(INTERVAL, velocities=True), [None], 4e-6)}
    models = [Model(Chain(np.full(n, 10e-3), offsets=offset), Striker(8e-3, 1.0), body), Model(resonant, Striker(8e-3, 0.7)), both,
              Model(resonant, Striker(8e-3, 1.5), body, law=Elastoplastic(1e-6), gravity=9.81),
              Model(Chain.uniform(n, 10e-3), Striker(8e-3, 0.9))]
    return {"bodies_mass_in_mass_laws": (models, Probes(INTERVAL, velocities=True), [None, 1e-8, None, None, None],
                                         8e-5 if long else 3.5e-5)}


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    """Largest difference relative to the variable's largest magnitude in each member (NaN-aware)."""
    a = a.reshape(a.shape[0], -1)
    b = b.reshape(b.shape[0], -1)
    if not np.isfinite(a).any():
        return 0.0 if np.array_equal(np.isnan(a), np.isnan(b)) else float("inf")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # members without the variable (all NaN)
        scale = np.nanmax(np.abs(a), axis=1, keepdims=True)
        scale[~(scale > 0)] = 1.0
        return float(np.nanmax(np.abs(a - b) / scale))


def compare(members: int = 3, beads: int = 3, kernel: str = "thread", which=None) -> dict:
    """Per case: max relative difference GPU vs CPU of every compared variable, and whether the
    step counts, steps and NaN layouts are identical. ``kernel``: "thread" or "warp" per member over
    :func:`cases`, or "register" (the register kernel) over :func:`register_cases`."""
    from hertzchain.integrate.cuda import launch as hc_cuda

    saved = hc_cuda.WARP_PER_MEMBER_BELOW, hc_cuda.USE_REGISTER_KERNEL
    hc_cuda.WARP_PER_MEMBER_BELOW = 10**12 if kernel == "warp" else 0
    hc_cuda.USE_REGISTER_KERNEL = kernel == "register"
    try:
        return _compare(which or (register_cases if kernel == "register" else cases)(members, beads))
    finally:
        hc_cuda.WARP_PER_MEMBER_BELOW, hc_cuda.USE_REGISTER_KERNEL = saved


def _compare(which: dict) -> dict:
    out = {}
    for name, (ens, probes, dts, duration) in which.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ElasticLimitWarning)
            cpu = simulate_batch(ens, duration, probes, dt=dts, device="cpu")
            launches: list = []
            gpu = simulate_batch(ens, duration, probes, dt=dts, device="cuda",
                                 progress=lambda d, t, reports=launches: reports.append(d))
        res = {"engine": gpu.attrs["engine"], "launches": len(launches)}
        for v in ("peak_wall_force", "peak_wall_time", "contact_force", "wall_force", "sensor_force", "velocity",
                  "kinetic_energy", "potential_energy", "dissipated_energy", "max_contact_force", "plastic_work",
                  "residual_overlap", *BODY):
            if v in cpu:
                res[v] = _rel(cpu[v].values, gpu[v].values)
        res["same_steps"] = bool(np.array_equal(cpu["n_steps"].values, gpu["n_steps"].values)
                                 and np.array_equal(cpu["dt"].values, gpu["dt"].values))
        res["same_nan"] = all(np.array_equal(np.isnan(cpu[v].values), np.isnan(gpu[v].values))
                              for v in cpu.data_vars if cpu[v].dtype.kind == "f")
        res["pulse_N"] = float(np.nanmax(cpu["contact_force"].values))
        has_wall = ens.has_wall if isinstance(ens, Ensemble) else ens[0].wall.present
        res["min_peak_wall_N"] = float(np.min(cpu["peak_wall_force"].values)) if has_wall else None
        res["n_steps"] = cpu["n_steps"].values.tolist()
        res["dissipated_J"] = float(np.nanmax(cpu["dissipated_energy"].values))
        if "plastic_work" in cpu:  # every member yields: its plastic work at the end
            res["plastic_work_J"] = cpu["plastic_work"].values[:, -1].tolist()
        if "peak_body_force" in cpu:  # the pulse loads the protected body
            res["peak_body_N"] = np.nan_to_num(cpu["peak_body_force"].values).tolist()
        # the GPU run's energy balance: kinetic + stored + dissipated (+ plastic work) against the start
        total = sum(np.nan_to_num(gpu[v].values) for v in ("kinetic_energy", "potential_energy", "dissipated_energy",
                                                           "plastic_work") if v in gpu)
        res["energy_drift"] = float(np.max(np.abs(total - total[:, :1]) / np.abs(total[:, :1])))
        out[name] = res
    return out


def multi_launch() -> dict:
    """A run cut into ~10 launches (small output budget): state carried across launches exactly."""
    from hertzchain.integrate.cuda import launch as hc_cuda

    ens = Ensemble(Model(Chain.uniform(3, 10e-3), Striker(8e-3, 0.2)), striker_velocity=[0.1, 0.2])
    saved = hc_cuda.LAUNCH_OUTPUT_BYTES, hc_cuda.WARP_PER_MEMBER_BELOW
    hc_cuda.LAUNCH_OUTPUT_BYTES, hc_cuda.WARP_PER_MEMBER_BELOW = 8 * 2 * (5 + 3) * 3, 0  # 3 samples a launch
    reports: list = []
    try:
        one = simulate_batch(ens, 3e-5, Probes(INTERVAL), device="cpu")
        many = simulate_batch(ens, 3e-5, Probes(INTERVAL), device="cuda", progress=lambda d, t: reports.append(d))
    finally:
        hc_cuda.LAUNCH_OUTPUT_BYTES, hc_cuda.WARP_PER_MEMBER_BELOW = saved
    return {"launches": len(reports), "last": reports[-1],
            "forces_equal": bool(np.array_equal(one["contact_force"].values, many["contact_force"].values)),
            "peaks_equal": bool(np.array_equal(one["peak_wall_force"].values, many["peak_wall_force"].values))}


def ptx() -> dict:
    """Compile the general kernels (one thread and one warp per member, the elastic-plastic law's
    state included) to PTX for an H100 (sm_90) without a GPU, as tests/cuda_lanes_compare.py
    does: numba-cuda asks the current device for its compute capability, answered here."""
    import types as pytypes

    from numba import cuda, types
    from numba.cuda import dispatcher

    from hertzchain.integrate.cuda.kernels import _kernels

    dispatcher.get_current_device = lambda: pytypes.SimpleNamespace(compute_capability=(9, 0))
    f1, f2, f3 = types.float64[::1], types.float64[:, ::1], types.float64[:, :, ::1]
    i1, b1, i8, f8 = types.int64[::1], types.boolean[::1], types.int64, types.float64
    # (u, v, a, g, vp[, sc]), 10 parameters, the 4 elastic-plastic state arrays, then law ... status, then
    # the extension: wa, ext (column, slot, member), ext_on, body_slot, out_b
    tail = (f2,) * 10 + (f2,) * 4 + (i1, b1, i1, f8, i1, i1, i1, f1, i1, i8, i8, i1, f3, f2, f2, f2, f2, f3, b1, f2, f2,
                                     f2, i1, f2, f3, b1, i1, f3)
    from hertzchain.integrate.core.kernels import elastoplastic_force

    from hertzchain.integrate.core.extension import extended_bound

    code, _ = cuda.compile_ptx(elastoplastic_force.py_func, (f8,) * 8, device=True, cc=(9, 0))
    out = {"elastoplastic_force": {"ieee_sqrt": code.count("sqrt.rn.f64"), "division": code.count("div.rn.f64"),
                                   "approximate": code.count(".approx."), "chars": len(code)}}
    # the extension's step bound (core.extension's source, as the kernels compile it)
    code, _ = cuda.compile_ptx(extended_bound.py_func, (f8, f8, f8, f8, i8, f8, f8, f8, f8, f8), device=True, cc=(9, 0))
    out["extended_bound"] = {"ieee_sqrt": code.count("sqrt.rn.f64"), "approximate": code.count(".approx."),
                             "chars": len(code)}
    # a registry law's kernel (the power law's, generated from its Python source), the extension's
    # arguments included: (u, v, a, g, vp, state), 10 parameters, wall_slot ... status, wa ... out_b
    import hertzchain as hc
    from hertzchain.integrate.cuda.generated import generated_kernel
    from hertzchain.laws import get_law

    hc.PowerLaw(2.0, 1e9)  # (registered on import; the name gives its engine code)
    gen = (f2,) * 16 + (i1, f8, i1, i1, i1, f1, i1, i8, i8, i1, f3, f2, f2, f2, f3, b1, f2, f2, f2, i1, f2, f3, b1, i1, f3)
    code, _ = cuda.compile_ptx(generated_kernel(get_law("power").code).py_func, gen, cc=(9, 0))
    out["generated_power"] = {"ieee_sqrt": code.count("sqrt.rn.f64"), "chars": len(code)}
    for name, n_state in (("thread", 5), ("warp", 6)):
        code, _ = cuda.compile_ptx(_kernels()[name].py_func, (f2,) * n_state + tail, cc=(9, 0))
        out[name] = {"ieee_sqrt": code.count("sqrt.rn.f64"), "division": code.count("div.rn.f64"),
                     "barriers": code.count("bar.sync"), "chars": len(code)}
    return out


if __name__ == "__main__":
    import sys

    from simulator_core import pin_to_one_cpu

    pin_to_one_cpu()

    if sys.argv[1:] == ["ptx"]:
        print(json.dumps(ptx()))
        sys.exit()
    if sys.argv[1:2] == ["bodies"]:
        from hertzchain.integrate.cuda import launch as hc_cuda

        long = sys.argv[2:] == ["long"]
        hc_cuda.LAUNCH_OUTPUT_BYTES = 2000  # ~4 samples a launch: the extension's state carried across launches
        print(json.dumps({"thread": compare(which=body_cases(long=long)),
                          **({} if long else {"warp": compare(kernel="warp", which=body_cases(warp=True))})}))
        sys.exit()
    if sys.argv[1:] == ["plastic_long"]:
        print(json.dumps({"plastic": compare(which=plastic_cases(long=True))}))
        sys.exit()
    print(json.dumps({"thread": compare(), "register": compare(kernel="register"),
                      "warp": compare(kernel="warp", which=warp_cases()),
                      "plastic": compare(which=plastic_cases()),
                      "plastic_warp": compare(kernel="warp", which=plastic_cases(warp=True)),
                      "multi_launch": multi_launch()}))
