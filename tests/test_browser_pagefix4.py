"""Uploads through the page as a new user does them (stranger run 3: R3-6, R3-7).

Debian's Chromium driven by Playwright; files go in through the page's own upload fields.

* R3-7: a hand file named ``..._leftHand.bvh`` (ManipNet's hand rig: its joint names carry
  no side) uploaded while the Side control says "right" is aligned as the left hand, as the
  CLI does without ``--side``: the Side control, the "Uploaded …" line and the command line
  say left; switching Side to right afterwards is taken, with a warning naming the file.
* R3-6: a take of several MB shows how much has arrived (percent and MB) while it is
  received, and is received in several chunks.
* R4-7: with that left-hand pair open, a hand file whose name says no side and whose
  joints are a right hand (gestification's ``rHand``) waits for the side: the question
  names the file as uploaded (not the server's ``<sha256>.bvh``), and the Side it asks for
  opens the new pair (not the old one again); the link and the session file then name it.
* R4-9: while a marker (C3D) pair opens, its first alignment included, nothing of the
  previous pair (its preview pictures, its suggested points) is shown unveiled beside the
  new pair, and the progress line counts the opening.
"""

from __future__ import annotations

import hashlib
import html
import json
import re
import time
from pathlib import Path
from urllib.parse import parse_qsl, urlsplit

import pytest
from conftest import (
    BODY_BVH,
    HAND_BVH,
    LONG_BODY,
    MOCAP,
    MUG_HAND,
    busy_line,
    cropped_bvh,
    pane_text,
)

pytestmark = [pytest.mark.browser, pytest.mark.timeout(1500)]

BUSY_S = 300.0
BODY_C3D = MOCAP / "pyomeca" / "markers_analogs.c3d"
#: a 64-digit hex name: the server's kept file of an upload
KEPT_NAME = re.compile(r"[0-9a-f]{64}")


@pytest.fixture()
def page(demo_page):
    """A fresh tab on the run's shared demo server (conftest's ``demo_page``; its default
    upload limit takes the several-MB take)."""
    return demo_page


def _upload(page, which: str, path: Path) -> None:
    page.locator(f".hs-upload-{which} input[type=file]").set_input_files(str(path))


def _wait_line(page, pattern: str, timeout: float = BUSY_S, refused_ok: bool = False) -> str:
    """The "Uploaded …" line once it matches ``pattern`` (a refusal shown first fails,
    unless ``refused_ok``)."""
    deadline = time.monotonic() + timeout
    while True:
        text = pane_text(page.locator(".hs-upload-status"))
        if re.search(pattern, text):
            return text
        alert = page.locator(".hs-upload-error")
        if not refused_ok and alert.count() and alert.is_visible():
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
    hand = cropped_bvh(MUG_HAND, tmp_path / "mug_leftHand.bvh", 480)  # 4 s at 120 fps
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
    # stranger 12 (F2): the same hand named without a side opens as the Side in force (right)
    # with a warning, never silently: its geometry forms a left hand here (ManipNet's
    # left-handed axes), so it is mirrored, and the line says how to take it as the left hand
    _upload(page, "hand", cropped_bvh(MUG_HAND, tmp_path / "mug.bvh", 400))
    text = _wait_line(page, r"mug\.bvh: its file name and joint names carry no side")
    warned = text[text.index("⚠ mug.bvh") :]  # the warning's mark, as a contradicting name's
    assert "spliced as the right hand (the side given), mirrored" in warned, text
    assert "if it is the left hand, choose Side left" in warned, text
    # stranger 14 (F2): a right hand (rHand...) whose file name says left, uploaded while the
    # Side shows right, opens on the right (its joints) with a warning naming the file; it
    # used to wait for "side right" with right already chosen, and a click on left then
    # right threw both uploads away
    left_named = tmp_path / "pointing_left_hand.bvh"
    left_named.write_bytes(HAND_BVH.read_bytes())
    _upload(page, "hand", left_named)
    text = _wait_line(page, r"hand: pointing_left_hand\.bvh.*— open[;.]")
    assert (
        "⚠ pointing_left_hand.bvh: the file name says left but its joint names are a right "
        "hand (rHand); taking it as the right hand"
    ) in text, text
    assert _active_side(page) == "right" and not page.locator(".hs-upload-error").is_visible()
    page.locator(".hs-side").first.locator("button", has_text="left").click()  # it lacks left
    error = page.locator(".hs-upload-error")
    error.wait_for(state="visible", timeout=BUSY_S * 1000)
    assert "it stays on the right side" in pane_text(error), pane_text(error)
    assert _active_side(page) == "right"
    assert "pointing_left_hand.bvh" in pane_text(page.locator(".hs-upload-hand"))  # kept
    assert "— open" in pane_text(page.locator(".hs-upload-status"))
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


