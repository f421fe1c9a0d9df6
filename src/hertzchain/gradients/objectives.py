"""The results a sensitivity differentiates: each one's value and its partials (*seeds*) with
respect to the forces it reads, from a taped run (:class:`hertzchain.integrate.derivatives.differentiate.Tape`).

Objectives (SI units; the names of the design objectives mean the same numbers as there):

- ``peak_wall_force`` [N]: the wall peak refined between steps (the vertex of the parabola through
  the force at the three steps around the largest one, ``verlet.refine_peak``); the derivative
  holds the step of the maximum fixed: the envelope theorem makes it the derivative of the true
  maximum as the step goes to zero, and where two separate maxima are equal the objective has a
  kink (one-sided derivatives: the gradient is that of the maximum the run found);
- ``peak_wall_time`` [s]: the time of that vertex; where the wall contact yields (Thornton's law
  without a viscous part), the time the wall overlap stops growing, the vertex of the parabola
  through the overlap at three steps (the force's curvature jumps there; the overlap is smooth,
  so the time and its derivative agree with central differences; it differs from the run's
  ``peak_wall_time`` attribute by a fraction of a step);
- ``time_of_flight`` [s], ``pulse_duration`` [s], ``front_momentum_at_wall`` [N s]: T, tau and Q_F of
  the wall pulse's cos^6 fit (paper Sec. III, :func:`hertzchain.analysis.fit_pulse`), differentiated
  through the fit's optimality conditions (implicit function theorem). The fit reads the samples
  with (t - T) / tau in (-1, 0]; as the pulse moves, samples enter and leave that window and the
  fitted values jump a little once per sample. The derivative is that of the fit with the window's
  ends moving continuously: the trend through the jumps (with the window held fixed, the slope
  between two jumps can be half the trend or less). The samples of the baseline (the median
  before T - 2 tau, zero for a simulated record that starts at rest) are held fixed;
- ``energy_at_wall`` [J]: the largest elastic energy stored in the bead N - wall contact,
  (2/5) F^(5/3) / kappa^(2/3) at the largest sampled wall force (within ``window``): the energy
  the pulse delivers into the wall's contact;
- ``peak_contact_force`` [N]: the largest sampled force of any contact;
  ``peak_contact_force[j]``: of contact j;
- ``max_force_over_yield`` [1]: the largest sampled contact force over its elastic limit F_Y
  (paper Sec. II; F_Y depends on the diameters and materials too).

A maximum over samples holds its sample (and contact) fixed, like the wall peak.
"""

from __future__ import annotations

import math
import re

import numpy as np

from ..errors import ConfigError, ObjectiveUndefined, PulseNotFound
from ..integrate.core import kernels
from ..laws import law_of_code
from . import state
from .reading import STEP, Reading, rising, span, vertex
from .state import BODY

__all__ = ["OBJECTIVES", "Reading", "read_objective", "objective_unit", "contacts_needed", "soft_peak"]

#: Objective name -> (unit, meaning).
OBJECTIVES: dict[str, tuple[str, str]] = {
    "peak_wall_force": ("N", "peak force on the wall, refined between steps"),
    "peak_wall_time": ("s", "time of the refined wall peak"),
    "time_of_flight": ("s", "T of the wall pulse's cos^6 fit (paper Sec. III)"),
    "pulse_duration": ("s", "tau of the wall pulse's cos^6 fit (paper Sec. III)"),
    "front_momentum_at_wall": ("N s", "front momentum Q_F of the wall pulse (paper Sec. III)"),
    "energy_at_wall": ("J", "largest elastic energy in the bead N - wall contact"),
    "peak_contact_force": ("N", "largest sampled force of any contact (peak_contact_force[j]: of contact j)"),
    "max_force_over_yield": ("1", "largest contact force over its elastic limit F_Y"),
    "peak_body_force": ("N", "peak force the protected body's mount passes to the ground, |k x + c v|"),
    "peak_body_acceleration": ("m s-2", "peak acceleration of the protected body"),
    "energy_to_body": ("J", "most energy delivered to the protected body"),
    "plastic_work": ("J", "plastic work done in all contacts by the end of the run (elastoplastic law)"),
    "residual_overlap_max": ("m", "largest permanent overlap of any contact at the end (elastoplastic law)"),
}

_NEEDS_WALL = {"peak_wall_force", "peak_wall_time", "time_of_flight", "pulse_duration", "front_momentum_at_wall",
               "energy_at_wall"}
