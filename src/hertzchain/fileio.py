"""Safe file writing shared by every part of hertzchain (results, figures, reports, sweeps, designs).

A file is written under a unique temporary name in its target folder, flushed to disk, then
renamed over the target in one step (``os.replace``), so a reader never sees half a file and two
writers never share a temporary name. A failed write leaves the target as it was and removes the
temporary file.
"""

from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator


@contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a unique temporary path beside ``path``; on success rename it onto ``path``.

    Parameters
    ----------
    path : str or os.PathLike
        Final file name. Its folder must exist.

    Yields
    ------
    pathlib.Path
        Where the caller writes (e.g. ``ds.to_netcdf(tmp)``, ``fig.savefig(tmp, format="png")``).
        Pass the format explicitly to writers that guess it from the suffix: the temporary
        name ends in ``.tmp``.
    """
    path = Path(path)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    # mkstemp creates the file private (0600); give it the permissions of an ordinary new file.
    umask = os.umask(0)
    os.umask(umask)
    os.fchmod(fd, 0o666 & ~umask)
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically (see :func:`atomic_path`)."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_path`)."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
