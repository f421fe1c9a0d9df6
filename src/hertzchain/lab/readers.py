"""Read a measured force record, whatever the oscilloscope wrote, into SI units.

:func:`read_trace` understands

- delimited text (``,`` ``;`` tab or blanks), with or without a header, a units row
  (``(s),(N)`` as PicoScope writes it), decimal commas, an Excel ``sep=;`` first line,
  ``#`` comments, a byte-order mark, and metadata lines above the data (Tektronix MSO/DPO
  CSV: ``Horizontal Units,s`` ... then ``TIME,CH1``);
- Tektronix TDS CSV (the metadata in the first two columns, time and value in the 4th and 5th);
- PicoScope CSV/TXT exports (``Time,Channel A`` then ``(ms),(V)``);
- Tektronix ``.isf`` (the scope's ``WFMPRE`` header and its ``CURVE`` block: every encoding,
  sample format, width and byte order; :mod:`hertzchain.lab.formats`);
- LeCroy ``.trc`` (the ``WAVEDESC`` descriptor: byte and word samples, either byte order;
  :mod:`hertzchain.lab.formats`);
- a signal of a hertzchain result (``.nc``), the instrument model's ``measured_*`` included.

The separator and the decimal mark are worked out here; the numbers are then parsed by
:func:`pandas.read_csv` and the units (``ms``, ``us``, ``mV``, ``kN`` ...) by the strict grammar of
:mod:`hertzchain.lab.units`.
Volts become newtons through the sensor's sensitivity [mV/N] (the paper's sensors are
presets, :data:`SENSOR_PRESETS`). A record whose time axis cannot hold a force pulse of a bead
chain (sample spacing or record length off by about 1e3, the mark of a wrong time unit) is
refused with a message that says which unit would fit.
"""

from __future__ import annotations

import io
import math
import os
import re
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from ..instrument import PCB_200B02_MV_PER_N, PCB_208A11_MV_PER_N
from .formats import _Table, read_isf, read_trc
from .textlayout import _layout, _number
from .units import KINDS as UNIT_KINDS, UnitError, parse_unit

__all__ = ["read_trace", "SENSOR_PRESETS", "PLAUSIBLE_SAMPLE_INTERVAL", "PLAUSIBLE_RECORD_LENGTH"]

#: Sensitivities [mV/N] of the paper's sensors (Sec. II), by preset name.
SENSOR_PRESETS = {"pcb_208a11": PCB_208A11_MV_PER_N, "pcb_200b02": PCB_200B02_MV_PER_N}

#: Sample spacing [s] a record of a bead-chain pulse can have: pulses last ~10-100 us (paper
#: Fig. 2, tau ~ 20-40 us), so a spacing above 20 us cannot resolve one, and below 10 ps no
#: scope samples.
PLAUSIBLE_SAMPLE_INTERVAL = (1e-11, 2e-5)
#: Record length [s] that can hold such a pulse: at least one pulse width (10 us), at most the
#: seconds after which every chain of the field is at rest (times of flight are ~0.1-10 ms).
PLAUSIBLE_RECORD_LENGTH = (1e-5, 10.0)

_TIME_NAMES = ("time", "t", "zeit", "temps", "x-axis")
_NETCDF = (".nc", ".nc4", ".netcdf", ".cdf", ".h5")


def _unit_factor(unit: str, where: str) -> tuple[float, str]:
    """SI factor of ``unit`` and its kind: ``"time"`` (to s), ``"force"`` (to N), ``"voltage"`` (to V),
    by the strict grammar of :mod:`hertzchain.lab.units` (never evaluated: the string is data)."""
    text = unit.strip().strip("()[]").strip()
    text = {"u": "", "": ""}.get(text, text)  # PicoScope's "(u)": no unit
    if not text:
        raise ConfigError(where, f"empty unit {unit!r}")
    try:
        factor, dims = parse_unit(text)
    except UnitError as exc:
        raise ConfigError(where, f"unknown unit {unit!r}, not one a scope writes ({exc}); use a time unit (s, ms, us, "
                          "ns), a force unit (N, mN, kN) or a voltage (V, mV)") from None
    kind = UNIT_KINDS.get(dims)
    if kind is None:
        raise ConfigError(where, f"unit {unit!r} is neither a time, a force nor a voltage")
    return factor, kind


#: Bytes of a text file read before its layout is known: its header, its first data lines (and the
#: whole of a small file). A larger file's rows are then counted from its size and parsed by pandas.
TEXT_HEAD = 1 << 20


