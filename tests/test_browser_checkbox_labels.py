"""Every checkbox of the page toggles when a person clicks its words, as on most web pages
(stranger R5-8: clicking "Hand trails" did nothing; only the tiny box itself toggled)."""

from __future__ import annotations

import time

import pytest

pytestmark = pytest.mark.browser

#: the page's checkboxes: (the element holding it, the words beside the box)
CHECKBOXES = [
    (".hs-trails", "Hand trails"),
    (".hs-follow", "Follow edits"),
    (".hs-teach-point", "Matching point"),
]


def _wait_checked(box, want: bool, what: str, timeout: float = 20.0) -> None:
    deadline = time.monotonic() + timeout
    while box.is_checked() != want:
        assert time.monotonic() < deadline, f"clicking {what!r} did not toggle its box"
        box.page.wait_for_timeout(100)


def test_clicking_a_checkbox_label_toggles_the_box(demo_page):
    page = demo_page
    for holder, words in CHECKBOXES:
        widget = page.locator(holder)
        box = widget.locator("input[type=checkbox]")
        before = box.is_checked()
        widget.get_by_text(words, exact=True).click()  # the words, not the box
        _wait_checked(box, not before, words)
        widget.get_by_text(words, exact=True).click()
        _wait_checked(box, before, words)
    if "trails" in page.locator(".hs-share-url input").input_value():
        pytest.fail("the trails went back off, the link still says trails=1")
