"""Browser machinery for the explorer's tests, its latency benchmark and its documentation
screenshot: ``hertzchain explore`` started as a subprocess, Debian's headless Chromium driven by
Selenium, controls found inside Bokeh's shadow DOM.

Run as a script to refresh the screenshot shown in the docs::

    python tests/browser.py --screenshot docs/_static/explorer.png
    python tests/browser.py --screenshot docs/_static/explorer_taper.png --taper
    python tests/browser.py --screenshot docs/_static/explorer_body.png --body
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request
from contextlib import contextmanager
from pathlib import Path

CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"
#: Without these Chromium tries the network (updates, sync, QUIC) and hangs on a machine without one.
CHROMIUM_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--disable-dev-shm-usage", "--window-size=1400,1100")


def browser_missing() -> str | None:
    """Why the browser tests cannot run here (None when they can)."""
    try:
        import selenium  # noqa: F401
        import panel  # noqa: F401
    except ImportError as exc:
        return f"{exc.name} is not installed (pip install -e '.[test]')"
    for path in (CHROMIUM, CHROMEDRIVER):
        if not Path(path).exists():
            return f"{path} is missing (apt-get install chromium chromium-driver; .ci/run does it)"
    return None


def free_port() -> int:
    """A TCP port nobody listens on now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def hertzchain_command() -> list[str]:
    """The ``hertzchain`` console script of this interpreter's environment."""
    script = Path(sys.executable).parent / "hertzchain"
    return [str(script)] if script.exists() else [sys.executable, "-m", "hertzchain.cli"]


def start_explorer(port: int, timeout: float = 120.0) -> subprocess.Popen:
    """``hertzchain explore --port PORT --no-browser`` in a subprocess, returned once the page answers."""
    proc = subprocess.Popen([*hertzchain_command(), "explore", "--port", str(port), "--no-browser"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env={**os.environ, "MPLBACKEND": "Agg"})
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise RuntimeError(f"hertzchain explore exited with {proc.returncode}:\n{proc.stdout.read()}")
        try:
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=5) as r:
                if r.status == 200:
                    return proc
        except OSError:
            time.sleep(0.3)
    stop(proc)
    raise RuntimeError(f"hertzchain explore did not answer on port {port} within {timeout:.0f} s")


def stop(proc: subprocess.Popen) -> None:
    """Stop the server by its PID (SIGTERM, then SIGKILL after 10 s)."""
    if proc.poll() is None:
        os.kill(proc.pid, signal.SIGTERM)
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait(10)


@contextmanager
def chromium():
    """A Selenium driver of headless Chromium with a fresh profile, quit at the end."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    profile = tempfile.mkdtemp(prefix="hc-chromium-")
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in CHROMIUM_FLAGS:
        options.add_argument(flag)
    options.add_argument(f"--user-data-dir={profile}")
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    driver.set_script_timeout(30)
    try:
        yield driver
    finally:
        driver.quit()
        shutil.rmtree(profile, ignore_errors=True)


#: JavaScript: the largest plotted value of a named data source's column (null before it exists).
JS_MAX = """
const doc = window.Bokeh && Bokeh.documents && Bokeh.documents[0];
if (!doc) return null;
const src = doc.get_model_by_name(arguments[0]);
if (!src) return null;
const y = src.data[arguments[1]];
if (!y || y.length === 0) return null;
let m = -Infinity; for (const v of y) if (v > m) m = v;
return m;
"""

#: JavaScript: the input element under a label with the given text, searched through shadow roots.
JS_INPUT = """
function* walk(root) {
  for (const el of root.querySelectorAll('*')) { yield el; if (el.shadowRoot) yield* walk(el.shadowRoot); }
}
for (const el of walk(document)) {
  if (el.tagName === 'LABEL' && el.textContent.trim() === arguments[0]) {
    const box = el.parentNode.querySelector('input, select');
    if (box) return box;
  }
}
return null;
"""

#: JavaScript: the text of the element with the given id, searched through shadow roots.
JS_TEXT = """
const id = arguments[0];
function find(root) {
  const hit = root.getElementById ? root.getElementById(id) : root.querySelector('#' + id);
  if (hit) return hit;
  for (const el of root.querySelectorAll('*')) if (el.shadowRoot) { const h = find(el.shadowRoot); if (h) return h; }
  return null;
}
const el = find(document);
return el ? el.textContent : null;
"""

#: JavaScript: the hosts of every script and stylesheet the page loaded (resource timing entries).
JS_HOSTS = """
return performance.getEntriesByType('resource').map(e => e.name)
  .concat([...document.scripts].map(s => s.src).filter(Boolean));
