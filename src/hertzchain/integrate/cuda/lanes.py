"""Several lanes per chain on a GPU: the batch engine's kernel for aligned elastic chains on a
fixed step, and the GPU path for one long chain (a tile kernel).

Prepared and checked on a CPU through Numba's CUDA simulator and by compiling PTX for an H100
(sm_90) without a GPU (tests/test_cuda_lanes.py); its speed on a GPU is not measured yet
(benchmarks/gpu_kernels.py is the script to run where one is lent).

**Batch kernel** (:func:`lanes_kernel`): L lanes (threads) per chain, lane l holds the positions
and velocities of its C = P / L consecutive slots in registers; the per-slot parameters (kappa,
1/m, and d0, the end forces of a precompressed chain) sit in shared memory and are read there at
every step (a compiler that hoists them into registers makes a thread-per-chain kernel spill:
docs/gpu figures, 3.3e11 against 4.9e11 bead-steps/s). After every step each lane publishes its
first and last positions in shared memory (two alternating slots) and one barrier later reads its
neighbours': the force of the contact on its left is computed again from them, with the very same
arithmetic as the neighbour's (kernels.step_elastic's recurrence cut at lane edges). One barrier
per step for the whole block, so every chain of a block must take as many steps: the kernel runs
batches whose members share one fixed step (``dt``); the adaptive step stays with the register
kernel (:func:`hertzchain.integrate.cuda.kernels._register_kernel`).

**Square roots**: on a GPU, sqrt(delta) = delta rsqrt(delta) with the hardware's approximate
reciprocal square root (``rsqrt.approx.f64``, ~23 bits) refined by two Newton steps
y <- y (3/2 - delta y^2 / 2) to full double precision (within ~1 ulp of the rounded square root;
the measured tuned CUDA C kernel: 8.0e11 bead-steps/s at 1e5 chains with it, 6.1e11 with IEEE
sqrt). Under the simulator the approximation is 1 / sqrt, refined the same way. The numbers agree
with the CPU engine within the bound of tests/test_cuda.py (rounding differences that add up at
most linearly with the steps, as fused multiply-adds do).
"""

from __future__ import annotations

import functools
import math
from typing import Any

from .device import _cuda, _simulated
from ..core.kernels import DELTA_MIN

__all__ = ["LANES", "CHAINS_PER_BLOCK", "lanes", "chains_per_block", "lanes_kernel", "tile_kernel", "TILE", "HALO"]

#: Lanes (threads) per chain: 4 at 1e5 chains (8 at 1e4) in the tuned CUDA C kernel.
LANES = 4
#: Chains per thread block (threads per block = CHAINS_PER_BLOCK x lanes).
CHAINS_PER_BLOCK = 32
#: Bodies per block of the long-chain tile kernel, and steps per launch (its halo on either side).
TILE = 256
HALO = 16

cuda: Any = None  # numba.cuda, set by _module(): the simulator swaps a module global for its fake module


def _module():
    """numba.cuda as this module's global ``cuda`` (the kernels refer to it by that name)."""
    global cuda
    cuda = _cuda()
    return cuda


def lanes() -> int:
    """Lanes per chain: LANES on a GPU; 2 under the simulator (every thread is a Python thread and
    every barrier costs milliseconds; 2 lanes still exchange their edges)."""
    return 2 if _simulated() else LANES


def chains_per_block() -> int:
    """Chains per thread block: CHAINS_PER_BLOCK on a GPU, 2 under the simulator."""
    return 2 if _simulated() else CHAINS_PER_BLOCK


@functools.lru_cache(maxsize=None)
def _fast_sqrt():
    """Device function sqrt(x) for x > 0: x rsqrt(x), rsqrt refined twice by Newton's method."""
    _module()
    if _simulated():
        @cuda.jit(device=True)
        def rsqrt(x):
            return 1.0 / math.sqrt(x)
    else:
        from numba.cuda import libdevice

        @cuda.jit(device=True, forceinline=True)
        def rsqrt(x):
            return libdevice.rsqrt(x)  # rsqrt.approx.f64

    inline = {} if _simulated() else {"forceinline": True}

    @cuda.jit(device=True, **inline)
    def fast_sqrt(x):
        y = rsqrt(x)
        y = y * (1.5 - 0.5 * x * y * y)
        y = y * (1.5 - 0.5 * x * y * y)
        return x * y

    return fast_sqrt


