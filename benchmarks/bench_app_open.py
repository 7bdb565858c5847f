"""Opening a long pair in Chromium: first byte, first text, first matrix (issue 13, R3-1).

Run: ``.venv/bin/python -m benchmarks.bench_app_open [--by-path-only | --by-upload-only |
--by-link-only] CODE [CODE ...]`` where CODE is
``now`` (this checkout) or a commit (its ``engine``, ``webapp``, ``sample_data``), each on
its own ``handsplice serve`` one after the other in the same run.

For the 2-minute 120 fps pair of ``benchmarks.long_pairs`` and each code: the server's
start (``serve BODY HAND``: read and warm-up), then tab 1 and tab 2 (fresh browser
contexts) by path: seconds from navigation to the page's HTTP answer (``byte``), to the
header's text on screen (``text``), to the cost image (``image``) and to band and path
(``path``), as ``bench_app_long`` waits for them; then by upload (a server without a
pair): seconds until both files are checked (``in_s``) and from then to the image and to
band and path; then by link (R5-2: the same server, the pair uploaded again, the page's
*Link to this session* copied once the path is drawn and opened in a new tab of the same
browser): seconds from navigation to the image and to band and path (``link``; the
uploading tab stays open). ``--by-path-only`` / ``--by-upload-only`` / ``--by-link-only``
run one part. Prints one JSON line per code with the load average before and after;
writes nothing (the machine is shared: compare codes within one run).
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

from benchmarks import bench_app_long as app_long
from benchmarks.long_pairs import baseline_tree, pair_files
from webapp.launch import launch_chromium


def _tab(browser, url: str, n: int) -> tuple[dict, object]:
    context = app_long._context(browser)
    page = context.new_page()
    times: dict = {}
    t0 = time.monotonic()
    page.on(
        "response",
        lambda r: (
            times.setdefault("byte", time.monotonic() - t0)
            if r.url.rstrip("/") == url.rstrip("/")
            else None
        ),
    )
    page.evaluate(f"location.href = {url!r}")
    while True:  # the header (in Panel's shadow roots: a locator, not innerText)
        try:
            if page.get_by_text("HandSplice", exact=True).count():
                break
        except Exception:  # noqa: BLE001 - still navigating
            pass
        time.sleep(0.05)
    times["text"] = time.monotonic() - t0
    times["image"] = app_long._wait(page, app_long.IMAGE_OF, n) - t0
    times["path"] = app_long._wait(page, app_long.PATH_OF, n) - t0
    return times, page


def by_link(browser, url: str, body: Path, hand: Path, n: int) -> dict:
    """Upload the pair, copy the page's share link and open it in a new tab: seconds from
    that tab's navigation to the image and to band and path (R5-2)."""
    context = app_long._context(browser)
    page = context.new_page()
    page.goto(url)
    app_long.demo_n(page)
    page.locator(".hs-upload-body input[type=file]").set_input_files(str(body))
    page.locator(".hs-upload-hand input[type=file]").set_input_files(str(hand))
    for which in ("body", "hand"):
        page.locator(f".hs-upload-{which} .filepond--item[data-hs-verdict='ok']").wait_for(
            timeout=1_800_000
        )
    try:
        app_long._wait(page, app_long.PATH_OF, n, timeout=300)
    except TimeoutError:  # the uploaded pair never opened: say so, with the page as it is
        shot = Path(tempfile.gettempdir()) / "bench_app_open_by_link.png"
        page.screenshot(path=str(shot), full_page=True)
        context.close()
        return {"error": f"the uploaded pair's path never came (page: {shot})"}
    box = page.locator(".hs-share-url input")
    deadline = time.monotonic() + 600
    while "body=" not in (link := box.input_value()) and time.monotonic() < deadline:
        time.sleep(0.2)  # the link follows the path once it is drawn
    tab = context.new_page()
    t0 = time.monotonic()
    tab.evaluate(f"location.href = {link!r}")
    t_image = app_long._wait(tab, app_long.IMAGE_OF, n) - t0
    t_path = app_long._wait(tab, app_long.PATH_OF, n) - t0
    context.close()
    return {"image_s": t_image, "path_s": t_path, "link": link.split("?", 1)[-1][:300]}


def main(argv=None) -> int:
    args = list(argv if argv is not None else sys.argv[1:])
    by_path_only = "--by-path-only" in args  # no upload server (a shorter run)
    by_upload_only = "--by-upload-only" in args  # no server of the pair by path
    by_link_only = "--by-link-only" in args  # only the reopening of an upload by its link
    codes = [a for a in args if not a.startswith("--")] or ["now"]
    from playwright.sync_api import sync_playwright

    seconds = 120.0
    body, hand, _ = pair_files(seconds)
    n = int(round(seconds * 120))
    with tempfile.TemporaryDirectory() as tmp, sync_playwright() as p:
        browser = launch_chromium(p)
        out_rows: list[dict] = []
        for code in codes:
            tree = (
                None
                if code == "now"
                else baseline_tree(code, ("engine", "webapp", "sample_data"), name="open-" + code)
            )
            out: dict = {"code": code, "load_before": app_long.loadavg()}
            up = Path(tmp) / f"up-{code}-{len(out_rows)}"
            if not (by_upload_only or by_link_only):
                with app_long.serve(tree, str(body), str(hand), "--upload-dir", str(up)) as (
                    url,
                    started,
                ):
                    out["start_s"] = started
                    out["tab1"], tab1 = _tab(browser, url, n)
                    out["tab2"], tab2 = _tab(browser, url, n)
                    tab1.context.close()
                    tab2.context.close()
            if not by_path_only:
                with app_long.serve(tree, "--upload-dir", str(up)) as (url, _):
                    if not by_link_only:
                        out["upload"] = app_long.by_upload(browser, url, body, hand, n)
                    if not by_upload_only:
                        out["link"] = by_link(browser, url, body, hand, n)
            out["load_after"] = app_long.loadavg()
            out_rows.append(out)
            print(json.dumps(out), flush=True)
        browser.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
