"""A result written for colleagues who do not read NetCDF: CSV (spreadsheets), MATLAB ``.mat`` and
parquet (pandas, R, Julia), SI units throughout.

- CSV and parquet: one row per sample; the columns are ``time`` and every signal on the
  simulation's time axis (wall force, sensor forces, contact forces, energies, velocities,
  displacements), one column per contact, sensor or body; the CSV header names each column with
  its unit (``wall_force [N]``, ``contact_force[3] [N]``), parquet keeps the units in its schema
  metadata. Above the CSV's table, ``#`` lines carry what has no time axis: the run's attributes
  (the config and the model as JSON) and every per-contact, per-bead or per-sensor variable (dents,
  kappa, F_Y, diameters...), one line each as JSON (:func:`csv_header`); ``pandas.read_csv(path,
  comment="#")`` reads the table, :func:`read_csv_header` the lines.
- MATLAB: one variable per result variable and coordinate (``time``, ``wall_force``,
  ``contact_force`` as a time x contact matrix, ``contact``, ``diameter``...), a struct ``units``
  (``units.wall_force = 'N'``) and a struct ``attrs`` with the run's attributes (the config and
  the model as JSON text).
- H5MD, VTK (ParaView) and LAMMPS: the formats of particle codes, written by
  :mod:`hertzchain.interchange` (``*.h5md``, ``*.pvd`` with its ``.vtp`` frames, ``*.data`` with
  its input script ``in.NAME``).
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .errors import ConfigError

if TYPE_CHECKING:  # annotations only: `hertzchain run` checks --out's format before xarray is needed
    import xarray as xr

__all__ = ["EXPORT_FORMATS", "check_format", "export", "signal_table", "csv_header", "read_csv_header"]

#: File suffixes :func:`export` writes, and what they are.
EXPORT_FORMATS = {".csv": "CSV, units in the header", ".mat": "MATLAB v5, scipy.io.savemat",
                  ".parquet": "pandas + pyarrow, the [export] extra",
                  ".h5md": "H5MD 1.1 trajectories", ".pvd": "ParaView time series, .vtp frames beside it",
                  ".data": "LAMMPS data file, input script in.NAME beside it"}
#: The formats of particle codes, written by hertzchain.interchange.
_INTERCHANGE = (".h5md", ".pvd", ".data")
#: Signals first in a table, in this order (the rest follow as stored).
_ORDER = ("wall_force", "sensor_force", "contact_force", "kinetic_energy", "potential_energy", "dissipated_energy",
          "velocity", "displacement")


def check_format(path: str | Path) -> str:
    """The export format of ``path`` by its suffix, checked before any work.

    Parameters
    ----------
    path : str or pathlib.Path
        The file to write.

    Returns
    -------
    str
        ``".csv"``, ``".mat"``, ``".parquet"``, ``".h5md"``, ``".pvd"`` or ``".data"``; a ConfigError naming ``--out`` for another
        suffix, or for parquet without pyarrow (naming the ``[export]`` extra).
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in EXPORT_FORMATS:
        raise ConfigError("--out", f"{path.name!r}: export writes "
                          + ", ".join(f"*{s} ({what})" for s, what in EXPORT_FORMATS.items()))
    if suffix == ".parquet":
        try:
            import pyarrow  # noqa: F401
        except ImportError:
            raise ConfigError("--out", "writing parquet needs pyarrow: pip install 'hertzchain[export]' "
                              "(or write *.csv or *.mat, which need nothing more)") from None
    return suffix


def _one_run(ds: xr.Dataset) -> xr.Dataset:
    if "time" not in ds.coords:
        raise ConfigError("RESULT", "is not a hertzchain result (no time axis)")
    if "member" in ds.dims:
        raise ConfigError("RESULT", f"holds {ds.sizes['member']} runs (a batch or sweep chunk); export one: "
                          "ds.sel(member=N) in Python")
    return ds


