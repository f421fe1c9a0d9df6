"""Cold start (issue 37): a run compiles only the engine it uses. Checked by which compiled
functions a fresh process compiled or loaded (a dispatcher with signatures), not by timing.

The reproduction's chain 1 (``examples/chain1.toml``: ``dashpot_scaled`` calibrated to eps =
0.985) runs on ``rkn4``'s y'' = f(y, y') method; its calibration and the two-body restitution of
its law run on the same kernels, so no Verlet kernel is compiled (it cost ~13 CPU-s of the first
run in a fresh environment, and of a cold ``reproduce``)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

SCRIPT = """
import gc, json, sys
import hertzchain as hc
from hertzchain.config import build_model, load_config
from numba.core.registry import CPUDispatcher
model = build_model(load_config(sys.argv[1], ()))
ds = hc.simulate(model)
e = hc.restitution(0.2, model.law, 8e-3, "AISI52100", 26e-3)  # the striker's bounce (paper/fidelity.py)
used = sorted({d.py_func.__module__ for d in gc.get_objects() if isinstance(d, CPUDispatcher) and d.signatures})
print(json.dumps({"integrator": ds.attrs["integrator_used"], "modules": used, "e": e}))
"""


def test_calibrated_chain1_compiles_only_the_engine_it_runs():
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO / "src"), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run([sys.executable, "-c", SCRIPT, str(REPO / "examples" / "chain1.toml")],
                          capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr
    seen = json.loads(proc.stdout.strip().splitlines()[-1])
    assert seen["integrator"] == "rkn4"
    assert 0.95 < seen["e"] < 0.97  # the size-scaled dashpot: a steel-like bounce (docs: e ~ 0.96 at 0.2 m/s)
    engine = [m for m in seen["modules"] if m.startswith("hertzchain.")]
    # the damped engine, and (typed only where it compiles, not when it loads from the cache) the
    # interpolation helpers of rkn_kernels it calls: no Verlet kernel, cold or warm
    assert engine in (["hertzchain.integrate.drivers.rkn_damped_kernels"],
                      ["hertzchain.integrate.drivers.rkn_damped_kernels", "hertzchain.integrate.drivers.rkn_kernels"])


OFFSETS = """
import json, warnings
warnings.simplefilter("ignore")
import hertzchain as hc
from hertzchain.integrate.drivers import rkn_damped_kernels as rk
chain, striker, law = hc.paper_chain("chain1").truncated(6), hc.Striker(8e-3, 0.2), hc.Dashpot(gamma=8.0)
models = [hc.Model(c, striker, hc.Wall("flat"), law) for c in (chain, chain.with_offsets({3: 2e-5}))]
runs = [hc.simulate(m, 2e-4).attrs["integrator_used"] for m in models]
print(json.dumps({"integrators": runs, "signatures": len(rk.damped_run.signatures)}))
"""


def test_aligned_and_offset_chains_share_one_compiled_engine():
    """An aligned chain's offsets are an array without columns, not None, so that aligned and
    offset chains run one compiled ``damped_run`` (rkn_damped_kernels.G_DE): a specialisation of
    its own for each cost ~6 CPU-s more in a fresh environment and in a cold ``reproduce``."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO / "src"), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run([sys.executable, "-c", OFFSETS], capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr
    seen = json.loads(proc.stdout.strip().splitlines()[-1])
    assert seen == {"integrators": ["rkn4", "rkn4"], "signatures": 1}


def test_calibration_on_rkn4_matches_the_verlet():
    """The calibration's engine does not move the law: the calibrated dashpot measures the target
    eps (xtol 1e-5 on gamma moves eps by ~1e-7), and the fitted contacts' peak forces are the
    Verlet's at a fine step (800 steps per radian) within 2e-6 (8e-7 measured: the peaks' refinement
    between 1 us samples; 2e-5 at the Verlet's coarse 50 steps per radian)."""
    import numpy as np

    import hertzchain as hc
    from hertzchain.dissipation import calibrate_law, measure_eps, refine_peaks
    from hertzchain.integrate.drivers.verlet import run_verlet

    striker = hc.Striker(8e-3, 0.2)
    law = calibrate_law("dashpot", 0.985, diameter=26e-3, striker=striker)
    m = measure_eps(law, 26e-3, striker=striker)
    assert abs(m.eps - 0.985) < 2e-6
    model = hc.Model(hc.Chain.uniform(m.contacts[-1] + 4, 26e-3), striker, hc.Wall("none"), law)
    raw = run_verlet(model.system(), m.duration, 1e-6, steps_per_radian=800.0, contacts=m.contacts)
    _, f_verlet = refine_peaks(raw.time, raw.contact_force)
    assert np.allclose(f_verlet, m.peak_force, rtol=2e-6, atol=0)


