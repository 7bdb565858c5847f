"""The app in Chromium on long 120 fps pairs (issue 13): first matrix on screen, drag latency,
and whether other tabs wait while a long pair is aligned.

Run: ``.venv/bin/python -m benchmarks.bench_app_long [--pairs 120 600] [--drags 20]
[--codes today now] [--no-write]``

Pairs: ``benchmarks.long_pairs.pair_files`` (2 and 10 minutes at 120 fps: LAFAN1
takes played in turn, a re-timed hand take with fingers). Codes, each on its own
``handsplice serve`` in the same run: *now* (this checkout) and *today* (the app at
``APP_BASELINE``, the commit this work started from, with one fix carried over: its
credits pane raised on a pair opened by path, so ``serve BODY HAND`` gave no page).

For each pair and code:

* **by path**: ``handsplice serve BODY HAND`` (the server reads the pair and warms up
  before it listens; that time is reported). Tab 1 and then tab 2 (fresh browser
  contexts) open the page: seconds from navigation to the cost image of the pair on
  screen, and to band and path on screen.
* **other tab while a tab opens the pair**: a tab on the bundled demo pair drags a
  matching point over and over while a third tab opens the long pair; the largest
  and median drag -> new path latency of the demo tab meanwhile (a frozen event loop
  shows as seconds).
* **drag**: one matching point of the long pair (placed on the path at mid-take)
  dragged ±4 screen pixels with the mouse; mouse release -> new path in the page (every
  animation frame), p50 / p95, and the server's compute time of each edit (status line).
* **by upload**: a server without a pair; both files put into the page's upload fields;
  "files in" = both tiles carry the server's *Checked* verdict; then seconds to the cost
  image and to band and path of the new pair.

Writes the ``app_long`` section of benchmarks/RESULTS.md with the machine's load
average before and after (the machine is shared: figures are only comparable within
one run).
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from benchmarks._results import write_section
from benchmarks.bench_app import WATCH, drag_once
from benchmarks.long_pairs import baseline_tree, pair_files
from webapp.launch import PAGE_HELPERS, launch_chromium, running_server

ROOT = Path(__file__).resolve().parents[1]
#: the app before issue 13's app side (main when this work began)
APP_BASELINE = os.environ.get("HANDSPLICE_APP_BASELINE", "46e6d22")
#: files of this checkout copied over the baseline (fixes without which a measure cannot run)
CARRIED_FIXES = ("webapp/views/credits.py",)
#: a drag moves the point this many screen pixels (Bokeh ignores a shorter one) on a view
#: zoomed to ZOOM_FRACTION of the take around the point (as a user zooms in to place a
#: point precisely: the whole 10-minute take is 128 frames a pixel)
DRAG_PX = 12
ZOOM_FRACTION = 0.05

IMAGE_OF = """
(n) => {
  if (!window.Bokeh || !Bokeh.documents.length) return false;
  const d = Bokeh.documents[0];
  const xr = d.get_model_by_name('hs-x-range'), img = d.get_model_by_name('hs-image-source');
  return !!(xr && xr.end === n - 0.5 && img && img.data.image && img.data.image[0]
            && img.data.image[0].length > 1);
}
"""
PATH_OF = """
(n) => {
  if (!window.Bokeh || !Bokeh.documents.length) return false;
  const d = Bokeh.documents[0];
  // the band's last vertex is the take's last body frame (its vertices may be thinned to
  // the screen's columns: their count is no frame count)
  const band = d.get_model_by_name('hs-band-source'), path = d.get_model_by_name('hs-path-source');
  return !!(band && band.data.x && band.data.x.length > 0
            && band.data.x[band.data.x.length - 1] === n - 1 && path && path.data.x
            && path.data.x.length > 0);
}
"""


def _pct(values, q) -> float:
    return float(np.percentile(np.asarray(values, dtype=float), q)) if len(values) else float("nan")


def baseline_app(ref: str = APP_BASELINE) -> Path:
    """``engine``, ``webapp`` and ``sample_data`` as at ``ref`` (plus CARRIED_FIXES)."""
    folder = baseline_tree(ref, ("engine", "webapp", "sample_data"), name="app-baseline")
    for rel in CARRIED_FIXES:
        shutil.copyfile(ROOT / rel, folder / rel)
    return folder


def _env(tree: Path | None) -> dict:
    env = dict(os.environ)
    if tree is not None:
        env["PYTHONPATH"] = str(tree)
        env["NUMBA_CACHE_DIR"] = str(tree / ".numba_cache")
    return env


@contextmanager
def serve(tree: Path | None, *args: str):
    """``handsplice serve *args`` of ``tree`` (None: this checkout); its output goes to
    ``$TMPDIR/handsplice-bench-app-long.log``."""
    log_path = Path(tempfile.gettempdir()) / "handsplice-bench-app-long.log"
    with (
        log_path.open("w+") as log,
        running_server(*args, log=log, timeout=1800, env=_env(tree), cwd=tree) as started,
    ):
        yield started


def _wait(page, js: str, arg, timeout: float = 900.0) -> float:
    """Poll ``js(arg)`` in the page until true; monotonic time it became true."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            if page.evaluate(js, arg):
                return time.monotonic()
        except Exception:  # the page is still navigating
            pass
        if time.monotonic() > deadline:
            raise TimeoutError(js[:60])
        time.sleep(0.05)