"""


def wait_for(driver, script: str, *args, timeout: float = 60.0, until=lambda v: v is not None):
    """Poll ``script`` in the page until ``until(value)``; the value (TimeoutError when it never holds)."""
    deadline = time.monotonic() + timeout
    while True:
        value = driver.execute_script(script, *args)
        if until(value):
            return value
        if time.monotonic() > deadline:
            raise TimeoutError(f"page state did not arrive within {timeout:.0f} s (last value {value!r})")
        time.sleep(0.02)


def set_input(driver, label: str, text: str) -> None:
    """Type ``text`` into the input labelled ``label`` as a user would, and commit it (Enter)."""
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.keys import Keys

    box = wait_for(driver, JS_INPUT, label)
    box.click()
    # select the old value and type over it, as a user would: a number box emptied first shows
    # "NaN" (Bokeh's spinner) while the server still receives the typed number
    ActionChains(driver).key_down(Keys.CONTROL).send_keys("a").key_up(Keys.CONTROL).send_keys(text, Keys.ENTER).perform()


def choose(driver, label: str, option: str) -> None:
    """Pick ``option`` (its visible text) in the drop-down list labelled ``label``, as a user would."""
    from selenium.webdriver.support.select import Select

    Select(wait_for(driver, JS_INPUT, label)).select_by_visible_text(option)


#: The protected body of the screenshot and the browser test: 0.5 kg on a 2e6 N/m mount (its half
#: period 1.6 ms), typed into the page.
BODY = {"protected body: mass [kg]": "0.5", "protected body: mount stiffness [N/m]": "2000000"}
BODY_OPTION = "protected body (mass on a mount)"


def show_body(driver, values: dict = BODY) -> float:
    """Choose the protected body and type its values, as a user would; the plotted body force peak
    once the last value is on the page."""
    choose(driver, "wall", BODY_OPTION)
    peak = wait_for(driver, JS_MAX, "body_source", "force", until=lambda v: v is not None)
    for label, text in values.items():
        set_input(driver, label, text)
        peak = wait_for(driver, JS_MAX, "body_source", "force", until=lambda v, p=peak: v is not None and v != p)
    return peak


def screenshot(out: Path, taper: bool = False, body: bool = False) -> None:
    """Open the explorer and save a screenshot of the page; with ``taper``, first switch to a
    uniform block + taper with Kuwabara-Kono contacts (the taper's controls shown); with ``body``,
    to a protected body (:data:`BODY`) with the size-scaled dashpot (the reproduction's law)."""
    port = free_port()
    proc = start_explorer(port)
    try:
        with chromium() as driver:
            driver.get(f"http://127.0.0.1:{port}/")
            peak = wait_for(driver, JS_MAX, "wall_source", "force")
            if taper:
                choose(driver, "chain", "uniform block + taper")
                peak = wait_for(driver, JS_MAX, "wall_source", "force", until=lambda v: v is not None and v != peak)
                choose(driver, "contact law", "Kuwabara-Kono, calibrated to eps")
                wait_for(driver, JS_MAX, "wall_source", "force", until=lambda v: v is not None and v != peak)
            if body:
                show_body(driver)
                peak = wait_for(driver, JS_MAX, "wall_source", "force")
                choose(driver, "contact law", "size-scaled dashpot, calibrated to eps (the reproduction's)")
                wait_for(driver, JS_MAX, "wall_source", "force", until=lambda v: v is not None and v != peak)
            time.sleep(1.0)
            # the whole page, however tall the controls and the theory table make it
            height = driver.execute_script("return document.documentElement.scrollHeight")
            driver.set_window_size(1400, max(1100, int(height) + 40))
            driver.execute_script("document.activeElement.blur(); window.scrollTo(0, 0);")
            time.sleep(0.5)
            out.parent.mkdir(parents=True, exist_ok=True)
            driver.save_screenshot(str(out))
    finally:
        stop(proc)


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--screenshot", type=Path, required=True, help="PNG file to write")
    parser.add_argument("--taper", action="store_true", help="a uniform block + taper, Kuwabara-Kono contacts")
    parser.add_argument("--body", action="store_true", help="a protected body, the size-scaled dashpot")
    args = parser.parse_args()
    screenshot(args.screenshot, taper=args.taper, body=args.body)
