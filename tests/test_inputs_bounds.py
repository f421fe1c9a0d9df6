"""The new physics' inputs (issue 38): bounds that keep every derived quantity representable, a
pre-flight that refuses absurd step counts naming the field that causes them, the elastic-plastic
law refused without a yield stress, and unit strings from scope files parsed by a strict grammar.

The property campaign draws configs of protected bodies, plasticity, gravity and elements over
many orders of magnitude (inside and outside the bounds) and checks, without running the engine,
that each is refused with a ConfigError naming a field or passes the pre-flight with finite,
positive derived quantities and a step count the engine can run; a few tiny drawn runs then
check that what passes runs to finite, energy-consistent results.
"""

from __future__ import annotations

import math
import subprocess
import sys
import warnings

import numpy as np
import pytest
import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import hertzchain as hc
from hertzchain.bounds import MAX_STEPS
from hertzchain.cli.main import main
from hertzchain.errors import ConfigError, TooManySteps

CHAIN = {"uniform": {"n": 3, "diameter_mm": 10.0}}


def _write(path, data: dict):
    path.write_text(tomli_w.dumps(data), encoding="utf-8")
    return path


def _cli_error(capsys, argv: list[str]) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "internal error" not in err and "Traceback" not in err
    return " ".join(err.split())


# ------------------------------------------------------------------ bounds and the pre-flight
def test_a_weightless_body_on_a_strong_dashpot_is_refused_naming_the_field(tmp_path, capsys):
    """mass = 1e-30 kg (below the bound: a 1 um steel bead weighs 4e-15 kg) is refused by the schema;
    at the bound, the dashpot's rate c/m = 1e27 1/s would need ~1e26 steps: the pre-flight names
    wall.damping before any work (it crashed in the engine with 'Int value is too large')."""
    cfg = {"chain": CHAIN, "striker": {"velocity": 0.2}, "wall": {"type": "body", "mass": 1e-30, "damping": 1e12}}
    out = tmp_path / "r.nc"
    assert "wall.mass" in _cli_error(capsys, ["run", str(_write(tmp_path / "a.toml", cfg)), "--out", str(out)])
    cfg["wall"]["mass"] = 1e-15
    err = _cli_error(capsys, ["run", str(_write(tmp_path / "b.toml", cfg)), "--out", str(out)])
    assert "wall.damping" in err and "time steps" in err and not out.exists()
    # the Python API refuses alike
    with pytest.raises(ConfigError, match="wall.mass"):
        hc.Wall("body", mass=1e-30)
    model = hc.Model(hc.Chain.uniform(3, 10e-3), hc.Striker(8e-3, 0.2), hc.Wall("body", mass=1e-15, damping=1e12))
    with pytest.raises(TooManySteps) as err:
        hc.simulate(model, 1e-3)
    assert err.value.field == "wall.damping"
    # a light undamped body: its mass against its contact sets the step
    light = hc.Model(hc.Chain.uniform(3, 10e-3), hc.Striker(8e-3, 0.2), hc.Wall("body", mass=1e-15))
    with pytest.raises(TooManySteps) as err:
        hc.simulate(light, 10.0)
    assert err.value.field == "wall.mass"


def test_a_step_count_past_the_limit_names_run_dt_and_the_batch_engine_refuses_too():
    model = hc.Model(hc.Chain.uniform(3, 10e-3), hc.Striker(8e-3, 0.2))
    with pytest.raises(TooManySteps) as err:
        hc.simulate(model, 50.0, dt=1e-15)
    assert err.value.field == "run.dt" and "5e+16" in err.value.message
    body = hc.Model(hc.Chain.uniform(3, 10e-3), hc.Striker(8e-3, 0.2), hc.Wall("body", mass=1e-15, damping=1e12))
    from hertzchain.runs.batch import simulate_many

    with pytest.raises(TooManySteps, match="wall.damping"):
        simulate_many([body, body], 1e-3)


def test_limiting_pressure_factor_bounds_in_config_and_api(tmp_path, capsys):
    """1e-300 underflowed the yield overlap (delta_y ~ p_y^2) to 0 and the step count to NaN."""
    cfg = {"chain": CHAIN, "contact": {"law": "elastoplastic", "limiting_pressure_factor": 1e-300}}
    err = _cli_error(capsys, ["run", str(_write(tmp_path / "c.toml", cfg)), "--out", str(tmp_path / "r.nc")])
    assert "contact.limiting_pressure_factor" in err
    for bad in (1e-300, 0.0, 11.0, math.nan):
        with pytest.raises(ConfigError, match="contact.limiting_pressure_factor"):
            hc.Elastoplastic(limiting_pressure_factor=bad)


