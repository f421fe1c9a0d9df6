"""Compiled kernels of the fourth-order integrator ``"rkn4"``: a symplectic Runge-Kutta-Nystrom
composition with contact-aware step control and probes interpolated between steps.

The method is Blanes & Moan's SRKN_6^b (J. Comput. Appl. Math. 142 (2002) 313, Table 3): six
force evaluations per step, order 4, an error constant ~1/100 of Yoshida's triple jump. A step
of size h from (u, v) with accelerations a(u) (paper eq. 1: a_i = (F_{i-1} - F_i + f_ext,i) / m_i)
is the symmetric sequence of kicks v += b_k h a(u) and drifts u += a_k h v::

    kick b1, drift a1, kick b2, drift a2, kick b3, drift a3, kick b4, drift a3, kick b3, drift a2,
    kick b2, drift a1, kick b1

whose last force evaluation is the next step's first (first same as last). Each kick-then-drift
pair is one fused pass over the bodies (:func:`_stage`), the force of the contact on a body's
left carried from the previous iteration as in ``kernels.step_elastic``, so that LLVM vectorises
it. Arrays are those of :mod:`hertzchain.integrate.core.kernels` (``layout.pack``).

Why a step control aware of contacts: Hertz's force kappa max(delta, 0)^(3/2) is not smooth where
a contact closes or opens (its second derivative is infinite there), and a step across that
instant makes a velocity error of order kappa |d(delta)/dt|^(3/2) h^(5/2) / m, whatever the order
of the method: the impact and the striker's rebound alone held fixed steps to order ~2.5 on the
paper's chain 1 (tests/test_rkn.py). :func:`next_step` bounds, per contact, the local velocity
error of a step of size h by

    e_j(h) = kappa_j (1/m_j + 1/m_{j+1}) |r_j|^(3/2) h^(5/2) min(1, h / tau_j)^(5/2),

r_j = d(delta_j)/dt, tau_j = |delta_j| / |r_j| the time to (or since) the contact's closing or
opening. Right at a crossing (tau < h) this is the crossing error above; away from it
(h < tau) it is kappa (1/m) |r|^4 |delta|^(-5/2) h^5, which for a contact that oscillates with
frequency omega is the fourth-order local error (F / m) h (omega h)^4: one estimate for both.
The step keeps max_j e_j(h) <= eps (a velocity), so it shrinks to a few ns at the impact, grows as
the contact's force becomes smooth, and does not shrink for contacts that close gently (the
precursor ahead of a solitary wave, whose |r| is tiny). A Gershgorin bound on the highest
frequency (as in ``kernels.required_stride``) keeps omega h below a fixed limit for stability.

Probes (forces, energies, velocities, positions) are recorded at the sample times by cubic
Hermite interpolation between the two steps around each sample, from the values and the time
derivatives the state gives exactly at the step ends (dF_j/dt = (3/2) kappa_j delta_j^(1/2)
r_j; dK/dt = sum v_i m_i a_i; dU/dt = sum F_j r_j - sum f_ext,i v_i), so the sample interval
never caps the step; the error of a cubic Hermite interpolant, h^4 f''''/384, is of the method's
order. The peak wall force is the largest value of the same cubic on the steps where the wall
force turns down.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from ..core import kernels
from ..core.kernels import DELTA_MIN
from ..core.structures import ChainArrays  # noqa: F401 (the runs' chain, shared with the Verlet runs)

#: Blanes & Moan SRKN_6^b kick (b) and drift (a) coefficients (order 4).
B1, A1 = 0.0829844064174052, 0.245298957184271
B2, A2 = 0.396309801498368, 0.604872665711080
B3 = -0.0390563049223486
A3 = 0.5 - (A1 + A2)
B4 = 1.0 - 2.0 * (B1 + B2 + B3)
#: The inner stages' kicks and drifts, in order (:func:`step`): a loop over them compiles the
#: stage once, not five times (0.3 CPU-s less in every new environment), the same numbers.
INNER_KICKS = np.array([B2, B3, B4, B3, B2])
INNER_DRIFTS = np.array([A2, A3, A3, A2, A1])

#: Largest omega h the step control allows (omega: the Gershgorin bound of the present stiffness
#: at overlaps extrapolated one step ahead). The method is stable to about 3.3 (Blanes & Moan's
#: stability interval for six stages); the error control keeps real steps far below this.
MAX_OMEGA_H = 0.5
#: A step grows at most by this factor over the previous one.
MAX_GROWTH = 2.0
#: A step does not end on a contact's opening or closing closer than this fraction of it to its
#: start (the kink is then taken at the step's start; see :func:`next_step`).
LAND_FLOOR = 1e-3
#: ... and it ends on it when crossing inside the step would make an error above sqrt(LAND_ERROR)
#: eps (the crossing bound keeps that error below eps; landing makes it the same every time).
LAND_ERROR = 1e-2

#: Slots of the per-step end data ``ends`` (see :func:`end_data`): the energies and their rates.
E_KE, E_DKE, E_PE, E_DPE = 0, 1, 2, 3


# The compiled runs of both fourth-order paths take these typed structures (Numba compiles a
# NamedTuple's fields as one typed argument), not dozens of positional arrays.

class ProbeBuffers(NamedTuple):
    """What a run records: the contacts ``rec``, one row per sample of their forces ``out_f``
    [N], the energies [J] (``out_d``: dissipated; unused by the elastic run), velocities [m/s]
    and positions [m] of bodies 0..N when ``record_v`` / ``record_u``, every contact's largest
    force ``fmax`` [N] and ``peak`` = [largest wall force, its time]."""

    rec: np.ndarray
    out_f: np.ndarray
    out_ke: np.ndarray
    out_pe: np.ndarray
    out_d: np.ndarray
    out_v: np.ndarray
    record_v: bool
    out_u: np.ndarray
    record_u: bool
    fmax: np.ndarray
    peak: np.ndarray


class StepControl(NamedTuple):
    """Samples ``interval`` [s] apart; a fixed step ``h_fixed`` [s] when > 0, else step control
    with the local velocity error ``eps`` [m/s] per step and steps of at most ``h_max`` [s]."""

    interval: float
    h_fixed: float
    eps: float
    h_max: float


class RknState(NamedTuple):
    """The elastic run's state (u, v, a, g, sq) and the end data of its last two step ends."""

    u: np.ndarray
    v: np.ndarray
    a: np.ndarray
    g: np.ndarray
    sq: np.ndarray
    ed: np.ndarray
    ends: np.ndarray


