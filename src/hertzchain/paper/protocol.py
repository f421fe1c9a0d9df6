"""The runs of the paper's measurement protocol, and their analysis (data only, no plotting).

Protocol (paper Sec. II; docs/guide/reproduction.rst): the tapered-chain pulses are the wall
force at the end of the chain truncated after bead n, n = n0..N, one run per truncation; the pulse
in the uniform part comes from sensors embedded in beads 1..n0 (of the full chain's run, which is
identical there until reflections come back). Dissipation, when on, is calibrated to the paper's
eps = 0.985 in the uniform part.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import xarray as xr

from .. import analysis, theory
from ..chain import Chain, paper_chain
from ..contact import Elastic
from ..errors import ElasticLimitWarning, PulseNotFound
from ..model import Model, Striker, Wall
from ..probes import Probes
from ..runs.simulation import simulate
from .values import PAPER

__all__ = ["Settings", "ChainStudy", "run_chain_study", "run_misalignment", "run_substitutions",
           "run_wall_chain_ratio", "run_speed_check", "fit_or_none", "contact_law",
           "study_from_datasets", "wall_chain_ratio_from_dataset"]

N0 = PAPER["n0"]


@dataclass(frozen=True)
class Settings:
    """Parameters of a reproduction (SI units).

    The striker speed is not given in the paper; 0.2 m/s keeps every contact of both chains far
    inside its elastic limit (the largest force is below 40 % of the contact's F_Y), and the
    normalised results do not depend on it (checked by :func:`run_speed_check`).

    Dissipation: the size-scaled dashpot (:class:`~hertzchain.contact.ScaledDashpot`) calibrated to
    the paper's eps, the one calibrated law under which the chain's eps and a steel-like bounce of
    the striker (two-body restitution 0.96 at 0.2 m/s) hold together; the Kuwabara-Kono laws give
    the striker 0.68 (constant A) and 0.86 (size-scaled A), see :mod:`hertzchain.paper.claims`.
    """

    striker_velocity: float = 0.2
    striker_diameter: float = PAPER["striker_diameter"]
    eps: float = PAPER["eps"]
    elastic: bool = False
    law: str = "dashpot_scaled"
    #: Long enough that the tails of the longest chains are recorded (Q_F + Q_T = const within
    #: ~2 %, as the paper checked with longer records); the pulses themselves arrive before 2.5 ms.
    duration: float = 8e-3
    sample_interval: float = 1e-7
    material: str = "AISI52100"

    def striker(self, velocity: float | None = None) -> Striker:
        return Striker(self.striker_diameter, velocity or self.striker_velocity, self.material)

    def describe(self) -> dict:
        return {"striker_velocity": self.striker_velocity, "striker_diameter": self.striker_diameter,
                "eps_target": None if self.elastic else self.eps, "law": "elastic" if self.elastic else self.law,
                "duration": self.duration, "sample_interval": self.sample_interval, "material": self.material,
                "n0": N0}


def contact_law(settings: Settings, chain: Chain, velocity: float | None = None):
    """The run's contact law: elastic, or calibrated to ``settings.eps`` for these beads and striker."""
    if settings.elastic:
        return Elastic()
    from ..dissipation import calibrate_law

    return calibrate_law(settings.law, settings.eps, chain=chain, striker=settings.striker(velocity))


def fit_or_none(time: np.ndarray, force: np.ndarray):
    """fit_pulse, or None when the record holds no pulse."""
    try:
        return analysis.fit_pulse(time, force)
    except PulseNotFound:
        return None


def _simulate(model: Model, settings: Settings, probes: Probes) -> xr.Dataset:
    with warnings.catch_warnings():
        # The reproduction records the elastic-limit check in each dataset; the report reads it.
        warnings.simplefilter("ignore", ElasticLimitWarning)
        return simulate(model, settings.duration, probes)


@dataclass
class ChainStudy:
    """Everything measured on one tapered chain (Figs. 1-2, 4-6).

    Arrays are over ``truncations`` (beads n0..N) unless said otherwise.
    """

    name: str
    chain: Chain
    q: float
    q_std: float
    truncations: np.ndarray
    wall: dict[int, xr.Dataset]                 # truncation -> dataset (wall force [+ sensors])
    wall_fits: dict[int, object]                # truncation -> PulseFit
    sensor_beads: np.ndarray                    # 1..n0
    sensor_fits: dict[int, object]              # bead -> PulseFit of the embedded sensor
    eps_measured: float = math.nan
    eps_measured_err: float = math.nan
    v1: float = math.nan
    T0: float = math.nan
    Q_fit: float = math.nan
    Q_fit_err: float = math.nan
    Q_theory: float = math.nan
    law: object = None
    extras: dict = field(default_factory=dict)

    # convenience arrays ---------------------------------------------------------------
    def series(self, attr: str) -> np.ndarray:
        """A fit attribute (peak_force, duration, time_of_flight, ...) over the truncations."""
        return np.array([getattr(self.wall_fits[n], attr) if self.wall_fits.get(n) else np.nan
                         for n in self.truncations])

    def sensor_series(self, attr: str) -> np.ndarray:
        return np.array([getattr(self.sensor_fits[n], attr) if self.sensor_fits.get(n) else np.nan
                         for n in self.sensor_beads])


def run_chain_study(name: str, settings: Settings, progress: Callable[[str], None] | None = None) -> ChainStudy:
    """Run the paper's protocol on ``chain1`` or ``chain2`` and analyse it (Sec. III)."""
    full = paper_chain(name, settings.material)
    law = contact_law(settings, full)
    truncations = np.arange(N0, full.n_beads + 1)
    sensors = tuple(range(1, N0 + 1))
    wall: dict[int, xr.Dataset] = {}
    for n in truncations:
        chain = full.truncated(int(n))
        model = Model(chain, settings.striker(), Wall("flat"), law)
        # Only the wall contact is stored (the wall sensor); the full chain's run also carries the
        # embedded sensors of the uniform part.
        probes = Probes(settings.sample_interval, sensors=sensors if n == full.n_beads else (), contacts=(int(n),))
        wall[int(n)] = _simulate(model, settings, probes)
        if progress:
            progress(f"{name}: truncated after bead {n}")
    return study_from_datasets(name, wall, settings, law)


def study_from_datasets(name: str, wall: dict[int, xr.Dataset], settings: Settings, law=None) -> ChainStudy:
    """Analyse the wall records of the truncated chains (the full chain's also carries the
    embedded sensors of the uniform part): pulse fits, eps, T fit, local velocities, Q fit."""
    full = paper_chain(name, settings.material)
    q, q_std = theory.tapering_factor(full.diameters, N0)
    truncations = np.array(sorted(wall))
    fits = {n: fit_or_none(ds.time.values, ds.wall_force.values) for n, ds in wall.items()}
    full_ds = wall[full.n_beads]
    sensors = tuple(int(b) for b in full_ds.sensor.values)
    sensor_fits = {b: fit_or_none(full_ds.time.values, full_ds.sensor_force.sel(sensor=b).values) for b in sensors}
    study = ChainStudy(name=name, chain=full, q=q, q_std=q_std, truncations=truncations, wall=dict(wall),
                       wall_fits=fits, sensor_beads=np.array(sensors), sensor_fits=sensor_fits, law=law)
    _analyse_timing(study, settings)
    return study


def _analyse_timing(study: ChainStudy, settings: Settings) -> None:
    """eps from the uniform part, T fit (v1, T0), local velocities and the Q fit (Sec. III)."""
    phi0 = float(study.chain.diameters[0])
    # eps = (F_{n+1}/F_n)^(5/6) fitted over the embedded sensors, away from the striker transient.
    beads = study.sensor_beads
    peaks = study.sensor_series("peak_force")
    use = (beads >= 4) & np.isfinite(peaks)
    rest = analysis.fit_restitution(beads[use], peaks[use])
    study.eps_measured, study.eps_measured_err = float(rest.eps), float(rest.eps_err)
    eps_for_theory = 1.0 if settings.elastic else settings.eps
    times = study.sensor_series("time_of_flight")
    use_t = (beads >= 4) & np.isfinite(times)
    tof = analysis.fit_uniform_time_of_flight(beads[use_t], times[use_t], phi0, eps_for_theory)
    study.v1, study.T0 = float(tof.v1), float(tof.T0)
    # Local velocities in the tapered part, from consecutive truncations.
    T = study.series("time_of_flight")
    phi = study.chain.diameters[study.truncations - 1]
    v_local = analysis.local_velocity(phi, T)            # beads n0+1..N
    beads_v = study.truncations[1:]
    growth = analysis.fit_velocity_growth(beads_v, v_local, n_ref=N0 + 1)
    study.Q_fit, study.Q_fit_err = float(growth.Q), float(growth.Q_err)
    study.Q_theory = float(theory.ballistic_ratios(study.q, eps_for_theory).speed)
    study.extras.update(v_local=v_local, v_local_beads=beads_v, v_ref=float(growth.v_ref))


#: Fig. 3a-b: the beads of chain 2 offset, and their offsets as fractions of the bead's diameter.
MISALIGNED_BEADS = (22, 28)
MISALIGNMENT_FRACTIONS = (0.0, 0.05, 0.10)


def run_misalignment(settings: Settings, beads=MISALIGNED_BEADS, fractions=MISALIGNMENT_FRACTIONS) -> dict:
    """Fig. 3a-b: chain 2 with bead ``b`` offset perpendicular by e = fraction * phi_b."""
    full = paper_chain("chain2", settings.material)
    law = contact_law(settings, full)
    out: dict = {}
    for b in beads:
        for frac in fractions:
            chain = full.with_offsets({b: frac * full.diameters[b - 1]})
            model = Model(chain, settings.striker(), Wall("flat"), law)
            ds = _simulate(model, settings, Probes(settings.sample_interval, contacts=(full.n_beads,)))
            out[(b, frac)] = ds
    return out


#: Fig. 3c substitutions in chain 1 truncated after bead 24 (see docs/guide/reproduction.rst (section "Fig. 3c")):
#: dq/q = +1: bead 18 replaced by one equal to its smaller neighbour (phi_18 = phi_19 = 22 mm);
#: dq/q = -1: bead 19 replaced by one equal to its bigger neighbour (phi_19 = phi_18 = 23 mm).
SUBSTITUTIONS = {"reference": None, "dq/q = +1": (18, 22.0e-3), "dq/q = -1": (19, 23.0e-3)}


def run_substitutions(settings: Settings) -> dict:
    """Fig. 3c: partial chain 1 (beads 1-24) and the two single-bead substitutions."""
    base = paper_chain("chain1", settings.material).truncated(24)
    law = contact_law(settings, base)
    out = {}
    for label, sub in SUBSTITUTIONS.items():
        chain = base if sub is None else base.substitute(sub[0], diameter=sub[1])
        model = Model(chain, settings.striker(), Wall("flat"), law)
        out[label] = _simulate(model, settings, Probes(settings.sample_interval, contacts=(24,)))
    return out


def run_wall_chain_ratio(settings: Settings) -> dict:
    """F_m and tau at the wall against those of an inter-bead contact in a uniform elastic chain.

    The paper quotes F_wall ~ 1.94 F_chain and tau_wall ~ 1.09 tau_chain from elastic simulations
    (Job et al. 2005), so this uses the elastic law on the 16-bead uniform part with its wall,
    comparing the wall pulse with the pulse at contact 12 (far from the striker and the wall).
    """
    chain = Chain.uniform(N0, PAPER["bead_diameter"], settings.material)
    model = Model(chain, settings.striker(), Wall("flat"), Elastic())
    short = Settings(**{**settings.__dict__, "duration": 2.5e-3})  # the pulse reaches the wall by ~1.3 ms
    return wall_chain_ratio_from_dataset(_simulate(model, short, Probes(settings.sample_interval / 4,
                                                                        contacts=(12, N0))))


def wall_chain_ratio_from_dataset(ds: xr.Dataset) -> dict:
    """Fit the wall pulse and the contact-12 pulse of the uniform elastic run; their ratios."""
    t = ds.time.values
    fw = analysis.fit_pulse(t, ds.wall_force.values)
    fc = analysis.fit_pulse(t, ds.contact_force.sel(contact=12).values)
    return {"force_ratio": fw.peak_force / fc.peak_force, "duration_ratio": fw.duration / fc.duration,
            "wall_fit": fw, "chain_fit": fc, "dataset": ds}


def run_speed_check(settings: Settings, factor: float = 2.0) -> dict:
    """Normalised chain-1 results at two striker speeds (v and factor * v).

    Hertz chains have no intrinsic force scale: F_m scales as v^(6/5) and times as v^(-1/5), so
    the normalised peak-force profile F_m,n / F_m,n0 and the pulse shape F/F_m against (t - T)/tau
    must not depend on the striker speed. With a dissipative law calibrated at each speed this
    holds too (the law is recalibrated, as an experimenter would measure eps again).
    """
    rows = {}
    for v in (settings.striker_velocity, factor * settings.striker_velocity):
        full = paper_chain("chain1", settings.material)
        law = Elastic() if settings.elastic else contact_law(settings, full, velocity=v)
        peaks, durations = [], []
        for n in (N0, 20, 24, 28, 30):
            model = Model(full.truncated(n), settings.striker(v), Wall("flat"), law)
            ds = _simulate(model, settings, Probes(settings.sample_interval, contacts=(n,)))
            fit = analysis.fit_pulse(ds.time.values, ds.wall_force.values)
            peaks.append(fit.peak_force)
            durations.append(fit.duration)
        peaks, durations = np.array(peaks), np.array(durations)
        rows[v] = {"beads": [N0, 20, 24, 28, 30], "peak_force": peaks, "duration": durations,
                   "peak_norm": peaks / peaks[0], "duration_norm": durations / durations[0]}
    v1, v2 = list(rows)
    dev = float(np.max(np.abs(rows[v2]["peak_norm"] / rows[v1]["peak_norm"] - 1)))
    dev_tau = float(np.max(np.abs(rows[v2]["duration_norm"] / rows[v1]["duration_norm"] - 1)))
    return {"velocities": [v1, v2], "rows": rows, "max_peak_norm_deviation": dev,
            "max_duration_norm_deviation": dev_tau}
