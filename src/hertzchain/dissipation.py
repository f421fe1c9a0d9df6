"""Dissipation: measure the paper's per-bead factor eps and calibrate a contact law to it.

Melo et al. (PRE 2006, Sec. III, text around eqs. 4-5) obtain eps from force measurements in the
monodisperse chain as

    eps = (F_m^{n+1} / F_m^n)^(5/6)  (= V_m^{n+1} / V_m^n),

and find eps ~ 0.985. This is an empirical per-bead decay factor of the travelling pulse, not a
two-body restitution coefficient (see the conventions page, dissipation). The engine's dissipative contact laws
(:class:`~hertzchain.contact.Viscoelastic`, Kuwabara-Kono, time constant A [s], and
:class:`~hertzchain.contact.Dashpot`, gamma [N s/m]) are therefore calibrated the way the paper
measures eps: a uniform chain is hit by the given striker, the peak force of the pulse is taken
at a range of contacts away from the striker transient and the free end, the geometric decay
F_{n+1}/F_n is fitted by log-linear least squares, and the law parameter is root-found so that
(ratio)^(5/6) equals the requested eps.

The dissipation of both laws depends on the pulse amplitude (the Kuwabara-Kono loss per bead
scales roughly as A / tau with tau ~ F_m^(-1/6); the dashpot's as gamma / (kappa tau delta^(1/2))),
so a calibration is only valid for the striker (diameter, material, speed) it was made with.
Two consequences worth knowing (26 mm AISI 52100 beads, 8 mm striker at 0.2 m/s, eps = 0.985):

- the same law also acts on the short, stiff striker contact: the pulse leaves the striker
  ~22 % (Kuwabara-Kono) or ~17 % (dashpot) weaker than in the elastic chain and loses more than
  eps^(6/5) per bead over the first few beads, so at bead 12 it is 0.60 (0.65) of the elastic
  amplitude, not 0.982^12 = 0.80; likewise smaller beads (shorter pulses) lose more per bead
  (the size-scaled :class:`~hertzchain.contact.ScaledViscoelastic`, A_j ~ (mu_j/kappa_j)^(2/5),
  keeps eps the same in geometrically similar chains: calibrate it as ``"viscoelastic_scaled"``;
  the size-scaled :class:`~hertzchain.contact.ScaledDashpot`, ``"dashpot_scaled"``, too, and its
  loss falls with the impact speed, so that the striker's own collision stays nearly elastic:
  a two-body restitution of 0.96 at 0.2 m/s where the Kuwabara-Kono laws give 0.68 and 0.86,
  see :func:`hertzchain.restitution` and the user guide's plasticity page);
- the loss per bead is not monotonic in the parameter: it peaks (eps ~ 0.970 near A ~ 2.5e-5 s;
  eps ~ 0.963 near gamma ~ 150 N s/m) and falls again as heavy damping spreads the pulse. Only
  the weak-damping branch is searched; a smaller eps is refused with a ConfigError.

Runs use the engine that ``integrator = "auto"`` gives the law's chains: the fourth-order RKN for
y'' = f(y, y') (:func:`hertzchain.integrate.drivers.rkn_damped.run_rkn_damped`, the elastic baseline
included) for Kuwabara-Kono and the dashpot, so that a calibrated run compiles one engine, not
two (issue 37: the Verlet's kernels cost ~13 CPU-s of a cold start); the compiled velocity
Verlet (:func:`hertzchain.integrate.drivers.verlet.run_verlet`) for a law rkn4 does not integrate. A
calibration of 26 mm AISI 52100 beads hit by an 8 mm striker takes about ten runs of a 34-bead
chain (a fraction of a second once the kernels are compiled). Results are cached.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import numpy as np
from scipy.optimize import brentq

from .chain import Chain
from .contact import (Dashpot, Elastic, ScaledDashpot, ScaledViscoelastic, SizedViscoelastic, Viscoelastic,
                      hertz_constant)
from .errors import ConfigError
from .integrate.drivers.refusals import why_not
from .integrate.drivers.rkn import DAMPED_EPS, RKN_RTOL, run_rkn
from .integrate.drivers.rkn_damped import run_rkn_damped
from .integrate.drivers.verlet import run_verlet
from .materials import Material, get_material
from .model import Model, Striker, Wall
from .laws import get_law, law_names, law_of_code

__all__ = ["EpsMeasurement", "refine_peaks", "fit_geometric_decay", "measure_eps", "calibrate_law",
           "DEFAULT_BEADS", "DEFAULT_TRAILING_BEADS"]

#: Contacts (n = first..last, "the right contact of bead n") whose peaks are fitted by default.
#: In a uniform 26 mm chain hit by an 8 mm striker the elastic peak force still exceeds its
#: settled value by 0.2 % at contact 8, 0.06 % at contact 10 and 0.015 % at contact 12 (striker
#: transient); from contact 12 on the transient biases the fitted ratio by < 1e-4 per bead.
DEFAULT_BEADS = (12, 30)
#: Beads kept after the last fitted contact. With a free end only the last ~2 contacts see the
#: end before their peak (peaks of a 36- and a 50-bead chain agree to 1e-6 up to contact 33).
DEFAULT_TRAILING_BEADS = 4
#: Sampling interval [s] of the calibration runs. The pulse lasts tau ~ 150 us in 26 mm beads; a
#: parabola through the three samples around the maximum then leaves an error of order
#: (h / tau)^4 ~ 1e-9 relative on the peak.
DEFAULT_SAMPLE_INTERVAL = 1e-6


class EpsMeasurement(NamedTuple):
    """Result of :func:`measure_eps`.

    ``eps`` = ``ratio``^(5/6) (paper Sec. III); errors are one standard error of the
    log-linear least-squares fit (they measure how far the decay is from geometric, not a
    sampling error). ``contacts`` are the contact numbers n (right contact of bead n) whose
    refined peak forces [N] and peak times [s] were fitted.
    """

    eps: float
    eps_err: float
    ratio: float
    ratio_err: float
    contacts: np.ndarray
    peak_force: np.ndarray
    peak_time: np.ndarray
    duration: float


def refine_peaks(time: np.ndarray, force: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Peak time [s] and force [N] of each column of ``force`` (time, contact), between samples.

    The sampled maximum is refined with the parabola through the sample of the maximum and its
    two neighbours, so that the sampling phase does not bias the ratio of consecutive peaks
    (a pulse F_m cos^6(t/tau) sampled every h loses up to 3 F_m (h/2tau)^2 at the raw maximum).
    A maximum on the first or last sample is returned unrefined.
    """
    time = np.asarray(time, dtype=float)
    force = np.asarray(force, dtype=float)
    if force.ndim == 1:
        force = force[:, None]
    k = np.argmax(force, axis=0)
    cols = np.arange(force.shape[1])
    f_pk = force[k, cols].copy()
    t_pk = time[k].copy()
    h = time[1] - time[0]
    inner = (k > 0) & (k < force.shape[0] - 1)
    ki, ci = k[inner], cols[inner]
    fb, f0, fa = force[ki - 1, ci], force[ki, ci], force[ki + 1, ci]
    denom = fb - 2.0 * f0 + fa
    ok = denom < 0.0
    s = np.where(ok, 0.5 * (fb - fa) / np.where(ok, denom, -1.0), 0.0)
    f_pk[inner] = f0 - 0.25 * (fb - fa) * s
    t_pk[inner] = time[ki] + s * h
    return t_pk, f_pk