def test_elastoplastic_without_a_yield_stress_names_the_material(tmp_path, capsys):
    mat = {"density": 7800.0, "young": 2e11, "poisson": 0.3}
    cfg = {"materials": {"soft": mat}, "chain": {**CHAIN, "material": "soft"}, "contact": {"law": "elastoplastic"}}
    out = tmp_path / "r.nc"
    err = _cli_error(capsys, ["run", str(_write(tmp_path / "e.toml", cfg)), "--out", str(out)])
    assert "materials.soft.yield_stress" in err and not out.exists()
    # a wall of a material without one is refused too (the wall's contact would stay elastic)
    cfg = {"materials": {"soft": mat}, "chain": CHAIN, "wall": {"material": "soft"}, "contact": {"law": "elastoplastic"}}
    assert "materials.soft.yield_stress" in _cli_error(capsys, ["run", str(_write(tmp_path / "f.toml", cfg)),
                                                                "--out", str(out)])


# ------------------------------------------------------------------ units of scope files
def _scope_csv(path, unit: str):
    t = np.arange(2000) * 1e-7
    rows = "\n".join(f"{a:.9g},{b:.6g}" for a, b in zip(t, 10 * np.exp(-((t - 1e-4) / 2e-5) ** 2)))
    path.write_text(f"time [{unit}],force [N]\n{rows}\n", encoding="utf-8")
    return path


@pytest.mark.parametrize("unit", ["s/0", "s**0", "s^-0", "1e-3 s", "s/", "s^99", "kilo", "s*/N", "2s"])
def test_unit_strings_outside_the_grammar_are_refused_naming_the_column(tmp_path, unit):
    """A CSV header's unit reached pint: s/0 and s**0 gave ZeroDivisionError."""
    from hertzchain.lab import read_trace

    with pytest.raises(ConfigError, match=r"time column 'time \[") as err:
        read_trace(_scope_csv(tmp_path / "scope.csv", unit))
    assert unit in err.value.message


def test_a_unit_that_pint_computed_for_ever_is_refused_at_once(tmp_path):
    """``10**10**10*s`` made pint compute 10**(10**10) with no end; run in a child process with a
    timeout, so that a hang fails the test instead of stalling the suite."""
    path = _scope_csv(tmp_path / "scope.csv", "10**10**10*s")
    code = ("import sys\nfrom hertzchain.lab import read_trace\nfrom hertzchain.errors import ConfigError\n"
            "try:\n    read_trace(sys.argv[1])\nexcept ConfigError as e:\n    print('REFUSED', e)\n")
    done = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("REFUSED") and "10**10**10*s" in done.stdout, done.stdout


@pytest.mark.parametrize("unit, factor, kind", [("ms", 1e-3, "time"), ("µs", 1e-6, "time"), ("us", 1e-6, "time"),
                                                ("S", 1.0, "time"), ("kN", 1e3, "force"), ("mV", 1e-3, "voltage"),
                                                ("Volts", 1.0, "voltage"), ("millisecond", 1e-3, "time"),
                                                ("kg m/s^2", 1.0, "force"), ("kg*m*s**-2", 1.0, "force"),
                                                ("W/A", 1.0, "voltage"), ("Pa m^2", 1.0, "force")])
def test_the_units_a_scope_writes_are_read_to_si(unit, factor, kind):
    from hertzchain.lab.readers import _unit_factor

    got = _unit_factor(unit, "column")
    assert got[1] == kind and got[0] == pytest.approx(factor, rel=1e-15)


def test_sensitivity_units_parse_to_volts_per_newton():
    from hertzchain.lab.units import parse_unit

    assert parse_unit("mV/N") == (pytest.approx(1e-3), (1, 0, -1, -1))  # V/N = m s^-1 A^-1


def test_a_lecroy_horizontal_unit_outside_the_grammar_is_refused(tmp_path):
    from lab_files import trc_bytes

    from hertzchain.lab import read_trace

    codes = (3000 * np.exp(-((np.arange(4000) - 300) / 40.0) ** 2)).astype(int)
    path = tmp_path / "x.trc"
    path.write_bytes(trc_bytes(codes, over={244: ("48s", b"s/0")}))
    with pytest.raises(ConfigError, match="s/0"):
        read_trace(path, sensitivity=100.0)


# ------------------------------------------------------------------ the property campaign
def _magnitude(lo_exp: int, hi_exp: int, wide: tuple[int, int] = (-320, 300)):
    """Positive floats, log-spread over the decades lo_exp..hi_exp (about the bounds, where most
    draws fall) or, one draw in ten, over ``wide`` (far outside them, to 1e-320 and 1e300)."""
    def number(far: bool, u: float, m: float) -> float:
        lo, hi = wide if far else (lo_exp, hi_exp)
        return m * 10.0 ** int(lo + u * (hi - lo))
    return st.builds(number, st.integers(0, 9).map(lambda k: k == 0), st.floats(0, 1), st.floats(1.0, 9.99))


