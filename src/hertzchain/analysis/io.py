"""Read force records and run the pulse analysis over many signals at once.

Two sources are understood:

- a CSV file with a time column and a force column (a measured oscilloscope trace, or a
  record exported by another program), read by :func:`read_signal_csv`;
- an :class:`xarray.Dataset` of a hertzchain run (variables ``wall_force(time)``,
  ``sensor_force(time, sensor)``, ``contact_force(time, contact)``), or a NetCDF file of one.

:func:`analyze_signals` fits every selected signal with :func:`~.pulse.fit_pulse` and returns one
plain dict per signal, ready for ``pandas.DataFrame(rows)``.
"""

from __future__ import annotations

import csv
import math
import os
import re
from pathlib import Path
from typing import Any, Iterable

import numpy as np

from ..errors import ConfigError, PulseNotFound
from .pulse import fit_pulse

__all__ = ["read_signal_csv", "analyze_signals", "ROW_KEYS", "ROW_UNITS"]

#: Keys of every row returned by :func:`analyze_signals` (numbers in SI units; NaN on error).
ROW_KEYS = ("signal", "index", "peak_force", "peak_force_err", "time_of_flight",
            "time_of_flight_err", "duration", "duration_err", "front_momentum",
            "tail_momentum", "baseline", "error")
#: Units of the numbers of a row (SI), as ``analyze --json`` writes them beside each row.
ROW_UNITS = {"peak_force": "N", "peak_force_err": "N", "time_of_flight": "s", "time_of_flight_err": "s",
             "duration": "s", "duration_err": "s", "front_momentum": "N s", "tail_momentum": "N s", "baseline": "N"}

_TIME_UNITS = {"s": 1.0, "sec": 1.0, "second": 1.0, "seconds": 1.0, "ms": 1e-3, "us": 1e-6,
               "µs": 1e-6, "μs": 1e-6, "ns": 1e-9}
_FORCE_UNITS = {"n": 1.0, "newton": 1.0, "newtons": 1.0, "kn": 1e3, "mn": 1e-3}
_TIME_NAMES = ("time", "t")
_FORCE_NAMES = ("force", "f")
_NETCDF_SUFFIXES = (".nc", ".nc4", ".netcdf", ".h5", ".hdf5", ".cdf")


def _split_name(column: str, units: dict[str, float]) -> tuple[str, float | None]:
    """Split a header like ``time [ms]``, ``time (ms)``, ``time_ms`` into (base name, SI factor).

    The factor is None when the header names no unit (SI assumed); a suffix is read as a unit
    only when it is a known one, so ``wall_force`` stays a name.
    """
    name = column.strip().strip('"').strip("'").strip().lower()
    match = re.fullmatch(r"(.*?)\s*[\[(]\s*([^\])]+?)\s*[\])]", name)
    if match:
        base, unit = match.group(1).strip(), match.group(2).strip()
        return base, units.get(unit, math.nan)  # NaN: a unit is given but unknown
    for sep in ("_", "/", " "):
        if sep in name:
            base, unit = name.rsplit(sep, 1)
            if unit in units:
                return base.strip(), units[unit]
    return name, None


