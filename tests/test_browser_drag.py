"""A matching point dragged with the mouse in real Chromium (Playwright driving Debian's
Chromium as a person does): the edit's new path reaches the page before the rest of what
the edit changes, and it is the session's path for the points the page shows.

Everything else an edit changes (status line, points table, link, trust summary) used to
be computed in the event-loop tick that drew the path, or while its solve ran, and sent
before it: the page applied those widgets' changes first (each one can lay the whole page
out again), and the path waited (``benchmarks/RESULTS.md``, drag latency).
"""

from __future__ import annotations

import time

import numpy as np
import pytest
from conftest import (
    DEMO_SAMPLE,
    DEMO_SERVER_START_S,
    open_demo_session,
    open_page,
    pane_text,
    revision,
)

pytestmark = [pytest.mark.browser, pytest.mark.timeout(900)]

#: the page records, in order, which of the edit's views changed (Bokeh's own change
#: signals of their models, as the page applies the server's messages)
_JS_RECORD = """() => {
  const doc = Bokeh.documents[0];
  const has = (m, c) => (m.css_classes ?? []).includes(c);
  window.hsOrder = [];
  // the document's own change events: every model change the page applies, in order
  // (robust to the document's models being pulled again on a reconnection)
  doc.on_change((ev) => {
    const m = ev.model;
    if (m == null) return;
    const attr = ev.attr;
    let what = null;
    if (m.name === 'hs-path-source') what = 'path';
    else if (m.name === 'hs-band-source') what = 'band';
    else if (has(m, 'hs-status') && attr === 'text') what = 'status';
    else if (has(m, 'hs-share-url') && attr === 'value') what = 'link';
    else if (has(m, 'hs-desync-summary') && attr === 'text') what = 'trust';
    else if ([...doc.all_models].some(t => has(t, 'hs-points') && t.source === m)) what = 'table';
    if (what !== null) window.hsOrder.push(what);
  });
}"""


@pytest.fixture(scope="module")
def page(browser, demo_url):
    """A tab of its own (a session of its own) on the run's shared demo server, for the
    module's two tests in turn (the second drags the first one's point)."""
    p = open_page(browser, demo_url, timeout_s=DEMO_SERVER_START_S, console=True)
    yield p
    p.context.close()


#: the page records each time the status line is dimmed or shown again (stranger 11 F6),
#: with the revision the line shows then (its text as the model holds it: escaped HTML)
_JS_RECORD_STALE = """() => {
  const doc = Bokeh.documents[0];
  const status = [...doc.all_models].find(m => (m.css_classes ?? []).includes('hs-status'));
  const el = Bokeh.index.find_one(status).el;
  const rev = () => Number(/data-revision=(?:"|&quot;)(\\d+)/.exec(status.text)[1]);
  window.hsStale = [];
  new MutationObserver(() => window.hsStale.push([el.dataset.hsStale === '1', rev()]))
    .observe(el, {attributes: true, attributeFilter: ['data-hs-stale']});
}"""