def _read_file(path: Path, suffix: str) -> _Table:
    """A scope file's table, its header looked at before its bulk is read.

    The file is opened as a received one (:func:`hertzchain.received.open_received`: a regular
    file, so a FIFO cannot hang the command) and its first bytes say the format. A LeCroy
    ``.trc`` or Tektronix ``.isf`` is then memory-mapped: :func:`~hertzchain.lab.formats.read_trc`
    and :func:`~hertzchain.lab.formats.read_isf` check the header (its sample count against
    :func:`~hertzchain.lab.formats.check_samples` and the file's size) and copy only the data the
    header declares, so a 3 GB file of which the record is a few MB costs a few MB (it was read
    whole, 3.2 GB). Delimited text is read whole up to :data:`TEXT_HEAD`; a larger file has its
    layout read from that head, its rows counted from its size (refused above
    :data:`~hertzchain.lab.formats.MAX_SAMPLES`) and its numbers parsed by pandas from the file.
    """
    import mmap

    from ..received import open_received

    where = str(path)
    with open_received(path) as fh:
        size = os.fstat(fh.fileno()).st_size
        try:
            head = fh.read(TEXT_HEAD)
        except OSError as exc:
            raise ConfigError(where, f"cannot read the file: {exc.strerror or exc}") from None
        if not size or not head.strip():
            raise ConfigError(where, "is empty")
        isf = head.lstrip()[:5].upper() in (b":WFMP", b":WFMO") or suffix == ".isf"
        if isf or suffix == ".trc" or b"WAVEDESC" in head[:64]:
            with mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as raw:
                return read_isf(path, raw) if isf else read_trc(path, raw)
        if size <= len(head):
            return _read_text(path, head)
        from .bigtext import read_big_text

        table = read_big_text(path, fh, head, size)
        if table is None:  # a Tektronix TDS CSV its Record Length bounds: read whole
            fh.seek(0)
            return _read_text(path, fh.read())
        return table


# ------------------------------------------------------------------------------------------
# delimited text
# ------------------------------------------------------------------------------------------
def _read_text(path: Path, raw: bytes) -> _Table:
    where = str(path)
    lay = _layout(where, raw)
    if lay.tds:
        return _read_tds_csv(path, lay.numbered)
    numbered, sep, decimal, start, width, names = lay.numbered, lay.sep, lay.decimal, lay.start, lay.width, lay.names
    units, meta, rows = lay.units, lay.meta, lay.rows
    import pandas as pd

    body = rows[start:]
    for no, cells in body:
        if len(cells) != width:
            raise ConfigError(where, f"line {no} has {len(cells)} field(s) where the data above has {width}: "
                              f"{' '.join(cells)[:60]!r}")
    text_block = "\n".join(numbered[start + i][1] for i in range(len(body)))
    ncols = max(len(numbered[start + i][1].split(sep)) if sep else len(c) for i, (_, c) in enumerate(body))
    try:
        frame = pd.read_csv(io.StringIO(text_block), sep=sep if sep is not None else r"\s+", decimal=decimal,
                            header=None, skip_blank_lines=False, names=range(ncols),
                            skipinitialspace=True)
    except (pd.errors.ParserError, ValueError) as exc:
        raise ConfigError(where, f"cannot split the data into columns ({exc})") from None
    frame = frame.iloc[:, :width]
    lineno = np.array([no for no, _ in body])
    data = np.empty((len(frame), width))
    for j in range(width):
        col = frame.iloc[:, j]
        if col.dtype.kind in "fi" and not col.isna().any():
            data[:, j] = col.to_numpy(dtype=float)
            continue
        # Slow path only for a column pandas could not read as numbers: find the bad cell
        # (or PicoScope's infinity sign for an out-of-range sample).
        cells = col.astype(str).where(col.notna(), "").str.strip().str.strip('"')
        values = cells.map(lambda c: _number(c, decimal))
        bad = values.isna().to_numpy()
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            label = names[j] if names else f"{j}"
            raw_cell = body[i][1][j]
            what = "an empty cell" if raw_cell == "" else f"{raw_cell!r} is not a number"
            raise ConfigError(where, f"line {lineno[i]}, column {label!r}: {what}")
        data[:, j] = values.to_numpy(dtype=float)
    columns = names if names is not None else [str(j) for j in range(width)]
    return _Table(columns, data, units, lineno, meta, "text")


