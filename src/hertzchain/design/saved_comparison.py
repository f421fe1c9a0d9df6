"""The comparison of a finished design with its references, kept beside the checkpoint.

:func:`hertzchain.design.report.compare_with_references` runs the best design, the base
configuration, the uniform chain and no chain (every robust scenario of each, then their nominal
records in one more engine call). A rerun of a finished search into the same ``--out`` replays
it without an engine run (:mod:`hertzchain.design.checkpoint`) to the same best, and its report
reads the comparison back from ``comparison.npz`` instead of running it again.

The file is read as data, like the checkpoint: a NumPy ``.npz`` archive read with
:func:`hertzchain.received.load_npz` (a regular file of the folder, no pickle, each member's
header checked before it is allocated) holding a JSON document ``meta`` (what it was computed
for: the problem's hash, the best configuration and the hertzchain version; the comparison
table; and the records' layout: every variable's dimensions, attributes and member) and one
array of plain numbers per variable of the records, each checked against its dimensions. One
computed for another best or version, or damaged, is not used: the comparison is run again and
the file rewritten (nothing is set aside: it holds no work that the rerun does not redo).
"""

from __future__ import annotations

import hashlib
import io
import json
import warnings
from typing import Any

import numpy as np

from ..errors import CheckpointWarning

__all__ = ["COMPARISON_FILE", "comparison_key", "read_comparison", "write_comparison"]

COMPARISON_FILE = "comparison.npz"
_FORMAT = "hertzchain design comparison"
#: Version of the file's layout (another is recomputed, not guessed at).
SCHEMA = 1


def _plain(x: Any) -> Any:
    """JSON values of NumPy scalars and arrays; NaN and infinities as JSON's extended literals."""
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    raise TypeError(f"{type(x).__name__} cannot be written to {COMPARISON_FILE}")


def comparison_key(result) -> str:
    """What a comparison was computed for: SHA-256 of the problem's hash, the best candidate's
    configuration and the hertzchain version (a finished search replays to the same best)."""
    from .. import __version__

    text = json.dumps({"problem": result.problem.hash, "best": result.best["config"], "hertzchain": __version__},
                      sort_keys=True, default=_plain, allow_nan=True)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def write_comparison(out, key: str, comparison: dict, ds) -> None:
    """Save ``comparison`` and the nominal records ``ds`` (numeric variables only) in ``out`` (atomically).

    Parameters
    ----------
    out : pathlib.Path
        The design's output folder.
    key : str
        :func:`comparison_key` of the search.
    comparison : dict
        :func:`~hertzchain.design.report.compare_with_references`' table.
    ds : xarray.Dataset
        Its nominal records.
    """
    from ..fileio import write_bytes

    layout, arrays = {}, {}
    for i, (name, var) in enumerate(ds.variables.items()):
        values = np.asarray(var.values)
        if values.dtype.kind not in "biuf":
            continue  # the report reads numbers only
        arrays[f"v{i}"] = values
        layout[str(name)] = {"member": f"v{i}", "dims": [str(d) for d in var.dims], "attrs": dict(var.attrs),
                             "coordinate": name in ds.coords}
    meta = {"format": _FORMAT, "schema": SCHEMA, "key": key, "comparison": comparison, "variables": layout,
            "attrs": dict(ds.attrs)}
    text = json.dumps(meta, default=_plain, allow_nan=True, separators=(",", ":"))
    buf = io.BytesIO()
    document = np.frombuffer(text.encode("utf-8"), np.uint8)
    np.savez(buf, meta=document, **arrays)  # type: ignore[arg-type]  # NumPy's stub: **arrays vs allow_pickle: bool
    write_bytes(out / COMPARISON_FILE, buf.getvalue())


def _check(ok: object, what: str) -> None:
    if not ok:
        raise ValueError(what)


def _attrs(raw: Any, where: str) -> dict:
    _check(isinstance(raw, dict) and all(isinstance(k, str) for k in raw), f"{where}: attributes are a table")
    for k, v in raw.items():
        flat = v if isinstance(v, list) else [v]
        _check(all(v is None or isinstance(v, (int, float, str, bool)) for v in flat), f"{where}.{k} is a number "
               "or a name (or a list of them)")
    return raw


