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
from hertzchain.explorer.compute import compute_view, uniform_count
from hertzchain.explorer.settings import ExplorerSettings


@pytest.mark.parametrize("changes", [
    {},
    {"chain": "chain2", "law": "viscoelastic", "eps": 0.98},
    {"chain": "uniform", "uniform_n": 10, "taper_n": 6, "taper_q": 0.08, "material": "brass", "law": "dashpot"},
    {"chain": "diameters", "diameters_mm": "20 20 20 18 16", "wall": "none", "striker_velocity": 0.1},
    {"law": "elastoplastic", "striker_velocity": 1.0},
    {"chain": "chain2", "bead_materials": "AISI52100 x 26, brass, brass", "wall_material": "brass"},
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


def test_uniform_count():
    assert uniform_count(np.array([26, 26, 26, 24, 23.0])) == 3
    assert uniform_count(np.array([26, 26.0])) == 2


def test_bad_values_are_refused_naming_the_config_field():
    with pytest.raises(ConfigError, match="chain.diameters_mm"):
        compute_view(ExplorerSettings(chain="diameters", diameters_mm="26, x"))
    with pytest.raises(ConfigError, match="striker.velocity"):
        compute_view(ExplorerSettings(striker_velocity=-1.0))


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
    # the function stays the package's attribute once the explorer's modules are imported
    import hertzchain.explorer.app  # noqa: F401
    assert math.isclose(hc.explore().view.force.max(), 8.511304981414646, rel_tol=1e-12)


def test_explore_command_without_panel_names_the_extra(monkeypatch, capsys):
    import sys

    monkeypatch.setitem(sys.modules, "panel", None)  # as if the [explore] extra were not installed
    assert main(["explore", "--port", "5999", "--no-browser"]) == 2
    err = capsys.readouterr().err
    assert "hertzchain[explore]" in err and "Traceback" not in err
