"""Tabs of one server share a pair's first alignment (issue 13, openlong).

``handsplice serve BODY HAND`` on a 30-second 120 fps pair (LAFAN1 ``multipleActions1``
resampled: 3,600 frames, with ManipNet's mug hand take), without the warm-up, so the
first tab solves the alignment. A second tab on the same pair shows that alignment
without solving it again: no "aligning…" line while it opens, the status line's
``data-aligned`` says ``shared`` (the first tab's says ``here``), and the costs and band
are the first tab's. Before, every tab solved its own first alignment.
"""

from __future__ import annotations

import re
import time
from pathlib import Path

import pytest
from conftest import HAS_PATH, band_cells, busy_line, open_tab, served_chromium, status_line

pytestmark = pytest.mark.browser

SECONDS = 30
FPS = 120.0
COSTS = re.compile(r"pass 1 cost \S+ · pass 2 cost \S+")


@pytest.fixture(scope="module")
def pair(long_pair) -> tuple[Path, Path]:
    return long_pair(SECONDS, FPS)


def _open(browser, url: str):
    """A tab in its own context once the page's path is drawn; the busy lines seen meanwhile."""
    context = browser.new_context(viewport={"width": 1300, "height": 1000})
    page = open_tab(
        context, url, timeout_s=300, ready="() => window.Bokeh && Bokeh.documents.length"
    )
    seen: set[str] = set()
    deadline = time.monotonic() + 300
    while not page.evaluate(HAS_PATH):
        assert time.monotonic() < deadline, f"no path; busy lines {seen}"
        seen.add(busy_line(page).split(":")[0])
        page.wait_for_timeout(50)
    span = page.locator(".hs-status span")
    deadline = time.monotonic() + 60
    while span.get_attribute("data-revision") in (None, "0"):  # the status of the path shown
        assert time.monotonic() < deadline, "the status line names no alignment"
        page.wait_for_timeout(50)
    return page, seen


def test_a_second_tab_shows_the_pairs_alignment_without_solving_it_again(pair, tmp_path_factory):
    body, hand = pair
    with served_chromium(tmp_path_factory, str(body), str(hand), "--no-warm") as (browser, url):
        first, _ = _open(browser, url)
        assert first.locator(".hs-status span").get_attribute("data-aligned") == "here"
        second, seen = _open(browser, url)
        assert not any("aligning" in line for line in seen), seen
        assert second.locator(".hs-status span").get_attribute("data-aligned") == "shared"
        a, b = status_line(first), status_line(second)
        assert COSTS.search(b).group(0) == COSTS.search(a).group(0)
        assert band_cells(b) == band_cells(a)
        errors = first.errors + second.errors
        first.context.close()
        second.context.close()
    assert not errors, errors