def fit_geometric_decay(contacts: np.ndarray, peaks: np.ndarray) -> tuple[float, float]:
    """Least-squares fit of ln F_n = a + n ln(r); returns (r, standard error of r).

    The standard error of the slope b = ln r is sqrt(s^2 / sum (n - <n>)^2) with s^2 the residual
    variance (n - 2 degrees of freedom); that of r is r times it.
    """
    x = np.asarray(contacts, dtype=float)
    y = np.log(np.asarray(peaks, dtype=float))
    if x.size < 3:
        raise ValueError("need at least 3 peaks to fit a geometric decay")
    xm = x - x.mean()
    sxx = float(np.sum(xm * xm))
    b = float(np.sum(xm * (y - y.mean())) / sxx)
    resid = y - y.mean() - b * xm
    s2 = float(np.sum(resid * resid)) / (x.size - 2)
    se = math.sqrt(s2 / sxx)
    r = math.exp(b)
    return r, r * se


def _uniform_chain(chain_or_diameter: Chain | float, material: Material | str, n_beads: int) -> Chain:
    if isinstance(chain_or_diameter, Chain):
        return chain_or_diameter
    d = float(chain_or_diameter)
    if not (math.isfinite(d) and d > 0):
        raise ConfigError("dissipation.diameter", f"must be a positive bead diameter in m, got {chain_or_diameter!r}")
    return Chain.uniform(n_beads, d, material)


