"""The CUDA engine with the extension (a protected body on a mount spring and dashpot, mass-in-mass
beads) against the CPU batched engine, through Numba's CUDA simulator in a fresh process
(tests/cuda_compare.py ``bodies``); the GPU run of the same cases is in tests/test_cuda.py.

Bounds: the simulator runs the kernels' Python source on Python floats, without fused
multiply-adds, so every force, velocity, body record and peak is the CPU engine's bit for bit.
The energies are not: the CPU engine sums them reassociated (``fastmath={"reassoc"}``, vectorised
partial sums) and the kernels in slot order, so they differ by rounding, bounded by
eps x steps as in tests/test_cuda.py (measured: <= 5.2e-16 relative).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.errors import ConfigError
from hertzchain.integrate.cuda import launch as hc_cuda
from hertzchain.runs.batch import simulate_batch

pytest.importorskip("numba.cuda", reason="the CUDA backend needs numba-cuda (the 'gpu' / 'test' extras)")

HERE = Path(__file__).resolve().parent
EPS = float(np.finfo(np.float64).eps)
EXACT = ("peak_wall_force", "peak_wall_time", "contact_force", "wall_force", "velocity", "max_contact_force",
         "residual_overlap", "body_force", "body_displacement", "body_velocity", "body_acceleration", "body_energy",
         "peak_body_force", "peak_body_acceleration", "peak_body_energy")
SUMMED = ("kinetic_energy", "potential_energy", "dissipated_energy", "plastic_work")
#: Energy balance of the runs (kinetic + stored + dissipated + plastic work against the start): the
#: Verlet's own error at the automatic step (measured 2.9e-7 on the 1-bead cases); leaving out a
#: term of the extension (the internal masses' kinetic energy, the mount's spring or dashpot) breaks
#: it by O(0.1).
DRIFT = 1e-5


def _run(*args: str) -> dict:
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1")
    proc = subprocess.run([sys.executable, str(HERE / "cuda_compare.py"), "bodies", *args], capture_output=True,
                          text=True, env=env, timeout=1200, cwd=HERE)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def simulated() -> dict:
    """The ``bodies`` comparisons through the simulator (~20 CPU-s), run once for this module."""
    return _run()


def _check(res: dict, n_body: int) -> None:
    assert res["engine"].startswith("batched velocity Verlet on the GPU")
    assert res["same_steps"] and res["same_nan"]
    for key in EXACT:
        if key in res:
            assert res[key] == 0.0, (key, res[key])
    accumulated = EPS * max(res["n_steps"])
    for key in SUMMED:
        if key in res:
            assert res[key] <= accumulated, (key, res[key], accumulated)
    assert res["energy_drift"] < DRIFT
    # the comparison is not vacuous: the pulse loads the protected bodies
    assert sum(f > 0.0 for f in res["peak_body_N"]) == n_body


def test_simulated_bodies_and_mass_in_mass_match_the_cpu_engine(simulated):
    """One batch on the thread-per-member kernel: (a) a protected body on a mount spring and
    dashpot (a bead off the axis), (b) mass-in-mass beads on a fixed step, (c) both with the
    Kuwabara-Kono law and with the elastic-plastic one (under gravity), (d) a plain member:
    forces, velocities, the bodies' records and peaks bit for bit, energies within eps x steps,
    the energy balance kept, every body loaded (its face force past its peak: > 100 N in every
    member), the plastic member yielded, the viscous ones
    dissipating. The run is cut into launches of ~4 samples: the internal masses' state and the
    bodies' work carried from launch to launch on the device, the internal accelerations
    recomputed at each launch's start as the CPU engine does at each chunk's, exactly."""
    (name, res), = simulated["thread"].items()
    _check(res, n_body=3)
    assert res["launches"] >= 8
    assert res["min_peak_wall_N"] > 100.0 and min(f for f in res["peak_body_N"] if f > 0) > 1.0
    assert res["dissipated_J"] > 0 and np.nanmax(res["plastic_work_J"]) > 0
    assert res["n_steps"][1] == 3500  # the fixed 10 ns step over 35 us


def test_simulated_warp_kernel_runs_the_extension(simulated):
    """The warp-per-member kernel (2 lanes under the simulator: bodies and contacts split between
    lanes, sums by lane 0) on a protected body with mass-in-mass beads and the Kuwabara-Kono law:
    the CPU engine's numbers (same bounds)."""
    (name, res), = simulated["warp"].items()
    _check(res, n_body=1)
    assert res["dissipated_J"] > 0


@pytest.mark.slow
def test_simulated_bodies_match_the_cpu_engine_on_longer_chains():
    """The same batch on 3-bead chains for 80 us (~1 min in the simulator)."""
    (name, res), = _run("long")["thread"].items()
    _check(res, n_body=3)
    assert res["min_peak_wall_N"] > 100.0


@pytest.mark.skipif(hc_cuda.gpu_usable() or hc_cuda._simulated(), reason="runs the batch where a GPU is usable")
def test_device_cuda_takes_bodies_and_asks_only_for_a_gpu():
    """A protected body with ``device="cuda"`` is no longer refused for its wall.type: without a
    GPU the one error is the missing device."""
    model = hc.Model(hc.Chain.uniform(1, 10e-3), hc.Striker(8e-3, 1.0),
                     hc.Wall("body", mass=0.01, stiffness=2e6, damping=20.0))
    with pytest.raises(ConfigError) as e:
        simulate_batch([model, model], 2e-5, hc.Probes(1e-6), device="cuda")
    assert e.value.field == "device"