class RknScratch(NamedTuple):
    """Work arrays of the elastic run: the step's start (up, vp, ap) when recorded, the sampled
    forces ``fi`` (contacts x up to ``SAMPLE_BLOCK`` samples of one step) at the samples' ``th``
    (theta, their fractions of the step), the crossing contacts ``cross``, the force quintics ``coef`` and the step
    control's (sx, sw, st, sc)."""

    up: np.ndarray
    vp: np.ndarray
    ap: np.ndarray
    fi: np.ndarray
    th: np.ndarray
    cross: np.ndarray
    coef: np.ndarray
    sx: np.ndarray
    sw: np.ndarray
    st: np.ndarray
    sc: np.ndarray


@njit(cache=True, nogil=True, inline="always")
def _stage(u, v, kappa, d0, fext, inv_mass, kick, drift):
    """Forces at u, then the kick v += kick a and the drift u += drift v, in one pass."""
    fprev = 0.0
    for i in range(inv_mass.shape[0]):
        d = u[i] - u[i + 1] + d0[i]
        d = d if d > DELTA_MIN else 0.0
        f = kappa[i] * d * np.sqrt(d)
        v[i] += kick * ((fprev - f + fext[i]) * inv_mass[i])
        u[i] += drift * v[i]
        fprev = f


@njit(cache=True, nogil=True, inline="always")
def _closing(u, v, a, g, sq, kappa, d0, fext, inv_mass, kick):
    """Forces at u into g (shifted by one, as ``kernels``), sqrt(overlap) into sq, a(u) into a,
    then the closing kick v += kick a: the state at the step's end, synchronised."""
    fprev = 0.0
    for i in range(inv_mass.shape[0]):
        d = u[i] - u[i + 1] + d0[i]
        d = d if d > DELTA_MIN else 0.0
        s = np.sqrt(d)
        f = kappa[i] * d * s
        g[i + 1] = f
        sq[i] = s
        ai = (fprev - f + fext[i]) * inv_mass[i]
        a[i] = ai
        v[i] += kick * ai
        fprev = f


@njit(cache=True, nogil=True)
def forces_at(u, v, a, g, sq, kappa, d0, fext, inv_mass):
    """g, sq and a at the state (u, v) without moving it (the start of a run)."""
    _closing(u, v, a, g, sq, kappa, d0, fext, inv_mass, 0.0)


@njit(cache=True, nogil=True)
def step(u, v, a, g, sq, kappa, d0, fext, inv_mass, h):
    """One SRKN_6^b step of size h [s] from a synchronised state whose a = a(u) (see the module
    docstring); leaves g, sq, a of the new positions and synchronised velocities."""
    n = inv_mass.shape[0]
    c = B1 * h
    d = A1 * h
    for i in range(n):  # the opening kick reuses a(u) of the last step's end (first same as last)
        v[i] += c * a[i]
        u[i] += d * v[i]
    for s in range(INNER_KICKS.shape[0]):
        _stage(u, v, kappa, d0, fext, inv_mass, INNER_KICKS[s] * h, INNER_DRIFTS[s] * h)
    _closing(u, v, a, g, sq, kappa, d0, fext, inv_mass, B1 * h)


