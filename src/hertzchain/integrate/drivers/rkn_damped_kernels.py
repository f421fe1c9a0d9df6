"""Compiled kernels of ``"rkn4"`` on the dissipative laws and offset beads: the classical
fourth-order Runge-Kutta-Nystrom method for y'' = f(y, y'), with a step control that sees every
contact's non-smooth instants and lands on them, and probes interpolated between steps.

Forces: Kuwabara-Kono F = kappa (delta^(3/2) + A delta^(1/2) r) or the dashpot F = kappa
delta^(3/2) + gamma r (r = d(delta)/dt), clipped at zero (never attractive), as the Verlet's
(``primitives._viscous_force``: the same function; the elastic law is the dashpot with gamma =
0); an offset pair's acts along its line of centres (:func:`_line`). A step of size h from (u, v) with a = f(u, v)
(paper eq. 1, a_i = (F_{i-1} - F_i + f_ext,i) / m_i) is Nystrom's classical method (RK4 on the
first-order system, Hairer-Norsett-Wanner I.14)::

    k1 = a,  k2 = f(u + h/2 v + h^2/8 k1, v + h/2 k1),  k3 = f(u + h/2 v + h^2/8 k1, v + h/2 k2),
    k4 = f(u + h v + h^2/2 k3, v + h k3),
    u' = u + h v + h^2/6 (k1 + k2 + k3),  v' = v + h/6 (k1 + 2 k2 + 2 k3 + k4),

and the dissipated energy, D' = sum_j (F_j - F_el,j) r_j, takes the same weights over the same
stages for the contacts that carry a force (fourth order); a contact clipped or open over a step
carries none, and what it dissipates is exactly the fall of its elastic energy (2/5) kappa
delta^(5/2) (whose delta^(3/2) singularity at the opening a quadrature would miss): KE + PE + D
is conserved to the method's order (:func:`step_dissipation`). f(u', v') is the next step's k1:
four force passes per step.

Non-smooth instants of a contact, each an *event* the step lands on (a step that would straddle one has the
error of a jump or kink, of order 1 or 2 in h whatever the method): its closing (delta crosses 0 upwards: the
dashpot force jumps by gamma r, Kuwabara-Kono's rises as delta^(1/2)), the clip (the unclipped force F_u crosses
0 downwards while unloading: dF/dt jumps to 0) and a reload (F_u back above 0 while delta > 0). A step is taken
with every contact on a fixed *branch* (``mode``: loaded, the unclipped force F_u extended smoothly, or no
force), the one its state at the step's start gives, so that no stage sees the other side of an instant. After
the step, where a contact's state at the end (open, closed and clipped, loaded) leaves its branch, the step is
redone ending on the instant (the root of the cubic Hermite of delta or F_u through its values and rates at both
ends), until the instant lies within :data:`EVENT_TOL` of a step's end; an instant at the step's start (a state
that ended the last step just short of it) switches the branch and restarts the step. The step's end data
(accelerations, their rates, the dissipated power) are on the step's own branches, so that its interpolants are
smooth up to its end; where the next step's branches differ (an instant within EVENT_TOL of the end), it
restarts on them (:func:`restart`). The opening after a clip carries no force on either side: no event.

Step control (:func:`next_step`): per loaded contact j the local velocity error of a step h is
bounded by

    e_j(h) = kappa_j m_j^-1 min(r^4 delta^(-5/2) h^5, |r|^(3/2) h^(5/2))            (Hertz part)
           + kappa_j A_j |r| m_j^-1 min(r^4 delta^(-7/2) h^5, |r|^(1/2) h^(3/2))    (K-K part)
           + |F_u| m_j^-1 (omega_j^4 + c_j^4) h^5                                  (dynamics)

(m_j^-1 = 1/m_j + 1/m_{j+1}, omega_j^2 = (3/2) kappa_j delta^(1/2) m_j^-1, c_j = gamma_j m_j^-1
or kappa_j A_j delta^(1/2) m_j^-1: the dashpot's own time scale): each singular term of the force
(delta^(3/2), delta^(1/2) r) takes the smaller of its smooth fourth-order error and its error
right after its closing (the min, as in :mod:`hertzchain.integrate.drivers.rkn_kernels`), the last term
the fourth-order error of a force that changes at the contact's frequency and damping rate. The
step keeps max_j e_j(h) <= eps, grows at most :data:`MAX_GROWTH`-fold, and a Gershgorin bound
keeps (omega + damping rate) h below :data:`MAX_RHO_H` (RK4 is stable to ~2.8 on both axes).

Probes (:mod:`.rkn_samples`): a contact's force is the law's (clipped) at its overlap's quintic Hermite through
(delta, r, q = d(r)/dt) and its rate's cubic through (r, q) at the step's ends; the energies are the cubic
Hermite through their values and exact rates. Events end steps, so each step's interpolants are smooth. The peak
wall force is the largest interpolated force on a step where the wall force turns down (golden-section search).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from ..core import kernels
from . import rkn_kernels, rkn_samples
from ..core.primitives import DELTA_MIN, LAW_VISCOELASTIC, _viscous_force, damped_force_sd
from .rkn_kernels import hermite, quintic, quintic_at_most, force_bound
from .rkn_samples import PATH_ROWS, axial, axial_factor, block_of_samples, hermite_root, path_at, path_coefficients, \
    record_bodies


class DampedState(NamedTuple):
    """The run's state (u, v, a = f(u, v)), the new state and stage state of a step, the stages
    k2..k4, each contact's stage-weighted dissipated power ``pw``, its branch in the step
    (``mode``) and in the last one (``last``), the step's start (up, vp, ap) when recorded, the
    sampled forces ``fi`` (contact, sample of a block) and the end data of the last two step ends
    (``ed``, ``ends``)."""

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
    up: np.ndarray
    vp: np.ndarray
    ap: np.ndarray
    fi: np.ndarray
    ed: np.ndarray
    ends: np.ndarray

#: Largest (omega + damping rate) h (Gershgorin bounds); RK4 is stable to ~2.8 on the imaginary and the negative
#: real axis, and the error control keeps real steps below this.
MAX_RHO_H = 1.0
#: A step grows at most by this factor over the last step the error bound chose.
MAX_GROWTH = 2.0
#: An event inside a step closer than this fraction of the step to one of its ends is taken in the step (its
#: error is then below ~EVENT_TOL (c h) |r|, c the damping rate); farther inside, the step is redone to end on it.
EVENT_TOL = 1e-7
#: A change of branch is landed on only where the contact's force at the step's end times m^-1 h (the most the
#: step's velocities can be off by taking the change inside it) exceeds this fraction of ``eps``: offset beads
#: barely touching (~1e-13 N) clipped and reloaded in nearly every step, and landing on each took steps of 1e-15 s
#: (a misaligned chain 1 ran for hours).
EVENT_EPS = 1e-3
#: Redos of one step at most (the root of the Hermite is accurate to O(h^4): a few suffice; the last try is kept).
MAX_REDO = 12

#: Rows of a step end's per-contact data ``ed[c]``: force, its time derivative, overlap, rate, d(rate)/dt,
#: unclipped force and its time derivative, elastic energy, dissipated power (on the branch of the step ending
#: there; :func:`end_data`).
R_F, R_DF, R_D, R_R, R_Q, R_FU, R_DFU, R_E, R_P = 0, 1, 2, 3, 4, 5, 6, 7, 8
ROWS = 9
#: Slots of ``ends[c]``: energies [J] and their rates [W] (dissipated: D and the power).
E_KE, E_DKE, E_PE, E_DPE, E_D, E_DD = 0, 1, 2, 3, 4, 5
ENDS = 6
#: Slots of the run's accumulator ``acc``.
A_T, A_TPREV, A_H, A_STEPS, A_HMIN, A_HMAX, A_HREF = 0, 1, 2, 3, 4, 5, 6
#: Contact states (:func:`_state`).
OPEN, CLIPPED, LOADED = 0, 1, 2


#: Rows of the offsets array ``off`` (``layout.pack``'s arrays): perpendicular offset difference e_{j+1} - e_j,
#: axial distance of centres at rest and R_j + R_{j+1} of an offset pair [m]. No columns for an aligned chain: one
#: specialisation for both (the width is a loop invariant, so LLVM keeps an offset-free copy of each contact loop).
G_DE, G_DX0, G_RSUM = 0, 1, 2


@njit(cache=True, nogil=True, inline="always")
def _line(du, dv, d0, off, j):
    """(delta, dx / d, d(delta)/dt, de^2 / d^3) of contact j from du = u_j - u_{j+1} and dv = v_j - v_{j+1}: an
    offset pair (de != 0) has d = sqrt(dx^2 + de^2), dx = dx0 - du, delta = R_j + R_{j+1} - d and its force acts
    along the line of centres, dx / d of it along the axis (docs/conventions.rst, misalignment); d2(delta)/dt2 =
    (dx / d) (a_j - a_{j+1}) - (de^2 / d^3) dv^2. An aligned pair: (du + d0_j, 1, dv, 0), chosen by selects,
    not a branch, in a misaligned chain (its contact loops vectorise)."""
    if off is not None and off.shape[1] > 0:
        de = off[G_DE, j]
        lined = de != 0.0
        dx = off[G_DX0, j] - du
        dist = np.sqrt(dx * dx + de * de) if lined else 1.0
        cc = dx / dist if lined else 1.0
        return (off[G_RSUM, j] - dist if lined else du + d0[j]), cc, cc * dv, de * de / (dist * dist * dist)
    return du + d0[j], 1.0, dv, 0.0


@njit(cache=True, nogil=True, inline="always")
def _accel(us, vs, kappa, damping, d0, off, fext, inv_mass, law, mode, out, pw, weight):
    """a = f(us, vs) into ``out`` with every contact's branch frozen (``mode[j]`` 1: the unclipped
    force F_u, extended to delta < 0 as at delta = 0; 0: no force); adds ``weight`` times each
    contact's dissipated power (F_j - F_el,j) r_j [W] to ``pw[j]``."""
    fprev = 0.0
    for i in range(inv_mass.shape[0]):
        d, cc, r, _ = _line(us[i] - us[i + 1], vs[i] - vs[i + 1], d0, off, i)
        dd = d if d > DELTA_MIN else 0.0
        sd = np.sqrt(dd)
        fel = kappa[i] * dd * sd
        fu = fel + kappa[i] * damping[i] * sd * r if law == LAW_VISCOELASTIC else fel + damping[i] * r
        f = fu if mode[i] > 0.0 else 0.0
        pw[i] += weight * ((f - fel) * r)
        f *= cc  # along the axis
        out[i] = (fprev - f + fext[i]) * inv_mass[i]
        fprev = f


