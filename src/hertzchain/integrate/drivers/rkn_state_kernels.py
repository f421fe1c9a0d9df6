"""Kernels of ``"rkn4"`` generated from a contact law's own scalar functions, per-contact state
included: the registry's generated laws (the power law, Hunt-Crossley, a user's law) and
Thornton's elastic-plastic law (:mod:`hertzchain.integrate.drivers.rkn_laws` builds the law's
*adapter* and :func:`build` the run from it; nothing here knows a law).

Method: the classical fourth-order Runge-Kutta-Nystrom method for y'' = f(y, y') of
:mod:`hertzchain.integrate.drivers.rkn_damped_kernels` (the same stages, the same dissipated-energy
quadrature with the stages' weights, the same cubic/quintic Hermite probes), with the law's force
from its adapter. Per-contact state (the largest overlap of the elastic-plastic law, the approach
speed of Hunt-Crossley) is **frozen during a step and committed when the step is accepted**: a
stage takes the state the law's update gives at the stage's own overlap and rate from the
committed one (on a step where the state grows: max(history, stage overlap), i.e. the loading
branch) or the committed state as it is (where it does not grow), and the accepted step's end
commits the update at the end. A contact that closes commits its state at the closing instant
(Hunt-Crossley's approach speed is the rate at touch).

Every contact is on a *branch* for the whole step, an integer: bit 0 loaded (carries a force,
``_state`` of the damped kernels: open below the law's opening overlap, clipped where the force
is not positive), bit 1 its state grows (the law's update, evaluated an instant ahead along the
trajectory, exceeds the present state: a max-type history while it increases), bit 2 the law's
``regime`` (a piece of a piecewise law: the elastic-plastic law past its yield overlap). Each
change of branch is a non-smooth instant of the force (a jump of the force or of one of its
first two time derivatives); a step that would straddle one is redone to end on it (bisection of
the branch along the step's interpolants of overlap and rate, to :data:`EVENT_TOL` of the
step), so every step integrates a smooth force and the method keeps its fourth order on smooth
stretches; the committed state at a step's end is the state at the event.

Order and error bound: with every event landed, the local velocity error of a step is
O(h^5) (fourth order) as for the damped laws; the step control bounds per loaded contact

    e_j(h) = |F_j| m_j^-1 h min(y^4, F(gap + |r| h) / |F_j|) + |F_j| m_j^-1 (omega_j^4 + c_j^4) h^5,
    y = |r| h / gap,

(gap: the overlap beyond the law's opening point; omega_j^2 = k_t m_j^-1, c_j = c_t m_j^-1 with
the tangent stiffness k_t = dF/d delta and damping c_t = dF/d rate from the adapter's
``tangent``, the law's analytic partials; central differences of its force where it has none):
the first term is the smooth fourth-order error of a force ~ gap^n, taken no
larger than the error of a step that starts at the contact's closing (the force the contact
reaches in it, times h), the second the fourth-order error of a force that changes at the
contact's frequency and damping rate. This is the damped kernels' Hertz bound written with the
law's own force, so the global error of a run is O(eps) with the same constant (``eps``: the local
velocity error per step, rtol times the striker speed times ``rkn.DAMPED_EPS``). A branch change
inside :data:`EVENT_TOL` of a step's end is taken in the step: an error of the size of the jump in
the force's (first or second) derivative times (EVENT_TOL h)^2 h, below eps for every law here.
"""

from __future__ import annotations

from typing import Any, Callable, NamedTuple

import numpy as np
from numba import njit

from ..core.primitives import DELTA_MIN
from .rkn_damped_kernels import (A_H, A_HMAX, A_HMIN, A_HREF, A_STEPS, A_T, A_TPREV, E_D, E_DD, E_DKE, E_DPE, E_KE,
                                 E_PE, ENDS, EVENT_EPS, MAX_GROWTH, MAX_REDO, MAX_RHO_H, _line, _right)
from .rkn_kernels import SAMPLE_BLOCK, hermite, quintic, quintic_at_most
from .rkn_samples import (FIT_FLOOR, FIT_NODES, FIT_SAMPLES, PATH_ROWS, axial, block_of_samples, fit_at,
                          fit_coefficients, path_at, path_coefficients, record_bodies, smooth_over_step)

__all__ = ["LawAdapter", "StateRun", "build", "ROWS", "ENDS", "E_W", "LOADED", "GROWS", "REGIME"]

