"""Driver of the fourth-order integrator ``"rkn4"`` (:mod:`hertzchain.integrate.drivers.rkn_kernels`).

``simulate(model, integrator="rkn4")``: a symplectic Runge-Kutta-Nystrom composition of order 4
with a step control that follows contacts as they close and open, and probes interpolated between
steps, so the step is not tied to the sample interval. It integrates aligned elastic chains
(paper eq. 1, with or without precompression); Kuwabara-Kono's law, the dashpot (plain or
size-scaled) and beads offset from the axis go to :mod:`hertzchain.integrate.drivers.rkn_damped` (the
classical RKN for y'' = f(y, y')), the elastic-plastic law and the registry's generated laws (power,
Hunt-Crossley, a user's) to :mod:`hertzchain.integrate.drivers.rkn_laws` (the same method with the
law's own functions and its per-contact state); protected bodies and mass-in-mass beads stay with
the velocity Verlet. Accuracy: ``rtol``, the local velocity error allowed per step relative to the
striker speed (default 1e-6 gives a peak wall force within ~1e-8 of DOP853 at rtol 1e-12 on the
paper's chains; benchmarks/time_to_accuracy.py).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Callable

import numpy as np

from ...errors import ConfigError
from ...model import System
from . import rkn_kernels as rk
from ..core.kernels import LAW_DASHPOT, LAW_ELASTIC, LAW_VISCOELASTIC
from ..core.layout import pack
from .rkn_chunks import advance_in_chunks, rkn_raw_run
from .verlet import RawRun, check_time_step

__all__ = ["run_rkn", "RKN_RTOL", "check_rkn"]

#: Default local velocity error per step, relative to the striker speed (``rtol``).
RKN_RTOL = 1e-6
#: The dissipative laws' method (:mod:`hertzchain.integrate.drivers.rkn_damped`) bounds its local error
#: by ``DAMPED_EPS`` rtol: the classical RKN's error constant is larger than SRKN_6^b's, and the
#: bound's terms carry none; with this factor the default rtol keeps the peak wall force of chain 1
#: with its dashpot within ~4e-7 of DOP853 (1.6 rtol without; tests/test_rkn_dissipative.py).
DAMPED_EPS = 0.2


def check_rkn(system: System) -> None:
    """Refuse a model the fourth-order integrator does not integrate (ConfigError naming ``run.integrator``).

    Parameters
    ----------
    system : hertzchain.model.System
        The model's arrays.
    """
    from .refusals import refuse

    refuse("rkn4", system)  # suggesting only integrators that take the model


def run_rkn(system: System, duration: float, sample_interval: float, dt: float | None = None,
            rtol: float = RKN_RTOL, record_velocities: bool = False, contacts: np.ndarray | None = None,
            progress: Callable[[int, int], None] | None = None, chunk_steps: int = 200_000,
            record_positions: bool = False, threads: int = 1) -> RawRun:
    """Integrate ``system`` for ``duration`` [s] with the fourth-order composition (module docstring).

    Parameters
    ----------
    system : hertzchain.model.System
        A model :func:`check_rkn` accepts (aligned elastic here; dissipative or offset chains go
        to :func:`hertzchain.integrate.drivers.rkn_damped.run_rkn_damped`).
    duration : float
        Simulated time [s].
    sample_interval : float
        Time between samples [s]; it does not limit the step.
    dt : float or None
        A fixed step [s] (checked like Verlet's), or None for the controlled step.
    rtol : float
        Local velocity error allowed per step, relative to the largest initial speed.
    record_velocities, record_positions : bool
        Also record every body's velocity / displacement.
    contacts : numpy.ndarray or None
        Contact numbers whose forces are recorded (all when None).
    progress : callable or None
        ``progress(done, total)`` in samples, between chunks of about ``chunk_steps`` steps.
    chunk_steps : int
        Steps per compiled call (about).
    threads : int
        Threads sharing an aligned elastic chain (:mod:`hertzchain.integrate.drivers.rkn_threaded`:
        the same numbers but for the energies' rounding); the other paths run on one.

    Returns
    -------
    RawRun
        ``integrator = "rkn4"``; ``dt`` and ``dt_max`` the smallest and largest step.
    """
    check_rkn(system)
    if not (math.isfinite(rtol) and rtol > 0):
        raise ConfigError("run.rtol", f"must be a positive relative tolerance, got {rtol!r}")
    if dt is not None:
        check_time_step(system, dt)
    from ...laws import hertz_equivalent, law_of_code

    if hertz_equivalent(system):
        # a registry law that is the elastic law on every contact (the power law at n = 3/2, its k
        # each pair's or its own: F = k delta^(3/2), paper eq. 1): the elastic law's engine, so that
        # the run is the elastic run (issue 33's contract), not the classical method's approximation
        system = dataclasses.replace(system, law=LAW_ELASTIC, damping=np.zeros_like(system.damping))
    spec = law_of_code(system.law)
    if spec.generated or spec.plastic:
        # a registry law or one with per-contact state: the law's own functions on the method for
        # y'' = f(y, y'), the state frozen over a step's stages
        from .rkn_laws import run_rkn_laws

        v_ref = float(np.max(np.abs(system.v0)))
        return run_rkn_laws(system, duration, sample_interval, dt, rtol * DAMPED_EPS * (v_ref if v_ref > 0 else 1.0),
                            record_velocities, contacts, progress, chunk_steps, record_positions)
    if system.law in (LAW_VISCOELASTIC, LAW_DASHPOT) or (system.law == LAW_ELASTIC and system.misaligned):
        # Kuwabara-Kono, the dashpot or offsets: the method for y'' = f(y, y')
        from .rkn_damped import run_rkn_damped

        v_ref = float(np.max(np.abs(system.v0)))
        return run_rkn_damped(system, duration, sample_interval, dt, rtol * DAMPED_EPS * (v_ref if v_ref > 0 else 1.0),
                              record_velocities, contacts, progress, chunk_steps, record_positions)
    n_samples = int(math.floor(duration / sample_interval + 1e-9)) + 1
    nc = system.n_contacts
    nb = system.n_beads + 1
    w = pack(system)
    p = w.n_slots
    u, v = w.u, w.v
    g = np.zeros(p + 1)
    a = np.zeros(p + 1)  # one slot more, always 0, so that contact P - 1 can read a[P] (as u[P], v[P])
    sq = np.zeros(p)
    ed = np.zeros((2, rk.ROWS, p))  # end data of the last two step ends (rkn_kernels.rkn_run)
    ends = np.zeros((2, 4))
    rk.forces_at(u, v, a, g, sq, w.kappa, w.d0, w.fext, w.inv_mass)
    rk.end_data(u, v, a, g, sq, w.kappa, w.d0, w.fext, w.mass, ed, ends, 0)
    rec = np.arange(nc) if contacts is None else np.asarray(contacts, dtype=np.int64)
    out_f = np.empty((n_samples, rec.size))
    out_ke = np.empty(n_samples)
    out_pe = np.empty(n_samples)
    out_v = np.empty((n_samples if record_velocities else 1, nb))
    out_u = np.empty((n_samples if record_positions else 1, nb))
    f0 = g[1 : nc + 1]
    out_f[0] = f0[rec]
    out_ke[0] = ends[0, rk.E_KE]
    out_pe[0] = ends[0, rk.E_PE]
    out_v[0] = v[:nb]
    out_u[0] = u[:nb]
    fmax = f0.copy()
    peak = np.array([g[system.n_beads + 1], 0.0])
    acc = np.array([0.0, 0.0, 0.0, 0.0, np.inf, 0.0])
    scratch = rk.RknScratch(np.zeros(p), np.zeros(p), np.zeros(p), np.zeros((nc, rk.SAMPLE_BLOCK)),
                            np.zeros(rk.SAMPLE_BLOCK), np.zeros(nc, dtype=np.int64),
                            np.zeros((6, nc)), np.zeros(p), np.zeros(p), np.zeros(p), np.zeros(p))
    v_ref = float(np.max(np.abs(system.v0)))
    eps = rtol * (v_ref if v_ref > 0 else 1.0)

    # samples per compiled call: about chunk_steps steps at the controlled step's typical size
    # (~1 us on the paper's chains), at least one
    per_call = max(1, round(chunk_steps * 1e-6 / sample_interval))
    state = rk.RknState(u, v, a, g, sq, ed, ends)
    chain = rk.ChainArrays(w.mass, w.inv_mass, w.kappa, w.damping, w.d0, w.fext, system.n_beads)
    probes = rk.ProbeBuffers(rec, out_f, out_ke, out_pe, out_ke, out_v, bool(record_velocities), out_u,
                             bool(record_positions), fmax, peak)
    control = rk.StepControl(float(sample_interval), 0.0 if dt is None else float(dt), float(eps), float(duration))
    advance: Callable[..., int] = rk.rkn_run
    if threads > 1:
        from .rkn_threaded import threaded_advance

        advance = threaded_advance(threads, p, rec, ends)
    advance_in_chunks(lambda k, k_stop: advance(state, scratch, chain, probes, control, k, k_stop, acc), n_samples,
                      per_call, sample_interval, dt is not None, progress)
    return rkn_raw_run(probes, acc, sample_interval, dt is not None, np.zeros(n_samples))
