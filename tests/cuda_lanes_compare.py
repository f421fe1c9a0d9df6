"""The lanes-per-chain and tile kernels (hertzchain.integrate.cuda.lanes) against the CPU engine.

Run as a script under Numba's CUDA simulator (``NUMBA_ENABLE_CUDASIM=1 python
tests/cuda_lanes_compare.py``) by tests/test_cuda_lanes.py, or on a GPU; prints JSON.
"""

from __future__ import annotations

import json
import warnings

import numpy as np

from hertzchain import Chain, Model, Probes, Striker
from hertzchain.errors import ElasticLimitWarning
from hertzchain.runs.batch import simulate_batch
from hertzchain.integrate.batch.ensemble import Ensemble


def lanes(members: int = 3, beads: int = 5, steps_per_sample: int = 8, samples: int = 6) -> dict:
    """CPU engine vs the lanes kernel on a fixed step: largest relative differences."""
    from hertzchain.integrate.cuda import launch as hc_cuda

    rng = np.random.default_rng(3)
    base = Model(Chain.uniform(beads, 10e-3), Striker(8e-3, 0.2))
    out = {}
    for name, pre in (("plain", np.zeros(members)), ("precompressed", np.r_[2.0, np.zeros(members - 1)])):
        ens = Ensemble(base, diameters=base.chain.diameters * (1 + 2e-3 * rng.standard_normal((members, beads))),
                       precompression=pre, striker_velocity=rng.uniform(0.1, 0.3, members))
        interval = 1e-6
        probes = Probes(interval, velocities=True)
        dt = interval / steps_per_sample
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ElasticLimitWarning)
            cpu = simulate_batch(ens, samples * interval, probes, dt=dt, device="cpu")
            saved = hc_cuda.USE_LANES_KERNEL
            hc_cuda.USE_LANES_KERNEL = True
            try:
                gpu = simulate_batch(ens, samples * interval, probes, dt=dt, device="cuda")
            finally:
                hc_cuda.USE_LANES_KERNEL = saved
        res = {"steps": int(cpu["n_steps"].values.max()), "same_steps": bool(np.array_equal(cpu["n_steps"].values,
                                                                                            gpu["n_steps"].values))}
        for v in ("contact_force", "velocity", "kinetic_energy", "potential_energy", "max_contact_force",
                  "peak_wall_force"):
            a, b = cpu[v].values, gpu[v].values
            scale = np.nanmax(np.abs(a))
            res[v] = float(np.nanmax(np.abs(a - b)) / scale) if scale > 0 else float(np.nanmax(np.abs(b)))
        res["pulse_N"] = float(np.nanmax(cpu["contact_force"].values))
        out[name] = res
    return out


def tile(beads: int = 40, steps: int = 12) -> dict:
    """One chain: ``steps`` lean steps on the CPU (kernels.step_elastic_lean) against the tile
    kernel with a tile of 8 bodies and a halo of 4 (3 launches of 4 steps)."""
    from hertzchain.integrate.core import kernels
    from hertzchain.integrate.cuda.device import _cuda
    from hertzchain.integrate.cuda.lanes import tile_kernel
    from hertzchain.integrate.core.layout import pack
    from numba import njit

    @njit
    def lean(u, v, kappa, inv_mass, dt, n):
        for _ in range(n):
            kernels.step_elastic_lean(u, v, kappa, inv_mass, dt)

    cuda = _cuda()
    model = Model(Chain.uniform(beads, 10e-3), Striker(8e-3, 0.3))
    w = pack(model.system())
    dt = 2e-8
    u, v = w.u.copy(), w.v.copy()
    lean(u, v, w.kappa, w.inv_mass, dt, 400)  # a pulse in the chain
    ref_u, ref_v = u.copy(), v.copy()
    lean(ref_u, ref_v, w.kappa, w.inv_mass, dt, steps)
    kernel, width = tile_kernel(8, 4)
    p = w.n_slots
    du, dv = cuda.to_device(u), cuda.to_device(v)
    ou, ov = cuda.to_device(u.copy()), cuda.to_device(v.copy())
    kap, inv = cuda.to_device(w.kappa), cuda.to_device(w.inv_mass)
    fw = cuda.to_device(np.zeros(4))
    for _ in range(steps // 4):
        kernel[-(-p // 8), width](du, dv, ou, ov, kap, inv, dt, 4, beads, fw)
        du, ou = ou, du
        dv, ov = ov, dv
    gu, gv = du.copy_to_host(), dv.copy_to_host()
    moving = np.abs(ref_v) > 0
    return {"moving_bodies": int(moving.sum()),
            "u": float(np.max(np.abs(gu - ref_u)) / np.max(np.abs(ref_u))),
            "v": float(np.max(np.abs(gv - ref_v)) / np.max(np.abs(ref_v)))}


def ptx() -> dict:
    """Compile both kernels to PTX for an H100 (sm_90) without a GPU: numba-cuda asks the current
    device for its compute capability when it compiles a device function, so that question is
    answered here. Counts what the choices of the module docstring should leave in the code."""
    import types as pytypes

    from numba import cuda, types
    from numba.cuda import dispatcher

    from hertzchain.integrate.cuda import lanes as cuda_lanes

    dispatcher.get_current_device = lambda: pytypes.SimpleNamespace(compute_capability=(9, 0))
    f1, f2, f3 = types.float64[::1], types.float64[:, ::1], types.float64[:, :, ::1]
    i1, b1 = types.int64[::1], types.boolean[::1]
    kernel, _ = cuda_lanes.lanes_kernel(32, cuda_lanes.LANES, False, cuda_lanes.CHAINS_PER_BLOCK)
    sig = (f2,) * 9 + (i1, types.float64, types.int64, types.int64, types.int64, i1, f3, f2, f2, f2, f3, b1, f2, f2, f2,
                       i1)
    lanes_ptx, _ = cuda.compile_ptx(kernel.py_func, sig, cc=(9, 0))
    tile, _ = cuda_lanes.tile_kernel()
    tile_ptx, _ = cuda.compile_ptx(tile.py_func, (f1,) * 6 + (types.float64, types.int64, types.int64, f1), cc=(9, 0))
    return {name: {"rsqrt_approx": code.count("rsqrt.approx.f64"), "ieee_sqrt": code.count("sqrt.rn.f64"),
                   "barriers": code.count("bar.sync"), "local_memory": code.count(".local"), "chars": len(code)}
            for name, code in (("lanes", lanes_ptx), ("tile", tile_ptx))}


if __name__ == "__main__":
    import sys

    from simulator_core import pin_to_one_cpu

    pin_to_one_cpu()

    if sys.argv[1:] == ["ptx"]:
        print(json.dumps(ptx()))
    else:
        print(json.dumps({"lanes": lanes(members=3, beads=3, steps_per_sample=5, samples=40), "tile": tile()}))
