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
        # a second click on the same body frame, 12 px lower: refused (one point per body
        # frame); the refusal is under the matrix and the matrix stays
        pts = page.evaluate("hs.cols('hs-points-source', ['x', 'y'])")
        x, y = page.evaluate("([a, b]) => hs.xy(a, b)", [pts["x"][0], pts["y"][0]])
        page.mouse.click(x, y - 12)
        alert = page.locator(".hs-error").first
        alert.wait_for(state="visible", timeout=120_000)
        assert "same body frame" in pane_text(alert), pane_text(alert)
        assert _top(page, matrix) == before
        height = page.locator(matrix).first.bounding_box()["height"]
        assert _top(page, ".hs-error") >= before + height - 1
        assert not page.errors, page.errors
    finally:
        page.context.close()
