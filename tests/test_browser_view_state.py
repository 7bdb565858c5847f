"""The page's view state (preview camera, hand trails, follow edits, pick mode) in real
Chromium: set with the page's own controls, it travels in the link and the session file
and comes back in a fresh page's controls."""

from __future__ import annotations

import json
import time

import pytest
from conftest import open_page, pane_text

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def browser_and_url(browser, demo_url):
    """(the run's Chromium, the URL of the run's shared demo server)."""
    return browser, demo_url


def _open(browser, url: str):
    """A fresh tab at ``url`` once its matrix shows a path and its preview an image."""
    page = open_page(browser, url, timeout_s=180)
    page.locator(".hs-preview-image img").wait_for(timeout=90_000)
    return page


def _preview_src(page) -> str:
    return page.locator(".hs-preview-image img").get_attribute("src") or ""


def _controls(page) -> dict:
    """The view state as a person reads it off the page's controls."""
    pick = page.locator(".hs-click-mode button", has_text="Pick frames")
    return {
        "camera": page.locator(".hs-camera select").input_value(),
        "trails": page.locator(".hs-trails input[type=checkbox]").is_checked(),
        "follow": page.locator(".hs-follow input[type=checkbox]").is_checked(),
        "pick": "bk-active" in (pick.get_attribute("class") or ""),
    }


def _wait_controls(page, want: dict, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while (seen := _controls(page)) != want:
        assert time.monotonic() < deadline, f"controls show {seen}, expected {want}"
        page.wait_for_timeout(100)


def test_view_state_set_in_the_page_comes_back_from_link_and_session_file(
    browser_and_url, tmp_path
):
    browser, url = browser_and_url
    page = _open(browser, url)
    default = {"camera": "three-quarter", "trails": False, "follow": True, "pick": False}
    assert _controls(page) == default
    before = _preview_src(page)

    # a person changes the view with the page's controls
    page.locator(".hs-camera select").select_option("side")
    page.locator(".hs-trails input[type=checkbox]").check()
    page.locator(".hs-follow input[type=checkbox]").uncheck()
    page.locator(".hs-click-mode button", has_text="Pick frames").click()
    want = {"camera": "side", "trails": True, "follow": False, "pick": True}
    _wait_controls(page, want)
    page.wait_for_function("() => hs.model('hs-point-tool').add === false")
    deadline = time.monotonic() + 90
    while _preview_src(page) == before:  # the side camera with trails re-renders the preview
        assert time.monotonic() < deadline, "the preview did not follow the camera"
        page.wait_for_timeout(200)

    link = page.locator(".hs-share-url input")
    deadline = time.monotonic() + 30
    while "pick=1" not in (shared := link.input_value()):
        assert time.monotonic() < deadline, f"the link does not follow the view: {shared}"
        page.wait_for_timeout(100)
    assert all(f in shared for f in ("camera=side", "trails=1", "follow=0", "pick=1"))
    # the address bar carries it too (it follows the link field once the view is still)
    query = shared[shared.index("?") :]
    deadline = time.monotonic() + 30
    while not page.url.endswith(query):
        assert time.monotonic() < deadline, f"the address bar does not follow: {page.url}"
        page.wait_for_timeout(100)

    with page.expect_download(timeout=60_000) as info:
        page.locator(".hs-download-session button").click()
    saved = tmp_path / "view.json"
    info.value.save_as(saved)
    assert {k: json.loads(saved.read_text())["view"][k] for k in want} == want

    # the link, opened in a fresh tab: its controls show the view, the matrix picks frames
    other = _open(browser, shared)
    try:
        _wait_controls(other, want)
        other.wait_for_function("() => hs.model('hs-point-tool').add === false")
        npts = len(other.evaluate("hs.cols('hs-points-source', ['x'])")["x"])
        path = other.evaluate("hs.cols('hs-path-source', ['x', 'y'])")
        k = len(path["x"]) // 2
        other.mouse.click(*other.evaluate(f"hs.xy({path['x'][k]}, {path['y'][k]})"))
        other.locator(f".hs-preview-info span[data-frame='{path['x'][k]}']").wait_for(
            timeout=90_000
        )
        assert len(other.evaluate("hs.cols('hs-points-source', ['x'])")["x"]) == npts
        other.locator(".hs-preview").screenshot(path=str(tmp_path / "restored_preview.png"))
        assert not other.errors, other.errors
    finally:
        other.context.close()

    # the session file, opened in a fresh tab through its file input
    third = _open(browser, url)
    try:
        assert _controls(third) == default
        third.locator(".hs-open-session input[type=file]").set_input_files(str(saved))
        _wait_controls(third, want)
        third.wait_for_function("() => hs.model('hs-point-tool').add === false")
        third.locator(".hs-cost-matrix").first.screenshot(path=str(tmp_path / "third.png"))
        assert not third.errors, third.errors
    finally:
        third.context.close()
    assert not page.errors, page.errors
    page.context.close()


def test_a_link_with_a_bad_camera_keeps_the_rest_and_says_why(browser_and_url):
    browser, url = browser_and_url
    page = _open(browser, url + "?sample=wave-ok&camera=%3Cb%3Etop%3C%2Fb%3E&trails=1")
    try:
        alert = page.locator(".hs-error")
        alert.wait_for(state="visible", timeout=30_000)
        text = pane_text(alert)
        expected = "view.camera: expected one of three-quarter, front, side, hands"
        assert f"shared link: URL: {expected}" in text
        assert "<b>" in text  # shown as text, never as markup
        assert _controls(page)["camera"] == "three-quarter"
        # only the bad value is left out: the link's pair and its good values open
        deadline = time.monotonic() + 30
        while not _controls(page)["trails"]:
            assert time.monotonic() < deadline, "the link's trails=1 was not kept"
            page.wait_for_timeout(100)
    finally:
        page.context.close()


def test_a_refused_click_is_worded_from_the_refusal(browser_and_url):
    """Two clicks that cross: the second point is refused, and the alert says which point
    as a user counts them and where it is (engine.dtw.constraints' one text)."""
    browser, url = browser_and_url
    page = _open(browser, url)
    try:
        page.mouse.click(*page.evaluate("hs.xy(40, 60)"))
        page.wait_for_function("() => hs.cols('hs-server-points', ['x']).x.length === 1")
        first = page.evaluate("hs.cols('hs-server-points', ['x', 'y'])")
        b, h = round(first["x"][0]), round(first["y"][0])
        page.mouse.click(*page.evaluate("hs.xy(80, 20)"))
        alert = page.locator(".hs-error")
        alert.wait_for(state="visible", timeout=60_000)
        text = pane_text(alert)
        assert text.startswith("matching point 2 (body 80, hand "), text
        assert f"is before matching point 1's hand frame {h}; a path cannot go back" in text
        assert b < 80 and "points[" not in text
        page.wait_for_function("() => hs.cols('hs-points-source', ['x']).x.length === 1")
        alert.screenshot(path="/tmp/rules_refusal.png")
        assert not page.errors, page.errors
    finally:
        page.context.close()