def _read_tds_csv(path: Path, numbered: list[tuple[int, str]]) -> _Table:
    """Tektronix TDS1000/2000 CSV: ``name,value,,time,value,`` on every line."""
    meta, data, lines = {}, [], []
    for no, ln in numbered:
        cells = [c.strip() for c in ln.split(",")]
        if len(cells) < 5:
            raise ConfigError(str(path), f"line {no}: a Tektronix CSV line has at least 5 fields "
                              f"(name, value, '', time, value), got {len(cells)}")
        if cells[0]:
            meta[cells[0]] = cells[1]
        t, v = _number(cells[3], "."), _number(cells[4], ".")
        if t is None or v is None:
            raise ConfigError(str(path), f"line {no}: {cells[3]!r}, {cells[4]!r} are not numbers")
        data.append((t, v))
        lines.append(no)
    name = meta.get("Source", "CH1")
    return _Table(["TIME", name], np.asarray(data, float), [meta.get("Horizontal Units"), meta.get("Vertical Units")],
                  np.asarray(lines), meta, "tektronix-csv")


def _read_result(path: Path, column) -> _Table:
    """A signal of a hertzchain result; ``column`` names it (``sensor_force:12`` for one sensor)."""
    import xarray as xr

    from ..result import load

    try:
        ds = load(path)
    except (OSError, ValueError) as exc:
        raise ConfigError(str(path), f"is not a hertzchain NetCDF result ({exc})") from None
    signals = [str(v) for v in ds.data_vars if any(str(d).endswith("time") for d in ds[v].dims)
               and ds[v].attrs.get("units") == "N"]
    name, _, index = str(column if column is not None else "").partition(":")
    if not name:
        name = next((s for s in ("measured_wall_force", "wall_force") if s in signals), signals[0] if signals else "")
    if name not in signals:
        raise ConfigError("--column", f"{name!r} is not a force signal of {path.name}; available: {', '.join(signals)}")
    da: xr.DataArray = ds[name]
    tdim = next(d for d in da.dims if str(d).endswith("time"))
    others = [d for d in da.dims if d != tdim]
    if others:
        dim = others[0]
        if not index:
            raise ConfigError("--column", f"{name} has one trace per {dim} ({list(da[dim].values)}): "
                              f"choose one as {name}:{da[dim].values[0]}")
        try:
            da = da.sel({dim: int(index)})
        except (KeyError, ValueError):
            raise ConfigError("--column", f"{name} has no {dim} {index}; available: {list(da[dim].values)}") from None
    t = da[tdim].values
    if np.issubdtype(t.dtype, np.timedelta64):
        t = t / np.timedelta64(1, "s")
    label = name + (f":{index}" if others else "")
    valid_max = da.attrs.get("valid_max")  # the instrument model's full scale (measured_* signals)
    return _Table(["time", label], np.column_stack([np.asarray(t, float), da.values.astype(float)]), ["s", "N"],
                  np.zeros(t.size, int), {}, "hertzchain", None if valid_max is None else float(valid_max))


# ------------------------------------------------------------------------------------------
def _split_unit(name: str) -> tuple[str, str | None]:
    """``Time (ms)`` -> (``time``, ``ms``); ``time_ms`` -> (``time``, ``ms``) when ``ms`` is a unit."""
    m = re.fullmatch(r"(.*?)\s*[\[(]\s*([^\])]+?)\s*[\])]", name.strip())
    if m:
        return m.group(1).strip().lower(), m.group(2).strip()
    for sep in ("_", "/", " "):
        if sep in name:
            base, unit = name.rsplit(sep, 1)
            try:
                _unit_factor(unit, name)
            except ConfigError:
                continue
            return base.strip().lower(), unit
    return name.strip().lower(), None


