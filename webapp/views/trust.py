"""Trust in the alignment on the page: confidence strip, uncertain region, desync meter,
suggested matching points (issue 17; the numbers come from ``engine.splice.uncertainty``).

* a strip under the body take's phase track, one cell per body frame, green / amber /
  red for an uncertainty under 50 ms / up to 100 ms / above (viewers notice desync
  above ~100 ms); rows with no hand match (open ends) light grey. In a pair the motion
  does not pin anywhere (its typical uncertainty is over 100 ms: two different
  performances) the summary says so once, and the colours count what a place adds to
  that typical level (grey: no worse than the rest of the pair; amber / red: 50 / 100 ms
  more), so the places to check first still stand out;
* a light region around the path on the matrix: ± the uncertainty, in hand frames;
* the desync meter: a bar under each gesture stroke of the body take's phase track in
  its verdict's colour, and a one-line summary;
* up to three suggested matching points: the first click shows that moment in the
  preview (body take and hand take side by side), the second places the point.

The assessment costs about four solves (tens of solves' CPU on a long pair's band), so
it runs off the event loop once edits pause: ``DEBOUNCE_MS`` after the last edit was
drawn, never while the session is solving or opening takes, and one at a time per page
(an edit made meanwhile is assessed when the running one ends; a result for an older edit
is dropped). A running assessment is given up as soon as a newer edit is being solved
(``engine.base.errors.Cancelled``, looked at between its γ sweeps), so it never holds a
core the next drag's solve needs. Assessments started during a drag competed with the drag's own solves for
the CPU and the GIL (benchmarks/RESULTS.md, section app).
"""

from __future__ import annotations

import concurrent.futures
import html
import time

import numpy as np
import panel as pn
from bokeh.models import ColumnDataSource, HoverTool

from engine.base.errors import Cancelled, run_cancellable
from webapp import safe_text
from webapp.state import Session
from webapp.views._dispatch import after, after_path, next_tick, with_document_lock

VERDICT_COLORS = {
    "ok": "#2e7d32",
    "check": "#f9a825",
    "desync": "#c62828",
    "typical": "#9e9e9e",
    "unmatched": "#e0e0e0",
}
VERDICT_WORDS = {
    "ok": "in sync (< 50 ms)",
    "check": "check (50–100 ms)",
    "desync": "may look out of sync (> 100 ms)",
    "typical": "not pinned, like the rest of this pair",
    "unmatched": "no hand match (the fingers hold)",
}
#: the words of a pair the motion does not pin (``Uncertainty.pinned`` false): the
#: verdicts then count what a place adds to the pair's typical uncertainty
UNPINNED_WORDS = {
    **VERDICT_WORDS,
    "check": "less certain than the rest of this pair (+50–100 ms)",
    "desync": "least certain: a matching point helps most here (+100 ms or more)",
}
REGION_COLOR = "#ffffff"
#: assess once edits have paused this long (each drag is an edit; an assessment costs more
#: CPU than a solve, and one started between two drags ran beside the next drag's solve)
DEBOUNCE_MS = 1000
_POOL = concurrent.futures.ThreadPoolExecutor(max_workers=2, thread_name_prefix="hs-trust")


#: the summary line while a pair's first assessment runs (about four solves' time: several
#: minutes for a 10-minute pair on a busy machine, where an empty line looked finished)
ASSESSING = "assessing how certain the timing is (about four solves' time)…"
#: the legend under the matrix (static: one text for pinned pairs and pairs not pinned)
LEGEND_WORDS = {
    **VERDICT_WORDS,
    "check": "check (50–100 ms; in a pair not pinned: 50–100 ms over its typical)",
    "desync": "may look out of sync (> 100 ms; in a pair not pinned: > 100 ms over its typical)",
}


def _runs(values: list[str], words: dict = VERDICT_WORDS) -> dict:
    """Runs of equal verdicts as quads along the body axis."""
    if not values:
        return {"start": [], "stop": [], "color": [], "verdict": []}
    v = np.asarray(values)
    cut = np.flatnonzero(v[1:] != v[:-1]) + 1
    starts = np.concatenate([[0], cut])
    stops = np.concatenate([cut, [len(v)]])
    return {
        "start": starts - 0.5,
        "stop": stops - 0.5,
        "color": [VERDICT_COLORS[x] for x in v[starts]],
        "verdict": [words[x] for x in v[starts]],
    }


#: the desync summary while the suggestions are stale (an edit is being assessed)
STALE_SUMMARY = '<b>Desync meter:</b> <span class="hs-updating">updating…</span>'

