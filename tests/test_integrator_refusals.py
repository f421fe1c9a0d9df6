"""Integrator refusals suggest only what runs: the check that refuses a model is the one that
lists the alternatives (an ``rkn4`` refusal of an elastic-plastic model once suggested
``dop853``, which refused it in turn)."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.integrate.drivers.refusals import INTEGRATORS, accepted_integrators

CHAIN = hc.Chain.uniform(4, 10e-3)
MODELS = {
    "elastoplastic": hc.Model(CHAIN, hc.Striker(8e-3, 1.0), hc.Wall(), hc.Elastoplastic()),
    "viscoelastic": hc.Model(CHAIN, hc.Striker(8e-3, 0.2), law=hc.Viscoelastic(A=1e-6)),
    "offset": hc.Model(hc.Chain.from_diameters(np.full(4, 10e-3), offsets=np.array([0, 1e-4, 0, 0])),
                       hc.Striker(8e-3, 0.2)),
    "body": hc.Model(CHAIN, hc.Striker(8e-3, 0.2), hc.Wall("body", mass=0.5, stiffness=1e6)),
}


def _run(model, integrator):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return hc.simulate(model, 5e-5, hc.Probes(1e-6), integrator=integrator)


@pytest.mark.parametrize("name", list(MODELS))
def test_a_refusal_suggests_exactly_the_integrators_that_run(name):
    model = MODELS[name]
    accepted = accepted_integrators(model.system())
    assert accepted[0] == "verlet"
    for integrator in INTEGRATORS:
        if integrator in accepted:
            assert _run(model, integrator).sizes["time"] == 51  # it runs
            continue
        with pytest.raises(hc.ConfigError, match="run.integrator") as refused:
            _run(model, integrator)
        suggested = re.findall(r"'(\w+)'", str(refused.value).split("use integrator")[1])
        assert suggested == ["auto"] + [i for i in accepted if i != integrator]  # 'auto': the default
        for other in suggested:  # every suggestion runs the model ('auto' included)
            assert _run(model, other).sizes["time"] == 51


def test_elastoplastic_dop853_refusal_suggests_verlet_and_rkn4():
    with pytest.raises(hc.ConfigError) as refused:
        _run(MODELS["elastoplastic"], "dop853")
    assert str(refused.value).endswith("use integrator 'auto' (the default) or 'verlet' or 'rkn4'")
    with pytest.raises(hc.ConfigError, match="protected body"):
        _run(MODELS["body"], "rkn4")
    assert accepted_integrators(MODELS["viscoelastic"].system()) == ["verlet", "rkn4", "dop853", "rk45"]
