"""The explorer in a real browser: ``hertzchain explore --port PORT --no-browser`` started as a
subprocess, Debian's headless Chromium (Selenium) types into a control as a user would, and the
plotted wall peak must become the one :func:`hertzchain.simulate` gives for the new settings;
with a protected body chosen and its mass and mount typed in, the plotted body force is the one
:func:`hertzchain.simulate` gives for that model.

Needs ``/usr/bin/chromium`` and ``/usr/bin/chromedriver`` (``.ci/run`` installs them): skipped
elsewhere with the reason, never skipped under CI.
"""

from __future__ import annotations

import os
import time
from urllib.parse import urlparse

import numpy as np
import pytest

from browser import (BODY, JS_HOSTS, JS_INPUT, JS_MAX, JS_TEXT, browser_missing, chromium, free_port, set_input,
                     show_body, start_explorer, stop, wait_for)

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


def test_page_loads_nothing_from_another_host_and_logs_no_error(page):
    wait_for(page, JS_MAX, "wall_source", "force")
    urls = page.execute_script(JS_HOSTS)
    assert urls, "the page reported no resources"
    foreign = [u for u in urls if urlparse(u).hostname not in ("127.0.0.1", "localhost", None)
               and not u.startswith(("data:", "blob:"))]
    assert not foreign
    # and no script failed in the page (Bokeh, Panel and the app's updates)
    assert not [e for e in page.get_log("browser") if e["level"] == "SEVERE"]
