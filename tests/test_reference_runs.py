"""References a protector is judged against (issue 36 items 4, 5) and one striker in config and API
(issue 38 item 6): a chain of zero beads (the striker straight onto the wall or the body) against
the closed-form two-body Hertz impact; the dynamic peak of a run under gravity beside its total; a
config and its Python transcription hit with the same striker."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.contact import effective_modulus
from hertzchain.errors import ConfigError
from hertzchain.theory import HERTZ_CONTACT_TIME, two_body_impact

STEEL = hc.get_material("AISI52100")


# ------------------------------------------------------------------ zero beads
def test_the_contact_time_constant_is_hertz_s():
    """2 int_0^1 dx / sqrt(1 - x^(5/2)), by quadrature, is the closed form's 2.943."""
    from scipy.integrate import quad

    value, _ = quad(lambda x: 1.0 / math.sqrt(1.0 - x**2.5), 0.0, 1.0)
    assert HERTZ_CONTACT_TIME == pytest.approx(2.0 * value, rel=1e-9)
    assert HERTZ_CONTACT_TIME == pytest.approx(2.943, abs=5e-4)


@pytest.mark.parametrize("velocity", [0.02, 0.2])
def test_zero_beads_is_the_two_body_hertz_impact_on_a_flat(velocity):
    """An 8 mm steel ball onto the steel flat: max overlap (5 mu v^2 / (4 kappa))^(2/5), peak force
    kappa delta_m^(3/2), contact time 2.943 delta_m / v, kappa = (4/3) E* sqrt(R) (paper eq. 1
    with 1/R' = 0), and the ball leaves at the speed it came (elastic)."""
    model = hc.Model(hc.Chain.uniform(0, 26e-3), hc.Striker(8e-3, velocity))
    system = model.system()
    kappa = 4.0 / 3.0 * effective_modulus(STEEL, STEEL) * math.sqrt(4e-3)
    assert system.n_beads == 0 and system.n_contacts == 1
    assert system.kappa[0] == pytest.approx(kappa, rel=1e-12)
    mass = STEEL.density * math.pi * 8e-3**3 / 6.0
    exact = two_body_impact(mass, kappa, velocity)
    ds = hc.simulate(model, probes=hc.Probes(sample_interval=1e-9, velocities=True))
    assert ds.sizes["bead"] == 0 and list(ds.contact.values) == [0]
    assert ds.attrs["peak_wall_force"] == pytest.approx(exact["peak_force"], rel=1e-6)  # the adaptive step's bound
    f = ds.wall_force.values
    touching = ds.time.values[f > 0]
    assert touching[-1] - touching[0] == pytest.approx(exact["contact_time"], abs=2e-9)
    assert f[-1] == 0.0  # the automatic duration holds the whole collision
    assert float(ds.velocity.values[-1, 0]) == pytest.approx(-velocity, rel=1e-6)
    # the overlap at the peak, from the force (F = kappa delta^(3/2))
    assert (ds.attrs["peak_wall_force"] / kappa) ** (2 / 3) == pytest.approx(exact["max_overlap"], rel=1e-6)


def test_zero_beads_from_a_config_is_the_api_run_and_analyses(tmp_path):
    from hertzchain.analysis import analyze_signals

    cfg = {"chain": {"uniform": {"n": 0, "diameter_mm": 26.0}}, "striker": {"velocity": 0.2},
           "probes": {"sensors": []}}
    ds = hc.run_config(cfg)
    api = hc.simulate(hc.Model(hc.Chain.uniform(0, 26e-3), hc.Striker(8e-3, 0.2)))
    assert ds.attrs["peak_wall_force"] == api.attrs["peak_wall_force"]
    assert np.array_equal(ds.wall_force.values, api.wall_force.values)
    row = analyze_signals(ds, signals=("wall_force",))[0]
    assert not row.get("error") and row["peak_force"] == pytest.approx(ds.attrs["peak_wall_force"], rel=0.1)
    hc.save(ds, tmp_path / "zero.nc")
    back = hc.load(tmp_path / "zero.nc")
    assert back.sizes["bead"] == 0 and back.attrs["peak_wall_force"] == ds.attrs["peak_wall_force"]