_CONTACT = re.compile(r"peak_contact_force\[(\d+)\]")


def objective_unit(name: str) -> str:
    """Unit of an objective.

    Parameters
    ----------
    name : str
        Objective name (:data:`OBJECTIVES`, or ``peak_contact_force[j]``).

    Returns
    -------
    str
        Its unit.
    """
    return OBJECTIVES["peak_contact_force" if _CONTACT.fullmatch(name) else name][0]


def check_objective(name: str, system) -> None:
    """Refuse an unknown objective, or one the model cannot give (ConfigError naming ``objective``).

    Parameters
    ----------
    name : str
        Objective name.
    system : System
        The model's arrays.
    """
    m = _CONTACT.fullmatch(name) if isinstance(name, str) else None
    if m:
        if int(m.group(1)) >= system.n_contacts:
            raise ConfigError("objective", f"{name}: the model has contacts 0..{system.n_contacts - 1}")
        return
    if name not in OBJECTIVES:
        raise ConfigError("objective", f"unknown objective {name!r}; allowed: {', '.join(OBJECTIVES)}, "
                          "peak_contact_force[j]")
    if name in _NEEDS_WALL and not system.has_wall:
        raise ConfigError("objective", f"{name} reads the wall force, but wall.type = 'none'")
    if name == "energy_at_wall" and law_of_code(system.law).exponent != 1.5:
        raise ConfigError("objective", f"energy_at_wall is the Hertz energy (2/5) F^(5/3) / kappa^(2/3) of the wall "
                          f"contact; law {law_of_code(system.law).name!r} declares no Hertz exponent 3/2: use "
                          "peak_wall_force or peak_wall_time")
    if name in ("plastic_work", "residual_overlap_max") and system.law != kernels.LAW_ELASTOPLASTIC:
        raise ConfigError("objective", f"{name} is the elastic-plastic law's: it needs contact.law = "
                          "'elastoplastic' (the other laws do no plastic work)")
    if name in BODY and not system.body:
        raise ConfigError("objective", f"{name} is a protected body's: it needs [wall] type = 'body' (with its mass, "
                          "stiffness and damping)")


def contacts_needed(name: str, system) -> list[int]:
    """Contacts whose every sample the objective reads (the wall's is always recorded).

    Parameters
    ----------
    name : str
        Objective name.
    system : System
        The model's arrays.

    Returns
    -------
    list of int
        Contact numbers: the wall's; with a protected body its mount's too (contact N + 1).
    """
    return [system.n_beads] + ([system.n_beads + 1] if system.body else []) if system.has_wall else []


