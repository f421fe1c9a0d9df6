"""Checks that keep a run from giving a silent wrong answer or from failing late.

Before a run (:func:`check_before_run`): the static overlap of a precompressed chain must stay in
the range of Hertz theory, and the records must fit in memory (:func:`estimate_resources`; a run
projected to take more than a few minutes is allowed with a :class:`~hertzchain.errors.LongRunWarning`).
After it (:func:`check_after_run`): the energy balance (kinetic + elastic + dissipated must not
grow: a run that gains energy is stopped with :class:`~hertzchain.errors.SimulationDiverged`
naming the cause), the overlaps the run reached (:class:`~hertzchain.errors.HertzRangeWarning`)
and whether the pulse reached the wall before the record ended
(:class:`~hertzchain.errors.PulseNotReachedWarning`).

The time step's own stability bound, damping included, is in
:meth:`hertzchain.model.System.max_frequency` and ``integrate.kernels.required_stride``.
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass

import numpy as np

from .bounds import TooManySteps, check_step_count
from .errors import ConfigError, HertzRangeWarning, LongRunWarning, PulseNotReachedWarning, SimulationDiverged
from .laws import spec_of

__all__ = ["ResourceEstimate", "estimate_resources", "check_resources", "check_before_run", "check_after_run",
           "preflight_batch", "duration_text", "run_time_hint",
           "check_energy_balance", "energy_gain", "estimate_memory", "energy_tolerance", "energy_cause", "available_memory",
           "process_baseline", "HERTZ_MAX_OVERLAP", "check_step_count",
           "LONG_RUN_S"]

#: Largest overlap delta / R_min (R_min the smaller radius of the pair) taken as inside the range of
#: Hertz theory (paper eq. 1 assumes a contact radius a = sqrt(R* delta) much smaller than R;
#: delta / R = 0.1 is a / R ~ 0.3 already). Independent of any yield stress.
HERTZ_MAX_OVERLAP = 0.1
#: A run projected to take longer than this [s] gets a LongRunWarning with the estimate.
LONG_RUN_S = 180.0
#: Cost of one bead-step of the compiled Verlet [s] (benchmarks/kernel.py: ~1.2 ns aligned
#: elastic; the general loop for dissipation or offsets is a few times slower), on one core.
#: ``"rkn4_general"``: rkn4 on the dissipative laws or offsets (integrate/drivers/rkn_damped.py: ~43 ns on
#: chain 1 with its dashpot, the probes apart: four force passes, the error bound and the events).
NS_PER_BEAD_STEP = {"elastic": 1.5e-9, "general": 6e-9, "rkn4": 1.2e-8, "rkn4_general": 4.5e-8}
#: The fourth-order integrator ``"rkn4"`` advances about this many radians of omega_max per step
#: at its default accuracy (an upper estimate of its steps; ~0.25 on the paper's chains).
RKN_RADIANS_PER_STEP = 0.1
#: solve_ivp (DOP853 at rtol ~1e-10) advances about this many radians of omega_max per step, at
#: about SCIPY_S_PER_STEP of Python overhead per step (plus the compiled forces).
SCIPY_RADIANS_PER_STEP = 0.05
SCIPY_S_PER_STEP = 2e-5
#: Share of the available memory a run may plan to use (the result is copied once when it is
#: assembled and written).
MEMORY_SHARE = 0.8
#: Bytes per recorded number: 12 when the records are written (the float64 record, which the
#: Dataset views, and the compressed file built in memory), 8 when they are only reduced to
#: numbers (a metrics-only sweep, a design generation). benchmarks/memory_estimates.py checks them.
BYTES_PER_VALUE, BYTES_PER_VALUE_UNWRITTEN = 12, 8
#: Resident memory of a process that has run the engine once [bytes]: the interpreter, NumPy,
#: SciPy, xarray, Numba and its kernels (~295 MiB measured, Linux x86-64, Python 3.11, the CLI's).
RUNTIME_BYTES = 300 * 2**20


def available_memory() -> int | None:
    """Memory available to a new allocation [bytes] (Linux MemAvailable), or None when unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


