"""The app's outputs of a long pair (issue 13): the first preview render, and another
tab's clicks while a long BVH download is prepared. Today's code beside this checkout,
in the same run.

Run: ``.venv/bin/python -m benchmarks.bench_long_outputs [--seconds 120] [--codes today now]
[--no-browser] [--no-write]``

The pair: ``benchmarks.long_pairs.pair_files`` (2 minutes at 120 fps, 14,400 frames).
Codes: *today* (``engine``, ``webapp`` and ``sample_data`` at ``BASELINE``, the commit
this work started from) and *now* (this checkout).

* **in process** (a fresh interpreter per code, ``long_pairs.run_child``): the pair is
  prepared and aligned (pass-1 band 3 s, pass 2 1 s), pyrender imported (the server
  does that once; reported apart); then the seconds of the first preview (the three
  panels and the hands' close-up, as the page asks) after opening (splice, meshes and
  framing of three 14,400-frame takes), and after an edit (a matching point: a new
  alignment); and the spliced BVH's bytes made on a thread, as the app does, while this
  interpreter's main thread wakes every 10 ms (a stand-in for the event loop answering
  other tabs): how late its wake-ups come (max, p95) while the file is made.
* **browser** (one ``handsplice serve BODY HAND`` per code, Chromium): tab A opens the
  long pair, tab B the demo pair; B adds matching points with mouse clicks, one after
  another; B's click → new path round trips with A idle, then while A's "Spliced BVH"
  button is preparing its file (until A's line says the file is made).

Writes the ``long_outputs`` section of benchmarks/RESULTS.md with the load averages.
"""

from __future__ import annotations

import argparse
import os
import re
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks._results import write_section
from benchmarks.long_pairs import baseline_tree, pair_files, run_child

#: the code before this work (the branch's start)
BASELINE = os.environ.get("HANDSPLICE_OUTPUTS_BASELINE", "d94916c")

CHILD = r"""
import json, sys, threading, time
import numpy as np
from webapp import backend, config
t = time.perf_counter(); import pyrender; pyrender_s = time.perf_counter() - t
# as the server's warm-up: the demo pair aligned and one preview frame rendered (numba
# kernels loaded, the OpenGL context open), so neither code pays for them below
name = config.demo_sample_name(config.SAMPLE_DIR)
demo = next(q for q in config.load_samples(config.SAMPLE_DIR) if q.name == name)
d = backend.prepare(demo.body, demo.hand, demo.side)
backend.render_closeup(d, backend.solve(d, "3s", "1s", []), 0)
body, hand, seconds = sys.argv[1], sys.argv[2], float(sys.argv[3])
p = backend.prepare(body, hand, "right")
sol = backend.solve(p, "3s", "1s", [])
def first_preview(s):
    t = time.perf_counter()
    backend.render_frame(p, s, 0, "three-quarter", False, (680, 240))
    backend.render_closeup(p, s, 0, (330, 300))
    return time.perf_counter() - t
open_s = first_preview(sol)
mid = p.n // 2
y = int(round(float(sol.warp[mid])))
sol2 = backend.solve(p, "3s", "1s", [(mid, y, 0)], previous=sol)
edit_s = first_preview(sol2)
t = time.perf_counter(); later = backend.render_frame(p, sol2, mid, "three-quarter", False, (680, 240)); next_s = time.perf_counter() - t
spliced = backend.splice(p, sol2)
out = {}
def make():
    t = time.perf_counter(); out["bytes"] = len(backend.bvh_bytes(spliced)); out["bvh_s"] = time.perf_counter() - t
def wake_ups(busy):
    late = []
    while busy():
        t = time.perf_counter(); time.sleep(0.010); late.append(time.perf_counter() - t - 0.010)
    return late
end = time.perf_counter() + 3.0
idle = wake_ups(lambda: time.perf_counter() < end)  # nothing else running: the machine's load
job = threading.Thread(target=make)
job.start()
late = wake_ups(job.is_alive)
job.join()
print(json.dumps(dict(pyrender_s=pyrender_s, open_s=open_s, edit_s=edit_s, next_s=next_s,
    late_max_ms=1000 * max(late), late_p95_ms=1000 * float(np.percentile(late, 95)),
    idle_max_ms=1000 * max(idle), idle_p95_ms=1000 * float(np.percentile(idle, 95)),
    bvh_s=out["bvh_s"], bvh_mb=out["bytes"] / 1e6, n=p.n)))
"""