#: An event inside a step closer than this fraction of the step to one of its ends is taken in
#: the step (the bisection of a branch along the step resolves 2^-40 of it).
EVENT_TOL = 1e-7
#: EVENT_EPS (imported from rkn_damped_kernels, which lands its events by the same rule): a change
#: of branch is landed on only where the contact's force at the step's end (on either branch) times
#: m^-1 h, the most a step's velocities can be off by taking the change inside it,
#: exceeds this fraction of ``eps``: the numerical precursor ahead of a pulse (overlaps ~1e-80 m,
#: forces ~1e-110 N) crosses zero in nearly every step, and landing on each crossing cost
#: thousands of redone steps on chain 1 for nothing a result can see. The state such a step
#: commits is the law's update at the step's end (a max-type state that peaked inside it, at
#: such forces, is overtaken by the pulse's: Hunt-Crossley's approach speed, the largest overlap).
#: Rows of a step end's per-contact data ``ed[c]``: force along the axis (clipped, on the
#: branch), its time derivative, overlap, rate, d(rate)/dt, the gap beyond the law's opening
#: overlap, elastic energy, dissipated power on the branch, then the unclipped force on the branch
#: and its tangent stiffness dF/d delta and damping dF/d rate (0 off the loaded branch).
R_F, R_DF, R_D, R_R, R_Q, R_GAP, R_E, R_P, R_FU, R_KT, R_CT = 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10
ROWS = 11
#: Slot of ``ends[c]`` after the damped kernels' six: the law's other dissipated energy (the
#: elastic-plastic law's plastic work [J]) at that end, from the committed state.
E_W = ENDS
#: Bits of a contact's branch.
LOADED, GROWS, REGIME = 1, 2, 4
#: The step's functions take arrays and allocate none: they are compiled without Numba's reference
#: counting (``_nrt=False``). With it, every call increfed and decrefed each of its array arguments
#: (an atomic operation each), and every contact's force the law's state ``S``: ~35 % of a Hunt-
#: Crossley step on chain 1 (perf), the run 5.8 -> 3.8 ms (1 us samples), the same numbers bit for bit.
NO_REFCOUNT = {"_nrt": False}


def njit_no_refcount(**options: Any) -> Callable[[Callable], Any]:
    """``numba.njit(**options)`` without reference counting (:data:`NO_REFCOUNT`): a keyword
    Numba takes but does not declare in the type stubs it ships (from 0.68)."""
    return njit(**options, **NO_REFCOUNT)  # type: ignore[call-overload]


class LawAdapter(NamedTuple):
    """A law's scalar functions for :func:`build` (all ``numba.njit``; ``S`` the (rows, P) state,
    ``j`` the contact; k [N/m^n] and p the contact's stiffness and parameter):

    - ``force(d, r, k, p, S, j, grow)``: (F [N] unclipped, its part at zero rate [N], gap [m]) at
      overlap d and rate r, with the committed state (``grow`` False) or the update at (d, r)
      (``grow`` True); F is 0 where the contact is open (gap < 0);
    - ``commit(d, r, k, p, S, j)``: store the update at (d, r);
    - ``key(d, r, k, p, S, j)``: a scalar of the state the update at (d, r) gives (increasing as
      the state grows);
    - ``regime(d, r, k, p, S, j)``: the piece of a piecewise law (0 for a smooth one);
    - ``stored(d, k, p, S, j)``: elastic energy [J] with the committed state;
    - ``work(k, p, S, j)``: energy the state holds as dissipated (plastic work [J]; 0);
    - ``tangent(d, r, k, p, S, j, grow)``: (dF/d delta [N/m], dF/d rate [N s/m], gap [m]) of the
      unclipped force as ``force`` takes it (with ``grow``, through the state's update: the
      derivative along the branch), from the law's analytic partials; None: central differences
      of ``force`` (a law with state that declares no ``state_partials``);
    - ``stored_state``: whether ``stored`` or ``work`` read the state (else the stored energy at a
      step's end is :func:`end_data`'s, not recomputed after the state's commit);
    - ``lossless``: the law dissipates nothing (its force does not depend on the rate): the
      dissipated energy stays 0, not the fall of a contact's elastic energy over a step off its
      loaded branch (which a closing not landed on, :data:`EVENT_EPS`, would make ~-1e-27 J)."""

    force: object
    commit: object
    key: object
    regime: object
    stored: object
    work: object
    tangent: object = None
    stored_state: bool = True
    lossless: bool = False


class StateRun(NamedTuple):
    """The run's state (u, v, a = f(u, v)), new and stage state, stages, the stage-weighted
    dissipated power ``pw``, branches of this step ``mode`` and the last ``last``, the law's
    state ``S`` and its copy at the step's start ``Sp``, the step's start (up, vp, ap) and end data
    ``ed``, ``ends`` of the last two step ends."""

    u: np.ndarray
    v: np.ndarray
    a: np.ndarray
    un: np.ndarray
    vn: np.ndarray
    an: np.ndarray
    us: np.ndarray
    vs: np.ndarray
    k2: np.ndarray
    k3: np.ndarray
    k4: np.ndarray
    pw: np.ndarray
    mode: np.ndarray
    last: np.ndarray
    S: np.ndarray
    Sp: np.ndarray
    up: np.ndarray
    vp: np.ndarray
    ap: np.ndarray
    ed: np.ndarray
    ends: np.ndarray