@njit(cache=True, nogil=True)
def accelerations(u, v, kappa, damping, d0, off, fext, inv_mass, law, a):
    """a = f(u, v) with the law as it is (clipped; the start of a run)."""
    fprev = 0.0
    for i in range(inv_mass.shape[0]):
        d, cc, r, _ = _line(u[i] - u[i + 1], v[i] - v[i + 1], d0, off, i)
        f, _ = _viscous_force(d, r, kappa[i], damping[i], law)
        f *= cc
        a[i] = (fprev - f + fext[i]) * inv_mass[i]
        fprev = f


@njit(cache=True, nogil=True)
def set_modes(ed, b, mode):
    """Every contact's branch for the step from ``ed[b]``: 1 where it carries a force, else 0."""
    for j in range(ed.shape[2]):
        mode[j] = 1.0 if _state(ed[b, R_D, j], ed[b, R_R, j], ed[b, R_FU, j]) == LOADED else 0.0


@njit(cache=True, nogil=True)
def restart(u, v, a, kappa, damping, d0, off, fext, mass, inv_mass, law, mode, pw, ed, ends, b):
    """After a branch changed at a step's start: a = f(u, v) on the branches ``mode``, and the
    start's end data ``ed[b]``, ``ends[b]`` on them (:func:`end_data`)."""
    _accel(u, v, kappa, damping, d0, off, fext, inv_mass, law, mode, a, pw, 0.0)
    end_data(u, v, a, kappa, damping, d0, off, fext, mass, law, mode, ends[b, E_D], ed, ends, b)