def read_objective(name: str, tape, window: tuple[float, float] | None = None) -> Reading:
    """Value and partials of objective ``name`` on a taped run.

    Parameters
    ----------
    name : str
        Objective name (:data:`OBJECTIVES`, or ``peak_contact_force[j]``).
    tape : Tape
        The taped run.
    window : (float, float), optional
        Time window [s] of ``energy_at_wall``.

    Returns
    -------
    Reading
        Value, seeds and direct partials.
    """
    sy = tape.system
    wall = sy.n_beads
    m = _CONTACT.fullmatch(name)
    if m:
        j = int(m.group(1))
        if not tape.max_force[j] > 0.0:
            raise ObjectiveUndefined("run.duration", f"contact {j} never closes within the run "
                                     f"({span(tape)}): {name} is 0 N and so is every derivative; lengthen "
                                     "run.duration (or leave it 'auto') or choose another contact")
        if tape.max_force_sample[j] == tape.time.size - 1:
            raise rising(tape, name)
        return Reading(float(tape.max_force[j]), samples=[(int(tape.max_force_sample[j]), j, 1.0)])
    if name == "energy_to_body":
        return state.energy_to_body(tape)
    if name == "plastic_work":
        return state.plastic_work(tape)
    if name == "residual_overlap_max":
        return state.residual_overlap_max(tape)
    if name in BODY:
        return state.body_peak(tape, name)
    if name in ("peak_wall_force", "peak_wall_time"):
        _check_wall_peak(tape, name)
        return _peak(tape, wall, name == "peak_wall_time")
    if name == "peak_contact_force":
        j = int(np.argmax(tape.max_force))
        return Reading(float(tape.max_force[j]), samples=[(int(tape.max_force_sample[j]), j, 1.0)])
    if name == "max_force_over_yield":
        fy = sy.yield_force[:sy.n_contacts]
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(np.isfinite(fy), tape.max_force / fy, np.nan)
        if not np.any(np.isfinite(ratio)):
            raise ConfigError("objective", "max_force_over_yield needs a material with a yield stress")
        j = int(np.nanargmax(ratio))
        direct = np.zeros(sy.yield_force.size)
        direct[j] = -tape.max_force[j] / fy[j] ** 2
        return Reading(float(ratio[j]), samples=[(int(tape.max_force_sample[j]), j, 1.0 / fy[j])],
                       direct={"yield_force": direct})
    f = tape.forces[:, int(np.searchsorted(tape.contacts, wall))]
    if name == "energy_at_wall":
        t = tape.time
        mask = np.ones(t.size, bool) if window is None else (t >= window[0]) & (t <= window[1])
        if not mask.any():
            raise ObjectiveUndefined("window", f"[{window[0] * 1e3:g}, {window[1] * 1e3:g}] ms holds no sample of the "
                                     f"run ({span(tape)}): energy_at_wall is undefined there; choose a window "
                                     "inside the run, or lengthen run.duration")
        fw = np.where(mask, np.maximum(f, 0.0), 0.0)
        k = int(np.argmax(fw))
        if not fw[k] > 0.0:
            where = "within the window" if window is not None else "during the run"
            raise ObjectiveUndefined("window" if window is not None else "run.duration",
                                     f"the wall force is 0 {where} ({span(tape, window)}): energy_at_wall is 0 J "
                                     "and so is every derivative; move the window to the wall pulse or lengthen "
                                     "run.duration (or leave it 'auto')")
        if k == t.size - 1:
            raise rising(tape, name)
        fpk, kap = fw[k], sy.kappa[wall]
        direct = np.zeros(sy.kappa.size)
        direct[wall] = -(2.0 / 3.0) * 0.4 * fpk ** (5.0 / 3.0) * kap ** (-5.0 / 3.0)
        seed = (2.0 / 3.0) * fpk ** (2.0 / 3.0) / kap ** (2.0 / 3.0) if fpk > 0 else 0.0
        return Reading(float(0.4 * fpk ** (5.0 / 3.0) / kap ** (2.0 / 3.0)), samples=[(k, wall, seed)],
                       direct={"kappa": direct})
    if not np.any(f > 0.0):
        raise ObjectiveUndefined("run.duration", f"the pulse does not reach the wall within the run ({span(tape)}): "
                                 f"{name} is undefined; lengthen run.duration (or leave it 'auto')")
    try:
        value, weights = pulse_partials(tape.time, f, name)
    except PulseNotFound as exc:
        raise ObjectiveUndefined("run.duration", f"{name} is undefined: the wall record of the run ({span(tape)}) "
                                 f"holds no whole pulse to fit ({exc}); lengthen run.duration (or leave it "
                                 "'auto')") from None
    return Reading(value, samples=[(int(k), wall, float(w)) for k, w in zip(np.flatnonzero(weights),
                                                                           weights[weights != 0])])


def _check_wall_peak(tape, name: str) -> None:
    """Refuse a wall peak that is no peak: a wall force that never rises above its value at t = 0
    (zero without a static load: the pulse does not reach the wall), or one still rising when the
    run ends (the pulse arriving: the maximum is the last step's force, its time the run's end)."""
    if tape.peak_step < 0:  # the tracker's step of the maximum: -1 until the force rises above t = 0's
        raise ObjectiveUndefined("run.duration", f"the pulse does not reach the wall within the run ({span(tape)}): "
                                 f"the wall force never rises above its value at t = 0 ({tape.peak[0]:.4g} N), so "
                                 f"{name} is that of the start and every derivative is 0; lengthen run.duration "
                                 "(or leave it 'auto')")
    if tape.peak_step >= tape.n_steps - 1:
        raise rising(tape, name)


