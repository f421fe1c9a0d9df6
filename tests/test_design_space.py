"""Design space decoding, objectives with closed forms, robust forms, Pareto fronts and executors."""

from __future__ import annotations

import concurrent.futures as cf

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.design import CATALOGUES, parse_design, run_design
from hertzchain.design.objectives import member_metrics
from hertzchain.runs.batch import simulate_batch
from hertzchain.errors import ConfigError

BASE = {"chain": {"uniform": {"n": 4, "diameter_mm": 26.0}, "taper": {"n": 4, "q": 0.05}},
        "striker": {"diameter_mm": 8.0, "velocity": 0.2}, "run": {"duration": 2.0e-3, "sample_interval": 1e-6}}


def _problem(design: dict, base: dict | None = None):
    return parse_design({"base": base or BASE, "design": design})


def test_power_linear_and_decorated_shapes_decode_to_their_formulas():
    p = _problem({"variables": {"shape.exponent": [0.5, 2.0]},
                  "shape": {"kind": "power", "n": 5, "last_mm": 11.0, "exponent": 1.0}},
                 base={**BASE, "chain": {"uniform": {"n": 3, "diameter_mm": 26.0}}})
    for e in (0.5, 1.0, 2.0):
        d = p.space.config({"shape.exponent": e})["chain"]["diameters_mm"]
        k = np.arange(1, 6)
        assert d[:3] == [26.0] * 3
        np.testing.assert_allclose(d[3:], 26.0 + (11.0 - 26.0) * (k / 5) ** e, rtol=1e-14)
    p = _problem({"variables": {"shape.small_mm": [5.0, 15.0]},
                  "shape": {"kind": "decorated", "n": 3, "small_mm": 8.0, "small_material": "brass"}},
                 base={**BASE, "chain": {"uniform": {"n": 2, "diameter_mm": 20.0}}})
    c = p.space.config({"shape.small_mm": 6.0})["chain"]
    assert c["diameters_mm"] == [20.0, 20.0, 6.0, 20.0, 6.0, 20.0, 6.0, 20.0]
    assert c["materials"] == ["AISI52100"] * 2 + ["brass", "AISI52100"] * 3
    with pytest.warns(hc.ElasticLimitWarning):  # a valid run config; small brass beads yield at 0.2 m/s
        hc.run_config({**BASE, "chain": c, "run": {"duration": 1e-3, "sample_interval": 1e-6}})


def test_catalogue_monotone_and_integer_variables_decode_to_allowed_values():
    base = {**BASE, "chain": {"diameters_mm": [26.0] * 10}}
    p = _problem({"variables": {"chain.diameters_mm[4:10]": {"low": 9.0, "high": 26.0, "catalogue": "inch",
                                                              "monotone": True},
                                "striker.diameter_mm": [6, 10]}}, base=base)
    allowed = {s for s in CATALOGUES["inch"] if 9.0 <= s <= 26.0}
    rng = np.random.default_rng(0)
    for _ in range(50):
        vals = p.space.values(rng.uniform(0, 1, p.space.dim))
        d = vals["chain.diameters_mm[4:10]"]
        assert set(d) <= allowed and d == sorted(d, reverse=True)
        assert isinstance(vals["striker.diameter_mm"], int) and 6 <= vals["striker.diameter_mm"] <= 10
    assert min(allowed) == pytest.approx(25.4 * 3 / 8) and max(allowed) == pytest.approx(25.4)
    with pytest.raises(ConfigError) as exc:
        _problem({"variables": {"chain.diameters_mm[4:10]": {"low": 9.0, "high": 26.0, "catalogue": "imperial"}}},
                 base=base)
    assert exc.value.field == 'design.variables["chain.diameters_mm[4:10]"].catalogue'


