"""Sphinx configuration of the hertzchain documentation.

Build (from the repository root, after ``pip install -e ".[docs]"``)::

    python -m sphinx -W -b html docs docs/_build/html

``-D plot_gallery=0`` skips running the gallery scripts (the figures are then missing); the test
suite builds that way by default and runs the gallery only with ``-m slow``.

The API reference is generated here from ``hertzchain.__all__`` at every build, so a name added
to the package's public list gets its page without any edit of the docs.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT / "src"))  # a plain checkout builds too (the editable install is preferred)
sys.path.insert(0, str(HERE))  # figure_scraper, named below

import hertzchain  # noqa: E402

project = "hertzchain"
author = "the hertzchain developers"
copyright = "the hertzchain developers"
release = version = hertzchain.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    # MathJax ships with the site (copied into _static/mathjax): the equations render offline.
    "sphinx-mathjax-offline",
    "numpydoc",
    "sphinx_gallery.gen_gallery",
]

exclude_patterns = ["_build", "figure_scraper.py", "**.ipynb_checkpoints", "gallery/*.py", "gallery/*.ipynb", "gallery/*.zip",
                    "gallery/*.md5", "gallery/*.json", "gallery/*.pickle"]
templates_path: list[str] = []
nitpicky = False
root_doc = "index"

# -- API reference -------------------------------------------------------------------------------
autosummary_generate = False  # pages are written below, one per public name
autodoc_typehints = "none"    # the numpydoc sections give the types (with units)
autodoc_member_order = "bysource"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_attributes_as_param_list = False


def _kind(obj) -> str:
    import inspect

    if inspect.isclass(obj):
        return "class"
    if callable(obj):
        return "function"
    return "data"


def _data_doc(name: str) -> str | None:
    """The ``#:`` comment documenting a public constant in the module that defines it."""
    import pkgutil

    from sphinx.pycode import ModuleAnalyzer

    modules = ["hertzchain"] + [m.name for m in pkgutil.walk_packages(hertzchain.__path__, "hertzchain.")]
    for module in modules:
        try:
            docs = ModuleAnalyzer.for_module(module).find_attr_docs()
        except Exception:  # noqa: BLE001 - a module the analyzer cannot read has no doc comments
            continue
        if ("", name) in docs:
            return "\n".join(docs[("", name)]).strip()
    return None


def _write_if_changed(path: Path, text: str) -> None:
    # Rewriting an unchanged page would make Sphinx rebuild it every time; a build stopped
    # half-way leaves no half-written page (atomic replace).
    from hertzchain.fileio import write_text

    if not path.exists() or path.read_text() != text:
        write_text(path, text)


def _generate_api_pages(app) -> None:
    """One page per name of ``hertzchain.__all__`` plus the summary table of the API index."""
    from sphinx.util import logging

    log = logging.getLogger("hertzchain.docs")
    out = HERE / "api" / "generated"
    out.mkdir(parents=True, exist_ok=True)
    names = [n for n in hertzchain.__all__ if not n.startswith("_")]
    wanted = set()
    for name in names:
        obj = getattr(hertzchain, name)
        kind = _kind(obj)
        title = f"hertzchain.{name}"
        if kind == "class":
            body = f".. autoclass:: hertzchain.{name}\n   :members:\n   :show-inheritance:\n"
        elif kind == "function":
            body = f".. autofunction:: hertzchain.{name}\n"
        else:
            doc = _data_doc(name)
            if doc is None:
                log.warning(f"public name hertzchain.{name} has no '#:' doc comment where it is defined")
                doc = ""
            body = f".. data:: hertzchain.{name}\n\n" + "".join(f"   {line}\n" for line in doc.splitlines())
        page = f"{title}\n{'=' * len(title)}\n\n.. currentmodule:: hertzchain\n\n{body}"
        _write_if_changed(out / f"hertzchain.{name}.rst", page)
        wanted.add(f"hertzchain.{name}.rst")
    for stale in out.glob("hertzchain.*.rst"):
        if stale.name not in wanted:
            stale.unlink()
    # One table per defining module, in the order the modules first appear in __all__.
    groups: dict[str, list[str]] = {}
    for name in names:
        module = getattr(getattr(hertzchain, name), "__module__", None) or "hertzchain"
        if not module.startswith("hertzchain."):
            module = _defining_module(name)
        groups.setdefault(".".join(module.split(".")[:2]), []).append(name)
    table = ""
    for module, members in groups.items():
        title = _GROUP_TITLES.get(module, f"``{module}``")
        table += f"{title}\n{'-' * len(title)}\n\n.. autosummary::\n\n" + "".join(f"   {m}\n" for m in members) + "\n"
    _write_if_changed(HERE / "api" / "summary.inc", table)


