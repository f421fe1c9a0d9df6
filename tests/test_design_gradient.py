"""The design search's gradient phase: coordinates, a known optimum, resumption, when it applies."""

from __future__ import annotations

import copy
import itertools

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.design import parse_design, run_design
from hertzchain.design.gradient import Coordinates, gradient_support
from hertzchain.runs.batch import simulate_batch

STRIKER = {"diameter_mm": 8.0, "velocity": 0.2}
RUN = {"duration": 1.5e-3, "sample_interval": 1e-6}


def _profile_design(**over) -> dict:
    """4 beads of 26 mm, then 3 free beads in [10, 26] mm, decreasing."""
    d = {"base": {"chain": {"diameters_mm": [26.0] * 7}, "striker": dict(STRIKER), "run": dict(RUN)},
         "design": {"objective": "peak_wall_force",
                    "variables": {"chain.diameters_mm[4:7]": {"low": 10.0, "high": 26.0, "monotone": True}},
                    "budget": 400, "seed": 2}}
    d["design"].update(over)
    return d


def test_coordinates_map_the_box_onto_monotone_profiles_and_carry_the_gradient():
    space = parse_design(_profile_design()).space
    c = Coordinates(space)
    rng = np.random.default_rng(0)
    z = rng.random(3)
    x = c.x_of(z)
    assert np.all(np.diff(x) <= 0) and np.all((0 <= x) & (x <= 1))  # every box point: a decreasing profile
    assert np.allclose(c.z_of(x), z) and np.allclose(c.x_of(c.z_of(c.sort(z))), c.sort(z))
    # chain rule through the cumulative products, against differences of J(x(z)) = w . x + (x_1 x_3)
    w = rng.normal(size=3)

    def J(zz):
        xx = c.x_of(zz)
        return w @ xx + xx[0] * xx[2]

    gx = w + np.array([x[2], 0.0, x[0]])
    gz = c.gradient(z, gx)
    h = 1e-7
    fd = np.array([(J(z + h * e) - J(z - h * e)) / (2 * h) for e in np.eye(3)])
    assert np.allclose(gz, fd, rtol=1e-6, atol=1e-9)


def test_gradient_search_beats_a_grid_of_every_monotone_profile(tmp_path):
    """The continuous optimum is at least as good as the best point of a grid of the same box
    (8 sizes per bead, every decreasing triple: 120 chains in one batched call, at full accuracy)."""
    res = run_design(parse_design(_profile_design()), tmp_path / "d")
    phases = {r["phase"] for r in res.history}
    assert "gradient" in phases and res.best["feasible"]
    sizes = np.linspace(10.0, 26.0, 8)
    triples = [t for t in itertools.product(sizes, repeat=3) if t[0] >= t[1] >= t[2]]
    models = [hc.Model(hc.Chain.from_diameters(np.array([26.0] * 4 + list(t)) * 1e-3), hc.Striker(8e-3, 0.2))
              for t in triples]
    ds = simulate_batch(models, RUN["duration"], hc.Probes(sample_interval=RUN["sample_interval"], contacts=()))
    grid_best = float(ds["peak_wall_force"].values.min())
    assert res.best["objective"] <= grid_best * (1 + 1e-4)
    # the reported value is the full-accuracy run of the best profile
    d = res.best["variables"]["chain.diameters_mm[4:7]"]
    assert all(a >= b for a, b in zip(d, d[1:]))
    check = hc.run_config(res.best["config"]).attrs["peak_wall_force"]
    assert check == pytest.approx(res.best["objective"], rel=1e-12)


def test_gradient_phase_resumes_to_the_same_result(tmp_path):
    ref = run_design(parse_design(_profile_design(budget=200)), tmp_path / "a")
    calls = []

    def killer(done, total):
        calls.append(done)
        if len(calls) == 3:  # after the initial sample and the first local search
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_design(parse_design(_profile_design(budget=200)), tmp_path / "b", progress=killer, checkpoint_interval=0)
    resumed = run_design(parse_design(_profile_design(budget=200)), tmp_path / "b")
    assert resumed.resumed
    assert resumed.best["objective"] == ref.best["objective"]
    assert resumed.n_evaluations == ref.n_evaluations
    assert [r["x"] for r in resumed.history] == [r["x"] for r in ref.history]


@pytest.mark.parametrize("change, reason", [
    ({"variables": {"chain.diameters_mm[4:7]": {"low": 10.0, "high": 26.0, "catalogue": "metric"}}}, "real"),
    ({"constraints": {"min_diameter_mm": 12.0}}, "geometric"),
    ({"robust": {"velocities": [0.2, 0.3]}}, "robust"),
    ({"objective": ["peak_wall_force", "energy_at_wall"]}, "one objective"),
])
def test_designs_the_gradient_phase_does_not_take_keep_the_population_search(tmp_path, change, reason):
    data = _profile_design(budget=60, population=8, **change)
    problem = parse_design(data)
    assert reason in gradient_support(problem)
    res = run_design(problem, tmp_path / "d")
    assert "gradient" not in {r["phase"] for r in res.history}


def test_a_law_the_sensitivity_engine_does_not_know_is_searched_without_gradients():
    data = _profile_design()
    data["base"]["contact"] = {"law": "viscoelastic", "eps": 0.99}
    assert "contact.eps" in gradient_support(parse_design(copy.deepcopy(data)))