def test_energy_at_wall_is_the_hertz_energy_of_the_last_contact():
    """(2/5) kappa delta^(5/2) with delta = (F / kappa)^(2/3) (paper eq. 1), kappa of bead N on the flat wall."""
    chains = [hc.Chain.uniform(4, 26e-3).append_taper(3, q) for q in (0.0, 0.1)]
    ds = simulate_batch([hc.Model(c, hc.Striker(8e-3, 0.2), hc.Wall("flat"), hc.Elastic()) for c in chains], 1.5e-3,
                        hc.Probes(sample_interval=1e-6, contacts=()))
    met = member_metrics(ds, ["energy_at_wall", "peak_wall_force"], window=(0.0, 1.5e-3))
    for i, c in enumerate(chains):
        kappa = hc.hertz_constant(c.radii[-1], None, "AISI52100", "AISI52100")
        f = ds["wall_force"].values[i].max()
        delta = (f / kappa) ** (2 / 3)
        assert met["energy_at_wall"][i] == pytest.approx(0.4 * kappa * delta ** 2.5, rel=1e-12)
        assert met["peak_wall_force"][i] >= f  # the refined peak is never below the sampled one
    # A window before the pulse arrives holds no energy.
    assert np.all(member_metrics(ds, ["energy_at_wall"], window=(0.0, 1e-5))["energy_at_wall"] == 0.0)


def test_robust_worst_case_over_speeds_matches_single_runs(tmp_path):
    design = {"variables": {"chain.taper.q": [0.0, 0.1]}, "budget": 64, "population": 8, "polish": False,
              "robust": {"velocities": [0.1, 0.3], "statistic": "worst"}}
    res = run_design(_problem(design), tmp_path)
    q = res.best["variables"]["chain.taper.q"]
    peaks = []
    for v in (0.1, 0.3):
        model = hc.Model(hc.Chain.uniform(4, 26e-3).append_taper(4, q), hc.Striker(8e-3, v), hc.Wall("flat"), hc.Elastic())
        peaks.append(hc.simulate(model, 2e-3, hc.Probes(sample_interval=1e-6, contacts=()),
                                 integrator="verlet").attrs["peak_wall_force"])
    assert res.best["objective"] == pytest.approx(max(peaks), rel=1e-12)
    # two runs per candidate and fidelity (the search's, then the best ones again at full accuracy)
    assert res.n_evaluations == 2 * len({(r["fidelity"], r["chain.taper.q"]) for r in res.history})


def test_robust_mean_plus_k_sigma_without_tolerance_is_the_nominal_value(tmp_path):
    nominal = run_design(_problem({"variables": {"chain.taper.q": [0.0, 0.1]}, "budget": 16, "population": 8,
                                   "polish": False}), tmp_path / "a")
    robust = run_design(_problem({"variables": {"chain.taper.q": [0.0, 0.1]}, "budget": 48, "population": 8,
                                  "polish": False, "robust": {"tolerances": {"diameter_rel": 0.0}, "draws": 3,
                                                              "statistic": "mean+ksigma", "k": 3.0}}), tmp_path / "b")
    # Same seed, same candidates; three identical draws: sigma = 0, so the objective is the nominal one.
    first = {(r["fidelity"], r["chain.taper.q"]): r["peak_wall_force"] for r in nominal.history}
    for r in robust.history[: len(nominal.history)]:
        assert r["peak_wall_force"] == pytest.approx(first[r["fidelity"], r["chain.taper.q"]], rel=1e-12)


