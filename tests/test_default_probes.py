"""Default probes sized to the run (issue 37): every contact of a short chain, the wall, the
sensors and a few contacts spread along a long one, at most DEFAULT_MAX_SAMPLES samples from
simulate() without probes, so that the automatic duration of a 1e4-1e6-bead chain fits in memory."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.checks import estimate_resources
from hertzchain.config import build_probes, parse_config
from hertzchain.probes import AUTO_ALL_CONTACTS, AUTO_SAMPLED_CONTACTS, DEFAULT_MAX_SAMPLES, default_probes
from hertzchain.runs.simulation import auto_duration


def test_auto_contacts_every_contact_of_a_short_chain():
    n = AUTO_ALL_CONTACTS - 1  # with the wall: AUTO_ALL_CONTACTS contacts
    assert np.array_equal(hc.Probes().recorded_contacts(n, True), np.arange(n + 1))
    assert np.array_equal(hc.Probes().recorded_contacts(30, False), np.arange(30))


def test_auto_contacts_of_a_long_chain_are_the_wall_sensors_and_a_few_spread():
    n = 10_000
    rec = hc.Probes(sensors=(5000, 7777)).recorded_contacts(n, True)
    assert rec[0] == 0 and rec[-1] == n  # the striker's contact and the wall's
    assert {4999, 5000, 7776, 7777} <= set(rec.tolist())  # each sensor's two contacts
    assert rec.size <= AUTO_SAMPLED_CONTACTS + 4 and np.all(np.diff(rec) > 0)
    spread = np.diff(hc.Probes().recorded_contacts(n, True))
    assert spread.max() - spread.min() <= 1  # evenly spread
    # every contact on request
    assert hc.Probes(contacts=None).recorded_contacts(n, True).size == n + 1
    with pytest.raises(hc.ConfigError, match="probes.contacts"):
        hc.Probes(contacts="some")


def test_config_contacts_auto_all_and_listed():
    base = {"chain": {"diameters_mm": [20.0] * 3}}
    assert build_probes(parse_config(base)).contacts == "auto"
    assert build_probes(parse_config({**base, "probes": {"contacts": "all"}})).contacts is None
    assert build_probes(parse_config({**base, "probes": {"contacts": [1, 2]}})).contacts == (1, 2)


def test_default_probes_cap_the_samples():
    assert default_probes(3e-3).sample_interval == 1e-7  # the paper's runs: 100 ns as before
    assert default_probes(1.0).sample_interval == pytest.approx(1.0 / DEFAULT_MAX_SAMPLES)


@pytest.mark.parametrize("n", [10**4, 10**5, 10**6])
def test_automatic_duration_of_long_chains_fits_in_memory_with_the_default_probes(n):
    model = hc.Model(hc.Chain.uniform(n, 5e-3), hc.Striker(8e-3, 0.2))
    duration = auto_duration(model)
    est = estimate_resources(model.system(), duration, default_probes(duration), integrator="rkn4")
    assert est.samples <= DEFAULT_MAX_SAMPLES + 1
    assert est.memory_bytes < 100e6  # ~43 MB; every contact every 100 ns was 160 GB at 1e4 beads


def test_long_chain_run_records_the_auto_contacts():
    model = hc.Model(hc.Chain.uniform(400, 5e-3), hc.Striker(8e-3, 0.2))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", hc.PulseNotReachedWarning)
        ds = hc.simulate(model, 2e-5)
        full = hc.simulate(model, 2e-5, hc.Probes(contacts=None))
    contacts = ds["contact"].values
    assert contacts[0] == 0 and contacts[-1] == 400 and contacts.size == AUTO_SAMPLED_CONTACTS
    assert full.sizes["contact"] == 401
    # the sampled contacts' forces are those of the full record (the same run)
    assert np.array_equal(ds.contact_force.values, full.contact_force.sel(contact=contacts).values)
