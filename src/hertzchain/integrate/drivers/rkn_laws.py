"""Driver of ``"rkn4"`` on the laws with per-contact state and the registry's generated laws
(:mod:`hertzchain.integrate.drivers.rkn_state_kernels`).

``simulate(model, integrator="rkn4")`` (and ``"auto"``, which picks it) on a chain with the
elastic-plastic law (Thornton; the state: each contact's largest overlap and the unloading curve
it implies) or a law of the registry run by the generated engines (the power law, Hunt-Crossley
whose state is the approach speed at touch, any user's law with or without state): the classical
fourth-order RKN of the damped laws with the law's own scalar functions (its force, state update
and energy from the registry; the elastic-plastic law's ``kernels.elastoplastic_force`` and
``energies``), the state frozen over a step's stages and committed when the step is accepted,
every change of a contact's branch (closing, clip, state growing or not, yield) landed on.
Fourth order on smooth stretches; ``eps`` is the local velocity error per step [m/s]
(``rkn.DAMPED_EPS`` rtol times the striker speed, as the damped laws'). Accuracy measured in
tests/test_rkn_laws.py and benchmarks/time_to_accuracy.py.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np
from numba import njit

from ...model import System
from ..core.disk_cache import INTEGRATE, files_digest, function_files_digest, on_disk
from ..core.energies import contact_plastic_work, unloading_energy
from ..core.kernels import DELTA_MIN, elastoplastic_force
from ..core.layout import pack
from . import rkn_state_kernels as rs
from .rkn_kernels import ChainArrays, ProbeBuffers, StepControl
from .rkn_chunks import advance_in_chunks, rkn_raw_run
from .verlet import RawRun

__all__ = ["run_rkn_laws", "law_run"]

_BUILT: dict = {}
#: The package's files compiled into these kernels (with the law's own: their on-disk cache key).
_COMPILED_IN = ("drivers/rkn_state_kernels.py", "drivers/rkn_laws.py", "drivers/rkn_damped_kernels.py",
                "drivers/rkn_kernels.py", "drivers/rkn_samples.py", "core/kernels.py", "core/primitives.py",
                "core/energies.py")


def _fixed(fn, value: float):
    """``fn(d, rate, k, p, s)`` with p = ``value``, a compile-time constant."""
    p = float(value)

    @njit(nogil=True, inline="always")
    def fixed(d, r, k, _p, s):
        return fn(d, r, k, p, s)

    return fixed


def _fixed_energy(fn, value: float):
    """``fn(d, k, p)`` with p = ``value``, a compile-time constant."""
    p = float(value)

    @njit(nogil=True, inline="always")
    def fixed(d, k, _p):
        return fn(d, k, p)

    return fixed


def _generated_adapter(force, update, stored, dissipative: bool, partials, state_partials,
                       stateful: bool, constant: float | None = None) -> rs.LawAdapter:
    """A registry law's functions (``force(d, rate, k, p, s)``, ``state``, ``energy``,
    ``partials``, ``state_partials``) as the kernels take them; its state (one number per
    contact) in row 0 of ``S``. The slopes come from the law's partials (through the state's
    update by the chain rule on a growing branch); a law with state that declares no
    ``state_partials`` gets the kernels' central differences. With ``constant`` (one of the law's
    ``constant_parameters``, every contact's parameter) the functions take it as a compile-time
    constant: the law's branches on it fold and its arithmetic simplifies (the power law at n = 2:
    d d, not pow), as in the generated Verlet loops (``core/generated.py``)."""
    if constant is not None:
        force, update, partials = (_fixed(fn, constant) for fn in (force, update, partials))
        state_partials = None if state_partials is None else _fixed(state_partials, constant)
        stored = _fixed_energy(stored, constant)

    @njit(nogil=True, inline="always")
    def lforce(d, r, k, p, S, j, grow):
        s = update(d, r, k, p, S[0, j]) if grow else S[0, j]
        if d < 0.0:
            return 0.0, 0.0, d
        dd = d if d > DELTA_MIN else 0.0
        f = force(dd, r, k, p, s)
        if not dissipative:  # a compile-time constant (generated.py's rule): F does not depend on the rate
            return f, f, d
        return f, force(dd, 0.0, k, p, s), d

    @njit(nogil=True, inline="always")
    def commit(d, r, k, p, S, j):
        S[0, j] = update(d, r, k, p, S[0, j])

    @njit(nogil=True, inline="always")
    def key(d, r, k, p, S, j):
        return update(d, r, k, p, S[0, j])

    @njit(nogil=True, inline="always")
    def regime(d, r, k, p, S, j):
        return 0

    @njit(nogil=True, inline="always")
    def energy(d, k, p, S, j):
        return stored(d, k, p) if d > 0.0 else 0.0

    @njit(nogil=True, inline="always")
    def work(k, p, S, j):
        return 0.0

    if stateful and state_partials is None:
        tangent = None  # the kernels' central differences
    elif stateful:
        @njit(nogil=True, inline="always")
        def tangent(d, r, k, p, S, j, grow):
            s = S[0, j]
            dd = d if d > DELTA_MIN else 0.0
            if not grow:  # the force at the committed state
                fd, fr, _, _ = partials(dd, r, k, p, s)
                return fd, fr, d
            sn = update(d, r, k, p, s)
            fd, fr, _, _ = partials(dd, r, k, p, sn)
            fs = state_partials(dd, r, k, p, sn)[0]  # dF/ds at the updated state
            _, sd, sr, _, _, _ = state_partials(d, r, k, p, s)  # ds'/d delta, ds'/d rate of the update
            return fd + fs * sd, fr + fs * sr, d
    else:
        @njit(nogil=True, inline="always")
        def tangent(d, r, k, p, S, j, grow):
            fd, fr, _, _ = partials(d if d > DELTA_MIN else 0.0, r, k, p, S[0, j])
            return fd, fr, d

    return rs.LawAdapter(lforce, commit, key, regime, energy, work, tangent, stored_state=False,
                         lossless=not dissipative)


# Thornton's elastic-plastic law, its state in rows (yield overlap, dmax, dres, kres) of S
@njit(nogil=True, inline="always")
def _ep_force(d, r, k, p, S, j, grow):
    f, fep, _, _, _ = elastoplastic_force(d, r, k, p, S[0, j], S[1, j], S[2, j], S[3, j])
    return f, fep, d - S[2, j]


@njit(nogil=True, inline="always")
def _ep_commit(d, r, k, p, S, j):
    _, _, S[1, j], S[2, j], S[3, j] = elastoplastic_force(d if d > 0.0 else 0.0, r, k, p, S[0, j], S[1, j], S[2, j],
                                                          S[3, j])


@njit(nogil=True, inline="always")
def _ep_key(d, r, k, p, S, j):
    """The largest overlap, once past the yield overlap (below it loading and unloading are the
    same Hertz curve: the state's growth is no event there)."""
    m = d if d > S[1, j] else S[1, j]
    return m if m > S[0, j] else S[0, j]


@njit(nogil=True, inline="always")
def _ep_regime(d, r, k, p, S, j):
    """1 past the yield overlap (the loading curve's straight part)."""
    return 1 if _ep_key(d, r, k, p, S, j) > S[0, j] else 0


@njit(nogil=True, inline="always")
def _ep_stored(d, k, p, S, j):
    return unloading_energy(d - S[2, j], S[3, j])


@njit(nogil=True, inline="always")
def _ep_work(k, p, S, j):
    return contact_plastic_work(k, S[0, j], S[1, j], S[2, j])


@njit(nogil=True, inline="always")
def _ep_tangent(d, r, k, p, S, j, grow):
    """(dF/d delta, dF/d rate, gap) of :func:`_ep_force` (``kernels.elastoplastic_force``
    unclipped, differentiated by hand): loading past the largest overlap (Hertz, then the yield
    line of slope (3/2) kappa dyield^(1/2), the damping term kappa A d^(1/2) r on the unloading
    curve through the point), else the unloading curve kres x^(3/2) + A kres x^(1/2) r,
    x = d - dres."""
    dy, dmax, dres, kres = S[0, j], S[1, j], S[2, j], S[3, j]
    if d > dmax:
        sd = math.sqrt(d)
        if d > dy:  # kres x^(1/2) on the new curve is kappa d^(1/2)
            kd = 1.5 * k * math.sqrt(dy)
            kr = k * sd
        else:
            kd = 1.5 * k * sd
            kr = kres * sd
        return kd + (0.5 * p * kr * r / d if d > DELTA_MIN else 0.0), p * kr, d - dres
    x = d - dres
    if x <= DELTA_MIN:
        return 0.0, 0.0, x
    sx = math.sqrt(x)
    return 1.5 * kres * sx + 0.5 * p * kres * r / sx, p * kres * sx, x


_PLASTIC = rs.LawAdapter(_ep_force, _ep_commit, _ep_key, _ep_regime, _ep_stored, _ep_work, _ep_tangent)


def law_run(code: int, constant: float | None = None, lossless: bool = False):
    """The compiled kernels (:func:`rkn_state_kernels.build`) of the law of engine code ``code``
    (with its parameter the compile-time ``constant``, one of its ``constant_parameters``, when
    given), built once per law definition, constant and process. ``lossless``: the elastic-plastic
    law without its viscous term (A = 0 on every contact), whose dissipated energy is then exactly
    0 (the bookkeeping of contacts off their loaded branch would otherwise count the ~1e-25 J a
    skipped closing, ``EVENT_EPS``, stores; the plastic work is its own record)."""
    from ...laws import law_of_code
    from ...laws.spec import FIRST_USER_CODE, compiled

    spec = law_of_code(code)
    lossless = lossless and spec.plastic
    key = (code, id(spec.force), id(spec.state), id(spec.energy), spec.dissipative, spec.plastic, constant, lossless)
    if key not in _BUILT:
        law_files: bytes | None
        if spec.plastic:
            adapter = _PLASTIC._replace(lossless=True) if lossless else _PLASTIC
            law_files = files_digest(INTEGRATE / "core/energies.py")
        else:
            adapter = _generated_adapter(compiled(spec.force), compiled(spec.state), compiled(spec.energy),
                                         bool(spec.dissipative), compiled(spec.partials),
                                         None if spec.state_partials is None else compiled(spec.state_partials),
                                         bool(spec.state_size), constant)
            # a user's law (its module may be one runpy made, not importable where Numba reloads
            # a cached closure): compiled in memory only
            law_files = (function_files_digest(spec.force, spec.state, spec.energy)
                         if spec.code < FIRST_USER_CODE else None)
        built = rs.build(adapter)
        if law_files is not None:  # on disk under the text of everything compiled in (a law typed at
            # the prompt: in memory only), as the generated Verlet loops (core/disk_cache.py)
            sources = law_files + files_digest(*(INTEGRATE / name for name in _COMPILED_IN))
            variant = ("rkn_laws", spec.name, spec.dissipative, spec.plastic, constant, lossless)
            built = tuple(on_disk(fn, *variant, i, sources=sources) for i, fn in enumerate(built))
        _BUILT[key] = built
    return _BUILT[key]


def _state_rows(system: System, w) -> np.ndarray:
    """The law's per-contact state ``S`` (rows as the adapter reads them) at the start."""
    from ...laws import law_of_code

    if law_of_code(system.law).plastic:
        return np.ascontiguousarray(np.stack([w.dyield, w.dmax, w.dres, w.kres]))
    return w.dmax.reshape(1, -1).copy()  # the generated engines' state slot, 0 at the start


def run_rkn_laws(system: System, duration: float, sample_interval: float, dt: float | None, eps: float,
                 record_velocities: bool, contacts: np.ndarray | None, progress: Callable[[int, int], None] | None,
                 chunk_steps: int, record_positions: bool) -> RawRun:
    """Integrate ``system`` (a stateful or generated law, module docstring) for ``duration`` [s].

    Called by :func:`hertzchain.integrate.drivers.rkn.run_rkn`, which checked the model and the
    options; parameters and result as :func:`hertzchain.integrate.drivers.rkn_damped.run_rkn_damped`'s,
    with the elastic-plastic law's plastic work, residual and largest overlaps.
    """
    from ...laws import law_of_code

    spec = law_of_code(system.law)
    plastic = spec.plastic
    n_samples = int(math.floor(duration / sample_interval + 1e-9)) + 1
    nc = system.n_contacts
    nb = system.n_beads + 1
    w = pack(system)
    # every contact's parameter one of the law's constants: the kernels with it compiled in
    params = set(w.damping[w.kappa != 0.0].tolist())
    constant = params.pop() if len(params) == 1 and not plastic else None
    accel, end_data, set_modes, commit_all, energies, run = law_run(
        system.law, constant if constant in spec.constant_parameters else None,
        lossless=plastic and not np.any(w.damping[w.kappa != 0.0]))
    p = w.n_slots
    u, v = w.u, w.v
    a, an, un, vn, us, vs = (np.zeros(p + 1) for _ in range(6))
    k2, k3, k4, up, vp, ap = (np.zeros(p) for _ in range(6))
    S = _state_rows(system, w)
    Sp = S.copy()
    ed = np.zeros((2, rs.ROWS, p))
    ends = np.zeros((2, rs.ENDS + 1))
    pw = np.zeros(p)
    mode = np.full(p, float(rs.LOADED))
    # None for an aligned chain: a specialisation of its own (the width test of an empty array, as the
    # dissipative engine takes it, cost these runs ~5 %: their per-sample law loops call axial())
    off = np.ascontiguousarray(np.stack([w.de, w.dx0, w.rsum])) if system.misaligned else None
    # a = f(u, v) on the loaded branches, then every contact on the branch its state gives
    accel(u, v, w.kappa, w.damping, w.d0, off, w.fext, w.inv_mass, S, mode, a, pw, 0.0)
    end_data(u, v, a, w.kappa, w.damping, w.d0, off, w.fext, w.mass, S, mode, 0.0, ed, ends, 0)
    set_modes(ed, 0, w.kappa, w.damping, S, mode, 1e-8 * duration)
    # the state of the contacts loaded at the start (touching ones take it as at their closing)
    commit_all(u, v, w.kappa, w.damping, w.d0, off, S, mode, np.zeros(p), ed, 0)
    accel(u, v, w.kappa, w.damping, w.d0, off, w.fext, w.inv_mass, S, mode, a, pw, 0.0)
    end_data(u, v, a, w.kappa, w.damping, w.d0, off, w.fext, w.mass, S, mode, 0.0, ed, ends, 0)
    energies(u, w.kappa, w.damping, w.d0, off, w.fext, S, ends, 0)
    last = mode.copy()
    rec = np.arange(nc) if contacts is None else np.asarray(contacts, dtype=np.int64)
    out_f = np.empty((n_samples, rec.size))
    out_ke = np.empty(n_samples)
    out_pe = np.empty(n_samples)
    out_d = np.empty(n_samples)
    out_w = np.empty(n_samples)
    out_v = np.empty((n_samples if record_velocities else 1, nb))
    out_u = np.empty((n_samples if record_positions else 1, nb))
    f0 = ed[0, 0, :nc].copy()
    out_f[0] = f0[rec]
    out_ke[0] = ends[0, rs.E_KE]
    out_pe[0] = ends[0, rs.E_PE]
    out_d[0] = 0.0
    out_w[0] = ends[0, rs.E_W]
    out_v[0] = v[:nb]
    out_u[0] = u[:nb]
    fmax = f0.copy()
    peak = np.array([f0[system.n_beads] if system.has_wall else 0.0, 0.0])
    acc = np.array([0.0, 0.0, 0.0, 0.0, np.inf, 0.0, 0.0])

    per_call = max(1, round(chunk_steps * 1e-6 / sample_interval))
    state = rs.StateRun(u, v, a, un, vn, an, us, vs, k2, k3, k4, pw, mode, last, S, Sp, up, vp, ap, ed, ends)
    chain = ChainArrays(w.mass, w.inv_mass, w.kappa, w.damping, w.d0, w.fext, system.n_beads)
    probes = ProbeBuffers(rec, out_f, out_ke, out_pe, out_d, out_v, bool(record_velocities), out_u,
                          bool(record_positions), fmax, peak)
    control = StepControl(float(sample_interval), 0.0 if dt is None else float(dt), float(eps), float(duration))
    advance_in_chunks(lambda k, k_stop: run(state, chain, off, probes, control, k, k_stop, acc, out_w), n_samples,
                      per_call, sample_interval, dt is not None, progress)
    return rkn_raw_run(probes, acc, sample_interval, dt is not None, out_d,
                       plastic_work=out_w if plastic else None,
                       residual_overlap=S[2, :nc].copy() if plastic else None,
                       max_overlap=S[1, :nc].copy() if plastic else None)
