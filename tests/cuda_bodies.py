"""The CUDA engine on models beyond the paper's (a given flat striker, gravity, cylinders, given
masses) against the CPU engine, run under Numba's CUDA simulator
(``NUMBA_ENABLE_CUDASIM=1 python tests/cuda_bodies.py``); prints the comparison as JSON. Protected
bodies and mass-in-mass beads: tests/cuda_compare.py's ``bodies``."""

from __future__ import annotations

import json

import numpy as np

from hertzchain import Chain, Dashpot, Model, Probes, Striker
from hertzchain.elements import Element
from hertzchain.runs.batch import simulate_batch


def main() -> dict:
    rod = Element("rod", "cylinder", "aligned", 12e-3)
    heavy = Element("heavy", mass=0.02)
    chain = Chain(np.full(3, 10e-3), "AISI52100", None, (Element(), rod, heavy))
    models = [Model(chain, Striker(8e-3, 0.2, mass=5e-3, shape="flat"), gravity=9.81),
              Model(chain, Striker(8e-3, 0.3), law=Dashpot(gamma=2.0)),
              Model(Chain.uniform(3, 10e-3), Striker(8e-3, 0.25, radius_of_curvature=20e-3), gravity=30.0)]
    probes = Probes(1e-6, velocities=True)
    cpu = simulate_batch(models, 6e-5, probes, device="cpu")
    gpu = simulate_batch(models, 6e-5, probes, device="cuda")
    out = {"engine": gpu.attrs.get("engine", ""), "pulse_N": float(np.nanmax(cpu.wall_force.values))}
    for name in ("contact_force", "wall_force", "velocity", "kinetic_energy", "potential_energy", "dissipated_energy",
                 "peak_wall_force"):
        a, b = cpu[name].values, gpu[name].values
        out[name] = float(np.nanmax(np.abs(a - b)) / np.nanmax(np.abs(a)))
    return out


if __name__ == "__main__":
    print(json.dumps(main()))
