"""Binary scope files of every documented variant, written by the tests from the vendors' layouts,
read back to the samples written (float samples too); every other variant refused with the header
field named. PicoScope exports in their locales likewise."""

from __future__ import annotations

import contextlib
import itertools

import numpy as np
import pytest

from hertzchain.errors import ConfigError
from hertzchain.lab import read_trace

from lab_files import ISF_FORMATS, isf_bytes, trc_bytes

N = 400
XINCR, XZERO = 4e-7, -4e-5


def _codes(fmt: str, width: int, seed: int) -> np.ndarray:
    """Samples spanning the whole range of the format (its extreme codes included) and a pulse."""
    rng = np.random.default_rng(seed)
    kind = ISF_FORMATS[fmt][0]
    if kind == "f":
        dtype = np.float32 if width == 4 else np.float64
        return (rng.normal(0.0, 1.0, N) * 10.0 ** rng.uniform(-6, 6, N)).astype(dtype)
    info = np.iinfo(np.dtype(f"{kind}{width}"))
    codes = rng.integers(info.min, info.max, N, endpoint=True, dtype=np.dtype(f"{kind}{width}"))
    codes[:2] = info.min, info.max
    return codes


ISF_VARIANTS = [(fmt, w, order, enc) for fmt, (_, widths) in ISF_FORMATS.items() for w in widths
                for order in ("MSB", "LSB") for enc in ("BIN", "ASC")]


@pytest.mark.parametrize("fmt,width,order,encoding", ISF_VARIANTS)
def test_every_isf_variant_reads_back_to_the_samples_written(tmp_path, fmt, width, order, encoding):
    codes = _codes(fmt, width, seed=width + 10 * len(order) + (encoding == "ASC"))
    ymult, yoff, yzero, pt_off = 2.5e-3, 3.0, 0.125, 17.0
    path = tmp_path / "TEK.ISF"
    path.write_bytes(isf_bytes(codes, fmt=fmt, width=width, order=order, encoding=encoding, xincr=XINCR,
                               xzero=XZERO, pt_off=pt_off, ymult=ymult, yoff=yoff, yzero=yzero, yunit="N"))
    da = read_trace(path, baseline=False, check=False)
    expect = (codes.astype(float) - yoff) * ymult + yzero
    assert np.array_equal(da.values, expect)
    assert np.array_equal(da["time"].values, XZERO + XINCR * (np.arange(N) - pt_off))
    assert da.attrs["format"] == "tektronix-isf"
    if fmt == "FP":
        assert "valid_max" not in da.attrs
    else:  # the largest code of the format: the scope's full scale
        info = np.iinfo(np.dtype(f"{ISF_FORMATS[fmt][0]}{width}"))
        assert da.attrs["valid_max"] == (float(info.max) - yoff) * ymult + yzero


@pytest.mark.parametrize("short,indefinite", [(True, False), (False, True), (True, True)])
def test_isf_short_keys_and_indefinite_blocks(tmp_path, short, indefinite):
    codes = _codes("RI", 2, 3)
    path = tmp_path / "s.isf"
    path.write_bytes(isf_bytes(codes, short=short, indefinite=indefinite, yunit="N"))
    assert np.array_equal(read_trace(path, baseline=False, check=False).values, codes.astype(float) * 1e-3)


def test_float_samples_are_read_as_floats_not_integers(tmp_path):
    """BN_FMT FP (a 35 N pulse stored as float32 volts) was read as unsigned integers: F_m = 8.6e9 N."""
    from hertzchain.analysis import cos6_pulse, fit_pulse

    t = XZERO + XINCR * np.arange(N)
    volts = (cos6_pulse(t, 35.0, 6e-5, 3e-5) * 0.1124).astype(np.float32)
    path = tmp_path / "fp.isf"
    path.write_bytes(isf_bytes(volts, fmt="FP", width=4, ymult=1.0, xincr=XINCR, xzero=XZERO))
    da = read_trace(path, sensor="pcb_208a11", baseline=False)
    np.testing.assert_allclose(da.values, volts.astype(float) / 0.1124, rtol=1e-15, atol=0)
    assert fit_pulse(da["time"].values, da.values).peak_force == pytest.approx(35.0, rel=1e-4)


