"""Run a driven chain (``Model.drive``): the step, the pre-flight checks, the compiled loop of
:mod:`hertzchain.crystal.drive_kernel` and the result Dataset (the engine's, plus the drive's
records). :func:`hertzchain.simulate` hands a model with a drive here.

The step is fixed: dt = 1 / (steps_per_radian omega_max), omega_max a Gershgorin bound of the
chain linearised at every contact's static force plus DRIVE_FORCE_FACTOR times the drive's force
amplitude (the chain can ring up near a resonance; a registry law's tangent stiffness from its
partials there), and at most 1 / (MIN_STEPS_PER_PERIOD f_max).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

import numba
import numpy as np

from ..checks import check_before_run
from ..errors import ConfigError, SimulationDiverged
from ..integrate.core.layout import pack
from ..integrate.core.generated import is_generated
from ..integrate.core.primitives import LAW_DASHPOT, LAW_ELASTIC, LAW_VISCOELASTIC
from ..integrate.drivers.verlet import RawRun, check_time_step
from ..laws import law_of_code
from .drive import drive_parameters, drive_table
from .drive_kernel import _accelerations, kernels_for

__all__ = ["simulate_driven", "run_driven_batch", "drive_step", "DEFAULT_STEPS_PER_RADIAN",
           "MIN_SAMPLES_PER_PERIOD", "MAX_DRIVE_STEPS"]

#: Default accuracy of the driven run's fixed step: omega_max dt = 1 / 100 (Verlet's frequency error
#: (omega dt)^2 / 24 ~ 4e-6 at the top of the spectrum, far less at the drive frequencies).
DEFAULT_STEPS_PER_RADIAN = 100.0
#: The dynamic force a contact may reach, in drive force amplitudes (for the step's stiffness bound).
DRIVE_FORCE_FACTOR = 10.0
#: Steps per period of the highest drive frequency, at least.
MIN_STEPS_PER_PERIOD = 50
#: Samples per period of the highest drive frequency, at least (a lock-in over whole periods).
MIN_SAMPLES_PER_PERIOD = 8
#: Steps a driven run may take (a few minutes of a short chain on one core).
MAX_DRIVE_STEPS = 1_000_000_000
#: Bytes the records of a driven run may take.
MAX_RECORD_BYTES = 4 * 2**30


def drive_force_amplitude(system, drive) -> float:
    """Force amplitude [N] the drive applies to bead 1: A (force), or the Hertz force of contact 0
    compressed by A beyond its static overlap (displacement), kappa_0 (delta_0 + A)^(3/2)."""
    amplitude = float(np.max(np.abs(drive.table[1]))) if drive.type == "history" else drive.amplitude
    if drive.quantity == "force":
        return amplitude
    spec = law_of_code(system.law)
    if spec.generated:  # the law's own force at that overlap, at rest
        return float(spec.force(system.d0[0] + amplitude, 0.0, system.kappa[0], system.damping[0], 0.0))
    return float(system.kappa[0] * (system.d0[0] + amplitude) ** 1.5)


def drive_step(system, drive, steps_per_radian: float | None = None) -> float:
    """The fixed step [s] of a driven run (see the module docstring)."""
    c = DEFAULT_STEPS_PER_RADIAN if steps_per_radian is None else float(steps_per_radian)
    from .statics import held_forces

    n = system.n_beads
    held = held_forces(system.fext, system.kappa, n)[: n + 1]
    force = held + DRIVE_FORCE_FACTOR * drive_force_amplitude(system, drive)
    kap = system.kappa
    spec = law_of_code(system.law)
    if spec.generated:  # a registry law: its force inverted and its tangent stiffness (its partials)
        from ..laws.solve import static_overlap

        dmax = np.array([static_overlap(spec, f, kk, p) if kk > 0 and f > 0 else 0.0
                         for f, kk, p in zip(force, kap, system.damping)])
        dmax = np.maximum(dmax, system.max_overlap())
        k = np.array([abs(spec.partials(d, 0.0, kk, p, 1.0)[0]) if kk > 0 and d > 0 else 0.0
                      for d, kk, p in zip(dmax, kap, system.damping)])
    else:
        with np.errstate(divide="ignore"):
            dmax = np.where(kap > 0, (force / np.where(kap > 0, kap, 1.0)) ** (2.0 / 3.0), 0.0)
        dmax = np.maximum(dmax, system.max_overlap())  # the striker's impact, when there is one
        k = 1.5 * kap * np.sqrt(dmax)
    nb = system.n_moving
    k = np.append(k, system.mount_k if system.body else 0.0)[: nb + 1]
    kin = np.zeros(nb) if system.res_k is None else system.res_k[:nb]
    omega2 = 2.0 * (np.concatenate([[0.0], k[: nb - 1]]) + k[:nb] + kin) * system.inv_mass[:nb]
    c_d = system.damping_coefficients(dmax)
    c_d = np.append(c_d, system.mount_c if system.body else 0.0)[: nb + 1]
    beta = 2.0 * (np.concatenate([[0.0], c_d[: nb - 1]]) + c_d[:nb]) * system.inv_mass[:nb]
    w = float(np.max(np.sqrt(omega2 + 0.25 * beta**2) + 0.5 * beta))
    if system.res_k is not None and np.any(system.res_m > 0):
        inner = system.res_m > 0
        w = max(w, float(np.max(np.sqrt(2.0 * system.res_k[inner] / system.res_m[inner]))))
    # and at least MIN_STEPS_PER_PERIOD steps per period of the drive
    return min(1.0 / (c * w), 1.0 / (MIN_STEPS_PER_PERIOD * drive.highest_frequency))


def _preflight(drive, duration: float, sample_interval: float, dt: float, n_rec: int, n_samples: int,
               given_dt: bool) -> None:
    """Refuse what the step or the samples do not resolve, and runs too long or too big."""
    f = drive.highest_frequency
    if given_dt and 1.0 / (f * dt) < MIN_STEPS_PER_PERIOD:
        raise ConfigError("drive.frequency", f"{f:.4g} Hz is beyond what run.dt = {dt:.3g} s resolves (at least "
                          f"{MIN_STEPS_PER_PERIOD} steps per period): lower it below {1.0 / (MIN_STEPS_PER_PERIOD * dt):.4g} "
                          "Hz or shorten run.dt (or leave run.dt out for the automatic step)")
    if drive.type != "history" and 1.0 / (f * sample_interval) < MIN_SAMPLES_PER_PERIOD:
        raise ConfigError("run.sample_interval", f"{sample_interval:.3g} s does not resolve the drive's {f:.4g} Hz "
                          f"(at least {MIN_SAMPLES_PER_PERIOD} samples per period): make it at most "
                          f"{1.0 / (MIN_SAMPLES_PER_PERIOD * f):.3g} s (or lower drive.frequency)")
    steps = duration / dt
    if steps > MAX_DRIVE_STEPS:
        raise ConfigError("run.duration", f"{duration:.4g} s of driven run takes {steps:.3g} steps of {dt:.3g} s, "
                          f"more than the {MAX_DRIVE_STEPS:.0e} allowed: shorten run.duration or drive fewer cycles")
    size = n_samples * (n_rec + 10) * 8
    if size > MAX_RECORD_BYTES:
        raise ConfigError("run.sample_interval", f"the driven run's records would take {size / 2**30:.3g} GiB "
                          f"(more than {MAX_RECORD_BYTES / 2**30:.0f} GiB): raise run.sample_interval, shorten "
                          "run.duration or record fewer contacts (probes.contacts)")


@dataclass
class _Member:
    """One driven run set up: its step, samples, packed arrays, state and records at t = 0."""

    system: object
    step: float
    stride: int
    n_samples: int
    rec: np.ndarray
    w: object
    u: np.ndarray
    v: np.ndarray
    a: np.ndarray
    wa: np.ndarray
    vp: np.ndarray
    g: np.ndarray
    out_f: np.ndarray
    out_e: np.ndarray
    out_b: np.ndarray
    fmax: np.ndarray
    acc: np.ndarray
    params: np.ndarray
    tt: np.ndarray
    vv: np.ndarray
    displacement: bool


def _check_driven(model, system, probes, integrator: str, threads: int) -> None:
    if integrator != "verlet":
        raise ConfigError("run.integrator", f"a driven chain runs on 'verlet' (a fixed step), not {integrator!r}")
    # the laws forces_general computes, and every registry law through its generated force loop
    if system.law not in (LAW_ELASTIC, LAW_VISCOELASTIC, LAW_DASHPOT) and not is_generated(system.law):
        raise ConfigError("contact.law", f"a driven chain takes the elastic, viscoelastic or dashpot laws (and "
                          f"their size-scaled forms) and the registry's laws; {model.law.name!r} is not supported "
                          "under a drive")
    if threads != 1:
        raise ConfigError("run.threads", "a driven chain runs on one thread: leave run.threads out")
    if probes.velocities or probes.positions:
        raise ConfigError("probes.velocities" if probes.velocities else "probes.positions",
                          "is not recorded for a driven chain (drive_displacement and the contact forces are)")


def _set_up(model, system, duration: float, probes, dt: float | None, steps_per_radian: float | None) -> _Member:
    """Step, pre-flight (the drive's and the engine's checks) and the state at t = 0 of one driven run."""
    drive = model.drive
    if dt is not None:
        check_time_step(system, dt)
    step = drive_step(system, drive, steps_per_radian) if dt is None else dt
    interval = probes.sample_interval
    stride = max(1, math.ceil(interval / step - 1e-9))
    step = interval / stride
    n_samples = int(math.floor(duration / interval + 1e-9)) + 1
    rec = probes.recorded_contacts(model.chain.n_beads, model.wall.present)
    _preflight(drive, duration, interval, step, rec.size, n_samples, dt is not None)
    # the engine's own checks: the static overlaps within Hertz's range, memory and run time
    check_before_run(model, system, duration, probes, dt=step, integrator="verlet")
    w = pack(system)
    p_slots = w.n_slots
    m = _Member(system=system, step=step, stride=stride, n_samples=n_samples, rec=rec, w=w, u=w.u, v=w.v,
                a=np.zeros(p_slots), wa=np.zeros(p_slots), vp=np.zeros(p_slots + 1), g=np.zeros(p_slots + 1),
                out_f=np.empty((n_samples, rec.size)), out_e=np.empty((n_samples, 6)),
                out_b=np.empty((n_samples if system.body else 1, 4)), fmax=np.full(system.n_contacts, -np.inf),
                acc=np.zeros(7), params=drive_parameters(drive), tt=drive_table(drive)[0], vv=drive_table(drive)[1],
                displacement=drive.quantity == "displacement")
    forces, record, _, _ = kernels_for(system.law)
    # t = 0: the static state (the drive starts at s(0) = 0 with the ramp)
    m.vp[:] = m.v
    m.acc[1] = forces(m.u, m.vp, m.g, w.kappa, w.damping, w.d0, w.de, w.dx0, w.rsum, system.law, w.dyield, w.dmax,
                      w.dres, w.kres, w.ext, system.extended)
    _accelerations(m.u, m.g, w.fext, w.inv_mass, w.ext, system.extended, m.a, m.wa)
    record(0, m.u, m.v, m.a, m.g, w.mass, w.kappa, w.damping, w.d0, w.de, w.dx0, w.rsum, w.fext, w.ext,
           system.extended, rec, m.out_f, m.out_e, m.fmax, m.acc, m.g[1] if m.displacement else 0.0, 0.0,
           w.body_slot, m.out_b)
    return m


def _diverged(until: float, step: float) -> SimulationDiverged:
    return SimulationDiverged(f"the driven integration diverged (non-finite state) before t = {until:.4g} s with the "
                              f"step {step:.3g} s; lower drive.amplitude or run.dt, and check the inputs")


def simulate_driven(model, system, duration: float, probes, *, integrator: str = "verlet", dt: float | None = None,
                    threads: int = 1, progress=None, config: dict | None = None,
                    steps_per_radian: float | None = None, extra_attrs: dict | None = None):
    """Simulate a model with a drive; the engine's Dataset plus ``drive_force`` [N] (on bead 1),
    ``drive_displacement`` [m] (the driver's position, or bead 1's under a force drive) and
    ``drive_work`` [J] (work the drive has done), and the attribute ``drive`` (its description).

    The driven loop is velocity Verlet on a fixed step (:func:`drive_step` unless ``dt`` [s] is
    given); probe velocities and positions are not recorded on this path (refused). A drive
    entering at bead N runs the chain read from there (:mod:`hertzchain.crystal.ends`).
    """
    from ..result import build_dataset
    from .ends import dataset_to_model_numbers, driven_from_last, from_driven_end, mirrored_probes

    if driven_from_last(model):  # the chain read from bead N: one code path for both ends (ends.py)
        turned = from_driven_end(model)
        ds = simulate_driven(turned, turned.system(), duration, mirrored_probes(probes, model.chain.n_beads),
                             integrator=integrator, dt=dt, threads=threads, progress=progress, config=config,
                             steps_per_radian=steps_per_radian, extra_attrs=extra_attrs)
        ds = dataset_to_model_numbers(ds, model)
        ds["drive_force"].attrs["long_name"] = "drive force on bead N"
        ds["drive_displacement"].attrs["long_name"] = "driver position (force drive: bead N displacement), towards the wall"
        return ds
    drive = model.drive
    _check_driven(model, system, probes, integrator, threads)
    m = _set_up(model, system, duration, probes, dt, steps_per_radian)
    w, step, stride, n_samples, rec = m.w, m.step, m.stride, m.n_samples, m.rec
    interval = probes.sample_interval
    run = kernels_for(system.law)[2]
    if progress is not None:
        progress(0, n_samples - 1)
    chunk = max(1, int(2_000_000 // stride))
    k = 1
    while k < n_samples:
        k_stop = min(n_samples, k + chunk)
        status = run(m.u, m.v, m.a, m.wa, m.vp, m.g, w.mass, w.inv_mass, w.kappa, w.damping, w.d0, w.de, w.dx0, w.rsum,
                     w.fext, w.dyield, w.dmax, w.dres, w.kres, system.law, w.ext, system.extended, m.params, m.tt, m.vv,
                     m.displacement, step, stride, k, k_stop, rec, m.out_f, m.out_e, m.fmax, m.acc, w.body_slot,
                     m.out_b)
        if status != 0:
            raise _diverged(k_stop * interval, step)
        k = k_stop
        if progress is not None:
            progress(k - 1, n_samples - 1)
    out_f, out_e, out_b, fmax = m.out_f, m.out_e, m.out_b, m.fmax

    time = np.arange(n_samples) * interval
    wall = model.chain.n_beads
    peak_f, peak_t = 0.0, 0.0
    if model.wall.present:
        col = int(np.searchsorted(rec, wall))
        i = int(np.argmax(out_f[:, col]))
        peak_f, peak_t = float(out_f[i, col]), float(time[i])
    raw = RawRun(time=time, contact_force=out_f, kinetic_energy=out_e[:, 0].copy(), potential_energy=out_e[:, 1].copy(),
                 dissipated_energy=out_e[:, 2].copy(), velocity=None, max_force=fmax, peak_wall_force=peak_f,
                 peak_wall_time=peak_t, dt=step, integrator="verlet", n_steps=(n_samples - 1) * stride, contacts=rec,
                 dt_max=step, adaptive=False, body=out_b if system.body else None,
                 plastic_work=None, residual_overlap=None, max_overlap=None)
    attrs = {"drive": json.dumps(drive.describe())}
    attrs.update(extra_attrs or {})
    ds = build_dataset(raw, model, probes, duration=duration, config=config, system=system, extra_attrs=attrs)
    ds["drive_force"] = ("time", out_e[:, 4].copy(), {"units": "N", "long_name": "drive force on bead 1"})
    ds["drive_displacement"] = ("time", out_e[:, 5].copy(),
                                {"units": "m", "long_name": "driver position (force drive: bead 1 displacement)"})
    ds["drive_work"] = ("time", out_e[:, 3].copy(), {"units": "J", "long_name": "work done by the drive"})
    return ds


def run_driven_batch(models, durations, probes, *, dt: float | None = None, steps_per_radian: float | None = None,
                     progress=None) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Run several driven models in one compiled call (:func:`~hertzchain.crystal.drive_kernel.driven_batch`).

    The members differ only in their drives (a frequency or an amplitude each): they share the
    chain's arrays, and each has its own step (:func:`drive_step`), stride, state and records. All
    have the same number of samples (``duration / sample_interval``, e.g. the same number of
    periods at the same samples per period); a member's records are those of
    :func:`simulate_driven` on it alone, bit for bit (the same compiled step, the same inputs).

    Parameters
    ----------
    models : sequence of hertzchain.Model
        Driven from bead 1 (a drive entering at bead N: pass the chain read from there,
        :func:`hertzchain.crystal.ends.from_driven_end`).
    durations : sequence of float
        Each member's duration [s].
    probes : sequence of hertzchain.Probes
        Each member's sample interval [s] and contacts (the same contacts for all).
    dt : float, optional
        A given step [s] (else each member's :func:`drive_step`).
    steps_per_radian : float, optional
        The automatic step's accuracy.
    progress : callable, optional
        ``progress(samples done, samples)`` after each chunk of samples (every member advanced).

    Returns
    -------
    list of (time [s], contact forces [N] (samples, recorded contacts), drive force [N],
    largest force of every contact [N])
    """
    # the batch's records at once, before any is allocated (each member's own by its pre-flight)
    size = sum((math.floor(d / pr.sample_interval + 1e-9) + 1) * (pr.recorded_contacts(m.chain.n_beads,
               m.wall.present).size + 10) * 8 for m, d, pr in zip(models, durations, probes))
    if len(models) > 1 and size > MAX_RECORD_BYTES:
        raise ConfigError("--batch", f"{len(models)} drives at once would record {size / 2**30:.3g} GiB (more than "
                          f"{MAX_RECORD_BYTES / 2**30:.0f} GiB): run fewer at a time")
    members = []
    for model, duration, pr in zip(models, durations, probes):
        system = model.system()
        _check_driven(model, system, pr, "verlet", 1)
        members.append(_set_up(model, system, float(duration), pr, dt, steps_per_radian))
    first = members[0]
    w, system = first.w, first.system
    for m in members[1:]:
        same = all(np.array_equal(getattr(m.w, k), getattr(w, k)) for k in ("mass", "kappa", "damping", "d0", "fext"))
        if not same or m.n_samples != first.n_samples or not np.array_equal(m.rec, first.rec):
            raise ValueError("run_driven_batch: the members must share the chain and the number of samples")
    stack = {k: np.stack([getattr(m, k) for m in members]) for k in
             ("u", "v", "a", "wa", "vp", "g", "out_f", "out_e", "out_b", "fmax", "acc", "params")}
    dmax = np.stack([m.w.dmax for m in members])
    ext = np.stack([m.w.ext for m in members])
    steps = np.array([m.step for m in members])
    strides = np.array([m.stride for m in members], dtype=np.int64)
    status = np.zeros(len(members), dtype=np.int64)
    batch = kernels_for(system.law)[3]
    n_samples = first.n_samples
    chunk = max(1, int(2_000_000 // int(strides.max())))
    if progress is not None:
        progress(0, n_samples - 1)
    k = 1
    while k < n_samples:
        k_stop = min(n_samples, k + chunk)
        # members of unequal cost (a low frequency takes more steps): handed to the threads one at a time
        with numba.parallel_chunksize(1):
            batch(stack["u"], stack["v"], stack["a"], stack["wa"], stack["vp"], stack["g"], w.mass, w.inv_mass,
                  w.kappa, w.damping, w.d0, w.de, w.dx0, w.rsum, w.fext, w.dyield, dmax, w.dres, w.kres, system.law,
                  ext, system.extended, stack["params"], first.tt, first.vv, first.displacement, steps, strides, k,
                  k_stop, first.rec, stack["out_f"], stack["out_e"], stack["fmax"], stack["acc"], w.body_slot,
                  stack["out_b"], status)
        if np.any(status != 0):
            bad = int(np.flatnonzero(status)[0])
            raise _diverged(k_stop * probes[bad].sample_interval, float(steps[bad]))
        k = k_stop
        if progress is not None:
            progress(k - 1, n_samples - 1)
    return [(np.arange(n_samples) * pr.sample_interval, stack["out_f"][i], stack["out_e"][i, :, 4], stack["fmax"][i])
            for i, pr in enumerate(probes)]
