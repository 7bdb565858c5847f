"""CPU per drag edit in one process: ``align_passes`` with the previous alignment, a
reference tree beside this checkout (issue 13, drag31).

Run: ``.venv/bin/python -m benchmarks.bench_drag_cpu [--ref d84f2f0] [--edits 8]
[--rounds 2] [--pairs mug,synthetic] [--now COMMIT]`` (prints a Markdown table; RESULTS.md's ``drag31``
section was written from it by hand, with the load).

Pairs (2 minutes at 120 fps):

* ``mug``: LAFAN1 ``multipleActions1`` resampled to 120 fps, its first 120 s, with
  ManipNet's ``mug1_rightHand`` (``tests/conftest.py``'s ``long_pair``): a hand take
  without a forearm, whose re-solves are forward-only (a fresh solve's path).
* ``synthetic``: ``long_pairs.pair_files(120)`` (a re-timed hand take with fingers).
* ``mug+2``: the mug pair with a second point at two thirds of the overlap, kept, while
  the one at a third is dragged (the rows after the kept point can settle).

Each code runs in its own child process (``long_pairs.run_child``; the reference from
``git archive``), the two taking turns ``--rounds`` times. In a child: the pair is
prepared, aligned once with a lone matching point at mid-overlap (tolerance 0), edited
twice (warm-up: kernels compile), then ``--edits`` edits moving the point to ``y ± 3``
hand frames in turn, each timed (process time of all threads, and wall). This checkout's
child also reports the cells each solver computed and checks the last edit against a
fresh solve (path and cost of both passes).
"""

from __future__ import annotations

import argparse
import os
import statistics

from benchmarks import long_pairs as LP

CHILD = r"""
import json, sys, time
import numpy as np
from pathlib import Path
from engine.io import load_take
from engine.model.kinematics import resample
from engine.splice import pipeline as P

pair, edits = sys.argv[1], int(sys.argv[2])
mocap = Path(sys.argv[3])
if pair.startswith("mug"):
    body = resample(load_take(mocap / "lafan1/multipleActions1_subject1.bvh"), 120.0)
    body = body.frames(0, 120 * 120)
    hand = load_take(mocap / "manipnet/mug1_rightHand.bvh")
else:
    from benchmarks.long_pairs import pair_files
    bp, hp, _ = pair_files(120)
    body, hand = load_take(bp), load_take(hp)
f = P.prepare(body, hand, side="auto")
r = P.align_passes(f, incremental=True)
(b0, b1), _ = r.overlap

def on_path(x):
    return int(r.pass2.path[np.searchsorted(r.pass2.path[:, 0], x), 1])

if pair.endswith("+2"):  # a point at a third of the overlap dragged, one at two thirds kept
    x, x2 = b0 + (b1 - b0) // 3, b0 + 2 * (b1 - b0) // 3
    later = [(x2, on_path(x2), 0)]
else:
    x, later = (b0 + b1) // 2, []
y = on_path(x)
r = P.align_passes(f, points=[(x, y, 0)] + later, incremental=True)

def cells(solver):
    st = getattr(solver, "last_stats", None)
    return None if st is None else int(st.cells_computed)

cpu, wall, fine, coarse, second = [], [], [], [], []
for k in range(edits + 2):
    pts = [(x, y + (3 if k % 2 == 0 else -3), 0)] + later
    c0, t0 = time.process_time(), time.perf_counter()
    r = P.align_passes(f, points=pts, previous=r, incremental=True)
    c1, t1 = time.process_time(), time.perf_counter()
    if k >= 2:
        cpu.append(c1 - c0)
        wall.append(t1 - t0)
        fine.append(cells(r.pass1.solver))
        coarse.append(cells(getattr(r.pass1.coarse, "solver", None)))
        second.append(cells(r.pass2.solver))
same = None
if len(sys.argv) > 4:
    fresh = P.align_passes(f, points=pts, incremental=False)
    same = bool(
        np.array_equal(r.pass1.path, fresh.pass1.path) and r.pass1.cost == fresh.pass1.cost
        and np.array_equal(r.pass2.path, fresh.pass2.path) and r.pass2.cost == fresh.pass2.cost
    )
print(json.dumps(dict(cpu=cpu, wall=wall, fine=fine, coarse=coarse, second=second,
                      n=f.n, m=f.m, point=[x, y], same=same)))
"""


def _median(values):
    values = [v for v in values if v is not None]
    return statistics.median(values) if values else None


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ref", default="d84f2f0", help="reference commit (main before drag31)")
    ap.add_argument(
        "--now", default=None, help="measure this commit instead of the checkout (git archive)"
    )
    ap.add_argument("--edits", type=int, default=8)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--pairs", default="mug,mug+2,synthetic")
    args = ap.parse_args(argv)
    mocap = os.environ.get("HANDSPLICE_MOCAP", str(LP.ROOT.parent / "shared" / "data" / "mocap"))
    tree = LP.baseline_tree(args.ref, name="drag31-ref")
    now = LP.baseline_tree(args.now, name="drag31-now") if args.now else None
    rows = []
    for pair in args.pairs.split(","):
        runs: dict[str, list[dict]] = {"ref": [], "now": []}
        for _ in range(args.rounds):
            for code in ("ref", "now"):
                extra = ("check",) if code == "now" else ()
                out = LP.run_child(
                    CHILD,
                    pair,
                    str(args.edits),
                    mocap,
                    *extra,
                    tree=tree if code == "ref" else now,
                )
                runs[code].append(out)
        ref_cpu = _median([c for o in runs["ref"] for c in o["cpu"]])
        now_cpu = _median([c for o in runs["now"] for c in o["cpu"]])
        for code in ("ref", "now"):
            outs = runs[code]
            flat = {k: [v for o in outs for v in o[k]] for k in ("cpu", "wall", "fine", "coarse")}
            second = [v for o in outs for v in o["second"]]
            rows.append(
                f"| {pair} ({outs[0]['n']} x {outs[0]['m']}) | {code} "
                f"| {1000 * _median(flat['cpu']):.0f} | {1000 * _median(flat['wall']):.0f} "
                f"| {_fmt(_median(flat['coarse']))} | {_fmt(_median(flat['fine']))} "
                f"| {_fmt(_median(second))} "
                f"| {'' if code == 'ref' else f'x{now_cpu / ref_cpu:.2f}'} "
                f"| {'' if code == 'ref' else outs[-1]['same']} |"
            )
    print(
        "| pair | code | CPU per edit, median (ms) | wall (ms) | coarse pass-1 cells "
        "| fine pass-1 cells | pass-2 cells (last solve) | CPU now / ref | = fresh solve |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))


def _fmt(v) -> str:
    return "" if v is None else f"{v / 1e6:.2f} M"


if __name__ == "__main__":
    main()