ILLEGAL_ISF = [
    ({"BYT_NR": "3"}, "BYT_NR is 3"),
    ({"BYT_NR": "0"}, "BYT_NR is 0"),
    ({"BYT_NR": "16"}, "BYT_NR is 16"),
    ({"BYT_NR": "two"}, "BYT_NR is 'two'"),
    ({"BN_FMT": "XX"}, "BN_FMT is 'XX'"),
    ({"BN_FMT": "FP"}, "BYT_NR is 2; BN_FMT FP samples are 4 or 8 bytes"),
    ({"BYT_OR": "MID"}, "BYT_OR is 'MID'"),
    ({"ENCDG": "HEX"}, "ENCDG is 'HEX'"),
    ({"PT_FMT": "ENV"}, "PT_FMT is 'ENV'"),
    ({"PT_OFF": "inf"}, "PT_OFF is inf"),
    ({"PT_OFF": "nan"}, "PT_OFF is nan"),
    ({"XINCR": "0"}, "XINCR is 0"),
    ({"XINCR": "-4e-7"}, "XINCR is -4e-7"),
    ({"XZERO": "abc"}, "XZERO is 'abc'"),
    ({"YMULT": "0"}, "YMULT is 0"),
    ({"YOFF": "inf"}, "YOFF is inf"),
    ({"NR_PT": "0"}, "NR_PT is 0"),
    ({"NR_PT": "12.5"}, "NR_PT is '12.5'"),
    ({"NR_PT": None}, "NR_PT is missing"),
    ({"YMULT": None}, "YMULT is missing"),
    ({"BIT_NR": "17"}, "BIT_NR is 17"),
    ({"NR_PT": "401"}, "NR_PT 401 x BYT_NR 2 say 802"),
]


@pytest.mark.parametrize("over,message", ILLEGAL_ISF)
def test_isf_outside_the_documented_variants_is_refused_naming_the_field(tmp_path, over, message):
    path = tmp_path / "bad.isf"
    path.write_bytes(isf_bytes(_codes("RI", 2, 0), header_over=over, yunit="N"))
    with pytest.raises(ConfigError, match="header field " + message.replace("(", r"\(").replace(".", r"\.")
                       if not message.startswith("NR_PT 401") else message):
        read_trace(path, baseline=False, check=False)


def test_isf_damaged_curves_are_refused(tmp_path):
    good = isf_bytes(_codes("RI", 2, 0), yunit="N")
    cases = {
        "truncated": (good[:-300], "the file is truncated"),
        "no block": (good.replace(b":CURVE #", b":CURVE X"), "not an IEEE 488.2 block"),
        "bad length digits": (good.replace(b":CURVE #3", b":CURVE #3x"), "does not give its length"),
        "frames": (isf_bytes(_codes("RI", 2, 0), extra=";NR_FR 3", yunit="N"), "NR_FR is 3"),
        "ascii sample": (_bad_ascii_sample(isf_bytes(_codes("RI", 2, 0), encoding="ASC", yunit="N")),
                         "CURVE sample 1 is 'x"),
        "ascii count": (isf_bytes(_codes("RI", 2, 0), encoding="ASC", header_over={"NR_PT": "399"}, yunit="N"),
                        "the curve holds 400 points, header field NR_PT says 399"),
        "no header": (b"#3800" + bytes(800), "is not a Tektronix .isf file"),
    }
    for name, (data, message) in cases.items():
        path = tmp_path / f"{name.replace(' ', '_')}.isf"
        path.write_bytes(data)
        with _named(name), pytest.raises(ConfigError, match=message):
            read_trace(path, baseline=False, check=False)


