"""Downloads (spliced BVH and GLB, preview GIF/MP4, session JSON) and the shareable link.

The browser's address bar always carries the link of the current state (updated
after every edit, in place: no history entries, :mod:`webapp.views.address_bar`), so
copying it shares the session; the field below shows it too.

GIF/MP4 exports take seconds: they render on a worker thread while the event loop
goes on serving every session (this one included); a progress bar and a line of
text follow the frames, and the file downloads when it is ready. A second click with
nothing changed (same alignment, same frames) downloads the file made before at once. The spliced BVH and
GLB are made on a worker thread too (a long take's splice takes seconds), their bytes
in a child process (``webapp.downloads``: the tens of megabytes of BVH text would hold
the interpreter, and every other tab, for seconds), with a "preparing…" line and the
seconds so far; the child writes the file to the server's disk and the page fetches it
over plain HTTP (``webapp.served_files``), not base64 in a Bokeh property (a 10-minute
take's BVH is ~80 MB). A download that
fails downloads nothing: its callback returns None and the page shows why.
"""

from __future__ import annotations

import asyncio
import io
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import panel as pn
from bokeh.models import CustomJS

from engine.render.video import remaining_text
from webapp import backend, safe_text
from webapp.served_files import STORE, ServedFile
from webapp.state import VIEW_STATE, Session
from webapp.views._dispatch import Settle, after_path, with_document_lock
from webapp.views.address_bar import AddressBar
from webapp.views.credits import file_credit, video_caption
from webapp.views.refusal import refusal_box

#: exports of all sessions share these threads (renders take turns on the OpenGL lock)
_EXPORTS = ThreadPoolExecutor(max_workers=2, thread_name_prefix="hs-export")
#: the spliced BVH and GLB of all sessions are made on these threads (no OpenGL)
_FILES = ThreadPoolExecutor(max_workers=2, thread_name_prefix="hs-download")
#: how often the page's progress follows an export, seconds
PROGRESS_INTERVAL = 0.25
#: the link takes the preview's frame once it has stood still this long, ms: not one link
#: (and address bar) per frame while Play runs or the slider is dragged
FRAME_LINK_MS = 300
#: the name the page gives the downloaded session file (the command line refers to it)
SESSION_FILENAME = "handsplice-session.json"


class _Download(pn.widgets.FileDownload):
    """A download button whose callback may return None: then nothing is sent and the
    browser downloads nothing (Panel 1.9's FileDownload would raise on None, and the
    browser only saves a file when the server sends new data).

    A callback may also return a ``webapp.served_files.ServedFile`` (a large file on the
    server's disk): then only its address and name go to the page (the button's model's
    ``tags``), whose script fetches it with a plain GET (``<a download>`` clicked), instead
    of Panel's base64 copy of the file in a Bokeh property. ``links`` counts those sent,
    ``served`` is the last."""

    links = 0
    served: ServedFile | None = None

    def _get_model(self, doc, root=None, parent=None, comm=None):
        model = super()._get_model(doc, root, parent, comm)
        model.js_on_change("tags", CustomJS(code=_JS_FETCH))
        return model

    def _sync_data(self, fileobj):
        if fileobj is None:
            return
        if isinstance(fileobj, ServedFile):
            self.served = fileobj
            self.links += 1
            self._send_link([_LINK_TAG, fileobj.url, fileobj.name, self.links])
            return
        super()._sync_data(fileobj)

    @with_document_lock
    def _send_link(self, tags: list) -> None:
        for model, _ in list(self._models.values()):
            model.tags = tags


_LINK_TAG = "hs-file"
#: the page fetches a served file: a hidden link to its address, named, clicked once
_JS_FETCH = """
const t = cb_obj.tags;
if (!Array.isArray(t) || t.length < 3 || t[0] !== 'hs-file') { return; }
const a = document.createElement('a');
a.href = t[1];
a.download = t[2];
a.style.display = 'none';
document.body.appendChild(a);
a.click();
a.remove();
"""


#: said once a file is made and handed to the browser (a finished step: the line is not
#: left saying "downloading" after the browser has saved it)
SENT = "handed to your browser (see its downloads)"