def read_comparison(out, key: str, objectives: list[str]):
    """The comparison saved in ``out`` for the search of ``key``, or None (none, another search's, damaged).

    Parameters
    ----------
    out : pathlib.Path
        The design's output folder.
    key : str
        :func:`comparison_key` of the search.
    objectives : list of str
        The design's objectives (each reference's values are checked).

    Returns
    -------
    (dict, xarray.Dataset) or None
        The comparison table and the nominal records, as
        :func:`~hertzchain.design.report.compare_with_references` returned them.
    """
    import os

    import xarray as xr

    from ..errors import ConfigError
    from ..received import load_npz

    path = out / COMPARISON_FILE
    if not os.path.lexists(path):
        return None
    try:
        files = load_npz(path, out)
        raw = files.pop("meta", None)
        _check(raw is not None and raw.dtype == np.uint8 and raw.ndim == 1, "no 'meta' document")
        assert raw is not None  # (_check raised otherwise)
        meta = json.loads(raw.tobytes().decode("utf-8"))
        _check(isinstance(meta, dict) and meta.get("format") == _FORMAT and meta.get("schema") == SCHEMA,
               "not a design comparison of this layout")
        if meta.get("key") != key:
            return None  # another best, problem or version: computed again
        cmp = meta.get("comparison")
        _check_comparison(cmp, objectives)
        layout = meta.get("variables")
        _check(isinstance(layout, dict) and layout, "no records")
        sizes: dict[str, int] = {}
        variables: dict[str, xr.Variable] = {}
        coords: dict[str, xr.Variable] = {}
        for name, spec in layout.items():
            where = f"variables.{name}"
            _check(isinstance(spec, dict) and isinstance(spec.get("member"), str), f"{where} names no member")
            dims = spec.get("dims")
            _check(isinstance(dims, list) and all(isinstance(d, str) for d in dims), f"{where}.dims are names")
            arr = files.get(spec["member"])
            _check(arr is not None and arr.ndim == len(dims), f"{where}: its array is missing or not {len(dims)}-D")
            assert arr is not None  # (_check raised otherwise)
            for d, n in zip(dims, arr.shape):
                _check(sizes.setdefault(d, n) == n, f"{where}: dimension {d} is {n} long, elsewhere {sizes[d]}")
            var = xr.Variable(dims, arr, attrs=_attrs(spec.get("attrs"), where))
            (coords if spec.get("coordinate") is True else variables)[name] = var
        ds = xr.Dataset(variables, coords=coords, attrs=_attrs(meta.get("attrs"), "attrs"))
    except (ConfigError, ValueError, UnicodeDecodeError, RecursionError, TypeError) as exc:
        # damaged or foreign: said, and the comparison is run again (the file rewritten)
        warnings.warn(CheckpointWarning(f"{path}: is damaged or not a design comparison ({exc}); the comparison "
                                        "with the references is run again"), stacklevel=3)
        return None
    return cmp, ds


def _check_comparison(cmp: Any, objectives: list[str]) -> None:
    """The table :func:`~hertzchain.design.report.compare_with_references` writes, field by field."""
    def number(v: Any) -> bool:
        return isinstance(v, (int, float)) and not isinstance(v, bool)

    _check(isinstance(cmp, dict) and isinstance(cmp.get("best"), dict), "its comparison has no best design")
    refs = [k for k in cmp if k != "improvement_percent"]
    _check(set(refs) <= {"best", "base", "uniform", "no_chain"}, f"its comparison names {refs}")
    for ref in refs:
        row = cmp[ref]
        _check(isinstance(row, dict), f"comparison.{ref} is not a table")
        for n in objectives:
            _check(row.get(n) is None or number(row[n]), f"comparison.{ref}.{n} is not a number")
        _check(number(row.get("n_beads")) and number(row.get("length_mm")), f"comparison.{ref}: no size")
        _check(all(isinstance(row.get(k), bool) for k in ("pulse_at_wall", "feasible")),
               f"comparison.{ref}: feasible and pulse_at_wall are true or false")
        _check(isinstance(row.get("breaks"), list) and all(isinstance(b, str) for b in row["breaks"]),
               f"comparison.{ref}.breaks is not a list of sentences")
    imp = cmp.get("improvement_percent")
    _check(isinstance(imp, dict) and all(r in refs and isinstance(v, dict) and
                                         all(v.get(n) is None or number(v[n]) for n in objectives)
                                         for r, v in imp.items()), "comparison.improvement_percent is damaged")
