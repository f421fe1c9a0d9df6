"""The documentation: the Sphinx site builds with warnings as errors, covers every public name,
and the README's Quick start works as pasted.

The default run builds the site without executing the gallery (``-D plot_gallery=0``, ~10 s);
``-m slow`` executes the gallery scripts and the README's Quick start.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import typing
from pathlib import Path

import pytest

import hertzchain as hc

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"

pytest.importorskip("sphinx")
pytest.importorskip("pydata_sphinx_theme")
pytest.importorskip("numpydoc")
pytest.importorskip("sphinx_gallery")
pytest.importorskip("sphinx-mathjax-offline")  # MathJax copied into the site (docs/conf.py)


def _build(out: Path, *extra: str) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-E", "-b", "html",
           "-d", str(out / "doctrees"), *extra, str(DOCS), str(out / "html")]
    env = {**os.environ, "MPLBACKEND": "Agg"}
    return subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=600)


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("docs")
    run = _build(out, "-D", "plot_gallery=0")
    assert run.returncode == 0, f"sphinx -W failed:\n{run.stdout}\n{run.stderr}"
    return out / "html"


def _text(page: Path) -> str:
    return re.sub(r"<[^>]+>", " ", page.read_text())


def test_site_builds_with_every_page(site):
    pages = ["index", "conventions", "theory", "benchmarks", "validation", "api/index", "gallery/index", "architecture"]
    pages += [f"guide/{p}" for p in ("config", "running", "explore", "results", "analysis", "reproduction", "sweeps", "cluster",
                                     "instrument", "lab", "design", "gpu", "plotting", "fidelity", "bodies", "plasticity", "errors")]
    for page in pages:
        assert (site / f"{page}.html").is_file(), page


def test_no_page_loads_anything_from_another_host(site):
    """The site works offline: no script, stylesheet or image from another host on any page, and
    the equations are typeset by the MathJax copied into the site."""
    from urllib.parse import urlparse

    pages = sorted(site.rglob("*.html"))
    assert len(pages) > 50
    offenders = []
    for page in pages:
        html = page.read_text(encoding="utf-8")
        for tag, attr in (("script", "src"), ("link", "href"), ("img", "src"), ("iframe", "src")):
            for url in re.findall(rf'<{tag}\b[^>]*\b{attr}="([^"]+)"', html):
                if urlparse(url).netloc:
                    offenders.append(f"{page.relative_to(site)}: <{tag}> {url}")
    assert not offenders
    theory = (site / "theory.html").read_text(encoding="utf-8")
    assert re.search(r'<script[^>]*src="_static/mathjax/tex-chtml.js', theory)
    assert (site / "_static" / "mathjax" / "tex-chtml.js").is_file()
    # MathJax's fonts come from beside its script, in the site
    assert list((site / "_static" / "mathjax" / "output" / "chtml" / "fonts").rglob("*.woff"))


def test_every_public_name_has_an_api_page(site):
    """Pages come from ``hertzchain.__all__`` at build time: a name added there gets one unedited."""
    index = (site / "api" / "index.html").read_text()
    for name in hc.__all__:
        if name.startswith("_"):
            continue
        page = site / "api" / "generated" / f"hertzchain.{name}.html"
        assert page.is_file(), name
        assert f"hertzchain.{name}" in _text(page)
        assert f"generated/hertzchain.{name}.html" in index, name


def test_api_pages_show_parameters_with_units(site):
    # Spot checks of the numpydoc rendering: parameter lists with their units in brackets.
    simulate = _text(site / "api" / "generated" / "hertzchain.simulate.html")
    assert "Parameters" in simulate and "Returns" in simulate and "duration" in simulate and "[s]" in simulate
    striker = _text(site / "api" / "generated" / "hertzchain.Striker.html")
    assert "[m/s]" in striker and "[m]" in striker
    assert "[N/m^1.5]" in _text(site / "api" / "generated" / "hertzchain.hertz_constant.html")


def test_conventions_page_covers_each_convention(site):
    text = _text(site / "conventions.html")
    for heading in ("Units", "Bodies and their numbering", "Contacts and their numbering", "Contact law (Hertz)",
                    "Materials", "Striker", "Wall", "Protected body", "Sensors", "Misalignment", "Dissipation",
                    "Precompression", "Gravity", "Elements", "Elastic limit"):
        assert re.search(rf"{re.escape(heading)}\s*#", text), heading


def test_config_reference_lists_every_schema_key(site):
    """The config page's key table is generated from the one schema: no key can be missing."""
    from pydantic import BaseModel

    from hertzchain.config import RunConfig

    text = _text(site / "guide" / "config.html")

    def keys(model, prefix):
        for name, field in model.model_fields.items():
            path = f"{prefix}.{name}" if prefix else name
            yield path
            origin = typing.get_origin(field.annotation)
            inner = {dict: f"{path}.NAME", list: f"{path}[i]"}.get(origin, path)  # as the table writes them
            for arg in (field.annotation, *typing.get_args(field.annotation)):
                if isinstance(arg, type) and issubclass(arg, BaseModel):
                    yield from keys(arg, inner)

    for key in keys(RunConfig, ""):
        assert key in text, key


