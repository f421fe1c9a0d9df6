"""The CUDA engine's extension: a protected body's mount and mass-in-mass beads on the device.

The law is the CPU's (:mod:`hertzchain.integrate.core.extension`): its per-contact and per-body
scalar functions (``linear_force``, ``body_accelerations``, ``internal_acceleration``,
``body_energies``, ``extended_bound``)
are compiled from their Python source as device functions, and the pieces here lay them over the
device layout, where the extension of member m is ``ext[column, slot, m]`` (the CPU's
``ext[slot, column]``, one member after another, with the member last so that a warp's threads
read neighbouring addresses). :func:`device_functions` builds them for
:func:`hertzchain.integrate.cuda.kernels._kernels` (compiled lazily: importing needs no GPU), and
``extended_block`` is ``core.kernels.step_extended`` for one member, in its order of operations.
"""

from __future__ import annotations

from typing import Any

from ..core import extension as core_ext
from ..core.extension import EXT_ACC, EXT_CLIN, EXT_IMIN, EXT_KIN, EXT_KLIN, EXT_MIN, EXT_W, EXT_WV

__all__ = ["device_functions"]


def device_functions(cuda: Any, inline: dict, forces_general: Any, track_peak: Any) -> dict:
    """The extension's device functions by name (``cuda``: numba.cuda or the simulator's module;
    ``inline``: the device functions' options; ``forces_general``, ``track_peak``: the kernels'
    device functions, which the extended block calls)."""
    linear_force = cuda.jit(device=True, **inline)(core_ext.linear_force.py_func)
    body_accelerations = cuda.jit(device=True, **inline)(core_ext.body_accelerations.py_func)
    body_energies = cuda.jit(device=True, **inline)(core_ext.body_energies.py_func)
    extended_bound = cuda.jit(device=True, **inline)(core_ext.extended_bound.py_func)
    internal_acceleration = cuda.jit(device=True, **inline)(core_ext.internal_acceleration.py_func)

    @cuda.jit(device=True, **inline)
    def stride_row(sc, damping, law, ext, inv_mass, j, m):
        """required_stride's omega_eff [rad/s] of body j of member m with the extension, from the
        contacts' tangent stiffnesses in sc (the warp kernel's rows, each on its own: contact
        j - 1's total stiffness and damping recomputed, the same numbers as the running ones)."""
        kprev = 0.0
        cprev = 0.0
        if j > 0:
            _, kprev, cprev = extended_bound(0.0, sc[j - 1, m], 0.0, damping[j - 1, m], law, ext[EXT_KLIN, j - 1, m],
                                             ext[EXT_CLIN, j - 1, m], ext[EXT_KIN, j - 1, m], ext[EXT_IMIN, j - 1, m],
                                             inv_mass[j - 1, m])
        return extended_bound(kprev, sc[j, m], cprev, damping[j, m], law, ext[EXT_KLIN, j, m], ext[EXT_CLIN, j, m],
                              ext[EXT_KIN, j, m], ext[EXT_IMIN, j, m], inv_mass[j, m])[0]

    @cuda.jit(device=True, **inline)
    def internal_accelerations(u, ext, wa, n, m):
        """The internal masses' accelerations of member m from its positions (verlet_run's start)."""
        for i in range(n):
            wa[i, m] = internal_acceleration(ext[EXT_KIN, i, m], ext[EXT_W, i, m], u[i, m], ext[EXT_IMIN, i, m])

    @cuda.jit(device=True, **inline)
    def linear_forces(u, vp, d0, ext, g, j, m):
        """Contact j's linear spring and dashpot added to its force g[j + 1, m]; returns their power [W]
        (core.extension.forces_linear's term)."""
        k = ext[EXT_KLIN, j, m]
        c = ext[EXT_CLIN, j, m]
        if k != 0.0 or c != 0.0:
            f, pj = linear_force(k, c, u[j, m] - u[j + 1, m] + d0[j, m], vp[j, m] - vp[j + 1, m])
            g[j + 1, m] += f
            return pj
        return 0.0

    @cuda.jit(device=True, **inline)
    def linear_power(u, vp, d0, ext, n, m):
        """The power [W] of member m's linear dashpots, summed in contact order (forces_linear's)."""
        pl = 0.0
        for j in range(n):
            k = ext[EXT_KLIN, j, m]
            c = ext[EXT_CLIN, j, m]
            if k != 0.0 or c != 0.0:
                pl += linear_force(k, c, u[j, m] - u[j + 1, m] + d0[j, m], vp[j, m] - vp[j + 1, m])[1]
        return pl

    @cuda.jit(device=True, **inline)
    def body_work(g, vp, ext, bs, half, m):
        """The trapezoidal step of the work contact N has done on the protected body ``bs``."""
        pb = g[bs, m] * vp[bs, m]  # contact N (g[N + 1]) pushing body N + 1
        ext[EXT_ACC, 0, m] += half * (ext[EXT_ACC, 1, m] + pb)
        ext[EXT_ACC, 1, m] = pb

    @cuda.jit(device=True, **inline)
    def extended_kick(u, v, a, wa, g, fext, inv_mass, ext, dt, half, last, i, m):
        """Body i of member m and its internal mass: accelerations, then step_extended's kick and
        drift, or the closing half kick on a block's last step."""
        a[i, m], wa[i, m] = body_accelerations(g[i, m], g[i + 1, m], fext[i, m], inv_mass[i, m], ext[EXT_KIN, i, m],
                                               ext[EXT_W, i, m], u[i, m], ext[EXT_IMIN, i, m])
        if last:
            v[i, m] += half * a[i, m]
            ext[EXT_WV, i, m] += half * wa[i, m]
        else:
            v[i, m] += dt * a[i, m]
            u[i, m] += dt * v[i, m]
            ext[EXT_WV, i, m] += dt * wa[i, m]
            ext[EXT_W, i, m] += dt * ext[EXT_WV, i, m]

    @cuda.jit(device=True, **inline)
    def extended_open(u, v, a, wa, ext, dt, half, i, m):
        """A block's opening half kick and drift of body i of member m and its internal mass."""
        v[i, m] += half * a[i, m]
        u[i, m] += dt * v[i, m]
        ext[EXT_WV, i, m] += half * wa[i, m]
        ext[EXT_W, i, m] += dt * ext[EXT_WV, i, m]

    @cuda.jit(device=True)
    def extended_block(u, v, vp, a, wa, g, kappa, damping, d0, de, dx0, rsum, fext, inv_mass, law, dyield, dmax, dres,
                       kres, ext, bs, ws, t0, dt, ns, peak, acc, n, m):
        """core.kernels.step_extended for member m: one block of ``ns`` steps, its opening half kick
        and drift included; the body's work (contact N's power on body ``bs``, trapezoidal) in
        ext[EXT_ACC, 0:2, m] when ``bs`` >= 0."""
        half = 0.5 * dt
        for i in range(n):
            extended_open(u, v, a, wa, ext, dt, half, i, m)
        for s in range(ns):
            for i in range(n):
                vp[i, m] = v[i, m] + half * a[i, m]
            p = forces_general(u, vp, kappa, damping, d0, de, dx0, rsum, law, g, dyield, dmax, dres, kres, n, m)
            pl = 0.0  # core.extension.forces_linear
            for j in range(n):
                pl += linear_forces(u, vp, d0, ext, g, j, m)
            p += pl
            acc[0, m] += half * (acc[1, m] + p)  # trapezoidal integral of the dissipated power
            acc[1, m] = p
            if bs >= 0:
                body_work(g, vp, ext, bs, half, m)
            track_peak(g[ws, m], t0 + (s + 1) * dt, dt, peak, m)
            # each body's accelerations read only its own position and the forces: per body, then the
            # kick (step_extended's two loops give the same numbers)
            for i in range(n):
                extended_kick(u, v, a, wa, g, fext, inv_mass, ext, dt, half, s == ns - 1, i, m)

    @cuda.jit(device=True, **inline)
    def extended_probes(row, u, v, a, d0, ext, bs, out_ke, out_pe, out_b, n, m):
        """The extension's part of member m's probes at a sample (row ``row``): the internal masses'
        kinetic energy and the linear and internal springs' energy added to out_ke, out_pe
        (core.extension.energies_extended, in slot order); with a protected body (``bs`` >= 0) its
        displacement, velocity, acceleration and the work done on it into out_b[row, :, m]."""
        ke = 0.0
        pe = 0.0
        for i in range(n):
            k, p = body_energies(ext[EXT_MIN, i, m], ext[EXT_WV, i, m], ext[EXT_KIN, i, m], ext[EXT_W, i, m] - u[i, m],
                                 ext[EXT_KLIN, i, m], u[i, m] - u[i + 1, m] + d0[i, m])
            ke += k
            pe += p
        out_ke[row, m] += ke
        out_pe[row, m] += pe
        if bs >= 0:
            out_b[row, 0, m] = u[bs, m]
            out_b[row, 1, m] = v[bs, m]
            out_b[row, 2, m] = a[bs, m]
            out_b[row, 3, m] = ext[EXT_ACC, 0, m]

    return {"extended_bound": extended_bound, "internal_accelerations": internal_accelerations,
            "extended_block": extended_block, "extended_probes": extended_probes, "linear_forces": linear_forces,
            "linear_power": linear_power, "body_work": body_work, "extended_kick": extended_kick,
            "extended_open": extended_open, "stride_row": stride_row}
