"""Run a model: choose the integrator, record the probes, check the elastic limit, build the result."""

from __future__ import annotations

import json
import math
import warnings
from typing import Callable, Literal

import xarray as xr

from .checks import check_after_run, check_before_run
from .errors import ConfigError, ElasticLimitWarning
from .integrate.reference import run_reference
from .integrate.verlet import run_verlet
from .model import Model
from .probes import Probes
from .result import build_dataset

__all__ = ["simulate", "warn_elastic_limit"]


def simulate(model: Model, duration: float, probes: Probes | None = None, *,
             integrator: Literal["verlet", "dop853", "rk45"] = "verlet", dt: float | None = None,
             rtol: float = 1e-10, progress: Callable[[int, int], None] | None = None,
             config: dict | None = None) -> xr.Dataset:
    """Simulate ``model`` for ``duration`` [s] and return the result Dataset.

    Parameters
    ----------
    model
        Chain, striker, wall and contact law.
    duration
        Simulated time [s] after impact.
    probes
        What to record (default: every contact force and the energies every 100 ns).
    integrator
        ``"verlet"`` (compiled, fixed step; default) or the scipy reference ``"dop853"``
        (``"rk45"`` also accepted), adaptive with relative tolerance ``rtol``.
    dt
        Verlet time step [s]; automatic when None (see :func:`hertzchain.integrate.verlet.auto_time_step`).
    progress
        Called as ``progress(done, total)`` between chunks of a Verlet run.
    rtol
        Relative tolerance of the scipy reference integrators (unused by ``"verlet"``).
    config
        The input it came from, stored in the result's attributes.

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
    probes = probes or Probes()
    if not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration > 0):
        raise ConfigError("run.duration", f"must be a positive time in s, got {duration!r}")
    if probes.sample_interval > duration:
        raise ConfigError("run.sample_interval", f"({probes.sample_interval:g} s) is longer than run.duration ({duration:g} s)")
    system = model.system()
    probes.validate(model.chain.n_beads, model.wall.present)
    if integrator not in ("verlet", "dop853", "rk45"):
        raise ConfigError("run.integrator", f"must be 'verlet', 'dop853' or 'rk45', got {integrator!r}")
    check_before_run(model, system, duration, probes, dt=dt, integrator=integrator)  # before any allocation
    rec = probes.recorded_contacts(model.chain.n_beads, model.wall.present)
    if integrator == "verlet":
        raw = run_verlet(system, duration, probes.sample_interval, dt=dt, record_velocities=probes.velocities,
                         contacts=rec, progress=progress)
    else:
        raw = run_reference(system, duration, probes.sample_interval, method=integrator.upper(), rtol=rtol,
                            record_velocities=probes.velocities)
    ds = build_dataset(raw, model, probes, duration=duration, config=config, system=system)
    check_after_run(ds, model, system, dt=dt, integrator=integrator, rtol=rtol, stacklevel=3)
    warn_elastic_limit(ds, stacklevel=3)
    return ds


def warn_elastic_limit(ds: xr.Dataset, where: str = "", stacklevel: int = 2) -> None:
    """Warn (ElasticLimitWarning) when the result records forces past the elastic limit."""
    if not ds.attrs.get("elastic_limit_exceeded", 1):
        return
    over = json.loads(ds.attrs["elastic_limit_contacts"])
    if over:
        ratio = ds.attrs.get("elastic_limit_ratio") or float((ds.max_contact_force / ds.yield_force).max())
        warnings.warn(ElasticLimitWarning(
            f"{where}contact forces pass the elastic limit of the paper (Sec. II) at contacts {over} "
            f"(up to {ratio:.2f} x F_Y); beads would yield plastically: lower the striker velocity"),
            stacklevel=stacklevel + 1)
