"""Sensitivities of registry laws (the engines generated from a law's declared functions,
:mod:`hertzchain.integrate.derivatives.law_derivatives`).

Every derivative is checked against central differences of the forward run itself
(``hertzchain.simulate`` with the Verlet engine, the generated loop), on a short chain at a fixed
step: the same step sequence on both sides, so the two agree to the difference's own error
(~1e-9 relative here; asserted to 1e-5). The taped run's value is the forward run's bit for bit,
and the power law with n = 3/2 and no stiffness (the pair's Hertz constant) has the elastic law's
gradients. Laws: the built-in power law (n = 1.7, its own stiffness) and Hunt-Crossley (e = 0.8,
a law with state: the approach speed), a user's law with state registered here, and the
laws guide's example file (Tsuji's law) through the command line's ``--laws``.
"""

from __future__ import annotations

import copy
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from numba import njit

import hertzchain as hc
from hertzchain.config import build_model, parse_config, parse_path
from hertzchain.errors import ConfigError
from hertzchain.gradients import sensitivity
from hertzchain.probes import Probes

ROOT = Path(__file__).resolve().parents[1]
MAT = {"mysteel": {"density": 7800.0, "young": 2.0e11, "poisson": 0.3}}
BASE = {"materials": MAT,
        "chain": {"diameters_mm": [20.0, 19.0, 18.0, 17.0, 16.0, 15.0], "material": "mysteel"},
        "striker": {"velocity": 0.3, "diameter_mm": 8.0, "material": "mysteel"},
        "run": {"duration": 5e-4, "sample_interval": 1e-6, "dt": 2e-8}}  # the wall peak at ~3e-4 s
POWER = {"law": "power", "exponent": 1.7, "stiffness": 2e11}
HUNT_CROSSLEY = {"law": "hunt_crossley", "restitution": 0.8}
VARIABLES = ["chain.diameters_mm[2]", "striker.velocity", "materials.mysteel.young"]


def _config(contact: dict, **run) -> dict:
    cfg = copy.deepcopy(BASE)
    cfg["contact"] = dict(contact)
    cfg["run"].update(run)
    return cfg


def forward(cfg: dict, objective: str) -> float:
    """The objective as the forward run reports it (a result attribute)."""
    c = parse_config(cfg)
    result = hc.simulate(build_model(c), c.run.duration, Probes(sample_interval=c.run.sample_interval),
                         integrator="verlet", dt=c.run.dt)
    return float(result.attrs[objective])


def central_difference(cfg: dict, path: str, objective: str, rel: float = 1e-6) -> float:
    """(J(x + h) - J(x - h)) / 2h of config field ``path``, h relative to its value."""
    tokens = parse_path(path)
    out = []
    for sign in (1, -1):
        c = copy.deepcopy(cfg)
        node = c
        for tok in tokens[:-1]:
            node = node[tok]
        x = node[tokens[-1]]
        h = rel * abs(x)
        node[tokens[-1]] = x + sign * h
        out.append(forward(c, objective))
    return (out[0] - out[1]) / (2 * h)


def check_against_differences(cfg: dict, variables: list[str], objectives=("peak_wall_force", "peak_wall_time"),
                              modes=("tangent", "adjoint")):
    for objective in objectives:
        value = forward(cfg, objective)
        for mode in modes:
            s = sensitivity(cfg, variables, objective=objective, mode=mode)
            assert s.value == value  # the taped run is the forward run
            for path in variables:
                assert s.gradient[path] == pytest.approx(central_difference(cfg, path, objective), rel=1e-5), \
                    (objective, mode, path)


@pytest.mark.parametrize("contact", [POWER, pytest.param(HUNT_CROSSLEY, marks=pytest.mark.slow)],
                         ids=["power", "hunt_crossley"])
def test_generated_law_gradients_match_central_differences(contact):
    """Tangent and adjoint derivatives of the wall peak and its time by a bead's diameter, the
    striker's speed, a material constant and the law's own parameters."""
    own = [f"contact.{name}" for name in contact if name != "law"]
    check_against_differences(_config(contact), VARIABLES + own)


def test_hunt_crossley_adjoint_matches_central_differences():
    """The adjoint through Hunt-Crossley's state (the approach speed, a running maximum) by a
    diameter, the striker speed and the restitution (the whole matrix: the slow test above)."""
    check_against_differences(_config(HUNT_CROSSLEY), ["chain.diameters_mm[2]", "striker.velocity",
                                                       "contact.restitution"], ("peak_wall_force",), ("adjoint",))