@njit(cache=True, nogil=True, error_model="numpy")
def step(u, v, a, un, vn, an, us, vs, k2, k3, k4, pw, mode, kappa, damping, d0, off, fext, inv_mass, law, h, ed, b):
    """One step of size h from (u, v) with a = f(u, v) and end data ``ed[b]`` there, every contact
    on its branch ``mode`` (module docstring): the new state into (un, vn), f(un, vn) into ``an``;
    ``pw[j]`` the weighted sum P_1 + 2 P_2 + 2 P_3 + P_4 of contact j's dissipated power over the
    stages (:func:`step_dissipation`)."""
    n = inv_mass.shape[0]
    hh, h8, h2, h6, hh6 = 0.5 * h, 0.125 * h * h, 0.5 * h * h, h / 6.0, h * (h / 6.0)
    # the four force passes are one loop over the stages: _accel is compiled once, not four times
    # (~1 CPU-s less for each of the engine's specialisations in a new environment), the same numbers
    for s in range(4):
        if s == 0:
            for i in range(n):
                us[i] = u[i] + hh * v[i] + h8 * a[i]
                vs[i] = v[i] + hh * a[i]
                pw[i] = ed[b, R_P, i]
        elif s == 1:
            for i in range(n):
                vs[i] = v[i] + hh * k2[i]
        elif s == 2:
            for i in range(n):
                us[i] = u[i] + h * v[i] + h2 * k3[i]
                vs[i] = v[i] + h * k3[i]
        else:
            for i in range(n):
                un[i] = u[i] + h * v[i] + hh6 * (a[i] + k2[i] + k3[i])
                vn[i] = v[i] + h6 * (a[i] + 2.0 * (k2[i] + k3[i]) + k4[i])
        # the last pass: f at the end on the step's branches (interpolants smooth up to its end)
        _accel(un if s == 3 else us, vn if s == 3 else vs, kappa, damping, d0, off, fext, inv_mass, law, mode,
               k2 if s == 0 else (k3 if s == 1 else (k4 if s == 2 else an)), pw, 2.0 if s < 2 else (1.0 if s == 2 else 0.0))


@njit(cache=True, nogil=True)
def step_dissipation(ed, b, c, pw, mode, h):
    """Energy [J] dissipated in the step of size h from ``ed[b]`` to ``ed[c]`` (after :func:`step` and
    :func:`end_data`): the stages' quadrature for each contact that carries a force (``mode``), the fall of the
    elastic energy of each that does not (open or clipped: it dissipates exactly that)."""
    h6 = h / 6.0
    e = 0.0
    for j in range(ed.shape[2]):
        e += h6 * pw[j] if mode[j] > 0.0 else ed[b, R_E, j] - ed[c, R_E, j]
    return e


