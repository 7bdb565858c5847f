"""Uploads through the page as a new user does them (stranger run 3: R3-6, R3-7).

Debian's Chromium driven by Playwright; files go in through the page's own upload fields.

* R3-7: a hand file named ``..._leftHand.bvh`` (ManipNet's hand rig: its joint names carry
  no side) uploaded while the Side control says "right" is aligned as the left hand, as the
  CLI does without ``--side``: the Side control, the "Uploaded …" line and the command line
  say left; switching Side to right afterwards is taken, with a warning naming the file.
* R3-6: a take of several MB shows how much has arrived (percent and MB) while it is
  received, and is received in several chunks.
"""

from __future__ import annotations

import html
import re
import time
from pathlib import Path

import pytest
from conftest import BODY_BVH, MOCAP, cropped_bvh, open_page, pane_text, served_app

pytestmark = [pytest.mark.browser, pytest.mark.timeout(1500)]

SERVER_START_S = 600.0
BUSY_S = 300.0
MUG = MOCAP / "manipnet" / "mug1_rightHand.bvh"
LAFAN = MOCAP / "lafan1" / "multipleActions1_subject1.bvh"


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    with served_app(tmp_path_factory, "--max-upload-mb", "40", timeout=SERVER_START_S) as s:
        yield s


@pytest.fixture()
def page(browser, served):
    page = open_page(browser, served[0], timeout_s=SERVER_START_S)
    yield page
    page.context.close()


def _upload(page, which: str, path: Path) -> None:
    page.locator(f".hs-upload-{which} input[type=file]").set_input_files(str(path))


def _wait_line(page, pattern: str, timeout: float = BUSY_S) -> str:
    deadline = time.monotonic() + timeout
    while True:
        text = pane_text(page.locator(".hs-upload-status"))
        if re.search(pattern, text):
            return text
        alert = page.locator(".hs-upload-error")
        if alert.count() and alert.is_visible():
            raise AssertionError(f"upload refused: {pane_text(alert)}")
        if time.monotonic() > deadline:
            raise AssertionError(f"no {pattern!r} within {timeout} s: {text!r}")
        page.wait_for_timeout(100)


def _active_side(page) -> str:
    side = page.locator(".hs-side").first
    for name in ("right", "left"):
        if "active" in (side.locator("button", has_text=name).get_attribute("class") or ""):
            return name
    return ""


def _cli(page, pattern: str) -> str:
    deadline = time.monotonic() + BUSY_S
    while True:
        text = pane_text(page.locator(".hs-cli").first)
        if re.search(pattern, text) or time.monotonic() > deadline:
            return text
        page.wait_for_timeout(200)


def test_an_uploaded_hand_takes_the_side_its_file_name_says(page, tmp_path):
    hand = cropped_bvh(MUG, tmp_path / "mug_leftHand.bvh", 480)  # 4 s at 120 fps
    assert _active_side(page) == "right"  # the demo pair's side
    _upload(page, "body", BODY_BVH)
    _wait_line(page, r"Uploaded body:.*now the other take")
    _upload(page, "hand", hand)
    text = _wait_line(page, r"Uploaded body:.*hand:.*— open[;.]")  # not "— opening"
    assert "side left, as the hand file's name says" in text, text
    assert _active_side(page) == "left"
    assert "--side left" in _cli(page, r"--side left")
    # the user insists on right: taken, and the line warns that the name says otherwise
    page.locator(".hs-side").first.locator("button", has_text="right").click()
    text = _wait_line(page, r"the file name says left")
    assert "mug_leftHand.bvh: the file name says left" in text and "right hand" in text, text
    assert "--side right" in _cli(page, r"--side right")
    assert not page.errors, page.errors


#: records every verdict the body field's tile gets and every text of the "Uploaded …"
#: line (Bokeh models: the page redraws both from them)
RECORD = """() => {
  window.hsTags = []; window.hsLines = [];
  for (const m of Bokeh.documents[0]._all_models.values()) {
    const classes = m.css_classes ?? [];
    if (classes.includes('hs-upload-body'))
      m.properties.tags.change.connect(() => window.hsTags.push([...m.tags]));
    if (classes.includes('hs-upload-status'))
      m.properties.text.change.connect(() => window.hsLines.push(m.text));
  }
}"""


def test_a_large_upload_says_how_much_has_arrived(page):
    assert LAFAN.stat().st_size > 3e6
    page.evaluate(RECORD)
    _upload(page, "body", LAFAN)
    _wait_line(page, r"Uploaded body:.*multipleActions1_subject1\.bvh.*now the other take")
    tags = page.evaluate("window.hsTags")
    receiving = [t for t in tags if t[0] == "receiving"]
    assert receiving, tags  # the tile said how much the server has, before "Checking…"
    for _, name, main, sub, _serial in receiving:
        assert name == LAFAN.name
        assert re.fullmatch(r"Receiving \d{1,2} %", main), main
        assert re.match(r"\d+\.\d of \d+\.\d MB", sub), sub
    assert [t[0] for t in tags][-2:] == ["checking", "ok"], tags
    lines = [html.unescape(x) for x in page.evaluate("window.hsLines")]  # the model's text
    assert any(
        re.search(r"receiving <b>multipleActions1_subject1\.bvh</b>: \d+ %, [\d.]+ of [\d.]+ MB", x)
        for x in lines
    ), lines
