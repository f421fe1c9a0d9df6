"""The output folder of a sweep: chunk files with their SHA-256, the folder lock, ``sweep.json``
and ``metrics.csv`` (the layout is described in :mod:`hertzchain.sweep`).

Every file is written through :mod:`hertzchain.fileio` (never a half file under a final name);
a chunk counts as finished only when its checksum, its sweep hash and its members match.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import os
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator

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
#: Elastic-plastic metrics of each member (elastoplastic law): table column -> (chunk variable,
#: units, meaning). In a chunk only when one of its members has the law (NaN for the others).
PLASTIC_METRICS = {"plastic_work": ("plastic_work_total", "J", "plastic work done in all contacts by the end"),
                   "residual_overlap_max": ("residual_overlap_max", "m", "largest residual (permanent) overlap")}
_CHUNK_NAME = "chunk_{:05d}.nc"


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
    from ..result import ENGINE

    # Force records are mostly zeros before the pulse arrives: gzip shrinks them ~5-10x, losslessly.
    encoding = {name: {"compression": "gzip", "compression_opts": 4, "shuffle": True}
                for name, var in ds.data_vars.items() if var.dtype.kind == "f" and var.size > 1000}
    data = bytes(ds.to_netcdf(None, engine=ENGINE, encoding=encoding))
    write_bytes(path, data)
    write_text(_checksum_path(path), hashlib.sha256(data).hexdigest() + "\n")


def _checksum_path(path: Path) -> Path:
    return path.with_name(path.name + ".sha256")


def _checksum_ok(path: Path) -> bool:
    """True when ``path`` has the SHA-256 recorded beside it (a damaged or unrecorded chunk: False)."""
    try:
        recorded = _checksum_path(path).read_text(encoding="ascii").strip()
        digest = hashlib.sha256()
        with open(path, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                digest.update(block)
    except (OSError, ValueError):
        return False
    return digest.hexdigest() == recorded


def _chunk_is_done(path: Path, sweep_hash: str, members: range) -> bool:
    """True when ``path`` is a complete, undamaged chunk of this sweep holding exactly ``members``."""
    import h5netcdf

    if not path.exists() or not _checksum_ok(path):
        return False
    try:
        # h5netcdf directly: ~10x faster than xarray.open_dataset, which decodes every variable.
        with h5netcdf.File(path, "r") as f:
            return (_text(f.attrs.get("sweep_hash")) == sweep_hash
                    and np.array_equal(f.variables["member"][...], np.asarray(members)))
    except (OSError, ValueError, KeyError):  # unreadable or foreign: recompute it
        return False


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
    if meta.exists():
        old = _recorded_hash(meta)
        if old != cfg.hash:
            if not force:
                raise SweepMismatch(f"{out} holds the results of a different sweep (hash {str(old)[:12]}, this one "
                                    f"{cfg.hash[:12]}); choose another output folder or use --force to replace them")
            for p in [*chunks.glob("chunk_*.nc"), *chunks.glob("chunk_*.nc.sha256"),
                      out / "metrics.csv", out / "metrics.parquet"]:
                p.unlink(missing_ok=True)
    elif chunks.exists() and any(chunks.glob("chunk_*.nc")) and not force:
        raise SweepMismatch(f"{chunks} holds chunk files but no sweep.json; use --force to replace them")
    chunks.mkdir(parents=True, exist_ok=True)
    # Temporary files left by a killed run (never a finished file); safe to remove under the lock.
    for p in [*chunks.glob(".chunk_*.tmp"), *out.glob(".metrics.*.tmp"), *out.glob(".sweep.json.*.tmp")]:
        p.unlink(missing_ok=True)
    if not meta.exists() or _recorded_hash(meta) != cfg.hash:  # a resumed sweep keeps its original record
        write_text(meta, json.dumps(_sweep_json(cfg), indent=2, default=str))
    return chunks


def _recorded_hash(meta: Path) -> str | None:
    """The hash recorded in ``sweep.json`` (None when unreadable)."""
    try:
        return json.loads(meta.read_bytes().decode("utf-8")).get("hash")
    except (OSError, ValueError, AttributeError):
        return None


def _metrics_table(cfg: SweepConfig, chunks_dir: Path):
    """Collect the per-member metrics of every chunk file into one DataFrame (ordered by member)."""
    import h5netcdf
    import pandas as pd

    cols = ["dt", "peak_wall_force", "peak_wall_time", "elastic_limit_exceeded", *METRIC_COLUMNS, "fit_error"]
    # a protected body's peaks (wall.type = "body"), where some chunk has them; NaN for other members
    body = ["peak_body_force", "peak_body_acceleration", "peak_body_energy"]
    rows: dict[str, list] = {"member": [], "chunk": [], **{c: [] for c in cols + body}}
    for index in range(len(cfg.chunks())):
        # Only these small per-member variables are read (h5netcdf directly: see _chunk_is_done).
        with h5netcdf.File(chunks_dir / _CHUNK_NAME.format(index), "r") as f:
            members = f.variables["member"][...]
            rows["member"] += members.tolist()
            rows["chunk"] += [index] * members.size
            for c in cols:
                rows[c] += [_text(x) for x in f.variables[c][...].tolist()]
            for c in body:
                rows[c] += f.variables[c][...].tolist() if c in f.variables else [float("nan")] * members.size
            for c, (var, *_) in PLASTIC_METRICS.items():
                rows.setdefault(c, [np.nan] * (len(rows["member"]) - members.size))
                rows[c] += f.variables[var][...].tolist() if var in f.variables else [np.nan] * members.size
    if all(v != v for c in body for v in rows[c]):  # NaN everywhere: no member has a body
        for c in body:
            del rows[c]
    table = {"member": rows.pop("member"), "chunk": rows.pop("chunk")}
    for name in cfg.parameter_names:
        vals = [cfg.members[m][name] for m in table["member"]]
        table[name] = [json.dumps(v) if isinstance(v, (list, dict)) else v for v in vals]
    for c in PLASTIC_METRICS:  # only sweeps with an elastoplastic member have these columns
        if c in rows and not np.any(np.isfinite(np.asarray(rows[c], dtype=float))):
            del rows[c]
    table.update(rows)
    df = pd.DataFrame(table)
    df["elastic_limit_exceeded"] = df["elastic_limit_exceeded"].astype(bool)
    df["fit_error"] = df["fit_error"].fillna("").astype(str)
    return df

