"""A new user's page findings (the third stranger's report), through the page's controls.

* F2: the matrix and the strips along its axes share their pixels.
* While only one take of a new pair is uploaded, the status line says it waits for the
  other (it showed the previous pair's numbers under a green "Checked" tile).
* The status line names the unmatched ends' remedies as the command line's (the page has
  no control for them).

F2 in detail:
The body frame axis, the wrist-speed curve and the phase bars below the matrix, and the
hand strip at its left, are the only numbered axes of the matrix: a frame read off them
must be the frame the matrix shows above (beside) it. The stranger saw the matrix's frame
21 px narrower than the strip's (its colour bar took them), so hovering the matrix above
the strip's tick 150 said body frame 156.

Measured in the page, on the demo pair, at the stranger's screen size (1440 x 900): the
Bokeh views' frames and scales, and a real mouse hover read back from the tooltip.
"""

from __future__ import annotations

import re
import time

import pytest
from conftest import BODY_BVH, pane_text, status_line, visible_tooltips

pytestmark = [pytest.mark.browser, pytest.mark.timeout(1500)]

#: client pixels of body frame ``body`` in the matrix and in the strip below it, of hand
#: frame ``hand`` in the matrix and in the hand strip at its left, and the frames' edges
_JS_PIXELS = """([body, hand]) => {
  const view = (name) => Bokeh.index.find_one(hs.model(name));
  const m = view('hs-cost-figure'), b = view('hs-body-signal'), h = view('hs-hand-signal');
  m.canvas_view.el.scrollIntoView({block: 'center'});
  const box = (v) => v.canvas_view.el.getBoundingClientRect();
  const edges = (v) => [box(v).left + v.frame.bbox.left, box(v).left + v.frame.bbox.right,
                        box(v).top + v.frame.bbox.top, box(v).top + v.frame.bbox.bottom];
  return {
    matrix_x: box(m).left + m.frame.x_scale.compute(body),
    strip_x: box(b).left + b.frame.x_scale.compute(body),
    matrix_y: box(m).top + m.frame.y_scale.compute(hand),
    strip_y: box(h).top + h.frame.y_scale.compute(hand),
    matrix: edges(m), body: edges(b), hand: edges(h),
  };
}"""


@pytest.fixture()
def page(stranger_page):
    """A fresh 1440 x 900 tab on the run's shared demo server (conftest's ``stranger_page``)."""
    return stranger_page


def _hovered_body_frame(page, x: float, y: float) -> int:
    """The body frame the matrix's tooltip names with the mouse at client pixel (x, y)."""
    deadline = time.monotonic() + 20
    nudge = 0.0
    while True:
        page.mouse.move(x, y + nudge)
        page.wait_for_timeout(200)
        for text in visible_tooltips(page):
            if found := re.search(r"body frame:?\s*(\d+)", text):
                return int(found.group(1))
        assert time.monotonic() < deadline, f"no tooltip at ({x}, {y})"
        nudge = 0.3 - nudge  # a pointer that did not move shows no new tooltip


def _assert_aligned(page) -> None:
    n = page.evaluate("hs.frames()")
    for body in (0, 150, n - 1):
        px = page.evaluate(_JS_PIXELS, [body, 20])
        assert abs(px["matrix_x"] - px["strip_x"]) < 0.5, (body, px)
    for hand in (0, 50, 150):
        px = page.evaluate(_JS_PIXELS, [0, hand])
        assert abs(px["matrix_y"] - px["strip_y"]) < 0.5, (hand, px)
    # the frames themselves: same left and right edge as the body strip's, same top and
    # bottom as the hand strip's
    assert px["matrix"][:2] == pytest.approx(px["body"][:2], abs=0.5), px
    assert px["matrix"][2:] == pytest.approx(px["hand"][2:], abs=0.5), px
    # a user reads a frame off the strip's axis and hovers the matrix right above it
    px = page.evaluate(_JS_PIXELS, [150, 20])
    mid_y = (px["matrix"][2] + px["matrix"][3]) / 2
    assert _hovered_body_frame(page, px["strip_x"], mid_y) == 150
    px = page.evaluate(_JS_PIXELS, [n - 1, 20])
    assert _hovered_body_frame(page, px["strip_x"], mid_y) == n - 1


def test_a_body_frame_is_one_pixel_in_every_view_and_one_take_makes_the_status_wait(page):
    """Both findings in one tab (one tab fewer per run): the matrix's view changes nothing
    of the status line, which the upload then changes."""
    _a_body_frame_is_the_same_pixel_in_the_matrix_and_in_the_strips(page)
    _one_uploaded_take_says_the_status_waits_for_the_other(page)


def _a_body_frame_is_the_same_pixel_in_the_matrix_and_in_the_strips(page) -> None:
    _assert_aligned(page)
    # the cumulative view's colour bar has 4-digit labels: the frame keeps its width
    page.get_by_role("button", name="Cumulative 1").click()
    deadline = time.monotonic() + 120
    while "cumulative" not in pane_text(page.locator(".hs-matrix-title").first).lower():
        assert time.monotonic() < deadline, "the matrix did not switch to Cumulative 1"
        page.wait_for_timeout(200)
    page.wait_for_timeout(500)
    _assert_aligned(page)


def _one_uploaded_take_says_the_status_waits_for_the_other(page) -> None:
    before = status_line(page)
    assert "waiting" not in before
    # open ends on the demo: the remedy is named as the command line's, not as a flag
    assert "no hand match" in before and "(the command line's --ends fixed" in before, before
    page.locator(".hs-upload-body input[type=file]").set_input_files(str(BODY_BVH))
    deadline = time.monotonic() + 300
    while "waiting for a hand take" not in (text := status_line(page)):
        assert time.monotonic() < deadline, text
        page.wait_for_timeout(300)
    assert text.startswith(f"body {BODY_BVH.name} checked: waiting for a hand take"), text
    assert "the views below still show the pair open before" in text
