"""The on-disk cache of the closures the engines build at run time (core/disk_cache.py): each
variant of a closure keeps its own index and data files, so that two processes compiling two
variants of one closure at once (two test workers, two Dask workers) cannot hand each other's
compiled code over (Numba names a new entry's data file by the first free number in an index it
reads and writes back without a lock)."""

from __future__ import annotations

from pathlib import Path

from numba import njit

from hertzchain.integrate.core.disk_cache import on_disk


def _make(power: float):
    @njit
    def f(x):
        return x**power
    return f


def test_each_variant_has_files_of_its_own():
    a = on_disk(_make(2.0), "test", 2.0, sources=b"x")
    b = on_disk(_make(3.0), "test", 3.0, sources=b"x")
    again = on_disk(_make(2.0), "test", 2.0, sources=b"x")
    paths = [Path(fn._cache._cache_file._index_path) for fn in (a, b, again)]
    assert paths[0] != paths[1] and paths[0] == paths[2]
    assert a(3.0) == 9.0 and b(3.0) == 27.0 and again(3.0) == 9.0