@functools.lru_cache(maxsize=None)
def _hertz():
    """Device function kappa max(d, 0)^(3/2) as kernels.step_elastic (0 at or below DELTA_MIN;
    the square root of a dummy 1.0 there: CUDA's sqrt(0) takes a slow path)."""
    _module()
    fast_sqrt = _fast_sqrt()
    inline = {} if _simulated() else {"forceinline": True}

    @cuda.jit(device=True, **inline)
    def hertz(kap, d):
        ok = d > DELTA_MIN
        dd = d if ok else 1.0
        f = kap * dd * fast_sqrt(dd)
        return f if ok else 0.0

    return hertz


@functools.lru_cache(maxsize=None)
def lanes_kernel(p: int, lanes: int, pre: bool, chains: int = CHAINS_PER_BLOCK):
    """The batch kernel for aligned elastic members of ``p`` slots on one fixed step (module
    docstring), compiled for (p, lanes, pre); launch with ``chains x lanes`` threads per block.

    Parameters
    ----------
    p : int
        Slots per member (a multiple of ``lanes``).
    lanes : int
        Threads per member.
    pre : bool
        Whether members carry a precompression (d0 and the end force in shared memory too).
    chains : int
        Members per thread block.

    Returns
    -------
    numba.cuda dispatcher
        ``kernel(u, v, a, g, kappa, inv_mass, d0, fext, mass, wall_slot, interval, stride, k_start,
        k_stop, rec, out_f, out_ke, out_pe, out_ed, out_v, record_v, fmax, peak, acc, status)``,
        arrays (slot, member) as :func:`hertzchain.integrate.cuda.launch.run_packed` lays them out.
    """
    from numba import float64

    from .kernels import _kernels

    _module()
    kern = _kernels()
    sample, track_peak = kern["sample"], kern["track_peak"]
    hertz = _hertz()
    c_slots = p // lanes
    tpb = chains * lanes
    pp = p if pre else 1
    c1 = c_slots + 1

    @cuda.jit
    def kernel(u, v, a, g, kappa, inv_mass, d0, fext, mass, wall_slot, interval, stride, k_start, k_stop, rec, out_f,
               out_ke, out_pe, out_ed, out_v, record_v, fmax, peak, acc, status):
        t = cuda.threadIdx.x
        cb = t // lanes
        lane = t - cb * lanes
        m = cuda.blockIdx.x * chains + cb
        live = m < status.shape[0]
        skap = cuda.shared.array((p, chains), float64)
        sinv = cuda.shared.array((p, chains), float64)
        sd0 = cuda.shared.array((pp, chains), float64)
        sfx = cuda.shared.array((pp, chains), float64)
        edge = cuda.shared.array((2, 2, lanes, chains), float64)  # [parity, first/last, lane, chain]
        s = lane * c_slots
        ul = cuda.local.array(c1, float64)
        vl = cuda.local.array(c1, float64)
        pk = cuda.local.array((8, 1), float64)
        mm = m if live else 0
        for c in range(c_slots):
            skap[s + c, cb] = kappa[s + c, mm]
            sinv[s + c, cb] = inv_mass[s + c, mm]
            if pre:
                sd0[s + c, cb] = d0[s + c, mm]
                sfx[s + c, cb] = fext[s + c, mm]
        for j in range(8):
            pk[j, 0] = peak[j, mm]
        ws = wall_slot[mm]
        owner = s <= ws < s + c_slots  # this lane computes the wall contact's force
        uend = u[p, mm]  # the far end (the wall ghost's right neighbour) never moves
        ns = stride
        dt = interval / ns
        half = 0.5 * dt
        step = acc[2, mm]
        cuda.syncthreads()
        for k in range(k_start, k_stop):
            t0 = (k - 1) * interval
            for c in range(c_slots):  # the block's opening half kick and drift
                vi = v[s + c, mm] + half * a[s + c, mm]
                vl[c] = vi
                ul[c] = u[s + c, mm] + dt * vi
            par = 0
            edge[par, 0, lane, cb] = ul[0]
            edge[par, 1, lane, cb] = ul[c_slots - 1]
            cuda.syncthreads()
            for st in range(ns):
                last = st == ns - 1
                fprev = 0.0
                if lane > 0:  # contact s - 1, from the left neighbour's last position
                    fprev = hertz(skap[s - 1, cb], edge[par, 1, lane - 1, cb] - ul[0] + (sd0[s - 1, cb] if pre else 0.0))
                ur = edge[par, 0, lane + 1, cb] if lane < lanes - 1 else uend
                ul[c_slots] = ur
                fw = 0.0
                for c in range(c_slots):
                    i = s + c
                    f = hertz(skap[i, cb], ul[c] - ul[c + 1] + (sd0[i, cb] if pre else 0.0))
                    if i == ws:
                        fw = f
                    ai = (fprev - f + (sfx[i, cb] if pre else 0.0)) * sinv[i, cb]
                    if last:  # kernels.final_step_elastic: closing half kick, state to memory
                        if live:
                            g[i + 1, m] = f
                            a[i, m] = ai
                            v[i, m] = vl[c] + half * ai
                            u[i, m] = ul[c]
                    else:
                        vl[c] += dt * ai
                        ul[c] += dt * vl[c]
                    fprev = f
                if owner and live:
                    track_peak(fw, t0 + interval if last else t0 + (st + 1) * dt, dt, pk, 0)
                if not last:
                    par = 1 - par
                    edge[par, 0, lane, cb] = ul[0]
                    edge[par, 1, lane, cb] = ul[c_slots - 1]
                cuda.syncthreads()
            step += ns
            if lane == 0 and live:  # the probes, on the state just written (every lane passed the barrier)
                if not sample(k - k_start, False, u, v, g, mass, kappa, d0, d0, d0, d0, fext, rec, out_f, fmax, out_ke,
                              out_pe, out_ed, out_v, record_v, acc, False, p, m):
                    status[m] = 1
            cuda.syncthreads()
        if live:
            if owner:
                for j in range(8):
                    peak[j, m] = pk[j, 0]
            if lane == 0:
                acc[2, m] = step

    return kernel, tpb


