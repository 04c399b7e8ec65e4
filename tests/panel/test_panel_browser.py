"""The panel in a real browser (Debian's chromium and chromedriver through selenium).

One shop for the module, all real processes: ``mppf sim`` (the simulated PLC), ``mppf panel``
(finding the PLC from the audit log of the running ``mppf press``), and ``mppf press`` driving
the plate's next cycle. The tests run in order: the placement view shows the cut outline's
corners, the stroke map follows the PLC while the press moves, STOP in the page stops the
press, the loop and history views, "link lost" when the simulated PLC is killed, and the login
of a panel with a token (which never appears in its log). Each view is photographed at
1280 x 800 and 1920 x 1080 into the test's folder (and into ``$MPPF_PANEL_SHOTS`` when set).
"""

from __future__ import annotations

import functools
import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from panel_helpers import record_loop, wait_until

from mppf.model.placement import placement_of
from mppf.planning.job import load_job
from mppf.model.press import press_to_toml

pytestmark = pytest.mark.slow

SIZES = ((1280, 800), (1920, 1080))
TOKEN = "browser-test-token-0123456789"
CHROME_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                "--disable-component-update", "--disable-sync", "--no-first-run", "--hide-scrollbars")


def _need(what: str):
    """Fail on CI (CI=true), skip elsewhere: the browser tests need an outside program."""
    message = f"the browser tests need {what} (apt-get install chromium chromium-driver; pip install selenium)"
    if os.environ.get("CI") == "true":
        pytest.fail(message)
    pytest.skip(message)


@pytest.fixture(scope="module")
def browser():
    chromium, chromedriver = shutil.which("chromium"), shutil.which("chromedriver")
    if not (chromium and chromedriver):
        _need("chromium and chromedriver")
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        _need("selenium")
    options = webdriver.ChromeOptions()
    options.binary_location = chromium
    for flag in CHROME_FLAGS:
        options.add_argument(flag)
    profile = tempfile.mkdtemp(prefix="mppf-chromium-")
    options.add_argument(f"--user-data-dir={profile}")
    driver = webdriver.Chrome(options=options, service=Service(chromedriver))
    driver.set_page_load_timeout(30)
    yield driver
    driver.quit()
    shutil.rmtree(profile, ignore_errors=True)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _mppf(*args, log: Path, env: dict) -> subprocess.Popen:
    with log.open("w") as out:  # the child keeps its own copy of the file
        return subprocess.Popen([sys.executable, "-m", "mppf", *args], stdout=out, stderr=subprocess.STDOUT, env=env,
                                stdin=subprocess.DEVNULL)


_wait = functools.partial(wait_until, poll_s=0.1)
"""Wait for a page or process condition, polled every 0.1 s."""


def _answers(url: str) -> bool:
    try:
        with urllib.request.urlopen(url, timeout=1):
            return True
    except OSError:
        return False


class Shop:
    """The processes of the test shop and their logs."""

    def __init__(self, folder: Path, job_path: Path):
        self.folder, self.job_path, self.procs = folder, job_path, {}
        self.env = {**os.environ, "MPPF_HOME": str(folder)}
        self.plc_port, self.panel_port = _free_port(), _free_port()
        self.plc_url = f"tcp://127.0.0.1:{self.plc_port}?unit=1"
        self.base = f"http://127.0.0.1:{self.panel_port}"
        self.shots = folder / "shots"
        self.shots.mkdir()

    def start(self, name: str, *args) -> subprocess.Popen:
        self.procs[name] = _mppf(*args, log=self.folder / f"{name}.log", env=self.env)
        return self.procs[name]

    def log(self, name: str) -> str:
        return (self.folder / f"{name}.log").read_text()

    def stop_all(self):
        for proc in self.procs.values():
            if proc.poll() is None:
                proc.terminate()
        for proc in self.procs.values():
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()