def _wait(page, cond, what: str, timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > deadline:
            raise AssertionError(what)
        page.wait_for_timeout(50)


def _order(page) -> list[str]:
    return page.evaluate("() => window.hsOrder")


def _link_settled(page, must: str, still_s: float = 1.5) -> None:
    """Wait until the share link contains ``must`` and has not changed for ``still_s``."""
    box = page.locator(".hs-share-url input")
    last, since = None, time.monotonic()
    deadline = since + 120.0
    while True:
        link = box.input_value()
        if link != last:
            last, since = link, time.monotonic()
        elif must in link and time.monotonic() - since >= still_s:
            return
        assert time.monotonic() < deadline, f"the link did not settle: {link!r}"
        page.wait_for_timeout(100)


def test_drag_sends_the_path_first_and_it_is_the_sessions_path(page, tmp_path):
    n = page.evaluate("hs.frames()")
    path = page.evaluate("hs.cols('hs-path-source', ['x', 'y'])")
    k = path["x"].index(n // 2)
    x, y = path["x"][k], path["y"][k]
    rev = revision(page)
    page.mouse.click(*page.evaluate("([a, b]) => hs.xy(a, b)", [x, y]))
    _wait(page, lambda: revision(page) > rev, "the click's point was not solved")
    # the click's trust assessment is in the page (its summary names the meter's verdict)
    summary = page.locator(".hs-desync-summary").first
    _wait(
        page,
        lambda: "Desync meter" in (t := pane_text(summary)) and "updating" not in t,
        "no trust summary after the click",
    )
    pts = page.evaluate("hs.cols('hs-points-source', ['x', 'y'])")
    assert len(pts["x"]) == 1
    # the click's own follow-up work is done: its link names the point, and it has stood
    # still longer than the link's wait for a picked frame and the after-path delay
    _link_settled(page, "pts=")

    page.evaluate(_JS_RECORD)
    page.evaluate(_JS_RECORD_STALE)
    rev = revision(page)
    target = pts["y"][0] + max(8, n // 8)
    a = page.evaluate("([a, b]) => hs.xy(a, b)", [pts["x"][0], pts["y"][0]])
    b = page.evaluate("([a, b]) => hs.xy(a, b)", [pts["x"][0], target])
    page.mouse.move(*a)
    page.mouse.down()
    page.mouse.move(*b, steps=6)
    page.mouse.up()
    # the edit's every view has changed: path, band, status, table, link, trust summary
    wanted = {"path", "band", "status", "table", "link", "trust"}
    _wait(page, lambda: wanted <= set(_order(page)), f"not every view changed: {_order(page)}")
    _wait(page, lambda: revision(page) > rev, "the drag was not solved")
    order = _order(page)
    first = {what: order.index(what) for what in wanted}
    # the path and the band came before any of the rest
    for what in ("status", "table", "link", "trust"):
        assert first["path"] < first[what] and first["band"] < first[what], order
    # the status line was dimmed from the release on, while it still said the old points,
    # and shown again with the edit's own line (stranger 11 F6)
    _wait(page, lambda: page.evaluate("window.hsStale").count([False, revision(page)]), "dim")
    stale = page.evaluate("window.hsStale")
    assert stale[0] == [True, rev] and stale[-1] == [False, revision(page)], stale

    # the path shown is the session's for the points the page shows: every vertex the
    # page draws (thinned to the screen's columns) is a cell of the engine's path
    pts = page.evaluate("hs.cols('hs-points-source', ['x', 'y', 'tol'])")
    assert abs(pts["y"][0] - target) <= 2, pts
    shown = page.evaluate("hs.cols('hs-path-source', ['x', 'y'])")
    session = open_demo_session(tmp_path, DEMO_SAMPLE)
    session.set_points_from_view(list(zip(pts["x"], pts["y"], [None] * len(pts["x"]))))
    assert session.error == "", session.error
    # the red line is the alignment used (pass 2 on the demo's forearm-less hand)
    from engine.splice.pipeline import alignment_pass

    used = alignment_pass(session.prepared.features)
    want = (session.solution.pass1 if used == 1 else session.solution.pass2).path
    r = session.hand_scale
    cells = {(int(i), float(np.float32(j * r))) for i, j in want}
    assert len(shown["x"]) > 10
    missing = [(i, j) for i, j in zip(shown["x"], shown["y"]) if (int(i), float(j)) not in cells]
    assert not missing, missing[:10]
    # and the path goes through the dragged point (the global tolerance is 0): its hand
    # frame is the hand file's, the path's cells sit hand_fps / fps apart
    at = [j for i, j in zip(shown["x"], shown["y"]) if i == round(pts["x"][0])]
    assert at and min(abs(j - round(pts["y"][0])) for j in at) <= r / 2 + 1e-3
    assert not page.errors, page.errors


#: the trust summary's text and whether each suggestion button is disabled, as shown
_JS_SUGGESTIONS = """() => {
  const doc = Bokeh.documents[0];
  const models = [...doc.all_models];
  const summary = models.find(m => (m.css_classes ?? []).includes('hs-desync-summary'));
  const buttons = models.filter(m => (m.css_classes ?? []).includes('hs-suggestion') && m.visible);
  return [String(summary.text), buttons.map(m => Bokeh.index.find_one(m).button_el.disabled)];
}"""


def test_stale_suggestions_are_greyed_by_the_page_not_by_model_changes(page):
    """After an edit the old suggestions are greyed out until the new ones arrive, without
    changing the buttons' models (each such change laid the whole page out again)."""

    def shown():
        text, disabled = page.evaluate(_JS_SUGGESTIONS)
        return "updating" in text, disabled

    _wait(page, lambda: (s := shown())[1] and not s[0] and not any(s[1]), "no usable suggestions")
    page.evaluate(
        """() => {
      window.hsButtonChanges = 0;
      for (const m of Bokeh.documents[0].all_models) {
        if ((m.css_classes ?? []).includes('hs-suggestion'))
          m.properties.disabled.change.connect(() => { window.hsButtonChanges += 1; });
      }
    }"""
    )
    rev = revision(page)
    pts = page.evaluate("hs.cols('hs-points-source', ['x', 'y'])")
    a = page.evaluate("([a, b]) => hs.xy(a, b)", [pts["x"][0], pts["y"][0]])
    b = page.evaluate("([a, b]) => hs.xy(a, b)", [pts["x"][0], pts["y"][0] - 6])
    page.mouse.move(*a)
    page.mouse.down()
    page.mouse.move(*b, steps=4)
    page.mouse.up()
    _wait(page, lambda: revision(page) > rev, "the drag was not solved")
    # greyed while the edit is assessed (the assessment waits a second for more edits)...
    _wait(page, lambda: shown()[0], "the summary never said the suggestions are stale")
    stale, disabled = shown()
    assert not stale or all(disabled), disabled
    # ...then usable again, with the buttons' models never changed
    _wait(page, lambda: (s := shown())[1] and not s[0] and not any(s[1]), "still greyed")
    assert page.evaluate("() => window.hsButtonChanges") == 0


def test_the_page_tells_the_server_when_a_drag_of_a_point_begins_and_ends(page):
    """drag11: the page says at once that a matching point is being dragged
    (``hs-drag-press``, synced to the server: the previous edit's preview and trust give
    way before the drag's edit arrives on release), and that it ended."""
    press = "() => Bokeh.documents[0].get_model_by_name('hs-drag-press').data.down[0]"
    pts = page.evaluate("hs.cols('hs-points-source', ['x', 'y'])")
    if not pts["x"]:  # run alone: a point on the path first
        n = page.evaluate("hs.frames()")
        path = page.evaluate("hs.cols('hs-path-source', ['x', 'y'])")
        k = path["x"].index(n // 2)
        rev = revision(page)
        page.mouse.click(*page.evaluate("([a, b]) => hs.xy(a, b)", [path["x"][k], path["y"][k]]))
        _wait(page, lambda: revision(page) > rev, "the click's point was not solved")
        pts = page.evaluate("hs.cols('hs-points-source', ['x', 'y'])")
    a = page.evaluate("([a, b]) => hs.xy(a, b)", [pts["x"][0], pts["y"][0]])
    b = page.evaluate("([a, b]) => hs.xy(a, b)", [pts["x"][0], pts["y"][0] + 6])
    rev = revision(page)
    assert page.evaluate(press) == 0
    page.mouse.move(*a)
    page.mouse.down()
    page.mouse.move(*b, steps=4)
    assert page.evaluate(press) == 1  # held: the drag is under way
    page.mouse.up()
    assert page.evaluate(press) == 0
    _wait(page, lambda: revision(page) > rev, "the drag was not solved")
    assert not page.errors, page.errors
