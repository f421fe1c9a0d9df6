"""Run a model: choose the integrator, record the probes, check the elastic limit, build the result."""

from __future__ import annotations

import json
import warnings
from typing import Callable, Literal

import numpy as np
import xarray as xr

from ..checks import check_after_run, check_before_run
from ..engine_choice import choose_engine
from ..errors import ConfigError, DurationWarning, ElasticLimitWarning
from ..model import Model
from ..laws import is_plastic
from ..probes import Probes, default_probes
from ..strict import real, run_options

__all__ = ["simulate", "warn_elastic_limit", "warn_members_elastic_limit", "auto_duration", "elastic_limit_message"]

#: Default relative tolerance of the scipy integrators (``rtol``).
SCIPY_RTOL = 1e-10
#: Bead masses a solitary wave sets in motion, in units of its peak bead velocity: the particle
#: velocity of Nesterenko's wave is V_m cos^4 over 5 pi / sqrt(10) bead diameters (paper eq. 3-4),
#: whose sum over beads is (3/8) 5 pi / sqrt(10) = 1.86 V_m.
WAVE_MASS_BEADS = 1.86
#: Margin of the automatic duration over the ballistic estimate (dissipation slows the pulse:
#: eps = 0.985 costs 9 % of the speed over 30 beads, paper eq. 8 with q = 0).
AUTO_MARGIN = 1.25
#: Pulse durations allowed after the front's arrival for the pulse and its tail to pass.
AUTO_TAIL_DURATIONS = 6.0


def auto_duration(model: Model) -> float:
    """Simulated time [s] long enough for the front to cross the chain and its tail to pass.

    From the slowest pulse the striker can launch: the chain receives at least the striker's
    momentum m_s v_0, carried by a solitary wave that moves WAVE_MASS_BEADS bead masses, so its
    peak bead velocity in bead n is at least V_n = v_0 min(m_s, m_n) / (1.86 m_n) (a heavier
    striker launches waves no slower than one of the bead's own mass). Eq. 5 (second form) turns
    V_n into the speed c_n; the front arrives after T = sum phi_n / c_n and the pulse lasts
    tau = sqrt(10) phi_N / (2 c_N) (paper Sec. III). The duration is
    AUTO_MARGIN (T + AUTO_TAIL_DURATIONS tau); behind a protected body on a mount, plus half the
    mount's period pi sqrt(M/k) (:func:`hertzchain.bodies.mount_half_period`), at most
    MAX_BODY_DURATION (25 ms) in all unless the pulse alone needs longer.

    Parameters
    ----------
    model : Model
        Chain, striker, wall and law (precompression only makes the pulse faster).

    Returns
    -------
    float
        Duration [s].
    """
    from ..theory import pulse_duration, solitary_wave_speed_from_velocity

    if model.drive is not None:  # a driven chain: the ramp and the drive's cycles (Drive.auto_duration)
        return model.drive.auto_duration
    striker = model.striker
    if striker is None:  # nothing sets the chain moving: no pulse to size the run by (simulate refuses it too)
        raise ConfigError("striker", "a model without a striker (striker=None) has no pulse to size a run by: give "
                          "it a striker or a drive (hertzchain.Drive, [drive])")
    chain = model.chain
    m = chain.masses
    v0 = striker.velocity
    wall = model.wall
    if chain.n_beads == 0:
        # no chain: one two-body Hertz collision of the striker with the wall or body, which lasts
        # 2.943 delta_m / v0 (delta_m = (5 mu v0^2 / (4 kappa))^(2/5)); twice that, with the margin
        from ..theory import two_body_impact

        mu = 1.0 / (1.0 / striker.mass + (1.0 / wall.mass if wall.mass is not None else 0.0))
        duration = AUTO_MARGIN * 2.0 * two_body_impact(mu, float(model.system().kappa[0]), v0)["contact_time"]
    else:
        vm = v0 * np.minimum(striker.mass, m) / (WAVE_MASS_BEADS * m)
        # eq. 5 per material, vectorised over its beads (a loop over 1e6 beads took seconds)
        materials = chain.materials
        ids = np.fromiter(map(id, materials), dtype=np.int64, count=len(materials))
        speed = np.empty(vm.size)
        for key in np.unique(ids):
            mask = ids == key
            speed[mask] = solitary_wave_speed_from_velocity(materials[int(np.argmax(mask))], vm[mask])
        arrival = float(np.sum(chain.diameters / speed))
        tau = float(pulse_duration(chain.diameters[-1], speed[-1]))
        duration = AUTO_MARGIN * (arrival + AUTO_TAIL_DURATIONS * tau)
    if wall.mass is not None and wall.stiffness > 0:  # (a mass: wall.type = "body")
        # the body swings on its mount: the force it passes to the ground peaks up to half a
        # period after the pulse has pushed it (a 1 kg body on 1e6 N/m behind chain 1: at
        # 4.4 ms, past the pulse's 3.6 ms)
        from ..bodies import MAX_BODY_DURATION, mount_half_period

        duration = min(duration + mount_half_period(wall.mass, wall.stiffness), max(duration, MAX_BODY_DURATION))
    return duration