def _pick_column(table: _Table, wanted, time_index: int, path: str) -> int:
    cols = table.columns
    listing = ", ".join(f"{i}: {c!r}" for i, c in enumerate(cols))
    if wanted is not None and not isinstance(wanted, (int, np.integer)) and str(wanted).strip().lstrip("-").isdigit():
        wanted = int(wanted)
    if isinstance(wanted, (int, np.integer)):
        if not -len(cols) <= wanted < len(cols):
            raise ConfigError("--column", f"{wanted} is out of range: {path} has the columns {listing}")
        index = int(wanted) % len(cols)
    elif wanted is not None:
        key = str(wanted).strip().lower()
        hits = [i for i, c in enumerate(cols) if c.strip().lower() == key or _split_unit(c)[0] == key]
        if not hits:
            raise ConfigError("--column", f"no column {wanted!r} in {path}; its columns are {listing}")
        index = hits[0]
    else:
        others = [i for i in range(len(cols)) if i != time_index]
        if not others:
            raise ConfigError(path, f"has a single column ({listing}); a record needs a time column and a signal")
        if len(others) == 1:
            index = others[0]
        else:
            forces = [i for i in others if "force" in cols[i].lower()]
            if len(forces) != 1:
                raise ConfigError("--column", f"{path} has several signal columns ({listing}): choose one "
                                  "with --column NAME_OR_INDEX (column= in Python)")
            index = forces[0]
    if index == time_index:
        raise ConfigError("--column", f"column {cols[index]!r} is the time column of {path}")
    return index


def _time_index(table: _Table) -> int:
    for i, c in enumerate(table.columns):
        if _split_unit(c)[0] in _TIME_NAMES:
            return i
    return 0