def test_pareto_front_is_mutually_non_dominated_and_dominates_the_rest(tmp_path):
    pytest.importorskip("pymoo")
    design = {"objective": ["peak_wall_force", "front_momentum_at_wall"],
              "variables": {"chain.taper.n": [2, 8], "chain.taper.q": [0.0, 0.15]}, "budget": 80, "population": 16,
              "constraints": {"min_diameter_mm": 12.0}}
    res = run_design(_problem(design), tmp_path)
    names = design["objective"]
    front = np.array([[r[n] for n in names] for r in res.pareto])
    feasible = np.array([[r[n] for n in names] for r in res.history if r["feasible"]])
    assert len(front) >= 1
    for a in front:  # no front point dominates another
        assert not np.any(np.all(front <= a, axis=1) & np.any(front < a, axis=1))
    for b in feasible:  # every feasible candidate is matched or dominated by the front
        assert np.any(np.all(front <= b, axis=1))
    # NSGA-II resumes from its checkpoint to the same search as well.
    calls = []

    def killer(done, total):
        calls.append(done)
        if len(calls) == 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_design(_problem(design), tmp_path / "b", progress=killer, checkpoint_interval=0)
    again = run_design(_problem(design), tmp_path / "b")
    assert again.resumed and [r["x"] for r in again.history] == [r["x"] for r in res.history]


def test_executor_spreading_a_generation_gives_the_same_search(tmp_path):
    design = {"variables": {"chain.taper.n": [2, 8], "chain.taper.q": [0.0, 0.15]}, "budget": 60, "population": 12,
              "chunk_size": 5, "constraints": {"min_diameter_mm": 12.0}}
    here = run_design(_problem(design), tmp_path / "a")
    with cf.ThreadPoolExecutor(2) as ex:
        spread = run_design(_problem(design), tmp_path / "b", client=ex)
    assert [r["x"] for r in spread.history] == [r["x"] for r in here.history]
    assert [r["peak_wall_force"] for r in spread.history] == [r["peak_wall_force"] for r in here.history]


def test_materials_are_categorical_variables_and_the_example_parses():
    from pathlib import Path

    from hertzchain.design import load_design

    p = _problem({"variables": {"chain.material": ["AISI52100", "brass", "PTFE"]}})
    seen = {p.space.values(np.array([x]))["chain.material"] for x in (0.0, 0.34, 0.99)}
    assert seen == {"AISI52100", "brass", "PTFE"}
    model = hc.build_model(hc.parse_config(p.space.config({"chain.material": "brass"})))
    assert {m.name for m in model.chain.materials} == {"brass"}
    example = load_design(Path(__file__).parent.parent / "examples" / "design_taper.toml")
    assert example.objectives == ["peak_wall_force"] and example.space.dim == 3
    assert load_design(Path(__file__).parent.parent / "examples" / "design_taper.toml",
                       ["striker.velocity=0.3"]).base["striker"]["velocity"] == 0.3


def test_a_member_that_gains_energy_is_flagged():
    """The batched engine has no energy check: the design's own (hertzchain.checks) flags a member
    whose kinetic + elastic + dissipated energy grows, so it can never be the best design."""
    from hertzchain.design.objectives import _energy_ok, _records_of_dataset, _Task

    models = [hc.Model(hc.Chain.uniform(4, 26e-3), hc.Striker(8e-3, 0.2), hc.Wall("flat"), hc.Elastic())] * 2
    probes = hc.Probes(sample_interval=1e-6, contacts=())
    ds = simulate_batch(models, 5e-4, probes)
    task = _Task(models, 5e-4, probes, None, ["peak_wall_force"], None)
    assert _energy_ok(_records_of_dataset(ds), task).tolist() == [True, True]
    ds["kinetic_energy"].values[1, 200:] *= 1.01  # a 1 % gain, as a too-large step would give
    assert _energy_ok(_records_of_dataset(ds), task).tolist() == [True, False]


@pytest.mark.parametrize("design, field", [
    ({"budget": 12.0}, "design.budget"),               # strict like the run config: 12.0 is not a count
    ({"budget": True}, "design.budget"),
    ({"window": [1e-3, 0.0]}, "design.window"),
    ({"constraints": {"min_diameter_mm": "10"}}, "design.constraints.min_diameter_mm"),
])
def test_design_table_types_are_strict(design, field):
    with pytest.raises(ConfigError) as exc:
        _problem({"variables": {"chain.taper.q": [0.0, 0.1]}, **design})
    assert exc.value.field == field