def _duration_estimate(chain: Chain, striker: Striker, last: int) -> float:
    """Time [s] by which the pulse peak should have passed contact ``last`` (first guess).

    Uses the Nesterenko speed v = (6/(5 pi rho))^(1/2) (F_m / (theta^2 R^2))^(1/6) (paper Sec. III)
    of the first bead with F_m taken as 1/6 of the two-body striker-bead peak force (about the
    ratio of the settled wave to the impact force for an 8 mm striker on 26 mm beads); since
    v ~ F_m^(1/6) a poor guess changes the time little, and :func:`measure_eps` extends the run
    when the peak has not passed.
    """
    mat = chain.materials[0]
    r = chain.radii[0]
    m1 = chain.masses[0]
    mu = striker.mass * m1 / (striker.mass + m1)
    kap = hertz_constant(striker.diameter / 2, r, striker.material, mat)
    delta_m = (1.25 * mu * striker.velocity**2 / kap) ** 0.4
    f_m = kap * delta_m**1.5 / 6.0
    v = math.sqrt(6.0 / (5.0 * math.pi * mat.density)) * (f_m / (mat.theta**2 * r**2)) ** (1.0 / 6.0)
    tau = r * math.sqrt(10.0) / v
    return float(np.sum(chain.diameters[: last + 1]) / v + 3.0 * tau)


def _run_peaks(model: Model, contacts: np.ndarray, duration: float, sample_interval: float):
    system = model.system()
    spec = law_of_code(system.law)
    if why_not("rkn4", system) is None and not (spec.generated or spec.plastic):
        # rkn4's default accuracy (rkn.run_rkn's local error bound), on its y'' = f(y, y') method
        # for every law, the elastic baseline too: the kernels the calibrated run will use
        eps = RKN_RTOL * DAMPED_EPS * float(np.max(np.abs(system.v0)))
        raw = run_rkn_damped(system, duration, sample_interval, None, eps, False, contacts, None, 200_000, False)
    elif why_not("rkn4", system) is None:  # a registry or elastic-plastic law: rkn4 on its own functions
        raw = run_rkn(system, duration, sample_interval, contacts=contacts)
    else:
        raw = run_verlet(system, duration, sample_interval, contacts=contacts)
    t_pk, f_pk = refine_peaks(raw.time, raw.contact_force)
    # The pulse has passed the last fitted contact when its maximum lies well inside the record
    # and the force there has fallen below half the peak.
    last = raw.contact_force[:, -1]
    passed = bool(np.argmax(last) < last.size - 3 and last[-1] < 0.5 * f_pk[-1] and f_pk[-1] > 0)
    return t_pk, f_pk, passed


