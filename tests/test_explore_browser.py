"""The explorer in a real browser: ``hertzchain explore --port PORT --no-browser`` started as a
subprocess, Debian's headless Chromium (Selenium) types into a control as a user would, and the
plotted wall peak must become the one :func:`hertzchain.simulate` gives for the new settings;
with a protected body chosen and its mass and mount typed in, the plotted body force is the one
:func:`hertzchain.simulate` gives for that model; a typed per-bead profile is plotted as simulate
gives it, and a refused value is named on the page while the plot stays.

Needs ``/usr/bin/chromium`` and ``/usr/bin/chromedriver`` (``.ci/run`` installs them): skipped
elsewhere with the reason, never skipped under CI.
"""

from __future__ import annotations

import os
import time
from urllib.parse import urlparse

import numpy as np
import pytest

from browser import (BODY, JS_HOSTS, JS_INPUT, JS_MAX, JS_TEXT, browser_missing, choose, chromium, free_port,
                     set_input, show_body, start_explorer, stop, wait_for)

_missing = browser_missing()
if _missing and os.environ.get("CI"):
    raise RuntimeError(f"the browser test must run under CI: {_missing}")
pytestmark = pytest.mark.skipif(_missing is not None, reason=_missing or "")


def _simulated_peak(**changes) -> float:
    from hertzchain.config import build_model, build_probes, parse_config, simulate_config
    from hertzchain.explorer.settings import ExplorerSettings

    cfg = parse_config(ExplorerSettings(**changes).config())
    return float(simulate_config(cfg, build_model(cfg), build_probes(cfg)).wall_force.max())


@pytest.fixture(scope="module")
def page(request):
    port = free_port()
    proc = start_explorer(port)
    request.addfinalizer(lambda: stop(proc))  # stopped by its PID whatever happens
    with chromium() as driver:
        driver.get(f"http://127.0.0.1:{port}/")
        yield driver


def test_control_change_replots_the_wall_peak_simulate_gives(page):
    before = wait_for(page, JS_MAX, "wall_source", "force")
    assert before == pytest.approx(_simulated_peak(), rel=1e-12)
    start = time.perf_counter()
    set_input(page, "striker velocity [m/s]", "0.35")
    after = wait_for(page, JS_MAX, "wall_source", "force", until=lambda v: v is not None and v != before)
    elapsed = time.perf_counter() - start
    expected = _simulated_peak(striker_velocity=0.35)
    assert after == pytest.approx(expected, rel=1e-12)
    # Hertz scaling: the peak force of the solitary wave grows as v^(6/5) (paper eq. 5).
    assert after / before == pytest.approx((0.35 / 0.2) ** 1.2, rel=0.02)
    # the fit follows the new pulse, and the readout quotes the new peak
    assert wait_for(page, JS_MAX, "fit_source", "force", until=lambda v: v and v > 0.9 * expected) < 1.1 * expected
    readout = wait_for(page, JS_TEXT, "hc-peak", until=lambda v: v and v.endswith(" N") and float(v[:-2]) > 0.9 * expected)
    assert float(readout[:-2]) == pytest.approx(expected, rel=1e-3)  # the refined peak, quoted to 4 digits
    print(f"control change -> new plot: {elapsed * 1e3:.0f} ms")


def test_protected_body_plots_the_body_force_simulate_gives(page):
    """Choose "protected body", type a mass and a mount stiffness: the plotted force the mount passes
    to the ground is the body_force of hertzchain.simulate for that model, built here with the
    Python API (not through the explorer's config)."""
    import hertzchain as hc
    from hertzchain.explorer.settings import ExplorerSettings

    velocity = float(wait_for(page, JS_INPUT, "striker velocity [m/s]").get_attribute("value"))  # whatever ran before
    plotted = show_body(page)
    mass, stiffness = (float(v) for v in BODY.values())
    model = hc.Model(hc.paper_chain("chain1"), hc.Striker(8e-3, velocity), hc.Wall("body", mass=mass, stiffness=stiffness))
    # the explorer runs for the automatic duration (which holds half the mount's period past the pulse)
    assert ExplorerSettings(striker_velocity=velocity, wall="body", body_mass=mass,
                            body_stiffness=stiffness).config()["run"]["duration"] == "auto"
    ds = hc.simulate(model, "auto", hc.Probes(5e-7))
    assert plotted == pytest.approx(float(ds.body_force.max()), rel=1e-12)
    # the mount's peak lies inside the record (not cut at its end), and it is what the readout quotes
    assert int(np.argmax(ds.body_force.values)) < ds.time.size - 10
    quoted = wait_for(page, JS_TEXT, "hc-body-peak", until=lambda v: v and v.endswith(" N"))
    assert float(quoted[:-2]) == pytest.approx(ds.attrs["peak_body_force"], rel=1e-3)
    # the force on the body's face (wall_force) is drawn beside it, and it is simulate's too
    assert wait_for(page, JS_MAX, "wall_source", "force") == pytest.approx(float(ds.wall_force.max()), rel=1e-12)


