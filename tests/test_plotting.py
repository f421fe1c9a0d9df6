"""plot --kind signals|spacetime|energy: the pictures checked by their data, not by eye."""

from __future__ import annotations

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.viz import common, energy, signals, spacetime
from hertzchain.cli.main import main


def _model(n=10, velocity=0.2, striker=8e-3):
    return hc.Model(hc.Chain.uniform(n, 26e-3).append_taper(4, 0.06), hc.Striker(striker, velocity),
                    hc.Wall("flat"), hc.Elastic())


@pytest.fixture(scope="module")
def result():
    return hc.simulate(_model(), 1.6e-3, hc.Probes(sample_interval=1e-6, sensors=(5,)))


@pytest.fixture(scope="module")
def batch():
    return hc.simulate_batch([_model(velocity=v) for v in (0.1, 0.2, 0.4)], 1.2e-3,
                             hc.Probes(sample_interval=1e-6))


def test_spacetime_array_is_the_contact_forces(result):
    fig = spacetime.plot_spacetime(result)
    mesh = fig.axes[0].collections[0]
    f = result.contact_force.values
    assert np.array_equal(np.asarray(mesh.get_array()).reshape(f.shape), f)
    # The colour scale tops at the chain's largest force: the striker contact's short, larger force
    # (contact 0) is drawn saturated, with the colour bar's arrow, instead of fading the chain out.
    chain_max = f[:, result.contact.values >= 1].max()
    assert f[:, 0].max() > 1.5 * chain_max
    assert mesh.norm.vmin == 0 and mesh.norm.vmax == chain_max and mesh.colorbar.extend == "max"
    everything = spacetime.plot_spacetime(result, vmax=None).axes[0].collections[0]
    assert everything.norm.vmax == f.max() and everything.colorbar.extend == "neither"
    assert spacetime.plot_spacetime(result, vmax=2.5).axes[0].collections[0].norm.vmax == 2.5
    # columns are the contacts, rows the samples (ms)
    x, y = mesh.get_coordinates()[0, :, 0], mesh.get_coordinates()[:, 0, 1]
    assert np.allclose(0.5 * (x[1:] + x[:-1]), result.contact.values)
    assert np.allclose(0.5 * (y[1:] + y[:-1]), result.time.values * 1e3)


def test_spacetime_log_scale_and_beads_to_scale(result):
    fig = spacetime.plot_spacetime(result, scale="log", to_scale=True, floor=1e-3)
    mesh = fig.axes[0].collections[0]
    f = result.contact_force.values
    arr = mesh.get_array()
    shown = ~np.ma.getmaskarray(arr).reshape(f.shape)
    assert np.array_equal(shown, f > 1e-3 * f.max())
    assert np.array_equal(np.asarray(arr).reshape(f.shape)[shown], f[shown])
    # contacts at their positions: contact 0 at 0, contact N at the chain's length, bead contacts
    # at the touching points (sum of the diameters before them)
    x = common.contact_positions(result)
    phi = result.diameter.values
    assert x[0] == 0 and x[-1] == pytest.approx(phi.sum())
    assert np.allclose(x[1:-1], np.cumsum(phi)[:-1])
    edges = np.asarray(mesh.get_coordinates()[0, :, 0])
    assert np.all((edges[:-1] < x * 1e3) & (x * 1e3 < edges[1:]))  # each column holds its contact


