"""A barrier for compiled threads: atomic loads, stores and adds on int64 arrays, for Numba.

The threads are Python threads running ``@njit(nogil=True)`` functions (each a real OS thread,
so every thread of a barrier runs; Numba's ``prange`` may run its iterations one after another,
which would deadlock a barrier). Loads acquire and stores release, so what a thread wrote before
a barrier is seen by every thread after it. A thread that has spun for a while yields its core
(``sched_yield``): on a machine shared with other work a descheduled partner would otherwise
leave it spinning for a whole time slice.
"""

from __future__ import annotations

from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

__all__ = ["atomic_load", "atomic_store", "atomic_add", "barrier", "new_barrier", "SPINS"]

#: Spins on the barrier's flag before a thread yields its core.
SPINS = 4000


def _pointer(context, builder, sig, args):
    aryty = sig.args[0]
    ary = context.make_array(aryty)(context, builder, args[0])
    return cgutils.get_item_pointer(context, builder, aryty, ary, [args[1]])


@intrinsic
def atomic_load(typingctx, arr, idx):
    """arr[idx] of an int64 array, read with acquire ordering."""
    sig = types.int64(arr, idx)

    def codegen(context, builder, sig, args):
        return builder.load_atomic(_pointer(context, builder, sig, args), ordering="acquire", align=8)

    return sig, codegen


@intrinsic
def atomic_store(typingctx, arr, idx, val):
    """arr[idx] = val on an int64 array, written with release ordering."""
    sig = types.void(arr, idx, val)

    def codegen(context, builder, sig, args):
        builder.store_atomic(args[2], _pointer(context, builder, sig, args), ordering="release", align=8)
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def atomic_add(typingctx, arr, idx, val):
    """arr[idx] += val on an int64 array, atomically; returns the value before."""
    sig = types.int64(arr, idx, val)

    def codegen(context, builder, sig, args):
        return builder.atomic_rmw("add", _pointer(context, builder, sig, args), args[2], ordering="acq_rel")

    return sig, codegen


#: libc's sched_yield, called by name (an external symbol keeps the compiled code cacheable,
#: where a ctypes pointer would not be)
_sched_yield = types.ExternalFunction("sched_yield", types.int32())


@njit(nogil=True, cache=True)
def barrier(bar, n_threads, sense):
    """Wait until all ``n_threads`` threads have called this with the same ``bar``.

    A sense-reversing barrier: ``bar`` is an int64 array of 16 (its count and flag on a cache
    line of their own, see :func:`new_barrier`); ``sense`` the caller's own flag, 0 at first.
    Returns the flag to pass next time.
    """
    sense = 1 - sense
    if atomic_add(bar, 0, 1) == n_threads - 1:
        atomic_store(bar, 0, 0)
        atomic_store(bar, 8, sense)
    else:
        spins = 0
        while atomic_load(bar, 8) != sense:
            spins += 1
            if spins >= SPINS:
                _sched_yield()
                spins = 0
    return sense


def new_barrier():
    """A fresh barrier array for :func:`barrier` (count at 0, flag at 8: two cache lines).

    Returns
    -------
    numpy.ndarray
        int64 zeros of length 16.
    """
    import numpy as np

    return np.zeros(16, dtype=np.int64)
