"""The discrete adjoint of velocity Verlet: gradients of one scalar result with respect to every
System parameter in one reverse sweep (reverse-mode differentiation of the steps the engine took).

The result J depends on the forces of some steps (the samples it reads, the three steps around
the wall peak): its partials dJ/dF^(s)_j are the *seeds*. With the step convention of
:mod:`hertzchain.integrate.derivatives.tape`, the adjoint of step s maps the adjoints (u', v', a') of
(u_{s+1}, v_{s+1}, a_{s+1}) to those of (u_s, v_s, a_s):

    a' += h/2 v';  Fbar_j = seed_j + a'_{j+1} / m_{j+1} - a'_j / m_j;
    u'_j += Fbar_j dF_j/dw, u'_{j+1} -= Fbar_j dF_j/dw;  vpbar_j, vpbar_{j+1} likewise with dF_j/dvrel;
    vhbar = v' + h u' + vpbar;  a'_s = h/2 (vhbar + vpbar);  v'_s = vhbar;  u'_s = u',

while the parameter adjoints collect Fbar_j dF_j/dtheta_j and a'_i (net force)_i for 1/m_i
(:mod:`hertzchain.integrate.derivatives.partials`). The sweep runs group by group backwards: each group of
blocks is replayed from its checkpoint (:func:`tape.replay_group`), then its steps are
differentiated in reverse (:func:`_steps_general` and its elastic variants). Cost: about one
primal run for the replay and one for the adjoint steps, whatever the number of parameters.

The elastic-plastic law (:func:`_steps_plastic`) has a state per contact (residual overlap and
unloading stiffness, ``kernels.elastoplastic_force``) that a step's forces update: the sweep
carries the adjoints of that state backwards too, from step to step and group to group, and
ends them in kappa (the stiffness every contact starts with). Its checkpoints and replays keep
the state as well: memory 6 P doubles per checkpoint, and 5 P per step of the group replayed.

Mass-in-mass beads: body i's internal mass (position w, on a spring k_in, 1/m_in) is stepped by the
same kick-drift-kick, s_i = k_in (w_{s+1} - u_{s+1}) joining the body's net force and -s_i / m_in
being the internal mass's acceleration; :func:`inner_back` carries its adjoints (w', wv', wa')
backwards like the body's (no dashpot: no predicted velocity), and collects the gradients of
k_in (row 11) and 1/m_in (row 12).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..core.extension import EXT_IMIN, EXT_KIN
from ..core.kernels import DELTA_MIN, LAW_ELASTOPLASTIC, RUN_ELASTIC, RUN_GENERAL, RUN_PLASTIC
from .partials import aligned_partials, contact_partials, has_mount, mount_partials, plastic_contact_adjoint
from .tape import _fused, has_inner, replay_group

#: Seeds on the state rather than on a force: a seed's contact number STATE_U + i (STATE_V + i)
#: is the position (velocity) of slot i after the step (``differentiate.Seeds``).
STATE_U = 1 << 30
STATE_V = 2 << 30


@njit(cache=True, nogil=True, inline="always")
def _take_seeds(s, p, fb, ub, vb, seed_step, seed_contact, seed_w):
    """Add the seeds of step ``s`` (those just below pointer ``p``) into ``fb`` (a force's) or into
    the adjoints ``ub``, ``vb`` of the state after the step (a position's or a velocity's);
    returns the new pointer."""
    q = p
    while q > 0 and seed_step[q - 1] == s:
        q -= 1
        c = seed_contact[q]
        if c >= STATE_V:
            vb[c - STATE_V] += seed_w[q]
        elif c >= STATE_U:
            ub[c - STATE_U] += seed_w[q]
        else:
            fb[c] += seed_w[q]
    return q


@njit(cache=True, nogil=True, inline="always")
def _clear_seeds(p, q, fb, seed_contact):
    """Zero the entries of ``fb`` that the force seeds q..p-1 wrote."""
    while p > q:
        p -= 1
        if seed_contact[p] < STATE_U:
            fb[seed_contact[p]] = 0.0


@njit(cache=True, nogil=True, inline="always")
def _force_adjoint(j, hh, fb, ab, ab1, vb, vb1, inv_mass, im1):
    """Fbar_j = seed_j + a'_{j+1} / m_{j+1} - a'_j / m_j (module docstring), a'_{s+1} formed where it
    is read (a' + h/2 v'); ``ab1``, ``vb1``, ``im1`` are the arrays shifted by one slot."""
    return fb[j] + im1[j] * (ab1[j] + hh * vb1[j]) - inv_mass[j] * (ab[j] + hh * vb[j])


@njit(cache=True, nogil=True, inline="always")
def _bodies_back(h, ub, vb, ab, fs, fs1, wb, wb1, rb, rb1, inv_mass, fext, ginv, gfext, damped, loaded):
    """The bodies' part of a step's adjoint (module docstring): 1/m_i and f_ext,i collect a'_{s+1,i}
    times the net force and 1/m_i; u' takes the contacts' position adjoints ``wb``; with
    ``damped`` the velocity adjoints ``rb`` enter vhbar and a'_s; then (u', v', a') become those of
    step s. ``fs1``, ``wb1``, ``rb1`` are ``fs``, ``wb``, ``rb`` shifted by one slot. ``damped`` and
    ``loaded`` (f_ext and its gradient kept) are constants at every call: after inlining, LLVM
    drops the branch not taken."""
    hh = 0.5 * h
    for i in range(ab.shape[0]):
        abi = ab[i] + hh * vb[i]
        if loaded:
            ginv[i] += abi * (fs[i] - fs1[i] + fext[i])
            gfext[i] += abi * inv_mass[i]
        else:
            ginv[i] += abi * (fs[i] - fs1[i])
        ub[i] += wb1[i] - wb[i]
        if damped:
            vpb = rb1[i] - rb[i]
            vh = vb[i] + h * ub[i] + vpb
            ab[i] = hh * (vh + vpb)
        else:
            vh = vb[i] + h * ub[i]
            ab[i] = hh * vh
        vb[i] = vh


@njit(cache=True, nogil=True, inline="always")
def inner_back(h, ustore, wstore, sl, ub, vb, ab, wub, wvb, wab, inv_mass, ext, grad):
    """The internal masses' part of a step's adjoint (module docstring), before the bodies' own
    (:func:`_bodies_back`, which then reads the u' this adds): with a'_{s+1} = a' + h/2 v' and
    wa'_{s+1} = wa' + h/2 wv' (formed here), the spring's s' = a'_{s+1} / m - wa'_{s+1} / m_in goes to
    u' (-k_in s'), w' (+k_in s') and k_in (s' (w - u)); 1/m and 1/m_in collect a'_{s+1} s and
    -wa'_{s+1} s; then (w', wv', wa') become those of the step before. ``ustore[sl]`` and
    ``wstore[sl]`` hold the positions the step's forces were taken at (h = 0: the state at t = 0,
    whose accelerations are a function of the positions only)."""
    hh = 0.5 * h
    for i in range(ab.shape[0]):
        k = ext[i, EXT_KIN]
        if k == 0.0:
            continue
        x = wstore[sl, i] - ustore[sl, i]
        sp = k * x
        abi = ab[i] + hh * vb[i]
        wabi = wab[i] + hh * wvb[i]
        sbar = abi * inv_mass[i] - wabi * ext[i, EXT_IMIN]
        grad[7, i] += abi * sp
        grad[11, i] += sbar * x
        grad[12, i] -= wabi * sp
        ub[i] -= k * sbar
        wub[i] += k * sbar
        wvh = wvb[i] + h * wub[i]
        wab[i] = hh * wvh
        wvb[i] = wvh


def _general_steps(plastic: bool):
    """The reverse steps of the general forces, compiled apart for the hand-written laws and for the
    elastic-plastic law (``plastic``, a constant of the closure: Numba prunes the branch not taken)."""

    @njit(cache=True, nogil=True)
    def steps(nsteps, ustore, vpstore, hstore, step0, ub, vb, ab, fb, fs, wb, rb, inv_mass, kappa, damping, d0, de,
              dx0, rsum, fext, law, seed_step, seed_contact, seed_w, ptr, grad, ext, inn, pl):
        """Steps ``step0 + nsteps - 1`` down to ``step0`` in reverse, general forces; returns the seed
        pointer.

        ``grad`` rows: kappa, damping, d0, de, dx0, rsum, fext, inv_mass, then the linear spring and
        dashpot of every contact (``ext``: a protected body's mount; an empty ``ext`` has none), the
        yield overlaps (row 10); with mass-in-mass beads, ``inn`` = (wstore, wub, wvb, wab, inner)
        (:func:`inner_back`). The elastic-plastic law (``plastic``, :func:`partials.plastic_contact_adjoint`,
        offset beads included) reads ``pl`` = (pstore: the state (dmax, dres, kres) each step started
        from; sb (2, P): the adjoints of the state (dres, kres) after the step being differentiated,
        carried backwards from step to step and group to group; dyield).
        Seeds are sorted by step; ``ptr`` is one past the last seed not consumed yet. ``fb`` (zero on
        entry and exit) receives a step's seeds; ``fs, wb, rb`` are scratch (size P + 1, slot 0 zero).
        The loops read shifted views (``x1[j]`` for x[j + 1], made once) so that LLVM vectorises them,
        the adjoint of a_{s+1}, a' + h/2 v', is formed where it is read, and the stored step is indexed
        (a row view per step costs two atomic reference counts). The kinds of steps (these,
        :func:`_steps_dissipative`, :func:`_steps_static`, :func:`_steps_plain`) are compiled apart:
        one function holding them all compiled each into slower code.
        """
        n = ab.shape[0]
        p = ptr
        gk, gdamp, gd0, gde, gdx0, grs, gfext, ginv = (grad[0], grad[1], grad[2], grad[3], grad[4], grad[5], grad[6],
                                                       grad[7])
        gkl, gcl, gdy = grad[8], grad[9], grad[10]
        wstore, wub, wvb, wab, inner = inn
        pstore, sb, dyield = pl
        ab1, vb1, im1, fs1, wb1, rb1 = ab[1:], vb[1:], inv_mass[1:], fs[1:], wb[1:], rb[1:]
        m = n - 1
        linear = ext.shape[0] > 0
        for sl in range(nsteps - 1, -1, -1):
            h = hstore[sl]
            hh = 0.5 * h
            q = _take_seeds(step0 + sl, p, fb, ub, vb, seed_step, seed_contact, seed_w)
            for j in range(m):
                fbar = _force_adjoint(j, hh, fb, ab, ab1, vb, vb1, inv_mass, im1)
                if plastic:  # the adjoints of w, vrel, the parameters and the state in, at once
                    f, wbar, rbar, kbar, abar, g0, gdd, gx, gr, dybar, sb[0, j], sb[1, j] = plastic_contact_adjoint(
                        ustore[sl, j], ustore[sl, j + 1], vpstore[sl, j], vpstore[sl, j + 1], kappa[j], damping[j],
                        d0[j], de[j], dx0[j], rsum[j], dyield[j], pstore[0, sl, j], pstore[1, sl, j],
                        pstore[2, sl, j], fbar, sb[0, j], sb[1, j])
                    gdy[j] += dybar
                else:  # the partials, times the force's adjoint
                    f, gw, gv, gkk, ga, g0, gdd, gx, gr = contact_partials(
                        ustore[sl, j], ustore[sl, j + 1], vpstore[sl, j], vpstore[sl, j + 1], kappa[j], damping[j],
                        d0[j], de[j], dx0[j], rsum[j], law)
                    wbar, rbar, kbar, abar = fbar * gw, fbar * gv, fbar * gkk, fbar * ga
                    g0, gdd, gx, gr = fbar * g0, fbar * gdd, fbar * gx, fbar * gr
                if linear and has_mount(ext, j):  # the mount's spring and dashpot (extension.forces_linear)
                    fl, kl, cl, dl, rl = mount_partials(ext, j, ustore[sl, j], ustore[sl, j + 1], vpstore[sl, j],
                                                        vpstore[sl, j + 1], d0[j])
                    f += fl
                    wbar += fbar * kl
                    rbar += fbar * cl
                    g0 += fbar * kl
                    gkl[j] += fbar * dl
                    gcl[j] += fbar * rl
                fs1[j] = f
                wb1[j] = wbar
                rb1[j] = rbar
                gk[j] += kbar
                gdamp[j] += abar
                gd0[j] += g0
                gde[j] += gdd
                gdx0[j] += gx
                grs[j] += gr
            if inner:
                inner_back(h, ustore, wstore, sl, ub, vb, ab, wub, wvb, wab, inv_mass, ext, grad)
            _bodies_back(h, ub, vb, ab, fs, fs1, wb, wb1, rb, rb1, inv_mass, fext, ginv, gfext, True, True)
            _clear_seeds(p, q, fb, seed_contact)
            p = q
        return p

    return steps


_steps_general = _general_steps(False)
_steps_plastic = _general_steps(True)


@njit(cache=True, nogil=True)
def _steps_dissipative(nsteps, ustore, vpstore, hstore, step0, ub, vb, ab, fb, fs, wb, rb, inv_mass, kappa, damping,
                       d0, fext, law, seed_step, seed_contact, seed_w, ptr, grad):
    """:func:`_steps_general` for an aligned viscoelastic or dashpot chain without a protected body
    (the chains ``kernels._verlet_run`` steps with its fused dissipative step): the partials of
    Kuwabara-Kono's and the dashpot's partials (``partials.law_partials``) written out with selects, so that
    LLVM vectorises the contact loop."""
    n = ab.shape[0]
    p = ptr
    gk, gdamp, gd0, gfext, ginv = grad[0], grad[1], grad[2], grad[6], grad[7]
    ab1, vb1, im1, fs1, wb1, rb1 = ab[1:], vb[1:], inv_mass[1:], fs[1:], wb[1:], rb[1:]
    m = n - 1
    for sl in range(nsteps - 1, -1, -1):
        h = hstore[sl]
        hh = 0.5 * h
        q = _take_seeds(step0 + sl, p, fb, ub, vb, seed_step, seed_contact, seed_w)
        for j in range(m):
            f, fd, fr, fk, fa = aligned_partials(ustore[sl, j] - ustore[sl, j + 1] + d0[j],
                                                 vpstore[sl, j] - vpstore[sl, j + 1], kappa[j], damping[j], law)
            fbar = _force_adjoint(j, hh, fb, ab, ab1, vb, vb1, inv_mass, im1)
            fs1[j] = f
            wb1[j] = fbar * fd
            rb1[j] = fbar * fr
            gk[j] += fbar * fk
            gdamp[j] += fbar * fa
            gd0[j] += fbar * fd
        _bodies_back(h, ub, vb, ab, fs, fs1, wb, wb1, rb, rb1, inv_mass, fext, ginv, gfext, True, True)
        _clear_seeds(p, q, fb, seed_contact)
        p = q
    return p


@njit(cache=True, nogil=True)
def _steps_static(nsteps, ustore, hstore, step0, ub, vb, ab, fb, fs, wb, inv_mass, kappa, d0, fext, seed_step,
                  seed_contact, seed_w, ptr, grad):
    """:func:`_steps_general` for an aligned elastic chain under a static load (precompression):
    F_j = kappa_j delta_j^(3/2) (kernels.step_elastic), d0 and f_ext differentiated too."""
    n = ab.shape[0]
    p = ptr
    gk, gd0, gfext, ginv = grad[0], grad[2], grad[6], grad[7]
    ab1, vb1, im1, fs1, wb1 = ab[1:], vb[1:], inv_mass[1:], fs[1:], wb[1:]
    m = n - 1
    for sl in range(nsteps - 1, -1, -1):
        h = hstore[sl]
        hh = 0.5 * h
        q = _take_seeds(step0 + sl, p, fb, ub, vb, seed_step, seed_contact, seed_w)
        for j in range(m):
            d = ustore[sl, j] - ustore[sl, j + 1] + d0[j]
            d = d if d > DELTA_MIN else 0.0
            sd = np.sqrt(d)
            fbar = _force_adjoint(j, hh, fb, ab, ab1, vb, vb1, inv_mass, im1)
            fs1[j] = kappa[j] * d * sd
            gw = 1.5 * kappa[j] * sd
            wb1[j] = fbar * gw
            gk[j] += fbar * d * sd
            gd0[j] += fbar * gw
        _bodies_back(h, ub, vb, ab, fs, fs1, wb, wb1, fs, fs1, inv_mass, fext, ginv, gfext, False, True)
        _clear_seeds(p, q, fb, seed_contact)
        p = q
    return p


@njit(cache=True, nogil=True)
def _steps_plain(nsteps, ustore, hstore, step0, ub, vb, ab, fb, fs, wb, inv_mass, kappa, seed_step, seed_contact,
                 seed_w, ptr, grad):
    """:func:`_steps_static` without a static load (d0 = f_ext = 0: their gradients are not kept)."""
    n = ab.shape[0]
    p = ptr
    gk, ginv = grad[0], grad[7]
    ab1, vb1, im1, fs1, wb1 = ab[1:], vb[1:], inv_mass[1:], fs[1:], wb[1:]
    m = n - 1
    for sl in range(nsteps - 1, -1, -1):
        h = hstore[sl]
        hh = 0.5 * h
        q = _take_seeds(step0 + sl, p, fb, ub, vb, seed_step, seed_contact, seed_w)
        for j in range(m):
            d = ustore[sl, j] - ustore[sl, j + 1]
            d = d if d > DELTA_MIN else 0.0
            sd = np.sqrt(d)
            fbar = _force_adjoint(j, hh, fb, ab, ab1, vb, vb1, inv_mass, im1)
            fs1[j] = kappa[j] * d * sd
            wb1[j] = fbar * 1.5 * kappa[j] * sd
            gk[j] += fbar * d * sd
        _bodies_back(h, ub, vb, ab, fs, fs1, wb, wb1, fs, fs1, inv_mass, fs, ginv, ginv, False, False)
        _clear_seeds(p, q, fb, seed_contact)
        p = q
    return p


@njit(cache=True, nogil=True)
def _adjoint_initial(u0, v0, ub, vb, ab, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, law, general,
                     seed_step, seed_contact, seed_w, ptr, grad, ext, dyield, sb, inn):
    """The state at t = 0: a_0 = (F(u_0, v_0)_{i-1} - F(u_0, v_0)_i + f_ext,i) / m_i (seeds of step -1).

    The elastic-plastic law's forces at t = 0 start its state from (0, 0, kappa) (``layout.pack``):
    ``sb`` holds the adjoints of the state they leave, and the stiffness's flows into kappa's.
    ``inn`` = (w0, wub, wvb, wab, inner): the internal masses' positions at t = 0 (1, P) and adjoints."""
    n = ab.shape[0]
    fb = np.zeros(n)
    p = _take_seeds(-1, ptr, fb, ub, vb, seed_step, seed_contact, seed_w)
    fs = np.zeros(n + 1)
    wb = np.zeros(n + 1)
    rb = np.zeros(n + 1)
    plastic = general and law == LAW_ELASTOPLASTIC
    for j in range(n - 1):
        fbar = fb[j] + inv_mass[j + 1] * ab[j + 1] - inv_mass[j] * ab[j]
        if plastic:  # as _steps_plastic, from the state (0, 0, kappa)
            f, wbar, rbar, kbar, abar, g0, gdd, gx, gr, dybar, _, kresb = plastic_contact_adjoint(
                u0[j], u0[j + 1], v0[j], v0[j + 1], kappa[j], damping[j], d0[j], de[j], dx0[j], rsum[j], dyield[j],
                0.0, 0.0, kappa[j], fbar, sb[0, j], sb[1, j])
            grad[0, j] += kbar + kresb  # the stiffness the state starts from is kappa
            grad[1, j] += abar
            grad[2, j] += g0
            grad[3, j] += gdd
            grad[4, j] += gx
            grad[5, j] += gr
            grad[10, j] += dybar
        else:
            f, gw, gv, gkk, ga, g0, gdd, gx, gr = contact_partials(u0[j], u0[j + 1], v0[j], v0[j + 1], kappa[j],
                                                                   damping[j], d0[j], de[j], dx0[j], rsum[j],
                                                                   law if general else 0)
            wbar = fbar * gw
            rbar = fbar * gv
            grad[0, j] += fbar * gkk
            grad[1, j] += fbar * ga
            grad[2, j] += fbar * g0
            grad[3, j] += fbar * gdd
            grad[4, j] += fbar * gx
            grad[5, j] += fbar * gr
        if has_mount(ext, j):
            fl, kl, cl, dl, rl = mount_partials(ext, j, u0[j], u0[j + 1], v0[j], v0[j + 1], d0[j])
            f += fl
            wbar += fbar * kl
            rbar += fbar * cl
            grad[2, j] += fbar * kl
            grad[8, j] += fbar * dl
            grad[9, j] += fbar * rl
        fs[j + 1] = f
        wb[j + 1] = wbar
        rb[j + 1] = rbar
    initial_bodies_back(u0, ub, vb, ab, fs, wb, rb, inv_mass, fext, grad, ext, inn)
    return p


@njit(cache=True, nogil=True, inline="always")
def initial_bodies_back(u0, ub, vb, ab, fs, wb, rb, inv_mass, fext, grad, ext, inn):
    """The bodies' part of the adjoint of the state at t = 0 (a_0 a function of u_0 and v_0): 1/m
    and f_ext collect a'_0 times the net force and 1/m, u' and v' the contacts' adjoints ``wb``,
    ``rb`` (and the internal masses', ``inn`` = (w0, wub, wvb, wab, inner): :func:`inner_back` at
    h = 0)."""
    w0, wub, wvb, wab, inner = inn
    if inner:
        inner_back(0.0, u0.reshape((1, u0.shape[0])), w0, 0, ub, vb, ab, wub, wvb, wab, inv_mass, ext, grad)
    for i in range(ab.shape[0]):
        grad[6, i] += ab[i] * inv_mass[i]
        grad[7, i] += ab[i] * (fs[i] - fs[i + 1] + fext[i])
        ub[i] += wb[i + 1] - wb[i]
        vb[i] += rb[i + 1] - rb[i]


@njit(cache=True, nogil=True)
def group_starts(ns_log, group, n_blocks):
    """The global number of the first step of every group of ``group`` blocks (and, last, the
    run's steps), from the taped step counts ``ns_log``."""
    n_groups = (n_blocks + group - 1) // group
    starts = np.zeros(n_groups + 1, dtype=np.int64)
    for b in range(n_blocks):
        starts[b // group + 1] += ns_log[b]
    for i in range(n_groups):
        starts[i + 1] += starts[i]
    return starts


def sweep_kind(law: int, general: bool) -> int:
    """The kind of reverse sweep (``kernels.RUN_ELASTIC``, ``RUN_GENERAL`` or ``RUN_PLASTIC``; a
    protected body or mass-in-mass beads step with the general loop) a system needs."""
    if not general:
        return RUN_ELASTIC
    return RUN_PLASTIC if law == LAW_ELASTOPLASTIC else RUN_GENERAL


@njit(cache=True, nogil=True, inline="always")
def _reverse_sweep(kind, ckpt, ns_log, group, n_blocks, block, u0, v0, ub, vb, ab, inv_mass, kappa, damping, d0, de,
                   dx0, rsum, fext, law, general, wall_slot, rest):
    """The whole reverse sweep: every group replayed and differentiated, last group first, then
    the initial state. On entry ``ub, vb, ab`` hold the seeds on the final state (usually zero);
    on exit the adjoints of (u_0, v_0, a_0), and ``grad`` the parameter gradients (rows as in
    :func:`_steps_general`; row 10: the yield overlaps of the elastic-plastic law). ``max_rows``:
    most steps in one group. With the elastic-plastic law the checkpoints hold its state too
    (rows 3-5), and the adjoints of its state (``sb``, (2, P): residual overlap and unloading
    stiffness; on entry those of the final state, for a result that reads it, as the plastic work)
    cross from group to group. ``w0`` (1, P): the internal masses' positions at t = 0 (mass-in-mass
    beads; their adjoints too cross from group to group). Inlined with ``kind`` (:func:`sweep_kind`)
    a constant into :func:`reverse_sweep_of`'s three sweeps, each compiling only its own steps (an
    elastic chain's first sweep compiled the general and elastic-plastic steps too). ``rest``: the
    arguments (seed_step, seed_contact, seed_w, grad, max_rows, ext, dyield, sb, w0), in a tuple
    (a call of more than 30 arguments compiles to ``f(*args)``, which Numba does not inline)."""
    seed_step, seed_contact, seed_w, grad, max_rows, ext, dyield, sb, w0 = rest
    expected = RUN_ELASTIC if not general else (RUN_PLASTIC if law == LAW_ELASTOPLASTIC else RUN_GENERAL)
    if expected != kind:
        raise ValueError("reverse_sweep: this compiled sweep differentiates another kind of model (sweep_kind)")
    n = ab.shape[0]
    u = np.zeros(n + 1)
    v = np.zeros(n + 1)
    a = np.zeros(n)
    g = np.zeros(n + 1)
    plastic = general and law == LAW_ELASTOPLASTIC
    dmax = np.zeros(n)  # the elastic-plastic state: scratch of the replays (from the checkpoints)
    dres = np.zeros(n)
    kres = kappa.copy()
    ustore = np.zeros((max_rows, n))
    vpstore = np.zeros((max_rows if general else 1, n))
    hstore = np.zeros(max_rows)
    pstore = np.zeros((3, max_rows if plastic else 1, n if plastic else 1))
    fb = np.zeros(n)
    fs = np.zeros(n + 1)
    wb = np.zeros(n + 1)
    rb = np.zeros(n + 1)
    inner = has_inner(ext)
    wstore = np.zeros((max_rows if inner else 1, n))
    wub, wvb, wab = np.zeros(n), np.zeros(n), np.zeros(n)
    n_groups = (n_blocks + group - 1) // group
    static = False
    for i in range(n):
        static = static or d0[i] != 0.0 or fext[i] != 0.0
    starts = group_starts(ns_log, group, n_blocks)
    p = seed_step.shape[0]
    fused = _fused(general, law, de, ext.shape[0] > 0)
    for gi in range(n_groups - 1, -1, -1):
        b0 = gi * group
        b1 = min(b0 + group, n_blocks)
        rows = replay_group(ckpt[gi], u, v, a, g, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, law, general,
                            wall_slot, ns_log, b0, b1, block, (ustore, vpstore, hstore, pstore, wstore), dyield, dmax,
                            dres, kres, ext, ext.shape[0] > 0)
        if kind == RUN_PLASTIC:
            p = _steps_plastic(rows, ustore, vpstore, hstore, starts[gi], ub, vb, ab, fb, fs, wb, rb, inv_mass, kappa,
                               damping, d0, de, dx0, rsum, fext, law, seed_step, seed_contact, seed_w, p, grad, ext,
                               (wstore, wub, wvb, wab, inner), (pstore, sb, dyield))
        elif kind == RUN_GENERAL and fused:
            p = _steps_dissipative(rows, ustore, vpstore, hstore, starts[gi], ub, vb, ab, fb, fs, wb, rb, inv_mass,
                                   kappa, damping, d0, fext, law, seed_step, seed_contact, seed_w, p, grad)
        elif kind == RUN_GENERAL:
            p = _steps_general(rows, ustore, vpstore, hstore, starts[gi], ub, vb, ab, fb, fs, wb, rb, inv_mass, kappa,
                               damping, d0, de, dx0, rsum, fext, law, seed_step, seed_contact, seed_w, p, grad, ext,
                               (wstore, wub, wvb, wab, inner), (pstore, sb, dyield))
        elif static:
            p = _steps_static(rows, ustore, hstore, starts[gi], ub, vb, ab, fb, fs, wb, inv_mass, kappa, d0, fext,
                              seed_step, seed_contact, seed_w, p, grad)
        else:
            p = _steps_plain(rows, ustore, hstore, starts[gi], ub, vb, ab, fb, fs, wb, inv_mass, kappa, seed_step,
                             seed_contact, seed_w, p, grad)
    return _adjoint_initial(u0, v0, ub, vb, ab, inv_mass, kappa, damping, d0, de, dx0, rsum, fext, law, general,
                            seed_step, seed_contact, seed_w, p, grad, ext, dyield, sb, (w0, wub, wvb, wab, inner))


@njit(cache=True, nogil=True)
def _sweep_elastic(ckpt, ns_log, group, n_blocks, block, u0, v0, ub, vb, ab, inv_mass, kappa, damping, d0, de, dx0,
                   rsum, fext, law, general, wall_slot, rest):
    return _reverse_sweep(RUN_ELASTIC, ckpt, ns_log, group, n_blocks, block, u0, v0, ub, vb, ab, inv_mass, kappa,
                          damping, d0, de, dx0, rsum, fext, law, general, wall_slot, rest)


@njit(cache=True, nogil=True)
def _sweep_general(ckpt, ns_log, group, n_blocks, block, u0, v0, ub, vb, ab, inv_mass, kappa, damping, d0, de, dx0,
                   rsum, fext, law, general, wall_slot, rest):
    return _reverse_sweep(RUN_GENERAL, ckpt, ns_log, group, n_blocks, block, u0, v0, ub, vb, ab, inv_mass, kappa,
                          damping, d0, de, dx0, rsum, fext, law, general, wall_slot, rest)


@njit(cache=True, nogil=True)
def _sweep_plastic(ckpt, ns_log, group, n_blocks, block, u0, v0, ub, vb, ab, inv_mass, kappa, damping, d0, de, dx0,
                   rsum, fext, law, general, wall_slot, rest):
    return _reverse_sweep(RUN_PLASTIC, ckpt, ns_log, group, n_blocks, block, u0, v0, ub, vb, ab, inv_mass, kappa,
                          damping, d0, de, dx0, rsum, fext, law, general, wall_slot, rest)


def reverse_sweep_of(law: int, general: bool):
    """The compiled reverse sweep for a system's law code and ``System.general``: called with
    :func:`_reverse_sweep`'s arguments after ``kind``."""
    return (_sweep_elastic, _sweep_general, _sweep_plastic)[sweep_kind(law, general)]