def test_result_page_lists_every_variable(site):
    from hertzchain.result import COORDINATES, VARIABLES

    text = _text(site / "guide" / "results.html")
    for name in [*VARIABLES, *COORDINATES]:
        assert name in text, name


def test_result_page_describes_every_attribute():
    """Every attribute of a result (a run with a wall, sensors and velocities) is described."""
    model = hc.Model(hc.Chain.uniform(4, 26e-3), hc.Striker(8e-3, 0.1))
    ds = hc.simulate(model, "auto", probes=hc.Probes(sample_interval=1e-6, sensors=(2,), velocities=True))
    page = (DOCS / "guide" / "results.rst").read_text()
    missing = [name for name in ds.attrs if f"``{name}``" not in page]
    assert not missing


def test_nothing_points_to_the_old_design_notes():
    """Conventions live on docs/conventions.rst; no file may send readers to notes outside the repo
    (the CI's own script aside)."""
    old = ("../" + "shared", "DESIGN" + ".md")
    this = Path(__file__).resolve()
    offenders = []
    for top in ("src", "tests", "docs", "examples", "benchmarks", "README.md", "pyproject.toml"):
        path = ROOT / top
        files = [path] if path.is_file() else [p for p in path.rglob("*") if p.is_file()]
        for f in files:
            built = any(p == "_build" or p.endswith(".egg-info") or p == "__pycache__" for p in f.parts)
            if f == this or built or f.suffix in (".png", ".pdf", ".nc", ".pyc", ".json"):
                continue
            text = f.read_text(errors="ignore")
            offenders += [f"{f.relative_to(ROOT)}: {s}" for s in old if s in text]
    assert not offenders


def test_result_conventions_attribute_names_the_conventions_page():
    model = hc.Model(hc.Chain.uniform(3, 26e-3), hc.Striker(8e-3, 0.1))
    ds = hc.simulate(model, "auto", probes=hc.Probes(sample_interval=1e-6))  # the pulse reaches the wall
    text = ds.attrs["conventions"]
    assert "Conventions page" in text and "docs/conventions.rst" in text
    assert (DOCS / "conventions.rst").is_file()


@pytest.mark.slow
def test_gallery_runs_and_makes_its_figures(tmp_path):
    run = _build(tmp_path)
    assert run.returncode == 0, f"sphinx -W failed:\n{run.stdout}\n{run.stderr}"
    scripts = sorted((ROOT / "examples" / "gallery").glob("plot_*.py"))
    assert len(scripts) >= 10
    for script in scripts:
        assert (tmp_path / "html" / "_images" / f"sphx_glr_{script.stem}_001.png").is_file(), script.name


def _readme_block(title: str, lang: str) -> str:
    text = (ROOT / "README.md").read_text()
    section = text.split(f"## {title}", 1)[1]
    return re.search(rf"```{lang}\n(.*?)```", section, re.S).group(1)


@pytest.mark.slow
def test_readme_quick_start_works_as_pasted(tmp_path):
    """Each shell line of the Quick start, run from a copy of the repository layout where
    ``.venv/bin`` is this interpreter's environment; then the Python block."""
    (tmp_path / ".venv").mkdir()
    (tmp_path / ".venv" / "bin").symlink_to(Path(sys.executable).parent)
    shutil.copytree(ROOT / "examples", tmp_path / "examples")
    lines = [ln for ln in _readme_block("Quick start", "bash").splitlines() if ln.strip()]
    assert all(ln.startswith(".venv/bin/hertzchain ") for ln in lines)
    for line in lines:
        run = subprocess.run(line, shell=True, cwd=tmp_path, capture_output=True, text=True, timeout=600,
                             env={**os.environ, "MPLBACKEND": "Agg"})
        assert run.returncode == 0, f"{line}\n{run.stdout}\n{run.stderr}"
    assert (tmp_path / "result.nc").is_file() and (tmp_path / "result.png").is_file()
    assert (tmp_path / "sweep" / "metrics.csv").is_file()
    code = _readme_block("Quick start", "python")
    run = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    assert (tmp_path / "chain1.nc").is_file()
