"""Beads that are not plain spheres: cylinders (elliptical Hertz contact), given masses and
mass-in-mass beads (an internal mass on a spring), with their energies and their band gap."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq

import hertzchain as hc
from hertzchain.elements import Element, Face, contact_constants, elliptic_hertz, relative_curvatures
from hertzchain.integrate.drivers.reference import run_reference
from hertzchain.integrate.drivers.verlet import run_verlet

STEEL = hc.get_material("AISI52100")
E_STAR = STEEL.young / (2 * (1 - STEEL.poisson ** 2))


def _boussinesq(a: float, b: float, x0: float, y0: float) -> float:
    """Surface deflection at (x0, y0) under the Hertz pressure sqrt(1 - x^2/a^2 - y^2/b^2) (p0 = 1,
    E* = 1): (1 / pi) times the integral of p / r, in polar coordinates around the point, the
    radial integral of the square root in closed form, the angle by quadrature."""
    alpha = 1 - x0 ** 2 / a ** 2 - y0 ** 2 / b ** 2

    def radial(phi: float) -> float:
        c, s = math.cos(phi), math.sin(phi)
        gamma = c * c / a ** 2 + s * s / b ** 2
        beta = x0 * c / a ** 2 + y0 * s / b ** 2
        d2 = (alpha * gamma + beta * beta) / gamma ** 2
        d, t0 = math.sqrt(d2), beta / gamma
        return math.sqrt(gamma) / 2 * (d2 * math.pi / 2 - t0 * math.sqrt(max(d2 - t0 * t0, 0.0)) - d2 * math.asin(t0 / d))

    return quad(radial, 0, 2 * math.pi, epsabs=1e-14, epsrel=1e-13, limit=400)[0] / math.pi


@pytest.mark.parametrize("b", [1.0, 0.6, 0.25])
def test_elliptical_hertz_constant_against_boussinesq(b):
    """The elliptical Hertz constant of hertzchain.elements against the elastic half-space itself:
    the deflection of Hertz's elliptical pressure (Boussinesq's 1/r kernel, integrated numerically)
    is delta - A x^2 - B y^2 inside the ellipse; with its delta, A, B and the load
    P = (2/3) pi a b p0, kappa = P / delta^(3/2) must be E* times the shape factor of (A, B)."""
    a = 1.0
    delta = _boussinesq(a, b, 0.0, 0.0)
    a_curv = (delta - _boussinesq(a, b, 0.5 * a, 0.0)) / (0.25 * a * a)
    b_curv = (delta - _boussinesq(a, b, 0.0, 0.5 * b)) / (0.25 * b * b)
    # the deflection is quadratic: another point gives the same curvatures
    assert delta - _boussinesq(a, b, 0.3 * a, 0.4 * b) == pytest.approx(a_curv * 0.09 + b_curv * 0.16 * b * b, rel=1e-9)
    load = 2 / 3 * math.pi * a * b
    c, p = elliptic_hertz(min(a_curv, b_curv), max(a_curv, b_curv))
    assert load / delta ** 1.5 == pytest.approx(c, rel=1e-9)
    assert load / (math.pi * a * b) == pytest.approx(p * c * math.sqrt(delta), rel=1e-9)  # mean pressure


def test_contact_geometries():
    r = 10e-3
    sphere = Face(1 / r, 1 / r, 0.0, STEEL, "sphere")
    cyl = Face(0.0, 1 / r, 0.0, STEEL, "cylinder")
    flat = Face(0.0, 0.0, 0.0, STEEL, "flat")
    # a sphere on a flat, two spheres: the circular Hertz constant (paper eq. 1)
    assert contact_constants(sphere, flat, "x")[0] == pytest.approx(hc.hertz_constant(r, None, STEEL, STEEL), rel=1e-12)
    assert contact_constants(sphere, sphere, "x")[0] == pytest.approx(hc.hertz_constant(r, r, STEEL, STEEL), rel=1e-12)
    # and its elastic limit the paper's (Sec. II)
    assert contact_constants(sphere, sphere, "x")[1] == pytest.approx(hc.yield_force(r, r, STEEL, STEEL)[0], rel=1e-9)
    # a sphere on a crossed cylinder of the same radius: curvature sums 1/r along the axis, 2/r
    # across it, so B/A = 1 + R1/R2 = 2
    a_c, b_c = relative_curvatures(sphere, cyl)
    assert (a_c, b_c) == pytest.approx((0.5 / r, 1.0 / r))
    # two equal cylinders crossed at right angles meet like a sphere on a flat
    crossed = Face(0.0, 1 / r, 90.0, STEEL, "other cylinder")
    assert contact_constants(cyl, crossed, "x")[0] == pytest.approx(contact_constants(sphere, flat, "x")[0], rel=1e-12)
    # the elliptical contact lies between the circular ones of its two radii
    k = contact_constants(sphere, cyl, "x")[0]
    assert hc.hertz_constant(r, r, STEEL, STEEL) < k < hc.hertz_constant(r, None, STEEL, STEEL)
    with pytest.raises(hc.ConfigError, match="line"):
        contact_constants(cyl, cyl, "chain.elements")
    with pytest.raises(hc.ConfigError, match="flat on flat"):
        contact_constants(flat, flat, "chain.elements")


def test_cylinder_chain_masses_and_constants():
    """A crossed cylinder between spheres: its mass rho pi phi^2 L / 4, its contacts elliptical; an
    aligned one meets its neighbours with its flat ends (sphere on a flat)."""
    d, length = 20e-3, 30e-3
    crossed = Element("rod", "cylinder", "crossed", length)
    aligned = Element("peg", "cylinder", "aligned", length)
    for el in (crossed, aligned):
        chain = hc.Chain(np.full(3, d), "AISI52100", None, (Element(), el, Element()))
        assert chain.masses[1] == pytest.approx(STEEL.density * math.pi * d * d * length / 4)
        s = hc.Model(chain, hc.Striker(8e-3, 0.2)).system()
        expected = contact_constants(Face(2 / d, 2 / d, 0, STEEL, "s"),
                                     Face(0.0, 0.0 if el is aligned else 2 / d, 0, STEEL, "c"), "x")[0]
        assert s.kappa[1] == pytest.approx(expected, rel=1e-12) and s.kappa[2] == pytest.approx(expected, rel=1e-12)
    # a cylinder cannot end on the flat wall (a line contact, a flat on a flat)
    with pytest.raises(hc.ConfigError, match="chain.elements"):
        hc.Model(hc.Chain(np.full(2, d), "AISI52100", None, (Element(), crossed))).system()
    # two crossed cylinders at 90 degrees are a point contact; parallel ones are refused
    turned = Element("rod90", "cylinder", "crossed", length, 90.0)
    chain = hc.Chain(np.full(4, d), "AISI52100", None, (Element(), crossed, turned, Element()))
    assert hc.Model(chain).system().kappa[2] == pytest.approx(hc.hertz_constant(d / 2, None, STEEL, STEEL), rel=1e-12)
    with pytest.raises(hc.ConfigError, match="line"):
        hc.Model(hc.Chain(np.full(4, d), "AISI52100", None, (Element(), crossed, crossed, Element()))).system()


def test_given_mass_and_config_elements():
    cfg = hc.parse_config({
        "chain": {"uniform": {"n": 4, "diameter_mm": 20.0}, "elements": ["sphere", "heavy", "rod", "sphere"]},
        "elements": {"heavy": {"mass": 0.5}, "rod": {"shape": "cylinder", "orientation": "aligned", "length_mm": 25.0}},
    })
    model = hc.build_model(cfg)
    assert model.chain.masses[1] == 0.5
    assert model.chain.masses[2] == pytest.approx(STEEL.density * math.pi * 0.02 ** 2 * 0.025 / 4)
    assert model.describe()["chain"]["elements"][1] == {"name": "heavy", "shape": "sphere", "mass": 0.5}
    with pytest.raises(hc.ConfigError, match=r"chain.elements\[1\]"):
        hc.build_model(hc.parse_config({"chain": {"uniform": {"n": 2, "diameter_mm": 20.0},
                                                  "elements": ["sphere", "nothing"]}}))
    with pytest.raises(hc.ConfigError, match="elements.bad.resonator.mass_fraction"):
        hc.parse_config({"chain": {"uniform": {"n": 2, "diameter_mm": 20.0}},
                         "elements": {"bad": {"resonator": {"mass_fraction": 1.5, "frequency": 1e3}}}})


# ------------------------------------------------------------------ mass-in-mass
def _mim_chain(n: int, fraction: float, frequency: float, d: float = 20e-3) -> hc.Chain:
    return hc.Chain(np.full(n, d), "AISI52100", None, Element("mim", resonator_fraction=fraction,
                                                              resonator_frequency=frequency))


def test_mass_in_mass_energy_and_momentum():
    """Internal masses in every bead of a free chain: kinetic (shells and internal masses) + Hertz
    + internal springs is constant to 1e-6, and the scipy reference integrates the same equations."""
    chain = _mim_chain(6, 0.3, 5000.0)
    model = hc.Model(chain, hc.Striker(20e-3, 0.2), hc.Wall("none"))
    s = model.system()
    m = chain.masses[0]
    assert s.mass[1] == pytest.approx(0.7 * m) and s.res_m[1] == pytest.approx(0.3 * m)
    assert s.res_k[1] == pytest.approx(0.3 * m * (2 * math.pi * 5000.0) ** 2)
    raw = run_verlet(s, 1e-3, 1e-7)
    e = raw.kinetic_energy + raw.potential_energy
    assert np.max(np.abs(e - e[0])) < 1e-6 * e[0]
    ref = run_reference(s, 1e-3, 1e-7, rtol=1e-11)
    peak = raw.contact_force.max()
    assert np.max(np.abs(raw.contact_force - ref.contact_force)) < 1e-5 * peak
    ds = hc.simulate(model, 1e-3, hc.Probes(velocities=True))
    e2 = (ds.kinetic_energy + ds.potential_energy).values
    assert np.max(np.abs(e2 - e2[0])) < 1e-6 * e2[0]
    # the internal masses took part: the shells alone no longer hold the striker's momentum
    p_shells = ds.velocity.values @ s.mass[:7]
    assert np.max(np.abs(p_shells - p_shells[0])) > 1e-3 * p_shells[0]


def _band_edges(m1: float, m2: float, k2: float, k_contact: float) -> tuple[float, float]:
    """Edges [rad/s] of the gap of the linearised mass-in-mass lattice.

    Shell m1 (displacement u_n) between contacts of stiffness K, internal mass m2 (w_n) on a spring
    k2: m1 u_n'' = K (u_{n+1} + u_{n-1} - 2 u_n) + k2 (w_n - u_n), m2 w_n'' = k2 (u_n - w_n). With
    u_n, w_n ~ exp(i (q n - omega t)): W = k2 U / (k2 - m2 omega^2), so
    m1 omega^2 + m2 omega^2 omega_2^2 / (omega_2^2 - omega^2) = 4 K sin^2(q / 2), omega_2^2 = k2 / m2.
    The left side rises with omega on (0, omega_2) and on (omega_2, inf): the acoustic branch tops
    out at q = pi (left side = 4 K), the optical one starts at q = 0 at omega_2 sqrt(1 + m2/m1).
    """
    w2 = math.sqrt(k2 / m2)

    def lhs(w: float) -> float:
        return m1 * w * w + m2 * w * w * w2 * w2 / (w2 * w2 - w * w)

    top = brentq(lambda w: lhs(w) - 4 * k_contact, 1e-6 * w2, w2 * (1 - 1e-12))
    return top, w2 * math.sqrt(1 + m2 / m1)


def test_mass_in_mass_band_gap():
    """The linear limit: a precompressed mass-in-mass chain tapped at 1e-4 m/s (dynamic forces ~1e-4
    of the static 20 N). The force spectrum 35 beads down the chain has no content between the
    analytic band edges (the acoustic branch's top and the optical branch's bottom, linearised
    contact stiffness K = (3/2) kappa^(2/3) F0^(1/3)) and finds both edges within 2 %, where the
    same chain of plain beads of the same mass passes that band."""
    n, f0, fraction, frequency = 40, 20.0, 0.4, 6000.0
    chain = _mim_chain(n, fraction, frequency)
    model = hc.Model(chain, hc.Striker(8e-3, 1e-4), precompression=f0)
    s = model.system()
    m = float(chain.masses[0])
    k_contact = 1.5 * s.kappa[2] ** (2 / 3) * f0 ** (1 / 3)
    top, bottom = (w / (2 * math.pi) for w in _band_edges((1 - fraction) * m, fraction * m, s.res_k[1], k_contact))
    assert 1.3 < bottom / top  # a wide gap, well resolved by 50 Hz bins

    def spectrum(mdl):
        ds = hc.simulate(mdl, 20e-3, hc.Probes(sample_interval=2e-6, contacts=(35,)))
        f = ds.contact_force.sel(contact=35).values
        dyn = f - f[0]
        amp = np.abs(np.fft.rfft(dyn * np.hanning(dyn.size)))
        return np.fft.rfftfreq(dyn.size, 2e-6), amp, float(np.max(np.abs(dyn))) / f0

    freq, amp, ratio = spectrum(model)
    assert ratio < 1e-3  # the linear limit
    passband = amp[(freq > 0.2 * top) & (freq < 0.5 * top)].max()
    gap = (freq > 1.05 * top) & (freq < 0.95 * bottom)
    assert amp[gap].max() < 1e-3 * passband
    present = freq[amp > 1e-2 * passband]
    below, above = present[present < 0.5 * (top + bottom)].max(), present[present > 0.5 * (top + bottom)].min()
    assert below == pytest.approx(top, rel=0.02) and above == pytest.approx(bottom, rel=0.02)
    # plain beads of the same mass: no gap there (their single band reaches 2 sqrt(K / m) / (2 pi))
    plain = hc.Model(hc.Chain(np.full(n, 20e-3), "AISI52100", None, Element("same", mass=m)), hc.Striker(8e-3, 1e-4),
                     precompression=f0)
    freq, amp_plain, _ = spectrum(plain)
    passband_plain = amp_plain[(freq > 0.2 * top) & (freq < 0.5 * top)].max()
    assert amp_plain[gap].max() > 1e-2 * passband_plain
