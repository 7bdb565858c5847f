"""Drag -> new path in the page on long pairs, this checkout beside a reference, in one run
(issue 13: p95 <= 150 ms on the 2-minute 120 fps pair, <= 300 ms on the 10-minute one).

Run: ``.venv/bin/python -m benchmarks.bench_app_drag_page [--pairs 120 600] [--drags 16]
[--before 5060c2f] [--pause-ms 0] [--no-write]``

Both codes serve the pair at once (``handsplice serve BODY HAND``, each its own server and
Chromium tab); each tab adopts its server's warm-up alignment, places a matching point on
the path at mid-take, zooms to 5 % of the take around it and waits for the page to settle;
then their drags take turns (a, b, b, a, ...), so a change of the machine's load falls on
both alike. A drag moves the point ``DRAG_PX`` screen pixels with the mouse; the latency is
mouse release -> the new path in an animation frame (``bench_app.WATCH``). Drags follow
each other as soon as the path is seen (``--pause-ms`` adds a pause): the previews, trust
assessments, tables of the last drag are then still due or running, as when a user drags
a point back and forth. Also: each edit's server time (its status line, waited for), and the
server process's CPU seconds per drag (``/proc``, every thread, the follow-up work included).

Writes the ``app_drag_page_long`` section of benchmarks/RESULTS.md with the load average
before and after (the machine is shared: compare the codes within the run).
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import tempfile
from contextlib import ExitStack
from pathlib import Path

from benchmarks._results import write_section
from benchmarks.bench_app import drag_once
from benchmarks.bench_app_long import (
    DRAG_PX,
    _env,
    _pct,
    baseline_app,
    loadavg,
    open_times,
    place_point,
)
from benchmarks.long_pairs import pair_files
from webapp.launch import launch_chromium, running_server

BEFORE = os.environ.get("HANDSPLICE_APP_BASELINE", "5060c2f")


def _cpu_s(pid: int) -> float:
    """CPU seconds (user + system, every thread) of process ``pid`` and its children."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return sum(int(v) for v in fields[11:15]) / os.sysconf("SC_CLK_TCK")


def _server_pid(port: int) -> int:
    """The pid of the process listening on ``port`` (its ``serve --port`` command line)."""
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            cmd = (proc / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if (
            b"serve" in cmd
            and b"--port" in cmd
            and cmd[cmd.index(b"--port") + 1] == str(port).encode()
        ):
            return int(proc.name)
    raise LookupError(f"no server on port {port}")


def _status_ms(page, revision: str | None, timeout_ms: int) -> float | None:
    """The server ms of the edit after ``revision`` (its status line, waited for)."""
    try:
        page.locator(f".hs-status span:not([data-revision='{revision}'])").wait_for(
            timeout=timeout_ms
        )
    except Exception:  # no status of its own: a refused edit, say
        return None
    found = re.search(r"([\d.]+) ms", page.locator(".hs-status span").inner_text())
    return float(found.group(1)) if found else None


def run(browser, seconds: float, codes: dict, drags: int, pause_ms: int, tmp: Path) -> dict:
    body, hand, _truth = pair_files(seconds)
    n = int(round(seconds * 120))
    out = {c: {"latency": [], "server": [], "cpu": [], "load_before": loadavg()} for c in codes}
    with ExitStack() as stack:
        pages = {}
        for name, tree in codes.items():
            log = stack.enter_context((tmp / f"serve-{name}-{seconds:g}.log").open("w+"))
            url, started = stack.enter_context(
                running_server(
                    str(body),
                    str(hand),
                    "--upload-dir",
                    str(tmp / f"up-{name}-{seconds:g}"),
                    log=log,
                    timeout=3600,
                    env=_env(tree),
                    cwd=tree,
                )  # fmt: skip
            )
            out[name]["start_s"] = started
            pid = _server_pid(int(url.rsplit(":", 1)[1].split("/")[0]))
            _img, _path, page = open_times(browser, url, n)
            x, y, per_px = place_point(page)
            pages[name] = (page, x, y, max(1.0, round(DRAG_PX * per_px)), pid)
        for page, *_ in pages.values():  # the point's follow-up work (preview, trust) ends
            page.wait_for_timeout(5000 if seconds < 300 else 30000)
        names = list(codes)
        for k in range(drags):
            for name in names if k % 2 == 0 else names[::-1]:
                page, x, y, step, pid = pages[name]
                page.bring_to_front()
                a, b = (y, y + step) if k % 2 == 0 else (y + step, y)
                rev = page.locator(".hs-status span").get_attribute("data-revision")
                cpu0 = _cpu_s(pid)
                out[name]["latency"].append(drag_once(page, x, a, b, timeout_ms=600_000))
                ms = _status_ms(page, rev, 120_000)
                if ms is not None:
                    out[name]["server"].append(ms)
                if pause_ms:
                    page.wait_for_timeout(pause_ms)
                out[name]["cpu"].append(_cpu_s(pid) - cpu0)
            print(k, {c: round(out[c]["latency"][-1]) for c in names}, loadavg(), flush=True)
        for page, *_ in pages.values():
            page.context.close()
    for name in codes:
        out[name]["load_after"] = loadavg()
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=float, nargs="+", default=[120.0])
    parser.add_argument("--drags", type=int, default=16)
    parser.add_argument("--before", default=BEFORE, help="the reference commit (the app then)")
    parser.add_argument("--pause-ms", type=int, default=0)
    parser.add_argument("--no-write", action="store_true")
    parser.add_argument(
        "--alone", action="store_true", help="this checkout's server only (no reference beside it)"
    )
    args = parser.parse_args(argv)
    from playwright.sync_api import sync_playwright

    codes = {"now": None} if args.alone else {args.before: baseline_app(args.before), "now": None}
    rows = []
    with tempfile.TemporaryDirectory() as tmp, sync_playwright() as p:
        browser = launch_chromium(p)
        for seconds in args.pairs:
            res = run(browser, seconds, codes, args.drags, args.pause_ms, Path(tmp))
            for code, r in res.items():
                lat, srv, cpu = r["latency"], r["server"], r["cpu"]
                row = (
                    f"| {seconds / 60:g} min | {code} | **{_pct(lat, 50):.0f} / "
                    f"{_pct(lat, 95):.0f}** / {max(lat):.0f} ms | {_pct(srv, 50):.0f} / "
                    f"{_pct(srv, 95):.0f} ms | {_pct(cpu, 50) * 1000:.0f} ms "
                    f"| {len(lat)} | {r['load_before']} → {r['load_after']} |"
                )
                print(row, flush=True)
                rows.append(row)
        browser.close()
    md = (
        "### Drag -> new path on long pairs, before and after (`benchmarks/bench_app_drag_page.py`, "
        "issue 13, drag150)\n\n"
        "| pair | code | drag → new path p50 / **p95** / max | server per edit p50 / p95 "
        "| server CPU per drag (median) | drags | load 1/5/15 min, before → after |\n"
        "|---|---|---|---|---|---|---|\n"
        + "\n".join(rows)
        + "\n\n"
        + (
            f"This checkout's server alone, {args.drags} drags, "
            if args.alone
            else f"Both codes' servers side by side, their drags taking turns, {args.drags} each, "
        )
        + f"{args.pause_ms} ms between drags"
        + ("; " if args.alone else f"; *{args.before}* = the app at that commit. ")
        + "Goals: p95 ≤ 150 ms (2 min), ≤ 300 ms (10 min)."
    )
    print(md)
    if not args.no_write:
        write_section("app_drag_page_long", md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