@pytest.fixture(scope="module")
def shop(tmp_path_factory, planned_plate):
    _, _, _, job = planned_plate
    folder = tmp_path_factory.mktemp("shop")
    record_loop(folder / "history.sqlite", job, folder / "plates" / "B12-P3", measured=2).close()
    shop = Shop(folder, folder / "plates" / "B12-P3" / "cycle-03.job.json")
    (folder / "press.toml").write_text(press_to_toml(job.press))  # this machine's press, installed once
    shop.start("sim", "sim", "--port", str(shop.plc_port), "--time-scale", "1")
    _wait(lambda: "listening" in shop.log("sim"), 20, "the simulated PLC")
    shop.start("panel", "panel", "--port", str(shop.panel_port))  # finds the PLC in the audit log
    _wait(lambda: _answers(shop.base + "/api/live"), 20, "the panel")
    yield shop
    shop.stop_all()


def shoot(browser, shop: Shop, name: str):
    """Photograph the page at both sizes (the page is reloaded at each, so its layout is fresh)."""
    for width, height in SIZES:
        browser.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                                {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False})
        time.sleep(1.0)
        path = shop.shots / f"{name}-{width}x{height}.png"
        browser.save_screenshot(str(path))
        if os.environ.get("MPPF_PANEL_SHOTS"):
            Path(os.environ["MPPF_PANEL_SHOTS"]).mkdir(parents=True, exist_ok=True)
            shutil.copy(path, Path(os.environ["MPPF_PANEL_SHOTS"]) / path.name)


def _by_id(browser, element_id):
    from selenium.webdriver.common.by import By

    return browser.find_element(By.ID, element_id)


def test_placement_view_shows_the_cut_outlines_corners(browser, shop):
    from selenium.webdriver.common.by import By

    placement = placement_of(load_job(shop.job_path).layout)
    browser.get(shop.base + "/place")
    rows = browser.find_elements(By.CSS_SELECTOR, "#corners tbody tr")
    shown = [[cell.text for cell in row.find_elements(By.TAG_NAME, "td")] for row in rows]
    expected = [[f"{name}{' mark' if k == 0 else ''}", f"{x:.0f}", f"{y:.0f}"]
                for k, (name, (x, y)) in enumerate(zip(placement.corner_names, placement.cut_corners_mm))]
    assert shown == expected
    labels = browser.find_elements(By.CSS_SELECTOR, "svg.bed text[data-corner]")
    assert [label.text for label in labels] == [f"{n} {x:.0f}, {y:.0f}" for n, (x, y) in
                                               zip(placement.corner_names, placement.cut_corners_mm)]
    assert "cycle 3" in browser.find_element(By.CSS_SELECTOR, "aside.side").text
    shoot(browser, shop, "place")


def _followed_punch(job_path: Path) -> tuple[str, float]:
    """The lower punch of step 1 with the longest travel from parking: its id prefix on the page and its target."""
    job = load_job(job_path)
    _, lower = job.steps[0].setpoints_mm(job.press)
    r, c = np.unravel_index(np.argmax(np.abs(lower - job.press.lower.park_mm)), lower.shape)
    return f"lower-actual-r{r + 1}-c{c + 1}", float(lower[r, c])


def test_the_stroke_map_follows_the_plc(browser, shop):
    shop.start("press", "press", str(shop.job_path), "--plc", shop.plc_url, "--yes")
    browser.get(shop.base + "/live")
    _wait(lambda: _by_id(browser, "state").text == "MOVING", 30, "the page showing the motion")
    assert shop.plc_url in _by_id(browser, "link").text
    with urllib.request.urlopen(shop.base + "/api/live", timeout=5) as reply:
        source = json.load(reply)["live"]["link"]["source"]
    assert source.startswith("from the audit log: mppf press"), source  # found without --plc
    cell, target_mm = _followed_punch(shop.job_path)
    seen = []
    for _ in range(8):
        seen.append(float(_by_id(browser, cell).get_attribute("data-mm")))
        time.sleep(0.3)
    assert len(set(seen)) >= 5, seen  # refreshed at least twice a second while the punch moves
    towards = np.sign(target_mm - seen[0]) * np.diff(seen)
    assert np.all(towards >= 0) and towards.sum() > 5.0, seen  # towards its target, never back
    assert float(_by_id(browser, cell.replace("actual", "target")).get_attribute("data-mm")) == \
        pytest.approx(target_mm, abs=0.01)
    shoot(browser, shop, "live-moving")


