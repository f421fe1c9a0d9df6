"""The CUDA kernels of the batched engine: :func:`kernels._verlet_run`'s velocity Verlet on a GPU.

Written with ``numba.cuda``, the same Numba family as the CPU kernels, so they also run on a CPU
through Numba's CUDA simulator (``NUMBA_ENABLE_CUDASIM=1``). Compiled lazily (:func:`_kernels`,
:func:`_register_kernel`), so that importing needs no GPU. Three kernels, one order of
operations: ``verlet_kernel`` (one thread per member), ``warp_kernel`` (one warp per member, a
lane per slot) and the register kernel for aligned elastic chains (a member's state on the chip);
the per-contact and per-body device functions are shared, so they integrate with the very same
arithmetic. The general kernels also run Thornton's elastic-plastic law: its device function is
the CPU kernel's own source (``core.kernels.elastoplastic_force.py_func``, and the energies'
per-contact terms likewise), its state (``dyield``, ``dmax``, ``dres``, ``kres``) four more
(slot, member) arrays updated in place; and a protected body and mass-in-mass beads, with the
device pieces of :mod:`hertzchain.integrate.cuda.extension` (the CPU's law, the same source). Every per-slot array is (slot, member), as
:func:`hertzchain.integrate.cuda.launch.run_packed` lays them out, so that the threads of a warp,
which run neighbouring members, read neighbouring addresses (coalesced).

Measured facts behind the choices (NVIDIA H100, 30-bead chains, fixed 5 ns step,
benchmarks/ensemble.py): ``sqrt(0)`` takes CUDA's slow path, so overlaps below
:data:`kernels.DELTA_MIN` take the square root of a dummy 1.0 and a zero force (1.5-2x). The
general kernels stream the state through global memory every step, which bounds them by memory
bandwidth: 1.7e10 bead-steps/s (thread per member, from 1e4 chains) and 1e10 (warp per member).
The register kernel reads and writes global memory once per block instead: 1.3e10 at 1e3 chains,
1.0e11 at 1e4, 1.3e11 at 1e5, 1.1e11 at 1e6.
"""

from __future__ import annotations

import functools
import math
from typing import Any

from .device import _cuda, _simulated, peak_tracker
from .extension import device_functions
from ..core import energies
from ..core import kernels as core_kernels
from ..core.extension import EXT_CLIN, EXT_IMIN, EXT_KIN, EXT_KLIN
from ..core.kernels import DELTA_MIN, FORCE_MIN, LAW_DASHPOT, LAW_ELASTIC, LAW_ELASTOPLASTIC, LAW_VISCOELASTIC


#: Threads (lanes) per member in the warp-per-member kernel: one warp, one slot per lane for
#: chains of up to 30 beads (32 slots).
LANES = 32


def _lanes() -> int:
    """Lanes per member of the warp kernel: LANES on a GPU; 2 under the simulator, where every
    lane is a Python thread and every barrier costs milliseconds (the kernel's arithmetic does
    not depend on the number of lanes; 2 still exchange forces and maxima between lanes)."""
    return 2 if _simulated() else LANES


_KERNEL = None
cuda: Any = None  # numba.cuda, imported by _kernels()