def simulate(model: Model, duration: float | str = "auto", probes: Probes | None = None, *,
             integrator: Literal["auto", "verlet", "rkn4", "dop853", "rk45"] = "auto", dt: float | None = None,
             rtol: float | None = None, progress: Callable[[int, int], None] | None = None,
             config: dict | None = None, steps_per_radian: float | None = None,
             threads: int | Literal["auto"] = "auto") -> xr.Dataset:
    """Simulate ``model`` for ``duration`` [s] and return the result Dataset.

    Parameters
    ----------
    model
        Chain, striker, wall and contact law.
    duration
        Simulated time [s] after impact, or ``"auto"`` (:func:`auto_duration`; the result's
        attribute ``duration`` holds the value, and ``duration_mode = "auto"`` says how it came).
    probes
        What to record (default :func:`hertzchain.probes.default_probes`: the energies and the
        contact forces of ``Probes.contacts = "auto"``, every contact of a chain of up to 256,
        else the wall's and 33 spread along it, every 100 ns or at most 1e5 samples; pass
        ``Probes(contacts=None)`` for every contact).
    integrator
        ``"auto"`` (default: the fastest of the two below that integrates the model,
        :mod:`hertzchain.engine_choice`; the result's attribute ``integrator_used`` says which),
        ``"verlet"`` (compiled velocity Verlet, adaptive step), ``"rkn4"`` (compiled
        fourth-order symplectic Runge-Kutta-Nystrom with a contact-aware step and probes
        interpolated between steps, for aligned elastic chains: the same accuracy in a fraction of
        the time, see :mod:`hertzchain.integrate.drivers.rkn`; for Kuwabara-Kono, the dashpot and offset
        beads the classical fourth-order RKN for y'' = f(y, y') that lands on every contact's
        closing and clip, :mod:`hertzchain.integrate.drivers.rkn_damped`) or the scipy reference ``"dop853"``
        (``"rk45"`` also accepted), adaptive with relative tolerance ``rtol``.
    dt
        Fixed time step [s] of ``"verlet"`` or ``"rkn4"``; automatic when None (see
        :func:`hertzchain.integrate.drivers.verlet.step_plan`).
    progress
        Called as ``progress(done, total)`` between chunks of a Verlet run.
    rtol
        Relative tolerance of the scipy reference integrators (default 1e-10), or of the step
        control of ``"rkn4"``: its local velocity error per step relative to the striker speed
        (default :data:`hertzchain.integrate.drivers.rkn.RKN_RTOL` = 1e-6, a peak wall force within ~1e-8
        on elastic chains, ~4e-7 with the dissipative laws);
        unused by ``"verlet"``.
    config
        The input it came from, stored in the result's attributes.
    steps_per_radian
        Accuracy of the adaptive Verlet step: omega dt <= 1 / steps_per_radian (default None:
        :data:`hertzchain.integrate.drivers.verlet.ADAPTIVE_STEPS_PER_RADIAN` = 400, a peak wall force
        within ~1e-6; the error scales as (1 / steps_per_radian)^2); unused with ``dt`` or the
        scipy integrators.
    threads
        ``"auto"`` (default: several only for a long chain on the Verlet with cores free,
        :mod:`hertzchain.engine_choice`; the attribute ``threads_used`` says how many), or threads
        sharing the chain (``"verlet"``, every contact law, offsets too, not a protected body or
        mass-in-mass beads; worth it from ~1e4 beads): forces, velocities, per-contact state and the
        peak are bit for bit those of one thread, the energies, dissipated energy and plastic work
        agree to rounding (:mod:`hertzchain.integrate.drivers.threaded`).

    Returns
    -------
    xarray.Dataset
        Forces [N], energies [J] and the model on the ``time`` [s] axis; every variable and
        attribute is described in the user guide's "Results" page.

    Raises
    ------
    ConfigError
        A bad input, a precompression beyond the range of Hertz theory, or records that cannot
        fit in memory (naming the field to change; nothing is allocated before these checks).
    SimulationDiverged
        The integration became non-finite or gained energy (:mod:`hertzchain.checks`).

    Warns
    -----
    ElasticLimitWarning
        When a recorded contact force passes the contact's elastic limit (paper Sec. II).
    HertzRangeWarning, PulseNotReachedWarning, LongRunWarning
        Overlaps beyond Hertz theory; a record that ends before the pulse reaches the wall; a run
        projected to take more than a few minutes.
    """
    from ..result import build_dataset

    mode = "given"
    if model.striker is None and model.drive is None:
        raise ConfigError("striker", "a model without a striker (striker=None) needs a drive to set it moving "
                          "(hertzchain.Drive, [drive]); its static state is hertzchain.equilibrium(model)")
    if isinstance(duration, str) and duration == "auto":
        duration, mode = auto_duration(model), "auto"
    duration = real(duration, "run.duration", low=0.0, open_low=True, unit="s")
    probes = probes or default_probes(duration)
    # The config's bounds at the API's door (hertzchain.strict): steps_per_radian=0, rtol=0, dt=nan
    # or threads=10**6 are refused, naming the field, as in a config file ("auto": engine_choice).
    dt, rtol, steps_per_radian, counted = run_options(dt=dt, rtol=rtol, steps_per_radian=steps_per_radian,
                                                      threads=None if threads == "auto" else threads)
    threads = "auto" if counted is None else counted
    if probes.sample_interval > duration:
        raise ConfigError("run.sample_interval", f"({probes.sample_interval:g} s) is longer than run.duration ({duration:g} s)")
    system = model.system()
    probes.validate(model.chain.n_beads, model.wall.present)
    if model.drive is not None:  # a driven chain: its own compiled Verlet loop (hertzchain.crystal.driven)
        from ..crystal.driven import simulate_driven

        ds = simulate_driven(model, system, duration, probes, integrator="verlet" if integrator == "auto" else integrator,
                             dt=dt, threads=1 if threads == "auto" else threads, progress=progress, config=config,
                             steps_per_radian=steps_per_radian,
                             extra_attrs={"duration_mode": "auto"} if mode == "auto" else None)
        warn_elastic_limit(ds, stacklevel=3)
        return ds
    choice = choose_engine(system, integrator, threads, steps_per_radian=steps_per_radian, dt=dt)
    engine, threads = choice.integrator, choice.threads
    check_before_run(model, system, duration, probes, dt=dt, integrator=engine)  # before any allocation
    rec = probes.recorded_contacts(model.chain.n_beads, model.wall.present)
    if threads > 1 and engine == "verlet":
        from ..integrate.drivers.threaded import run_verlet_threaded

        raw = run_verlet_threaded(system, duration, probes.sample_interval, threads, dt=dt,
                                  record_velocities=probes.velocities, contacts=rec, progress=progress,
                                  record_positions=probes.positions, steps_per_radian=steps_per_radian)
    elif engine == "verlet":
        from ..integrate.drivers.verlet import run_verlet

        raw = run_verlet(system, duration, probes.sample_interval, dt=dt, record_velocities=probes.velocities,
                         contacts=rec, progress=progress, record_positions=probes.positions,
                         steps_per_radian=steps_per_radian)
    elif engine == "rkn4":
        from ..integrate.drivers.rkn import RKN_RTOL, run_rkn

        rtol = RKN_RTOL if rtol is None else rtol
        raw = run_rkn(system, duration, probes.sample_interval, dt=dt, rtol=rtol, record_velocities=probes.velocities,
                      contacts=rec, progress=progress, record_positions=probes.positions, threads=threads)
    else:
        rtol = SCIPY_RTOL if rtol is None else rtol
        from ..integrate.drivers.reference import run_reference  # scipy.integrate: loaded only for these

        raw = run_reference(system, duration, probes.sample_interval, method=engine.upper(), rtol=rtol,
                            record_velocities=probes.velocities, record_positions=probes.positions)
    extra = {"integrator_used": engine, "threads_used": threads, "engine_choice": choice.reason}
    if mode == "auto":
        extra["duration_mode"] = "auto"
    ds = build_dataset(raw, model, probes, duration=duration, config=config, system=system, extra_attrs=extra)
    check_after_run(ds, model, system, dt=dt, integrator=engine, rtol=rtol, stacklevel=3)
    warn_elastic_limit(ds, stacklevel=3, law=model.law.name)
    if mode == "auto" and "wall_force" in ds and ds.attrs["peak_wall_time"] > 0.8 * duration:
        warnings.warn(DurationWarning(
            f"the automatic duration ({duration * 1e3:.3g} ms) may cut the wall pulse (its peak comes at "
            f"{ds.attrs['peak_wall_time'] * 1e3:.3g} ms); set run.duration longer"), stacklevel=2)
    return ds


