"""The explorer without a browser: its settings are a run config of the one schema, "save as
config" reproduces the view through ``hertzchain run``, the view's numbers are the simulation's
and the paper's, and ``hertzchain.explore()`` is a displayable app in Jupyter."""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.cli.main import main
from hertzchain.config import parse_config
from hertzchain.errors import ConfigError
from hertzchain.explorer.ballistic import WALL_BEADS, measure_ratios
from hertzchain.explorer.compute import compute_view, uniform_count
from hertzchain.explorer.settings import MAX_BODY_DURATION, ExplorerSettings, mount_half_period


@pytest.mark.parametrize("changes", [
    {},
    {"chain": "chain2", "law": "viscoelastic", "eps": 0.98},
    {"chain": "uniform", "uniform_n": 10, "taper_n": 6, "taper_q": 0.08, "material": "brass", "law": "dashpot"},
    {"chain": "diameters", "diameters_mm": "20 20 20 18 16", "wall": "none", "striker_velocity": 0.1},
    {"law": "elastoplastic", "striker_velocity": 1.0},
    {"chain": "chain2", "bead_materials": "AISI52100 x 26, brass, brass", "wall_material": "brass"},
    {"wall": "body", "body_mass": 0.5, "body_stiffness": 2e6, "body_damping": 20.0, "law": "dashpot_scaled"},
    {"wall": "body", "gravity": 9.81, "striker_mass": 0.02, "striker_shape": "flat"},
    {"wall": "body", "body_stiffness": 0.0, "body_damping": 50.0, "striker_shape": "flat"},
    {"chain": "uniform", "uniform_n": 20, "taper_n": 0, "gravity": 4.0, "law": "elastoplastic", "striker_velocity": 1.0},
])
def test_saved_config_reproduces_the_view_through_hertzchain_run(tmp_path, changes):
    settings = ExplorerSettings(**changes)
    view = compute_view(settings)
    path = tmp_path / "view.toml"
    path.write_text(settings.toml())
    cfg = parse_config(tomllib.loads(path.read_text()))  # the one schema reads it
    assert cfg.striker.velocity == settings.striker_velocity
    assert main(["run", str(path), "--out", str(tmp_path / "r.nc"), "-q"]) == 0
    ds = hc.load(tmp_path / "r.nc")
    if "wall_force" in view.result:
        assert ds.attrs["peak_wall_force"] == view.result.attrs["peak_wall_force"]
        np.testing.assert_array_equal(ds.wall_force.values, view.force)
    else:
        np.testing.assert_array_equal(ds.contact_force.values[:, -1], view.force)
    if settings.wall == "body":  # the force the mount passes to the ground, drawn beside the wall force
        assert ds.attrs["peak_body_force"] == view.result.attrs["peak_body_force"]
        np.testing.assert_array_equal(ds.body_force.values, view.body_force)
    else:
        assert view.body_force is None
    for name in ("plastic_work", "residual_overlap_max"):  # the elastoplastic law's readout
        assert ds.attrs.get(name) == view.result.attrs.get(name)


def test_view_numbers_are_the_simulation_and_the_paper():
    view = compute_view(ExplorerSettings())  # the paper's chain 1, elastic, 0.2 m/s
    assert view.signal == "wall_force" and view.force.max() == pytest.approx(8.5113, rel=1e-4)
    # the cos^6 fit (paper Sec. III) passes through the simulated pulse's top
    assert view.fit.peak_force == pytest.approx(view.force.max(), rel=0.02)
    # the space-time map keeps every peak (bins keep their largest force)
    assert view.map_force.max() == pytest.approx(view.result.contact_force.values.max(), rel=1e-12)
    assert view.map_vmax == pytest.approx(view.result.contact_force.values[:, 1:].max(), rel=1e-12)
    # the energies: an elastic run conserves the striker's kinetic energy
    total = dict(view.energies)["total"]
    e0 = 0.5 * view.result.mass.values[0] * 0.2 ** 2 if "mass" in view.result and view.result.mass.size > 30 else total[0]
    assert np.ptp(total) < 1e-3 * e0
    # eq. 8 for chain 1's q = 5.60 % (elastic): the paper's Q_th with eps = 1
    rows = {r.equation: r for r in view.theory}
    assert float(rows["eq. 8"].theory) == pytest.approx(hc.ballistic_ratios(0.0560, 1.0).speed, abs=2e-4)


