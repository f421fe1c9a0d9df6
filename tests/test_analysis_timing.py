"""Bead-to-bead fits of hertzchain.analysis.timing (paper Sec. III, Figs. 4, 6)."""

from __future__ import annotations

import numpy as np
import pytest

from hertzchain import theory as th
from hertzchain.analysis import (
    collapse, cos6_pulse, fit_pulse, fit_restitution, fit_uniform_time_of_flight,
    fit_velocity_growth, local_velocity,
)
from hertzchain.errors import ConfigError

STEEL = "AISI52100"


def test_local_velocity_exact():
    phi = np.array([26.0, 24.0, 23.0, 22.0]) * 1e-3
    v = np.array([420.0, 425.0, 431.0, 440.0])
    T = 1e-3 + np.cumsum(phi / v)
    np.testing.assert_allclose(local_velocity(phi, T), v[1:], rtol=1e-12)
    np.testing.assert_allclose(local_velocity(phi, T, t0=1e-3), v, rtol=1e-12)
    with pytest.raises(ConfigError):
        local_velocity(phi, T[::-1])


def test_local_velocity_of_ballistic_prediction():
    phi = np.asarray(th.PAPER_CHAINS["chain2"]) * 1e-3
    p = th.predict_chain(phi, STEEL, 100.0, eps=0.985, T0=2e-4)
    np.testing.assert_allclose(local_velocity(p.diameter, p.time_of_flight), p.speed[1:], rtol=1e-11)


def test_fit_velocity_growth_exact_and_noisy():
    n = np.arange(17, 31)
    v = 410.0 * 1.025 ** (n - 17)
    Q, Q_err, v_ref = fit_velocity_growth(n, v)
    assert Q == pytest.approx(1.025, rel=1e-12)
    assert v_ref == pytest.approx(410.0, rel=1e-12)
    assert Q_err < 1e-12
    # reference bead elsewhere
    fit = fit_velocity_growth(n, v, n_ref=20)
    assert fit.v_ref == pytest.approx(410.0 * 1.025**3, rel=1e-12)

    # 3 % multiplicative scatter, as local velocities from time differences are noisy (Sec. III)
    rng = np.random.default_rng(2006)
    n = np.arange(17, 61)
    v_noisy = v_ref * 1.025 ** (n - 17) * np.exp(rng.normal(0, 0.03, n.size))
    fit = fit_velocity_growth(n, v_noisy)
    # expected standard error of ln Q: 0.03 / sqrt(sum (n - mean)^2) = 0.03 / 84.6 = 3.5e-4
    assert 2e-4 < fit.Q_err < 6e-4
    assert abs(fit.Q - 1.025) < 4 * fit.Q_err
    # with the true errors given, the weighted fit gives the same answer (equal weights here)
    fit_w = fit_velocity_growth(n, v_noisy, velocity_err=0.03 * v_noisy)
    assert fit_w.Q == pytest.approx(fit.Q, rel=1e-12)


def test_fit_velocity_growth_weights_matter():
    n = np.arange(10)
    v = 100.0 * 1.05**n
    v[-1] *= 1.5  # one outlier ...
    err = np.full(n.size, 0.1)
    err[-1] = 1e6  # ... with a huge error bar is ignored by the weighted fit
    fit = fit_velocity_growth(n, v, velocity_err=err)
    assert fit.Q == pytest.approx(1.05, rel=1e-9)
    assert fit_velocity_growth(n, v).Q > 1.06


def test_fit_uniform_time_of_flight_recovers_v1_T0():
    phi0, v1, T0, eps = 0.026, 428.6, 1.5e-4, 0.985
    n = np.arange(1, 17)
    T = th.time_of_flight_uniform(n, phi0, v1, T0, eps)
    fit = fit_uniform_time_of_flight(n, T, phi0, eps)
    assert fit.v1 == pytest.approx(v1, rel=1e-10)
    assert fit.T0 == pytest.approx(T0, abs=1e-14)
    assert fit.v1_err < 1e-8 and fit.T0_err < 1e-15

    # 0.5 us timing jitter (a 2 MHz oscilloscope): v1 within a few tenths of a percent
    rng = np.random.default_rng(11)
    T_noisy = T + rng.normal(0, 0.5e-6, n.size)
    fit = fit_uniform_time_of_flight(n, T_noisy, phi0, eps)
    assert abs(fit.v1 - v1) < 4 * fit.v1_err and fit.v1_err < 0.01 * v1
    assert abs(fit.T0 - T0) < 4 * fit.T0_err and fit.T0_err < 1e-6


def test_fit_uniform_time_of_flight_elastic_limit():
    n = np.arange(1, 10)
    T = 1e-4 + n * 0.02 / 380.0
    fit = fit_uniform_time_of_flight(n, T, 0.02, 1.0)
    assert fit.v1 == pytest.approx(380.0, rel=1e-12)
    assert fit.T0 == pytest.approx(1e-4, rel=1e-12)


def test_fit_restitution():
    n = np.arange(1, 17)
    F = 100.0 * (0.985 ** (6 / 5)) ** (n - 1)  # eps = (F_n+1/F_n)^(5/6) (Sec. III)
    eps, eps_err = fit_restitution(n, F)
    assert eps == pytest.approx(0.985, rel=1e-13)
    assert eps_err < 1e-12
    # from the ballistic prediction of a uniform chain
    p = th.predict_chain(np.full(16, 0.026), STEEL, 80.0, eps=0.97)
    assert fit_restitution(p.bead, p.peak_force).eps == pytest.approx(0.97, rel=1e-12)
    # 1 % scatter on the peak forces: eps known to ~1e-3, as the paper's 0.985
    rng = np.random.default_rng(5)
    fit = fit_restitution(n, F * np.exp(rng.normal(0, 0.01, n.size)))
    assert fit.eps_err < 2e-3
    assert abs(fit.eps - 0.985) < 4 * fit.eps_err


def test_collapse():
    t = np.arange(0, 2e-3, 0.5e-6)
    pulses = [(100.0, 8e-4, 60e-6), (55.0, 1.1e-3, 35e-6)]
    for F, T, tau in pulses:
        force = cos6_pulse(t, F, T, tau) + 2.0
        fit = fit_pulse(t, force)
        x, y = collapse(t, force, fit)
        rising = (x > -1) & (x < 0)
        np.testing.assert_allclose(y[rising], np.cos(x[rising]) ** 6, atol=1e-8)
        assert x[np.argmax(y)] == pytest.approx(0.0, abs=0.5e-6 / tau)
