"""Scope files are read header first, with bounded memory (issue 38: "whole input files are read
into memory before their header is checked"): a sparse 3 GB file (no disk used) whose header
declares more samples than the file holds, or more than a reader holds, is refused naming the
header field without reading the file (tracemalloc: the reading allocates < 50 MB); a large text
record is counted from its size before it is parsed, then parsed by pandas from the file, and reads
back exactly as the small-file path does, its damaged lines named."""

from __future__ import annotations

import re
import tracemalloc

import numpy as np
import pytest

from hertzchain.errors import ConfigError
from hertzchain.lab import formats, read_trace

from lab_files import isf_bytes, trc_bytes, write_isf

BIG = 3 * 10**9
#: What the header-first reading may allocate [bytes]: the 1 MiB text head, the declared record.
PEAK = 50e6


def _peak(call):
    """(result or exception, peak traced allocation [bytes]) of ``call()``."""
    tracemalloc.start()
    try:
        try:
            out = call()
        except ConfigError as exc:
            out = exc
        return out, tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def _sparse(path, content: bytes):
    path.write_bytes(content)
    with open(path, "r+b") as f:
        f.truncate(BIG)
    return path


def _pulse(n: int = 20_000):
    t = np.arange(n) * 1e-8
    return t, 0.5 * np.exp(-(((t - 1e-4) / 2e-5) ** 2))


def test_a_huge_isf_costs_its_declared_record_not_its_size(tmp_path):
    t, volts = _pulse()
    small = read_trace(write_isf(tmp_path / "small.isf", t, volts), sensitivity=2.0, check=False)
    path = _sparse(tmp_path / "big.isf", (tmp_path / "small.isf").read_bytes())
    trace, peak = _peak(lambda: read_trace(path, sensitivity=2.0, check=False))
    assert peak < PEAK, peak
    np.testing.assert_array_equal(trace.values, small.values)


@pytest.mark.parametrize("nr_pt,indefinite,message", [
    (2 * 10**9, True, "header field NR_PT declares 2000000000 samples; .* at most"),
    (10**7, True, "the CURVE block holds 40001 of its 20000000 bytes: the file is truncated"),  # + its line feed
    (1_000_000, False, "the CURVE block holds 40000 bytes, header fields NR_PT 1000000 x BYT_NR 2 say 2000000"),
])
def test_an_isf_declaring_more_than_the_file_holds_is_refused_unread(tmp_path, nr_pt, indefinite, message):
    codes = np.zeros(20_000, dtype=">i2")
    content = isf_bytes(codes, width=2, indefinite=indefinite, header_over={"NR_PT": str(nr_pt)})
    path = tmp_path / "bad.isf"
    path.write_bytes(content)  # not sparse: the declared block really is missing
    if nr_pt > formats.MAX_SAMPLES:
        path = _sparse(path, content)
    err, peak = _peak(lambda: read_trace(path, sensitivity=2.0, check=False))
    assert isinstance(err, ConfigError) and peak < PEAK, (err, peak)
    assert err.field == str(path)
    assert re.search(message, str(err)), str(err)


def test_an_ascii_isf_far_larger_than_its_points_is_refused_unread(tmp_path):
    content = isf_bytes(np.arange(100, dtype=">i2"), width=2, encoding="ASC")
    path = _sparse(tmp_path / "big_ascii.isf", content.rstrip(b"\n") + b",")
    err, peak = _peak(lambda: read_trace(path, sensitivity=2.0, check=False))
    assert isinstance(err, ConfigError) and peak < PEAK
    assert "far more than header field NR_PT 100 points can fill" in str(err)


def test_a_trc_declaring_a_huge_record_is_refused_naming_the_field(tmp_path):
    content = trc_bytes(np.zeros(100, dtype="i1"), comm_type=0, over={116: ("i", 1_400_000_000),
                                                                     60: ("i", 1_400_000_000)})
    path = _sparse(tmp_path / "big.trc", content)
    err, peak = _peak(lambda: read_trace(path, sensitivity=2.0, check=False))
    assert isinstance(err, ConfigError) and peak < PEAK, (err, peak)
    assert "WAVE_ARRAY_COUNT declares 1400000000 samples" in str(err)