def signal_table(ds: xr.Dataset):
    """The signals of a result on its ``time`` axis as one table, units in the column names.

    Parameters
    ----------
    ds : xarray.Dataset
        One run (a result of :func:`hertzchain.simulate` or a file written by :func:`hertzchain.save`).

    Returns
    -------
    pandas.DataFrame
        Column ``time [s]`` then one column per signal and per contact/sensor/body:
        ``wall_force [N]``, ``contact_force[j] [N]``, ``sensor_force[n] [N]``, ``velocity[k] [m s-1]``...
    """
    import pandas as pd

    run = _one_run(ds)
    columns = {f"time [{run.time.attrs.get('units', 's')}]": run.time.values}
    names = sorted(run.data_vars, key=lambda n: _ORDER.index(n) if n in _ORDER else len(_ORDER))
    for name in names:
        var = run[name]
        if var.dims[:1] != ("time",) or var.ndim > 2 or not np.issubdtype(var.dtype, np.number):
            continue
        unit = var.attrs.get("units", "")
        if var.ndim == 1:
            columns[f"{name} [{unit}]"] = var.values
        else:
            dim = var.dims[1]
            for k, label in enumerate(run[dim].values):
                columns[f"{name}[{label}] [{unit}]"] = var.values[:, k]
    return pd.DataFrame(columns)


def _matlab_name(name: str) -> str:
    """A valid MATLAB identifier (letters, digits, underscores; a letter first; <= 63 characters)."""
    out = re.sub(r"\W", "_", name)
    if not out[:1].isalpha():
        out = "v_" + out
    return out[:63]


def _write_mat(run: xr.Dataset, path: Path) -> None:
    from scipy.io import savemat

    variables: dict[str, Any] = {}
    units: dict[str, str] = {}
    for name in [*run.coords, *run.data_vars]:
        var = run[name]
        if not (np.issubdtype(var.dtype, np.number) or var.dtype == bool):
            continue
        key = _matlab_name(str(name))
        variables[key] = np.asarray(var.values, dtype=float if var.dtype != bool else np.uint8)
        units[key] = var.attrs.get("units", "")
    attrs: dict[str, Any] = {}
    for key, value in run.attrs.items():
        if isinstance(value, (str, int, float, np.number)) and not isinstance(value, bool):
            attrs[_matlab_name(key)] = value
        elif isinstance(value, (bool, np.bool_)):
            attrs[_matlab_name(key)] = int(value)
        elif isinstance(value, (list, tuple, np.ndarray)):
            attrs[_matlab_name(key)] = np.asarray(value)
        else:
            attrs[_matlab_name(key)] = json.dumps(value, default=str)
    variables["units"] = units
    variables["attrs"] = attrs
    with open(path, "wb") as fh:
        savemat(fh, variables, do_compression=True, oned_as="column")