@njit(cache=True, nogil=True, inline="always")
def _max4(x):
    """Largest element of x (length a multiple of 4, elements >= 0): four running maxima, which
    LLVM packs into one vector register (a single running maximum is not vectorised)."""
    x0 = 0.0
    x1 = 0.0
    x2 = 0.0
    x3 = 0.0
    for j in range(0, x.shape[0], 4):
        a = x[j]
        b = x[j + 1]
        c = x[j + 2]
        e = x[j + 3]
        x0 = a if a > x0 else x0
        x1 = b if b > x1 else x1
        x2 = c if c > x2 else x2
        x3 = e if e > x3 else x3
    x0 = x1 if x1 > x0 else x0
    x2 = x3 if x3 > x2 else x2
    return x2 if x2 > x0 else x0


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _contact_bound(u, v, kappa, d0, inv_mass, j, imr, inv_eps, h_prev, sx, sw, st, sc):
    """Contact j's terms of :func:`next_step` into ``sx``, ``sw``, ``st``, ``sc`` (its docstring);
    ``imr`` the inverse mass on its right (0 past the last slot)."""
    d = u[j] - u[j + 1] + d0[j]
    r = v[j] - v[j + 1]
    ad = abs(d)
    r2 = r * r
    km = kappa[j] * (inv_mass[j] + imr)
    ki = km * inv_eps
    ki2 = ki * ki
    r4 = r2 * r2
    ad5 = ad * ad * ad * ad * ad
    # e_j(h) <= eps  <=>  h^-10 >= ki^2 (min(r^8 |delta|^-5, ki^2 r^6) + 4.5 km^2 r^4
    # + 5.0625 km^4 delta+^5): the crossing bound at tau < h, the smooth one beyond, and the
    # oscillation term where the rate vanishes (padding and the free end: kappa = 0, no
    # bound). A touching contact (delta = 0) takes the crossing bound; r = 0 gives 0, no NaN.
    sing = r4 * r4 / (ad5 + 1e-300)
    cap = ki2 * r4 * r2
    km2 = km * km
    xj = ki2 * ((sing if sing < cap else cap) + 4.5 * km2 * r4 + 5.0625 * km2 * km2 * (ad5 if d > 0.0 else 0.0))
    # an open contact moving apart (or at rest) carries no force in this step: no bound (its
    # opening was bounded while it was closed)
    m = d if d > r else r
    sx[j] = xj if m > 0.0 else 0.0
    # stability: tangent stiffness k = (3/2) kappa delta^(1/2) at the overlap one step ahead
    dp = d + 2.0 * h_prev * (r if r > 0.0 else 0.0)
    dp = dp if dp > 0.0 else 0.0
    im = inv_mass[j] if inv_mass[j] > imr else imr
    sw[j] = kappa[j] * kappa[j] * dp * im * im
    # a contact that will open (delta > 0 > r) or close (delta < 0 < r): 1 / its time to
    # do so (linear), and ki^2 |r|^3 = h_f^-5, h_f the step whose crossing error is eps
    ar = abs(r)
    st[j] = ar / ad if d * r < 0.0 else 0.0
    sc[j] = ki2 * r2 * ar


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def contact_bounds(u, v, kappa, d0, inv_mass, eps, h_prev, sx, sw, st, sc):
    """:func:`next_step`'s per-contact terms for the contacts of ``kappa`` (``u``, ``v``,
    ``inv_mass`` from the same first slot to the end: the threaded engine passes a block's views).
    The last slot's contact (padding, kappa = 0) has nothing on its right: it takes 0 there (a
    select in the one loop, which inlines the bound once), so that no contact reads the inverse
    mass past the array's end."""
    inv_eps = 1.0 / eps
    n = kappa.shape[0]
    m = min(n, inv_mass.shape[0] - 1)
    for j in range(n):
        _contact_bound(u, v, kappa, d0, inv_mass, j, inv_mass[j + 1] if j < m else 0.0, inv_eps, h_prev, sx, sw, st, sc)


