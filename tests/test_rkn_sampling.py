"""The elastic ``"rkn4"`` run's samples, evaluated a step's samples at a time
(``rkn_kernels.SAMPLE_BLOCK``): every sample is the same whatever is recorded beside it and however
many samples a step holds, and the largest contact forces are the maxima of the samples."""

from __future__ import annotations

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.integrate.drivers import rkn_kernels as rk
from hertzchain.integrate.drivers.rkn import run_rkn


@pytest.fixture(scope="module")
def chain1():
    return hc.Model(hc.paper_chain("chain1"), hc.Striker(8e-3, 0.5), hc.Wall("flat")).system()


def test_max_force_is_the_maximum_of_the_samples(chain1):
    """Every contact recorded: each contact's largest force is its largest sample (or the start's)."""
    r = run_rkn(chain1, 2.5e-3, 1e-7)
    assert np.array_equal(r.max_force, r.contact_force.max(axis=0))
    assert r.max_force[0] > 0 and r.max_force[-1] > 0  # the pulse reached the wall


def test_recorded_subset_is_the_full_records_columns(chain1):
    """Recording a few contacts, in any order, gives the full record's columns bit for bit, the
    same maxima of every contact and the same run (the samples do not steer the step)."""
    full = run_rkn(chain1, 1.5e-3, 1e-7)
    pick = np.array([30, 3, 0, 17])
    sub = run_rkn(chain1, 1.5e-3, 1e-7, contacts=pick)
    assert np.array_equal(sub.contact_force, full.contact_force[:, pick])
    assert np.array_equal(sub.max_force, full.max_force)
    assert np.array_equal(sub.kinetic_energy, full.kinetic_energy)
    assert (sub.n_steps, sub.peak_wall_force) == (full.n_steps, full.peak_wall_force)


def test_steps_holding_more_samples_than_a_block(chain1):
    """Steps holding many more samples than SAMPLE_BLOCK (a 1 ns record of a ~1 us step) give the
    coarse record's samples at its times (to rounding of the sample times) and the same maxima."""
    coarse = run_rkn(chain1, 2e-4, 1e-7)
    fine = run_rkn(chain1, 2e-4, 1e-9)
    assert coarse.dt_max > 2 * rk.SAMPLE_BLOCK * 1e-9  # the blocks are exercised
    np.testing.assert_allclose(fine.contact_force[::100], coarse.contact_force, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fine.kinetic_energy[::100], coarse.kinetic_energy, rtol=1e-12, atol=0)
    assert np.all(fine.max_force >= coarse.max_force)  # the finer record samples more of each pulse
    np.testing.assert_allclose(fine.max_force, coarse.max_force, rtol=1e-3)


def test_model_text_is_built_once_and_follows_the_model():
    """The result's ``model`` attribute is the model's description, cached per model: a changed
    model (dataclasses.replace) describes itself anew."""
    import dataclasses
    import json
    import warnings

    model = hc.Model(hc.paper_chain("chain1"), hc.Striker(8e-3, 0.2), hc.Wall("flat"))
    assert model.describe_text() == json.dumps(model.describe())
    assert model.describe_text() is model.describe_text()
    other = dataclasses.replace(model, precompression=2.0)
    assert json.loads(other.describe_text())["precompression"] == 2.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ds = hc.simulate(other, 1e-4)
    assert ds.attrs["model"] == json.dumps(other.describe())


@pytest.mark.filterwarnings("ignore::hertzchain.ElasticLimitWarning")
@pytest.mark.parametrize("law", [hc.HuntCrossley(0.8), hc.HuntCrossley(0.1), hc.Elastoplastic(), hc.Dashpot(gamma=8.0)],
                         ids=["hunt_crossley", "hunt_crossley_clipped", "elastoplastic", "dashpot"])
def test_law_kernels_fitted_samples_are_the_law_on_the_path(law):
    """The dissipative and state kernels sample the law at each contact's interpolated path; where
    a step holds FIT_SAMPLES samples or more, a contact far from its opening takes them from a
    degree-5 fit of its force over the step (rkn_samples). The same run (the samples do not steer
    the step) recorded every 100 ns (~20 samples a step: fitted) and every 1 us (~2 a step: the law
    at every sample) agrees at the common times within the fit's documented error, and each
    contact's largest force is its largest sample. Hunt-Crossley at e = 0.1 is strongly damped:
    its contacts clip (the damping pulls the force to 0) while still overlapped, and its steps
    around the many events are short (its longest steps still fit)."""
    from hertzchain.integrate.drivers import rkn_samples

    model = hc.Model(hc.paper_chain("chain1"), hc.Striker(8e-3, 0.5), hc.Wall("flat"), law=law)
    fine = hc.simulate(model, 2.5e-3, hc.Probes(sample_interval=1e-7, contacts=None))
    coarse = hc.simulate(model, 2.5e-3, hc.Probes(sample_interval=1e-6, contacts=None))
    assert fine.attrs["integrator_used"] == coarse.attrs["integrator_used"] == "rkn4"
    assert fine.attrs["n_steps"] == coarse.attrs["n_steps"]
    assert fine.attrs["dt_max"] > 2 * rkn_samples.FIT_SAMPLES * 1e-7  # the fine record's long steps fit
    assert coarse.attrs["dt_max"] < rkn_samples.FIT_SAMPLES * 1e-6  # the coarse one's do not
    f, fc = fine.contact_force.values[::10], coarse.contact_force.values
    peak = fc.max(axis=0)
    assert peak.min() > 0.1  # the pulse crossed every contact
    # each contact within 1e-9 of its own largest force (near its openings too: a fit there, not
    # clear of the opening by FIT_CLEARANCE steps, errs by ~1e-8 of it and ~1e-4 of the force),
    # and within 1e-8 of the force itself where that exceeds 1e-3 of the contact's largest
    assert np.all(np.abs(f - fc).max(axis=0) <= 1e-9 * peak)
    big = fc > 1e-3 * peak
    assert np.all(np.abs(f - fc)[big] <= 1e-8 * fc[big])
    np.testing.assert_allclose(fine.kinetic_energy.values[::10], coarse.kinetic_energy.values, rtol=1e-12, atol=0)
    assert np.array_equal(fine.max_contact_force.values, np.maximum(fine.contact_force.values.max(axis=0),
                                                                    fine.contact_force.values[0]))