@njit(cache=True, nogil=True, inline="always")
def _unclipped(d, sd, r, q, k, c, law):
    """(F_u, dF_u/dt) at overlap d > 0 (``sd`` = sqrt(d)), rate r, d(rate)/dt q (before the clip)."""
    if law == LAW_VISCOELASTIC:
        fu = k * sd * (d + c * r)
        dfu = k * (1.5 * sd * r + c * (0.5 * r * r / sd + sd * q))
    else:
        fu = k * d * sd + c * r
        dfu = 1.5 * k * sd * r + c * q
    return fu, dfu


@njit(cache=True, nogil=True, error_model="numpy")
def end_data(u, v, a, kappa, damping, d0, off, fext, mass, law, mode, dis, ed, ends, c):
    """Per contact j into ``ed[c]`` (rows R_*): F_j along the axis (the law's, clipped), dF_j/dt
    (0 when open or clipped), delta_j, r_j, q_j = d(r_j)/dt (:func:`_line`), F_u and dF_u/dt (0
    when open), the elastic energy (2/5) F_el,j delta_j and the dissipated power
    (F_j - F_el,j) r_j on the branch ``mode[j]`` (that of the step ending here, as ``a``);
    into ``ends[c]``: kinetic, elastic (minus the work of f_ext) and dissipated energy ``dis`` [J]
    with their rates dK/dt = sum m_i v_i a_i, dU/dt = sum F_el,j r_j - sum f_ext,i v_i,
    dD/dt = sum_j of that power [W]."""
    ke = 0.0
    dke = 0.0
    pe = 0.0
    dpe = 0.0
    dd = 0.0
    for i in range(mass.shape[0]):
        dv = v[i] - v[i + 1]
        d, cc, r, k = _line(u[i] - u[i + 1], dv, d0, off, i)
        q = cc * (a[i] - a[i + 1]) - k * dv * dv
        dc = d if d > DELTA_MIN else 0.0  # damped_force's, its square root shared with F_u and fb below
        sd = np.sqrt(dc)
        visco = law == LAW_VISCOELASTIC
        f, fel = damped_force_sd(d, dc, sd, r, kappa[i], kappa[i] * damping[i] if visco else damping[i], visco)
        fu, dfu = 0.0, 0.0
        if d > DELTA_MIN:
            fu, dfu = _unclipped(d, sd, r, q, kappa[i], damping[i], law)
        elif d >= 0.0:
            fu = f
        ed[c, R_F, i] = cc * f
        ed[c, R_DF, i] = dfu if f > 0.0 else 0.0
        ed[c, R_D, i] = d
        ed[c, R_R, i] = r
        ed[c, R_Q, i] = q
        ed[c, R_FU, i] = fu
        ed[c, R_DFU, i] = dfu
        el = 0.4 * fel * (d if d > 0.0 else 0.0)
        ed[c, R_E, i] = el
        if mode[i] > 0.0:  # the branch's force: F_u, extended below delta = 0 as at 0 (sd = 0)
            fb = fel + (kappa[i] * damping[i] * sd * r if law == LAW_VISCOELASTIC else damping[i] * r)
        else:
            fb = 0.0
        pb = (fb - fel) * r
        ed[c, R_P, i] = pb
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


@njit(cache=True, nogil=True, inline="always")
def _right(inv_mass, j):
    """1/m right of contact j; 0 past the last slot (contact P - 1: padding, kappa = 0)."""
    return inv_mass[j + 1] if j + 1 < inv_mass.shape[0] else 0.0


@njit(cache=True, nogil=True, inline="always")
def _state(d, r, fu):
    """OPEN (delta < 0), CLIPPED (closed, no force) or LOADED (a force, or touching and closing:
    Kuwabara-Kono's force at delta = 0 is 0 but rises as delta^(1/2))."""
    if d < 0.0:
        return OPEN
    return LOADED if fu > 0.0 or (d <= DELTA_MIN and r > 0.0) else CLIPPED


@njit(cache=True, nogil=True, error_model="numpy")
def _error_terms(ed, c, kappa, damping, inv_mass, law, mode, et):
    """e_j(h)'s factors of h^5 and h^(5/2) (Hertz part; at delta = 0 only the crossing term), h^5
    and h^(3/2) (Kuwabara-Kono's), h^5 (dynamics) into ``et[:, i]``, i counting the contacts on
    the loaded branch ``mode``; returns their count (:func:`_max_error` evaluates them)."""
    n = 0
    for j in range(kappa.shape[0]):
        if mode[j] > 0.0:
            d = ed[c, R_D, j]
            d = d if d > DELTA_MIN else 0.0
            r = ed[c, R_R, j]
            im = inv_mass[j] + _right(inv_mass, j)
            km = kappa[j] * im
            sd = np.sqrt(d)
            ar = abs(r)
            sr = np.sqrt(ar)
            r4 = r * r * r * r
            et[0, n] = km * r4 / (d * d * sd) if d > 0.0 else np.inf
            et[1, n] = km * ar * sr
            rate = damping[j] * im
            if law == LAW_VISCOELASTIC:
                kv = km * damping[j] * ar
                et[2, n] = kv * r4 / (d * d * d * sd) if d > 0.0 else np.inf
                et[3, n] = kv * sr
                rate = damping[j] * kappa[j] * sd * im
            w2 = 1.5 * km * sd
            et[4, n] = abs(ed[c, R_FU, j]) * im * (w2 * w2 + rate * rate * rate * rate)
            n += 1
    return n


