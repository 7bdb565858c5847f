"""A long alignment runs off the server's event loop (issue 13): other tabs stay responsive.

``handsplice serve BODY HAND`` on a two-minute body take (LAFAN1 ``multipleActions1``
resampled to 120 fps: 14,400 frames) with ManipNet's mug hand take; a full solve of
that pair takes a few seconds. Tab A opens it and shows the "aligning…" line while
its first alignment runs; tab B opens the demo pair. Then A's pass-1 band width is
typed in (a full re-solve) and, while A is still aligning, B adds a matching point
with a click: B's new path must arrive before A's alignment ends (before, every
session waited for A's solve). On a quiet machine A's solve may end first; each try
widens A's band (a longer solve) until one outlasts B's round trip. Everything
through the page's own controls.
"""

from __future__ import annotations

import re
import time
from pathlib import Path

import pytest

from webapp.launch import PAGE_HELPERS, launch_chromium, running_server

pytestmark = pytest.mark.browser

MOCAP = Path(__file__).resolve().parents[2] / "shared" / "data" / "mocap"
BODY_SECONDS = 120
FPS = 120.0
SERVER_START_S = 400


@pytest.fixture(scope="module")
def long_pair(tmp_path_factory) -> tuple[Path, Path]:
    from engine.io import load_take
    from engine.io.bvh import write_bvh
    from engine.model.kinematics import resample

    folder = tmp_path_factory.mktemp("long")
    body = resample(load_take(MOCAP / "lafan1" / "multipleActions1_subject1.bvh"), FPS)
    body_path = folder / "multipleActions1_120fps.bvh"
    write_bvh(body.frames(0, int(BODY_SECONDS * FPS)), body_path)
    return body_path, MOCAP / "manipnet" / "mug1_rightHand.bvh"


def _page(context, url: str):
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(f"pageerror: {e}"))
    page.goto(url)
    page.locator(".hs-cost-matrix").first.wait_for(timeout=120_000)
    page.wait_for_function("() => window.Bokeh && Bokeh.documents.length", timeout=60_000)
    page.evaluate(PAGE_HELPERS)
    page.errors = errors
    return page


HAS_PATH = "() => Bokeh.documents[0].get_model_by_name('hs-path-source')?.data.x?.length > 0"


def _busy(page) -> str:
    """The "aligning…" line's text ('' when nothing runs)."""
    line = page.locator(".hs-busy")
    return line.first.inner_text() if line.count() else ""


def _revision(page) -> int:
    return int(page.locator(".hs-status span").get_attribute("data-revision"))


def _band_cells(page) -> int:
    status = page.locator(".hs-status span").inner_text()
    match = re.search(r"band ([\d,]+) cells", status)
    assert match, status
    return int(match.group(1).replace(",", ""))


def test_second_tab_answers_while_first_tab_aligns_a_long_pair(long_pair, tmp_path):
    sync_api = pytest.importorskip("playwright.sync_api")
    from webapp.config import SAMPLE_DIR, demo_sample_name

    body, hand = long_pair
    demo = demo_sample_name(SAMPLE_DIR)
    log_path = tmp_path / "serve.log"
    with (
        log_path.open("w+") as log,
        running_server(
            str(body),
            str(hand),
            "--no-warm",
            "--upload-dir",
            str(tmp_path / "up"),
            log=log,
            timeout=SERVER_START_S,
        ) as (url, _),
        sync_api.sync_playwright() as p,
    ):
        browser = launch_chromium(p)
        context = browser.new_context(viewport={"width": 1300, "height": 1000})
        # tab A: the long pair; its first alignment runs off the loop, the page says so
        a = _page(context, url)
        a.locator(".hs-busy").first.wait_for(timeout=60_000)
        assert "aligning" in _busy(a) or "opening" in _busy(a), _busy(a)
        a.wait_for_function(HAS_PATH, timeout=180_000)
        a.locator(".hs-busy").first.wait_for(state="detached", timeout=60_000)
        n = len(a.evaluate("hs.cols('hs-band-source', ['x'])")["x"])
        assert n == BODY_SECONDS * FPS
        # tab B: the demo pair, open and idle
        b = _page(context, url + f"?sample={demo}")
        b.wait_for_function(HAS_PATH, timeout=120_000)
        b.wait_for_timeout(500)
        b_points = len(b.evaluate("hs.cols('hs-points-source', ['x'])")["x"])
        nb = len(b.evaluate("hs.cols('hs-band-source', ['x'])")["x"])

        # A: a wider pass-1 band in seconds (a full re-solve of the long pair); B, meanwhile,
        # adds a matching point with one click. On a quiet machine A's re-solve can end
        # before B's round trip does, which proves nothing either way, so each try widens
        # A's band further (a longer solve). With A's solve on the loop, B's answer would
        # always come after A's, and every try would fail.
        width = a.locator(".hs-params input").nth(0)  # "W1 in seconds" (a long take has one)
        tries: list[str] = []
        for k, extra_s in enumerate((3, 15, 40, 90)):
            a_rev, a_cells = _revision(a), _band_cells(a)
            width.scroll_into_view_if_needed()
            old = float(width.input_value())
            width.fill(f"{old + extra_s:g}")
            width.press("Enter")
            a.locator(".hs-busy").first.wait_for(timeout=30_000)
            t_a = time.monotonic()
            b.bring_to_front()
            b_rev = _revision(b)
            bx, by = nb * (5 + k) // 10, nb * (5 + k) // 15  # each point after the last
            xy = b.evaluate("([x, y]) => hs.xy(x, y)", [bx, by])
            b.mouse.click(*xy)
            deadline = time.monotonic() + 60
            while _revision(b) <= b_rev:
                assert time.monotonic() < deadline, "tab B got no new path within 60 s"
                b.wait_for_timeout(20)
            t_b = time.monotonic()
            a_still_busy = bool(_busy(a)) and _revision(a) == a_rev
            b_points += 1
            assert len(b.evaluate("hs.cols('hs-points-source', ['x'])")["x"]) == b_points
            # A's new alignment arrives in its turn, with the width typed
            deadline = time.monotonic() + 120
            while _revision(a) <= a_rev:
                assert time.monotonic() < deadline, "tab A's re-solve never arrived"
                a.wait_for_timeout(100)
            a.locator(".hs-busy").first.wait_for(state="detached", timeout=30_000)
            t_done = time.monotonic()
            assert _band_cells(a) > a_cells  # the wider band was solved
            tries.append(
                f"W1 +{extra_s} s: B answered after {t_b - t_a:.2f} s, A after {t_done - t_a:.2f} s"
            )
            if a_still_busy:
                break
        assert a_still_busy, "tab A's re-solve always ended before tab B's edit was answered: " + (
            "; ".join(tries)
        )
        a.locator(".hs-cost-matrix").first.scroll_into_view_if_needed()
        a.screenshot(path=str(tmp_path / "long_a.png"))
        assert not a.errors and not b.errors, a.errors + b.errors
        browser.close()
    text = log_path.read_text(errors="replace")
    assert "Traceback" not in text, text[text.find("Traceback") :][:3000]
