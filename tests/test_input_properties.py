"""Property tests (Hypothesis) of what hertzchain reads from outside: scope files (random headers
and byte layouts of each format), design files, design checkpoints (random bytes never execute
and never crash) and the inputs of ``fit``.

Every outcome is a result or a :class:`~hertzchain.errors.ConfigError` (or the documented
exception of the function), never another exception. The default run draws a few dozen examples
per property (a few seconds each, ``EXAMPLES``); ``-m slow`` runs each property ten times longer.
"""

from __future__ import annotations

import io
import json
import math
import types
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hertzchain.errors import CheckpointWarning, ConfigError

from lab_files import ISF_FORMATS, isf_bytes, trc_bytes
from test_scope_formats import picoscope_text

#: Examples per property in the default run (the slow variants: ten times as many).
EXAMPLES = {"isf_roundtrip": 60, "isf_fields": 80, "isf_bytes": 60, "trc_roundtrip": 40, "trc_fields": 60,
            "pico_roundtrip": 30, "pico_garbage": 40, "design_values": 60, "design_bytes": 40,
            "checkpoint_bytes": 80, "checkpoint_values": 60, "fit_records": 100, "fit_runs": 6}
SETTINGS = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture,
                                                      HealthCheck.data_too_large])


def properties(name: str, **strategies):
    """The property ``body`` given ``strategies``, as a default test (EXAMPLES[name] examples) and a
    slow one (ten times as many): ``test_x, test_x_deep = properties(...)(body)``."""
    def wrap(body):
        slow_body = types.FunctionType(body.__code__, body.__globals__, body.__name__ + "_deep", body.__defaults__,
                                       body.__closure__)
        fast = settings(max_examples=EXAMPLES[name], **SETTINGS)(given(**strategies)(body))
        slow = settings(max_examples=10 * EXAMPLES[name], **SETTINGS)(given(**strategies)(slow_body))
        return fast, pytest.mark.slow(slow)
    return wrap


def _read(tmp: Path, name: str, data: bytes, **kw):
    from hertzchain.lab import read_trace

    path = tmp / name
    path.write_bytes(data)
    return read_trace(path, baseline=False, check=False, **kw)


FINITE = st.floats(allow_nan=False, allow_infinity=False, width=64)


# ------------------------------------------------------------------------------------------
# Tektronix .isf
# ------------------------------------------------------------------------------------------
@st.composite
def isf_layouts(draw):
    fmt = draw(st.sampled_from(sorted(ISF_FORMATS)))
    kind, widths = ISF_FORMATS[fmt]
    width = draw(st.sampled_from(widths))
    n = draw(st.integers(10, 300))
    dtype = np.dtype(f"{kind}{width}")
    if kind == "f":
        codes = draw(st.lists(st.floats(allow_nan=False, allow_infinity=False, width=8 * width), min_size=n,
                              max_size=n))
    else:
        info = np.iinfo(dtype)
        codes = draw(st.lists(st.integers(int(info.min), int(info.max)), min_size=n, max_size=n))
    return dict(codes=np.array(codes, dtype=dtype), fmt=fmt, width=width, order=draw(st.sampled_from(["MSB", "LSB"])),
                encoding=draw(st.sampled_from(["BIN", "ASC"])), short=draw(st.booleans()),
                indefinite=draw(st.booleans()),
                xincr=draw(st.floats(1e-12, 1e-3)), xzero=draw(st.floats(-1.0, 1.0)),
                pt_off=float(draw(st.integers(-1000, 1000))), ymult=draw(st.floats(1e-9, 1e3)),
                yoff=draw(st.floats(-1e4, 1e4)), yzero=draw(st.floats(-10.0, 10.0)))


def _isf_layouts_read_back(tmp_path_factory, layout):
    codes = layout.pop("codes")
    data = isf_bytes(codes, yunit="N", **layout)
    try:
        da = _read(tmp_path_factory.mktemp("isf"), "r.isf", data)
    except ConfigError as exc:
        # only the record's own checks may refuse it: a constant or non-finite signal
        assert "constant" in str(exc) or "not a finite" in str(exc) or "the signal is" in str(exc), exc
        return
    expect = (codes.astype(float) - layout["yoff"]) * layout["ymult"] + layout["yzero"]
    assert np.array_equal(da.values, expect)
    assert np.array_equal(da["time"].values, layout["xzero"] + layout["xincr"] * (np.arange(codes.size) -
                                                                                  layout["pt_off"]))