def test_power_law_three_halves_has_the_elastic_gradients():
    """n = 3/2 without a stiffness is Hertz's law (k the pair's constant): the generated engines'
    gradients equal the hand-written elastic engines' to 1e-12 (the same arithmetic up to rounding)."""
    variables = ["chain.diameters_mm[1]", "chain.diameters_mm[4]", "striker.velocity", "materials.mysteel.density"]
    for mode in ("tangent", "adjoint"):
        power = sensitivity(_config({"law": "power", "exponent": 1.5}), variables, mode=mode)
        elastic = sensitivity(_config({"law": "elastic"}), variables, mode=mode)
        assert power.value == pytest.approx(elastic.value, rel=1e-12)
        for path in variables:
            assert power.gradient[path] == pytest.approx(elastic.gradient[path], rel=1e-12), (mode, path)


# A user's law with state, written as docs/guide/laws.rst describes: Hertz with a viscous term
# set by the largest overlap reached since the contact closed, F = k d^(3/2) + p s^(1/2) rate
# (s: that overlap; cohesion-free: the engines clip F at zero).
@njit
def _memory_force(d, rate, k, p, s):
    return k * d * np.sqrt(d) + p * np.sqrt(s) * rate


@njit
def _memory_state(d, rate, k, p, s):
    if d < 0.0:
        return 0.0
    return d if d > s else s


@njit
def _memory_energy(d, k, p):
    return 0.4 * k * d * d * np.sqrt(d)


@njit
def _memory_partials(d, rate, k, p, s):
    return 1.5 * k * np.sqrt(d), p * np.sqrt(s), d * np.sqrt(d), np.sqrt(s) * rate


@njit
def _memory_state_partials(d, rate, k, p, s):
    fs = 0.5 * p * rate / np.sqrt(s) if s > 0.0 else 0.0
    if d < 0.0:
        return fs, 0.0, 0.0, 0.0, 0.0, 0.0
    if d > s:
        return fs, 1.0, 0.0, 0.0, 0.0, 0.0
    return fs, 0.0, 0.0, 0.0, 0.0, 1.0


@dataclass(frozen=True)
class MemoryLaw:
    damping: float
    name = "test_memory"

    @property
    def parameter(self) -> float:
        return self.damping


def _register_memory(state_partials=_memory_state_partials, name="test_memory"):
    law = type(f"Law_{name}", (MemoryLaw,), {"name": name})  # its objects carry the registered name
    return hc.register_law(hc.LawSpec(
        name=name, title="Hertz + p s^(1/2) d(delta)/dt, s the largest overlap", force=_memory_force,
        state=_memory_state, energy=_memory_energy, partials=_memory_partials, state_partials=state_partials,
        state_size=1, dissipative=True, params=(hc.Param("damping", "N s/m^(3/2)", "p", 0.0, 1e12),),
        make=lambda params, chain=None: law(params["damping"])), replace=True)


# slow (~8 s): the default run keeps a stateful law through Hunt-Crossley's adjoint test below
@pytest.mark.parametrize("modes", [pytest.param(m, marks=pytest.mark.slow) for m in (("tangent",), ("tangent", "adjoint"))],
                         ids=["tangent", "both"])
def test_users_law_with_state_gradients_match_central_differences(modes):
    """A law registered with hc.register_law, its state carried by its declared state_partials:
    the derivatives of the wall peak (and its time) by a diameter, the striker speed and its own
    parameter."""
    _register_memory()
    cfg = _config({"law": "test_memory", "parameters": {"damping": 2e4}})
    variables = ["chain.diameters_mm[3]", "striker.velocity", "contact.parameters.damping"]
    objectives = ("peak_wall_force", "peak_wall_time") if len(modes) > 1 else ("peak_wall_force",)
    check_against_differences(cfg, variables, objectives, modes)


def test_law_with_state_but_no_state_partials_is_refused():
    _register_memory(state_partials=None, name="test_memory_bare")
    cfg = _config({"law": "test_memory_bare", "parameters": {"damping": 2e4}})
    with pytest.raises(ConfigError) as err:
        sensitivity(cfg, ["striker.velocity"])
    assert err.value.field == "contact.law" and "state_partials" in str(err.value)


def test_energy_at_wall_needs_the_hertz_exponent():
    with pytest.raises(ConfigError) as err:
        sensitivity(_config(POWER), ["striker.velocity"], objective="energy_at_wall")
    assert err.value.field == "objective"


def test_cli_sensitivity_of_the_power_law(tmp_path):
    """``hertzchain sensitivity`` on a config with law = "power" prints the derivatives (JSON)."""
    from click.testing import CliRunner

    from hertzchain.cli.main import cli

    cfg = tmp_path / "power.toml"
    cfg.write_text(_toml(_config(POWER)))
    res = CliRunner().invoke(cli, ["sensitivity", str(cfg), "--wrt", "striker.velocity", "--wrt",
                                   "contact.exponent", "--json", "-"], env={"COLUMNS": "60"})
    assert res.exit_code == 0, res.output
    data = json.loads(res.output)  # printed
    expected = sensitivity(_config(POWER), ["striker.velocity", "contact.exponent"])
    got = {row["path"]: row["derivative"] for row in data["variables"]}
    for path, value in expected.gradient.items():
        assert got[path] == pytest.approx(value, rel=1e-12)


