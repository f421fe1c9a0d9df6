"""What a quantising scope records on average, and the noise under its codes.

An integer-sample record (an 8-bit ``.isf`` or ``.trc``) holds y = Q(m + n): the signal m plus
white noise n of standard deviation sigma, rounded to the nearest level origin + i q. When sigma
is below about half a code the rounding does not average out: on a flat stretch the mean of the
samples sits off m by up to q/2 (sigma -> 0) and by ~0.09 q at sigma = q/4, a bias that no
least-squares error bar holds. A fit is unbiased when it compares the record with the
quantiser's expected value (Widrow & Kollar, *Quantization Noise*, 2008, eq. 5.28 for Gaussian
noise):

    E[Q(m + n)] = m + q * sum_k (-1)^k exp(-2 pi^2 k^2 sigma^2 / q^2) sin(2 pi k u) / (pi k),
    u = (m - origin) / q,

which needs sigma itself, not the spread of the codes: it is found by maximising the exact
likelihood of the codes, P(y | m, sigma) = Phi((y - m + q/2)/sigma) - Phi((y - m - q/2)/sigma),
given the fitted signal (the samples on the pulse's slopes, where the signal crosses levels, fix
it; a flat stretch only fixes (level - m)/sigma).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["DITHERED", "expected", "noise_by_likelihood", "refit_noise", "robust_covariance"]

#: sigma / q above which the rounding averages out (its bias below 1e-4 of a code): the record
#: is then fitted as it is.
DITHERED = 0.7


def _terms(sigma: float, q: float) -> np.ndarray:
    """k = 1..K with the series' factors exp(-2 pi^2 k^2 s^2) above 1e-9."""
    s = max(sigma / q, 1e-3)
    kmax = int(math.ceil(math.sqrt(math.log(1e9) / (2.0 * math.pi**2)) / s)) + 1
    return np.arange(1, min(kmax, 2000) + 1, dtype=float)


