"""Calibrate a run config on measured traces by least squares (``hertzchain fit``).

The model is seen through the instrument: trace k, recorded at the scope's times t_i (relative
to its trigger), is compared with

    m_k(t_i) = g * F_k(t_i + tau_k) + b_k

where F_k is the simulated force of the signal the trace measures (the wall force, contact N,
or the embedded sensor of bead n, (F_{n-1} + F_n)/2), linearly interpolated on the
simulation's samples, g the sensor gain (one per sensor kind: wall, embedded), tau_k the time
of the trace's trigger on the simulation clock and b_k a residual baseline [N]. Any numeric
config field may be free (``striker.velocity``, ``contact.A``, ``materials.X.young``...), with
the measurement's ``gain``, ``time_offset`` and ``baseline``.

Residuals are weighted by each trace's noise (robust sample-to-sample estimate,
:func:`hertzchain.analysis.estimate_noise`), and minimised with
:func:`scipy.optimize.least_squares` (trust region reflective, positive bounds on the config
fields and the gain), after a first fit of gain, time offsets and baselines alone on the
starting model (time offsets first placed by cross-correlation). The Jacobian is exact: its
config-field columns are the derivatives of the simulated signals by the tangent model of the
engine's steps (:mod:`hertzchain.lab.jacobian`, one run per trace), falling back to forward
differences (one batched member per trace and field) for a field the sensitivity engine does
not differentiate; the derivatives in gain, time offset and baseline are the simulated signal,
its time derivative and one. The covariance is ``s^2 (J^T J)^-1`` with ``s^2``
the residual variance per degree of freedom, taken trace by trace (each trace's rows of J are
scaled by its own), so the standard errors hold when the noise estimates are off.
"""

from __future__ import annotations

import math
import time as _time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ..errors import ConfigError
from .fit_checks import check_records, fit_doubts, parameter_unit
from .quantised import expected, refit_noise, robust_covariance

__all__ = ["Trace", "FitResult", "fit_traces", "MEASUREMENT_PARAMETERS"]

#: Free parameters that belong to the measurement, not to the config.
MEASUREMENT_PARAMETERS = ("gain", "time_offset", "baseline")
#: Relative forward-difference step of a config field.
FD_STEP = 1e-4
#: Stopping tolerances of the least squares: relative change of the cost (half chi^2, ~n/2 at
#: the optimum, so 1e-6 is a change far below the 0.5 that moves a parameter by one standard
#: error) and relative step in the parameters' natural units.
FTOL = 1e-6
XTOL = 1e-6
#: Condition number of the column-normalised Jacobian above which a parameter set is refused
#: as not identifiable (a combination of parameters leaves the traces unchanged).
MAX_CONDITION = 1e7


@dataclass(frozen=True)
class Trace:
    """One measured record and how the model sees it.

    Parameters
    ----------
    data : xarray.DataArray
        Force [N] along ``time`` [s] (what :func:`~hertzchain.lab.read_trace` returns).
    signal : str
        The simulated signal it measures: ``"wall"`` (contact N) or ``"sensor:n"`` (the sensor
        embedded in bead n).
    overrides : tuple of str
        ``DOTTED.PATH=VALUE`` settings for this trace only, e.g. ``("chain.truncate=16",)`` for
        the wall trace of the chain truncated after bead 16 (the paper's protocol).
    name : str
        Label in tables and plots (default: the file name).
    """

    data: object
    signal: str = "wall"
    overrides: tuple[str, ...] = ()
    name: str = ""

    def sensor_bead(self) -> int | None:
        """The bead the trace's sensor sits in.

        Returns
        -------
        int or None
            Bead number of an embedded sensor, None for the wall.
        """
        if self.signal == "wall":
            return None
        kind, _, bead = self.signal.partition(":")
        if kind != "sensor" or not bead.strip().isdigit():
            raise ConfigError("signal", f"must be 'wall' or 'sensor:N' (N a bead number), got {self.signal!r}")
        return int(bead)


