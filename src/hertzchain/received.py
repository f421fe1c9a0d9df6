"""Files read from a folder that may come from someone else: opened as data, never trusted.

A design checkpoint, a sweep's chunks and tables, a reproduction's traces or a scope record may
have been made, or edited, by another person. Reading one must not hang, allocate what the file
merely *declares*, nor follow a link out of the folder it was found in:

- :func:`open_received` opens a **regular file** only: a FIFO (named pipe), a device, a socket
  or a folder is refused before it is read (opened with ``O_NONBLOCK``, checked with ``fstat``
  on the open descriptor: no window between the check and the read), and so is a symbolic link
  whose target lies outside the folder given (a link inside it is followed);
- :func:`load_npz` reads a NumPy ``.npz`` archive member by member: each member must be an
  uncompressed ``.npy`` array of plain numbers (no pickled objects), whose header, read first
  with :mod:`numpy.lib.format`, declares exactly the bytes the member holds; so an array is
  allocated only after the file has shown it holds that many bytes (a header declaring a shape
  of 10**12 in a file of a few kB is refused, not allocated).

Every refusal is a :class:`~hertzchain.errors.ConfigError` naming the file (a ``ValueError``:
a reader that sets damaged files aside catches it as such).
"""

from __future__ import annotations

import os
import stat
import zipfile
from pathlib import Path
from typing import BinaryIO

import numpy as np

from .errors import ConfigError

__all__ = ["open_received", "load_npz", "read_received"]

_KINDS = ((stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"), (stat.S_ISDIR, "a folder"))


def _kind(mode: int) -> str:
    return next((name for test, name in _KINDS if test(mode)), "not a regular file")


def _inside(path: Path, folder: Path) -> bool:
    try:
        Path(os.path.realpath(path)).relative_to(os.path.realpath(folder))
    except ValueError:
        return False
    return True


def open_received(path: str | os.PathLike, folder: str | os.PathLike | None = None) -> BinaryIO:
    """Open ``path`` for binary reading if it is a regular file (see the module docstring).

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    folder : str or os.PathLike or None
        The folder it was found in: a symbolic link to a file outside it is refused (None: any
        link to a regular file is followed).

    Returns
    -------
    file object
        Open for reading (binary, blocking).

    Raises
    ------
    ConfigError
        Naming the file: missing, unreadable, not a regular file, or a link out of ``folder``.
    """
    path = Path(path)
    where = str(path)
    try:
        if folder is not None and os.path.islink(path) and not _inside(path, Path(folder)):
            raise ConfigError(where, f"is a symbolic link to {os.path.realpath(path)}, outside {folder}; "
                              "hertzchain reads only the folder's own files")
        # O_NONBLOCK: opening a FIFO for reading would otherwise wait for a writer, forever.
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise ConfigError(where, "no such file") from None
    except OSError as exc:
        raise ConfigError(where, f"cannot be read: {exc.strerror or exc}") from None
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            raise ConfigError(where, f"is {_kind(mode)}, not a regular file; hertzchain reads only regular files")
        os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def read_received(path: str | os.PathLike, folder: str | os.PathLike | None = None,
                  max_bytes: int = 1 << 28) -> bytes:
    """The bytes of a small received file (a JSON document, a checksum), its size checked first.

    Parameters
    ----------
    path, folder : see :func:`open_received`
    max_bytes : int
        The most bytes such a file may hold (default 256 MiB).

    Returns
    -------
    bytes

    Raises
    ------
    ConfigError
        As :func:`open_received`, or a file larger than ``max_bytes``.
    """
    with open_received(path, folder) as fh:
        size = os.fstat(fh.fileno()).st_size
        if size > max_bytes:
            raise ConfigError(str(path), f"holds {size} bytes; a file of this kind holds at most {max_bytes}")
        return fh.read(max_bytes + 1)[:max_bytes]


def load_npz(path: str | os.PathLike, folder: str | os.PathLike | None = None) -> dict[str, np.ndarray]:
    """The arrays of a NumPy ``.npz`` archive, each checked before it is allocated.

    Parameters
    ----------
    path, folder : see :func:`open_received`

    Returns
    -------
    dict of str to numpy.ndarray
        By member name (without ``.npy``).

    Raises
    ------
    ConfigError
        Naming the file and the member: not a zip archive, a member that is not an uncompressed
        ``.npy`` array, an object (pickle) array, a header whose shape and type declare other
        than the bytes the member holds, or more data than half the memory available.
    """
    from .checks import available_memory

    where = str(path)
    out: dict[str, np.ndarray] = {}
    with open_received(path, folder) as fh:
        size = os.fstat(fh.fileno()).st_size
        memory = available_memory()
        if memory is not None and size > memory // 2:
            raise ConfigError(where, f"holds {size} bytes, more than half the memory available ({memory})")
        try:
            archive = zipfile.ZipFile(fh)
        except Exception as exc:  # noqa: BLE001 - a damaged zip directory raises anything (struct.error, ...)
            raise ConfigError(where, f"is not a NumPy .npz archive ({type(exc).__name__}: {exc})") from None
        with archive:
            for info in archive.infolist():
                name = info.filename
                what = f"member {name!r}"
                if not name.endswith(".npy") or "/" in name or info.is_dir():
                    raise ConfigError(where, f"{what} is not a .npy array")
                if info.compress_type != zipfile.ZIP_STORED or info.file_size != info.compress_size:
                    raise ConfigError(where, f"{what} is compressed; hertzchain writes (and reads) stored arrays")
                if info.header_offset + info.file_size > size:
                    raise ConfigError(where, f"{what} declares {info.file_size} bytes, beyond the end of the file")
                out[name[:-4]] = _member(archive, info, f"{where}: {what}")
    return out


def _member(archive: zipfile.ZipFile, info: zipfile.ZipInfo, where: str) -> np.ndarray:
    """One ``.npy`` member: its header first, then exactly the bytes it declares."""
    fmt = np.lib.format
    try:
        with archive.open(info) as m:
            version = fmt.read_magic(m)
            if version == (1, 0):
                shape, fortran, dtype = fmt.read_array_header_1_0(m)
            elif version == (2, 0):
                shape, fortran, dtype = fmt.read_array_header_2_0(m)
            else:
                raise ConfigError(where, f".npy format version {version} (hertzchain reads 1.0 and 2.0)")
            if dtype.hasobject or dtype.kind not in "biufc" or dtype.itemsize == 0:
                raise ConfigError(where, f"holds {dtype} values, not plain numbers")
            count = 1
            for n in shape:
                count *= int(n)
            header = m.tell()
            if header + count * dtype.itemsize != info.file_size:
                raise ConfigError(where, f"declares shape {shape} of {dtype} ({count * dtype.itemsize} bytes) but "
                                  f"holds {info.file_size - header} bytes of data")
            data = m.read(count * dtype.itemsize)
    except ConfigError:
        raise
    except Exception as exc:  # noqa: BLE001 - a damaged header or member raises anything (SyntaxError, TokenError, ...)
        raise ConfigError(where, f"is not a readable .npy array ({type(exc).__name__}: {exc})") from None
    if len(data) != count * dtype.itemsize:
        raise ConfigError(where, f"holds {len(data)} of its {count * dtype.itemsize} bytes")
    arr = np.frombuffer(data, dtype=dtype, count=count)
    return arr.reshape(shape[::-1]).T if fortran else arr.reshape(shape)