def _kernels() -> dict:
    """Compile (once) and return the CUDA kernels by name; built lazily so that importing needs no GPU."""
    from numba import float64

    # ``cuda`` is a module global: Numba's simulator swaps the kernels' global reference to
    # numba.cuda for its fake module (cuda.grid...), and cannot see a local one.
    global _KERNEL, cuda
    if _KERNEL is not None:
        return _KERNEL
    cuda = _cuda()
    nl = _lanes()  # a compile-time constant of the warp kernel
    # inlined by NVVM on a GPU (the simulator takes no such option)
    inline = {} if _simulated() else {"forceinline": True}

    # Thornton's elastic-plastic law and its energies: the CPU kernels' own Python source compiled
    # for the device (one definition of the law; plain math, which numba.cuda takes)
    elastoplastic_force = cuda.jit(device=True, **inline)(core_kernels.elastoplastic_force.py_func)
    unloading_energy = cuda.jit(device=True, **inline)(energies.unloading_energy.py_func)
    contact_plastic_work = cuda.jit(device=True, **inline)(energies.contact_plastic_work.py_func)

    @cuda.jit(device=True, **inline)
    def hertz(kap, d):
        # kappa d^(3/2), 0 for d <= DELTA_MIN; sqrt of a dummy 1.0 there, not of 0 (CUDA's slow path)
        ok = d > DELTA_MIN
        dd = d if ok else 1.0
        f = kap * dd * math.sqrt(dd)
        return f if ok else 0.0

    # The per-contact and per-body pieces below are shared by both kernels (one thread per member,
    # one warp per member), so that they integrate with the very same arithmetic; inlined, they
    # compile to what the kernels held written out.

    @cuda.jit(device=True, **inline)
    def overlap(u, d0, de, dx0, rsum, j, m):
        """Overlap [m] of contact j of member m, as kernels.required_stride and
        kernels.potential_energy take it: along the line of centres of a misaligned pair."""
        if de[j, m] != 0.0:
            dx = dx0[j, m] - (u[j, m] - u[j + 1, m])
            return rsum[j, m] - math.sqrt(dx * dx + de[j, m] * de[j, m])
        return u[j, m] - u[j + 1, m] + d0[j, m]

    @cuda.jit(device=True, **inline)
    def contact_general(u, v, kappa, damping, d0, de, dx0, rsum, law, g, dyield, dmax, dres, kres, j, m, power):
        """kernels.contact_general for contact j of member m: writes its axial force g[j + 1, m]
        and returns ``power`` plus the contact's dissipated power [W] (the running sum). The
        elastic-plastic law's state (dmax, dres, kres; (slot, member) like the rest, read only for
        that law) is updated in place."""
        if de[j, m] != 0.0:
            dx = dx0[j, m] - (u[j, m] - u[j + 1, m])
            dist = math.sqrt(dx * dx + de[j, m] * de[j, m])
            d = rsum[j, m] - dist
            c = dx / dist
        else:
            d = u[j, m] - u[j + 1, m] + d0[j, m]
            c = 1.0
        if d < 0.0:
            g[j + 1, m] = 0.0
            return power
        if law == LAW_ELASTOPLASTIC:  # before the Hertz square root, which this law does not use
            if kappa[j, m] == 0.0:  # no contact (free end, padding)
                g[j + 1, m] = 0.0
                return power
            rate = c * (v[j, m] - v[j + 1, m])
            f, fep, dmax[j, m], dres[j, m], kres[j, m] = elastoplastic_force(
                d if d > DELTA_MIN else 0.0, rate, kappa[j, m], damping[j, m], dyield[j, m], dmax[j, m], dres[j, m],
                kres[j, m])
            g[j + 1, m] = c * f
            return power + (f - fep) * rate
        sd = 0.0
        if d > DELTA_MIN:
            sd = math.sqrt(d)
        else:
            d = 0.0
        fel = kappa[j, m] * d * sd
        if law == LAW_ELASTIC:
            g[j + 1, m] = c * fel
            return power
        rate = c * (v[j, m] - v[j + 1, m])
        if law == LAW_VISCOELASTIC:
            f = fel + kappa[j, m] * damping[j, m] * sd * rate
        else:
            f = fel + damping[j, m] * rate
        f = f if f > FORCE_MIN else 0.0  # the CPU engines' floor (primitives.FORCE_MIN)
        g[j + 1, m] = c * f
        return power + (f - fel) * rate

    @cuda.jit(device=True, **inline)
    def tangent_stiffness(u, v, a, kappa, d0, de, dx0, rsum, dcap, inv_mass, horizon, hh, j, m):
        """kernels.required_stride's tangent stiffness [N/m] of contact j of member m over the
        horizon [s] (hh = horizon^2 / 2)."""
        if kappa[j, m] == 0.0:
            return 0.0
        d = overlap(u, d0, de, dx0, rsum, j, m)
        rate = v[j, m] - v[j + 1, m]
        q = a[j, m] - a[j + 1, m]
        dt_ = d + 2.0 * (q if q > 0.0 else 0.0) * hh
        if rate > 0.0 and d + 2.0 * rate * horizon > 0.0:
            dp = d if d > 0.0 else 0.0
            e = 0.4 * kappa[j, m] * dp * dp * math.sqrt(dp) + 0.5 * rate * rate / (
                inv_mass[j, m] + inv_mass[j + 1, m])
            de_ = (2.5 * e / kappa[j, m]) ** 0.4
            dt_ = de_ if de_ > dt_ else dt_
        dt_ = dt_ if dt_ < dcap[j, m] else dcap[j, m]
        return 1.5 * kappa[j, m] * math.sqrt(dt_) if dt_ > 0.0 else 0.0

    @cuda.jit(device=True, **inline)
    def adapt_stride(req, ns, relax, r4, r5):
        """kernels._adapt_stride on the controller state (r4, r5) = (acc[4], acc[5]) of a member:
        returns the new (ns, r4, r5)."""
        if req > ns:
            return req, 0.0, 0.0
        if req < ns:
            r4 += 1.0
            r5 = max(r5, req)
            if r4 >= relax:
                return int(r5), 0.0, 0.0
            return ns, r4, r5
        return ns, 0.0, 0.0

    @cuda.jit(device=True, **inline)
    def kick_drift(u, v, a, fl, fr, fext, inv_mass, dt, half, last, i, m):
        """Body i of member m between contact forces fl (left) and fr (right): its acceleration,
        then kernels.step_elastic's kick and drift, or the closing half kick on the last step."""
        ai = (fl - fr + fext[i, m]) * inv_mass[i, m]
        a[i, m] = ai
        if last:
            v[i, m] += half * ai
        else:
            v[i, m] += dt * ai
            u[i, m] += dt * v[i, m]

    @cuda.jit(device=True)
    def forces_general(u, v, kappa, damping, d0, de, dx0, rsum, law, g, dyield, dmax, dres, kres, n, m):
        """kernels.forces_general for member m (returns the dissipated power [W])."""
        power = 0.0
        for j in range(n):
            power = contact_general(u, v, kappa, damping, d0, de, dx0, rsum, law, g, dyield, dmax, dres, kres, j, m,
                                    power)
        return power

    @cuda.jit(device=True, **inline)
    def plastic_probes(row, u, kappa, d0, de, dx0, rsum, fext, dyield, dmax, dres, kres, out_pe, out_wp, n, m):
        """The elastic-plastic member m's probes at a sample (row ``row``), as kernels._verlet_run
        takes them: the potential energy is what the unloading curves give back
        (energies.potential_energy_plastic, written over the Hertz sum of ``sample``) and the
        plastic work so far (energies.plastic_work)."""
        pe = 0.0
        w = 0.0
        for j in range(n):
            pe += unloading_energy(overlap(u, d0, de, dx0, rsum, j, m) - dres[j, m], kres[j, m])
            w += contact_plastic_work(kappa[j, m], dyield[j, m], dmax[j, m], dres[j, m])
        for i in range(n):
            pe -= fext[i, m] * u[i, m]
        out_pe[row, m] = pe
        out_wp[row, m] = w

    @cuda.jit(device=True)
    def required_stride(u, v, a, kappa, d0, de, dx0, rsum, dcap, inv_mass, horizon, block, c_steps, damping, law,
                        ext, eon, n, m):
        """kernels.required_stride for member m (``eon``: with its extension ``ext``)."""
        kprev = 0.0
        cprev = 0.0
        w2 = 0.0
        weff = 0.0
        hh = 0.5 * horizon * horizon
        for j in range(n):
            k = tangent_stiffness(u, v, a, kappa, d0, de, dx0, rsum, dcap, inv_mass, horizon, hh, j, m)
            if eon:
                w, k, cprev = extended_bound(kprev, k, cprev, damping[j, m], law, ext[EXT_KLIN, j, m],
                                             ext[EXT_CLIN, j, m], ext[EXT_KIN, j, m], ext[EXT_IMIN, j, m],
                                             inv_mass[j, m])
                weff = max(weff, w)
            elif law == LAW_ELASTIC:
                w2 = max(w2, (kprev + k) * inv_mass[j, m])
            else:
                w, cprev = damped_bound(kprev, k, cprev, damping[j, m], inv_mass[j, m], law)
                weff = max(weff, w)
            kprev = k
        w = math.sqrt(2.0 * w2) if law == LAW_ELASTIC and not eon else weff
        return max(1, int(math.ceil(block * c_steps * w - 1e-9)))

    @cuda.jit(device=True, **inline)
    def damped_bound(kprev, k, cprev, damp, inv_m, law):
        """kernels.required_stride's bound for a body between contacts of stiffness kprev, k and
        damping cprev, c (dashpot: gamma; Kuwabara-Kono: (2/3) A k): (omega_eff, c)."""
        c = damp if law == LAW_DASHPOT else (2.0 / 3.0) * damp * k
        om2 = 2.0 * (kprev + k) * inv_m
        beta = 2.0 * (cprev + c) * inv_m
        return math.sqrt(om2 + 0.25 * beta * beta) + 0.5 * beta, c

    track_peak = peak_tracker(cuda, inline)

    # a protected body and mass-in-mass beads: core.extension's law, compiled from its source
    ext_fns = device_functions(cuda, inline, forces_general, track_peak)
    extended_bound, extended_block = ext_fns["extended_bound"], ext_fns["extended_block"]
    internal_accelerations, extended_probes = ext_fns["internal_accelerations"], ext_fns["extended_probes"]
    linear_forces, linear_power, body_work = ext_fns["linear_forces"], ext_fns["linear_power"], ext_fns["body_work"]
    extended_kick, extended_open, stride_row = ext_fns["extended_kick"], ext_fns["extended_open"], ext_fns["stride_row"]

    @cuda.jit(device=True, **inline)
    def adapt(u, v, a, kappa, d0, de, dx0, rsum, dcap, inv_mass, horizon, block, c_steps, damping, lw, ext, eon, n, m,
              ns, relax, acc):
        """The adaptive step's evaluation for member m (kernels.required_stride, then
        kernels._adapt_stride on acc[3:8]): returns the new steps per block."""
        req = required_stride(u, v, a, kappa, d0, de, dx0, rsum, dcap, inv_mass, horizon, block, c_steps, damping,
                              lw, ext, eon, n, m)
        ns, r4, r5 = adapt_stride(req, ns, relax, acc[4, m], acc[5, m])
        acc[4, m] = r4
        acc[5, m] = r5
        acc[3, m] = ns
        acc[6, m] = max(acc[6, m], ns)
        acc[7, m] = min(acc[7, m], ns)
        return ns

    @cuda.jit(device=True, **inline)
    def sample(row, gen, u, v, g, mass, kappa, d0, de, dx0, rsum, fext, rec, out_f, fmax, out_ke, out_pe, out_ed,
               out_v, record_v, acc, plastic, n, m):
        """The probes of member m at a sample time into row ``row`` (recorded forces, running
        maxima, energies, velocities); returns False when the state is no longer finite. With
        ``plastic`` (the elastic-plastic law) the potential energy is left to ``plastic_probes``."""
        for j in range(rec.shape[0]):
            out_f[row, j, m] = g[rec[j] + 1, m]
        for j in range(fmax.shape[0]):
            x = g[j + 1, m]
            if x > fmax[j, m]:
                fmax[j, m] = x
        ke = 0.0
        pe = 0.0
        if gen:  # kernels.kinetic_energy and kernels.potential_energy
            for i in range(n):
                ke += 0.5 * mass[i, m] * v[i, m] * v[i, m]
            if not plastic:
                for j in range(n):
                    d = overlap(u, d0, de, dx0, rsum, j, m)
                    if d > 0.0:
                        pe += 0.4 * kappa[j, m] * d * d * math.sqrt(d)
                for i in range(n):
                    pe -= fext[i, m] * u[i, m]
        else:  # kernels.energies_elastic
            for i in range(n):
                ke += mass[i, m] * v[i, m] * v[i, m]
                pe += 0.4 * g[i + 1, m] * (u[i, m] - u[i + 1, m] + d0[i, m]) - fext[i, m] * u[i, m]
            ke = 0.5 * ke
        out_ke[row, m] = ke
        if not plastic:
            out_pe[row, m] = pe
        out_ed[row, m] = acc[0, m]
        if record_v[m]:
            for i in range(out_v.shape[1]):
                out_v[row, i, m] = v[i, m]
        return math.isfinite(ke) and math.isfinite(g[1, m])

    @cuda.jit
    def verlet_kernel(u, v, a, g, vp, mass, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, dcap, dyield, dmax,
                      dres, kres, law, general, wall_slot, interval, stride, n_sub, n_eval, c_steps, relax, k_start,
                      k_stop, rec, out_f, out_ke, out_pe, out_ed, out_wp, out_v, record_v, fmax, peak, acc, status, wa,
                      ext, ext_on, body_slot, out_b):
        """kernels._verlet_run for member m = the thread's index, samples k_start..k_stop - 1.

        Sample k is written at row k - k_start of out_f (rows, rec, M), out_ke/pe/ed/wp (rows, M)
        and out_v (rows, bodies, M). The elastic-plastic state (dyield ... kres, (slot, member))
        and ``out_wp`` are read and written for members of that law only. A member with the
        extension (``ext_on``: a protected body, mass-in-mass beads) steps with its
        ``ext[column, slot, m]`` (cuda.extension) and its internal masses' accelerations ``wa``
        (slot, member); one with a protected body (``body_slot`` >= 0) records it in out_b (rows, 4, M).
        """
        m = cuda.grid(1)
        if m >= status.shape[0] or status[m] != 0:
            return
        n = a.shape[0]
        lw = law[m]
        gen = general[m]
        ws = wall_slot[m] + 1
        nsub = n_sub[m]
        neval = n_eval[m]
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
                if adaptive and ((k - 1) * nsub + b) % neval == 0:
                    ns = adapt(u, v, a, kappa, d0, de, dx0, rsum, dcap, inv_mass, neval * block, block, c_steps[m],
                               damping, lw, ext, eon, n, m, ns, relax[m], acc)
                dt = block / ns
                half = 0.5 * dt
                t0 = (k - 1) * interval + b * block
                if eon:  # kernels.step_extended
                    extended_block(u, v, vp, a, wa, g, kappa, damping, d0, de, dx0, rsum, fext, inv_mass, lw, dyield,
                                   dmax, dres, kres, ext, bs, ws, t0, dt, ns, peak, acc, n, m)
                    step += ns
                    continue
                for i in range(n):
                    v[i, m] += half * a[i, m]
                    u[i, m] += dt * v[i, m]
                if gen:
                    for s in range(ns):
                        for i in range(n):
                            vp[i, m] = v[i, m] + half * a[i, m]
                        p = forces_general(u, vp, kappa, damping, d0, de, dx0, rsum, lw, g, dyield, dmax, dres,
                                           kres, n, m)
                        acc[0, m] += half * (acc[1, m] + p)  # trapezoidal integral of the dissipated power
                        acc[1, m] = p
                        track_peak(g[ws, m], t0 + (s + 1) * dt, dt, peak, m)
                        last = s == ns - 1
                        for i in range(n):
                            kick_drift(u, v, a, g[i, m], g[i + 1, m], fext, inv_mass, dt, half, last, i, m)
                else:
                    for s in range(ns):
                        # kernels.step_elastic (final_step_elastic on the last step: closing half kick)
                        last = s == ns - 1
                        fprev = 0.0
                        for i in range(n):
                            f = hertz(kappa[i, m], u[i, m] - u[i + 1, m] + d0[i, m])
                            g[i + 1, m] = f
                            kick_drift(u, v, a, fprev, f, fext, inv_mass, dt, half, last, i, m)
                            fprev = f
                        track_peak(g[ws, m], t0 + block if last else t0 + (s + 1) * dt, dt, peak, m)
                step += ns
            # --- probes, sampled on the device
            if lw == LAW_ELASTOPLASTIC:
                plastic_probes(k - k_start, u, kappa, d0, de, dx0, rsum, fext, dyield, dmax, dres, kres, out_pe,
                               out_wp, n, m)
            ok = sample(k - k_start, gen, u, v, g, mass, kappa, d0, de, dx0, rsum, fext, rec, out_f, fmax, out_ke,
                        out_pe, out_ed, out_v, record_v, acc, lw == LAW_ELASTOPLASTIC, n, m)
            if eon:
                extended_probes(k - k_start, u, v, a, d0, ext, bs, out_ke, out_pe, out_b, n, m)
                ok = ok and math.isfinite(out_ke[k - k_start, m])
            if not ok:
                acc[2, m] = step
                status[m] = 1
                return
        acc[2, m] = step


    @cuda.jit
    def warp_kernel(u, v, a, g, vp, sc, mass, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, dcap, dyield, dmax,
                    dres, kres, law, general, wall_slot, interval, stride, n_sub, n_eval, c_steps, relax, k_start,
                    k_stop, rec, out_f, out_ke, out_pe, out_ed, out_wp, out_v, record_v, fmax, peak, acc, status, wa,
                    ext, ext_on, body_slot, out_b):
        """verlet_kernel with one block of nl threads per member (m = the block's index).

        Lane l owns slots l, l + nl, ...: forces of its contacts, then (after a barrier) the
        kick and drift of its bodies, as in kernels.step_elastic; sums are taken by lane 0 in
        slot order from per-slot terms in ``sc``, maxima through shared memory. The whole block
        is one member, so every thread takes the same branches and reaches every barrier.
        """
        m = cuda.blockIdx.x
        lane = cuda.threadIdx.x
        if m >= status.shape[0] or status[m] != 0:
            return
        red = cuda.shared.array(nl, float64)
        n = a.shape[0]
        nrec = rec.shape[0]
        lw = law[m]
        gen = general[m]
        ws = wall_slot[m] + 1
        nsub = n_sub[m]
        neval = n_eval[m]
        block = interval / nsub
        adaptive = stride[m] == 0
        ns = stride[m] if not adaptive else int(acc[3, m])
        r4 = acc[4, m]
        r5 = acc[5, m]
        step = acc[2, m]
        eon = ext_on[m]
        bs = body_slot[m]
        if eon and lane == 0:
            internal_accelerations(u, ext, wa, n, m)
        cuda.syncthreads()
        for k in range(k_start, k_stop):
            for b in range(nsub):
                if adaptive and ((k - 1) * nsub + b) % neval == 0:
                    # kernels.required_stride: tangent stiffness of every contact into sc, then the
                    # Gershgorin maximum over the bodies (a maximum: the order does not matter)
                    horizon = neval * block
                    hh = 0.5 * horizon * horizon
                    for j in range(lane, n, nl):
                        sc[j, m] = tangent_stiffness(u, v, a, kappa, d0, de, dx0, rsum, dcap, inv_mass, horizon, hh,
                                                     j, m)
                    cuda.syncthreads()
                    w2 = 0.0  # elastic: max (k_left + k_right) / m; dissipative: max omega_eff
                    for j in range(lane, n, nl):
                        kprev = sc[j - 1, m] if j > 0 else 0.0
                        if eon:
                            w2 = max(w2, stride_row(sc, damping, lw, ext, inv_mass, j, m))
                        elif lw == LAW_ELASTIC:
                            w2 = max(w2, (kprev + sc[j, m]) * inv_mass[j, m])
                        else:
                            cprev = 0.0
                            if j > 0 and lw == LAW_DASHPOT:
                                cprev = damping[j - 1, m]
                            elif j > 0:
                                cprev = (2.0 / 3.0) * damping[j - 1, m] * kprev
                            w, _ = damped_bound(kprev, sc[j, m], cprev, damping[j, m], inv_mass[j, m], lw)
                            w2 = max(w2, w)
                    red[lane] = w2
                    cuda.syncthreads()
                    w2 = 0.0
                    for i in range(nl):
                        w2 = max(w2, red[i])
                    w = math.sqrt(2.0 * w2) if lw == LAW_ELASTIC and not eon else w2
                    req = max(1, int(math.ceil(block * c_steps[m] * w - 1e-9)))
                    ns, r4, r5 = adapt_stride(req, ns, relax[m], r4, r5)
                    if lane == 0:
                        acc[3, m] = ns
                        acc[6, m] = max(acc[6, m], ns)
                        acc[7, m] = min(acc[7, m], ns)
                    cuda.syncthreads()  # red is read before the next reduction writes it
                dt = block / ns
                half = 0.5 * dt
                t0 = (k - 1) * interval + b * block
                for i in range(lane, n, nl):
                    if eon:
                        extended_open(u, v, a, wa, ext, dt, half, i, m)
                    else:
                        v[i, m] += half * a[i, m]
                        u[i, m] += dt * v[i, m]
                for s in range(ns):
                    last = s == ns - 1
                    if gen:
                        for i in range(lane, n, nl):
                            vp[i, m] = v[i, m] + half * a[i, m]
                    cuda.syncthreads()  # positions (and predicted velocities) of the neighbours are written
                    if gen:
                        for j in range(lane, n, nl):  # contact j's dissipated power into sc
                            sc[j, m] = contact_general(u, vp, kappa, damping, d0, de, dx0, rsum, lw, g, dyield, dmax,
                                                       dres, kres, j, m, 0.0)
                            if eon:  # its power summed by lane 0 below, in forces_linear's order
                                linear_forces(u, vp, d0, ext, g, j, m)
                    else:
                        for j in range(lane, n, nl):
                            g[j + 1, m] = hertz(kappa[j, m], u[j, m] - u[j + 1, m] + d0[j, m])
                    cuda.syncthreads()  # every contact force is written
                    if lane == 0:
                        if gen:
                            p = 0.0
                            for j in range(n):  # in contact order, as forces_general sums
                                p += sc[j, m]
                            if eon:
                                p += linear_power(u, vp, d0, ext, n, m)
                            acc[0, m] += half * (acc[1, m] + p)
                            acc[1, m] = p
                            if bs >= 0:
                                body_work(g, vp, ext, bs, half, m)
                            track_peak(g[ws, m], t0 + (s + 1) * dt, dt, peak, m)
                        else:
                            track_peak(g[ws, m], t0 + block if last else t0 + (s + 1) * dt, dt, peak, m)
                    for i in range(lane, n, nl):
                        if eon:
                            extended_kick(u, v, a, wa, g, fext, inv_mass, ext, dt, half, last, i, m)
                        else:
                            kick_drift(u, v, a, g[i, m], g[i + 1, m], fext, inv_mass, dt, half, last, i, m)
                    cuda.syncthreads()  # bodies moved before the next step's forces (and g is read)
                step += ns
            # --- probes: per-slot energy terms into sc and vp, summed by lane 0 in slot order
            row = k - k_start
            for j in range(lane, nrec, nl):
                out_f[row, j, m] = g[rec[j] + 1, m]
            for j in range(lane, fmax.shape[0], nl):
                x = g[j + 1, m]
                if x > fmax[j, m]:
                    fmax[j, m] = x
            for i in range(lane, n, nl):
                if gen:
                    sc[i, m] = 0.5 * mass[i, m] * v[i, m] * v[i, m]
                    d = overlap(u, d0, de, dx0, rsum, i, m)
                    if lw == LAW_ELASTOPLASTIC:  # energies.potential_energy_plastic's term
                        vp[i, m] = unloading_energy(d - dres[i, m], kres[i, m])
                    else:
                        vp[i, m] = 0.4 * kappa[i, m] * d * d * math.sqrt(d) if d > 0.0 else 0.0
                else:
                    sc[i, m] = mass[i, m] * v[i, m] * v[i, m]
                    vp[i, m] = 0.4 * g[i + 1, m] * (u[i, m] - u[i + 1, m] + d0[i, m]) - fext[i, m] * u[i, m]
            if record_v[m]:
                for i in range(lane, out_v.shape[1], nl):
                    out_v[row, i, m] = v[i, m]
            cuda.syncthreads()
            if lane == 0:
                ke = 0.0
                pe = 0.0
                for i in range(n):
                    ke += sc[i, m]
                    pe += vp[i, m]
                if gen:
                    for i in range(n):
                        pe -= fext[i, m] * u[i, m]
                else:
                    ke = 0.5 * ke
                out_ke[row, m] = ke
                out_pe[row, m] = pe
                out_ed[row, m] = acc[0, m]
                if lw == LAW_ELASTOPLASTIC:  # energies.plastic_work, in contact order
                    w = 0.0
                    for j in range(n):
                        w += contact_plastic_work(kappa[j, m], dyield[j, m], dmax[j, m], dres[j, m])
                    out_wp[row, m] = w
                if eon:
                    extended_probes(row, u, v, a, d0, ext, bs, out_ke, out_pe, out_b, n, m)
                if not (math.isfinite(out_ke[row, m]) and math.isfinite(g[1, m])):
                    status[m] = 1
            cuda.syncthreads()
            if status[m] != 0:
                if lane == 0:
                    acc[2, m] = step
                    acc[4, m] = r4
                    acc[5, m] = r5
                return
        if lane == 0:
            acc[2, m] = step
            acc[4, m] = r4
            acc[5, m] = r5

    _KERNEL = {"thread": verlet_kernel, "warp": warp_kernel, "adapt": adapt, "sample": sample,
               "track_peak": track_peak, "hertz": hertz}
    return _KERNEL