@njit(cache=True, nogil=True, error_model="numpy")
def _max_error(et, n, visco, h):
    """(max_j e_j(h) over the ``n`` contacts of :func:`_error_terms`, that contact's local
    exponent d log e / d log h)."""
    sh = np.sqrt(h)
    h5 = h * h * h * h * h
    emax = 0.0
    pmax = 5.0
    for i in range(n):
        s1 = et[0, i] * h5
        c1 = et[1, i] * h * h * sh
        e1, p1 = (s1, 5.0) if s1 < c1 else (c1, 2.5)
        e2, p2 = 0.0, 0.0
        if visco:
            s2 = et[2, i] * h5
            c2 = et[3, i] * h * sh
            e2, p2 = (s2, 5.0) if s2 < c2 else (c2, 1.5)
        e3 = et[4, i] * h5
        e = e1 + e2 + e3
        if e > emax:
            emax = e
            pmax = (e1 * p1 + e2 * p2 + 5.0 * e3) / e
    return emax, pmax


@njit(cache=True, nogil=True, error_model="numpy")
def next_step(ed, c, kappa, damping, inv_mass, law, mode, eps, h_ref, h_max, et):
    """Size [s] of the next step from the end data ``ed[c]`` of the present state, its contacts on
    the branches ``mode``: the largest h with max_j e_j(h) <= eps (Newton's method on log e
    against log h from the last step the bound chose, ``h_ref``: log e is convex in log h, so the
    iterates approach from above; the bound's factors computed once into the scratch ``et``,
    :func:`_error_terms`), at most MAX_GROWTH h_ref and ``h_max``, and within the stability bound
    (module docstring)."""
    # stability: Gershgorin bounds of the stiffness and damping rates at overlaps one step ahead
    w = 0.0
    cw = 0.0
    for j in range(kappa.shape[0]):
        d = ed[c, R_D, j]
        r = ed[c, R_R, j]
        dp = d + 2.0 * h_ref * (r if r > 0.0 else 0.0)
        dp = dp if dp > 0.0 else 0.0
        im = max(inv_mass[j], _right(inv_mass, j))
        sd = np.sqrt(dp)
        kt = 1.5 * kappa[j] * sd * im
        cj = (kappa[j] * damping[j] * sd if law == LAW_VISCOELASTIC else damping[j]) * im
        w = kt if kt > w else w
        cw = cj if cj > cw else cw
    h = h_max
    if h_ref > 0.0 and MAX_GROWTH * h_ref < h:
        h = MAX_GROWTH * h_ref
    rho = 2.0 * np.sqrt(w) + 4.0 * cw
    if rho > 0.0 and MAX_RHO_H / rho < h:
        h = MAX_RHO_H / rho
    n = _error_terms(ed, c, kappa, damping, inv_mass, law, mode, et)
    visco = law == LAW_VISCOELASTIC
    e, p = _max_error(et, n, visco, h)
    if e <= eps:
        return h
    for _ in range(8):
        h *= (eps / e) ** (1.0 / p)
        e, p = _max_error(et, n, visco, h)
        if e <= eps * 1.0001:
            return h
    # every term grows at least as h^1.5: this factor bounds them all
    return h * (eps / e) ** (1.0 / 1.5)


@njit(cache=True, nogil=True, error_model="numpy")
def event_inside(ed, b, c, h, mode, inv_mass, eps):
    """Where the law left a contact's branch ``mode`` in the step from end data ``ed[b]`` to
    ``ed[c]`` (its state at the end differs from the branch): the root theta of delta (a closing)
    or of F_u (a clip or reload) on the cubic Hermite through both ends. Returns the earliest
    theta in (EVENT_TOL, 1 - EVENT_TOL), 2 when a contact's branch was wrong from the start
    (theta <= EVENT_TOL: at the event; ``mode`` is switched there, the step must restart), else -1
    (every event at the step's end: the next step takes the new branch). Not landed on: changes
    at forces below EVENT_EPS eps / (m^-1 h) at the step's end."""
    best = 2.0
    switched = False
    for j in range(ed.shape[2]):
        s1 = _state(ed[c, R_D, j], ed[c, R_R, j], ed[c, R_FU, j])
        m = mode[j] > 0.0
        if m == (s1 == LOADED):
            continue
        if max(abs(ed[c, R_FU, j]), abs(ed[c, R_F, j])) * (inv_mass[j] + _right(inv_mass, j)) * h <= EVENT_EPS * eps:
            continue
        if not m and ed[b, R_D, j] < 0.0:  # closing
            x = hermite_root(ed[b, R_D, j], ed[b, R_R, j], ed[c, R_D, j], ed[c, R_R, j], h)
        else:  # clip (loaded branch, F_u down through 0) or reload
            y0, y1 = ed[b, R_FU, j], ed[c, R_FU, j]
            if m:
                y1 = y1 if y1 < 0.0 else -1e-300
            else:
                y1 = y1 if y1 > 0.0 else 1e-300
            x = hermite_root(y0, ed[b, R_DFU, j], y1, ed[c, R_DFU, j], h)
        if x <= EVENT_TOL:
            mode[j] = 0.0 if m else 1.0
            switched = True
        best = x if x < best else best
    if switched:
        return 2.0
    if EVENT_TOL < best < 1.0 - EVENT_TOL:
        return best
    return -1.0


