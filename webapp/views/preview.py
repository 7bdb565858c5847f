"""Preview: skinned renders of the body take, the hand take and the spliced result.

The panels show one moment: body frame ``i``, the hand-file frame the alignment
matches to it, and the spliced take's frame ``i`` side by side, and next to them the
spliced hands close up (the fingers fill that frame, so they can be judged). The
first frame is rendered when the page opens. One frame slider chooses the moment;
Play runs at the take's own frame rate, skipping frames when a render is slower
than a frame. While playing, the slider, the caption, the matrix's frame marker and the
image move together: a frame is rendered first and the page steps to it with its
image (the slider never runs ahead of the picture); when the picture waits on a slow
render (a long take's first frame after an edit builds its meshes: seconds), a line
under Play says so, with the frame and the seconds waited. A click on the cost matrix
in "Pick frames" mode chooses the frame too. Rendering is offscreen (pyrender,
EGL/OSMesa) on the server; each image is sent as a PNG.
"""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor

import panel as pn

from engine.base.errors import Cancelled, check_cancelled, run_cancellable
from webapp import backend, safe_text
from webapp.state import Session
from webapp.views._dispatch import after, after_path, next_tick
from webapp.views.checkbox import Checkbox

#: a preview following edits is rendered once edits have paused this long, ms (a render
#: started between two drags ran beside the next drag's solve: on a 2-minute pair it is
#: ~0.3 s of CPU, most of it holding the interpreter, and its first steps cannot stop);
#: the trust assessment waits for the same pause (``webapp.views.trust.DEBOUNCE_MS``)
FOLLOW_PAUSE_MS = 1000
#: how often the player looks at the clock, ms (each look shows the frame of that moment)
PLAY_TICK_MS = 30
#: a render this long (s) holds Play visibly: the page says it waits for it
SLOW_RENDER_S = 0.5
#: a turning ring before that line (drawn by CSS: no emoji font needed)
_SPINNER = (
    "<style>@keyframes hs-spin{to{transform:rotate(360deg)}}</style>"
    '<span style="display:inline-block;width:9px;height:9px;margin-right:4px;'
    "border:2px solid #8a5a00;border-top-color:transparent;border-radius:50%;"
    'animation:hs-spin 0.8s linear infinite;vertical-align:-1px"></span>'
)
#: the preview's line while new takes have no picture yet (the previous pair's are gone)
PENDING = "the first frame of these takes is drawn once they are aligned…"
#: the worker that renders previews of all sessions (OpenGL calls take turns anyway:
#: engine.render.backend.GL_LOCK), so the event loop never waits for a render
_RENDERS = ThreadPoolExecutor(max_workers=1, thread_name_prefix="hs-preview")


def _render_images(prepared, solution, frame, camera, trails, size, closeup_size, stale=None):
    """``(png, close-up png, (body, hand, spliced frame), ms)`` of one moment (run on the
    render worker, or at once without a server). ``stale``: a callable; when it returns
    True before a step (the spliced take, the full view, the close-up), or between the
    blocks of frames of the spliced take and of its view, the render stops with
    ``engine.base.errors.Cancelled``."""
    t0 = time.perf_counter()
    check_cancelled(stale)
    # the whole spliced take (cached): a step of its own, given up between its blocks of
    # frames when stale
    backend.splice(prepared, solution, cancelled=stale)
    check_cancelled(stale)
    # the preview's views of the new spliced take (posed block by block): given up too
    image = backend.render_frame(prepared, solution, frame, camera, trails, size, stale)
    check_cancelled(stale)
    closeup = backend.render_closeup(prepared, solution, frame, closeup_size)
    pngs = backend.png_bytes(image), backend.png_bytes(closeup)
    frames = backend.frame_triplet(prepared, solution, frame)
    return (*pngs, frames, (time.perf_counter() - t0) * 1000)


