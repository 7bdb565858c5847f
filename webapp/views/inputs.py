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
        self.sample = pn.widgets.Select(options=names,
                                        value=session.sample if session.sample in names else None,
                                        css_classes=["hs-sample"], width=260)
        self.sample.param.watch(self._on_sample, "value")
        limit = f"{cfg.max_upload_bytes / 2**20:.0f} MiB"
        self.body_file = pn.widgets.FileInput(accept=",".join(uploads.EXTENSIONS),
                                              css_classes=["hs-upload-body"], width=280)
        self.hand_file = pn.widgets.FileInput(accept=",".join(uploads.EXTENSIONS),
                                              css_classes=["hs-upload-hand"], width=280)
        self.body_file.param.watch(lambda e: self._on_upload("body"), "value")
        self.hand_file.param.watch(lambda e: self._on_upload("hand"), "value")
        self.side = pn.widgets.RadioButtonGroup.from_param(session.param.side,
                                                           css_classes=["hs-side"], width=180)
        self.message = pn.pane.Alert("", alert_type="danger", visible=False,
                                     css_classes=["hs-upload-error"], sizing_mode="stretch_width")
        self.uploaded = pn.pane.Markdown("", css_classes=["hs-upload-status"])
        self._pending: dict[str, tuple[str, str]] = {}
        self.roles_body = pn.widgets.TextAreaInput(
            label="Body take", placeholder="right.wrist = RHand\nright.elbow = RForeArm",
            height=90, css_classes=["hs-roles-body"])
        self.roles_hand = pn.widgets.TextAreaInput(
            label="Hand take", placeholder="right.index1 = rIndex1", height=90,
            css_classes=["hs-roles-hand"])
        self.roles_apply = pn.widgets.Button(label="Apply overrides", width=140,
                                             css_classes=["hs-roles-apply"])
        self.roles_apply.on_click(self._on_roles)
        self._show_roles()
        session.param.watch(self._on_session_inputs, ["sample", "roles"])
        self.limit_note = pn.pane.Markdown(
            f"BVH, C3D or TRC, up to {limit} each. Files are checked with the engine's reader "
            "and kept on this server by content hash, so a shared link can name them.",
            styles={"color": "#555", "font-size": "12px"})

    def _on_sample(self, event):
        if event.new and event.new != self.session.sample:
            self.session.load_sample(event.new)

    def _on_session_inputs(self, *_):
        """Follow inputs set by the session itself (a session file, undo of roles)."""
        sample = self.session.sample if self.session.sample in self.sample.options else None
        if self.sample.value != sample:
            self.sample.value = sample
        self._show_roles()

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
            if self.session.body_sha256 != b or self.session.hand_sha256 != h:
                self._show_error(self.session.error or "the uploaded pair could not be opened")
            else:
                self.sample.value = None

    def _show_roles(self):
        for take, widget in (("body", self.roles_body), ("hand", self.roles_hand)):
            mapping = self.session.roles.get(take, {})
            widget.value = "\n".join(f"{k} = {'none' if v is None else v}"
                                     for k, v in mapping.items())

    def _on_roles(self, _event=None):
        roles = {}
        for take, widget in (("body", self.roles_body), ("hand", self.roles_hand)):
            mapping = {}
            for n, line in enumerate((widget.value or "").splitlines(), 1):
                line = line.split("#", 1)[0].strip()
                if not line:
                    continue
                key, sep, joint = line.partition("=")
                if not sep:
                    self._show_error(f"{take} role overrides line {n}: expected "
                                     f"'right.wrist = JointName', got {line!r}")
                    return
                joint = joint.strip()
                mapping[key.strip()] = None if joint.lower() in ("", "none", "null") else joint
            if mapping:
                roles[take] = mapping
        before = self.session.error
        if self.session.set_roles(roles) and self.session.error in ("", before):
            self.message.visible = False
        else:
            self._show_error(self.session.error)
        self._show_roles()

    def _show_error(self, text: str):
        self.message.object = text
        self.message.visible = True

    def panel(self) -> pn.viewable.Viewable:
        def labelled(text, widget, width):
            return pn.Column(pn.pane.Markdown(f"**{text}**", margin=(0, 10, -10, 10)), widget,
                             width=width, sizing_mode=None)

        return pn.Column(
            pn.Row(labelled("Sample pair", self.sample, 280), labelled("Side", self.side, 200),
                   labelled("or upload a body take", self.body_file, 300),
                   labelled("and a hand take", self.hand_file, 300)),
            self.limit_note, self.uploaded, self.message,
            pn.Card(pn.pane.Markdown(
                "Joints are found by name (SMPL-X, Mixamo, Bandai, CMU, Leap and more). When a "
                "take names them differently, map roles to joint names, one per line: "
                "`right.wrist = RHand` (roles: shoulder, elbow, wrist, hand, thumb1..pinky3; "
                "`none` switches one off).", styles={"font-size": "12px"}),
                pn.Row(self.roles_body, self.roles_hand), self.roles_apply,
                title="Joint-role overrides", collapsed=True, sizing_mode="stretch_width",
                css_classes=["hs-roles"]),
            sizing_mode="stretch_width")
