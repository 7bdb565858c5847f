"""Upload throughput through the page's file field (stranger R3-6).

    python -m benchmarks.bench_upload [--mb 20] [--chunks 4194304 1048576]

A page holding only the app's upload field (``webapp.views.dropper.TakeDropper``, the
server side of every chunk as in the app: written to a staging file, progress told to
the page) served in this process; Chromium (Playwright) puts a file into it. Measured:
seconds from choosing the file to the server holding all of it (``on_staged``), for each
chunk size (``--chunks``; 4 MiB was the app's until R3-6), with how often the page was
told the progress. The app's own page adds its warm-up, not its transfer path. Files:
LAFAN1 ``multipleActions1`` (3.2 MB) and that take's motion repeated to ``--mb`` MB.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

MOCAP = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "mocap"
BODY = MOCAP / "lafan1" / "multipleActions1_subject1.bvh"


def big_file(folder: Path, mb: float) -> Path:
    """``BODY`` with its motion lines repeated to about ``mb`` MB (a valid BVH)."""
    text = BODY.read_text()
    head, _, motion = text.partition("MOTION\n")
    lines = motion.splitlines()
    frames = [x for x in lines[2:] if x.strip()]
    per = sum(len(x) + 1 for x in frames) / len(frames)
    n = int(mb * 1e6 / per)
    rows = [frames[i % len(frames)] for i in range(n)]
    path = folder / f"big{mb:g}MB_body.bvh"
    body = "\n".join(rows)
    path.write_text(f"{head}MOTION\nFrames: {n}\n{lines[1]}\n{body}\n")
    return path


def main(argv=None) -> int:
    import panel as pn
    from playwright.sync_api import sync_playwright

    from webapp.config import AppConfig
    from webapp.launch import free_port, launch_chromium
    from webapp.views import dropper as D

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mb", type=float, nargs="*", default=[20.0], help="extra file sizes")
    ap.add_argument("--chunks", type=int, nargs="*", default=[4 << 20, D.CHUNK_BYTES])
    args = ap.parse_args(argv)
    folder = Path(tempfile.mkdtemp(prefix="hs-upload-bench-"))
    files = [BODY] + [big_file(folder, mb) for mb in args.mb]
    cfg = AppConfig(upload_dir=folder / "up", max_upload_bytes=400 << 20)
    results: dict[str, dict] = {}

    def app():
        chunk = int(pn.state.session_args.get("chunk", [b"4194304"])[0])
        field = D.TakeDropper(cfg, chunk_size=chunk, css_classes=["bench-field"])
        done = pn.pane.HTML("", css_classes=["bench-done"])
        key = pn.state.session_args.get("key", [b""])[0].decode()
        results[key] = {"told": 0}

        def progress(receipt):
            results[key]["told"] += 1
            field.verdict("receiving", receipt.tile, *receipt.words())

        def staged(s):
            results[key]["staged"] = time.perf_counter()
            s.path.unlink(missing_ok=True)
            done.object = f"<span>done {s.size}</span>"

        field.on_progress, field.on_staged = progress, staged
        return pn.Column(field, done)

    port = free_port()
    server = pn.serve(
        app, port=port, threaded=True, show=False, websocket_max_message_size=64 << 20
    )
    time.sleep(2)
    print(f"load {os.getloadavg()[0]:.1f} at start", flush=True)
    with sync_playwright() as p:
        browser = launch_chromium(p)
        for path in files:
            for chunk in args.chunks:
                key = f"{path.name}-{chunk}"
                page = browser.new_page()
                page.goto(f"http://127.0.0.1:{port}/?chunk={chunk}&key={key}", timeout=600_000)
                field = page.locator(".bench-field input[type=file]")
                field.wait_for(state="attached", timeout=600_000)
                page.wait_for_timeout(500)
                t0 = time.perf_counter()
                field.set_input_files(str(path))
                page.locator(".bench-done span").wait_for(timeout=900_000)
                r = results[key]
                seconds = r["staged"] - t0
                mb = path.stat().st_size / 1e6
                print(
                    f"{path.name:32s} {mb:5.1f} MB  chunk {chunk / 2**20:5.2f} MiB: received in "
                    f"{seconds:6.2f} s = {mb / seconds:6.2f} MB/s, page told {r['told']} times  "
                    f"(load {os.getloadavg()[0]:.1f})",
                    flush=True,
                )
                page.close()
        browser.close()
    server.stop()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
