"""The 10-minute pair in the app, end to end, with the server's memory over time (issue 13).

Run: ``python -m benchmarks.bench_app_tenmin OUT [--seconds 600] [--drags 3]
[--steps bvh,glb,drag] [--code REF]``

``--code REF`` serves a commit's ``engine``, ``webapp`` and ``sample_data`` (made once by
``benchmarks.long_pairs.baseline_tree``) instead of this checkout: run it and ``now`` one
after the other, alternating, to compare the two within one run.

``handsplice serve BODY HAND`` (at ``nice -n 19``) on ``benchmarks.long_pairs.pair_files
(seconds)`` (made once under ``$TMPDIR/handsplice-long-pairs``), one Chromium tab, and
every 0.5 s the resident memory of the server and of its children (the download
encoders). The tab records when each part of the page is first on screen after
navigation (matrix image, band, path, wrist-speed strips, preview, points table, trust),
then downloads the spliced BVH and GLB (seconds, size), then places a matching point on
the path at mid-take and drags it ``--drags`` times (mouse release -> new path, and the
server's stated compute). Screenshots of each stage, ``rss.json`` ((s, server MB,
children MB) rows), ``events.json`` and ``serve.log`` go to OUT. Prints as it goes, with
the machine's load on every line; writes nothing to RESULTS.md.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import threading
import time
import urllib.request
from pathlib import Path

from benchmarks.bench_app import WATCH, drag_once
from benchmarks.long_pairs import baseline_tree, pair_files
from webapp.launch import PAGE_HELPERS, free_port, launch_chromium

ROOT = Path(__file__).resolve().parents[1]
#: page parts and how to tell they are on screen (a JS predicate, or a CSS selector that
#: Playwright's locator finds through Panel's shadow roots)
PARTS = {
    "image": "() => { const i = Bokeh.documents[0].get_model_by_name('hs-image-source');"
    " return !!(i && i.data.image && i.data.image[0] && i.data.image[0].length > 1); }",
    "band": "() => { const b = Bokeh.documents[0].get_model_by_name('hs-band-source');"
    " return !!(b && b.data.x && b.data.x.length > 0); }",
    "path": "() => { const b = Bokeh.documents[0].get_model_by_name('hs-path-source');"
    " return !!(b && b.data.x && b.data.x.length > 0); }",
    "strips": "() => { const b = Bokeh.documents[0].get_model_by_name('hs-body-signal-source');"
    " return !!(b && Object.values(b.data).some(v => v.length > 0)); }",
    "trust": "() => { const b = Bokeh.documents[0].get_model_by_name('hs-confidence-source');"
    " return !!(b && b.data.start && b.data.start.length > 0); }",
    "preview": ".hs-preview-image img",
    "points_table": ".hs-points",
}


class Recorder:
    """Events with seconds since start and the load; the server's RSS sampled meanwhile."""

    def __init__(self, out: Path):
        self.out, self.t0 = out, time.monotonic()
        self.events: list[dict] = []
        self.rss: list[tuple[float, int, int]] = []
        self._stop = threading.Event()

    def note(self, what: str, **kw) -> None:
        t = time.monotonic() - self.t0
        self.events.append({"t": round(t, 1), "what": what, "load": os.getloadavg()[0], **kw})
        print(f"[{t:7.1f}s] {what} {kw or ''} load={os.getloadavg()[0]:.1f}", flush=True)

    def sample(self, pid: int) -> None:
        import psutil

        def loop():
            proc = psutil.Process(pid)
            while not self._stop.is_set():
                try:
                    main = proc.memory_info().rss
                    kids = sum(c.memory_info().rss for c in proc.children(recursive=True))
                except psutil.Error:
                    break
                self.rss.append((round(time.monotonic() - self.t0, 1), main >> 20, kids >> 20))
                time.sleep(0.5)

        threading.Thread(target=loop, daemon=True).start()

    def save(self) -> None:
        (self.out / "rss.json").write_text(json.dumps(self.rss))
        (self.out / "events.json").write_text(json.dumps(self.events, indent=1))

    def stop(self) -> dict:
        self._stop.set()
        self.save()
        return {
            "peak_mb": max((m + k for _, m, k in self.rss), default=0),
            "peak_server_mb": max((m for _, m, _ in self.rss), default=0),
        }


def _ok(page, test: str) -> bool:
    try:
        if test.startswith("."):
            return page.locator(test).count() > 0
        return bool(page.evaluate(test))
    except Exception:  # the page is still navigating
        return False


def open_page(page, url: str, rec: Recorder, out: Path, timeout: float = 3600.0) -> dict:
    t_nav = time.monotonic()
    page.goto(url, wait_until="commit")
    seen: dict[str, float] = {}
    deadline, saved = time.monotonic() + timeout, 0.0
    while len(seen) < len(PARTS) and time.monotonic() < deadline:
        for name, test in PARTS.items():
            if name not in seen and _ok(page, test):
                seen[name] = round(time.monotonic() - t_nav, 1)
                rec.note(f"on screen: {name}", s=seen[name])
                if name in ("image", "path", "trust", "preview"):
                    page.screenshot(path=str(out / f"shot_{name}.png"), full_page=True)
        if time.monotonic() - saved > 30:
            saved = time.monotonic()
            rec.save()
        time.sleep(0.5)
    rec.note("opened", seen=seen)
    page.screenshot(path=str(out / "shot_opened.png"), full_page=True)
    return seen