def test_elastoplastic_view_accounts_for_the_plastic_work():
    """Thornton's law: the plastic work is drawn as its own energy, and with it the sum is the
    striker's kinetic energy again (nothing else dissipates: no eps, no viscous term)."""
    view = compute_view(ExplorerSettings(law="elastoplastic", striker_velocity=2.0))
    assert "eps" not in view.config["contact"]
    curves = dict(view.energies)
    e0 = curves["total"][0]
    assert curves["plastic"][-1] > 0.1 * e0 and curves["dissipated"][-1] == 0
    assert np.ptp(curves["total"]) < 1e-5 * e0
    rows = {r.equation: r for r in view.theory}
    assert float(rows["eq. 8"].theory) == pytest.approx(hc.ballistic_ratios(0.0560, 1.0).speed, abs=2e-4)


def test_protected_body_view_is_the_model_simulate_gives():
    """The explorer's body is hc.Wall("body", ...) behind the paper's chain: the same wall and body
    forces as hertzchain.simulate of that model built with the Python API; the run lasts the
    automatic duration, which holds half the mount's period past the pulse, so the mount's peak is
    inside the record; an
    undamped mount conserves the energy (the body's kinetic and the mount's elastic energy in it)."""
    settings = ExplorerSettings(wall="body", body_mass=0.5, body_stiffness=2e6)
    view = compute_view(settings)
    model = hc.Model(hc.paper_chain("chain1"), hc.Striker(8e-3, 0.2), hc.Wall("body", mass=0.5, stiffness=2e6))
    duration = view.result.attrs["duration"]
    assert duration == hc.auto_duration(model)
    ds = hc.simulate(model, duration, hc.Probes(5e-7))
    np.testing.assert_array_equal(view.body_force, ds.body_force.values)
    np.testing.assert_array_equal(view.force, ds.wall_force.values)
    assert np.argmax(view.body_force) < view.body_force.size - 100  # the mount's peak, not the record's end
    total = dict(view.energies)["total"]
    assert np.ptp(total) < 1e-6 * total[0]


def test_body_runs_last_the_automatic_duration_which_holds_the_swing_at_most_to_the_limit():
    """The explorer's config keeps duration = "auto" (what `hertzchain run` of the saved TOML redoes):
    behind a body, hertzchain.auto_duration holds half the mount's period past the pulse, at most
    MAX_BODY_DURATION; a slow mount's view is cut there (and the readout says so)."""
    free = ExplorerSettings(wall="body", body_stiffness=0.0, body_damping=50.0).config()
    assert free["run"]["duration"] == "auto"  # a free body: its dashpot force follows its velocity, no swing
    slow = ExplorerSettings(wall="body", body_mass=10.0, body_stiffness=1e4)  # swings in 0.2 s
    assert slow.config()["run"]["duration"] == "auto"
    assert mount_half_period(10.0, 1e4) > MAX_BODY_DURATION
    view = compute_view(slow)
    assert view.result.attrs["duration"] == pytest.approx(MAX_BODY_DURATION, rel=1e-12)
    with pytest.raises(ConfigError, match="wall.mass"):
        ExplorerSettings(wall="body", body_mass=None).config()  # an emptied box
    with pytest.raises(ConfigError, match="wall.mass"):
        compute_view(ExplorerSettings(wall="body", body_mass=-1.0))


def test_striker_mass_and_face():
    """A given striker mass equal to the sphere's own is the same run, bit for bit; a flat face meets
    bead 1 in a sphere-flat Hertz contact, kappa = 4/3 E* sqrt(R) with R the bead's radius (paper eq. 1
    with 1/R' = 0 for the striker)."""
    base = compute_view(ExplorerSettings())
    same = compute_view(ExplorerSettings(striker_mass=hc.Striker(8e-3, 0.2).mass))
    np.testing.assert_array_equal(same.force, base.force)
    flat = compute_view(ExplorerSettings(striker_shape="flat"))
    steel = hc.CATALOGUE["AISI52100"]
    e_star = 1.0 / (2.0 * (1.0 - steel.poisson ** 2) / steel.young)
    assert float(flat.result.kappa[0]) == pytest.approx(4.0 / 3.0 * e_star * math.sqrt(13e-3), rel=1e-12)
    heavy = compute_view(ExplorerSettings(striker_mass=0.0716))  # a striker as heavy as a 26 mm bead
    assert heavy.force.max() > 5 * base.force.max()


