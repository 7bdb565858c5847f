"""Choosing the takes: a bundled sample pair, or two uploaded files (BVH/C3D/TRC).

Uploads arrive in chunks (:class:`webapp.views.dropper.TakeDropper`), are checked by
the engine's reader in a child process off the event loop (:func:`webapp.uploads.check`)
and the pair's features are computed on a worker thread, so a large or hostile file
never holds up this or any other session. A refused file shows the reader's one-line
reason and the pair that is open stays open; a new pair whose hand has only the other
side waits for the Side chosen (the question names the files as uploaded), and choosing
it opens that pair (:meth:`webapp.state.Session.load_uploads`); the takes a shared link
waited for open that link (its points, bands, view), and the line says so. Each field's tile says
what the server made of its file (checking, checked, refused:
:meth:`TakeDropper.verdict`), and the "Uploaded …" line names only takes that are open or
waiting for their partner: a sample, a session file or a link that opens other takes
clears both. Every file name and message shown here goes through :mod:`webapp.safe_text`.
"""

from __future__ import annotations

import asyncio
import dataclasses
import functools
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import panel as pn

from engine.model.hand_side import unnamed_side_warning
from engine.model.motion import Motion
from engine.model.roles import HandFileSide, hand_file_side, side_name_conflict
from webapp import backend, safe_text, uploads
from webapp.backend import one_line
from webapp.state import Session
from webapp.views.dropper import Receipt, TakeDropper
from webapp.views.refusal import refusal_box

#: the upload checks of all sessions share these threads (the pair then opens on the
#: session's own worker: webapp.solves)
_WORKERS = ThreadPoolExecutor(max_workers=2, thread_name_prefix="hs-upload")
#: a field's file counts as on its way while its last chunk or check is this recent (s): an
#: upload given up in the browser does not hold the other field's take back for long
INCOMING_S = 20.0
#: the sample selector's entry while an uploaded pair is open
UPLOADED = "(your uploaded pair)"
#: the sample selector's entry while one uploaded take waits for its partner (the views
#: still show the pair open before, which the selector must not claim is the one chosen);
#: short enough to be read whole in the selector (stranger 6 saw "…waiting for its partn…")
WAITING = "(upload: needs its partner)"
#: and while an uploaded pair waits for the Side its hand has (Session.waits_for_side)
WAITING_SIDE = "(upload: needs its side)"
#: the "Uploaded …" line's tail while the pair opens
OPENING = " <span class='hs-opening'>— opening (progress below)</span>"
#: and once the uploads opened the shared link that waited for them (Session.load_uploads)
LINK_APPLIED = "The shared link's matching points and bands now apply to your uploads."

#: the "Uploaded …" line's word on a body take that looks like a hand take, until a pair
#: with it opens or is refused (the refusal then says it: engine.splice.pipeline)
HAND_AS_BODY = (
    "<span class='hs-hand-as-body'>⚠ it looks like a hand take (no shoulder or clavicle "
    "above the elbow): a pair with it as the body take is refused unless a role override "
    "names its shoulder (Joint-role overrides, below); a hand take goes in the hand "
    "field</span>"
)
#: and on a hand take without finger joints (a body take, by its joint names): the mirror
BODY_AS_HAND = (
    "<span class='hs-body-as-hand'>⚠ it has no finger joints (it looks like a body take): a "
    "pair with it as the hand take is refused unless a role override names its fingers "
    "(Joint-role overrides, below); a body take goes in the body field</span>"
)

MARKER_BODY_NOTE = (
    "The body take holds **markers** (C3D/TRC): it has no skeleton to receive fingers. "
    "The alignment, matching points and bands work as for any pair; *Spliced BVH* gives the "
    "**hand take retimed to the body** (one frame per body frame, at the body's frame rate) "
    "to pair with your markers in an animation tool, *Spliced GLB (3D)* the same retimed "
    "hand as a skinned 3D hand (no body), and the preview draws the body's "
    "markers (the aligned arm in orange) beside the hand."
)
MARKER_HAND_NOTE = (
    "The hand take holds **markers** (C3D/TRC): it has no finger rotations to give. The "
    "alignment works; splicing and the preview need a skeletal hand take (.bvh)."
)