def download(page, kind: str, rec: Recorder, out: Path) -> None:
    t = time.monotonic()
    try:
        with page.expect_download(timeout=3_600_000) as info:
            page.locator(f".hs-download-{kind} button").click()
        dest = out / f"spliced.{kind}"
        info.value.save_as(dest)
        rec.note(f"download {kind}", s=round(time.monotonic() - t, 1), mb=dest.stat().st_size >> 20)
    except Exception as exc:  # a download that never comes is a result too
        rec.note(f"download {kind} failed", error=str(exc)[:300])
        page.screenshot(path=str(out / f"shot_failed_{kind}.png"), full_page=True)


def drags(page, count: int, rec: Recorder, out: Path) -> None:
    page.evaluate(WATCH)
    path = page.evaluate("hs.cols('hs-path-source', ['x', 'y'])")
    xs, ys = path["x"], path["y"]
    x, y = int(xs[len(xs) // 2]), float(round(ys[len(xs) // 2]))
    page.evaluate("() => { window.hsChanged = null; }")
    t = time.monotonic()
    page.mouse.click(*page.evaluate("([x, y]) => hs.xy(x, y)", [x, y]))
    page.wait_for_function("() => window.hsChanged !== null", timeout=3_600_000)
    rec.note("point placed -> new path", ms=round((time.monotonic() - t) * 1000))
    # zoomed to 5 % of the take around the point (as bench_app_long: ranges set from JS,
    # which fires no RangesUpdate, so the matrix image keeps the whole take's pixels), so
    # that 12 screen pixels are a drag a user makes (on the whole take: 1,500 hand frames)
    half = page.evaluate("() => hs.model('hs-x-range').bounds[1] + 0.5") * 0.05 / 2
    page.evaluate(
        "([x, y, h]) => { hs.model('hs-x-range').setv({start: x - h, end: x + h});"
        " hs.model('hs-y-range').setv({start: y - h, end: y + h}); }",
        [x, y, half],
    )
    page.wait_for_timeout(3000)
    per_px = page.evaluate(
        "() => { const v = Bokeh.index.find_one(hs.model('hs-cost-figure'));"
        " return (hs.model('hs-y-range').end - hs.model('hs-y-range').start)"
        " / v.frame.bbox.height; }"
    )
    step = max(1.0, round(12 * per_px))
    for k in range(count):
        a, b = (y, y + step) if k % 2 == 0 else (y + step, y)
        ms = drag_once(page, x, a, b, timeout_ms=3_600_000)
        found = re.search(r"([\d.]+) ms", page.locator(".hs-status span").inner_text())
        rec.note("drag", ms=round(ms), server_ms=float(found.group(1)) if found else None)
    page.screenshot(path=str(out / "shot_dragged.png"), full_page=True)


def run(
    out: Path, body: Path, hand: Path, steps: list[str], count: int, tree: Path | None = None
) -> dict:
    """Serve the pair from ``tree`` (None: this checkout), open one tab, run ``steps``."""
    from playwright.sync_api import sync_playwright

    rec = Recorder(out)
    tree = tree or ROOT
    env = dict(
        os.environ,
        PYTHONPATH=str(tree),
        NUMBA_CACHE_DIR=str(tree / ".numba_cache"),
        PYOPENGL_PLATFORM="egl",
    )
    exe = Path(sys.executable).with_name("handsplice")
    port = free_port()
    cmd = ["nice", "-n", "19", str(exe), "serve", str(body), str(hand), "--port", str(port)]
    with (out / "serve.log").open("w") as log:
        server = subprocess.Popen(
            [*cmd, "--upload-dir", str(out / "uploads")],
            cwd=tree,
            env=env,
            stdout=log,
            stderr=subprocess.STDOUT,
        )
    try:
        time.sleep(0.3)  # nice execs the server: the same pid
        rec.sample(server.pid)
        rec.note("server started")
        url = f"http://127.0.0.1:{port}/"
        while server.poll() is None:
            try:
                with urllib.request.urlopen(url, timeout=120) as reply:
                    if reply.status == 200:
                        break
            except OSError:
                time.sleep(0.5)
        rec.note("server answers", rc=server.poll())
        with sync_playwright() as p:
            browser = launch_chromium(p)
            context = browser.new_context(
                viewport={"width": 1400, "height": 1100}, accept_downloads=True
            )
            context.set_default_timeout(3_600_000)
            page = context.new_page()
            open_page(page, url, rec, out)
            page.evaluate(PAGE_HELPERS)
            for kind in ("bvh", "glb"):
                if kind in steps:
                    download(page, kind, rec, out)
            if "drag" in steps:
                drags(page, count, rec, out)
            browser.close()
    finally:
        server.terminate()
        try:
            server.wait(timeout=20)
        except subprocess.TimeoutExpired:
            server.kill()
        peaks = rec.stop()
        rec.note("done", **peaks)
    return peaks


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, help="folder for screenshots, rss.json, events.json")
    parser.add_argument("--seconds", type=float, default=600.0, help="pair length (120 fps)")
    parser.add_argument("--drags", type=int, default=3)
    parser.add_argument("--steps", default="bvh,glb,drag", help="after opening: bvh,glb,drag")
    parser.add_argument("--code", default="now", help="now (this checkout) or a commit")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    body, hand, _truth = pair_files(args.seconds)
    tree = (
        None
        if args.code == "now"
        else baseline_tree(args.code, ("engine", "webapp", "sample_data"), name="tenmin")
    )
    peaks = run(args.out, body, hand, args.steps.split(","), args.drags, tree)
    print(json.dumps({"code": args.code, **peaks}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
