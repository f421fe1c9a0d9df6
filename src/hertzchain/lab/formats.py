"""The binary scope formats: Tektronix ``.isf`` and LeCroy ``.trc``, decoded from their documented layouts.

Every field the decoding relies on is checked, and a file outside the documented variants is
refused with a :class:`~hertzchain.errors.ConfigError` naming the file and the header field
(``BN_FMT``, ``BYT_NR``, ``COMM_TYPE``...) with the values allowed; nothing is guessed.

Tektronix ``.isf`` (programmer manual, WFMPre and CURVe): a ``:WFMPRE:`` header of ``KEY value;``
pairs (long or short key names), then ``:CURVE`` and the samples. Sample i is at
``XZERO + XINCR (i - PT_OFF)`` [XUNIT] and reads ``(code - YOFF) YMULT + YZERO`` [YUNIT]. Decoded:

- ``ENCDG BIN`` (an IEEE 488.2 block ``#<n><length><bytes>``, or ``#0`` for a block of
  indefinite length) or ``ENCDG ASC`` (the codes as comma-separated text);
- ``BN_FMT RI`` (signed integers), ``RP`` (unsigned) with ``BYT_NR`` 1, 2, 4 or 8, and ``FP``
  (IEEE floats) with ``BYT_NR`` 4 or 8;
- ``BYT_OR MSB`` or ``LSB``; ``PT_FMT Y`` (one value a point; ``ENV``, min/max pairs, is refused).

LeCroy ``.trc`` (remote control manual, template ``LECROY_2_3``): the 346-byte ``WAVEDESC``
block (after an optional ``#9<length>`` block header), then the user text, trigger-time and
RIS-time arrays, and the codes: ``COMM_TYPE`` 0 (bytes) or 1 (16-bit words), ``COMM_ORDER`` 0
(big-endian, HIFIRST) or 1 (LOFIRST); value = ``VERTICAL_GAIN code - VERTICAL_OFFSET``
[VERTUNIT], time = ``HORIZ_OFFSET + i HORIZ_INTERVAL`` [HORUNIT]. Single sweeps and RIS
records are read (``RECORD_TYPE`` 0, 1, 8); histograms, sequences, extrema and the like are
refused.

For integer samples the largest code of the format is the scope's full scale: the reader
returns the value it stands for (``valid_max``), at which a pulse is clipped
(:func:`hertzchain.analysis.saturation.find_clipping`).
"""

from __future__ import annotations

import math
import mmap
import re
import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import ConfigError

__all__ = ["read_isf", "read_trc", "MAX_SAMPLES", "BYTES_PER_SAMPLE", "check_samples"]

#: Most samples one record may hold: 5e7 (a 50 ms record at 1 GS/s; a bead-chain pulse needs
#: 1e3-1e6). A header declaring more, or a text file with more rows, is refused before any sample
#: is read (the reader's arrays would take BYTES_PER_SAMPLE each: 2.4 GB).
MAX_SAMPLES = 50_000_000
#: Memory the reading takes a sample [bytes]: the codes, time and signal as float64, their SI copies.
BYTES_PER_SAMPLE = 48


def check_samples(n: int, field_name: str, where: str) -> None:
    """Refuse a record of ``n`` samples above :data:`MAX_SAMPLES` or above what half the memory
    available holds (:func:`hertzchain.checks.available_memory`), naming the header field (or
    what counted them) that declares it. Called before any sample is read."""
    from .. import checks

    limit, why = MAX_SAMPLES, "hertzchain reads records of at most"
    memory = checks.available_memory()
    if memory is not None and memory // (2 * BYTES_PER_SAMPLE) < limit:
        limit, why = memory // (2 * BYTES_PER_SAMPLE), "half the memory available holds"
    if n > limit:
        raise ConfigError(where, f"{field_name} declares {n} samples; {why} {limit} samples "
                          f"({BYTES_PER_SAMPLE} bytes each as read): cut or decimate the record on the scope")


@dataclass
class _Table:
    """What a text or binary reader found, before units and checks."""

    columns: list[str]
    data: np.ndarray                     # (n_rows, n_columns) floats
    units: list[str | None]
    lines: np.ndarray                    # file line number of each row (0 for binary formats)
    meta: dict = field(default_factory=dict)
    fmt: str = "text"
    valid_max: float | None = None       # largest value the scope records, in the signal's unit
    quantum: tuple[float, float] | None = None  # (code step, one level's value) of integer samples, signal's unit