CAMPAIGN = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _drawn_config(draw) -> dict:
    """A config of a short chain with, each drawn or not: a protected body, the elastic-plastic law
    with a drawn material, gravity, and element masses or resonators."""
    n = draw(st.integers(0, 4))  # 0: the striker onto the wall or body
    cfg: dict = {"chain": {"uniform": {"n": n, "diameter_mm": draw(_magnitude(-3, 3))}},
                 "striker": {"velocity": draw(_magnitude(-6, 2)), "diameter_mm": draw(_magnitude(-2, 2))},
                 "run": {"duration": draw(st.sampled_from([1e-4, 1e-3, 0.1, 100.0]))}}
    if draw(st.booleans()):
        cfg["wall"] = {"type": "body", "mass": draw(_magnitude(-15, 5)),
                       "stiffness": draw(st.one_of(st.just(0.0), _magnitude(-3, 14))),
                       "damping": draw(st.one_of(st.just(0.0), _magnitude(-3, 11)))}
    if draw(st.booleans()):
        cfg["contact"] = {"law": "elastoplastic", "limiting_pressure_factor": draw(_magnitude(-1, 1))}
        cfg["materials"] = {"x": {"density": draw(_magnitude(0, 4)), "young": draw(_magnitude(3, 12)),
                                  "poisson": 0.3, "yield_stress": draw(_magnitude(3, 11))}}
        cfg["chain"]["material"] = "x"
    if draw(st.booleans()):
        cfg["chain"]["gravity"] = draw(_magnitude(-3, 3))
        if "wall" in cfg:
            cfg["wall"]["stiffness"] = draw(_magnitude(-3, 14))
    if draw(st.booleans()):
        el: dict = {"mass": draw(_magnitude(-15, 5))}
        if draw(st.booleans()):
            el["resonator"] = {"mass_fraction": draw(st.floats(0.01, 0.99)), "frequency": draw(_magnitude(0, 8))}
        cfg["elements"] = {"e": el}
        cfg["chain"]["elements"] = ["e"] * n
    return cfg


def _preflight(cfg: dict):
    """Validation, model, its arrays and the pre-flight: a ConfigError, or what passed it."""
    from hertzchain.checks import estimate_resources
    from hertzchain.config import build_model, build_probes, parse_config
    from hertzchain.runs.simulation import auto_duration

    parsed = parse_config(cfg)
    model = build_model(parsed)
    system = model.system()
    duration = auto_duration(model) if parsed.run.duration == "auto" else parsed.run.duration
    return model, system, estimate_resources(system, duration, build_probes(parsed))


@settings(max_examples=300, **CAMPAIGN)
@given(data=st.data())
def test_drawn_inputs_are_refused_by_name_or_pass_with_representable_quantities(data):
    cfg = _drawn_config(data.draw)
    try:
        model, system, est = _preflight(cfg)
    except ConfigError as exc:
        assert exc.field and exc.message  # a field named, said why
        return
    for name in ("mass", "kappa", "damping", "d0", "fext"):
        values = getattr(system, name)[: system.n_moving]
        assert np.all(np.isfinite(values)), name
    assert np.all(system.mass[: system.n_moving] > 0) and np.all(system.kappa[: system.n_contacts] > 0)
    assert np.all(system.max_overlap()[: system.n_contacts] > 0)
    w = system.max_frequency()
    assert math.isfinite(w) and w > 0
    assert math.isfinite(est.steps) and 0 < est.steps <= MAX_STEPS and est.memory_bytes > 0
    if system.law == hc.contact.LAW_CODES["elastoplastic"]:
        dy = system.yield_overlap()[: system.n_contacts]
        assert np.all(np.isfinite(dy) & (dy > 0))


@settings(max_examples=24, **CAMPAIGN)
@given(data=st.data())
def test_drawn_inputs_that_pass_run_to_finite_results(data):
    cfg = _drawn_config(data.draw)
    cfg["run"] = {"duration": 2e-5 * cfg["chain"]["uniform"]["diameter_mm"] / 10.0,
                  "sample_interval": 1e-7 * cfg["chain"]["uniform"]["diameter_mm"] / 10.0}
    try:
        _, _, est = _preflight(cfg)
    except ConfigError:
        return
    if est.steps > 1e6:  # a tiny run only
        return
    from hertzchain.config import run_config

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            ds = run_config(cfg)
        except ConfigError as exc:  # refused by a check that needs the run's set-up, naming a field
            assert exc.field
            return
    for name in ("contact_force", "kinetic_energy", "potential_energy"):
        assert np.all(np.isfinite(ds[name].values)), name
    assert np.all(ds.contact_force.values >= 0)