class InputsView:
    """Sample selector, two upload fields and the side; problems shown as an alert."""

    def __init__(self, session: Session):
        self.session = session
        cfg = session.config
        self._names = [p.name for p in cfg.samples()]
        self.sample = pn.widgets.Select(
            options=self._sample_options(),
            value=self._sample_value(),
            css_classes=["hs-sample"],
            width=260,
        )
        self.sample.param.watch(self._on_sample, "value")
        limit = uploads.limit_words(cfg.max_upload_bytes)
        self.body_file = TakeDropper(
            cfg, css_classes=["hs-upload-body"], width=320, label="body take"
        )
        self.hand_file = TakeDropper(
            cfg, css_classes=["hs-upload-hand"], width=320, label="hand take"
        )
        for which, dropper in (("body", self.body_file), ("hand", self.hand_file)):
            dropper.on_progress = lambda receipt, w=which: self._on_progress(w, receipt)
            dropper.on_staged = lambda staged, w=which: self._on_staged(w, staged)
            dropper.on_refused = lambda text, words, w=which: self._refuse(w, text, words=words)
        self.side = pn.widgets.RadioButtonGroup.from_param(
            session.param.side, css_classes=["hs-side"], width=180
        )
        self.message = refusal_box("hs-upload-error", sizing_mode="stretch_width")
        self.uploaded = pn.pane.HTML(
            "", css_classes=["hs-upload-status"], sizing_mode="stretch_width"
        )
        #: the pair opened from disk: its Side against its hand file's name
        self.local_side = pn.pane.HTML(
            "", css_classes=["hs-local-side"], sizing_mode="stretch_width", visible=False
        )
        self.note = pn.pane.Alert(
            "",
            alert_type="info",
            visible=False,
            css_classes=["hs-marker-note"],
            sizing_mode="stretch_width",
        )
        #: checked takes the next pair opens with; the uploaded pair that is open (if any)
        self._pending: dict[str, uploads.Kept] = {}
        #: fields whose file is on its way (receiving or being checked), with when it was
        #: last heard of (monotonic s): a pair does not open with the other field's older
        #: take meanwhile (stranger 14 F8: a new long body was aligned with the previous
        #: hand while its own hand was still coming)
        self._incoming: dict[str, float] = {}
        self._open: dict[str, uploads.Kept] = {}
        self._opening = False
        #: what the last opening did with the side (followed the hand file's name)
        self._side_note = ""
        #: the last opening's hand take had no side in its names: the engine's warning
        self._side_guess = ""
        #: the last opening's hand file name says the other side than its joint names: the
        #: engine's warning (the joints' side was taken: ``roles.hand_file_side``)
        self._name_joints = ""
        #: the last opening opened the shared link that waited for these uploads
        self._link_applied = False
        self._droppers = {"body": self.body_file, "hand": self.hand_file}
        #: each field's refused file's reason (shown one line a field, body first)
        self._refusals: dict[str, str] = {}
        # none yet: the first look (below, or once an opening ends) shows what is open; the
        # page's takes section is built after the first pair began to open (webapp.app)
        self._inputs_key: tuple | None = None
        self.roles_body = pn.widgets.TextAreaInput(
            label="Body take",
            placeholder="right.wrist = RHand\nright.elbow = RForeArm",
            height=90,
            css_classes=["hs-roles-body"],
        )
        self.roles_hand = pn.widgets.TextAreaInput(
            label="Hand take",
            placeholder="right.index1 = rIndex1",
            height=90,
            css_classes=["hs-roles-hand"],
        )
        self.roles_apply = pn.widgets.Button(
            label="Apply overrides", width=140, css_classes=["hs-roles-apply"]
        )
        self.roles_apply.on_click(self._on_roles)
        self._show_roles()
        session.param.watch(
            self._on_session_inputs,
            ["sample", "body_sha256", "hand_sha256", "roles", "opening", "waiting"],
        )
        session.param.watch(self._show_note, ["inputs_revision"])
        session.param.watch(self._on_pair_shown, ["inputs_revision"])
        session.param.watch(self._show_local_side, ["inputs_revision", "sample"])
        session.param.watch(self._on_side, ["side"])
        # a side the takes lack is refused here, under the Side control that asked for it
        # (the page's error line is far below it)
        self._side_refused = False
        session.param.watch(self._on_error, ["error"])
        self._show_note()
        self.limit_note = pn.pane.Markdown(
            f"BVH, C3D or TRC, up to {limit} each (sent in chunks; the browser refuses larger "
            "files before sending). Files are checked with the engine's reader and kept on "
            "this server by content hash, so a shared link can name them. A C3D/TRC body "
            "aligns with a BVH hand; what it cannot give is said here once it is open.",
            styles={"color": "#555", "font-size": "12px"},
        )
        self._on_session_inputs()
        self._show_local_side()

    # ------------------------------------------------------------ the sample selector

    def _waiting_label(self) -> str:
        return WAITING_SIDE if self.session.waits_for_side else WAITING

    def _sample_options(self) -> list[str]:
        if self.session.waiting:
            return [self._waiting_label(), *self._names]
        uploaded = self._shown_entry() is None and self.session.body_sha256
        return ([UPLOADED] if uploaded else []) + self._names

    def _sample_value(self) -> str | None:
        s = self.session
        if s.waiting:  # the chosen takes are the upload, not the pair still shown
            return self._waiting_label()
        entry = self._shown_entry()
        if entry in self._names:
            return entry
        return UPLOADED if s.body_sha256 else None

    def _shown_entry(self) -> str | None:
        """The selector's entry of the takes open: the sample's, or the disk pair's own
        entry when they are the very files of ``serve BODY HAND`` (a link or session file
        of uploads with their bytes opens them: ``uploads.file_for``), as on a plain load
        of that server (stranger 13 F2: it said "your uploaded pair" over the line "opened
        from disk"); None for other uploads."""
        s, local = self.session, self.session.config.local
        if s.sample or local is None or not (s.body_sha256 and s.hand_sha256):
            return s.sample or None
        try:
            paths = s.take_paths()
        except uploads.UploadError:
            return None
        return local.name if tuple(paths) == (local.body, local.hand) else None

    def _on_sample(self, event):
        if not event.new or event.new in (UPLOADED, WAITING, WAITING_SIDE):
            return
        if event.new != self._shown_entry():
            self.session.load_sample(event.new)
        elif self.session.waiting:  # back to the sample still shown: the upload is dropped
            self._forget_uploads()
            self._on_session_inputs()

    def _session_key(self) -> tuple:
        return self.session.takes_key

    def _on_session_inputs(self, *_):
        """Follow inputs set by the session itself (uploads, a session file, undo of roles):
        the selector shows the open sample, or "your uploaded pair" (never a sample that
        would then be loaded over the upload). Other takes opened (a sample, a session
        file, a link) clear the upload fields, the "Uploaded …" line and its message."""
        if self.session.opening:  # the labels switch when the new pair is shown
            return
        key = self._session_key()
        if key != self._inputs_key and not self._opening:
            self._inputs_key = key
            opened = (self._open.get("body"), self._open.get("hand"))
            if self._is_pending(key):  # the upload that waited for its side is opening
                self._show_uploaded()
                self.uploaded.object += OPENING
            elif key[0] or None in opened or key[1:] != tuple(k.digest for k in opened):
                self._forget_uploads()
                self._show_kept_pair()
        options, value = self._sample_options(), self._sample_value()
        if list(self.sample.options) != options:
            self.sample.param.update(options=options, value=value)
        elif self.sample.value != value and value is not None:
            self.sample.value = value
        self._show_roles()

    def _is_pending(self, key: tuple) -> bool:
        """``key`` (the session's takes) is the checked upload pair not yet open here."""
        pending = (self._pending.get("body"), self._pending.get("hand"))
        return (
            not key[0]
            and None not in pending
            and self._pending != self._open
            and key[1:] == tuple(k.digest for k in pending)
        )

    def _on_pair_shown(self, *_):
        """New takes are shown: the upload pair that waited for its side (opened by the
        Side chosen, not by this view) is the open one now."""
        if not self._opening and self._is_pending(self._session_key()):
            self._inputs_key = self._session_key()
            self._open = dict(self._pending)
            self._show_uploaded(opened=True)

    def _show_kept_pair(self):
        """An uploaded pair opened by a link or a session file (not through these fields,
        whose tiles stay empty): the "Uploaded …" line names its files, escaped."""
        s = self.session
        if s.sample or not (s.body_sha256 and s.hand_sha256) or self._pending:
            return
        parts = [
            f"{which}: <b>{safe_text.html(name or f'{which} take (name unknown)')}</b>"
            for which, name in (("body", s.body_name), ("hand", s.hand_name))
        ]
        try:
            paths = s.take_paths()
        except uploads.UploadError:
            paths = ()
        # the files of ``serve BODY HAND`` with the link's bytes (uploads.file_for)
        own = any(not uploads.is_kept(s.config, p) for p in paths)
        self.uploaded.object = (
            "<span class='hs-uploaded hs-kept-pair'>Open: "
            + ", ".join(parts)
            + (
                " (this server's own files with these contents, opened from disk)."
                if own
                else " (kept on this server from an earlier upload)."
            )
            + "</span>"
        )

    def _show_note(self, *_):
        """What the open takes cannot give (markers), and what their readers noted
        (``meta.notes``: a TRC cut short ...), each note escaped."""
        prepared = self.session.prepared
        if prepared is None:
            self.note.visible = False
            return
        parts = [f"Note: {safe_text.markdown(n)}" for n in self._reader_notes(prepared)]
        if backend.marker_body(prepared):
            parts.append(MARKER_BODY_NOTE)
        elif not hasattr(prepared.hand, "skeleton"):
            parts.append(MARKER_HAND_NOTE)
        if not parts:
            self.note.visible = False
            return
        self.note.object = "\n\n".join(parts)
        self.note.visible = True

    def _reader_notes(self, prepared) -> list[str]:
        """The body and hand takes' reader notes, naming each file as the user knows it
        (an upload's own name, not the name it is kept under)."""
        s = self.session
        notes = []
        for take, shown in ((prepared.body, s.body_name), (prepared.hand, s.hand_name)):
            meta = getattr(take, "meta", None)
            kept = Path(meta.source).name if meta is not None and meta.source else ""
            for note in getattr(meta, "notes", ()):
                if shown and kept and note.startswith(f"{kept}: "):
                    note = f"{shown}: {note[len(kept) + 2 :]}"
                notes.append(note)
        return notes

    # ------------------------------------------------------------ uploads

    def _forget_uploads(self):
        """Other takes are open: the uploads' line, message and fields are cleared."""
        self._pending, self._open = {}, {}
        self._refusals = {}
        self._link_applied = False
        self.session.drop_side_wait()
        self.session.waiting = ""
        self.uploaded.object = ""
        self.message.visible = False
        for dropper in self._droppers.values():
            dropper.verdict("clear")

    def _on_progress(self, which: str, receipt: Receipt):
        """How much of a file is on the server: in its tile (percent, MB, time left) and
        on the line below the fields."""
        main, sub = receipt.words()
        self._incoming[which] = time.monotonic()
        if receipt.chunk < receipt.chunks:  # the last chunk's tile says "Checking…" next
            self._droppers[which].verdict("receiving", receipt.tile, main, sub)
        self.uploaded.object = (
            f"<span class='hs-receiving'>receiving <b>{safe_text.html(receipt.name)}</b>: "
            f"{receipt.percent} %, {safe_text.html(sub)}</span>"
        )

    def _on_staged(self, which: str, staged: uploads.Staged):
        self._incoming[which] = time.monotonic()
        self.uploaded.object = f"checking <b>{safe_text.html(staged.name)}</b>…"
        tile = self._droppers[which].file_name
        self._droppers[which].verdict("checking", tile, "Checking…", "on the server")
        pn.state.execute(functools.partial(self._check, which, staged, tile))

    async def _check(self, which: str, staged: uploads.Staged, tile: str):
        """Check the file off the event loop; open the pair once both takes are in."""
        loop = asyncio.get_running_loop()
        try:
            kept = await loop.run_in_executor(_WORKERS, uploads.check, self.session.config, staged)
        except uploads.UploadError as exc:
            self._refuse(which, one_line(exc), tile)
            await self._open_if_complete(new_only=True)
            return
        except Exception as exc:  # never a traceback in the page
            self._refuse(which, f"{staged.name}: cannot be read ({type(exc).__name__})", tile)
            await self._open_if_complete(new_only=True)
            return
        # the tile is narrow: the frame count there, the whole description in the line below
        frames = kept.summary.get("frames", 0)
        doubt = _other_fields_take(which, kept)
        if doubt:  # read, but a pair will refuse it (stranger 11 F10)
            self._droppers[which].verdict("doubt", tile, "Checked", f"{frames} frames · {doubt}")
        else:
            self._droppers[which].verdict("ok", tile, "Checked", f"{frames} frames")
        self._pending[which] = kept
        self._incoming.pop(which, None)
        self._refusals.pop(which, None)
        self._show_refusals()
        self._show_uploaded()
        await self._open_if_complete()

    async def _open_if_complete(self, new_only: bool = False) -> None:
        """Open the pair once both fields hold a checked take and neither field's file is
        still on its way (heard of in the last :data:`INCOMING_S`: the other field's take
        would be replaced a moment later, and its own check opens the pair then).
        ``new_only`` (after a refusal): only when a field holds a take the open pair lacks."""
        now = time.monotonic()
        coming = [w for w, t in self._incoming.items() if now - t < INCOMING_S]
        if len(self._pending) != 2 or coming or (new_only and self._pending == self._open):
            return
        await self._open_pair()

    def _refuse(self, which: str, text: str, tile: str | None = None, words: str = "see below"):
        """A take was refused: its tile turns red with ``words`` under "Refused", the
        reason is shown, and the take of the open uploaded pair (if any) is the one the next
        upload pairs with."""
        self._incoming.pop(which, None)
        self._red_tile(which, "Refused", words, tile)
        if which in self._open:
            self._pending[which] = self._open[which]
        else:
            self._pending.pop(which, None)
        self._show_uploaded()
        self._refusals[which] = text
        self._show_refusals()

    def _show_refusals(self) -> None:
        """The reasons of the fields whose file was refused, one line each (body first;
        each names its file); hidden when none is."""
        lines = [self._refusals[w] for w in ("body", "hand") if w in self._refusals]
        if lines:
            self.message.object = "\n\n".join(safe_text.markdown(t) for t in lines)
            self.message.visible = True
        else:
            self.message.visible = False

    def _show_uploaded(self, opened: bool = False, failed: bool = False):
        parts = []
        for which in ("body", "hand"):
            kept = self._pending.get(which)
            if kept is not None:
                notes = "".join(
                    f"; <span class='hs-reader-note'>note: {safe_text.html(n)}</span>"
                    for n in _own_notes(kept)
                )
                if _other_fields_take(which, kept) and not (opened or failed):
                    notes += f"; {HAND_AS_BODY if which == 'body' else BODY_AS_HAND}"
                parts.append(
                    f"{which}: <b>{safe_text.html(kept.name)}</b> "
                    f"({safe_text.html(_describe(kept.summary))}{notes})"
                )
        self._show_waiting(opened or failed)
        if not parts:
            self.uploaded.object = ""
            return
        if not opened and len(parts) == 2:
            opened = self._pending == self._open and self._open_is_shown()
        side = self._side_words() if len(parts) == 2 and (opened or failed) else ""
        link = f" <span class='hs-link-applied'>{LINK_APPLIED}</span>"
        tail = (
            f" — open{side}." + (link if self._link_applied else "")
            if opened
            else " — waiting for the side you choose (its question is below)."
            if self.session.waits_for_side
            else " — not opened (the reason is below)."
            if failed
            else ""
            if len(parts) == 2
            else " — now the other take."
        )
        self.uploaded.object = (
            "<span class='hs-uploaded'>Uploaded " + ", ".join(parts) + tail + "</span>"
        )

    def _on_side(self, *_):
        """The Side changed on the open uploaded pair: the line says whether it now
        contradicts the hand file's name."""
        if self._open and self._pending == self._open and self._open_is_shown():
            self._side_note = self._side_guess = ""  # the side is the one chosen now
            self._show_uploaded(opened=True)
        self._show_local_side()

    def _show_local_side(self, *_):
        """The pair of ``handsplice serve BODY HAND`` (opened from disk, not uploaded): the
        same warning as an upload's when the Side in force contradicts the hand file's name
        (the CLI's stderr says it too), on a line of its own; hidden otherwise."""
        s = self.session
        local = s.config.local
        shown = local is not None and s.sample == local.name
        named = local.extra.get("name_side") if shown and s.side == local.side else ""
        warning = _side_warning_html(named) if named else ""  # the joints' side, not the name's
        warning = warning or (side_warning(local.hand.name, s.side) if shown else "")
        guess = local.extra.get("unnamed_side") if shown and s.side == local.side else ""
        if guess and not warning:  # no side in the hand's names: never silent (stranger 13)
            warning = _side_warning_html(guess)
        self.local_side.object = warning
        self.local_side.visible = bool(warning)

    def _side_words(self) -> str:
        """``; side right, as the hand file's name says`` when the opening followed the
        name, or the warning when the side in force contradicts it (escaped)."""
        hand = self._pending.get("hand")
        if self._name_joints:  # the name said the other side: the joints' side was taken
            return f"; {_side_warning_html(self._name_joints)}"
        warning = side_warning(hand.name, self.session.side) if hand else ""
        if warning:
            return f"; {warning}"
        if self._side_guess:  # no side in the hand's names: never silent
            return f"; {_side_warning_html(self._side_guess)}"
        if self._side_note:
            return f"; <span class='hs-side-from-name'>{safe_text.html(self._side_note)}</span>"
        return ""

    def _show_waiting(self, done: bool) -> None:
        """One checked upload and no partner yet: the status line says what it waits for
        (the views still show the pair open before). A pair waiting for its side is the
        session's to say (``Session.waits_for_side``)."""
        if self.session.waits_for_side:
            return
        text = ""
        if len(self._pending) == 1 and not done and self._pending != self._open:
            ((which, kept),) = self._pending.items()
            other = "hand" if which == "body" else "body"
            text = f"{which} {kept.name} checked: waiting for a {other} take"
        self.session.waiting = text

    async def _open_pair(self):
        """Open the two checked uploads through the session (the takes the check read are
        handed over: the session's worker computes the features; the page's progress line
        counts the opening, the first alignment included). The open pair stays when the
        new one cannot be opened; one whose hand has only the other side waits for the Side
        chosen (the session's rule: :meth:`Session.load_uploads`)."""
        s = self.session
        body, hand = self._pending["body"], self._pending["hand"]
        if (s.body_sha256, s.hand_sha256) == (body.digest, hand.digest) and not s.sample:
            # the same content again, maybe under another name: the newest name is used
            s.rename_takes(body.name, hand.name)
            self._side_guess = _unnamed_side(hand.name, hand.take, s.side)
            self._name_joints = _hand_file_side(hand.name, hand.take).warning or ""
            self._open = dict(self._pending)
            self._show_uploaded(opened=True)
            return
        # the side follows the hand file's name (mug1_rightHand.bvh: right), as the CLI's
        # without --side, unless its joint names are the other hand's (then theirs, warned:
        # the one rule, engine.model.roles.hand_file_side); the Side control then shows it
        # and the line below says why
        named = _hand_file_side(hand.name, hand.take)
        side = named.side or s.side
        self._side_note = (
            f"side {side}, as the hand file's name says"
            if named.side and named.side != s.side and not named.warning
            else ""
        )
        self._side_guess = ""
        self._name_joints = named.warning or ""
        # a hand take whose name says no side: warned about once open, as the side then in force
        unnamed = hand.take if not named.side else None
        self._link_applied = False
        self.uploaded.object += OPENING
        # the session holds the takes from now on (the engine's cache once they are open):
        # this view keeps only their names
        takes = (body.take, hand.take)
        self._pending = {k: dataclasses.replace(v, take=None) for k, v in self._pending.items()}
        before = s.error
        # without a server it is all done within load_uploads
        opened = asyncio.get_running_loop().create_future()

        def then(ok: bool) -> None:
            if not opened.done():
                opened.set_result(ok)

        self._opening = True
        try:
            s.load_uploads(
                body.digest, hand.digest, body.name, hand.name, then=then, side=side, takes=takes
            )
            del takes
            await opened
        finally:
            self._opening = False
            # the takes now shown (the new pair, or the one that stayed open) are the ones
            # this view has seen: the uploads' fields and line are not cleared for them
            self._inputs_key = self._session_key()
        if s.body_sha256 != body.digest or s.hand_sha256 != hand.digest:
            self._show_uploaded(failed=True)
            reason = s.error if s.error and s.error != before else ""
            self._show_error(reason or "the uploaded pair could not be opened")
            if not s.waits_for_side:
                self._mark_unusable(reason, body.name, hand.name)
        else:
            self._open = dict(self._pending)
            if s.link_applied:  # the shared link that waited for them: its side is used
                self._link_applied, self._side_note = True, ""
            self._side_guess = _unnamed_side(hand.name, unnamed, s.side)
            self._show_uploaded(opened=True)

    def _mark_unusable(self, reason: str, body_name: str, hand_name: str) -> None:
        """The pair was refused for one of its takes (a hand take in the body field, a body
        take in the hand field): that take's tile, green *Checked* (the file reads), turns
        red *Not used*, pointing to the reason below (stranger 6). Only when the reason
        names one of the two files."""
        named = [
            which
            for which, name in (("body", body_name), ("hand", hand_name))
            if name and name in reason
        ]
        if len(named) == 1 and body_name != hand_name:
            self._red_tile(named[0], "Not used", "see below")

    def _red_tile(self, which: str, title: str, words: str, tile: str | None = None) -> None:
        """``which`` field's tile turns red: ``title`` ("Refused", "Not used") over ``words``,
        named ``tile`` (default: the file the field holds)."""
        dropper = self._droppers[which]
        dropper.verdict("refused", dropper.file_name if tile is None else tile, title, words)

    def _open_is_shown(self) -> bool:
        s, opened = self.session, self._open
        return (
            not s.sample
            and "body" in opened
            and "hand" in opened
            and (s.body_sha256, s.hand_sha256) == (opened["body"].digest, opened["hand"].digest)
        )

    def _show_roles(self):
        for take, widget in (("body", self.roles_body), ("hand", self.roles_hand)):
            mapping = self.session.roles.get(take, {})
            widget.value = "\n".join(
                f"{k} = {'none' if v is None else v}" for k, v in mapping.items()
            )

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
                    self._show_error(
                        f"{take} role overrides line {n}: expected "
                        f"'right.wrist = JointName', got {line!r}"
                    )
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

    def _on_error(self, *_):
        s = self.session
        if s.error and "side" in s.refused_inputs:
            self._side_refused = True
            self._show_error(s.error)
        elif self._side_refused:  # that refusal is over (another edit, a new pair)
            self._side_refused = False
            self.message.visible = False

    def _show_error(self, text: str):
        self.message.object = safe_text.markdown(text)
        self.message.visible = True

    def panel(self) -> pn.viewable.Viewable:
        def labelled(text, widget, width):
            return pn.Column(
                pn.pane.Markdown(f"**{text}**", margin=(0, 10, -10, 10)),
                widget,
                width=width,
                sizing_mode=None,
            )

        return pn.Column(
            pn.Row(
                labelled("Sample pair", self.sample, 280),
                labelled("Side", self.side, 200),
                labelled("or upload a body take", self.body_file, 340),
                labelled("and a hand take", self.hand_file, 340),
            ),
            self.limit_note,
            self.uploaded,
            self.local_side,
            self.message,
            self.note,
            pn.Card(
                pn.pane.Markdown(
                    "Joints are found by name (SMPL-X, Mixamo, Bandai, CMU, Leap and more). When a "
                    "take names them differently, map roles to joint names, one per line: "
                    "`right.wrist = RHand` (roles: shoulder, elbow, wrist, hand, thumb1..pinky3; "
                    "`none` switches one off).",
                    styles={"font-size": "12px"},
                ),
                pn.Row(self.roles_body, self.roles_hand),
                self.roles_apply,
                title="Joint-role overrides",
                collapsed=True,
                sizing_mode="stretch_width",
                css_classes=["hs-roles"],
            ),
            sizing_mode="stretch_width",
        )