def test_gravity_starts_from_the_static_state():
    """A column on the wall: contact j carries the weight g (m_0 + ... + m_j) of the striker and the
    beads above it (docs/conventions.rst, gravity), and the energy (with gravity's) is conserved."""
    view = compute_view(ExplorerSettings(chain="uniform", uniform_n=10, taper_n=0, gravity=9.81))
    assert view.config["chain"]["gravity"] == 9.81
    masses = np.concatenate([[hc.Striker(8e-3, 0.2).mass], view.result.mass.values])
    np.testing.assert_allclose(view.result.contact_force.values[0], 9.81 * np.cumsum(masses), rtol=1e-9)
    total = dict(view.energies)["total"]
    assert np.ptp(total) < 1e-6 * total[0]
    assert "gravity" not in ExplorerSettings().config()["chain"]  # absent: a horizontal chain


def _synthetic_run(n_beads=12, n0=4, q=0.05, force_ratio=0.97, speed_ratio=1.02, velocity_ratio=1.06):
    """Cos^6 pulses at every contact with known geometric ratios, each followed by a larger, later
    'reflection', and the last WALL_BEADS beads spoilt: what measure_ratios must see through."""
    import xarray as xr

    phi = np.concatenate([np.full(n0, 26e-3), 26e-3 * (1 - q) ** np.arange(1, n_beads - n0 + 1)])
    dt, tau = 1e-7, 3e-5
    t = np.arange(0.0, 2e-3, dt)
    contacts = np.arange(n_beads + 1)
    arrival = 1e-4 + np.concatenate([[0.0], np.cumsum(phi / (500.0 * speed_ratio ** np.arange(1, n_beads + 1)))])

    def pulse(centre, power):
        u = (t - centre) / tau
        return np.where(np.abs(u) < np.pi / 2, np.cos(u) ** power, 0.0)

    peak = 5.0 * force_ratio ** contacts
    peak[n_beads - WALL_BEADS + 1:] *= 2.0  # the contacts that read the wall
    echo = arrival[-1] + (arrival[-1] - arrival) + 3 * tau
    # echoes larger than the pulses (less than the five times fit_pulse tells apart), and not in geometric
    # progression: taking one spoils the ratios
    force = np.stack([peak[j] * pulse(arrival[j], 6) + (2 + 0.15 * j) * peak[j] * pulse(echo[j], 6) for j in contacts], axis=1)
    bodies = np.arange(n_beads + 2)
    v_peak = 0.1 * velocity_ratio ** bodies.astype(float)
    v_peak[n_beads - WALL_BEADS + 1:] *= 0.5
    # bead n's velocity peaks on a sample between its two contacts' arrivals; the echo is larger
    centre = [np.round(0.5 * (arrival[max(n - 1, 0)] + arrival[min(n, n_beads)]) / dt) * dt for n in bodies]
    velocity = np.stack([v_peak[n] * pulse(centre[n], 4) + (2 + n) * v_peak[n] * pulse(echo[min(n, n_beads)] + tau, 4)
                         for n in bodies], axis=1)
    return xr.Dataset({"contact_force": (("time", "contact"), force), "velocity": (("time", "body"), velocity),
                       "diameter": (("bead",), phi)},
                      coords={"time": t, "contact": contacts, "bead": np.arange(1, n_beads + 1), "body": bodies})


def test_measured_ratios_recover_known_ratios_on_synthetic_pulses():
    ds = _synthetic_run()
    m = measure_ratios(ds, 4)
    np.testing.assert_array_equal(m.beads, np.arange(5, 12 - WALL_BEADS + 1))  # the taper, away from the wall
    assert m.force == pytest.approx(0.97, rel=1e-9) and m.force_err < 1e-9
    assert m.speed == pytest.approx(1.02, rel=1e-9)
    assert m.velocity == pytest.approx(1.06, rel=1e-12)
    uniform = ds.assign(diameter=("bead", np.full(12, 26e-3)))
    assert measure_ratios(uniform, 12).beads[0] == 4  # a uniform chain: past the striker transient
    with pytest.raises(hc.PulseNotFound, match="too few"):
        measure_ratios(ds, 8)