@njit(cache=True, nogil=True, inline="always")
def _force_w(ed, b, c, j, q, w, kappa, damping, d0, off, law):
    """Contact j's force along the axis from the weights ``q`` of the quintic Hermite (its overlap,
    through delta, r, q at both ends) and ``w`` of the cubic (its rate, through r, q): the law's,
    clipped (times dx / d for an offset pair, d = R_j + R_{j+1} - delta)."""
    d = (q[0] * ed[b, R_D, j] + q[1] * ed[b, R_R, j] + q[2] * ed[b, R_Q, j] + q[3] * ed[c, R_D, j]
         + q[4] * ed[c, R_R, j] + q[5] * ed[c, R_Q, j])
    r = w[0] * ed[b, R_R, j] + w[1] * ed[b, R_Q, j] + w[2] * ed[c, R_R, j] + w[3] * ed[c, R_Q, j]
    return axial(_viscous_force(d, r, kappa[j], damping[j], law)[0], off, j, d)


@njit(cache=True, nogil=True)
def _force_at(ed, b, c, j, theta, h, kappa, damping, d0, off, law):
    """Contact j's force at theta of the step (:func:`_force_w`)."""
    return _force_w(ed, b, c, j, quintic(theta, h), hermite(theta, h), kappa, damping, d0, off, law)


@njit(cache=True, nogil=True)
def _peak_in_step(ed, b, c, j, h, kappa, damping, d0, off, law):
    """(largest interpolated force of contact j in the step, its theta): golden-section search."""
    g = 0.6180339887498949
    lo, hi = 0.0, 1.0
    x1 = hi - g * (hi - lo)
    x2 = lo + g * (hi - lo)
    f1 = _force_at(ed, b, c, j, x1, h, kappa, damping, d0, off, law)
    f2 = _force_at(ed, b, c, j, x2, h, kappa, damping, d0, off, law)
    for _ in range(60):
        if f1 < f2:
            lo = x1
            x1, f1 = x2, f2
            x2 = lo + g * (hi - lo)
            f2 = _force_at(ed, b, c, j, x2, h, kappa, damping, d0, off, law)
        else:
            hi = x2
            x2, f2 = x1, f1
            x1 = hi - g * (hi - lo)
            f1 = _force_at(ed, b, c, j, x1, h, kappa, damping, d0, off, law)
        if hi - lo < 1e-12:
            break
    x = 0.5 * (lo + hi)
    return _force_at(ed, b, c, j, x, h, kappa, damping, d0, off, law), x


