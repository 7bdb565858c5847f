"""A file dropper whose chunks go straight to disk.

Panel's ``FileDropper`` sends a file in chunks (``chunk_size`` bytes per websocket
message, so no message is ever near the websocket's limit) and checks its size in
the browser before sending (``max_file_size``; FilePond says "File is too large").
Panel keeps every chunk in memory and joins them; :class:`TakeDropper` instead
appends each chunk to a staging file (:class:`webapp.uploads.Incoming`) and hands
the finished :class:`webapp.uploads.Staged` file to its owner.
"""

from __future__ import annotations

from collections.abc import Callable

import panel as pn

from webapp import uploads
from webapp.config import AppConfig

#: bytes per websocket message of an upload
CHUNK_BYTES = 4 * 1024 * 1024


class TakeDropper(pn.widgets.FileDropper):
    """One take's upload field. Callbacks (set by the owner), all on the event loop:
    ``on_progress(name, received_bytes, total_bytes)``, ``on_staged(Staged)`` and
    ``on_refused(message)``."""

    def __init__(self, cfg: AppConfig, **params):
        params.setdefault("chunk_size", CHUNK_BYTES)
        params.setdefault("multiple", False)
        params.setdefault("previews", [])
        # FilePond counts KB in thousands of bytes: the browser refuses what the server would
        params.setdefault("max_file_size", f"{cfg.max_upload_bytes // 1000}KB")
        super().__init__(**params)
        self._cfg = cfg
        self._incoming: dict[str, uploads.Incoming | None] = {}
        self.on_progress: Callable[[str, int, int], None] = lambda *a: None
        self.on_staged: Callable[[uploads.Staged], None] = lambda s: None
        self.on_refused: Callable[[str], None] = lambda m: None

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
                self._drop(name)
                self._incoming[name] = None  # refused until opened (a bad name stays refused)
                self._incoming[name] = uploads.Incoming(self._cfg, name)
            incoming = self._incoming.get(name)
            if incoming is None:
                return  # the rest of a refused file
            incoming.write(data.get("data") or b"")
            self.on_progress(incoming.name, incoming.size, total * self.chunk_size)
            if chunk >= total:
                del self._incoming[name]
                self.on_staged(incoming.finish())
        except uploads.UploadError as exc:
            self._drop(name)
            self._incoming[name] = None
            self.on_refused(str(exc))

    def _drop(self, name: str) -> None:
        incoming = self._incoming.pop(name, None)
        if incoming is not None:
            incoming.discard()