@dataclass
class FitResult:
    """What :func:`fit_traces` found.

    Attributes
    ----------
    names : list of str
        Free parameters, in order (config paths, ``gain``, ``time_offset[k]``, ``baseline[k]``).
    values, stderr : numpy.ndarray
        Best values and standard errors (SI: m/s, s, N, Pa...; ``gain`` dimensionless).
    start : numpy.ndarray
        Starting values.
    covariance, correlation : numpy.ndarray
        ``s^2 (J^T J)^-1`` (each trace's rows scaled by its own residual variance) and the
        correlation matrix derived from it.
    cost : float
        Half the sum of squared weighted residuals at the optimum.
    residual_variance : float
        ``s^2`` = 2 cost / (n - p): about 1 when the noise estimate is right.
    n_points : int
        Number of samples fitted.
    n_evaluations : int
        Residual evaluations (each one batched engine call, or one tangent run per trace).
    n_members : int
        Chains simulated in all.
    converged : bool
        ``scipy.optimize.least_squares`` stopped on a tolerance (not on the evaluation limit).
    message : str
        Its message.
    config : dict
        The calibrated config mapping (the input with the free fields at their best values).
    traces : list of dict
        Per trace: ``name``, ``signal``, ``time`` [s], ``data``, ``model``, ``residual`` [N],
        ``noise`` [N], ``rms_residual`` [N].
    bootstrap : numpy.ndarray
        Parameter vectors of the bootstrap refits, shape (refits, parameters); empty without.
    warnings : list of str
        What makes the result doubtful (:func:`~hertzchain.lab.fit_checks.fit_doubts`: not
        converged; residuals far above the noise, the mark of a local minimum or of physics the
        model lacks; a model pulse that leaves a record's window; a fitted pulse hardly above
        the noise).
    elapsed : float
        Wall time of the fit [s].
    jacobian : str
        ``"exact"`` (the config fields' columns by the tangent model), or ``"finite differences"``
        with the reason (a field or model the sensitivity engine does not differentiate).
    n_tangent_runs : int
        Runs of the tangent model made for the Jacobians (one per trace and Jacobian).
    """

    names: list[str]
    values: np.ndarray
    stderr: np.ndarray
    start: np.ndarray
    covariance: np.ndarray
    correlation: np.ndarray
    cost: float
    residual_variance: float
    n_points: int
    n_evaluations: int
    n_members: int
    converged: bool
    message: str
    config: dict
    traces: list[dict] = field(repr=False)
    bootstrap: np.ndarray = field(default_factory=lambda: np.empty((0, 0)), repr=False)
    warnings: list[str] = field(default_factory=list)
    elapsed: float = 0.0
    jacobian: str = "exact"
    n_tangent_runs: int = 0

    def __repr__(self) -> str:
        pars = ", ".join(f"{n} = {v:.6g} ± {e:.2g}" for n, v, e in zip(self.names, self.values, self.stderr))
        state = "converged" if self.converged else "NOT converged"
        return (f"FitResult({pars}; {len(self.traces)} trace(s), {self.n_points} points, s^2 = "
                f"{self.residual_variance:.3g}, {state}, {self.n_evaluations} engine calls"
                + (f"; {len(self.warnings)} warning(s)" if self.warnings else "") + ")")

    def as_json(self) -> dict:
        """The result as the ``fit.json`` mapping (SI units).

        Returns
        -------
        dict
            ``parameters`` ({name: {value, stderr, start, unit[, bootstrap]}}), ``correlation``,
            ``cost``, ``residual_variance``, ``n_points``, ``n_parameters``, ``n_evaluations``,
            ``n_members``, ``jacobian`` (``"exact"``, or ``"finite differences (why)"``),
            ``n_tangent_runs``, ``converged``, ``message``, ``warnings``, ``elapsed_s``, ``traces``.
        """
        pars = {n: {"value": float(v), "stderr": float(e), "start": float(s), "unit": parameter_unit(n)}
                for n, v, e, s in zip(self.names, self.values, self.stderr, self.start)}
        if self.bootstrap.size:
            for i, n in enumerate(self.names):
                b = self.bootstrap[:, i]
                pars[n]["bootstrap"] = {"stderr": float(np.std(b, ddof=1)),
                                        "interval_68": [float(q) for q in np.percentile(b, [15.87, 84.13])],
                                        "refits": int(b.size)}
        return {
            "parameters": pars,
            "correlation": {"names": list(self.names), "matrix": np.round(self.correlation, 6).tolist()},
            "cost": float(self.cost), "residual_variance": float(self.residual_variance),
            "n_points": int(self.n_points), "n_parameters": len(self.names),
            "n_evaluations": int(self.n_evaluations), "n_members": int(self.n_members),
            "jacobian": self.jacobian, "n_tangent_runs": int(self.n_tangent_runs), "converged": bool(self.converged), "message": self.message, "warnings": list(self.warnings),
            "elapsed_s": float(self.elapsed),
            "traces": [{"name": t["name"], "signal": t["signal"], "n_points": int(t["time"].size),
                        "noise": float(t["noise"]), "rms_residual": float(t["rms_residual"])} for t in self.traces],
        }


