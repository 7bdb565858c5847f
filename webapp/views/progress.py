"""The page's "aligning…" line: what the session computes off the event loop, and for how long.

Shown while :attr:`webapp.state.Session.busy` is set (takes being opened, an
alignment being solved on the worker: :mod:`webapp.solves`): a moving progress bar,
the engine's stage (pass 1, pass 2, merge) and the seconds since it started, updated
when its text changes (looked at twice a second); hidden when the path on screen is the current one. The rest of the
page stays usable meanwhile (edits made then are solved next, the newest wins).
"""

from __future__ import annotations

import time

import panel as pn

from webapp import safe_text
from webapp.state import Session
from webapp.views._dispatch import after, after_path

#: how often the line's stage and seconds are looked at while busy, ms (the page gets a
#: message only when the line's text changed: whole seconds, a new stage)
TICK_MS = 500
#: work shorter than this shows no line (a drag's re-solve, even a long pair's on a busy
#: machine): no flicker, and no page update that the new path would wait behind (each
#: showing re-renders the pane on the server and lays the page out again in the browser)
SHOW_AFTER_S = 1.0
#: the line keeps its height when empty, so showing it never lays the page out again
HEIGHT_PX = 24


class BusyLine:
    """An indeterminate progress bar and a line of text while ``session.busy``."""

    def __init__(self, session: Session):
        self.session = session
        self.pane = pn.pane.HTML(
            "",
            css_classes=["hs-busy-line"],
            height=HEIGHT_PX,
            margin=(2, 10),
            sizing_mode="stretch_width",
            styles={"font-family": "monospace", "font-size": "13px", "color": "#1d3557"},
        )
        self._timer = False  # a tick is due (``_tick``)
        self._doc = None
        self._shown = False
        session.param.watch(self._on_busy, ["busy", "opening"])
        self._on_busy()

    def _line(self) -> str:
        s = self.session
        runner = s.runner
        running = runner is not None and runner.busy
        stage = (runner.stage if running and runner.stage else s.busy) or "working"
        seconds = time.monotonic() - runner.started if runner is not None else 0.0
        size = f" · {s.n:,} × {s.m:,} frames" if s.n and s.m and stage.startswith("align") else ""
        tail = "the page stays usable; edits made now are solved next"
        if s.opening:  # one line for the whole opening (checking, reading, first solve)
            stage = f"opening {s.opening}" + (f": {stage}" if running else ": reading the takes")
            seconds, size = time.monotonic() - s.opening_since, ""
            tail = "the greyed views below take no edits until it is aligned"
        return (
            f'<div class="hs-busy" data-busy="{safe_text.html(s.busy or "opening")}" '
            'style="display:flex;gap:10px;align-items:center">'
            '<progress style="width:140px;height:12px"></progress>'
            f"<span>{safe_text.html(stage)}… {seconds:.0f} s{size} · {tail}</span></div>"
        )

    def _show(self, text: str) -> None:
        self._shown = bool(text)
        if self.pane.object != text:
            self.pane.object = text

    def _on_busy(self, *_):
        busy = bool(self.session.busy or self.session.opening)
        doc = pn.state.curdoc
        if doc is None or doc.session_context is None:  # no server: shown as it is
            self._show(self._line() if busy else "")
            return
        self._doc = doc
        if busy and not self._timer:
            if self.session.opening or not self.session.busy.startswith("align"):  # at once
                self._show(self._line())
            # Bokeh timeouts, not Panel's periodic callbacks: each run of one of those
            # toggles Panel's busy state, a message to the page during every solve
            self._timer = True
            after(doc, self._tick, TICK_MS)
        elif not busy and self._shown:
            # a solve's line goes once its path is in the page: hiding it in the tick that
            # draws the path sent the pane's change before the path
            after_path(self.session, ("busy-line", id(self)), self._hide, doc)

    def _hide(self) -> None:
        if self._shown and not (self.session.busy or self.session.opening):
            self._show("")

    def _tick(self):
        self._timer = False
        s, runner = self.session, self.session.runner
        if not (s.busy or s.opening):
            return
        self._timer = True
        after(self._doc, self._tick, TICK_MS)
        if s.opening:
            self._show(self._line())
            return
        if runner is None:
            return
        if self._shown or time.monotonic() - runner.started >= SHOW_AFTER_S:
            self._show(self._line())

    def panel(self) -> pn.viewable.Viewable:
        return self.pane


#: ms between the first matrix being in the page and the page's later sections (share,
#: lesson) being built: the browser draws the matrix before the server sends more
LATER_MS = 300


