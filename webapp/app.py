"""The HandSplice page: one notebook-like layout built per browser session.

``create_app()`` is what the Bokeh server calls for every new session, so each
tab gets its own :class:`webapp.state.Session` and widgets; nothing mutable is
shared between sessions except the read-only per-pair caches in
:mod:`webapp.backend`.
"""

from __future__ import annotations

import time

import panel as pn

from webapp import backend, config
from webapp.backend import one_line
from webapp.state import Session

pn.extension("tabulator", "filedropper", notifications=False, sizing_mode="stretch_width")

CSS = """
.hs-section-text { color: #444; max-width: 980px; }
"""

HEADER = """
<div style="background:linear-gradient(90deg,#1d3557,#274c77);color:white;padding:14px 22px;
            border-radius:6px;font-family:Helvetica,Arial,sans-serif">
  <div style="font-size:26px;font-weight:600;letter-spacing:0.5px">HandSplice</div>
  <div style="font-size:14px;opacity:0.9;margin-top:4px">
    Hands and body are captured in separate sessions, so the takes differ in timing.
    A two-pass dynamic time warping (Majkowska et al. 2006) finds which hand frame belongs to
    each body frame; steer it with matching points, check the skinned result, share it.
  </div>
</div>
"""

ALIGN_TEXT = """
Each pixel compares a body frame (x) with a hand frame (y); dark is similar. Each pass's
optimal path is the cheapest monotone route between the frame pairs it matches, searched
only inside its **band** (blue). Pass 1 compares the signs of arm velocities and
accelerations (phases of the gesture), pass 2 refines inside a narrow band around the
pass-1 path by comparing forearm/hand directions (a hand take without a forearm: how the
hand turns, over pass 1's whole band, so its path can lie far from pass 1's). The **red
line is the alignment used**, in every view: the path the splice, the preview and the status
line follow (pass 2's; the legend says which); the dashed line is the other pass's path.

**Matching points** (yellow): *click* the matrix to add one, *drag* it to move it,
select it and press *Backspace* to delete it. The path then passes within the point's
tolerance (the yellow bar). Edit tolerances in the table; sliders set the band widths.
*Ctrl+Z* undoes, *Ctrl+Shift+Z* or *Ctrl+Y* redoes.

**Frame numbers** are each file's own everywhere in this page (matrix, table, preview,
command line, session file): body frames of the body file, hand frames of the hand file
at its own frame rate, with times in seconds next to them. (Internally the hand take is
resampled to the body's frame rate for the alignment; you never need those numbers.)
"""


def _section(title: str, text: str, *objects) -> pn.Column:
    head = [pn.pane.Markdown(f"## {title}", margin=(20, 10, 0, 10))]
    if text:
        head.append(pn.pane.Markdown(text, css_classes=["hs-section-text"]))
    return pn.Column(*head, *objects, sizing_mode="stretch_width")


def _link_args() -> dict[str, str]:
    """The page address's query (a shared link), decoded."""
    if not pn.state.session_args:
        return {}
    return {k: v[0].decode("utf-8", "replace") for k, v in pn.state.session_args.items() if v}


def _initial_state(session: Session, args: dict[str, str] | None = None) -> None:
    """Open the default sample pair, then restore the URL query's session over it.

    A bad value of a link (``band=99``) is left out and said in the page; the rest of the
    link (its takes above all) opens. A link whose takes cannot be opened (unknown sample
    or upload, points outside the matrix) leaves the default pair open and says why in
    the page; the address bar then shows the pair that is open, not the link's values.
    """
    if args is None:
        args = _link_args()
    cfg = session.config

    def open_default():
        if cfg.default_sample:
            try:
                session.load_sample(cfg.default_sample)
            except Exception as exc:
                session.refuse(exc)

    def link_refused(exc):  # the link's takes cannot be opened: the default pair opens
        session.keep_error(f"shared link: {one_line(exc)}", exc)
        session.link_not_opened(_not_opened(exc))
        if session.prepared is None:
            open_default()

    # a link of parameters only (``?frame=75``) opens the default pair with them: the
    # session's rule for a spec without takes (Session.apply_spec)
    linked = bool(args)  # a key that is not a link's is said too (read_query)
    if session.runner is not None:  # off the loop: the link's opening supersedes the default
        if linked:
            try:
                session.open_link(args, failed=link_refused)
                return
            except Exception as exc:  # the link itself is unreadable
                link_refused(exc)
                return
        open_default()
        return
    open_default()
    if linked:
        try:
            session.open_link(args)
        except Exception as exc:  # nothing was applied: the reason is shown
            session.refuse(exc, f"shared link: {one_line(exc)}")
            session.link_not_opened(_not_opened(exc))