@pytest.mark.slow
def test_cli_sensitivity_of_a_users_law_file(tmp_path):
    """``--laws examples/laws/tsuji.py`` (the laws guide's example) with law = "tsuji": the
    derivatives the command prints match central differences of the forward run."""
    from click.testing import CliRunner

    from hertzchain.cli.main import cli

    contact = {"law": "tsuji", "parameters": {"eta": 300.0}}
    cfg = tmp_path / "tsuji.toml"
    cfg.write_text(_toml(_config(contact)))
    out = tmp_path / "s.json"
    res = CliRunner().invoke(cli, ["sensitivity", str(cfg), "--laws", str(ROOT / "examples/laws/tsuji.py"),
                                   "--wrt", "chain.diameters_mm[2]", "--wrt", "contact.parameters.eta",
                                   "--json", str(out)], env={"COLUMNS": "60"})
    assert res.exit_code == 0, res.output
    data = json.loads(out.read_text())
    got = {row["path"]: row["derivative"] for row in data["variables"]}
    for path in ("chain.diameters_mm[2]", "contact.parameters.eta"):
        assert got[path] == pytest.approx(central_difference(_config(contact), path, "peak_wall_force"), rel=1e-5)


def _toml(cfg: dict) -> str:
    import tomli_w

    return tomli_w.dumps(cfg)


def test_design_gradient_phase_takes_registry_laws():
    """The design search's gradient phase accepts a power-law chain (its sensitivities exist) and
    declines energy_at_wall for it with the sensitivity's reason (no Hertz exponent 3/2)."""
    from hertzchain.design import parse_design
    from hertzchain.design.gradient import gradient_support

    base = _config(POWER)
    data = {"base": base, "design": {"objective": "peak_wall_force", "budget": 40, "seed": 1,
                                     "variables": {"chain.diameters_mm[3:6]": {"low": 10.0, "high": 20.0}}}}
    assert gradient_support(parse_design(copy.deepcopy(data))) is None
    data["design"]["objective"] = "energy_at_wall"
    assert "objective" in gradient_support(parse_design(copy.deepcopy(data)))


def test_hunt_crossley_state_partials_match_central_differences():
    """Hunt-Crossley's declared state_partials: dF/dv_in and the state update's partials by delta,
    the rate, k, chi and v_in, against central differences on each branch (rate above and below v_in)."""
    from hertzchain.laws import hunt_crossley as law

    k, chi = 1.2e10, law.damping_factor(0.8)
    for d, rate, vin in ((1e-6, 0.1, 0.2), (1e-6, 0.3, 0.2), (2e-6, -0.05, 0.15)):
        x = np.array([d, rate, k, chi, vin])
        got = law.state_partials(*x)
        for i in range(5):
            h = np.zeros(5)
            h[i] = 1e-6 * abs(x[i])
            ds = (law.state(*(x + h)) - law.state(*(x - h))) / (2 * h[i])
            assert got[1 + i] == pytest.approx(ds, rel=1e-6, abs=1e-9), (i, x)
        h = 1e-6 * vin
        fs = (law.force(d, rate, k, chi, vin + h) - law.force(d, rate, k, chi, vin - h)) / (2 * h)
        assert got[0] == pytest.approx(fs, rel=1e-6)


@pytest.mark.slow
@pytest.mark.parametrize("contact", [POWER, HUNT_CROSSLEY], ids=["power", "hunt_crossley"])
def test_misaligned_chain_gradients(contact):
    """Offsets (the misaligned geometry around the law's partials): tangent and adjoint agree to
    1e-8 and central differences to 1e-4. The wall peak moves by ~1e-9 of itself for a 1e-6
    relative change of an offset, at rounding's level: the differences take a 1e-3 step, whose
    truncation error is ~3e-5 here."""
    cfg = _config(contact)
    cfg["chain"]["offsets_mm"] = [0.0, 0.3, 0.0, -0.2, 0.0, 0.0]
    variables = ["chain.offsets_mm[1]", "chain.offsets_mm[3]", "chain.diameters_mm[2]"]
    tangent = sensitivity(cfg, variables, mode="tangent").gradient
    adjoint = sensitivity(cfg, variables, mode="adjoint").gradient
    for path in variables:
        assert adjoint[path] == pytest.approx(tangent[path], rel=1e-8)
        assert tangent[path] == pytest.approx(central_difference(cfg, path, "peak_wall_force", rel=1e-3), rel=1e-4)
