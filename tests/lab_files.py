"""Oscilloscope files written from the vendors' documented layouts, and synthetic lab records.

The writers follow the formats' documentation, not hertzchain's reader:

- Tektronix TDS1000/TDS2000 "spreadsheet" CSV (TDS1000/TDS2000 series user manual, Save/Recall:
  18 setting lines, each ``name,value,,time,value,``, in the first two columns);
- Tektronix MSO/DPO CSV (setting lines ``name,value``, then ``TIME,CH1`` and the samples);
- Tektronix ``.isf`` (programmer manual, WFMPre? and CURVe?: ``:WFMPRE:`` KEY value pairs, then
  ``:CURVE #<n><length><bytes>``; value = (code - YOFF) * YMULT + YZERO, time = XZERO +
  XINCR * (i - PT_OFF));
- PicoScope 6 CSV/TXT export (``Time,Channel A`` / ``(us),(mV)`` / blank line / data);
- LeCroy ``.trc`` (remote control manual, template LECROY_2_3: 346-byte WAVEDESC block, value =
  VERTICAL_GAIN * code - VERTICAL_OFFSET, time = HORIZ_OFFSET + i * HORIZ_INTERVAL, preceded
  by the IEEE 488.2 ``#9nnnnnnnnn`` block header the scope writes to disk).
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np


def write_tds_csv(path: Path, t: np.ndarray, volts: np.ndarray, source: str = "CH1") -> Path:
    settings = [("Record Length", f"{t.size:.6e}"), ("Sample Interval", f"{t[1] - t[0]:.6e}"),
                ("Trigger Point", f"{int(np.argmin(np.abs(t))):.12e}"), ("", ""), ("", ""), ("", ""),
                ("Source", source), ("Vertical Units", "V"), ("Vertical Scale", "2.000000e-01"),
                ("Vertical Offset", "0.000000e+00"), ("Horizontal Units", "s"),
                ("Horizontal Scale", f"{(t[-1] - t[0]) / 10:.6e}"), ("Pt Fmt", "Y"), ("Yzero", "0.000000e+00"),
                ("Probe Atten", "1.000000e+00"), ("Model Number", "TDS2024B"), ("Serial Number", "C010101"),
                ("Firmware Version", "FV:v22.16")]
    lines = []
    for i, (ti, vi) in enumerate(zip(t, volts)):
        name, value = settings[i] if i < len(settings) else ("", "")
        lines.append(f"{name},{value},,{ti:.12f},{vi:.5f},")
    path.write_text("\r\n".join(lines) + "\r\n", encoding="ascii")
    return path


def write_mso_csv(path: Path, t: np.ndarray, volts: np.ndarray) -> Path:
    head = ["Model,MSO54", "Firmware Version,1.20.6.4282", ",", "Waveform Type,ANALOG", "Point Format,Y",
            "Horizontal Units,s", f"Horizontal Scale,{(t[-1] - t[0]) / 10:g}", f"Sample Interval,{t[1] - t[0]:g}",
            f"Record Length,{t.size}", "Gating,0.0% to 100.0%", "Probe Attenuation,1", "Vertical Units,V",
            "Vertical Offset,0", "Vertical Scale,0.2", "Vertical Position,0", ",", ",", ",", "Label,", "TIME,CH1"]
    body = [f"{ti:.7e},{vi:.6g}" for ti, vi in zip(t, volts)]
    path.write_text("\n".join(head + body) + "\n", encoding="ascii")
    return path


def write_picoscope(path: Path, t: np.ndarray, volts: np.ndarray, sep: str = ",") -> Path:
    """PicoScope 6 export: time in us, channel A in mV, channel B (unused) in V."""
    lines = [sep.join(["Time", "Channel A", "Channel B"]), sep.join(["(us)", "(mV)", "(V)"]), ""]
    lines += [sep.join([f"{ti * 1e6:.8f}", f"{vi * 1e3:.8f}", f"{0.001 * (i % 7):.8f}"])
              for i, (ti, vi) in enumerate(zip(t, volts))]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def isf_codes(volts: np.ndarray, ymult: float, yoff: float = 0.0, yzero: float = 0.0, width: int = 2) -> np.ndarray:
    lim = 2 ** (8 * width - 1)
    return np.clip(np.rint((volts - yzero) / ymult + yoff), -lim, lim - 1).astype(f">i{width}")


def write_isf(path: Path, t: np.ndarray, volts: np.ndarray, width: int = 2) -> Path:
    ymult = float(f"{8.0 / 2 ** (8 * width):.6E}")   # a +-4 V window over the code range, as printed
    yoff, yzero = 3.0, 0.0
    codes = isf_codes(volts, ymult, yoff, yzero, width)
    payload = codes.tobytes()
    header = (f':WFMPRE:BYT_NR {width};BIT_NR {8 * width};ENCDG BIN;BN_FMT RI;BYT_OR MSB;NR_PT {t.size};'
              f'WFID "Ch1, DC coupling, 2.0E-1 V/div, 4.0E-5 s/div, {t.size} points, Sample mode";PT_FMT Y;'
              f'XINCR {t[1] - t[0]:.6E};PT_OFF 0;XZERO {t[0]:.6E};XUNIT "s";YMULT {ymult:.6E};YZERO {yzero:.1E};'
              f'YOFF {yoff:.1E};YUNIT "V";:CURVE #{len(str(len(payload)))}{len(payload)}')
    path.write_bytes(header.encode("ascii") + payload + b"\n")
    return path


def isf_values(t: np.ndarray, volts: np.ndarray, width: int = 2) -> np.ndarray:
    """What an exact reader must return for :func:`write_isf`'s file."""
    ymult = float(f"{8.0 / 2 ** (8 * width):.6E}")
    return (isf_codes(volts, ymult, 3.0, 0.0, width).astype(float) - 3.0) * ymult


