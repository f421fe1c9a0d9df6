"""The house rules of the package layout (docs/architecture.rst), checked from the code itself.

- Imports point down: no circle among the modules of ``src/hertzchain``, counting imports inside
  functions (a deferred import is still a dependency).
- No module longer than 700 lines.
- The command line: ``cli/main.py`` registers the commands; no command module imports another
  command module or ``main``.
- The layer contracts of ``pyproject.toml`` (``[tool.importlinter]``) hold, run by import-linter,
  and the architecture page names each of them.
- ``ruff check src`` is clean (where ruff is installed), and so is ``mypy`` (slow set).
"""

from __future__ import annotations

import ast
import importlib.util
import os
import subprocess
import sys
import textwrap
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "hertzchain"
PACKAGE = SRC.name
MAX_LINES = 700


def _modules() -> dict[str, tuple[Path, bool]]:
    """Dotted module name -> (file, is a package's __init__)."""
    out = {}
    for path in sorted(SRC.rglob("*.py")):
        parts = list(path.relative_to(SRC.parent).with_suffix("").parts)
        is_package = parts[-1] == "__init__"
        if is_package:
            parts = parts[:-1]
        out[".".join(parts)] = (path, is_package)
    return out


def _targets(module: str, is_package: bool, node: ast.Import | ast.ImportFrom) -> list[str]:
    """Absolute names an import statement may load (``from . import x`` may load module ``.x``)."""
    if isinstance(node, ast.Import):
        return [alias.name for alias in node.names]
    if node.level:
        base = module.split(".")
        if not is_package:
            base = base[:-1]
        base = base[: len(base) - (node.level - 1)]
        target = ".".join(base + ([node.module] if node.module else []))
    else:
        target = node.module or ""
    return [target] + [f"{target}.{alias.name}" for alias in node.names]


def import_graph() -> dict[str, set[str]]:
    """Module -> the package's modules it imports (anywhere in its body, functions included).

    An import resolves to the longest existing module name it starts with. A module's own parent
    packages are left out: importing ``a.b.c`` always runs ``a/__init__`` and ``a/b/__init__``
    first, whatever ``c`` imports, so such an edge is no circle of the layout.
    """
    modules = _modules()
    graph: dict[str, set[str]] = {}
    for name, (path, is_package) in modules.items():
        deps: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
            if not isinstance(node, (ast.Import, ast.ImportFrom)):
                continue
            for target in _targets(name, is_package, node):
                parts = target.split(".")
                if parts[0] != PACKAGE:
                    continue
                while parts and ".".join(parts) not in modules:
                    parts.pop()
                if parts:
                    deps.add(".".join(parts))
        graph[name] = {d for d in deps if d != name and not name.startswith(d + ".")}
    return graph


def strongly_connected(graph: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's algorithm (iterative): the components with more than one module, or a self-loop."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    counter = 0
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            for child in children:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    component = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        component.append(member)
                        if member == node:
                            break
                    if len(component) > 1:
                        found.append(sorted(component))
    return found


def test_the_checker_finds_a_circle_and_a_clean_chain():
    assert strongly_connected({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert strongly_connected({"a": {"b"}, "b": {"c"}, "c": set()}) == []


def test_relative_imports_resolve_to_modules_of_the_package():
    graph = import_graph()
    # A known edge of each kind: a top-level import and a deferred one inside a function.
    assert "hertzchain.chain" in graph["hertzchain.model"]
    assert any(deps for deps in graph.values())
    assert all(dep in graph for deps in graph.values() for dep in deps)


def test_no_import_circle_in_the_package():
    circles = strongly_connected(import_graph())
    assert circles == [], "import circles (each list is one strongly connected component): " + "; ".join(
        " <-> ".join(c) for c in circles)


def test_no_module_is_longer_than_700_lines():
    long = {str(path.relative_to(SRC)): n for path, _ in _modules().values()
            if (n := len(path.read_text(encoding="utf-8").splitlines())) > MAX_LINES}
    assert long == {}, f"modules over {MAX_LINES} lines: {long}"


def test_cli_commands_import_only_the_shared_helpers():
    graph = import_graph()
    commands = [m for m in graph if m.startswith(f"{PACKAGE}.cli.") and m.split(".")[-1] not in ("main", "common", "__main__")]
    assert commands, "no command modules found under hertzchain/cli/"
    for module in commands:
        cli_deps = {d for d in graph[module] if d.startswith(f"{PACKAGE}.cli.")}
        assert cli_deps <= {f"{PACKAGE}.cli.common"}, f"{module} imports {sorted(cli_deps)}"


def _lint_imports(root: Path, config: str) -> subprocess.CompletedProcess:
    """import-linter on ``root/config``, importing the package from ``root/src`` (this tree).

    import-linter is required (the test extra), not skipped: the layers are a house rule."""
    assert importlib.util.find_spec("importlinter") is not None, "import-linter is missing: pip install -e .[test]"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(root / "src"), *filter(None, [os.environ.get("PYTHONPATH")])]))
    code = ("import sys; from importlinter.cli import lint_imports; "
            f"sys.exit(lint_imports(config_filename={config!r}, no_cache=True, no_logo=True))")
    return subprocess.run([sys.executable, "-c", code], cwd=root, env=env, capture_output=True,
                          text=True, timeout=300)


