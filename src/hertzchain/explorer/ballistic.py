"""The explorer's theory table: the ballistic approximation of the paper (Sec. III, eqs. 6-8)
beside what the simulated pulse does in the same chain.

The paper measures its ratios on chains truncated after bead n (the wall force of each
truncation, Figs. 5-6). One run of the whole chain holds the same information away from the wall:
contact n joins bead n to bead n + 1, so the pulse that contact n carries is the pulse that
reaches the end of bead n, and bead n's velocity is recorded (``[probes] velocities``). The
simulated ratios are measured on the first pulse at each bead, as the paper's fits do:

- V_m^(n+1)/V_m^n (eq. 6): the peak velocity of bead n during its first pulse;
- F_m^(n+1)/F_m^n (eq. 7): the peak F_m of the cos^6 fit of contact n's first pulse
  (:func:`hertzchain.fit_pulse`);
- Q = v_(n+1)/v_n (eq. 8): the local wave speed v_n = phi_n / (T_n - T_(n-1)) from the fitted
  times of flight T_n at successive contacts (:func:`hertzchain.analysis.timing.local_velocity`).

Each ratio is the geometric mean over the taper's beads, the slope of a least-squares line of
the logarithm against n (:func:`hertzchain.analysis.timing.fit_velocity_growth`, as the paper
fits Q in Fig. 6c), with its standard error. The last :data:`WALL_BEADS` beads are left out: there
the pulse coming back from the wall (or the free end) overlaps the incident one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["WALL_BEADS", "STRIKER_BEADS", "RATIOS_NOTE", "TheoryRow", "MeasuredRatios", "uniform_count",
           "bead_peaks", "measure_ratios", "theory_rows"]

#: Beads next to the wall (or the free end) left out of the measured ratios: in the paper's chains
#: bead N - 1 already reads the reflection (its contact force ratio is off by 2 %), bead N - 2 does
#: not (the same bead in a chain with more taper beads beyond it reads the same to 1e-4).
WALL_BEADS = 2
#: In a uniform chain, the beads next to the striker left out (its transient; the paper fits eps
#: from bead 4 on).
STRIKER_BEADS = 3
#: How the simulated ratios of eqs. 6-8 are measured, said under the table.
RATIOS_NOTE = ("Simulated ratios: each on the first pulse at each bead n of the taper (of a uniform chain: from "
               f"bead {STRIKER_BEADS + 1} on), leaving out the last {WALL_BEADS} beads, which read the wall's "
               "reflection; the geometric mean ratio between consecutive beads is the slope of a least-squares "
               "line of its logarithm against n (± its standard error), as the paper fits Q (Fig. 6c).")


@dataclass(frozen=True)
class TheoryRow:
    """One line of the theory table: a quantity, the paper's prediction and the simulation's value.

    Attributes
    ----------
    quantity : str
        What is compared (HTML allowed: sub- and superscripts).
    equation : str
        Where the prediction comes from ("eq. 7").
    theory : str
        The predicted value, formatted.
    simulated : str
        The simulated value, formatted ("" when the simulation has none).
    how : str
        How the simulated value is measured (or why there is none).
    """

    quantity: str
    equation: str
    theory: str
    simulated: str = ""
    how: str = ""


@dataclass(frozen=True)
class MeasuredRatios:
    """Ratios between consecutive beads measured on a run (paper eqs. 6-8; see the module).

    Attributes
    ----------
    beads : numpy.ndarray
        Bead numbers n whose ratios are averaged (the speed uses the time at bead ``beads[0] - 1``
        as well).
    velocity, velocity_err : float
        V_m^(n+1)/V_m^n and its standard error [-] (NaN without recorded bead velocities).
    force, force_err : float
        F_m^(n+1)/F_m^n and its standard error [-].
    speed, speed_err : float
        Q = v_(n+1)/v_n and its standard error [-].
    """

    beads: np.ndarray
    velocity: float
    velocity_err: float
    force: float
    force_err: float
    speed: float
    speed_err: float


def uniform_count(diameters: np.ndarray) -> int:
    """Number n0 of leading beads as large as the first: the uniform part before the taper.

    Parameters
    ----------
    diameters : numpy.ndarray
        phi_1..phi_N [m].

    Returns
    -------
    int
        n0 (at least 1).
    """
    same = np.isclose(diameters, diameters[0], rtol=1e-9, atol=0.0)
    return int(np.argmin(same)) if not same.all() else int(diameters.size)


def bead_peaks(result) -> np.ndarray:
    """Largest force (F_(n-1) + F_n)/2 seen in each bead n = 1..N: what an embedded sensor reads.

    Parameters
    ----------
    result : xarray.Dataset
        A run with every contact force recorded.

    Returns
    -------
    numpy.ndarray
        One peak force [N] per bead.
    """
    f = result.contact_force.values  # (time, contact 0..N or N-1)
    n = result.sizes["bead"]
    right = f[:, 1:n + 1] if f.shape[1] > n else np.concatenate([f[:, 1:], np.zeros((f.shape[0], 1))], axis=1)
    return (0.5 * (f[:, :n] + right)).max(axis=0)


def measure_ratios(result, n0: int) -> MeasuredRatios:
    """The paper's ratios between consecutive beads, measured on the first pulse of one run.

    Parameters
    ----------
    result : xarray.Dataset
        A run with every contact force (and, for eq. 6, the bead velocities) recorded.
    n0 : int
        Beads in the uniform part; the ratios are measured over the taper's beads n0 + 1 ..
        N - WALL_BEADS, or over beads STRIKER_BEADS + 1 .. N - WALL_BEADS of a uniform chain
        (n0 = N).

    Returns
    -------
    MeasuredRatios
        The three ratios with their standard errors.

    Raises
    ------
    PulseNotFound
        Fewer than three beads to measure on, or a contact without a pulse to fit.
    ConfigError
        The fitted times of flight do not increase along the chain.
    """
    from ..analysis import fit_pulse
    from ..analysis.timing import fit_velocity_growth, local_velocity
    from ..errors import PulseNotFound

    n = result.sizes["bead"]
    first = n0 + 1 if n0 < n else STRIKER_BEADS + 1
    beads = np.arange(first, n - WALL_BEADS + 1)
    if beads.size < 3:
        raise PulseNotFound(f"beads {first}..{n - WALL_BEADS} are too few to average over (three at least): "
                            f"the last {WALL_BEADS} read the wall's reflection")
    t = result.time.values
    timed = np.concatenate([[first - 1], beads])  # the time at the bead before the first gives its speed
    forces = result.contact_force.sel(contact=timed).values
    # every contact rests at its static force (0, or the weight it carries) until the pulse arrives
    fits = [fit_pulse(t, forces[:, k], baseline=forces[0, k], compiled=True) for k in range(timed.size)]
    times = np.array([f.time_of_flight for f in fits])
    peaks = np.array([f.peak_force for f in fits[1:]])
    force = fit_velocity_growth(beads, peaks)
    speed = fit_velocity_growth(beads, local_velocity(result.diameter.sel(bead=timed).values, times))
    velocity_ratio = velocity_err = float("nan")
    if "velocity" in result:
        v = result.velocity.sel(body=beads).values
        # bead n moves while contacts n - 1 and n carry its pulse: the first pulse is over at
        # T_n + tau_n, long before the wall's reflection comes back (at least 2 WALL_BEADS transits)
        ends = np.array([f.time_of_flight + f.duration for f in fits[1:]])
        vmax = np.array([v[t <= end, k].max() for k, end in enumerate(ends)])
        velocity = fit_velocity_growth(beads, vmax)
        velocity_ratio, velocity_err = velocity.Q, velocity.Q_err
    return MeasuredRatios(beads=beads, velocity=velocity_ratio, velocity_err=velocity_err, force=force.Q,
                          force_err=force.Q_err, speed=speed.Q, speed_err=speed.Q_err)


def _ratio(value: float, err: float) -> str:
    return f"{value:.4f} ± {err:.4f}" if np.isfinite(value) else ""


def theory_rows(result, eps: float, fit, chain) -> list[TheoryRow]:
    """Paper eqs. 6-8 (ballistic approximation, Sec. III) for the chain of ``result``, beside the
    simulated values.

    Parameters
    ----------
    result : xarray.Dataset
        The run (every contact force, the bead velocities).
    eps : float
        The per-bead factor the theory takes (the calibrated laws' eps; 1 for the others).
    fit : PulseFit or None
        The cos^6 fit of the drawn force's first pulse.
    chain : Chain
        The run's chain (its materials for eq. 7's prediction).

    Returns
    -------
    list of TheoryRow
        Tapering factor, eqs. 6, 7, 8 (theory and measured), eq. 7 carried from the uniform part
        into the taper, and the wall pulse's fit.
    """
    from ..errors import HertzchainError
    from ..theory import ballistic_ratios, predict_chain, tapering_factor

    phi = result.diameter.values
    if not phi.size:  # no chain: the striker hits the wall, one two-body Hertz impact (no ballistic theory)
        peak = float(result.attrs.get("peak_wall_force", np.nan))
        return [TheoryRow("chain", "def.", "none: the striker hits the wall or body (two-body Hertz impact)",
                          f"peak wall force {peak:.4g} N")]
    n0 = uniform_count(phi)
    rows = []
    if n0 < phi.size:
        q, q_sd = tapering_factor(phi, n0)
        rows.append(TheoryRow("tapering factor q (Sec. II), n<sub>0</sub> = %d" % n0, "def.",
                              f"{100 * q:.2f} ± {100 * q_sd:.2f} %"))
    else:
        q = 0.0
        rows.append(TheoryRow("tapering factor q", "def.", "0 (uniform chain)"))
    r = ballistic_ratios(q, eps)
    try:
        m = measure_ratios(result, n0)
    except HertzchainError as exc:
        m, why = None, f"not measured: {exc}"
    if m is not None:
        span = f"n = {m.beads[0]}-{m.beads[-1]}"
        how = {"velocity": f"peak velocity of bead n, {span}",
               "force": f"F<sub>m</sub> of the cos<sup>6</sup> fit at contact n, {span}",
               "speed": f"φ<sub>n</sub>/(T<sub>n</sub> - T<sub>n-1</sub>), T<sub>n</sub> the fitted arrival at "
                        f"contact n, {span}"}
        if not np.isfinite(m.velocity):
            how["velocity"] = "not measured: the bead velocities were not recorded"
        sim = {"velocity": _ratio(m.velocity, m.velocity_err), "force": _ratio(m.force, m.force_err),
               "speed": _ratio(m.speed, m.speed_err)}
    else:
        how = dict.fromkeys(("velocity", "force", "speed"), why)
        sim = dict.fromkeys(("velocity", "force", "speed"), "")
    rows += [TheoryRow("V<sub>m</sub><sup>n+1</sup>/V<sub>m</sub><sup>n</sup> (bead velocity)", "eq. 6",
                       f"{r.velocity:.4f}", sim["velocity"], how["velocity"]),
             TheoryRow("F<sub>m</sub><sup>n+1</sup>/F<sub>m</sub><sup>n</sup> (peak force)", "eq. 7",
                       f"{r.force:.4f}", sim["force"], how["force"]),
             TheoryRow("Q<sup>th</sup> = v<sub>n+1</sub>/v<sub>n</sub> (wave speed)", "eq. 8", f"{r.speed:.4f}",
                       sim["speed"], how["speed"])]
    # Anchor the prediction on the simulated pulse in the uniform part (bead n0), then eq. 7 bead
    # by bead to the middle of the taper: far enough from the wall that its reflection has not
    # come back yet (near the wall the two overlap and a bead reads their sum).
    peaks = bead_peaks(result)
    anchor = max(1, min(n0, phi.size - 1))
    target = anchor + (phi.size - anchor) // 2
    if target > anchor and peaks[anchor - 1] > 0:
        # eq. 7 for one material: the anchor bead's (a chain of mixed materials is beyond the theory)
        pred = predict_chain(phi[anchor - 1:], chain.materials[anchor - 1], float(peaks[anchor - 1]), eps=eps, n0=0)
        rows.append(TheoryRow(f"F<sub>m</sub> in bead {target}, from bead {anchor}", "eq. 7",
                              f"{pred.peak_force[target - anchor]:.4g} N", f"{peaks[target - 1]:.4g} N",
                              "largest (F<sub>n-1</sub> + F<sub>n</sub>)/2 in the bead (an embedded sensor)"))
    if fit is not None:
        rows.append(TheoryRow("wall pulse F<sub>m</sub>, T, τ (cos<sup>6</sup> fit, Sec. III)", "fit", "",
                              f"{fit.peak_force:.4g} N, {fit.time_of_flight * 1e3:.4g} ms, "
                              f"{fit.duration * 1e6:.4g} µs", "cos<sup>6</sup> fit of the drawn force's first pulse"))
    return rows
