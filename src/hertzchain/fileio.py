"""Safe file writing shared by every part of hertzchain (results, figures, reports, sweeps, designs).

A file is written under a unique temporary name in its target folder, flushed to disk, then
renamed over the target in one step (``os.replace``), so a reader never sees half a file and two
writers never share a temporary name (the last one to finish wins, with a whole file). A failed
write leaves the target as it was and removes the temporary file. The temporary name carries the
writer's host and process id (``.NAME.HOST-PID.RANDOM.tmp``): a process killed while it wrote
(SIGKILL, a power cut) cannot remove its file, so the next write to that name removes every such
file whose writer is no longer alive on this host.

Guarantees, and the :class:`~hertzchain.errors.ConfigError` (its ``field`` is the path) otherwise:

- only a regular file is ever replaced: an existing target that is a symbolic link, a FIFO, a
  device, a socket or a folder is refused, and left alone;
- a full disk (ENOSPC), a missing permission (EACCES, EPERM, a read-only file system) or a busy
  or locked file ends in one message saying so, with the partial file removed;
- the new file gets the permissions a plain ``open()`` would give it (or those of the file it
  replaces), not the private mode of a temporary file.
"""

from __future__ import annotations

import errno
import json
import math
import os
import re
import socket
import stat
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator

from .errors import ConfigError

__all__ = ["atomic_path", "write_text", "write_bytes", "check_target", "check_writable", "check_not_input",
           "json_text", "remove_stale_temporaries"]

_REASONS = {
    errno.ENOSPC: "no space left on the device",
    errno.EDQUOT: "the disk quota is exhausted",
    errno.EACCES: "permission denied",
    errno.EPERM: "operation not permitted",
    errno.EROFS: "the file system is read-only",
    errno.EBUSY: "the file is busy or locked by another program",
    errno.ETXTBSY: "the file is busy or locked by another program",
    errno.ENOENT: "its folder does not exist",
    errno.ENOTDIR: "a part of its folder path is not a folder",
    errno.ENAMETOOLONG: "the name is too long",
    errno.EFBIG: "the file is too large for the file system",
}


def _kind(mode: int) -> str:
    for test, name in ((stat.S_ISLNK, "a symbolic link"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISSOCK, "a socket"), (stat.S_ISDIR, "a folder")):
        if test(mode):
            return name
    return "not a regular file"


def check_target(path: str | os.PathLike) -> None:
    """Refuse to replace ``path`` unless it is absent or a regular file (ConfigError naming it).

    Parameters
    ----------
    path : str or os.PathLike
        The file about to be written.
    """
    path = Path(path)
    try:
        st = os.lstat(path)  # lstat: a symlink is reported as itself, not as what it points to
    except FileNotFoundError:  # absent (or its folder is): writing will create it, or say why not
        return
    except OSError as exc:
        raise ConfigError(str(path), f"cannot be written: {_reason(exc)}") from None
    if not stat.S_ISREG(st.st_mode):
        raise ConfigError(str(path), f"exists and is {_kind(st.st_mode)}; hertzchain only replaces regular files, "
                          "so it was left alone: choose another output name")


def check_writable(path: str | os.PathLike) -> None:
    """Refuse, before any work, a file that cannot be written: not a regular file (see
    :func:`check_target`), or a folder that is not a folder, read-only or not ours.

    The folder is tried for real (a temporary file made and removed at once, as the final write
    will make one): permission bits alone do not tell (an administrator, a read-only mount, an
    ACL). A folder still to be created (``hertzchain run`` creates the result's folder) is tried
    at its deepest existing ancestor, and nothing is created.

    Parameters
    ----------
    path : str or os.PathLike
        The file about to be written.

    Raises
    ------
    ConfigError
        Naming the path and the reason.
    """
    path = Path(path)
    check_target(path)
    folder = path.parent
    while not os.path.lexists(folder) and folder != folder.parent:
        folder = folder.parent
    try:
        fd, probe = tempfile.mkstemp(prefix=f".{path.name}.{_host()}-{os.getpid()}.", suffix=".tmp",
                                     dir=folder)
    except OSError as exc:
        raise ConfigError(str(path), f"cannot be written: {_reason(exc)}") from None
    os.close(fd)
    os.unlink(probe)


def check_not_input(out: str | os.PathLike, *inputs: str | os.PathLike, option: str = "--out") -> None:
    """Refuse an output that is one of the job's input files (it would be replaced, and lost).

    Parameters
    ----------
    out : str or os.PathLike
        The file about to be written.
    *inputs : str or os.PathLike
        The files the job reads.
    option : str
        How the user named the output (for the message).
    """
    for src in inputs:
        try:
            same = os.path.samefile(out, src)
        except OSError:  # one of them does not exist: not the same file
            continue
        if same:
            raise ConfigError(option, f"{str(out)!r} is the input file {str(src)!r}; writing there would replace "
                              "it: choose another output name")


def _reason(exc: OSError) -> str:
    return _REASONS.get(exc.errno or 0, exc.strerror or str(exc))


def _new_file_mode(path: Path) -> int:
    try:
        return stat.S_IMODE(os.stat(path).st_mode)
    except OSError:
        mask = os.umask(0)
        os.umask(mask)
        return 0o666 & ~mask