@njit(cache=True, nogil=True)
def _copy(dst, src):
    """dst[:, :] = src by loops: the slice assignment's shape check compiles Numba's formatted
    error message (~2.8 CPU-s in every new process, issue 37)."""
    for i in range(src.shape[0]):
        for j in range(src.shape[1]):
            dst[i, j] = src[i, j]


def build(law: LawAdapter):
    """The compiled (``accelerations``, ``end_data``, ``set_modes``, ``run``) of ``law`` (module
    docstring); ``run(state, chain, off, probes, control, k_start, k_stop, acc, out_w)`` advances
    as :func:`hertzchain.integrate.drivers.rkn_damped_kernels.damped_run` does (its arguments and
    accumulators), ``out_w`` receiving the plastic work at the samples."""
    lforce, lcommit, lkey, lregime, lstored, lwork, ltangent, stored_state, lossless = law

    @njit(nogil=True, inline="always")
    def branch_force(d, r, k, p, S, j, m):
        """(F on branch m, its zero-rate part, gap)."""
        if k == 0.0:
            return 0.0, 0.0, -1.0
        fu, fel, gap = lforce(d, r, k, p, S, j, (m & GROWS) != 0)
        if (m & LOADED) == 0:
            return 0.0, fel if gap >= 0.0 else 0.0, gap
        if gap < 0.0:  # the loaded branch extended below the opening as at it
            fu, fel, _ = lforce(d - gap, r, k, p, S, j, (m & GROWS) != 0)
        return fu, fel, gap

    @njit_no_refcount(nogil=True)
    def branch_at(d, r, q, k, p, S, j, tau):
        """The branch a contact's state (d, r, q = d(rate)/dt) puts it on (module docstring)."""
        if k == 0.0:
            return 0
        fu, _, gap = lforce(d, r, k, p, S, j, True)
        m = 0
        if gap >= 0.0 and (fu > 0.0 or (gap <= DELTA_MIN and r > 0.0)):
            m |= LOADED
        if lkey(d + r * tau, r + q * tau, k, p, S, j) > lkey(d, r, k, p, S, j):
            m |= GROWS
        if lregime(d, r, k, p, S, j) != 0:
            m |= REGIME
        return m

    @njit_no_refcount(nogil=True)
    def accel(us, vs, kappa, damping, d0, off, fext, inv_mass, S, mode, out, pw, weight):
        """a = f(us, vs) on the branches ``mode``; adds ``weight`` times each contact's dissipated
        power (F - F_el) r to ``pw``."""
        fprev = 0.0
        for i in range(inv_mass.shape[0]):
            d, cc, r, _ = _line(us[i] - us[i + 1], vs[i] - vs[i + 1], d0, off, i)
            f, fel, _ = branch_force(d, r, kappa[i], damping[i], S, i, int(mode[i]))
            pw[i] += weight * ((f - fel) * r)
            f *= cc
            out[i] = (fprev - f + fext[i]) * inv_mass[i]
            fprev = f

    if ltangent is None:
        @njit_no_refcount(nogil=True)
        def tangents(d, r, k, p, S, j, m):
            """(dF/d delta, dF/d rate) on branch m by central differences of the law's force."""
            hd = 1e-7 * (abs(d) + 1e-12)
            hr = 1e-7 * (abs(r) + 1e-6)
            kt = (branch_force(d + hd, r, k, p, S, j, m)[0] - branch_force(d - hd, r, k, p, S, j, m)[0]) / (2.0 * hd)
            ct = (branch_force(d, r + hr, k, p, S, j, m)[0] - branch_force(d, r - hr, k, p, S, j, m)[0]) / (2.0 * hr)
            return kt, ct
    else:
        @njit(nogil=True, inline="always")
        def tangents(d, r, k, p, S, j, m):
            """(dF/d delta, dF/d rate) on the loaded branch m from the law's partials (below the
            opening the branch is the force at the opening: no delta-derivative)."""
            if k == 0.0:
                return 0.0, 0.0
            grow = (m & GROWS) != 0
            kt, ct, gap = ltangent(d, r, k, p, S, j, grow)
            if gap < 0.0:
                _, ct, _ = ltangent(d - gap, r, k, p, S, j, grow)
                kt = 0.0
            return kt, ct

    @njit_no_refcount(nogil=True, error_model="numpy")
    def end_data(u, v, a, kappa, damping, d0, off, fext, mass, S, mode, dis, ed, ends, c):
        """Per contact into ``ed[c]`` (rows R_*) on the branches ``mode`` (with the state ``S``),
        the energies and their rates into ``ends[c]`` (``rkn_damped_kernels.end_data``'s)."""
        ke = 0.0
        dke = 0.0
        pe = 0.0
        dpe = 0.0
        dd = 0.0
        for i in range(mass.shape[0]):
            dv = v[i] - v[i + 1]
            d, cc, r, kk = _line(u[i] - u[i + 1], dv, d0, off, i)
            q = cc * (a[i] - a[i + 1]) - kk * dv * dv
            m = int(mode[i])
            f, fel, gap = branch_force(d, r, kappa[i], damping[i], S, i, m)
            df = 0.0
            kt, ct = 0.0, 0.0
            if (m & LOADED) != 0:
                kt, ct = tangents(d, r, kappa[i], damping[i], S, i, m)
                if f > 0.0:
                    df = kt * r + ct * q
            ed[c, 8, i] = f
            ed[c, 9, i] = kt
            ed[c, 10, i] = ct
            fc = f if f > 0.0 else 0.0
            ed[c, 0, i] = cc * fc
            ed[c, 1, i] = df
            ed[c, 2, i] = d
            ed[c, 3, i] = r
            ed[c, 4, i] = q
            ed[c, 5, i] = gap
            el = lstored(d, kappa[i], damping[i], S, i) if kappa[i] != 0.0 else 0.0
            ed[c, 6, i] = el
            pb = 0.0 if lossless else (f - fel) * r
            ed[c, 7, i] = pb
            mv = mass[i] * v[i]
            ke += mv * v[i]
            dke += mv * a[i]
            pe += el - fext[i] * u[i]
            dpe += fel * r - fext[i] * v[i]
            dd += pb
        ends[c, E_KE] = 0.5 * ke
        ends[c, E_DKE] = dke
        ends[c, E_PE] = pe
        ends[c, E_DPE] = dpe
        ends[c, E_D] = dis
        ends[c, E_DD] = dd

    @njit_no_refcount(nogil=True)
    def set_modes(ed, b, kappa, damping, S, mode, tau):
        """Every contact's branch from its state at ``ed[b]``."""
        for j in range(kappa.shape[0]):
            mode[j] = branch_at(ed[b, 2, j], ed[b, 3, j], ed[b, 4, j], kappa[j], damping[j], S, j, tau)

    @njit_no_refcount(nogil=True, error_model="numpy")
    def max_error(ed, c, kappa, damping, inv_mass, S, mode, h):
        """(max_j e_j(h) over the loaded contacts (module docstring), its local exponent)."""
        emax = 0.0
        pmax = 5.0
        h5 = h * h * h * h * h
        for j in range(kappa.shape[0]):
            m = int(mode[j])
            if (m & LOADED) == 0:
                continue
            d = ed[c, 2, j]
            r = ed[c, 3, j]
            gap = ed[c, 5, j]
            im = inv_mass[j] + _right(inv_mass, j)
            f = ed[c, 8, j]
            # the force a closing contact reaches in the step: the crossing error
            fx, _, _ = branch_force(d - (gap if gap > 0.0 else 0.0) + abs(r) * h, r, kappa[j], damping[j], S, j, m)
            e1, p1 = abs(fx) * im * h, 2.5
            if gap > DELTA_MIN:
                y = abs(r) * h / gap
                es = abs(f) * im * h * y * y * y * y
                if es < e1:
                    e1, p1 = es, 5.0
            w2 = abs(ed[c, 9, j]) * im
            ct = ed[c, 10, j]
            cr = abs(ct) * im
            e3 = abs(f) * im * (w2 * w2 + cr * cr * cr * cr) * h5
            e = e1 + e3
            if e > emax:
                emax = e
                pmax = (e1 * p1 + 5.0 * e3) / e
        return emax, pmax

    @njit_no_refcount(nogil=True, error_model="numpy")
    def next_step(ed, c, kappa, damping, inv_mass, S, mode, eps, h_ref, h_max):
        """The largest h with max_j e_j(h) <= eps, at most MAX_GROWTH h_ref and h_max, within the
        stability bound (omega + damping rate) h <= MAX_RHO_H (tangents at twice the overlap a
        step ahead reaches: a Gershgorin bound)."""
        w = 0.0
        cw = 0.0
        for j in range(kappa.shape[0]):
            m = int(mode[j])
            if (m & LOADED) == 0:
                continue
            r = ed[c, 3, j]
            d = ed[c, 2, j] + 2.0 * h_ref * (r if r > 0.0 else 0.0)
            im = max(inv_mass[j], _right(inv_mass, j))
            kt, ct = tangents(d, r, kappa[j], damping[j], S, j, m)
            w = max(w, abs(kt) * im)
            cw = max(cw, abs(ct) * im)
        h = h_max
        if h_ref > 0.0 and MAX_GROWTH * h_ref < h:
            h = MAX_GROWTH * h_ref
        rho = 2.0 * np.sqrt(w) + 4.0 * cw
        if rho > 0.0 and MAX_RHO_H / rho < h:
            h = MAX_RHO_H / rho
        e, p = max_error(ed, c, kappa, damping, inv_mass, S, mode, h)
        if e <= eps:
            return h
        for _ in range(8):
            h *= (eps / e) ** (1.0 / p)
            e, p = max_error(ed, c, kappa, damping, inv_mass, S, mode, h)
            if e <= eps * 1.0001:
                return h
        return h * (eps / e) ** (1.0 / 1.5)

    @njit(nogil=True, inline="always")
    def path_w(ed, b, c, j, qw, hw, theta):
        """(delta, rate, d(rate)/dt) of contact j from the step's interpolation weights (``qw``
        :func:`quintic`'s, ``hw`` :func:`hermite`'s at theta): quintic, cubic, linear."""
        d = (qw[0] * ed[b, 2, j] + qw[1] * ed[b, 3, j] + qw[2] * ed[b, 4, j] + qw[3] * ed[c, 2, j]
             + qw[4] * ed[c, 3, j] + qw[5] * ed[c, 4, j])
        r = hw[0] * ed[b, 3, j] + hw[1] * ed[b, 4, j] + hw[2] * ed[c, 3, j] + hw[3] * ed[c, 4, j]
        return d, r, (1.0 - theta) * ed[b, 4, j] + theta * ed[c, 4, j]

    @njit(nogil=True, inline="always")
    def path(ed, b, c, j, theta, h):
        """(delta, rate, d(rate)/dt) of contact j at theta of the step (:func:`path_w`)."""
        return path_w(ed, b, c, j, quintic(theta, h), hermite(theta, h), theta)

    @njit_no_refcount(nogil=True, error_model="numpy")
    def event_inside(ed, b, c, h, kappa, damping, inv_mass, S, mode, eps):
        """Earliest theta in (EVENT_TOL, 1 - EVENT_TOL) where a contact leaves its branch (its
        branch at the end differs; bisection along :func:`path`); 2 when one left it at the step's
        start (``mode`` switched there: restart); -1 when none inside. A change where the
        contact's force on either branch at the step's end is below EVENT_EPS eps / (m^-1 h) is
        not landed on (:data:`EVENT_EPS`)."""
        best = 2.0
        switched = False
        tau = 1e-8 * h
        for j in range(kappa.shape[0]):
            m = int(mode[j])
            d1, r1 = ed[c, 2, j], ed[c, 3, j]
            mn = branch_at(d1, r1, ed[c, 4, j], kappa[j], damping[j], S, j, tau)
            if mn == m:
                continue
            fa = abs(branch_force(d1, r1, kappa[j], damping[j], S, j, mn)[0])
            fb = abs(branch_force(d1, r1, kappa[j], damping[j], S, j, m)[0])
            if (fa if fa > fb else fb) * (inv_mass[j] + _right(inv_mass, j)) * h <= EVENT_EPS * eps:
                continue
            lo, hi = 0.0, 1.0
            for _ in range(40):
                x = 0.5 * (lo + hi)
                d, r, q = path(ed, b, c, j, x, h)
                if branch_at(d, r, q, kappa[j], damping[j], S, j, tau) == m:
                    lo = x
                else:
                    hi = x
            if hi <= EVENT_TOL:
                d, r, q = path(ed, b, c, j, hi, h)
                mode[j] = branch_at(d, r, q, kappa[j], damping[j], S, j, tau)
                switched = True
            best = hi if hi < best else best
        if switched:
            return 2.0
        if EVENT_TOL < best < 1.0 - EVENT_TOL:
            return best
        return -1.0

    @njit(nogil=True, inline="always")
    def force_w(ed, b, c, j, qw, hw, theta, kappa, damping, off, S, m):
        """Contact j's force along the axis on branch m (clipped) from the step's interpolation
        weights at theta (:func:`path_w`); 0 off the loaded branch (as :func:`branch_force`)."""
        if (m & LOADED) == 0:
            return 0.0
        d, r, _ = path_w(ed, b, c, j, qw, hw, theta)
        f, _, _ = branch_force(d, r, kappa[j], damping[j], S, j, m)
        return axial(f if f > 0.0 else 0.0, off, j, d)

    @njit_no_refcount(nogil=True)
    def force_at(ed, b, c, j, theta, h, kappa, damping, off, S, m):
        """Contact j's force along the axis at theta of the step, on branch m (clipped)."""
        return force_w(ed, b, c, j, quintic(theta, h), hermite(theta, h), theta, kappa, damping, off, S, m)

    @njit_no_refcount(nogil=True)
    def peak_in_step(ed, b, c, j, h, kappa, damping, off, S, m):
        """(largest interpolated force of contact j in the step, its theta): golden section."""
        g = 0.6180339887498949
        lo, hi = 0.0, 1.0
        x1 = hi - g * (hi - lo)
        x2 = lo + g * (hi - lo)
        f1 = force_at(ed, b, c, j, x1, h, kappa, damping, off, S, m)
        f2 = force_at(ed, b, c, j, x2, h, kappa, damping, off, S, m)
        for _ in range(60):
            if f1 < f2:
                lo = x1
                x1, f1 = x2, f2
                x2 = lo + g * (hi - lo)
                f2 = force_at(ed, b, c, j, x2, h, kappa, damping, off, S, m)
            else:
                hi = x2
                x2, f2 = x1, f1
                x1 = hi - g * (hi - lo)
                f1 = force_at(ed, b, c, j, x1, h, kappa, damping, off, S, m)
            if hi - lo < 1e-12:
                break
        x = 0.5 * (lo + hi)
        return force_at(ed, b, c, j, x, h, kappa, damping, off, S, m), x

    @njit_no_refcount(nogil=True, error_model="numpy")
    def step(u, v, a, un, vn, an, us, vs, k2, k3, k4, pw, mode, kappa, damping, d0, off, fext, inv_mass, S, h, ed, b):
        """One classical RKN step (``rkn_damped_kernels.step``) on the branches ``mode``."""
        n = inv_mass.shape[0]
        hh = 0.5 * h
        h8 = 0.125 * h * h
        for i in range(n):
            us[i] = u[i] + hh * v[i] + h8 * a[i]
            vs[i] = v[i] + hh * a[i]
            pw[i] = ed[b, 7, i]
        accel(us, vs, kappa, damping, d0, off, fext, inv_mass, S, mode, k2, pw, 2.0)
        for i in range(n):
            vs[i] = v[i] + hh * k2[i]
        accel(us, vs, kappa, damping, d0, off, fext, inv_mass, S, mode, k3, pw, 2.0)
        h2 = 0.5 * h * h
        for i in range(n):
            us[i] = u[i] + h * v[i] + h2 * k3[i]
            vs[i] = v[i] + h * k3[i]
        accel(us, vs, kappa, damping, d0, off, fext, inv_mass, S, mode, k4, pw, 1.0)
        h6 = h / 6.0
        hh6 = h * h6
        for i in range(n):
            un[i] = u[i] + h * v[i] + hh6 * (a[i] + k2[i] + k3[i])
            vn[i] = v[i] + h6 * (a[i] + 2.0 * (k2[i] + k3[i]) + k4[i])
        accel(un, vn, kappa, damping, d0, off, fext, inv_mass, S, mode, an, pw, 0.0)

    @njit_no_refcount(nogil=True)
    def commit_all(u, v, kappa, damping, d0, off, S, mode, last, ed, b):
        """Commit every contact's state at the state (u, v); a contact that closes (loaded now,
        not in the last step) takes it at its closing (gap 0)."""
        for j in range(kappa.shape[0]):
            if kappa[j] == 0.0:
                continue
            d, _, r, _ = _line(u[j] - u[j + 1], v[j] - v[j + 1], d0, off, j)
            m = int(mode[j])
            gap = ed[b, 5, j]
            if (m & LOADED) != 0 and (int(last[j]) & LOADED) == 0 and gap < 0.0:
                d -= gap
            lcommit(d, r, kappa[j], damping[j], S, j)

    @njit_no_refcount(nogil=True)
    def energies(u, kappa, damping, d0, off, fext, S, ends, c):
        """The stored energy (minus the work of f_ext) and the law's other dissipated energy
        (plastic work) at the end ``c`` from the committed state ``S``."""
        w = 0.0
        pe = 0.0
        for j in range(kappa.shape[0]):
            if kappa[j] != 0.0:
                d, _, _, _ = _line(u[j] - u[j + 1], 0.0, d0, off, j)
                pe += lstored(d, kappa[j], damping[j], S, j)
                w += lwork(kappa[j], damping[j], S, j)
            pe -= fext[j] * u[j]
        ends[c, E_PE] = pe
        ends[c, E_W] = w

    @njit_no_refcount(nogil=True, error_model="numpy")
    def step_paths(ed, b, c, hl, fits, floor, kappa, damping, off, Sp, last, shut, fitted, pc, fv):
        """A step's samples, prepared once (``run``'s probes): which contacts carry no force over
        it (``shut``), the others' paths (``pc``) and, with ``fits``, the fitted forces of those
        clear of their opening or whose force stays at or below ``floor`` [N] (``fitted``; rows
        0-5 of ``pc``, rkn_samples: FIT_CLEARANCE, FIT_FLOOR); returns the range lo..hi-1 of the
        contacts with a force."""
        lo, hi = kappa.shape[0], 0
        for j in range(shut.shape[0]):
            m = int(last[j])
            fitted[j] = False  # (not the last step's fit)
            shut[j] = (m & LOADED) == 0 or (
                quintic_at_most(ed[b, 2, j], ed[b, 3, j], ed[b, 4, j], ed[c, 2, j], ed[c, 3, j], ed[c, 4, j], hl,
                                DELTA_MIN)
                and branch_force(DELTA_MIN, ed[b, 3, j], kappa[j], damping[j], Sp, j, m)[0] == 0.0
                and branch_force(DELTA_MIN, ed[c, 3, j], kappa[j], damping[j], Sp, j, m)[0] == 0.0)
            if not shut[j]:
                lo = j if j < lo else lo
                hi = j + 1
                path_coefficients(ed, b, c, j, hl, pc, 2)
                clear = smooth_over_step(ed[b, 5, j], ed[b, 3, j], ed[c, 5, j], ed[c, 3, j], hl)
                faint = not clear and ed[b, 0, j] <= floor and ed[c, 0, j] <= floor
                fitted[j] = fits and (clear or faint)
                for i in range(6 if fitted[j] else 0):
                    d, rt = path_at(pc, j, FIT_NODES[i])
                    f, _, _ = branch_force(d, rt, kappa[j], damping[j], Sp, j, m)
                    f = f if f > 0.0 else 0.0
                    fitted[j] = fitted[j] and (f <= floor if faint else f > 0.0)
                    fv[i] = axial(f, off, j, d)
                if fitted[j]:
                    fit_coefficients(fv, pc, j)
        return (lo, hi) if hi > 0 else (0, 0)

    @njit(nogil=True, error_model="numpy")
    def run(state, chain, off, probes, control, k_start, k_stop, acc, out_w):
        u, v, a, un, vn, an, us, vs, k2, k3, k4, pw, mode, last, S, Sp, up, vp, ap, ed, ends = state
        mass, inv_mass, kappa, damping, d0, fext, ws = chain
        rec, out_f, out_ke, out_pe, out_d, out_v, record_v, out_u, record_u, fmax, peak = probes
        interval, h_fixed, eps, h_max = control
        n = mass.shape[0]
        nc = fmax.shape[0]
        nrec = rec.shape[0]
        t = acc[A_T]
        tp = acc[A_TPREV]
        hl = acc[A_H]
        href = acc[A_HREF]
        steps = int(acc[A_STEPS])
        fi = np.zeros((nc, SAMPLE_BLOCK))  # a block of samples' forces
        shut = np.zeros(nc, dtype=np.bool_)  # contacts whose force is 0 over the whole step
        seen = -1  # the step they were found for
        lo, hi = 0, 0  # the contacts lo..hi-1 hold every one with a force in it
        pc = np.zeros((PATH_ROWS, nc))  # their paths over it (rkn_samples)
        fitted = np.zeros(nc, dtype=np.bool_)  # ... or their forces fitted over it (rows 0-5 of pc)
        fv = np.zeros(6)
        th = np.zeros(SAMPLE_BLOCK)  # a block of samples in it: their theta
        fscale = fmax.max() if nc > 0 else 0.0  # the largest force sampled so far (FIT_FLOOR: step_paths)
        k = k_start
        while k < k_stop:
            tk = k * interval
            while t < tk:
                b = steps % 2
                c = 1 - b
                hguess = h_fixed if h_fixed > 0.0 else (href if href > 0.0 else h_max)
                set_modes(ed, b, kappa, damping, S, mode, 1e-8 * hguess)
                changed = False
                for j in range(nc):
                    if mode[j] != last[j]:
                        changed = True
                if changed:  # a branch changed at the last step's end: its state and f(u, v) on it
                    commit_all(u, v, kappa, damping, d0, off, S, mode, last, ed, b)
                    accel(u, v, kappa, damping, d0, off, fext, inv_mass, S, mode, a, pw, 0.0)
                    end_data(u, v, a, kappa, damping, d0, off, fext, mass, S, mode, ends[b, E_D], ed, ends, b)
                if h_fixed > 0.0:
                    h = h_fixed
                else:
                    h = next_step(ed, b, kappa, damping, inv_mass, S, mode, eps, href, h_max)
                    href = h
                _copy(Sp, S)
                for redo in range(MAX_REDO + 1):
                    step(u, v, a, un, vn, an, us, vs, k2, k3, k4, pw, mode, kappa, damping, d0, off, fext, inv_mass,
                         S, h, ed, b)
                    end_data(un, vn, an, kappa, damping, d0, off, fext, mass, S, mode, 0.0, ed, ends, c)
                    if h_fixed > 0.0 or redo == MAX_REDO:
                        break
                    x = event_inside(ed, b, c, h, kappa, damping, inv_mass, S, mode, eps)
                    if x < 0.0:
                        break
                    if x > 1.0:  # a branch switched at the start: its state, f(u, v) and the step afresh
                        commit_all(u, v, kappa, damping, d0, off, S, mode, last, ed, b)
                        accel(u, v, kappa, damping, d0, off, fext, inv_mass, S, mode, a, pw, 0.0)
                        end_data(u, v, a, kappa, damping, d0, off, fext, mass, S, mode, ends[b, E_D], ed, ends, b)
                        _copy(Sp, S)
                        hm = next_step(ed, b, kappa, damping, inv_mass, S, mode, eps, href, h_max)
                        h = hm if hm < h else h
                    else:
                        h *= x
                # dissipated energy: the stages' quadrature on loaded contacts, the fall of the
                # elastic energy of the others (rkn_damped_kernels.step_dissipation)
                dis = 0.0
                if not lossless:
                    for j in range(nc):
                        dis += h / 6.0 * pw[j] if (int(mode[j]) & LOADED) != 0 else ed[b, 6, j] - ed[c, 6, j]
                ends[c, E_D] = ends[b, E_D] + dis
                for j in range(nc):
                    last[j] = mode[j]
                commit_all(un, vn, kappa, damping, d0, off, S, mode, last, ed, c)
                if stored_state:
                    energies(un, kappa, damping, d0, off, fext, S, ends, c)
                if record_v or record_u:
                    for i in range(n):
                        up[i] = u[i]
                        vp[i] = v[i]
                        ap[i] = a[i]
                for i in range(n):
                    u[i] = un[i]
                    v[i] = vn[i]
                    a[i] = an[i]
                steps += 1
                # the wall's peak up to the run's end (h_max: its duration; a last step may pass it,
                # the sample there counts below)
                if ed[b, 1, ws] > 0.0 and ed[c, 1, ws] <= 0.0:
                    fk, x = peak_in_step(ed, b, c, ws, h, kappa, damping, off, Sp, int(mode[ws]))
                    if fk > peak[0] and t + x * h <= h_max:
                        peak[0] = fk
                        peak[1] = t + x * h
                if ed[c, 0, ws] > peak[0] and t + h <= h_max:
                    peak[0] = ed[c, 0, ws]
                    peak[1] = t + h
                tp = t
                t += h
                hl = h
                acc[A_HMIN] = h if h < acc[A_HMIN] else acc[A_HMIN]
                acc[A_HMAX] = h if h > acc[A_HMAX] else acc[A_HMAX]
            # --- probes at samples k..kb-1, between the steps' ends tp < tk <= t (the step's
            # branches and state; rkn_samples)
            c = steps % 2
            b = 1 - c
            # a new step: the contacts whose force stays 0 over it, without interpolating (the same
            # numbers): off their loaded branch, or overlapped at most DELTA_MIN (the law's force at
            # zero overlap, 0 at the step's two rates: Hunt-Crossley, the power law; the precursor
            # ahead of a pulse) over the whole step (rkn_kernels.quintic_at_most)
            # (a step holding FIT_SAMPLES or more: the force of a contact far from its opening
            # fitted over the step from six of the law's values, rkn_samples)
            if steps != seen:
                seen = steps
                lo, hi = step_paths(ed, b, c, hl, hl >= FIT_SAMPLES * interval, FIT_FLOOR * fscale, kappa, damping,
                                    off, Sp, last, shut, fitted, pc, fv)
            kb = block_of_samples(k, k_stop, interval, tp, t, hl, th)
            nb = kb - k
            for j in range(lo, hi):  # one loop a contact over the samples (vectorised where fitted)
                m = int(last[j])
                if shut[j]:
                    for i in range(nb):
                        fi[j, i] = 0.0
                elif fitted[j]:
                    for i in range(nb):
                        fi[j, i] = fit_at(pc, j, th[i])
                else:
                    for i in range(nb):
                        d, rt = path_at(pc, j, th[i])
                        f, _, _ = branch_force(d, rt, kappa[j], damping[j], Sp, j, m)
                        fi[j, i] = axial(f if f > 0.0 else 0.0, off, j, d)
                fm = fmax[j]
                for i in range(nb):
                    fm = fi[j, i] if fi[j, i] > fm else fm
                fmax[j] = fm
                fscale = fm if fm > fscale else fscale
            for i in range(nb):
                kk = k + i
                for r in range(nrec):
                    j = rec[r]
                    out_f[kk, r] = fi[j, i] if lo <= j < hi else 0.0
                if lo <= ws < hi and fi[ws, i] > peak[0]:
                    peak[0] = fi[ws, i]
                    peak[1] = kk * interval
                w0, w0d, w1, w1d = hermite(th[i], hl)
                ke = w0 * ends[b, E_KE] + w0d * ends[b, E_DKE] + w1 * ends[c, E_KE] + w1d * ends[c, E_DKE]
                out_ke[kk] = ke
                # stored + plastic work has the rate sum F_el r: interpolated together, the work linearly
                wk = (1.0 - th[i]) * ends[b, E_W] + th[i] * ends[c, E_W]
                out_pe[kk] = (w0 * (ends[b, E_PE] + ends[b, E_W]) + w0d * ends[b, E_DPE]
                              + w1 * (ends[c, E_PE] + ends[c, E_W]) + w1d * ends[c, E_DPE]) - wk
                out_w[kk] = wk
                out_d[kk] = w0 * ends[b, E_D] + w0d * ends[b, E_DD] + w1 * ends[c, E_D] + w1d * ends[c, E_DD]
                record_bodies(out_v, record_v, out_u, record_u, kk, th[i], hl, up, vp, ap, u, v, a)
                if not np.isfinite(ke) or not np.isfinite(ed[c, 0, 0]):
                    acc[A_T], acc[A_TPREV], acc[A_H], acc[A_STEPS], acc[A_HREF] = t, tp, hl, steps, href
                    return 1
            k = kb
        acc[A_T], acc[A_TPREV], acc[A_H], acc[A_STEPS], acc[A_HREF] = t, tp, hl, steps, href
        return 0

    return accel, end_data, set_modes, commit_all, energies, run