#: The sample formats of the .isf programmer manual: BN_FMT -> (NumPy kind, allowed BYT_NR).
ISF_FORMATS = {"RI": ("i", (1, 2, 4, 8)), "RP": ("u", (1, 2, 4, 8)), "FP": ("f", (4, 8))}


def isf_bytes(codes: np.ndarray, *, fmt: str = "RI", width: int = 2, order: str = "MSB", encoding: str = "BIN",
              xincr: float = 4e-7, xzero: float = -4e-5, pt_off: float = 0.0, ymult: float = 1e-3,
              yoff: float = 0.0, yzero: float = 0.0, xunit: str = "s", yunit: str = "V", short: bool = False,
              indefinite: bool = False, extra: str = "", header_over: dict | None = None) -> bytes:
    """A Tektronix .isf file of the sample ``codes`` in any documented variant (programmer manual,
    WFMPre? and CURVe?): ``fmt`` RI/RP/FP, ``width`` BYT_NR, ``order`` MSB/LSB, ``encoding``
    BIN/ASC, long or ``short`` key names, a ``#0`` block of ``indefinite`` length; ``header_over``
    replaces header values as written (to write illegal ones)."""
    kind = ISF_FORMATS[fmt][0]
    dtype = np.dtype(f"{'>' if order == 'MSB' else '<'}{kind}{width}")
    codes = np.asarray(codes)
    fields = {"BYT_NR": str(width), "BIT_NR": str(8 * width), "ENCDG": encoding, "BN_FMT": fmt, "BYT_OR": order,
              "NR_PT": str(codes.size), "WFID": f'"Ch1, DC coupling, 2.0E-1 V/div, 4.0E-5 s/div, {codes.size} points"',
              "PT_FMT": "Y", "XINCR": repr(float(xincr)), "PT_OFF": repr(float(pt_off)), "XZERO": repr(float(xzero)),
              "XUNIT": f'"{xunit}"', "YMULT": repr(float(ymult)), "YZERO": repr(float(yzero)),
              "YOFF": repr(float(yoff)), "YUNIT": f'"{yunit}"'}
    fields.update(header_over or {})
    shorts = {"BYT_NR": "BYT_N", "BIT_NR": "BIT_N", "ENCDG": "ENC", "BN_FMT": "BN_F", "BYT_OR": "BYT_O",
              "NR_PT": "NR_P", "WFID": "WFI", "PT_FMT": "PT_F", "XINCR": "XIN", "PT_OFF": "PT_O", "XZERO": "XZE",
              "XUNIT": "XUN", "YMULT": "YMU", "YZERO": "YZE", "YOFF": "YOF", "YUNIT": "YUN"}
    keys = [(shorts.get(k, k) if short else k, v) for k, v in fields.items() if v is not None]
    header = (":WFMP:" if short else ":WFMPRE:") + ";".join(f"{k} {v}" for k, v in keys) + extra + ";"
    if encoding.upper().startswith("ASC"):
        body = ",".join(repr(float(c)) if kind == "f" else str(int(c)) for c in codes).encode("ascii")
        return (header + (":CURV " if short else ":CURVE ")).encode("latin-1") + body + b"\n"
    payload = codes.astype(dtype).tobytes()
    block = b"#0" if indefinite else f"#{len(str(len(payload)))}{len(payload)}".encode("ascii")
    return (header + (":CURV " if short else ":CURVE ")).encode("latin-1") + block + payload + b"\n"


