"""Static equilibrium (hertzchain.equilibrium): closed forms under precompression, gravity, a body
on its mount and loads on chosen beads, and the engine really starting from it."""

from __future__ import annotations

import numpy as np
import pytest

import hertzchain as hc


def test_uniform_precompression_overlaps_closed_form():
    """F0 in every contact of the chain: delta = (F0 / kappa)^(2/3); the striker only touches."""
    chain = hc.Chain([10e-3, 12e-3, 10e-3, 8e-3, 10e-3])
    model = hc.Model(chain, precompression=20.0)
    eq = hc.equilibrium(model)
    kappa = model.system().kappa
    assert eq.forces[0] == 0.0 and eq.overlaps[0] == 0.0
    np.testing.assert_allclose(eq.forces[1:], 20.0, rtol=1e-15)
    np.testing.assert_allclose(eq.overlaps[1:], (20.0 / kappa[1:]) ** (2.0 / 3.0), rtol=1e-14)
    # the runs of today start from it (Model.system's own precompression path)
    np.testing.assert_array_equal(model.system().d0, eq.overlaps)
    assert eq.residual < 1e-12 * 20.0
    # displacements: the wall stays, bead N moves by the wall contact's overlap, ...
    assert eq.displacements[-1] == pytest.approx(eq.overlaps[-1], rel=1e-15)
    assert eq.displacements[1] == pytest.approx(eq.overlaps[1:].sum(), rel=1e-14)


def test_gravity_column_each_contact_carries_the_weight_above():
    """A vertical column (bead 1 on top, the striker resting on it): contact j carries
    g (m_s + m_1 + ... + m_j), on a flat and on a protected body whose mount carries it all."""
    chain = hc.Chain([20e-3, 15e-3, 10e-3, 15e-3])
    striker = hc.Striker(8e-3, 0.1)
    g = 9.81
    weights = g * np.concatenate([[striker.mass], chain.masses])
    for wall in (hc.Wall(), hc.Wall("body", mass=0.3, stiffness=1e5)):
        model = hc.Model(chain, striker, wall, gravity=g)
        eq = hc.equilibrium(model)
        np.testing.assert_allclose(eq.forces, np.cumsum(weights), rtol=1e-14)
        kappa = model.system().kappa
        np.testing.assert_allclose(eq.overlaps, (np.cumsum(weights) / kappa) ** (2.0 / 3.0), rtol=1e-14)
        assert eq.residual < 1e-12 * weights.sum()
        if wall.is_body:
            assert eq.mount_deflection == pytest.approx((weights.sum() + 0.3 * g) / 1e5, rel=1e-14)
            assert eq.displacements[-1] == pytest.approx(eq.mount_deflection + eq.overlaps[-1], rel=1e-14)


def test_loads_on_chosen_beads():
    """Loads add to what the contacts beyond them carry; a load pulling beads off is refused."""
    chain = hc.Chain.uniform(5, 10e-3)
    model = hc.Model(chain, precompression=5.0, loads=((2, 3.0), (4, -1.5)))
    eq = hc.equilibrium(model)
    np.testing.assert_allclose(eq.forces, [0.0, 5.0, 8.0, 8.0, 6.5, 6.5], rtol=1e-15)
    assert eq.residual < 1e-12 * 8.0
    with pytest.raises(hc.ConfigError, match="load.forces"):
        hc.equilibrium(hc.Model(chain, precompression=1.0, loads=((3, -2.0),)))
    with pytest.raises(hc.ConfigError, match="load.beads"):
        hc.Model(chain, loads=((6, 1.0),))
    with pytest.raises(hc.ConfigError, match="load"):
        hc.Model(chain, hc.Striker(), hc.Wall("none"), loads=((1, 1.0),))


def test_the_engine_starts_at_rest_in_the_equilibrium():
    """Loaded, precompressed and under gravity, a chain hit by the slowest striker allowed (1 um/s)
    keeps its contact forces at the static ones: the equilibrium is the engine's."""
    chain = hc.Chain([10e-3, 12e-3, 10e-3, 12e-3])
    model = hc.Model(chain, hc.Striker(8e-3, 1e-6), gravity=9.81, precompression=2.0, loads=((3, 1.0),))
    eq = hc.equilibrium(model)
    ds = hc.simulate(model, 1e-4, hc.Probes(1e-6))
    f = ds.contact_force.values
    # a 1 um/s striker changes the forces by < 1e-4 N; the static forces are ~2-3 N
    assert np.max(np.abs(f[:, 1:] - eq.forces[1:])) < 1e-3
    assert np.max(np.abs(f[0, :] - eq.forces)) < 1e-12 * eq.forces.max()


def test_driven_chains_static_state():
    """Without a striker, a force drive has no contact 0; a displacement drive's massless driver
    presses bead 1 with the precompression (contact 0 carries F0, like the others)."""
    chain = hc.Chain.uniform(3, 10e-3)
    eq = hc.equilibrium(hc.Model(chain, precompression=4.0, gravity=9.81, drive=hc.Drive(amplitude=0.1)))
    assert eq.forces[0] == 0.0
    np.testing.assert_allclose(eq.forces[1:], 4.0 + 9.81 * np.cumsum(chain.masses), rtol=1e-14)
    shaker = hc.Model(chain, precompression=4.0, drive=hc.Drive(quantity="displacement", amplitude=1e-8))
    eq = hc.equilibrium(shaker)
    np.testing.assert_allclose(eq.forces, 4.0, rtol=1e-15)
    assert eq.residual < 1e-12 * 4.0
