"""The registry's laws (power, Hunt-Crossley, a user's) on models beyond the paper's kind: striker
faces, gravity, cylinders (the arrays kappa, fext, d0 change, the engines do not), a protected body
and mass-in-mass beads (the extension, written once for every law's force pass:
``core.extension.extended_steps``).

The power law at n = 3/2 without a stiffness of its own is the elastic law under another name: at
the same fixed step its run must give the elastic law's numbers (the same step sequence, the same
arithmetic up to rounding). Hunt-Crossley, dissipative and with state, must balance its energy:
kinetic + stored + dissipated constant, the internal masses and the mount included.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import test_gradients as tg
from test_gradients import BASE, _with

import hertzchain as hc
from hertzchain.elements import Element
from hertzchain.gradients import sensitivity

CYLINDERS = hc.Chain(np.linspace(20e-3, 12e-3, 6), "AISI52100", None,
                     (Element(), Element("rod", "cylinder", "crossed", 25e-3), *(Element(),) * 4))
MASS_IN_MASS = hc.Chain(np.full(5, 10e-3), "AISI52100", None,
                        Element("mim", resonator_fraction=0.3, resonator_frequency=5000.0))
MODELS = {
    "flat striker under gravity": lambda law: hc.Model(hc.Chain.uniform(5, 10e-3),
                                                       hc.Striker(8e-3, 0.2, mass=5e-3, shape="flat"),
                                                       gravity=9.81, law=law),
    "curved striker": lambda law: hc.Model(hc.Chain.uniform(3, 10e-3),
                                           hc.Striker(8e-3, 0.25, radius_of_curvature=20e-3), law=law),
    "cylinder": lambda law: hc.Model(CYLINDERS, hc.Striker(8e-3, 0.2), law=law),
    "protected body": lambda law: hc.Model(hc.Chain.uniform(5, 10e-3), hc.Striker(8e-3, 0.2),
                                           hc.Wall("body", mass=0.05, stiffness=1e6, damping=5.0), law=law),
    "mass-in-mass": lambda law: hc.Model(MASS_IN_MASS, hc.Striker(8e-3, 0.2), law=law),
}
EXTENDED = ("protected body", "mass-in-mass")
SIGNALS = ("wall_force", "kinetic_energy", "potential_energy", "contact_force")


def _run(model, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a short record may end before the pulse arrives
        return hc.simulate(model, 3e-4, **kw)


@pytest.mark.parametrize("name", list(MODELS))
def test_power_law_at_three_halves_is_the_elastic_law_on_every_model(name):
    make = MODELS[name]
    elastic, power = _run(make(hc.Elastic()), integrator="verlet", dt=2e-8), \
        _run(make(hc.PowerLaw(1.5)), integrator="verlet", dt=2e-8)
    assert float(np.abs(elastic.contact_force.values).max()) > 0  # something was struck
    for signal in SIGNALS:
        a, b = elastic[signal].values, power[signal].values
        assert np.max(np.abs(a - b)) <= 1e-12 * np.max(np.abs(a)), signal
    if name == "protected body":
        a, b = elastic.body_displacement.values, power.body_displacement.values
        assert np.max(np.abs(a - b)) <= 1e-12 * np.max(np.abs(a))
    if name not in EXTENDED:  # the default path (rkn4 for these) takes the registry law too
        auto = _run(make(hc.PowerLaw(1.5)))
        assert auto.attrs["integrator_used"] == "rkn4"
        ref = _run(make(hc.Elastic()), integrator="rkn4")
        assert np.max(np.abs(auto.wall_force.values - ref.wall_force.values)) <= 1e-12 * max(
            float(np.abs(ref.wall_force.values).max()), 1e-30)


@pytest.mark.parametrize("name", EXTENDED)
def test_hunt_crossley_balances_its_energy_with_the_extension(name):
    """Kinetic (shells, internal masses, the body) + stored (contacts, mount, internal springs) +
    dissipated (the law's and the mount's dashpot) stays constant: the extension's forces, energies
    and powers enter the generated run where the hand-written laws' do."""
    ds = _run(MODELS[name](hc.HuntCrossley(0.8)))
    assert ds.attrs["integrator_used"] == "verlet"  # rkn4 takes chains of beads without the extension
    total = ds.kinetic_energy.values + ds.potential_energy.values + ds.dissipated_energy.values
    assert np.ptp(total) < 1e-6 * total[0]
    assert float(ds.dissipated_energy[-1]) > 0.05 * total[0]


def test_a_batch_runs_registry_laws_with_the_extension_as_single_runs_do():
    models = [MODELS[name](hc.PowerLaw(2.0, 1e9)) for name in EXTENDED]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        batch = hc.simulate_batch(models, duration=3e-4, integrator="verlet")
    for m, model in enumerate(models):
        single = _run(model, integrator="verlet")
        np.testing.assert_array_equal(batch.isel(member=m).wall_force.values, single.wall_force.values)


def test_gradients_of_a_registry_law_with_a_flat_striker_match_differences():
    cfg = _with(BASE, striker={"shape": "flat", "mass": 0.004}, contact={"law": "power", "exponent": 1.8,
                                                                          "stiffness": 6e11}, run={"duration": 1.2e-3})
    paths = ["striker.velocity", "striker.mass", "chain.diameters_mm[0]", "contact.exponent"]
    tg.assert_matches(sensitivity(cfg, paths), cfg, paths, tol=1e-5)
