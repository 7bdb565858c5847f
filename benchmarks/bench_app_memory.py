"""The app server's memory with a long pair open and one edit, without a browser (issue 13, mem10).

Run: ``python -m benchmarks.bench_app_memory [--seconds 600] [--base 5060c2f]``

A fresh child process does what ``handsplice serve BODY HAND`` does for one tab, through
``webapp.backend`` (the server's own calls, no Panel page): prepare the pair (read both
takes, features), the shared first alignment, the spliced take, the preview
(``Preview`` of body | hand | spliced: world joints of every frame, mannequins, one frame
rendered offscreen), the trust assessment; then one edit (a matching point at mid-take
on the path: ``backend.solve(previous=...)``), its spliced take, preview and trust. A
thread samples the resident memory (VmRSS) every 10 ms; the peak of each step and the
process's VmHWM are printed. The reference code runs the same child from ``git archive
BASE`` (engine and webapp), one after the other. Not measured here: the Panel document,
the matrix image's Bokeh models and the websocket (the browser bench
``bench_app_tenmin`` samples the real server).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

from benchmarks import long_pairs as LP

BASE = os.environ.get("HANDSPLICE_MEMORY_BASE", "5060c2f")

CHILD = r"""
import json, sys, threading, time
from pathlib import Path
def status(key):
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith(key):
                return int(line.split()[1]) / 1024
steps, order, cur = {}, [], [None]
def sampler():
    while True:
        r = status("VmRSS:")
        s = steps.get(cur[0])
        if s is not None and r > s["peak"]:
            s["peak"] = r
        time.sleep(0.01)
threading.Thread(target=sampler, daemon=True).start()
def step(name, fn):
    r = status("VmRSS:")
    steps[name] = {"start": r, "peak": r}
    order.append(name)
    cur[0] = name
    t0 = time.perf_counter()
    out = fn()
    steps[name]["wall"] = time.perf_counter() - t0
    steps[name]["end"] = status("VmRSS:")
    cur[0] = None
    return out
from webapp import backend
from engine.dtw import constraints as C
body, hand = Path(sys.argv[1]), Path(sys.argv[2])
prep = step("prepare", lambda: backend.prepare(body, hand, "right"))
n = prep.features.n
band, refine = C.BAND.default_for(n, prep.fps), C.REFINE_BAND.default_for(n, prep.fps)
sol = step("first alignment", lambda: backend.first_solution(prep, band, refine, []))
step("spliced take", lambda: backend.splice(prep, sol))
pv = step("preview", lambda: backend.preview_for(prep, sol))
from engine.io.session import VIEW_DEFAULTS
step("preview frame", lambda: backend.render_frame(prep, sol, n // 2, VIEW_DEFAULTS["camera"], False))
step("trust", lambda: backend.assess(prep, sol))
i = n // 2
j = min(int(round(float(sol.cache["engine"].map[i]))) + 24, prep.m_hand - 1)  # hand frames
sol2 = step("edit: solve", lambda: backend.solve(prep, band, refine, [(i, j, 0.0)], previous=sol))
step("edit: spliced take", lambda: backend.splice(prep, sol2))
step("edit: preview", lambda: backend.preview_for(prep, sol2))
step("edit: trust", lambda: backend.assess(prep, sol2))
print(json.dumps({"hwm": status("VmHWM:"), "order": order, "steps": steps}))
"""


def run(seconds: int, tree: Path | None) -> dict:
    body, hand, _ = LP.pair_files(seconds)
    root = str(tree) if tree is not None else str(LP.ROOT)
    env = dict(os.environ, PYTHONPATH=root, PYOPENGL_PLATFORM="egl")
    env["NUMBA_CACHE_DIR"] = str(Path(root) / ".numba_cache")
    out = subprocess.run(
        [sys.executable, "-c", CHILD, str(body), str(hand)],
        env=env,
        cwd=root,
        capture_output=True,
        text=True,
        check=False,
    )
    if out.returncode != 0:
        raise RuntimeError(out.stderr[-3000:])
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=int, default=600)
    ap.add_argument("--base", default=BASE)
    ap.add_argument("--only", choices=("before", "now"), default=None)
    args = ap.parse_args(argv)
    trees = [
        ("before", LP.baseline_tree(args.base, ("engine", "webapp", "sample_data"), name="appmem")),
        ("now", None),
    ]
    for label, tree in trees:
        if args.only and label != args.only:
            continue
        load = os.getloadavg()[0]
        r = run(args.seconds, tree)
        print(f"{label}: VmHWM {r['hwm']:.0f} MB (load {load:.1f} -> {os.getloadavg()[0]:.1f})")
        for name in r["order"]:
            s = r["steps"][name]
            print(
                f"  {name:20s} {s['start']:6.0f} -> peak {s['peak']:6.0f}, "
                f"end {s['end']:6.0f} MB ({s['wall']:.1f} s)"
            )
        print(json.dumps(r), flush=True)


if __name__ == "__main__":
    main()