@njit(cache=True, nogil=True, error_model="numpy")
def damped_run(state, chain, off, law, probes, control, k_start, k_stop, acc, all_forces=True):
    """Advance until sample ``k_stop - 1`` (samples ``interval`` seconds apart) is recorded.

    ``state`` (:class:`DampedState`), ``chain`` (:class:`~.rkn_kernels.ChainArrays`), ``probes``
    (:class:`~.rkn_kernels.ProbeBuffers`) and ``control`` (:class:`~.rkn_kernels.StepControl`)
    carry the arrays and numbers named below; ``off`` the offset pairs' geometry (rows G_*, no
    columns for an aligned chain), ``law`` the law's code.

    On entry and exit (u, v, a) is the state at time acc[A_T], a = f(u, v); the end data of the
    last two step ends are ``ed[c]``, ``ends[c]`` (this one) and ``ed[1 - c]``, ``ends[1 - c]``
    (the step's start, acc[A_TPREV]), c = steps % 2; ``mode`` the contacts' branches of the step,
    ``last`` those of the last one (a = f(u, v) on them); ``up``, ``vp``, ``ap`` the bodies' state at
    the step's start when recorded. Steps: ``h_fixed`` [s] when > 0 (no event location), else
    :func:`next_step` with ``eps`` [m/s] and ``h_max`` [s], redone to end on an event
    (:func:`event_inside`). Probes, a step's samples a block at a time (module docstring): forces
    into ``fi`` (their running maxima into ``fmax``; 0 without interpolating for a contact whose
    overlap stays where its force is 0, :func:`~.rkn_kernels.quintic_at_most`), the contacts
    ``rec`` into row k of ``out_f``, energies into ``out_ke``, ``out_pe``, ``out_d``, velocities and
    positions of bodies 0..N when asked. ``peak`` = [largest wall force up to ``h_max`` (the run's
    duration), its time]. ``acc`` = [time, previous step's start, last step, steps, smallest step,
    largest step, last step the error bound chose]. With ``all_forces`` False (a batch that keeps only its metrics) only the contacts ``rec`` are
    interpolated at the samples, and ``fmax`` holds every contact's largest force over the run
    instead of over the samples: its value at every step's end and, in a step where its force
    turns down, the interpolant's maximum (as the wall's peak): never below the sampled maximum,
    above it by the interpolant's curvature over at most one sample interval (every contact is
    interpolated at the last sample, k_stop - 1, the end of a batch's run).
    Returns 0, or 1 when the state became non-finite.
    """
    u, v, a, un, vn, an, us, vs, k2, k3, k4, pw, mode, last, up, vp, ap, fi, ed, ends = state
    mass, inv_mass, kappa, damping, d0, fext, wall_slot = chain
    rec, out_f, out_ke, out_pe, out_d, out_v, record_v, out_u, record_u, fmax, peak = probes
    interval, h_fixed, eps, h_max = control
    n = mass.shape[0]
    nc = fmax.shape[0]
    nrec = rec.shape[0]
    ws = wall_slot
    t = acc[A_T]
    tp = acc[A_TPREV]
    hl = acc[A_H]
    href = acc[A_HREF]
    steps = int(acc[A_STEPS])
    t_last = (k_stop - 1) * interval
    shut = np.zeros(nc, dtype=np.bool_)  # contacts without a force over the whole step
    et = np.zeros((5, kappa.shape[0]))  # the error bound's factors (next_step)
    seen = -1  # the step they were found for
    lo, hi = 0, 0  # the contacts lo..hi-1 hold every one with a force in it
    pc = np.zeros((PATH_ROWS, nc))  # their paths over it (rkn_samples)
    th = np.zeros(fi.shape[1])  # a block of samples in it: their theta
    rec_at = np.zeros(nc, dtype=np.bool_)  # recorded contacts
    for r in range(nrec):
        rec_at[rec[r]] = True
    k = k_start
    while k < k_stop:
        tk = k * interval
        while t < tk:
            b = steps % 2
            c = 1 - b
            set_modes(ed, b, mode)
            for j in range(nc):
                if mode[j] != last[j]:  # an instant at the last step's end: f(u, v) on the new branches
                    restart(u, v, a, kappa, damping, d0, off, fext, mass, inv_mass, law, mode, pw, ed, ends, b)
                    break
            if h_fixed > 0.0:
                h = h_fixed
            else:
                h = next_step(ed, b, kappa, damping, inv_mass, law, mode, eps, href, h_max, et)
                href = h
            for redo in range(MAX_REDO + 1):
                step(u, v, a, un, vn, an, us, vs, k2, k3, k4, pw, mode, kappa, damping, d0, off, fext, inv_mass, law, h,
                     ed, b)
                end_data(un, vn, an, kappa, damping, d0, off, fext, mass, law, mode, 0.0, ed, ends, c)
                if h_fixed > 0.0 or redo == MAX_REDO:
                    break
                x = event_inside(ed, b, c, h, mode, inv_mass, eps)
                if x < 0.0:
                    break
                if x > 1.0:  # a branch switched at the start: its step is bounded afresh
                    restart(u, v, a, kappa, damping, d0, off, fext, mass, inv_mass, law, mode, pw, ed, ends, b)
                    hm = next_step(ed, b, kappa, damping, inv_mass, law, mode, eps, href, h_max, et)
                    h = hm if hm < h else h
                else:
                    h *= x
            ends[c, E_D] = ends[b, E_D] + step_dissipation(ed, b, c, pw, mode, h)
            for j in range(nc):
                last[j] = mode[j]
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
            # the wall's peak up to the run's end (h_max, its duration: a last step may pass it;
            # the samples up to it count below)
            dw0 = ed[b, R_DF, ws]
            dw1 = ed[c, R_DF, ws]
            if dw0 > 0.0 and dw1 <= 0.0:
                fk, x = _peak_in_step(ed, b, c, ws, h, kappa, damping, d0, off, law)
                if fk > peak[0] and t + x * h <= h_max:
                    peak[0] = fk
                    peak[1] = t + x * h
            if ed[c, R_F, ws] > peak[0] and t + h <= h_max:
                peak[0] = ed[c, R_F, ws]
                peak[1] = t + h
            if not all_forces:  # the run's maxima up to the last sample (a last step may pass it)
                for j in range(nc):
                    fj = ed[c, R_F, j] if t + h <= t_last else 0.0
                    # the search only where the step's force may pass the maximum so far
                    if ed[b, R_DF, j] > 0.0 and ed[c, R_DF, j] <= 0.0 and fmax[j] < force_bound(
                            ed[b, R_D, j], ed[b, R_R, j], ed[b, R_Q, j], ed[c, R_D, j], ed[c, R_R, j], ed[c, R_Q, j], h,
                            kappa[j], damping[j], law == LAW_VISCOELASTIC):
                        fk, x = _peak_in_step(ed, b, c, j, h, kappa, damping, d0, off, law)
                        fj = fk if fk > fj and t + x * h <= t_last else fj
                    fmax[j] = fj if fj > fmax[j] else fmax[j]
            tp = t
            t += h
            hl = h
            acc[A_HMIN] = h if h < acc[A_HMIN] else acc[A_HMIN]
            acc[A_HMAX] = h if h > acc[A_HMAX] else acc[A_HMAX]
        # --- probes at samples k..kb-1, between the steps' ends tp < tk <= t (rkn_samples)
        c = steps % 2
        b = 1 - c
        if steps != seen:  # a new step: the contacts whose force stays 0 over it (its overlap's
            seen = steps   # interpolant never above DELTA_MIN; a dashpot's: never above 0, or no rate)
            lo, hi = nc, 0
            for r in range(nc if all_forces else nrec):
                j = r if all_forces else rec[r]
                shut[j] = quintic_at_most(ed[b, R_D, j], ed[b, R_R, j], ed[b, R_Q, j], ed[c, R_D, j], ed[c, R_R, j],
                                          ed[c, R_Q, j], hl,
                                          DELTA_MIN if law == LAW_VISCOELASTIC or damping[j] == 0.0 else 0.0)
                if not shut[j]:
                    lo = j if j < lo else lo
                    hi = j + 1 if j >= hi else hi
                    path_coefficients(ed, b, c, j, hl, pc, R_D)
        kb = block_of_samples(k, k_stop, interval, tp, t, hl, th)
        nb = kb - k
        for j in range(lo, hi):  # all_forces False: the recorded contacts among them (shut[j] is theirs)
            if shut[j] or not (all_forces or rec_at[j]):
                for m in range(nb):
                    fi[j, m] = 0.0
                continue
            kj, cj = kappa[j], damping[j]
            if off is not None and off.shape[1] > 0 and off[G_DE, j] != 0.0:
                de2, rsum = off[G_DE, j] * off[G_DE, j], off[G_RSUM, j]
                for m in range(nb):
                    d, rt = path_at(pc, j, th[m])
                    fi[j, m] = _viscous_force(d, rt, kj, cj, law)[0] * axial_factor(de2, rsum, d)
            else:  # two loops: the aligned one stays vectorised (a select inside halves its speed)
                for m in range(nb):
                    d, rt = path_at(pc, j, th[m])
                    fi[j, m] = _viscous_force(d, rt, kj, cj, law)[0]
        if all_forces:
            for j in range(lo, hi):
                fm = fmax[j]
                for m in range(nb):
                    fm = fi[j, m] if fi[j, m] > fm else fm
                fmax[j] = fm
        elif kb == k_stop:  # every contact at the last sample: a force still rising
            qw = quintic(th[nb - 1], hl)
            hw = hermite(th[nb - 1], hl)
            for j in range(nc):
                f = _force_w(ed, b, c, j, qw, hw, kappa, damping, d0, off, law)
                fmax[j] = f if f > fmax[j] else fmax[j]
                if j == ws and f > peak[0]:
                    peak[0] = f
                    peak[1] = (k_stop - 1) * interval
        for m in range(nb):
            kk = k + m
            for r in range(nrec):
                j = rec[r]
                out_f[kk, r] = fi[j, m] if lo <= j < hi else 0.0
            if all_forces and lo <= ws < hi and fi[ws, m] > peak[0]:
                peak[0] = fi[ws, m]
                peak[1] = kk * interval
            w0, w0d, w1, w1d = hermite(th[m], hl)
            ke = w0 * ends[b, E_KE] + w0d * ends[b, E_DKE] + w1 * ends[c, E_KE] + w1d * ends[c, E_DKE]
            out_ke[kk] = ke
            out_pe[kk] = w0 * ends[b, E_PE] + w0d * ends[b, E_DPE] + w1 * ends[c, E_PE] + w1d * ends[c, E_DPE]
            out_d[kk] = w0 * ends[b, E_D] + w0d * ends[b, E_DD] + w1 * ends[c, E_D] + w1d * ends[c, E_DD]
            record_bodies(out_v, record_v, out_u, record_u, kk, th[m], hl, up, vp, ap, u, v, a)
            if not np.isfinite(ke) or not np.isfinite(ed[c, R_F, 0]):
                acc[A_T], acc[A_TPREV], acc[A_H], acc[A_STEPS], acc[A_HREF] = t, tp, hl, steps, href
                return 1
        k = kb
    acc[A_T], acc[A_TPREV], acc[A_H], acc[A_STEPS], acc[A_HREF] = t, tp, hl, steps, href
    return 0


# the law's force (primitives.py) and the interpolants (rkn_kernels.py, rkn_samples.py) are compiled
# in: an edit there recompiles the run
kernels.flush_stale_cache(damped_run, also=(rkn_kernels.__file__, rkn_samples.__file__))
