"""Bytes the server sends the page per matching-point edit on a long pair (issue 13).

Run: ``.venv/bin/python -m benchmarks.bench_app_bytes [--pairs 120] [--drags 6]
[--codes today now] [--no-write]``

For each pair (``benchmarks.long_pairs.pair_files``: 2 or 10 minutes at 120 fps) and
code, each on its own ``handsplice serve BODY HAND`` in the same run: *today* (the app at
``BYTES_BASELINE``, where this work began) and *now* (this checkout). Chromium opens the
pair; a matching point is placed on the path at mid-take and dragged ``--drags`` times by
±12 screen pixels on the whole-take view, each drag once the last one's path is drawn:

* **websocket bytes per edit**: every frame the page received (Chromium's DevTools
  protocol via Playwright) from the first release until the page has been quiet for 5 s
  (paths, band, trust layers and previews of every edit arrived), divided by the edits:
  all messages (lines, tables, status, the preview's PNGs);
* **line bytes**: the bytes of the arrays the page then holds in the band, both paths and
  the uncertain region (``hs-band-source``, ``hs-path-source``, ``hs-other-path``,
  ``hs-uncertain-region-source``): what those sources cost each edit, and their vertices.

Writes the ``app_bytes`` section of benchmarks/RESULTS.md. ``--offline`` measures only
the band and paths' arrays of one edit, without a browser or server (the 10-minute pair's
figure: today's app there needs minutes per edit on a loaded machine).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks._results import write_section
from benchmarks.long_pairs import baseline_tree, pair_files
from webapp.launch import PAGE_HELPERS, launch_chromium, running_server

ROOT = Path(__file__).resolve().parents[1]

#: the app before the band and path were thinned (this work's starting commit)
BYTES_BASELINE = os.environ.get("HANDSPLICE_BYTES_BASELINE", "6b1b359")
LINES = ("hs-band-source", "hs-path-source", "hs-other-path", "hs-uncertain-region-source")
DRAG_PX = 12
QUIET_S = 5.0

LINE_BYTES = """
(names) => {
  let bytes = 0, vertices = 0;
  for (const name of names) {
    const src = Bokeh.documents[0].get_model_by_name(name);
    if (!src) continue;
    for (const col of Object.values(src.data)) {
      bytes += col.byteLength ?? (col.length * 8);
    }
    vertices += (src.data.x ?? []).length;
  }
  return [bytes, vertices];
}
"""

READY = """
(n) => {
  if (!window.Bokeh || !Bokeh.documents.length) return false;
  const band = Bokeh.documents[0].get_model_by_name('hs-band-source');
  const path = Bokeh.documents[0].get_model_by_name('hs-path-source');
  return !!(band && band.data.x.length && band.data.x[band.data.x.length - 1] === n - 1
            && path && path.data.x.length);
}
"""


def _env(tree: Path | None) -> dict:
    env = dict(os.environ)
    if tree is not None:
        env["PYTHONPATH"] = str(tree)
        env["NUMBA_CACHE_DIR"] = str(tree / ".numba_cache")
    return env


def _quiet(counter: dict, since: float, timeout: float = 600.0) -> None:
    """Wait until no websocket frame has come for QUIET_S seconds (after ``since``)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        time.sleep(0.1)
        if time.monotonic() - max(counter["last"], since) > QUIET_S:
            return
    raise TimeoutError("the page never went quiet")


def measure(browser, url: str, n: int, drags: int) -> dict:
    context = browser.new_context(viewport={"width": 1400, "height": 1100})
    context.set_default_timeout(900_000)
    page = context.new_page()
    counter = {"bytes": 0, "last": time.monotonic()}

    def frame(payload):
        counter["bytes"] += len(payload)  # str frames: ASCII JSON, one byte a character
        counter["last"] = time.monotonic()

    page.on("websocket", lambda ws: ws.on("framereceived", frame))
    page.goto(url)
    page.wait_for_function(READY, arg=n, timeout=900_000)
    page.evaluate(PAGE_HELPERS)
    _quiet(counter, time.monotonic())
    path = page.evaluate("hs.cols('hs-path-source', ['x', 'y'])")
    k = len(path["x"]) // 2
    x, y = int(path["x"][k]), float(round(path["y"][k]))
    rev = _revision(page)
    page.mouse.click(*page.evaluate("([x, y]) => hs.xy(x, y)", [x, y]))
    deadline = time.monotonic() + 600
    while _revision(page) <= rev:
        if time.monotonic() > deadline:
            raise TimeoutError("no new path after the click")
        time.sleep(0.05)
    _quiet(counter, time.monotonic())
    per_px = page.evaluate(
        "() => { const v = Bokeh.index.find_one(hs.model('hs-cost-figure'));"
        " return (hs.model('hs-y-range').end - hs.model('hs-y-range').start)"
        " / v.frame.bbox.height; }"
    )
    step = max(1.0, round(DRAG_PX * per_px))
    line_bytes, vertices = [], []
    before = counter["bytes"]
    for k in range(drags):
        a, b = (y, y + step) if k % 2 == 0 else (y + step, y)
        start = page.evaluate("([x, y]) => hs.xy(x, y)", [x, a])
        end = page.evaluate("([x, y]) => hs.xy(x, y)", [x, b])
        rev = _revision(page)
        page.mouse.move(*start)
        page.mouse.down()
        page.mouse.move(*end, steps=4)
        page.mouse.up()
        deadline = time.monotonic() + 600
        while _revision(page) <= rev:  # each edit solved and drawn before the next
            if time.monotonic() > deadline:
                raise TimeoutError("no new path after a drag")
            time.sleep(0.05)
        lb, nv = page.evaluate(LINE_BYTES, list(LINES))
        line_bytes.append(lb)
        vertices.append(nv)
    # the trust layers and previews of the last edits arrive after their paths: everything
    # received until the page is quiet, shared by the edits
    _quiet(counter, time.monotonic())
    ws = (counter["bytes"] - before) / drags
    context.close()
    return {"ws": [ws], "lines": line_bytes, "vertices": vertices}


