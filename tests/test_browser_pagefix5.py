"""A new user's page findings (run 3 of the stranger's report), through the page's controls.

* R3-13: on a long body with a short hand take without a forearm (ManipNet) the red line the
  page opened on (Pass 1 view) was pass 1's path, while the splice, the preview and the
  status line follow pass 2's, which searches pass 1's whole band there and can land far
  away. Now the red line is the alignment used in every view, and the legend says so.
* R3-14: the points table cut 5-digit body frames ("110…" for 11013).
* R3-15: a click on the matrix right after switching to "Pick frames" added a matching
  point (the mode reached the matrix only after a round trip to the server).

The pairs are small cuts of sample takes: a 3 s piece of ManipNet's mug take (a hand
without a forearm) against a 6.7 s body, and the same hand against that body repeated
to over 10,000 frames.
"""

from __future__ import annotations

import re
import time
from pathlib import Path

import pytest
from conftest import (
    SAMPLE_DATA,
    assert_no_traceback,
    open_page,
    pane_text,
    served_app,
    served_chromium,
    status_line,
)

pytestmark = [pytest.mark.browser, pytest.mark.timeout(1500)]

SERVER_START_S = 600.0
BUSY_S = 240.0

BODY = SAMPLE_DATA / "bandai-namco" / "dataset-2_wave-both-hands_normal_001.bvh"
HAND = SAMPLE_DATA / "manipnet" / "mug1_rightHand.bvh"


def _cut_bvh(src: Path, dst: Path, start: int = 0, count: int = 0, repeat: int = 1) -> Path:
    """``dst``: ``src`` with its motion repeated ``repeat`` times, then frames ``start`` to
    ``start + count`` of it (``count`` 0: all)."""
    lines = src.read_text().splitlines()
    k = next(i for i, line in enumerate(lines) if line.startswith("MOTION"))
    motion = [line for line in lines[k + 3 :] if line.strip()] * repeat
    motion = motion[start : start + count] if count else motion[start:]
    dst.write_text("\n".join([*lines[: k + 1], f"Frames: {len(motion)}", lines[k + 2], *motion]))
    return dst


def _until(page, condition, what: str, seconds: float = BUSY_S) -> None:
    deadline = time.monotonic() + seconds
    while not condition():
        assert time.monotonic() < deadline, what
        page.wait_for_timeout(50)


def _matched_body_frames(status: str, n: int) -> tuple[int, int]:
    """The first and last body frame with a hand match, as the status line says."""
    found = re.search(r"body frames ([\d, -]+?) \(", status)
    first, last = 0, n - 1
    for span in found.group(1).split(", ") if found else []:
        a, _, b = span.partition("-")
        a, b = int(a), int(b or a)
        if a == 0:
            first = b + 1
        if b == n - 1:
            last = a - 1
    return first, last


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    folder = tmp_path_factory.mktemp("pair")
    body = _cut_bvh(BODY, folder / "wave.bvh")
    hand = _cut_bvh(HAND, folder / "mug_rightHand.bvh", start=1200, count=360)
    with served_chromium(
        tmp_path_factory, str(body), str(hand), "--side", "right", timeout=SERVER_START_S
    ) as (browser, url):
        yield browser, url


@pytest.fixture()
def page(served):
    browser, url = served
    page = open_page(browser, url, timeout_s=SERVER_START_S)
    yield page
    page.context.close()
    assert not page.errors, page.errors


def test_the_red_line_is_the_alignment_used_in_every_view(page):
    """R3-13: the red line is the path the status line (and the splice) follow, in the
    Pass 1 view the page opens on and in the Pass 2 view; the legend says so."""
    assert "pass 1" in pane_text(page.locator(".hs-matrix-title").first).lower()
    used = page.locator(".hs-used-path").first
    assert "alignment used" in used.inner_text()
    assert used.get_attribute("data-pass") == "2"  # a hand take that pass 2 compares by turning
    n = page.evaluate("hs.frames()")
    red = page.evaluate("hs.cols('hs-path-source', ['x', 'y'])")
    dashed = page.evaluate("hs.cols('hs-other-path', ['x', 'y'])")
    # the pair is one where the passes' paths differ (else the test could not tell them apart)
    assert (min(red["x"]), max(red["x"])) != (min(dashed["x"]), max(dashed["x"]))
    status = status_line(page)
    assert (min(red["x"]), max(red["x"])) == _matched_body_frames(status, n), (status, red["x"])
    # the Pass 2 view draws the same red line (and pass 1's dashed)
    page.locator(".hs-matrix-choice button", has_text="Pass 2").first.click()
    legend = page.locator(".hs-matrix-colour").first
    _until(page, lambda: legend.get_attribute("data-matrix") == "pass2", "no Pass 2 view")
    assert page.evaluate("hs.cols('hs-path-source', ['x', 'y'])") == red
    assert page.evaluate("hs.cols('hs-other-path', ['x', 'y'])") == dashed
    assert page.locator(".hs-used-path").first.get_attribute("data-pass") == "2"


