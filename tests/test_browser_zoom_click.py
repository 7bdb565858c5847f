"""A click adds a matching point after a box zoom (stranger 7's medium finding).

Stranger 7 zoomed the matrix with the toolbar's Box Zoom (a long take needs it), then
clicked the matrix: nothing was added, silently, until the toolbar's point icon was
chosen again. A box zoom is now one gesture: once its box is drawn the matching-point
tool is active again, and the next click on the matrix adds a point.
"""

from __future__ import annotations

import pytest

pytestmark = pytest.mark.browser

_POINTS = "hs.cols('hs-points-source', ['x']).x.length"
_X_RANGE = "[hs.model('hs-x-range').start, hs.model('hs-x-range').end]"


def test_a_click_after_a_box_zoom_adds_a_point(demo_page):
    page = demo_page
    assert page.evaluate(_POINTS) == 0
    n = page.evaluate("hs.frames()")
    path = page.evaluate("hs.cols('hs-path-source', ['x', 'y'])")
    k = path["x"].index(n // 2)
    x, y = path["x"][k], path["y"][k]
    page.locator('[title="Box Zoom"]').first.click()
    before = page.evaluate(_X_RANGE)
    # a box around the path's middle cell, from its lower left to its upper right
    x0, y0 = page.evaluate(f"hs.xy({x - n // 5}, {y})")
    x1, y1 = page.evaluate(f"hs.xy({x + n // 5}, {y})")
    page.mouse.move(x0, y0 + 60)
    page.mouse.down()
    page.mouse.move((x0 + x1) / 2, y0, steps=5)
    page.mouse.move(x1, y1 - 60, steps=5)
    page.mouse.up()
    page.wait_for_function(f"() => {_X_RANGE}[0] !== {before[0]}", timeout=30_000)
    after = page.evaluate(_X_RANGE)
    assert after[1] - after[0] < before[1] - before[0], (before, after)  # zoomed in
    assert page.evaluate(_POINTS) == 0  # the zoom's gesture added nothing
    # the next click on the path's middle cell (zoomed: at its new place) adds a point
    page.mouse.click(*page.evaluate(f"hs.xy({x}, {y})"))
    page.wait_for_function(f"() => {_POINTS} === 1", timeout=60_000)
    assert page.evaluate("hs.model('hs-point-tool').active")
