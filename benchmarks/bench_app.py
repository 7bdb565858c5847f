"""The app in a real browser: drag latency on a 2,000 x 2,000 matrix, first page load.

Run: ``.venv/bin/python -m benchmarks.bench_app [--drags 40] [--loads 5] [--before REF
[--rounds 2]]`` (``--before``: the app at git REF measured too, side by side in the same
run: before, now, and again per extra round)

* **Drag**: a 2,000-frame body take (LAFAN1 ``dance1_subject1`` resampled to 60 fps)
  against ManipNet's mug take (4,000 frames at 120 fps = 2,001 alignment-grid
  frames), default bands. One matching point (mid-take, 45 % up the hand axis) is
  dragged up and down by 60 alignment-grid rows (120 hand-file frames) with the mouse;
  the time from the mouse release (``pointerup`` in the
  page) to the new path arriving in the page's path data source (checked every
  animation frame, so the path is drawn in that frame) is recorded.
  The server-side compute time of each edit (status line) is reported beside it.
* **Page load**: a fresh browser context opens the demo pair (server already
  started, i.e. warm: features and JIT done at start-up); the time from
  navigation to the cost image, band and path being in the page.

Both against ``handsplice serve`` started here on free ports; Chromium from
/usr/bin/chromium. Writes the ``app`` section of benchmarks/RESULTS.md and a
screenshot of the demo pair to benchmarks/figures/app_demo.png.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from benchmarks._results import write_section
from webapp.launch import PAGE_HELPERS, launch_chromium, running_server

ROOT = Path(__file__).resolve().parents[1]
MOCAP = ROOT.parent / "shared" / "data" / "mocap"
FIGURES = Path(__file__).with_name("figures")

WATCH = """
() => {
  const src = Bokeh.documents[0].get_model_by_name('hs-path-source');
  window.hsLast = src.data; window.hsChanged = null; window.hsUp = null;
  const tick = () => {
    if (src.data !== window.hsLast) { window.hsLast = src.data; window.hsChanged = performance.now(); }
    requestAnimationFrame(tick);
  };
  requestAnimationFrame(tick);
  window.addEventListener('pointerup', () => { window.hsUp = performance.now(); }, true);
}
"""
READY = """
() => {
  if (!window.Bokeh || !Bokeh.documents.length) return false;
  const doc = Bokeh.documents[0];
  const path = doc.get_model_by_name('hs-path-source');
  const band = doc.get_model_by_name('hs-band-source');
  const img = doc.get_model_by_name('hs-image-source');
  return !!(path && path.data.x && path.data.x.length > 0 && band && band.data.lo.length > 0
            && img && img.data.image && img.data.image[0] && img.data.image[0].length > 1);
}
"""


def drag_once(page, x: int, a: float, b: float, timeout_ms: int = 60_000) -> float:
    """Drag the matching point at body frame ``x`` from hand frame ``a`` to ``b`` with the
    mouse; the milliseconds from the mouse release to the new path in the page (``WATCH``)."""
    page.evaluate("() => { window.hsChanged = null; window.hsUp = null; }")
    start = page.evaluate("([x, y]) => hs.xy(x, y)", [x, a])
    end = page.evaluate("([x, y]) => hs.xy(x, y)", [x, b])
    page.mouse.move(*start)
    page.mouse.down()
    page.mouse.move(*end, steps=4)
    page.mouse.up()
    page.wait_for_function(
        "() => window.hsChanged !== null && window.hsUp !== null", timeout=timeout_ms
    )
    return float(page.evaluate("() => window.hsChanged - window.hsUp"))


@contextmanager
def serve(*extra: str, tree: Path | None = None):
    """``handsplice serve`` of ``tree`` (None: this checkout) on a free port; yields (url,
    seconds until it answered)."""
    env = None
    if tree is not None:
        env = dict(os.environ, PYTHONPATH=str(tree), NUMBA_CACHE_DIR=str(tree / ".numba_cache"))
    with (
        tempfile.TemporaryFile() as log,
        running_server(*extra, log=log, env=env, cwd=tree, timeout=900) as started,
    ):
        yield started


def before_tree(ref: str) -> Path:
    """``engine``, ``webapp`` and ``sample_data`` as at git ``ref`` (made once)."""
    from benchmarks.long_pairs import baseline_tree

    return baseline_tree(ref, ("engine", "webapp", "sample_data"), name="app-before")


def big_pair(folder: Path) -> tuple[int, int]:
    """Write the 2,000 x 2,001 pair and its samples.json into ``folder``."""
    from engine.io import load_take
    from engine.io.bvh import write_bvh
    from engine.model.kinematics import resample

    body = load_take(MOCAP / "lafan1" / "dance1_subject1.bvh")
    write_bvh(resample(body, 60.0).frames(0, 2000), folder / "dance1_60fps_2000.bvh")
    hand = ROOT / "sample_data" / "manipnet" / "mug1_rightHand.bvh"
    (folder / hand.name).write_bytes(hand.read_bytes())
    (folder / "samples.json").write_text(
        json.dumps(
            {
                "pairs": [
                    {
                        "name": "big",
                        "body": "dance1_60fps_2000.bvh",
                        "hand": hand.name,
                        "side": "right",
                        "demo": True,
                    }
                ]
            }
        )
    )
    return 2000, 2001


def _pct(values, q) -> float:
    return float(np.percentile(np.asarray(values, dtype=float), q))


def server_cpu_s(url: str) -> float:
    """CPU seconds (user + system, all threads) used so far by the ``handsplice serve``
    process that listens at ``url`` (found by its ``--port``)."""
    port = url.rstrip("/").rsplit(":", 1)[1]
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            args = (proc / "cmdline").read_bytes().split(b"\0")
            if b"serve" not in args or b"--port" not in args:
                continue
            if args[args.index(b"--port") + 1].decode() != port:
                continue
            fields = (proc / "stat").read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError, ValueError):
            continue
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    return float("nan")


def measure_drags(browser, url: str, drags: int) -> dict:
    page = browser.new_page(viewport={"width": 1400, "height": 1100})
    page.goto(url, timeout=180_000)
    page.wait_for_function(READY, timeout=120_000)
    page.evaluate(WATCH)
    page.evaluate(PAGE_HELPERS)
    # body frames of the pair, hand-file frames per alignment-grid row (hand fps / body fps):
    # the point sits at mid-take, 45 % up the hand axis, and moves by 60 grid rows (as on
    # 2026-11-24, when the matrix's hand axis counted grid rows)
    n, scale = page.evaluate(
        "() => [hs.frames(), hs.model('hs-rates').data.hand_fps[0] / hs.model('hs-rates').data.fps[0]]"
    )
    x, y0 = n // 2, round(0.45 * n * scale)
    y1 = y0 + round(60 * scale)
    page.mouse.click(*page.evaluate("([x, y]) => hs.xy(x, y)", [x, y0]))
    page.wait_for_function("() => window.hsChanged !== null", timeout=60_000)
    page.wait_for_timeout(3000)  # the click's follow-up work (trust, preview) settles
    latencies, server_ms = [], []
    cpu0 = server_cpu_s(url)
    for k in range(drags):
        a, b = (y0, y1) if k % 2 == 0 else (y1, y0)
        rev = page.locator(".hs-status span").get_attribute("data-revision")
        latencies.append(drag_once(page, x, a, b))
        # the status line of this drag's solve (it may follow the path by a tick or more)
        page.locator(f".hs-status span:not([data-revision='{rev}'])").wait_for(timeout=60_000)
        status = page.locator(".hs-status span").inner_text()
        found = re.search(r"([\d.]+) ms", status)
        if found:
            server_ms.append(float(found.group(1)))
    page.wait_for_timeout(3000)  # the last drag's follow-up work is counted too
    cpu = (server_cpu_s(url) - cpu0) / drags
    page.close()
    return {"latency": latencies, "server": server_ms, "n": n, "cpu_per_drag": cpu}


def measure_loads(browser, url: str, loads: int) -> list[float]:
    times = []
    for _ in range(loads):
        context = browser.new_context(viewport={"width": 1400, "height": 1100})
        page = context.new_page()
        t0 = time.perf_counter()
        page.goto(url, timeout=180_000)
        page.wait_for_function(READY, timeout=120_000)
        times.append(time.perf_counter() - t0)
        context.close()
    return times


def screenshot(browser, url: str, path: Path) -> None:
    """The header, the alignment and the preview of the demo pair (one picture)."""
    page = browser.new_page(viewport={"width": 1360, "height": 1000})
    page.goto(url, timeout=180_000)
    page.wait_for_function(READY, timeout=120_000)
    page.locator(".hs-preview-image img").wait_for(timeout=120_000)  # rendered on load
    page.wait_for_timeout(800)
    bottom = page.locator(".hs-preview-image").evaluate(
        "e => e.getBoundingClientRect().bottom + window.scrollY"
    )
    page.screenshot(
        path=str(path), full_page=True, clip={"x": 0, "y": 0, "width": 1360, "height": bottom + 12}
    )
    page.close()


def demo_query() -> str:
    """URL query of the demo pair with one matching point on its path (tolerance 2) and the
    preview a third into the take."""
    from webapp import config
    from webapp.state import Session

    cfg = config.configure(upload_dir=Path(tempfile.gettempdir()) / "hs-bench-uploads")
    session = Session(cfg)
    session.load_sample(cfg.default_sample)
    path = session.solution.pass1.path
    x = session.n // 2
    y = int(path[path[:, 0] == x, 1][0])
    return f"?sample={cfg.default_sample}&pts={x}:{y}:2&frame={session.n // 3}"


def measure(browser, tmp: Path, drags: int, loads: int, tree: Path | None, shot: Path | None):
    """Every measure of one version of the app (``tree``; None: this checkout)."""
    load_before = os.getloadavg()
    with serve("--upload-dir", str(tmp / "up"), tree=tree) as (url, start_demo):
        demo_loads = measure_loads(browser, url, loads)
        if shot is not None:
            screenshot(browser, url + demo_query(), shot)
    with serve("--sample-dir", str(tmp / "big"), "--upload-dir", str(tmp / "up"), tree=tree) as (
        url,
        start_big,
    ):
        big_loads = measure_loads(browser, url, 2)
        drag = measure_drags(browser, url, drags)
    return {
        "loads": demo_loads,
        "big_loads": big_loads,
        "start": (start_demo, start_big),
        "drags": drag,
        "load_avg": (load_before, os.getloadavg()),
    }


def _row(r: dict) -> list[str]:
    lat, srv, loads = r["drags"]["latency"], r["drags"]["server"], r["loads"]
    la0, la1 = r["load_avg"]
    return [
        f"{_pct(lat, 50):.0f} / **{_pct(lat, 95):.0f}** / {max(lat):.0f} ms",
        f"{_pct(srv, 50):.0f} / {_pct(srv, 95):.0f} ms" if srv else "n/a",
        f"{1000 * r['drags']['cpu_per_drag']:.0f} ms",
        f"**{statistics.median(loads):.2f}** / {max(loads):.2f} s",
        f"{statistics.median(r['big_loads']):.2f} s",
        f"{r['start'][0]:.1f} / {r['start'][1]:.1f} s",
        f"{la0[0]:.1f}/{la0[1]:.1f} → {la1[0]:.1f}/{la1[1]:.1f}",
    ]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--drags", type=int, default=40)
    parser.add_argument("--loads", type=int, default=5)
    parser.add_argument(
        "--before",
        default=None,
        metavar="REF",
        help="also measure the app at git REF, side by side in the same run (before, now, "
        "before, now when --rounds 2)",
    )
    parser.add_argument("--rounds", type=int, default=1)
    parser.add_argument("--no-write", action="store_true", help="print only")
    args = parser.parse_args(argv)
    from playwright.sync_api import sync_playwright

    FIGURES.mkdir(exist_ok=True)
    codes = [("now", None)]
    if args.before:
        codes = [(f"before ({args.before})", before_tree(args.before)), ("now", None)]
    results: dict[str, list[dict]] = {name: [] for name, _ in codes}
    with tempfile.TemporaryDirectory() as tmp, sync_playwright() as p:
        tmp = Path(tmp)
        (tmp / "big").mkdir()
        n, m = big_pair(tmp / "big")
        browser = launch_chromium(p)
        for k in range(args.rounds):
            for name, tree in codes:
                shot = FIGURES / "app_demo.png" if tree is None and k == 0 else None
                results[name].append(measure(browser, tmp, args.drags, args.loads, tree, shot))
                print(name, _row(results[name][-1]), flush=True)
        browser.close()

    head = (
        "| code | drag -> new path in the page, p50 / **p95** / max (goal p95 < 150 ms) "
        "| server time per edit (edit to solution applied), p50 / p95 "
        "| server CPU per drag (all threads, incl. trust and preview) "
        "| first page load, demo pair, warm server: **median** / max (goal < 5 s) "
        f"| first page load, {n} x {m} pair: median | server start (demo / {n}-frame pair) "
        "| load average 1/5 min, before → after |\n|---|---|---|---|---|---|---|---|\n"
    )
    table = head + "\n".join(
        f"| {name} | " + " | ".join(_row(r)) + " |" for name, _ in codes for r in results[name]
    )
    ratios = ""
    if args.before:
        b, a = (results[name] for name, _ in codes)

        def pooled(rs, key, q):
            return _pct([v for r in rs for v in r["drags"][key]], q)

        med = [statistics.median([v for r in rs for v in r["loads"]]) for rs in (b, a)]
        ratios = (
            f"\n\nNow / before (pooled over the rounds): drag p50 "
            f"{pooled(a, 'latency', 50) / pooled(b, 'latency', 50):.2f}, drag p95 "
            f"{pooled(a, 'latency', 95) / pooled(b, 'latency', 95):.2f}, server time per edit "
            f"p50 {pooled(a, 'server', 50) / max(pooled(b, 'server', 50), 1e-9):.2f}, demo page "
            f"load median {med[1] / med[0]:.2f}, server CPU per drag "
            f"{sum(r['drags']['cpu_per_drag'] for r in a) / sum(r['drags']['cpu_per_drag'] for r in b):.2f}."
        )
    lat = [v for r in results["now"] for v in r["drags"]["latency"]]
    md = (
        f"### Browser app (`benchmarks/bench_app.py`, Chromium headless via Playwright)\n\n"
        f"{table}{ratios}\n\n"
        f"Drag: {len(lat) // len(results['now'])} mouse drags of one matching point by 60 rows "
        f"of the alignment grid (120 hand frames) on the pass-1 matrix of a {n} x {m} pair (LAFAN1 dance1 at 60 fps vs ManipNet "
        "mug1, default bands); latency = mouse release (pointerup) to the new path in the "
        "page's data source, checked every animation frame. Server time per edit = the status "
        "line's ms: from the edit reaching the session to its solution applied on the event "
        "loop (the solve runs on a worker thread since 15725c4, so this includes waiting for "
        "the worker and for the loop; on 2026-11-24 it was the solve alone, run on the loop). "
        "Page load: fresh browser context, navigation until cost image, band and path are in "
        f"the page ({len(results['now'][0]['loads'])} loads). Screenshot: "
        "`benchmarks/figures/app_demo.png`."
    )
    print(md)
    if not args.no_write:
        write_section("app", md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