# ------------------------------------------------------------------------------------------
# Tektronix .isf
# ------------------------------------------------------------------------------------------
_ISF_KEYS = {"BYT_N": "BYT_NR", "BIT_N": "BIT_NR", "ENC": "ENCDG", "BN_F": "BN_FMT", "BYT_O": "BYT_OR",
             "NR_P": "NR_PT", "WFI": "WFID", "PT_F": "PT_FMT", "XIN": "XINCR", "PT_O": "PT_OFF",
             "XZE": "XZERO", "XUN": "XUNIT", "YMU": "YMULT", "YZE": "YZERO", "YOF": "YOFF", "YUN": "YUNIT",
             "NR_F": "NR_FR"}
#: Sample formats: NumPy kind and the sample widths [bytes] the manual allows.
_ISF_FORMATS = {"RI": ("i", (1, 2, 4, 8)), "RP": ("u", (1, 2, 4, 8)), "FP": ("f", (4, 8))}


def _isf_header(text: str) -> dict[str, str]:
    hdr: dict[str, str] = {}
    for item in text.split(";"):
        item = item.strip()
        if not item:
            continue
        parts = item.split(None, 1)
        key = parts[0].rsplit(":", 1)[-1].upper()  # ':WFMPRE:BYT_NR' -> 'BYT_NR'
        hdr[_ISF_KEYS.get(key, key)] = parts[1].strip().strip('"').strip() if len(parts) > 1 else ""
    return hdr


def _field_number(hdr: dict, key: str, where: str, default: float | None = None, *, positive: bool = False,
                  nonzero: bool = False) -> float:
    raw = hdr.get(key)
    if raw is None:
        if default is None:
            raise ConfigError(where, f"header field {key} is missing; a Tektronix .isf header needs NR_PT, XINCR, "
                              "XZERO and YMULT")
        return default
    try:
        value = float(raw)
    except ValueError:
        raise ConfigError(where, f"header field {key} is {raw!r}, not a number") from None
    if not math.isfinite(value) or (positive and not value > 0) or (nonzero and value == 0):
        need = "a positive finite number" if positive else "a finite non-zero number" if nonzero else "a finite number"
        raise ConfigError(where, f"header field {key} is {raw}; it must be {need}")
    return value


def _field_count(hdr: dict, key: str, where: str, default: int | None, allowed: str) -> int:
    raw = hdr.get(key)
    if raw is None:
        if default is None:
            raise ConfigError(where, f"header field {key} is missing; it must be {allowed}")
        return default
    try:
        value = float(raw)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value == int(value)):
        raise ConfigError(where, f"header field {key} is {raw!r}; it must be {allowed}")
    return int(value)


def _choice(hdr: dict, key: str, where: str, default: str, allowed: dict[str, str]) -> str:
    raw = hdr.get(key, default).upper()
    if raw not in allowed:
        names = ", ".join(sorted(set(allowed.values())))
        raise ConfigError(where, f"header field {key} is {hdr.get(key)!r}; a Tektronix .isf file has {key} {names}")
    return allowed[raw]


#: The WFMPRE header lies in a file's first bytes (~500 of them; at most this many are searched).
_ISF_HEAD = 1 << 16
#: Bytes an ASCII CURVE point may take (a float's repr and its comma).
_ISF_ASCII_POINT = 32


