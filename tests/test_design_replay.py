"""A finished design search rerun into the same --out replays with no engine run, the report
included (issue 38 item 2): the comparison with the references is read back from comparison.npz
(data: checked like every received file), so design.json and design.html's signals are those of
the first run; a damaged or foreign comparison file is named and the comparison run again."""

from __future__ import annotations

import json
import re
import warnings

import numpy as np
import pytest

from hertzchain.design import parse_design, run_design, write_report
from hertzchain.design.report import compare_with_references
from hertzchain.design.saved_comparison import COMPARISON_FILE, comparison_key, read_comparison
from hertzchain.errors import CheckpointWarning
from hertzchain.runs import batch

DESIGN = {"base": {"chain": {"uniform": {"n": 4, "diameter_mm": 26.0}, "taper": {"n": 4, "q": 0.05}},
                   "striker": {"diameter_mm": 8.0, "velocity": 0.2},
                   "run": {"duration": 2.5e-3, "sample_interval": 1e-6}},
          "design": {"objective": "peak_wall_force", "variables": {"chain.taper.q": [0.0, 0.12]},
                     "budget": 24, "population": 6, "seed": 2, "polish": False}}


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    out = tmp_path_factory.mktemp("design")
    res = run_design(parse_design(DESIGN), out)
    info = write_report(res)
    return out, info, (out / "design.html").read_text()


@pytest.fixture
def engine_runs(monkeypatch):
    """Calls of the engine's entries (the batched engine: every design and comparison run)."""
    calls = []
    for name in ("run_batch", "simulate_batch"):
        real = getattr(batch, name)

        def counted(*a, _real=real, _name=name, **k):
            calls.append(_name)
            return _real(*a, **k)

        monkeypatch.setattr(batch, name, counted)
    return calls


def _images(page: str) -> list[str]:
    return re.findall(r'src="data:image/png;base64,([^"]+)"', page)


def test_a_finished_search_replays_with_no_engine_run_and_the_same_report(finished, engine_runs):
    out, info, page = finished
    res = run_design(parse_design(DESIGN), out)
    again = write_report(res)
    assert res.resumed and engine_runs == []
    assert again["comparison"] == info["comparison"] and again["best"] == info["best"]
    new_page = (out / "design.html").read_text()
    assert re.findall(r"<h2>([^<]*)</h2>", new_page) == re.findall(r"<h2>([^<]*)</h2>", page)
    assert _images(new_page) == _images(page)  # the same records drawn, pixel for pixel


def test_the_saved_records_are_the_comparisons(finished):
    """What comparison.npz gives back is what compare_with_references computes: the table and every
    numeric variable of the nominal records, bit for bit (the same engine path)."""
    out, info, _ = finished
    res = run_design(parse_design(DESIGN), out)
    cmp, ds = compare_with_references(res)
    saved = read_comparison(out, comparison_key(res), res.problem.objectives)
    assert saved is not None
    assert json.loads(json.dumps(cmp)) == saved[0]
    for name, var in ds.variables.items():
        if var.dtype.kind in "biuf":
            np.testing.assert_array_equal(saved[1][name].values, var.values)
            assert saved[1][name].dims == var.dims


def _edited(path, edit) -> None:
    """Rewrite comparison.npz with its JSON document edited by ``edit(meta)`` (a valid archive)."""
    with np.load(path, allow_pickle=False) as f:
        arrays = {k: f[k] for k in f.files}
    meta = json.loads(arrays.pop("meta").tobytes())
    edit(meta)
    np.savez(path, meta=np.frombuffer(json.dumps(meta).encode(), np.uint8), **arrays)


@pytest.mark.parametrize("damage, reason", [
    (lambda p: p.write_bytes(b"PK\x03\x04 not really"), "not a NumPy .npz archive"),
    (lambda p: _edited(p, lambda m: m["comparison"]["base"].update(feasible=1)),
     "feasible and pulse_at_wall are true or false"),
    (lambda p: _edited(p, lambda m: m["variables"]["wall_force"].update(dims=["member"])),
     "variables.wall_force: its array is missing or not 1-D"),
])
def test_a_damaged_comparison_is_named_and_run_again(finished, tmp_path, damage, reason, engine_runs):
    out, info, _ = finished
    import shutil

    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    damage(copy / COMPARISON_FILE)
    res = run_design(parse_design(DESIGN), copy)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        again = write_report(res, figures=False)
    said = [str(w.message) for w in caught if issubclass(w.category, CheckpointWarning)]
    assert len(said) == 1 and reason in said[0] and COMPARISON_FILE in said[0]
    assert again["comparison"] == info["comparison"] and engine_runs  # run again, the same numbers
    assert read_comparison(copy, comparison_key(res), res.problem.objectives) is not None  # rewritten