def _bad_ascii_sample(data: bytes) -> bytes:
    head, _, curve = data.partition(b":CURVE ")
    return head + b":CURVE " + curve.replace(b",", b",x", 1)


@contextlib.contextmanager
def _named(case: str):
    """Say which case failed."""
    try:
        yield
    except BaseException as exc:
        exc.add_note(f"case: {case}")
        raise


TRC_VARIANTS = list(itertools.product((0, 1), (0, 1), (True, False), (b"", b"a user text block")))


@pytest.mark.parametrize("comm_type,comm_order,block_header,user_text", TRC_VARIANTS)
def test_every_lecroy_variant_reads_back(tmp_path, comm_type, comm_order, block_header, user_text):
    rng = np.random.default_rng(comm_type * 4 + comm_order)
    lim = 127 if comm_type == 0 else 32767
    codes = rng.integers(-lim - 1, lim, N, endpoint=True)
    gain, offset = float(np.float32(3e-3)), float(np.float32(0.25))
    path = tmp_path / "C1.trc"
    path.write_bytes(trc_bytes(codes, comm_type=comm_type, comm_order=comm_order, gain=gain, offset=offset,
                               block_header=block_header, user_text=user_text))
    da = read_trace(path, sensitivity=100.0, baseline=False, check=False)
    assert np.array_equal(da.values, (gain * codes.astype(float) - offset) / 0.1)
    assert np.allclose(da["time"].values, -4e-5 + np.arange(N) * float(np.float32(4e-7)), rtol=0, atol=1e-15)
    assert da.attrs["format"] == "lecroy-trc" and da.attrs["valid_max"] == pytest.approx((gain * lim - offset) / 0.1)


ILLEGAL_TRC = [
    ({32: ("h", 2)}, "COMM_TYPE is 2"),
    ({316: ("H", 2)}, "RECORD_TYPE is 2 \\(histogram\\)"),
    ({316: ("H", 7)}, "RECORD_TYPE is 7 \\(sequence\\)"),
    ({60: ("i", 5)}, "WAVE_ARRAY_1 is 5 bytes"),
    ({64: ("i", 40)}, "WAVE_ARRAY_2 holds 40 bytes"),
    ({116: ("i", 0)}, "WAVE_ARRAY_COUNT is 0"),
    ({156: ("f", 0.0)}, "VERTICAL_GAIN is 0.0"),
    ({160: ("f", float("nan"))}, "VERTICAL_OFFSET is nan"),
    ({176: ("f", -1e-7)}, "HORIZ_INTERVAL is -1"),
    ({180: ("d", float("inf"))}, "HORIZ_OFFSET is inf"),
    ({36: ("i", 100)}, "WAVE_DESCRIPTOR is 100 bytes"),
    ({40: ("i", -3)}, "USER_TEXT is -3"),
    ({128: ("i", 10_000)}, "LAST_VALID_PNT 10000"),
    ({16: ("16s", b"LECROY_9_9")}, "TEMPLATE_NAME is 'LECROY_9_9'"),
]


@pytest.mark.parametrize("over,message", ILLEGAL_TRC)
def test_lecroy_outside_the_documented_variants_is_refused_naming_the_field(tmp_path, over, message):
    path = tmp_path / "bad.trc"
    path.write_bytes(trc_bytes(np.arange(N) % 50, over=over))
    with pytest.raises(ConfigError, match=message):
        read_trace(path, sensitivity=100.0, baseline=False, check=False)


def test_lecroy_truncated_and_byte_order_word_refused(tmp_path):
    good = trc_bytes(np.arange(N) % 50)
    (tmp_path / "t.trc").write_bytes(good[:-10])
    with pytest.raises(ConfigError, match="data array holds 790 of its 800 bytes"):
        read_trace(tmp_path / "t.trc", sensitivity=100.0, check=False)
    (tmp_path / "d.trc").write_bytes(good[:200])
    with pytest.raises(ConfigError, match="WAVEDESC descriptor holds"):
        read_trace(tmp_path / "d.trc", sensitivity=100.0, check=False)
    bad = bytearray(good)
    bad[11 + 34:11 + 36] = b"\x07\x00"  # COMM_ORDER after the 11-byte '#9' header
    (tmp_path / "o.trc").write_bytes(bytes(bad))
    with pytest.raises(ConfigError, match="COMM_ORDER is 7"):
        read_trace(tmp_path / "o.trc", sensitivity=100.0, check=False)


