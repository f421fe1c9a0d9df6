"""The output folder of a sweep: chunk files with their SHA-256, the folder lock, ``sweep.json``
and ``metrics.csv`` (the layout is described in :mod:`hertzchain.sweep`).

Every file is written through :mod:`hertzchain.fileio` (never a half file under a final name)
and read back as a received file (:mod:`hertzchain.received`: regular files of the folder only);
a chunk counts as finished only when its checksum, its sweep hash and its members match.
``--force`` onto another sweep's folder moves that sweep's results into ``.replaced-<hash>/``
and removes them only once the new sweep is complete: a run killed midway leaves them whole (and
rerunning the old sweep with ``--force`` takes them back without computing anything).
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import os
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator, Sequence

import numpy as np

from ..errors import ConfigError, HertzchainError
from .schema import SweepConfig

#: Wall-pulse metrics of each member (paper Sec. III), in SI units, with their PulseFit attribute.
METRIC_COLUMNS = {"F_m": "peak_force", "T": "time_of_flight", "tau": "duration", "Q_F": "front_momentum",
                  "Q_T": "tail_momentum"}
_METRIC_UNITS = {"F_m": ("N", "peak wall force F_m of the cos^6 fit"),
                 "T": ("s", "time of flight T of the wall pulse"),
                 "tau": ("s", "duration tau of the wall pulse"),
                 "Q_F": ("N s", "front momentum Q_F (integral of F up to T + tau)"),
                 "Q_T": ("N s", "tail momentum Q_T (integral of F after T + tau)")}
#: What every member's run leaves besides its pulse fit (computed from its records in the chunk).
RUN_METRICS = {"kinetic_energy_end": ("J", "kinetic energy at the end of the run"),
               "potential_energy_end": ("J", "elastic (Hertz) energy at the end of the run"),
               "dissipated_energy_end": ("J", "energy dissipated by the contacts during the run"),
               "force_over_yield": ("1", "largest contact force over its elastic limit (yield) during the run")}
#: Per-member variables of every chunk, in the order of metrics.csv (after member, chunk and the
#: swept parameters), with their units.
TABLE_COLUMNS = {"dt": "s", "peak_wall_force": "N", "peak_wall_time": "s", "elastic_limit_exceeded": "1",
                 **{k: u for k, (u, _) in _METRIC_UNITS.items()}, **{k: u for k, (u, _) in RUN_METRICS.items()},
                 "fit_error": ""}
#: Elastic-plastic metrics of each member (elastoplastic law): table column -> (chunk variable,
#: units, meaning). In a chunk only when one of its members has the law (NaN for the others).
PLASTIC_METRICS = {"plastic_work": ("plastic_work_total", "J", "plastic work done in all contacts by the end"),
                   "residual_overlap_max": ("residual_overlap_max", "m", "largest residual (permanent) overlap")}
#: A protected body's peaks (wall.type = "body"), per member, with their units.
_BODY_COLUMNS = {"peak_body_force": "N", "peak_body_acceleration": "m/s^2", "peak_body_energy": "J"}
#: Runs under gravity: the peak wall force minus the static (weight) force, per member.
_GRAVITY_COLUMNS = {"peak_wall_force_dynamic": "N"}
#: Units of every column metrics.csv may have (the optional ones after fit_error when present).
COLUMN_UNITS = {**TABLE_COLUMNS, **_BODY_COLUMNS, **_GRAVITY_COLUMNS, **{c: u for c, (_, u, _) in PLASTIC_METRICS.items()}}
_CHUNK_NAME = "chunk_{:05d}.nc"
#: The full records of the members named by ``sweep.traces`` (store = "metrics"), one file per chunk.
_TRACES_NAME = "traces_{:05d}.nc"


class SweepMismatch(HertzchainError):
    """``out_dir`` already holds the results of a different sweep."""


class SweepLocked(HertzchainError):
    """Another sweep is writing into ``out_dir`` now."""


def _write_chunk(ds, path: Path) -> None:
    """Write a chunk (hertzchain.fileio: never a half file under ``path``) and its SHA-256 beside it.

    The file is built in memory so that the checksum is that of the bytes written; the checksum
    file comes second, so a chunk without one (killed in between) is simply computed again.
    """
    from ..fileio import write_bytes, write_text
    from ..result import netcdf_bytes

    # Force records are mostly zeros before the pulse arrives: gzip shrinks them ~5-10x, losslessly.
    encoding = {name: {"compression": "gzip", "compression_opts": 4, "shuffle": True}
                for name, var in ds.data_vars.items() if var.dtype.kind == "f" and var.size > 1000}
    data = netcdf_bytes(ds, encoding)
    write_bytes(path, data)
    write_text(_checksum_path(path), hashlib.sha256(data).hexdigest() + "\n")


def _checksum_path(path: Path) -> Path:
    return path.with_name(path.name + ".sha256")


def _checksum_ok(path: Path) -> bool:
    """True when ``path`` has the SHA-256 recorded beside it (a damaged or unrecorded chunk: False).

    Both are read as received files (:mod:`hertzchain.received`): regular files of the chunk
    folder only, so a FIFO named like a chunk is recomputed (and its replacement refused by
    :mod:`hertzchain.fileio`, which names it) instead of hanging the sweep."""
    from ..received import open_received, read_received

    try:
        recorded = read_received(_checksum_path(path), path.parent, max_bytes=1024).decode("ascii").strip()
        digest = hashlib.sha256()
        with open_received(path, path.parent) as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                digest.update(block)
    except (OSError, ValueError):
        return False
    return digest.hexdigest() == recorded


def _chunk_is_done(path: Path, sweep_hash: str, members, traced: Sequence[int] = ()) -> bool:
    """True when ``path`` is a complete, undamaged chunk of this sweep holding exactly ``members``
    (and, with ``traced``, its traces file beside it holding exactly those members)."""
    if not _file_holds(path, sweep_hash, members):
        return False
    return not traced or _file_holds(_traces_path(path), sweep_hash, traced)


def _traces_path(chunk: Path) -> Path:
    return chunk.with_name(_TRACES_NAME.format(int(chunk.stem.split("_")[1])))


def _file_holds(path: Path, sweep_hash: str, members) -> bool:
    import h5py

    if not os.path.lexists(path) or not _checksum_ok(path):
        return False
    try:
        # h5py directly (a NetCDF-4 file is an HDF5 file): ~10x faster than h5netcdf, ~100x than
        # xarray.open_dataset, which decodes every variable; a million members are 2000 chunks.
        with h5py.File(path, "r") as f:
            if _text(f.attrs.get("sweep_hash")) != sweep_hash or not _table_shapes_ok(f, len(members)):
                return False
            return np.array_equal(f["member"][...], np.asarray(members))
    except (OSError, ValueError, KeyError, TypeError, AttributeError):  # unreadable or foreign: recompute it
        return False


def _table_shapes_ok(f, n: int) -> bool:
    """The per-member variables of a chunk (what the metrics table reads) are ``n`` values each,
    of numbers (``fit_error``: text): checked from the file's declarations before anything is
    read, so a variable declaring 10**12 members is never allocated, and a damaged or foreign
    chunk is computed again rather than breaking the table."""
    import h5py

    names = ["member", *TABLE_COLUMNS, *_BODY_COLUMNS, *(var for var, *_ in PLASTIC_METRICS.values())]
    for name in names:
        if name not in f:
            if name == "member":
                return False
            continue
        d = f[name]
        if not isinstance(d, h5py.Dataset) or d.shape != (n,):
            return False
        if d.dtype.kind not in ("OSU" if name == "fit_error" else "fiub"):
            return False
    return True


def _text(x: Any) -> Any:
    return x.decode() if isinstance(x, bytes) else x



def _sweep_json(cfg: SweepConfig) -> dict:
    from .. import __version__

    return {"hash": cfg.hash, "n_members": cfg.n_members, "n_chunks": len(cfg.chunks()),
            "chunk_size": cfg.sweep.chunk_size, "parameters": cfg.parameter_names,
            "definition": cfg.definition(), "hertzchain_version": __version__,
            "created_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")}


@contextmanager
def _folder_lock(out: Path, kind: str = "sweep", error: type[HertzchainError] | None = None) -> Iterator[None]:
    """Hold ``out/.{kind}.lock`` (``flock``, released by the system even if the process is killed);
    refuse with ``error`` (:class:`SweepLocked`) when another run of that kind holds it. Also used
    by ``hertzchain design`` (``kind="design"``)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX: no lock
        yield
        return
    path = out / f".{kind}.lock"
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        raise ConfigError(str(out), f"cannot create the {kind} lock file: {exc.strerror}") from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            holder = os.pread(fd, 64, 0).decode("ascii", "replace").strip() or "?"
            raise (error or SweepLocked)(f"{out} is in use by another {kind} (process {holder}); wait for it to "
                                         "finish (rerunning afterwards resumes it) or choose another --out") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, str(os.getpid()).encode(), 0)
        yield
    finally:
        os.close(fd)  # closing releases the lock


