"""The page answers at once and says what it waits for (issue 13, stranger R3-1).

``handsplice serve BODY HAND --no-warm`` on a 30-second 120 fps pair (LAFAN1
``multipleActions1`` resampled: 3,600 frames, with ManipNet's mug hand take): the first
tab aligns the pair itself (seconds).
Before, the server built the whole page (matrix, trust, share, the DTW lesson) before
its first byte, and the opening started after that: a blank white page for 18-22 s on
a long pair. Now the first answer is a light shell (the header and a line) and the
line says what the server does and for how long (building the page, opening the takes,
aligning) until the matrix, band and path are in the page; the share and lesson
sections come after the matrix.
"""

from __future__ import annotations

import html
import re
import time
from pathlib import Path

import pytest
from conftest import HAS_PATH, open_tab, served_chromium

pytestmark = pytest.mark.browser

LESSON = "How DTW works"


SECONDS = 30
FPS = 120.0


@pytest.fixture(scope="module")
def pair(long_pair) -> tuple[Path, Path]:
    return long_pair(SECONDS, FPS)


@pytest.fixture(scope="module")
def served(tmp_path_factory, pair):
    body, hand = pair
    with served_chromium(tmp_path_factory, str(body), str(hand), "--no-warm") as s:
        yield s


def _first_line(page) -> str:
    line = page.locator(".hs-first")
    try:
        return line.first.inner_text(timeout=500).strip() if line.count() else ""
    except Exception:  # noqa: BLE001 - the line went away meanwhile
        return ""


#: records, at the first moment the page has its document, what that document holds
#: (``__hs_first``), and every text the server gives the first line (``__hs_lines``: a
#: busy browser may apply several before it paints, so polling the screen could miss one)
FIRST_DOCUMENT = """
(() => {
  window.__hs_lines = [];
  const look = () => {
    const d = window.Bokeh && Bokeh.documents.length ? Bokeh.documents[0] : null;
    if (d == null) { setTimeout(look, 5); return; }
    const line = [...d._all_models.values()].find(
      m => (m.css_classes || []).includes('hs-first-line'));
    window.__hs_first = {matrix: !!d.get_model_by_name('hs-x-range'),
                         line: line ? String(line.text) : null};
    if (line) {
      window.__hs_lines.push(String(line.text));
      line.properties.text.change.connect(() => window.__hs_lines.push(String(line.text)));
    }
  };
  look();
})();
"""
#: the stage a line's HTML names (its ``data-stage``), with its seconds
STAGE = re.compile(r'data-stage="([^"]*)".*?… <span class="hs-first-s">(\d+) s<', re.S)
#: ``[the seconds the first line shows, the browser's seconds since the page was asked for]``
#: once the line shows its seconds (in the page's shadow roots), else null
SHOWN_SECONDS = """
() => {
  const find = (root) => {
    const el = root.querySelector('.hs-first-s');
    if (el) { return el; }
    for (const e of root.querySelectorAll('*')) {
      const f = e.shadowRoot && find(e.shadowRoot);
      if (f) { return f; }
    }
    return null;
  };
  const el = find(document);
  return el ? [el.textContent, performance.now() / 1000] : null;
}
"""
#: the server's first answer comes this late (s): a loaded server
LATE_S = 3.0


def test_the_first_answer_is_a_light_shell_with_the_line(served):
    """The document the browser gets first holds the header and the first line, not the
    matrix: the server sends it before it builds the rest of the page or opens the pair."""
    browser, url = served
    context = browser.new_context(viewport={"width": 1300, "height": 1000})
    context.add_init_script(FIRST_DOCUMENT)

    def late(route):  # the page's request is answered LATE_S late, as by a loaded server
        time.sleep(LATE_S)
        route.continue_()

    context.route(lambda u: u.split("?")[0].rstrip("/") == url.split("?")[0].rstrip("/"), late)
    page = open_tab(context, url, timeout_s=300, ready="() => window.__hs_first !== undefined")
    first = page.evaluate("window.__hs_first")
    assert not first["matrix"], first
    assert first["line"] and "opening the page" in first["line"], first
    # stranger 7: "opening the page… 0 s" 3 s after the request. The seconds count from
    # the request (the browser's clock), not from when the server began the page
    text, since = page.wait_for_function(SHOWN_SECONDS, timeout=60_000).json_value()
    shown = int(re.fullmatch(r"(\d+) s", text).group(1))
    assert since >= LATE_S and abs(shown - since) <= 1.5, (text, since)
    page.wait_for_function(HAS_PATH, timeout=300_000)  # the rest of the page follows
    errors = page.errors
    context.close()
    assert not errors, errors


def test_the_line_names_the_stage_and_seconds_until_the_matrix_then_the_rest_comes(served):
    browser, url = served
    context = browser.new_context(viewport={"width": 1300, "height": 1000})
    context.add_init_script(FIRST_DOCUMENT)
    page = open_tab(
        context, url, timeout_s=300, ready="() => window.Bokeh && Bokeh.documents.length"
    )
    lesson_before_path = False
    deadline = time.monotonic() + 300
    while not page.evaluate(HAS_PATH):
        assert time.monotonic() < deadline, "no path"
        lesson_before_path |= page.get_by_text(LESSON).count() > 0
        page.wait_for_timeout(50)
    lines = [html.unescape(t) for t in page.evaluate("window.__hs_lines")]  # Panel escapes
    seen = [m.group(1) for m in map(STAGE.search, lines) if m]
    assert seen and seen[0] == "opening the page", [t[-80:] for t in lines]
    # while the page is built, the pair's opening (on the worker meanwhile) is named too
    assert any(
        t.startswith("building the page · opening ") and "opening the page" not in t for t in seen
    ), [t[-80:] for t in lines]
    assert not lesson_before_path, "the lesson was built before the matrix"
    # after the path: the line goes, the share and lesson sections arrive
    page.get_by_text(LESSON).first.wait_for(timeout=120_000)
    page.get_by_text("4 · Share").first.wait_for(timeout=10_000)
    deadline = time.monotonic() + 10
    while _first_line(page):
        assert time.monotonic() < deadline, _first_line(page)
        page.wait_for_timeout(50)
    errors = page.errors
    context.close()
    assert not errors, errors


def test_a_side_against_the_hand_files_name_is_warned_for_a_pair_from_disk(served):
    """Stranger 6, finding 7: ``serve BODY mug1_rightHand.bvh`` and Side *left* chosen in
    the page: the page says what an upload's line says (the same rule and words), not
    only the server's stderr; back to *right*, the warning goes."""
    from engine.model.roles import side_name_conflict

    browser, url = served
    context = browser.new_context(viewport={"width": 1300, "height": 1000})
    page = open_tab(context, url, timeout_s=300)
    warning = page.locator(".hs-local-side .hs-side-warning")
    assert warning.count() == 0  # the side the name says: nothing to warn of
    side = page.locator(".hs-side").first
    side.locator("button", has_text="left").click()
    warning.wait_for(state="visible", timeout=60_000)
    text = warning.inner_text()
    assert text == f"⚠ {side_name_conflict('mug1_rightHand.bvh', 'left')}", text
    side.locator("button", has_text="right").click()
    warning.wait_for(state="detached", timeout=60_000)
    errors = page.errors
    context.close()
    assert not errors, errors