def _not_opened(exc: BaseException) -> str:
    """The page's top line for a link whose takes could not be opened: why, and that the
    pair the page shows (the default one) is not the link's."""
    return f"{one_line(exc)} (the pair below is not the link's)"


def _local_stylesheets(doc) -> None:
    """Give every component of ``doc`` the server's own stylesheet URLs from its birth.

    Panel makes each component's stylesheets with its CDN's URLs unless the document
    already names a local ``dist_url``, which it does only once the page's HTML is
    rendered; at that moment it rewrites the URLs of the models then in the page. A model
    made earlier but shown later (a widget built before a callback puts it on the page,
    as under load) kept the CDN's URLs: an offline machine then drew the upload boxes
    and the points table unstyled. The URL is the one Panel's page render computes for a
    served page (its "server" resources: nothing leaves this machine).
    """
    from panel.io.resources import LOCAL_DIST
    from panel.io.state import state

    if doc is not None and doc.session_context is not None:
        local = f"{state.rel_path}/{LOCAL_DIST}" if state.rel_path else LOCAL_DIST
        doc._template_variables.setdefault("dist_url", local)


def create_app() -> pn.viewable.Viewable:
    """Build the page for one browser session.

    Served, the page's first answer is a light shell: the header and a line that says
    what the server does and for how long (building the page, opening the takes,
    aligning), so a long pair never shows a blank page. Once the browser has the shell
    (Panel's ``onload``), the pair starts opening on the worker and the takes and
    alignment sections are built beside it; the share and lesson sections follow once
    the first matrix is in the page (:class:`webapp.views.progress.FirstLine`).
    Without a server (tests, scripts) the whole page is built at once."""
    from webapp.views import connection
    from webapp.views.progress import FirstLine

    session = Session(config.get())
    doc = pn.state.curdoc
    _local_stylesheets(doc)
    args = _link_args()
    served = doc is not None and doc.session_context is not None
    first = FirstLine(session)
    page = pn.Column(
        pn.pane.HTML(HEADER, sizing_mode="stretch_width", margin=(10, 10, 0, 10)),
        first.panel(),
        sizing_mode="stretch_width",
        css_classes=["hs-app"],
        styles={"max-width": "2000px", "margin": "0 auto"},
    )
    page.session = session  # for tests and debugging
    if served:
        # opening and solving never hold the event loop; they start once the shell is in
        # the browser (a page fetched but never shown, e.g. a readiness probe, computes
        # nothing and builds no more than the shell)
        session.compute_off_loop(doc)
        pn.state.onload(lambda: fill_page(page, session, first, args))
        # the page closed: the alignment it showed is no longer shown (Session.page_closed)
        doc.on_session_destroyed(lambda _: session.page_closed())
    else:
        fill_page(page, session, first, args)
    connection.install(doc if served else None)
    return page


def fill_page(page: pn.Column, session: Session, first, args: dict[str, str] | None) -> None:
    """Open the session's first pair and put the page's sections into the shell ``page``:
    the matrix at once (the pair opens on the worker meanwhile), the takes' inputs, the
    matrix's controls and the preview in the next tick (so the matrix goes to the browser
    first), share and lesson once the first matrix is drawn (``first.built``); without a
    server all at once."""
    from webapp.views.link_notice import link_notice

    first.building()
    if args is None:
        args = _link_args()
    page.append(link_notice(session, args))  # before the link opens: it may refuse
    _initial_state(session, args)  # served: the pair opens on the worker from here on
    first.update()  # "building the page · opening NAME: …" goes out with the matrix
    try:
        sections, rest = _work_sections(session)
        page.extend(sections)
    except Exception as exc:  # the line says so (no endless "building the page…"); logged
        first.failed(f"the page could not be built ({one_line(exc)}); reload to try again")
        raise

    def fill_rest():
        try:
            rest()
        except Exception as exc:
            first.failed(f"the page could not be built ({one_line(exc)}); reload to try again")
            raise
        first.built(lambda: page.extend(_later_sections(session)))

    doc = pn.state.curdoc
    if doc is not None and doc.session_context is not None:
        from webapp.views._dispatch import after

        after(doc, fill_rest, 0)
    else:
        fill_rest()