def _host() -> str:
    """This machine's name as it goes into a temporary name (letters, digits and dashes)."""
    return re.sub(r"[^A-Za-z0-9-]", "-", socket.gethostname())[:32] or "host"


def _alive(pid: int) -> bool:
    """Whether process ``pid`` exists on this machine."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):  # another user's process, or cannot tell: alive
        return True
    return True


#: A temporary file of an older hertzchain (no writer id in its name) is left alone this long [s].
_UNNAMED_STALE_S = 3600.0


def remove_stale_temporaries(path: str | os.PathLike) -> list[Path]:
    """Remove the temporary files that killed writes to ``path`` left behind.

    A temporary file ``.NAME.HOST-PID.RANDOM.tmp`` is stale when HOST is this machine and
    process PID is gone; one without a writer id (an older hertzchain) when it is older than an
    hour. Files of live writers, of other machines (a shared folder) and other names are kept.

    Parameters
    ----------
    path : str or os.PathLike
        The file about to be written.

    Returns
    -------
    list of pathlib.Path
        The files removed.
    """
    path = Path(path)
    prefix, host = f".{path.name}.", _host()
    removed: list[Path] = []
    try:
        entries = list(os.scandir(path.parent if str(path.parent) else "."))
    except OSError:
        return removed
    for entry in entries:
        name = entry.name
        if not (name.startswith(prefix) and name.endswith(".tmp")):
            continue
        tag = name[len(prefix):-len(".tmp")]
        m = re.fullmatch(r"(?P<host>[A-Za-z0-9-]+)-(?P<pid>\d+)\.[^.]+", tag)
        try:
            if m is not None:
                stale = m.group("host") == host and not _alive(int(m.group("pid")))
            else:
                stale = "." not in tag and time.time() - entry.stat(follow_symlinks=False).st_mtime > _UNNAMED_STALE_S
            if stale and entry.is_file(follow_symlinks=False):
                os.unlink(entry.path)
                removed.append(Path(entry.path))
        except OSError:  # gone meanwhile, or not ours to remove
            continue
    return removed


@contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a unique temporary path beside ``path``; on success rename it onto ``path``.

    Parameters
    ----------
    path : str or os.PathLike
        Final file name. Its folder must exist; an existing ``path`` must be a regular file.

    Yields
    ------
    pathlib.Path
        Where the caller writes (e.g. ``ds.to_netcdf(tmp)``, ``fig.savefig(tmp, format="png")``).
        Pass the format explicitly to writers that guess it from the suffix: the temporary
        name ends in ``.tmp``.

    Raises
    ------
    ConfigError
        The target is not a regular file, or the write failed (full disk, permissions, a locked
        file): the message names the path and the reason; the temporary file is removed and the
        target left as it was.
    """
    path = Path(path)
    check_target(path)
    remove_stale_temporaries(path)
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.{_host()}-{os.getpid()}.", suffix=".tmp",
                                        dir=path.parent)
    except OSError as exc:
        raise ConfigError(str(path), f"cannot be written: {_reason(exc)}") from None
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        try:
            yield tmp
            with open(tmp, "rb+") as fh:
                os.fsync(fh.fileno())
            os.chmod(tmp, _new_file_mode(path))
            check_target(path)  # it may have been replaced by a FIFO or a link meanwhile
            os.replace(tmp, path)
        except OSError as exc:
            raise ConfigError(str(path), f"cannot be written: {_reason(exc)}; nothing was written "
                              "(the partial file was removed)") from None
        _fsync_folder(path.parent)
    finally:
        try:
            tmp.unlink()
        except FileNotFoundError:
            pass
        except OSError:  # pragma: no cover - a folder gone read-only meanwhile: nothing more to do
            pass


def _fsync_folder(folder: Path) -> None:
    """Flush the rename itself to disk (best effort: not every system can open a folder)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically (see :func:`atomic_path`)."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def write_bytes(path: str | os.PathLike, data: bytes | memoryview) -> None:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_path`)."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def _finite_or_none(obj: Any) -> Any:
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite_or_none(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite_or_none(v) for v in obj]
    return obj


def _plain(x: Any) -> Any:
    """NumPy scalars and arrays as plain Python (then NaN/inf become null)."""
    if hasattr(x, "tolist"):
        return _finite_or_none(x.tolist())
    if isinstance(x, Path):
        return str(x)
    raise TypeError(f"{type(x).__name__} is not JSON serialisable")


def json_text(obj: Any, indent: int | None = 2) -> str:
    """Valid JSON text of ``obj``: NaN and infinities become ``null`` (bare ``NaN`` is not JSON).

    Parameters
    ----------
    obj : Any
        Plain data (dicts, lists, numbers, strings; NumPy scalars and arrays are converted).
    indent : int or None
        Passed to :func:`json.dumps`.

    Returns
    -------
    str
        Text that any JSON parser reads.
    """
    clean = _finite_or_none(obj)
    # default= sees NumPy values only after the walk above; convert them and clean again.
    return json.dumps(clean, indent=indent, allow_nan=False, default=_plain)
