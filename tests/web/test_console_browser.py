"""The console page in Debian's headless chromium (selenium): every panel, the frame rate measured in the
page, press-and-release on the joystick, a socket lost mid-motion, the latched e-stop, a mission launched
from the page and a finding confirmed in it. Screenshots go to build/test-artifacts/console/."""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rsi.archive import Archive

from .conftest import ARTIFACTS, UVICORN_WEBSOCKETS_WARNING, Live

# uvicorn's websockets protocol (rsi.web.server.websocket_protocol) warns on every handshake
pytestmark = pytest.mark.filterwarnings(UVICORN_WEBSOCKETS_WARNING)

CHROMIUM, CHROMEDRIVER = Path("/usr/bin/chromium"), Path("/usr/bin/chromedriver")
PANELS = (
    "panel-video",
    "panel-scene",
    "panel-teleop",
    "panel-plots",
    "panel-inspect",
    "panel-mission",
    "panel-archive",
)
STOP_BUDGET_S = 0.2


@pytest.fixture(scope="module")
def page(live: Live) -> Iterator[Any]:
    """The console in headless chromium (skipped without it, failed when RSI_REQUIRE_BROWSER is set)."""
    missing = [str(path) for path in (CHROMIUM, CHROMEDRIVER) if not path.exists()]
    if missing:
        message = (
            f"headless chromium not found ({', '.join(missing)}): apt-get install chromium chromium-driver"
        )
        if os.environ.get("RSI_REQUIRE_BROWSER"):
            pytest.fail(message)
        pytest.skip(message)
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for flag in (
        "--headless",
        "--no-sandbox",
        "--disable-dev-shm-usage",
        "--enable-unsafe-swiftshader",
        "--window-size=1600,1250",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--disable-background-timer-throttling",
    ):
        options.add_argument(flag)  # fmt: skip
    driver = webdriver.Chrome(options=options, service=Service(executable_path=str(CHROMEDRIVER)))
    driver.get(f"{live.url}/?token={live.token}")
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    yield driver
    driver.quit()


def _wait(condition: Callable[[], Any], seconds: float, what: str) -> Any:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(0.1)
    pytest.fail(f"timed out after {seconds} s waiting for {what}")


def _click(page: Any, selector: str) -> None:
    """Click, again if the page re-drew the element in between (its tables refresh as data arrives)."""
    from selenium.common.exceptions import StaleElementReferenceException

    for _ in range(20):
        try:
            page.find_element("css selector", selector).click()
            return
        except StaleElementReferenceException:
            time.sleep(0.1)
    pytest.fail(f"{selector} kept going stale")


def _text(page: Any, selector: str) -> str:
    from selenium.common.exceptions import StaleElementReferenceException

    try:
        return str(page.find_element("css selector", selector).text)
    except StaleElementReferenceException:
        return ""


def _console(live: Live) -> Any:
    return live.console


def _tool_m(live: Live) -> np.ndarray:
    console = _console(live)
    with console.lock:
        return np.asarray(console.world.arm.tool_pose()[0])


def _take_control(page: Any) -> None:
    if not page.execute_script("return window.rsiConsole.controlling"):
        page.find_element("id", "acquire").click()
    _wait(lambda: page.execute_script("return window.rsiConsole.controlling"), 10, "the control lock")


def _drag_joystick(
    page: Any, offset_x_px: int, hold_s: float, *, offset_y_px: int = 0, release: bool = True
) -> Any:
    from selenium.webdriver.common.action_chains import ActionChains

    stick = page.find_element("id", "joystick")
    actions = ActionChains(page)
    actions.move_to_element(stick).click_and_hold().move_by_offset(offset_x_px, offset_y_px).perform()
    time.sleep(hold_s)
    if release:
        ActionChains(page).release().perform()
    return actions


def test_every_panel_is_there_and_each_view_runs_at_10_fps_in_the_page(page: Any, live: Live) -> None:
    for panel in PANELS:
        assert page.find_element("id", panel).is_displayed(), panel
    # past the page's start (three.js builds the scene in software while the first frames arrive: in the
    # whole suite's run the first 2 s windows read 7.3 and 9.7 frames/s, then 10.0 and 10.2)
    _wait(lambda: page.execute_script("return (window.rsiConsole.frames.raw || 0) > 60"), 90, "video frames")
    # the page's own 2 s window of arrivals, read over up to eight windows: a capability, so one window the
    # machine (2 cores shared with the browser and the test) stalls does not decide it
    windows = []
    for _ in range(8):
        time.sleep(2.5)
        windows.append(page.execute_script("return window.rsiConsole.fps"))
        if min(windows[-1][c] for c in ("raw", "compensated", "overview")) >= 10.0:
            break
    fps = windows[-1]
    ages = page.execute_script("return window.rsiConsole.age")
    assert min(fps[c] for c in ("raw", "compensated", "overview")) >= 10.0, windows
    assert max(ages.values()) < 1000.0, (
        ages
    )  # the badge's age: exposure to arrival (docs/console.md: ~30-60 ms)
    assert page.execute_script("return document.querySelector('#scene canvas') !== null")  # three.js drew
    page.save_screenshot(str(ARTIFACTS / "console-live.png"))
    video = live.get("/api/status").json()["video"]
    measured = {"page_fps_windows": windows, "page_age_ms": ages, "server_video": video}
    (ARTIFACTS / "console-live-fps.json").write_text(json.dumps(measured, indent=1))


def _moving_after(live: Live, since_s: float) -> list[float]:
    """Server times (its 44 Hz telemetry) after `since_s` at which the tool was still moving."""
    console = _console(live)
    with console.lock:
        return [s["t"] for s in console.telemetry if s["t"] > since_s and s["moving"]]


