"""Preview: skinned renders of the body take, the hand take and the spliced result.

The three panels show one moment: body frame ``i``, the hand-take frame the
alignment matches to it, and the spliced take's frame ``i``. A frame slider and a
player step through the take; a click on the cost matrix in "Pick frames" mode
chooses the frame too. Rendering is offscreen (pyrender, EGL/OSMesa) on the
server; each image is sent as a PNG.
"""

from __future__ import annotations

import time

import panel as pn

from webapp import backend, safe_text
from webapp.state import Session


class PreviewView:
    TEXT = ("Skinned mannequins of the body take, the hand take at the matched frame, and the "
            "spliced result (body with the hand take's wrist and fingers). Drag the frame "
            "slider or press play; with *Pick frames* a click on the matrix jumps there.")

    def __init__(self, session: Session, size: tuple[int, int] = (960, 360)):
        self.session = session
        self.size = size
        self.image = pn.pane.PNG(None, width=size[0], height=size[1], sizing_mode="fixed",
                                 css_classes=["hs-preview-image"])
        self.info = pn.pane.HTML("", css_classes=["hs-preview-info"],
                                 styles={"font-family": "monospace", "font-size": "12px"})
        self.alert = pn.pane.Alert("", alert_type="warning", visible=False,
                                   css_classes=["hs-preview-error"])
        n = max(session.n, 1)
        self.slider = pn.widgets.IntSlider(label="Body frame", start=0, end=max(n - 1, 1),
                                           value=session.frame, css_classes=["hs-frame-slider"],
                                           sizing_mode="stretch_width")
        self.player = pn.widgets.Player(start=0, end=max(n - 1, 1), value=session.frame,
                                        interval=120, loop_policy="loop", show_loop_controls=False,
                                        width=360, css_classes=["hs-player"], step=2,
                                        visible_buttons=["previous", "reverse", "pause", "play",
                                                         "next"])
        self.camera = pn.widgets.Select(label="Camera", options=["three-quarter", "front", "side"],
                                        value="three-quarter", width=150)
        self.trails = pn.widgets.Checkbox(label="Hand trails", value=False, width=110)
        self.render_button = pn.widgets.Button(label="Render", color="primary", width=90,
                                               css_classes=["hs-render"])
        self.auto = pn.widgets.Checkbox(label="Follow edits", value=True, width=110)
        self.slider.param.watch(self._on_slider, "value_throttled")
        self.player.param.watch(lambda e: setattr(session, "frame", int(e.new)), "value")
        session.param.watch(self._on_frame, ["frame"])
        session.param.watch(self._on_inputs, ["inputs_revision"])
        session.param.watch(self._on_solution, ["revision"])
        self.camera.param.watch(lambda e: self.render(), "value")
        self.trails.param.watch(lambda e: self.render(), "value")
        self.render_button.on_click(lambda e: self.render())
        self._rendered_key = None
        self._inflight = False
        self._scheduled = False

    def _on_slider(self, event):
        self.session.frame = int(event.new)

    def _on_inputs(self, *_):
        end = max(self.session.n - 1, 1)
        self.slider.end = end
        self.player.end = end
        self._rendered_key = None

    def _on_frame(self, *_):
        f = self.session.frame
        if self.slider.value != f:
            self.slider.value = f
        if self.player.value != f:
            self.player.value = f
        self._render_soon()

    def _on_solution(self, *_):
        if self.auto.value and self._rendered_key is not None:
            self._render_soon()

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
                self.render()

            doc.add_next_tick_callback(run)

    def render(self) -> bool:
        """Render the current frame; False (and a message) when it cannot."""
        s = self.session
        if s.prepared is None or s.solution is None or self._inflight:
            return False
        key = (s.revision, s.frame, self.camera.value, self.trails.value)
        if key == self._rendered_key:
            return True
        self._inflight = True
        t0 = time.perf_counter()
        try:
            image = backend.render_frame(s.prepared, s.solution, s.frame, self.camera.value,
                                         self.trails.value, self.size)
            png = backend.png_bytes(image)
        except Exception as exc:  # shown in the page, never a traceback
            self.alert.object = safe_text.markdown(f"preview: {backend.one_line(exc)}")
            self.alert.visible = True
            return False
        finally:
            self._inflight = False
        self.alert.visible = False
        self.image.object = png
        self._rendered_key = key
        b, h, o = backend.frame_triplet(s.prepared, s.solution, s.frame)
        ms = (time.perf_counter() - t0) * 1000
        self.info.object = (f'<span data-frame="{b}">body frame {b} · hand frame {h} · '
                            f"spliced frame {o} · rendered in {ms:.0f} ms</span>")
        return True

    def panel(self) -> pn.viewable.Viewable:
        return pn.Column(
            pn.Row(self.render_button, self.player, self.camera, self.trails, self.auto),
            self.slider, self.info, self.alert, self.image, sizing_mode="stretch_width")
