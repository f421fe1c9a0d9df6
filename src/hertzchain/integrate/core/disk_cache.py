"""Numba's on-disk cache for closures the engines build at run time (issue 37: compile once per
installation, not per process or Dask worker).

Numba keys a cached function by its bytecode and, for a closure, its cells pickled; a compiled
function pickles with an id new in every process, so a closure over compiled functions (the
threaded engine's thread function over its contact, the loops generated from a registry law over
the law's force) was compiled again in every process. :func:`on_disk` keys such a closure instead
by what it was built from: the text of the source files compiled into it and the constants it
was built with (``variant``). An edit of any of those files gives a new key (compiled afresh); a
file that cannot be read gives no key, and the closure stays cached in memory only.

Numba names a compiled function's symbol by its qualified name and a number counted from 1 in
each process (``FunctionIdentity._unique_ids``); a function loaded from the cache takes no
number. So the first closure a process compiles gets number 1 in every process: two variants of
one closure (the threaded loop of two laws) compiled first in two processes were stored under one
symbol name with two bodies, and a process that loaded both ran the first body for both (an
elastic-plastic run refused as "gains energy" after a dashpot run; numba/numba#10486).
:func:`_distinct_symbols` draws the numbers at random instead, once per process, on import.
"""

from __future__ import annotations

import hashlib
import inspect
import itertools
import secrets
from pathlib import Path

__all__ = ["on_disk", "files_digest", "function_files_digest"]

#: hertzchain/integrate/, against which the engines name the files compiled into their closures.
INTEGRATE = Path(__file__).resolve().parents[1]

_DIGESTS: dict = {}


class _RandomIds:
    """Numbers for Numba's symbol names drawn at random (62 bits, :mod:`secrets`: fresh in a
    forked process too), so that two processes never give one name to two bodies."""

    def __iter__(self):
        return self

    def __next__(self) -> int:
        return secrets.randbits(62) | 1 << 62


def _distinct_symbols() -> None:
    """Replace Numba's per-process counter of function numbers by :class:`_RandomIds` (where this
    Numba still keeps that counter: otherwise nothing changes)."""
    try:
        from numba.core.bytecode import FunctionIdentity
    except ImportError:  # pragma: no cover - Numba moved it
        return
    if isinstance(getattr(FunctionIdentity, "_unique_ids", None), itertools.count):
        FunctionIdentity._unique_ids = _RandomIds()  # type: ignore[assignment]  # (a drop-in for its count)


_distinct_symbols()

#: In every key: entries stored before the numbers were random (whose symbols may clash) are
#: never loaded.
_SYMBOLS = b"random function numbers"


def _digest(paths) -> bytes:
    h = hashlib.sha256()
    for p in paths:
        h.update(Path(p).read_bytes())
    return h.digest()


def files_digest(*paths: Path) -> bytes:
    """SHA-256 of the text of ``paths``, this package's own files (read once per process)."""
    key = tuple(str(p) for p in paths)
    if key not in _DIGESTS:
        _DIGESTS[key] = _digest(paths)
    return _DIGESTS[key]


def function_files_digest(*functions) -> bytes | None:
    """SHA-256 of the files defining ``functions`` (Python functions or Numba dispatchers: their
    ``py_func``), whole files so that module constants count; None where one has no readable
    source file (a function typed at the prompt, made by ``exec``). Read at every call (a law is
    built once per process and definition): a law file edited and registered again in the same
    session gets the key of its new text."""
    paths = []
    for fn in functions:
        if fn is None:
            continue
        try:
            path = inspect.getsourcefile(getattr(fn, "py_func", fn))
        except TypeError:
            return None
        if path is None or not Path(path).is_file():
            return None
        paths.append(Path(path).resolve())
    try:
        return _digest(sorted(set(paths)))
    except OSError:
        return None


def on_disk(dispatcher, *variant, sources: bytes):
    """Give ``dispatcher``, a closure, Numba's on-disk cache under a key made of ``variant`` and
    ``sources`` (a digest of every file compiled into it), and return it. Where Numba's caching API
    has moved, the closure stays cached in memory only."""
    try:
        from numba.core.caching import FunctionCache, IndexDataCacheFile

        key = hashlib.sha256(repr(variant).encode() + sources + _SYMBOLS).hexdigest()

        class StableKey(FunctionCache):
            def __init__(self, py_func):
                super().__init__(py_func)
                # One index and data file per key, not one per closure: Numba reads, extends and
                # writes back a function's index without a lock and names a new entry's data file
                # by the first free number, so two processes (test workers, Dask workers) compiling
                # two variants of one closure at once both wrote ".1.nbc", and one of them could
                # then load the other's code (a run that never ended, in CI).
                self._cache_file = IndexDataCacheFile(cache_path=self._cache_path,
                                                      filename_base=f"{self._impl.filename_base}-{key[:16]}",
                                                      source_stamp=self._impl.locator.get_source_stamp())

            def _index_key(self, sig, codegen):
                return (sig, codegen.magic_tuple(), (key,))

        dispatcher._cache = StableKey(dispatcher.py_func)
    except (ImportError, AttributeError, TypeError, RuntimeError, OSError):  # no usable cache: compiled per process
        pass
    return dispatcher