def measure_eps(law: Elastic | Viscoelastic | Dashpot, chain_or_diameter: Chain | float,
                material: Material | str = "AISI52100", striker: Striker | None = None, *,
                n_beads: int | None = None, beads: tuple[int, int] = DEFAULT_BEADS,
                sample_interval: float = DEFAULT_SAMPLE_INTERVAL, duration: float | None = None) -> EpsMeasurement:
    """Measure the paper's per-bead factor eps = (F_{n+1}/F_n)^(5/6) of a contact law (Sec. III).

    A chain with a free end (no wall, so nothing is reflected back onto the fitted contacts) is
    hit by ``striker``; the peak force of every contact n = first..last is refined between samples
    (:func:`refine_peaks`) and the geometric decay ratio is fitted by log-linear least squares
    (:func:`fit_geometric_decay`).

    Parameters
    ----------
    law
        Contact law, e.g. ``Viscoelastic(A=3e-6)`` (A [s]) or ``Dashpot(gamma=20.0)`` (gamma [N s/m]).
    chain_or_diameter
        A :class:`Chain` used as given (it should be uniform: the decay of a tapered chain also
        holds the (1 - q)^2 geometric factor of paper eq. 5), or a bead diameter [m] for a
        uniform chain of ``n_beads`` beads of ``material``.
    material
        Bead material when a diameter is given.
    striker
        The impacting sphere (default :class:`Striker`: 8 mm AISI 52100 at 0.5 m/s); its speed
        matters, since both laws dissipate a fraction of the pulse that depends on amplitude.
    n_beads
        Chain length for a diameter; default ``last + DEFAULT_TRAILING_BEADS``.
    beads
        (first, last) contact numbers fitted, away from the striker transient (default (12, 30)).
    sample_interval
        Sampling interval [s] of the contact forces (default 1 us).
    duration
        First guess of the simulated time [s] (default: estimated from the solitary-wave speed);
        the run is repeated 1.5 times longer until the pulse has passed contact ``last``.

    Returns
    -------
    EpsMeasurement
        eps, its standard error, the per-bead force ratio F_{n+1}/F_n and its error, the fitted
        peaks.
    """
    first, last = int(beads[0]), int(beads[1])
    if not (1 <= first and last - first >= 2):
        raise ConfigError("dissipation.beads", f"need 1 <= first and at least 3 contacts, got {beads!r}")
    striker = striker if striker is not None else Striker()
    material = get_material(material)
    if n_beads is None:
        n_beads = last + DEFAULT_TRAILING_BEADS
    chain = _uniform_chain(chain_or_diameter, material, n_beads)
    if last >= chain.n_beads:
        raise ConfigError("dissipation.beads", f"last contact {last} must be an inter-bead contact of the "
                          f"{chain.n_beads}-bead chain (at most {chain.n_beads - 1})")
    model = Model(chain, striker, Wall("none"), law)
    contacts = np.arange(first, last + 1)
    if duration is None:
        duration = _duration_estimate(chain, striker, last)
    for _ in range(8):
        t_pk, f_pk, passed = _run_peaks(model, contacts, duration, sample_interval)
        if passed:
            break
        duration *= 1.5
    if not passed:
        raise ConfigError("dissipation.duration", f"the pulse has not passed contact {last} after "
                          f"{duration:.3g} s; give a longer duration")
    ratio, ratio_err = fit_geometric_decay(contacts, f_pk)
    eps = ratio ** (5.0 / 6.0)
    return EpsMeasurement(eps=eps, eps_err=(5.0 / 6.0) * eps * ratio_err / ratio, ratio=ratio, ratio_err=ratio_err,
                          contacts=contacts, peak_force=f_pk, peak_time=t_pk, duration=float(duration))


#: Smallest per-bead factor :func:`calibrate_law` searches for. The laws' loss per bead peaks on
#: their weak-damping branch (eps ~ 0.970 for 26 mm beads hit at 0.2 m/s; the viscoelastic loss
#: grows as v^(1/5), the dashpot's as v^(-1/5): eps ~ 0.84 at 1000 m/s, ~ 0.70 at 1 um/s).
MIN_EPS = 0.5
#: The calibration searches parameters up to a damping time of this many pulse durations (the
#: loss per bead peaks near A ~ 0.3 tau and falls beyond; and each run slows as A grows).
MAX_DAMPING_DURATIONS = 2.0

#: Laws that :func:`calibrate_law` can calibrate, with the name of their parameter: the built-in
#: Kuwabara-Kono (A) and dashpot (gamma) laws and their size-scaled forms, as the registry declares
#: them (a generated law declares no calibrated parameter: it has no calibration search).
CALIBRATED_LAWS = {name: get_law(name).calibrated for name in law_names()
                   if get_law(name).calibrated and not get_law(name).generated}


def _make_law(kind: str, parameter: float, diameter: float, material: Material):
    """The law ``kind`` with ``parameter``; a size-scaled law takes the calibration beads as reference."""
    spec = get_law(kind)
    assert spec.make is not None  # every registered law has its maker (laws.spec.attach_maker)
    return spec.make({p: parameter if p == spec.calibrated else None for p in spec.param_names},
                     Chain.uniform(1, diameter, material))


