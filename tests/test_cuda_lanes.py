"""The lanes-per-chain batch kernel and the long-chain tile kernel (hertzchain.integrate.cuda.lanes):
against the CPU engine through Numba's CUDA simulator, and compiled to PTX for an H100 without a
GPU (when the CUDA compiler libraries, the ``gpu`` extra, are installed)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("numba.cuda", reason="the CUDA kernels need numba-cuda (the 'gpu' / 'test' extras)")

HERE = Path(__file__).resolve().parent
EPS = float(np.finfo(np.float64).eps)


def _run(*args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1" if not args else "0")
    return subprocess.run([sys.executable, str(HERE / "cuda_lanes_compare.py"), *args], capture_output=True, text=True,
                          env=env, timeout=600, cwd=HERE)


def test_lanes_and_tile_kernels_match_the_cpu_engine_simulated():
    """Square roots from a refined reciprocal square root: within a few ulps per step of the CPU
    engine (the documented bound: eps x steps relative, as for the GPU's fused multiply-adds); the
    tile kernel's halo steps reproduce the CPU's lean steps."""
    proc = _run()
    assert proc.returncode == 0, proc.stderr[-3000:]
    res = json.loads(proc.stdout.strip().splitlines()[-1])
    for name, r in res["lanes"].items():
        assert r["same_steps"] and r["pulse_N"] > 1.0, name
        bound = EPS * r["steps"]
        for key in ("contact_force", "velocity", "kinetic_energy", "potential_energy", "max_contact_force",
                    "peak_wall_force"):
            assert r[key] <= bound, (name, key, r[key], bound)
    tile = res["tile"]
    assert tile["moving_bodies"] > 3
    assert tile["u"] <= EPS * 12 and tile["v"] <= EPS * 12


def test_kernels_compile_to_ptx_for_h100():
    proc = _run("ptx")
    if proc.returncode != 0:
        if any(s in proc.stderr for s in ("nvrtc", "NVVM", "libnvvm", "DynamicLibNotFound", "CudaSupportError")):
            pytest.skip("the CUDA compiler libraries are not installed (pip install 'hertzchain[gpu]')")
        raise AssertionError(proc.stderr[-3000:])
    res = json.loads(proc.stdout.strip().splitlines()[-1])
    lanes, tile = res["lanes"], res["tile"]
    # the refined fast reciprocal square root, no IEEE square root, one barrier a step (+ the
    # block's), and no chain state spilled to local memory
    assert lanes["rsqrt_approx"] > 0 and lanes["ieee_sqrt"] == 0 and lanes["local_memory"] == 0
    assert lanes["barriers"] >= 2 and tile["rsqrt_approx"] > 0 and tile["barriers"] >= 2
