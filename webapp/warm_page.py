"""The light page ``handsplice serve`` shows while it warms up.

The warm-up (reading the takes, aligning them, compiling the kernels) can take minutes on
long takes; the app's server listens only after it. Meanwhile :class:`WarmPage` listens on
the same address and port and answers every request with a small page: what the server
is doing (the console's latest stage lines, escaped: they name the user's files) and for
how long. The page asks again every :data:`POLL_S` seconds, shows the new stage lines, and
reloads itself (its own address: a link's query stays) once the app answers. It answers
with HTTP 503 and ``Retry-After``, so a script waiting for the app (``webapp.launch``)
waits on, and with the header ``X-HandSplice: warming-up`` that the page looks for.

Stranger 11 F3: the browser said "This site can't be reached" for the whole warm-up (96 s
on a long pair), as if the server had failed.
"""

from __future__ import annotations

import socket
import threading
import time
from collections import deque
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

from webapp import safe_text

#: seconds between the page's questions to the server
POLL_S = 1.5
#: the console lines the page shows, the latest last
LINES = 8
#: the response header by which the page knows it is still the warm-up page
HEADER = "X-HandSplice"

_PAGE = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>HandSplice is warming up</title>
<meta name="viewport" content="width=device-width, initial-scale=1">
<style>
body {{ font-family: sans-serif; margin: 40px; color: #1d3557; }}
pre {{ background: #f3f5f7; border: 1px solid #dde2e6; padding: 10px; white-space: pre-wrap; }}
</style></head>
<body>
<h2>HandSplice is warming up <progress style="width:140px;height:12px"></progress></h2>
<p id="hs-warm-since">{seconds:.0f} s so far: reading the takes, aligning them and compiling the
engine before the first page (a minute or two the first time, longer for long takes).
This page turns into the app by itself when it is ready.</p>
<pre id="hs-warm-lines">{lines}</pre>
<script>
const ask = async () => {{
  try {{
    const reply = await fetch(location.href, {{cache: 'no-store'}});
    if (reply.headers.get('{header}') !== 'warming-up') {{ location.reload(); return; }}
    const page = new DOMParser().parseFromString(await reply.text(), 'text/html');
    for (const id of ['hs-warm-since', 'hs-warm-lines'])
      document.getElementById(id).textContent = page.getElementById(id).textContent;
  }} catch (err) {{}}  // the app's server is taking over the port: ask again
  setTimeout(ask, {poll_ms});
}};
setTimeout(ask, {poll_ms});
</script>
</body></html>
"""


class WarmPage:
    """A small HTTP server on ``(address, port)`` answering with the warm-up page until
    :meth:`close`; :meth:`note` adds a console line to it (thread-safe). Raises OSError
    when the port cannot be listened on."""

    def __init__(self, address: str, port: int):
        self.started = time.monotonic()
        self._lines: deque[str] = deque(maxlen=LINES)
        self._lock = threading.Lock()
        page = self

        class Handler(BaseHTTPRequestHandler):
            def do_GET(self):  # noqa: N802 - the standard library's name
                body = page.html().encode()
                self.send_response(503)
                self.send_header("Content-Type", "text/html; charset=utf-8")
                self.send_header("Content-Length", str(len(body)))
                self.send_header("Cache-Control", "no-store")
                self.send_header("Retry-After", str(int(POLL_S + 0.5)))
                self.send_header(HEADER, "warming-up")
                self.end_headers()
                self.wfile.write(body)

            def log_message(self, *args):  # the console is the warm-up's own
                pass

        server = type(
            "Server",
            (ThreadingHTTPServer,),
            {"address_family": socket.AF_INET6 if ":" in address else socket.AF_INET},
        )
        self._server = server((address, port), Handler)
        self._server.daemon_threads = True
        self._thread = threading.Thread(
            target=self._server.serve_forever, daemon=True, name="hs-warm-page"
        )
        self._thread.start()

    def note(self, line: str) -> None:
        with self._lock:
            self._lines.append(line)

    def html(self) -> str:
        """The page as it is now: the seconds since the warm-up began, the latest lines."""
        with self._lock:
            lines = list(self._lines) or ["starting ..."]
        return _PAGE.format(
            seconds=time.monotonic() - self.started,
            lines="\n".join(safe_text.html(line) for line in lines),
            header=HEADER,
            poll_ms=int(POLL_S * 1000),
        )

    def close(self) -> None:
        """Stop answering and free the port (the app's server listens on it next)."""
        self._server.shutdown()
        self._server.server_close()
        self._thread.join(timeout=5)
