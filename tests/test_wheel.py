"""A release that works from a wheel, outside the repository: build the wheel and the sdist, install
the wheel alone (core dependencies only) into a fresh virtual environment, and from an empty folder
run what a new user runs: ``--version``, ``example``, ``run``, ``plot``, ``analyze`` and ``reproduce``.

Marked ``wheel`` (minutes: the build, the install, cold Numba compiles, ``reproduce``): excluded from
the default run, run by CI (``.ci/run``) as ``pytest -m wheel tests/test_wheel.py``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

import hertzchain as hc

pytestmark = pytest.mark.wheel

ROOT = Path(__file__).resolve().parents[1]
#: What the core must not pull in: each belongs to a named extra.
OPTIONAL = ("dask", "distributed", "cma", "tomli-w", "tomli_w", "pymoo", "panel", "bokeh", "pyarrow")


def _run(args, cwd, env, timeout=900, check=True) -> subprocess.CompletedProcess:
    run = subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    if check:
        assert run.returncode == 0, f"{' '.join(map(str, args))}\n{run.stdout[-3000:]}\n{run.stderr[-3000:]}"
    return run


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """(bin folder, empty working folder, environment) of a fresh venv holding only the wheel."""
    base = tmp_path_factory.mktemp("wheel")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME")}
    env.update(MPLBACKEND="Agg", PIP_DISABLE_PIP_VERSION_CHECK="1")
    dist = base / "dist"
    _run([sys.executable, "-m", "build", "--outdir", str(dist), str(ROOT)], base, env, timeout=1200)
    wheels, sdists = sorted(dist.glob("hertzchain-*.whl")), sorted(dist.glob("hertzchain-*.tar.gz"))
    assert len(wheels) == 1 and len(sdists) == 1, sorted(p.name for p in dist.iterdir())
    assert wheels[0].name.startswith(f"hertzchain-{hc.__version__}-py3-none-any")
    venv = base / "venv"
    _run([sys.executable, "-m", "venv", str(venv)], base, env)
    _run([str(venv / "bin" / "python"), "-m", "pip", "install", "-q", str(wheels[0])], base, env, timeout=1800)
    work = base / "empty"
    work.mkdir()
    return venv / "bin", work, env


def test_the_wheel_installs_only_the_core(installed):
    bin_, work, env = installed
    listed = _run([str(bin_ / "python"), "-m", "pip", "list", "--format=json"], work, env).stdout
    names = {p["name"].lower() for p in json.loads(listed)}
    assert "hertzchain" in names and not names & set(OPTIONAL), names & set(OPTIONAL)
    core = {r.split(">")[0].split("[")[0].lower() for r in
            tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]}
    assert core <= names
    where = _run([str(bin_ / "python"), "-c", "import hertzchain; print(hertzchain.__file__)"], work, env).stdout
    assert str(bin_.parent) in where and str(ROOT) not in where  # the installed copy, not this tree


def test_a_new_user_runs_plots_and_analyzes_from_an_empty_folder(installed, tmp_path):
    bin_, work, env = installed
    hz = str(bin_ / "hertzchain")
    assert _run([hz, "--version"], work, env).stdout.strip() == f"hertzchain, version {hc.__version__}"
    config = _run([hz, "example", "chain1"], work, env).stdout
    (work / "chain1.toml").write_text(config)
    assert config == (ROOT / "examples" / "chain1.toml").read_text()
    _run([hz, "run", "chain1.toml", "--out", "chain1.nc", "-q"], work, env)
    _run([hz, "plot", "chain1.nc", "--out", "chain1.png"], work, env)
    assert (work / "chain1.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    _run([hz, "analyze", "chain1.nc", "--json", "analysis.json"], work, env)
    # The installed package computes what this tree computes (same engine, same config).
    theirs = hc.load(work / "chain1.nc")
    ours = hc.run_config(ROOT / "examples" / "chain1.toml")
    assert theirs.attrs["peak_wall_force"] == pytest.approx(ours.attrs["peak_wall_force"], rel=1e-9)
    (work / "scope.csv").write_text(_run([hz, "example", "scope"], work, env).stdout)
    out = _run([hz, "analyze", "scope.csv"], work, env).stdout
    assert "read with time in us, signal in N" in out and "F_m [N]" in out  # units of the file's header
    # Optional features say which extra to install (exit status 2), not a traceback.
    (work / "sweep.toml").write_text(_run([hz, "example", "sweep_taper"], work, env).stdout)
    refused = _run([hz, "sweep", "sweep.toml", "--out", "s", "--scheduler", "tcp://127.0.0.1:1"], work, env,
                   check=False)
    assert refused.returncode == 2 and "hertzchain[cluster]" in refused.stderr and "Traceback" not in refused.stderr
    (work / "design.toml").write_text(_run([hz, "example", "design_taper"], work, env).stdout)
    refused = _run([hz, "design", "design.toml", "--out", "d"], work, env, check=False)
    assert refused.returncode == 2 and "hertzchain[design]" in refused.stderr


def test_reproduce_from_the_wheel_in_an_empty_folder(installed):
    bin_, work, env = installed
    _run([str(bin_ / "hertzchain"), "reproduce", "--out", "reproduction"], work, env, timeout=1800)
    out = work / "reproduction"
    for name in ("fig1.png", "fig6.png", "summary.json", "report.md", "report.html"):
        assert (out / name).is_file(), name
    s = json.loads((out / "summary.json").read_text())
    assert s["hertzchain_version"] == hc.__version__
    # the traces and Fig. 3's numbers are made by the drawing processes (paper.reproduce.draw's jobs)
    from hertzchain.paper.inputs import expected_traces
    from hertzchain.paper.protocol import N0

    missing = [name for name in [*expected_traces(N0), "uniform16_elastic_wall_chain_ratio.nc"]
               if not (out / "data" / name).is_file()]
    assert not missing, missing
    assert s["fidelity"]["misalignment"]["rigid"] and len(s["claims"]) >= 10
    # The installed reproduction finds the paper's physics, as the tree's does (tests/test_reproduce.py):
    # eps measured back = the calibrated 0.985, Q_fit within the paper's error bar of eq. 8's Q_th.
    assert s["eps"] == pytest.approx(0.985, rel=3e-3)
    for chain in ("chain1", "chain2"):
        assert abs(s[chain]["Q_fit"] - s[chain]["Q_theory"]) < s["paper"][chain]["Q_fit_err"]