#: the page greys the suggestion buttons out while the summary says they are stale: the
#: buttons' own DOM state, not their models' ``disabled`` (see ``TrustView._draw``)
_JS_GREY = """
const stale = String(source.text ?? "").includes("hs-updating");
for (const b of [b0, b1, b2]) {
  const el = Bokeh.index.find_one(b)?.button_el;
  if (el != null) el.disabled = stale;
}
"""


class TrustView:
    """The trust layers of one session's cost matrix view."""

    def __init__(self, session: Session, matrix):
        self.session = session
        self._width = matrix.panel_width
        self._matrix = matrix  # draws the region thinned to the screen (``show_line``)
        self._doc = pn.state.curdoc
        self._pending = False  # a timeout callback to _start is waiting
        self._due = 0.0  # monotonic s before which no assessment starts (edits still coming)
        self._running = False  # an assessment of this page is on the pool
        self._failed = -1  # the revision whose assessment failed (not tried again)
        #: assessments given up because a newer edit made them stale (read by tests)
        self.cancelled = 0
        self._armed: int | None = None  # suggestion index whose moment is being shown
        self._takes = session.takes_key  # the takes the layers and suggestions are of
        fig = matrix.figure
        self.region_source = ColumnDataSource(
            {"x": [], "lo": [], "hi": []}, name="hs-uncertain-region-source"
        )
        fig.varea(
            x="x",
            y1="lo",
            y2="hi",
            source=self.region_source,
            fill_color=REGION_COLOR,
            fill_alpha=0.22,
            name="hs-uncertain-region",
            level="underlay",
        )
        # two rows under the body take's phase track (which spans -0.32..-0.08): the desync
        # meter (one bar per stroke) and the confidence strip (one cell per body frame)
        body_fig = matrix.body_figure
        body_fig.y_range.start = -0.80
        self.meter_source = ColumnDataSource(
            {"start": [], "stop": [], "color": [], "verdict": [], "ms": []},
            name="hs-desync-meter-source",
        )
        meter = body_fig.quad(
            left="start",
            right="stop",
            bottom=-0.52,
            top=-0.37,
            color="color",
            line_color="#202020",
            line_width=1,
            source=self.meter_source,
            name="hs-desync-meter",
        )
        body_fig.add_tools(
            HoverTool(
                renderers=[meter],
                tooltips=[
                    ("stroke", "body frames @start{0}–@stop{0}"),
                    ("timing uncertainty", "@ms{0} ms"),
                    ("verdict", "@verdict"),
                ],
            )
        )
        self.strip_source = ColumnDataSource(
            {"start": [], "stop": [], "color": [], "verdict": []}, name="hs-confidence-source"
        )
        quads = body_fig.quad(
            left="start",
            right="stop",
            bottom=-0.78,
            top=-0.58,
            color="color",
            source=self.strip_source,
            name="hs-confidence-strip",
        )
        body_fig.add_tools(
            HoverTool(
                renderers=[quads],
                tooltips=[("body frames", "@start{0}–@stop{0}"), ("timing", "@verdict")],
            )
        )
        body_fig.frame_height = body_fig.frame_height + 22
        self.summary = pn.pane.HTML(
            "",
            css_classes=["hs-desync-summary"],
            styles={"font-size": "13px"},
            margin=(2, 10),
            width=matrix.panel_width - 20,
        )
        self.buttons = [
            pn.widgets.Button(
                label="",
                visible=False,
                color="primary",
                variant="outline",  # a button to press, not a line of text
                css_classes=["hs-suggestion"],
                margin=(2, 4),
                width=400,
            )
            for _ in range(3)
        ]
        for k, b in enumerate(self.buttons):
            b.on_click(lambda _e, k=k: self._on_suggestion(k))
        self.summary.jscallback(text=_JS_GREY, args=dict(zip(("b0", "b1", "b2"), self.buttons)))
        session.param.watch(self._on_revision, ["revision"])
        session.param.watch(self._on_trust, ["trust"])
        session.param.watch(self._on_takes, ["inputs_revision"])
        # a solve or a drag ended
        session.param.watch(lambda *_: self._schedule(0), ["busy", "dragging"])
        self._on_revision()

    # ------------------------------------------------------------ computing

    def _on_revision(self, *_):
        self._armed = None
        self._draw_soon()
        if self.session.solution is None:
            return
        doc = self._doc
        if doc is None or doc.session_context is None:  # tests without a server: at once
            self.session.update_trust()
            return
        self._schedule(DEBOUNCE_MS)

    def _wanted(self) -> bool:
        """An assessment is due: a solution without one, no solve or opening running, no
        drag under way, none of this page's assessments running."""
        s = self.session
        return (
            s.solution is not None
            and s.trust is None
            and not s.busy
            and not s.edit_coming()
            and not self._running
            and s.revision != self._failed
        )

    def _schedule(self, delay_ms: float) -> None:
        """Start an assessment ``delay_ms`` from now (later if edits keep coming)."""
        doc = self._doc
        if doc is None or doc.session_context is None:
            return
        now = time.monotonic()
        self._due = max(self._due, now + delay_ms / 1000.0)
        if not self._pending and self._wanted():
            self._pending = True
            after(doc, self._start, max(self._due - now, 0.0) * 1000.0)

    def _start(self):
        self._pending = False
        wait = self._due - time.monotonic()
        if wait > 0.005:  # an edit since the timer was set: wait for the pause after it
            self._schedule(0)
            return
        if not self._wanted():  # solving (assessed when it is drawn) or one is running
            return
        s = self.session
        revision = s.revision
        self._running = True

        def stale() -> bool:  # on the worker: a newer edit is coming or solved, or was drawn
            return s.revision != revision or s.edit_coming()

        # given up as soon as it is stale: an assessment (about four solves' work) beside
        # the next drag's solve would take a core from it and slow its path
        future = _POOL.submit(run_cancellable, s.assess, stale)
        doc = self._doc

        def finished(result):  # on the event loop
            self._running = False
            if result is Cancelled:
                self.cancelled += 1  # the newer edit is assessed once it is drawn
            elif result is None:
                self._failed = revision
            else:
                s.update_trust(result, revision)
            self._schedule(0)  # an edit drawn meanwhile is assessed now

        def done(f):
            try:
                result = f.result()
            except Cancelled:
                result = Cancelled
            except Exception:  # an assessment that fails leaves the page as it is
                result = None
            try:
                next_tick(doc, lambda: finished(result))
            except Exception:  # the page was closed meanwhile
                pass

        future.add_done_callback(done)

    # ------------------------------------------------------------ drawing

    def _on_trust(self, *_):
        self._draw_soon()

    @with_document_lock
    def _on_takes(self, *_):
        """Other takes are shown: the layers, summary and suggestions of the previous pair
        go at once (in the tick that shows the takes, under the page's veil), not greyed
        as an edit's are: they name another pair's frames."""
        if self.session.takes_key == self._takes:
            return
        self._takes = self.session.takes_key
        self.summary.object = ""
        for b in self.buttons:
            b.visible = False
        self._draw(None)

    def _draw_soon(self) -> None:
        """Draw the session's trust (None: the old one greyed) once the edit's path is in
        the page (``after_path``): the layers and the buttons' changes went out before it."""
        after_path(
            self.session, ("trust", id(self)), lambda: self._draw(self.session.trust), self._doc
        )

    @with_document_lock
    def _draw(self, trust):
        s = self.session
        if trust is None or s.solution is None:
            self._matrix.show_line(self.region_source, np.zeros(0, np.int32), {"lo": [], "hi": []})
            self.strip_source.data = _runs([])
            self.meter_source.data = {"start": [], "stop": [], "color": [], "verdict": [], "ms": []}
            # the old suggestions are greyed out, not hidden, until the new ones arrive, by
            # the page itself (``_JS_GREY``, on this text): showing, hiding, disabling or
            # enabling a widget lays the whole page out again in the browser (150-300 ms
            # each in a software-rendered page on a busy machine; six per edit), which
            # held up the next drag's path
            if self.summary.object:
                self.summary.object = STALE_SUMMARY
            elif s.solution is not None:  # the first assessment: minutes on a long take
                self.summary.object = f"<b>Desync meter:</b> {ASSESSING}"
            for b in self.buttons:
                if s.solution is None:  # no takes: no suggestions to come
                    b.visible = False
            return
        unc = trust.uncertainty
        r = s.hand_scale  # the matrix's hand axis counts hand-file frames
        warp = np.asarray(s.solution.warp, dtype=float) * r
        frames = unc.ms * unc.fps / 1000.0 * r  # ms -> grid columns -> hand-file frames
        x = np.arange(len(warp), dtype=np.int32)
        self._matrix.show_line(
            self.region_source,
            x,
            {"lo": (warp - frames).astype(np.float32), "hi": (warp + frames).astype(np.float32)},
        )
        words = VERDICT_WORDS if unc.pinned else UNPINNED_WORDS
        self.strip_source.data = _runs(unc.frame_verdicts(), words)
        st = trust.strokes
        self.meter_source.data = {
            "start": [k.start - 0.5 for k in st],
            "stop": [k.end + 0.5 for k in st],
            "color": [VERDICT_COLORS[k.verdict] for k in st],
            "verdict": [words[k.verdict] for k in st],
            "ms": [k.uncertainty_ms for k in st],
        }
        self.summary.object = "<b>Desync meter:</b> " + html.escape(trust.summary)
        for k, b in enumerate(self.buttons):
            if k < len(trust.suggestions):
                body, _ = trust.suggestions[k]
                b.label = f"Check body frame {body} (±{unc.ms[body]:.0f} ms)"
                b.color = "light"
                b.visible = True
            else:
                b.visible = False

    def _on_suggestion(self, k: int):
        s, trust = self.session, self.session.trust
        if trust is None or k >= len(trust.suggestions):
            return
        body = int(trust.suggestions[k][0])
        if self._armed != k:  # first click: show the moment (body and hand side by side)
            self._armed = k
            s.frame = body
            self.buttons[k].label = f"Place a matching point at body frame {body}"
            self.buttons[k].color = "primary"
            return
        self._armed = None
        s.add_point(body, s.hand_frame_for(body))

    @property
    def width(self) -> int:
        """Pixels of the matrix panel this view sits under (its margins included)."""
        return self._width + 20

    def panel(self) -> pn.viewable.Viewable:
        """Legend, summary and suggestions, no wider than the matrix (the preview sits
        beside them on a wide screen)."""
        width = self._width
        legend = " ".join(
            f'<span style="display:inline-block;width:10px;height:10px;background:{c};'
            f'margin:0 3px 0 10px"></span>{html.escape(LEGEND_WORDS[k])}'
            for k, c in VERDICT_COLORS.items()
        )
        for b in self.buttons:
            b.width = width - 30
        return pn.Column(
            pn.pane.HTML(
                "Under the body's gesture phases: <b>desync meter</b> (one bar per "
                "stroke) and <b>timing confidence</b> per body frame; the light "
                "region around the path is where the match could move." + "<br>" + legend,
                styles={"font-size": "12px"},
                margin=(2, 10),
                width=width - 20,
            ),
            self.summary,
            pn.pane.HTML(
                "<b>Least certain places</b> (most uncertainty around them first; ± is the "
                "frame's own):",
                margin=(4, 10, 0, 10),
            ),
            *self.buttons,
            width=width,
            margin=0,
        )


