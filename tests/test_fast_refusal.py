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