def _context(browser):
    """A fresh browser context; long waits allowed (a shared machine can be slow)."""
    context = browser.new_context(viewport={"width": 1400, "height": 1100})
    context.set_default_timeout(900_000)
    return context


def open_times(browser, url: str, n: int) -> tuple[float, float, object]:
    """(s to the cost image, s to band and path) of a fresh tab; the tab stays open."""
    context = _context(browser)
    page = context.new_page()
    t0 = time.monotonic()
    page.evaluate(f"location.href = {url!r}")
    t_image = _wait(page, IMAGE_OF, n) - t0
    t_path = _wait(page, PATH_OF, n) - t0
    return t_image, t_path, page


def place_point(page) -> tuple[int, float, float]:
    """Add a matching point on the path at mid-take; (x, y, hand frames per pixel)."""
    page.bring_to_front()  # animation frames (the latency watch) run in the front tab only
    page.evaluate(PAGE_HELPERS)
    page.evaluate(WATCH)
    path = page.evaluate("hs.cols('hs-path-source', ['x', 'y'])")
    xs, ys = np.asarray(path["x"]), np.asarray(path["y"])
    x = int(xs[len(xs) // 2])
    y = float(round(ys[len(xs) // 2]))
    page.evaluate("() => { window.hsChanged = null; }")
    page.mouse.click(*page.evaluate("([x, y]) => hs.xy(x, y)", [x, y]))
    page.wait_for_function("() => window.hsChanged !== null", timeout=600_000)
    n = page.evaluate("() => hs.model('hs-x-range').bounds[1] + 0.5")  # body frames
    if n * ZOOM_FRACTION > 200:  # zoom in around the point (the figure's x and y ranges)
        half = n * ZOOM_FRACTION / 2
        page.evaluate(
            "([x, y, h]) => { hs.model('hs-x-range').setv({start: x - h, end: x + h});"
            " hs.model('hs-y-range').setv({start: y - h, end: y + h}); }",
            [x, y, half],
        )
        page.wait_for_timeout(500)
    per_px = page.evaluate(
        "() => { const v = Bokeh.index.find_one(hs.model('hs-cost-figure'));"
        " return (hs.model('hs-y-range').end - hs.model('hs-y-range').start) / v.frame.bbox.height; }"
    )
    return x, y, float(per_px)


def measure_drags(page, drags: int) -> dict:
    x, y, per_px = place_point(page)
    step = max(1.0, round(DRAG_PX * per_px))
    latencies, server_ms = [], []
    for k in range(drags):
        a, b = (y, y + step) if k % 2 == 0 else (y + step, y)
        latencies.append(drag_once(page, x, a, b, timeout_ms=600_000))
        found = re.search(r"([\d.]+) ms", page.locator(".hs-status span").inner_text())
        if found:
            server_ms.append(float(found.group(1)))
    return {"latency": latencies, "server": server_ms, "step": step}


def other_tab_while_opening(browser, url: str, demo: str, n: int) -> dict:
    """Drag latencies of a demo-pair tab while a new tab opens the long pair."""
    context = _context(browser)
    demo_page = context.new_page()
    demo_page.goto(url + f"?sample={demo}")
    _wait(demo_page, PATH_OF, demo_n(demo_page))
    x, y, per_px = place_point(demo_page)
    step = max(2.0, round(DRAG_PX * per_px))
    other = _context(browser).new_page()
    t0 = time.monotonic()
    other.evaluate(f"location.href = {url!r}")
    demo_page.bring_to_front()
    latencies, k = [], 0
    while True:
        a, b = (y, y + step) if k % 2 == 0 else (y + step, y)
        latencies.append(drag_once(demo_page, x, a, b, timeout_ms=600_000))
        k += 1
        try:
            if other.evaluate(PATH_OF, n):
                break
        except Exception:
            pass
        if time.monotonic() - t0 > 900:
            break
    opened = time.monotonic() - t0
    demo_page.context.close()
    other.context.close()
    return {"latency": latencies, "opened_s": opened}


def demo_n(page) -> int:
    _wait(
        page,
        "() => !!(window.Bokeh && Bokeh.documents.length && "
        "Bokeh.documents[0].get_model_by_name('hs-x-range'))",
        None,
    )
    for _ in range(600):
        n = page.evaluate(  # the band's last vertex is the last body frame
            "() => { const x = Bokeh.documents[0].get_model_by_name('hs-band-source').data.x;"
            " return x.length ? x[x.length - 1] + 1 : 0; }"
        )
        if n:
            return int(n)
        time.sleep(0.1)
    raise TimeoutError("demo pair")


def by_upload(browser, url: str, body: Path, hand: Path, n: int) -> dict:
    context = _context(browser)
    page = context.new_page()
    page.goto(url)
    demo_n(page)
    t0 = time.monotonic()
    page.locator(".hs-upload-body input[type=file]").set_input_files(str(body))
    page.locator(".hs-upload-hand input[type=file]").set_input_files(str(hand))
    for which in ("body", "hand"):
        page.locator(f".hs-upload-{which} .filepond--item[data-hs-verdict='ok']").wait_for(
            timeout=1_800_000
        )
    t_in = time.monotonic()
    t_image = _wait(page, IMAGE_OF, n) - t_in
    t_path = _wait(page, PATH_OF, n) - t_in
    context.close()
    return {"in_s": t_in - t0, "image_s": t_image, "path_s": t_path}


def loadavg() -> str:
    return "/".join(f"{v:.1f}" for v in os.getloadavg())


def run_pair(browser, seconds: float, code: str, tree: Path | None, drags: int, tmp: Path):
    from webapp.config import SAMPLE_DIR, demo_sample_name

    body, hand, _truth = pair_files(seconds)

    n = int(round(seconds * 120))
    demo = demo_sample_name(SAMPLE_DIR)
    out: dict = {"pair": f"{seconds / 60:g} min", "code": code, "load_before": loadavg()}
    up = tmp / f"up-{code}-{seconds:g}"
    with serve(tree, str(body), str(hand), "--upload-dir", str(up)) as (url, started):
        out["start_s"] = started
        img1, path1, tab1 = open_times(browser, url, n)
        img2, path2, tab2 = open_times(browser, url, n)
        tab2.context.close()
        out.update(tab1=(img1, path1), tab2=(img2, path2))
        print(code, seconds, "start, tab 1, tab 2:", started, out["tab1"], out["tab2"], flush=True)
        out["other"] = other_tab_while_opening(browser, url, demo, n)
        print(code, seconds, "other tab:", out["other"], flush=True)
        out["drag"] = measure_drags(tab1, drags)
        print(code, seconds, "drags:", out["drag"], flush=True)
        tab1.context.close()
    with serve(tree, "--upload-dir", str(up)) as (url, _):
        out["upload"] = by_upload(browser, url, body, hand, n)
    out["load_after"] = loadavg()
    print(out, flush=True)
    return out


def interleaved_drags(browser, seconds: float, codes: dict, drags: int, tmp: Path) -> dict:
    """Drag latency of several codes on one pair, their drags interleaved in one run.

    ``codes``: ``{name: tree or None}``. Each code's ``handsplice serve BODY HAND`` starts
    at once beside the others; one tab each adopts its server's warm-up alignment and
    places the matching point; then the codes' drags take turns (a, b, b, a, a, b, ...),
    so a change of the machine's load falls on both alike."""
    from contextlib import ExitStack

    body, hand, _truth = pair_files(seconds)
    n = int(round(seconds * 120))
    out = {name: {"latency": [], "server": [], "load_before": loadavg()} for name in codes}
    with ExitStack() as stack:
        urls = {}
        for name, tree in codes.items():
            log = stack.enter_context((tmp / f"serve-{name}.log").open("w+"))
            up = tmp / f"up-{name}-{seconds:g}"
            urls[name] = stack.enter_context(
                running_server(
                    str(body),
                    str(hand),
                    "--upload-dir",
                    str(up),
                    log=log,
                    timeout=1800,
                    env=_env(tree),
                    cwd=tree,
                )  # fmt: skip
            )
        pages = {}
        for name, (url, started) in urls.items():
            out[name]["start_s"] = started
            img, path, page = open_times(browser, url, n)
            out[name]["tab1"] = (img, path)
            x, y, per_px = place_point(page)
            pages[name] = (page, x, y, max(1.0, round(DRAG_PX * per_px)))
        names = list(codes)
        for k in range(drags):
            order = names if k % 2 == 0 else names[::-1]
            for name in order:
                page, x, y, step = pages[name]
                page.bring_to_front()
                a, b = (y, y + step) if k % 2 == 0 else (y + step, y)
                out[name]["latency"].append(drag_once(page, x, a, b, timeout_ms=600_000))
                found = re.search(r"([\d.]+) ms", page.locator(".hs-status span").inner_text())
                if found:
                    out[name]["server"].append(float(found.group(1)))
            print(k, {c: round(out[c]["latency"][-1]) for c in names}, loadavg(), flush=True)
        for page, *_ in pages.values():
            page.context.close()
    for name in codes:
        out[name]["load_after"] = loadavg()
    return out


def _row(r: dict) -> str:
    d, o, u = r["drag"], r["other"], r["upload"]
    return (
        f"| {r['pair']} | {r['code']} | {r['start_s']:.0f} s "
        f"| {r['tab1'][0]:.1f} / {r['tab1'][1]:.1f} s | {r['tab2'][0]:.1f} / {r['tab2'][1]:.1f} s "
        f"| {u['in_s']:.0f} s | {u['image_s']:.1f} / {u['path_s']:.1f} s "
        f"| {max(o['latency']):.0f} / {_pct(o['latency'], 50):.0f} ms ({len(o['latency'])}) "
        f"| **{_pct(d['latency'], 50):.0f} / {_pct(d['latency'], 95):.0f} ms** "
        f"| {_pct(d['server'], 50):.0f} / {_pct(d['server'], 95):.0f} ms "
        f"| {r['load_before']} → {r['load_after']} |"
    )


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=float, nargs="+", default=[120.0, 600.0])
    parser.add_argument("--codes", nargs="+", default=["today", "now"])
    parser.add_argument("--drags", type=int, default=20)
    parser.add_argument("--no-write", action="store_true")
    parser.add_argument(
        "--keep",
        type=Path,
        default=None,
        help="JSON file of rows: each run appends its rows, the table shows them all",
    )
    parser.add_argument(
        "--table-only", action="store_true", help="measure nothing: the table of --keep's rows"
    )
    parser.add_argument(
        "--interleaved",
        action="store_true",
        help="drag latency only: the codes' servers side by side, their drags taking turns "
        "(each pair of --pairs; prints, writes nothing)",
    )
    args = parser.parse_args(argv)
    from playwright.sync_api import sync_playwright

    trees = {"now": None, "today": baseline_app()}
    if args.interleaved:
        with tempfile.TemporaryDirectory() as tmp, sync_playwright() as p:
            browser = launch_chromium(p)
            for seconds in args.pairs:
                res = interleaved_drags(
                    browser, seconds, {c: trees[c] for c in args.codes}, args.drags, Path(tmp)
                )
                for code, r in res.items():
                    lat, srv = r["latency"], r["server"]
                    print(
                        f"{seconds:g} s | {code} | start {r['start_s']:.0f} s | tab 1 "
                        f"{r['tab1'][0]:.1f} / {r['tab1'][1]:.1f} s | drag p50 / p95 "
                        f"{_pct(lat, 50):.0f} / {_pct(lat, 95):.0f} ms | server p50 / p95 "
                        f"{_pct(srv, 50):.0f} / {_pct(srv, 95):.0f} ms | load "
                        f"{r['load_before']} -> {r['load_after']}",
                        flush=True,
                    )
            browser.close()
        return 0
    rows = []
    if args.table_only:
        args.pairs = []
    with tempfile.TemporaryDirectory() as tmp, sync_playwright() as p:
        browser = launch_chromium(p)
        for seconds in args.pairs:
            for code in args.codes:
                rows.append(run_pair(browser, seconds, code, trees[code], args.drags, Path(tmp)))
        browser.close()
    if args.keep is not None:
        import json

        kept = json.loads(args.keep.read_text()) if args.keep.exists() else []
        rows = kept + rows
        if not args.table_only:
            args.keep.write_text(json.dumps(rows))
    head = (
        "| pair | code | server start (read, features, warm-up) | by path, tab 1: image / "
        "band+path | tab 2: image / band+path | upload: files in | upload: image / band+path "
        "after files in | other tab's drag while a tab opens the pair: max / p50 (drags) "
        "| drag → new path p50 / p95 | server compute per edit p50 / p95 | load average "
        "1/5/15 min, before → after |\n|---|---|---|---|---|---|---|---|---|---|---|\n"
    )
    md = (
        "### Long pairs in the browser (`benchmarks/bench_app_long.py`, issue 13)\n\n"
        + head
        + "\n".join(_row(r) for r in rows)
        + "\n\n"
        f"Pairs of `benchmarks/long_pairs.py` at 120 fps (2 min: 14,400 frames; 10 min: "
        f"72,000), Chromium headless. *today* = the app at `{APP_BASELINE}` (credits pane "
        "fix carried over, else a pair opened by path gives no page), *now* = this "
        "checkout, each on its own `handsplice serve` in the same run, one after the "
        "other. Goals: first matrix ≤ 5 s after the files are in; drag p95 ≤ 150 ms "
        "(2 min), ≤ 300 ms (10 min). Drags: ±"
        f"{DRAG_PX} screen pixels of one matching point on the path at mid-take; the "
        "page's previews and trust layers recompute after each edit too (as for a user). "
        "Tab 1 of *now* adopts the server's warm-up alignment; tab 2 solves its own."
    )
    print(md)
    if not args.no_write:
        write_section("app_long", md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
