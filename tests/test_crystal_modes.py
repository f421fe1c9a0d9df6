"""Linear analysis of granular crystals: normal modes against a hand-assembled matrix, and the Bloch
band structure against the monatomic, diatomic and mass-in-mass closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest

import hertzchain as hc

F0 = 10.0


def _k(kappa, force):
    """Linearised Hertz stiffness K = (3/2) kappa^(2/3) F^(1/3) [N/m]."""
    return 1.5 * kappa ** (2.0 / 3.0) * force ** (1.0 / 3.0)


def test_modes_of_a_short_chain_against_a_hand_assembled_matrix():
    """Three beads of different sizes pressed by F0 against the wall; a striker that only touches
    is no degree of freedom. K by hand from the contacts' Hertz constants (Johnson's formula)."""
    chain = hc.Chain([10e-3, 14e-3, 8e-3])
    model = hc.Model(chain, precompression=F0)
    mds = hc.modes(model)
    m = chain.masses
    theta = hc.get_material("AISI52100").theta  # 3 (1 - nu^2) / (4 Y), paper eq. 1
    r = chain.radii
    inv_r = [1 / r[0] + 1 / r[1], 1 / r[1] + 1 / r[2], 1 / r[2]]  # the wall is a flat of the same steel
    kap = [1.0 / (2 * theta * math.sqrt(x)) for x in inv_r]
    k1, k2, k3 = (_k(x, F0) for x in kap)
    kmat = np.array([[k1, -k1, 0.0], [-k1, k1 + k2, -k2], [0.0, -k2, k2 + k3]])
    w2 = np.sort(np.linalg.eigvals(np.diag(1.0 / m) @ kmat).real)
    np.testing.assert_allclose(mds.frequencies, np.sqrt(w2) / (2 * math.pi), rtol=1e-10)
    assert list(mds.labels) == ["bead 1", "bead 2", "bead 3"]
    # mass-normalised shapes; effective mass fractions add up to 1
    np.testing.assert_allclose(mds.shapes.T @ np.diag(m) @ mds.shapes, np.eye(3), atol=1e-10)
    assert mds.participation.sum() == pytest.approx(1.0, rel=1e-12)
    np.testing.assert_allclose(mds.matrices.stiffness, kmat, rtol=1e-12)


def test_mass_in_mass_and_body_degrees_of_freedom():
    """A mass-in-mass bead adds its internal mass; a body on a mount adds itself (k to ground)."""
    res = hc.Element("mim", resonator_fraction=0.3, resonator_frequency=2000.0)
    chain = hc.Chain([10e-3, 10e-3], elements=(hc.elements.SPHERE, res))
    model = hc.Model(chain, hc.Striker(), hc.Wall("body", mass=0.05, stiffness=1e6), precompression=F0)
    mds = hc.modes(model)
    assert mds.labels == ["bead 1", "bead 2", "body", "resonator 2"]
    lin = mds.matrices
    m_in = 0.3 * chain.masses[1]
    k_in = m_in * (2 * math.pi * 2000.0) ** 2
    assert lin.mass[3, 3] == pytest.approx(m_in, rel=1e-14)
    assert lin.stiffness[3, 1] == pytest.approx(-k_in, rel=1e-12)
    assert lin.stiffness[2, 2] == pytest.approx(lin.contact_stiffness[2] + 1e6, rel=1e-12)


def test_monatomic_dispersion_and_cut_off():
    cell = hc.Chain.uniform(1, 10e-3)
    ds = hc.dispersion(cell, F0, points=31)
    kappa = hc.Model(cell.concat(cell), precompression=F0).system().kappa[1]
    k, m = _k(kappa, F0), cell.masses[0]
    q = ds.wavenumber.values
    np.testing.assert_allclose(ds.frequency.sel(branch=0).values,
                               2 * np.sqrt(k / m) * np.abs(np.sin(q / 2)) / (2 * math.pi), rtol=1e-10, atol=1e-9)
    assert float(ds.frequency.max()) == pytest.approx(2 * math.sqrt(k / m) / (2 * math.pi), rel=1e-12)
    assert q[0] == 0.0 and q[-1] == pytest.approx(math.pi, rel=1e-15)
    assert ds.attrs["gaps"] == []


def test_diatomic_gap_edges():
    """Steel 10 mm and 6 mm beads alternating: the gap is sqrt(2K/m_heavy)..sqrt(2K/m_light)."""
    cell = hc.Chain([10e-3, 6e-3])
    ds = hc.dispersion(cell, F0, points=41)
    kappa = hc.Model(cell.concat(cell), precompression=F0).system().kappa[1:3]
    assert kappa[0] == pytest.approx(kappa[1], rel=1e-14)  # heavy-light and light-heavy: the same pair
    k = _k(kappa[0], F0)
    mh, ml = cell.masses
    (low, high), = ds.attrs["gaps"]
    assert low == pytest.approx(math.sqrt(2 * k / mh) / (2 * math.pi), rel=1e-10)
    assert high == pytest.approx(math.sqrt(2 * k / ml) / (2 * math.pi), rel=1e-10)
    # optical branch top at q = 0: sqrt(2K (1/m_h + 1/m_l))
    assert float(ds.frequency.sel(branch=1).max()) == pytest.approx(
        math.sqrt(2 * k * (1 / mh + 1 / ml)) / (2 * math.pi), rel=1e-10)


def test_mass_in_mass_gap_edges_closed_form():
    """Shell m1 (= (1 - f) m), internal m2 = f m on k2 = m2 (2 pi f_r)^2, shells joined by K.
    At q = pi: det [[4K + k2 - m1 w^2, -k2], [-k2, k2 - m2 w^2]] = 0; at q = 0 the optical branch
    starts at w^2 = k2 (1/m1 + 1/m2). The gap: the acoustic top (lower root at pi) to the lower of
    the optical branch's ends."""
    f, fr = 0.4, 3000.0
    cell = hc.Chain([10e-3], elements=(hc.Element("mim", resonator_fraction=f, resonator_frequency=fr),))
    ds = hc.dispersion(cell, F0, points=61)
    kappa = hc.Model(cell.concat(cell), precompression=F0).system().kappa[1]
    k = _k(kappa, F0)
    m = cell.masses[0]
    m1, m2 = (1 - f) * m, f * m
    k2 = m2 * (2 * math.pi * fr) ** 2
    # (4K + k2 - m1 x)(k2 - m2 x) - k2^2 = 0, x = w^2
    a, b, c = m1 * m2, -(m1 * k2 + m2 * (4 * k + k2)), 4 * k * k2
    roots = np.sort(np.roots([a, b, c]).real)
    top_acoustic = math.sqrt(roots[0])
    optical_bottom = min(math.sqrt(k2 * (1 / m1 + 1 / m2)), math.sqrt(roots[1]))
    (low, high), = ds.attrs["gaps"]
    assert low == pytest.approx(top_acoustic / (2 * math.pi), rel=1e-9)
    assert high == pytest.approx(optical_bottom / (2 * math.pi), rel=1e-9)
    assert low < fr < high  # the local resonance opens the gap


