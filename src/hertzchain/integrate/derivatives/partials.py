"""Partial derivatives of the contact forces, for the tangent and adjoint engines.

:func:`law_partials` gives a hand-written law's force, exactly as
:func:`hertzchain.integrate.core.kernels.forces_general` evaluates it, and its partials as the law
declares them in the registry (:mod:`hertzchain.laws.builtin`, checked against central
differences in tests/test_laws.py). Laws run by the generated engines (the power law,
Hunt-Crossley, users' laws) are differentiated by :mod:`hertzchain.integrate.derivatives.law_derivatives`
from their declarations alone; the fused aligned paths of the tangent and adjoint
(:func:`aligned_partials`, shared by the tangent and the adjoint) keep Kuwabara-Kono's and the
dashpot's partials written out with selects, so that LLVM vectorises them. The forces and hence
every taped value are bit for bit those of before the partials came from the registry; of the
partials only Kuwabara-Kono's dF/d delta on the general path (offsets, a protected body) is
written differently there, so its gradients change at rounding level (~1e-16 relative a step).

:func:`contact_partials` wraps a law in the geometry of the contact (aligned, or misaligned:
delta = R_j + R_{j+1} - sqrt(dx^2 + de^2), axial force f dx / d; docs/conventions.rst) and
returns the derivatives of the axial force with respect to w = u_j - u_{j+1}, the relative
velocity, and the System parameters of the contact.

Non-smooth points (measure zero in parameter space; the derivative returned is the one-sided
derivative of the branch the computed state is on):

- closure and opening, delta = 0: the Hertz force kappa delta^(3/2) is C1 there (force and
  stiffness vanish), so the elastic and Kuwabara-Kono elastic parts are differentiable across
  it; overlaps below ``kernels.DELTA_MIN`` count as zero, derivative zero;
- the Kuwabara-Kono rate term kappa A delta^(1/2) d(delta)/dt has an infinite delta-derivative at
  delta -> 0 (finite at every overlap a step actually visits);
- the clipping f = max(f, 0) of the dissipative laws (no attraction while unloading): derivative
  zero where the clipped force is zero;
- the dashpot force jumps from 0 to gamma d(delta)/dt at closure: the computed result jumps where a
  parameter change moves a closure across a step; the derivative is that between the jumps;
- the elastic-plastic law (:func:`elastoplastic_adjoint`) has a state, and a branch per step:
  loading past the largest overlap (Hertz below the yield overlap, Thornton's line above it)
  or unloading/reloading on the present unloading curve. The branch a step took is held fixed;
  the onset of yield (d = dyield: the force is C1 there, the unloading curve's derivative is
  not) and the turn from loading to unloading are the measure-zero switches.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ...laws import law_of_code
from ...laws.spec import compiled
from ..core.extension import EXT_CLIN, EXT_KLIN, linear_force
from ..core.kernels import DELTA_MIN, LAW_DASHPOT, LAW_ELASTIC, LAW_VISCOELASTIC, elastoplastic_force


#: The built-in laws' partials as their registry entries declare them (:mod:`hertzchain.laws.builtin`:
#: (dF/d delta, dF/d rate, dF/dkappa, dF/dp), the same functions every engine and the laws' tests read).
_ELASTIC = compiled(law_of_code(LAW_ELASTIC).partials)
_VISCOELASTIC = compiled(law_of_code(LAW_VISCOELASTIC).partials)
_DASHPOT = compiled(law_of_code(LAW_DASHPOT).partials)


@njit(cache=True, nogil=True, inline="always")
def law_partials(law, d, sd, rate, kappa, damping):
    """(f, df/d delta, df/d rate, df/d kappa, df/d damping) of contact law ``law`` (LAW_CODES).

    f is computed with the very expression of ``kernels.forces_general`` (clipped at zero for the
    dissipative laws: no partials there), so that a step taken with these forces is the engine's
    step bit for bit (:mod:`hertzchain.integrate.derivatives.tangent`); the partials are the law's declared
    ones (:data:`_ELASTIC` ...)."""
    if law == LAW_ELASTIC:
        fd, fr, fk, fa = _ELASTIC(d, rate, kappa, damping, 0.0)
        return kappa * d * sd, fd, fr, fk, fa
    if law == LAW_VISCOELASTIC:
        f = kappa * d * sd + kappa * damping * sd * rate  # Kuwabara-Kono
        if f <= 0.0:
            return 0.0, 0.0, 0.0, 0.0, 0.0
        fd, fr, fk, fa = _VISCOELASTIC(d, rate, kappa, damping, 0.0)
        return f, fd, fr, fk, fa
    if law == LAW_DASHPOT:
        f = kappa * d * sd + damping * rate  # Hertz with a linear dashpot
        if f <= 0.0:
            return 0.0, 0.0, 0.0, 0.0, 0.0
        fd, fr, fk, fa = _DASHPOT(d, rate, kappa, damping, 0.0)
        return f, fd, fr, fk, fa
    return np.nan, np.nan, np.nan, np.nan, np.nan  # unknown law: poisons the result (refused upstream)


@njit(cache=True, nogil=True, inline="always")
def contact_geometry(uj, uj1, d0, de, dx0, rsum):
    """(overlap d [m], direction cosine c = dx / dist, axial gap dx [m], centre distance dist [m]) of
    a contact whose beads sit at ``uj``, ``uj1`` [m], as ``kernels.forces_general`` takes them: aligned
    (``de`` = 0: d = u_j - u_{j+1} + d0, c = 1, dist = 1 as a placeholder) or misaligned (d = R_j +
    R_{j+1} - sqrt(dx^2 + de^2), dx = dx0 - (u_j - u_{j+1}); docs/conventions.rst)."""
    if de != 0.0:
        dx = dx0 - (uj - uj1)
        dist = np.sqrt(dx * dx + de * de)
        return rsum - dist, dx / dist, dx, dist
    return uj - uj1 + d0, 1.0, 0.0, 1.0


@njit(cache=True, nogil=True, inline="always")
def has_mount(ext, j):
    """Whether contact slot j has a linear spring or dashpot in ``ext`` (a protected body's mount)."""
    return ext.shape[0] > 0 and (ext[j, EXT_KLIN] != 0.0 or ext[j, EXT_CLIN] != 0.0)


@njit(cache=True, nogil=True, inline="always")
def mount_partials(ext, j, uj, uj1, vj, vj1, d0):
    """Contact slot j's linear spring and dashpot in ``ext`` (:func:`has_mount`: a protected body's
    mount, ``extension.linear_force``, in parallel with the contact law) at overlap w + d0 closing at
    vrel: (force [N], dF/dw = dF/dd0 = k [N/m], dF/dvrel = c [N s/m], dF/dk = the overlap [m],
    dF/dc = the rate [m/s]). The callers test :func:`has_mount` first: adding the zeros of every
    other contact cost the general reverse sweep ~10 %."""
    k = ext[j, EXT_KLIN]
    c = ext[j, EXT_CLIN]
    dl = uj - uj1 + d0
    rl = vj - vj1
    return linear_force(k, c, dl, rl)[0], k, c, dl, rl


@njit(cache=True, nogil=True, inline="always")
def contact_partials(uj, uj1, vj, vj1, kappa, damping, d0, de, dx0, rsum, law):
    """Axial force F of one contact and its partials, as ``kernels.forces_general`` computes F.

    Returns (F, dF/dw, dF/dvrel, dF/dkappa, dF/ddamping, dF/dd0, dF/dde, dF/ddx0, dF/drsum) with
    w = u_j - u_{j+1} and vrel = v_j - v_{j+1} (the velocities the force sees).
    """
    d, c, dx, dist = contact_geometry(uj, uj1, d0, de, dx0, rsum)
    if d < 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    if d <= DELTA_MIN:
        d = 0.0
    sd = np.sqrt(d)
    vrel = vj - vj1
    f, fd, fr, fk, fa = law_partials(law, d, sd, c * vrel, kappa, damping)
    if de == 0.0:
        return f, fd, fr, fk, fa, fd, 0.0, 0.0, 0.0
    # misaligned: d = rsum - dist(dx), c = dx / dist, F = c f(d, c vrel)
    inv3 = 1.0 / (dist * dist * dist)
    dc_dw = -de * de * inv3
    gw = dc_dw * f + c * (fd * c + fr * vrel * dc_dw)
    dc_dde = -dx * de * inv3
    gde = dc_dde * f + c * (-fd * de / dist + fr * vrel * dc_dde)
    return c * f, gw, c * c * fr, c * fk, c * fa, 0.0, gde, -gw, c * fd


@njit(cache=True, nogil=True, inline="always")
def plastic_contact_adjoint(uj, uj1, vj, vj1, kappa, damping, d0, de, dx0, rsum, dyield, dmax, dres, kres, fbar,
                            dresb, kresb):
    """Reverse-mode derivative of one elastic-plastic contact as ``plastic.contact_general`` computes
    it, the geometry of offset beads included (d = R_j + R_{j+1} - dist, c = dx / dist, axial force
    c f(d, c v_rel): :func:`contact_partials`'s geometry around :func:`elastoplastic_adjoint`).

    Given the adjoint ``fbar`` of the axial force and those of the state out (``dresb``,
    ``kresb``), returns (F, w_bar, vrel_bar, kappa_bar, damping_bar, d0_bar, de_bar, dx0_bar,
    rsum_bar, dyield_bar, dresb in, kresb in), w = u_j - u_{j+1}, vrel = v_j - v_{j+1}; an open
    contact (d < 0, kappa = 0) has none and carries the state's adjoints through."""
    d, c, dx, dist = contact_geometry(uj, uj1, d0, de, dx0, rsum)
    if d < 0.0 or kappa == 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, dresb, kresb
    live = d > DELTA_MIN  # below it the engine takes d = 0: no derivative by d
    vrel = vj - vj1
    f, dbar, rbar, kbar, abar, dybar, dresb, kresb = elastoplastic_adjoint(
        d if live else 0.0, c * vrel, kappa, damping, dyield, dmax, dres, kres, c * fbar, dresb, kresb)
    dbar = dbar if live else 0.0
    if de == 0.0:
        return f, dbar, rbar, kbar, abar, dbar, 0.0, 0.0, 0.0, dybar, dresb, kresb
    # misaligned: dd/dw = c, dc/dw = -de^2 / dist^3, dd/dde = -de / dist, dc/dde = -dx de / dist^3
    inv3 = 1.0 / (dist * dist * dist)
    cbar = fbar * f + rbar * vrel  # F = c f and rate = c vrel
    dc_dw = -de * de * inv3
    gw = dbar * c + cbar * dc_dw
    gde = -dbar * de / dist - cbar * dx * de * inv3
    return c * f, gw, rbar * c, kbar, abar, 0.0, gde, -gw, dbar, dybar, dresb, kresb


@njit(cache=True, nogil=True, inline="always")
def elastoplastic_adjoint(d, rate, kappa, damping, dyield, dmax, dres, kres, fbar, dresb, kresb):
    """Reverse-mode derivative of one call of ``kernels.elastoplastic_force`` (Thornton's law).

    The call maps (overlap d >= 0, rate, kappa, A, dyield, state in: dmax, dres, kres) to the force
    f and the state out. Given the adjoints of f (``fbar``) and of the state out (``dresb``,
    ``kresb``; the largest overlap dmax only enters comparisons, so its adjoint is zero), returns
    (f, dbar, ratebar, kappabar, dampingbar, dyieldbar, dresb in, kresb in): f exactly as the kernel
    computes it, the adjoints of the inputs, and those of the state in. Branches as the kernel's:

    - loading past yield (d > dmax, d > dyield): f = kappa sy (1.5 d - 0.5 dy) + A kappa d^(1/2) rate
      (sy = dy^(1/2); kres x^(1/2) = kappa d^(1/2)), new state x = d - dres = sy (1.5 d - 0.5 dy) / d^(1/2),
      kres = kappa d^(1/2) / x^(1/2): the state in is overwritten (adjoint zero);
    - Hertz loading (dmax < d <= dyield): f = kappa d^(3/2) + A kres d^(1/2) rate, state carried;
    - unloading or reloading (d <= dmax): f = kres x^(3/2) + A kres x^(1/2) rate, x = d - dres,
      zero for x <= DELTA_MIN; state carried.

    A force clipped at zero has no partials (its state's still flow).
    """
    f, _, _, _, _ = elastoplastic_force(d, rate, kappa, damping, dyield, dmax, dres, kres)
    fb = fbar if f > 0.0 else 0.0
    if d > dmax:
        sd = np.sqrt(d)
        if d > dyield:
            sy = np.sqrt(dyield)
            p = 1.5 * d - 0.5 * dyield
            x = sy * p / sd
            sx = np.sqrt(x)
            x_d = sy * (0.75 / sd + 0.25 * dyield / (d * sd))
            x_dy = (0.75 * d / sy - 0.75 * sy) / sd
            c = 0.5 * kappa * sd / (x * sx)  # -d kres / dx
            kr_d = 0.5 * kappa / (sd * sx) - c * x_d
            dbar = fb * (1.5 * kappa * sy + 0.5 * damping * kappa * rate / sd) + dresb * (1.0 - x_d) + kresb * kr_d
            dybar = fb * kappa * (0.75 * d / sy - 0.75 * sy) - dresb * x_dy - kresb * c * x_dy
            kbar = fb * (sy * p + damping * sd * rate) + kresb * sd / sx
            return f, dbar, fb * damping * kappa * sd, kbar, fb * kappa * sd * rate, dybar, 0.0, 0.0
        dbar = fb * (1.5 * kappa * sd + 0.5 * damping * kres * rate / sd)
        return (f, dbar, fb * damping * kres * sd, fb * d * sd, fb * kres * sd * rate, 0.0, dresb,
                kresb + fb * damping * sd * rate)
    x = d - dres
    if x > DELTA_MIN:
        sx = np.sqrt(x)
        fx = fb * (1.5 * kres * sx + 0.5 * damping * kres * rate / sx)
        return (f, fx, fb * damping * kres * sx, 0.0, fb * kres * sx * rate, 0.0, dresb - fx,
                kresb + fb * (x * sx + damping * sx * rate))
    return f, 0.0, 0.0, 0.0, 0.0, 0.0, dresb, kresb


@njit(cache=True, nogil=True, inline="always")
def aligned_partials(d, rate, kappa, damping, law):
    """The force of an aligned Kuwabara-Kono (``law == LAW_VISCOELASTIC``) or dashpot contact at
    overlap ``d`` [m] and overlap rate ``rate`` [m/s] (``kernels._viscous_force``, the same
    expressions: paper eq. 1 plus the damping term) with the partials of :func:`law_partials`:
    (f, dF/dw, dF/drate, dF/dkappa, dF/ddamping), zero where the contact is open or the force
    clipped; written with selects, so that LLVM vectorises the contact loops of the tangent
    (``tangent._aligned_step``) and the adjoint (``adjoint._steps_dissipative``) that call it."""
    dd = d if d > DELTA_MIN else 0.0
    sd = np.sqrt(dd)
    fel = kappa * dd * sd
    if law == LAW_VISCOELASTIC:
        f = fel + kappa * damping * sd * rate
        isd = 1.0 / sd if sd > 0.0 else 0.0
        fd = kappa * (1.5 * sd + 0.5 * damping * rate * isd)
        fr = kappa * damping * sd
        fk = dd * sd + damping * sd * rate
        fa = kappa * sd * rate
    else:  # dashpot
        f = fel + damping * rate
        fd = 1.5 * kappa * sd
        fr = damping
        fk = dd * sd
        fa = rate
    on = (d >= 0.0) & (f > 0.0)
    return (f if on else 0.0), (fd if on else 0.0), (fr if on else 0.0), (fk if on else 0.0), (fa if on else 0.0)