def read_isf(path: Path, raw) -> _Table:
    """Decode a Tektronix ``.isf`` file (see the module docstring for the variants).

    The header is read from the file's first bytes and checked, NR_PT against
    :func:`check_samples` and against the bytes the file holds, before the samples: of a
    memory-mapped file only the declared CURVE block is then read.

    Parameters
    ----------
    path : Path
        The file (for messages).
    raw : bytes or mmap.mmap
        Its content (slices of it are read, never the whole).

    Returns
    -------
    _Table
        Time [XUNIT] and signal [YUNIT] columns, the header as ``meta`` and ``valid_max`` for
        integer samples.
    """
    where = str(path)
    window = bytes(raw[:_ISF_HEAD])
    lead = len(window) - len(window.lstrip())
    head = window[lead:]
    m = re.search(rb":CURV[A-Za-z]*", head)
    if head[:5].upper() not in (b":WFMP", b":WFMO") or m is None:
        raise ConfigError(where, "is not a Tektronix .isf file (no ':WFMPRE:' header or ':CURVE' block in its "
                          f"first {_ISF_HEAD // 1024} KiB)")
    hdr = _isf_header(head[:m.start()].decode("latin-1"))
    ascii_enc = _choice(hdr, "ENCDG", where, "BIN", {"BIN": "BIN", "BINARY": "BIN", "ASC": "ASC",
                                                     "ASCII": "ASC"}) == "ASC"
    fmt = _choice(hdr, "BN_FMT", where, "RI", {"RI": "RI", "RP": "RP", "FP": "FP"})
    kind, widths = _ISF_FORMATS[fmt]
    width = _field_count(hdr, "BYT_NR", where, 4 if fmt == "FP" else 1,
                         f"{', '.join(map(str, widths))} (bytes a sample) for BN_FMT {fmt}")
    if width not in widths:
        raise ConfigError(where, f"header field BYT_NR is {width}; BN_FMT {fmt} samples are "
                          f"{' or '.join(map(str, widths))} bytes wide")
    order = ">" if _choice(hdr, "BYT_OR", where, "MSB", {"MSB": "MSB", "LSB": "LSB"}) == "MSB" else "<"
    if "BIT_NR" in hdr:
        bits = _field_count(hdr, "BIT_NR", where, None, f"a number of bits from 1 to {8 * width}")
        if not 1 <= bits <= 8 * width:
            raise ConfigError(where, f"header field BIT_NR is {bits}; samples of {width} byte(s) have 1 to "
                              f"{8 * width} bits")
    pt_fmt = hdr.get("PT_FMT", "Y").upper()
    if pt_fmt != "Y":
        raise ConfigError(where, f"header field PT_FMT is {hdr['PT_FMT']!r}; hertzchain reads records of one value "
                          "per point (PT_FMT Y), not envelopes (ENV: min/max pairs); save the waveform in sample mode")
    frames = _field_count(hdr, "NR_FR", where, 1, "a number of frames")
    if frames != 1:
        raise ConfigError(where, f"header field NR_FR is {frames}: a FastFrame file of several records; save "
                          "one frame")
    n = _field_count(hdr, "NR_PT", where, None, "the number of points, at least 1")
    if n < 1:
        raise ConfigError(where, f"header field NR_PT is {n}; a record has at least one point")
    check_samples(n, "header field NR_PT", where)
    xincr = _field_number(hdr, "XINCR", where, positive=True)
    xzero = _field_number(hdr, "XZERO", where)
    pt_off = _field_number(hdr, "PT_OFF", where, 0.0)
    ymult = _field_number(hdr, "YMULT", where, nonzero=True)
    yzero = _field_number(hdr, "YZERO", where, 0.0)
    yoff = _field_number(hdr, "YOFF", where, 0.0)
    at = lead + m.end()
    at += len(window[at:at + 64]) - len(window[at:at + 64].lstrip())  # the blanks before the block
    dtype = np.dtype(f"{order}{kind}{width}")
    if ascii_enc:
        if len(raw) - at > n * _ISF_ASCII_POINT + 64:
            raise ConfigError(where, f"the ASCII CURVE holds {len(raw) - at} bytes, far more than header field NR_PT "
                              f"{n} points can fill (at most {_ISF_ASCII_POINT} bytes a point)")
        codes = _isf_ascii(bytes(raw[at:]), n, where)
    else:
        codes = np.frombuffer(_isf_block(raw, at, n * width, n, width, where), dtype=dtype).astype(float)
    if codes.size != n:
        raise ConfigError(where, f"the curve holds {codes.size} points, header field NR_PT says {n}")
    with np.errstate(over="ignore", invalid="ignore"):  # beyond float range: refused by read_trace's checks
        t = xzero + xincr * (np.arange(n) - pt_off)
        y = (codes - yoff) * ymult + yzero
    valid_max = quantum = None
    if kind in "iu":
        info = np.iinfo(dtype)
        valid_max = float(((info.max if ymult > 0 else info.min) - yoff) * ymult + yzero)
        quantum = (abs(float(ymult)), float(yzero - yoff * ymult))
    source = hdr.get("WFID", "CH1").split(",")[0].strip() or "CH1"
    return _Table(["TIME", source], np.column_stack([t, y]), [hdr.get("XUNIT") or None, hdr.get("YUNIT") or None],
                  np.zeros(n, int), hdr, "tektronix-isf", valid_max, quantum)


