"""A new user's rough edges of the page, through its own controls in real Chromium:

- while one uploaded take waits for its partner, the sample picker does not name the
  sample pair still shown as the one chosen (it said "wave-ok").
"""

from __future__ import annotations

import time

import pytest
from conftest import (
    BODY_BVH,
    assert_no_traceback,
    open_page,
    pane_text,
    served_app,
    status_line,
)

pytestmark = [pytest.mark.browser, pytest.mark.timeout(1500)]

SERVER_START_S = 600.0
BUSY_S = 300.0


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    with served_app(tmp_path_factory, timeout=SERVER_START_S) as (url, _, log_path):
        yield url
    assert_no_traceback(log_path)


@pytest.fixture()
def page(browser, server):
    page = open_page(browser, server, timeout_s=SERVER_START_S)
    yield page
    page.context.close()
    assert not page.errors, page.errors


def _until(condition, what: str, seconds: float = BUSY_S):
    deadline = time.monotonic() + seconds
    while not (value := condition()):
        assert time.monotonic() < deadline, what
        time.sleep(0.2)
    return value


def _picker(page) -> str:
    """The sample picker's shown entry (the text of its selected option)."""
    return page.locator(".hs-sample select").first.evaluate(
        "s => s.options[s.selectedIndex]?.text ?? ''"
    )


def _uploaded_line(page) -> str:
    line = page.locator(".hs-upload-status")
    return pane_text(line) if line.count() else ""


def test_the_sample_picker_does_not_name_the_sample_while_an_upload_waits(page):
    demo = _picker(page)
    assert demo and not demo.startswith("(")
    page.locator(".hs-upload-body input[type=file]").set_input_files(str(BODY_BVH))
    _until(lambda: "waiting for a hand take" in status_line(page), "no waiting status")
    shown = _until(lambda: _picker(page) if _picker(page) != demo else "", "picker kept the sample")
    assert "waiting" in shown and demo not in shown, shown
    # choosing the sample that is shown drops the waiting upload
    page.locator(".hs-sample select").first.select_option(demo)
    _until(lambda: "waiting" not in status_line(page), "the upload still waits")
    _until(lambda: _picker(page) == demo, "the picker does not show the sample")
    assert "now the other take" not in _uploaded_line(page)