def soft_peak(tape, width: float) -> Reading:
    """The soft maximum of the sampled wall force, mu log sum_k exp(F_k / mu) with mu = ``width`` [N],
    and its partials (the soft-max weights) on every sample.

    The peak wall force is a maximum over time: where two pulses (a front and a reflection) reach
    the same height it has a kink, and the best designs sit on such kinks (they level their
    peaks); a gradient method stalls there. The soft maximum is smooth, within ``width`` log(m)
    above the largest sample (m: the samples within a few ``width`` of it), and its gradient
    weighs every nearly highest peak: the stand-in the design search's local searches minimise.

    Parameters
    ----------
    tape : Tape
        The taped run (with a wall).
    width : float
        mu [N], > 0.

    Returns
    -------
    Reading
        The soft maximum [N] and its partials on the wall samples.
    """
    wall = tape.system.n_beads
    f = tape.forces[:, int(np.searchsorted(tape.contacts, wall))]
    top = float(np.max(f))
    e = np.exp((f - top) / width)
    z = float(e.sum())
    w = e / z
    keep = np.flatnonzero(w > 1e-14)
    return Reading(top + width * math.log(z), samples=[(int(k), wall, float(w[k])) for k in keep])


def _peak(tape, wall: int, want_time: bool) -> Reading:
    """The refined wall peak (or its time) and its partials on the three steps around the maximum;
    the time of a wall contact that yielded is that of its overlap's peak (:func:`~hertzchain.gradients.state.overlap_peak_time`)."""
    from ..integrate.drivers.verlet import refine_peak

    if want_time and state.yielded_wall(tape, wall):
        return state.overlap_peak_time(tape, wall)
    pk = tape.peak
    k = tape.peak_step
    fpk, t_pk, fb, fa, h0, h1 = pk[0], pk[1], pk[2], pk[3], pk[6], pk[7]
    value, time = refine_peak(pk)
    if value == fpk and time == t_pk:  # not refined (the peak at an end of the run, or no curvature)
        if want_time:
            return Reading(float(time))
        return Reading(float(value), steps=[(k, wall, 1.0)])
    w = []
    for i in range(3):
        e = [0j, 0j, 0j]
        e[i] = 1j * STEP
        v, t = vertex(fb + e[0], fpk + e[1], fa + e[2], h0, h1, t_pk)
        w.append(((t if want_time else v).imag) / STEP)
    return Reading(float(time if want_time else value),
                   steps=[(k - 1, wall, w[0]), (k, wall, w[1]), (k + 1, wall, w[2])])


# ------------------------------------------------------------------ the cos^6 fit (paper Sec. III)
def _cos6_jacobian(s, p):
    """d model / d (a, b, c) of a cos^6((s - b) / c) at the samples s (complex-safe)."""
    a, b, c = p
    u = (s - b) / c
    inside = np.abs(np.real(u)) < math.pi / 2.0
    cu, su = np.cos(u), np.sin(u)
    return np.column_stack([np.where(inside, cu**6, 0.0), np.where(inside, 6.0 * a * cu**5 * su / c, 0.0),
                            np.where(inside, 6.0 * a * cu**5 * su * u / c, 0.0)])