def _pick(header: list[str], wanted: str | int | None, names: tuple[str, ...], units: dict[str, float],
          kind: str, path: str, extra_match=None) -> tuple[int, float]:
    """Index and SI factor of the time or force column of a CSV header."""
    if isinstance(wanted, int):
        if not -len(header) <= wanted < len(header):
            raise ConfigError(path, f"{kind}_column={wanted} is out of range for {len(header)} columns")
        index = wanted % len(header)
    else:
        parsed = [_split_name(h, units) for h in header]
        if wanted is not None:
            target = _split_name(wanted, units)[0]
            hits = [i for i, (base, _) in enumerate(parsed) if base == target or header[i].strip() == wanted]
        else:
            hits = [i for i, (base, _) in enumerate(parsed) if base in names]
            if not hits and extra_match is not None:
                hits = [i for i, (base, _) in enumerate(parsed) if extra_match(base)]
        if not hits:
            raise ConfigError(path, f"no {kind} column among {header}; name it {' or '.join(names)} "
                              f"(optionally with a unit: '{names[0]}_ms', '{names[0]} [ms]') or pass "
                              f"{kind}_column=")
        if len(hits) > 1:
            raise ConfigError(path, f"several {kind} columns {[header[i] for i in hits]}; choose one with "
                              f"{kind}_column=")
        index = hits[0]
    factor = _split_name(header[index], units)[1]
    if factor is not None and math.isnan(factor):
        raise ConfigError(path, f"unknown unit in column {header[index]!r}; known {kind} units: "
                          f"{', '.join(units)}")
    return index, 1.0 if factor is None else factor


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _read_csv(path, time_column=None, force_column=None) -> tuple[np.ndarray, np.ndarray, str]:
    """Read (time [s], force [N], force column name) from a CSV file."""
    from ..received import open_received

    path = Path(path)
    where = str(path)
    try:
        with open_received(path) as fh:  # a regular file only: a FIFO would hang the read
            text = fh.read().decode("utf-8-sig")
    except ConfigError as exc:
        raise ConfigError(where, f"cannot read the file: {exc.message}") from None
    except OSError as exc:
        raise ConfigError(where, f"cannot read the file: {exc.strerror or exc}") from exc
    except UnicodeDecodeError as exc:
        raise ConfigError(where, f"is not UTF-8 text (byte {exc.start} cannot be decoded); save the CSV "
                          "as UTF-8 (plain ASCII numbers are fine)") from None
    lines = [(i + 1, ln) for i, ln in enumerate(text.splitlines())
             if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise ConfigError(where, "the file holds no data (empty, or only '#' comments)")
    sample = lines[min(1, len(lines) - 1)][1]
    delimiter = next((d for d in (";", "\t", ",") if d in sample), None)

    def split(line: str) -> list[str]:
        if delimiter is None:
            return line.split()
        return [cell.strip() for cell in next(csv.reader([line], delimiter=delimiter))]

    first = split(lines[0][1])
    has_header = not all(_is_number(cell) for cell in first)
    body = lines[1:] if has_header else lines
    if has_header:
        header = first
        t_idx, t_factor = _pick(header, time_column, _TIME_NAMES, _TIME_UNITS, "time", where)
        f_idx, f_factor = _pick(header, force_column, _FORCE_NAMES, _FORCE_UNITS, "force", where,
                                extra_match=lambda base: "force" in base)
        force_name = _split_name(header[f_idx], _FORCE_UNITS)[0]
    else:
        n_cols = len(first)
        if (time_column is None or force_column is None) and n_cols != 2:
            raise ConfigError(where, f"no header line and {n_cols} columns: expected two unnamed columns "
                              "(time [s], force [N]), a header naming them (time, force), or "
                              "time_column=/force_column= indices")
        if isinstance(time_column, str) or isinstance(force_column, str):
            raise ConfigError(where, "the file has no header line: give time_column/force_column as "
                              "0-based column indices, not names")
        t_idx = 0 if time_column is None else int(time_column)
        f_idx = 1 if force_column is None else int(force_column)
        t_factor = f_factor = 1.0
        force_name = "force"
    if t_idx == f_idx:
        raise ConfigError(where, "the time and force columns are the same column")
    rows = []
    for lineno, line in body:
        cells = split(line)
        try:
            rows.append((float(cells[t_idx]), float(cells[f_idx])))
        except (IndexError, ValueError):
            raise ConfigError(where, f"line {lineno}: cannot read a number in the time/force columns: "
                              f"{line.strip()[:80]!r}") from None
    if len(rows) < 2:
        raise ConfigError(where, f"only {len(rows)} data row(s); a signal needs many samples")
    data = np.asarray(rows, dtype=float)
    time, force = data[:, 0] * t_factor, data[:, 1] * f_factor
    if not (np.all(np.isfinite(time)) and np.all(np.isfinite(force))):
        raise ConfigError(where, "the time or force column contains NaN or infinite values")
    if np.any(np.diff(time) <= 0):
        raise ConfigError(where, "the time column is not strictly increasing")
    return time, force, force_name


def read_signal_csv(path: str | os.PathLike, *, time_column: str | int | None = None,
                    force_column: str | int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Read a force record from a CSV file, in SI units.

    The file has a time column and a force column, separated by commas, semicolons, tabs or
    blanks; lines starting with ``#`` are comments. Columns are found by their header:
    ``time`` or ``t`` and ``force`` or ``F`` (or a single name containing "force", such as
    ``wall_force``), optionally with a unit, ``time_ms``, ``time [us]``, ``force (kN)``; times
    are converted to s and forces to N. A file without a header must have exactly two numeric
    columns, time [s] then force [N].

    Parameters
    ----------
    path:
        CSV file.
    time_column, force_column:
        Header name or 0-based index of the column, when the automatic choice does not apply.

    Returns
    -------
    (time [s], force [N]) as float arrays.

    Raises
    ------
    ConfigError
        The file cannot be read, the columns cannot be identified, a unit is unknown, a value is
        not a number, or time does not increase; the message says which.
    """
    time, force, _ = _read_csv(path, time_column, force_column)
    return time, force


# --------------------------------------------------------------------------------------------
def _row(signal: str, index, time: np.ndarray, force: np.ndarray, fit_kwargs: dict) -> dict:
    row: dict[str, Any] = dict.fromkeys(ROW_KEYS, math.nan)
    row.update(signal=signal, index=index, error=None)
    try:
        fit = fit_pulse(time, force, **fit_kwargs)
    except (PulseNotFound, ConfigError) as exc:
        row["error"] = str(exc)
        return row
    for key in ROW_KEYS[2:-1]:
        row[key] = getattr(fit, key)
    return row


def _unit_factor(attrs: dict, units: dict[str, float], what: str) -> float:
    unit = attrs.get("units")
    if unit is None or str(unit).strip() == "":
        return 1.0
    factor = units.get(str(unit).strip().lower())
    if factor is None:
        raise ConfigError(what, f"unknown unit {unit!r}; known: {', '.join(units)}")
    return factor


def _dataset_rows(ds, signals: Iterable[str], fit_kwargs: dict) -> list[dict]:
    rows: list[dict] = []
    if isinstance(signals, str):
        signals = (signals,)
    for name in signals:
        if name not in ds.data_vars:
            raise ConfigError("signals", f"{name!r} is not a variable of the dataset; available: "
                              f"{', '.join(map(str, ds.data_vars))}")
        da = ds[name]
        if "time" not in da.dims or "time" not in da.coords:
            raise ConfigError(f"signals.{name}", f"has no 'time' coordinate (dims {da.dims})")
        tcoord = da["time"]
        if np.issubdtype(tcoord.dtype, np.timedelta64):  # xarray decodes 'seconds' to timedelta
            time = tcoord.values / np.timedelta64(1, "s")
        else:
            time = np.asarray(tcoord.values, dtype=float) * _unit_factor(tcoord.attrs, _TIME_UNITS, "time")
        others = [d for d in da.dims if d != "time"]
        values = np.asarray(da.transpose("time", *others).values, dtype=float)
        force_factor = _unit_factor(da.attrs, _FORCE_UNITS, name)
        values = values * force_factor
        kwargs = dict(fit_kwargs)
        if "valid_max" in da.attrs and "valid_max" not in kwargs:  # the scope's full scale: clipping
            kwargs["valid_max"] = float(da.attrs["valid_max"]) * force_factor
        if not others:
            rows.append(_row(name, None, time, values, kwargs))
            continue
        labels = [da[d].values if d in da.coords else np.arange(da.sizes[d]) for d in others]
        for pos in np.ndindex(*values.shape[1:]):
            key = tuple(lab[i].item() if hasattr(lab[i], "item") else lab[i] for lab, i in zip(labels, pos))
            index = key[0] if len(key) == 1 else key
            rows.append(_row(name, index, time, values[(slice(None),) + pos], kwargs))
    return rows


def analyze_signals(source, signals: Iterable[str] = ("wall_force",), **fit_kwargs) -> list[dict]:
    """Fit the front pulse of every selected signal (paper Sec. III) and tabulate the results.

    Parameters
    ----------
    source:
        An :class:`xarray.Dataset` of a run (``wall_force(time)``, ``sensor_force(time, sensor)``
        with ``sensor`` = bead numbers, ``contact_force(time, contact)``...), a NetCDF file of one
        (``.nc``), or a CSV file of a single record (see :func:`read_signal_csv`; ``signals`` is
        then ignored and the row is named after the force column).
    signals:
        Names of the dataset variables to analyse. A variable with dimensions besides ``time``
        gives one row per entry, its ``index`` being the coordinate value (sensor bead number,
        contact number), or a tuple of them for several extra dimensions.
    **fit_kwargs:
        Passed to :func:`~.pulse.fit_pulse` (``min_prominence``, ``baseline``...).

    Returns
    -------
    list of dict
        One row per signal with the keys of :data:`ROW_KEYS`: ``signal``, ``index`` (None for a
        1-D signal), ``peak_force`` [N], ``time_of_flight`` [s], ``duration`` [s], their ``_err``
        standard errors, ``front_momentum`` and ``tail_momentum`` [N s], ``baseline`` [N] and
        ``error`` (None, or why no pulse could be fitted; the numbers are then NaN).

    Raises
    ------
    ConfigError
        A requested variable does not exist, has no time coordinate, or the CSV is unreadable.
    """
    if isinstance(source, (str, os.PathLike)):
        path = Path(source)
        if path.suffix.lower() in _NETCDF_SUFFIXES:
            import xarray as xr  # deferred: only NetCDF input needs it

            if not path.exists():
                raise ConfigError(str(path), "no such file")
            with xr.open_dataset(path) as ds:
                return _dataset_rows(ds.load(), signals, fit_kwargs)
        time, force, name = _read_csv(path)
        return [_row(name, None, time, force, fit_kwargs)]
    if hasattr(source, "data_vars"):
        return _dataset_rows(source, signals, fit_kwargs)
    raise ConfigError("source", f"must be an xarray Dataset or a path to a CSV/NetCDF file, "
                      f"got {type(source).__name__}")