def test_dispersion_refuses_no_precompression():
    with pytest.raises(hc.ConfigError, match="chain.precompression"):
        hc.dispersion(hc.Chain.uniform(1, 10e-3), 0.0)


def test_a_chain_without_striker():
    """striker=None (a crystal with no impact): no body 0 and no contact 0. Its modes are those of
    the chain whose striker only touches bead 1 (no static force, no degree of freedom); a force
    drive runs as with drive.striker = False (the same arrays, bit for bit; its plots say "no
    striker"); a displacement drive's
    driver is a flat of bead 1's material (the sphere-flat Hertz constant 1 / (2 theta sqrt(1/R)),
    paper eq. 1); a run with nothing to excite the chain is refused naming the striker."""
    chain = hc.Chain([10e-3, 14e-3, 8e-3])
    bare = hc.Model(chain, striker=None, precompression=F0)
    touching = hc.Model(chain, precompression=F0)
    np.testing.assert_array_equal(hc.modes(bare).frequencies, hc.modes(touching).frequencies)
    eq = hc.equilibrium(bare)
    assert eq.forces[0] == 0.0 and eq.overlaps[0] == 0.0
    np.testing.assert_allclose(eq.forces[1:], F0, rtol=1e-12)
    assert bare.describe()["striker"] is None
    drive = hc.Drive(amplitude=0.1, frequency=5000.0, ramp_cycles=2)
    a = hc.simulate(hc.Model(chain, striker=None, law=hc.Dashpot(5.0), precompression=F0, drive=drive), 1e-3,
                    hc.Probes(5e-6))
    b = hc.simulate(hc.Model(chain, law=hc.Dashpot(5.0), precompression=F0, drive=drive), 1e-3, hc.Probes(5e-6))
    np.testing.assert_array_equal(a.contact_force.values, b.contact_force.values)
    from hertzchain.viz.common import result_title

    assert result_title(a) == "3 beads, no striker"
    shaker = hc.Model(chain, striker=None, precompression=F0, drive=hc.Drive(quantity="displacement", amplitude=1e-9))
    theta = hc.get_material("AISI52100").theta
    assert shaker.system().kappa[0] == pytest.approx(1.0 / (2 * theta * math.sqrt(2.0 / 10e-3)), rel=1e-12)
    assert hc.equilibrium(shaker).forces[0] == pytest.approx(F0, rel=1e-12)  # the driver applies F0
    with pytest.raises(hc.ConfigError, match="striker"):
        hc.simulate(bare, 1e-3)
    with pytest.raises(hc.ConfigError, match="drive.striker"):
        hc.Model(chain, striker=None, precompression=F0, drive=hc.Drive(striker=True))


def test_modes_of_a_registry_law():
    """hc.modes linearises any registry law by its own dF/d(delta) at the static overlap: the power
    law F = k delta^2 gives K = 2 k delta0 with delta0 = sqrt(F0 / k) (a hand-assembled matrix);
    with n = 3/2 and no stiffness it is the elastic law's chain (1e-12)."""
    chain = hc.Chain([10e-3, 14e-3, 8e-3])
    k_law = 1e12
    mds = hc.modes(hc.Model(chain, law=hc.PowerLaw(2.0, stiffness=k_law), precompression=F0))
    k = 2.0 * k_law * math.sqrt(F0 / k_law)  # every contact, the wall's included, carries F0
    kmat = np.array([[k, -k, 0.0], [-k, 2 * k, -k], [0.0, -k, 2 * k]])
    w2 = np.sort(np.linalg.eigvals(np.diag(1.0 / chain.masses) @ kmat).real)
    np.testing.assert_allclose(mds.frequencies, np.sqrt(w2) / (2 * math.pi), rtol=1e-10)
    hertz = hc.modes(hc.Model(chain, law=hc.PowerLaw(1.5), precompression=F0)).frequencies
    np.testing.assert_allclose(hertz, hc.modes(hc.Model(chain, precompression=F0)).frequencies, rtol=1e-12)
