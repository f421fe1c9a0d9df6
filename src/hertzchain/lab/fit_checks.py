"""What makes a calibration impossible (refused before any run) or doubtful (flagged on the result).

Refused (:func:`check_records`, a :class:`~hertzchain.errors.ConfigError` naming the trace):

- a record without a significant pulse: its largest excursion above its baseline (the 10th
  percentile) is not SNR_MIN times its noise, as :func:`hertzchain.analysis.fit_pulse` (and
  so ``hertzchain analyze``) requires: a least-squares fit of noise converges too, on a
  meaningless striker speed with small error bars;
- a clipped record (:func:`hertzchain.analysis.saturation.find_clipping`): the fit would match
  the cut top;
- (:func:`check_identifiable`, at the start and at the optimum, naming ``--free NAME``) a free
  parameter the simulated traces do not depend on, or a combination of them that leaves the
  traces unchanged.

Flagged (:func:`fit_doubts`, the result's ``warnings``): a fit that did not converge; residuals
above the noise (s^2 > S2_DOUBT: a local minimum, physics the model lacks, or a record the
model misreads); residuals with structure (their sums over blocks of the record too uneven for
independent noise, :func:`structure_p` below STRUCTURE_P; a model off by a smooth amount over stretches of the
record, such as a baseline off by a fraction of a code, which s^2 of ~1.2 hardly shows); a model pulse that leaves
the record window (the record holds only part of what the parameters are fitted to); a fitted
pulse whose height is not SNR_MIN times the noise.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from ..errors import ConfigError

__all__ = ["SNR_MIN", "MAX_RESIDUAL_VARIANCE", "S2_DOUBT", "STRUCTURE_P", "EDGE_FRACTION", "MAX_CONDITION",
           "check_records", "check_identifiable", "fit_doubts", "parameter_unit", "structure_p"]

#: Least height of a record's pulse over its noise (fit_pulse's snr_min: analyze's criterion).
SNR_MIN = 8.0
#: Residual variance (in units of the estimated noise variance) above which a fit is flagged.
MAX_RESIDUAL_VARIANCE = 10.0
#: Residual variance above which the residuals are said to exceed the noise: the noise is estimated
#: from the record itself to a few per cent, so a correct model gives 1 +- ~0.1.
S2_DOUBT = 1.3
#: p-value of the residuals' block sums (:func:`structure_p`) below which they have structure.
STRUCTURE_P = 1e-6
#: A model pulse "leaves the record" when it is above this fraction of its height at an end of the
#: record, or before the record starts.
EDGE_FRACTION = 0.5
#: Condition number of the column-normalised Jacobian above which a parameter set is refused
#: as not identifiable (a combination of parameters leaves the traces unchanged).
MAX_CONDITION = 1e7


#: Units of the free parameters, by the last part of their name (SI, as fit reports them).
_UNITS = {"gain": "1", "time_offset": "s", "baseline": "N", "velocity": "m/s", "A": "s", "gamma": "N s/m", "eps": "1",
          "young": "Pa", "poisson": "1", "density": "kg/m^3", "yield_stress": "Pa", "precompression": "N",
          "duration": "s", "sample_interval": "s", "q": "1", "sensitivity_mV_per_N": "mV/N"}


def parameter_unit(name: str) -> str:
    """The unit of a free parameter as ``fit`` reports it (``striker.velocity`` -> ``m/s``).

    Parameters
    ----------
    name : str
        A config path (``materials.X.young``, ``chain.diameters_mm[3]``) or a measurement
        parameter (``gain``, ``time_offset[2]``, ``baseline``).

    Returns
    -------
    str
        The unit (``mm`` for ``*_mm`` fields; ``SI`` when the name says nothing).
    """
    last = name.split("[")[0].rsplit(".", 1)[-1]
    if last.endswith("_mm"):
        return "mm"
    return _UNITS.get(last, "SI")


def check_records(labels: Sequence[str], times: Sequence[np.ndarray], records: Sequence[np.ndarray],
                  noise: np.ndarray, valid_max: Sequence[float | None]) -> None:
    """Refuse a record that holds no significant pulse, or a clipped one.

    Parameters
    ----------
    labels : sequence of str
        Trace names (the error's field).
    times, records : sequence of numpy.ndarray
        Each trace's times [s] and force [N].
    noise : numpy.ndarray
        Each trace's noise standard deviation [N].
    valid_max : sequence of float or None
        Each trace's full scale [N] when its file gives one.

    Raises
    ------
    ConfigError
        Naming the trace, with its pulse height over its noise, or where it is clipped.
    """
    from ..analysis.saturation import find_clipping

    for label, t, y, sigma, top in zip(labels, times, records, noise, valid_max):
        clipped = find_clipping(t, y, valid_max=top)
        if clipped is not None:
            raise ConfigError(label, f"is clipped ({clipped}); a calibration on it would fit the cut top")
        height = float(np.max(y) - np.percentile(y, 10))
        if not height > SNR_MIN * sigma:
            ratio = height / sigma if sigma > 0 else 0.0
            raise ConfigError(label, f"holds no significant pulse: its largest excursion above the baseline "
                              f"({height:.3g} N) is {ratio:.2g} times its noise ({sigma:.3g} N), less than "
                              f"{SNR_MIN:g} (the criterion of hertzchain analyze); a fit of noise would report a "
                              "meaningless calibration. Check the file, the column and the sensitivity")


def structure_p(residual: np.ndarray, block: int = 64) -> float:
    """Chance that independent residuals of mean 0 sum as unevenly over blocks as these do.

    The record is cut into blocks of ``block`` samples (fewer when that leaves under 8 blocks);
    block b gives z_b = sum r_i / sqrt(sum r_i^2), which is ~N(0, 1) for independent residuals of
    mean 0 whatever their variances (so it holds for the residuals of a quantised record, whose
    variance and sign balance change with the signal's place between two codes, where a runs
    test of signs takes that for structure), and sum z_b^2 follows chi^2(blocks). A model off by
    a smooth amount over stretches of the record (a baseline off by a fraction of a code, a
    drift, a pulse of the wrong shape) makes the blocks' sums grow as their length.

    Parameters
    ----------
    residual : numpy.ndarray
        A trace's residuals, in time order.
    block : int
        Samples per block (at most).

    Returns
    -------
    float
        The p-value (1 for a record too short to test or all zero).
    """
    from scipy.stats import chi2

    r = np.asarray(residual, float)
    block = int(min(block, r.size // 8))
    if block < 4:
        return 1.0
    b = r[: r.size // block * block].reshape(-1, block)
    norm = np.sqrt(np.sum(b**2, axis=1))
    keep = norm > 0
    z = np.sum(b[keep], axis=1) / norm[keep]
    return float(chi2.sf(np.sum(z**2), z.size)) if z.size else 1.0


def fit_doubts(sol, s2: float, labels: Sequence[str], times: Sequence[np.ndarray], noise: np.ndarray,
               taus: np.ndarray, gains: np.ndarray, parts: list, records: Sequence[np.ndarray] = ()) -> list[str]:
    """What makes a finished fit doubtful, one sentence each.

    Parameters
    ----------
    sol : scipy.optimize.OptimizeResult
        The least-squares solution (``status``, ``nfev``, ``message``).
    s2 : float
        Residual variance per degree of freedom (in units of the noise variance).
    labels : sequence of str
        Trace names.
    times : sequence of numpy.ndarray
        Each trace's times [s] (its own clock).
    noise : numpy.ndarray
        Each trace's noise [N].
    taus, gains : numpy.ndarray
        Each trace's time offset [s] (its time 0 on the simulation clock) and gain.
    parts : list
        Per trace: (simulated times [s], simulated force [N], the force at the record's times,
        the model on the record [N]).
    records : sequence of numpy.ndarray
        Each trace's samples [N] (for the structure of its residuals; none: not checked).

    Returns
    -------
    list of str
        The doubts (empty: none).
    """
    doubts = []
    if not sol.status > 0:
        doubts.append(f"not converged after {sol.nfev} evaluations ({sol.message}); raise --max-evaluations "
                      "or start closer")
    # With the noise estimated from the records themselves, s^2 is ~1 for a model that fits;
    # far above it the optimum is a local one (e.g. a pulse aligned on the wrong peak) or the
    # model misses part of the physics.
    if s2 > MAX_RESIDUAL_VARIANCE:
        doubts.append(f"the residuals are {math.sqrt(s2):.3g} times the noise: the model does not describe "
                      "the records (a local minimum from a poor start, or physics the model lacks); look at "
                      "fit.png before trusting the values")
    elif s2 > S2_DOUBT:
        doubts.append(f"the residual variance is {s2:.3g} times the noise's (s^2; ~1 when the model describes the "
                      "records): the model or the record is off (a wrong baseline, a quantised record, a "
                      "signal the model lacks); the error bars are not to be trusted")
    for label, y, (_, _, _, mk) in zip(labels, records, parts):
        p = structure_p(np.asarray(y) - mk)
        if p < STRUCTURE_P:
            doubts.append(f"{label}: the residuals have structure (their sums over stretches of the record are too "
                          f"uneven for noise: p = {p:.2g}): the model is off by a smooth amount (a baseline, a "
                          "drift, a pulse shape); look at fit.png, free baseline, before trusting the values")
    for label, t, sigma, tau, g, (ts, f, fk, _) in zip(labels, times, noise, taus, gains, parts):
        inside = g * fk
        height = float(np.max(inside)) if inside.size else 0.0
        if not height > SNR_MIN * sigma:
            doubts.append(f"{label}: the fitted pulse is {height / sigma:.2g} times the noise ({sigma:.3g} N) in "
                          f"the record, less than {SNR_MIN:g}: the record hardly constrains the fit")
            continue
        before = g * f[ts < t[0] + tau]
        ends = [what for what, v in (("before the record starts", float(before.max()) if before.size else 0.0),
                                     ("at the record's start", float(inside[0])),
                                     ("at the record's end", float(inside[-1]))) if v > EDGE_FRACTION * height]
        if ends:
            doubts.append(f"{label}: the model's pulse leaves the record window (it is above {EDGE_FRACTION:g} of "
                          f"its height {', '.join(ends)}; the record spans [{t[0]:.4g}, {t[-1]:.4g}] s on its "
                          f"clock): the fit sees part of the pulse only; record a longer window or check "
                          "time_offset")
    return doubts


def check_identifiable(names: list[str], J: np.ndarray, when: str) -> None:
    """Refuse free parameters the traces cannot determine (ConfigError naming ``--free NAME``): a
    column of the Jacobian ``J`` (samples, parameters) that is zero, or a combination of columns
    that leaves the traces unchanged (condition number of the column-normalised J over
    MAX_CONDITION); ``when`` says at which point (the start, the optimum)."""
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