def test_spacetime_bins_long_records_keeping_peaks():
    ds = hc.simulate(_model(), 1.2e-3, hc.Probes(sample_interval=1e-7))
    assert ds.sizes["time"] > spacetime.MAX_MAP_ROWS
    arr = np.asarray(spacetime.plot_spacetime(ds).axes[0].collections[0].get_array())
    k = -(-ds.sizes["time"] // spacetime.MAX_MAP_ROWS)
    rows = ds.sizes["time"] // k
    expect = ds.contact_force.values[: rows * k].reshape(rows, k, -1).max(axis=1)
    assert np.array_equal(arr.reshape(expect.shape), expect)
    assert arr.max() == ds.contact_force.values.max()


def _panel_checks(fig):
    """Every panel: the axis ranges cover the drawn data; the label (axes title) sits above the
    data area, so it cannot cover a curve."""
    renderer = fig.canvas.get_renderer()
    fig.draw(renderer)
    for ax in fig.axes:
        for line in ax.get_lines():
            x, y = line.get_xdata(), line.get_ydata()
            lo, hi = ax.get_ylim()
            assert lo <= np.min(y) and np.max(y) <= hi
            assert ax.get_xlim()[0] <= np.min(x) and np.max(x) <= ax.get_xlim()[1]
        title = ax.title.get_window_extent(renderer)
        assert title.y0 >= ax.get_window_extent(renderer).y1 - 1


def test_signals_window_and_ranges(result):
    fig = signals.plot_signals(result, window=(0.5e-3, 1.0e-3))
    labels = [ax.get_title(loc="left") for ax in fig.axes]
    assert labels == ["wall force", "sensor in bead 5"]
    sel = (result.time.values >= 0.5e-3) & (result.time.values <= 1.0e-3)
    line = fig.axes[0].get_lines()[0]
    assert np.allclose(line.get_xdata(), result.time.values[sel] * 1e3)
    assert np.array_equal(line.get_ydata(), result.wall_force.values[sel])
    assert fig.axes[0].get_xlim() == pytest.approx((0.5, 1.0))
    _panel_checks(fig)


def test_signals_of_a_batch_member(batch):
    with pytest.raises(hc.ConfigError, match="--member"):
        signals.plot_signals(batch)
    with pytest.raises(hc.ConfigError, match="member 7 is not in this file"):
        signals.plot_signals(batch, member=7)
    fig = signals.plot_signals(batch, member=2, signals=["wall_force", "contact_force"], contacts=[3])
    assert np.array_equal(fig.axes[0].get_lines()[0].get_ydata(), batch.wall_force.sel(member=2).values)
    assert np.array_equal(fig.axes[1].get_lines()[0].get_ydata(),
                          batch.contact_force.sel(member=2, contact=3).values)
    assert "0.4 m/s" in fig.texts[0].get_text() or "0.4 m/s" in fig._suptitle.get_text()
    mesh = spacetime.plot_spacetime(batch, member=1).axes[0].collections[0]
    f = batch.contact_force.sel(member=1).values
    assert np.array_equal(np.asarray(mesh.get_array()).reshape(f.shape), f)
    _panel_checks(fig)


def test_measured_signal_on_its_own_time_axis(result):
    from hertzchain.instrument import Instrument, measure_dataset

    ds = measure_dataset(result, wall=Instrument.pcb_208a11(seed=1, sample_rate=1e6, record_length=300))
    fig = signals.plot_signals(ds, signals=["measured_wall_force", "wall_force"])
    line = fig.axes[0].get_lines()[0]
    assert np.allclose(line.get_xdata(), ds.wall_scope_time.values * 1e3)
    assert np.array_equal(line.get_ydata(), ds.measured_wall_force.values)
    assert "trigger" in fig.axes[0].get_xlabel() and "trigger" not in fig.axes[1].get_xlabel()
    _panel_checks(fig)


def test_energy_lines_and_total(result):
    fig = energy.plot_energy(result)
    ax = fig.axes[0]
    lines = {l.get_label(): l.get_ydata() for l in ax.get_lines()}
    ke, pe, ed = (result[v].values * 1e3 for v in ("kinetic_energy", "potential_energy", "dissipated_energy"))
    assert np.array_equal(lines["kinetic"], ke) and np.array_equal(lines["potential"], pe)
    assert np.allclose(lines["total"], ke + pe + ed)
    # elastic chain: the total is the striker's kinetic energy, constant
    e0 = 0.5 * _model().striker.mass * 0.2**2 * 1e3
    assert np.allclose(lines["total"], e0, rtol=1e-5)
    renderer = fig.canvas.get_renderer()
    fig.draw(renderer)
    legend, axes_box = ax.get_legend().get_window_extent(renderer), ax.get_window_extent(renderer)
    assert legend.x0 >= axes_box.x1  # beside the data, not on it
    assert ax.get_ylim()[1] >= lines["total"].max()


def test_plot_cli(tmp_path, result, batch, capsys):
    path, bpath = tmp_path / "r.nc", tmp_path / "b.nc"
    hc.save(result, path)
    hc.save(batch, bpath)
    for kind in ("signals", "spacetime", "energy"):
        out = tmp_path / f"{kind}.png"
        assert main(["plot", str(path), "--out", str(out), "--kind", kind, "--window", "0.2,1.1"]) == 0
        assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main(["plot", str(bpath), "--out", str(tmp_path / "m.pdf"), "--member", "1", "--kind", "spacetime",
                 "--scale", "log", "--to-scale"]) == 0
    assert (tmp_path / "m.pdf").read_bytes()[:4] == b"%PDF"
    capsys.readouterr()
    for args, words in ((["--window", "2,1"], "--window"), (["--window", "5,6"], "--window"),
                        (["--window", "a"], "--window"), (["--member", "0"], "--member"),
                        (["--signal", "pressure"], "--signal"), (["--kind", "energy", "--scale", "log"], "--scale")):
        assert main(["plot", str(path), "--out", str(tmp_path / "x.png"), *args]) == 2, args
        err = capsys.readouterr().err
        assert words in err and "Traceback" not in err
    assert main(["plot", str(bpath), "--out", str(tmp_path / "x.png")]) == 2
    assert "--member" in capsys.readouterr().err
    (tmp_path / "bad.nc").write_text("not a result")
    assert main(["plot", str(tmp_path / "bad.nc"), "--out", str(tmp_path / "x.png")]) == 2
    assert main(["plot", str(path), "--out", str(tmp_path / "x.doc")]) == 2
    assert not (tmp_path / "x.png").exists()