@njit(cache=True, nogil=True, error_model="numpy")
def next_step(u, v, kappa, d0, inv_mass, eps, h_prev, h_max, sx, sw, st, sc):
    """Size [s] of the next step from the synchronised state (see the module docstring).

    ``eps`` [m/s] bounds the local velocity error e_j(h) of every contact; ``h_prev`` is the last
    step (the step grows at most MAX_GROWTH-fold, and the overlaps are extrapolated over 2 h_prev
    for the stability bound); ``h_max`` caps the step. ``sx``, ``sw``, ``st``, ``sc``: scratch
    arrays of the slot count. Both bounds are taken squared, so that the loop needs no square root (it runs every
    step), and written without branches, so that LLVM vectorises it; the maxima are exact
    whatever the order of evaluation, so the step does not depend on the vectorisation.
    """
    contact_bounds(u, v, kappa, d0, inv_mass, eps, h_prev, sx, sw, st, sc)
    x = _max4(sx)  # max_j h_j^(-10)
    w = _max4(sw)  # max_j kappa_j^2 delta_j+ max(1/m_j, 1/m_{j+1})^2
    h = h_max
    if h_prev > 0.0 and MAX_GROWTH * h_prev < h:
        h = MAX_GROWTH * h_prev
    if w > 0.0:
        # Gershgorin: omega^2 <= max_i 2 (k_{i-1} + k_i) / m_i <= 4 max_j k_j max(1/m_j, 1/m_{j+1})
        hw = MAX_OMEGA_H / np.sqrt(6.0 * np.sqrt(w))
        h = hw if hw < h else h
    if x > 0.0:
        hx = x ** -0.1
        h = hx if hx < h else h
    # A step that would cross a contact's opening or closing at an error above sqrt(LAND_ERROR) eps
    # ends on it instead (the next one then starts at the kink, whatever the phase of the crossing in the
    # step would have been: the error stops depending on where the steps happened to fall).
    # Crossings within LAND_FLOOR h of the start are taken in the step.
    h5 = h * h * h * h * h
    inv_h = 1.0 / h
    for j in range(inv_mass.shape[0]):
        y = st[j]
        st[j] = y if (y > inv_h and y * LAND_FLOOR < inv_h and sc[j] * h5 > LAND_ERROR) else 0.0
    y = _max4(st)
    if y > 0.0:
        h = 1.0 / y
    return h


#: Rows of a step end's per-contact data ``ed`` (see :func:`end_data`).
R_F, R_DF, R_DDF, R_D, R_R, R_Q = 0, 1, 2, 3, 4, 5
ROWS = 6


@njit(cache=True, nogil=True, fastmath={"reassoc"}, error_model="numpy")
def end_data(u, v, a, g, sq, kappa, d0, fext, mass, ed, ends, c):
    """What the interpolation needs at a step's end, per contact j into the rows of ``ed[c]``:
    the force F_j (R_F) and its first and second time derivatives (R_DF, R_DDF),
    dF/dt = (3/2) kappa delta^(1/2) r and d2F/dt2 = (3/2) kappa (r^2 / (2 delta^(1/2)) +
    delta^(1/2) q) (0 for an open contact), the overlap delta_j (R_D), its rate
    r = d(delta_j)/dt (R_R) and q = d2(delta_j)/dt2 = a_j - a_{j+1} (R_Q); and the kinetic and
    potential energies with their rates into ``ends[c]`` (E_KE, E_DKE, E_PE, E_DPE) [J, W]:
    dK/dt = sum m_i v_i a_i, dU/dt = sum F_j r_j - sum f_ext,i v_i.

    Indexed in place, not through views (``ed[c]``, ``g[1:]``): every view of an array costs two
    atomic reference-count updates, which were a quarter of a run's time."""
    ke = 0.0
    dke = 0.0
    pe = 0.0
    dpe = 0.0
    for i in range(mass.shape[0]):
        d = u[i] - u[i + 1] + d0[i]
        r = v[i] - v[i + 1]
        q = a[i] - a[i + 1]
        f = g[i + 1]
        si = sq[i]
        k = 1.5 * kappa[i]
        ed[c, R_F, i] = f
        ed[c, R_DF, i] = k * si * r
        # si = 0 for an open contact: r^2 / (2 si) is then inf or NaN, and the select gives 0
        x = k * (0.5 * r * r / si + si * q)
        ed[c, R_DDF, i] = x if si > 0.0 else 0.0
        ed[c, R_D, i] = d
        ed[c, R_R, i] = r
        ed[c, R_Q, i] = q
        mv = mass[i] * v[i]
        ke += mv * v[i]
        dke += mv * a[i]
        pe += 0.4 * f * d - fext[i] * u[i]
        dpe += f * r - fext[i] * v[i]
    ends[c, E_KE] = 0.5 * ke
    ends[c, E_DKE] = dke
    ends[c, E_PE] = pe
    ends[c, E_DPE] = dpe