def _prepare_out_dir(cfg: SweepConfig, out: Path, force: bool) -> Path:
    """Create ``out``'s chunk folder; refuse (or, with ``force``, clear) the results of a different sweep.
    Called with the folder lock held."""
    from ..fileio import write_text

    chunks = out / "chunks"
    meta = out / "sweep.json"
    if os.path.lexists(meta):
        old = _recorded_hash(meta)
        if old != cfg.hash:
            if not force:
                raise SweepMismatch(f"{out} holds the results of a different sweep (hash {str(old)[:12]}, this one "
                                    f"{cfg.hash[:12]}); choose another output folder or use --force to replace them")
            # --force: the other sweep's results are kept until this one is complete (a kill midway
            # leaves them whole), then removed (:func:`_drop_replaced`).
            _set_aside(out, old)
    elif chunks.exists() and any(chunks.glob("chunk_*.nc")) and not force:
        raise SweepMismatch(f"{chunks} holds chunk files but no sweep.json; use --force to replace them")
    _restore(out, cfg.hash)  # this sweep's own results, set aside by a --force run killed midway
    chunks.mkdir(parents=True, exist_ok=True)
    # Temporary files left by a killed run (never a finished file); safe to remove under the lock.
    for p in [*chunks.glob(".chunk_*.tmp"), *chunks.glob(".traces_*.tmp"), *out.glob(".metrics.*.tmp"),
              *out.glob(".sweep.json.*.tmp")]:
        p.unlink(missing_ok=True)
    if not meta.exists() or _recorded_hash(meta) != cfg.hash:  # a resumed sweep keeps its original record
        write_text(meta, json.dumps(_sweep_json(cfg), indent=2, default=str))
    return chunks


