"""Engines generated from a registered contact law's scalar functions (:mod:`hertzchain.laws`).

For a law with ``generated=True`` (the power law, Hunt-Crossley, every user's law),
:func:`law_kernels` builds, once per law and process, compiled functions that close over the
law's ``force``/``state``/``energy``/``partials`` (Numba inlines the jitted closures):

- ``contact(ui, uj, vi, vj, kappa, damping, d0, de, dx0, rsum, state)``: one contact's axial
  force, dissipated power and new state (``forces`` loops over it; the threaded engine,
  :mod:`hertzchain.integrate.drivers.threaded_laws`, compiles it into its thread function);
- ``forces(u, v, kappa, damping, d0, de, dx0, rsum, g, state)``: every contact's force, written
  as ``kernels.forces_general`` writes them (the same overlap geometry, misaligned pairs
  included, the same d == 0 convention), the law's state updated in place; returns the
  dissipated power (F - F(rate = 0)) d(delta)/dt [W];
- ``runs``: two compiled runs, for models without and with the extension (:func:`run_kernel`
  picks one), each :func:`hertzchain.integrate.core.kernels._verlet_run` with the same arguments
  after its ``kind`` (the typed
  structures of :mod:`.structures`, a protected body's and mass-in-mass beads' extension
  included: :func:`~.extension.extended_steps` around the law's force pass, its bound
  :func:`~.extension.extension_stride` added to the law's) and the same kick-drift-kick steps, adaptive
  step controller and probes (the law's per-contact state lives in the ``dmax`` slots; ``kappa``
  holds the law's stiffness k, ``damping`` its parameter p);
- ``energy(u, kappa, damping, d0, de, dx0, rsum, fext)``: the stored energy minus the work of the
  external forces [J];
- ``stride``: the adaptive step's bound (below).

The step's accuracy bound uses the law's partials: tangent stiffness dF/d delta and damping
dF/d rate at an upper estimate of each overlap, as ``kernels.required_stride`` does for Hertz.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .disk_cache import INTEGRATE, files_digest, function_files_digest, on_disk
from .extension import EXT_IMIN, EXT_KIN, EXT_W, close_sample, extended_steps, extension_stride, internal_acceleration
from . import kernels
from .kernels import DELTA_MIN, _adapt_stride, kinetic_energy
from .primitives import _track_peak, kick, open_block, predict, total

_CACHE: dict = {}
#: The package's files compiled into a generated law's loops (with the law's own file: their
#: on-disk cache key, :mod:`.disk_cache`).
_COMPILED_IN = ("core/generated.py", "core/kernels.py", "core/primitives.py", "core/energies.py",
                "core/extension.py", "core/fused.py")


def law_kernels(code: int):
    """(forces, runs, energy, stride, contact) compiled for the law of engine code ``code``; built on
    first use (``runs``: the runs without and with the extension; ``stride``: the adaptive step's
    steps per block, which the sensitivity engines' taped run,
    :mod:`hertzchain.integrate.derivatives.law_derivatives`, takes as the run does; ``contact``: one
    contact of ``forces``, the threaded engine's force, :mod:`hertzchain.integrate.drivers.threaded_laws`)."""
    from ...laws import law_of_code
    from ...laws.spec import compiled

    spec = law_of_code(code)
    key = (code, id(spec.force), id(spec.state), id(spec.energy), id(spec.partials), spec.dissipative,
           spec.constant_parameters, spec.state_size)
    if key not in _CACHE:
        force, state, stored, partials = (compiled(f) for f in (spec.force, spec.state, spec.energy, spec.partials))
        inverse = compiled(spec.overlap_at_energy) if spec.overlap_at_energy is not None else _bisect(stored)
        built = _build(force, state, stored, partials, inverse, spec.dissipative, spec.constant_parameters,
                       spec.state_size > 0)
        # The loops Python calls, cached on disk under the text of everything compiled into them:
        # the law's own file(s) and this package's (a law without a source file: in memory only)
        law_files = function_files_digest(force, state, stored, partials, spec.overlap_at_energy)
        if law_files is not None:
            sources = law_files + files_digest(*(INTEGRATE / name for name in _COMPILED_IN))
            variant = ("generated", spec.name, spec.dissipative, spec.overlap_at_energy is not None,
                       spec.constant_parameters, spec.state_size)
            forces, runs, energy, stride, contact = built
            runs = tuple(on_disk(r, *variant, "run", extended, sources=sources) for extended, r in enumerate(runs))
            built = (on_disk(forces, *variant, "forces", sources=sources), runs,
                     on_disk(energy, *variant, "energy", sources=sources),
                     on_disk(stride, *variant, "stride", sources=sources), contact)
        _CACHE[key] = built
    return _CACHE[key]


def bisection(stored):
    """The overlap storing energy e by bisection of a law's ``energy`` (increasing in d), as plain
    Python closing over ``stored``: the caller compiles it for its target (CPU here, a CUDA device
    function in :mod:`hertzchain.integrate.cuda.generated`)."""
    def inverse(e, k, p):
        hi = 1e-9
        while stored(hi, k, p) < e and hi < 1.0:
            hi *= 2.0
        lo = 0.0
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if stored(mid, k, p) < e:
                lo = mid
            else:
                hi = mid
        return hi
    return inverse


def _bisect(stored):
    """:func:`bisection` compiled for the CPU."""
    return njit(nogil=True)(bisection(stored))


def _build(force, update, stored, partials, inverse, dissipative, constants=(), stateful=True):
    uses_rate = dissipative or stateful
    @njit(nogil=True)
    def overlap(u, d0, de, dx0, rsum, j):
        if de[j] != 0.0:
            dx = dx0[j] - (u[j] - u[j + 1])
            dist = np.sqrt(dx * dx + de[j] * de[j])
            return rsum[j] - dist, dx / dist
        return u[j] - u[j + 1] + d0[j], 1.0

    def make_contact(aligned):
        """``contact`` below; with ``aligned`` (a compile-time constant) for chains without
        offsets, whose step then has no geometry branch per contact (the untaken branch alone
        made a step of the generated loop ~2x slower)."""
        @njit(nogil=True, inline="always")
        def contact(ui, uj, vi, vj, kappa, damping, d0, de, dx0, rsum, state):
            return _contact(ui, uj, vi, vj, kappa, damping, d0, de, dx0, rsum, state, aligned)
        return contact

    @njit(nogil=True, inline="always")
    def _contact(ui, uj, vi, vj, kappa, damping, d0, de, dx0, rsum, state, aligned):
        """One contact of ``forces`` (bodies at ``ui``, ``uj`` [m] moving at ``vi``, ``vj`` [m/s]):
        (axial force [N], dissipated power [W], new state). Shared with the threaded engine.

        Branch-free (an open contact, d < 0, and a slot without contact, kappa = 0, are selected
        to 0 and their state kept; the law is evaluated at d = 0 there, which it must take
        anyway), so that LLVM vectorises the loops over the contacts: with early returns the
        pass stayed scalar (Hunt-Crossley ~1.6x its bare loop on 300 beads)."""
        if not aligned and de != 0.0:
            dx = dx0 - (ui - uj)
            dist = np.sqrt(dx * dx + de * de)
            d, c = rsum - dist, dx / dist
        else:
            d, c = ui - uj + d0, 1.0
        rate = c * (vi - vj)
        on = kappa != 0.0  # no contact (free end, padding)
        new = update(d, rate, kappa, damping, state)
        state = new if on else state
        on = on & (d >= 0.0)
        dd = d if d > DELTA_MIN else 0.0
        f = force(dd, rate, kappa, damping, state)
        f = f if f > 0.0 else 0.0
        f = f if on else 0.0
        if not dissipative:  # a compile-time constant: a law declared without dissipation does not
            return c * f, 0.0, state  # depend on the rate (F - F(rate = 0) = 0): one force, not two
        fel = force(dd, 0.0, kappa, damping, state)
        return c * f, ((f - fel) * rate if on else 0.0), state

    contact = make_contact(False)

    def make_forces_into(cf):
        @njit(nogil=True, inline="always")
        def forces_into(u, v, kappa, damping, d0, de, dx0, rsum, g, state, pw):
            """``forces`` with each contact's dissipated power in ``pw`` instead of their sum."""
            for j in range(kappa.shape[0]):
                g[j + 1], pw[j], state[j] = cf(u[j], u[j + 1], v[j], v[j + 1], kappa[j], damping[j], d0[j], de[j],
                                               dx0[j], rsum[j], state[j])
        return forces_into

    forces_into = make_forces_into(contact)

    def make_step(constant=math.nan):
        fixed = not math.isnan(constant)  # every contact's parameter is ``constant``, a compile-time constant
        cf = make_contact(True)

        @njit(nogil=True, inline="always")
        def step(u, v, vp, a, g, pw, kappa, damping, d0, fext, inv_mass, state, dt, half, last):
            """One step of an aligned chain in one pass: each contact's force at the predicted
            velocities ``vp`` (its power into ``pw``), then the kick and drift of the body on its
            left (or, when ``last``, the closing half kick), as ``kernels.step_dissipative``: the
            numbers of ``forces_into`` then :func:`~hertzchain.integrate.core.primitives.kick`
            (the left contact's force carried in ``fprev``), ~1.4x faster than the two passes.
            With ``fixed``, the law compiled with its parameter the constant ``constant``: its
            branches on the parameter fold (the power law's n == 1.5 at run time, a select
            computing both d sqrt(d) and d**n in every contact of the vectorised loop, made a
            contact ~9 instead of ~0.6 ns)."""
            fprev = 0.0
            for i in range(a.shape[0]):
                p = constant if fixed else damping[i]
                # a law without dissipation and state never reads the rate: no predicted
                # velocities, powers or state to stream (compile-time constants)
                vl, vr = (vp[i], vp[i + 1]) if uses_rate else (0.0, 0.0)
                f, pi, si = cf(u[i], u[i + 1], vl, vr, kappa[i], p, d0[i], 0.0, 0.0, 0.0, state[i] if stateful else 0.0)
                if dissipative:
                    pw[i] = pi
                if stateful:
                    state[i] = si
                g[i + 1] = f
                ai = (fprev - f + fext[i]) * inv_mass[i]
                a[i] = ai
                if last:
                    v[i] += half * ai
                else:
                    vi = v[i] + dt * ai
                    v[i] = vi
                    if uses_rate:
                        vp[i] = vi + half * ai
                    u[i] += dt * vi
                fprev = f
        return step

    def make_aligned_block(constant=math.nan):
        """The ``ns`` steps of an aligned block (:func:`make_step`, the law's parameter folded as
        ``constant`` where given) in a function of its own, called once per block, as
        ``kernels.dissipative_block`` calls its loops: inside one block with the unaligned pass
        and the other parameters' loops beside it, the step loop ran ~1.4x slower (power law at
        n = 3/2 1.74x the hand-written elastic step, the same arithmetic; benchmarks/laws.py)."""
        step = make_step(constant)

        @njit(nogil=True)
        def aligned_block(u, v, vp, a, g, pw, kappa, damping, d0, fext, inv_mass, state, ns, dt, t0, wall_slot,
                          peak, acc):
            half = 0.5 * dt
            for s in range(ns):
                if s < ns - 1:
                    step(u, v, vp, a, g, pw, kappa, damping, d0, fext, inv_mass, state, dt, half, False)
                else:
                    step(u, v, vp, a, g, pw, kappa, damping, d0, fext, inv_mass, state, dt, half, True)
                p = total(pw) if dissipative else 0.0  # a law without dissipation leaves pw at 0
                acc[0] += half * (acc[1] + p)  # trapezoidal integral of the dissipated power
                acc[1] = p
                _track_peak(g[wall_slot + 1], t0 + (s + 1) * dt, dt, peak)
        return aligned_block

    def make_blocks(values):
        """The aligned block for a chain whose contacts all have the parameter values[which]
        (which = len(values): any parameters): one compiled block per value."""
        if not values:
            any_block = make_aligned_block()

            @njit(nogil=True, inline="always")
            def block_any(which, u, v, vp, a, g, pw, kappa, damping, d0, fext, inv_mass, state, ns, dt, t0,
                          wall_slot, peak, acc):
                any_block(u, v, vp, a, g, pw, kappa, damping, d0, fext, inv_mass, state, ns, dt, t0, wall_slot, peak,
                          acc)
            return block_any
        first = make_aligned_block(values[0])
        rest = make_blocks(values[1:])

        @njit(nogil=True, inline="always")
        def block_fixed(which, u, v, vp, a, g, pw, kappa, damping, d0, fext, inv_mass, state, ns, dt, t0, wall_slot,
                        peak, acc):
            if which == 0:
                first(u, v, vp, a, g, pw, kappa, damping, d0, fext, inv_mass, state, ns, dt, t0, wall_slot, peak, acc)
            else:
                rest(which - 1, u, v, vp, a, g, pw, kappa, damping, d0, fext, inv_mass, state, ns, dt, t0, wall_slot,
                     peak, acc)
        return block_fixed

    constants = tuple(float(c) for c in constants)
    aligned_blocks = make_blocks(constants)
    n_constants = len(constants)
    constants_array = np.array(constants + (math.nan,))

    @njit(nogil=True, inline="always")
    def which_constant(kappa, damping):
        """The index in ``constants`` of the parameter every contact (kappa != 0) has, else
        len(constants)."""
        for i in range(n_constants):
            c = constants_array[i]
            same = True
            for j in range(kappa.shape[0]):
                same = same and (kappa[j] == 0.0 or damping[j] == c)
            if same:
                return i
        return n_constants

    @njit(nogil=True)
    def forces(u, v, kappa, damping, d0, de, dx0, rsum, g, state):
        power = 0.0
        for j in range(kappa.shape[0]):
            g[j + 1], p, state[j] = contact(u[j], u[j + 1], v[j], v[j + 1], kappa[j], damping[j], d0[j], de[j],
                                            dx0[j], rsum[j], state[j])
            power += p
        return power

    @njit(nogil=True)
    def misaligned_block(u, v, vp, a, g, pw, kappa, damping, d0, de, dx0, rsum, fext, inv_mass, state, ns, dt, t0,
                         wall_slot, peak, acc):
        """The ``ns`` steps of a block of a chain with offsets: the forces at the predicted
        velocities (:func:`forces_into`), then :func:`~hertzchain.integrate.core.primitives.kick`."""
        half = 0.5 * dt
        for s in range(ns):
            forces_into(u, vp, kappa, damping, d0, de, dx0, rsum, g, state, pw)
            kick(u, v, vp, a, g, fext, inv_mass, dt, half, s == ns - 1)
            p = total(pw) if dissipative else 0.0
            acc[0] += half * (acc[1] + p)
            acc[1] = p
            _track_peak(g[wall_slot + 1], t0 + (s + 1) * dt, dt, peak)

    @njit(nogil=True)
    def law_block(u, v, vp, a, g, pw, kappa, damping, d0, de, dx0, rsum, fext, inv_mass, state, aligned, ns, dt, t0,
                  wall_slot, peak, acc):
        """The ``ns`` steps of a block (its opening half kick and drift done by the caller): the
        forces at the predicted velocities ``vp`` (P + 1 slots, vp[P] = 0), the dissipated energy's
        trapezoidal integral in acc[0:2], the wall peak, then the kick, which leaves the next
        step's predictions in ``vp`` (``aligned``: no offsets); the contacts' powers are summed by
        :func:`~hertzchain.integrate.core.primitives.total`. Each block's step loop is one
        function with everything inlined: a call per step and pass (arrays passed field by field,
        their references counted) cost as much as the pass on short chains."""
        predict(v, a, 0.5 * dt, vp)
        if aligned:
            aligned_blocks(which_constant(kappa, damping), u, v, vp, a, g, pw, kappa, damping, d0, fext, inv_mass,
                           state, ns, dt, t0, wall_slot, peak, acc)
        else:
            misaligned_block(u, v, vp, a, g, pw, kappa, damping, d0, de, dx0, rsum, fext, inv_mass, state, ns, dt,
                             t0, wall_slot, peak, acc)

    @njit(nogil=True)
    def energy(u, kappa, damping, d0, de, dx0, rsum, fext):
        e = 0.0
        for j in range(kappa.shape[0]):
            if kappa[j] != 0.0:
                d, c = overlap(u, d0, de, dx0, rsum, j)
                if d > 0.0:
                    e += stored(d, kappa[j], damping[j])
        for i in range(fext.shape[0]):
            e -= fext[i] * u[i]
        return e

    @njit(nogil=True)
    def stride(u, v, a, kappa, damping, d0, de, dx0, rsum, dcap, state, inv_mass, horizon, block, c_steps):
        """Steps per block so that omega dt <= 1 / c_steps: ``kernels.required_stride``'s Gershgorin
        bound and overlap estimate (Taylor over the horizon, or the closing contact's energy all
        stored, capped by the run's bound dcap) with the law's tangent stiffness and damping."""
        kprev = 0.0
        cprev = 0.0
        weff = 0.0
        hh = 0.5 * horizon * horizon
        for j in range(kappa.shape[0]):
            k = 0.0
            c = 0.0
            if kappa[j] != 0.0:
                d, cc = overlap(u, d0, de, dx0, rsum, j)
                rate = v[j] - v[j + 1]
                q = a[j] - a[j + 1]
                est = d + 2.0 * (q if q > 0.0 else 0.0) * hh
                if rate > 0.0 and d + 2.0 * rate * horizon > 0.0:  # closing, touching within the horizon
                    dp = d if d > 0.0 else 0.0
                    e = stored(dp, kappa[j], damping[j]) + 0.5 * rate * rate / (inv_mass[j] + inv_mass[j + 1])
                    de_ = inverse(e, kappa[j], damping[j])
                    est = de_ if de_ > est else est
                est = est if est < dcap[j] else dcap[j]
                if est > 0.0:
                    vin = state[j] if state[j] > abs(rate) else abs(rate)
                    k, c, _, _ = partials(est, abs(rate), kappa[j], damping[j], vin)
                    k = abs(k)
                    c = abs(c)
            om2 = 2.0 * (kprev + k) * inv_mass[j]
            beta = 2.0 * (cprev + c) * inv_mass[j]
            weff = max(weff, np.sqrt(om2 + 0.25 * beta * beta) + 0.5 * beta)
            kprev = k
            cprev = c
        return max(1, int(np.ceil(block * c_steps * weff - 1e-9)))

    @njit(nogil=True, inline="always")
    def law_forces(u, v, kappa, damping, d0, de, dx0, rsum, law, g, dyield, dmax, dres, kres):
        """``forces`` in ``kernels.forces_general``'s signature (the law's state lives in ``dmax``)."""
        return forces(u, v, kappa, damping, d0, de, dx0, rsum, g, dmax)

    ext_block = extended_steps(law_forces)

    def make_run(extended):
        """The run of a model with (``extended``) or without the extension (a protected body,
        mass-in-mass beads), a compile-time constant: each compiles only its own steps (the
        extension's ~2.5 CPU-s of a first run of Hunt-Crossley's 12)."""
        @njit(nogil=True)
        def run(state, chain, contacts, extension, probes, control, law, general, k_start, k_stop):
            u, v, a, g, acc = state
            mass, inv_mass, kappa, damping, d0, fext, wall_slot = chain
            de, dx0, rsum, dcap, _, dmax, _, _ = contacts
            ext, ext_on, body_slot = extension
            rec, out_f, _, _, _, _, _, _, _, _, fmax, peak, _ = probes
            interval, stride_, n_sub, n_eval, c_steps, relax = control
            n = a.shape[0]
            if ext_on != extended:  # a compile-time constant against the model's extension
                raise ValueError("generated law: this compiled run steps the other kind of model (extension)")
            if dmax.shape[0] < n:  # the law's state lives in dmax: the caller must give one slot per contact
                raise ValueError("generated law: the state array (dmax) is shorter than the contacts")
            nout = rec.shape[0]
            block = interval / n_sub
            adaptive = stride_ == 0
            ns = stride_ if not adaptive else int(acc[3])
            vp = np.zeros_like(v)
            pw = np.zeros(n)
            aligned = True
            for i in range(n):
                aligned = aligned and de[i] == 0.0
            wa = np.zeros(n)
            if ext_on:  # the internal masses' accelerations: a function of the positions, not state
                for i in range(n):
                    wa[i] = internal_acceleration(ext[i, EXT_KIN], ext[i, EXT_W], u[i], ext[i, EXT_IMIN])
            step = int(acc[2])
            for k in range(k_start, k_stop):
                for b in range(n_sub):
                    if adaptive and ((k - 1) * n_sub + b) % n_eval == 0:
                        req = stride(u, v, a, kappa, damping, d0, de, dx0, rsum, dcap, dmax, inv_mass, n_eval * block,
                                     block, c_steps)
                        if extended:
                            req += extension_stride(ext, inv_mass, block, c_steps)
                        ns = _adapt_stride(req, ns, relax, acc)
                    dt = block / ns
                    half = 0.5 * dt
                    t0 = (k - 1) * interval + b * block
                    if extended:
                        ext_block(u, v, vp, a, wa, g, kappa, damping, d0, de, dx0, rsum, fext, inv_mass, law, dmax, dmax,
                                  dmax, dmax, ext, body_slot, wall_slot, t0, dt, ns, peak, acc)
                        step += ns
                        continue
                    open_block(u, v, a, dt, half)
                    law_block(u, v, vp, a, g, pw, kappa, damping, d0, de, dx0, rsum, fext, inv_mass, dmax, aligned, ns, dt,
                              t0, wall_slot, peak, acc)
                    step += ns
                for j in range(nout):
                    out_f[k, j] = g[rec[j] + 1]
                for j in range(fmax.shape[0]):
                    x = g[j + 1]
                    fmax[j] = x if x > fmax[j] else fmax[j]
                ke = kinetic_energy(v, mass)
                pe = energy(u, kappa, damping, d0, de, dx0, rsum, fext)
                if close_sample(k, ke, pe, u, v, a, g, d0, extension, probes, acc, step):
                    return 1
            acc[2] = step
            return 0

        return run

    return forces, (make_run(False), make_run(True)), energy, stride, contact


def is_generated(code: int) -> bool:
    """True when engine code ``code`` is run by the generated engines (not a hand-written one)."""
    from ...laws import FIRST_GENERATED_CODE

    return int(code) >= FIRST_GENERATED_CODE


def run_kernel(code: int, general: bool, extended: bool):
    """The stepping loop for law code ``code`` (and ``System.general``, ``System.extended``): the
    law's generated ``run``, or the hand-written run of that kind (``kernels.verlet_run_of``)."""
    if is_generated(code):
        return law_kernels(code)[1][int(bool(extended))]
    return kernels.verlet_run_of(kernels.run_kind(code, general, extended))
