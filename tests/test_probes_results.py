"""Probes (sensors, contact subsets), the result Dataset and its NetCDF round trip."""

from __future__ import annotations

import json

import numpy as np
import pytest

import hertzchain as hc


@pytest.fixture(scope="module")
def chain1_run():
    model = hc.Model(hc.paper_chain("chain1"), hc.Striker(8e-3, 0.2))
    return model, hc.simulate(model, 2.5e-3, hc.Probes(sensors=(8, 12, 30)))


def test_sensor_reads_mean_of_its_two_contacts(chain1_run):
    _, ds = chain1_run
    for n in (8, 12, 30):  # bead 30 is the last one: its right contact is the wall
        expected = 0.5 * (ds.contact_force.sel(contact=n - 1) + ds.contact_force.sel(contact=n))
        np.testing.assert_array_equal(ds.sensor_force.sel(sensor=n).values, expected.values)
    np.testing.assert_array_equal(ds.wall_force.values, ds.contact_force.sel(contact=30).values)


def test_contact_subset_gives_same_signals(chain1_run):
    model, full = chain1_run
    part = hc.simulate(model, 2.5e-3, hc.Probes(sensors=(12,), contacts=(3, 17)))
    assert list(part.contact.values) == [3, 17]
    np.testing.assert_array_equal(part.contact_force.values, full.contact_force.sel(contact=[3, 17]).values)
    np.testing.assert_array_equal(part.sensor_force.values, full.sensor_force.sel(sensor=[12]).values)
    np.testing.assert_array_equal(part.wall_force.values, full.wall_force.values)


def test_dataset_is_self_describing(chain1_run):
    _, ds = chain1_run
    for name, var in ds.data_vars.items():
        assert var.attrs.get("units") and var.attrs.get("long_name"), name
    assert ds.time.attrs["units"] == "s"
    for key in ("hertzchain_version", "integrator", "dt", "config", "model", "peak_wall_force"):
        assert key in ds.attrs
    model = json.loads(ds.attrs["model"])
    assert model["chain"]["diameters_mm"][-1] == pytest.approx(11.0)
    assert ds.attrs["elastic_limit_exceeded"] == 0


def test_netcdf_round_trip(tmp_path, chain1_run):
    _, ds = chain1_run
    path = hc.save(ds, tmp_path / "sub" / "r.nc")
    back = hc.load(path)
    np.testing.assert_array_equal(back.wall_force.values, ds.wall_force.values)
    assert back.attrs["config"] == ds.attrs["config"]
    assert back.contact_force.attrs["units"] == "N"


def test_elastic_limit_warns_and_is_recorded(contract_model):
    with pytest.warns(hc.ElasticLimitWarning, match="elastic limit"):
        ds = hc.simulate(contract_model, 1e-4)
    assert ds.attrs["elastic_limit_exceeded"] == 1
    assert json.loads(ds.attrs["elastic_limit_contacts"]) == [0]  # the small striker's contact


def test_yield_limit_of_paper_beads():
    f_y, d_y = hc.yield_force(13e-3, 13e-3, "AISI52100", "AISI52100")
    assert f_y == pytest.approx(470, rel=0.02)
    assert d_y == pytest.approx(11e-6, rel=0.06)


def test_bad_probe_numbers():
    model = hc.Model(hc.Chain.uniform(5, 1e-2))
    with pytest.raises(hc.ConfigError, match=r"probes.sensors\[0\]"):
        hc.simulate(model, 1e-4, hc.Probes(sensors=(6,)))
    with pytest.raises(hc.ConfigError, match=r"probes.contacts\[0\]"):
        hc.simulate(model, 1e-4, hc.Probes(contacts=(9,)))


def test_elastic_limit_checks_contacts_that_are_not_stored():
    # Only the wall is stored, but the small striker's contact passes its limit: still caught.
    model = hc.Model(hc.paper_chain("chain1"), hc.Striker(8e-3, 0.5))
    with pytest.warns(hc.ElasticLimitWarning):
        ds = hc.simulate(model, 2e-4, hc.Probes(contacts=(30,)))
    assert list(ds.contact.values) == [30]
    assert ds.max_contact_force.sizes["contact_all"] == 31
    assert json.loads(ds.attrs["elastic_limit_contacts"]) == [0]
