"""The CUDA kernel of a law run by the generated engines: :mod:`.generated`'s loop on a GPU.

One thread per member, arrays (slot, member) as in :mod:`.cuda_kernels`; the law's device
functions are compiled from the same Python source as its CPU functions (``spec.force.py_func``
...), so the GPU and the CPU evaluate one definition. The steps, adaptive step controller and
probes are those of ``generated.law_kernels``'s ``run``; the law's state is one (slot, member)
array. A member with a protected body or mass-in-mass beads steps with the extension's block
(:mod:`.extension`, around this law's force pass, as the CPU's generated run does), its step
bound the law's plus the extension's (``core.extension.extension_stride``). Checked in Numba's
CUDA simulator against the CPU engine (tests/cuda_laws.py).
"""

from __future__ import annotations

import math
from typing import Any

from .device import _cuda, _simulated, peak_tracker
from .extension import device_functions
from ..core.generated import bisection
from ..core.extension import EXT_CLIN, EXT_IMIN, EXT_KIN, EXT_KLIN
from ..core.kernels import DELTA_MIN, LAW_ELASTIC

_CACHE: dict = {}
cuda: Any = None  # numba.cuda (a module global, as cuda_kernels: the simulator swaps it)


def generated_kernel(code: int):
    """The thread-per-member kernel for law ``code``, compiled on first use."""
    global cuda
    from ...laws import law_of_code

    spec = law_of_code(code)
    if code in _CACHE:
        return _CACHE[code]
    cuda = _cuda()
    dev = cuda.jit(device=True)
    inline = {} if _simulated() else {"forceinline": True}
    # (Numba dispatchers: their Python functions, compiled again for the device)
    functions: tuple[Any, ...] = (spec.force, spec.state, spec.energy, spec.partials, spec.overlap_at_energy)
    force, update, stored, partials = (dev(f.py_func) for f in functions[:4])
    if functions[4] is not None:
        inverse = dev(functions[4].py_func)
    else:
        inverse = dev(bisection(stored))  # the CPU loop's bisection, compiled for the device

    @dev
    def overlap(u, d0, de, dx0, rsum, j, m):
        if de[j, m] != 0.0:
            dx = dx0[j, m] - (u[j, m] - u[j + 1, m])
            dist = math.sqrt(dx * dx + de[j, m] * de[j, m])
            return rsum[j, m] - dist, dx / dist
        return u[j, m] - u[j + 1, m] + d0[j, m], 1.0

    @dev
    def forces(u, v, kappa, damping, d0, de, dx0, rsum, g, state, n, m):
        power = 0.0
        for j in range(n):
            if kappa[j, m] == 0.0:
                g[j + 1, m] = 0.0
                continue
            d, c = overlap(u, d0, de, dx0, rsum, j, m)
            rate = c * (v[j, m] - v[j + 1, m])
            state[j, m] = update(d, rate, kappa[j, m], damping[j, m], state[j, m])
            if d < 0.0:
                g[j + 1, m] = 0.0
                continue
            if d <= DELTA_MIN:
                d = 0.0
            f = force(d, rate, kappa[j, m], damping[j, m], state[j, m])
            fel = force(d, 0.0, kappa[j, m], damping[j, m], state[j, m])
            f = f if f > 0.0 else 0.0
            power += (f - fel) * rate
            g[j + 1, m] = c * f
        return power

    @dev
    def stride_of(u, v, a, kappa, damping, d0, de, dx0, rsum, dcap, state, inv_mass, horizon, block, c_steps, n, m):
        kprev = 0.0
        cprev = 0.0
        weff = 0.0
        hh = 0.5 * horizon * horizon
        for j in range(n):
            k = 0.0
            c = 0.0
            if kappa[j, m] != 0.0:
                d, cc = overlap(u, d0, de, dx0, rsum, j, m)
                rate = v[j, m] - v[j + 1, m]
                q = a[j, m] - a[j + 1, m]
                est = d + 2.0 * (q if q > 0.0 else 0.0) * hh
                if rate > 0.0 and d + 2.0 * rate * horizon > 0.0:
                    dp = d if d > 0.0 else 0.0
                    e = stored(dp, kappa[j, m], damping[j, m]) + 0.5 * rate * rate / (inv_mass[j, m] + inv_mass[j + 1, m])
                    de_ = inverse(e, kappa[j, m], damping[j, m])
                    est = de_ if de_ > est else est
                est = est if est < dcap[j, m] else dcap[j, m]
                if est > 0.0:
                    vin = state[j, m] if state[j, m] > abs(rate) else abs(rate)
                    k, c, _, _ = partials(est, abs(rate), kappa[j, m], damping[j, m], vin)
                    k = abs(k)
                    c = abs(c)
            om2 = 2.0 * (kprev + k) * inv_mass[j, m]
            beta = 2.0 * (cprev + c) * inv_mass[j, m]
            weff = max(weff, math.sqrt(om2 + 0.25 * beta * beta) + 0.5 * beta)
            kprev = k
            cprev = c
        return max(1, int(math.ceil(block * c_steps * weff - 1e-9)))

    track_peak = peak_tracker(cuda, inline)

    @cuda.jit(device=True, **inline)
    def law_forces(u, v, kappa, damping, d0, de, dx0, rsum, law, g, dyield, dmax, dres, kres, n, m):
        """``forces`` in the built-in laws' signature (the extension's block calls it; the state in dmax)."""
        return forces(u, v, kappa, damping, d0, de, dx0, rsum, g, dmax, n, m)

    ext_fns = device_functions(cuda, inline, law_forces, track_peak)
    extended_block, extended_probes = ext_fns["extended_block"], ext_fns["extended_probes"]
    internal_accelerations, extended_bound = ext_fns["internal_accelerations"], ext_fns["extended_bound"]

    @dev
    def extension_stride(ext, inv_mass, block, c_steps, n, m):
        """core.extension.extension_stride for member m."""
        weff = 0.0
        kprev = 0.0
        cprev = 0.0
        for i in range(n):
            w, kprev, cprev = extended_bound(kprev, 0.0, cprev, 0.0, LAW_ELASTIC, ext[EXT_KLIN, i, m], ext[EXT_CLIN, i, m],
                                             ext[EXT_KIN, i, m], ext[EXT_IMIN, i, m], inv_mass[i, m])
            weff = max(weff, w)
        return int(math.ceil(block * c_steps * weff - 1e-9))

    @cuda.jit
    def kernel(u, v, a, g, vp, state, mass, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, dcap, wall_slot,
               interval, stride, n_sub, n_eval, c_steps, relax, k_start, k_stop, rec, out_f, out_ke, out_pe, out_ed,
               out_v, record_v, fmax, peak, acc, status, wa, ext, ext_on, body_slot, out_b):
        m = cuda.grid(1)
        if m >= status.shape[0] or status[m] != 0:
            return
        n = a.shape[0]
        ws = wall_slot[m] + 1
        nsub = n_sub[m]
        block = interval / nsub
        adaptive = stride[m] == 0
        ns = stride[m] if not adaptive else int(acc[3, m])
        step = acc[2, m]
        eon = ext_on[m]
        bs = body_slot[m]
        if eon:  # the internal masses' accelerations: a function of the positions, not state
            internal_accelerations(u, ext, wa, n, m)
        for k in range(k_start, k_stop):
            for b in range(nsub):
                if adaptive and ((k - 1) * nsub + b) % n_eval[m] == 0:
                    req = stride_of(u, v, a, kappa, damping, d0, de, dx0, rsum, dcap, state, inv_mass,
                                    n_eval[m] * block, block, c_steps[m], n, m)
                    if eon:
                        req += extension_stride(ext, inv_mass, block, c_steps[m], n, m)
                    # kernels._adapt_stride on acc[3:8]
                    if req > ns:
                        ns = req
                        acc[4, m] = 0.0
                        acc[5, m] = 0.0
                    elif req < ns:
                        acc[4, m] += 1.0
                        acc[5, m] = max(acc[5, m], req)
                        if acc[4, m] >= relax[m]:
                            ns = int(acc[5, m])
                            acc[4, m] = 0.0
                            acc[5, m] = 0.0
                    else:
                        acc[4, m] = 0.0
                        acc[5, m] = 0.0
                    acc[3, m] = ns
                    acc[6, m] = max(acc[6, m], ns)
                    acc[7, m] = min(acc[7, m], ns)
                dt = block / ns
                half = 0.5 * dt
                t0 = (k - 1) * interval + b * block
                if eon:
                    extended_block(u, v, vp, a, wa, g, kappa, damping, d0, de, dx0, rsum, fext, inv_mass, 0, state,
                                   state, state, state, ext, bs, ws, t0, dt, ns, peak, acc, n, m)
                    step += ns
                    continue
                for i in range(n):
                    v[i, m] += half * a[i, m]
                    u[i, m] += dt * v[i, m]
                for s in range(ns):
                    for i in range(n):
                        vp[i, m] = v[i, m] + half * a[i, m]
                    p = forces(u, vp, kappa, damping, d0, de, dx0, rsum, g, state, n, m)
                    acc[0, m] += half * (acc[1, m] + p)
                    acc[1, m] = p
                    track_peak(g[ws, m], t0 + (s + 1) * dt, dt, peak, m)
                    last = s == ns - 1
                    for i in range(n):
                        a[i, m] = (g[i, m] - g[i + 1, m] + fext[i, m]) * inv_mass[i, m]
                        if last:
                            v[i, m] += half * a[i, m]
                        else:
                            v[i, m] += dt * a[i, m]
                            u[i, m] += dt * v[i, m]
                step += ns
            row = k - k_start
            for j in range(rec.shape[0]):
                out_f[row, j, m] = g[rec[j] + 1, m]
            for j in range(fmax.shape[0]):
                x = g[j + 1, m]
                if x > fmax[j, m]:
                    fmax[j, m] = x
            ke = 0.0
            for i in range(n):
                ke += 0.5 * mass[i, m] * v[i, m] * v[i, m]
            pe = 0.0
            for j in range(n):
                if kappa[j, m] != 0.0:
                    d, c = overlap(u, d0, de, dx0, rsum, j, m)
                    if d > 0.0:
                        pe += stored(d, kappa[j, m], damping[j, m])
            for i in range(n):
                pe -= fext[i, m] * u[i, m]
            out_ke[row, m] = ke
            out_pe[row, m] = pe
            if eon:
                extended_probes(row, u, v, a, d0, ext, bs, out_ke, out_pe, out_b, n, m)
            out_ed[row, m] = acc[0, m]
            if record_v[m]:
                for i in range(out_v.shape[1]):
                    out_v[row, i, m] = v[i, m]
            if not (math.isfinite(ke) and math.isfinite(g[1, m])):
                acc[2, m] = step
                status[m] = 1
                return
        acc[2, m] = step

    _CACHE[code] = kernel
    return kernel
