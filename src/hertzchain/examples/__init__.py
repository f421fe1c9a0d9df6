"""The example configs and scope records shipped with the package (``hertzchain example NAME``).

The same files as the repository's ``examples/`` folder (``tests/test_packaging.py`` checks that the
two copies agree), here as package data so that an installed wheel carries them: a user without a
clone gets one with ``hertzchain example chain1 > chain1.toml``.
"""

from __future__ import annotations

from importlib import resources
from typing import TYPE_CHECKING

from ..errors import ConfigError

if TYPE_CHECKING:
    from importlib.resources.abc import Traversable

__all__ = ["example_names", "example_summary", "example_text"]

#: File suffixes of the shipped examples: run configs and oscilloscope records.
_SUFFIXES = (".toml", ".csv")


def _files() -> dict[str, Traversable]:
    """The shipped examples by name (file name without its suffix)."""
    root = resources.files(__name__)
    return {p.name.rsplit(".", 1)[0]: p for p in root.iterdir()
            if p.is_file() and p.name.endswith(_SUFFIXES)}


def example_names() -> list[str]:
    """Names of the shipped examples, sorted (``chain1``, ``contract``, ``scope``...)."""
    return sorted(_files())


def example_text(name: str) -> str:
    """The text of the shipped example ``name`` (a TOML config or a CSV scope record).

    Raises
    ------
    ConfigError
        (field ``NAME``) for a name that is not shipped, listing those that are.
    """
    files = _files()
    if name not in files:
        raise ConfigError("NAME", f"no example {name!r}; the package ships: {', '.join(sorted(files))}")
    return files[name].read_text(encoding="utf-8")


def example_summary(name: str) -> str:
    """The first line of the example's leading comment (what it is), or "" when it has none."""
    for line in example_text(name).splitlines():
        if line.startswith("#"):
            return line.lstrip("#").strip()
        if line.strip():
            break
    return ""
