"""A file dropper whose chunks go straight to disk.

Panel's ``FileDropper`` sends a file in chunks (``chunk_size`` bytes per websocket
message, so no message is ever near the websocket's limit) and checks its size in
the browser before sending (``max_file_size``; FilePond says "File is too large").
Panel keeps every chunk in memory and joins them; :class:`TakeDropper` instead
appends each chunk to a staging file (:class:`webapp.uploads.Incoming`) and hands
the finished :class:`webapp.uploads.Staged` file to its owner.

FilePond marks a file "Upload complete" as soon as its last chunk is sent; whether the
server then accepts it is told by :meth:`TakeDropper.verdict`, which rewrites the
file's tile in the page: grey "Checking…", green "Checked" with what was read (amber
when it reads but does not look like its field's take: the page's line says why), or
red "Refused" (the reason is in the page's message), or empties the field. Text reaches
the tile through ``textContent`` only.

A file of a kind the server does not read (by its name's extension,
:data:`webapp.uploads.EXTENSIONS`) is refused in the browser before a byte is sent:
the field's ``accept`` lists those extensions (the file picker offers only them) and
FilePond checks a dropped file's extension (browsers give these files no MIME type, so
its type check is told to use the extension). The tile turns red at once and the
browser sends the server only the file's name, whose refusal (the same message as a
sent file's, :func:`webapp.uploads.check_name`) the page shows like any other.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable
from dataclasses import dataclass

import panel as pn
from bokeh.models import CustomJS

from webapp import uploads
from webapp.config import AppConfig
from webapp.views import page_js
from webapp.views._dispatch import with_document_lock

#: bytes per websocket message of an upload: the server counts what has arrived after
#: each (the tile's percent), so a few-MB take shows it moving; smaller chunks did not
#: slow a 3.2 MB upload down (``benchmarks/bench_upload.py``, RESULTS "pagefix4")
CHUNK_BYTES = 1024 * 1024
#: tile colours of the server's verdicts (FilePond's own green and red, a neutral grey)
VERDICT_COLORS = {
    "receiving": "#64605e",
    "checking": "#64605e",
    "ok": "#369763",
    # read, but it will not fit its field as it is (a hand take in the body field)
    "doubt": "#b26b00",
    "refused": "#c44e47",
}
#: the page is told how much has arrived at most this often (and at the last chunk)
PROGRESS_EVERY_S = 0.25

#: the page side of :meth:`TakeDropper.verdict`: the model's ``tags`` are
#: ``[state, file name, main text, sub text, serial]``; the tile of that file gets the
#: texts and colour once FilePond has marked it sent (status 5), and keeps them: an
#: observer writes them back whenever FilePond writes its own ("Upload complete") there
_JS_VERDICT = """
const [state, name, main, sub] = cb_obj.tags;
const pond = Bokeh.index.find_one(cb_obj)?._file_pond;
if (pond == null || !(state in colors || state === 'clear')) return;  // not a verdict
if (state === 'clear') { pond.removeFiles(); return; }
const paint = () => {
  const item = pond.getFiles().find(f => f.filename === name.split(/[\\\\/]/).pop());
  // "receiving" (the server's count of the bytes on its disk) also while FilePond still
  // sends (status 3: its ring counts what the browser queued, not what arrived)
  // "refused" also on a file FilePond did not send (status 8: refused by its kind), and
  // while FilePond still counts its "Uploading %" (status 3: the server refused it already)
  const shown = item != null && (
    item.status === 5 || (state === 'receiving' && item.status === 3) ||
    (state === 'refused' && (item.status === 8 || item.status === 3)));
  if (!shown) return false;
  const li = pond.element.querySelector('#filepond--item-' + item.id);
  if (li == null) return false;
  li._hsVerdict = {state, main, sub};
  const apply = () => {  // the server's texts, again whenever FilePond writes its own
    const v = li._hsVerdict;
    const m = li.querySelector('.filepond--file-status-main');
    const s = li.querySelector('.filepond--file-status-sub');
    if (m != null && m.textContent !== v.main) m.textContent = v.main;
    if (s != null && s.textContent !== v.sub) s.textContent = v.sub;
    li.dataset.hsVerdict = v.state;
    for (const part of li.querySelectorAll('.filepond--item-panel'))  // top, centre, bottom
      part.style.backgroundColor = colors[v.state] ?? '';
  };
  apply();
  if (li._hsObserver == null) {
    li._hsObserver = new MutationObserver(apply);
    const status = li.querySelector('.filepond--file-status') ?? li;
    li._hsObserver.observe(status, {childList: true, characterData: true, subtree: true});
  }
  return true;
};
const serial = cb_obj.tags[4];
let tries = 0;
const again = () => {  // until FilePond has drawn the sent state; then check it stayed
  if (cb_obj.tags[4] !== serial) return;  // a newer verdict took over
  const done = paint();
  tries += 1;
  if (tries < 40) setTimeout(again, done ? 500 : 100);
};
again();
"""
_SERIAL = itertools.count(1)

#: the tags state by which the page tells the server of a file it refused by its kind
WRONG_KIND = "wrong-kind"

#: the page side of the kind check (once per field, when the page is ready; it also has
#: FilePond say the size limit and file sizes as the page does, in MiB): FilePond
#: checks a file's type against the field's ``accept`` list; browsers give .bvh/.c3d/.trc
#: files no MIME type (or a guess), so the "type" it checks is the name's extension. A
#: file it refuses is not sent; the field's model's ``tags`` tell the server its name
_JS_KIND = """
if (dropper._hsKind) return;
dropper._hsKind = true;
const kind = (name) => (/\\.[^.\\\\/]*$/.exec(name ?? '') ?? [''])[0].toLowerCase();
const setup = () => {
  if (window.FilePond == null) { setTimeout(setup, 100); return; }
  window.FilePond.setOptions({
    fileValidateTypeDetectType: (file, type) => Promise.resolve(kind(file.name)),
    labelFileTypeNotAllowed: 'Refused',
    fileValidateTypeLabelExpectedTypes: 'not sent: expected {allButLastType} or {lastType}',
    // FilePond would say the limit in decimal MB (209.7 MB for 200 MiB)
    labelMaxFileSize: limit,
    // and a file's size too (220.2 MB beside "200 MiB"): in binary units, as the page
    // (only what FilePond shows: the size limit it checks is parsed in bytes as before)
    fileSizeBase: 1024,
    labelFileSizeKilobytes: 'KiB',
    labelFileSizeMegabytes: 'MiB',
    labelFileSizeGigabytes: 'GiB',
  });
};
setup();
document.addEventListener('FilePond:addfile', (event) => {
  const {error, file} = event.detail;
  if (error == null || file == null || exts.includes(kind(file.filename))) return;
  const own = Bokeh.index.find_one(dropper)?._file_pond;
  // FilePond dispatches on its root element (in the field's shadow root)
  if (own == null || own.element !== event.composedPath()[0]) return;  // the other field's
  dropper.tags = [wrong, file.filename, '', '', -Date.now()];
});
"""


@dataclass(frozen=True)
class Receipt:
    """How much of an upload is on the server's disk: ``received`` of about ``expected``
    bytes (exact once the last of ``chunks`` chunks is in), ``seconds`` since the first;
    ``name`` the shown name, ``tile`` the browser's name of the file (its tile)."""

    name: str
    tile: str
    received: int
    expected: int
    chunk: int
    chunks: int
    seconds: float

    @property
    def percent(self) -> int:
        if self.chunk >= self.chunks:
            return 100
        return min(99, int(100 * self.received / max(self.expected, 1)))

    def words(self) -> tuple[str, str]:
        """(main, sub) texts: ``Receiving 42 %``, ``1.3 of 3.2 MiB · about 4 s left`` (in
        binary units, as the page says the limit and FilePond the file's size)."""
        main = f"Receiving {self.percent} %"
        sub = f"{self.received / 2**20:.1f} of {self.expected / 2**20:.1f} MiB"
        if 0 < self.received < self.expected and self.seconds > 0.5:
            left = (self.expected - self.received) * self.seconds / self.received
            sub += f" · about {left:.0f} s left"
        return main, sub


