"""Closed-form theory of a pulse in a (tapered) Hertzian chain, Melo et al., PRE 2006, Sec. III.

Everything here is a plain function of numbers (SI units: m, kg, s, N, Pa) and needs no
simulation. Equation numbers are those of the paper:

- eq. 1  Hertz contact, F = kappa delta^(3/2) (implemented in :mod:`hertzchain.contact`);
- eq. 3-4 Nesterenko's solitary wave and its force profile F = F_m cos^6[(x - v t)/(R sqrt(10))];
- eq. 5  the solitary wave speed v as a function of the peak force F_m or the peak bead velocity V_m;
- eq. 6  ballistic bead-velocity ratio V_m^(n+1)/V_m^n = 2 eps / (1 + (1 - q)^3);
- eq. 7  peak-force ratio F_m^(n+1)/F_m^n = (1 - q)^2 [2 eps / (1 + (1 - q)^3)]^(6/5);
- eq. 8  wave-speed ratio v_(n+1)/v_n = [2 eps / (1 + (1 - q)^3)]^(1/5).

Beads are numbered 1..N from the impact end, as in the paper; the first ``n0`` beads form the
uniform (monodisperse) part of diameter phi_0 and the tapered part starts at bead n0 + 1.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike

from .contact import yield_force
from .errors import ConfigError
from .materials import Material, get_material

__all__ = [
    "HERTZ_CONTACT_TIME",
    "two_body_impact",
    "PAPER_CHAINS",
    "PAPER_N0",
    "PAPER_RESTITUTION",
    "HALF_MAX_PHASE",
    "tapering_factor",
    "BallisticRatios",
    "ballistic_ratios",
    "solitary_wave_speed",
    "solitary_wave_speed_from_velocity",
    "peak_bead_velocity",
    "nesterenko_force",
    "yield_limit",
    "pulse_duration",
    "ChainPrediction",
    "predict_chain",
    "time_of_flight_uniform",
]

#: Bead diameters [mm] of the two tapered chains of the paper's Table I (beads 1..N; beads 1-16
#: form the uniform part of diameter phi_0 = 26 mm). Chain 1 has q1 = 5.60 %, chain 2 q2 = 8.27 %.
PAPER_CHAINS: dict[str, list[float]] = {
    "chain1": [26.00] * 16 + [24.00, 23.00, 22.00, 21.00, 20.00, 19.00, 18.00,
                              16.65, 16.00, 15.00, 14.00, 13.00, 12.00, 11.00],
    "chain2": [26.00] * 16 + [24.00, 22.00, 20.00, 18.00, 16.65, 16.00, 14.00,
                              13.00, 12.00, 11.00, 10.00, 9.00],
}

#: Number of beads of the uniform part in the paper's experiments (Sec. II).
PAPER_N0: int = 16

#: The paper's empirical per-bead restitution factor eps = (F_m^(n+1)/F_m^n)^(5/6) (Sec. III).
PAPER_RESTITUTION: float = 0.985

#: Phase (t - T)/tau at which F_m cos^6 reaches half its maximum on the rise: -arccos(2^(-1/6)).
HALF_MAX_PHASE: float = -math.acos(0.5 ** (1.0 / 6.0))


def _positive(name: str, value: float) -> float:
    value = float(value)
    if not (math.isfinite(value) and value > 0):
        raise ConfigError(name, f"must be a positive finite number, got {value!r}")
    return value


# --------------------------------------------------------------------------------------------
# Geometry of the tapered chain
# --------------------------------------------------------------------------------------------
def tapering_factor(diameters: ArrayLike, n0: int = PAPER_N0) -> tuple[float, float]:
    """Tapering factor q of a chain and its sample standard deviation (paper Sec. II).

    The paper defines q = 1 - <(phi_n / phi_0)^(1/(n - n0))>_{n > n0}: every bead of the tapered
    part gives its own estimate of the per-bead shrink factor (1 - q), and the estimates are
    averaged. (The printed formula drops the ``1/`` of the exponent; only the 1/(n - n0) exponent
    reproduces the paper's values, 5.60 +- 0.67 % and 8.27 +- 0.31 % for the Table I chains.)

    Parameters
    ----------
    diameters
        Bead diameters phi_1..phi_N in any unit (only ratios enter); phi_0 = ``diameters[0]``.
    n0
        Number of beads of the uniform part; beads n > n0 are the tapered part.

    Returns
    -------
    (q, q_std):
        q [-] (a fraction, 0.056 for 5.6 %) and the unbiased sample standard deviation
        (ddof = 1) of the per-bead estimates, the paper's error bar. ``q_std`` is NaN when the
        tapered part has a single bead.
    """
    phi = np.asarray(diameters, dtype=float)
    if phi.ndim != 1 or not np.all(np.isfinite(phi)) or np.any(phi <= 0):
        raise ConfigError("diameters", "must be a 1-D sequence of positive finite numbers")
    if not (0 <= n0 < phi.size):
        raise ConfigError("n0", f"must satisfy 0 <= n0 < number of beads ({phi.size}), got {n0}")
    n = np.arange(1, phi.size + 1)
    tapered = n > n0
    shrink = (phi[tapered] / phi[0]) ** (1.0 / (n[tapered] - n0))
    q = 1.0 - float(shrink.mean())
    q_std = float(shrink.std(ddof=1)) if shrink.size > 1 else math.nan
    return q, q_std


# --------------------------------------------------------------------------------------------
# Ballistic approximation (eqs. 6-8)
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class BallisticRatios:
    """Bead-to-bead ratios of the ballistic approximation (paper eqs. 6-8), all dimensionless.

    Attributes
    ----------
    velocity:
        V_m^(n+1) / V_m^n = 2 eps / (1 + (1 - q)^3), eq. 6 (peak bead velocity).
    force:
        F_m^(n+1) / F_m^n = (1 - q)^2 [2 eps / (1 + (1 - q)^3)]^(6/5), eq. 7 (peak force).
    speed:
        v_(n+1) / v_n = [2 eps / (1 + (1 - q)^3)]^(1/5), eq. 8 (wave speed, the paper's Q_th).
    """

    velocity: float | np.ndarray
    force: float | np.ndarray
    speed: float | np.ndarray


def ballistic_ratios(q: float | np.ndarray, eps: float = 1.0) -> BallisticRatios:
    """Ballistic-approximation ratios between consecutive beads (paper eqs. 6, 7, 8).

    A bead of mass m hits the next one, of mass (1 - q)^3 m, as in a two-body collision with the
    empirical restitution factor eps; the pulse is assumed to re-adapt to the self-similar
    Nesterenko shape at every bead, so that eq. 5 turns the velocity ratio into force and
    speed ratios.

    Parameters
    ----------
    q
        Tapering factor [-] (phi_(n+1) = (1 - q) phi_n); scalar or array.
    eps
        Per-bead restitution factor [-] (the paper measures 0.985; 1 = elastic).

    Returns
    -------
    BallisticRatios
        ``velocity`` (eq. 6), ``force`` (eq. 7) and ``speed`` (eq. 8), with the shape of ``q``.
        For q = 0.056 and eps = 0.985, ``speed`` = 1.014, the paper's Q_1^th.
    """
    q_arr = np.asarray(q, dtype=float)
    shrink = 1.0 - q_arr
    velocity = 2.0 * eps / (1.0 + shrink**3)
    force = shrink**2 * velocity ** (6.0 / 5.0)
    speed = velocity ** (1.0 / 5.0)
    if q_arr.ndim == 0:
        return BallisticRatios(float(velocity), float(force), float(speed))
    return BallisticRatios(velocity, force, speed)


# --------------------------------------------------------------------------------------------
# Nesterenko solitary wave (eqs. 3-5)
# --------------------------------------------------------------------------------------------
def solitary_wave_speed(material: str | Material, diameter: float | np.ndarray,
                        peak_force: float | np.ndarray) -> float | np.ndarray:
    """Speed v [m/s] of Nesterenko's solitary wave of peak force F_m (paper eq. 5, first form).

    v = (6 / (5 pi rho))^(1/2) (F_m / (theta^2 R^2))^(1/6), with R = diameter / 2 and
    theta = 3 (1 - nu^2) / (4 Y). This is the long-wavelength (continuum) result; the discrete
    chain's wave is about 1 % faster at the same F_m (see the theory page of the documentation).

    Parameters
    ----------
    material
        Bead material (catalogue name or :class:`~hertzchain.materials.Material`).
    diameter
        Bead diameter phi [m].
    peak_force
        Peak contact force F_m [N] of the wave.

    Returns
    -------
    float or numpy.ndarray
        Wave speed v [m/s], with the broadcast shape of ``diameter`` and ``peak_force``.
    """
    mat = get_material(material)
    radius = np.asarray(diameter, dtype=float) / 2.0
    force = np.asarray(peak_force, dtype=float)
    v = math.sqrt(6.0 / (5.0 * math.pi * mat.density)) * (force / (mat.theta**2 * radius**2)) ** (1.0 / 6.0)
    return float(v) if np.ndim(v) == 0 else v


def solitary_wave_speed_from_velocity(material: str | Material,
                                      bead_velocity: float | np.ndarray) -> float | np.ndarray:
    """Speed v [m/s] of the solitary wave from the peak bead velocity V_m (paper eq. 5, second form).

    v = (6 / (5 pi rho))^(2/5) (V_m / theta^2)^(1/5). Independent of the bead size. It agrees
    with :func:`solitary_wave_speed` when V_m = v delta_m / (2R), the continuum relation between
    particle velocity and strain (V_m = v psi_m, psi_m = delta_m / (2R), F_m = kappa delta_m^(3/2));
    see :func:`peak_bead_velocity`.

    Parameters
    ----------
    material:
        Bead material.
    bead_velocity:
        Peak bead velocity V_m [m/s] in the wave.
    """
    mat = get_material(material)
    vel = np.asarray(bead_velocity, dtype=float)
    v = (6.0 / (5.0 * math.pi * mat.density)) ** 0.4 * (vel / mat.theta**2) ** 0.2
    return float(v) if np.ndim(v) == 0 else v


def peak_bead_velocity(material: str | Material, diameter: float | np.ndarray,
                       peak_force: float | np.ndarray) -> float | np.ndarray:
    """Peak bead velocity V_m [m/s] in a solitary wave of peak force F_m (relation behind eq. 5).

    In the continuum solution (eq. 3) the particle velocity is v times the strain psi, and the
    peak strain is psi_m = delta_m / (2R) with F_m = kappa delta_m^(3/2) (eq. 1, two equal
    spheres: 1/kappa = 2 theta sqrt(2/R)). Hence V_m = v (F_m / kappa)^(2/3) / (2R), v from
    eq. 5. Inverting this reproduces the second form of eq. 5.

    Parameters
    ----------
    material:
        Bead material.
    diameter:
        Bead diameter phi [m].
    peak_force:
        Peak contact force F_m [N].
    """
    mat = get_material(material)
    radius = np.asarray(diameter, dtype=float) / 2.0
    kappa = 1.0 / (2.0 * mat.theta * np.sqrt(2.0 / radius))
    delta_m = (np.asarray(peak_force, dtype=float) / kappa) ** (2.0 / 3.0)
    vel = solitary_wave_speed(mat, 2.0 * radius, peak_force) * delta_m / (2.0 * radius)
    return float(vel) if np.ndim(vel) == 0 else vel


def nesterenko_force(xi_or_t: float | np.ndarray, peak_force: float,
                     width: float) -> float | np.ndarray:
    """One hump of Nesterenko's solitary wave, F = F_m cos^6(x / w) (paper eq. 4), w = ``width``.

    The periodic solution of the continuum equation (eq. 3) is cut to a single hump,
    abs(x / w) < pi/2, and is exactly zero outside (a compacton), as the paper does.

    Parameters
    ----------
    xi_or_t
        Position in the wave frame xi = x - v t [m] with ``width`` = R sqrt(10) [m], or a time
        offset t - T [s] with ``width`` = tau [s] (the form fitted to signals, Sec. III).
    peak_force
        F_m [N].
    width
        R sqrt(10) [m] in space, or tau [s] in time; must be positive.

    Returns
    -------
    float or numpy.ndarray
        Force [N], with the shape of ``xi_or_t``.
    """
    width = _positive("width", width)
    phase = np.asarray(xi_or_t, dtype=float) / width
    force = np.where(np.abs(phase) < math.pi / 2.0, peak_force * np.cos(phase) ** 6, 0.0)
    return float(force) if force.ndim == 0 else force


def yield_limit(material: str | Material, diameter: float) -> tuple[float, float]:
    """Elastic limit of the contact of two equal beads, as estimated in the paper (Sec. II).

    Yield is reached when the mean contact pressure F / (pi a^2) equals sigma_Y, with
    a^3 = theta R F (Landau-Lifshitz contact radius for two equal spheres, eq. 1 geometry).
    For 26 mm AISI 52100 beads this gives F_Y ~ 470 N and delta_Y ~ 11 um, as in the paper.

    Parameters
    ----------
    material
        Bead material (must have a ``yield_stress``; otherwise (inf, inf) is returned).
    diameter
        Bead diameter [m].

    Returns
    -------
    (F_Y [N], delta_Y [m])
    """
    radius = _positive("diameter", diameter) / 2.0
    mat = get_material(material)
    return yield_force(radius, radius, mat, mat)


def pulse_duration(diameter: float | np.ndarray, speed: float | np.ndarray) -> float | np.ndarray:
    """Duration tau [s] of the solitary wave seen at a fixed point (paper Sec. III, Fig. 5c).

    The spatial width R sqrt(10) of eq. 4 travelling at speed v gives tau = (phi / 2) sqrt(10) / v:
    the signal is F_m cos^6((t - T) / tau).

    Parameters
    ----------
    diameter:
        Bead diameter phi [m].
    speed:
        Wave speed v [m/s].
    """
    tau = np.asarray(diameter, dtype=float) / 2.0 * math.sqrt(10.0) / np.asarray(speed, dtype=float)
    return float(tau) if tau.ndim == 0 else tau


#: Hertz's two-body contact time in units of delta_m / v: 2 int_0^1 dx / sqrt(1 - x^(5/2))
#: = 2 sqrt(pi) Gamma(2/5) / (5/2 Gamma(9/10)) = 2.9432 (Landau & Lifshitz, Theory of Elasticity, Sec. 9).
HERTZ_CONTACT_TIME = 2.0 * math.sqrt(math.pi) * math.gamma(0.4) / (2.5 * math.gamma(0.9))


def two_body_impact(mu: float, kappa: float, velocity: float) -> dict[str, float]:
    """Closed-form elastic impact of two bodies through one Hertz contact F = kappa delta^(3/2)
    (paper eq. 1; a sphere on a flat or on another sphere, the flat immovable or of finite mass).

    Energy balance mu v^2 / 2 = (2/5) kappa delta_m^(5/2) gives the largest overlap
    delta_m = (5 mu v^2 / (4 kappa))^(2/5), the peak force kappa delta_m^(3/2) and the contact
    time HERTZ_CONTACT_TIME delta_m / v (2.943 delta_m / v).

    Parameters
    ----------
    mu : float
        Reduced mass [kg] (the striker's mass against an immovable wall).
    kappa : float
        Hertz constant of the contact [N/m^1.5].
    velocity : float
        Relative impact speed [m/s].

    Returns
    -------
    dict
        ``max_overlap`` [m], ``peak_force`` [N], ``contact_time`` [s].
    """
    dm = (1.25 * mu * velocity**2 / kappa) ** 0.4
    return {"max_overlap": dm, "peak_force": kappa * dm**1.5, "contact_time": HERTZ_CONTACT_TIME * dm / velocity}


# --------------------------------------------------------------------------------------------
# Predictions along a chain
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ChainPrediction:
    """Ballistic-approximation prediction of the front pulse along a chain (arrays over beads).

    Attributes
    ----------
    bead:
        Bead numbers 1..N.
    diameter:
        phi_n [m].
    tapering:
        q_n [-] used between bead n - 1 and bead n (0 for bead 1).
    peak_force:
        F_m,n [N] (eq. 7 applied bead by bead).
    bead_velocity:
        Peak bead velocity V_m,n [m/s] (eq. 5 relation at bead 1, then eq. 6).
    speed:
        Wave speed v_n [m/s] (eq. 5 at bead 1, then eq. 8).
    duration:
        tau_n = (phi_n / 2) sqrt(10) / v_n [s].
    time_of_flight:
        T_n = T_(n-1) + phi_n / v_n [s], with T at bead 0 equal to the given T0.
    """

    bead: np.ndarray
    diameter: np.ndarray
    tapering: np.ndarray
    peak_force: np.ndarray
    bead_velocity: np.ndarray
    speed: np.ndarray
    duration: np.ndarray
    time_of_flight: np.ndarray


def predict_chain(diameters: Sequence[float], material: str | Material, peak_force0: float,
                  eps: float = 1.0, n0: int = PAPER_N0, T0: float = 0.0,
                  q: float | None = None) -> ChainPrediction:
    """Predict peak force, speed, duration and time of flight of the front pulse bead by bead.

    This is the paper's "monodisperse-ballistic approximation" (Sec. III, Figs. 5b-c, 6):

    - peak force: F_m,1 = ``peak_force0`` and F_m,n = F_m,n-1 * (eq. 7 ratio with q_n, eps);
      eps acts at every bead, uniform part included (there q_n = 0 and the ratio is eps^(6/5),
      the paper's definition eps = (F_m^(n+1) / F_m^n)^(5/6));
    - wave speed: v_1 from eq. 5 with F_m,1 and phi_1, then v_n = v_n-1 * (eq. 8 ratio), as the
      paper does ("we have used the calculated value of the quasisolitary wave speed at every bead
      from Eq. 8"). With the local tapering factor (``q=None``) this is *identical* to applying
      eq. 5 at every bead with F_m,n and phi_n, because eq. 8 is eq. 5 combined with eq. 7 and
      phi_n = (1 - q_n) phi_n-1. With a constant ``q`` the two differ wherever the real
      diameters depart from phi_0 (1 - q)^(n - n0), and eq. 8 keeps the paper's prediction;
    - duration tau_n = (phi_n / 2) sqrt(10) / v_n and time of flight T_n = T_n-1 + phi_n / v_n
      (Sec. III), both with the actual diameters.

    Parameters
    ----------
    diameters
        phi_1..phi_N [m] from the impact end.
    material
        Bead material (the same for all beads).
    peak_force0
        Peak force F_m [N] of the pulse at bead 1 (the uniform part).
    eps
        Per-bead restitution factor [-] (1 = elastic; the paper uses 0.985).
    n0
        Beads 1..n0 form the uniform part; a constant ``q`` acts only for n > n0.
    T0
        Time of flight [s] assigned to "bead 0" (the origin of the T_n sum).
    q
        Tapering factor [-]. None: local tapering q_n = 1 - phi_n / phi_n-1 (the chain as built). A number: that
        constant factor for every bead n > n0 (0 there elsewhere); ``q=0`` gives the paper's
        "restitution only" prediction (dashed lines of Fig. 5b).

    Returns
    -------
    ChainPrediction
    """
    phi = np.asarray(diameters, dtype=float)
    if phi.ndim != 1 or phi.size == 0 or not np.all(np.isfinite(phi)) or np.any(phi <= 0):
        raise ConfigError("diameters", "must be a non-empty 1-D sequence of positive diameters (m)")
    _positive("peak_force0", peak_force0)
    _positive("eps", eps)
    mat = get_material(material)
    n_beads = phi.size
    bead = np.arange(1, n_beads + 1)

    q_n = np.zeros(n_beads)
    if q is None:
        q_n[1:] = 1.0 - phi[1:] / phi[:-1]
    else:
        if not (math.isfinite(q) and q < 1.0):
            raise ConfigError("q", f"must be a finite number < 1, got {q!r}")
        q_n[bead > n0] = q
        q_n[0] = 0.0  # bead 1 has no predecessor; the pulse enters with the given F_m
    ratios = ballistic_ratios(q_n, eps)
    ratios_force = np.asarray(ratios.force)
    ratios_velocity = np.asarray(ratios.velocity)
    ratios_speed = np.asarray(ratios.speed)
    ratios_force[0] = ratios_velocity[0] = ratios_speed[0] = 1.0

    peak_force = peak_force0 * np.cumprod(ratios_force)
    speed = solitary_wave_speed(mat, phi[0], peak_force0) * np.cumprod(ratios_speed)
    bead_velocity = peak_bead_velocity(mat, phi[0], peak_force0) * np.cumprod(ratios_velocity)
    duration = pulse_duration(phi, speed)
    time_of_flight = T0 + np.cumsum(phi / speed)
    return ChainPrediction(bead=bead, diameter=phi, tapering=q_n, peak_force=peak_force,
                           bead_velocity=np.asarray(bead_velocity), speed=np.asarray(speed),
                           duration=np.asarray(duration), time_of_flight=time_of_flight)


def _geometric_sum(n: np.ndarray, eps: float) -> np.ndarray:
    """S_n = sum_{k=0}^{n-1} eps^(-k/5) = (1 - eps^(-n/5)) / (1 - eps^(-1/5)); S_n = n at eps = 1."""
    n = np.asarray(n, dtype=float)
    r = eps ** (-0.2)
    if abs(r - 1.0) < 1e-12:
        return n
    # expm1 keeps the ratio accurate when eps is close to 1 (1 - r^n loses digits there)
    log_r = math.log(r)
    return np.expm1(n * log_r) / math.expm1(log_r)


def time_of_flight_uniform(n: int | np.ndarray, phi0: float, v1: float, T0: float = 0.0,
                           eps: float = 1.0) -> float | np.ndarray:
    """Time of flight T_n [s] to bead n of a uniform chain with restitution (paper Sec. III).

    T_n = T0 + sum_{m=1}^{n} phi_0 / v_m with v_m = v_1 eps^((m-1)/5) (eq. 8 with q = 0), i.e.
    T_n = T0 + (phi_0 / v_1) (1 - eps^(-n/5)) / (1 - eps^(-1/5)); for eps = 1 the limit
    T0 + n phi_0 / v_1.

    Parameters
    ----------
    n:
        Bead number(s) n >= 0.
    phi0:
        Bead diameter phi_0 [m].
    v1:
        Wave speed at bead 1 [m/s].
    T0:
        Time [s] at n = 0.
    eps:
        Per-bead restitution factor [-].
    """
    _positive("phi0", phi0)
    _positive("v1", v1)
    _positive("eps", eps)
    t = T0 + phi0 / v1 * _geometric_sum(np.asarray(n), eps)
    return float(t) if np.ndim(t) == 0 else t