def expected(m: np.ndarray, q: float, origin: float, sigma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Expected recorded value of signal ``m`` [N] under Gaussian noise and rounding to the levels.

    Parameters
    ----------
    m : numpy.ndarray
        The signal before noise and rounding [N].
    q, origin : float
        Code step [N] and the value of one level [N].
    sigma : float
        Noise standard deviation before rounding [N].

    Returns
    -------
    value, d_dm, d_dsigma : numpy.ndarray
        E[Q(m + n)] [N] (module docstring), and its derivatives in m [1] and sigma [1].
    """
    k = _terms(sigma, q)
    u = (np.asarray(m, float) - origin) / q
    damp = (-1.0) ** k * np.exp(-2.0 * math.pi**2 * k**2 * sigma**2 / q**2)
    phase = 2.0 * math.pi * np.multiply.outer(u, k)
    value = m + q * (np.sin(phase) @ (damp / (math.pi * k)))
    d_dm = 1.0 + np.cos(phase) @ (2.0 * damp)
    d_dsigma = np.sin(phase) @ (damp * (-4.0 * math.pi * k * sigma / q))
    return value, d_dm, d_dsigma


def _loglik(sigma: float, y: np.ndarray, m: np.ndarray, q: float) -> float:
    from scipy.special import log_ndtr, ndtr

    hi, lo = (y - m + 0.5 * q) / sigma, (y - m - 0.5 * q) / sigma
    # log(Phi(hi) - Phi(lo)) without cancellation in either tail (mirror the upper one).
    upper = lo > 0
    a, b = np.where(upper, -hi, lo), np.where(upper, -lo, hi)
    p = ndtr(b) - ndtr(a)
    small = p < 1e-12
    out = np.log(np.where(small, 1.0, p))
    out[small] = log_ndtr(b[small]) + np.log1p(-np.exp(np.minimum(log_ndtr(a[small]) - log_ndtr(b[small]), -1e-16)))
    return float(np.sum(out))


def noise_by_likelihood(y: np.ndarray, m: np.ndarray, q: float, start: float) -> tuple[float, float]:
    """Noise sigma [N] under the codes of a quantised record, given the signal, by maximum likelihood.

    Parameters
    ----------
    y : numpy.ndarray
        The recorded levels [N].
    m : numpy.ndarray
        The fitted signal at the same samples [N] (the model before noise and rounding).
    q : float
        Code step [N].
    start : float
        A scale for the search [N] (e.g. the spread of the samples): sigma is sought in
        [1e-3, 10] times max(start, q).

    Returns
    -------
    sigma, stderr : float
        The maximum-likelihood sigma [N] and its standard error from the likelihood's curvature.
    """
    from scipy.optimize import minimize_scalar

    scale = max(start, q)
    sol = minimize_scalar(lambda ls: -_loglik(math.exp(ls), y, m, q),
                          bounds=(math.log(1e-3 * scale), math.log(10.0 * scale)), method="bounded",
                          options={"xatol": 1e-5})
    s = math.exp(sol.x)
    h = 1e-3 * s
    curv = -(_loglik(s + h, y, m, q) - 2.0 * _loglik(s, y, m, q) + _loglik(s - h, y, m, q)) / h**2
    return s, (1.0 / math.sqrt(curv) if curv > 0 else math.inf)


def refit_noise(prob, sol, solve, rounds: int = 8):
    """Alternate the noise under the codes of each quantised trace and the fit, to a fixed point.

    Parameters
    ----------
    prob : hertzchain.lab.fit._Problem
        The problem (``quanta``: each trace's code step and level [N] or None; ``code_noise``:
        the noise the model uses, None for a record fitted as it is).
    sol : scipy.optimize.OptimizeResult
        The fit of the records as they are.
    solve : callable
        ``solve(x)``: the fit again from ``x``.
    rounds : int
        Most noise updates (each one refit from the last optimum, a few engine calls).

    Returns
    -------
    sol : scipy.optimize.OptimizeResult
        The last fit.
    columns : callable
        ``columns(x)``: per quantised trace, (d residuals / d sigma, standard error of sigma [N]),
        for the covariance of the other parameters (the noise's error moves them).
    """
    errors: dict[int, float] = {}
    for _ in range(rounds if any(q is not None for q in prob.quanta) else 0):
        _, gains, _, bases, _ = prob.split(sol.x)
        parts = prob.model(sol.x)[1]
        moved = False
        for k, grid in enumerate(prob.quanta):
            if grid is None:
                continue
            sigma, err = noise_by_likelihood(prob.y[k], gains[k] * parts[k][2] + bases[k], grid[0], prob.sigma[k])
            new = sigma if sigma < DITHERED * grid[0] else None
            old = prob.code_noise[k]
            moved |= (new is None) != (old is None) or (new is not None and abs(new - old) > 0.05 * err)
            prob.code_noise[k] = new
            if new is None:
                errors.pop(k, None)
            else:
                errors[k] = err
        if not moved:
            break
        prob._cache = {}
        sol = solve(sol.x)

    def columns(x: np.ndarray) -> list[tuple[np.ndarray, float]]:
        _, gains, _, bases, _ = prob.split(x)
        parts = prob.model(x)[1]
        edges = np.concatenate([[0], np.cumsum([t.size for t in prob.t])])
        out = []
        for k, err in errors.items():
            col = np.zeros(edges[-1])
            quantiser = prob.quantiser(k)
            assert quantiser is not None  # errors holds the traces whose code noise is fitted
            d_dsigma = expected(gains[k] * parts[k][2] + bases[k], *quantiser)[2]
            col[edges[k]:edges[k + 1]] = -d_dsigma / prob.sigma[k]
            out.append((col, err))
        return out

    return sol, columns


def robust_covariance(prob, J: np.ndarray, res: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """The parameters' covariance of a fit with quantised traces, robust to their uneven variance.

    The residuals of a quantised record are independent with mean 0 but not of one variance: a
    sample whose signal sits at a level's centre hardly ever leaves it, one between two levels
    takes either with equal chance. ``s^2 (J^T J)^-1`` assumes one variance; the sandwich
    ``(J^T J)^-1 J^T diag(r^2) J (J^T J)^-1`` (White's, with the n / (n - p) correction) does not.

    Parameters
    ----------
    prob : hertzchain.lab.fit._Problem
        The problem (``code_noise``: whether a trace is fitted as quantised).
    J, res : numpy.ndarray
        Jacobian and residuals at the optimum (weighted).
    cov : numpy.ndarray
        The plain covariance, returned as it is when no trace is fitted as quantised.

    Returns
    -------
    numpy.ndarray
        The covariance.
    """
    if all(s is None for s in prob.code_noise):
        return cov
    n, p = J.shape
    bread = np.linalg.pinv(J.T @ J)
    meat = (J * res[:, None] ** 2).T @ J * (n / max(n - p, 1))
    return bread @ meat @ bread
