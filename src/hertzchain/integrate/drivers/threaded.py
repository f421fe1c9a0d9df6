"""One long chain on several cores: the compiled velocity Verlet split into blocks of bodies.

``simulate(model, threads=T)`` for chains of beads with any contact law, offsets included (a
protected body and mass-in-mass beads are refused, naming ``run.threads``). Aligned elastic
chains run the loops of this module; every other model the thread function that
:mod:`hertzchain.integrate.drivers.threaded_laws` builds from the law's one-contact function, with the
same blocks, publication and barrier. Aligned elastic chains: every thread owns a block of consecutive
slots (a multiple of 8, so that no cache line is written by two threads) and runs
:func:`kernels.verlet_run`'s elastic loop over it: the same per-body arithmetic in the same order
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
The run watches for it (:class:`_Pace`): when a thread got less than CONTENDED of a chunk's
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
from ..core.kernels import DELTA_MIN, LEAN_SLOTS
from ..core.layout import PAD, pack
from ..core.primitives import open_block, running_max
from .threaded_laws import law_thread_run
from .verlet import RawRun, _dt_used, initialise, refine_peak, step_plan

__all__ = ["run_verlet_threaded", "split", "MIN_SLOTS_PER_THREAD", "CHUNK_BEAD_STEPS", "CONTENDED", "PROBE_EVERY"]

#: A thread gets at least this many slots (fewer threads for shorter chains).
MIN_SLOTS_PER_THREAD = 512
#: Work (slots x steps) per compiled call between two progress reports (~0.2 s on one core).
CHUNK_BEAD_STEPS = 3e8
#: Threads one of which ran less than this fraction of a chunk's wall time were descheduled
#: (cores shared with other work): one thread is timed on a chunk (``_Pace``).
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


@njit(cache=True, nogil=True)
def _segment_step(u, v, a, g, kappa, d0, fext, inv_mass, dt, fprev, gr):
    """``kernels.step_elastic`` on one block's bodies, given as views that start at its first body
    (``u``, ``v``, ``g`` one slot longer): ``fprev`` the force of the contact on its left (computed
    from the left neighbour's published position), ``gr`` the right neighbour's published
    position (read instead of u[-1], which the neighbour may be moving). Views from 0, so that the
    indices are known to be non-negative: with an index range from the block's first slot, Numba
    wrapped every access for negative indices and LLVM left the loop scalar (1.7x slower)."""
    n = inv_mass.shape[0]
    for i in range(n - 1):
        d = u[i] - u[i + 1] + d0[i]
        d = d if d > DELTA_MIN else 0.0
        f = kappa[i] * d * np.sqrt(d)
        g[i + 1] = f
        ai = (fprev - f + fext[i]) * inv_mass[i]
        a[i] = ai
        v[i] += dt * ai
        u[i] += dt * v[i]
        fprev = f
    i = n - 1
    f = _hertz(kappa[i], u[i] - gr + d0[i])
    g[i + 1] = f
    ai = (fprev - f + fext[i]) * inv_mass[i]
    a[i] = ai
    v[i] += dt * ai
    u[i] += dt * v[i]


@njit(cache=True, nogil=True)
def _segment_lean(u, v, kappa, inv_mass, dt, fprev, gr):
    """``kernels.step_elastic_lean`` on one block's bodies (see :func:`_segment_step`)."""
    n = inv_mass.shape[0]
    for i in range(n - 1):
        d = u[i] - u[i + 1]
        d = d if d > DELTA_MIN else 0.0
        f = kappa[i] * d * np.sqrt(d)
        v[i] += dt * ((fprev - f) * inv_mass[i])
        u[i] += dt * v[i]
        fprev = f
    i = n - 1
    f = _hertz(kappa[i], u[i] - gr)
    v[i] += dt * ((fprev - f) * inv_mass[i])
    u[i] += dt * v[i]


@njit(cache=True, nogil=True)
def _segment_final(u, v, a, g, kappa, d0, fext, inv_mass, half, fprev, gr):
    """``kernels.final_step_elastic`` on one block's bodies (see :func:`_segment_step`)."""
    n = inv_mass.shape[0]
    for i in range(n - 1):
        d = u[i] - u[i + 1] + d0[i]
        d = d if d > DELTA_MIN else 0.0
        f = kappa[i] * d * np.sqrt(d)
        g[i + 1] = f
        ai = (fprev - f + fext[i]) * inv_mass[i]
        a[i] = ai
        v[i] += half * ai
        fprev = f
    i = n - 1
    f = _hertz(kappa[i], u[i] - gr + d0[i])
    g[i + 1] = f
    ai = (fprev - f + fext[i]) * inv_mass[i]
    a[i] = ai
    v[i] += half * ai


@njit(cache=True, nogil=True, inline="always")
def _publish(pub, par, tid, u, s, e):
    """The block's first and last positions into the other parity's slots; returns that parity.
    A slot is written only after a barrier has followed every read of it (the parities alternate)."""
    par = 1 - par
    pub[par, tid, 0] = u[s]
    pub[par, tid, 1] = u[e - 1]
    return par


@njit(cache=True, nogil=True)
def _thread_run(tid, nthr, bounds, rbounds, bar, pub, part, energy, u, v, a, g, mass, inv_mass, kappa, damping, d0,
                de, dx0, rsum, fext, dcap, wall_slot, lean, interval, stride, n_sub, n_eval, c_steps, relax, k_start,
                k_stop, rec, out_f, out_ke, out_pe, out_ed, out_v, record_v, out_u, record_u, fmax, peak, acc, ext):
    """Thread ``tid``'s share of ``kernels.verlet_run`` (aligned elastic chain) from sample
    ``k_start`` to ``k_stop``: bodies [bounds[tid], bounds[tid + 1]), recorded contacts
    rec[rbounds[tid]:rbounds[tid + 1]]. ``pub`` (2, nthr, 2): the first and last position of each
    block, by parity (:func:`_publish`); ``part`` (nthr,) int64 and ``energy`` (nthr, 2): each
    block's required steps and energy sums. Thread 0 keeps ``acc`` and writes the energies (the
    others keep a copy of ``acc``: the same numbers). Every thread sums the blocks' energies in
    the same order, so all stop together when the state is not finite. Returns 1 then, else 0.
    """
    s = bounds[tid]
    e = bounds[tid + 1]
    nc = fmax.shape[0]
    ws = wall_slot
    owns_wall = s <= ws < e
    left = tid > 0
    right = tid < nthr - 1
    my = acc if tid == 0 else acc.copy()
    sense = 0
    par = 0
    block = interval / n_sub
    adaptive = stride == 0
    ns = stride if not adaptive else int(my[3])
    step = int(my[2])
    j0 = s - 1 if s > 0 else 0
    kl = kappa[j0]  # the contact on the block's left (its force: kernels.step_elastic's arithmetic)
    dl = d0[j0]
    for k in range(k_start, k_stop):
        for b in range(n_sub):
            if adaptive and ((k - 1) * n_sub + b) % n_eval == 0:
                # every block has finished the last one; kernels.required_stride is a maximum over
                # bodies of an increasing function: the largest of the blocks' values (each block
                # with its left contact) is the chain's
                sense = barrier(bar, nthr, sense)
                part[tid] = kernels.required_stride(u[j0:e + 1], v[j0:e + 1], a[j0:e + 1], kappa[j0:e], d0[j0:e],
                                                    de[j0:e], dx0[j0:e], rsum[j0:e], dcap[j0:e],
                                                    inv_mass[j0:e + 1], n_eval * block, block, c_steps,
                                                    damping[j0:e], 0, ext, False)
                sense = barrier(bar, nthr, sense)
                req = part[0]
                for t in range(1, nthr):
                    req = part[t] if part[t] > req else req
                ns = kernels._adapt_stride(req, ns, relax, my)
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
        # --- probes: each thread its own contacts and bodies (positions stay put in the last
        # step, so the neighbour's first position is final), the energies as block sums
        for r in range(rbounds[tid], rbounds[tid + 1]):
            out_f[k, r] = g[rec[r] + 1]
        m = min(e, nc)
        if m > s:
            running_max(fmax[s:m], g[s + 1:m + 1])
        ke, pe = kernels.energies_elastic(u[s:e + 1], v[s:e + 1], g[s:e + 1], mass[s:e], d0[s:e], fext[s:e])
        energy[tid, 0] = ke
        energy[tid, 1] = pe
        if record_v:
            m = min(e, out_v.shape[1])
            out_v[k, s:m] = v[s:m]
        if record_u:
            m = min(e, out_u.shape[1])
            out_u[k, s:m] = u[s:m]
        sense = barrier(bar, nthr, sense)
        ke = energy[0, 0]
        pe = energy[0, 1]
        for t in range(1, nthr):
            ke += energy[t, 0]
            pe += energy[t, 1]
        if tid == 0:
            out_ke[k] = ke
            out_pe[k] = pe
            out_ed[k] = my[0]
        # every thread read the sums before any writes the next sample's
        sense = barrier(bar, nthr, sense)
        if not np.isfinite(ke) or not np.isfinite(g[1]):
            my[2] = step
            return 1
    my[2] = step
    return 0


# _thread_run compiles the kernels' functions into itself: an edit of kernels.py must recompile it
kernels.flush_stale_cache(_thread_run)


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


class _Pace:
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
    nc = system.n_contacts
    nb = system.n_beads + 1
    w = pack(system)
    p = w.n_slots
    nthr = max(1, min(int(threads), p // MIN_SLOTS_PER_THREAD))
    u, v = w.u, w.v
    g = np.zeros(p + 1)
    a = np.zeros(p)
    rec = np.arange(nc) if contacts is None else np.asarray(contacts, dtype=np.int64)
    out_f = np.empty((n_samples, rec.size))
    out_ke = np.empty(n_samples)
    out_pe = np.empty(n_samples)
    out_ed = np.empty(n_samples)
    plastic = system.law == kernels.LAW_ELASTOPLASTIC
    out_wp = np.empty(n_samples if plastic else 1)
    out_v = np.empty((n_samples if record_velocities else 1, nb))
    out_u = np.empty((n_samples if record_positions else 1, nb))
    fmax = np.empty(nc)
    peak = np.empty(8)
    acc = np.zeros(8)
    initialise(system, w, u, v, g, a, rec, out_f, out_ke, out_pe, out_ed, out_v, record_velocities, fmax, peak, acc,
               out_wp)
    out_u[0] = u[:nb]
    steps = (sample_interval, plan.stride, plan.n_sub, plan.n_eval, plan.c_steps, plan.relax)
    general = system.general
    if general:  # every other law, offsets: the thread function built from the law's contact
        run = law_thread_run(system.law, not system.misaligned)
        arrays = (u, v, a, g, w.mass, w.inv_mass, w.kappa, w.damping, w.d0, w.de, w.dx0, w.rsum, w.fext, w.dcap,
                  w.dyield, w.dmax, w.dres, w.kres, w.wall_slot, *steps)
        tail = (rec, out_f, out_ke, out_pe, out_ed, out_wp, out_v, record_velocities, out_u, record_positions, fmax,
                peak, acc, w.ext)
    else:
        run = _thread_run
        lean = bool(p >= LEAN_SLOTS and not np.any(w.d0) and not np.any(w.fext))
        arrays = (u, v, a, g, w.mass, w.inv_mass, w.kappa, w.damping, w.d0, w.de, w.dx0, w.rsum, w.fext, w.dcap,
                  w.wall_slot, lean, *steps)
        tail = (rec, out_f, out_ke, out_pe, out_ed, out_v, record_velocities, out_u, record_positions, fmax, peak, acc,
                w.ext)
    layouts = {n: _Layout(p, n, rec, general) for n in {nthr, 1}}
    layouts[nthr].edacc[0, 1] = acc[1]  # the dissipated power at t = 0 (the trapezoid's first point), on block 0

    def call(n: int, k0: int, k1: int) -> tuple[int, float]:
        """Samples k0..k1 on n threads: the status and the least CPU time [s] a thread got."""
        lay = layouts[n]
        head = (lay.pub, lay.part, lay.energy, lay.edacc) if general else (lay.pub, lay.part, lay.energy)
        args = (n, lay.bounds, lay.rbounds, new_barrier(), *head, *arrays, k0, k1, *tail)
        cpu = np.zeros(n)
        status = np.zeros(n, dtype=np.int64)

        def one(t: int) -> None:
            c0 = time.thread_time()
            status[t] = run(t, *args)
            cpu[t] = time.thread_time() - c0

        workers = [threading.Thread(target=one, args=(t,), daemon=True) for t in range(1, n)]
        for th in workers:
            th.start()
        one(0)
        for th in workers:
            th.join()
        return int(status[0]), float(cpu.min())

    call(nthr, 1, 1)  # compiles (no sample), so that the first chunk's pace is the run's
    pace = _Pace(nthr)
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
    fpk, t_pk = refine_peak(peak)
    dt_min, dt_max = _dt_used(plan, acc, sample_interval)
    return RawRun(time=np.arange(n_samples) * sample_interval, contact_force=out_f, kinetic_energy=out_ke,
                  potential_energy=out_pe, dissipated_energy=out_ed, velocity=out_v if record_velocities else None,
                  max_force=fmax, peak_wall_force=fpk, peak_wall_time=t_pk, dt=dt_min, integrator="verlet",
                  n_steps=int(acc[2]), contacts=rec, dt_max=dt_max, adaptive=plan.adaptive,
                  displacement=out_u if record_positions else None, plastic_work=out_wp if plastic else None,
                  residual_overlap=w.dres[:nc].copy() if plastic else None,
                  max_overlap=w.dmax[:nc].copy() if plastic else None)
