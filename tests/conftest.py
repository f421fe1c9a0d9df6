"""Shared fixtures: small models used across the engine tests."""

from __future__ import annotations

import os

import numpy as np
import pytest
from hypothesis import settings

import hertzchain as hc

# Property tests draw the same examples on every run ("ci", the default), so CI never turns red
# on a draw no one has seen; HYPOTHESIS_PROFILE=explore draws new ones to hunt for bugs.
settings.register_profile("ci", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

#: The core-engine issue's contract chain: 16 beads of 26 mm then 24, 23, 22 mm.
CONTRACT_DIAMETERS_MM = [26.0] * 16 + [24.0, 23.0, 22.0]


@pytest.fixture(scope="session")
def contract_model() -> hc.Model:
    chain = hc.Chain.from_diameters(np.array(CONTRACT_DIAMETERS_MM) * 1e-3)
    return hc.Model(chain, hc.Striker(8e-3, 0.5), hc.Wall("flat"))


@pytest.fixture(scope="session")
def gentle_contract_model() -> hc.Model:
    """The contract chain hit at 0.2 m/s: every contact stays inside its elastic limit."""
    chain = hc.Chain.from_diameters(np.array(CONTRACT_DIAMETERS_MM) * 1e-3)
    return hc.Model(chain, hc.Striker(8e-3, 0.2), hc.Wall("flat"))


def assert_same_run(single, other) -> None:
    """Every array bit for bit (np.array_equal), every attribute but the creation time and why the
    engine was chosen (``engine_choice``: a single run's reason, which a batch member has not)."""
    assert set(single.variables) == set(other.variables)
    for name in single.variables:
        assert np.array_equal(single[name].values, other[name].values), name
    skip = ("created_utc", "engine_choice")
    assert {k: v for k, v in single.attrs.items() if k not in skip} == \
        {k: v for k, v in other.attrs.items() if k not in skip}