class PreviewView:
    TEXT = (
        "Skinned mannequins of the body take, the hand take at the matched frame and the "
        "spliced result (body with the hand take's wrist and fingers), and the spliced "
        "hands close up. Drag the frame slider or press Play (the take's real speed); "
        "with *Pick frames* a click on the matrix jumps there."
    )

    def __init__(
        self,
        session: Session,
        size: tuple[int, int] = (680, 240),
        closeup_size: tuple[int, int] = (330, 300),
    ):
        self.session = session
        self.size = size
        self.closeup_size = closeup_size
        self.image = pn.pane.PNG(
            None,
            width=size[0],
            height=size[1],
            sizing_mode="fixed",
            css_classes=["hs-preview-image"],
            margin=(0, 0, 4, 0),
        )
        self.closeup = pn.pane.PNG(
            None,
            width=closeup_size[0],
            height=closeup_size[1],
            sizing_mode="fixed",
            css_classes=["hs-closeup-image"],
            margin=0,
        )
        self.info = pn.pane.HTML(
            "",
            css_classes=["hs-preview-info"],
            styles={"font-family": "monospace", "font-size": "12px"},
        )
        self.alert = pn.pane.Alert(
            "", alert_type="warning", visible=False, css_classes=["hs-preview-error"]
        )
        n = max(session.n, 1)
        self.slider = pn.widgets.IntSlider(
            label="Body frame",
            start=0,
            end=max(n - 1, 1),
            value=session.frame,
            css_classes=["hs-frame-slider"],
            width=330,
            tooltips=False,  # the label says the frame; a tooltip would cover it
        )
        self.play = pn.widgets.Toggle(
            label="▶ Play", value=False, width=90, css_classes=["hs-play"]
        )
        # Play waiting on a slow render: a line that is empty otherwise (its height is kept,
        # so the page does not lay out again when it appears)
        self.waiting = pn.pane.HTML(
            "",
            css_classes=["hs-play-wait"],
            height=18,
            margin=(0, 10),
            styles={"font-size": "12px", "color": "#8a5a00"},
        )
        # the view state lives in the session (saved in its file and link): widgets of its
        # parameters
        self.camera = pn.widgets.Select.from_param(
            session.param.camera,
            name="Camera",
            width=130,
            css_classes=["hs-camera"],
            description=None,  # no tooltip from the parameter's doc (the page looks as before)
        )
        self.trails = Checkbox.from_param(
            session.param.trails, name="Hand trails", width=110, css_classes=["hs-trails"]
        )
        self.auto = Checkbox.from_param(
            session.param.follow, name="Follow edits", width=110, css_classes=["hs-follow"]
        )
        self.slider.param.watch(self._on_slider, "value")
        self.play.param.watch(self._on_play, "value")
        session.param.watch(self._on_frame, ["frame"])
        session.param.watch(self._on_inputs, ["inputs_revision"])
        session.param.watch(self._on_solution, ["revision"])
        session.param.watch(self._on_busy, ["busy", "dragging"])
        self._points_seen = session.points  # the points of the alignment last followed
        self._after_solve = False  # a solution to render once edits pause and solves end
        self._follow_due = 0.0  # monotonic s of that pause's end
        self._follow_timer = False
        self._doc = pn.state.curdoc  # the tab's document (callbacks may run outside it)
        session.param.watch(lambda *_: self._render_soon(), ["camera", "trails"])
        self._rendered_key = None
        self._takes = session.takes_key  # the takes of the pictures shown
        self._played = None
        self._inflight = False
        self._since = 0.0  # when the render in flight was asked for (perf_counter s)
        self._again = False
        self._scheduled = False
        self._player = None
        self._clock = (0.0, 0)
        doc = pn.state.curdoc
        if doc is not None and doc.session_context is not None:
            pn.state.onload(self.render)  # the first frame as soon as the page is up

    def _on_slider(self, event):
        frame = int(event.new)
        if self.play.value and frame != self.session.frame:  # moved by hand while playing:
            self._clock = (time.perf_counter(), frame)  # play on from there
        self.session.frame = frame

    def _on_inputs(self, *_):
        end = max(self.session.n - 1, 1)
        self.slider.end = end
        self._rendered_key = None
        if self.session.takes_key != self._takes:  # other takes: the pictures were not theirs
            self._takes = self.session.takes_key
            self.image.object = self.closeup.object = None
            self.info.object = f'<span class="hs-preview-pending">{PENDING}</span>'
        self._points_seen = self.session.points  # a new pair: no edit to follow
        self._render_soon()

    def _on_frame(self, *_):
        f = self.session.frame
        if self.slider.value != f:
            self.slider.value = f
        self._render_soon()

    def _on_solution(self, *_):
        # the first solution of a pair opened off the loop arrives after the takes: its
        # first frame is rendered then, later ones only when following edits, and once no
        # newer edit is being solved (a render beside a solve slows the solve: the next
        # path waits; the newest solution is rendered when the session is idle)
        if self._rendered_key is None:
            self._points_seen = self.session.points
            self._render_soon()
        elif self.session.follow:
            self._follow_due = time.monotonic() + FOLLOW_PAUSE_MS / 1000.0
            self._after_solve = True
            self._follow_later(FOLLOW_PAUSE_MS)
        else:
            self._points_seen = self.session.points

    def _follow_later(self, ms: float) -> None:
        doc = pn.state.curdoc or self._doc
        if doc is None or doc.session_context is None:
            self._after_solve = False
            self._follow_edit()
        elif not self._follow_timer:
            self._follow_timer = True
            after(doc, self._on_busy, max(ms, 0.0))

    def _on_busy(self, *_):
        """Render the newest solution once no solve runs, no drag is under way and edits
        have paused."""
        self._follow_timer = False
        if not self._after_solve or self.session.busy or self.session.dragging:
            return
        wait = self._follow_due - time.monotonic()
        if wait > 0.005:
            self._follow_later(wait * 1000.0)
            return
        self._after_solve = False
        self._follow_edit()

    def _follow_edit(self) -> None:
        """Following edits: the preview goes to the body frame of the point the edits placed
        (added, moved, or brought back by undo; a band, tolerance or delete edit keeps the
        frame) and shows it with the new alignment."""
        s = self.session
        old = {(p.body, p.hand) for p in self._points_seen or ()}
        placed = [p.body for p in s.points or () if (p.body, p.hand) not in old]
        self._points_seen = s.points
        frame = placed[-1] if placed else None
        if frame is not None and not self.play.value and s.n:
            frame = int(min(max(frame, 0), s.n - 1))
            if frame != s.frame:
                s.frame = frame  # _on_frame renders it
                return
        self._render_soon()

    # ------------------------------------------------------------ playing

    def _on_play(self, event):
        if event.new:
            self.play.label = "❚❚ Pause"
            self._clock = (time.perf_counter(), self.session.frame)
            doc = pn.state.curdoc
            if doc is not None and doc.session_context is not None:
                self._player = pn.state.add_periodic_callback(self._tick, period=PLAY_TICK_MS)
        else:
            self.play.label = "▶ Play"
            self.waiting.object = ""
            if self._player is not None:
                self._player.stop()
                self._player = None

    def _tick(self) -> None:
        """Render the frame the clock has reached (at the take's rate); frames that went
        by while the last render ran are skipped, so playback keeps real time. The
        session's frame (slider, caption, marker) steps when that frame's image is shown."""
        s = self.session
        if self._inflight:
            waited = time.perf_counter() - self._since
            if waited >= SLOW_RENDER_S:  # the picture is held: say so (and for how long)
                frame = self._played[2] if self._played is not None else s.frame
                self.waiting.object = (
                    f'<span data-waiting="{frame}">{_SPINNER} waiting for the render of body '
                    f"frame {frame}… {waited:.1f} s</span>"
                )
            return
        if s.n <= 1 or self._scheduled:
            return
        start, first = self._clock
        frame = (first + int((time.perf_counter() - start) * s.fps)) % s.n
        if frame != s.frame:
            self.render(frame)

    # ------------------------------------------------------------ rendering

    def _render_soon(self):
        """Render after the current update has gone out (a drag's new path is not held
        back by the preview)."""
        doc = pn.state.curdoc
        if doc is None or doc.session_context is None:
            self.render()
        elif not self._scheduled:
            self._scheduled = True

            def run():
                self._scheduled = False
                self.render()

            next_tick(doc, run)

    def _key(self, frame: int | None = None) -> tuple:
        s = self.session
        frame = s.frame if frame is None else frame
        return (s.revision, s.inputs_revision, frame, s.camera, s.trails)

    def render(self, frame: int | None = None) -> bool:
        """Render the current frame, or body frame ``frame`` (Play: the session steps to
        it when its image is shown); full bodies and the hands close up. False (and a
        message) when it cannot.

        In a server session the render runs on a worker thread (hundreds of ms with a
        software OpenGL): the event loop goes on serving this page and every other
        meanwhile, and the images are shown when they are ready. A frame asked for while
        one renders is rendered next (only the newest). Without a server (tests, page
        building) it renders at once."""
        s = self.session
        if s.prepared is None or s.solution is None:
            return False
        key = self._key(frame)
        if key == self._rendered_key:
            return True
        job = (s.prepared, s.solution, key[2], s.camera, s.trails)
        doc = pn.state.curdoc
        if doc is None or doc.session_context is None:
            if self._inflight:
                return False
            self._inflight = True
            try:
                result = _render_images(*job, self.size, self.closeup_size)
            except Exception as exc:  # shown in the page, never a traceback
                result = exc
            finally:
                self._inflight = False
            return self._show(key, result)
        if self._inflight:
            if frame is None:
                self._again = True  # rendered when the one in flight is shown
            return True
        self._inflight = True
        self._since = time.perf_counter()
        if frame is not None:
            self._played = key  # shown, it moves the session to its frame
        # a render of an edit's alignment is given up when a newer edit is being solved or
        # a drag is under way (it would take a core from that solve; the newer one is
        # rendered when drawn)
        stale = None if self.play.value or s.runner is None else s.edit_coming
        future = _RENDERS.submit(
            run_cancellable, _render_images, *job, self.size, self.closeup_size, stale
        )

        def done(f):
            try:
                next_tick(doc, lambda: self._finish(key, f))
            except Exception:  # the page was closed meanwhile: nothing to show
                pass

        future.add_done_callback(done)
        return True

    def _finish(self, key: tuple, future) -> None:
        """Show a worker's render (on the event loop, under the document lock); while an
        edit is being solved, once its path is in the page (the images' messages are the
        largest of an edit: they went out before the path)."""
        runner = self.session.runner
        if runner is not None and runner.solving() and not self.play.value:
            after_path(
                self.session,
                ("preview", id(self)),
                lambda: self._finish_now(key, future),
                pn.state.curdoc or self._doc,
            )
            return
        self._finish_now(key, future)

    def _finish_now(self, key: tuple, future) -> None:
        self._inflight = False
        if self.waiting.object:
            self.waiting.object = ""
        try:
            result = future.result()
        except Cancelled:  # a newer edit: rendered once it is drawn and edits pause
            self._played = None
            self._after_solve = True
            self._follow_due = time.monotonic() + FOLLOW_PAUSE_MS / 1000.0
            self._follow_later(FOLLOW_PAUSE_MS)
            return
        except Exception as exc:  # the worker's own failure: shown like any other
            result = exc
        shown = self._show(key, result)
        s = self.session
        played, self._played = self._played, None
        if (
            shown
            and key == played
            and self.play.value
            and not self._again  # nothing asked for meanwhile (a slider moved by hand)
            and key[:2] == self._key()[:2]
        ):
            s.frame = key[2]  # a played frame: slider, caption and marker step with its image
        if self._again or key != self._key():
            self._again = False
            self.render()

    def _show(self, key: tuple, result) -> bool:
        """Put a render's PNGs (or its error) on the page."""
        if isinstance(result, Exception):  # shown in the page, never a traceback
            self.alert.object = safe_text.markdown(f"preview: {backend.one_line(result)}")
            self.alert.visible = True
            return False
        png, close_png, (b, h, o), ms = result
        s = self.session
        self.alert.visible = False
        self.image.object = png
        self.closeup.object = close_png
        self._rendered_key = key
        self.info.object = (
            f'<span data-frame="{b}" data-hand-frame="{h}">body frame {b} ({b / s.fps:.2f} s)'
            f" · hand frame {h} ({h / s.hand_fps:.2f} s) · spliced frame {o}"
            f"<br>rendered in {ms:.0f} ms</span>"
        )
        return True

    def panel(self) -> pn.viewable.Viewable:
        controls = pn.Column(
            pn.Row(self.play, self.camera, margin=0),
            self.waiting,
            self.slider,
            pn.Row(self.trails, self.auto, margin=0),
            self.info,
            self.alert,
            width=self.size[0] - self.closeup_size[0] - 10,
            sizing_mode=None,
        )
        return pn.Column(
            self.image,
            pn.Row(
                pn.Column(
                    self.closeup,
                    pn.pane.HTML(
                        "<div style='font-size:11px;color:#555'>the spliced hands close up</div>",
                        margin=(0, 4),
                    ),
                    margin=0,
                ),
                controls,
                margin=0,
            ),
            css_classes=["hs-preview"],
            width=self.size[0] + 10,
            sizing_mode=None,
        )