def side_warning(hand_name: str, side: str) -> str:
    """The page's warning (HTML, escaped) when ``side`` contradicts what the hand file's
    name says (the rule: ``engine.model.roles.side_name_conflict``), else ''. The one
    wording for an uploaded pair and for a pair opened from disk."""
    conflict = side_name_conflict(hand_name, side) if hand_name else None
    return _side_warning_html(conflict) if conflict else ""


def _side_warning_html(text: str) -> str:
    """A side warning's words (plain text) as the page shows every one: escaped, in the
    ``hs-side-warning`` span with its sign."""
    return f"<span class='hs-side-warning'>⚠ {safe_text.html(text)}</span>"


def _other_fields_take(which: str, kept: uploads.Kept) -> str:
    """The tile's words ("a hand?", "a body?") when the take in ``which`` field looks like
    the other field's by its joint names, else '': in the body field a hand take (no
    shoulder above any hand's elbow: ``Roles.looks_like_hand_take``), in the hand field a
    body take without fingers (``Roles.looks_like_body_take``). It is kept, not refused: a
    role override naming the shoulder (the fingers) makes it one."""
    if which == "body" and kept.summary.get("hand_take"):
        return "a hand?"
    if which == "hand" and kept.summary.get("body_take"):
        return "a body?"
    return ""


