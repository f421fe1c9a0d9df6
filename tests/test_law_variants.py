"""The reproduction's contact-law variants, shared between the caller and a forked process
(hertzchain.paper.fidelity.LawVariants): every variant once, the run's own law first, only plain
numbers back from the fork, a failure there named, and nothing left running."""

from __future__ import annotations

import os

import pytest

from hertzchain.errors import ConfigError
from hertzchain.paper import fidelity
from hertzchain.paper.protocol import Settings


@pytest.fixture
def fake_runs(monkeypatch):
    """Variant runs replaced by their law's name and the process that ran it (a fork inherits the
    patch); the run's own studies by a marker."""
    monkeypatch.setattr(fidelity, "_variant_numbers", lambda settings, law, progress=None: {"pid": os.getpid(), "law": law})
    monkeypatch.setattr(fidelity, "law_numbers", lambda variants, settings: {law: {"own": True} for law in variants})


def test_every_variant_once_in_order_and_the_forks_runs_ticked(fake_runs):
    ticks = []
    variants = fidelity.LawVariants(Settings())
    out = variants.finish({}, ticks.append)
    assert list(out) == ["dashpot_scaled", "elastic", "viscoelastic", "viscoelastic_scaled", "viscoelastic_sized"]
    assert out["dashpot_scaled"] == {"own": True}
    assert all(out[law]["law"] == law for law in variants.laws)
    forked = [law for law in variants.laws if out[law]["pid"] != os.getpid()]
    per_law = sum(fidelity.PAPER[c]["n_beads"] - fidelity.N0 + 1 for c in ("chain1", "chain2"))
    assert len(ticks) == per_law * len(forked)  # the caller's own runs tick in run_chain_study
    assert variants._proc is None


def test_an_elastic_run_compares_every_dissipative_law(fake_runs):
    out = fidelity.LawVariants(Settings(elastic=True)).finish({})
    assert list(out)[0] == "elastic" and set(out) == set(fidelity.LAW_VARIANTS)


@pytest.mark.parametrize("error, raised, message", [
    (lambda law: ValueError(f"no {law}"), RuntimeError, "variants' runs failed: ValueError: no elastic"),
    (lambda law: ConfigError("contact.eps", f"{law} cannot give it"), ConfigError, "contact.eps: elastic cannot"),
])
def test_a_failure_in_the_fork_is_raised_by_the_caller(monkeypatch, error, raised, message):
    """A ConfigError in the fork (an eps a law cannot reach) is the caller's ConfigError, naming its
    field as a serial run did (the CLI's exit 2); anything else a RuntimeError naming it."""
    if len(os.sched_getaffinity(0)) < 2:
        pytest.skip("one core: no fork, the variants run in the caller")

    def fail(settings, law, progress=None):
        if os.getpid() != parent:
            raise error(law)
        return {}

    parent = os.getpid()
    monkeypatch.setattr(fidelity, "_variant_numbers", fail)
    monkeypatch.setattr(fidelity, "law_numbers", lambda variants, settings: {law: {} for law in variants})
    variants = fidelity.LawVariants(Settings())
    # let the fork claim its first variant before the caller takes the rest
    while variants._ends[0] == 0 and variants._proc.is_alive():
        pass
    with pytest.raises(raised, match=message):
        variants.finish({})
    assert variants._proc is None


def test_cancel_stops_the_fork(monkeypatch):
    import time

    monkeypatch.setattr(fidelity, "_variant_numbers", lambda settings, law, progress=None: time.sleep(60))
    variants = fidelity.LawVariants(Settings())
    proc = variants._proc
    variants.cancel()
    assert proc is None or not proc.is_alive()