test_isf_layouts_read_back, test_isf_layouts_read_back_deep = properties(
    "isf_roundtrip",
    layout=isf_layouts(),
    )(_isf_layouts_read_back)


ISF_FIELDS = ["BYT_NR", "BIT_NR", "ENCDG", "BN_FMT", "BYT_OR", "NR_PT", "PT_FMT", "XINCR", "PT_OFF", "XZERO", "YMULT",
              "YZERO", "YOFF", "XUNIT", "YUNIT", "NR_FR", "WFID"]
HEADER_VALUES = st.one_of(st.sampled_from(["0", "-1", "3", "16", "1e400", "inf", "-inf", "nan", "", "RI", "RP",
                                           "FP", "MSB", "LSB", "BIN", "ASC", "ENV", "Y", '"s"', "1.5", "2.0",
                                           "9" * 40, "1e-400"]),
                          st.text(st.characters(max_codepoint=255), max_size=12).filter(
                              lambda s: ";" not in s and ":" not in s))


def _isf_random_headers(tmp_path_factory, over):
    codes = np.arange(-100, 100, dtype=np.int16)
    data = isf_bytes(codes, header_over=over, yunit="N")
    try:
        _read(tmp_path_factory.mktemp("isf"), "h.isf", data)
    except ConfigError:
        pass


test_isf_random_headers, test_isf_random_headers_deep = properties(
    "isf_fields",
    over=st.dictionaries(st.sampled_from(ISF_FIELDS), st.one_of(st.none(), HEADER_VALUES), min_size=1, max_size=4),
    )(_isf_random_headers)


@st.composite
def damaged(draw, good: bytes):
    data = bytearray(good)
    for _ in range(draw(st.integers(1, 6))):
        op = draw(st.sampled_from(["flip", "cut", "insert", "delete"]))
        pos = draw(st.integers(0, max(len(data) - 1, 0)))
        if op == "flip" and data:
            data[pos] = draw(st.integers(0, 255))
        elif op == "cut":
            del data[pos:]
        elif op == "insert":
            data[pos:pos] = draw(st.binary(min_size=1, max_size=8))
        elif data:
            del data[pos:pos + draw(st.integers(1, 16))]
    return bytes(data)


ISF_GOOD = isf_bytes((np.sin(np.arange(200) / 9.0) * 3000).astype(np.int16), yunit="N")


def _isf_damaged_bytes(tmp_path_factory, data):
    try:
        _read(tmp_path_factory.mktemp("isf"), "d.isf", data)
    except ConfigError:
        pass


test_isf_damaged_bytes, test_isf_damaged_bytes_deep = properties(
    "isf_bytes",
    data=damaged(ISF_GOOD),
    )(_isf_damaged_bytes)


# ------------------------------------------------------------------------------------------
# LeCroy .trc
# ------------------------------------------------------------------------------------------
def _trc_layouts_read_back(tmp_path_factory, comm_type, comm_order, header, text, seed, gain,
                                                    offset, interval, h_offset, n):
    lim = 127 if comm_type == 0 else 32767
    codes = np.random.default_rng(seed).integers(-lim - 1, lim, n, endpoint=True)
    codes[0], codes[1] = -lim - 1, lim  # never constant
    data = trc_bytes(codes, comm_type=comm_type, comm_order=comm_order, gain=gain, offset=offset, interval=interval,
                     h_offset=h_offset, block_header=header, user_text=text)
    da = _read(tmp_path_factory.mktemp("trc"), "C1.trc", data, signal_unit="V", sensitivity=1000.0)
    g, o, dt = (float(np.float32(v)) for v in (gain, offset, interval))
    np.testing.assert_allclose(da.values, g * codes.astype(float) - o, rtol=1e-12, atol=1e-12 * (abs(o) + g * lim))
    assert np.array_equal(da["time"].values, h_offset + dt * np.arange(n))


