"""Physical bounds of the inputs, shared by the config schema (:mod:`hertzchain.config.schema`) and
the Python API's checks (:func:`check_bound`), so that a config and its Python transcription are
refused alike.

The bounds are generous enough for any granular-chain experiment and tight enough that every
derived quantity stays representable: nothing reaches the engine as 0, inf, NaN or an overflowing
product (1e300 m/s, 1e-300 mm, 1e30 beads, a 1e-30 kg body whose mount's period is 1e-40 s).
What stays representable but would take absurdly many time steps is refused by the pre-flight
(:func:`hertzchain.checks.check_step_count`), naming the field that sets the step.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from .errors import ConfigError, TooManySteps

__all__ = ["BOUNDS", "MAX_STEPS", "TooManySteps", "check_bound", "check_step_count"]

#: (low, high), inclusive unless a field says otherwise, in the unit its comment gives.
BOUNDS = {
    "diameter_mm": (1e-3, 1e4),       # 1 um .. 10 m
    "beads": (1, 10_000_000),         # bead counts and numbers (memory is checked separately)
    # m/s: far beyond yield at the top; below 1 um/s the impact's overlaps (~1e-11 m in steel) are
    # below anything a Hertz contact of real surfaces means, and the engine counts overlaps below
    # 1e-30 m as none (a striker at 1e-300 m/s moved nothing)
    "velocity": (1e-6, 1e3),
    "density": (1.0, 1e5),            # kg/m^3
    "young": (1e3, 1e13),             # Pa
    "yield_stress": (1e3, 1e12),      # Pa
    "precompression": (0.0, 1e9),     # N (and the Hertz-range check on the static overlap)
    "offset_mm": (-1e4, 1e4),
    "A": (0.0, 1.0),                  # s (the paper's eps = 0.985 needs A ~ 4.5e-6 s)
    "gamma": (0.0, 1e9),              # N s/m
    "duration": (0.0, 100.0),         # s, > 0 (memory and run time are checked separately)
    "sample_interval": (1e-12, 1.0),  # s
    "dt": (1e-15, 1.0),               # s
    "rtol": (1e-14, 0.1),
    # adaptive Verlet accuracy, omega dt <= 1 / steps_per_radian: below ~10 the peak force is off
    # by more than ~3e-4 (error ~ (1 / steps_per_radian)^2) and Verlet nears its stability limit
    "steps_per_radian": (10.0, 1e5),
    "threads": (1, 1024),             # threads sharing one chain
    # kg: a striker, a bead or a protected body; the low end is a 1 um steel bead (4e-15 kg), the
    # smallest the diameter's bound allows, so c / m and sqrt(k / m) stay finite (<= 1e27 1/s)
    "mass": (1e-15, 1e6),
    "stiffness": (0.0, 1e15),         # N/m, the protected body's mount (0: a free body)
    "damping": (0.0, 1e12),           # N s/m
    "gravity": (0.0, 1e4),            # m/s^2 along the chain (a centrifuge reaches 1e4)
    "frequency": (0.0, 1e9),          # Hz, > 0: a mass-in-mass bead's internal resonance
    # Thornton's limiting pressure p_y over sigma_Y: ~1.1 at first yield (Hertz's mean pressure),
    # ~3 fully plastic (Tabor); below 0.5 p_y is below anything a metal carries, and at 1e-300 the
    # yield overlap delta_y ~ p_y^2 underflowed to 0 and the run's step count to NaN
    "limiting_pressure_factor": (0.5, 10.0),
}


#: A run of more time steps than this (per member) is refused, naming the input that sets the step
#: (:func:`check_step_count`): at the fastest kernel's ~1.5 ns per bead-step it would take hours per
#: bead, and far past it the step count is no longer a machine integer (a 1e-30 kg protected body on
#: a 1e12 N s/m dashpot asked for 3e41 steps, and the engine failed on "Int value is too large").
MAX_STEPS = 1e13


def check_bound(value, kind: str, field: str, unit: str = "", *, allow_none: bool = False):
    """``value`` as a float inside ``BOUNDS[kind]``, or a ConfigError naming ``field``.

    Parameters
    ----------
    value : float or None
        What the caller gave (a real number; None only with ``allow_none``).
    kind : str
        A key of :data:`BOUNDS`.
    field : str
        The field's name as a config spells it (``wall.mass``).
    unit : str
        The unit named in the message (``kg``).
    allow_none : bool
        Whether None (the field left out) passes unchanged.

    Returns
    -------
    float or None
    """
    if value is None and allow_none:
        return None
    lo, hi = BOUNDS[kind]
    ok = (not isinstance(value, bool) and isinstance(value, numbers.Real) and math.isfinite(value)
          and lo <= float(value) <= hi)
    if not ok:
        raise ConfigError(field, f"must be a number from {lo:g} to {hi:g}{' ' + unit if unit else ''}, got {value!r}")
    return float(value)


def check_step_count(system, steps: float, duration: float, dt: float | None = None,
                     integrator: str = "verlet") -> None:
    """Refuse a run of more than :data:`MAX_STEPS` time steps (or a step count that is not a
    number), naming the input that sets the step.

    With a fixed step it is ``run.dt``; else the body whose bound of
    :meth:`~hertzchain.model.System.frequency_rows` is the highest (the stable step is ~2 /
    omega_max): the striker (``striker.mass``), a bead (``chain.diameters_mm[i]``), the protected
    body (``wall.damping`` when its dashpot's rate beta dominates, else ``wall.mass``), a
    mass-in-mass bead's internal resonance (``chain.elements``), or the contacts' damping
    (``contact.*``) when the beads' beta dominates.

    Parameters
    ----------
    system : hertzchain.model.System
        The model's arrays.
    steps : float
        The projected steps of one run (:func:`estimate_resources`).
    duration : float
        Simulated time [s].
    dt : float or None
        The user's fixed step [s] (None: automatic).
    integrator : str
        The integrator (named in the message).

    Raises
    ------
    TooManySteps
        A :class:`~hertzchain.errors.ConfigError` naming the field.
    """
    if math.isfinite(steps) and steps <= MAX_STEPS:
        return
    step = duration / steps if steps > 0 and math.isfinite(steps) else 0.0
    what = (f"{duration:g} s of simulated time in steps of {step:.3g} s would take {steps:.3g} time steps "
            f"({integrator}), more than the {MAX_STEPS:.0e} allowed")
    if dt is not None:
        raise TooManySteps("run.dt", f"{what}: raise run.dt (or leave it out for the automatic step) or shorten "
                           "run.duration")
    field, why = _fastest_body(system)
    raise TooManySteps(field, f"{what}; {why} sets the stable step. Choose a value that makes its time scale "
                       "closer to the contacts' (microseconds), or shorten run.duration")


def _fastest_body(system) -> tuple[str, str]:
    """The config field of the body whose frequency bound sets the time step, and why in words."""
    omega2, beta, inner = system.frequency_rows()
    bound = np.sqrt(omega2 + 0.25 * beta**2) + 0.5 * beta
    i = int(np.argmax(bound))
    if inner.size and float(np.max(inner)) > bound[i]:
        j = int(np.argmax(inner))
        return "chain.elements", (f"the internal resonator of bead {j} (period {2 * math.pi / inner[j]:.3g} s, "
                                  "elements.NAME.resonator.frequency and mass_fraction)")
    damped = beta[i] ** 2 > omega2[i]  # the dashpot's rate, not the springs, bounds the step
    rate = f"(omega {math.sqrt(omega2[i]):.3g} rad/s, damping rate {beta[i]:.3g} 1/s)"
    n = system.n_beads
    if system.body and i == n + 1:
        if damped and system.mount_c > 0:
            return "wall.damping", f"the protected body's dashpot wall.damping over its wall.mass {rate}"
        return "wall.mass", f"the protected body's mass wall.mass against its mount and contact {rate}"
    if damped:
        return "contact", f"the contacts' damping (contact.A, contact.gamma or contact.eps) {rate}"
    if i == 0:
        return "striker.mass", f"the striker's mass against its contact {rate}"
    return f"chain.diameters_mm[{i - 1}]", f"bead {i}'s mass against its contacts {rate}"