def unpinned_words(trust) -> str:
    """What the downloads say about an alignment the motion does not pin
    (``Uncertainty.pinned`` false: the trust panel's "do not pin the timing"), with the
    body frames the trust panel suggests checking; '' for a pinned one or none yet. The
    alignment itself is as the aligner left it: a person who downloads without reading
    the trust panel is told here."""
    if trust is None or trust.uncertainty.pinned:
        return ""
    frames = [int(body) for body, _ in trust.suggestions]
    text = (
        "⚠ The motion does not pin the timing of this splice (typical uncertainty "
        f"±{trust.uncertainty.typical_ms:.0f} ms): the fingers may land on the wrong moment."
    )
    if frames:
        where = ", ".join(str(f) for f in frames)
        text += (
            f" Check body frame{'s' if len(frames) > 1 else ''} {where} in the preview (the "
            "Check buttons under the matrix)"
        )
    else:
        text += " Check it in the preview"
    return text + " and place matching points by eye before downloading."


def unpinned_alert(session: Session) -> pn.viewable.Viewable:
    """:func:`unpinned_words` next to the downloads: follows each assessment; hidden when
    other takes are shown until theirs arrives (meanwhile an edit's assessment keeps the
    last words: showing and hiding lays the page out again)."""
    alert = pn.pane.Alert(
        "",
        alert_type="warning",
        css_classes=["hs-unpinned-alert"],
        sizing_mode="stretch_width",
        visible=False,
    )

    def update(*events):
        if any(e.name == "inputs_revision" for e in events):
            alert.visible = False
        if session.trust is None:
            return
        words = unpinned_words(session.trust)
        if words:
            alert.object = safe_text.markdown(words)
        alert.visible = bool(words)

    session.param.watch(update, ["trust", "inputs_revision"])
    update()
    return alert
