"""What every rkn4 driver does around its compiled run (:mod:`rkn`, :mod:`rkn_damped`,
:mod:`rkn_laws`): the samples advanced a chunk of calls at a time, with progress and a clean error
when the state diverges, and the records gathered into a :class:`~.verlet.RawRun`.

The compiled runs return between chunks, so a long run reports progress and can be interrupted;
their accumulators ``acc`` share one layout (``rkn_kernels.A_*``: the step count and the smallest
and largest steps).
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from ...errors import SimulationDiverged
from .rkn_kernels import A_HMAX, A_HMIN, A_STEPS
from .verlet import RawRun

__all__ = ["advance_in_chunks", "rkn_raw_run"]


def advance_in_chunks(advance: Callable[[int, int], int], n_samples: int, per_call: int, sample_interval: float,
                      fixed_step: bool, progress: Callable[[int, int], None] | None) -> None:
    """Samples 1 .. n_samples - 1 through ``advance(k, k_stop)`` (the compiled run from sample k to
    k_stop, returning its status: 0, or non-zero when the state became non-finite), ``per_call``
    samples a call; ``progress(done, total)`` after each.

    Raises
    ------
    SimulationDiverged
        When a call returns a non-zero status: with ``fixed_step`` (a given ``run.dt``) the advice
        is a smaller step, else to check the inputs.
    """
    if progress is not None:
        progress(0, n_samples - 1)
    k = 1
    while k < n_samples:
        k_stop = min(n_samples, k + per_call)
        if advance(k, k_stop) != 0:
            raise SimulationDiverged(f"the integration diverged (non-finite state) before t = "
                                     f"{k_stop * sample_interval:.4g} s with integrator 'rkn4'; "
                                     + ("use a smaller run.dt" if fixed_step else
                                        "check the inputs (masses, velocities) and report the case"))
        k = k_stop
        if progress is not None:
            progress(k - 1, n_samples - 1)


def rkn_raw_run(probes, acc: np.ndarray, sample_interval: float, fixed_step: bool, dissipated: np.ndarray,
                **extra) -> RawRun:
    """The run's records from its probe buffers (``rkn_kernels.ProbeBuffers``) and accumulators.

    ``dissipated`` is the dissipated energy per sample [J] (zeros for a lossless law); ``extra``
    the law's own records (the elastic-plastic law's plastic work and overlaps).
    """
    n_samples = probes.out_ke.shape[0]
    return RawRun(time=np.arange(n_samples) * sample_interval, contact_force=probes.out_f,
                  kinetic_energy=probes.out_ke, potential_energy=probes.out_pe, dissipated_energy=dissipated,
                  velocity=probes.out_v if probes.record_v else None, max_force=probes.fmax,
                  peak_wall_force=float(probes.peak[0]), peak_wall_time=float(probes.peak[1]),
                  dt=float(acc[A_HMIN]), integrator="rkn4", n_steps=int(acc[A_STEPS]), contacts=probes.rec,
                  dt_max=float(acc[A_HMAX]), adaptive=not fixed_step,
                  displacement=probes.out_u if probes.record_u else None, **extra)