def test_per_bead_profile_replots_and_a_refused_value_is_named_and_not_plotted(page):
    """Type a per-bead profile: the plot becomes simulate's for that chain (the box used to fail on
    the server, outside Bokeh's document lock, and leave the page stale). Then a diameter of 0 and a
    velocity of -1: each is named in red above the plots and the plot stays; a box still holding a
    refused value keeps the view from changing until it is corrected."""
    velocity = float(wait_for(page, JS_INPUT, "striker velocity [m/s]").get_attribute("value"))
    choose(page, "wall", "flat wall (the paper's sensor cap)")
    choose(page, "chain", "per-bead diameters")
    wait_for(page, JS_TEXT, "hc-readout", until=lambda v: v and v.startswith("13 beads") and "body" not in v)
    profile = "26, 26, 26, 26, 26, 26, 24, 22, 20, 18"
    set_input(page, "per-bead diameters [mm]", profile)
    wait_for(page, JS_TEXT, "hc-readout", until=lambda v: v and v.startswith("10 beads"))
    plotted = wait_for(page, JS_MAX, "wall_source", "force")
    expected = _simulated_peak(chain="diameters", diameters_mm=profile, striker_velocity=velocity)
    assert plotted == pytest.approx(expected, rel=1e-12)
    assert plotted != pytest.approx(_simulated_peak(striker_velocity=velocity), rel=1e-3)  # not chain 1's

    def refused(label, text, field):
        set_input(page, label, text)
        message = wait_for(page, JS_TEXT, "hc-message", until=lambda v: v and field in v)
        assert message.startswith("Not applied") and "last valid settings" in message
        assert page.execute_script(JS_MAX, "wall_source", "force") == plotted  # not re-plotted
        assert page.execute_script(JS_TEXT, "hc-readout").startswith("10 beads")
        return message

    assert "bead 2" in refused("per-bead diameters [mm]", "26, 0, 24", "chain.diameters_mm")
    set_input(page, "per-bead diameters [mm]", profile)  # corrected: the same profile, plotted again
    wait_for(page, JS_TEXT, "hc-message", until=lambda v: not v)
    assert "-1" in refused("striker velocity [m/s]", "-1", "striker.velocity")
    # another box changed while the velocity box holds -1: still refused, still the same plot
    refused("per-bead diameters [mm]", "26, 26, 26, 26, 26, 26, 26, 24, 22, 20", "striker.velocity")
    set_input(page, "striker velocity [m/s]", "0.3")
    wait_for(page, JS_TEXT, "hc-message", until=lambda v: not v)
    new = wait_for(page, JS_MAX, "wall_source", "force", until=lambda v: v is not None and v != plotted)
    assert new == pytest.approx(_simulated_peak(chain="diameters", diameters_mm="26, 26, 26, 26, 26, 26, 26, 24, 22, 20",
                                                striker_velocity=0.3), rel=1e-12)


def test_page_loads_nothing_from_another_host_and_logs_no_error(page):
    wait_for(page, JS_MAX, "wall_source", "force")
    urls = page.execute_script(JS_HOSTS)
    assert urls, "the page reported no resources"
    foreign = [u for u in urls if urlparse(u).hostname not in ("127.0.0.1", "localhost", None)
               and not u.startswith(("data:", "blob:"))]
    assert not foreign
    # and no script failed in the page (Bokeh, Panel and the app's updates)
    assert not [e for e in page.get_log("browser") if e["level"] == "SEVERE"]