@functools.lru_cache(maxsize=256)
def _calibrate_cached(kind: str, eps: float, diameter: float, material: Material, striker: Striker,
                      n_beads: int, beads: tuple[int, int], xtol: float) -> float:
    """Law parameter (A [s] or gamma [N s/m]) giving ``eps``; cached on its hashable inputs."""
    chain = Chain.uniform(n_beads, diameter, material)
    # The elastic run gives the first duration of the calibration runs (a decaying pulse slows
    # down, v ~ F_m^(1/6), so measure_eps lengthens it when needed; the longest one is kept for
    # the next runs) and the elastic baseline of the fit.
    base = measure_eps(Elastic(), chain, striker=striker, beads=beads)
    duration = [base.duration * 1.05]
    loss_target = -math.log(eps)

    cache: dict[float, float] = {}

    def loss(z: float) -> float:
        """-ln eps measured with the parameter p = exp(z) (memoised: Brent re-reads its ends)."""
        if z not in cache:
            m = measure_eps(_make_law(kind, math.exp(z), diameter, material), chain, striker=striker, beads=beads, duration=duration[0])
            duration[0] = max(duration[0], m.duration)
            cache[z] = -math.log(m.eps)
        return cache[z]

    def unreachable(best: float, z: float) -> ConfigError:
        name = CALIBRATED_LAWS[kind]
        return ConfigError("contact.eps", f"the {kind} law cannot give eps = {eps} in a uniform chain of "
                           f"{diameter * 1e3:g} mm beads hit by this striker: the smallest eps found is {math.exp(-best):.4f} "
                           f"(near {name} = {math.exp(z):.3g}); stronger damping spreads the pulse and lowers "
                           "the loss per bead again")

    # First guess from the dimensions of the problem: a Kuwabara-Kono loss per bead ~ A / tau,
    # with tau the pulse duration (paper Sec. III, tau = R sqrt(10) / v); a dashpot gamma ~
    # kappa A delta_m^(1/2) gives the same damping force at the peak overlap.
    t = base.peak_time
    v = diameter / float(np.mean(np.diff(t)))
    tau = 0.5 * diameter * math.sqrt(10.0) / v
    kap = hertz_constant(diameter / 2, diameter / 2, material, material)
    delta_m = (float(np.mean(base.peak_force)) / kap) ** (2.0 / 3.0)

    def parameter(a: float) -> float:
        """The law's parameter for a damping time ``a`` [s]."""
        return a if get_law(kind).calibrated == "A" else kap * a * math.sqrt(delta_m)

    p0 = parameter(min(0.5 * tau * loss_target, MAX_DAMPING_DURATIONS * tau))
    z_max = math.log(parameter(MAX_DAMPING_DURATIONS * tau))
    # For weak damping the loss is nearly proportional to the parameter: one secant step from p0
    # lands within a few per cent (the step is capped at x4: the loss per bead is not monotonic,
    # it peaks -- at eps ~ 0.970 for A ~ 2.5e-5 s in 26 mm beads hit at 0.2 m/s -- and falls again
    # as heavy damping spreads the pulse; only the first, weak-damping branch is searched). The
    # root is then bracketed in z = ln p and polished by Brent's method.
    base_loss = -math.log(base.eps)
    if not loss_target > base_loss:
        raise ConfigError("contact.eps", f"eps = {eps} is closer to 1 than the calibration resolves: the elastic "
                          f"chain itself measures eps = {base.eps:.7f} over contacts {beads[0]}-{beads[1]} "
                          "(striker transient); use eps = 1 or the elastic law")
    z0 = math.log(p0)
    l0 = loss(z0)
    if not l0 > base_loss:
        raise RuntimeError(f"the {kind} law with parameter {p0:.3g} does not dissipate (eps {math.exp(-l0):.6f})")
    z1 = min(z0 + min(math.log((loss_target - base_loss) / (l0 - base_loss)), math.log(4.0)), z_max)
    step = math.log(1.05)
    lo, hi = z1 - step, min(z1 + step, z_max)
    flo, fhi = loss(lo) - loss_target, loss(hi) - loss_target
    for _ in range(60):
        if flo <= 0.0 <= fhi:
            break
        if flo > fhi:  # the loss no longer grows with the parameter: past the weak-damping branch
            raise unreachable(max(cache.values()), max(cache, key=lambda z: cache[z]))
        if flo > 0.0:
            hi, fhi = lo, flo
            lo -= math.log(1.5)
            flo = loss(lo) - loss_target
        else:
            if hi >= z_max:  # as strong as the search goes, and still too weak
                raise unreachable(max(cache.values()), max(cache, key=lambda z: cache[z]))
            lo, flo = hi, fhi
            hi = min(hi + math.log(1.5), z_max)
            fhi = loss(hi) - loss_target
    else:
        raise RuntimeError(f"could not bracket the {kind} parameter for eps = {eps}")
    x = brentq(lambda z: loss(z) - loss_target, lo, hi, xtol=xtol)
    return math.exp(x)


