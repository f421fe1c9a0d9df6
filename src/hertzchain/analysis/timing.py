"""Times of flight, local velocities and bead-to-bead fits (Melo et al., PRE 2006, Sec. III).

These work on per-bead series: the time of flight T_n and peak force F_m,n measured (or
simulated) at the end of chains truncated after bead n, as in the paper's Figs. 5 and 6.
All fits are linear least squares; their standard errors come from the residual scatter
(as scipy's ``curve_fit`` with ``absolute_sigma=False``), or from the given errors.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ConfigError
from ..theory import time_of_flight_uniform

if TYPE_CHECKING:
    from .pulse import PulseFit

__all__ = [
    "local_velocity", "VelocityGrowthFit", "fit_velocity_growth", "TimeOfFlightFit",
    "fit_uniform_time_of_flight", "RestitutionFit", "fit_restitution", "collapse",
]


def _series(name: str, values, size: int | None = None) -> np.ndarray:
    arr = np.asarray(values, dtype=float)
    if arr.ndim != 1 or not np.all(np.isfinite(arr)):
        raise ConfigError(name, "must be a 1-D array of finite numbers")
    if size is not None and arr.size != size:
        raise ConfigError(name, f"must have {size} entries (one per bead), got {arr.size}")
    return arr


def _linear_fit(x: np.ndarray, y: np.ndarray, sigma: np.ndarray | None):
    """Weighted least squares y = a + b x; returns (a, b, cov) with cov scaled by chi2/dof.

    With fewer than three points the scatter cannot be estimated and cov is NaN.
    """
    if x.size < 2:
        raise ConfigError("data", f"need at least two points for a straight-line fit, got {x.size}")
    w = np.ones_like(x) if sigma is None else 1.0 / np.asarray(sigma, dtype=float) ** 2
    design = np.column_stack([np.ones_like(x), x])
    normal = design.T @ (design * w[:, None])
    try:
        cov_unscaled = np.linalg.inv(normal)
    except np.linalg.LinAlgError as exc:
        raise ConfigError("data", "the abscissae are all equal; no straight line can be fitted") from exc
    a, b = cov_unscaled @ (design.T @ (w * y))
    dof = x.size - 2
    if dof > 0:
        chi2 = float(np.sum(w * (y - a - b * x) ** 2))
        cov = cov_unscaled * chi2 / dof
    else:
        cov = np.full((2, 2), math.nan)
    return float(a), float(b), cov


def local_velocity(diameters: ArrayLike, times: ArrayLike, *, t0: float | None = None) -> np.ndarray:
    """Local pulse velocity v_n = phi_n / (T_n - T_(n-1)) [m/s] (paper Sec. III, Fig. 6c).

    Parameters
    ----------
    diameters:
        phi_n [m] of consecutive beads.
    times:
        Times of flight T_n [s] at the same beads (wall force of the chain truncated after bead n).
    t0:
        Time [s] at the bead before the first one; when given the first bead gets a velocity too.

    Returns
    -------
    Velocities [m/s]: ``len(diameters) - 1`` values for beads 2..N of the input (``v[k]`` belongs
    to ``diameters[k + 1]``), or ``len(diameters)`` values when ``t0`` is given.
    """
    phi = _series("diameters", diameters)
    T = _series("times", times, phi.size)
    if t0 is not None:
        T = np.concatenate([[float(t0)], T])
    else:
        phi = phi[1:]
    dT = np.diff(T)
    if np.any(dT <= 0):
        raise ConfigError("times", "must increase from bead to bead (a pulse cannot arrive earlier further down)")
    return phi / dT


class VelocityGrowthFit(NamedTuple):
    """Fit of v_n = Q^(n - n') v_n' (paper Fig. 6c)."""

    Q: float
    """Per-bead velocity ratio Q [-] (the paper finds Q_1 = 1.025 +- 0.016, Q_2 = 1.049 +- 0.044)."""
    Q_err: float
    """Standard error of Q [-]."""
    v_ref: float
    """Fitted velocity v_n' [m/s] at the reference bead n'."""


def fit_velocity_growth(beads: ArrayLike, velocities: ArrayLike, n_ref: float | None = None, *,
                        velocity_err: ArrayLike | None = None) -> VelocityGrowthFit:
    """Fit local velocities to v_n = Q^(n - n') v_n' (paper Sec. III, Fig. 6c).

    A straight line is fitted to ln v_n against n - n' (log-linear least squares), which smooths
    the large scatter of single local velocities as the paper does.

    Parameters
    ----------
    beads:
        Bead numbers n.
    velocities:
        Local velocities v_n [m/s] (positive).
    n_ref:
        Reference bead n' (default: the first of ``beads``).
    velocity_err:
        Optional standard errors of v_n [m/s]; then the fit is weighted by (v_n / err_n)^2,
        the inverse variance of ln v_n.

    Returns
    -------
    VelocityGrowthFit(Q, Q_err, v_ref)
    """
    n = _series("beads", beads)
    v = _series("velocities", velocities, n.size)
    if np.any(v <= 0):
        raise ConfigError("velocities", "must be positive")
    sigma = None
    if velocity_err is not None:
        err = _series("velocity_err", velocity_err, n.size)
        if np.any(err <= 0):
            raise ConfigError("velocity_err", "must be positive")
        sigma = err / v
    n_ref = float(n[0]) if n_ref is None else float(n_ref)
    a, b, cov = _linear_fit(n - n_ref, np.log(v), sigma)
    Q = math.exp(b)
    return VelocityGrowthFit(Q=Q, Q_err=Q * math.sqrt(cov[1, 1]), v_ref=math.exp(a))


class TimeOfFlightFit(NamedTuple):
    """Fit of T_n = T0 + (phi_0 / v_1) (1 - eps^(-n/5)) / (1 - eps^(-1/5)) (paper Sec. III)."""

    v1: float
    """Wave speed at bead 1 [m/s]."""
    v1_err: float
    """Standard error of v1 [m/s]."""
    T0: float
    """Time of flight extrapolated to bead 0 [s]."""
    T0_err: float
    """Standard error of T0 [s]."""


def fit_uniform_time_of_flight(beads: ArrayLike, times: ArrayLike, phi0: float, eps: float = 1.0) -> TimeOfFlightFit:
    """Fit times of flight in a uniform chain with restitution for v_1 and T_0 (paper Sec. III).

    T_n = T0 + sum_{m=1}^{n} phi_0 / v_m with v_m = v_1 eps^((m-1)/5) (eq. 8, q = 0) is linear
    in T0 and phi_0 / v_1 once eps is known, so an ordinary least-squares line in
    S_n = (1 - eps^(-n/5)) / (1 - eps^(-1/5)) gives both; the error of v_1 follows by
    propagation.

    Parameters
    ----------
    beads:
        Bead numbers n (<= n0, the uniform part).
    times:
        Times of flight T_n [s].
    phi0:
        Bead diameter [m].
    eps:
        Per-bead restitution factor [-] (from :func:`fit_restitution`).

    Returns
    -------
    TimeOfFlightFit(v1, v1_err, T0, T0_err)
    """
    n = _series("beads", beads)
    T = _series("times", times, n.size)
    if not (phi0 > 0 and eps > 0):
        raise ConfigError("phi0/eps", "must be positive")
    # S_n is T_n of a chain with phi_0 = v_1 = 1 and T0 = 0
    s_n = np.asarray(time_of_flight_uniform(n, 1.0, 1.0, 0.0, eps), dtype=float)
    a, b, cov = _linear_fit(s_n, T, None)
    if not b > 0:
        raise ConfigError("times", "do not increase with the bead number; no positive speed fits them")
    v1 = phi0 / b
    return TimeOfFlightFit(v1=v1, v1_err=phi0 * math.sqrt(cov[1, 1]) / b**2,
                           T0=a, T0_err=math.sqrt(cov[0, 0]))


class RestitutionFit(NamedTuple):
    """Restitution factor from the decay of the peak force (paper Sec. III)."""

    eps: float
    """eps = (F_m^(n+1) / F_m^n)^(5/6) [-]."""
    eps_err: float
    """Standard error of eps [-]."""


def fit_restitution(beads: ArrayLike, peak_forces: ArrayLike) -> RestitutionFit:
    """Estimate the paper's restitution factor eps from peak forces along a uniform chain.

    The paper defines eps = (F_m^(n+1) / F_m^n)^(5/6) = V_m^(n+1) / V_m^n (Sec. III, from
    eq. 5, F_m ~ V_m^(6/5)). With a constant eps, ln F_m,n is linear in n with slope
    (6/5) ln eps; the slope of a least-squares line gives eps = exp(5/6 * slope).

    Parameters
    ----------
    beads:
        Bead numbers n (in the uniform part).
    peak_forces:
        F_m,n [N] (positive).

    Returns
    -------
    RestitutionFit(eps, eps_err)
    """
    n = _series("beads", beads)
    F = _series("peak_forces", peak_forces, n.size)
    if np.any(F <= 0):
        raise ConfigError("peak_forces", "must be positive")
    _, slope, cov = _linear_fit(n, np.log(F), None)
    eps = math.exp(5.0 / 6.0 * slope)
    return RestitutionFit(eps=eps, eps_err=eps * 5.0 / 6.0 * math.sqrt(cov[1, 1]))


def collapse(time: ArrayLike, force: ArrayLike, fit: PulseFit) -> tuple[np.ndarray, np.ndarray]:
    """Rescale a record by its fitted pulse, for the self-similarity plot of paper Fig. 4.

    Parameters
    ----------
    time:
        Times [s].
    force:
        Forces [N].
    fit:
        The :class:`~hertzchain.analysis.pulse.PulseFit` of this record.

    Returns
    -------
    ((t - T) / tau, (F - baseline) / F_m), both dimensionless; the loading parts of all
    pulses fall on cos^6 of the first array.
    """
    t = np.asarray(time, dtype=float)
    f = np.asarray(force, dtype=float)
    return (t - fit.time_of_flight) / fit.duration, (f - fit.baseline) / fit.peak_force