#: Section titles of the API index, by defining module (a module not listed is titled by its name).
_GROUP_TITLES = {
    "hertzchain.errors": "Errors and warnings",
    "hertzchain.materials": "Materials",
    "hertzchain.contact": "Contact laws",
    "hertzchain.chain": "Chains",
    "hertzchain.elements": "Bead elements",
    "hertzchain.model": "Model",
    "hertzchain.probes": "Probes",
    "hertzchain.runs.simulation": "Running",
    "hertzchain.result": "Results",
    "hertzchain.config": "Configuration files",
    "hertzchain.integrate": "Many chains at once",
    "hertzchain.sweep": "Sweeps",
    "hertzchain.dissipation": "Dissipation",
    "hertzchain.instrument": "Instrument",
    "hertzchain.analysis": "Analysis",
    "hertzchain.theory": "Theory",
    "hertzchain.viz": "Pictures",
    "hertzchain.gradients": "Sensitivities",
    "hertzchain.exporting": "Exporting results (CSV, MATLAB, parquet)",
    "hertzchain.explorer": "Explorer",
}


def _defining_module(name: str) -> str:
    """Module whose source defines a public constant (constants carry no ``__module__``)."""
    exports = getattr(hertzchain, "_EXPORTS", {})
    return f"hertzchain.{exports[name]}" if name in exports else "hertzchain"


_SECTIONS_WITH_NAMES = {"Parameters", "Other Parameters", "Attributes", "Returns", "Yields", "Raises", "Warns"}


def _accept_colon_headers(app, what, name, obj, options, lines) -> None:
    """Read ``name:`` entry lines of numpydoc sections as ``name``.

    Much of the code base writes ``x:`` above the description of parameter ``x``; numpydoc reads
    ``x : type`` or ``x``, and would otherwise take the colon as part of the name. Runs before
    numpydoc (priority 400 < 500), so its validation sees the names.
    """
    import re

    section = None
    for i, line in enumerate(lines):
        nxt = lines[i + 1] if i + 1 < len(lines) else ""
        if line.strip() and re.fullmatch(r"-{3,}", nxt.strip()):
            section = line.strip()
            continue
        if section in _SECTIONS_WITH_NAMES and re.fullmatch(r"[\w*(][\w*, ()\[\]]*:\s*", line):
            lines[i] = line.rstrip()[:-1]


def setup(app) -> None:
    app.connect("autodoc-process-docstring", _accept_colon_headers, priority=400)
    app.connect("builder-inited", _generate_api_pages)
    app.connect("builder-inited", _generate_config_reference)
    app.connect("builder-inited", _generate_result_reference)
    app.connect("builder-inited", _generate_law_reference)
    app.connect("builder-inited", _generate_benchmarks_page)
    app.connect("builder-inited", _generate_test_catalogue)


# Every public function and class documents each parameter (PR01) and what it returns (RT01);
# their methods and attributes are checked only for valid RST.
numpydoc_validation_checks = {"PR01", "RT01"}
numpydoc_validation_exclude = {r"^hertzchain\.\w+\.\w+$"}
# A record (a result, a problem definition) documents its fields under "Attributes" rather than
# as constructor parameters: that satisfies PR01 too.
numpydoc_validation_overrides = {"PR01": [r"\n\s*Attributes\n\s*-{3,}\n"]}

