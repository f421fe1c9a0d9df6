"""Sensitivities in memory linear in the beads and the variables (issue 38: the set-up's
derivatives were a dense variables x beads matrix, 0.57 GB at 1,000 beads, 1.5 GB at 2,000).

The set-up's derivatives are computed on a few rows of the complex step shared by a list's
items (colours) and stored by their nonzero entries: they must equal those computed one
variable at a time, their size must double when the chain doubles (every bead a variable), and
the estimate made before the run must hold (the set-up's traced allocations and the taped run's
arrays stay below their parts of it)."""

from __future__ import annotations

import json
import subprocess
import sys
import tracemalloc

import numpy as np
import pytest

from hertzchain.config import build_model, parse_config
from hertzchain.errors import ConfigError
from hertzchain.gradients.memory import MemoryEstimate, check_memory, estimate_memory
from hertzchain.gradients.setup import _plan, expand_paths, setup_derivatives
from hertzchain.integrate.derivatives import differentiate as D

CONFIGS = {
    # a listed chain extended by a taper (its last listed bead scales every tapered one), under a
    # static load, with the size-scaled dashpot (bead 1 sets every contact's damping) and a body
    "taper-scaled-body": {"chain": {"diameters_mm": [20.0, 19.0, 18.0, 17.0, 16.0, 15.0, 14.0, 13.0, 12.0, 11.0],
                                    "taper": {"n": 4, "q": 0.05}, "precompression": 2.0},
                          "contact": {"law": "dashpot_scaled", "gamma": 20.0},
                          "wall": {"type": "body", "mass": 0.05, "stiffness": 2e5, "damping": 5.0}},
    "uniform-offsets": {"chain": {"uniform": {"n": 12, "diameter_mm": 20.0}, "offsets_mm": [0.0] * 3 + [0.1] * 9},
                        "contact": {"law": "viscoelastic_scaled", "A": 1e-6}},
}


def _uniform(n: int) -> dict:
    return {"chain": {"uniform": {"n": n, "diameter_mm": 20.0}}, "striker": {"velocity": 0.3},
            "run": {"duration": 2e-4, "sample_interval": 1e-6}}


@pytest.mark.parametrize("name", list(CONFIGS))
def test_shared_rows_give_each_variable_its_own_derivatives(name):
    cfg = parse_config(CONFIGS[name])
    system = build_model(cfg).system()
    lists = ["chain.offsets_mm"] if "offsets_mm" in CONFIGS[name]["chain"] else []
    paths = expand_paths(cfg, ["chain.diameters_mm[0:10]", "striker.velocity", *lists])
    rows, masks = _plan(cfg, paths)
    assert max(rows.values()) + 1 < len(paths) and masks  # items do share rows
    sd = setup_derivatives(cfg, system, paths)
    for p in paths:
        alone = setup_derivatives(cfg, system, [p])  # a row of its own: the plain complex step
        for array in sd.values:
            np.testing.assert_allclose(sd.dense(p, array), alone.dense(p, array), rtol=1e-13, atol=0, err_msg=p)


def test_memory_grows_linearly_with_beads_and_variables():
    sizes, rows = [], []
    for n in (400, 800, 1600):
        cfg = parse_config(_uniform(n))
        system = build_model(cfg).system()
        paths = expand_paths(cfg, ["chain.diameters_mm"])
        sd = setup_derivatives(cfg, system, paths)
        sizes.append(sd.nbytes)
        rows.append(max(_plan(cfg, paths)[0].values()) + 1)
        # a bead's diameter moves a bounded number of entries, whatever the chain's length
        assert max(sum(i.size for i, _ in d.values()) for d in sd.derivatives.values()) <= 24
    assert rows[0] == rows[1] == rows[2]  # the complex step's rows do not grow with the chain
    assert sizes[1] / sizes[0] == pytest.approx(2.0, rel=0.01) and sizes[2] / sizes[1] == pytest.approx(2.0, rel=0.01)


def test_the_estimate_holds_for_the_setup_and_the_tape():
    cfg = parse_config(_uniform(2000))
    system = build_model(cfg).system()
    paths = expand_paths(cfg, ["chain.diameters_mm", "materials.AISI52100.young"])
    est = estimate_memory(cfg, system, 2e-4, paths, tangent=False)
    tracemalloc.start()
    setup_derivatives(cfg, system, paths)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert peak <= est.parts["setup"] + est.parts["variables"] <= 4 * peak
    tape = D.record(system, 2e-4, 1e-6)
    held = sum(a.nbytes for a in (tape.ckpt, tape.forces, tape.ns_log, tape.step_end, tape.time))
    assert held <= est.parts["tape"]
    twice = estimate_memory(parse_config(_uniform(4000)), build_model(parse_config(_uniform(4000))).system(), 2e-4,
                            expand_paths(parse_config(_uniform(4000)), ["chain.diameters_mm",
                                                                        "materials.AISI52100.young"]), tangent=False)
    assert twice.total / est.total == pytest.approx(2.0, rel=0.05)


def test_past_the_memory_available_it_is_refused_naming_the_cause():
    est = MemoryEstimate({"setup": 10, "variables": 2**31, "tape": 5}, {"setup": "variables", "variables": "variables",
                                                                      "tape": "run.duration"})
    with pytest.raises(ConfigError, match="fewer variables") as info:
        check_memory(est, available=2**30)
    assert info.value.field == "variables"
    est = MemoryEstimate({"variables": 10, "tape": 2**31}, {"variables": "variables", "tape": "run.duration"})
    with pytest.raises(ConfigError, match="run.duration") as info:
        check_memory(est, available=2**30)
    check_memory(est, available=2**33)  # fits: no error


CHILD = r"""
import json, resource, sys
import hertzchain as hc
from hertzchain.gradients import memory_estimate
def cfg(n):
    return {"chain": {"uniform": {"n": n, "diameter_mm": 20.0}}, "striker": {"velocity": 0.3},
            "run": {"duration": 2e-4, "sample_interval": 1e-6}}
hc.sensitivity(cfg(50), ["chain.diameters_mm"], "peak_contact_force[2]")  # compiled code loaded
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
est = memory_estimate(cfg(int(sys.argv[1])), ["chain.diameters_mm"])
hc.sensitivity(cfg(int(sys.argv[1])), ["chain.diameters_mm"], "peak_contact_force[2]")
print(json.dumps({"grew": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 - before, "estimate": est}))
"""


def test_peak_rss_stays_within_the_estimate():
    """A whole sensitivity of 8,000 bead diameters, in a fresh process: its peak resident set grows
    by less than the estimate (before: ~4 GB for 4,000 beads)."""
    out = subprocess.run([sys.executable, "-c", CHILD, "8000"], capture_output=True, text=True, check=True)
    res = json.loads(out.stdout.strip().splitlines()[-1])
    assert res["grew"] <= res["estimate"] < 2**30