@njit(cache=True, nogil=True, inline="always")
def hermite(theta, h):
    """Weights (w0, w0', w1, w1') of the cubic Hermite interpolant p(t_0 + theta h) =
    w0 f0 + w0' f0' + w1 f1 + w1' f1' (values and time derivatives at both ends)."""
    t1 = 1.0 - theta
    return ((1.0 + 2.0 * theta) * t1 * t1, theta * t1 * t1 * h, theta * theta * (3.0 - 2.0 * theta),
            -theta * theta * t1 * h)


@njit(cache=True, nogil=True, inline="always")
def quintic(theta, h):
    """Weights (w0, w0', w0'', w1, w1', w1'') of the quintic Hermite interpolant through the
    values and first and second time derivatives at both ends of a step of size h."""
    t2 = theta * theta
    t3 = t2 * theta
    t4 = t3 * theta
    t5 = t4 * theta
    hh = h * h
    return (1.0 - 10.0 * t3 + 15.0 * t4 - 6.0 * t5, (theta - 6.0 * t3 + 8.0 * t4 - 3.0 * t5) * h,
            (0.5 * t2 - 1.5 * t3 + 1.5 * t4 - 0.5 * t5) * hh, 10.0 * t3 - 15.0 * t4 + 6.0 * t5,
            (-4.0 * t3 + 7.0 * t4 - 3.0 * t5) * h, (0.5 * t3 - t4 + 0.5 * t5) * hh)


@njit(cache=True, nogil=True, inline="always")
def _quintic_bound(y0, s0, c0, y1, s1, c1, h):
    """(an upper bound of the :func:`quintic` interpolant through (y, y', y'') at both ends of a
    step of size h over the whole step, the size of its data: 1e-9 of it exceeds any rounding of
    the interpolant's evaluation).

    The weights of y0 and y1 are non-negative and sum to 1, and each other weight keeps one sign on
    [0, 1]: theta (1 - theta)^3 (1 + 3 theta) h and -theta^3 (1 - theta) (4 - 3 theta) h, at most
    16/81 h in size; (1/2) theta^2 (1 - theta)^3 h^2 and (1/2) theta^3 (1 - theta)^2 h^2, at most
    54/3125 h^2. Hence p <= max(y0, y1) + (16/81) h (max(s0, 0) + max(-s1, 0))
    + (54/3125) h^2 (max(c0, 0) + max(c1, 0))."""
    hh = h * h
    bound = (max(y0, y1) + 0.1976 * h * (max(s0, 0.0) + max(-s1, 0.0))
             + 0.01729 * hh * (max(c0, 0.0) + max(c1, 0.0)))
    return bound, abs(y0) + abs(y1) + h * (abs(s0) + abs(s1)) + hh * (abs(c0) + abs(c1))


@njit(cache=True, nogil=True)
def quintic_at_most(y0, s0, c0, y1, s1, c1, h, level):
    """True when the :func:`quintic` interpolant through (y, y', y'') at both ends of a step of size
    h stays at or below ``level`` over the whole step, with a margin that no rounding of its
    evaluation crosses (:func:`_quintic_bound`); when every datum is 0 it evaluates to exactly 0."""
    bound, scale = _quintic_bound(y0, s0, c0, y1, s1, c1, h)
    return bound + 1e-9 * scale <= level


@njit(cache=True, nogil=True)
def force_bound(d0, r0, q0, d1, r1, q1, h, kappa, damping, kuwabara_kono):
    """An upper bound [N] of a contact's force over a step, as the probes interpolate it (the law
    at the overlap's :func:`quintic` through (delta, r, q) and the rate's :func:`hermite` through
    (r, q) at both ends, clipped, times dx / d <= 1 for an offset pair): the law, which grows with
    both, at their bounds. The rate's cubic weights of r0 and r1 are non-negative and sum to 1, the
    others theta (1 - theta)^2 h and -theta^2 (1 - theta) h, at most 4/27 h in size. A margin of
    1e-9 covers rounding: no interpolated force of the step exceeds it."""
    dm, ds = _quintic_bound(d0, r0, q0, d1, r1, q1, h)
    dm = max(dm + 1e-9 * ds, 0.0)
    rm = max(r0, r1) + 0.1482 * h * (max(q0, 0.0) + max(-q1, 0.0))
    rm = max(rm + 1e-9 * (abs(r0) + abs(r1) + h * (abs(q0) + abs(q1))), 0.0)
    sd = np.sqrt(dm)
    f = kappa * dm * sd + (kappa * damping * sd * rm if kuwabara_kono else damping * rm)
    return f * (1.0 + 1e-9)


