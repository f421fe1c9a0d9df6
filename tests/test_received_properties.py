"""Property tests (Hypothesis, the derandomised ``ci`` profile of conftest): received files and the
options that reach the engine or a cluster never crash, hang or pass silently.

- design checkpoints: a valid checkpoint mutated at random (bytes flipped, cut, members added
  with any header, any name, any bytes, a value of its JSON document replaced by any JSON value) is either resumed or set aside with a CheckpointWarning,
  never an other exception, never an allocation beyond the file's size;
- ``.npz`` archives built from arbitrary members: arrays whose bytes the file holds, or a
  ConfigError;
- ``metrics.csv`` damaged at random (a cell replaced, a line cut or lengthened): the table read
  has every row of the file as a member with numeric metrics, or a ConfigError naming a line;
- ``--scheduler`` addresses: ``tcp://HOST:PORT`` (or an in-process ``inproc://``) or a
  ConfigError naming ``--scheduler``, with no connection tried;
- the run keywords of the Python API: within the config schema's bounds, or a ConfigError naming
  the field.
"""

from __future__ import annotations

import io
import math
import warnings
import zipfile

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hertzchain.config.schema import BOUNDS
from hertzchain.design import parse_design, run_design
from hertzchain.design.checkpoint import _CHECKPOINT, _load
from hertzchain.errors import CheckpointWarning, ConfigError
from hertzchain.parallel import check_address
from hertzchain.received import load_npz
from hertzchain.strict import run_options
from hertzchain.sweep.statistics import read_metrics

_DESIGN = {"base": {"chain": {"uniform": {"n": 4, "diameter_mm": 26.0}, "taper": {"n": 4, "q": 0.05}},
                    "striker": {"diameter_mm": 8.0, "velocity": 0.2},
                    "run": {"duration": 2.0e-3, "sample_interval": 1e-6}},
           "design": {"objective": "peak_wall_force",
                      "variables": {"chain.taper.n": [2, 12], "chain.taper.q": [0.0, 0.15]},
                      "constraints": {"min_diameter_mm": 15.0}, "budget": 40, "seed": 5}}


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory):
    """A finished search's checkpoint (bytes) and its problem."""
    out = tmp_path_factory.mktemp("design")
    run_design(parse_design(_DESIGN), out)
    return (out / _CHECKPOINT).read_bytes(), parse_design(_DESIGN)


def _members(data: bytes) -> dict[str, bytes]:
    with zipfile.ZipFile(io.BytesIO(data)) as z:
        return {name: z.read(name) for name in z.namelist()}


def _zip(members: dict[str, bytes]) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_STORED) as z:
        for name, blob in members.items():
            z.writestr(name, blob)
    return buf.getvalue()


_DTYPES = st.sampled_from(["<f8", "<i4", "|u1", "|b1", "<c16", "|O", "<U3", "|V8", ">f4", "<M8[s]"])
_SHAPES = st.lists(st.one_of(st.integers(0, 8), st.sampled_from([10**12, 2**62, 2**31])), max_size=3).map(tuple)


@st.composite
def _npy(draw) -> bytes:
    """A .npy member: a header of any dtype and shape (maybe lying), then any bytes."""
    buf = io.BytesIO()
    header = {"descr": draw(_DTYPES), "fortran_order": draw(st.booleans()), "shape": draw(_SHAPES)}
    (np.lib.format.write_array_header_1_0 if draw(st.booleans()) else np.lib.format.write_array_header_2_0)(
        buf, header)
    return buf.getvalue() + draw(st.binary(max_size=96))


_JSON = st.recursive(st.one_of(st.none(), st.booleans(), st.integers(-2**70, 2**70), st.floats(), st.text(max_size=5)),
                     lambda inner: st.one_of(st.lists(inner, max_size=3), st.dictionaries(st.text(max_size=4), inner,
                                                                                          max_size=3)), max_leaves=6)


def _paths(doc, prefix=()):
    """Every path (tuple of keys / indices) into a JSON document, the first 40 items of a list."""
    yield prefix
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from _paths(v, (*prefix, k))
    elif isinstance(doc, list):
        for i, v in enumerate(doc[:40]):
            yield from _paths(v, (*prefix, i))


@st.composite
def _edited_meta(draw, good: bytes) -> bytes:
    """The checkpoint with one value of its JSON document replaced by any JSON value."""
    import json

    members = _members(good)
    meta_bytes = members["meta.npy"]
    header = meta_bytes.index(b"\n") + 1
    doc = json.loads(meta_bytes[header:])
    path = draw(st.sampled_from([p for p in _paths(doc) if p]))
    target = doc
    for key in path[:-1]:
        target = target[key]
    target[path[-1]] = draw(_JSON)
    buf = io.BytesIO()
    np.save(buf, np.frombuffer(json.dumps(doc).encode(), np.uint8))
    members["meta.npy"] = buf.getvalue()
    return _zip(members)


@st.composite
def _damaged_checkpoints(draw, good: bytes) -> bytes:
    kind = draw(st.sampled_from(["flip", "cut", "member", "replace", "garbage", "json", "json"]))
    if kind == "json":
        return draw(_edited_meta(good))
    if kind == "flip":
        data = bytearray(good)
        for _ in range(draw(st.integers(1, 8))):
            i = draw(st.integers(0, len(data) - 1))
            data[i] = draw(st.integers(0, 255))
        return bytes(data)
    if kind == "cut":
        return good[:draw(st.integers(0, len(good)))]
    if kind == "garbage":
        return draw(st.binary(max_size=256))
    members = _members(good)
    name = draw(st.sampled_from([*members, "extra.npy", "notes.txt", "dir/x.npy", "meta.npy"]))
    members[name] = draw(st.one_of(_npy(), st.binary(max_size=64)))
    return _zip(members)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                    HealthCheck.too_slow])