THREADED = """
import gc, json, warnings
warnings.simplefilter("ignore")
import hertzchain as hc
from numba.core.registry import CPUDispatcher
m = hc.Model(hc.Chain.uniform(64, 26e-3), hc.Striker(8e-3, 0.2), hc.Wall("flat"), hc.Dashpot(20.0))
ds = hc.simulate(m, 1e-4, threads=2)
stats = {d.py_func.__qualname__: [sum(d.stats.cache_hits.values()), sum(d.stats.cache_misses.values())]
         for d in gc.get_objects() if isinstance(d, CPUDispatcher) and d.signatures
         and d.py_func.__module__ == "hertzchain.integrate.drivers.threaded_laws"}
print(json.dumps({"threads": int(ds.attrs["threads_used"]), "stats": stats,
                  "force": ds.contact_force.values[-1].tolist()}))
"""


def test_threaded_law_closures_load_from_the_cache_in_a_new_process():
    """The threaded engine's closures over compiled functions (a built-in law's thread function and
    its segments) are cached on disk: a second process (a new Dask worker, a second run) loads
    them instead of compiling them (~7 CPU-s a law before), and runs the same numbers."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO / "src"), os.environ.get("PYTHONPATH", "")])}
    runs = []
    for _ in range(2):  # the first fills the cache where no earlier run did
        proc = subprocess.run([sys.executable, "-c", THREADED], capture_output=True, text=True, env=env, timeout=600)
        assert proc.returncode == 0, proc.stderr
        runs.append(json.loads(proc.stdout.strip().splitlines()[-1]))
    second = runs[1]
    assert second["threads"] == 2
    # the thread function comes from the cache whole (its segments, stride and energies compiled
    # in): nothing of the module is compiled
    assert second["stats"]["_build.<locals>.thread_run"][0] >= 1
    assert all(misses == 0 for _, misses in second["stats"].values()), second["stats"]
    assert runs[0]["force"] == second["force"]  # the cached code is the compiled one


def test_report_formulas_are_drawn_once_per_installation(tmp_path, monkeypatch):
    """The report's formulas (~0.7 CPU-s of mathtext) are kept beside Numba's cache: a new process
    reads them instead of drawing them, the same HTML; a damaged or foreign file is redrawn over."""
    from hertzchain.paper import render

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(render, "_DRAWN", {})
    monkeypatch.setattr(render, "_STORE", {"read": False, "new": False})
    tex = r"(F_m^{n+1}/F_m^{n})^{5/6}"
    drawn = render._svg_formula(tex)
    assert drawn.startswith('<span class="math"') and "<path" in drawn
    render._save_formulas()
    store = render._formula_store()
    assert store.parent == tmp_path and store.is_file()

    def no_drawing(tex):
        raise AssertionError("drawn again")

    # a new process: nothing in memory, the formula read from the file
    monkeypatch.setattr(render, "_DRAWN", {})
    monkeypatch.setattr(render, "_STORE", {"read": False, "new": False})
    monkeypatch.setattr(render, "_draw_formula", no_drawing)
    assert render._svg_formula(tex) == drawn

    # a damaged file: ignored, the formula drawn
    store.write_text('{"x": "<script>alert(1)</script>", ' * 3)
    monkeypatch.setattr(render, "_DRAWN", {})
    monkeypatch.setattr(render, "_STORE", {"read": False, "new": False})
    monkeypatch.setattr(render, "_draw_formula", lambda t: drawn)
    assert render._svg_formula(tex) == drawn
    # a foreign entry that is not a drawn formula is not taken
    store.write_text(json.dumps({tex: "<script>alert(1)</script>"}))
    monkeypatch.setattr(render, "_DRAWN", {})
    monkeypatch.setattr(render, "_STORE", {"read": False, "new": False})
    assert render._svg_formula(tex) == drawn


GENERATED = """
import gc, json, warnings
warnings.simplefilter("ignore")
import hertzchain as hc
from numba.core.registry import CPUDispatcher
m = hc.Model(hc.Chain.uniform(12, 20e-3), hc.Striker(8e-3, 0.2), hc.Wall("flat"), hc.PowerLaw(1.7, 2e11))
ds = hc.simulate(m, 1e-4, integrator="verlet", threads=1)
stats = {d.py_func.__qualname__: [sum(d.stats.cache_hits.values()), sum(d.stats.cache_misses.values())]
         for d in gc.get_objects() if isinstance(d, CPUDispatcher) and d.signatures
         and d.py_func.__module__ == "hertzchain.integrate.core.generated"}
print(json.dumps({"stats": stats, "force": ds.contact_force.values[-1].tolist(),
                  "peak": float(ds.attrs["peak_wall_force"])}))