def loadavg() -> str:
    return "/".join(f"{v:.1f}" for v in os.getloadavg())


def trees(codes) -> dict:
    return {
        code: None
        if code == "now"
        else baseline_tree(BASELINE, ("engine", "webapp", "sample_data"), name="outputs-baseline")
        for code in codes
    }


def in_process(seconds: float, code: str, tree: Path | None) -> dict:
    body, hand, _ = pair_files(seconds)
    before = loadavg()
    row = run_child(CHILD, str(body), str(hand), f"{seconds:g}", tree=tree)
    row.update(code=code, load=f"{before} → {loadavg()}")
    print(row, flush=True)
    return row


# ------------------------------------------------------------------ browser

HAS_PATH = "() => Bokeh.documents[0]?.get_model_by_name('hs-path-source')?.data.x?.length > 0"


def _page(context, url: str):
    from webapp.launch import PAGE_HELPERS

    page = context.new_page()
    page.set_default_timeout(900_000)
    page.goto(url, timeout=900_000)
    page.wait_for_function(HAS_PATH, timeout=900_000)
    page.evaluate(PAGE_HELPERS)
    return page


def _revision(page) -> int:
    return int(page.locator(".hs-status span").get_attribute("data-revision"))


def _click(page, k: int) -> float:
    """A matching point added with a click (the k-th, on the matrix's diagonal band); the
    seconds to the server's new path in the page."""
    n = page.evaluate("hs.frames()")
    f = 0.1 + 0.8 * ((k * 0.37) % 1.0)
    x, y = round(n * f), round(n * f * 2 / 3)
    rev = _revision(page)
    xy = page.evaluate("([x, y]) => hs.xy(x, y)", [x, y])
    t0 = time.monotonic()
    page.mouse.click(*xy)
    while _revision(page) <= rev:
        if time.monotonic() - t0 > 300:
            raise TimeoutError("no new path within 300 s")
        page.wait_for_timeout(10)
    return time.monotonic() - t0


def _line(page) -> str:
    status = page.locator(".hs-download-status")
    if not status.count() or not status.first.is_visible():
        return ""
    return status.first.evaluate(
        "e => [...(e.shadowRoot ? e.shadowRoot.children : []), ...e.children]"
        ".filter(c => c.tagName !== 'STYLE' && c.tagName !== 'LINK')"
        ".map(c => c.innerText).join(' ')"
    )


def _edit_preview(page, k: int) -> dict:
    """A matching point added on A's path with a click (at 30 %, 50 %, 70 % of the take):
    seconds from the click to the new path, and to the preview's first render of the new
    alignment on screen, with the render time the page states."""
    page.bring_to_front()
    info = page.locator(".hs-preview-info span")
    before = info.inner_text()
    path = page.evaluate("hs.cols('hs-path-source', ['x', 'y'])")
    j = int(len(path["x"]) * (0.3 + 0.2 * k))
    rev = _revision(page)
    xy = page.evaluate("([x, y]) => hs.xy(x, y)", [path["x"][j], path["y"][j]])
    t0 = time.monotonic()
    page.mouse.click(*xy)
    while _revision(page) <= rev:
        page.wait_for_timeout(10)
    t_path = time.monotonic() - t0
    while info.inner_text() == before:  # the preview follows edits: a new render comes
        if time.monotonic() - t0 > 600:
            raise TimeoutError("no preview after the edit within 600 s")
        page.wait_for_timeout(20)
    t_image = time.monotonic() - t0
    ms = re.search(r"rendered in (\d+) ms", info.inner_text())
    return {"path_s": t_path, "image_s": t_image, "render_ms": float(ms.group(1)) if ms else -1}


