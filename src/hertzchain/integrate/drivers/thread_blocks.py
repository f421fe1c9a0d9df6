"""What the threaded long-chain runs share: the team of threads a compiled call runs on, and the
steps of a thread function that do not depend on the contact law.

Both thread functions (:mod:`hertzchain.integrate.drivers.threaded`'s aligned elastic one and the
one :mod:`hertzchain.integrate.drivers.threaded_laws` builds from a law's contact) cut the chain
into blocks of bodies, one per thread, agree on the adaptive step through a maximum over the
blocks and record their own block at a sample, the energies as block sums added in block
order; those parts are written once, here (inlined into each thread function, so that its loops
compile as one body).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from ..core import kernels
from ..core.barrier import barrier
from ..core.disk_cache import INTEGRATE, files_digest, on_disk
from ..core.primitives import running_max

__all__ = ["ThreadTeam", "COMPILED_IN", "kept_on_disk", "thread_start", "agree_steps", "record_block", "move_body",
           "end_sample", "column_sum"]

#: The files whose functions a thread function compiles in, besides its own module (its on-disk
#: cache key holds their text: an edit of any of them compiles it afresh).
COMPILED_IN = ("drivers/thread_blocks.py", "core/kernels.py", "core/primitives.py", "core/barrier.py",
               "core/extension.py", "core/energies.py", "core/fused.py", "core/plastic.py")


def kept_on_disk(dispatcher, module: str, *variant):
    """``dispatcher``, a thread function (or a closure it compiles in) defined in ``module`` (its
    path under ``hertzchain/integrate/``), cached on disk under ``variant`` (what a closure was
    built for) and the text of ``module`` and :data:`COMPILED_IN`
    (:func:`hertzchain.integrate.core.disk_cache.on_disk`): a new process or Dask worker loads it
    instead of compiling it (~7 CPU-s a law, issue 37), and an edit of any of those files
    compiles it afresh (Numba's own key would see ``module`` only)."""
    return on_disk(dispatcher, *variant, sources=files_digest(*(INTEGRATE / name for name in (module, *COMPILED_IN))))


class ThreadTeam(NamedTuple):
    """The ``nthr`` threads of one compiled call: thread t owns bodies and contacts
    [bounds[t], bounds[t + 1]) and the recorded contacts rec[rbounds[t]:rbounds[t + 1]]; ``bar``
    their barrier (:func:`~hertzchain.integrate.core.barrier.new_barrier`); ``pub`` (2, nthr, 2 or
    4) the blocks' published edges by parity; ``part`` (nthr,) int64 the blocks' required steps
    per block; ``energy`` (nthr, 2 or 3) their kinetic and potential energies (and plastic work);
    ``edacc`` (nthr, 2) their dissipated energy and last dissipated power (the law runs', kept
    from call to call)."""

    nthr: int
    bounds: np.ndarray
    rbounds: np.ndarray
    bar: np.ndarray
    pub: np.ndarray
    part: np.ndarray
    energy: np.ndarray
    edacc: np.ndarray


@njit(cache=True, nogil=True, inline="always")
def thread_start(team, tid, acc, wall_slot, control):
    """Thread ``tid``'s block [s, e), whether it owns the wall's contact and has neighbours on its
    left and right, its accumulators (thread 0 keeps ``acc``, the others a copy: the same
    numbers), the block length [s] of the schedule ``control`` and its steps per block and step
    count so far: (s, e, owns_wall, left, right, my, block, ns, step)."""
    s = team.bounds[tid]
    e = team.bounds[tid + 1]
    my = acc if tid == 0 else acc.copy()
    stride = control.stride
    ns = stride if stride != 0 else int(my[3])
    return s, e, s <= wall_slot < e, tid > 0, tid < team.nthr - 1, my, control.interval / control.n_sub, ns, int(my[2])


@njit(cache=True, nogil=True, inline="always")
def agree_steps(team, tid, sense, req, ns, relax, my):
    """The adaptive step's evaluation across threads: block ``tid`` requires ``req`` steps per
    block (a bound over its contacts, computed after a barrier); the chain requires the largest
    (exact: a maximum over contacts), and every thread updates its controller with it
    (``kernels._adapt_stride``). Returns (steps per block, the barrier's sense)."""
    part = team.part
    part[tid] = req
    sense = barrier(team.bar, team.nthr, sense)
    req = part[0]
    for t in range(1, team.nthr):
        req = part[t] if part[t] > req else req
    return kernels._adapt_stride(req, ns, relax, my), sense


@njit(cache=True, nogil=True, inline="always")
def record_block(team, tid, k, s, e, u, v, g, probes):
    """Sample ``k`` of block ``tid`` = [s, e): its recorded contacts' forces, its contacts' running
    maximum forces and, when asked, its bodies' velocities and positions (positions stay put in a
    block's last step, so a neighbour's first position is final)."""
    rec, out_f, out_v, record_v, out_u, record_u, fmax = (probes.rec, probes.out_f, probes.out_v, probes.record_v,
                                                          probes.out_u, probes.record_u, probes.fmax)
    for r in range(team.rbounds[tid], team.rbounds[tid + 1]):
        out_f[k, r] = g[rec[r] + 1]
    m = min(e, fmax.shape[0])
    if m > s:
        running_max(fmax[s:m], g[s + 1:m + 1])
    if record_v:
        m = min(e, out_v.shape[1])
        out_v[k, s:m] = v[s:m]
    if record_u:
        m = min(e, out_u.shape[1])
        out_u[k, s:m] = u[s:m]


@njit(cache=True, nogil=True, inline="always")
def move_body(u, v, a, g, i, f, fprev, fext, inv_mass, dt, half, last):
    """Contact i's force ``f`` into g, body i's acceleration, then its kick and drift (or, ``last``,
    the closing half kick): the Verlet's update loops, one body (``fprev`` the force of the
    contact on its left, ``fext`` and ``inv_mass`` the body's)."""
    g[i + 1] = f
    ai = (fprev - f + fext) * inv_mass
    a[i] = ai
    if last:
        v[i] += half * ai
    else:
        v[i] += dt * ai
        u[i] += dt * v[i]


@njit(cache=True, nogil=True, inline="always")
def end_sample(team, sense, ke, g):
    """A sample's last barrier (every thread has read the block sums before any writes the next
    sample's) and whether the state is still finite, from the summed kinetic energy ``ke`` and the
    first contact's force: the same answer on every thread. Returns (sense, finite)."""
    sense = barrier(team.bar, team.nthr, sense)
    return sense, np.isfinite(ke) and np.isfinite(g[1])


@njit(cache=True, nogil=True, inline="always")
def column_sum(x, col):
    """x[0, col] + x[1, col] + ... in block order (the same sum on every thread)."""
    total = x[0, col]
    for t in range(1, x.shape[0]):
        total += x[t, col]
    return total