"""


def test_a_registry_laws_loops_load_from_the_cache_in_a_new_process(tmp_path):
    """The loops generated from a registry law (closures over the law's own functions) are cached
    on disk under the text of the law's file and of the engine's files: a second process loads the
    run instead of compiling it (~2-5 CPU-s a law before), and runs the same numbers."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path),
           "PYTHONPATH": os.pathsep.join([str(REPO / "src"), os.environ.get("PYTHONPATH", "")])}
    runs = []
    for _ in range(2):  # an empty cache, then the one the first process left
        proc = subprocess.run([sys.executable, "-c", GENERATED], capture_output=True, text=True, env=env, timeout=600)
        assert proc.returncode == 0, proc.stderr
        runs.append(json.loads(proc.stdout.strip().splitlines()[-1]))
    first, second = runs
    assert first["stats"]["_build.<locals>.make_run.<locals>.run"][1] >= 1  # compiled in the first process
    assert second["stats"]["_build.<locals>.make_run.<locals>.run"] == [1, 0]  # loaded in the second: nothing compiled
    assert all(misses == 0 for _, misses in second["stats"].values()), second["stats"]
    assert first["force"] == second["force"] and first["peak"] == second["peak"]


def test_the_cache_key_follows_the_law_files_text(tmp_path):
    """The key holds the whole text of the file that defines a law's functions (its constants
    too), read when the law is built: an edit (in the same session too) gives another key; a
    function without a source file gives none (memory only)."""
    import importlib.util

    from hertzchain.integrate.core import disk_cache

    path = tmp_path / "mylaw.py"
    path.write_text("K = 2.0\ndef force(d):\n    return K * d\n")
    spec = importlib.util.spec_from_file_location("mylaw", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    before = disk_cache.function_files_digest(module.force)
    path.write_text("K = 3.0\ndef force(d):\n    return K * d\n")
    after = disk_cache.function_files_digest(module.force)
    assert before is not None and after is not None and before != after
    namespace: dict = {}
    exec("def typed(d):\n    return d\n", namespace)
    assert disk_cache.function_files_digest(namespace["typed"]) is None


AHEAD = """
import gc, json, warnings
warnings.simplefilter("ignore")
from numba.core.registry import CPUDispatcher
from hertzchain.contact import Dashpot
from hertzchain.paper import fidelity
from hertzchain.paper.ahead import CompileAhead
from hertzchain.paper.protocol import Settings
settings = Settings()
ahead = CompileAhead(settings, kinds=("lateral",))
forked = ahead._proc is not None
ahead.wait("lateral")
ahead.close()
fidelity.warm_lateral(settings, Dashpot(2.0))
stats = {d.py_func.__qualname__: [sum(d.stats.cache_hits.values()), sum(d.stats.cache_misses.values())]
         for d in gc.get_objects() if isinstance(d, CPUDispatcher) and d.signatures
         and d.py_func.__module__ == "hertzchain.integrate.drivers.lateral"}
print(json.dumps({"forked": forked, "stats": stats}))
"""


def test_a_kind_compiled_ahead_is_loaded_not_compiled(tmp_path):
    """reproduce's fork (paper/ahead.py) compiles a model kind into Numba's cache while the
    reproduction runs others: in a fresh installation (an empty cache), once ``wait`` returns, the
    kind's run in this process loads every kernel of its engine and compiles none."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path),
           "PYTHONPATH": os.pathsep.join([str(REPO / "src"), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run([sys.executable, "-c", AHEAD], capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr
    seen = json.loads(proc.stdout.strip().splitlines()[-1])
    if not seen["forked"]:  # one usable core or no fork: nothing compiled ahead, by design
        pytest.skip("no second core or no fork here")
    assert seen["stats"]["lateral_run"] == [1, 0]
    assert all(misses == 0 for _, misses in seen["stats"].values()), seen["stats"]


def test_the_compiling_fork_runs_the_wall_chain_ratio_with_the_same_numbers(monkeypatch):
    """reproduce's compiling fork (paper/ahead.py) also runs the elastic wall/chain ratio once its
    kernels are compiled and sends it back: the same numbers and trace, bit for bit, as this
    process's run (the same compiled kernels), and this process does not run it again."""
    import numpy as np

    from hertzchain.paper import ahead as ahead_module
    from hertzchain.paper.protocol import Settings, run_wall_chain_ratio

    settings = Settings()
    ahead = ahead_module.CompileAhead(settings, kinds=("elastic",))
    if ahead._proc is None:  # one usable core or no fork: nothing runs ahead, by design
        pytest.skip("no second core or no fork here")

    def not_here(_settings):
        raise AssertionError("the ratio was run again in this process")

    try:
        with monkeypatch.context() as m:
            m.setattr(ahead_module, "run_wall_chain_ratio", not_here)  # (the fork holds the real one)
            theirs = ahead.wall_chain_ratio()
    finally:
        ahead.close()
    mine = run_wall_chain_ratio(settings)
    assert theirs["force_ratio"] == mine["force_ratio"] and theirs["duration_ratio"] == mine["duration_ratio"]
    for name in ("wall_force", "contact_force", "kinetic_energy"):
        assert np.array_equal(theirs["dataset"][name].values, mine["dataset"][name].values), name
