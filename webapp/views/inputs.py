"""Choosing the takes: a bundled sample pair, or two uploaded files (BVH/C3D/TRC)."""

from __future__ import annotations

import panel as pn

from webapp import uploads
from webapp.backend import one_line
from webapp.state import Session


class InputsView:
    """Sample selector, two upload fields and the side; problems shown as an alert."""

    def __init__(self, session: Session):
        self.session = session
        cfg = session.config
        names = [p.name for p in cfg.samples()]
        self.sample = pn.widgets.Select(label="Sample pair", options=names,
                                        value=session.sample if session.sample in names else None,
                                        css_classes=["hs-sample"], width=260)
        self.sample.param.watch(self._on_sample, "value")
        limit = f"{cfg.max_upload_bytes / 2**20:.0f} MiB"
        self.body_file = pn.widgets.FileInput(accept=",".join(uploads.EXTENSIONS),
                                              css_classes=["hs-upload-body"], label="Body take")
        self.hand_file = pn.widgets.FileInput(accept=",".join(uploads.EXTENSIONS),
                                              css_classes=["hs-upload-hand"], label="Hand take")
        self.body_file.param.watch(lambda e: self._on_upload("body"), "value")
        self.hand_file.param.watch(lambda e: self._on_upload("hand"), "value")
        self.side = pn.widgets.RadioButtonGroup.from_param(session.param.side,
                                                           css_classes=["hs-side"])
        self.message = pn.pane.Alert("", alert_type="danger", visible=False,
                                     css_classes=["hs-upload-error"], sizing_mode="stretch_width")
        self.uploaded = pn.pane.Markdown("", css_classes=["hs-upload-status"])
        self._pending: dict[str, tuple[str, str]] = {}
        self.limit_note = pn.pane.Markdown(
            f"BVH, C3D or TRC, up to {limit} each. Files are checked with the engine's reader "
            "and kept on this server by content hash, so a shared link can name them.",
            styles={"color": "#555", "font-size": "12px"})

    def _on_sample(self, event):
        if event.new and event.new != self.session.sample:
            self.session.load_sample(event.new)

    def _on_upload(self, which: str):
        widget = self.body_file if which == "body" else self.hand_file
        if widget.value is None:
            return
        try:
            digest, _ = uploads.store(self.session.config, widget.filename or "", widget.value)
        except uploads.UploadError as exc:
            self._show_error(one_line(exc))
            self._pending.pop(which, None)
            return
        except Exception as exc:  # never a traceback in the page
            self._show_error(f"{widget.filename}: cannot be read ({type(exc).__name__})")
            return
        self._pending[which] = (digest, widget.filename or "")
        self.message.visible = False
        done = [f"{k}: **{v[1]}**" for k, v in self._pending.items()]
        self.uploaded.object = "Uploaded " + ", ".join(done) + (
            "" if len(self._pending) == 2 else " — now the other take.")
        if len(self._pending) == 2:
            (b, bn), (h, hn) = self._pending["body"], self._pending["hand"]
            self.session.load_uploads(b, h, bn, hn)
            if self.session.error and self.session.prepared is None:
                self._show_error(self.session.error)
            else:
                self.sample.value = None

    def _show_error(self, text: str):
        self.message.object = text
        self.message.visible = True

    def panel(self) -> pn.viewable.Viewable:
        return pn.Column(
            pn.Row(self.sample, pn.Column(pn.pane.Markdown("**Side**", margin=(0, 10)),
                                          self.side)),
            pn.Row(pn.Column(pn.pane.Markdown("**Body take**", margin=(0, 10)), self.body_file),
                   pn.Column(pn.pane.Markdown("**Hand take**", margin=(0, 10)), self.hand_file)),
            self.limit_note, self.uploaded, self.message, sizing_mode="stretch_width")
