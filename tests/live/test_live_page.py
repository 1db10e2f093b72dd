"""The live page in a real browser: headless Chromium (Debian's, installed by .ci/run)
driven by playwright loads the page of a simulated run and sees it work.

Nothing here asserts timing: every wait is for something to appear, with a timeout
long enough for a slow machine. The screenshot is kept in tests/artifacts/.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

HERE = Path(__file__).parent
ARTIFACTS = HERE.parent / "artifacts"
WAIT_MS = 180_000


def chromium_executable() -> str | None:
    """The system's Chromium (playwright drives it; it never downloads a browser)."""
    named = os.environ.get("LABRIG_CHROMIUM")
    candidates = [named] if named else []
    candidates += ["chromium", "chromium-browser", "google-chrome", "google-chrome-stable"]
    for name in candidates:
        path = shutil.which(name) if name else None
        if path:
            return path
    return None


@pytest.fixture(scope="module")
def browser():
    executable = chromium_executable()
    if executable is None:
        if os.environ.get("CI"):
            pytest.fail("no Chromium on CI: .ci/run installs it (apt-get install chromium)")
        pytest.skip(
            "no Chromium found (tried $LABRIG_CHROMIUM, chromium, chromium-browser, "
            "google-chrome); .ci/run installs Debian's: apt-get install chromium"
        )
    from playwright.sync_api import sync_playwright  # here: not in every worker's collection

    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=executable, headless=True)
        yield browser
        browser.close()


def count(page, selector: str) -> int:
    return page.locator(selector).count()


def open_page(browser, run, **options):
    """The run's page, with its script errors collected in ``page.errors`` and its
    failed requests in ``page.failed_requests``."""
    page = browser.new_page(**options)
    page.errors = []
    page.on("pageerror", lambda error: page.errors.append(str(error)))
    page.failed_requests = []  # told on a timeout (the page retries its polls itself)
    page.on("requestfailed", lambda r: page.failed_requests.append(f"{r.url}: {r.failure}"))
    page.goto(run.url)
    return page


def waiting(page, run, wait, *args):
    """``wait(*args)``; on a timeout, an AssertionError saying what the page and the
    run had to say (script errors, the live state, the run's last lines)."""
    from playwright.sync_api import TimeoutError as PlaywrightTimeout

    try:
        return wait(*args, timeout=WAIT_MS)
    except PlaywrightTimeout:
        live = page.evaluate(
            "({state: window.labrigLive.state, transitions: window.labrigLive.transitions,"
            " detection: window.labrigLive.detectionError, n: window.labrigLive.pressure.length})"
        )
        raise AssertionError(
            f"timed out on {args[0]!r}: page errors {page.errors}, failed requests "
            f"{page.failed_requests}, live {live}, "
            f"run: {''.join(run.lines[-15:])}"
        ) from None


def test_page_shows_data_growing_the_model_and_a_transition(live_run, browser):
    run = live_run("--live", "--live-hold", "30")
    page = open_page(browser, run, viewport={"width": 1360, "height": 760})

    # the data grow: a count of points drawn, then a larger one
    points = "Number(document.querySelector('#pv').dataset.points)"
    waiting(page, run, page.wait_for_function, f"{points} > 0")
    first = int(page.locator("#pv").get_attribute("data-points"))
    waiting(page, run, page.wait_for_function, f"{points} > {first}")
    assert count(page, "#pv polyline.current") == 1
    # the camera's frames come in batches, each a camera period or two after it was
    # taken (measured in the tracker's process meanwhile)
    waiting(page, run, page.wait_for_selector, "#lv polyline.current")
    assert count(page, "#lv polyline.current") == 1

    # the model's curve, dashed, with its predicted transitions
    model_points = "Number(document.querySelector('#pv').dataset.modelPoints)"
    waiting(page, run, page.wait_for_function, f"{model_points} > 100")
    model = page.evaluate("window.labrigLive.model")
    assert count(page, "#pv polyline.model") >= 1
    assert count(page, "#pv line.model-transition") == len(model["transitions"])
    # dashed by the page's stylesheet (seen once beside two CPU burners: the style not
    # yet applied when the curve was first drawn; a stylesheet that never arrives fails
    # here, with the failed requests)
    dashed = (
        "['', 'none'].indexOf(getComputedStyle("
        "document.querySelector('#pv polyline.model')).strokeDasharray) < 0"
    )
    waiting(page, run, page.wait_for_function, dashed)

    # a transition marker after the snap, near the model's first snap on inflation
    marker_or_end = (
        "document.querySelector('#pv circle.measured-transition') !== null"
        " || ['aborted', 'faulted'].includes(window.labrigLive.state.status)"
    )
    waiting(page, run, page.wait_for_function, marker_or_end)
    state = page.evaluate("[window.labrigLive.state.status, window.labrigLive.reason]")
    assert count(page, "#pv circle.measured-transition") >= 1, f"the run stopped: {state}"
    assert count(page, "#lv circle.measured-transition") >= 1
    measured = page.evaluate("window.labrigLive.transitions")[0]
    snaps = [t for t in model["transitions"] if t["direction"] == "inflate" and not t["stable"]]
    assert measured["direction"] == "inflate"
    assert abs(measured["v_ml"] - snaps[0]["v_ml"]) < 2.0, (measured, snaps)

    # the second repetition in colour over the first in grey, then the final status
    waiting(page, run, page.wait_for_selector, "#pv polyline.earlier[data-repetition='1']")
    waiting(page, run, page.wait_for_function, "window.labrigLive.state.status === 'complete'")
    assert page.locator("#pv polyline.current").get_attribute("data-repetition") == "2"
    assert page.locator("#banner").is_hidden()
    assert page.locator("#left").inner_text() == "0:00 min"
    assert page.errors == []

    ARTIFACTS.mkdir(exist_ok=True)
    shot = ARTIFACTS / "live_view.png"
    page.screenshot(path=str(shot), full_page=True)
    print(f"screenshot: {shot}")
    assert shot.stat().st_size > 10_000


def test_page_shows_an_interlock_trip_in_red(live_run, browser, tmp_path):
    protocol = tmp_path / "trip.yaml"
    text = (HERE / "live_demo.yaml").read_text()
    protocol.write_text(text.replace("max_pressure_kpa: 95", "max_pressure_kpa: 20"))
    run = live_run("--live", "--live-hold", "30", protocol=protocol)
    page = open_page(browser, run)
    waiting(page, run, page.wait_for_selector, "#banner:not([hidden])")
    banner = page.locator("#banner")
    assert "aborted" in banner.inner_text()
    assert "pressure" in banner.inner_text()
    colour = banner.evaluate("e => getComputedStyle(e).backgroundColor")
    assert colour == "rgb(221, 0, 0)"
    assert page.locator("#status").inner_text() == "aborted"
    ARTIFACTS.mkdir(exist_ok=True)
    page.screenshot(path=str(ARTIFACTS / "live_view_trip.png"), full_page=True)
