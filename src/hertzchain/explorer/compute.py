"""One view of the explorer computed: the run of its config, the wall pulse and its cos^6 fit,
the space-time map, the energies and the ballistic theory beside them (no web library here, so
the numbers are testable on their own).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .ballistic import TheoryRow, theory_rows, uniform_count
from .settings import EPS_LAWS, ExplorerSettings

if TYPE_CHECKING:
    import xarray as xr

    from ..analysis import PulseFit

__all__ = ["MAP_ROWS", "TheoryRow", "ExplorerView", "compute_view", "uniform_count"]

#: Rows of the space-time map sent to the browser (each keeps its time bin's largest force).
MAP_ROWS = 600


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
    body_force : numpy.ndarray or None
        With a protected body, the force its mount passes to the ground [N] at the same times
        (``body_force``: k x + c dx/dt); None otherwise.
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
        Kinetic, potential, dissipated, plastic (the elastoplastic law) and total energy [J].
    theory : list of TheoryRow
        Paper eqs. 6-8 for this chain beside the simulation
        (:func:`~hertzchain.explorer.ballistic.theory_rows`).
    seconds : float
        Wall-clock time of the computation [s].
    """

    settings: ExplorerSettings
    config: dict
    result: xr.Dataset
    signal: str
    time: np.ndarray
    force: np.ndarray
    fit: PulseFit | None
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
    body_force: np.ndarray | None = None


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
        fit = fit_pulse(t, force, compiled=True)  # the server fits at every change
        half = 0.5 * math.pi * fit.duration
        fit_t = np.linspace(fit.time_of_flight - half, fit.time_of_flight + half, 200)
        fit_f = fit.baseline + fit.peak_force * np.cos((fit_t - fit.time_of_flight) / fit.duration) ** 6
    except PulseNotFound:
        fit, fit_t, fit_f = None, np.zeros(0), np.zeros(0)
    grid = spacetime_grid(result, max_rows=MAP_ROWS)
    energy_t, energies = energy_curves(result)
    # the ballistic theory knows the per-bead factor eps; an elastic or plastic contact has none
    eps = float(settings.eps) if settings.law in EPS_LAWS else 1.0
    theory = theory_rows(result, eps, fit, model.chain)
    return ExplorerView(settings=settings, config=config, result=result, signal=signal, time=t, force=force,
                        fit=fit, fit_time=fit_t, fit_force=fit_f, map_x=grid.x, map_time=grid.time,
                        map_force=grid.force, map_vmax=robust_vmax(grid), energy_time=energy_t, energies=energies,
                        theory=theory, seconds=time.perf_counter() - start,
                        body_force=result.body_force.values if "body_force" in result else None)