def _ranges(indices: list[int]) -> str:
    """``[0, 1, 2, 5, 7, 8]`` -> ``"0-2, 5, 7-8"``."""
    parts, start = [], None
    for k, c in enumerate(indices):
        if start is None:
            start = c
        if k + 1 == len(indices) or indices[k + 1] != c + 1:
            parts.append(f"{start}" if c == start else f"{start}-{c}")
            start = None
    return ", ".join(parts)


def elastic_limit_message(ds: xr.Dataset, where: str = "") -> str | None:
    """One line on the contacts past the elastic limit of a result, or None when there are none.

    Names the worst contact and its ratio F_max / F_Y, and the range(s) of contacts past the
    limit (F_Y: mean contact pressure = yield stress, paper Sec. II).

    Parameters
    ----------
    ds : xarray.Dataset
        A result of :func:`simulate` (uses ``max_contact_force`` and ``yield_force``).
    where : str
        Prefix naming the run (e.g. ``"chain 1 cut after bead 20: "``).

    Returns
    -------
    str or None
        The message.
    """
    # a Dataset's arrays straight from its variables (a DataArray each costs ~20 us); the batch
    # engine passes a namespace holding the arrays instead
    source = (ds.variables if isinstance(ds, xr.Dataset)
              else {k: getattr(ds, k, None) for k in ("max_contact_force", "yield_force")})
    fmax, fy = source.get("max_contact_force"), source.get("yield_force")
    if fmax is None or fy is None:
        return None
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.asarray(getattr(fmax, "values", fmax), dtype=float) / np.asarray(getattr(fy, "values", fy), dtype=float)
    ratio = np.where(np.isfinite(ratio), ratio, 0.0)
    over = np.flatnonzero(ratio > 1.0).tolist()
    if not over:
        return None
    worst = int(np.argmax(ratio))
    if worst == 0:
        sizes = getattr(ds, "sizes", None)  # a batch's member view has none (it has beads)
        name = "striker-wall" if sizes is not None and sizes.get("bead", 1) == 0 else "striker-bead 1"
    else:  # the bead count, to name the wall's contact (reading the model text only then: ~40 us)
        try:
            n = len(json.loads(ds.attrs["model"])["chain"]["diameters_mm"])
        except (KeyError, TypeError, ValueError):
            n = -1
        name = "bead N-wall" if worst == n else f"bead {worst}-bead {worst + 1}"
    return (f"{where}contact forces pass the elastic limit F_Y of the paper (Sec. II) at {len(over)} of "
            f"{ratio.size} contacts ({_ranges(over)}); worst: contact {worst} ({name}) at "
            f"{ratio[worst]:.2f} x F_Y. Beads would yield plastically: lower the striker velocity, or let "
            f"the contacts yield (contact.law = \"elastoplastic\", Thornton's law)")