def trc_bytes(codes: np.ndarray, *, comm_type: int = 1, comm_order: int = 1, gain: float = 8.0 / 65536,
              offset: float = 0.0, interval: float = 4e-7, h_offset: float = -4e-5, block_header: bool = True,
              user_text: bytes = b"", record_type: int = 0, over: dict | None = None) -> bytes:
    """A LeCroy .trc file (template LECROY_2_3) of the sample ``codes``: ``comm_type`` 0 (bytes) or 1
    (words), ``comm_order`` 0 (HIFIRST) or 1 (LOFIRST), a user text block, with or without the
    ``#9`` block header; ``over`` sets {offset: (struct format, value)} (illegal values)."""
    e = ">" if comm_order == 0 else "<"
    codes = np.asarray(codes).astype(f"{e}i{1 if comm_type == 0 else 2}")
    desc = bytearray(346)

    def put(fmt: str, pos: int, *values) -> None:
        struct.pack_into(e + fmt, desc, pos, *values)

    put("16s", 0, b"WAVEDESC")
    put("16s", 16, b"LECROY_2_3")
    put("h", 32, comm_type)
    put("h", 34, comm_order)
    put("i", 36, 346)
    put("i", 40, len(user_text))
    put("i", 60, codes.nbytes)
    put("16s", 76, b"LECROYWR104Xi")
    put("i", 116, codes.size)
    put("i", 120, codes.size)
    put("i", 124, 0)
    put("i", 128, codes.size - 1)
    put("i", 144, 1)
    put("i", 148, 1)
    put("f", 156, gain)
    put("f", 160, offset)
    put("H", 172, 8)
    put("f", 176, interval)
    put("d", 180, h_offset)
    put("48s", 196, b"V")
    put("48s", 244, b"S")
    put("H", 316, record_type)
    put("H", 344, 0)
    for pos, (fmt, value) in (over or {}).items():
        put(fmt, pos, value)
    body = bytes(desc) + user_text + codes.tobytes()
    return (f"#9{len(body):09d}".encode("ascii") if block_header else b"") + body


