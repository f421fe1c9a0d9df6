"""Reading a run file: TOML text, dotted field paths (``chain.diameters_mm[3]``) and the
``--set DOTTED.PATH=VALUE`` overrides applied before validation (also used by sweep and design
files, whose ``[base]`` is a run config).
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from ..errors import ConfigError
from .schema import RunConfig, parse_config


def read_toml(path: str | Path, what: str = "config file") -> dict:
    """Read a TOML file; a missing file or bad TOML is a ConfigError naming the path."""
    path = Path(path)
    try:
        text = path.read_bytes().decode("utf-8")
    except OSError as exc:
        raise ConfigError(str(path), f"cannot read the {what}: {exc.strerror}") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(str(path), f"is not UTF-8 text (byte {exc.start} cannot be decoded); "
                          f"a {what} is a TOML text file saved as UTF-8") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(str(path), f"is not valid TOML: {exc}") from None


_TOKEN = re.compile(r"([^.\[\]]+)|\[(\d+)\]")


def parse_path(path: str) -> list[str | int]:
    """``"chain.diameters_mm[3]"`` -> ``["chain", "diameters_mm", 3]``; ValueError when malformed."""
    tokens: list[str | int] = []
    pos = 0
    for m in _TOKEN.finditer(path):
        gap = path[pos:m.start()]
        if gap not in ("", "."):
            raise ValueError
        tokens.append(m.group(1) if m.group(1) is not None else int(m.group(2)))
        pos = m.end()
    if pos != len(path) or not tokens or not isinstance(tokens[0], str) or path.endswith("."):
        raise ValueError
    return tokens


def set_path(cfg: dict, tokens: list[str | int], value: Any, name: str) -> None:
    """Set ``value`` at ``tokens`` (from a dotted path) in ``cfg``; missing tables are created.

    Shared by sweeps and the design search; a path that does not fit the base config is a
    ConfigError naming ``name`` (the field as the user wrote it).
    """
    node: Any = cfg
    for tok, nxt in zip(tokens[:-1], tokens[1:]):
        if isinstance(tok, int):
            if not isinstance(node, list) or tok >= len(node):
                raise ConfigError(name, f"index [{tok}] is outside the base list")
            node = node[tok]
        else:
            if not isinstance(node, dict):
                raise ConfigError(name, f"'{tok}' is not inside a table of the base config")
            if tok not in node:
                if isinstance(nxt, int):
                    raise ConfigError(name, f"the base config has no list '{tok}' to index")
                node[tok] = {}
            node = node[tok]
    last = tokens[-1]
    if isinstance(last, int):
        if not isinstance(node, list) or last >= len(node):
            raise ConfigError(name, f"index [{last}] is outside the base list")
    elif not isinstance(node, dict):
        raise ConfigError(name, f"'{last}' is not inside a table of the base config")
    node[last] = value


def apply_overrides(data: dict, assignments: Iterable[str], prefix: str = "") -> dict:
    """Apply ``--set DOTTED.PATH=VALUE`` assignments to a config mapping read from TOML.

    Parameters
    ----------
    data : dict
        The mapping as read from the TOML file (left unchanged; a changed copy is returned).
    assignments : iterable of str
        ``"striker.velocity=0.3"``, ``"chain.taper={n = 30, q = 0.05}"``, ``"probes.sensors=[8, 12]"``.
        VALUE is read as exactly one TOML value (so ``0.3`` is a number, ``"elastic"`` or a bare
        word a string; anything after the value, such as a table, is refused); list items are
        addressed as ``key[i]``.
    prefix : str
        Section the paths are relative to (``"base"`` for sweep and design files).

    Returns
    -------
    dict
        The new mapping, to be validated by the same schema as the file itself.
    """
    import copy

    out = copy.deepcopy(data)
    for item in assignments:
        if "=" not in item:
            raise ConfigError("--set", f"{item!r} is not DOTTED.PATH=VALUE (e.g. striker.velocity=0.3)")
        path, raw = (part.strip() for part in item.split("=", 1))
        try:
            parsed = tomllib.loads(f"v = {raw}")
        except tomllib.TOMLDecodeError:
            parsed = None
        if parsed is not None and set(parsed) != {"v"}:
            # "0.3\n[run]\nduration = 9" parses as a value and a table: the rest would be dropped.
            raise ConfigError(f"--set {path}", f"takes exactly one TOML value, got {raw!r} (more keys or tables "
                              "after the value); give one --set per field")
        if parsed is not None:
            value = parsed["v"]
        elif "\n" in raw or "\r" in raw:
            raise ConfigError(f"--set {path}", f"takes exactly one TOML value on one line, got {raw!r}")
        else:
            value = raw  # a bare word such as elastic: a string
        try:
            tokens = parse_path(path)
        except ValueError:
            raise ConfigError(f"--set {path}", "is not a dotted field path (names joined by '.', list items "
                              "as key[i])") from None
        set_path(out, [*([prefix] if prefix else []), *tokens], value, f"--set {path}")
    return out


def load_config(path: str | Path, overrides: Iterable[str] = ()) -> RunConfig:
    """Read and validate a TOML run file, after applying ``--set`` overrides (:func:`apply_overrides`).

    Parameters
    ----------
    path : str or pathlib.Path
        The TOML run file (sections and keys: the user guide's "Configuration files" page).
    overrides : iterable of str
        ``DOTTED.PATH=VALUE`` assignments applied before validation (``"striker.velocity=0.3"``,
        value in the key's own unit).

    Returns
    -------
    RunConfig
        The validated config.

    Raises
    ------
    ConfigError
        Naming the first bad field (``chain.diameters_mm[3]``), what was wrong and what is allowed.
    """
    return parse_config(apply_overrides(read_toml(path), overrides))
