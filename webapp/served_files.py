"""Large downloads served over plain HTTP by the app's own server (issue 13).

A Panel ``FileDownload`` sends its file inside a Bokeh property: base64 text (4/3 of the
file) built in the server's memory, copied into the document's JSON message, kept in the
document until the next download, and pushed down the websocket. For a 10-minute take's
spliced BVH (~80 MB) that was +0.5 GB of server memory for seconds. Here the file is
written to the server's disk by the child that encodes it (``webapp.downloads.write``:
the command line's own writer) and the page fetches it with a plain GET of
``hs-file/TOKEN`` (:class:`FileHandler`, on the same Tornado server as the page), which
streams it in :data:`PIECE_BYTES` pieces: the server never holds the file whole.

* A token is 32 random bytes (``secrets.token_urlsafe``): only the page that asked knows
  it. The handler looks the token up; no path is ever taken from the request.
* The files live in the server's own folder (``tempfile.mkdtemp``: mode 0700), each named
  by its token, written whole and then renamed into place (nothing half-written is
  served, no name a user chose is ever a path), removed when the server exits.
* The name the browser saves under travels in ``Content-Disposition``
  (:func:`disposition`: an ASCII fallback and RFC 5987's UTF-8 form, both escaped).
* An owner (a page) keeps its latest file of each kind (:meth:`FileStore.put` removes the
  one it replaces, :meth:`FileStore.drop` all of an owner's); the store keeps at most
  :data:`MAX_FILES` files (the oldest go first).
"""

from __future__ import annotations

import atexit
import os
import re
import secrets
import shutil
import tempfile
import threading
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import quote

import tornado.web

#: the files the store keeps at most (all pages together); the oldest are removed first
MAX_FILES = 24
#: bytes read from disk and written to the socket at a time
PIECE_BYTES = 1 << 20
#: the route's prefix, relative to the page (the app is served at the server's root)
PREFIX = "hs-file"
_TOKEN = r"[A-Za-z0-9_-]{43}"
#: the route the server serves (``pn.serve(extra_patterns=[ROUTE])``)
ROUTE_PATTERN = rf"/{PREFIX}/({_TOKEN})"
#: what a download kind's file is sent as
CONTENT_TYPES = {"bvh": "application/octet-stream", "glb": "model/gltf-binary"}
_UNSAFE = re.compile(r"[^A-Za-z0-9 ._()+-]")


@dataclass(frozen=True)
class ServedFile:
    """A file the page may fetch: ``url`` (relative to the page), ``name`` (what the
    browser saves it as), ``size`` in bytes."""

    token: str
    name: str
    size: int
    kind: str
    path: Path

    @property
    def url(self) -> str:
        return f"{PREFIX}/{self.token}"


def disposition(name: str) -> str:
    """The ``Content-Disposition`` value that saves the file as ``name``: ``attachment;
    filename="ASCII"; filename*=UTF-8''PERCENT-ENCODED`` (RFC 6266). Only the last path
    component counts; control characters are dropped; the ASCII form keeps letters,
    digits and ``._()+- `` (anything else is ``_``), the UTF-8 form percent-encodes every
    byte outside the unreserved set, so neither can end the header or the quotes."""
    name = re.sub(r"[\x00-\x1f\x7f]", "", str(name)).replace("\\", "/").rsplit("/", 1)[-1]
    name = name.strip().lstrip(".") or "download"
    ascii_name = _UNSAFE.sub("_", name)
    return f"attachment; filename=\"{ascii_name}\"; filename*=UTF-8''{quote(name, safe='')}"


class FileStore:
    """Files being served (see the module docstring). Thread-safe: files are added from
    download threads, read by the server's event loop."""

    def __init__(self, max_files: int = MAX_FILES):
        self.max_files = max_files
        self._folder: Path | None = None
        self._files: OrderedDict[str, ServedFile] = OrderedDict()
        self._latest: dict[tuple, str] = {}
        self._lock = threading.Lock()

    @property
    def folder(self) -> Path:
        with self._lock:
            if self._folder is None:
                self._folder = Path(tempfile.mkdtemp(prefix="handsplice-downloads-"))
                atexit.register(self.close)
            return self._folder

    def put(self, write: Callable[[Path], None], name: str, kind: str, owner=None) -> ServedFile:
        """Serve the file ``write(path)`` makes (it must create ``path`` whole, e.g. by
        renaming a finished temporary file onto it) under the browser name ``name``.

        ``owner``: who asked (a page); its previous file of this ``kind`` is removed."""
        token = secrets.token_urlsafe(32)
        path = self.folder / token
        try:
            write(path)
            size = path.stat().st_size
        except BaseException:
            path.unlink(missing_ok=True)
            raise
        served = ServedFile(token, str(name), size, kind, path)
        gone = []
        with self._lock:
            self._files[token] = served
            if owner is not None:
                old = self._latest.get((owner, kind))
                self._latest[(owner, kind)] = token
                if old is not None:
                    gone.append(self._files.pop(old, None))
            while len(self._files) > self.max_files:
                gone.append(self._files.popitem(last=False)[1])
        for old in gone:
            if old is not None:
                old.path.unlink(missing_ok=True)
        return served

    def get(self, token: str) -> ServedFile | None:
        with self._lock:
            return self._files.get(token)

    def drop(self, owner) -> None:
        """Remove every file ``owner`` made (its page closed)."""
        with self._lock:
            tokens = [t for (o, _), t in self._latest.items() if o == owner]
            self._latest = {k: t for k, t in self._latest.items() if k[0] != owner}
            gone = [self._files.pop(t, None) for t in tokens]
        for old in gone:
            if old is not None:
                old.path.unlink(missing_ok=True)

    def close(self) -> None:
        """Remove every file and the folder."""
        with self._lock:
            folder, self._folder = self._folder, None
            self._files.clear()
            self._latest.clear()
        if folder is not None:
            shutil.rmtree(folder, ignore_errors=True)


#: the server's store (one per process)
STORE = FileStore()


class FileHandler(tornado.web.RequestHandler):
    """``GET hs-file/TOKEN``: the file :data:`STORE` serves under ``TOKEN``, as an
    attachment, in :data:`PIECE_BYTES` pieces; 404 (a one-line text) for any other."""

    store = STORE

    def set_default_headers(self) -> None:
        self.set_header("Cache-Control", "no-store")
        self.set_header("X-Content-Type-Options", "nosniff")

    async def get(self, token: str) -> None:
        served = self.store.get(token)
        try:
            fh = open(served.path, "rb") if served is not None else None  # noqa: SIM115
        except OSError:
            fh = None
        if fh is None:
            self.set_status(404)
            self.set_header("Content-Type", "text/plain; charset=utf-8")
            self.finish("this download is no longer on the server: click its button again\n")
            return
        with fh:
            size = os.fstat(fh.fileno()).st_size
            self.set_header("Content-Type", CONTENT_TYPES.get(served.kind, CONTENT_TYPES["bvh"]))
            self.set_header("Content-Length", str(size))
            self.set_header("Content-Disposition", disposition(served.name))
            while piece := fh.read(PIECE_BYTES):
                self.write(piece)
                await self.flush()
        self.finish()


#: ``pn.serve(extra_patterns=[ROUTE])``
ROUTE = (ROUTE_PATTERN, FileHandler)