def write_trc(path: Path, t: np.ndarray, volts: np.ndarray) -> Path:
    gain = np.float32(8.0 / 65536)
    offset = np.float32(0.0)
    codes = np.clip(np.rint((volts + float(offset)) / float(gain)), -32768, 32767).astype("<i2")
    desc = bytearray(346)

    def put(fmt: str, pos: int, *values) -> None:
        struct.pack_into("<" + fmt, desc, pos, *values)

    put("16s", 0, b"WAVEDESC")
    put("16s", 16, b"LECROY_2_3")
    put("H", 32, 1)                  # COMM_TYPE: word (16-bit) data
    put("H", 34, 1)                  # COMM_ORDER: LOFIRST
    put("i", 36, 346)                # WAVE_DESCRIPTOR length
    put("i", 40, 0)                  # USER_TEXT
    put("i", 48, 0)                  # TRIGTIME_ARRAY
    put("i", 52, 0)                  # RIS_TIME_ARRAY
    put("i", 60, codes.nbytes)       # WAVE_ARRAY_1 [bytes]
    put("16s", 76, b"LECROYWR104Xi")
    put("i", 92, 1234)
    put("i", 116, codes.size)        # WAVE_ARRAY_COUNT
    put("i", 120, codes.size)
    put("i", 128, codes.size - 1)
    put("i", 148, 1)
    put("f", 156, float(gain))       # VERTICAL_GAIN
    put("f", 160, float(offset))     # VERTICAL_OFFSET
    put("H", 172, 8)                 # NOMINAL_BITS
    put("f", 176, float(t[1] - t[0]))  # HORIZ_INTERVAL
    put("d", 180, float(t[0]))       # HORIZ_OFFSET
    put("48s", 196, b"V")            # VERTUNIT
    put("48s", 244, b"S")            # HORUNIT (LeCroy writes it capitalised)
    put("d", 296, 12.5)              # TRIGGER_TIME: seconds, minutes, hours, day, month, year
    put("BBBBh", 304, 30, 10, 23, 11, 2026)
    put("H", 316, 0)                 # RECORD_TYPE single_sweep
    put("H", 324, 20)                # TIMEBASE
    put("H", 326, 2)                 # VERT_COUPLING DC1M
    put("f", 328, 1.0)               # PROBE_ATT
    put("H", 344, 0)                 # WAVE_SOURCE channel 1
    body = bytes(desc) + codes.tobytes()
    path.write_bytes(f"#9{len(body):09d}".encode("ascii") + body)
    return path


def trc_values(volts: np.ndarray) -> np.ndarray:
    gain = float(np.float32(8.0 / 65536))
    return np.clip(np.rint(volts / gain), -32768, 32767) * gain


# ------------------------------------------------------------------------------------------
# synthetic laboratory data with hidden parameters
# ------------------------------------------------------------------------------------------
#: The start config of the fit tests: chain 1 of the paper, Kuwabara-Kono contacts, striker 8 mm.
START = {"chain": {"preset": "chain1"}, "striker": {"diameter_mm": 8.0, "velocity": 0.2},
         "contact": {"law": "viscoelastic", "A": 2e-6}, "run": {"duration": 3.0e-3, "sample_interval": 1e-7}}
#: The hidden truth: striker speed [m/s], sensor gain (true / nominal sensitivity), DC offset [V].
TRUTH = {"velocity": 0.23, "gain": 1.04, "offset_V": 0.03}


def truth_signal():
    """The ideal wall force of the hidden truth (time [s], force [N])."""
    import copy

    import hertzchain as hc
    from hertzchain.config import build_model, build_probes, parse_config

    data = copy.deepcopy(START)
    data["striker"]["velocity"] = TRUTH["velocity"]
    cfg = parse_config(data)
    ds = hc.simulate(build_model(cfg), cfg.run.duration, build_probes(cfg))
    return ds.time.values, ds.wall_force.values


def lab_record(signal, seed: int, noise_mV: float = 8.0):
    """One scope record of the truth: PCB 208A11 wall sensor whose real sensitivity is TRUTH gain
    times the nominal, white noise, 8-bit 2 V window, 2.5 MS/s (25 times coarser than the
    simulation), random sample-clock phase, plus a DC offset. Returns (time [s] from the trigger,
    volts, true time offset [s])."""
    from hertzchain.instrument import PCB_208A11_MV_PER_N, Instrument

    t, f = signal
    inst = Instrument(sensitivity_mV_per_N=PCB_208A11_MV_PER_N * TRUTH["gain"], noise_rms_mV=noise_mV,
                      sample_rate=2.5e6, record_length=1000, trigger_level_N=0.5, pretrigger_fraction=0.15,
                      bits=8, full_scale_V=2.0, offset_V=0.5, n_average=1, trigger_jitter=True, seed=seed)
    acq = inst.acquire(t, f)
    return acq.time, acq.volts + TRUTH["offset_V"], acq.trigger_time + float(acq.jitter[0])