#: The results of another sweep replaced by ``--force``, kept until the new sweep is complete.
_REPLACED = ".replaced-{}"
#: What a sweep leaves in its folder (the folder lock stays).
_RESULTS = ("chunks", "sweep.json", "metrics.csv", "metrics.csv.json", "metrics.parquet")


def _set_aside(out: Path, old_hash: str | None) -> None:
    """Move the results of the sweep ``old_hash`` into ``out/.replaced-<hash>/`` (renames: instant)."""
    import shutil

    keep = out / _REPLACED.format(str(old_hash)[:16] if isinstance(old_hash, str) else "unknown")
    if keep.exists():  # an older copy of the same sweep's results: the ones in the folder are newer
        shutil.rmtree(keep)
    keep.mkdir()
    for name in _RESULTS:
        if os.path.lexists(out / name):
            os.replace(out / name, keep / name)


def _restore(out: Path, sweep_hash: str) -> None:
    """Move this sweep's results set aside by an interrupted ``--force`` run back into ``out``."""
    keep = out / _REPLACED.format(sweep_hash[:16])
    if not keep.is_dir() or os.path.lexists(out / "sweep.json"):
        return
    for name in _RESULTS:
        if os.path.lexists(keep / name):
            os.replace(keep / name, out / name)
    keep.rmdir()


def _drop_replaced(out: Path) -> None:
    """Remove the results of the sweeps this one replaced (called once it is complete)."""
    import shutil

    for keep in out.glob(_REPLACED.format("*")):
        if keep.is_dir() and not keep.is_symlink():
            shutil.rmtree(keep, ignore_errors=True)


def _recorded_hash(meta: Path) -> str | None:
    """The hash recorded in ``sweep.json`` (None when unreadable, or not a regular file)."""
    from ..received import read_received

    try:
        return json.loads(read_received(meta, meta.parent).decode("utf-8")).get("hash")
    except (OSError, ValueError, AttributeError):
        return None


def _metrics_table(cfg: SweepConfig, chunks_dir: Path):
    """Collect the per-member metrics of every chunk file into one DataFrame (ordered by member).

    Column by column as NumPy arrays (a million members are ~150 MB of numbers, not a billion
    Python objects); only the small per-member variables of each chunk file are read.
    """
    import h5py
    import pandas as pd

    cols = list(TABLE_COLUMNS)
    # columns only some sweeps have (NaN for the members without them, left out where no member
    # has them): a protected body's peaks (wall.type = "body"), the elastoplastic metrics
    optional = {c: c for c in (*_BODY_COLUMNS, *_GRAVITY_COLUMNS)} | {c: var for c, (var, *_) in PLASTIC_METRICS.items()}
    parts: dict[str, list] = {"member": [], "chunk": [], **{c: [] for c in [*cols, *optional]}}
    for index in range(len(cfg.chunks())):
        with h5py.File(chunks_dir / _CHUNK_NAME.format(index), "r") as f:  # h5py: see _file_holds
            members = np.asarray(f["member"][...])
            parts["member"].append(members)
            parts["chunk"].append(np.full(members.size, index, dtype=np.int64))
            for c in cols:
                parts[c].append(np.asarray(f[c][...]) if c in f else np.full(members.size, np.nan))
            for c, var in optional.items():
                parts[c].append(np.asarray(f[var][...], dtype=float) if var in f else np.full(members.size, np.nan))
    table: dict[str, Any] = {"member": np.concatenate(parts.pop("member")), "chunk": np.concatenate(parts.pop("chunk"))}
    for name in cfg.parameter_names:
        vals = [cfg.members[m][name] for m in table["member"].tolist()]
        table[name] = [json.dumps(v) if isinstance(v, (list, dict)) else v for v in vals]
    for c in cols:
        table[c] = np.concatenate(parts[c])
    for c in optional:
        values = np.concatenate(parts[c])
        if np.isfinite(values).any():
            table[c] = values
    df = pd.DataFrame(table)
    df["elastic_limit_exceeded"] = df["elastic_limit_exceeded"].astype(bool)
    df["fit_error"] = [_text(x) for x in df["fit_error"].tolist()]
    df["fit_error"] = df["fit_error"].fillna("").astype(str)
    return df