def _a_large_upload_says_how_much_has_arrived(page) -> None:
    """R3-6, on the demo pair with nothing uploaded: it leaves the long body uploaded,
    waiting for the other take (the demo pair still shown)."""
    assert LONG_BODY.stat().st_size > 3e6
    page.evaluate(RECORD)
    _upload(page, "body", LONG_BODY)
    _wait_line(page, r"Uploaded body:.*multipleActions1_subject1\.bvh.*now the other take")
    tags = page.evaluate("window.hsTags")
    receiving = [t for t in tags if t[0] == "receiving"]
    assert receiving, tags  # the tile said how much the server has, before "Checking…"
    for _, name, main, sub, _serial in receiving:
        assert name == LONG_BODY.name
        assert re.fullmatch(r"Receiving \d{1,2} %", main), main
        assert re.match(r"\d+\.\d of \d+\.\d MiB", sub), sub
    assert [t[0] for t in tags][-2:] == ["checking", "ok"], tags
    lines = [html.unescape(x) for x in page.evaluate("window.hsLines")]  # the model's text
    assert any(
        re.search(
            r"receiving <b>multipleActions1_subject1\.bvh</b>: \d+ %, [\d.]+ of [\d.]+ MiB", x
        )
        for x in lines
    ), lines


def _link(page, pattern: str) -> dict:
    """The share link's query once the link matches ``pattern``."""
    box, deadline = page.locator(".hs-share-url input"), time.monotonic() + BUSY_S
    while not re.search(pattern, link := box.input_value()):
        assert time.monotonic() < deadline, link
        page.wait_for_timeout(200)
    return dict(parse_qsl(urlsplit(link).query))


def test_a_hand_with_only_the_other_side_waits_and_the_side_chosen_opens_it(page, tmp_path):
    left = cropped_bvh(MUG_HAND, tmp_path / "mug_leftHand.bvh", 480)  # as the R3-7 test's
    _upload(page, "body", BODY_BVH)
    _wait_line(page, r"Uploaded body:.*now the other take")
    _upload(page, "hand", left)
    _wait_line(page, r"hand: mug_leftHand\.bvh.*— open[;.]")
    assert _active_side(page) == "left"
    before = _link(page, r"hname=mug_leftHand\.bvh")
    # a right hand whose file name says no side: refused for the left side, and it waits
    _upload(page, "hand", HAND_BVH)
    pattern = r"hand: hello-world\.bvh.*(waiting for the side|not opened)"
    text = _wait_line(page, pattern, refused_ok=True)
    assert "waiting for the side" in text, text
    question = pane_text(page.locator(".hs-upload-error"))
    assert "hello-world.bvh has no left hand" in question, question
    assert "choose side right" in question, question
    for shown in (text, question, busy_line(page), pane_text(page.locator(".hs-status"))):
        assert not KEPT_NAME.search(shown), shown
    assert _active_side(page) == "left"  # the pair shown is still the left-hand one
    assert _link(page, r"hname=") == before
    # the side it asks for opens the new upload, not the old pair for the other side
    page.locator(".hs-side").first.locator("button", has_text="right").click()
    _wait_line(page, r"hand: hello-world\.bvh.*— open[;.]", refused_ok=True)
    assert not page.locator(".hs-upload-error").is_visible()  # the question was answered
    assert _active_side(page) == "right"
    hand_sha = hashlib.sha256(HAND_BVH.read_bytes()).hexdigest()
    query = _link(page, r"hname=hello-world\.bvh")
    assert (query["hand"], query["body"], query["side"]) == (hand_sha, before["body"], "right")
    assert query["bname"] == BODY_BVH.name
    with page.expect_download(timeout=BUSY_S * 1000) as info:
        page.locator(".hs-download-session button").click()
    saved = json.loads(Path(info.value.path()).read_text())
    assert saved["inputs"]["hand"] == {"sha256": hand_sha, "name": HAND_BVH.name}
    assert saved["side"] == "right"
    assert not page.errors, page.errors


