"""Model building: numbering, masses, Hertz constants, builders and the paper's chains."""

from __future__ import annotations

import math

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.chain import TABLE_I_MM, Chain
from hertzchain.errors import ConfigError


def test_masses_and_hertz_constants_follow_design():
    steel = hc.get_material("AISI52100")
    chain = hc.Chain.from_diameters([26e-3, 20e-3])
    assert chain.masses[0] == pytest.approx(7780 * math.pi * 0.026**3 / 6)
    model = hc.Model(chain, hc.Striker(8e-3, 0.1))
    s = model.system()
    theta = 3 * (1 - 0.3**2) / (4 * 203e9)
    # contact 0 striker-bead 1, contact 1 bead 1-bead 2, contact 2 bead 2-wall (flat: 1/R' = 0)
    assert s.kappa[0] == pytest.approx(1 / (2 * theta * math.sqrt(1 / 4e-3 + 1 / 13e-3)))
    assert s.kappa[1] == pytest.approx(1 / (2 * theta * math.sqrt(1 / 13e-3 + 1 / 10e-3)))
    assert s.kappa[2] == pytest.approx(1 / (2 * theta * math.sqrt(1 / 10e-3)))
    assert steel.theta == pytest.approx(theta)
    # F = kappa delta^1.5 is the same as (4/3) E* sqrt(R*) delta^1.5
    e_star = 203e9 / (2 * (1 - 0.09))
    assert s.kappa[1] == pytest.approx(4 / 3 * e_star * math.sqrt(1 / (1 / 13e-3 + 1 / 10e-3)))


def test_free_end_has_no_wall_contact():
    model = hc.Model(hc.Chain.uniform(3, 1e-2), hc.Striker(1e-2, 0.1), hc.Wall("none"))
    s = model.system()
    assert s.kappa[-1] == 0 and s.n_contacts == 3
    ds = hc.simulate(model, 1e-4)
    assert list(ds.contact.values) == [0, 1, 2] and "wall_force" not in ds


def test_wall_of_another_material():
    chain = hc.Chain.uniform(2, 1e-2)
    k_steel = hc.Model(chain, wall=hc.Wall("flat")).system().kappa[-1]
    k_brass = hc.Model(chain, wall=hc.Wall("flat", "brass")).system().kappa[-1]
    assert k_brass < k_steel


def test_table_i_chains():
    c1, c2 = hc.paper_chain("chain1"), hc.paper_chain("chain2")
    assert (c1.n_beads, c2.n_beads) == (30, 28)
    assert c1.diameters[16] == pytest.approx(24e-3) and c2.diameters[-1] == pytest.approx(9e-3)
    assert len(TABLE_I_MM["chain1"]) == 30


def test_exponential_taper_builder():
    chain = hc.Chain.uniform(16, 26e-3).append_taper(14, 0.056)
    assert chain.n_beads == 30
    ratios = chain.diameters[16:] / chain.diameters[15:-1]
    assert np.allclose(ratios, 0.944)


def test_substitution_truncation_offsets():
    chain = hc.paper_chain("chain1").truncated(24).substitute(19, diameter=23e-3)
    assert chain.n_beads == 24 and chain.diameters[18] == pytest.approx(23e-3)
    off = chain.with_offsets({22: 1e-3})
    assert off.offsets[21] == 1e-3 and not off.is_aligned


@pytest.mark.parametrize("bad", [[26e-3, -1e-3], [26e-3, float("nan")], [[26e-3]]])  # [] is the zero-bead chain
def test_bad_diameters_rejected(bad):
    with pytest.raises(hc.ConfigError, match="chain.diameters"):
        hc.Chain.from_diameters(bad)


def test_precompression_is_static_equilibrium():
    # With a static force F0 and no striker speed to speak of, nothing moves.
    model = hc.Model(hc.Chain.uniform(5, 26e-3), hc.Striker(8e-3, 1e-9), precompression=10.0)
    ds = hc.simulate(model, 2e-4)
    chain_forces = ds.contact_force.sel(contact=slice(1, 5)).values
    assert np.allclose(chain_forces, 10.0, rtol=1e-6)
    e = (ds.kinetic_energy + ds.potential_energy).values
    assert np.abs(e - e[0]).max() < 1e-9 * abs(e[0])


@pytest.mark.parametrize("bad, index", [([0.01, float("nan")], 1), ([-1.0, 0.01], 0), ([0.01, 0.02, float("inf")], 2)])
def test_bad_diameters_are_named_by_index(bad, index):
    """The fast check of Chain (min > 0, max finite) falls back to the one that names the bead."""
    with pytest.raises(ConfigError) as e:
        Chain(np.array(bad))
    assert e.value.field == f"chain.diameters[{index}]" and f"bead {index + 1}" in str(e.value)


def test_aligned_chains_stay_aligned_through_concat_and_keep_offsets_otherwise():
    plain = Chain.uniform(3, 10e-3).concat(Chain.uniform(2, 8e-3))
    assert plain.offsets.shape == (5,) and not plain.offsets.any() and not plain.offsets.flags.writeable
    bent = Chain.uniform(3, 10e-3).with_offsets({2: 1e-3}).concat(Chain.uniform(2, 8e-3))
    np.testing.assert_array_equal(bent.offsets, [0.0, 1e-3, 0.0, 0.0, 0.0])