def _jsonable(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    return value.item() if isinstance(value, np.generic) else value


def csv_header(ds: xr.Dataset) -> str:
    """The ``#`` lines above a CSV export: the run's attributes and its variables without a time axis.

    Parameters
    ----------
    ds : xarray.Dataset
        One run.

    Returns
    -------
    str
        Lines ``# attr NAME = JSON`` (each run attribute: the config, the model, the engine...)
        and ``# var NAME [UNIT] (DIM) = JSON`` (each variable or coordinate without a time axis,
        one value per contact, bead or sensor, e.g. ``dent``, ``kappa``, ``yield_force``), each
        value as one line of JSON (text with its newlines escaped).
    """
    run = _one_run(ds)
    lines = ["# hertzchain result as CSV: one row per sample, SI units in the column names; read the table "
             "with pandas.read_csv(path, comment='#'), these lines with hertzchain.exporting.read_csv_header"]
    for key, value in run.attrs.items():
        lines.append(f"# attr {key} = {json.dumps(_jsonable(value), default=str)}")
    for name in [*run.coords, *run.data_vars]:
        var = run[name]
        if "time" in var.dims or var.ndim > 1:
            continue
        dims = f" ({var.dims[0]})" if var.ndim else ""
        values = var.values.astype(str) if var.dtype.kind not in "biufcm" else var.values
        lines.append(f"# var {name} [{var.attrs.get('units', '')}]{dims} = {json.dumps(_jsonable(values), default=str)}")
    return "\n".join(line.replace("\r", " ") for line in lines) + "\n"


def read_csv_header(path: str | Path) -> dict:
    """The metadata of a CSV export (:func:`csv_header`), as read back.

    Parameters
    ----------
    path : str or pathlib.Path
        A CSV written by :func:`export`.

    Returns
    -------
    dict
        ``{"attrs": {name: value}, "variables": {name: {"units", "dim", "values"}}}``.

    Raises
    ------
    ConfigError
        A header line that is not ``# attr`` / ``# var`` NAME ... = JSON.
    """
    out: dict = {"attrs": {}, "variables": {}}
    pattern = re.compile(r"# (attr|var) ([^\s\[=]+)(?: \[([^\]]*)\])?(?: \((\w+)\))? = (.*)")
    with open(path, encoding="utf-8") as f:
        for no, line in enumerate(f, 1):
            if not line.startswith("#"):
                break
            if no == 1:
                continue
            m = pattern.fullmatch(line.rstrip("\n"))
            try:
                value = json.loads(m.group(5)) if m else None
            except ValueError:
                m = None
            if m is None:
                raise ConfigError(str(path), f"line {no}: not a '# attr NAME = JSON' or '# var NAME [UNIT] (DIM) = JSON' "
                                  f"header line: {line[:60]!r}")
            if m.group(1) == "attr":
                out["attrs"][m.group(2)] = value
            else:
                out["variables"][m.group(2)] = {"units": m.group(3) or "", "dim": m.group(4), "values": value}
    return out


def export(ds: xr.Dataset, path: str | Path, *, frames: int | None = None) -> Path:
    """Write a result as CSV, MATLAB, parquet, H5MD, VTK or LAMMPS input, by the file's suffix (SI units).

    Parameters
    ----------
    ds : xarray.Dataset
        One run (:func:`hertzchain.simulate`, :func:`hertzchain.load`).
    path : str or pathlib.Path
        ``*.csv`` (signals on the time axis, units in the header, the run's metadata in ``#``
        lines above it: :func:`csv_header`), ``*.mat`` (every variable,
        a ``units`` struct and an ``attrs`` struct; ``time`` [s] and ``wall_force`` [N] among
        them) or ``*.parquet`` (the CSV's table; needs pyarrow, the ``[export]`` extra); for
        particle codes ``*.h5md`` (H5MD 1.1: positions, velocities, forces of every body over
        time), ``*.pvd`` (ParaView: ``NAME_000000.vtp``... beside it) or ``*.data`` (LAMMPS data
        file, input script ``in.NAME`` beside it), see :mod:`hertzchain.interchange`.
        Written atomically; its folder is created.
    frames : int, optional
        ``*.pvd`` only: the number of frames, evenly spread over the samples (default 200).

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    from .fileio import atomic_path

    path = Path(path)
    suffix = check_format(path)
    run = _one_run(ds)
    path.parent.mkdir(parents=True, exist_ok=True)
    if suffix in _INTERCHANGE:
        from .interchange import write

        write(run, path, suffix, frames)
        return path
    with atomic_path(path) as tmp:
        if suffix == ".csv":
            with open(tmp, "w", encoding="utf-8", newline="") as f:
                f.write(csv_header(run))
                signal_table(run).to_csv(f, index=False, float_format="%.10g", lineterminator="\n")
        elif suffix == ".parquet":
            table = signal_table(run)
            table.attrs = {"units": "in the column names, SI", "conventions": str(run.attrs.get("conventions", ""))}
            table.to_parquet(tmp, index=False)
        else:
            _write_mat(run, Path(tmp))
    return path
