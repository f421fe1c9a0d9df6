"""The members of a batch dealt to threads of this package's own, each running a compiled loop
over its share without the GIL.

The batched engines (:mod:`.engine`, :mod:`.rkn`) ran their member loop as Numba ``prange``:
its parallel-loop compilation cost ~10 CPU-s per engine in every new process (the first design,
sweep or ensemble, each test worker, each Dask worker; issue 37), and Numba's workqueue layer
aborts the process when two threads launch such loops at once (two Dask worker threads), so
launches were serialised. Here the members, sorted most expensive first, are dealt round-robin:
thread t runs order[t], order[t + T], ... in one compiled call, so the threads' shares differ
by at most one member's cost. A member's arithmetic does not depend on the thread that runs it:
the results are the same whatever the count.
"""

from __future__ import annotations

from typing import Callable

import numba
import numpy as np

from ...parallel import on_threads

__all__ = ["default_threads", "run_dealt"]


def default_threads(n_threads: int | None) -> int:
    """``n_threads``, or Numba's configured thread count (``NUMBA_NUM_THREADS``: the usable cores
    unless set) where None."""
    return max(1, int(n_threads) if n_threads is not None else int(numba.config.NUMBA_NUM_THREADS))  # type: ignore[attr-defined]


def run_dealt(kernel: Callable, order: np.ndarray, n_threads: int | None, *args) -> None:
    """``kernel(share, *args)`` for the shares of ``order`` (member indices, most expensive
    first) dealt round-robin to ``n_threads`` threads (:func:`default_threads`); ``kernel`` a
    ``nogil`` compiled function over the members of its share. Returns when every share is done;
    the first error a share raised is raised here."""
    threads = max(1, min(default_threads(n_threads), order.shape[0]))
    on_threads(kernel, [np.ascontiguousarray(order[t::threads]) for t in range(threads)], *args)