@njit(cache=True, nogil=True)
def quintic_peak(f0, d0, e0, f1, d1, e1, h):
    """(value, offset in [0, h]) of the largest value of the quintic Hermite through (f, f', f'')
    at both ends, where its slope turns from d0 > 0 to d1 <= 0; else the larger end. Newton's
    method on p' = 0 from the vertex of the cubic through (f, f') (bisection-safe in [0, h])."""
    best, where = (f0, 0.0) if f0 >= f1 else (f1, h)
    if not (d0 > 0.0 and d1 <= 0.0):
        return best, where
    lo, hi = 0.0, 1.0
    x = 0.5
    for _ in range(40):
        w = quintic_slopes(x, h)
        p1 = w[0] * f0 + w[1] * d0 + w[2] * e0 + w[3] * f1 + w[4] * d1 + w[5] * e1
        if p1 > 0.0:
            lo = x
        else:
            hi = x
        w2 = quintic_curvatures(x, h)
        p2 = w2[0] * f0 + w2[1] * d0 + w2[2] * e0 + w2[3] * f1 + w2[4] * d1 + w2[5] * e1
        xn = x - p1 / (p2 * h) if p2 < 0.0 else 0.5 * (lo + hi)  # x in units of h
        if not (lo < xn < hi):
            xn = 0.5 * (lo + hi)
        if abs(xn - x) < 1e-13:
            x = xn
            break
        x = xn
    w = quintic(x, h)
    p = w[0] * f0 + w[1] * d0 + w[2] * e0 + w[3] * f1 + w[4] * d1 + w[5] * e1
    if p > best:
        best, where = p, x * h
    return best, where


@njit(cache=True, nogil=True, inline="always")
def quintic_slopes(theta, h):
    """d/dt of the :func:`quintic` weights."""
    t2 = theta * theta
    t3 = t2 * theta
    t4 = t3 * theta
    return ((-30.0 * t2 + 60.0 * t3 - 30.0 * t4) / h, 1.0 - 18.0 * t2 + 32.0 * t3 - 15.0 * t4,
            (theta - 4.5 * t2 + 6.0 * t3 - 2.5 * t4) * h, (30.0 * t2 - 60.0 * t3 + 30.0 * t4) / h,
            -12.0 * t2 + 28.0 * t3 - 15.0 * t4, (1.5 * t2 - 4.0 * t3 + 2.5 * t4) * h)


@njit(cache=True, nogil=True, inline="always")
def quintic_curvatures(theta, h):
    """d2/dt2 of the :func:`quintic` weights."""
    t2 = theta * theta
    t3 = t2 * theta
    hh = h * h
    return ((-60.0 * theta + 180.0 * t2 - 120.0 * t3) / hh, (-36.0 * theta + 96.0 * t2 - 60.0 * t3) / h,
            1.0 - 9.0 * theta + 18.0 * t2 - 10.0 * t3, (60.0 * theta - 180.0 * t2 + 120.0 * t3) / hh,
            (-24.0 * theta + 84.0 * t2 - 60.0 * t3) / h, 3.0 * theta - 12.0 * t2 + 10.0 * t3)


@njit(cache=True, nogil=True, inline="always")
def _quintic_coefficients(ed, b, c, h, coef, lo, hi):
    """coef[m, j] such that sum_m coef[m, j] theta^m is :func:`quintic`'s interpolant of contact
    j's force over the step from end data ``ed[b]`` to ``ed[c]`` (theta = (t - t_b) / h), for
    the contacts lo <= j < hi."""
    hh = h * h
    for j in range(lo, hi):
        quintic_row(coef, j, ed[b, R_F, j], h * ed[b, R_DF, j], 0.5 * hh * ed[b, R_DDF, j], ed[c, R_F, j],
                    h * ed[c, R_DF, j], 0.5 * hh * ed[c, R_DDF, j])


@njit(cache=True, nogil=True, inline="always")
def quintic_row(coef, j, y0, s0, e0, y1, s1, e1):
    """coef[0:6, j]: the monomial coefficients in theta of the :func:`quintic` interpolant through
    y, h y' and (h^2 / 2) y'' at a step's ends (``y0``, ``s0``, ``e0`` and ``y1``, ``s1``, ``e1``)."""
    coef[0, j] = y0
    coef[1, j] = s0
    coef[2, j] = e0
    coef[3, j] = 10.0 * (y1 - y0) - 6.0 * s0 - 4.0 * s1 - 3.0 * e0 + e1
    coef[4, j] = 15.0 * (y0 - y1) + 8.0 * s0 + 7.0 * s1 + 3.0 * e0 - 2.0 * e1
    coef[5, j] = 6.0 * (y1 - y0) - 3.0 * s0 - 3.0 * s1 - e0 + e1


#: Samples of one step evaluated together (:func:`rkn_run`): the force quintics are evaluated one
#: contact at a time over a step's samples (~20 of them at the default 100 ns on the paper's
#: chains), a loop LLVM vectorises, where a loop over the few contacts a pulse loads is not.
SAMPLE_BLOCK = 32