test_trc_layouts_read_back, test_trc_layouts_read_back_deep = properties(
    "trc_roundtrip",
    comm_type=st.sampled_from([0, 1]),
    comm_order=st.sampled_from([0, 1]),
    header=st.booleans(),
    text=st.binary(max_size=40),
    seed=st.integers(0, 2**16),
    gain=st.floats(1e-6, 10.0),
    offset=st.floats(-10.0, 10.0),
    interval=st.floats(1e-11, 1e-4),
    h_offset=st.floats(-1.0, 1.0),
    n=st.integers(10, 300),
    )(_trc_layouts_read_back)


FIELDS = st.sampled_from([(32, "h"), (34, "h"), (36, "i"), (40, "i"), (48, "i"), (52, "i"), (56, "i"), (60, "i"),
                          (64, "i"), (116, "i"), (124, "i"), (128, "i"), (156, "f"), (160, "f"), (176, "f"),
                          (180, "d"), (316, "H"), (344, "H")])


def _trc_random_descriptors(tmp_path_factory, over):
    sets = {}
    for (pos, fmt), value in over.items():
        if fmt in "hHi":
            lo, hi = {"h": (-2**15, 2**15 - 1), "H": (0, 2**16 - 1), "i": (-2**31, 2**31 - 1)}[fmt]
            value = int(min(max(int(value) if math.isfinite(value) else 0, lo), hi))
        else:
            value = float(value)
        sets[pos] = (fmt, value)
    data = trc_bytes(np.arange(100) % 37 - 18, over=sets)
    try:
        _read(tmp_path_factory.mktemp("trc"), "f.trc", data, sensitivity=100.0)
    except ConfigError:
        pass


test_trc_random_descriptors, test_trc_random_descriptors_deep = properties(
    "trc_fields",
    over=st.dictionaries(FIELDS, st.one_of(st.integers(-2**31, 2**31 - 1), st.floats(width=32)), min_size=1,
                         max_size=4),
    )(_trc_random_descriptors)


