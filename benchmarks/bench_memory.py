"""Where the memory of a long splice goes (issue 13, mem10), beside the reference code.

Run: ``python -m benchmarks.bench_memory [--seconds 120 600] [--base 5060c2f] [--no-write]``

Each run is a fresh child process running ``handsplice splice BODY HAND -o OUT --report R``
in-process (``engine.cli.main``), with a thread sampling its resident memory
(``/proc/self/status`` VmRSS) every 10 ms. The CLI's own stage lines (features, pass 1,
pass 2, merge, transfer, trust, write) and the reading of both takes mark the stages; for
each stage the table gives the resident memory when it began and the highest sample while it
ran. Peak = VmHWM of the child (the whole process: interpreter, numba, both takes). The
reference code runs the same child from ``git archive BASE`` (engine only), one after the
other in the same run; the two output BVH files are compared byte for byte.

The pairs are ``benchmarks.long_pairs.pair_files`` (2- and 10-minute 120 fps pairs).
Before the timed child runs, one untimed child of each code splices a 600-frame crop so the
numba caches are warm (the peak of a cold first run includes compilation).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks import long_pairs as LP

#: main when the memory work began (issue 13, mem10)
BASE = os.environ.get("HANDSPLICE_MEMORY_BASE", "5060c2f")

CHILD = r"""
import json, sys, threading, time
state = {"stage": "start", "rows": [], "peak": 0}
def rss_mb():
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
def hwm_mb():
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
stages = {}
order = []
def enter(name):
    r = rss_mb()
    state["stage"] = name
    if name not in stages:
        order.append(name)
        stages[name] = {"start": r, "peak": r, "t0": time.perf_counter()}
def leave(name):
    s = stages.get(name)
    if s is not None:
        s["end"] = rss_mb()
        s["wall"] = time.perf_counter() - s["t0"]
    state["stage"] = "between"
def sampler():
    while True:
        r = rss_mb()
        s = stages.get(state["stage"])
        if s is not None and r > s["peak"]:
            s["peak"] = r
        time.sleep(0.01)
threading.Thread(target=sampler, daemon=True).start()
import engine.cli as cli
import engine.cli.splice as cs
read = cli.load_take
def load_take(path):
    enter("reading")
    try:
        return read(path)
    finally:
        s = stages["reading"]
        s["end"] = rss_mb()
        s["wall"] = time.perf_counter() - s["t0"]
cli.load_take = load_take
class Progress(cs._Progress):
    def __call__(self, stage, fraction):
        if fraction <= 0.0:
            enter(stage)
        elif fraction >= 1.0:
            leave(stage)
cs._Progress = Progress
t0 = time.perf_counter()
code = cli.main(["splice", *sys.argv[1:], "--quiet"])
wall = time.perf_counter() - t0
print(json.dumps({"code": code, "wall": wall, "hwm": hwm_mb(), "order": order, "stages": stages}))
"""

WARM = r"""
import sys
from engine.io.bvh import read_bvh
from engine.splice import pipeline as P
from engine.trust import assess_splice
body, hand = read_bvh(sys.argv[1]), read_bvh(sys.argv[2])
r = P.splice(body.frames(0, 600), hand.frames(0, 600))
assess_splice(r.features, r.alignment)
print("{}")
"""


def _run(code: str, args: list[str], tree: Path | None) -> dict:
    env = dict(os.environ)
    root = str(tree) if tree is not None else str(LP.ROOT)
    env["PYTHONPATH"] = root
    env["NUMBA_CACHE_DIR"] = str(Path(root) / ".numba_cache")  # each tree's own (warm) cache
    out = subprocess.run(
        [sys.executable, "-c", code, *args],
        env=env,
        cwd=root,
        capture_output=True,
        text=True,
        check=False,
    )
    if out.returncode != 0:
        raise RuntimeError(out.stderr[-3000:])
    return json.loads(out.stdout.strip().splitlines()[-1])


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()[:12]


def measure(
    seconds: int, base: str, folder: Path, only: str | None = None, base_tree: Path | None = None
) -> list[dict]:
    body, hand, _ = LP.pair_files(seconds)
    before = base_tree or LP.baseline_tree(base, ("engine",), name="mem")
    trees = [("before", before), ("now", None)]
    trees = [t for t in trees if only in (None, t[0])]
    rows = []
    for _label, tree in trees:
        _run(WARM, [str(body), str(hand)], tree)
    for label, tree in trees:
        out = folder / f"{label}-{seconds}.bvh"
        load = os.getloadavg()[0]
        r = _run(
            CHILD, [str(body), str(hand), "-o", str(out), "--report", str(out) + ".json"], tree
        )
        r.update(label=label, seconds=seconds, load=(load, os.getloadavg()[0]))
        r["digest"] = _digest(out)
        rows.append(r)
        print(json.dumps(r), flush=True)
    return rows


def table(rows: list[dict]) -> str:
    names = []
    for r in rows:
        for n in r["order"]:
            if n not in names:
                names.append(n)
    head = "| pair | code | peak (VmHWM) | wall | " + " | ".join(names) + " | load | output |"
    lines = [head, "|" + "---|" * (len(names) + 6)]
    for r in rows:
        cells = []
        for n in names:
            s = r["stages"].get(n)
            cells.append("–" if s is None else f"{s['start']:.0f} → **{s['peak']:.0f}**")
        lines.append(
            f"| {r['seconds'] // 60} min | {r['label']} | **{r['hwm']:.0f} MB** | {r['wall']:.0f} s | "
            + " | ".join(cells)
            + f" | {r['load'][0]:.1f} → {r['load'][1]:.1f} | `{r['digest']}` |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=int, nargs="+", default=[120, 600])
    ap.add_argument("--base", default=BASE)
    ap.add_argument("--out", default=None, help="folder for the rows (JSON) and outputs")
    ap.add_argument("--only", choices=("before", "now"), default=None)
    ap.add_argument(
        "--base-tree",
        type=Path,
        default=None,
        help="a checkout of BASE to run as it is, with its own warm .numba_cache (a fresh "
        "git archive compiles every kernel first: minutes on a loaded machine)",
    )
    ap.add_argument("--table", default=None, help="print the table of these rows.json files")
    args = ap.parse_args(argv)
    if args.table:
        rows = [r for f in args.table.split(",") for r in json.loads(Path(f).read_text())]
        print(table(rows))
        return
    folder = Path(args.out or tempfile.mkdtemp(prefix="bench-memory-"))
    folder.mkdir(parents=True, exist_ok=True)
    rows = []
    for s in args.seconds:
        rows += measure(s, args.base, folder, args.only, args.base_tree)
        (folder / "rows.json").write_text(json.dumps(rows, indent=1))
    print(table(rows))
    print(time.strftime("%H:%M"), os.getloadavg())


if __name__ == "__main__":
    main()