def test_zero_beads_onto_a_protected_body_with_a_calibrated_law():
    """The reference of a protector: the striker straight onto the body; a calibrated law
    (eps) refers to the uniform block's beads, as it would in the chain."""
    cfg = {"chain": {"uniform": {"n": 0, "diameter_mm": 26.0}},
           "striker": {"velocity": 0.2},
           "wall": {"type": "body", "mass": 0.5, "stiffness": 2e6},
           "contact": {"law": "dashpot_scaled", "eps": 0.985}}
    model = hc.build_model(hc.parse_config(cfg))
    assert model.law.diameter == pytest.approx(26e-3)
    ds = hc.run_config(cfg)
    m_s = model.striker.mass
    mu = m_s * 0.5 / (m_s + 0.5)
    exact = two_body_impact(mu, float(model.system().kappa[0]), 0.2)
    # the dashpot takes a few per cent of the elastic peak (restitution ~ 0.96)
    assert 0.9 * exact["peak_force"] < ds.attrs["peak_wall_force"] < exact["peak_force"]
    assert ds.attrs["peak_body_force"] > 0


@pytest.mark.parametrize("cfg, field", [
    ({"wall": {"type": "none"}}, "chain.uniform.n"),
    ({"chain": {"uniform": {"n": 0, "diameter_mm": 26.0}, "precompression": 5.0}}, "chain.precompression"),
    ({"chain": {"uniform": {"n": 0, "diameter_mm": 26.0}, "taper": {"n": 3, "q": 0.05}}}, "chain.taper"),
])
def test_zero_beads_refuses_what_has_no_meaning(cfg, field):
    full = {"chain": {"uniform": {"n": 0, "diameter_mm": 26.0}}, **cfg}
    with pytest.raises(ConfigError) as err:
        hc.run_config(full)
    assert err.value.field == field


# ------------------------------------------------------------------ gravity: the dynamic peak
def test_gravity_dynamic_peak_vanishes_with_the_speed_while_the_total_is_the_weight():
    """A column of 10 beads on the wall: the wall carries the weights (m_s + sum m_n) g at rest;
    touched at a tiny speed the dynamic peak -> 0 (linear in the speed about the static state),
    while the total -> the weight."""
    g = 9.81
    peaks = {}
    for v in (1e-6, 1e-4):
        cfg = {"chain": {"uniform": {"n": 10, "diameter_mm": 26.0}, "gravity": g}, "striker": {"velocity": v},
               "run": {"duration": 2e-3}}
        model = hc.build_model(hc.parse_config(cfg))
        weight = g * (model.striker.mass + model.chain.masses.sum())
        ds = hc.run_config(cfg)
        a = ds.attrs
        assert a["static_wall_force"] == pytest.approx(weight, rel=1e-12)
        assert a["peak_wall_force_dynamic"] == pytest.approx(a["peak_wall_force"] - weight, rel=1e-9, abs=1e-12)
        peaks[v] = a["peak_wall_force_dynamic"]
    assert 0 < peaks[1e-6] < 1e-5 * weight
    assert peaks[1e-4] / peaks[1e-6] == pytest.approx(100.0, rel=0.01)  # linear response about the static state
    # no static force, no dynamic attribute: the total is the dynamic peak
    flat = hc.run_config({"chain": {"uniform": {"n": 3, "diameter_mm": 26.0}}, "striker": {"velocity": 0.2},
                          "run": {"duration": 5e-4}})
    assert "peak_wall_force_dynamic" not in flat.attrs