def _law_name(ds) -> str | None:
    """The contact law's name in a result's ``model`` attribute (None when not readable)."""
    try:
        return json.loads(ds.attrs["model"])["contact"]["law"]
    except (KeyError, TypeError, ValueError):
        return None


def warn_elastic_limit(ds: xr.Dataset, where: str = "", stacklevel: int = 2, law: str | None = None) -> None:
    """Warn (ElasticLimitWarning, :func:`elastic_limit_message`) when the result records forces
    past the elastic limit of an elastic or viscous law (the elastoplastic law models the yield).

    Parameters
    ----------
    ds : xarray.Dataset
        A result of :func:`simulate`.
    where : str
        Prefix naming the run in the message.
    stacklevel : int
        Passed on to :func:`warnings.warn`.
    law : str or None
        The contact law's name when the caller has it (else read from the ``model`` attribute).
    """
    if not ds.attrs.get("elastic_limit_exceeded", 1) or is_plastic(law or _law_name(ds)):
        return  # the elastoplastic law models the yield: nothing to warn about
    msg = elastic_limit_message(ds, where)
    if msg:
        warnings.warn(ElasticLimitWarning(msg), stacklevel=stacklevel + 1)


def warn_members_elastic_limit(flagged: list, n_members: int, stacklevel: int = 2) -> None:
    """The elastic-limit check of a batch: ONE :class:`~hertzchain.errors.ElasticLimitWarning`
    naming the members past the limit and the worst one's contacts (not one line per member:
    10,000 of them for an ensemble).

    Parameters
    ----------
    flagged : list of (int, object)
        ``(member, result)`` of every member whose forces passed the limit; ``result`` is what
        :func:`elastic_limit_message` reads (``max_contact_force``, ``yield_force``, ``attrs``).
    n_members : int
        Members in the batch.
    stacklevel : int
        Passed on to :func:`warnings.warn`.
    """
    if not flagged:
        return
    if n_members == 1:
        warn_elastic_limit(flagged[0][1], stacklevel=stacklevel + 1)
        return

    def worst_ratio(item) -> float:
        r = item[1]
        fmax, fy = (np.asarray(getattr(x, "values", x), dtype=float) for x in (r.max_contact_force, r.yield_force))
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = fmax / fy
        return float(np.nanmax(np.where(np.isfinite(ratio), ratio, 0.0)))

    worst = max(flagged, key=worst_ratio)
    msg = elastic_limit_message(worst[1], f"member {worst[0]}: ")
    if msg is None:
        return
    some = ", ".join(str(i) for i, _ in flagged[:8]) + (", ..." if len(flagged) > 8 else "")
    warnings.warn(ElasticLimitWarning(f"{len(flagged)} of {n_members} members (member {some}) pass the elastic "
                                      f"limit; worst: {msg}"), stacklevel=stacklevel + 1)
