"""Closed-form theory of Melo et al., PRE 2006, Sec. II-III (hertzchain.theory)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hertzchain import theory as th
from hertzchain.contact import hertz_constant
from hertzchain.errors import ConfigError
from hertzchain.materials import get_material

STEEL = get_material("AISI52100")


# --- tapering factor, Table I ------------------------------------------------------------------
def test_paper_chains_match_table_I():
    c1, c2 = th.PAPER_CHAINS["chain1"], th.PAPER_CHAINS["chain2"]
    assert len(c1) == 30 and len(c2) == 28
    assert c1[:16] == [26.0] * 16 and c2[:16] == [26.0] * 16
    assert c1[16] == 24.0 and c1[23] == 16.65 and c1[-1] == 11.0  # beads 17, 24, 30
    assert c2[17] == 22.0 and c2[20] == 16.65 and c2[-1] == 9.0  # beads 18, 21, 28


@pytest.mark.parametrize("chain, q_paper, std_paper", [("chain1", 5.60, 0.67), ("chain2", 8.27, 0.31)])
def test_tapering_factor_reproduces_paper(chain, q_paper, std_paper):
    q, q_std = th.tapering_factor(th.PAPER_CHAINS[chain], n0=16)
    # the paper prints percent with two decimals
    assert round(100 * q, 2) == q_paper
    assert round(100 * q_std, 2) == std_paper


def test_tapering_factor_exact_geometric_chain():
    phi = 26e-3 * np.concatenate([np.ones(16), 0.93 ** np.arange(1, 11)])
    q, q_std = th.tapering_factor(phi)
    assert q == pytest.approx(0.07, abs=1e-12)
    assert q_std == pytest.approx(0.0, abs=1e-12)


def test_tapering_factor_rejects_bad_n0():
    with pytest.raises(ConfigError):
        th.tapering_factor([1.0, 0.9], n0=2)


# --- ballistic ratios, eqs. 6-8 ------------------------------------------------------------------
@pytest.mark.parametrize("q, Q_paper", [(0.056, 1.014), (0.0827, 1.022)])
def test_speed_ratio_is_paper_Q_th(q, Q_paper):
    # paper Sec. III: Q_1^th = 1.014, Q_2^th = 1.022 with eps = 0.985
    assert th.ballistic_ratios(q, eps=0.985).speed == pytest.approx(Q_paper, abs=1e-3)


def test_ballistic_ratios_limits_and_consistency():
    r = th.ballistic_ratios(0.0, eps=1.0)
    assert (r.velocity, r.force, r.speed) == (1.0, 1.0, 1.0)
    # uniform chain with dissipation: F ratio = eps^(6/5), so eps = (F_n+1/F_n)^(5/6) (Sec. III)
    r = th.ballistic_ratios(0.0, eps=0.985)
    assert r.force ** (5 / 6) == pytest.approx(0.985, rel=1e-14)
    # array input, and eq. 8 = (eq. 6)^(1/5), eq. 7 = (1-q)^2 (eq. 6)^(6/5)
    q = np.array([0.0, 0.05, 0.1])
    r = th.ballistic_ratios(q, eps=0.99)
    assert r.speed.shape == (3,)
    np.testing.assert_allclose(r.speed, r.velocity ** 0.2, rtol=1e-15)
    np.testing.assert_allclose(r.force, (1 - q) ** 2 * r.velocity ** 1.2, rtol=1e-15)
    # a smaller next bead is pushed faster: V ratio > 1, F ratio < 1 (shock mitigation)
    assert np.all(r.velocity[1:] > 1) and np.all(r.force[1:] < 1)


# --- solitary wave, eqs. 4-5 ---------------------------------------------------------------------
def test_speed_formula_value():
    # direct evaluation of eq. 5 for 26 mm steel at F_m = 100 N
    theta = 3 * (1 - 0.3**2) / (4 * 203e9)
    expected = math.sqrt(6 / (5 * math.pi * 7780)) * (100 / (theta**2 * 0.013**2)) ** (1 / 6)
    assert th.solitary_wave_speed(STEEL, 0.026, 100.0) == pytest.approx(expected, rel=1e-14)
    assert 400 < expected < 460  # a few hundred m/s, as in the paper's chains


@pytest.mark.parametrize("diameter, force", [(0.026, 100.0), (0.011, 20.0), (0.009, 400.0)])
def test_two_forms_of_eq5_agree_through_bead_velocity(diameter, force):
    # Independent route from F_m to V_m: Hertz eq. 1 with contact.hertz_constant gives delta_m,
    # the continuum relation V_m = v * strain = v delta_m / (2R) gives V_m, and the second
    # form of eq. 5 must give back the same speed.
    R = diameter / 2
    kappa = hertz_constant(R, R, STEEL, STEEL)
    delta_m = (force / kappa) ** (2 / 3)
    v1 = th.solitary_wave_speed(STEEL, diameter, force)
    V_m = v1 * delta_m / (2 * R)
    assert th.peak_bead_velocity(STEEL, diameter, force) == pytest.approx(V_m, rel=1e-13)
    assert th.solitary_wave_speed_from_velocity(STEEL, V_m) == pytest.approx(v1, rel=1e-12)


def test_speed_scaling_laws():
    v = th.solitary_wave_speed("AISI52100", 0.02, np.array([1.0, 64.0]))
    assert v[1] / v[0] == pytest.approx(2.0, rel=1e-14)  # v ~ F_m^(1/6)
    v = th.solitary_wave_speed("AISI52100", np.array([0.01, 0.08]), 10.0)
    assert v[0] / v[1] == pytest.approx(2.0, rel=1e-14)  # v ~ R^(-1/3)


def test_nesterenko_force_profile():
    x = np.array([-2.0, -math.pi / 2, 0.0, 0.4, 1.0, math.pi / 2 - 1e-9, 3.0])
    f = th.nesterenko_force(x, 50.0, 1.0)
    assert f[2] == 50.0 and f[0] == 0.0 and f[1] == 0.0 and f[-1] == 0.0
    assert f[4] == pytest.approx(50.0 * math.cos(1.0) ** 6)
    assert 0 < f[5] < 1e-40
    # half maximum at |x| = arccos(2^(-1/6)) = 0.4715 widths
    assert th.nesterenko_force(th.HALF_MAX_PHASE * 3.0, 1.0, 3.0) == pytest.approx(0.5, rel=1e-12)
    assert th.HALF_MAX_PHASE == pytest.approx(-0.4715, abs=1e-4)


def test_yield_limit_paper_values():
    F_Y, delta_Y = th.yield_limit("AISI52100", 0.026)
    assert F_Y == pytest.approx(470, rel=0.02)  # paper: F_Y ~ 470 N
    assert delta_Y == pytest.approx(11e-6, rel=0.06)  # paper: delta_Y ~ 11 um
    # the estimate F_Y = (pi sigma_Y)^3 (theta R / 2)^2 scales as R^2
    F_small, _ = th.yield_limit("AISI52100", 0.013)
    assert F_small == pytest.approx(F_Y / 4, rel=1e-12)


def test_pulse_duration():
    v = th.solitary_wave_speed(STEEL, 0.026, 100.0)
    tau = th.pulse_duration(0.026, v)
    assert tau == pytest.approx(0.013 * math.sqrt(10) / v, rel=1e-15)
    assert 80e-6 < tau < 110e-6  # ~0.1 ms, the scale of the paper's Fig. 1


# --- predictions along a chain -----------------------------------------------------------------
def test_predict_chain_elastic_uniform_is_constant():
    phi = np.full(20, 0.026)
    p = th.predict_chain(phi, STEEL, 100.0, eps=1.0, q=0.0)
    np.testing.assert_allclose(p.peak_force, 100.0, rtol=1e-15)
    v = th.solitary_wave_speed(STEEL, 0.026, 100.0)
    np.testing.assert_allclose(p.speed, v, rtol=1e-14)
    np.testing.assert_allclose(p.duration, th.pulse_duration(0.026, v), rtol=1e-14)
    np.testing.assert_allclose(p.time_of_flight, np.arange(1, 21) * 0.026 / v, rtol=1e-13)
    np.testing.assert_array_equal(p.bead, np.arange(1, 21))


def test_predict_chain_q0_on_tapered_chain_keeps_force_and_speed():
    # q = 0 everywhere: the "restitution only" prediction ignores the tapering (Fig. 5b dashed)
    phi = np.asarray(th.PAPER_CHAINS["chain2"]) * 1e-3
    p = th.predict_chain(phi, STEEL, 100.0, eps=1.0, q=0.0)
    np.testing.assert_allclose(p.peak_force, 100.0, rtol=1e-15)
    np.testing.assert_allclose(p.speed, p.speed[0], rtol=1e-15)


def test_predict_chain_uniform_time_of_flight_matches_closed_form():
    phi0, eps, T0 = 0.026, 0.985, 2e-4
    p = th.predict_chain(np.full(16, phi0), STEEL, 150.0, eps=eps, T0=T0)
    n = np.arange(1, 17)
    expected = th.time_of_flight_uniform(n, phi0, p.speed[0], T0, eps)
    np.testing.assert_allclose(p.time_of_flight, expected, rtol=1e-13)
    np.testing.assert_allclose(p.peak_force, 150.0 * eps ** (1.2 * (n - 1)), rtol=1e-13)


def test_predict_chain_local_q_equals_eq5_at_every_bead():
    # With the local tapering factor, eq. 8 ratios reproduce eq. 5 evaluated with F_m,n and phi_n
    phi = np.asarray(th.PAPER_CHAINS["chain1"]) * 1e-3
    p = th.predict_chain(phi, STEEL, 120.0, eps=0.985)
    np.testing.assert_allclose(p.speed, th.solitary_wave_speed(STEEL, phi, p.peak_force), rtol=1e-12)
    np.testing.assert_allclose(p.bead_velocity, th.peak_bead_velocity(STEEL, phi, p.peak_force), rtol=1e-12)
    np.testing.assert_allclose(p.tapering[17], 1 - 23 / 24, rtol=1e-12)
    # the front pulse weakens and accelerates in the tapered part (paper Figs. 5b, 6c)
    assert np.all(np.diff(p.peak_force[16:]) < 0) and np.all(np.diff(p.speed[16:]) > 0)
    np.testing.assert_allclose(np.diff(p.time_of_flight), phi[1:] / p.speed[1:], rtol=1e-12)


def test_predict_chain_constant_q():
    phi = np.asarray(th.PAPER_CHAINS["chain1"]) * 1e-3
    p = th.predict_chain(phi, STEEL, 100.0, eps=0.985, q=0.056)
    r = th.ballistic_ratios(0.056, 0.985)
    assert p.speed[20] / p.speed[19] == pytest.approx(r.speed, rel=1e-13)
    assert p.peak_force[20] / p.peak_force[19] == pytest.approx(r.force, rel=1e-13)
    assert p.speed[10] / p.speed[9] == pytest.approx(0.985**0.2, rel=1e-13)
    assert np.all(p.tapering[:16] == 0) and np.all(p.tapering[16:] == 0.056)


def test_time_of_flight_uniform_limit_eps_1():
    n = np.arange(0, 10)
    np.testing.assert_allclose(th.time_of_flight_uniform(n, 0.02, 400.0, 1e-4, 1.0),
                               1e-4 + n * 0.02 / 400.0, rtol=1e-15)
    # continuity of the closed form as eps -> 1
    near = th.time_of_flight_uniform(n, 0.02, 400.0, 1e-4, 1 - 1e-9)
    np.testing.assert_allclose(near, 1e-4 + n * 0.02 / 400.0, rtol=1e-8)
    # dissipation slows the wave down: later arrival
    assert th.time_of_flight_uniform(9, 0.02, 400.0, 0.0, 0.985) > 9 * 0.02 / 400.0