def _isf_block(raw, at: int, nbytes_expected: int, n: int, width: int, where: str) -> bytes:
    """The bytes of the binary CURVE block ``#<n><length><bytes>`` (``#0<bytes>``: indefinite length)
    starting at byte ``at`` of ``raw``; its declared length is checked against NR_PT and against the
    bytes the file holds before the samples are read."""
    lead = bytes(raw[at:at + 11])
    if not lead.startswith(b"#") or len(lead) < 2 or not lead[1:2].isdigit():
        raise ConfigError(where, f"the CURVE block starts with {lead[:12]!r}, not an IEEE 488.2 block "
                          "'#<digits><length>' (ENCDG BIN)")
    ndig = int(lead[1:2])
    if ndig == 0:  # indefinite length: the samples, then a line feed
        start, announced = at + 2, nbytes_expected
    else:
        text = lead[2:2 + ndig]
        if len(text) != ndig or not text.isdigit():
            raise ConfigError(where, f"the CURVE block header {lead[:2 + ndig]!r} does not give its length in "
                              f"{ndig} digits")
        start, announced = at + 2 + ndig, int(text)
    if announced != nbytes_expected:
        raise ConfigError(where, f"the CURVE block holds {announced} bytes, header fields NR_PT {n} x BYT_NR {width} "
                          f"say {nbytes_expected}")
    held = max(0, min(len(raw) - start, announced))
    if held != announced:
        raise ConfigError(where, f"the CURVE block holds {held} of its {announced} bytes: the file is truncated")
    return bytes(raw[start:start + announced])


def _isf_ascii(rest: bytes, n: int, where: str) -> np.ndarray:
    """The codes of an ASCII CURVE: comma-separated numbers."""
    text = rest.decode("latin-1").strip().rstrip(";").strip()
    cells = [c.strip() for c in text.split(",")] if text else []
    out = np.empty(len(cells))
    for k, c in enumerate(cells):
        try:
            out[k] = float(c)
        except ValueError:
            raise ConfigError(where, f"CURVE sample {k} is {c[:20]!r}, not a number (ENCDG ASC)") from None
        if not math.isfinite(out[k]):
            raise ConfigError(where, f"CURVE sample {k} is {c[:20]!r}, not a finite number (ENCDG ASC)")
    return out


# ------------------------------------------------------------------------------------------
# LeCroy .trc
# ------------------------------------------------------------------------------------------
#: Record types read: one record per file on a uniform time axis.
_TRC_RECORDS = {0: "single_sweep", 1: "interleaved", 8: "centered_RIS"}
_TRC_OTHER = {2: "histogram", 3: "graph", 4: "filter_coefficient", 5: "complex", 6: "extrema",
              7: "sequence", 9: "peak_detect"}
_DESC_BYTES = 346