class SharingView:
    TEXT = (
        "Download the spliced take (BVH, opens in Blender and MotionBuilder; or GLB: the "
        "skinned mannequin in 3D for Blender and browser glTF viewers), an animated "
        "preview (GIF or MP4 at the take's speed, up to 30 frames a second: the whole take, "
        "or 10 s from the frame the preview shows; the three views with the preview's "
        "camera and the spliced hands close up; a bar follows the rendering), or the "
        "session file. The link "
        "restores this exact state on this server: sample or uploaded files, parameters "
        "and matching points; so does opening a downloaded session file. The command line "
        "below redoes the same splice offline."
    )

    def __init__(self, session: Session):
        self.session = session
        self.message = refusal_box("hs-share-error", into_view=True)

        self._names = None  # (inputs, (body file name, hand file name)): ``_take_names``
        self.bvh = _Download(
            callback=self._bvh,
            filename="spliced.bvh",
            label="Spliced BVH",
            color="primary",
            css_classes=["hs-download-bvh"],
            width=160,
        )
        self.glb = _Download(
            callback=self._glb,
            filename="spliced.glb",
            label="Spliced GLB (3D)",
            css_classes=["hs-download-glb"],
            width=160,
        )
        self.session_file = _Download(
            callback=self._session_json,
            filename=SESSION_FILENAME,
            label="Session JSON",
            css_classes=["hs-download-session"],
            width=160,
        )
        self.gif = _Download(
            callback=self._gif,
            filename="preview.gif",
            label="Preview GIF",
            css_classes=["hs-download-gif"],
            width=160,
        )
        self.mp4 = _Download(
            callback=self._mp4,
            filename="preview.mp4",
            label="Preview MP4",
            css_classes=["hs-download-mp4"],
            width=160,
        )
        self.progress = pn.indicators.Progress(
            value=0, max=100, visible=False, width=300, css_classes=["hs-export-progress"]
        )
        self.progress_text = pn.pane.HTML(
            "",
            visible=False,
            css_classes=["hs-export-status"],
            styles={"font-size": "12px", "color": "#444"},
        )
        self.prepare_text = pn.pane.HTML(
            "",
            visible=False,
            css_classes=["hs-download-status"],
            styles={"font-size": "12px", "color": "#444"},
        )
        self._exporting = False
        self.open_session = pn.widgets.FileInput(
            accept=".json", css_classes=["hs-open-session"], width=260, sizing_mode=None
        )
        self.open_session.param.watch(self._on_open_session, "value")
        self.link = pn.widgets.TextInput(
            label="Link to this session", value="", css_classes=["hs-share-url"], disabled=False
        )
        self.address = AddressBar()
        self.command = pn.pane.HTML(
            "",
            css_classes=["hs-cli"],
            sizing_mode="stretch_width",
            styles={
                "font-family": "monospace",
                "font-size": "12px",
                "background": "#f3f5f7",
                "padding": "6px 10px",
                "border-radius": "4px",
            },
        )
        doc = pn.state.curdoc
        self._doc = doc
        session.param.watch(  # after the edit's path is in the page (``after_path``)
            lambda *_: self._link_soon(),
            ["revision", "inputs_revision", "matrix", "body_name", "hand_name", *VIEW_STATE],
        )
        session.param.watch(lambda *_: self._new_pair(), ["inputs_revision"])
        # the preview's frame (slider, Play, a picked cell) is in the link too, once it stands
        self._frame_settle = Settle(doc, self._link_soon, FRAME_LINK_MS)
        session.param.watch(lambda *_: self._frame_settle.moved(), ["frame"])
        self._update_link()
        doc = pn.state.curdoc
        if doc is not None and doc.session_context is not None:
            # the page's served files go when it closes (the store keeps a few in any case)
            owner = id(self)
            doc.on_session_destroyed(lambda _: STORE.drop(owner))
            # the browser reports its own address once the page is up; the address bar then
            # gets the state that is open (a link that could not be restored is replaced)
            pn.state.onload(self._update_link)

    # ---------------------------------------------------------------- downloads

    def _new_pair(self) -> None:
        """Other takes are open: the lines of downloads that ended (and their refusals) were
        of the pair before, so they go (stranger 11: "spliced GLB: 444 KiB ... handed to
        your browser" stayed under another pair's buttons); one still running stays."""
        if SENT in self.prepare_text.object:
            self.prepare_text.visible = False
        if not self._exporting:
            self.progress.visible = self.progress_text.visible = False
        self.message.visible = False

    def _guard(self, make, what: str):
        try:
            data = make()
        except Exception as exc:  # shown in the page, never a traceback
            self.message.object = safe_text.markdown(f"{what}: {backend.one_line(exc)}")
            self.message.visible = True
            return None  # nothing downloads
        self.message.visible = False
        return io.BytesIO(data)

    def _stem(self) -> str:
        """The downloads' file stem: a marker body gives the hand take retimed to it (see
        the page's note), named so (``-hand-retimed``), in BVH and in 3D alike."""
        s = self.session
        retimed = s.prepared is not None and backend.marker_body(s.prepared)
        return f"{s.output_stem()}{'-hand-retimed' if retimed else ''}"

    async def _bvh(self):
        return await self._off_loop(self.bvh, "spliced BVH", "bvh")

    async def _glb(self):
        return await self._off_loop(self.glb, "spliced GLB", "glb")

    async def _off_loop(self, widget, what: str, kind: str) -> ServedFile | None:
        """The spliced take's ``kind`` file of the alignment shown now, made on a download
        thread (its bytes by a child, onto the server's disk: ``backend.served_file``) while
        the event loop serves every session; the page says what is being prepared and for
        how long, then fetches the file over HTTP. None (nothing downloads) when it fails,
        with the reason shown."""
        s = self.session
        name = widget.filename = f"{self._stem()}.{kind}"
        if s.prepared is None or s.solution is None:
            return self._guard(s.spliced, what)  # says why (no takes loaded)
        prepared, solution = s.prepared, s.solution  # this state, whatever is edited meanwhile
        widget.disabled = True
        self.prepare_text.object = f"{what}: preparing…"
        self.prepare_text.visible = True
        t0 = time.perf_counter()
        owner = id(self)
        credit = file_credit(s)  # the takes' sources and licences, inside a GLB
        job = asyncio.get_running_loop().run_in_executor(
            _FILES,
            lambda: backend.served_file(prepared, solution, kind, name, owner=owner, credit=credit),
        )
        try:
            while True:
                done, _ = await asyncio.wait({job}, timeout=PROGRESS_INTERVAL)
                if done:
                    break
                self.prepare_text.object = f"{what}: preparing… {time.perf_counter() - t0:.1f} s"
            data = job.result()
        except Exception as exc:  # shown in the page, never a traceback
            self.message.object = safe_text.markdown(f"{what}: {backend.one_line(exc)}")
            self.message.visible = True
            self.prepare_text.visible = False
            return None
        finally:
            widget.disabled = False
        self.message.visible = False
        self.prepare_text.object = (
            f"{what}: {data.size / 1024:.0f} KiB in {time.perf_counter() - t0:.1f} s, {SENT}"
        )
        return data

    def _session_json(self):
        return self._guard(lambda: self.session.to_json().encode("utf-8"), "session")

    async def _gif(self):
        return await self._video("gif", self.gif, "preview GIF")

    async def _mp4(self):
        return await self._video("mp4", self.mp4, "preview MP4")

    async def _video(self, fmt: str, widget, what: str) -> io.BytesIO | None:
        """Render the preview video on a worker thread; the page shows its progress.

        Returns the file's bytes, or None (nothing downloads) when the export fails or
        another export of this session is still running; the page then says why."""
        s = self.session
        if self._exporting:
            self.message.object = f"{what}: another export of this session is still running"
            self.message.visible = True
            return None
        widget.filename = f"{s.output_stem()}.{fmt}"
        prepared, solution = s.prepared, s.solution  # this state, whatever is edited meanwhile
        start = s.frame  # a long take's video starts at the frame the preview shows
        camera = s.camera  # and shows it with the preview's camera (hands: close up)
        try:
            shown, fps = backend.video_frames(prepared.n, float(prepared.body.fps), start)
        except Exception as exc:  # no takes open: shown in the page
            self.message.object = safe_text.markdown(f"{what}: {backend.one_line(exc)}")
            self.message.visible = True
            return None
        span = f"body frames {shown.start}–{shown[-1]} at {fps:.3g} fps, {camera} camera"
        # the takes' credit inside the file, and a caption under its frames (stranger 12 F7)
        credit, caption = file_credit(s), video_caption(s)
        key = backend.video_key(prepared, start, camera, credit, caption)
        made = backend.made_video(solution, fmt, key)
        if made is not None:  # nothing changed since it was made: the same file again
            self.message.visible = False
            self.progress.value = 100
            self.progress.visible = self.progress_text.visible = True
            self.progress_text.object = (
                f"{what} ({span}): {len(made) / 1024:.0f} KiB, unchanged since it was made: "
                f"the same file, {SENT}"
            )
            return io.BytesIO(made)
        counts = {"done": 0, "total": 1}
        lock = threading.Lock()

        def progress(done, total):
            with lock:
                counts.update(done=done, total=total)

        def show():
            with lock:
                done, total = counts["done"], counts["total"]
            self.progress.value = int(100 * done / max(total, 1))
            spent = time.perf_counter() - t0
            left = remaining_text(spent, done, total - 1)
            step = "encoding" if done >= total - 1 else f"frame {done} of {total - 1}"
            self.progress_text.object = f"{what} ({span}): rendering… {step}, {spent:.0f} s" + (
                f", {left}" if left else ""
            )

        self._exporting = True
        self.gif.disabled = self.mp4.disabled = True
        self.progress.value = 0
        self.progress.visible = self.progress_text.visible = True
        self.progress_text.object = f"{what}: starting…"
        t0 = time.perf_counter()
        loop = asyncio.get_running_loop()
        job = loop.run_in_executor(
            _EXPORTS,
            lambda: backend.preview_video(
                prepared,
                solution,
                fmt,
                camera=camera,
                progress=progress,
                start=start,
                cancelled=lambda: s.page_is_closed,  # its tab is gone: nobody will get it
                credit=credit,
                caption=caption,
            ),
        )
        try:
            while True:
                done, _ = await asyncio.wait({job}, timeout=PROGRESS_INTERVAL)
                if done:
                    break
                show()
            data = job.result()
        except Exception as exc:  # shown in the page, never a traceback
            self.message.object = safe_text.markdown(f"{what}: {backend.one_line(exc)}")
            self.message.visible = True
            self.progress.visible = self.progress_text.visible = False
            return None
        finally:
            self._exporting = False
            self.gif.disabled = self.mp4.disabled = False
        self.message.visible = False
        self.progress.value = 100
        self.progress_text.object = (
            f"{what} ({span}): {len(data) / 1024:.0f} KiB in {time.perf_counter() - t0:.1f} s, "
            f"{SENT}"
        )
        return io.BytesIO(data)

    def _on_open_session(self, *_):
        """Restore a session file; a bad one changes nothing and says why here."""
        data = self.open_session.value
        if data is None:
            return
        name = self.open_session.filename or "session.json"

        def refused(exc):  # nothing was applied; never a traceback
            self.message.object = safe_text.markdown(f"session file: {backend.one_line(exc)}")
            self.message.visible = True

        self.message.visible = False
        try:  # off the event loop the file's takes are opened and solved on the worker
            self.session.from_json(data, source=name, failed=refused)
        except Exception as exc:
            refused(exc)

    # ---------------------------------------------------------------- link

    def _base_url(self) -> str:
        loc = pn.state.location
        if loc is not None and loc.href:
            origin = f"{loc.protocol}//{loc.hostname}" + (f":{loc.port}" if loc.port else "")
            return origin + (loc.pathname or "/")
        return ""

    def _link_soon(self) -> None:
        after_path(self.session, ("link", id(self)), self._update_link, self._doc)

    def _take_names(self) -> tuple[str, str]:
        """The takes' file names in the commands (``take_paths`` reads the samples' manifest
        and looks at the files: once per pair, not once per edit)."""
        s = self.session
        key = (s.sample, s.body_sha256, s.hand_sha256, s.body_name, s.hand_name)
        if self._names is None or self._names[0] != key:
            paths = s.take_paths()
            names = (s.body_name or paths[0].name, s.hand_name or paths[1].name)
            self._names = (key, names)
        return self._names[1]

    def _update_link(self, *_):
        query = self.session.share_url()
        self.link.value = self._base_url() + query
        # a shared link waiting for its takes stays in the address bar (stranger 12: a
        # reload lost it): the address follows the page again once the link opened
        if not self.session.link_waiting:
            self.address.show(query)
        s = self.session
        if s.prepared is not None:
            body, hand = self._take_names()
            session_cmd = backend.cli_session_command(body, hand, SESSION_FILENAME)
            flags_cmd = backend.cli_command(
                body, hand, s.side, *s.chosen_widths(), s.user_points(), s.roles, s.max_unmatched_s
            )
            self.command.object = (
                f"<span style='color:#777'>{safe_text.html(backend.CLI_WHERE)}</span><br>"
                "$ " + safe_text.html(session_cmd) + "<br>"
                "<span style='color:#777'># or with explicit flags (--match takes hand-file "
                "frames):</span><br>$ " + safe_text.html(flags_cmd)
            )

    def panel(self) -> pn.viewable.Viewable:
        from webapp.views.credits import share_terms_alert
        from webapp.views.trust import unpinned_alert

        return pn.Column(
            share_terms_alert(self.session),
            unpinned_alert(self.session),
            pn.Row(self.bvh, self.glb, self.session_file, self.gif, self.mp4),
            pn.Row(self.progress, self.progress_text),
            self.prepare_text,
            pn.Row(
                pn.pane.Markdown(  # its own width: the chooser sits next to its label
                    "**Open a session file**", margin=(12, 10, 0, 10), sizing_mode=None, width=160
                ),
                self.open_session,
            ),
            # a refused file or download is said under the controls used, brought into view
            self.message,
            self.link,
            self.command,
            self.address.panel(),
            sizing_mode="stretch_width",
        )