def test_the_memory_available_bounds_a_record(tmp_path, monkeypatch):
    """A record the memory cannot hold (48 bytes a sample as read, half the memory available) is
    refused before it is read, however the file got there."""
    from hertzchain import checks

    t, volts = _pulse()
    path = write_isf(tmp_path / "r.isf", t, volts)
    monkeypatch.setattr(checks, "available_memory", lambda: 1_000_000)
    with pytest.raises(ConfigError, match=r"NR_PT declares 20000 samples; half the memory available holds 10416"):
        read_trace(path, sensitivity=2.0, check=False)


def _csv(path, t, volts, bad: dict | None = None):
    lines = ["Time,Channel A", "(us),(V)", ""] + [f"{a * 1e6:.6f},{b:.6f}" for a, b in zip(t, volts)]
    for k, v in (bad or {}).items():
        lines[k] = v
    path.write_text("\n".join(lines) + "\n")
    return path


def test_a_text_record_larger_than_the_head_reads_back_as_a_small_one(tmp_path, monkeypatch):
    """100,000 rows (2.3 MB, more than the 1 MiB head): parsed from the file by pandas, the same
    numbers and line numbers as the whole-file path gives (TEXT_HEAD raised above the file)."""
    from hertzchain.lab import readers

    t, volts = _pulse(100_000)
    path = _csv(tmp_path / "big.csv", t, volts)
    assert path.stat().st_size > readers.TEXT_HEAD
    big, peak = _peak(lambda: read_trace(path, sensitivity=2.0, check=False, baseline=False))
    monkeypatch.setattr(readers, "TEXT_HEAD", 1 << 30)
    small = read_trace(path, sensitivity=2.0, check=False, baseline=False)
    np.testing.assert_array_equal(big.values, small.values)
    np.testing.assert_array_equal(big.time.values, small.time.values)
    assert peak < PEAK, peak


@pytest.mark.parametrize("line,cell,message", [
    (60_003, "12.5,abc", "line 60004, column 'Channel A': 'abc' is not a number"),
    (80_003, "12.5", "line 80004 has 1 field(s) where the data above has 2: '12.5'"),
    (90_003, "12.5,1,2", "line 90004 has 3 field(s) where the data above has 2"),
])
def test_a_large_texts_damaged_line_is_named(tmp_path, line, cell, message):
    t, volts = _pulse(100_000)
    path = _csv(tmp_path / "bad.csv", t, volts, {line: cell})
    with pytest.raises(ConfigError, match=message.replace("(", r"\(").replace(")", r"\)")):
        read_trace(path, sensitivity=2.0, check=False)


def test_a_text_record_with_too_many_rows_is_refused_before_parsing(tmp_path, monkeypatch):
    """Its rows counted from its size and its first lines' length (here 100,000 against a limit of
    50,000): refused without a number parsed."""
    t, volts = _pulse(100_000)
    path = _csv(tmp_path / "long.csv", t, volts)
    read_trace(_csv(tmp_path / "short.csv", *_pulse(20_000)), sensitivity=2.0, check=False)  # the imports, unmeasured
    monkeypatch.setattr(formats, "MAX_SAMPLES", 50_000)
    err, peak = _peak(lambda: read_trace(path, sensitivity=2.0, check=False))
    assert isinstance(err, ConfigError) and peak < 3 * (1 << 20), (err, peak)  # the 1 MiB head and its layout
    assert re.search(r"its size \(1989025 bytes, rows of ~19 bytes\) declares 1\d{5} samples; hertzchain reads "
                     r"records of at most 50000 samples", str(err)), str(err)


def test_a_sparse_text_file_is_refused_as_binary_unread(tmp_path):
    t, volts = _pulse(1000)
    path = _sparse(tmp_path / "sparse.csv", _csv(tmp_path / "x.csv", t, volts).read_bytes())
    err, peak = _peak(lambda: read_trace(path, sensitivity=2.0, check=False))
    assert isinstance(err, ConfigError) and peak < PEAK
    assert "is a binary file, not text (NUL bytes)" in str(err)
