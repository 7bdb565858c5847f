"""Run the app in a child process and drive it from a real browser.

One place for what the browser tests and the app benchmark both need: a free
port, ``handsplice serve`` started and polled until it answers, Debian's
Chromium with the flags this closed network needs, and the page-side helpers
that turn matrix cells into screen coordinates.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
import urllib.request
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO

ROOT = Path(__file__).resolve().parents[1]
CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]

#: page-side helpers (``page.evaluate(PAGE_HELPERS)`` once the document is up):
#: ``hs.model(name)``, ``hs.xy(body_frame, hand_frame)`` -> screen pixels of a matrix
#: cell (scrolling the matrix into view first), ``hs.cols(source, keys)``, ``hs.frames()``
#: (body frames of the open pair).
PAGE_HELPERS = """
window.hs = {
  model(name) { return Bokeh.documents[0].get_model_by_name(name); },
  xy(x, y) {
    const v = Bokeh.index.find_one(this.model('hs-cost-figure'));
    let r = v.canvas_view.el.getBoundingClientRect();
    if (r.top < 0 || r.bottom > window.innerHeight) {  // bring the matrix into view first
      v.canvas_view.el.scrollIntoView({block: 'center'});
      r = v.canvas_view.el.getBoundingClientRect();
    }
    return [r.left + v.frame.x_scale.compute(x), r.top + v.frame.y_scale.compute(y)];
  },
  frames() {  // body frames of the open pair (the matrix's x extent; the band's and the
    // path's vertices are thinned to the screen, so their count is no frame count)
    return Math.round(this.model('hs-x-range').bounds[1] + 0.5);
  },
  cols(name, keys) {
    const d = this.model(name).data;
    return Object.fromEntries(keys.map(k => [k, Array.from(d[k] ?? [])]));
  },
};
"""


def free_port(address: str = "127.0.0.1") -> int:
    """A TCP port on ``address`` that nothing listens on right now."""
    with socket.socket() as sock:
        sock.bind((address, 0))
        return int(sock.getsockname()[1])


@contextmanager
def running_server(
    *serve_args: str, log: IO, timeout: float = 120.0, env: dict | None = None, cwd=None
) -> Iterator[tuple[str, float]]:
    """``handsplice serve --port FREE *serve_args`` in a child process, output to ``log``.

    ``env``, ``cwd``: the child's environment and folder (default: this one's, the
    repository root); benchmarks run another version of the code this way. By default
    the child imports this checkout's ``engine`` and ``webapp`` (its folder first on
    ``PYTHONPATH``), not whichever checkout the environment's ``handsplice`` was
    installed from: a second worktree sharing one virtual environment tests its own
    server.

    Yields ``(url, seconds until it answered)``; the server is stopped on exit.
    Raises ``RuntimeError`` (with the end of the log) if it exits or does not answer
    within ``timeout`` seconds.
    """
    port = free_port()
    exe = Path(sys.executable).with_name("handsplice")
    if env is None:
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH")) if p)
    t0 = time.monotonic()
    proc = subprocess.Popen(
        [str(exe), "serve", "--port", str(port), *serve_args],
        cwd=cwd or ROOT,
        env=env,
        stdout=log,
        stderr=subprocess.STDOUT,
    )
    url = f"http://127.0.0.1:{port}/"
    try:
        while True:
            if proc.poll() is not None:
                raise RuntimeError(f"handsplice serve exited ({proc.returncode}):\n{_tail(log)}")
            try:
                # building the first page can take long on a busy machine: a short
                # timeout would abandon every attempt (and queue another page build)
                with urllib.request.urlopen(url, timeout=60) as reply:
                    if reply.status == 200:
                        break
            except OSError:
                pass
            if time.monotonic() - t0 > timeout:
                raise RuntimeError(
                    f"handsplice serve did not answer within {timeout:g} s:\n{_tail(log)}"
                )
            time.sleep(0.2)
        yield url, time.monotonic() - t0
    finally:
        stop_process(proc, timeout=10)


def stop_process(proc: subprocess.Popen, timeout: float = 10.0) -> None:
    """Stop a child process: SIGTERM, then SIGKILL if it has not exited within ``timeout``
    seconds; returns once it has exited."""
    proc.terminate()
    try:
        proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def launch_chromium(playwright, headless: bool = True):
    """Debian's Chromium through Playwright (``playwright install`` cannot download here)."""
    if not Path(CHROMIUM).exists():
        raise RuntimeError(f"{CHROMIUM} is missing (apt-get install chromium)")
    return playwright.chromium.launch(
        executable_path=CHROMIUM, args=CHROMIUM_ARGS, headless=headless
    )


def _tail(log: IO, chars: int = 3000) -> str:
    log.flush()
    log.seek(0)
    text = log.read()
    return (text.decode(errors="replace") if isinstance(text, bytes) else text)[-chars:]
