"""hertzchain animate and the positions probe: frames checked by their data."""

from __future__ import annotations

import numpy as np
import pytest

import hertzchain as hc
from hertzchain.viz import animation
from hertzchain.cli.main import main


def _model(n=8):
    return hc.Model(hc.Chain.uniform(n, 26e-3).append_taper(3, 0.06), hc.Striker(8e-3, 0.2), hc.Wall("flat"),
                    hc.Elastic())


@pytest.fixture(scope="module")
def with_positions():
    return hc.simulate(_model(), 1.2e-3, hc.Probes(sample_interval=1e-6, velocities=True, positions=True))


def test_positions_probe_is_exact_and_changes_nothing_else(with_positions):
    plain = hc.simulate(_model(), 1.2e-3, hc.Probes(sample_interval=1e-6, velocities=True))
    assert "displacement" not in plain  # ordinary runs stay small
    for name in ("contact_force", "velocity", "kinetic_energy", "potential_energy"):
        assert np.array_equal(plain[name].values, with_positions[name].values)
    u = with_positions.displacement.values
    assert u.shape == (with_positions.sizes["time"], 12) and np.all(u[0] == 0)
    ref = hc.simulate(_model(), 1.2e-3, hc.Probes(sample_interval=1e-6, positions=True), integrator="dop853",
                      rtol=1e-11)
    assert np.max(np.abs(ref.displacement.values - u)) < 1e-6 * np.max(np.abs(u))
    # the striker's displacement starts as v0 t
    assert u[1, 0] == pytest.approx(0.2 * 1e-6, rel=1e-3)
    with pytest.raises(hc.ConfigError, match="probes.positions"):
        hc.simulate_batch([_model()], 1e-4, hc.Probes(positions=True))


def test_frames_show_the_recorded_forces_and_positions(with_positions):
    ds = with_positions
    fr = animation.chain_frames(ds, 25)
    assert fr.time.size == 25 and fr.time[0] == 0 and fr.time[-1] == ds.time.values[-1]
    f = ds.contact_force.values[fr.index]
    assert np.array_equal(fr.force[:, 0], f[:, 0])
    assert np.allclose(fr.force[:, 1:], 0.5 * (f[:, :-1] + f[:, 1:]))
    phi = ds.diameter.values
    rest = np.concatenate([[-4e-3], np.cumsum(phi) - 0.5 * phi])
    assert np.allclose(fr.centre, rest + fr.exaggeration * ds.displacement.values[fr.index])
    assert fr.wall_x == pytest.approx(phi.sum())
    # default exaggeration: 1, 2 or 5 x 10^k, the largest bead displacement at most a quarter of
    # the smallest bead and at least a tenth of it (the beads visibly move; the rebounding
    # striker, hundreds of times farther, does not set the scale)
    mant = fr.exaggeration / 10 ** np.floor(np.log10(fr.exaggeration))
    assert round(mant, 9) in (1, 2, 5)
    beads = np.abs(ds.displacement.values[fr.index][:, 1:]).max()
    assert 0.1 * phi.min() <= fr.exaggeration * beads <= 0.25 * phi.min()
    assert np.abs(ds.displacement.values[:, 0]).max() > 50 * beads
    at_rest = animation.chain_frames(ds.drop_vars("displacement"), 5)
    assert at_rest.exaggeration == 0 and np.allclose(at_rest.centre, rest)
    with pytest.raises(hc.ConfigError, match="--exaggeration"):
        animation.chain_frames(ds.drop_vars("displacement"), 5, exaggeration=10)


def test_gif_has_the_frames_and_size(tmp_path, with_positions):
    from PIL import Image

    out = animation.animate(with_positions, tmp_path / "a.gif", n_frames=12, window=(0.2e-3, 1.0e-3))
    with Image.open(out) as im:
        assert im.format == "GIF" and im.n_frames == 12
        assert im.size == tuple(int(x * animation.FRAME_DPI) for x in animation.FRAME_INCHES)
        first = np.asarray(im.convert("RGB")).copy()
        im.seek(11)
        last = np.asarray(im.convert("RGB"))
    assert not np.array_equal(first, last)  # the frames move
    assert [p.name for p in tmp_path.iterdir()] == ["a.gif"]  # no temporary file left


def test_animate_cli_and_errors(tmp_path, with_positions, capsys, monkeypatch):
    path = tmp_path / "r.nc"
    hc.save(with_positions, path)
    assert main(["animate", str(path), "--out", str(tmp_path / "a.gif"), "--frames", "5", "-q"]) == 0
    capsys.readouterr()
    for args, words in ((["--frames", "1"], "--frames"), (["--fps", "0"], "--fps"),
                        (["--window", "3,4"], "--window")):
        assert main(["animate", str(path), "--out", str(tmp_path / "b.gif"), "-q", *args]) == 2
        assert words in capsys.readouterr().err
    assert main(["animate", str(path), "--out", str(tmp_path / "b.avi"), "-q"]) == 2
    monkeypatch.setattr(animation.shutil, "which", lambda name: None)
    assert main(["animate", str(path), "--out", str(tmp_path / "b.mp4"), "-q"]) == 2
    assert "ffmpeg" in capsys.readouterr().err
    only_wall = hc.simulate(_model(), 1.2e-3, hc.Probes(sample_interval=1e-6, contacts=()))
    hc.save(only_wall, tmp_path / "w.nc")
    assert main(["animate", str(tmp_path / "w.nc"), "--out", str(tmp_path / "b.gif"), "-q"]) == 2
    assert "every contact force" in capsys.readouterr().err
    assert not (tmp_path / "b.gif").exists()


def test_wall_force_grows_beside_the_chain_drawn_to_scale(with_positions):
    """Side by side: the trace's axes lies right of the chain's, the chain keeps one scale on both
    axes, and at frame k the trace is the recorded wall force up to the frame's time."""
    from hertzchain.viz.common import result_title

    ds = with_positions
    fr = animation.chain_frames(ds, 9, window=(0.1e-3, 1.1e-3))
    view = animation._frame_figure(ds, fr, result_title(ds, None))
    view.figure.canvas.draw()  # applies the equal aspect to the chain's box
    chain, trace_ax = view.chain_axes.get_position(), view.trace_axes.get_position()
    assert trace_ax.x0 > chain.x1  # beside, not below: the trace starts right of the chain's end
    assert trace_ax.y0 < chain.y1 and chain.y0 < trace_ax.y1  # and the two overlap in height
    # to scale: metres per pixel equal along and across the chain
    (x0, y0), (x1, y1) = view.chain_axes.transData.transform([(0.0, 0.0), (0.1, 0.1)])
    assert x1 - x0 == pytest.approx(y1 - y0, rel=1e-9)
    t_ms, wall = ds.time.values * 1e3, ds.wall_force.values
    for k in (0, 4, 8):
        view.show(k)
        x, y = view.trace.get_data()
        assert x[-1] == pytest.approx(fr.time[k] * 1e3, rel=1e-12)  # ends at the frame's time
        assert x[0] == pytest.approx(fr.time[0] * 1e3, rel=1e-12)
        span = slice(int(fr.index[0]), int(fr.index[k]) + 1)
        assert np.array_equal(x, t_ms[span]) and np.array_equal(y, wall[span])
    # the axis holds the whole window, so the trace grows inside a fixed frame
    assert view.trace_axes.get_xlim() == pytest.approx((fr.time[0] * 1e3, fr.time[-1] * 1e3))
    assert view.trace_axes.get_ylim()[1] >= wall[int(fr.index[0]): int(fr.index[-1]) + 1].max()