def test_a_click_right_after_choosing_pick_frames_adds_no_point(page):
    """R3-15: the click mode applies in the page at once, before the server has heard of it."""
    path = page.evaluate("hs.cols('hs-path-source', ['x', 'y'])")
    k = len(path["x"]) // 2
    body, hand = path["x"][k], path["y"][k]
    assert page.evaluate("hs.cols('hs-frame-source', ['x'])")["x"][0] != body
    xy = page.evaluate("([a, b]) => hs.xy(a, b)", [body, hand])
    page.locator(".hs-click-mode button", has_text="Pick frames").first.click()
    page.mouse.click(*xy)  # at once: no wait for the server
    _until(
        page,
        lambda: page.evaluate("hs.cols('hs-frame-source', ['x'])")["x"][0] == body,
        "the click did not pick the body frame",
    )
    page.wait_for_timeout(500)  # an added point would be in the page by now (it adds first)
    assert page.evaluate("hs.cols('hs-points-source', ['x'])")["x"] == []
    assert page.locator(".hs-points .tabulator-row").count() == 0
    assert "0 matching points" in status_line(page)


@pytest.fixture(scope="module")
def long_page(served, tmp_path_factory):
    """A tab (the module's Chromium) on a body of over 10,000 frames (the 6.7 s body 51
    times) and the hand piece, served by its own server."""
    folder = tmp_path_factory.mktemp("long")
    body = _cut_bvh(BODY, folder / "wave51.bvh", repeat=51)
    hand = _cut_bvh(HAND, folder / "mug_rightHand.bvh", start=1200, count=360)
    args = (str(body), str(hand), "--side", "right")
    with served_app(tmp_path_factory, *args, timeout=SERVER_START_S) as (url, _, log_path):
        page = open_page(served[0], url, width=1440, height=900, timeout_s=SERVER_START_S)
        yield page
        page.context.close()
        assert not page.errors, page.errors
    assert_no_traceback(log_path)


def test_the_points_table_shows_5_digit_frames_whole(long_page):
    """R3-14: a point at body frame >= 10000 reads whole in the table (it showed "110…"),
    and the table still fits its panel (nothing scrolled sideways)."""
    page = long_page
    n = page.evaluate("hs.frames()")
    assert n > 10_000
    # a cell at body frame >= 10000 inside the band (the short hand piece matches one of
    # the body's 51 repeats: the path need not reach that far)
    body = n - 100
    band = page.evaluate("hs.cols('hs-band-source', ['x', 'lo', 'hi'])")
    i = min(range(len(band["x"])), key=lambda k: abs(band["x"][k] - body))
    hand = round((band["lo"][i] + band["hi"][i]) / 2)
    page.mouse.click(*page.evaluate("([a, b]) => hs.xy(a, b)", [body, hand]))
    rows = page.locator(".hs-points .tabulator-row")
    _until(page, lambda: rows.count() == 1, "the click's point is not in the table")
    cell = rows.first.locator(".tabulator-cell[tabulator-field='body frame']")
    _until(page, lambda: cell.inner_text().strip().isdigit(), "no body frame in the table")
    assert int(cell.inner_text()) >= 10_000
    fits = "e => e.scrollWidth <= e.clientWidth"
    for field in ("body frame", "hand frame", "effective"):
        one = rows.first.locator(f".tabulator-cell[tabulator-field='{field}']")
        assert one.evaluate(fits), (field, one.inner_text())
    assert page.locator(".hs-points .tabulator-tableholder").first.evaluate(fits)