def test_press_and_release_on_the_joystick_moves_then_stops_the_arm(page: Any, live: Live) -> None:
    _take_control(page)
    before = _tool_m(live)
    console = _console(live)
    stops_before = len(console.stops)
    _drag_joystick(page, 0, 1.2, offset_y_px=-60)  # full push up: 5 cm/s toward the surface, blended (Fig. 4)
    released_s = time.monotonic()  # the server's clock too (time.monotonic)
    time.sleep(0.5)
    moved = float(np.linalg.norm(_tool_m(live) - before))
    assert moved > 0.02, moved
    stops = list(console.stops)[stops_before:]
    assert stops and stops[-1].reason in ("pointer up", "watchdog: heartbeat lost")
    assert max(stop.latency_s for stop in stops) <= STOP_BUDGET_S, (stops, console.loop_overrun_s)
    # measured on the server: not one 44 Hz sample moving later than 200 ms after the release
    assert not _moving_after(live, released_s + STOP_BUDGET_S)
    still = _tool_m(live)
    time.sleep(0.3)
    assert np.allclose(_tool_m(live), still, atol=1e-5)
    page.save_screenshot(str(ARTIFACTS / "console-teleop.png"))


def test_closing_the_socket_mid_motion_stops_the_arm(page: Any, live: Live) -> None:
    from selenium.webdriver.common.action_chains import ActionChains

    _take_control(page)
    console = _console(live)
    stops_before = len(console.stops)
    _drag_joystick(page, -60, 0.5, release=False)
    page.execute_script("window.rsiConsole.closeControl()")
    closed_s = time.monotonic()
    time.sleep(0.5)
    ActionChains(page).release().perform()
    # the server reads the close when the socket's task next runs (under a test worker's load on the other
    # core, more than 0.5 s later in two of four full runs), and frees the control lock then
    _wait(lambda: console.operator is None, 5, "the server to read the closed socket")
    reasons = [stop.reason for stop in list(console.stops)[stops_before:]]
    # the arm stopped when the socket closed, or (a page starved of CPU) the watchdog stopped it before
    assert reasons and reasons[-1] in ("socket closed", "watchdog: heartbeat lost"), reasons
    assert not _moving_after(live, closed_s + STOP_BUDGET_S)


def test_the_e_stop_latches_until_reset_in_the_page(page: Any, live: Live) -> None:
    _wait(lambda: page.execute_script("return window.rsiConsole.status !== null"), 10, "status")
    time.sleep(1.5)  # the control socket reconnects after the previous test closed it
    _take_control(page)
    page.find_element("id", "estop").click()
    _wait(lambda: "LATCHED" in page.find_element("id", "estop-state").text, 5, "the latched e-stop")
    before = _tool_m(live)
    _drag_joystick(page, 60, 0.6)
    assert np.allclose(_tool_m(live), before, atol=1e-5)  # latched: the joystick moves nothing
    assert _console(live).estop_latched
    reset = page.find_element("id", "estop-reset")
    _wait(reset.is_enabled, 5, "the reset button")
    reset.click()
    _wait(lambda: "clear" in page.find_element("id", "estop-state").text, 5, "the reset")
    _drag_joystick(page, 60, 0.6)
    assert float(np.linalg.norm(_tool_m(live) - before)) > 0.01


def test_a_mission_from_the_page_lists_its_findings_and_a_confirmed_one_is_archived(
    page: Any, live: Live
) -> None:
    from selenium.webdriver.support.ui import Select

    Select(page.find_element("id", "mission-setting")).select_by_value("small")
    # each visit's findings arrive while the mission runs (provisional), then the run's fused ones. The page
    # itself notes a provisional row shown under a "running" state line: polled from here, a busy machine
    # can pass the whole window between two polls (the suite under load, twice)
    page.execute_script(
        "window.sawProvisional = false;"
        "new MutationObserver(() => {"
        "  const running = document.getElementById('mission-state').textContent.startsWith('running');"
        "  if (running && document.querySelector('#mission-findings tr.mission-provisional'))"
        "    window.sawProvisional = true;"
        "}).observe(document.getElementById('mission-findings'), {childList: true, subtree: true});"
    )
    page.find_element("id", "mission-start").click()
    _wait(lambda: "finished" in page.find_element("id", "mission-state").text, 300, "the mission")
    assert page.execute_script("return window.sawProvisional"), "no visit's findings shown while it ran"
    provisional = live.get("/api/mission").json()["provisional"]
    assert provisional and {"vista", "kind", "confidence"} <= set(provisional[0])
    rows = _wait(
        lambda: page.find_elements("css selector", "#mission-findings tr.mission-finding"), 10, "findings"
    )
    assert len(rows) >= 1
    run_id = live.get("/api/mission").json()["run_id"]
    finding_id = live.get(f"/api/archive/runs/{run_id}/findings").json()[0]["id"]
    _click(page, f"#runs tr[data-run='{run_id}']")
    row = f"#findings tr[data-finding='{finding_id}']"
    _wait(lambda: page.find_elements("css selector", row), 10, "the run's findings")
    _click(page, f"{row} button.confirm")
    _wait(lambda: "confirmed" in _text(page, row), 10, "the verdict in the page")
    with Archive.open(live.archive) as store:
        assert store.reviews(finding_id)[-1].verdict == "confirmed"
    page.execute_script("document.getElementById('panel-archive').scrollIntoView()")
    page.save_screenshot(str(ARTIFACTS / "console-review.png"))
