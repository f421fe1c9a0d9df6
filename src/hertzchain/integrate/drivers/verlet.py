"""Driver of the compiled velocity-Verlet integrator: time step, chunking, progress, divergence."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ...errors import ConfigError, SimulationDiverged
from ...model import System
from ..core import kernels
from ..core.generated import is_generated, law_kernels, run_kernel
from ..core.layout import Packed, pack
from ..core.structures import VerletControl, VerletProbes, VerletState

__all__ = ["auto_time_step", "check_time_step", "run_verlet", "RawRun", "StepPlan", "step_plan", "new_probes",
           "initialise_run", "raw_run", "STEPS_PER_RADIAN", "ADAPTIVE_STEPS_PER_RADIAN"]

#: Fixed automatic step (:func:`auto_time_step`): dt = 1 / (STEPS_PER_RADIAN * omega_max), with
#: omega_max the whole run's bound (System.max_frequency).
STEPS_PER_RADIAN = 300.0
#: Adaptive step (the default): omega dt <= 1 / ADAPTIVE_STEPS_PER_RADIAN with omega bounded from
#: the present overlaps (kernels.required_stride). Calibrated so that the peak wall force of the
#: paper's chains is within 1e-6 of a DOP853 rtol=1e-12 reference and the energy error stays
#: below 1e-6 (tests/test_accuracy.py, tests/test_conservation.py). ``run.steps_per_radian``
#: overrides it: Verlet is second order, so the error scales as (1 / steps_per_radian)^2.
ADAPTIVE_STEPS_PER_RADIAN = 400.0
#: The adaptive step is re-evaluated at least every HORIZON_RADIANS / omega_max seconds (a
#: twentieth of the shortest contact, roughly), looking that far ahead, at the default accuracy.
HORIZON_RADIANS = 0.4
#: A block between two re-evaluations spans at least this many steps at omega_max: at coarse
#: accuracy (few steps per radian) the look-ahead is lengthened (see :func:`horizon_radians`).
HORIZON_STEPS = 32.0


def horizon_radians(steps_per_radian: float) -> float:
    """Look-ahead of the adaptive step, in radians of omega_max: HORIZON_RADIANS, or HORIZON_STEPS
    steps when that is longer (below 80 steps per radian).

    Re-evaluating the step (``kernels.required_stride``: a bound over every contact) costs several
    steps' worth of work; at 20 steps per radian a 0.4 rad block held about two steps, and the
    evaluations were most of the run. The longer look-ahead is at least as conservative (the
    overlaps are extrapolated over it) and the stability margin of a coarse step is wide (omega dt
    <= 1 / 10 at the coarsest allowed accuracy, against Verlet's limit of 2).
    """
    return max(HORIZON_RADIANS, HORIZON_STEPS / steps_per_radian)
#: An adaptive step grows only after this many evaluations in a row allowed it.
RELAX_EVALUATIONS = 5
#: A user time step with omega_max dt above this is refused (Verlet is unstable at 2; the error
#: on forces is already ~1 % well before).
MAX_OMEGA_DT = 0.5


@dataclass
class RawRun:
    """Arrays produced by an integrator, before they become an xarray Dataset."""

    time: np.ndarray            # (K,) s
    contact_force: np.ndarray   # (K, C) N, the contacts listed in ``contacts``
    kinetic_energy: np.ndarray  # (K,) J
    potential_energy: np.ndarray
    dissipated_energy: np.ndarray
    velocity: np.ndarray | None  # (K, N+1) m/s, bodies 0..N
    max_force: np.ndarray       # (n_contacts,) N, every contact's maximum over the samples
    peak_wall_force: float      # N, refined between steps
    peak_wall_time: float       # s
    dt: float                   # s, the (smallest) step used; 0 for solve_ivp
    integrator: str
    n_steps: int                # steps (Verlet) or right-hand-side evaluations (solve_ivp)
    contacts: np.ndarray        # contact numbers of the columns of contact_force
    dt_max: float = 0.0         # s, the largest step used (= dt for a fixed step)
    adaptive: bool = False      # True when the step was chosen as the run went
    displacement: np.ndarray | None = None  # (K, N+1) m, bodies 0..N, when positions were asked for
    body: np.ndarray | None = None  # (K, 4) protected body: displacement [m] from rest, velocity, acceleration, work [J]
    plastic_work: np.ndarray | None = None  # (K,) J, elastic-plastic law only
    residual_overlap: np.ndarray | None = None  # (n_contacts,) m, at the end (elastic-plastic law only)
    max_overlap: np.ndarray | None = None  # (n_contacts,) m, largest overlap reached (elastic-plastic law only)


def auto_time_step(system: System, sample_interval: float | None = None) -> float:
    """Automatic Verlet step [s]: 1 / (STEPS_PER_RADIAN * omega_max) (see System.max_frequency)."""
    dt = 1.0 / (STEPS_PER_RADIAN * system.max_frequency())
    if sample_interval is not None:
        dt = sample_interval / math.ceil(sample_interval / dt - 1e-9)
    return dt


def check_time_step(system: System, dt: float) -> None:
    """Refuse a user step too large for the stiffest contact (ConfigError naming ``run.dt``)."""
    if not (math.isfinite(dt) and dt > 0):
        raise ConfigError("run.dt", f"must be a positive time step in s, got {dt!r}")
    w = system.max_frequency()
    if w * dt > MAX_OMEGA_DT:
        raise ConfigError("run.dt", f"time step {dt:.3g} s is too large for the stiffest contact and its damping "
                          f"(omega_max = {w:.3g} rad/s): it must be below {MAX_OMEGA_DT / w:.3g} s; "
                          f"leave it out to use the automatic step ({auto_time_step(system):.3g} s)")


def _stride(sample_interval: float, dt: float) -> tuple[int, float]:
    stride = max(1, math.ceil(sample_interval / dt - 1e-9))
    return stride, sample_interval / stride


@dataclass(frozen=True)
class StepPlan:
    """How the kernel steps through sample intervals (see ``kernels._verlet_run``).

    ``stride`` > 0: fixed step dt = interval / stride. ``stride`` == 0: adaptive; each interval is
    cut into ``n_sub`` blocks and the number of steps per block is re-evaluated every ``n_eval``
    blocks.
    """

    stride: int
    dt: float          # s: the fixed step, or the smallest possible adaptive step
    n_sub: int = 1
    n_eval: int = 1
    c_steps: float = 0.0    # adaptive: steps per radian of the bound omega (ADAPTIVE_STEPS_PER_RADIAN)
    relax: int = 0          # adaptive: evaluations in a row before the step may grow (RELAX_EVALUATIONS)

    @property
    def adaptive(self) -> bool:
        return self.stride == 0

    def control(self, interval: float) -> VerletControl:
        """The plan as the compiled runs take it, for samples ``interval`` [s] apart."""
        return VerletControl(float(interval), int(self.stride), int(self.n_sub), int(self.n_eval),
                             float(self.c_steps), int(self.relax))


def step_plan(system: System, sample_interval: float, dt: float | None,
              steps_per_radian: float | None = None) -> StepPlan:
    """Fixed step ``dt`` [s] (checked, shortened to divide the sample interval) or, when None, the
    adaptive step: blocks short enough (<= horizon_radians / omega_max) for the look-ahead of
    ``kernels.required_stride`` to hold, with omega dt <= 1 / ``steps_per_radian`` (default
    ADAPTIVE_STEPS_PER_RADIAN; unused with a fixed step)."""
    if dt is not None:
        check_time_step(system, dt)
        stride, dt = _stride(sample_interval, dt)
        return StepPlan(stride=stride, dt=dt)
    w = system.max_frequency()
    if w <= 0.0:  # nothing moves: any step is exact
        return StepPlan(stride=1, dt=sample_interval)
    c = ADAPTIVE_STEPS_PER_RADIAN if steps_per_radian is None else float(steps_per_radian)
    bmax = horizon_radians(c) / w
    if sample_interval <= bmax:
        n_sub, n_eval = 1, max(1, math.floor(bmax / sample_interval))
    else:
        n_sub, n_eval = math.ceil(sample_interval / bmax - 1e-9), 1
    block = sample_interval / n_sub
    return StepPlan(stride=0, dt=block / math.ceil(block * c * w - 1e-9),
                    n_sub=n_sub, n_eval=n_eval, c_steps=c, relax=RELAX_EVALUATIONS)


def initialise(system: System, w: Packed, u, v, g, a, rec, out_f, out_ke, out_pe, out_ed, out_v, record_v: bool,
               fmax, peak, acc, out_wp=None, ext=None, out_b=None) -> None:
    """State at t = 0 (forces, accelerations) and sample 0 of every probe, written in place.

    Shared by :func:`run_verlet` and the batched engine, which passes per-member views, so
    both start from exactly the same numbers. ``peak`` and ``acc`` (8 slots each) are the
    kernel's wall-peak tracker and accumulators (see ``kernels._verlet_run``). ``out_wp`` receives
    the plastic work of the elastic-plastic law (the state ``w.dmax``... is that of the static
    overlaps after this call). An extended system also takes its extension array ``ext``
    (``w.ext`` when None) and, with a protected body, the body's record ``out_b``.
    """
    power0 = 0.0
    if is_generated(system.law):  # a law run by the generated engines (hertzchain.laws)
        power0 = law_kernels(system.law)[0](u, v, w.kappa, w.damping, w.d0, w.de, w.dx0, w.rsum, g, w.dmax)
    elif system.general:
        power0 = kernels.forces_general(u, v, w.kappa, w.damping, w.d0, w.de, w.dx0, w.rsum, system.law, g,
                                        w.dyield, w.dmax, w.dres, w.kres)
    else:
        kernels.forces_elastic(u, w.kappa, w.d0, g)
    if system.extended:
        ext = w.ext if ext is None else ext
        power0 += kernels.forces_linear(u, v, w.d0, ext, g)
        kernels.accelerations_extended(u, g, w.fext, w.inv_mass, ext, a, np.zeros(a.size))
    else:
        kernels.accelerations(g, w.fext, w.inv_mass, a)
    out_f[0] = g[rec + 1]
    out_ke[0] = kernels.kinetic_energy(v, w.mass)
    if system.law == kernels.LAW_ELASTOPLASTIC:
        out_pe[0] = kernels.potential_energy_plastic(u, w.d0, w.de, w.dx0, w.rsum, w.fext, w.dres, w.kres)
        out_wp[0] = kernels.plastic_work(w.kappa, w.dyield, w.dmax, w.dres)
    elif is_generated(system.law):
        out_pe[0] = law_kernels(system.law)[2](u, w.kappa, w.damping, w.d0, w.de, w.dx0, w.rsum, w.fext)
    else:
        out_pe[0] = kernels.potential_energy(u, g, w.kappa, w.d0, w.de, w.dx0, w.rsum, w.fext, False)
    if system.extended:
        ke_in, pe_lin = kernels.energies_extended(u, w.d0, ext)
        out_ke[0] += ke_in
        out_pe[0] += pe_lin
        if system.body:
            b = w.body_slot
            ext[1, kernels.EXT_ACC] = g[b] * v[b]  # power of contact N on the body at t = 0
            out_b[0] = (u[b], v[b], a[b], 0.0)
    out_ed[0] = 0.0
    if record_v:
        out_v[0] = v[: out_v.shape[1]]
    fmax[:] = g[1 : fmax.size + 1]
    fw0 = g[w.wall_slot + 1]
    peak[:8] = (fw0, 0.0, 0.0, 0.0, 0.0, fw0, 0.0, 0.0)
    # dissipated power at t = 0 (first point of the trapezoidal integral); no adaptive step chosen yet
    acc[:8] = (0.0, power0, 0.0, 0.0, 0.0, 0.0, 0.0, np.inf)


def refine_peak(peak: np.ndarray) -> tuple[float, float]:
    """Peak wall force [N] and its time [s] from the kernel's tracker: the vertex of the parabola
    through the force at the steps around the maximum (the peak falls between steps; the two
    steps may differ when the adaptive step changed there)."""
    fpk, t_pk, fb, fa, h0, h1 = peak[0], peak[1], peak[2], peak[3], peak[6], peak[7]
    if t_pk > 0 and peak[4] == 0.0 and h0 > 0 and h1 > 0:
        s01 = (fpk - fb) / h0
        s12 = (fa - fpk) / h1
        c = (s12 - s01) / (h0 + h1)
        if c < 0.0:
            b = s12 - c * h1  # slope at the maximum step: p(t) = fpk + b (t - t_pk) + c (t - t_pk)^2
            return float(fpk - 0.25 * b * b / c), float(t_pk - 0.5 * b / c)
    return float(fpk), float(t_pk)


def run_verlet(system: System, duration: float, sample_interval: float, dt: float | None = None,
               record_velocities: bool = False, contacts: np.ndarray | None = None,
               progress: Callable[[int, int], None] | None = None, chunk_steps: int = 2_000_000,
               record_positions: bool = False, steps_per_radian: float | None = None) -> RawRun:
    """Integrate ``system`` for ``duration`` [s] with the compiled velocity Verlet.

    Probes are sampled every ``sample_interval`` [s]; the step is ``dt`` [s], shortened if needed
    so that it divides the sample interval, or adaptive when None (see :func:`step_plan`). ``contacts`` lists the
    contact numbers whose forces are recorded (all when None). ``progress(done, total)``
    is called between chunks of about ``chunk_steps`` steps. ``steps_per_radian`` sets the
    adaptive step's accuracy (:func:`step_plan`).
    """
    plan = step_plan(system, sample_interval, dt, steps_per_radian)
    n_samples = int(math.floor(duration / sample_interval + 1e-9)) + 1
    nb = system.n_beads + 1
    w = pack(system)
    state = VerletState(w.u, w.v, np.zeros(w.n_slots), np.zeros(w.n_slots + 1), np.zeros(8))
    probes = new_probes(system, n_samples, contacts, record_velocities, record_positions)
    initialise_run(system, w, state, probes)

    samples_per_chunk = 1 if record_positions else max(1, round(chunk_steps * plan.dt / sample_interval))
    report_every = max(1, round(chunk_steps * plan.dt / sample_interval))
    reported = 1
    if progress is not None:
        progress(0, n_samples - 1)  # the checks passed and the work starts
    k = 1
    stepper = run_kernel(system.law, system.general, system.extended)  # hand-written, or generated from the law
    chain, contacts_, extension, control = w.chain(), w.contacts(), w.extension(), plan.control(sample_interval)
    while k < n_samples:
        k_stop = min(n_samples, k + samples_per_chunk)
        status = stepper(state, chain, contacts_, extension, probes, control, system.law, system.general, k, k_stop)
        if status != 0:
            used = _dt_used(plan, state.acc, sample_interval)[0]
            advice = (f"with run.dt = {dt:.3g} s; use a smaller run.dt (or leave it out for the automatic step)"
                      if dt is not None else f"with the automatic step (down to {used:.3g} s); check the inputs "
                      "(contact law parameters, masses, velocities) and report the case")
            raise SimulationDiverged(f"the integration diverged (non-finite state) before "
                                     f"t = {k_stop * sample_interval:.4g} s {advice}")
        if record_positions:
            probes.out_u[k] = w.u[:nb]
        k = k_stop
        if progress is not None and (k - reported >= report_every or k == n_samples):
            reported = k
            progress(k - 1, n_samples - 1)
    return raw_run(system, w, plan, probes, state.acc, sample_interval)


def new_probes(system: System, n_samples: int, contacts: np.ndarray | None, record_velocities: bool,
               record_positions: bool) -> VerletProbes:
    """The probes of a run of ``n_samples`` samples (uninitialised): the forces of the contacts
    ``contacts`` (all when None), velocities and positions of bodies 0..N when asked, the plastic
    work of the elastic-plastic law, the record of a protected body."""
    nc = system.n_contacts
    nb = system.n_beads + 1
    rec = np.arange(nc) if contacts is None else np.asarray(contacts, dtype=np.int64)
    plastic = system.law == kernels.LAW_ELASTOPLASTIC
    return VerletProbes(rec=rec, out_f=np.empty((n_samples, rec.size)), out_ke=np.empty(n_samples),
                        out_pe=np.empty(n_samples), out_ed=np.empty(n_samples),
                        out_wp=np.empty(n_samples if plastic else 1),
                        out_v=np.empty((n_samples if record_velocities else 1, nb)), record_v=bool(record_velocities),
                        out_u=np.empty((n_samples if record_positions else 1, nb)), record_u=bool(record_positions),
                        fmax=np.empty(nc), peak=np.empty(8), out_b=np.empty((n_samples if system.body else 0, 4)))


def initialise_run(system: System, w: Packed, state: VerletState, probes: VerletProbes) -> None:
    """:func:`initialise` of a run's structures (sample 0 of the positions too, when recorded)."""
    u, v, a, g, acc = state
    initialise(system, w, u, v, g, a, probes.rec, probes.out_f, probes.out_ke, probes.out_pe, probes.out_ed,
               probes.out_v, probes.record_v, probes.fmax, probes.peak, acc, probes.out_wp, out_b=probes.out_b)
    if probes.record_u:
        probes.out_u[0] = u[: probes.out_u.shape[1]]


def raw_run(system: System, w: Packed, plan: StepPlan, probes: VerletProbes, acc: np.ndarray,
            sample_interval: float) -> RawRun:
    """The :class:`RawRun` of a finished run: its probes, the refined wall peak, the steps used, the
    elastic-plastic law's final state."""
    nc = system.n_contacts
    plastic = system.law == kernels.LAW_ELASTOPLASTIC
    fpk, t_pk = refine_peak(probes.peak)
    dt_min, dt_max = _dt_used(plan, acc, sample_interval)
    return RawRun(time=np.arange(probes.out_ke.size) * sample_interval, contact_force=probes.out_f,
                  kinetic_energy=probes.out_ke, potential_energy=probes.out_pe, dissipated_energy=probes.out_ed,
                  velocity=probes.out_v if probes.record_v else None, max_force=probes.fmax, peak_wall_force=fpk,
                  peak_wall_time=t_pk, dt=dt_min, integrator="verlet", n_steps=int(acc[2]), contacts=probes.rec,
                  dt_max=dt_max, adaptive=plan.adaptive, displacement=probes.out_u if probes.record_u else None,
                  plastic_work=probes.out_wp if plastic else None,
                  residual_overlap=w.dres[:nc].copy() if plastic else None,
                  max_overlap=w.dmax[:nc].copy() if plastic else None,
                  body=probes.out_b if system.body else None)


def _dt_used(plan: StepPlan, acc: np.ndarray, sample_interval: float) -> tuple[float, float]:
    """Smallest and largest step [s] a run used (from the kernel's accumulators)."""
    if not plan.adaptive or acc[6] == 0:
        return plan.dt, plan.dt
    block = sample_interval / plan.n_sub
    return block / acc[6], block / acc[7]