@functools.lru_cache(maxsize=None)
def tile_kernel(tile: int = TILE, halo: int = HALO):
    """One long aligned elastic chain on a GPU: ``n_steps`` <= ``halo`` fixed steps per launch.

    Each thread block loads a tile of ``tile`` bodies and ``halo`` bodies on either side into shared
    memory, and steps them all ``n_steps`` times (kernels.step_elastic's arithmetic, a force pass
    then an update pass, two barriers a step); after step s the outermost s bodies of either halo
    are stale, so after at most ``halo`` steps the tile itself is still exact and is written
    back. The state is at the start of a leapfrog step (velocities half a step ahead, as between
    :func:`hertzchain.integrate.core.kernels.step_elastic` calls); ``fw`` receives the wall contact's
    force after every step (the block that holds it).

    Parameters
    ----------
    tile : int
        Bodies written back per thread block (threads per block = tile + 2 halo).
    halo : int
        Bodies recomputed on either side; the most steps per launch.

    Returns
    -------
    numba.cuda dispatcher
        ``kernel(u_in, v_in, u_out, v_out, kappa, inv_mass, dt, n_steps, wall_slot, fw)``, 1D arrays
        of the packed chain (u, v: P + 1 slots), ``fw`` (n_steps,).
    """
    from numba import float64

    _module()
    hertz = _hertz()
    width = tile + 2 * halo
    w1 = width + 1  # array shapes must be compile-time constants (an expression in the kernel is not)

    @cuda.jit
    def kernel(u_in, v_in, u_out, v_out, kappa, inv_mass, dt, n_steps, wall_slot, fw):
        t = cuda.threadIdx.x
        first = cuda.blockIdx.x * tile - halo  # body of thread 0
        i = first + t
        n = u_in.shape[0] - 1  # slots (the last u is the fixed far end)
        su = cuda.shared.array(w1, float64)
        sf = cuda.shared.array(w1, float64)
        inside = 0 <= i < n
        ui = u_in[i] if inside else 0.0
        vi = v_in[i] if inside else 0.0
        kap = kappa[i] if inside else 0.0
        im = inv_mass[i] if inside else 0.0
        su[t] = ui
        if t == width - 1:  # the right neighbour of the last thread
            su[width] = u_in[i + 1] if 0 <= i + 1 <= n else 0.0
        cuda.syncthreads()
        for s in range(n_steps):
            f = hertz(kap, su[t] - su[t + 1])
            sf[t + 1] = f
            if i == wall_slot and halo <= t < halo + tile:  # the tile that owns it, not a halo copy
                fw[s] = f
            if t == 0:
                sf[0] = hertz(kappa[i - 1], u_in[i - 1] - su[0]) if 0 < i <= n else 0.0
            cuda.syncthreads()
            vi += dt * ((sf[t] - f) * im)
            ui += dt * vi
            su[t] = ui
            cuda.syncthreads()
        if halo <= t < halo + tile and inside:
            u_out[i] = ui
            v_out[i] = vi

    return kernel, width