#: the first line's seconds, counted in the browser from the moment the page was asked
#: for (``performance.now()``: milliseconds since the navigation began), so they include
#: the wait for the server's first answer and for the page's scripts. The server's own
#: count starts when it builds the page: a loaded server's shell read "0 s" 3 s after the
#: request (stranger 7), and stayed so until the server's first tick. Rewritten whenever
#: the server sends the line again and every quarter second; stops once the line is empty.
_JS_CLOCK = """
if (window.__hs_first_clock) { return; }
window.__hs_first_clock = true;
const doc = Bokeh.documents[0];
const line = doc && [...doc._all_models.values()].find(
  m => (m.css_classes || []).includes(CLASS));
if (!line) { return; }
const fix = () => {
  const view = Bokeh.index.find_one(line);
  const root = view && (view.shadow_el || view.el);
  const clock = root && root.querySelector('.' + CLOCK);
  if (clock) { clock.textContent = `${Math.round(performance.now() / 1000)} s`; }
};
const timer = setInterval(() => {
  if (!line.text || line.document == null) { clearInterval(timer); return; }
  fix();
}, 250);
line.properties.text.change.connect(() => { fix(); queueMicrotask(fix); });
fix();
"""
#: the classes of the first line's pane and of its seconds
FIRST_LINE_CLASS, CLOCK_CLASS = "hs-first-line", "hs-first-s"


class FirstLine:
    """The page's first line, sent with its first answer: what the server does for this
    page and the seconds since it was asked for it (building the page, opening the takes
    and the engine's stage, aligning), until the first matrix is in the page; then empty.
    In the browser the seconds count from the request (:data:`_JS_CLOCK`); the server's
    text counts from its building the page (a page without a browser: tests, scripts).

    ``building()`` when the page's sections are being built; ``built(then)`` once they
    are in the page: ``then()`` runs once nothing is opening or aligning any more (the
    first matrix, band and path are drawn), :data:`LATER_MS` later."""

    def __init__(self, session: Session):
        self.session = session
        self.since = time.monotonic()
        self._phase = "opening the page"  # what the page itself does ('' once built)
        self._then = None
        self._timer = None
        self._doc = pn.state.curdoc
        self.done = False
        self.pane = pn.pane.HTML(
            self._html(self._phase),
            css_classes=[FIRST_LINE_CLASS],
            height=HEIGHT_PX,
            margin=(6, 10, 0, 10),
            sizing_mode="stretch_width",
            styles={"font-family": "monospace", "font-size": "13px", "color": "#1d3557"},
        )
        if self._served():
            from bokeh.models import CustomJS

            args = {"CLASS": FIRST_LINE_CLASS, "CLOCK": CLOCK_CLASS}
            self._doc.js_on_event("document_ready", CustomJS(args=args, code=_JS_CLOCK))

    def _served(self) -> bool:
        doc = self._doc
        return doc is not None and doc.session_context is not None

    def _html(self, stage: str) -> str:
        seconds = time.monotonic() - self.since
        return (
            f'<div class="hs-first" data-stage="{safe_text.html(stage)}" '
            'style="display:flex;gap:10px;align-items:center">'
            '<progress style="width:140px;height:12px"></progress>'
            f'<span>{safe_text.html(stage)}… <span class="{CLOCK_CLASS}">{seconds:.0f} s</span>'
            "</span></div>"
        )

    def _stage(self) -> str | None:
        """What the line says now: the page's own phase and the session's work (opening
        the takes, aligning, with the engine's stage); None: the first matrix is in."""
        s = self.session
        runner = s.runner
        running = runner is not None and runner.busy and runner.stage
        work = ""
        if s.opening:
            work = f"opening {s.opening}: " + (runner.stage if running else "reading the takes")
        elif s.busy:
            work = runner.stage if running else s.busy
        return " · ".join(part for part in (self._phase, work) if part) or None

    def building(self) -> None:
        self._phase = "building the page"
        if self._served() and self._timer is None:
            self._timer = pn.state.add_periodic_callback(self._tick, period=TICK_MS)
        self._tick()

    def built(self, then) -> None:
        self._phase = ""
        self._then = then
        if not self._served():
            self._finish()
            return
        self._tick()

    def failed(self, text: str) -> None:
        """The page could not be built: the line says ``text`` and stops."""
        self.done = True
        if self._timer is not None:
            self._timer.stop()
            self._timer = None
        self.pane.object = f'<div class="hs-first" data-stage="failed">{safe_text.html(text)}</div>'

    def update(self) -> None:
        """Say what happens now (the periodic tick does so too, between callbacks)."""
        self._tick()

    def _tick(self) -> None:
        if self.done:
            return
        stage = self._stage()
        if stage is None:
            self._finish()
        else:
            self.pane.object = self._html(stage)

    def _finish(self) -> None:
        self.done = True
        if self._timer is not None:
            self._timer.stop()
            self._timer = None
        self.pane.object = ""
        then, self._then = self._then, None
        if then is None:
            return
        if self._served():
            from webapp.views._dispatch import after

            after(self._doc, then, LATER_MS)
        else:
            then()

    def panel(self) -> pn.viewable.Viewable:
        return self.pane