def calibrate_law(law: str, eps: float, chain: Chain | None = None, striker: Striker | None = None, *,
                  diameter: float | None = None, material: Material | str | None = None,
                  n_beads: int | None = None, beads: tuple[int, int] = DEFAULT_BEADS,
                  xtol: float = 1e-5) -> Viscoelastic | ScaledViscoelastic | SizedViscoelastic | Dashpot | ScaledDashpot:
    """Contact law whose per-bead factor in a uniform chain is ``eps`` (paper Sec. III).

    The paper measures eps ~ 0.985 in the 26 mm monodisperse part of its chains, so the uniform
    calibration chain is made of the FIRST bead of ``chain`` (its diameter and material) unless
    ``diameter`` / ``material`` are given. The parameter is found with Brent's method on its
    logarithm so that :func:`measure_eps` returns ``eps`` (relative step ``xtol`` on the
    parameter; a 1e-5 relative change of A moves eps by ~2e-7). Results are cached.

    Parameters
    ----------
    law
        ``"viscoelastic"`` (Kuwabara-Kono, returns :class:`Viscoelastic` with A [s]),
        ``"viscoelastic_scaled"`` (Kuwabara-Kono with A_j following each contact's collision time,
        returns :class:`ScaledViscoelastic` whose reference beads are the calibration chain's, so
        that every uniform chain of similar beads hit at the same speed by a similar striker
        measures the same eps), ``"viscoelastic_sized"`` (returns :class:`SizedViscoelastic`:
        A_j following the square of each contact's collision time, the restitution falling with
        speed while a light striker's contact loses less than the beads'), ``"dashpot"`` (returns :class:`Dashpot` with gamma [N s/m]) or
        ``"dashpot_scaled"`` (returns :class:`ScaledDashpot`: gamma_j following each contact pair,
        the same restitution for every pair at a given speed, reference beads as above).
    eps
        Target per-bead factor [-], 0 < eps <= 1; eps = 1 returns the parameter 0 (elastic).
    chain
        The chain to be simulated; only its first bead is used.
    striker
        The striker of the run to be simulated (default :class:`Striker`). Its mass and speed set
        the pulse amplitude, on which both laws' dissipation depends.
    diameter, material
        Bead diameter [m] and material of the calibration chain, overriding ``chain``.
    n_beads, beads
        Calibration chain length and fitted contacts (see :func:`measure_eps`).
    xtol
        Relative tolerance on the law parameter (dimensionless).

    Returns
    -------
    Viscoelastic or ScaledViscoelastic or SizedViscoelastic or Dashpot or ScaledDashpot
        The calibrated law (A [s] or gamma [N s/m]).

    Raises
    ------
    ConfigError
        (field ``contact.eps``) when eps is out of [MIN_EPS, 1], smaller than the law can give on its
        weak-damping branch, or closer to 1 than the striker transient lets the fit resolve.
    """
    if law not in CALIBRATED_LAWS:
        raise ConfigError("contact.law", f"calibration needs one of {', '.join(map(repr, CALIBRATED_LAWS))}, got {law!r}")
    eps = float(eps)
    if not (MIN_EPS <= eps <= 1.0):
        raise ConfigError("contact.eps", f"must lie in [{MIN_EPS:g}, 1], got {eps!r}: the contact laws lose a few "
                          "per cent of the pulse per bead at most (eps ~ 0.97 and above)")
    if diameter is None:
        if chain is None:
            if eps == 1.0:  # nothing to calibrate; the reference beads of a scaled law: the paper's
                diameter = 26e-3
            else:
                raise ConfigError("contact.eps", "calibration needs a chain or a bead diameter")
        else:
            diameter = float(chain.diameters[0])
    if material is None:
        material = chain.materials[0] if chain is not None else "AISI52100"
    if eps == 1.0:
        return _make_law(law, 0.0, float(diameter), get_material(material))
    striker = striker if striker is not None else Striker()
    first, last = int(beads[0]), int(beads[1])
    n = int(n_beads) if n_beads is not None else last + DEFAULT_TRAILING_BEADS
    param = _calibrate_cached(law, eps, float(diameter), get_material(material), striker, n, (first, last),
                              float(xtol))
    return _make_law(law, param, float(diameter), get_material(material))