# -- gallery -------------------------------------------------------------------------------------
sphinx_gallery_conf = {
    "examples_dirs": str(ROOT / "examples" / "gallery"),
    "gallery_dirs": "gallery",
    "filename_pattern": r"/plot_",
    "within_subsection_order": "FileNameSortKey",
    "download_all_examples": False,
    "remove_config_comments": True,
    "matplotlib_animations": False,
    # hertzchain's plotting functions draw outside pyplot: figure_scraper saves those too
    "image_scrapers": ("figure_scraper", "matplotlib"),
    "reset_modules": ("matplotlib",),
    # The timing page loads jQuery and DataTables from CDNs: no page of the site may need the network.
    "write_computation_times": False,
}
# Timing pages left by a build with an older configuration would still be built from the source
# tree (they are generated files, git-ignored): remove them so no stale page reaches the network.
for _stale in (HERE / "sg_execution_times.rst", HERE / "gallery" / "sg_execution_times.rst"):
    _stale.unlink(missing_ok=True)

# -- HTML ----------------------------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = f"hertzchain {release}"
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
}
html_sidebars = {"**": ["sidebar-nav-bs"]}
html_static_path = ["_static"]
html_show_sourcelink = False


# -- config reference generated from the one schema (hertzchain.config.RunConfig) ----------------
def _type_text(annotation) -> str:
    """Allowed values of a field, in words, from its type annotation."""
    import types
    import typing

    from pydantic import BaseModel

    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin is typing.Literal:
        return " or ".join(f'``"{a}"``' if isinstance(a, str) else f"``{a}``" for a in args)
    if origin in (typing.Union, types.UnionType):
        parts = [_type_text(a) for a in args if a is not type(None)]
        return " or ".join(parts)
    if origin is list:
        return f"list of {_type_text(args[0])}"
    if origin is dict:
        return f"table of {_type_text(args[1])}"
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return "table"
    return {float: "number", int: "integer", bool: "true/false", str: "string"}.get(annotation, str(annotation))