def test_gravity_dynamic_peak_in_the_run_summary(tmp_path, capsys):
    import tomli_w

    from hertzchain.cli.main import main

    path = tmp_path / "column.toml"
    path.write_text(tomli_w.dumps({"chain": {"uniform": {"n": 4, "diameter_mm": 26.0}, "gravity": 9.81},
                                   "striker": {"velocity": 0.2}, "run": {"duration": 2e-3}}), encoding="utf-8")
    assert main(["run", str(path), "--out", str(tmp_path / "c.nc")]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "N dynamic over the" in out and "N static" in out
    assert main(["analyze", str(tmp_path / "c.nc"), "--json", str(tmp_path / "fit.json")]) == 0
    assert "static (the weights) +" in " ".join(capsys.readouterr().out.split())
    ds = hc.load(tmp_path / "c.nc")
    fit = json.loads((tmp_path / "fit.json").read_text())[0]
    # the pulse fitted above the weights: its F_m is near the dynamic peak, not the total
    assert fit["peak_force"] == pytest.approx(ds.attrs["peak_wall_force_dynamic"], rel=0.1)


# ------------------------------------------------------------------ one default striker
def test_a_config_and_its_python_transcription_hit_with_the_same_striker():
    """A glass chain without striker.material: both are hit by AISI 52100 (the config's striker
    took the chain's material, hc.Striker's default was AISI 52100)."""
    cfg = {"chain": {"uniform": {"n": 3, "diameter_mm": 20.0}, "material": "glass"},
           "striker": {"velocity": 0.3}, "run": {"duration": 3e-4}}
    model = hc.build_model(hc.parse_config(cfg))
    assert model.striker.material.name == "AISI52100"
    api = hc.Model(hc.Chain.uniform(3, 20e-3, "glass"), hc.Striker(8e-3, 0.3))
    assert api.striker.material.name == "AISI52100"
    a, b = hc.run_config(cfg), hc.simulate(api, 3e-4)
    assert a.attrs["peak_wall_force"] == b.attrs["peak_wall_force"]
    assert np.array_equal(a.contact_force.values, b.contact_force.values)


def test_a_sweep_under_gravity_tabulates_the_dynamic_peak_and_takes_no_chain(tmp_path):
    """metrics.csv: peak_wall_force_dynamic = peak_wall_force - the weights, per member; a member of
    zero beads (chain.uniform.n = 0) is the striker's two-body impact on the wall."""
    from hertzchain.sweep import run_sweep

    base = {"chain": {"uniform": {"n": 3, "diameter_mm": 10.0}, "gravity": 9.81},
            "striker": {"velocity": 0.2}, "run": {"duration": 2e-4, "sample_interval": 1e-6}}
    sweep = {"mode": "grid", "chunk_size": 2, "parameters": {"chain.uniform.n": [0, 3]}}
    df = run_sweep({"base": base, "sweep": sweep}, tmp_path).metrics
    for _, row in df.iterrows():
        cfg = {**base, "chain": {**base["chain"], "uniform": {"n": int(row["chain.uniform.n"]), "diameter_mm": 10.0}}}
        model = hc.build_model(hc.parse_config(cfg))
        weight = 9.81 * (model.striker.mass + model.chain.masses.sum())
        assert row["peak_wall_force_dynamic"] == pytest.approx(row["peak_wall_force"] - weight, rel=1e-9)
    alone = hc.run_config({**base, "chain": {"uniform": {"n": 0, "diameter_mm": 10.0}, "gravity": 9.81}})
    assert df.loc[df["chain.uniform.n"] == 0, "peak_wall_force"].item() == alone.attrs["peak_wall_force"]


def test_every_command_takes_a_zero_bead_run_or_refuses_it_by_name(tmp_path, capsys):
    """run, analyze, plot and export handle the striker onto the wall; sensitivity and animate, which
    are about a chain, refuse it naming why (exit 2), never an internal error."""
    import tomli_w

    from hertzchain.cli.main import main

    cfg = tmp_path / "zero.toml"
    cfg.write_text(tomli_w.dumps({"chain": {"uniform": {"n": 0, "diameter_mm": 26.0}}, "striker": {"velocity": 0.2}}),
                   encoding="utf-8")
    nc = tmp_path / "zero.nc"
    assert main(["run", str(cfg), "--out", str(nc), "-q"]) == 0
    assert main(["analyze", str(nc)]) == 0
    for kind in ("signals", "spacetime", "energy"):
        assert main(["plot", str(nc), "--kind", kind, "-o", str(tmp_path / f"{kind}.png")]) == 0
    assert main(["export", str(nc), "--out", str(tmp_path / "zero.csv")]) == 0
    capsys.readouterr()
    for argv in (["sensitivity", str(cfg), "--wrt", "striker.velocity"], ["animate", str(nc), "-o", str(tmp_path / "a.gif")]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert "internal error" not in err and ("chain.uniform.n" in err or "RESULT" in err)