def pulse_partials(time: np.ndarray, force: np.ndarray, name: str) -> tuple[float, np.ndarray]:
    """A quantity of the wall pulse's cos^6 fit and its partials on every sample.

    The fit (:func:`hertzchain.analysis.fit_pulse`) minimises the squared residuals
    r_i = (y_i - b) - F_m cos^6((t_i - T) / tau) over the window W of samples with (t - T) / tau in
    (-1, 0], with b the median of the samples before T - 2 tau. At the optimum G = sum_i r_i grad m_i
    = 0; differentiating it gives dp = (H - B)^-1 sum_i grad m_i (dy_i - db): H the exact Hessian
    (Gauss-Newton term minus sum r_i Hess m_i, the second derivatives by complex step), B the
    motion of the window's ends (r grad m at each end, per sample spacing, times the end's
    derivative), the baseline's samples fixed.
    Q_F = int (f - b) dt up to T + tau (trapezoids, the split interpolated) then adds its own
    partials on the samples, on b and on the split time.

    Parameters
    ----------
    time, force : numpy.ndarray
        The wall record: sample times [s] and force [N].
    name : str
        ``time_of_flight``, ``pulse_duration`` or ``front_momentum_at_wall``.

    Returns
    -------
    (float, numpy.ndarray)
        The value and its partials on every sample of ``force``.
    """
    from ..analysis import fit_pulse

    t, y = np.asarray(time, float), np.asarray(force, float)
    fit = fit_pulse(t, y)
    b0 = fit.baseline
    # the fit's own scaling (analysis.pulse._fit_loading): force / F_0, (t - T_0) / tau_0
    f_scale, t_ref, t_scale = fit.peak_force, fit.time_of_flight, fit.duration
    p = np.array([1.0, 0.0, 1.0])
    s = (t - t_ref) / t_scale
    W = np.flatnonzero((t >= fit.window[0]) & (t <= fit.window[1]))
    if W.size < 3:
        raise PulseNotFound("the pulse fit has too few samples to differentiate")
    z = (y[W] - b0) / f_scale
    J = _cos6_jacobian(s[W], p)
    r = z - J[:, 0]  # residuals (a = 1: m = cos^6 = dm/da)
    H = J.T @ J
    for k in range(3):
        e = np.zeros(3, complex)
        e[k] = 1j * STEP
        d2 = _cos6_jacobian(s[W], p + e).imag / STEP  # d (grad m_i) / d p_k
        H[:, k] -= d2.T @ r
    # The window (b + w0 c, b + w1 c] follows the fit: as its ends move, samples enter and leave it,
    # and the values jump once per sample. Differentiated with the ends moving continuously (the
    # sum over the window as a density of samples, 1 / ds per unit of s): G = sum r_i grad m_i gains
    # r grad m / ds at each end times the end's motion. This is the slope of the jumps' envelope;
    # with the window held fixed the slope between two jumps can differ from it by a factor two.
    ds = float(np.median(np.diff(s)))
    w0, w1 = -1.0, 0.0  # fit_pulse's default fit_window (loading part, paper Sec. III)
    for w, sign in ((w1, 1.0), (w0, -1.0)):
        edge = p[1] + w * p[2]
        ze = (np.interp(edge, s, y) - b0) / f_scale
        je = _cos6_jacobian(np.array([edge]), p)[0]
        H -= sign * np.outer((ze - je[0]) * je, [0.0, 1.0, w]) / ds
    dp_dz = np.linalg.solve(H, J.T)  # (3, |W|): d p / d z_i
    n = t.size
    dp_dy = np.zeros((3, n))
    dp_dy[:, W] = dp_dz / f_scale
    # baseline: the median of the pre-pulse samples (0 when there are too few: then fixed)
    from ..analysis.pulse import MIN_BASELINE_POINTS, PRE_PULSE_GAP

    pre = np.flatnonzero(t < fit.time_of_flight - PRE_PULSE_GAP * fit.duration)
    db = np.zeros(n)
    if pre.size >= MIN_BASELINE_POINTS:
        order = pre[np.argsort(y[pre], kind="stable")]
        mid = order.size // 2
        if order.size % 2:
            db[order[mid]] = 1.0
        else:
            db[order[mid - 1]] = db[order[mid]] = 0.5
        dp_dy -= np.outer(dp_dz.sum(axis=1) / f_scale, db)
    dT = t_scale * dp_dy[1]
    dtau = t_scale * dp_dy[2]
    if name == "time_of_flight":
        return fit.time_of_flight, dT
    if name == "pulse_duration":
        return fit.duration, dtau
    if name != "front_momentum_at_wall":
        raise ConfigError("objective", f"unknown pulse quantity {name!r}")
    split = fit.time_of_flight + fit.duration
    w, f_split = _front_weights(t, y - b0, split)
    grad = w - (min(max(split, t[0]), t[-1]) - t[0]) * db + f_split * (dT + dtau)
    return fit.front_momentum, grad


def _front_weights(t: np.ndarray, f: np.ndarray, split: float) -> tuple[np.ndarray, float]:
    """Partials of Q_F = ``analysis.front_tail_momenta(t, f, split)[0]`` on f, and f at the split
    (the partial on the split time)."""
    n = t.size
    w = np.zeros(n)
    if split <= t[0]:
        return w, 0.0
    if split >= t[-1]:
        dt = np.diff(t)
        w[:-1] += 0.5 * dt
        w[1:] += 0.5 * dt
        return w, 0.0
    k = int(np.searchsorted(t, split, side="right"))  # t[k-1] <= split < t[k]
    dt = np.diff(t[:k])
    w[:k - 1] += 0.5 * dt
    w[1:k] += 0.5 * dt
    span = split - t[k - 1]
    lam = span / (t[k] - t[k - 1])
    f_split = f[k - 1] + (f[k] - f[k - 1]) * lam
    w[k - 1] += 0.5 * span * (2.0 - lam)
    w[k] += 0.5 * span * lam
    return w, float(f_split)