def _baseline(t: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Mean of the record before the pulse rises (the chain is at rest before the impact), and
    its standard error [N].

    The pulse starts where the signal first leaves the first samples' level by 5 % of its
    largest excursion; the earlier 80 % of those samples are the candidates. They give the
    level only if they are flat: the means of their two halves may differ by no more than
    three standard errors. A record that starts on the pulse's slow front, or with fewer than
    ten candidates, keeps its values (nothing is removed: a fit can free ``baseline``).

    The mean, not the median: the median of quantised samples (an 8-bit scope whose noise is
    below one code) snaps to a whole code, a bias of up to half a code that no error bar holds
    (issue 36: 2.2 N on a 20 mV/code record, a striker speed 10 sigma off). The mean of such
    samples is still off by the quantiser's dither bias (up to ~0.1 code at a noise of a
    quarter code), which :func:`hertzchain.lab.fit_traces` removes by fitting the baseline of
    a quantised record with the quantiser's expected value (:mod:`hertzchain.lab.quantised`).
    """
    head = np.median(y[: max(5, y.size // 50)])
    dev = np.abs(y - head)
    rise = np.flatnonzero(dev > 0.05 * dev.max())
    n = int(0.8 * (rise[0] if rise.size else y.size))
    if n < 10:
        return 0.0, 0.0
    pre = y[:n]
    spread = float(np.std(pre, ddof=1))
    # Standard error of a mean of n/2 samples: spread / sqrt(n/2); of the difference of two.
    drift = abs(float(np.mean(pre[n // 2:]) - np.mean(pre[: n // 2])))
    if drift > 3.0 * spread * math.sqrt(2.0 / (n // 2)) + 1e-12 * float(np.ptp(y)):
        return 0.0, 0.0
    return float(np.mean(pre)), spread / math.sqrt(n)


def read_trace(path: str | os.PathLike, column: str | int | None = None, *, sensitivity: float | None = None,
               sensor: str | None = None, time_unit: str | None = None, signal_unit: str | None = None,
               time_column: str | int | None = None, baseline: bool = True, check: bool = True):
    """Read one measured force record into SI units (time [s], force [N]).

    Parameters
    ----------
    path : str or os.PathLike
        Delimited text (``.csv``, ``.txt``, ``.dat``...), Tektronix CSV or ``.isf``, PicoScope
        CSV/TXT, LeCroy ``.trc``, or a hertzchain result ``.nc`` (see the module docstring).
    column : str or int, optional
        The signal column by header name (with or without its unit, case-insensitive) or
        0-based index among all columns (the time column included). Default: the only column
        besides time, or the one whose name contains "force". For a result ``.nc``: a signal
        name, ``NAME:INDEX`` for one sensor (``sensor_force:12``); default the measured or
        ideal wall force.
    sensitivity : float, optional
        Sensor sensitivity [mV/N]; the signal is then a voltage (its unit, or V when the file
        names none) and is divided by it.
    sensor : str, optional
        A sensor preset instead of ``sensitivity``: ``pcb_208a11`` (112.40 mV/N, the paper's
        wall sensor) or ``pcb_200b02`` (11.24 mV/N, the embedded one).
    time_unit : str, optional
        Unit of the time column when the file does not say (``s``, ``ms``, ``us``, ``ns``).
    signal_unit : str, optional
        Unit of the signal column when the file does not say (``N``, ``kN``, ``V``, ``mV``...).
    time_column : str or int, optional
        The time column, by name or index (default: the one named time/t, else the first).
    baseline : bool
        Subtract the level before the pulse [N]: the mean of the pre-pulse samples when they
        are flat (a record starting on the pulse's front keeps its values).
    check : bool
        Refuse a time axis that cannot hold a pulse of a bead chain (sample spacing outside
        :data:`PLAUSIBLE_SAMPLE_INTERVAL` or record length outside
        :data:`PLAUSIBLE_RECORD_LENGTH`, e.g. milliseconds read as seconds).

    Returns
    -------
    xarray.DataArray
        The force [N] along ``time`` [s] (attribute ``units``), named after the column; attrs
        ``source``, ``format`` (``text``, ``tektronix-csv``, ``tektronix-isf``, ``lecroy-trc``,
        ``hertzchain``), ``column``, ``raw_unit``, ``time_unit``, ``sensitivity_mV_per_N``
        (NaN when none was applied), ``baseline`` [N] (the level removed), ``baseline_stderr``
        [N] (its standard error) and, for the integer samples of ``.isf`` and ``.trc`` files,
        ``valid_max`` [N]: the value of the format's largest code, the scope's full scale (a
        pulse that reaches it is clipped), ``quantum`` [N] (one code step) and
        ``quantum_origin`` [N] (the value of one code: the levels are origin + i quantum).

    Raises
    ------
    ConfigError
        A missing, empty or binary-unknown file, text among the numbers (with its line), a time
        axis that does not strictly increase, a constant signal, an unknown unit, a voltage
        without a sensitivity, or an implausible time axis; the message names the file or the
        option (``--column``, ``--sensitivity``, ``--time-unit``) and what is allowed.
    """
    import xarray as xr

    path = Path(path)
    where = str(path)
    if not os.path.lexists(path):
        raise ConfigError(where, "no such file")
    if sensitivity is not None and sensor is not None:
        raise ConfigError("--sensitivity", "give either --sensitivity or --sensor, not both")
    if sensor is not None:
        key = sensor.strip().lower().replace(" ", "_")
        key = key if key.startswith("pcb_") else f"pcb_{key}"
        if key not in SENSOR_PRESETS:
            raise ConfigError("--sensor", f"unknown sensor {sensor!r}; known: {', '.join(SENSOR_PRESETS)}")
        sensitivity = SENSOR_PRESETS[key]
    if sensitivity is not None and not (isinstance(sensitivity, (int, float)) and math.isfinite(sensitivity)
                                        and sensitivity > 0):
        raise ConfigError("--sensitivity", f"must be a positive sensitivity in mV/N, got {sensitivity!r}")
    suffix = path.suffix.lower()
    if suffix in _NETCDF:
        table = _read_result(path, column)
        column = 1
    else:
        table = _read_file(path, suffix)
    if time_column is not None:
        ti = _pick_column(table, time_column, -1, where)
    else:
        ti = _time_index(table)
    ci = _pick_column(table, column, ti, where)
    t_raw, y_raw = table.data[:, ti], table.data[:, ci]

    # --- units: an option when the file says nothing; a conflict is an error, not a guess.
    def unit_of(i: int) -> str | None:
        return table.units[i] or _split_unit(table.columns[i])[1]

    t_unit_file = unit_of(ti) or table.meta.get("Horizontal Units")
    if time_unit is not None:
        if _unit_factor(time_unit, "--time-unit")[1] != "time":
            raise ConfigError("--time-unit", f"{time_unit!r} is not a time unit; use s, ms, us or ns")
        if t_unit_file and _unit_factor(t_unit_file, where)[0] != _unit_factor(time_unit, "--time-unit")[0]:
            raise ConfigError("--time-unit", f"{path.name} says its time column is in {t_unit_file}; "
                              f"--time-unit {time_unit} contradicts it (leave the option out)")
    t_unit = t_unit_file or time_unit or "s"
    t_factor, t_kind = _unit_factor(t_unit, f"{where}: time column {table.columns[ti]!r}")
    if t_kind != "time":
        raise ConfigError(where, f"the time column {table.columns[ti]!r} is in {t_unit}, not a time unit")
    y_unit = unit_of(ci) or table.meta.get("Vertical Units") or signal_unit
    if y_unit is None:
        y_unit = "V" if sensitivity is not None else "N"
    y_factor, y_kind = _unit_factor(y_unit, f"{where}: column {table.columns[ci]!r}")
    if y_kind == "time":
        raise ConfigError("--column", f"column {table.columns[ci]!r} of {path.name} is a time ({y_unit}), not a signal")
    if y_kind == "voltage":
        if sensitivity is None:
            raise ConfigError("--sensitivity", f"column {table.columns[ci]!r} of {path.name} is in {y_unit}: give "
                              "the sensor's sensitivity (--sensitivity MV_PER_N) or a preset (--sensor pcb_208a11 "
                              "or pcb_200b02) to turn volts into newtons")
        y_factor /= sensitivity * 1e-3
    elif sensitivity is not None:
        raise ConfigError("--sensitivity", f"column {table.columns[ci]!r} of {path.name} is already a force "
                          f"({y_unit}); a sensitivity applies to volts only")
    t, y = t_raw * t_factor, y_raw * y_factor

    # --- checks: what the pulse analysis and the fit rely on.
    if t.size < 10:
        raise ConfigError(where, f"holds {t.size} samples; a pulse record needs at least 10")
    bad = np.flatnonzero(~np.isfinite(y))
    if bad.size:
        i = int(bad[0])
        at = f"line {table.lines[i]}" if table.lines[i] else f"sample {i}"
        raise ConfigError(where, f"{at}: the signal is {y_raw[i]} (the scope was out of range, or a gap, or a scale "
                          "beyond float range): record again with a wider vertical range, or cut the file")
    steps = np.diff(t)
    back = np.flatnonzero(~(steps > 0))
    if back.size:
        i = int(back[0]) + 1
        at = f"line {table.lines[i]}: " if table.lines[i] else f"sample {i}: "
        raise ConfigError(where, f"{at}time does not increase ({t_raw[i - 1]:g} then {t_raw[i]:g}); the time "
                          "column must be strictly increasing (one record, in order)")
    if np.ptp(y) == 0:
        raise ConfigError(where, f"the signal {table.columns[ci]!r} is constant ({y_raw[0]:g} {y_unit}): "
                          "no pulse was recorded")
    if check:
        dt, span = float(np.median(steps)), float(t[-1] - t[0])
        lo_dt, hi_dt = PLAUSIBLE_SAMPLE_INTERVAL
        lo_span, hi_span = PLAUSIBLE_RECORD_LENGTH
        if not (lo_dt <= dt <= hi_dt and lo_span <= span <= hi_span):
            guess = next((u for u, f in (("ms", 1e-3), ("us", 1e-6), ("ns", 1e-9), ("s", 1.0))
                          if lo_dt <= dt * f / t_factor <= hi_dt and lo_span <= span * f / t_factor <= hi_span),
                         None)
            hint = (f"; if the time column is in {guess}, say so with --time-unit {guess}" if guess and
                    not t_unit_file else "")
            raise ConfigError(where, f"read in {t_unit}, the samples are {dt:.3g} s apart over {span:.3g} s; a "
                              f"force pulse in a bead chain needs a spacing in [{lo_dt:g}, {hi_dt:g}] s and a "
                              f"record of [{lo_span:g}, {hi_span:g}] s{hint}")
    level, level_err = _baseline(t, y) if baseline else (0.0, 0.0)
    name = table.columns[ci]
    attrs = {"units": "N", "long_name": f"force ({name})", "source": str(path), "format": table.fmt,
             "column": name, "raw_unit": y_unit, "time_unit": t_unit,
             "sensitivity_mV_per_N": float("nan") if sensitivity is None or y_kind != "voltage" else float(sensitivity),
             "baseline": level, "baseline_stderr": level_err}
    if table.valid_max is not None and ci == 1:
        # The scope's full scale in the record's units (CF convention valid_max): a pulse reaching
        # it is clipped (hertzchain.analysis.saturation).
        attrs["valid_max"] = table.valid_max * y_factor - level
    if table.quantum is not None and ci == 1:
        # The code grid of integer samples [N]: its step and one level's value after the
        # baseline's removal (a fit models the quantiser's expected value on it).
        attrs["quantum"] = table.quantum[0] * abs(y_factor)
        attrs["quantum_origin"] = table.quantum[1] * y_factor - level
    return xr.DataArray(y - level, dims="time", name=name,
                        coords={"time": ("time", t, {"units": "s", "long_name": "time"})}, attrs=attrs)
