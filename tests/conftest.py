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


def assert_sums_agree(a, b, total: float, n_terms: int) -> None:
    """Two code paths' sums of the same ``n_terms`` per-body terms (an energy [J]) agree to rounding.

    Forces, positions and velocities of two paths that run the same arithmetic are equal bit for
    bit; a *sum* over bodies is not: Numba/LLVM vectorise a reduction for the host CPU (SSE, AVX2,
    AVX-512, NEON lanes), so its order of additions, hence its last bits, depend on the code path
    and the machine. Summing n non-negative terms in any order is exact to (n - 1) u times their
    total (u = 2^-53): two orders differ by at most 2 (n - 1) u ``total``. The bound asserted is
    2 n u ``total`` (``total``: the energy the sum is part of, e.g. the striker's initial kinetic
    energy), a few ulp of the total energy for the chains of the tests.
    """
    a, b = np.asarray(a, float), np.asarray(b, float)
    bound = 2.0 * n_terms * np.finfo(float).eps * total
    worst = float(np.max(np.abs(a - b))) if a.size else 0.0
    assert a.shape == b.shape and worst <= bound, f"sums differ by {worst:.3g} J > {bound:.3g} J"


@pytest.fixture(autouse=True)
def _sigint_handler_kept():
    """Every test leaves Ctrl-C's handling as it found it: SIGINT's handler, and no
    ``hertzchain.interrupts.latched`` block open. Either left behind makes a later sweep in the
    same worker swallow its Ctrl-C (tests/test_sweep.py's test of it failed twice in one session
    in whichever worker ran it), so the test that leaves it fails instead."""
    import signal
    import sys

    before = signal.getsignal(signal.SIGINT)
    yield
    after = signal.getsignal(signal.SIGINT)
    if after is not before:
        signal.signal(signal.SIGINT, before)
        pytest.fail(f"the test left SIGINT's handler changed: {before!r} -> {after!r}")
    interrupts = sys.modules.get("hertzchain.interrupts")
    if interrupts is not None and interrupts._state["depth"] != 0:  # a latched block left open
        depth, interrupts._state["depth"] = interrupts._state["depth"], 0
        pytest.fail(f"the test left hertzchain.interrupts.latched open ({depth} deep)")


@pytest.fixture
def default_sigint():
    """SIGINT with Python's default handler for the test (a process started in the background by a
    shell without job control, ``cmd &``, inherits SIGINT ignored, and ``latched`` then rightly
    leaves it so); the handler it had is put back after."""
    import signal

    before = signal.getsignal(signal.SIGINT)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)