def _bounds_text(field) -> str:
    words = []
    for m in field.metadata:
        for attr, sym in (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<=")):
            value = getattr(m, attr, None)
            if value is not None:
                words.append(f"{sym} {value:g}")
    return ", ".join(words)


def _schema_rows(model, prefix: str, rows: list) -> None:
    import typing

    from pydantic import BaseModel
    from pydantic_core import PydanticUndefined

    for name, field in model.model_fields.items():
        path = f"{prefix}.{name}" if prefix else name
        annotation = field.annotation
        inner = [a for a in (annotation, *typing.get_args(annotation))
                 if isinstance(a, type) and issubclass(a, BaseModel)]
        allowed = _type_text(annotation)
        bounds = _bounds_text(field)
        if bounds:
            allowed += f" ({bounds})"
        if field.default is PydanticUndefined or field.default_factory is not None:
            default = "required" if field.is_required() else ""
        elif isinstance(field.default, BaseModel):
            default = ""
        elif field.default is None:
            default = "absent"
        else:
            default = f"``{field.default!r}``".replace("'", '"')
        rows.append((f"``{path}``", allowed, default, field.description or ""))
        if inner:
            origin = typing.get_origin(annotation)
            sub = {dict: f"{path}.NAME", list: f"{path}[i]"}.get(origin, path)
            _schema_rows(inner[0], sub, rows)


def _generate_config_reference(app) -> None:
    from hertzchain.config import RunConfig

    rows: list = []
    _schema_rows(RunConfig, "", rows)
    header = ("key", "allowed values", "default", "unit / meaning")
    lines = [".. list-table::", "   :header-rows: 1", "   :widths: 28 32 14 26", ""]
    for row in (header, *rows):
        lines.append(f"   * - {row[0]}")
        lines.extend(f"     - {cell}" for cell in row[1:])
    _write_if_changed(HERE / "guide" / "config_keys.inc", "\n".join(lines) + "\n")


def _generate_law_reference(app) -> None:
    """The table of registered contact laws and their parameters, from their declarations (hertzchain.laws)."""
    from hertzchain.laws import get_law, law_names

    lines = [".. list-table::", "   :header-rows: 1", "   :widths: 18 36 46", "",
             "   * - ``law``", "     - form", "     - parameters (unit, bounds, default)"]
    for name in law_names():
        spec = get_law(name)
        params = []
        for p in spec.params:
            lo, hi = ("(" if p.open_low else "[") + f"{p.low:g}", f"{p.high:g}" + (")" if p.open_high else "]")
            dflt = f", default {p.default:g}" if p.default is not None else (", optional" if p.optional else "")
            params.append(f"``{p.name}`` ({p.unit}, {lo}, {hi}{dflt}): {p.description}")
        lines += [f"   * - ``{name}``", f"     - {spec.title}", f"     - {'; '.join(params) or 'none'}"]
    _write_if_changed(HERE / "guide" / "laws_table.inc", "\n".join(lines) + "\n")


def _generate_result_reference(app) -> None:
    """Tables of the variables and coordinates a result may hold, from ``hertzchain.result``."""
    from hertzchain.result import COORDINATES, VARIABLES

    lines = [".. list-table:: Variables", "   :header-rows: 1", "   :widths: 22 12 66", "",
             "   * - name", "     - units", "     - long_name"]
    for name, (units, long_name) in VARIABLES.items():
        lines += [f"   * - ``{name}``", f"     - {units}", f"     - {long_name}"]
    lines += ["", ".. list-table:: Coordinates", "   :header-rows: 1", "   :widths: 22 12 66", "",
              "   * - name", "     - units", "     - long_name"]
    for name, attrs in COORDINATES.items():
        lines += [f"   * - ``{name}``", f"     - {attrs.get('units', '')}", f"     - {attrs.get('long_name', '')}"]
    _write_if_changed(HERE / "guide" / "result_variables.inc", "\n".join(lines) + "\n")


# -- benchmarks and validation pages, generated from benchmarks/README.md and tests/ --------------
def _inline(text: str) -> str:
    """Markdown inline text -> RST: code spans, bold and links kept, RST markup characters escaped."""
    import re

    out = ""
    parts = re.split(r"(`[^`]*`)", text)
    for i, part in enumerate(parts):
        if i % 2:
            code = part[1:-1]
            if not code.strip():
                out += "\\`" * 2
                continue
            # Inline markup must not touch a word character: separate it with an escaped space.
            glue_before = "\\ " if out[-1:].isalnum() else ""
            glue_after = "\\ " if parts[i + 1][:1].isalnum() else ""
            out += f"{glue_before}``{code}``{glue_after}"
            continue
        part = part.replace("\\", "\\\\")
        links: list[str] = []

        def keep_link(m):
            links.append(f"`{m.group(1)} <{m.group(2)}>`__")
            return f"\x00{len(links) - 1}\x00"

        part = re.sub(r"\[([^\]]+)\]\(([^)\s]+)\)", keep_link, part)
        bold: list[str] = []

        def keep_bold(m):
            bold.append(m.group(1))
            return f"\x01{len(bold) - 1}\x01"

        part = re.sub(r"\*\*([^*]+)\*\*", keep_bold, part)
        for ch in "*_|`":
            part = part.replace(ch, "\\" + ch)

        def put_bold(m):
            before = "\\ " if m.group(1) else ""
            after = "\\ " if m.group(3) else ""
            return f"{m.group(1)}{before}**{bold[int(m.group(2))].replace(chr(92), '')}**{after}{m.group(3)}"

        part = re.sub(r"(\w?)\x01(\d+)\x01(\w?)", put_bold, part)
        part = re.sub(r"\x00(\d+)\x00", lambda m: links[int(m.group(1))], part)
        out += part
    return out


def _markdown_to_rst(md: str, skip_title: bool = True) -> str:
    """The subset of Markdown that benchmarks/README.md uses: headings, paragraphs, lists,
    fenced code and pipe tables."""
    import re

    lines, out, i = md.splitlines(), [], 0
    underline = {2: "-", 3: "~", 4: "^"}
    while i < len(lines):
        line = lines[i]
        if line.startswith("```"):
            lang = line[3:].strip() or "text"
            body = []
            i += 1
            while i < len(lines) and not lines[i].startswith("```"):
                body.append(lines[i])
                i += 1
            out += [f".. code-block:: {lang}", ""] + [f"   {b}" for b in body] + [""]
            i += 1
            continue
        m = re.match(r"(#+)\s+(.*)", line)
        if m:
            level = len(m.group(1))
            if level == 1 and skip_title:
                i += 1
                continue
            title = _inline(m.group(2))
            out += [title, underline.get(level, "^") * len(title), ""]
            i += 1
            continue
        if line.startswith("|"):
            rows = []
            while i < len(lines) and lines[i].startswith("|"):
                cells = [c.strip() for c in lines[i].strip().strip("|").split("|")]
                if not all(re.fullmatch(r":?-+:?", c) for c in cells):
                    rows.append(cells)
                i += 1
            out += [".. list-table::", "   :header-rows: 1", ""]
            for row in rows:
                out.append(f"   * - {_inline(row[0])}")
                out += [f"     - {_inline(c)}" for c in row[1:]]
            out.append("")
            continue
        m = re.match(r"(\s*)[-*]\s+(.*)", line)
        if m and not m.group(1):
            item = [m.group(2)]
            i += 1
            while i < len(lines) and lines[i].startswith("  ") and not re.match(r"\s*[-*]\s", lines[i]):
                item.append(lines[i].strip())
                i += 1
            out.append("- " + _inline(" ".join(item)))
            # nested items
            while i < len(lines) and re.match(r"\s+[-*]\s+", lines[i]):
                sub = [re.sub(r"^\s+[-*]\s+", "", lines[i])]
                i += 1
                while i < len(lines) and lines[i].startswith("    ") and not re.match(r"\s*[-*]\s", lines[i]):
                    sub.append(lines[i].strip())
                    i += 1
                out += ["", "  - " + _inline(" ".join(sub))]
            if i < len(lines) and re.match(r"[-*]\s", lines[i]):
                continue
            out.append("")
            continue
        if not line.strip():
            out.append("")
            i += 1
            continue
        para = []
        while i < len(lines) and lines[i].strip() and not re.match(r"(#|```|\||[-*]\s)", lines[i]):
            para.append(lines[i].strip())
            i += 1
        out += [_inline(" ".join(para)), ""]
    return "\n".join(out) + "\n"


def _generate_benchmarks_page(app) -> None:
    readme = ROOT / "benchmarks" / "README.md"
    text = readme.read_text() if readme.exists() else "No benchmarks in this tree.\n"
    figure = ROOT / "benchmarks" / "results" / "scaling.png"
    if figure.exists():
        text += ("\n## Scaling figure\n\n`benchmarks/results/scaling.png` from the latest `compare.py` run: "
                 "ns per bead-step against chain length and against batch size.\n")
    rst = _markdown_to_rst(text)
    if figure.exists():
        rst += "\n.. image:: ../benchmarks/results/scaling.png\n   :width: 100%\n"
    _write_if_changed(HERE / "benchmarks_readme.inc", rst)


def _generate_test_catalogue(app) -> None:
    """Every test module of tests/: its docstring and each test with its docstring's first line."""
    import ast

    out = []
    for path in sorted((ROOT / "tests").glob("test_*.py")):
        tree = ast.parse(path.read_text())
        doc = ast.get_docstring(tree) or ""
        title = f"``tests/{path.name}``"
        out += [title, "~" * len(title), ""]
        if doc:
            out += [_inline(" ".join(doc.split("\n\n")[0].split())), ""]
        for node in tree.body:
            tests = []
            if isinstance(node, ast.FunctionDef) and node.name.startswith("test_"):
                tests = [node]
            elif isinstance(node, ast.ClassDef) and node.name.startswith("Test"):
                tests = [n for n in node.body if isinstance(n, ast.FunctionDef) and n.name.startswith("test_")]
            for fn in tests:
                slow = any("slow" in ast.unparse(d) for d in fn.decorator_list) or any(
                    "slow" in ast.unparse(d) for d in getattr(node, "decorator_list", []))
                first = (ast.get_docstring(fn) or "").split("\n\n")[0]
                line = f"- ``{fn.name}``" + (" (slow)" if slow else "")
                if first:
                    line += ": " + _inline(" ".join(first.split()))
                out.append(line)
        out.append("")
    _write_if_changed(HERE / "validation_tests.inc", "\n".join(out) + "\n")