def browser_row(browser, seconds: float, code: str, tree: Path | None, tmp: Path) -> dict:
    from benchmarks.bench_app_long import serve
    from webapp.config import SAMPLE_DIR, demo_sample_name

    body, hand, _ = pair_files(seconds)
    demo = demo_sample_name(SAMPLE_DIR)
    row: dict = {"code": code, "load_before": loadavg()}
    with serve(tree, str(body), str(hand), "--upload-dir", str(tmp / f"up-{code}")) as (url, _):
        context = browser.new_context(
            viewport={"width": 1300, "height": 1000}, accept_downloads=True
        )
        a = _page(context, url)
        b = _page(context, url + f"?sample={demo}")
        b.wait_for_timeout(1000)
        idle = [_click(b, k) for k in range(5)]
        button = a.locator(".hs-download-bvh button")
        button.scroll_into_view_if_needed()
        during, t0 = [], time.monotonic()
        with a.expect_download(timeout=900_000) as info:
            button.click()
            k = 5
            while "KiB in" not in (text := _line(a)):
                during.append(_click(b, k))
                k += 1
        row["bvh_line"] = text
        row["bvh_wall_s"] = time.monotonic() - t0
        path = tmp / f"{code}.bvh"
        info.value.save_as(path)
        row["bvh_mb"] = path.stat().st_size / 1e6
        row["preview"] = [_edit_preview(a, k) for k in range(3)]
        row.update(idle=idle, during=during, load_after=loadavg())
        context.close()
    print(row, flush=True)
    return row


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=120.0)
    parser.add_argument("--codes", nargs="+", default=["today", "now"])
    parser.add_argument("--no-browser", action="store_true")
    parser.add_argument("--no-write", action="store_true")
    args = parser.parse_args(argv)
    code_trees = trees(args.codes)
    rows = [in_process(args.seconds, c, code_trees[c]) for c in args.codes]
    clicks = []
    if not args.no_browser:
        from playwright.sync_api import sync_playwright

        from webapp.launch import launch_chromium

        with tempfile.TemporaryDirectory() as tmp, sync_playwright() as p:
            browser = launch_chromium(p)
            clicks = [
                browser_row(browser, args.seconds, c, code_trees[c], Path(tmp)) for c in args.codes
            ]
            browser.close()
    text = _markdown(args.seconds, rows, clicks)
    print(text)
    if not args.no_write:
        write_section("long_outputs", text)
    return 0


def _ms(values, q=None) -> str:
    if not values:
        return "–"
    v = max(values) if q is None else float(np.percentile(values, q))
    return f"{1000 * v:.0f}"


def _markdown(seconds: float, rows: list[dict], clicks: list[dict]) -> str:
    n = rows[0]["n"] if rows else 0
    out = [
        "## The app's outputs of a long pair: first preview, BVH download (issue 13, longapp3)\n",
        f"`python -m benchmarks.bench_long_outputs`: a {seconds / 60:g}-minute pair at 120 fps "
        f"({n} frames), today's code (`{BASELINE}`) beside this checkout, same run.\n",
        "| code | first preview after opening | first preview after an edit | next frame "
        "| (pyrender import, once) | spliced BVH made | main thread's 10 ms wake-ups meanwhile: "
        "late max / p95 | the same for 3 s with nothing else running | load 1/5/15, before → "
        "after |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        out.append(
            f"| {r['code']} | **{r['open_s']:.2f} s** | **{r['edit_s']:.2f} s** | {r['next_s']:.2f} s "
            f"| {r['pyrender_s']:.1f} s | {r['bvh_s']:.1f} s ({r['bvh_mb']:.0f} MB) "
            f"| **{r['late_max_ms']:.0f} / {r['late_p95_ms']:.0f} ms** "
            f"| {r['idle_max_ms']:.0f} / {r['idle_p95_ms']:.0f} ms | {r['load']} |"
        )
    if clicks:
        out += [
            "",
            "In Chromium (one server per code): tab B's click → new path (demo pair) while tab A "
            "on the long pair is idle, and while A's *Spliced BVH* download is being prepared.\n",
            "| code | B idle: p50 / max | B while A's BVH is prepared: p50 / max (clicks) "
            "| A's line at the end | A: edit → new path / → preview of it on screen "
            "(render as the page states), 3 edits | load 1/5/15, before → after |",
            "|---|---|---|---|---|---|",
        ]
        for r in clicks:
            edits = ", ".join(
                f"{e['path_s']:.1f} / **{e['image_s']:.1f} s** ({e['render_ms'] / 1000:.1f} s)"
                for e in r["preview"]
            )
            out.append(
                f"| {r['code']} | {_ms(r['idle'], 50)} / {_ms(r['idle'])} ms "
                f"| **{_ms(r['during'], 50)} / {_ms(r['during'])} ms** ({len(r['during'])}) "
                f"| {r['bvh_line']} | {edits} | {r['load_before']} → {r['load_after']} |"
            )
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    raise SystemExit(main())