# ------------------------------------------------------------------------------------------
# PicoScope exports
# ------------------------------------------------------------------------------------------
def _picoscope_locales_read_back(tmp_path_factory, sep, time_unit, volt_unit, channels, n, seed,
                                                    comma):
    from hertzchain.lab import read_trace

    decimal = "," if comma and sep != "," else "."
    rng = np.random.default_rng(seed)
    t = -1e-5 + 4e-7 * np.arange(n)
    mv = rng.normal(0.0, 100.0, n)
    path = tmp_path_factory.mktemp("pico") / "p.txt"
    path.write_text(picoscope_text(t, mv, sep=sep, decimal=decimal, time_unit=time_unit, volt_unit=volt_unit,
                                   channels=channels))
    da = read_trace(path, "Channel A", sensitivity=100.0, baseline=False, check=False)
    np.testing.assert_allclose(da.values, mv * 1e-2, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(da["time"].values, t, rtol=1e-12, atol=1e-20)


test_picoscope_locales_read_back, test_picoscope_locales_read_back_deep = properties(
    "pico_roundtrip",
    sep=st.sampled_from([",", "\t", ";"]),
    time_unit=st.sampled_from(["s", "ms", "us", "ns"]),
    volt_unit=st.sampled_from(["V", "mV"]),
    channels=st.integers(1, 4),
    n=st.integers(10, 200),
    seed=st.integers(0, 2**16),
    comma=st.booleans(),
    )(_picoscope_locales_read_back)


def _picoscope_garbage_lines(tmp_path_factory, lines):
    from hertzchain.lab import read_trace

    rows = picoscope_text(-1e-5 + 4e-7 * np.arange(60), np.linspace(-50, 50, 60)).splitlines()
    for at, text in lines:
        rows.insert(min(at, len(rows)), text)
    path = tmp_path_factory.mktemp("pico") / "g.csv"
    path.write_bytes("\n".join(rows).encode("utf-8", "replace"))
    try:
        read_trace(path, "Channel A", sensitivity=100.0, check=False)
    except ConfigError:
        pass


test_picoscope_garbage_lines, test_picoscope_garbage_lines_deep = properties(
    "pico_garbage",
    lines=st.lists(st.tuples(st.integers(0, 60), st.text(max_size=30)), min_size=1, max_size=5),
    )(_picoscope_garbage_lines)


# ------------------------------------------------------------------------------------------
# design files
# ------------------------------------------------------------------------------------------
DESIGN = {"base": {"chain": {"uniform": {"n": 4, "diameter_mm": 26.0}, "taper": {"n": 4, "q": 0.05}},
                   "striker": {"diameter_mm": 8.0, "velocity": 0.2},
                   "run": {"duration": 2e-3, "sample_interval": 1e-6}},
          "design": {"objective": "peak_wall_force",
                     "variables": {"chain.taper.n": [2, 12], "chain.taper.q": [0.0, 0.15]},
                     "constraints": {"min_diameter_mm": 15.0}, "budget": 60, "seed": 3}}
HOSTILE = st.sampled_from([True, False, "0.5", "x", "", 0, -1, 1, 2**62, 1e300, -1e300, 1e-300, 0.0, float("nan"),
                           float("inf"), [], {}, [1.0, "a"], {"a": 1}, [2, 1], [0.0, 0.0], ["a", "b"],
                           {"low": 1.0, "high": 0.5}, {"chain.taper.q": [0.1, 0.2]}, "peak_wall_force",
                           ["peak_wall_force", "peak_wall_force"], "worst"])
DESIGN_VARIABLES = ["chain.taper.n", "chain.taper.q", "striker.velocity", "chain.nope", "chain.diameters_mm[0:2]"]
DESIGN_KEYS = ["objective", "variables", "constraints", "budget", "seed", "population", "polish", "window",
               "chunk_size", "robust", "shape", "search_steps_per_radian", "verify_top", "unknown_key"]


def _design_hostile_values(changes, variable):
    import copy

    from hertzchain.design import parse_design

    data = copy.deepcopy(DESIGN)
    data["design"].update(changes)
    if variable is not None and isinstance(data["design"].get("variables"), dict):
        data["design"]["variables"][variable[0]] = variable[1]
    try:
        problem = parse_design(data)
    except ConfigError:
        return
    assert problem.space.dim >= 1 and len(problem.hash) == 64


test_design_hostile_values, test_design_hostile_values_deep = properties(
    "design_values",
    changes=st.dictionaries(st.sampled_from(DESIGN_KEYS), HOSTILE, min_size=1, max_size=3),
    variable=st.one_of(st.none(), st.tuples(st.sampled_from(DESIGN_VARIABLES), HOSTILE)),
    )(_design_hostile_values)


def _design_random_bytes(tmp_path_factory, raw):
    from hertzchain.design import load_design

    path = tmp_path_factory.mktemp("design") / "d.toml"
    path.write_bytes(raw)
    with pytest.raises(ConfigError):
        load_design(path)


test_design_random_bytes, test_design_random_bytes_deep = properties(
    "design_bytes",
    raw=st.one_of(st.binary(max_size=300), st.text(max_size=300).map(lambda s: s.encode("utf-8"))),
    )(_design_random_bytes)


# ------------------------------------------------------------------------------------------
# design checkpoints
# ------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory):
    """A real checkpoint (the design above, stopped after three engine calls) and its problem."""
    from hertzchain.design import parse_design, run_design
    from hertzchain.design.checkpoint import _CHECKPOINT

    out = tmp_path_factory.mktemp("ckpt")
    calls = []

    def killer(done, total):
        calls.append(done)
        if len(calls) == 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_design(parse_design(DESIGN), out, progress=killer, checkpoint_interval=0)
    return (out / _CHECKPOINT).read_bytes(), parse_design(DESIGN)


def _load(tmp: Path, data: bytes, problem):
    from hertzchain.design.checkpoint import _CHECKPOINT, DesignMismatch, Saved, _load

    (tmp / _CHECKPOINT).write_bytes(data)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            saved = _load(tmp, problem, force=False)
        except DesignMismatch:
            return "mismatch", caught
    assert saved is None or isinstance(saved, Saved)
    if saved is None:  # set aside, and said so
        assert [w for w in caught if issubclass(w.category, CheckpointWarning)]
        assert not (tmp / _CHECKPOINT).exists() and list(tmp.glob("checkpoint.npz.unreadable-*"))
    return saved, caught


def _checkpoint_random_bytes(tmp_path_factory, checkpoint, raw):
    _, problem = checkpoint
    saved, _ = _load(tmp_path_factory.mktemp("c"), raw, problem)
    assert saved is None


test_checkpoint_random_bytes, test_checkpoint_random_bytes_deep = properties(
    "checkpoint_bytes",
    raw=st.one_of(st.binary(max_size=2000), st.builds(lambda b: b"PK\x03\x04" + b, st.binary(max_size=500))),
    )(_checkpoint_random_bytes)


JSON_VALUES = st.recursive(st.one_of(st.none(), st.booleans(), st.integers(-10**20, 10**20), st.floats(),
                                     st.text(max_size=8)),
                           lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                   st.dictionaries(st.text(max_size=6), inner, max_size=4)),
                           max_leaves=10)


