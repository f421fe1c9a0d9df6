"""One view of the explorer computed: the run of its config, the wall pulse and its cos^6 fit,
the space-time map, the energies and the ballistic theory beside them (no web library here, so
the numbers are testable on their own).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from .settings import ExplorerSettings

__all__ = ["MAP_ROWS", "TheoryRow", "ExplorerView", "compute_view", "uniform_count"]

#: Rows of the space-time map sent to the browser (each keeps its time bin's largest force).
MAP_ROWS = 600


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
    """

    quantity: str
    equation: str
    theory: str
    simulated: str = ""


@dataclass
class ExplorerView:
    """Everything the explorer draws for one :class:`ExplorerSettings` (SI units).

    Attributes
    ----------
    settings : ExplorerSettings
        The view's controls.
    config : dict
        The run config simulated (what "save as config" writes).
    result : xarray.Dataset
        The run (:func:`hertzchain.simulate` through the config).
    signal : str
        The force drawn: ``"wall_force"``, or the last contact's force for a free end.
    time, force : numpy.ndarray
        That force [N] against time [s], every recorded sample.
    fit : PulseFit or None
        The paper's cos^6 fit of its first pulse (Sec. III), None when no pulse was found.
    fit_time, fit_force : numpy.ndarray
        The fitted profile F_m cos^6((t - T)/tau) + baseline over |t - T| < pi tau / 2.
    map_x, map_time, map_force : numpy.ndarray
        The space-time map: contacts, row times [s] and (row, contact) forces [N].
    map_vmax : float
        Top of its colour scale [N] (:func:`hertzchain.viz.spacetime.robust_vmax`).
    energy_time : numpy.ndarray
        Times [s] of ``energies``.
    energies : list of (str, numpy.ndarray)
        Kinetic, potential, dissipated and total energy [J].
    theory : list of TheoryRow
        Paper eqs. 6-8 for this chain beside the simulation.
    seconds : float
        Wall-clock time of the computation [s].
    """

    settings: ExplorerSettings
    config: dict
    result: object
    signal: str
    time: np.ndarray
    force: np.ndarray
    fit: object | None
    fit_time: np.ndarray
    fit_force: np.ndarray
    map_x: np.ndarray
    map_time: np.ndarray
    map_force: np.ndarray
    map_vmax: float
    energy_time: np.ndarray
    energies: list = field(default_factory=list)
    theory: list = field(default_factory=list)
    seconds: float = 0.0


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


def _bead_peaks(result) -> np.ndarray:
    """Largest force (F_(n-1) + F_n)/2 seen in each bead n = 1..N: what an embedded sensor reads."""
    f = result.contact_force.values  # (time, contact 0..N or N-1)
    n = result.sizes["bead"]
    right = f[:, 1:n + 1] if f.shape[1] > n else np.concatenate([f[:, 1:], np.zeros((f.shape[0], 1))], axis=1)
    return (0.5 * (f[:, :n] + right)).max(axis=0)