def _hand_file_side(hand_name: str, take) -> HandFileSide:
    """:func:`engine.model.roles.hand_file_side` of an uploaded hand take as read (a
    ``Motion``; markers or None: its file name's side)."""
    return hand_file_side(hand_name, take.skeleton if isinstance(take, Motion) else None)


def _unnamed_side(hand_name: str, take, side: str) -> str:
    """The engine's warning (plain text) when an uploaded hand take (``take``, Motion; None
    or markers: '') whose file name and joint names carry no side opens as ``side`` (the
    rule: ``engine.model.hand_side.unnamed_side_warning``), else ''."""
    if not isinstance(take, Motion):
        return ""
    return unnamed_side_warning(hand_name, take, side, "choose Side {side}") or ""


def _own_notes(kept: uploads.Kept) -> list[str]:
    """An upload's reader notes without the file's name in front (the line names it)."""
    prefix = f"{kept.name}: "
    return [n[len(prefix) :] if n.startswith(prefix) else n for n in kept.summary.get("notes", ())]


def _describe(summary: dict) -> str:
    """``BVH, 59 joints, 839 frames at 120 fps`` from an upload's check summary."""
    what = (
        f"{summary.get('markers', 0)} markers"
        if summary.get("kind") == "markers"
        else f"{summary.get('joints', 0)} joints"
    )
    return f"{what}, {summary.get('frames', 0)} frames at {summary.get('fps', 0):g} fps"
