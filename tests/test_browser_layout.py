"""The matrix stays under the pointer (stranger 6, finding 1), in real Chromium.

A person clicks the matrix to add a matching point, then clicks near it again. Before, the
status line above the matrix wrapped to a second line after the first click and a refusal
box appeared above the matrix after the second: each moved the matrix down under the
pointer (19 px, then 77 px), so the next click landed on another frame. Now the status
line keeps two lines' height and a refusal shows under the matrix.
"""

from __future__ import annotations

import pytest
from conftest import DEMO_SERVER_START_S, click_path_mid_take, open_page, pane_text, revision

pytestmark = [pytest.mark.browser, pytest.mark.timeout(600)]


def _top(page, selector: str) -> float:
    """The element's top in the document (not the viewport: a click scrolls), px."""
    return page.locator(selector).first.evaluate(
        "e => e.getBoundingClientRect().top + window.scrollY"
    )


def test_a_point_and_a_refusal_leave_the_matrix_where_it_was(browser, demo_url):
    # a narrow screen: the status line wraps, as on the stranger's laptop
    page = open_page(browser, demo_url, width=900, timeout_s=DEMO_SERVER_START_S)
    try:
        matrix = ".hs-cost-matrix"
        before = _top(page, matrix)
        rev = revision(page)
        click_path_mid_take(page)
        # the first click's status line is in (a new revision) and the matrix has not moved
        for _ in range(600):
            if revision(page) > rev:
                break
            page.wait_for_timeout(100)
        assert revision(page) > rev, "the click was not solved"
        page.wait_for_timeout(1500)  # the status line follows the path (after-path work)
        status_h = page.locator(".hs-status").first.bounding_box()["height"]
        assert _top(page, matrix) == before, (before, _top(page, matrix), status_h)
        # a second click on the same body frame, 18 px lower (beyond the point's 12 px hit
        # area, where a click selects it): refused (one point per body
        # frame); the refusal is under the matrix and the matrix stays
        pts = page.evaluate("hs.cols('hs-points-source', ['x', 'y'])")
        x, y = page.evaluate("([a, b]) => hs.xy(a, b)", [pts["x"][0], pts["y"][0]])
        page.mouse.click(x, y - 18)
        alert = page.locator(".hs-error").first
        alert.wait_for(state="visible", timeout=120_000)
        assert "same body frame" in pane_text(alert), pane_text(alert)
        assert _top(page, matrix) == before
        height = page.locator(matrix).first.bounding_box()["height"]
        assert _top(page, ".hs-error") >= before + height - 1
        assert not page.errors, page.errors
    finally:
        page.context.close()


def _magenta_pixels(page, x: float, y: float, r: int = 14) -> int:
    """Pixels near the selected point's ring colour in a (2r)² square around (x, y)."""
    import io

    import numpy as np
    from PIL import Image

    from webapp.views.cost_matrix import SELECTED_POINT_RING

    shot = page.screenshot(clip={"x": x - r, "y": y - r, "width": 2 * r, "height": 2 * r})
    rgb = np.asarray(Image.open(io.BytesIO(shot)).convert("RGB"), dtype=int)
    want = np.array([int(SELECTED_POINT_RING[i : i + 2], 16) for i in (1, 3, 5)])
    return int((np.abs(rgb - want).sum(axis=2) < 60).sum())


def _poll(measure, good, page, timeout_s: float = 10.0):
    """``measure()`` until ``good`` of it (the canvas is redrawn on the next frames), or
    its last value after ``timeout_s``."""
    import time

    deadline = time.monotonic() + timeout_s
    while not good(value := measure()) and time.monotonic() < deadline:
        page.wait_for_timeout(100)
    return value


def test_the_selected_point_has_a_ring_that_the_others_lack(browser, demo_url):
    """Backspace deletes the selected point: a person can see which one it is."""
    page = open_page(browser, demo_url, timeout_s=DEMO_SERVER_START_S)
    try:
        click_path_mid_take(page)
        page.mouse.move(5, 5)  # away from the point (its tooltip off)
        pts = page.evaluate("hs.cols('hs-points-source', ['x', 'y'])")
        x, y = page.evaluate("([a, b]) => hs.xy(a, b)", [pts["x"][0], pts["y"][0]])
        selected = "() => Bokeh.documents[0].get_model_by_name('hs-points-source')"
        page.evaluate(f"({selected})().selected.indices = []")
        plain = _poll(lambda: _magenta_pixels(page, x, y), lambda n: n == 0, page)
        page.mouse.click(x, y)  # a click on the point selects it
        page.wait_for_function(f"() => ({selected})().selected.indices.length === 1")
        page.mouse.move(5, 5)
        ring = _poll(lambda: _magenta_pixels(page, x, y), lambda n: n >= 20, page)
        assert plain == 0 and ring >= 20, (plain, ring)
    finally:
        page.context.close()