def test_stop_in_the_page_stops_the_press(browser, shop):
    button = _by_id(browser, "stop")
    assert button.text.splitlines() == ["STOP", "software stop"]
    button.click()
    _wait(lambda: "STOP sent" in _by_id(browser, "banner").text, 5, "the page confirming STOP")
    press = shop.procs["press"]
    assert press.wait(30) != 0  # the other master saw its step end short
    assert "STOP" in shop.log("press") or "not in position" in shop.log("press")
    _wait(lambda: _by_id(browser, "state").text == "STOPPED", 10, "the press stopped (PLC state STOPPED)")
    cell, target_mm = _followed_punch(shop.job_path)
    first = float(_by_id(browser, cell).get_attribute("data-mm"))
    time.sleep(1.5)
    assert float(_by_id(browser, cell).get_attribute("data-mm")) == first
    assert abs(first - target_mm) > 10.0  # stopped on its way
    shoot(browser, shop, "live-stopped")


def test_loop_and_history_views(browser, shop):
    from selenium.webdriver.common.by import By

    browser.get(shop.base + "/loop")
    assert _by_id(browser, "verdict").text.startswith("OUT OF TOLERANCE")
    assert len(browser.find_elements(By.CSS_SELECTOR, ".dev-maps svg.heat")) == 3  # 2 cycles + the correction
    shoot(browser, shop, "loop")
    browser.get(shop.base + "/history")
    assert "B12-P3" in _by_id(browser, "plates").text
    shoot(browser, shop, "history")
    browser.get(shop.base + "/history/B12-P3")
    assert len(browser.find_elements(By.CSS_SELECTOR, "#cycles tbody tr")) == 3
    shoot(browser, shop, "history-plate")


def test_link_lost_when_the_plc_stops_answering(browser, shop):
    browser.get(shop.base + "/live")
    _wait(lambda: _by_id(browser, "link").text.startswith("link ok"), 10, "the link")
    shop.procs["sim"].kill()
    _wait(lambda: _by_id(browser, "link").text.startswith("LINK LOST"), 5, "LINK LOST on the page")
    assert _by_id(browser, "state").text == "LINK LOST"
    shoot(browser, shop, "live-link-lost")


def test_a_panel_with_a_token_asks_for_it_and_never_logs_it(browser, shop):
    from selenium.webdriver.common.by import By

    port = _free_port()
    env = {**shop.env, "MPPF_PANEL_TOKEN": TOKEN}
    log = shop.folder / "panel-token.log"
    proc = _mppf("panel", "--port", str(port), "--plc", shop.plc_url, log=log, env=env)
    try:
        base = f"http://127.0.0.1:{port}"
        _wait(lambda: _answers(base + "/login"), 20, "the panel with a token")
        browser.get(base + "/live")
        assert browser.current_url == base + "/login"
        shoot(browser, shop, "login")
        browser.find_element(By.ID, "token").send_keys(TOKEN)
        browser.find_element(By.CSS_SELECTOR, "form button").click()
        _wait(lambda: browser.current_url == base + "/live", 10, "the live view after the login")
        _by_id(browser, "stop").click()  # the PLC is gone: STOP is reported as not sent
        _wait(lambda: "STOP NOT SENT" in _by_id(browser, "banner").text, 10, "the STOP report")
    finally:
        proc.terminate()
        proc.wait(10)
    text = log.read_text()
    assert "POST /stop" in text and "POST /login" in text  # the access log is there...
    assert TOKEN not in text  # ... without the token
