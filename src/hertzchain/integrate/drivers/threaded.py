"""One long chain on several cores: the compiled velocity Verlet split into blocks of bodies.

``simulate(model, threads=T)`` for chains of beads with any contact law, offsets included (a
protected body and mass-in-mass beads are refused, naming ``run.threads``). Aligned elastic
chains run the loops of this module; every other model the thread function that
:mod:`hertzchain.integrate.drivers.threaded_laws` builds from the law's one-contact function, with the
same blocks, publication and barrier. Aligned elastic chains: every thread owns a block of consecutive
slots (a multiple of 8, so that no cache line is written by two threads) and runs
:func:`kernels._verlet_run`'s elastic loop over it: the same per-body arithmetic in the same order
(``kernels.step_elastic``, ``step_elastic_lean``, ``final_step_elastic``), so positions,
velocities, forces and the wall peak are bit for bit those of one thread. The only exchange is
the position of the body on either side of a block: each thread publishes its first and last
positions after it moves them, in one of two slots that alternate from step to step, and reads
its neighbours' after one barrier (:mod:`hertzchain.integrate.core.barrier`): one barrier per step.
The adaptive step's evaluation is a maximum over contacts (each thread takes its blocks', then
the largest; exact), the wall peak is tracked by the thread that owns the wall's contact.

What differs: the kinetic and potential energies are sums over the chain; each thread sums its
block and the sums are added in block order, which rounds differently from one sum over the
whole chain (relative difference ~1e-15 x sqrt(N); tests/test_threaded.py bounds it by 1e-12).

Cost: a barrier is ~0.1-1 us on an idle machine, a step of 1e5 beads ~70 us on one core, so the
split pays from ~1e4 beads (benchmarks/long_chain.py measures the speed-up at 1e4-1e6 beads).

Shared cores: a barrier spins a bounded number of times, then yields its core (:mod:`barrier`),
but a descheduled thread still holds the others at the next barrier until its next time slice.
The run watches for it (:class:`Pace`): when a thread got less than CONTENDED of a chunk's
wall time as CPU time, the next chunk runs on one thread (the same thread function over one block:
the same forces bit for bit), and the faster of the two keeps running, the slower timed again
every PROBE_EVERY chunks. Only the block sums (energies, dissipated energy, plastic work) depend on
which chunks ran on how many threads, at the rounding level stated above.
"""

from __future__ import annotations

import math
import threading
import time
from typing import Callable

import numpy as np
from numba import njit

from ...errors import ConfigError, SimulationDiverged
from ...model import System
from ..core import kernels
from ..core.barrier import barrier, new_barrier
from ..core.extension import EXT_COLUMNS
from ..core.kernels import DELTA_MIN, LEAN_SLOTS
from ..core.layout import PAD, pack
from ..core.primitives import open_block
from ..core.structures import VerletState
from .thread_blocks import (ThreadTeam, agree_steps, column_sum, end_sample, kept_on_disk, move_body, record_block,
                            thread_start)
from .threaded_laws import law_thread_run
from .verlet import RawRun, _dt_used, initialise_run, new_probes, raw_run, step_plan

__all__ = ["run_verlet_threaded", "split", "Pace", "MIN_SLOTS_PER_THREAD", "CHUNK_BEAD_STEPS", "CONTENDED", "PROBE_EVERY"]

#: A thread gets at least this many slots (fewer threads for shorter chains).
MIN_SLOTS_PER_THREAD = 512
#: Work (slots x steps) per compiled call between two progress reports (~0.2 s on one core).
CHUNK_BEAD_STEPS = 3e8
#: Threads one of which ran less than this fraction of a chunk's wall time were descheduled
#: (cores shared with other work): one thread is timed on a chunk (``Pace``).
CONTENDED = 0.9
#: ... at most once every this many chunks; a slower thread count is timed again as often.
PROBE_EVERY = 16