#: Slots of the run's accumulator ``acc`` (see :func:`rkn_run`).
A_T, A_TPREV, A_H, A_STEPS, A_HMIN, A_HMAX = 0, 1, 2, 3, 4, 5


@njit(cache=True, nogil=True)
def rkn_run(state, scratch, chain, probes, control, k_start, k_stop, acc):
    """Advance until sample ``k_stop - 1`` (samples ``interval`` seconds apart) is recorded.

    ``state`` (:class:`RknState`), ``scratch`` (:class:`RknScratch`), ``chain``
    (:class:`ChainArrays`), ``probes`` (:class:`ProbeBuffers`) and ``control``
    (:class:`StepControl`) carry the arrays and numbers named below.

    On entry and exit (u, v, a, g, sq) is the state at time acc[A_T]. The end data of the last
    two step ends (:func:`end_data`) are ``ed[c]``, ``ends[c]`` (this one) and ``ed[1 - c]``,
    ``ends[1 - c]`` (the step's start, acc[A_TPREV]), c = steps % 2; ``up``, ``vp``, ``ap`` hold
    positions, velocities and accelerations at the step's start when they are recorded; so a run
    can be cut into chunks anywhere. Steps: ``h_fixed`` [s] when > 0, else :func:`next_step`
    with ``eps`` [m/s] and ``h_max`` [s] (``sx``, ``sw``, ``st``, ``sc`` its scratch arrays).

    Sample k is interpolated in the step that holds time k ``interval``: every contact's force by
    the quintic Hermite through its value and first and second time derivatives at the step's
    ends (:func:`quintic`); where a contact opens or closes inside the step (listed in ``cross``)
    (or is within one step of doing so) the force is not smooth, and it is kappa delta^(3/2) of the
    quintic of its overlap instead (the overlap is smooth there). The samples of a step are taken
    together, up to SAMPLE_BLOCK at a time, each force quintic over them in one vectorised loop
    (every sample's value is the one a sample alone gives, bit for bit). Forces go into ``fi``
    (never below zero: a Hertz contact does not pull; their running maxima into ``fmax``), the
    contacts ``rec`` into row k of ``out_f``;
    the energies (cubic Hermite, :func:`hermite`) into ``out_ke``, ``out_pe``; velocities (cubic)
    and positions (quintic) of bodies 0..N when asked. ``peak`` = [largest wall force, its time]:
    from the quintic of the wall contact's overlap on every step where it turns down
    (:func:`quintic_peak`). ``acc`` = [time, previous step's start, last step, steps, smallest
    step, largest step]. Returns 0, or 1 when the state became non-finite.
    """
    u, v, a, g, sq, ed, ends = state
    up, vp, ap, fi, th, cross, coef, sx, sw, st, sc = scratch
    mass, inv_mass, kappa, _, d0, fext, wall_slot = chain
    rec, out_f, out_ke, out_pe, _, out_v, record_v, out_u, record_u, fmax, peak = probes
    interval, h_fixed, eps, h_max = control
    n = mass.shape[0]
    nc = fmax.shape[0]
    nrec = rec.shape[0]
    ws = wall_slot
    t = acc[A_T]
    tp = acc[A_TPREV]
    hl = acc[A_H]
    steps = int(acc[A_STEPS])
    ncross = -1  # crossing contacts of the last step: not listed yet
    # contacts lo..hi-1 hold every contact loaded at either end of the last step: the others'
    # force quintic is zero (its value and derivatives vanish at both ends, so it evaluates to 0
    # exactly), and samples evaluate this range only (a pulse loads a stretch of the chain: most
    # of a long chain is open or at rest); a range, not a list, keeps the loops vectorised
    lo, hi = 0, nc
    sb = fi.shape[1]
    k = k_start
    while k < k_stop:
        tk = k * interval
        while t < tk:
            if record_v or record_u:
                for i in range(n):
                    up[i] = u[i]
                    vp[i] = v[i]
                    ap[i] = a[i]
            h = h_fixed if h_fixed > 0.0 else next_step(u, v, kappa, d0, inv_mass, eps, hl, h_max, sx, sw, st, sc)
            step(u, v, a, g, sq, kappa, d0, fext, inv_mass, h)
            steps += 1
            c = steps % 2
            end_data(u, v, a, g, sq, kappa, d0, fext, mass, ed, ends, c)
            b = 1 - c
            dk, x = quintic_peak(ed[b, R_D, ws], ed[b, R_R, ws], ed[b, R_Q, ws], ed[c, R_D, ws], ed[c, R_R, ws],
                                 ed[c, R_Q, ws], h)
            fk = kappa[ws] * dk * np.sqrt(dk) if dk > DELTA_MIN else 0.0
            if fk > peak[0]:
                peak[0] = fk
                peak[1] = t + x
            tp = t
            t += h
            hl = h
            ncross = -1
            acc[A_HMIN] = h if h < acc[A_HMIN] else acc[A_HMIN]
            acc[A_HMAX] = h if h > acc[A_HMAX] else acc[A_HMAX]
        # --- probes at samples k..kb-1 (at most sb of them), all between the steps' ends tp < tk <= t
        c = steps % 2
        b = 1 - c
        if ncross < 0:
            # contacts whose force is not smooth over the step: open at one end, or closer to
            # opening (or to their closing) than one step at either end, where the Taylor terms
            # of the force (whose second derivative grows as delta^(-1/2)) do not hold
            ncross = 0
            lo, hi = nc, 0
            for j in range(nc):
                da, db = ed[b, R_D, j], ed[c, R_D, j]
                ca, cb = da > DELTA_MIN, db > DELTA_MIN
                if ca or cb:
                    lo = j if j < lo else lo
                    hi = j + 1
                if ca != cb or (ca and da < abs(ed[b, R_R, j]) * hl) or (cb and db < abs(ed[c, R_R, j]) * hl):
                    cross[ncross] = j
                    ncross += 1
            # the step's quintic of every loaded contact's force in powers of theta (evaluated by
            # Horner at each sample: fewer operations than the six weights)
            _quintic_coefficients(ed, b, c, hl, coef, lo, hi)
        kb = k + 1
        while kb < k_stop and kb - k < sb and kb * interval <= t:
            kb += 1
        nb = kb - k
        for m in range(nb):
            th[m] = ((k + m) * interval - tp) / hl
        # the force quintics at the samples, one contact at a time, vectorised over the samples
        # (a pulse loads a few contacts at once: a loop over them is too short to vectorise); fi[j, m]
        # is contact j at sample k + m for lo <= j < hi, the contacts loaded at either end
        for j in range(lo, hi):
            c0, c1, c2, c3, c4, c5 = coef[0, j], coef[1, j], coef[2, j], coef[3, j], coef[4, j], coef[5, j]
            for m in range(nb):
                x = th[m]
                f = c0 + x * (c1 + x * (c2 + x * (c3 + x * (c4 + x * c5))))
                fi[j, m] = f if f > 0.0 else 0.0
        if ncross > 0:
            for m in range(nb):
                q0, q0d, q0dd, q1, q1d, q1dd = quintic(th[m], hl)
                for r in range(ncross):
                    j = cross[r]
                    d = (q0 * ed[b, R_D, j] + q0d * ed[b, R_R, j] + q0dd * ed[b, R_Q, j] + q1 * ed[c, R_D, j]
                         + q1d * ed[c, R_R, j] + q1dd * ed[c, R_Q, j])
                    fi[j, m] = kappa[j] * d * np.sqrt(d) if d > DELTA_MIN else 0.0
        for j in range(lo, hi):
            fm = fmax[j]
            for m in range(nb):
                f = fi[j, m]
                fm = f if f > fm else fm
            fmax[j] = fm
        for m in range(nb):
            kk = k + m
            for r in range(nrec):
                j = rec[r]
                out_f[kk, r] = fi[j, m] if lo <= j < hi else 0.0
            w0, w0d, w1, w1d = hermite(th[m], hl)
            ke = w0 * ends[b, E_KE] + w0d * ends[b, E_DKE] + w1 * ends[c, E_KE] + w1d * ends[c, E_DKE]
            out_ke[kk] = ke
            out_pe[kk] = w0 * ends[b, E_PE] + w0d * ends[b, E_DPE] + w1 * ends[c, E_PE] + w1d * ends[c, E_DPE]
            if record_v:
                for i in range(out_v.shape[1]):
                    out_v[kk, i] = w0 * vp[i] + w0d * ap[i] + w1 * v[i] + w1d * a[i]
            if record_u:
                q0, q0d, q0dd, q1, q1d, q1dd = quintic(th[m], hl)
                for i in range(out_u.shape[1]):
                    out_u[kk, i] = q0 * up[i] + q0d * vp[i] + q0dd * ap[i] + q1 * u[i] + q1d * v[i] + q1dd * a[i]
            if not np.isfinite(ke) or not np.isfinite(g[1]):
                acc[A_T], acc[A_TPREV], acc[A_H], acc[A_STEPS] = t, tp, hl, steps
                return 1
        k = kb
    acc[A_T], acc[A_TPREV], acc[A_H], acc[A_STEPS] = t, tp, hl, steps
    return 0


# the threshold DELTA_MIN is compiled in as a constant: an edit of kernels.py recompiles the run
kernels.flush_stale_cache(rkn_run)
