"""The on-disk cache of the closures the engines build at run time (core/disk_cache.py): each
variant of a closure keeps its own index and data files, so that two processes compiling two
variants of one closure at once (two test workers, two Dask workers) cannot hand each other's
compiled code over (Numba names a new entry's data file by the first free number in an index it
reads and writes back without a lock)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
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



_CHILD = """
import math
import sys
from numba import njit
from hertzchain.integrate.core.disk_cache import on_disk

def make(c):
    @njit
    def inner(x):  # a closure the cached one calls by its symbol name (a loop: not inlined)
        total = x
        for i in range(int(x) + 11):
            total += c if i % 3 else math.sqrt(c * c + i)
        return total

    @njit
    def outer(x):
        return inner(x) + inner(x + 1.0)

    return on_disk(outer, "symbols", c, sources=b"test")

print(",".join(str(make(float(c))(0.0)) for c in sys.argv[1:]))
"""


def test_closures_compiled_first_in_two_processes_keep_their_own_code(tmp_path):
    """Each process compiles one variant first (Numba numbered both 1 and stored both under one
    symbol name); a third loads both from the cache and must run each variant's own code."""
    import os
    import subprocess
    import sys

    script = tmp_path / "child.py"
    script.write_text(_CHILD)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}

    def run(*consts):
        out = subprocess.run([sys.executable, str(script), *consts], env=env, capture_output=True, text=True,
                             check=True)
        return [float(x) for x in out.stdout.strip().split(",")]

    def expected(c):  # the same sums in Python
        def inner(x):
            return x + sum(c if i % 3 else math.sqrt(c * c + i) for i in range(int(x) + 11))
        return inner(0.0) + inner(1.0)

    one, two = expected(1.0), expected(2.0)
    assert run("1") == pytest.approx([one], rel=1e-14)
    assert run("2") == pytest.approx([two], rel=1e-14)
    assert run("1", "2") == pytest.approx([one, two], rel=1e-14)  # without random numbers: [one, one]
    assert run("2", "1") == pytest.approx([two, one], rel=1e-14)
