"""The exact Jacobian of a fit's simulated signals with respect to its free config fields.

``hertzchain fit`` compares each measured trace with a simulated signal (the wall force, or an
embedded sensor's); the derivative of that whole signal by the free config fields comes from the
tangent model of the engine's steps (:func:`hertzchain.trace_sensitivity`), one run per trace with
one tangent per field, instead of one finite-difference run per trace and field. The runs are
independent: they are spread over threads (the compiled kernels release the GIL).
"""

from __future__ import annotations

import warnings
from concurrent.futures import ThreadPoolExecutor

import numpy as np

__all__ = ["signal_jacobians"]


def signal_jacobians(configs: list, paths: list[str], beads: list[int | None], duration: float,
                     n_threads: int | None = None) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per trace, the simulated signal's times and its derivative by every free field.

    Parameters
    ----------
    configs : list of RunConfig
        One validated config per trace (the trace's own settings and the fields' present values).
    paths : list of str
        The free config fields (dotted paths).
    beads : list of int or None
        Per trace, the bead of its embedded sensor, or None for the wall.
    duration : float
        Simulated time [s].
    n_threads : int, optional
        Threads (default: Numba's thread count).

    Returns
    -------
    list of (numpy.ndarray, numpy.ndarray, numpy.ndarray)
        Per trace: sample times [s] (K,), the signal [N] (K,) and d signal / d field (P, K) [N per
        the field's unit].

    Raises
    ------
    ConfigError
        A field or a model the sensitivity engine does not differentiate (the caller may fall back
        to finite differences).
    """
    from ..errors import ElasticLimitWarning, PulseNotReachedWarning
    from ..gradients import trace_sensitivity

    def one(k: int):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ElasticLimitWarning)
            warnings.simplefilter("ignore", PulseNotReachedWarning)
            s = trace_sensitivity(configs[k], paths, "wall" if beads[k] is None else f"sensor:{beads[k]}", duration)
        return s.time, s.value, s.jacobian

    if n_threads is None:
        import numba

        n_threads = numba.config.NUMBA_NUM_THREADS  # type: ignore[attr-defined]  # numba sets it at import
    first = one(0)  # the first run compiles or loads the kernels, once
    if len(configs) == 1 or n_threads <= 1:
        return [first] + [one(k) for k in range(1, len(configs))]
    with ThreadPoolExecutor(max_workers=min(n_threads, len(configs))) as pool:
        return [first] + list(pool.map(one, range(1, len(configs))))


def config_columns(prob, cfg: np.ndarray, gains: np.ndarray, taus: np.ndarray, parts: list, edges: np.ndarray,
                   J: np.ndarray) -> None:
    """Fill the free config fields' columns of a fit's Jacobian (``lab.fit._Problem.jacobian``).

    Exact (tangent model, :func:`signal_jacobians`) where the sensitivity engine differentiates
    every free field and the model; otherwise (a field such as ``run.dt``, a law given by ``eps``)
    one forward difference per field, all members in one batched engine call, and
    ``prob.jacobian_kind`` says why. Column j of trace k's rows is -g_k dF_k/dx_j (t + tau_k) / sigma_k.

    Parameters
    ----------
    prob : lab.fit._Problem
        The least-squares problem.
    cfg, gains, taus : numpy.ndarray
        The free fields' values, each trace's gain and time offset [s].
    parts : list
        Per trace (sim time, sim signal, signal at the scope times, model) at ``cfg``.
    edges : numpy.ndarray
        First row of each trace in J, and the end.
    J : numpy.ndarray
        The Jacobian, written in place.
    """
    from ..errors import ConfigError

    K, P = len(prob.traces), len(prob.cfg_paths)
    if prob.jacobian_kind == "exact":
        cached = getattr(prob, "_tangents", None)
        if cached is not None and cached[0] == cfg.tobytes():
            cols = cached[1]  # the residuals at these values were computed by the tangent model
        else:
            end = max(float(t[-1]) + float(tau) for t, tau in zip(prob.t, taus))
            duration = max(end * 1.02 + 2 * prob.sample_interval, 4 * prob.sample_interval)
            try:
                cols = signal_jacobians(prob._configs(cfg), prob.cfg_paths, prob.beads, duration, prob.n_threads)
            except ConfigError as exc:
                prob.jacobian_kind = f"finite differences ({exc.field}: {exc.message})"
                cols = None
            else:
                prob.n_tangent_runs += K
        if cols is not None:
            for k, (ts, _, jac) in enumerate(cols):
                for j in range(P):
                    J[edges[k]:edges[k + 1], j] = -gains[k] * np.interp(prob.t[k] + taus[k], ts, jac[j]) / prob.sigma[k]
            return
    steps = prob.rel_step * np.maximum(np.abs(cfg), 1e-300)
    sets = []
    for j in range(P):
        v = cfg.copy()
        v[j] += steps[j]
        sets.append(v)
    sims = prob.simulate(sets, taus)
    for j in range(P):
        for k in range(K):
            ts, f = sims[j][k]
            dm = gains[k] * (np.interp(prob.t[k] + taus[k], ts, f) - parts[k][2]) / steps[j]
            J[edges[k]:edges[k + 1], j] = -dm / prob.sigma[k]


def signals(prob, cfg: np.ndarray, taus: np.ndarray, duration: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """Every trace's simulated (time, signal) at the free fields' values ``cfg``: one evaluation.

    With an exact Jacobian, by the tangent model (the engine's very steps, so the same numbers as
    the batched engine's), whose derivatives are kept for the Jacobian at the same values (least
    squares asks for it at nearly every point it evaluates); otherwise one batched engine call.

    Parameters
    ----------
    prob : lab.fit._Problem
        The least-squares problem.
    cfg, taus : numpy.ndarray
        The free fields' values and each trace's time offset [s].
    duration : float
        Simulated time [s].

    Returns
    -------
    list of (numpy.ndarray, numpy.ndarray)
        Per trace: sample times [s] and the signal [N].
    """
    from ..errors import ConfigError

    if prob.jacobian_kind == "exact" and prob.cfg_paths:
        try:
            cols = signal_jacobians(prob._configs(cfg), prob.cfg_paths, prob.beads, duration, prob.n_threads)
        except ConfigError as exc:
            prob.jacobian_kind = f"finite differences ({exc.field}: {exc.message})"
        else:
            prob.n_evaluations += 1
            prob.n_tangent_runs += len(cols)
            prob._tangents = (cfg.tobytes(), cols)
            return [(ts, np.nan_to_num(value)) for ts, value, _ in cols]
    return prob.simulate([cfg], taus, duration=duration)[0]