def _revision(page) -> int:
    return int(page.locator(".hs-status span").get_attribute("data-revision"))


def run(browser, seconds: float, code: str, tree: Path | None, drags: int, tmp: Path) -> dict:
    body, hand, _ = pair_files(seconds)
    n = int(round(seconds * 120))
    log_path = Path(tempfile.gettempdir()) / "handsplice-bench-app-bytes.log"
    with (
        log_path.open("w+") as log,
        running_server(
            str(body),
            str(hand),
            "--upload-dir",
            str(tmp / f"up-{code}"),
            log=log,
            timeout=1800,
            env=_env(tree),
            cwd=tree,
        ) as (url, _),
    ):
        out = measure(browser, url, n, drags)
    out.update(pair=f"{seconds / 60:g} min", code=code)
    print(out, flush=True)
    return out


def offline(seconds: float) -> dict:
    """Without a browser: the band and both paths' arrays an edit of the ``seconds`` pair
    sends now (``CostMatrixView`` on the whole-take view) and one vertex per frame or path
    step (as before thinning, same dtypes)."""
    from webapp import config
    from webapp.state import Session
    from webapp.views.cost_matrix import CostMatrixView

    body, hand, _ = pair_files(seconds)
    local = config.local_pair(body, hand, "right")
    with tempfile.TemporaryDirectory() as up:
        cfg = config.AppConfig(
            sample_dir=ROOT / "sample_data",
            upload_dir=Path(up),
            default_sample=local.name,
            local=local,
        )
        s = Session(cfg)
        s.load_sample(local.name)
        view = CostMatrixView(s)
    sol = s.solution
    sources = (view.band_source, view.path_source, view.other_path_source)
    now = sum(np.asarray(v).nbytes for src in sources for v in src.data.values())
    before = sol.pass1.band.n * 12 + (len(sol.pass1.path) + len(sol.pass2.path)) * 8
    return {"pair": f"{seconds / 60:g} min", "now": now, "before": before, "n": s.n}


def _mb(v) -> str:
    return f"{np.median(v) / 1e6:.3f} MB"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=float, nargs="+", default=[120.0])
    parser.add_argument("--codes", nargs="+", default=["today", "now"])
    parser.add_argument("--drags", type=int, default=6)
    parser.add_argument("--no-write", action="store_true")
    parser.add_argument(
        "--offline",
        action="store_true",
        help="no browser: print the band and paths' bytes per edit of each pair, now and "
        "one vertex per frame",
    )
    args = parser.parse_args(argv)
    if args.offline:
        for seconds in args.pairs:
            r = offline(seconds)
            print(
                f"{r['pair']} ({r['n']:,} body frames): band and paths {r['now'] / 1e6:.3f} MB "
                f"per edit, one vertex per frame {r['before'] / 1e6:.3f} MB "
                f"(×{r['now'] / r['before']:.3f})"
            )
        return 0
    from playwright.sync_api import sync_playwright

    trees = {"now": None}
    if "today" in args.codes:
        trees["today"] = baseline_tree(
            BYTES_BASELINE, ("engine", "webapp", "sample_data"), name="app-bytes"
        )
    rows = []
    with tempfile.TemporaryDirectory() as tmp, sync_playwright() as p:
        browser = launch_chromium(p)
        for seconds in args.pairs:
            for code in args.codes:
                rows.append(run(browser, seconds, code, trees[code], args.drags, Path(tmp)))
        browser.close()
    lines = []
    for r in rows:
        lines.append(
            f"| {r['pair']} | {r['code']} | {_mb(r['ws'])} | {_mb(r['lines'])} "
            f"| {int(np.median(r['vertices'])):,} | {len(r['lines'])} |"
        )
    ratio = ""
    for pair in {r["pair"] for r in rows}:
        by = {r["code"]: r for r in rows if r["pair"] == pair}
        if {"today", "now"} <= by.keys():
            ratio += (
                f" {pair}: websocket bytes per edit ×"
                f"{np.median(by['now']['ws']) / np.median(by['today']['ws']):.3f}, line bytes ×"
                f"{np.median(by['now']['lines']) / np.median(by['today']['lines']):.4f}."
            )
    md = (
        "### Bytes per edit on long pairs (`benchmarks/bench_app_bytes.py`, issue 13)\n\n"
        "| pair | code | websocket bytes per edit (all, mean) | band, paths, region arrays per edit "
        "| their vertices | edits |\n|---|---|---|---|---|---|\n" + "\n".join(lines) + "\n\n"
        f"*today* = the app at `{BYTES_BASELINE}`, *now* = this checkout, each on its own "
        "`handsplice serve BODY HAND` in the same run, Chromium headless 1400×1100, the "
        f"whole-take view; one matching point dragged ±{DRAG_PX} screen pixels per edit; "
        "websocket bytes: every frame received from the first release until 5 s of quiet, "
        "divided by the edits (lines, status, tables, trust layers, the preview's PNGs)." + ratio
    )
    print(md)
    if not args.no_write:
        write_section("app_bytes", md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
