"""How long the explorer takes from a control change to the updated plot, in a real browser.

``hertzchain explore`` is started as a subprocess and opened in headless Chromium (the project's
browser-test machinery, ``tests/browser.py``); the striker-velocity box is set to a new value as a
user would (the digits typed, then Enter), ``REPEAT`` times with alternating values on the
paper's 30-bead chain 1, in two views:

- ``paper``: the first view (a flat wall, elastic contacts);
- ``body``: a protected body (0.5 kg on a 2e6 N/m mount, run past the pulse by half the mount's
  period) with the size-scaled dashpot calibrated to eps = 0.985 (the reproduction's law; every
  new striker speed is calibrated once, then cached).

The clock starts when Enter is sent and stops when the browser's copy of the plotted wall force
(the Bokeh data source) holds the new run; polled every 5 ms, so a time is at most ~5 ms late.
The server-side share (config, simulation, fit, map, energies, the theory table with its measured
ratios) is the explorer's own "computed in" figure.

Run from the repository root (needs the ``[explore]`` extra, selenium, ``/usr/bin/chromium`` and
``/usr/bin/chromedriver``)::

    python benchmarks/explore_latency.py      # prints, and writes benchmarks/results/explore_latency.json
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time

from pathlib import Path

from _common import RESULTS, REPO, machine_info

sys.path.insert(0, str(REPO / "tests"))
from browser import (JS_INPUT, JS_MAX, JS_TEXT, chromium, choose, free_port, show_body,  # noqa: E402
                     start_explorer, stop, wait_for)

REPEAT = 12
VELOCITIES = (0.35, 0.2, 0.5, 0.25)


def _changes(driver, peak: float) -> tuple[list[float], list[float]]:
    """REPEAT velocity changes: (browser latencies [s], server compute times [s])."""
    from selenium.webdriver.common.keys import Keys

    latencies, computed = [], []
    for k in range(REPEAT):
        v = VELOCITIES[k % len(VELOCITIES)]
        box = wait_for(driver, JS_INPUT, "striker velocity [m/s]")
        box.click()
        old = box.get_attribute("value") or ""
        box.send_keys(Keys.END, *[Keys.BACKSPACE] * (len(old) + 2), str(v))
        t0 = time.perf_counter()
        box.send_keys(Keys.ENTER)
        peak = wait_for(driver, JS_MAX, "wall_source", "force", until=lambda x, p=peak: x is not None and x != p)
        latencies.append(time.perf_counter() - t0)
        readout = wait_for(driver, JS_TEXT, "hc-readout", until=lambda x: x and "computed in" in x)
        computed.append(float(readout.split("computed in ")[1].split(" ms")[0]) * 1e-3)
    return latencies, computed


def _summary(latencies: list[float], computed: list[float]) -> dict:
    return {"latency_s": {"median": statistics.median(latencies), "min": min(latencies), "max": max(latencies),
                          "all": latencies},
            "server_compute_s": {"median": statistics.median(computed), "min": min(computed), "max": max(computed)}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", type=Path, default=RESULTS / "explore_latency.json", help="where to save the results")
    args = ap.parse_args()
    port = free_port()
    started = time.perf_counter()
    proc = start_explorer(port)
    server_start = time.perf_counter() - started
    scenarios = {}
    try:
        with chromium() as driver:
            t0 = time.perf_counter()
            driver.get(f"http://127.0.0.1:{port}/")
            peak = wait_for(driver, JS_MAX, "wall_source", "force")
            first_page = time.perf_counter() - t0
            scenarios["paper"] = _summary(*_changes(driver, peak))
            show_body(driver)
            peak = wait_for(driver, JS_MAX, "wall_source", "force")
            choose(driver, "contact law", "size-scaled dashpot, calibrated to eps (the reproduction's)")
            peak = wait_for(driver, JS_MAX, "wall_source", "force", until=lambda x, p=peak: x is not None and x != p)
            scenarios["body"] = _summary(*_changes(driver, peak))
    finally:
        stop(proc)
    result = {
        "what": "explorer: control change (Enter in the striker-velocity box) -> plotted wall force updated, "
                "paper's chain 1 (30 beads), headless Chromium; 'paper': flat wall, elastic; 'body': a protected "
                "body (0.5 kg, 2e6 N/m) and the size-scaled dashpot calibrated to eps = 0.985",
        "repeat": REPEAT,
        **scenarios["paper"],
        "scenarios": scenarios,
        "server_start_s": server_start,
        "first_page_s": first_page,
        "machine": machine_info(),
    }
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(result, indent=2) + "\n")
    for name, sc in scenarios.items():
        lat, comp = sc["latency_s"], sc["server_compute_s"]
        print(f"{name}: control change -> new plot: median {lat['median'] * 1e3:.0f} ms (min {lat['min'] * 1e3:.0f}, "
              f"max {lat['max'] * 1e3:.0f}, {REPEAT} changes); of which computing the view: median "
              f"{comp['median'] * 1e3:.0f} ms (max {comp['max'] * 1e3:.0f})")
    print(f"server start {server_start:.1f} s, first page {first_page:.1f} s; "
          f"load average {result['machine'].get('load_average_at_start')}")


if __name__ == "__main__":
    main()