def split(n_slots: int, n_threads: int) -> np.ndarray:
    """Block boundaries: (n_threads + 1,) slot numbers, multiples of PAD, as even as possible.

    Parameters
    ----------
    n_slots : int
        Slots of the packed chain (a multiple of PAD).
    n_threads : int
        Threads.

    Returns
    -------
    numpy.ndarray
        int64 boundaries from 0 to n_slots; block t is [b[t], b[t + 1]).
    """
    lines = n_slots // PAD
    edges = [PAD * (lines * t // n_threads) for t in range(n_threads + 1)]
    return np.array(edges, dtype=np.int64)


@njit(cache=True, nogil=True, inline="always")
def _hertz(kappa, d):
    d = d if d > DELTA_MIN else 0.0
    return kappa * d * np.sqrt(d)


def _elastic_segment(last: bool):
    """``kernels.step_elastic`` (``last`` False: kick and drift by ``h``, the step) or
    ``kernels.final_step_elastic`` (``last``: the closing half kick, ``h`` the half step) on one
    block's bodies, given as views that start at its first body (``u``, ``v``, ``g`` one slot
    longer): ``fprev`` the force of the contact on its left (computed from the left neighbour's
    published position), ``gr`` the right neighbour's published position (read instead of u[-1],
    which the neighbour may be moving). ``last`` is a constant of the compiled loop (no branch in
    it). Views from 0, so that the indices are known to be non-negative: with an index range from
    the block's first slot, Numba wrapped every access for negative indices and LLVM left the loop
    scalar (1.7x slower)."""

    @njit(nogil=True)
    def segment(u, v, a, g, kappa, d0, fext, inv_mass, h, fprev, gr):
        n = inv_mass.shape[0]
        for i in range(n - 1):
            f = kernels.contact_force(u, kappa, d0, i)
            move_body(u, v, a, g, i, f, fprev, fext[i], inv_mass[i], h, h, last)
            fprev = f
        i = n - 1
        move_body(u, v, a, g, i, _hertz(kappa[i], u[i] - gr + d0[i]), fprev, fext[i], inv_mass[i], h, h, last)

    return segment


_segment_step = _elastic_segment(False)
_segment_final = _elastic_segment(True)


@njit(cache=True, nogil=True)
def _segment_lean(u, v, kappa, inv_mass, dt, fprev, gr):
    """``kernels.step_elastic_lean`` on one block's bodies (see :func:`_segment_step`)."""
    n = inv_mass.shape[0]
    for i in range(n - 1):
        f = _hertz(kappa[i], u[i] - u[i + 1])
        v[i] += dt * ((fprev - f) * inv_mass[i])
        u[i] += dt * v[i]
        fprev = f
    i = n - 1
    f = _hertz(kappa[i], u[i] - gr)
    v[i] += dt * ((fprev - f) * inv_mass[i])
    u[i] += dt * v[i]


@njit(cache=True, nogil=True, inline="always")
def _publish(pub, par, tid, u, s, e):
    """The block's first and last positions into the other parity's slots; returns that parity.
    A slot is written only after a barrier has followed every read of it (the parities alternate)."""
    par = 1 - par
    pub[par, tid, 0] = u[s]
    pub[par, tid, 1] = u[e - 1]
    return par


def _thread_run(tid, team, state, chain, contacts, probes, control, k_start, k_stop):
    """Thread ``tid``'s share of ``kernels._verlet_run`` (aligned elastic chain) from sample
    ``k_start`` to ``k_stop``: its block of :class:`~.thread_blocks.ThreadTeam` ``team``, whose
    ``pub`` (2, nthr, 2) holds the first and last position of each block, by parity
    (:func:`_publish`), ``energy`` (nthr, 2) the blocks' energy sums; the other structures are
    ``verlet_run``'s. Thread 0 keeps ``acc`` and writes the energies (the others keep a copy of
    ``acc``: the same numbers). Every thread sums the blocks' energies in the same order, so all
    stop together when the state is not finite. Returns 1 then, else 0.
    """
    u, v, a, g, acc = state
    mass, inv_mass, kappa, damping, d0, fext, ws = chain
    de, dx0, rsum, dcap, _, _, _, _ = contacts
    out_ke, out_pe, out_ed, peak = probes.out_ke, probes.out_pe, probes.out_ed, probes.peak
    interval, stride, n_sub, n_eval, c_steps, relax = control
    nthr, bar, pub, energy = team.nthr, team.bar, team.pub, team.energy
    s, e, owns_wall, left, right, my, block, ns, step = thread_start(team, tid, acc, ws, control)
    adaptive = stride == 0
    # long chain without precompression: kernels.step_elastic_lean's segments (verlet_run's choice)
    lean = a.shape[0] >= LEAN_SLOTS
    for i in range(a.shape[0]):
        lean = lean and d0[i] == 0.0 and fext[i] == 0.0
    no_ext = np.zeros((0, EXT_COLUMNS))
    sense = 0
    par = 0
    j0 = s - 1 if left else 0
    kl = kappa[j0]  # the contact on the block's left (its force: kernels.step_elastic's arithmetic)
    dl = d0[j0]
    for k in range(k_start, k_stop):
        for b in range(n_sub):
            if adaptive and ((k - 1) * n_sub + b) % n_eval == 0:
                # every block has finished the last one; kernels.required_stride is a maximum over
                # bodies of an increasing function: the largest of the blocks' values (each block
                # with its left contact) is the chain's
                sense = barrier(bar, nthr, sense)
                req = kernels.required_stride(u[j0:e + 1], v[j0:e + 1], a[j0:e + 1], kappa[j0:e], d0[j0:e], de[j0:e],
                                              dx0[j0:e], rsum[j0:e], dcap[j0:e], inv_mass[j0:e + 1], n_eval * block,
                                              block, c_steps, damping[j0:e], 0, no_ext, False)
                ns, sense = agree_steps(team, tid, sense, req, ns, relax, my)
            dt = block / ns
            half = 0.5 * dt
            t0 = (k - 1) * interval + b * block
            open_block(u[s:e], v[s:e], a[s:e], dt, half)
            par = _publish(pub, par, tid, u, s, e)
            sense = barrier(bar, nthr, sense)
            for st in range(ns - 1):
                gr = pub[par, tid + 1, 0] if right else u[e]
                if lean:
                    # the force of contact s - 1 as the left neighbour computes it
                    fl = _hertz(kl, pub[par, tid - 1, 1] - u[s]) if left else 0.0
                    if owns_wall:  # the wall force this step computes (at the positions it starts from)
                        kernels._track_peak(kernels.contact_force(u, kappa, d0, ws), t0 + (st + 1) * dt, dt, peak)
                    _segment_lean(u[s:e + 1], v[s:e], kappa[s:e], inv_mass[s:e], dt, fl, gr)
                else:
                    fl = _hertz(kl, pub[par, tid - 1, 1] - u[s] + dl) if left else 0.0
                    _segment_step(u[s:e + 1], v[s:e], a[s:e], g[s:e + 1], kappa[s:e], d0[s:e], fext[s:e],
                                  inv_mass[s:e], dt, fl, gr)
                    if owns_wall:
                        kernels._track_peak(g[ws + 1], t0 + (st + 1) * dt, dt, peak)
                par = _publish(pub, par, tid, u, s, e)
                sense = barrier(bar, nthr, sense)
            gr = pub[par, tid + 1, 0] if right else u[e]
            fl = _hertz(kl, pub[par, tid - 1, 1] - u[s] + dl) if left else 0.0
            _segment_final(u[s:e + 1], v[s:e], a[s:e], g[s:e + 1], kappa[s:e], d0[s:e], fext[s:e], inv_mass[s:e],
                           half, fl, gr)
            if owns_wall:
                kernels._track_peak(g[ws + 1], t0 + block, dt, peak)
            step += ns
        # --- probes: each thread its own contacts and bodies, the energies as block sums
        record_block(team, tid, k, s, e, u, v, g, probes)
        ke, pe = kernels.energies_elastic(u[s:e + 1], v[s:e + 1], g[s:e + 1], mass[s:e], d0[s:e], fext[s:e])
        energy[tid, 0] = ke
        energy[tid, 1] = pe
        sense = barrier(bar, nthr, sense)
        ke = column_sum(energy, 0)
        pe = column_sum(energy, 1)
        if tid == 0:
            out_ke[k] = ke
            out_pe[k] = pe
            out_ed[k] = my[0]
        sense, finite = end_sample(team, sense, ke, g)
        if not finite:
            my[2] = step
            return 1
    my[2] = step
    return 0


# _thread_run compiles in the functions of other files: its on-disk cache is keyed on their text too
_thread_run = kept_on_disk(njit(nogil=True)(_thread_run), "drivers/threaded.py", "elastic")


class _Layout:
    """The blocks of ``n`` threads over ``p`` slots and their exchange arrays (see the thread
    functions): boundaries, recorded contacts per block, published edges, required steps, energy
    sums and (``general``) the blocks' dissipated energies."""

    def __init__(self, p: int, n: int, rec: np.ndarray, general: bool) -> None:
        self.bounds = split(p, n)
        self.rbounds = np.searchsorted(rec, self.bounds).astype(np.int64)
        self.pub = np.zeros((2, n, 4 if general else 2))
        self.part = np.zeros(n, dtype=np.int64)
        self.energy = np.zeros((n, 3 if general else 2))
        self.edacc = np.zeros((n, 2))


class Pace:
    """How many threads run the next compiled call (chunk): the threads asked for, unless one
    thread was timed faster.

    One thread is timed (one chunk) only when the threads' last chunk found them descheduled,
    the CPU time of one of them below CONTENDED of the wall time (its cores shared with other
    work: a barrier then waits for that thread's next time slice), at most once every
    PROBE_EVERY chunks; while one thread is the faster, the threads are timed again every
    PROBE_EVERY chunks (the other work may have ended). Forces and positions do not depend on it.
    """

    def __init__(self, threads: int) -> None:
        self.threads = threads
        self.rate: dict[int, float] = {}  # threads -> bead-steps per second in its last chunk
        self.seen: dict[int, int] = {}    # threads -> the chunk that measured it
        self.chunk = 0
        self.contended = False

    def next(self) -> int:
        """Threads for the next chunk."""
        many = self.threads
        if many == 1 or many not in self.rate:
            return many
        best = many if self.rate[many] >= self.rate.get(1, 0.0) else 1
        other = 1 if best == many else many
        stale = other not in self.seen or self.chunk - self.seen[other] >= PROBE_EVERY
        if best == many:
            return 1 if stale and self.contended else many
        return many if stale else 1

    def record(self, threads: int, work: float, wall: float, cpu: float) -> None:
        """A chunk of ``work`` bead-steps on ``threads`` threads took ``wall`` seconds, and the
        thread that ran least got ``cpu`` seconds of CPU time."""
        if wall > 0.0 and work > 0.0:
            self.rate[threads] = work / wall
            self.seen[threads] = self.chunk
            if threads > 1:
                self.contended = cpu < CONTENDED * wall
        self.chunk += 1


def run_verlet_threaded(system: System, duration: float, sample_interval: float, threads: int,
                        dt: float | None = None, record_velocities: bool = False, contacts: np.ndarray | None = None,
                        progress: Callable[[int, int], None] | None = None, record_positions: bool = False,
                        steps_per_radian: float | None = None) -> RawRun:
    """:func:`hertzchain.integrate.drivers.verlet.run_verlet` of a chain on ``threads`` threads.

    Parameters
    ----------
    system : hertzchain.model.System
        A chain of beads: any contact law, offsets too (a protected body or mass-in-mass beads:
        ConfigError naming ``run.threads``).
    duration : float
        Simulated time [s].
    sample_interval : float
        Time between samples [s].
    threads : int
        Threads (fewer when the chain is short: at least MIN_SLOTS_PER_THREAD slots each).
    dt : float or None
        Fixed step [s], or None for the adaptive one.
    record_velocities, record_positions : bool
        Also record every body's velocity / displacement.
    contacts : numpy.ndarray or None
        Contact numbers whose forces are recorded (all when None).
    progress : callable or None
        ``progress(done, total)`` in samples, between compiled calls.
    steps_per_radian : float or None
        The adaptive step's accuracy (as ``run_verlet``).

    Returns
    -------
    RawRun
        What ``run_verlet`` returns (the elastic-plastic law's plastic work, residual and largest
        overlaps too); the same numbers but for the rounding of the energies, the dissipated energy
        and the plastic work (module docstring, :mod:`hertzchain.integrate.drivers.threaded_laws`).
    """
    if system.extended:
        what = "a protected body (wall.type = 'body')" if system.body else "mass-in-mass beads (chain.elements)"
        raise ConfigError("run.threads", f"several threads run chains of beads with any contact law and offsets, "
                          f"not {what}; use run.threads = 1 or 'auto' for this model")
    plan = step_plan(system, sample_interval, dt, steps_per_radian)
    n_samples = int(math.floor(duration / sample_interval + 1e-9)) + 1
    w = pack(system)
    p = w.n_slots
    nthr = max(1, min(int(threads), p // MIN_SLOTS_PER_THREAD))
    state = VerletState(w.u, w.v, np.zeros(p), np.zeros(p + 1), np.zeros(8))
    acc = state.acc
    probes = new_probes(system, n_samples, contacts, record_velocities, record_positions)
    initialise_run(system, w, state, probes)
    general = system.general
    # every other law, offsets: the thread function built from the law's contact
    run = law_thread_run(system.law, not system.misaligned) if general else _thread_run
    structures = (state, w.chain(), w.contacts(), probes, plan.control(sample_interval))
    layouts = {n: _Layout(p, n, probes.rec, general) for n in {nthr, 1}}
    layouts[nthr].edacc[0, 1] = acc[1]  # the dissipated power at t = 0 (the trapezoid's first point), on block 0

    def call(n: int, k0: int, k1: int) -> tuple[int, float]:
        """Samples k0..k1 on n threads: the status and the least CPU time [s] a thread got."""
        lay = layouts[n]
        team = ThreadTeam(n, lay.bounds, lay.rbounds, new_barrier(), lay.pub, lay.part, lay.energy, lay.edacc)
        cpu = np.zeros(n)
        status = np.zeros(n, dtype=np.int64)

        def one(t: int) -> None:
            c0 = time.thread_time()
            status[t] = run(t, team, *structures, k0, k1)
            cpu[t] = time.thread_time() - c0

        workers = [threading.Thread(target=one, args=(t,), daemon=True) for t in range(1, n)]
        for th in workers:
            th.start()
        one(0)
        for th in workers:
            th.join()
        return int(status[0]), float(cpu.min())

    call(nthr, 1, 1)  # compiles (no sample), so that the first chunk's pace is the run's
    pace = Pace(nthr)
    per_call = max(1, round(CHUNK_BEAD_STEPS * plan.dt / (p * sample_interval)))
    if progress is not None:
        progress(0, n_samples - 1)
    k = 1
    used = nthr
    while k < n_samples:
        k_stop = min(n_samples, k + per_call)
        n = pace.next()
        if n != used:  # the dissipated energy of the blocks, gathered on the new layout's first block
            layouts[n].edacc[:] = 0.0
            layouts[n].edacc[0] = layouts[used].edacc.sum(axis=0)
            used = n
        steps0, wall0 = acc[2], time.perf_counter()
        status, cpu = call(n, k, k_stop)
        pace.record(n, (acc[2] - steps0) * p, time.perf_counter() - wall0, cpu)
        if status != 0:
            dt_low = _dt_used(plan, acc, sample_interval)[0]
            raise SimulationDiverged(f"the integration diverged (non-finite state) before t = "
                                     f"{k_stop * sample_interval:.4g} s with the step down to {dt_low:.3g} s; use a "
                                     "smaller run.dt (or leave it out for the automatic step)")
        k = k_stop
        if progress is not None:
            progress(k - 1, n_samples - 1)
    return raw_run(system, w, plan, probes, acc, sample_interval)
