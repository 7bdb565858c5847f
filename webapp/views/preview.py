"""Preview: skinned renders of the body take, the hand take and the spliced result.

The panels show one moment: body frame ``i``, the hand-file frame the alignment
matches to it, and the spliced take's frame ``i`` side by side, and next to them the
spliced hands close up (the fingers fill that frame, so they can be judged). The
first frame is rendered when the page opens. One frame slider chooses the moment;
Play runs at the take's own frame rate, skipping frames when a render is slower
than a frame, with the slider always on the frame shown. A click on the cost matrix
in "Pick frames" mode chooses the frame too. Rendering is offscreen (pyrender,
EGL/OSMesa) on the server; each image is sent as a PNG.
"""

from __future__ import annotations

import time

import panel as pn

from webapp import backend, safe_text
from webapp.state import Session

#: how often the player looks at the clock, ms (each look shows the frame of that moment)
PLAY_TICK_MS = 30


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
        )
        self.play = pn.widgets.Toggle(
            label="▶ Play", value=False, width=90, css_classes=["hs-play"]
        )
        self.camera = pn.widgets.Select(
            label="Camera",
            options=["three-quarter", "front", "side"],
            value="three-quarter",
            width=130,
        )
        self.trails = pn.widgets.Checkbox(label="Hand trails", value=False, width=110)
        self.auto = pn.widgets.Checkbox(label="Follow edits", value=True, width=110)
        self.slider.param.watch(self._on_slider, "value")
        self.play.param.watch(self._on_play, "value")
        session.param.watch(self._on_frame, ["frame"])
        session.param.watch(self._on_inputs, ["inputs_revision"])
        session.param.watch(self._on_solution, ["revision"])
        self.camera.param.watch(lambda e: self.render(), "value")
        self.trails.param.watch(lambda e: self.render(), "value")
        self._rendered_key = None
        self._inflight = False
        self._scheduled = False
        self._player = None
        self._clock = (0.0, 0)
        doc = pn.state.curdoc
        if doc is not None and doc.session_context is not None:
            pn.state.onload(self.render)  # the first frame as soon as the page is up

    def _on_slider(self, event):
        self.session.frame = int(event.new)

    def _on_inputs(self, *_):
        end = max(self.session.n - 1, 1)
        self.slider.end = end
        self._rendered_key = None
        self._render_soon()

    def _on_frame(self, *_):
        f = self.session.frame
        if self.slider.value != f:
            self.slider.value = f
        self._render_soon()

    def _on_solution(self, *_):
        if self.auto.value and self._rendered_key is not None:
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
            if self._player is not None:
                self._player.stop()
                self._player = None

    def _tick(self) -> None:
        """Show the frame the clock has reached (at the take's rate); frames that went by
        while the last render ran are skipped, so playback keeps real time."""
        s = self.session
        if s.n <= 1 or self._inflight or self._scheduled:
            return
        start, first = self._clock
        frame = (first + int((time.perf_counter() - start) * s.fps)) % s.n
        if frame != s.frame:
            s.frame = frame

    # ------------------------------------------------------------ rendering

    def _render_soon(self):
        """Render after the current update has gone out (a drag's new path is not held
        back by the preview's tens of milliseconds)."""
        doc = pn.state.curdoc
        if doc is None or doc.session_context is None:
            self.render()
        elif not self._scheduled:
            self._scheduled = True

            def run():
                self._scheduled = False
                from webapp.views.sharing import exports_running

                if exports_running():  # the renderer is busy: try again soon
                    self._scheduled = True
                    doc.add_timeout_callback(run, 500)
                    return
                self.render()

            doc.add_next_tick_callback(run)

    def render(self) -> bool:
        """Render the current frame (full bodies and the hands close up); False (and a
        message) when it cannot."""
        s = self.session
        if s.prepared is None or s.solution is None or self._inflight:
            return False
        key = (s.revision, s.inputs_revision, s.frame, self.camera.value, self.trails.value)
        if key == self._rendered_key:
            return True
        self._inflight = True
        t0 = time.perf_counter()
        try:
            image = backend.render_frame(
                s.prepared, s.solution, s.frame, self.camera.value, self.trails.value, self.size
            )
            closeup = backend.render_closeup(s.prepared, s.solution, s.frame, self.closeup_size)
            png, close_png = backend.png_bytes(image), backend.png_bytes(closeup)
        except Exception as exc:  # shown in the page, never a traceback
            self.alert.object = safe_text.markdown(f"preview: {backend.one_line(exc)}")
            self.alert.visible = True
            return False
        finally:
            self._inflight = False
        self.alert.visible = False
        self.image.object = png
        self.closeup.object = close_png
        self._rendered_key = key
        b, h, o = backend.frame_triplet(s.prepared, s.solution, s.frame)
        ms = (time.perf_counter() - t0) * 1000
        self.info.object = (
            f'<span data-frame="{b}" data-hand-frame="{h}">body frame {b} ({b / s.fps:.2f} s)'
            f" · hand frame {h} ({h / s.hand_fps:.2f} s) · spliced frame {o}"
            f"<br>rendered in {ms:.0f} ms</span>"
        )
        return True

    def panel(self) -> pn.viewable.Viewable:
        controls = pn.Column(
            pn.Row(self.play, self.camera, margin=0),
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