@dataclass(frozen=True)
class ResourceEstimate:
    """What a run will need, computed before anything is allocated.

    Attributes
    ----------
    samples : int
        Recorded time samples per member.
    signals : int
        Recorded numbers per sample and member (forces, energies, velocities, sensors).
    members : int
        Runs held in memory at once (1, or a sweep chunk).
    memory_bytes : int
        Memory the job allocates [bytes]: its records and the file built from them, if written.
    steps : float
        Time steps of one member (an upper estimate for the adaptive step).
    seconds : float
        Projected run time [s] on one core.
    process_bytes : int
        Resident memory of the process besides the job [bytes] (:func:`process_baseline`).
    """

    samples: int
    signals: int
    members: int
    memory_bytes: int
    steps: float
    seconds: float
    process_bytes: int = 0

    @property
    def peak_bytes(self) -> int:
        """The process's peak resident memory during the job [bytes]: ``process_bytes + memory_bytes``."""
        return self.process_bytes + self.memory_bytes


def process_baseline() -> int:
    """Resident memory a job starts from [bytes]: this process's now (Linux), at least :data:`RUNTIME_BYTES`."""
    try:
        with open("/proc/self/statm", encoding="ascii") as fh:
            return max(int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE"), RUNTIME_BYTES)
    except (OSError, ValueError, IndexError, AttributeError):
        return RUNTIME_BYTES


def estimate_resources(system, duration: float, probes, dt: float | None = None, members: int = 1,
                       integrator: str = "verlet", steps_per_radian: float | None = None,
                       written: bool = True) -> ResourceEstimate:
    """Samples x recorded signals x members and the steps for ``duration``, before any allocation.

    Parameters
    ----------
    system : hertzchain.model.System
        The model's arrays (``Model.system()``).
    duration : float
        Simulated time [s].
    probes : hertzchain.probes.Probes
        What is recorded, and how often.
    dt : float or None
        Fixed time step [s], or None for the adaptive one (its smallest step is used: an upper
        estimate of the step count).
    members : int
        Runs held in memory together (a sweep chunk).
    integrator : str
        ``"verlet"``, ``"rkn4"``, or a scipy method (``"dop853"``, ``"rk45"``; a rougher estimate).
    steps_per_radian : float or None
        Accuracy of the adaptive step (``run.steps_per_radian``; None: the default).
    written : bool
        Whether the records are written to a file (a result, a sweep chunk) or only reduced to numbers.

    Returns
    -------
    ResourceEstimate
        Samples, signals, members, memory [bytes], steps and seconds on one core.
    """
    n = system.n_beads
    samples, signals, memory = _records_size(n, system.has_wall, duration, probes, members, written)
    if integrator == "verlet":
        # imported here only: the Verlet module defines its kernels on import (0.3 CPU-s that an
        # rkn4 run, the default, never needs)
        from .integrate.drivers.verlet import step_plan

        plan = step_plan(system, probes.sample_interval, dt, steps_per_radian)
        steps = duration / plan.dt
        per = NS_PER_BEAD_STEP["general" if system.general else "elastic"]
        seconds = steps * (n + 1) * members * per
    elif integrator == "rkn4":
        steps = duration / dt if dt is not None else duration * system.max_frequency() / RKN_RADIANS_PER_STEP
        seconds = steps * (n + 1) * members * NS_PER_BEAD_STEP["rkn4_general" if system.general else "rkn4"]
    else:
        # solve_ivp: about SCIPY_RADIANS_PER_STEP of the fastest motion per step, each step a few
        # Python-level right-hand-side calls
        steps = duration * system.max_frequency() / SCIPY_RADIANS_PER_STEP
        seconds = steps * (SCIPY_S_PER_STEP + (n + 1) * NS_PER_BEAD_STEP["general"]) * members
    check_step_count(system, steps, duration, dt, integrator)
    return ResourceEstimate(samples=samples, signals=signals, members=members, memory_bytes=int(memory),
                            steps=steps, seconds=seconds, process_bytes=process_baseline())


def _records_size(n_beads: int, has_wall: bool, duration: float, probes, members: int,
                  written: bool = True) -> tuple[int, int, int]:
    """Samples per member, recorded numbers per sample and member, and the job's bytes."""
    samples = int(math.floor(duration / probes.sample_interval + 1e-9)) + 1
    recorded = probes.recorded_contacts(n_beads, has_wall).size
    bodies = (n_beads + 1) * (int(bool(probes.velocities)) + int(bool(getattr(probes, "positions", False))))
    signals = recorded + 3 + len(probes.sensors) + bodies  # the wall's contact among the recorded; 3 energies
    per_value = BYTES_PER_VALUE if written else BYTES_PER_VALUE_UNWRITTEN
    return samples, signals, per_value * samples * signals * members


def estimate_memory(n_beads: int, has_wall: bool, duration: float, probes, members: int = 1,
                    written: bool = False) -> ResourceEstimate:
    """:func:`estimate_resources` without the run time (``steps`` and ``seconds`` 0): what the
    records need, from the bead count alone (no System to build; a design search checks every
    generation).

    Parameters
    ----------
    n_beads : int
        Beads of the largest member.
    has_wall : bool
        Whether the chain ends at a wall (one more contact).
    duration : float
        Simulated time [s].
    probes : hertzchain.probes.Probes
        What is recorded, and how often.
    members : int
        Runs held in memory together.
    written : bool
        Whether the records are written to a file (a design generation's are not).

    Returns
    -------
    ResourceEstimate
    """
    samples, signals, memory = _records_size(n_beads, has_wall, duration, probes, members, written)
    return ResourceEstimate(samples=samples, signals=signals, members=members, memory_bytes=int(memory), steps=0.0,
                            seconds=0.0, process_bytes=process_baseline())


def _gib(x: float) -> str:
    return f"{x / 2**30:.3g} GiB"


def duration_text(seconds: float) -> str:
    """``about 21 h``, ``about 5 min``, ``about 40 s``: a projected time ``seconds`` [s] in words,
    rounded in the largest unit that fits."""
    for unit, size in (("days", 86400.0), ("h", 3600.0), ("min", 60.0)):  # noqa: B007 (read after the break)
        if seconds >= 2 * size:
            break
    else:
        unit, size = "s", 1.0
    value = seconds / size
    return f"about {value:.0f} {unit}" if value >= 10 else f"about {value:.2g} {unit}"


def check_resources(est: ResourceEstimate, *, memory_field: str = "run.duration",
                    available: int | None = None, time_hint: str | None = None,
                    memory_hint: str | None = None) -> None:
    """Refuse a job whose records cannot fit in memory (ConfigError naming ``memory_field``); warn
    (:class:`~hertzchain.errors.LongRunWarning`, before any work) when it is projected to take
    more than LONG_RUN_S, with the time, the memory and what to change.

    Parameters
    ----------
    est : ResourceEstimate
        From :func:`estimate_resources`.
    memory_field : str
        The input field to change when the records do not fit.
    available : int or None
        Memory available [bytes]; :func:`available_memory` when None.
    time_hint : str or None
        What to change to make it faster, naming the field (``run.dt``, the number of members);
        default: a shorter run.duration or a smaller model.
    memory_hint : str or None
        What to change to make it fit; default: shorten run.duration, raise run.sample_interval
        or record fewer contacts (probes.contacts).
    """
    available = available_memory() if available is None else available
    if available is not None and est.memory_bytes > MEMORY_SHARE * available:
        raise ConfigError(memory_field, f"the run would record {est.samples:,} samples x {est.signals:,} signals"
                          + (f" x {est.members:,} members" if est.members > 1 else "")
                          + f", about {_gib(est.memory_bytes)}, more than the {_gib(available)} of memory "
                          "available; " + (memory_hint or "shorten run.duration, raise run.sample_interval or record "
                                           "fewer contacts (probes.contacts)"))
    if est.seconds > LONG_RUN_S:
        warnings.warn(LongRunWarning(
            f"this run is projected to take {duration_text(est.seconds)} ({est.steps:.3g} time steps"
            + (f" x {est.members:,} members" if est.members > 1 else "")
            + f", records of {_gib(est.memory_bytes)}); it goes on (Ctrl-C stops it), but "
            + (time_hint or "a shorter run.duration or a smaller model would be faster")), stacklevel=3)


def run_time_hint(dt: float | None) -> str | None:
    """What makes a single run faster, naming ``run.dt`` when the user fixed the step.

    Parameters
    ----------
    dt : float or None
        The user's fixed step [s] (None: automatic).

    Returns
    -------
    str or None
        The hint (None: the default one).
    """
    if dt is None:
        return None
    return (f"the time step run.dt = {dt:g} s sets the number of steps: leave it out (the automatic step) or raise "
            "it; a shorter run.duration or a smaller model would be faster too")


def preflight_batch(models, duration: float, probes, dt=None, *, n_threads: int | None = None,
                    steps_per_radian: float | None = None, members_field: str = "models",
                    on_gpu: bool = False) -> ResourceEstimate:
    """The pre-flight of a batch (:func:`hertzchain.simulate_batch`, :func:`hertzchain.simulate_many`):
    memory and time estimated before anything is set up or allocated.

    The records of every member are held at once (BYTES_PER_VALUE per recorded number); the
    time is that of the member with the most beads, times the members, over the threads.

    Parameters
    ----------
    models : sequence of Model or Ensemble
        The members.
    duration : float
        Simulated time [s].
    probes : Probes or sequence of Probes or None
        What each member records (None: the default Probes).
    dt : float, sequence or None
        The members' fixed steps [s] (None: automatic).
    n_threads : int or None
        Threads of the engine (None: every core Numba sees).
    steps_per_radian : float or None
        Accuracy of the adaptive step.
    members_field : str
        How the caller names the members (the field of the error).
    on_gpu : bool
        The batch runs on a GPU: the time per bead-step measured on the CPU does not apply, so
        only the memory is checked.

    Returns
    -------
    ResourceEstimate
        The batch's estimate (``seconds`` on ``n_threads`` cores).

    Raises
    ------
    ConfigError
        The records cannot fit in memory (naming ``probes.contacts`` and the number of members).
    """
    from dataclasses import replace

    import numba

    from .probes import Probes

    if hasattr(models, "n_members"):  # an Ensemble: one layout
        n, n_beads, has_wall = int(models.n_members), int(models.n_beads), bool(models.has_wall)
        big = 0
        member = models.model(0)
    else:
        models = list(models)
        n = len(models)
        beads = [m.chain.n_beads for m in models]
        big = int(np.argmax(beads))
        member, n_beads, has_wall = models[big], beads[big], any(m.wall.present for m in models)
    if isinstance(probes, Probes) or probes is None:
        plist = [probes or Probes()]
    else:
        plist = [p or Probes() for p in probes]
    p = plist[big] if len(plist) > big else plist[0]
    mem = estimate_memory(n_beads, has_wall, duration, p, n)
    step = dt[big] if isinstance(dt, (list, tuple, np.ndarray)) else dt
    step = float(step) if step is not None and float(step) > 0 else None  # NaN: the automatic step
    threads = n_threads or numba.config.NUMBA_NUM_THREADS  # type: ignore[attr-defined]  # numba sets it at import
    try:
        one = replace(mem, steps=0.0, seconds=0.0)
        if not on_gpu:
            one = estimate_resources(member.system(), duration, p, dt=step, steps_per_radian=steps_per_radian)
    except ConfigError as exc:  # a bad step: the set-up reports it, naming the member
        if isinstance(exc, TooManySteps):
            raise
        one = replace(mem, steps=0.0, seconds=0.0)
    est = replace(mem, steps=one.steps, seconds=one.seconds * n / max(1, min(threads, n)))
    check_resources(est, memory_field="probes.contacts",
                    memory_hint=f"record fewer contacts (probes.contacts: {p.recorded_contacts(n_beads, has_wall).size}"
                                " a member now), raise probes.sample_interval, shorten the duration, or split the "
                                f"{n:,} members ({members_field}) into smaller batches",
                    time_hint=f"split the {n:,} members ({members_field}) into smaller batches, or shorten the duration")
    return est


def smaller_radii(striker_diameter: np.ndarray, diameters: np.ndarray) -> np.ndarray:
    """Smaller radius of the two bodies of every contact 0..N [m] (the wall is a flat), per member.

    Parameters
    ----------
    striker_diameter : numpy.ndarray
        (M,) striker diameters [m].
    diameters : numpy.ndarray
        (M, N) bead diameters [m].

    Returns
    -------
    numpy.ndarray
        (M, N + 1); the last column is bead N against the wall.
    """
    r = np.concatenate([np.asarray(striker_diameter, float)[:, None], np.asarray(diameters, float)], axis=1) / 2
    return np.concatenate([np.minimum(r[:, :-1], r[:, 1:]), r[:, -1:]], axis=1)


def _smaller_radius(model) -> np.ndarray:
    """:func:`smaller_radii` of one model (a flat striker face: bead 1's radius; a curved one: the
    smaller of its radius of curvature and bead 1's)."""
    face = model.body0.face_radius
    if face is None:  # no beads: a flat striker meets the body's curved face
        face = model.chain.radii[0] if model.chain.n_beads else (model.wall.face_radius or model.body0.diameter / 2)
    size = 2.0 * face
    return smaller_radii(np.array([size]), model.chain.diameters[None, :])[0]


def check_before_run(model, system, duration: float, probes, *, dt: float | None = None,
                     integrator: str = "verlet") -> ResourceEstimate:
    """Hertz range of the static overlaps and the resources, before anything is allocated.

    Parameters
    ----------
    model : hertzchain.model.Model
        The model (for the radii).
    system : hertzchain.model.System
        ``model.system()``.
    duration : float
        Simulated time [s].
    probes : hertzchain.probes.Probes
        What is recorded.
    dt : float or None
        Fixed step [s] or None (adaptive).
    integrator : str
        ``"verlet"``, ``"rkn4"``, ``"dop853"`` or ``"rk45"``.

    Returns
    -------
    ResourceEstimate
        The estimate the checks used.
    """
    if np.any(system.d0 > 0):
        ratio = system.d0 / _smaller_radius(model)
        j = int(np.argmax(ratio))
        if ratio[j] > HERTZ_MAX_OVERLAP:
            what, key = ((f"{model.precompression:g} N", "chain.precompression") if model.precompression > 0 else
                         (f"gravity ({model.gravity:g} m/s^2)", "chain.gravity"))
            raise ConfigError(key, f"{what} squeezes contact {j} by "
                              f"{ratio[j]:.3g} times the smaller bead radius; Hertz contact (paper eq. 1) holds for "
                              f"overlaps below {HERTZ_MAX_OVERLAP:g} R. Lower the static load")
    est = estimate_resources(system, duration, probes, dt=dt, integrator=integrator)
    check_resources(est, time_hint=run_time_hint(dt))
    return est


def check_energy_balance(time: np.ndarray, kinetic: np.ndarray, potential: np.ndarray, dissipated: np.ndarray,
                         *, tolerance: float, cause: str) -> None:
    """Stop a run whose energy balance grows (SimulationDiverged, naming ``cause``).

    Kinetic + elastic (Hertz potential, paper Sec. III) + dissipated energy is constant for the
    exact motion; a numerical gain larger than ``tolerance`` times the initial energy means the
    integration is wrong (a step too large for the stiffness or the damping).

    Parameters
    ----------
    time : numpy.ndarray
        Sample times [s].
    kinetic, potential, dissipated : numpy.ndarray
        Energies [J] at the samples (``dissipated``: every loss, viscous and plastic).
    tolerance : float
        Allowed relative gain.
    cause : str
        What to change, named as the user wrote it (``run.dt``, ``contact.gamma``...).
    """
    gain = energy_gain(kinetic, potential, dissipated)
    bad = ~np.isfinite(gain) | (gain > tolerance)
    if np.any(bad):
        k = int(np.argmax(bad))
        what = "became non-finite" if not np.isfinite(gain[k]) else f"grew by {gain[k]:.3g} of its initial value"
        raise SimulationDiverged(f"the run gains energy: kinetic + elastic + dissipated energy {what} at "
                                 f"t = {time[k]:.4g} s (allowed: {tolerance:.2g}); the results would be wrong. "
                                 f"Cause: {cause}")


def energy_gain(kinetic: np.ndarray, potential: np.ndarray, dissipated: np.ndarray) -> np.ndarray:
    """Gain of kinetic + elastic + dissipated energy since the first sample, relative to the
    initial kinetic + elastic energy (0 for the exact motion; see :func:`check_energy_balance`).

    Parameters
    ----------
    kinetic, potential, dissipated : numpy.ndarray
        Energies [J], samples along the last axis (one row per run of a batch).

    Returns
    -------
    numpy.ndarray
        The relative gain at every sample (0 throughout for a run that starts with no energy).
    """
    gain = kinetic + potential
    gain += dissipated
    gain -= gain[..., :1].copy()
    scale = np.abs(kinetic[..., :1]) + np.abs(potential[..., :1])
    if np.all(scale > 0):  # in place: a run's check is ~4 passes over its samples instead of ~7
        gain /= scale
        return gain
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(scale > 0, gain / scale, 0.0)


def energy_tolerance(system, dt_max: float, integrator: str = "verlet", rtol: float | None = 1e-10) -> float:
    """Relative energy gain a correct run may show (see :func:`check_energy_balance`).

    Verlet conserves a shadow energy; the true one oscillates by O((omega dt)^2) (about 1 % at the
    largest user step allowed, omega dt = MAX_OMEGA_DT = 0.5; ~1e-7 with the adaptive step), so
    the allowance follows the largest step used, up to that of the largest step allowed, and is
    at least 1e-3. The scipy integrators are stable but their error control lets the energy
    wander by 10-100 ``rtol`` (chain 1: RK45 at rtol 1e-5 gains 1e-3), so there the allowance is
    1000 ``rtol``, at least 1e-2: only a gross failure is stopped. The fourth-order ``"rkn4"``
    keeps the energy within ~1e-8 at its default tolerance: the floor 1e-3 applies.

    Parameters
    ----------
    system : hertzchain.model.System
        The model's arrays.
    dt_max : float
        Largest Verlet step used [s].
    integrator : str
        ``"verlet"``, ``"rkn4"``, ``"dop853"`` or ``"rk45"``.
    rtol : float or None
        Relative tolerance of the scipy integrators (None: their default, 1e-10).

    Returns
    -------
    float
        The tolerance, relative to the initial energy.
    """
    if integrator == "rkn4":
        return 1e-3
    if integrator != "verlet":
        return max(1e-2, 1e3 * (1e-10 if rtol is None else rtol))
    from .integrate.drivers.verlet import MAX_OMEGA_DT

    if not dt_max > 0:  # no step to follow (system may then be None): the floor
        return 1e-3
    return max(1e-3, 0.1 * min(system.max_frequency() * dt_max, MAX_OMEGA_DT) ** 2)


def energy_cause(model, dt: float | None, integrator: str = "verlet") -> str:
    """What to change when a run gains energy, named as the user wrote it.

    Parameters
    ----------
    model : hertzchain.model.Model
        The model.
    dt : float or None
        The user's fixed step [s] (None: automatic).
    integrator : str
        ``"verlet"``, ``"rkn4"``, ``"dop853"`` or ``"rk45"``.

    Returns
    -------
    str
        A sentence naming ``run.dt``, ``contact.gamma``, ``contact.A`` or ``run.rtol``.
    """
    if integrator == "rkn4" and dt is None:
        return "the step control's tolerance run.rtol is too loose for this model; lower it"
    if integrator not in ("verlet", "rkn4"):
        return "the solver tolerance run.rtol is too loose; lower it"
    if dt is not None:
        return f"the time step run.dt = {dt:g} s is too large for this model; lower it or leave it out"
    spec = spec_of(model.law)
    if spec.calibrated or (spec.plastic and model.law.parameter > 0):
        key = f"contact.{spec.calibrated or 'A'}"
        return (f"the automatic step could not follow the damping of {key} = {model.law.parameter:g}; "
                "lower it or give a smaller run.dt")
    return "the automatic step could not follow the model; give a smaller run.dt and report the case"


def check_after_run(ds, model, system, *, dt: float | None = None, integrator: str = "verlet",
                    rtol: float = 1e-10, stacklevel: int = 2) -> None:
    """Energy balance, Hertz range of the overlaps reached, and the pulse's arrival at the wall.

    Parameters
    ----------
    ds : xarray.Dataset
        The result (:func:`hertzchain.simulate`).
    model : hertzchain.model.Model
        The model it came from.
    system : hertzchain.model.System
        ``model.system()``.
    dt : float or None
        The user's fixed step [s] (None: automatic).
    integrator : str
        ``"verlet"``, ``"rkn4"``, ``"dop853"`` or ``"rk45"``.
    rtol : float or None
        Relative tolerance of the scipy integrators (None: their default, 1e-10).
    stacklevel : int
        Passed to :func:`warnings.warn`.

    Raises
    ------
    SimulationDiverged
        The run gained energy (see :func:`check_energy_balance`).
    """
    tolerance = energy_tolerance(system, float(ds.attrs.get("dt_max") or ds.attrs["dt"]), integrator, rtol)
    var = ds.variables  # the arrays without a DataArray each (~20 us apiece)
    lost = var["dissipated_energy"].values
    if "plastic_work" in var:  # the elastoplastic law: plastic work is energy lost too
        lost = lost + var["plastic_work"].values
    check_energy_balance(var["time"].values, var["kinetic_energy"].values, var["potential_energy"].values,
                         lost, tolerance=tolerance, cause=energy_cause(model, dt, integrator))

    nc = system.n_contacts
    fmax = var["max_contact_force"].values
    kap = system.kappa[:nc]
    with np.errstate(divide="ignore", invalid="ignore"):
        overlap = np.where(kap > 0, (np.maximum(fmax, 0.0) / np.where(kap > 0, kap, 1.0)) ** (2.0 / 3.0), 0.0)
    if "max_overlap" in ds:  # past yield the overlap is deeper than Hertz's at that force
        overlap = np.maximum(overlap, ds.max_overlap.values)
    ratio = overlap / _smaller_radius(model)[:nc]
    if ratio.size and ratio.max() > HERTZ_MAX_OVERLAP:
        j = int(np.argmax(ratio))
        warnings.warn(HertzRangeWarning(
            f"contact {j} was compressed by {ratio[j]:.3g} times the smaller bead radius, beyond the range of "
            f"Hertz contact (overlaps below {HERTZ_MAX_OVERLAP:g} R, paper eq. 1): the forces are not physical; "
            "lower striker.velocity"), stacklevel=stacklevel + 1)

    if model.wall.present and nc > 1:
        # the impact's part of each force: a precompressed (or weighed) chain carries its static load
        # from the start
        _warn_pulse_not_reached(ds, fmax - system.static_forces()[:nc], nc, stacklevel + 1)


def _warn_pulse_not_reached(ds, fmax: np.ndarray, nc: int, stacklevel: int) -> None:
    """Warn when the wall contact never carried a pulse: the record ended before it arrived."""
    loaded = fmax > 1e-6 * fmax.max() if fmax.max() > 0 else np.zeros(nc, bool)
    if loaded[nc - 1]:
        return
    reached = int(np.flatnonzero(loaded).max()) if loaded.any() else 0
    duration = float(ds.attrs["duration"] if "duration" in ds.attrs else ds["time"].values[-1])
    estimate = ""
    if reached > 0:
        # the front moved `reached` contacts in `duration`: the wall is about (nc - 1) / reached as far
        estimate = f" (at this pace it would arrive near t = {duration * (nc - 1) / reached:.3g} s)"
    warnings.warn(PulseNotReachedWarning(
        f"the record ends (run.duration = {duration:g} s) before the pulse reaches the wall: the front got to "
        f"contact {reached} of {nc - 1}{estimate}; the wall force is 0 N because nothing arrived yet. "
        "Lengthen run.duration"), stacklevel=stacklevel + 1)


def warn_members_hertz_range(fmax: np.ndarray, kappa: np.ndarray, smaller_radius: np.ndarray,
                             stacklevel: int = 2) -> None:
    """The Hertz-range check of :func:`check_after_run` for a batch: ONE warning naming the members
    whose largest contact force compressed a contact beyond ``HERTZ_MAX_OVERLAP`` of the smaller
    radius (paper eq. 1 holds for small overlaps only).

    Parameters
    ----------
    fmax, kappa, smaller_radius : numpy.ndarray
        (member, contact): every contact's largest force [N], its Hertz stiffness kappa
        [N m^-3/2] and the smaller radius of its two bodies [m]; NaN where a member has no such
        contact.
    stacklevel : int
        Passed to :func:`warnings.warn`.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        overlap = np.where(kappa > 0, (np.maximum(fmax, 0.0) / np.where(kappa > 0, kappa, 1.0)) ** (2.0 / 3.0), 0.0)
        ratio = np.nan_to_num(overlap / smaller_radius, nan=0.0)
    if ratio.size == 0:
        return
    worst = ratio.max(axis=1)
    over = np.flatnonzero(worst > HERTZ_MAX_OVERLAP)
    if over.size == 0:
        return
    i = int(over[np.argmax(worst[over])])
    j = int(np.argmax(ratio[i]))
    some = ", ".join(str(k) for k in over[:8].tolist()) + (", ..." if over.size > 8 else "")
    warnings.warn(HertzRangeWarning(
        f"{over.size} of {ratio.shape[0]} members (member {some}) compressed a contact beyond the range of Hertz "
        f"contact (overlaps below {HERTZ_MAX_OVERLAP:g} R, paper eq. 1); worst: member {i}, contact {j}, "
        f"{ratio[i, j]:.3g} times the smaller bead radius. Their forces are not physical: lower the striker "
        "velocity"), stacklevel=stacklevel + 1)


def warn_members_pulse_not_reached(ds, stacklevel: int = 2) -> None:
    """The pulse-arrival check of :func:`check_after_run` for a batch: ONE warning naming the members
    on a wall whose wall contact never carried a pulse (the record ended before it arrived).

    Parameters
    ----------
    ds : xarray.Dataset
        A :func:`hertzchain.simulate_batch` result (``max_contact_force`` (member, contact_all),
        ``n_contacts``, ``has_wall``, ``duration`` attribute).
    stacklevel : int
        Passed to :func:`warnings.warn`.
    """
    if ds.sizes.get("member", 0) == 0 or "max_contact_force" not in ds:
        return
    fmax = ds["max_contact_force"].values
    nc = ds["n_contacts"].values.astype(np.int64)
    on_wall = ds["has_wall"].values.astype(bool) & (nc > 1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN rows of members without contacts
        top = np.nanmax(fmax, axis=1)
    wall = fmax[np.arange(fmax.shape[0]), np.maximum(nc - 1, 0)]
    # a precompressed member's wall contact carries F0 from the start and is never flagged
    missed = np.flatnonzero(on_wall & ~(wall > 1e-6 * np.where(top > 0, top, np.inf)))
    if missed.size == 0:
        return
    duration = float(ds.attrs.get("duration", ds["time"].values[-1]))
    some = ", ".join(str(i) for i in missed[:8].tolist()) + (", ..." if missed.size > 8 else "")
    warnings.warn(PulseNotReachedWarning(
        f"{missed.size} of {fmax.shape[0]} members (member {some}): the record ends (duration = {duration:g} s) "
        "before the pulse reaches the wall; their wall force is 0 N because nothing arrived yet. Lengthen the "
        "duration (hertzchain.auto_duration(model) gives one long enough)"), stacklevel=stacklevel + 1)