# ------------------------------------------------------------------------------------------
def _get(mapping: dict, path: str):
    """The value at a dotted path (list items as ``key[i]``, as ``--set`` writes them), or None."""
    import re

    node = mapping
    for key in path.split("."):
        m = re.fullmatch(r"([A-Za-z_][A-Za-z0-9_]*)(?:\[(\d+)\])?", key)
        if m is None or not isinstance(node, dict) or m.group(1) not in node:
            return None
        node = node[m.group(1)]
        if m.group(2) is not None:
            if not isinstance(node, list) or int(m.group(2)) >= len(node):
                return None
            node = node[int(m.group(2))]
    return node


def _assign(value: float) -> str:
    return repr(float(value)) if math.isfinite(value) else "nan"


class _Problem:
    """The least-squares problem: parameter vector <-> configs, engine calls, residuals."""

    def __init__(self, data: dict, traces: Sequence[Trace], free: Sequence[str], rel_step: float,
                 n_threads: int | None):
        from ..analysis.pulse import estimate_noise
        from ..config import apply_overrides, parse_config

        self.data, self.traces, self.rel_step, self.n_threads = data, list(traces), rel_step, n_threads
        if not self.traces:
            raise ConfigError("MEASURED", "give at least one measured trace")
        free = list(dict.fromkeys(free))
        if not free:
            raise ConfigError("--free", "name at least one parameter to fit (a config field such as "
                              "striker.velocity, or gain, time_offset, baseline)")
        self.cfg_paths = [p for p in free if p not in MEASUREMENT_PARAMETERS]
        K = len(self.traces)
        self.beads = [t.sensor_bead() for t in self.traces]
        groups = sorted({"wall" if b is None else "sensor" for b in self.beads})
        self.group = ["wall" if b is None else "sensor" for b in self.beads]
        self.names: list[str] = list(self.cfg_paths)
        self.gain_idx: dict[str, int] = {}
        self.tau_idx: list[int | None] = [None] * K
        self.base_idx: list[int | None] = [None] * K
        if "gain" in free:
            for g in groups:
                self.gain_idx[g] = len(self.names)
                self.names.append("gain" if len(groups) == 1 else f"gain[{g}]")
        for key, idx in (("time_offset", self.tau_idx), ("baseline", self.base_idx)):
            if key in free:
                for k in range(K):
                    idx[k] = len(self.names)
                    self.names.append(key if K == 1 else f"{key}[{k}]")
        # Per-trace config mappings (global data + the trace's own settings), validated now so a
        # bad override is reported before any simulation.
        from ..config import build_chain

        self.trace_data = []
        for k, tr in enumerate(self.traces):
            d = apply_overrides(data, tr.overrides)
            n_beads = build_chain(parse_config(d)).n_beads
            if self.beads[k] is not None and not 1 <= self.beads[k] <= n_beads:
                raise ConfigError(f"{tr.name or f'trace {k}'}@signal", f"sensor:{self.beads[k]} names no bead of "
                                  f"this trace's chain (beads 1..{n_beads})")
            self.trace_data.append(d)
        base_cfg = parse_config(data).model_dump(mode="json")
        self.x_cfg0 = []
        for p in self.cfg_paths:
            value = _get(base_cfg, p)
            if value is None or isinstance(value, (bool, str, list, dict)):
                raise ConfigError(f"--free {p}", "is not a numeric field of the config" +
                                  ("" if value is None else f" (its value is {value!r})") +
                                  "; give a number in the config first (e.g. contact.A with law = "
                                  "'viscoelastic'), or free gain, time_offset or baseline")
            if isinstance(value, int):
                raise ConfigError(f"--free {p}", f"is an integer field ({value}); fit calibrates continuous "
                                  "parameters only")
            if value == 0:
                raise ConfigError(f"--free {p}", "starts at 0; the finite-difference step is relative to the "
                                  "value, so give a non-zero starting value in the config")
            self.x_cfg0.append(float(value))
        self.sample_interval = parse_config(data).run.sample_interval
        self.t = [np.asarray(tr.data["time"].values, float) for tr in self.traces]
        self.y = [np.asarray(tr.data.values, float) for tr in self.traces]
        # No record is more precise than a millionth of its range (a 20-bit converter): the floor
        # keeps a noise-free record (a simulation, a finely written file) from getting a weight
        # set by rounding errors.
        self.sigma = np.array([max(estimate_noise(y), 1e-6 * float(np.ptp(y))) for y in self.y])
        # Before any run: a record of noise alone, or a clipped one, cannot calibrate anything.
        check_records([self._label(k) for k in range(K)], self.t, self.y, self.sigma,
                      [tr.data.attrs.get("valid_max") for tr in self.traces])
        # Integer samples: the code grid [N] (step, one level) and, once fitted, the noise under
        # the codes; the model is then the quantiser's expected value (lab.quantised).
        self.quanta = [(tr.data.attrs["quantum"], tr.data.attrs["quantum_origin"]) if "quantum" in tr.data.attrs
                       else None for tr in self.traces]
        self.code_noise: list[float | None] = [None] * K
        # A trace whose time offset is not free reads the simulation on its own clock.
        self.tau_fixed = np.zeros(K)
        self.n_evaluations = 0
        self.n_members = 0
        self.n_tangent_runs = 0
        self.jacobian_kind = "exact"  # or "finite differences (why)": lab.jacobian.config_columns
        self._cache: dict[bytes, tuple] = {}
        self._sim_cache: dict[bytes, tuple] = {}

    # ---- engine ----------------------------------------------------------------------------
    def _configs(self, cfg_values: np.ndarray) -> list:
        from ..config import apply_overrides, parse_config

        out = []
        for d in self.trace_data:
            sets = [f"{p}={_assign(v)}" for p, v in zip(self.cfg_paths, cfg_values)]
            out.append(parse_config(apply_overrides(d, sets)))
        return out

    def simulate(self, cfg_sets: list[np.ndarray], taus: np.ndarray,
                 duration: float | None = None) -> list[list[tuple[np.ndarray, np.ndarray]]]:
        """One batched engine call: for every config vector, every trace's (sim time, force)."""
        from ..config import build_model
        from ..errors import ElasticLimitWarning, PulseNotReachedWarning
        from ..runs.batch import simulate_batch
        from ..probes import Probes

        models, probes = [], []
        for values in cfg_sets:
            for k, cfg in enumerate(self._configs(values)):
                models.append(build_model(cfg))
                bead = self.beads[k]
                probes.append(Probes(sample_interval=self.sample_interval, sensors=() if bead is None else (bead,),
                                     contacts=()))
        if duration is None:
            # Just past the last scope sample on the simulation clock.
            end = max(float(t[-1]) + float(tau) for t, tau in zip(self.t, taus))
            duration = max(end * 1.02 + 2 * self.sample_interval, 4 * self.sample_interval)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ElasticLimitWarning)  # reported once on the final model
            # a record of embedded sensors may rightly end before the pulse reaches the wall
            warnings.simplefilter("ignore", PulseNotReachedWarning)
            ds = simulate_batch(models, duration, probes, n_threads=self.n_threads)
        self.n_evaluations += 1
        self.n_members += len(models)
        tsim = ds["time"].values
        if np.issubdtype(tsim.dtype, np.timedelta64):
            tsim = tsim / np.timedelta64(1, "s")
        out, K = [], len(self.traces)
        for i in range(len(cfg_sets)):
            row = []
            for k in range(K):
                m = i * K + k
                bead = self.beads[k]
                if bead is None:
                    if "wall_force" not in ds:
                        raise ConfigError("wall.type", "a wall trace needs a wall (wall.type = 'flat')")
                    f = ds["wall_force"].values[m]
                else:
                    f = ds["sensor_force"].sel(sensor=bead).values[m]
                row.append((tsim, np.nan_to_num(np.asarray(f, float))))
            out.append(row)
        return out

    # ---- parameter vector ------------------------------------------------------------------
    def split(self, x: np.ndarray):
        P = len(self.cfg_paths)
        K = len(self.traces)
        gains = np.array([x[self.gain_idx[g]] if g in self.gain_idx else 1.0 for g in self.group])
        taus = np.array([x[i] if i is not None else self.tau_fixed[k] for k, i in enumerate(self.tau_idx)])
        bases = np.array([x[i] if i is not None else 0.0 for i in self.base_idx])
        return x[:P], gains, taus, bases, K

    def model(self, x: np.ndarray):
        """Weighted residuals and, per trace, the simulated (time, force) used."""
        from .jacobian import signals

        key = x.tobytes()
        if key in self._cache:
            return self._cache[key]
        cfg, gains, taus, bases, K = self.split(x)
        # The simulation depends on the config fields only (the gain, time offsets and baselines
        # act on its output), and a longer run is the same run continued: reuse the last one for
        # these fields while it reaches the last scope sample.
        need = max(float(t[-1]) + float(tau) for t, tau in zip(self.t, taus))
        hit = self._sim_cache.get(cfg.tobytes())
        if hit is not None and hit[0] >= need:
            sims = hit[1]
        else:
            span = max(float(t[-1] - t[0]) for t in self.t)
            duration = need + 0.25 * span + 2 * self.sample_interval
            sims = signals(self, cfg, taus, duration)  # the tangent model's run when the Jacobian is exact
            self._sim_cache = {cfg.tobytes(): (float(sims[0][0][-1]), sims)}
        res, parts = [], []
        for k, (ts, f) in enumerate(sims):
            fk = np.interp(self.t[k] + taus[k], ts, f)
            mk = gains[k] * fk + bases[k]
            if self.code_noise[k] is not None:
                mk = expected(mk, *self.quanta[k], self.code_noise[k])[0]
            res.append((self.y[k] - mk) / self.sigma[k])
            parts.append((ts, f, fk, mk))
        out = (np.concatenate(res), parts)
        self._cache = {key: out}
        return out

    def residuals(self, x: np.ndarray) -> np.ndarray:
        return self.model(x)[0]

    def jacobian(self, x: np.ndarray, config_fields: bool = True) -> np.ndarray:
        """d residual / d x, exact: the config fields' columns by the tangent model
        (:func:`hertzchain.lab.jacobian.config_columns`), the measurement's from the simulated signal
        (``config_fields=False``: those columns are left at zero and no engine call is made)."""
        res, parts = self.model(x)
        cfg, gains, taus, bases, K = self.split(x)
        P = len(self.cfg_paths) if config_fields else 0
        sizes = [t.size for t in self.t]
        edges = np.concatenate([[0], np.cumsum(sizes)])
        J = np.zeros((res.size, len(self.names)))
        if P:
            from .jacobian import config_columns

            config_columns(self, cfg, gains, taus, parts, edges, J)
        for k in range(K):
            ts, f, fk, mk = parts[k]
            rows = slice(edges[k], edges[k + 1])
            if self.group[k] in self.gain_idx:
                J[rows, self.gain_idx[self.group[k]]] = -fk / self.sigma[k]
            if self.tau_idx[k] is not None:
                dfdt = np.interp(self.t[k] + taus[k], ts, np.gradient(f, ts))
                J[rows, self.tau_idx[k]] = -gains[k] * dfdt / self.sigma[k]
            if self.base_idx[k] is not None:
                J[rows, self.base_idx[k]] = -1.0 / self.sigma[k]
            if self.code_noise[k] is not None:  # chain rule through the quantiser's expected value
                J[rows] *= expected(gains[k] * fk + bases[k], *self.quanta[k], self.code_noise[k])[1][:, None]
        return J

    # ---- start -----------------------------------------------------------------------------
    def start(self) -> np.ndarray:
        """Starting vector: config values as given; time offsets by cross-correlation, gain and
        baseline by linear least squares on the starting model."""
        x = np.zeros(len(self.names))
        x[:len(self.cfg_paths)] = self.x_cfg0
        # The starting model over the config's own run.duration (at least one record long),
        # where the records are then placed by cross-correlation.
        from ..config import parse_config

        span = max(float(t[-1] - t[0]) for t in self.t)
        duration = max(parse_config(self.data).run.duration, span)
        sims = self.simulate([np.asarray(self.x_cfg0)], self.tau_fixed, duration=duration)[0]
        for k, (ts, f) in enumerate(sims):
            if not np.any(f > 0):
                raise ConfigError("--free", f"bad start: the starting model gives no force at all on trace "
                                  f"{self._label(k)}; check the config (striker, wall, signal)")
            if self.tau_idx[k] is not None:
                x[self.tau_idx[k]] = self._align(k, ts, f)
            else:
                # A fixed time offset: the record must overlap the simulated pulse on its clock.
                level = np.abs(np.interp(self.t[k], ts, f))
                if not level.max() > 1e-3 * np.abs(f).max():
                    peak = float(ts[int(np.argmax(f))])
                    raise ConfigError(f"{self._label(k)}", f"bad start: the record spans [{self.t[k][0]:.4g}, "
                                      f"{self.t[k][-1]:.4g}] s on its own clock, and the simulated signal peaks at "
                                      f"{peak:.4g} s with nothing inside the record; a scope record counts time "
                                      "from its trigger: free time_offset")
        for g, i in self.gain_idx.items():
            num = den = 0.0
            for k, (ts, f) in enumerate(sims):
                if self.group[k] == g:
                    tau = x[self.tau_idx[k]] if self.tau_idx[k] is not None else 0.0
                    fk = np.interp(self.t[k] + tau, ts, f)
                    num += float(fk @ self.y[k]) / self.sigma[k] ** 2
                    den += float(fk @ fk) / self.sigma[k] ** 2
            if not den > 0:
                raise ConfigError("--free gain", "bad start: the model is zero over every record of this sensor, "
                                  "so no gain can scale it; free time_offset or check the config")
            x[i] = num / den
            if not x[i] > 0:
                raise ConfigError("--free gain", f"bad start: the records are anti-correlated with the model "
                                  f"(best gain {x[i]:.3g}); is the signal inverted?")
        return x

    def _label(self, k: int) -> str:
        return self.traces[k].name or f"#{k}"

    def _align(self, k: int, ts: np.ndarray, f: np.ndarray) -> float:
        """tau maximising the cross-correlation of trace k with the simulated signal."""
        from scipy.signal import correlate

        t, y = self.t[k], self.y[k]
        dt = float(ts[1] - ts[0])
        grid = np.arange(t[0], t[-1], dt)
        yg = np.interp(grid, t, y)
        c = correlate(f - f.mean(), yg - yg.mean(), mode="full", method="fft")
        lag = int(np.argmax(c)) - (grid.size - 1)
        return float(ts[0] + lag * dt - grid[0])