#: Threads per block of the register kernel: its per-member parameters sit in shared memory,
#: (slots x threads) doubles per array, under the 48 KiB of static shared memory a block may use.
REGISTER_THREADS = 64


@functools.lru_cache(maxsize=None)
def _register_kernel(p: int, pre: bool):
    """The thread-per-member kernel for aligned elastic members of ``p`` slots, compiled for that p.

    Same integration, same order of operations as ``verlet_kernel``'s elastic branch (so the same
    numbers), but what a step touches stays on the chip: with p known at compile time NVVM
    unrolls the loops over the bodies and keeps positions and velocities in registers, and the
    per-member parameters (kappa, 1/m; d0 and the end forces only when a member is precompressed,
    ``pre``) are read from shared memory. Global memory is read and written once per block (the
    adaptive step's evaluation and the probes read the state there), not once per step: the
    general kernel's state, streamed through global memory every step, held an H100 to ~1.6e10
    bead-steps/s at 1e5 chains (benchmarks/ensemble.py), bound by memory bandwidth.
    """
    from numba import float64

    kern = _kernels()
    adapt, sample, track_peak, hertz = kern["adapt"], kern["sample"], kern["track_peak"], kern["hertz"]
    tpb = REGISTER_THREADS if not pre else REGISTER_THREADS // 2
    # array shapes must be compile-time constants (an expression inside the kernel is not)
    p1 = p + 1
    pp = p if pre else 1

    @cuda.jit
    def register_kernel(u, v, a, g, mass, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, dcap, wall_slot,
                        interval, stride, n_sub, n_eval, c_steps, relax, k_start, k_stop, rec, out_f, out_ke, out_pe,
                        out_ed, out_v, record_v, fmax, peak, acc, status):
        m = cuda.grid(1)
        t = cuda.threadIdx.x
        if m >= status.shape[0] or status[m] != 0:
            return
        skap = cuda.shared.array((p, tpb), float64)
        sinv = cuda.shared.array((p, tpb), float64)
        sd0 = cuda.shared.array((pp, tpb), float64)
        sfx = cuda.shared.array((pp, tpb), float64)
        for i in range(p):
            skap[i, t] = kappa[i, m]
            sinv[i, t] = inv_mass[i, m]
            if pre:
                sd0[i, t] = d0[i, m]
                sfx[i, t] = fext[i, m]
        ul = cuda.local.array(p1, float64)
        vl = cuda.local.array(p, float64)
        pk = cuda.local.array((8, 1), float64)  # the member's peak tracker, a per-thread copy
        no_ext = cuda.local.array((1, 1, 1), float64)  # the extension required_stride takes, never read here
        for j in range(8):
            pk[j, 0] = peak[j, m]
        ul[p] = u[p, m]  # the far end (wall) never moves
        ws = wall_slot[m] + 1
        nsub = n_sub[m]
        neval = n_eval[m]
        block = interval / nsub
        adaptive = stride[m] == 0
        ns = stride[m] if not adaptive else int(acc[3, m])
        step = acc[2, m]
        for k in range(k_start, k_stop):
            for b in range(nsub):
                if adaptive and ((k - 1) * nsub + b) % neval == 0:
                    ns = adapt(u, v, a, kappa, d0, de, dx0, rsum, dcap, inv_mass, neval * block, block, c_steps[m],
                               damping, LAW_ELASTIC, no_ext, False, p, m, ns, relax[m], acc)
                dt = block / ns
                half = 0.5 * dt
                t0 = (k - 1) * interval + b * block
                for i in range(p):  # the block's opening half kick and drift
                    vi = v[i, m] + half * a[i, m]
                    vl[i] = vi
                    ul[i] = u[i, m] + dt * vi
                for s in range(ns - 1):  # kernels.step_elastic
                    fprev = 0.0
                    fw = 0.0
                    for i in range(p):
                        f = hertz(skap[i, t], ul[i] - ul[i + 1] + (sd0[i, t] if pre else 0.0))
                        if i + 1 == ws:
                            fw = f
                        ai = (fprev - f + (sfx[i, t] if pre else 0.0)) * sinv[i, t]
                        vl[i] += dt * ai
                        ul[i] += dt * vl[i]
                        fprev = f
                    track_peak(fw, t0 + (s + 1) * dt, dt, pk, 0)
                fprev = 0.0  # kernels.final_step_elastic: forces, closing half kick, state to memory
                for i in range(p):
                    f = hertz(skap[i, t], ul[i] - ul[i + 1] + (sd0[i, t] if pre else 0.0))
                    g[i + 1, m] = f
                    ai = (fprev - f + (sfx[i, t] if pre else 0.0)) * sinv[i, t]
                    a[i, m] = ai
                    v[i, m] = vl[i] + half * ai
                    u[i, m] = ul[i]
                    fprev = f
                track_peak(g[ws, m], t0 + block, dt, pk, 0)
                step += ns
            # --- probes, sampled on the device (verlet_kernel's, elastic branch)
            if not sample(k - k_start, False, u, v, g, mass, kappa, d0, de, dx0, rsum, fext, rec, out_f, fmax, out_ke,
                          out_pe, out_ed, out_v, record_v, acc, False, p, m):
                status[m] = 1
                break
        for j in range(8):
            peak[j, m] = pk[j, 0]
        acc[2, m] = step

    return register_kernel, tpb
