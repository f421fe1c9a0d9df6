"""No module outside ``hertzchain/laws/`` compares a contact law's name: it asks the registry.

An AST scan of every module of the package: a comparison (==, !=, in, not in) with a string
literal that names a registered law, or with a tuple/list/set of such literals, is a law-name
comparison; the law's spec (``hertzchain.laws.spec_of(law).dissipative`` ...) says instead what
the comparison wanted to know, so that a new law (a user's) is handled everywhere at once.
"""

from __future__ import annotations

import ast
from pathlib import Path

import hertzchain
from hertzchain.laws import law_names

PACKAGE = Path(hertzchain.__file__).parent


def _names_in(node: ast.AST, names: set[str]) -> list[str]:
    if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in names:
        return [node.value]
    if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
        return [x for elt in node.elts for x in _names_in(elt, names)]
    return []


#: Law names that are also ordinary words ("power" is a design-space scale too): a comparison
#: with them counts only when the other side's code mentions a law.
AMBIGUOUS = {"elastic", "power"}


def law_name_comparisons(source: str, names: set[str]) -> list[tuple[int, str]]:
    """(line, law name) of every comparison of ``source`` against a law-name literal."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Compare) and any(isinstance(op, (ast.Eq, ast.NotEq, ast.In, ast.NotIn))
                                                 for op in node.ops):
            sides = [node.left, *node.comparators]
            about_law = any("law" in ast.unparse(side).lower() for side in sides)
            for side in sides:
                found += [(node.lineno, n) for n in _names_in(side, names) if about_law or n not in AMBIGUOUS]
    return found


def test_the_scan_finds_a_law_name_comparison():
    names = set(law_names())
    src = ("if law.name == 'elastoplastic':\n    pass\nok = kind in ('dashpot', 'x')\nfine = law == 'other'\n"
           "scale = kind == 'power'\nbad = cfg.law == 'power'\n")
    assert law_name_comparisons(src, names) == [(1, "elastoplastic"), (3, "dashpot"), (6, "power")]


def test_no_module_outside_the_registry_compares_a_law_name():
    names = set(law_names())
    offenders = []
    for path in sorted(PACKAGE.rglob("*.py")):
        if (PACKAGE / "laws") in path.parents:
            continue
        for line, name in law_name_comparisons(path.read_text(encoding="utf-8"), names):
            offenders.append(f"{path.relative_to(PACKAGE)}:{line} compares {name!r}")
    assert not offenders, "ask hertzchain.laws instead:\n" + "\n".join(offenders)
