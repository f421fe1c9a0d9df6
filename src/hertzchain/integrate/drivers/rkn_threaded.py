"""The fourth-order integrator ``"rkn4"`` on several cores: a long aligned elastic chain cut into
blocks of bodies, one thread each (:mod:`hertzchain.integrate.drivers.rkn_threaded_kernels`).

``simulate(model, threads=T)`` (and ``threads="auto"`` on long chains, :mod:`hertzchain.engine_choice`)
with the ``rkn4`` path of an aligned elastic chain (paper eq. 1; the power law at n = 3/2 too):
:func:`hertzchain.integrate.drivers.rkn.run_rkn` advances its state with :func:`threaded_advance`
instead of ``rkn_kernels.rkn_run``. Positions, velocities, forces, the step sequence (so the
number of steps and the smallest and largest step) are bit for bit those of one thread; the
energies are block sums (relative difference ~1e-15 sqrt(N); tests/test_rkn_threaded.py bounds
it, and the probes, by 1e-12).

Cost: a step of 1e5 beads is ~1 ms on one core (six force evaluations) against eight barriers
of ~0.1-1 us each on an idle machine, so the split pays from ~1e4 beads. Shared cores: as the
threaded Verlet (:class:`hertzchain.integrate.drivers.threaded.Pace`), a chunk in which a thread
got less than ``CONTENDED`` of the wall time as CPU time is followed by one on one thread (the
one-thread engine ``rkn_kernels.rkn_run`` on the same state: the same numbers), and the faster
keeps running; the verdict carries over to the process's next run of the same chain size (its
first chunks would otherwise pay for the threads again).
"""

from __future__ import annotations

import threading
import time
from typing import Any, Callable

import numpy as np

from . import rkn_kernels as rk
from .rkn_kernels import A_STEPS
from .rkn_threaded_kernels import RknTeam, rkn_thread_run
from .threaded import MIN_SLOTS_PER_THREAD, Pace, split
from ..core.barrier import new_barrier

__all__ = ["threaded_advance", "RKN_CHUNK_BEAD_STEPS"]

#: Work (slots x steps) of one compiled call on the threads (~0.1-0.3 s on one core), so that the
#: pace between one and several threads is measured often.
RKN_CHUNK_BEAD_STEPS = 2e7

_PACES: dict[tuple[int, int], Pace] = {}


def threaded_advance(threads: int, n_slots: int, rec: np.ndarray, ends: np.ndarray) -> Callable[..., int]:
    """A replacement for ``rkn_kernels.rkn_run`` (same arguments and status) that runs on up to
    ``threads`` threads.

    Parameters
    ----------
    threads : int
        Threads asked for (fewer on a short chain: at least ``MIN_SLOTS_PER_THREAD`` slots each).
    n_slots : int
        Slots of the packed chain.
    rec : numpy.ndarray
        The recorded contacts, ascending.
    ends : numpy.ndarray
        (2, 4) the energies and rates at the run's start (``rkn_kernels.end_data``, row 0).

    Returns
    -------
    callable
        ``advance(state, scratch, chain, probes, control, k_start, k_stop, acc) -> status``.
    """
    nthr = max(1, min(int(threads), n_slots // MIN_SLOTS_PER_THREAD))
    bounds = split(n_slots, nthr)
    team = RknTeam(nthr, bounds, np.searchsorted(rec, bounds).astype(np.int64), new_barrier(),
                   np.zeros((2, nthr, 2)), np.zeros((nthr, 3)), np.zeros((nthr, 2, 4)))
    team.energy[0] = ends  # the start's energies on the first block (the others' 0: the same sums)
    # one pace per chain size and thread count for the process: a run on cores that the last run
    # found shared starts on the engine that was faster there, and times the other as Pace does
    pace = _PACES.setdefault((n_slots, nthr), Pace(nthr))
    used = [nthr]
    per_call = [1]  # samples per compiled call, sized from the steps the last one took

    def call(args: tuple[Any, Any, Any, Any, Any], k0: int, k1: int, acc: np.ndarray) -> tuple[int, float]:
        """Samples k0..k1 - 1 on the threads: the status and the least CPU time [s] a thread got."""
        fresh = team._replace(bar=new_barrier())
        cpu = np.zeros(nthr)
        status = np.zeros(nthr, dtype=np.int64)

        def one(t: int) -> None:
            c0 = time.thread_time()
            state, scratch, chain, probes, control = args
            status[t] = rkn_thread_run(t, fresh, state, scratch, chain, probes, control, k0, k1, acc)
            cpu[t] = time.thread_time() - c0

        workers = [threading.Thread(target=one, args=(t,), daemon=True) for t in range(1, nthr)]
        for th in workers:
            th.start()
        one(0)
        for th in workers:
            th.join()
        return int(status.max()), float(cpu.min())

    compiled = [False]

    def advance(state, scratch, chain, probes, control, k_start: int, k_stop: int, acc: np.ndarray) -> int:
        args = (state, scratch, chain, probes, control)
        if not compiled[0] and nthr > 1:  # compiles (no sample), so that the first chunk's pace is the run's
            call(args, k_start, k_start, acc)
            compiled[0] = True
        k = k_start
        while k < k_stop:
            n = pace.next()
            if n != used[0]:  # the energies at the last two step ends, as the next engine keeps them
                if n == 1:
                    state.ends[:] = team.energy.sum(axis=0)  # block order, as the threads sum them
                else:
                    team.energy[:] = 0.0
                    team.energy[0] = state.ends
                used[0] = n
            k1 = min(k_stop, k + per_call[0])
            steps0, wall0, cpu0 = acc[A_STEPS], time.perf_counter(), time.thread_time()
            if n == 1:  # one thread: the one-thread engine itself (the same state, bit for bit)
                status, cpu = rk.rkn_run(*args, k, k1, acc), time.thread_time() - cpu0
            else:
                status, cpu = call(args, k, k1, acc)
            steps = acc[A_STEPS] - steps0
            pace.record(n, steps * n_slots, time.perf_counter() - wall0, cpu)
            if status != 0:
                return status
            # next call ~RKN_CHUNK_BEAD_STEPS of work (at most doubling)
            per_sample = max(steps, 1.0) / (k1 - k)
            per_call[0] = max(1, min(2 * per_call[0], int(RKN_CHUNK_BEAD_STEPS / (n_slots * per_sample))))
            k = k1
        return 0

    return advance