def picoscope_text(t: np.ndarray, mv: np.ndarray, *, sep: str = ",", decimal: str = ".", time_unit: str = "us",
                   volt_unit: str = "mV", channels: int = 2) -> str:
    """A PicoScope 6/7 export (Time, Channel A, B...; a units row; a blank line; the samples) in a
    locale's separator and decimal mark."""
    scale = {"s": 1.0, "ms": 1e3, "us": 1e6, "ns": 1e9}[time_unit]
    vscale = {"V": 1e-3, "mV": 1.0}[volt_unit]
    names = ["Time"] + [f"Channel {chr(65 + k)}" for k in range(channels)]
    units = [f"({time_unit})"] + [f"({volt_unit})"] * channels
    rows = [sep.join(names), sep.join(units), ""]
    for i, (ti, vi) in enumerate(zip(t, mv)):
        cells = [repr(float(ti * scale)), repr(float(vi * vscale))] + [repr(0.001 * (i % 7))] * (channels - 1)
        rows.append(sep.join(c.replace(".", decimal) for c in cells))
    return "\n".join(rows) + "\n"


@pytest.mark.parametrize("sep,decimal", [(",", "."), ("\t", "."), (";", ","), ("\t", ",")])
@pytest.mark.parametrize("time_unit,volt_unit", [("s", "V"), ("ms", "mV"), ("us", "mV"), ("ns", "V")])
def test_picoscope_exports_in_every_locale_read_back(tmp_path, sep, decimal, time_unit, volt_unit):
    rng = np.random.default_rng(1)
    t = XZERO + XINCR * np.arange(N)
    mv = rng.normal(0.0, 50.0, N)
    path = tmp_path / "pico.csv"
    path.write_text(picoscope_text(t, mv, sep=sep, decimal=decimal, time_unit=time_unit, volt_unit=volt_unit))
    da = read_trace(path, "Channel A", sensitivity=100.0, baseline=False)
    np.testing.assert_allclose(da.values, mv * 1e-3 / 0.1, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(da["time"].values, t, rtol=1e-12, atol=1e-18)


def test_picoscope_out_of_range_sample_is_refused_with_its_line(tmp_path):
    t = XZERO + XINCR * np.arange(N)
    text = picoscope_text(t, np.ones(N)).splitlines()
    text[50] = text[50].split(",")[0] + ",∞,0.0"
    (tmp_path / "p.csv").write_text("\n".join(text) + "\n")
    with pytest.raises(ConfigError, match="line 51: the signal is inf .*out of range"):
        read_trace(tmp_path / "p.csv", "Channel A", sensitivity=100.0)


def test_a_huge_lecroy_file_costs_its_declared_record_not_its_size(tmp_path):
    """A .trc whose WAVEDESC declares a 20,000-sample record, in a 3 GB file (sparse: no disk
    used): the descriptor is read first and only the declared record is copied (read whole before,
    3.2 GB of memory): the reading allocates less than 50 MB (tracemalloc; ~2 MB measured)."""
    import tracemalloc

    from lab_files import write_trc

    t = np.arange(20_000) * 1e-8
    volts = 0.5 * np.exp(-(((t - 1e-4) / 2e-5) ** 2))
    path = write_trc(tmp_path / "big.trc", t, volts)
    read_trace(path, sensitivity=2.0, check=False)  # imports and caches, before the measurement
    with open(path, "r+b") as f:
        f.truncate(3 * 2**30)
    tracemalloc.start()
    try:
        trace = read_trace(path, sensitivity=2.0, check=False)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert trace.size == t.size and peak < 50e6, peak