def test_measured_ratios_meet_the_ballistic_theory_where_it_holds():
    """Paper eqs. 6-8: a uniform chain calibrated to eps loses eps per bead in velocity and
    eps^(6/5) in force (Sec. III); along a gentle taper (q = 3 %, 20 beads) the pulse re-adapts
    bead by bead as the ballistic approximation assumes, and eqs. 6-8 hold to a few 1e-3."""
    view = compute_view(ExplorerSettings(chain="uniform", uniform_n=30, taper_n=0, law="dashpot_scaled"))
    m = measure_ratios(view.result, 30)
    assert m.velocity == pytest.approx(0.985, abs=1e-3)
    assert m.force ** (5 / 6) == pytest.approx(0.985, abs=1e-3)
    view = compute_view(ExplorerSettings(chain="uniform", uniform_n=10, taper_n=20, taper_q=0.03))
    m = measure_ratios(view.result, 10)
    theory = hc.ballistic_ratios(0.03, 1.0)
    assert m.speed == pytest.approx(theory.speed, rel=5e-4)
    assert m.velocity == pytest.approx(theory.velocity, rel=5e-3)
    assert m.force == pytest.approx(theory.force, rel=5e-3)
    rows = {r.equation: r for r in view.theory if r.equation in ("eq. 6", "eq. 8")}
    assert rows["eq. 8"].simulated.startswith(f"{m.speed:.4f} ± ") and "contact n, n = 11-28" in rows["eq. 8"].how
    assert rows["eq. 6"].simulated.startswith(f"{m.velocity:.4f} ± ")


def test_uniform_count():
    assert uniform_count(np.array([26, 26, 26, 24, 23.0])) == 3
    assert uniform_count(np.array([26, 26.0])) == 2


def test_bad_values_are_refused_naming_the_config_field():
    with pytest.raises(ConfigError, match="chain.diameters_mm"):
        compute_view(ExplorerSettings(chain="diameters", diameters_mm="26, x"))
    with pytest.raises(ConfigError, match="striker.velocity"):
        compute_view(ExplorerSettings(striker_velocity=-1.0))
    with pytest.raises(ConfigError, match="striker.velocity: the box is empty: type a number in m/s"):
        compute_view(ExplorerSettings(striker_velocity=None))  # an emptied number box


def test_explore_is_a_displayable_app_in_jupyter():
    pytest.importorskip("panel")
    app = hc.explore(striker_velocity=0.3)
    assert callable(getattr(app, "_repr_mimebundle_", None))  # what Jupyter calls to show it
    root = app.__panel__().get_root()  # the Bokeh model the notebook renders
    assert root.select_one({"name": "wall_source"}).data["force"].max() == app.view.force.max()
    peak = app.view.force.max()
    assert app.apply(striker_velocity=0.4).force.max() / peak == pytest.approx((0.4 / 0.3) ** 1.2, rel=0.02)
    # a refused value leaves the view as it was and says why
    assert app.apply(striker_velocity=-1.0) is None and "striker.velocity" in app.message.object
    # a protected body: its force is drawn beside the wall force, its peak quoted; a mount too slow
    # for the record is said to be cut short
    view = app.apply(wall="body", body_mass=10.0, body_stiffness=1e4)
    root = app.__panel__().get_root()
    assert root.select_one({"name": "body_source"}).data["force"].max() == view.body_force.max()
    assert f"{view.result.attrs['peak_body_force']:.4g} N" in app.readout.object
    assert "ends before the body's first swing" in app.readout.object
    assert app.widgets["body_mass"].visible and not app.apply(wall="flat").body_force
    assert not app.widgets["body_mass"].visible and len(root.select_one({"name": "body_source"}).data["force"]) == 0
    # Thornton's law: the plastic work and the deepest dent in the readout
    view = app.apply(law="elastoplastic", striker_velocity=2.0)
    assert f"{view.result.attrs['plastic_work']:.3g} J" in app.readout.object
    assert f"{view.result.attrs['residual_overlap_max'] * 1e6:.3g} µm" in app.readout.object
    app.apply(law="elastic", striker_velocity=0.3)
    # the function stays the package's attribute once the explorer's modules are imported
    import hertzchain.explorer.app  # noqa: F401
    assert math.isclose(hc.explore().view.force.max(), 8.511304981414646, rel_tol=1e-12)


def test_explore_command_without_panel_names_the_extra(monkeypatch, capsys):
    import sys

    monkeypatch.setitem(sys.modules, "panel", None)  # as if the [explore] extra were not installed
    assert main(["explore", "--port", "5999", "--no-browser"]) == 2
    err = capsys.readouterr().err
    assert "hertzchain[explore]" in err and "Traceback" not in err