def _identifiability(names: list[str], J: np.ndarray, when: str) -> None:
    norms = np.linalg.norm(J, axis=0)
    scale = norms.max() if norms.size else 0.0
    for n, v in zip(names, norms):
        if not v > 1e-9 * max(scale, 1e-300):
            raise ConfigError(f"--free {n}", f"cannot be fitted ({when}): the simulated traces do not change "
                              "when it changes, so the data say nothing about it; leave it out")
    Jn = J / norms
    _, s, vt = np.linalg.svd(Jn, full_matrices=False)
    if s[-1] < s[0] / MAX_CONDITION:
        v = vt[-1]
        involved = [names[i] for i in np.argsort(-np.abs(v)) if abs(v[i]) > 0.2]
        raise ConfigError(f"--free {involved[0]}", f"cannot be separated from {', '.join(involved[1:]) or 'the others'} "
                          f"({when}): changing them together along ({', '.join(f'{c:+.2f}' for c in v)}) leaves the "
                          f"traces unchanged (condition number {s[0] / s[-1]:.2g}); fix one of them")


def fit_traces(config, traces: Sequence[Trace], free: Sequence[str], *, overrides: Sequence[str] = (),
               rel_step: float = FD_STEP, max_evaluations: int = 100, n_threads: int | None = None,
               bootstrap: int = 0, seed: int | None = 0,
               progress: Callable[[int, float], None] | None = None, jacobian: str = "exact",
               client=None) -> FitResult:
    """Calibrate the free parameters of a run config on measured traces (least squares).

    Parameters
    ----------
    config : str, os.PathLike or dict
        A run config (TOML file or the mapping read from one).
    traces : sequence of Trace
        The measured records with the signal each one measures and its own config settings
        (e.g. the truncation of the chain it was recorded on).
    free : sequence of str
        Dotted config paths of numeric fields (``striker.velocity`` [m/s], ``contact.A`` [s],
        ``materials.NAME.young`` [Pa] ...) and/or ``gain`` (one per sensor kind, dimensionless),
        ``time_offset`` (one per trace, [s]: the trace's time 0 on the simulation clock) and
        ``baseline`` (one per trace, [N]).
    overrides : sequence of str
        ``DOTTED.PATH=VALUE`` settings applied to the config first (``--set``).
    rel_step : float
        Relative forward-difference step of the config fields.
    max_evaluations : int
        Most residual evaluations (each one batched engine call).
    n_threads : int, optional
        Threads of the batched engine.
    bootstrap : int
        Number of residual-bootstrap refits (0: none). Each one refits, from the optimum, the
        best model plus the trace's residuals drawn with replacement (scaled by
        sqrt(n / (n - p))); the spread of the refits is an uncertainty that does not assume the
        model is linear in its parameters over the error bars.
    seed : int, optional
        Seed of the bootstrap's random draws.
    progress : callable, optional
        ``progress(n_evaluations, cost)`` after each residual evaluation.
    jacobian : {"exact", "finite differences"}
        How the config fields' columns of the Jacobian are made: the tangent model (default; forward
        differences where it does not apply) or forward differences (``rel_step``) throughout.
    client : object, optional
        Where the bootstrap refits run: None (here) or a Dask ``distributed.Client`` (or an
        executor), one task per refit (:mod:`hertzchain.lab.bootstrap`); the same numbers either way.

    Returns
    -------
    FitResult
        Best values, standard errors (covariance ``s^2 (J^T J)^-1``), correlations, cost,
        engine-call counts, the calibrated config, the per-trace model and residuals, and the
        bootstrap samples when asked for.

    Raises
    ------
    ConfigError
        A record without a significant pulse or a clipped one
        (:func:`~hertzchain.lab.fit_checks.check_records`, naming the trace), an unknown or
        non-numeric free field, a bad start (the starting model gives no pulse where the records
        are, or a gain of the wrong sign), or a parameter the traces cannot determine (the
        message names it and what it is confused with).
    """
    from ..config import apply_overrides, read_toml

    t0 = _time.perf_counter()
    if not (isinstance(bootstrap, (int, np.integer)) and (bootstrap == 0 or bootstrap >= 2)):
        raise ConfigError("--bootstrap", f"must be 0 (none) or a number of refits >= 2, got {bootstrap!r}")
    data = read_toml(config) if isinstance(config, (str, Path)) else dict(config)
    data = apply_overrides(data, overrides)
    if any("quantum" in tr.data.attrs for tr in traces):
        # The level before the pulse of a quantised record is known to a fraction of a code only
        # (its mean carries the rounding's bias): it is fitted, with its error bar.
        free = list(free) + ["baseline"]
    prob = _Problem(data, traces, free, rel_step, n_threads)
    if jacobian not in ("exact", "finite differences"):
        raise ConfigError("jacobian", f"must be 'exact' or 'finite differences', got {jacobian!r}")
    prob.jacobian_kind = jacobian
    x0 = prob.start()
    P = len(prob.cfg_paths)
    lower = np.full(x0.size, -np.inf)
    upper = np.full(x0.size, np.inf)
    lower[:P] = np.where(x0[:P] > 0, 0.0, -np.inf)
    upper[:P] = np.where(x0[:P] < 0, 0.0, np.inf)
    for i in prob.gain_idx.values():
        lower[i] = 0.0
    # Natural scales: config fields relative to their start, gain 1, times the scope's sample
    # spacing, baselines the noise. The identifiability check compares the Jacobian's columns
    # in these units (a modulus in Pa and a time in s differ by 1e16 otherwise).
    scale = np.ones(x0.size)
    scale[:P] = np.abs(x0[:P])
    for k in range(len(prob.traces)):
        if prob.tau_idx[k] is not None:
            scale[prob.tau_idx[k]] = float(np.median(np.diff(prob.t[k])))
        if prob.base_idx[k] is not None:
            scale[prob.base_idx[k]] = prob.sigma[k]
    _identifiability(prob.names, prob.jacobian(x0) * scale, "at the start")

    meas = np.arange(P, x0.size)
    if P and meas.size:
        # First the measurement's own parameters on the starting model: they need no engine call
        # (the one simulation is reused), and the full fit then starts with the records aligned
        # and scaled by least squares rather than by the cross-correlation's coarse guess.
        x0[meas] = _solve(lambda xm: prob.residuals(_put(x0, meas, xm)),
                          lambda xm: prob.jacobian(_put(x0, meas, xm), config_fields=False)[:, meas],
                          x0[meas], scale[meas], lower[meas], upper[meas], max_evaluations).x

    def fun(x):
        r = prob.residuals(x)
        if progress is not None:
            progress(prob.n_evaluations, 0.5 * float(r @ r))
        return r

    sol = _solve(fun, prob.jacobian, x0, scale, lower, upper, max_evaluations)
    sol, noise_columns = refit_noise(prob, sol, lambda x1: _solve(fun, prob.jacobian, x1, scale, lower, upper,
                                                                   max_evaluations))
    x = sol.x
    J = prob.jacobian(x)
    _identifiability(prob.names, J * scale, "at the optimum")
    res, parts = prob.model(x)
    n, p = res.size, x.size
    s2 = float(res @ res) / max(n - p, 1)
    # Each trace's rows scaled by its own residual variance (its share of the n - p degrees of
    # freedom), so a trace whose noise estimate was off does not carry a wrong weight into the
    # errors; with one trace this is s^2 (J^T J)^-1.
    edges = np.concatenate([[0], np.cumsum([t.size for t in prob.t])])
    Jw = J.copy()
    for k in range(len(prob.t)):
        rk = res[edges[k]:edges[k + 1]]
        s2k = float(rk @ rk) / max(rk.size * (n - p) / n, 1)
        Jw[edges[k]:edges[k + 1]] /= math.sqrt(s2k)
    _, s, vt = np.linalg.svd(Jw, full_matrices=False)
    cov = robust_covariance(prob, J, res, (vt.T / s**2) @ vt)
    for column, sd in noise_columns(x):  # the fitted noise under the codes: its error moves the others
        shift = -np.linalg.lstsq(J, column, rcond=None)[0]
        cov = cov + np.outer(shift, shift) * sd**2
    err = np.sqrt(np.diag(cov))
    corr = cov / np.outer(err, err)
    _, gains, taus, _, _ = prob.split(x)
    doubts = fit_doubts(sol, s2, [prob._label(k) for k in range(len(prob.traces))], prob.t, prob.sigma, taus, gains,
                        parts, prob.y)
    samples = np.empty((0, p))
    if bootstrap:
        from .bootstrap import bootstrap as run_bootstrap

        samples = run_bootstrap(prob, _solve, x, parts, bootstrap, seed, scale, lower, upper, max_evaluations, client)
    cfg_values = x[:P]
    calibrated = apply_overrides(data, [f"{path}={_assign(v)}" for path, v in zip(prob.cfg_paths, cfg_values)])
    out_traces = []
    for k, tr in enumerate(prob.traces):
        ts, f, fk, mk = parts[k]
        r = prob.y[k] - mk
        out_traces.append({"name": prob._label(k), "signal": tr.signal, "time": prob.t[k], "data": prob.y[k],
                           "model": mk, "residual": r, "noise": float(prob.sigma[k]),
                           "rms_residual": float(np.sqrt(np.mean(r**2)))})
    return FitResult(names=prob.names, values=x, stderr=err, start=x0, covariance=cov, correlation=corr,
                     cost=float(sol.cost), residual_variance=s2, n_points=n, n_evaluations=prob.n_evaluations,
                     n_members=prob.n_members, converged=bool(sol.status > 0), message=str(sol.message),
                     config=calibrated, traces=out_traces, bootstrap=samples, warnings=doubts,
                     elapsed=_time.perf_counter() - t0, jacobian=prob.jacobian_kind, n_tangent_runs=prob.n_tangent_runs)


def _put(x: np.ndarray, index: np.ndarray, values: np.ndarray) -> np.ndarray:
    out = x.copy()
    out[index] = values
    return out


def _solve(fun, jac, x0: np.ndarray, scale: np.ndarray, lower: np.ndarray, upper: np.ndarray, max_nfev: int):
    """:func:`scipy.optimize.least_squares` (trust region reflective) in the offsets from the
    start in natural units, u = (x - x0) / scale; returns its result with ``x`` in the
    parameters' own units.

    Solving for offsets keeps the first trust region at one natural unit: on ``x`` itself it
    would be ``|x0 / scale|``, thousands of sample spacings for a time offset of milliseconds,
    and the first steps would be rejected until the region had shrunk.
    """
    from scipy.optimize import least_squares

    sol = least_squares(lambda u: fun(x0 + u * scale), np.zeros(x0.size), jac=lambda u: jac(x0 + u * scale) * scale,
                        bounds=((lower - x0) / scale, (upper - x0) / scale), method="trf", max_nfev=max_nfev,
                        xtol=XTOL, ftol=FTOL, gtol=1e-8)
    sol.x = x0 + sol.x * scale
    return sol
