"""CPU engine vs CUDA engine for the laws run by the generated engines (power, Hunt-Crossley).

Run under Numba's CUDA simulator by tests/test_laws.py (``NUMBA_ENABLE_CUDASIM=1 python
tests/cuda_laws.py``); prints, per law, the largest force difference relative to the largest
force, and the largest energy difference relative to the initial energy, as JSON.
"""

from __future__ import annotations

import json
import warnings

import numpy as np

import hertzchain as hc


def compare(law) -> dict:
    models = [hc.Model(hc.Chain.uniform(3, 10e-3), hc.Striker(8e-3, v), law=law) for v in (0.2, 0.3)]
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
    return out


if __name__ == "__main__":
    print(json.dumps({"power": compare(hc.PowerLaw(2.0, 1e13)), "hunt_crossley": compare(hc.HuntCrossley(0.8))}))
