"""CPU engine vs CUDA engine for the laws run by the generated engines (power, Hunt-Crossley), on
chains against a flat wall, a protected body and of mass-in-mass beads.

Run under Numba's CUDA simulator by tests/test_laws.py (``NUMBA_ENABLE_CUDASIM=1 python
tests/cuda_laws.py``); prints, per law, the largest force difference relative to the largest
force, and the largest energy difference relative to the initial energy, as JSON.
"""

from __future__ import annotations

import json
import warnings

import numpy as np

import hertzchain as hc


def compare(law, wall=None, chain=None) -> dict:
    chain = hc.Chain.uniform(3, 10e-3) if chain is None else chain
    models = [hc.Model(chain, hc.Striker(8e-3, v), *(() if wall is None else (wall,)), law=law) for v in (0.2, 0.3)]
    out = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cpu = hc.simulate_batch(models, duration=4e-5, probes=hc.Probes(sample_interval=1e-6), device="cpu")
        gpu = hc.simulate_batch(models, duration=4e-5, probes=hc.Probes(sample_interval=1e-6), device="cuda")
    f = cpu.contact_force.values
    out["force"] = float(np.max(np.abs(gpu.contact_force.values - f)) / np.max(np.abs(f)))
    e0 = float(cpu.kinetic_energy.values[:, 0].max())
    out["energy"] = max(float(np.max(np.abs(gpu[k].values - cpu[k].values))) / e0
                        for k in ("kinetic_energy", "potential_energy", "dissipated_energy"))
    out["peak_force"] = float(np.max(f))
    if wall is not None:  # the protected body's record
        out["body"] = float(np.max(np.abs(gpu.body_displacement.values - cpu.body_displacement.values))
                            / np.max(np.abs(cpu.body_displacement.values)))
    return out


if __name__ == "__main__":
    from simulator_core import pin_to_one_cpu

    from hertzchain.elements import Element

    pin_to_one_cpu()

    body = hc.Wall("body", mass=0.02, stiffness=1e6, damping=5.0)
    mim = hc.Chain(np.full(3, 10e-3), "AISI52100", None, Element("mim", resonator_fraction=0.3,
                                                                 resonator_frequency=20e3))
    print(json.dumps({"power": compare(hc.PowerLaw(2.0, 1e13)), "hunt_crossley": compare(hc.HuntCrossley(0.8)),
                      "hunt_crossley, protected body": compare(hc.HuntCrossley(0.8), wall=body),
                      "power, mass-in-mass": compare(hc.PowerLaw(2.0, 1e13), chain=mim)}))