def _work_sections(session: Session) -> tuple[list, object]:
    """The takes and the alignment sections, and ``rest()``, which fills in what the first
    matrix does not need: the takes' inputs, the matrix's controls and points table, the
    preview."""
    from webapp.views import controls, credits
    from webapp.views.cost_matrix import CostMatrixView
    from webapp.views.progress import BusyLine
    from webapp.views.trust import TrustView
    from webapp.views.veil import Veil

    matrix = CostMatrixView(session)
    trust = TrustView(session, matrix)
    status = controls.status_line(session)
    # matrix, its controls and the preview side by side on a wide screen (they wrap below
    # one another on a narrow one); the trust layers sit under the matrix. A refusal shows
    # right under the matrix, never above it: a box (or a status line wrapping to a second
    # line) above the matrix moved it down under the pointer, and the next click landed on
    # another frame (stranger 6)
    views = pn.FlexBox(
        pn.Column(
            matrix.panel(),
            controls.error_alert(session),
            trust.panel(),
            margin=0,
            sizing_mode=None,
            width=trust.width,
        ),
        flex_wrap="wrap",
        align_items="flex-start",
        sizing_mode="stretch_width",
    )
    Veil(session, status, views)  # greyed, no input, while a new pair opens
    alignment = _section(
        "2 · Alignment",
        ALIGN_TEXT,
        status,
        BusyLine(session).panel(),
        views,
    )
    takes = _section("1 · Takes", "")

    def rest() -> None:
        from webapp.views.inputs import InputsView

        inputs = InputsView(session)
        takes.extend([inputs.panel(), credits.credits_pane(session)])
        points = controls.PointsTable(session)
        pick = pn.widgets.RadioButtonGroup.from_param(  # the session's pick mode (file, link)
            session.param.pick,
            name="",
            options={"Edit points": False, "Pick frames": True},
            css_classes=["hs-click-mode"],
            description=None,
        )
        # the mode applies in the browser at once (a click made before the server's answer
        # arrives must not add a point); the server sets the same (CostMatrixView.set_pick_mode)
        pick.jscallback(
            value="tool.add = cb_obj.labels[cb_obj.active] !== 'Pick frames'; tool.active = true",
            args={"tool": matrix.point_tool},
        )
        work = [
            pn.Column(
                controls.parameter_widgets(session),
                pn.pane.Markdown("**A click on the matrix**", margin=(10, 10, 0, 10)),
                pick,
                controls.undo_redo(session),
                pn.pane.Markdown(
                    "**Matching points** (empty tolerance = global)", margin=(10, 10, 0, 10)
                ),
                controls.hand_rate_note(session),
                points.panel(),
                width=420,
                sizing_mode=None,
            )
        ]
        try:
            from webapp.views.preview import PreviewView

            work.append(
                pn.Column(
                    pn.pane.Markdown("### 3 · Preview", margin=(0, 10)),
                    pn.pane.Markdown(
                        PreviewView.TEXT,
                        css_classes=["hs-section-text"],
                        width=680,
                        margin=(0, 10),
                    ),
                    PreviewView(session).panel(),
                    sizing_mode=None,
                    width=700,
                )
            )
        except ImportError:
            pass
        views.extend(work)

    return [takes, alignment], rest


def _later_sections(session: Session) -> list:
    """Share and the DTW lesson: built once the first matrix is in the page."""
    from webapp.views.sharing import SharingView

    sections = [_section("4 · Share", SharingView.TEXT, SharingView(session).panel())]
    try:
        from webapp.views.teaching import TeachingView

        sections.append(_section("5 · How DTW works", TeachingView.TEXT, TeachingView().panel()))
    except ImportError:
        pass
    return sections