def _paths(node, prefix=()):
    yield prefix
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node[:6]):
            yield from _paths(v, prefix + (i,))


def _checkpoint_random_values(tmp_path_factory, checkpoint, data):
    good, problem = checkpoint
    with np.load(io.BytesIO(good), allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    meta = json.loads(arrays["meta"].tobytes())
    paths = [p for p in _paths(meta) if p]
    path = data.draw(st.sampled_from(paths))
    node = meta
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = data.draw(JSON_VALUES)
    arrays["meta"] = np.frombuffer(json.dumps(meta).encode(), np.uint8)
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    _load(tmp_path_factory.mktemp("c"), buf.getvalue(), problem)


test_checkpoint_random_values, test_checkpoint_random_values_deep = properties(
    "checkpoint_values",
    data=st.data(),
    )(_checkpoint_random_values)


# ------------------------------------------------------------------------------------------
# fit inputs
# ------------------------------------------------------------------------------------------
RECORDS = st.builds(
    lambda n, kind, amp, noise, seed, clip: _record(n, kind, amp, noise, seed, clip),
    st.integers(10, 400), st.sampled_from(["pulse", "noise", "step", "spikes", "ramp"]), st.floats(1e-3, 1e3),
    st.floats(0.0, 1.0), st.integers(0, 2**16), st.one_of(st.none(), st.floats(0.05, 1.0)))


def _record(n, kind, amp, noise, seed, clip):
    from hertzchain.analysis import cos6_pulse

    rng = np.random.default_rng(seed)
    t = np.arange(n) * 2e-6
    y = {"pulse": cos6_pulse(t, amp, t[n // 2], 20e-6), "noise": np.zeros(n), "step": np.where(t > t[n // 2], amp, 0.0),
         "spikes": np.where(rng.random(n) < 0.02, amp, 0.0), "ramp": amp * t / t[-1]}[kind]
    y = y + noise * amp * rng.normal(size=n)
    if clip is not None:
        y = np.minimum(y, clip * amp)
    return t, y


def _fit_record_gate(rec):
    """check_records (the fit's gate): a ConfigError naming the trace, or nothing."""
    from hertzchain.analysis.pulse import estimate_noise
    from hertzchain.lab.fit_checks import check_records

    t, y = rec
    sigma = max(estimate_noise(y), 1e-6 * float(np.ptp(y)))
    try:
        check_records(["trace"], [t], [y], np.array([sigma]), [None])
    except ConfigError as exc:
        assert exc.field == "trace"
        assert "no significant pulse" in exc.message or "clipped" in exc.message


test_fit_record_gate, test_fit_record_gate_deep = properties(
    "fit_records",
    rec=RECORDS,
    )(_fit_record_gate)


FREE = ["striker.velocity", "gain", "time_offset", "baseline", "striker.diameter_mm", "run.duration", "wall", "nope"]
FIT_CONFIG = {"chain": {"uniform": {"n": 6, "diameter_mm": 26.0}}, "striker": {"diameter_mm": 8.0, "velocity": 0.2},
              "run": {"duration": 6e-4, "sample_interval": 1e-6}}


def _fit_any_record(rec, free):
    import xarray as xr

    from hertzchain.lab import Trace, fit_traces

    t, y = rec
    da = xr.DataArray(y, dims="time", coords={"time": t}, attrs={"units": "N"})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            res = fit_traces(FIT_CONFIG, [Trace(da, name="trace")], free, max_evaluations=8)
        except ConfigError:
            return
    assert np.all(np.isfinite(res.values)) and isinstance(res.warnings, list)





test_fit_any_record, test_fit_any_record_deep = properties(
    "fit_runs",
    rec=RECORDS,
    free=st.lists(st.sampled_from(FREE), min_size=1, max_size=3, unique=True),
    )(_fit_any_record)