class TakeDropper(pn.widgets.FileDropper):
    """One take's upload field. Callbacks (set by the owner), all on the event loop:
    ``on_progress(Receipt)`` (at most every :data:`PROGRESS_EVERY_S`), ``on_staged(Staged)``
    and ``on_refused(message, tile_words)`` (``tile_words``: the tile's short word under
    "Refused": "not sent" when the page refused the file by its kind, else "see below")."""

    def __init__(self, cfg: AppConfig, **params):
        params.setdefault("chunk_size", CHUNK_BYTES)
        params.setdefault("multiple", False)
        params.setdefault("previews", [])
        # the file picker offers only what the server reads; FilePond refuses the rest
        params.setdefault("accepted_filetypes", list(uploads.EXTENSIONS))
        # FilePond counts KB in thousands of bytes: the browser refuses what the server would
        params.setdefault("max_file_size", f"{cfg.max_upload_bytes // 1000}KB")
        super().__init__(**params)
        self._cfg = cfg
        self._incoming: dict[str, uploads.Incoming | None] = {}
        self._started: dict[str, float] = {}
        self.on_progress: Callable[[Receipt], None] = lambda r: None
        self._told = 0.0  # when on_progress was last called
        self.on_staged: Callable[[uploads.Staged], None] = lambda s: None
        self.on_refused: Callable[[str, str], None] = lambda m, w: None
        #: the name the browser gave the latest file (its tile's name; shown names are cleaned)
        self.file_name = ""

    def _get_model(self, doc, root=None, parent=None, comm=None):
        model = super()._get_model(doc, root, parent, comm)
        model.js_on_change("tags", CustomJS(args={"colors": VERDICT_COLORS}, code=_JS_VERDICT))
        model.on_change("tags", self._on_tags)
        if doc is not None:
            args = {
                "dropper": model,
                "exts": list(uploads.EXTENSIONS),
                "wrong": WRONG_KIND,
                "limit": f"Maximum file size is {uploads.limit_words(self._cfg.max_upload_bytes)}",
            }
            page_js.run_once(model, _JS_KIND, args, doc=doc)
        return model

    def _on_tags(self, attr, old, new) -> None:
        """The page refused a file by its kind (:data:`WRONG_KIND`, its name) without
        sending it: the owner is told why, in the words of a sent file's refusal."""
        if not new or new[0] != WRONG_KIND or len(new) < 2:
            return
        name = str(new[1])
        try:
            uploads.check_name(name)
        except uploads.UploadError as exc:
            self.file_name = name
            self._drop(name)
            self.on_refused(str(exc), "not sent")

    @with_document_lock
    def verdict(self, state: str, name: str = "", main: str = "", sub: str = "") -> None:
        """Show the server's word on file ``name`` in its tile: ``state`` "checking",
        "ok", "doubt" or "refused" with a main and a sub text, or "clear" (empty the
        field)."""
        tags = [state, name, main, sub, next(_SERIAL)]
        for model, _ in list(self._models.values()):
            model.tags = tags

    def _process_event(self, event) -> None:
        if event.event_name != "upload_event":
            return  # the user removed the file from the field: the kept upload stays
        data = event.data
        name, chunk, total = (
            str(data.get("name", "")),
            int(data["chunk"]),
            int(data["total_chunks"]),
        )
        try:
            if chunk == 1:
                self.file_name = name
                self._drop(name)
                self._incoming[name] = None  # refused until opened (a bad name stays refused)
                self._incoming[name] = uploads.Incoming(self._cfg, name)
                self._started[name] = time.monotonic()
                self._told = 0.0
            incoming = self._incoming.get(name)
            if incoming is None:
                return  # the rest of a refused file
            incoming.write(data.get("data") or b"")
            now = time.monotonic()
            if chunk >= total or now - self._told >= PROGRESS_EVERY_S:
                self._told = now
                self.on_progress(
                    Receipt(
                        name=incoming.name,
                        tile=name,
                        received=incoming.size,
                        # every chunk but the last is whole: the size is known within one
                        expected=incoming.size
                        if chunk >= total
                        else max(incoming.size, int((total - 0.5) * self.chunk_size)),
                        chunk=chunk,
                        chunks=total,
                        seconds=now - self._started.get(name, now),
                    )
                )
            if chunk >= total:
                del self._incoming[name]
                self.on_staged(incoming.finish())
        except uploads.UploadError as exc:
            self._drop(name)
            self._incoming[name] = None
            self.on_refused(str(exc), "see below")

    def _drop(self, name: str) -> None:
        incoming = self._incoming.pop(name, None)
        if incoming is not None:
            incoming.discard()