def test_automatic_duration_is_resolved_once_for_the_whole_space(tmp_path):
    """run.duration = "auto" (the default): one duration for every candidate (one time axis per
    batch), the longest automatic one over the space's corners and centre, written into best.toml."""
    from hertzchain.runs.simulation import auto_duration

    base = {"chain": {"uniform": {"n": 4, "diameter_mm": 26.0}, "taper": {"n": 4, "q": 0.05}},
            "striker": {"diameter_mm": 8.0, "velocity": 0.2}, "run": {"sample_interval": 1e-6}}
    p = _problem({"variables": {"chain.taper.n": [2, 12]}, "budget": 40, "population": 8, "polish": False}, base=base)
    longest = auto_duration(hc.Model(hc.Chain.uniform(4, 26e-3).append_taper(12, 0.05), hc.Striker(8e-3, 0.2),
                                     hc.Wall("flat"), hc.Elastic()))
    assert p.base["run"]["duration"] == pytest.approx(longest, rel=1e-12)
    res = run_design(p, tmp_path)
    assert res.best["config"]["run"]["duration"] == p.base["run"]["duration"]
    assert "duration" not in base["run"]  # the caller's mapping is left alone


@pytest.mark.parametrize("chain", [
    {"uniform": {"n": 4, "diameter_mm": 26.0}, "taper": {"n": 6, "q": 0.07}},
    {"preset": "chain2", "truncate": 20},
    {"diameters_mm": [26.0, 20.0, 14.0], "materials": ["AISI52100", "brass", "AISI52100"]},
    {"uniform": {"n": 3, "diameter_mm": 10.0}, "offsets_fraction": [0.0, 0.1, 0.0],
     "substitutions": [{"bead": 2, "diameter_mm": 8.0}]},
])
def test_chain_of_validates_the_chain_alone_with_the_same_numbers(chain):
    """The design's geometry checks build the chain from [chain] alone: the same Chain (bit for bit)
    as the whole config gives, and the same field-named errors."""
    from hertzchain.config import build_chain, chain_of, parse_config

    data = {**BASE, "chain": chain}
    a, b = chain_of(data), build_chain(parse_config(data))
    assert np.array_equal(a.diameters, b.diameters) and np.array_equal(a.offsets, b.offsets)
    assert [m.name for m in a.materials] == [m.name for m in b.materials]
    bad = {**BASE, "chain": {**chain, "taper": {"n": 2, "q": 1.5}}} if "uniform" in chain else \
        {**BASE, "chain": {**chain, "truncate": 0}}
    with pytest.raises(ConfigError) as whole:
        build_chain(parse_config(bad))
    with pytest.raises(ConfigError) as alone:
        chain_of(bad)
    assert alone.value.field == whole.value.field and alone.value.field.startswith("chain.")


def test_geometric_margin_is_signed_and_agrees_with_the_violation():
    """The margin the boundary search uses is >= 0 exactly where no geometric constraint is broken,
    its size the smallest relative slack (here the 15 mm bead limit: 26 (1 - q)^n / 15 - 1)."""
    from hertzchain.design.constraints import Constraints, geometric_margin, geometric_violation, geometry

    c = Constraints(min_diameter_mm=15.0, max_length_mm=400.0, max_beads=20)
    for n in range(1, 16):
        for q in np.linspace(0.0, 0.2, 9):
            geo = geometry(hc.Chain.uniform(4, 26e-3).append_taper(n, q))
            m = geometric_margin(c, geo)
            assert (m >= 0) == (geometric_violation(c, geo) == 0)
            expected = min(26 * (1 - q) ** n / 15 - 1, (400 - geo["length_mm"]) / 400, (20 - 4 - n) / 20)
            assert m == pytest.approx(expected, rel=1e-12, abs=1e-12)
    assert geometric_margin(Constraints(), geo) == np.inf