def test_import_linter_reports_an_import_that_runs_up_a_layer(tmp_path):
    package = tmp_path / "src" / "toy"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "high.py").write_text("")
    (package / "low.py").write_text("def f():\n    from . import high  # deferred: still counts\n")
    (tmp_path / "pyproject.toml").write_text(textwrap.dedent("""\
        [tool.importlinter]
        root_package = "toy"
        [[tool.importlinter.contracts]]
        name = "toy layers"
        type = "layers"
        layers = ["toy.high", "toy.low"]
        """))
    run = _lint_imports(tmp_path, "pyproject.toml")
    assert run.returncode != 0 and "BROKEN" in run.stdout, run.stdout + run.stderr
    assert "toy.low -> toy.high" in run.stdout


def test_the_layer_contracts_hold():
    run = _lint_imports(ROOT, "pyproject.toml")
    assert run.returncode == 0, run.stdout + run.stderr
    assert "0 broken" in run.stdout


def test_the_architecture_page_lists_the_contracts_the_test_enforces():
    contracts = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))[
        "tool"]["importlinter"]["contracts"]
    page = (ROOT / "docs" / "architecture.rst").read_text(encoding="utf-8")
    assert {c["id"] for c in contracts} == {"layers", "runs", "engine", "engine-entries"}
    for contract in contracts:
        assert contract["name"] in page, f"docs/architecture.rst does not name {contract['name']!r}"
    # Every layer's modules are drawn on the page, as hertzchain.X or X/ or X.py (the layers inside
    # runs/ and integrate/ by their file or folder name).
    for contract in (c for c in contracts if c["type"] == "layers"):
        for layer in contract["layers"]:
            for module in (m.strip().strip("()") for m in layer.split("|")):  # (optional layer)
                tail = module.removeprefix("hertzchain.").replace(".", "/")
                if contract["id"] != "layers":
                    tail = tail.rsplit("/", 1)[1]
                assert f"{tail}/" in page or f"{tail}.py" in page, f"{module} missing from the page"


def test_ruff_finds_nothing_in_src():
    if importlib.util.find_spec("ruff") is None:
        pytest.skip("ruff is not installed (pip install -e .[test])")
    run = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache", "src"], cwd=ROOT,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout + run.stderr


@pytest.mark.slow  # 26 s of CPU from an empty cache (27-45 s wall on 2 shared cores): mypy reads the stubs first
def test_mypy_finds_nothing_in_src(tmp_path):
    """``mypy`` as configured in ``[tool.mypy]`` (all of ``src/hertzchain``, no error code or module
    switched off) reports no error."""
    if importlib.util.find_spec("mypy") is None:
        pytest.skip("mypy is not installed (pip install -e .[test])")
    run = subprocess.run([sys.executable, "-m", "mypy", "--cache-dir", str(tmp_path / "cache")], cwd=ROOT,
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "Success: no issues found" in run.stdout, run.stdout