#: records, on every change of the matrix's x range and every 25 ms, what the page shows:
#: the matrix's body frames, whether the preview and the suggestions are greyed (an
#: ancestor's opacity under 0.9: the veil), the preview picture (a short fingerprint) and
#: the suggestions' labels shown, and the progress line
RECORD_VIEWS = """() => {
  const deep = (root, sel, out) => {
    out.push(...root.querySelectorAll(sel));
    for (const el of root.querySelectorAll('*')) if (el.shadowRoot) deep(el.shadowRoot, sel, out);
    return out;
  };
  const dim = (el) => {
    for (let n = el; n; n = n.parentNode || n.host)
      if (n.nodeType === 1 && parseFloat(getComputedStyle(n).opacity) < 0.9) return true;
    return false;
  };
  const inner = (el, sel) => (el.shadowRoot || el).querySelector(sel);
  const preview = deep(document, '.hs-preview-image', [])[0];
  const buttons = deep(document, '.hs-suggestion', []);
  const busy = deep(document, '.hs-busy-line', [])[0];
  const xr = hs.model('hs-x-range');
  const rec = window.hsRec = [];
  const sample = (why) => {
    const img = inner(preview, 'img');
    const src = img ? (img.getAttribute('src') || '') : '';
    rec.push({
      why,
      frames: Math.round(xr.bounds[1] + 0.5),
      picture: src ? src.length + ':' + src.slice(-48) : '',
      previewDim: dim(preview),
      labels: buttons.filter((b) => b.getClientRects().length > 0)
        .map((b) => (inner(b, 'button')?.innerText || '').trim()),
      suggestionsDim: buttons.length ? dim(buttons[0]) : true,
      busy: busy ? (busy.shadowRoot || busy).textContent : '',
    });
  };
  xr.change.connect(() => sample('x-range'));
  window.hsRecTimer = setInterval(() => sample('tick'), 25);
  sample('start');
}"""


def test_a_large_upload_says_how_much_has_arrived_and_then_a_marker_pair_opens_veiled(page):
    """R3-6 and then R4-9 in the same tab (one tab fewer per run): the large body upload
    leaves the demo pair shown, which the marker pair then replaces."""
    _a_large_upload_says_how_much_has_arrived(page)
    _nothing_of_the_previous_pair_is_shown_as_a_marker_pairs(page)


def _nothing_of_the_previous_pair_is_shown_as_a_marker_pairs(page) -> None:
    """R4-9, on the demo pair shown (a body upload may wait for its hand)."""
    # the demo pair shown with its picture and its suggested points
    page.locator(".hs-preview-image img").wait_for(timeout=BUSY_S * 1000)
    page.locator(".hs-suggestion button", has_text="Check body frame").first.wait_for(
        timeout=BUSY_S * 1000
    )
    page.evaluate(RECORD_VIEWS)
    old = page.evaluate("window.hsRec[0]")
    assert old["picture"] and old["labels"] and not old["previewDim"], old
    _upload(page, "body", BODY_C3D)
    _wait_line(page, r"Uploaded body:.*markers_analogs\.c3d.*now the other take")
    _upload(page, "hand", HAND_BVH)
    frames = 580  # markers_analogs.c3d
    page.wait_for_function(
        "(n) => hs.frames() === n && !window.hsRec.at(-1).previewDim"
        " && window.hsRec.at(-1).picture !== '' && window.hsRec.at(-1).picture !== "
        "window.hsRec[0].picture",
        arg=frames,
        timeout=BUSY_S * 1000,
    )
    rec = page.evaluate("clearInterval(window.hsRecTimer); window.hsRec")
    opening = [r for r in rec if "opening markers_analogs.c3d + hello-world.bvh" in r["busy"]]
    assert opening, "no progress line for the opening"
    start = rec.index(opening[0])
    shown_as_new = [
        r
        for r in rec[start:]
        if (r["picture"] == old["picture"] and not r["previewDim"])
        or (set(r["labels"]) & set(old["labels"]) and not r["suggestionsDim"])
    ]
    assert not shown_as_new, shown_as_new[:3]
    # the new pair's matrix came in under the veil (the opening counts its first alignment)
    first = next(r for r in rec[start:] if r["frames"] == frames)
    assert first["previewDim"] and first["suggestionsDim"], first
    assert not page.errors, page.errors
