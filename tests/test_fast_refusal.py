"""A bad config is refused before anything compiles: config validation, the engine choice and the
pre-flight compile nothing and import no engine module, nor xarray (issue 37: ``--set
striker.velocity=-1`` was refused only after 11-25 s of compilation). Checked by what a fresh
process compiled and imported, not by a wall-clock bound (which is flaky on shared machines)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SCRIPT = """
import json, sys
from hertzchain.cli.main import main
try:
    rc = main(sys.argv[1:])
except SystemExit as exc:
    rc = exc.code
compiled = []
if "numba" in sys.modules:  # the contact-law registry defines its compiled functions at import: none may compile
    import gc
    from numba.core.registry import CPUDispatcher
    compiled = [d.py_func.__qualname__ for d in gc.get_objects() if isinstance(d, CPUDispatcher) and d.signatures]
print(json.dumps({"rc": rc, "compiled": compiled, "xarray": "xarray" in sys.modules,
                  "integrate": sorted(m for m in sys.modules if m.startswith("hertzchain.integrate"))}))
"""


@pytest.mark.parametrize("override, field", [("striker.velocity=-1", "striker.velocity"),
                                             ("run.threads=0", "run.threads"),
                                             ("run.integrator=euler", "run.integrator")])
def test_bad_config_is_refused_before_any_kernel_is_imported(tmp_path, override, field):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO / "src"), os.environ.get("PYTHONPATH", "")])}
    out = tmp_path / "x.nc"
    proc = subprocess.run([sys.executable, "-c", SCRIPT, "run", str(REPO / "examples" / "chain1.toml"),
                           "--set", override, "--out", str(out)],
                          capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300)
    seen = json.loads(proc.stdout.strip().splitlines()[-1])
    assert seen["rc"] == 2
    assert field in proc.stderr and "Traceback" not in proc.stderr
    # at most the integrate package and its refusal checks (plain Python), no compiled module
    assert seen["compiled"] == []
    assert set(seen["integrate"]) <= {"hertzchain.integrate", "hertzchain.integrate.drivers.refusals"}
    assert not seen["xarray"]  # ~0.5 s of imports, needed only once the config is valid
    assert not out.exists()


@pytest.mark.parametrize("overrides, field", [
    (("probes.sensors=[99]",), "probes.sensors[0]"),
    (("probes.contacts=[31]",), "probes.contacts[0]"),
    (("run.sample_interval=0.01",), "run.sample_interval"),
    (("chain.precompression=1e9",), "chain.precompression"),
    (("run.duration=50",), "run.duration"),  # 207 GiB of records
    (("run.integrator=dop853", "run.threads=2"), "run.threads"),
    (("track.friction=0.1", "run.threads=2"), "run.threads"),
])
def test_a_run_is_refused_before_its_law_is_calibrated(tmp_path, overrides, field):
    """What the run refuses once the model is built (the probes against the chain, the engine the
    options ask for, the static overlaps, the memory of the records, the lateral path's options)
    is refused before the calibration of chain 1's law: its runs compile (or load) the law's
    engine, ~8 CPU-s in a fresh installation. No compiled function is typed, from the cache or
    not (the calibration's would be)."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO / "src"), os.environ.get("PYTHONPATH", "")])}
    out = tmp_path / "x.nc"
    sets = [a for o in overrides for a in ("--set", o)]
    proc = subprocess.run([sys.executable, "-c", SCRIPT, "run", str(REPO / "examples" / "chain1.toml"), *sets,
                           "--out", str(out)], capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300)
    seen = json.loads(proc.stdout.strip().splitlines()[-1])
    assert seen["rc"] == 2, proc.stderr
    assert f"{field}:" in proc.stderr and "Traceback" not in proc.stderr
    assert seen["compiled"] == []
    assert "hertzchain.integrate.drivers.rkn_damped" not in seen["integrate"]  # the calibration's driver
    assert not out.exists()


def test_bad_value_in_a_config_file_is_refused_before_any_kernel_is_imported(tmp_path):
    """The same for a bad value written in the file (not an override): named with its file field."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO / "src"), os.environ.get("PYTHONPATH", "")])}
    text = (REPO / "examples" / "chain1.toml").read_text().replace("velocity = 0.2 ", "velocity = -0.2 ")
    assert "velocity = -0.2" in text
    config = tmp_path / "bad.toml"
    config.write_text(text)
    out = tmp_path / "x.nc"
    proc = subprocess.run([sys.executable, "-c", SCRIPT, "run", str(config), "--out", str(out)],
                          capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300)
    seen = json.loads(proc.stdout.strip().splitlines()[-1])
    assert seen["rc"] == 2 and "striker.velocity" in proc.stderr and "Traceback" not in proc.stderr
    assert seen["compiled"] == [] and not seen["xarray"]
    assert set(seen["integrate"]) <= {"hertzchain.integrate", "hertzchain.integrate.drivers",
                                      "hertzchain.integrate.drivers.refusals"}
    assert not out.exists()


API = """
import gc, json, sys
import hertzchain as hc
m = hc.Model(hc.Chain.uniform(5, 26e-3), hc.Striker(8e-3, 0.2), hc.Wall("flat"), hc.Elastic())
calls = {"run.duration": lambda: hc.simulate(m, -1.0),
         "run.integrator": lambda: hc.simulate(m, 1e-4, integrator="euler"),
         "run.threads": lambda: hc.simulate(m, 1e-4, threads=0),
         "run.dt": lambda: hc.simulate(m, 1e-4, dt=float("nan")),
         "run.sample_interval": lambda: hc.simulate(m, 1e-4, hc.Probes(sample_interval=-1.0)),
         "striker.velocity": lambda: hc.simulate(hc.Model(hc.Chain.uniform(5, 26e-3), hc.Striker(8e-3, -1.0)), 1e-4)}
seen = {}
for field, call in calls.items():
    try:
        call()
        seen[field] = None
    except hc.ConfigError as exc:
        seen[field] = str(exc)
compiled = []
if "numba" in sys.modules:
    from numba.core.registry import CPUDispatcher
    compiled = [d.py_func.__qualname__ for d in gc.get_objects() if isinstance(d, CPUDispatcher) and d.signatures]
print(json.dumps({"errors": seen, "compiled": compiled,
                  "kernels": sorted(k for k in sys.modules if k.endswith("kernels"))}))
"""


def test_simulate_refuses_a_bad_call_before_any_kernel_is_imported():
    """``hc.simulate`` with a bad argument or model: a ConfigError naming the field, before any
    compiled module is imported (so before anything compiles)."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO / "src"), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run([sys.executable, "-c", API], capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr
    seen = json.loads(proc.stdout.strip().splitlines()[-1])
    for field, message in seen["errors"].items():
        assert message is not None and message.startswith(field), (field, message)
    assert seen["compiled"] == [] and seen["kernels"] == []