@given(data=st.data())
def test_a_damaged_checkpoint_is_resumed_or_set_aside_never_a_crash(tmp_path_factory, checkpoint, data):
    good, problem = checkpoint
    blob = data.draw(_damaged_checkpoints(good))
    out = tmp_path_factory.mktemp("case")
    (out / _CHECKPOINT).write_bytes(blob)
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        saved = _load(out, problem, force=False)
    if saved is None:  # set aside, named, kept byte for byte
        assert any(issubclass(w.category, CheckpointWarning) for w in rec)
        kept = list(out.glob("checkpoint.npz.unreadable-*"))
        assert len(kept) == 1 and kept[0].read_bytes() == blob
    else:  # read: every array is one the file holds
        assert sum(a.nbytes for a in saved.arrays.values()) <= len(blob)
        assert not any(issubclass(w.category, CheckpointWarning) for w in rec)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(members=st.dictionaries(st.sampled_from(["a.npy", "b.npy", "c", "d/e.npy", "f.npy.txt"]),
                               st.one_of(_npy(), st.binary(max_size=32)), max_size=3))
def test_an_npz_of_any_members_gives_held_arrays_or_a_named_error(tmp_path_factory, members):
    path = tmp_path_factory.mktemp("npz") / "x.npz"
    path.write_bytes(_zip(members))
    try:
        arrays = load_npz(path, path.parent)
    except ConfigError as exc:
        assert str(path) in str(exc)
        return
    assert set(arrays) == {name[:-4] for name in members}
    for name, arr in arrays.items():
        assert arr.dtype.kind in "biufc" and arr.nbytes <= len(members[name + ".npy"])


_TABLE = pd.DataFrame({"member": range(6), "chunk": [0, 0, 1, 1, 2, 2], "striker.velocity": [0.1, 0.2] * 3,
                       "dt": 1e-8, "peak_wall_force": np.linspace(1, 2, 6), "elastic_limit_exceeded": False,
                       "F_m": np.linspace(1, 2, 6), "T": 1e-3, "fit_error": ""})


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(row=st.integers(0, 5), column=st.integers(0, len(_TABLE.columns) - 1),
       cell=st.one_of(st.text(alphabet="abcINFnan+-.e0123456789 ;", max_size=6), st.floats().map(repr)),
       how=st.sampled_from(["cell", "cut", "extra"]), cut=st.integers(0, 80))
def test_a_damaged_metrics_table_is_whole_or_refused_naming_a_line(tmp_path_factory, row, column, cell, how, cut):
    lines = _TABLE.to_csv(index=False).splitlines()
    cells = lines[row + 1].split(",")
    if how == "cell":
        cells[column] = cell.replace(",", "")
        lines[row + 1] = ",".join(cells)
    elif how == "cut":
        lines[row + 1] = lines[row + 1][:cut]
    else:
        lines[row + 1] += "," + cell.replace(",", "")
    folder = tmp_path_factory.mktemp("table")
    (folder / "metrics.csv").write_text("\n".join(lines) + "\n")
    try:
        df = read_metrics(folder)
    except ConfigError as exc:
        assert "line " in exc.message or "cannot be read" in exc.message
        return
    # Accepted: every line of the file is a member, and every metric column holds numbers.
    assert len(df) == sum(1 for ln in lines[1:] if ln.strip())
    for c in ("member", "chunk", "dt", "peak_wall_force", "F_m", "T"):
        assert df[c].dtype.kind in "fiu", (c, df[c].tolist())


@settings(max_examples=150, deadline=None)
@given(address=st.one_of(
    st.text(max_size=40),
    st.builds(lambda scheme, host, port: f"{scheme}{host}:{port}",
              st.sampled_from(["", "tcp://", "tls://", "ucx://", "inproc://", "TCP://", "ws://", "tcp:/"]),
              st.sampled_from(["127.0.0.1", "localhost", "[::1]", "", "host name", "a/b", "user@h"]),
              st.one_of(st.integers(-5, 70000).map(str), st.text(max_size=5)))))
def test_a_scheduler_address_is_tcp_or_refused_naming_the_option(address):
    try:
        url = check_address(address)
    except ConfigError as exc:
        assert exc.field == "--scheduler"
        return
    if url.startswith("inproc://"):  # a scheduler in this process (LocalCluster(processes=False))
        return
    assert url.startswith("tcp://")
    port = int(url.rsplit(":", 1)[1])
    assert 1 <= port <= 65535


_ANY = st.one_of(st.none(), st.booleans(), st.integers(-10, 10**7), st.floats(allow_nan=True, allow_infinity=True),
                 st.text(max_size=4), st.lists(st.one_of(st.none(), st.floats(1e-16, 2.0)), max_size=3))


@settings(max_examples=150, deadline=None)
@given(dt=_ANY, rtol=_ANY, spr=_ANY, threads=_ANY)
def test_run_keywords_are_within_the_schema_bounds_or_refused(dt, rtol, spr, threads):
    try:
        out_dt, out_rtol, out_spr, out_threads = run_options(dt=dt, rtol=rtol, steps_per_radian=spr, threads=threads)
    except ConfigError as exc:
        assert exc.field.startswith(("run.dt", "run.rtol", "run.steps_per_radian", "run.threads"))
        return

    def inside(x, kind):
        lo, hi = BOUNDS[kind]
        return x is None or (isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
                             and lo <= x <= hi)

    assert all(inside(d, "dt") for d in (out_dt if isinstance(out_dt, list) else [out_dt]))
    assert inside(out_rtol, "rtol") and inside(out_spr, "steps_per_radian")
    assert out_threads is None or (type(out_threads) is int and inside(out_threads, "threads"))