def _theory(result, settings: ExplorerSettings, fit, chain) -> list[TheoryRow]:
    """Paper eqs. 6-8 (ballistic approximation, Sec. III) for the chain of ``result``."""
    from ..theory import ballistic_ratios, predict_chain, tapering_factor

    phi = result.diameter.values
    n0 = uniform_count(phi)
    from .settings import EPS_LAWS

    # the ballistic theory knows the per-bead factor eps; an elastic or plastic contact has none
    eps = float(settings.eps) if settings.law in EPS_LAWS else 1.0
    rows = []
    if n0 < phi.size:
        q, q_sd = tapering_factor(phi, n0)
        rows.append(TheoryRow("tapering factor q (Sec. II), n<sub>0</sub> = %d" % n0, "def.",
                              f"{100 * q:.2f} ± {100 * q_sd:.2f} %"))
    else:
        q = 0.0
        rows.append(TheoryRow("tapering factor q", "def.", "0 (uniform chain)"))
    r = ballistic_ratios(q, eps)
    rows += [TheoryRow("V<sub>m</sub><sup>n+1</sup>/V<sub>m</sub><sup>n</sup> (bead velocity)", "eq. 6", f"{r.velocity:.4f}"),
             TheoryRow("F<sub>m</sub><sup>n+1</sup>/F<sub>m</sub><sup>n</sup> (peak force)", "eq. 7", f"{r.force:.4f}"),
             TheoryRow("Q<sup>th</sup> = v<sub>n+1</sub>/v<sub>n</sub> (wave speed)", "eq. 8", f"{r.speed:.4f}")]
    # Anchor the prediction on the simulated pulse in the uniform part (bead n0), then eq. 7 bead
    # by bead to the middle of the taper: far enough from the wall that its reflection has not
    # come back yet (near the wall the two overlap and a bead reads their sum).
    peaks = _bead_peaks(result)
    anchor = max(1, min(n0, phi.size - 1))
    target = anchor + (phi.size - anchor) // 2
    if target > anchor and peaks[anchor - 1] > 0:
        # eq. 7 for one material: the anchor bead's (a chain of mixed materials is beyond the theory)
        pred = predict_chain(phi[anchor - 1:], chain.materials[anchor - 1], float(peaks[anchor - 1]), eps=eps, n0=0)
        rows.append(TheoryRow(f"F<sub>m</sub> in bead {target}, from bead {anchor}", "eq. 7",
                              f"{pred.peak_force[target - anchor]:.4g} N", f"{peaks[target - 1]:.4g} N"))
    if fit is not None:
        rows.append(TheoryRow("wall pulse F<sub>m</sub>, T, τ (cos<sup>6</sup> fit, Sec. III)", "fit", "",
                              f"{fit.peak_force:.4g} N, {fit.time_of_flight * 1e3:.4g} ms, "
                              f"{fit.duration * 1e6:.4g} µs"))
    return rows


def compute_view(settings: ExplorerSettings) -> ExplorerView:
    """Simulate the view's config and prepare what the explorer draws.

    Parameters
    ----------
    settings : ExplorerSettings
        The controls.

    Returns
    -------
    ExplorerView
        The run, the drawn force and its fit, the space-time map, the energies and the theory;
        a :class:`~hertzchain.errors.ConfigError` naming the config field when a value is refused.
    """
    import warnings

    from ..analysis import fit_pulse
    from ..config import build_model, build_probes, parse_config, simulate_config
    from ..errors import PulseNotFound
    from ..viz.energy import energy_curves
    from ..viz.spacetime import robust_vmax, spacetime_grid

    start = time.perf_counter()
    config = settings.config()
    cfg = parse_config(config)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the explorer shows the numbers; the elastic-limit note is in its text
        model = build_model(cfg)
        result = simulate_config(cfg, model, build_probes(cfg))
    if "wall_force" in result:
        signal, force = "wall_force", result.wall_force.values
    else:
        signal, force = f"contact {int(result.contact.values[-1])}", result.contact_force.values[:, -1]
    t = result.time.values
    try:
        fit = fit_pulse(t, force)
        half = 0.5 * math.pi * fit.duration
        fit_t = np.linspace(fit.time_of_flight - half, fit.time_of_flight + half, 200)
        fit_f = fit.baseline + fit.peak_force * np.cos((fit_t - fit.time_of_flight) / fit.duration) ** 6
    except PulseNotFound:
        fit, fit_t, fit_f = None, np.zeros(0), np.zeros(0)
    grid = spacetime_grid(result, max_rows=MAP_ROWS)
    energy_t, energies = energy_curves(result)
    return ExplorerView(settings=settings, config=config, result=result, signal=signal, time=t, force=force,
                        fit=fit, fit_time=fit_t, fit_force=fit_f, map_x=grid.x, map_time=grid.time,
                        map_force=grid.force, map_vmax=robust_vmax(grid), energy_time=energy_t, energies=energies,
                        theory=_theory(result, settings, fit, model.chain), seconds=time.perf_counter() - start)