#: a warm-up stage running this long (s) says so again on the console, and again after
#: as long (a long pair's first pass 1 compiles and runs for minutes on a busy machine)
HEARTBEAT_S = 15.0
#: the engine's stage names (``progress(stage, fraction)``) as the console says them
_STAGE_WORDS = {
    "features": "computing the takes' features (markers, phases; compiles the kernels "
    "the first time)",
    "pass 1": "aligning: pass 1 of 2",
    "pass 2": "aligning: pass 2 of 2",
    "merge": "aligning: merging the passes",
}


class ConsoleStages:
    """``progress(stage, fraction)`` lines on the console while the server warms up:
    ``HandSplice: aligning: pass 1 of 2 ...``, then ``... done (3.2 s)``, a percentage
    for a fraction between 0 and 1 (where the engine reports one), and every
    :data:`HEARTBEAT_S` of a stage still running ``... still aligning: pass 1 of 2
    (45 s)``, so a long start shows it is alive."""

    def __init__(self, out=None, heartbeat_s: float = HEARTBEAT_S):
        import threading

        self.out = out
        self.heartbeat_s = heartbeat_s
        #: also told each line (``webapp.warm_page.WarmPage.note``: the browser's page)
        self.also = None
        self.started = time.perf_counter()
        self._lock = threading.Lock()
        self._running: dict[str, float] = {}
        self._stop = threading.Event()
        self._beat = threading.Thread(target=self._beats, daemon=True, name="hs-warm-up")
        self._beat.start()

    def say(self, text: str) -> None:
        import sys

        print(f"HandSplice: {text}", file=self.out or sys.stderr, flush=True)
        if self.also is not None:
            self.also(text)

    def __call__(self, stage: str, fraction: float) -> None:
        words = _STAGE_WORDS.get(stage, stage)
        now = time.perf_counter()
        with self._lock:
            if fraction <= 0.0:
                self._running[words] = (now, now + self.heartbeat_s)
                self.say(f"{words} ...")
            elif fraction >= 1.0:
                began, _ = self._running.pop(words, (now, now))
                self.say(f"{words} done ({now - began:.1f} s)")
            else:
                self.say(f"{words} {100.0 * fraction:.0f}%")

    def _beats(self) -> None:
        while not self._stop.wait(min(1.0, self.heartbeat_s / 3.0)):
            now = time.perf_counter()
            with self._lock:
                for words, (began, due) in list(self._running.items()):
                    if now >= due:
                        self.say(f"... still {words} ({now - began:.0f} s)")
                        self._running[words] = (began, now + self.heartbeat_s)

    def close(self, done: bool = True) -> None:
        """Stop the heartbeat; ``done``: say how long the warm-up took."""
        self._stop.set()
        self._beat.join(timeout=1.0)
        if done:
            self.say(f"warm-up done in {time.perf_counter() - self.started:.1f} s")


def warm_up(cfg: config.AppConfig, progress=None) -> None:
    """Precompute the demo pair (features, JIT compilation) so the first page load is fast.

    ``progress(stage, fraction)`` (:class:`ConsoleStages` on the server's console): the
    stages as they start and end (reading, features, pass 1, pass 2, the matrix image,
    the preview's first frame)."""
    if not cfg.default_sample:
        return
    say = progress or (lambda stage, fraction: None)
    session = Session(cfg)
    try:
        with backend.stages_to(progress):
            session.load_sample(cfg.default_sample)
        if session.solution is not None:
            say("the cost matrix image", 0.0)
            session.cost_view((0, session.n, 0, session.m), 600)
            say("the cost matrix image", 1.0)
            backend.offer(session.prepared, session.solution)  # the first page's alignment
    except Exception as exc:  # the page will show the same problem; the server still starts
        print(f"warm-up of sample {cfg.default_sample!r} failed: {one_line(exc)}", flush=True)
        return
    try:  # the preview's first frame: imports the renderer, opens its OpenGL context and
        # builds the pair's meshes (kept with the pair), so the first page's preview is quick
        say("the preview's first frame (renderer, meshes)", 0.0)
        backend.render_frame(
            session.prepared, session.solution, session.frame, session.camera, False
        )
        backend.render_closeup(session.prepared, session.solution, session.frame)
        say("the preview's first frame (renderer, meshes)", 1.0)
    except Exception:  # noqa: BLE001 - the page's preview says what is wrong, if anything
        pass