def read_trc(path: Path, raw: bytes | mmap.mmap) -> _Table:
    """Decode a LeCroy ``.trc`` file (template LECROY_2_3; see the module docstring).

    Parameters
    ----------
    path : Path
        The file (for messages).
    raw : bytes
        Its content.

    Returns
    -------
    _Table
        Time [HORUNIT] and signal [VERTUNIT] columns and ``valid_max``.
    """
    where = str(path)
    base = raw[:64].find(b"WAVEDESC")
    if base < 0:
        raise ConfigError(where, "is not a LeCroy .trc file (no WAVEDESC descriptor in its first bytes)")
    desc = raw[base:base + _DESC_BYTES]
    if len(desc) < _DESC_BYTES:
        raise ConfigError(where, f"the WAVEDESC descriptor holds {len(desc)} of its {_DESC_BYTES} bytes: the file "
                          "is truncated")
    template = desc[16:32].split(b"\x00")[0].decode("ascii", "replace").strip()
    if template not in ("LECROY_2_3", "LECROY_2_2"):
        raise ConfigError(where, f"TEMPLATE_NAME is {template!r}; hertzchain reads the LECROY_2_3 (and 2_2) layout")
    comm_order = struct.unpack_from("<H", desc, 34)[0]
    if comm_order not in (0, 1):
        raise ConfigError(where, f"COMM_ORDER is {comm_order}; it is 0 (HIFIRST) or 1 (LOFIRST)")
    e = ">" if comm_order == 0 else "<"

    def get(fmt: str, offset: int):
        return struct.unpack_from(e + fmt, desc, offset)[0]

    comm_type = get("h", 32)
    if comm_type not in (0, 1):
        raise ConfigError(where, f"COMM_TYPE is {comm_type}; it is 0 (byte samples) or 1 (16-bit word samples)")
    width = 1 if comm_type == 0 else 2
    lengths = {}
    for name, off in (("WAVE_DESCRIPTOR", 36), ("USER_TEXT", 40), ("TRIGTIME_ARRAY", 48), ("RIS_TIME_ARRAY", 52),
                      ("RES_ARRAY1", 56), ("WAVE_ARRAY_1", 60), ("WAVE_ARRAY_2", 64), ("WAVE_ARRAY_COUNT", 116),
                      ("FIRST_VALID_PNT", 124), ("LAST_VALID_PNT", 128), ("SUBARRAY_COUNT", 144)):
        lengths[name] = get("i", off)
        if lengths[name] < 0:
            raise ConfigError(where, f"{name} is {lengths[name]}; it must not be negative")
    if lengths["WAVE_DESCRIPTOR"] < _DESC_BYTES:
        raise ConfigError(where, f"WAVE_DESCRIPTOR is {lengths['WAVE_DESCRIPTOR']} bytes; the LECROY_2_3 "
                          f"descriptor has {_DESC_BYTES}")
    record = get("H", 316)
    if record not in _TRC_RECORDS:
        what = _TRC_OTHER.get(record, "unknown")
        raise ConfigError(where, f"RECORD_TYPE is {record} ({what}); hertzchain reads single sweeps and RIS records "
                          "(RECORD_TYPE 0, 1, 8) of one waveform")
    if lengths["WAVE_ARRAY_2"]:
        raise ConfigError(where, f"WAVE_ARRAY_2 holds {lengths['WAVE_ARRAY_2']} bytes: a second data array (extrema "
                          "or complex data); save a plain waveform")
    n = lengths["WAVE_ARRAY_COUNT"]
    if n < 1:
        raise ConfigError(where, "WAVE_ARRAY_COUNT is 0: the file holds no samples")
    check_samples(n, "WAVE_ARRAY_COUNT", where)
    if lengths["WAVE_ARRAY_1"] != n * width:
        raise ConfigError(where, f"WAVE_ARRAY_1 is {lengths['WAVE_ARRAY_1']} bytes, WAVE_ARRAY_COUNT {n} samples of "
                          f"{width} byte(s) (COMM_TYPE {comm_type}) are {n * width}")
    first, last = lengths["FIRST_VALID_PNT"], lengths["LAST_VALID_PNT"]
    if not first <= last < n:
        raise ConfigError(where, f"FIRST_VALID_PNT {first} and LAST_VALID_PNT {last} are not points of the "
                          f"WAVE_ARRAY_COUNT {n} samples")
    gain, offset = get("f", 156), get("f", 160)
    interval, h_offset = get("f", 176), get("d", 180)
    if not (math.isfinite(gain) and gain != 0):
        raise ConfigError(where, f"VERTICAL_GAIN is {gain}; it must be a finite non-zero number")
    if not math.isfinite(offset):
        raise ConfigError(where, f"VERTICAL_OFFSET is {offset}; it must be a finite number")
    if not (math.isfinite(interval) and interval > 0):
        raise ConfigError(where, f"HORIZ_INTERVAL is {interval}; it must be a positive finite time")
    if not math.isfinite(h_offset):
        raise ConfigError(where, f"HORIZ_OFFSET is {h_offset}; it must be a finite time")
    start = base + sum(lengths[k] for k in ("WAVE_DESCRIPTOR", "USER_TEXT", "TRIGTIME_ARRAY", "RIS_TIME_ARRAY",
                                            "RES_ARRAY1"))
    held = max(0, min(len(raw) - start, n * width))
    if held != n * width:  # checked on the file's size, before the array is read
        raise ConfigError(where, f"the data array holds {held} of its {n * width} bytes (WAVE_ARRAY_1): the "
                          "file is truncated")
    payload = raw[start:start + n * width]
    dtype = np.dtype(f"{e}i{width}")
    codes = np.frombuffer(payload, dtype=dtype).astype(float)
    index = np.arange(n, dtype=float)
    keep = slice(first, last + 1)
    with np.errstate(over="ignore", invalid="ignore"):  # beyond float range: refused by read_trace's checks
        t = (h_offset + interval * index)[keep]
        y = (float(gain) * codes - float(offset))[keep]
    info = np.iinfo(dtype)
    valid_max = float(gain) * (info.max if gain > 0 else info.min) - float(offset)

    def unit(off: int) -> str | None:
        text = desc[off:off + 48].split(b"\x00")[0].decode("ascii", "replace").strip()
        return text or None

    source = get("H", 344)
    label = f"C{source + 1}" if source in (0, 1, 2, 3) else "signal"
    instrument = desc[76:92].split(b"\x00")[0].decode("ascii", "replace").strip()
    return _Table(["TIME", label], np.column_stack([t, y]), [unit(244), unit(196)], np.zeros(t.size, int),
                  {"instrument": instrument, "record_type": _TRC_RECORDS[record]}, "lecroy-trc", valid_max,
                  (abs(float(gain)), -float(offset)))
