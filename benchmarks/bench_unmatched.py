"""The default open-end limit for takes of different lengths (issue 13, real takes), beside
main before the change (``cbd2ea7``: half the shorter take at each end, the paper's strip
plus the end widening) in the same run.

Run: ``.venv/bin/python -m benchmarks.bench_unmatched [--seeds 4] [--no-120fps] [--write]``

Each (tree, case) runs in a fresh interpreter (``long_pairs.run_child``): ``prepare`` +
``align_passes`` seconds (the alignment; the finger transfer does not change), the
interpreter's peak RSS (MB), pass-1 band cells, and the timing error in hand frames of
the map against the truth (on the body frames that have a hand match).

* inside: ``benchmarks.split.inside_case``: a 33 s stretch of a 2-minute LAFAN1 take at
  offsets 10 / 45 / 80 s, as the hand take (body longer) or as the body take (hand
  longer), 30 fps; and the 120 fps body-longer case (14,400 x 3,960 frames) of the
  stranger's report.
* long: the 2-minute 120 fps pair of ``benchmarks.long_pairs`` (takes of one length).
* split: families of ``bench_splice_accuracy`` (the hand take at 0.85-1.2 times the
  body's tempo, untrimmed ends 1-2 s, other rates, ManipNet): pooled timing error in ms.
"""

from __future__ import annotations

import argparse
import json
import os

import numpy as np

from benchmarks import long_pairs as LP
from benchmarks._results import write_section

BEFORE = "cbd2ea7"

CHILD = r"""
import json, resource, sys, time
import numpy as np
from engine.splice import pipeline as P

spec = json.loads(sys.argv[1])

def measure(body, hand, truth, hand_fps=None):
    t0 = time.perf_counter()
    f = P.prepare(body, hand)
    t1 = time.perf_counter()
    a = P.align_passes(f)
    t2 = time.perf_counter()
    ok = np.isfinite(truth)
    err = np.abs(np.asarray(a.map)[ok] - truth[ok])
    out = {"prepare_s": t1 - t0, "align_s": t2 - t1, "cells1": int(a.pass1.band.area),
           "cells2": int(a.pass2.band.area), "err": err.tolist()}
    if hand_fps:
        out["err_ms"] = (err / hand_fps * 1000.0).tolist()
    return out

rows = []
if spec["kind"] == "inside":
    from benchmarks.split import inside_case
    c = inside_case(120.0, 33.0, spec["offset"], seed=spec["seed"],
                    hand_longer=spec["hand_longer"], hand_fps=spec["fps"], fps=spec["fps"])
    r = measure(c.body, c.hand, c.truth)
    r["shape"] = [c.body.n_frames, c.hand.n_frames]
    rows.append(r)
elif spec["kind"] == "long":
    from engine.io.bvh import read_bvh
    from benchmarks import long_pairs as LP
    b, h, t = LP.pair_files(spec["seconds"])
    r = measure(read_bvh(b), read_bvh(h), np.load(t))
    rows.append(r)
else:
    from benchmarks.bench_splice_accuracy import FAMILIES
    for seed in range(spec["seeds"]):
        c = FAMILIES[spec["family"]].make(seed)
        r = measure(c.body, c.hand, c.truth, c.hand.fps)
        rows.append(r)
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
print(json.dumps({"rows": rows, "peak_mb": peak}))
"""


SPLIT_FAMILIES = ("beat", "lafan1", "untrimmed", "fps", "manipnet")


def cases(seeds: int, with_120: bool, families=SPLIT_FAMILIES) -> list[dict]:
    out = []
    for hand_longer in (False, True):
        for k, offset in enumerate((10.0, 45.0, 80.0)):
            out.append(
                {
                    "kind": "inside",
                    "offset": offset,
                    "seed": k,
                    "hand_longer": hand_longer,
                    "fps": 30.0,
                }
            )
    if with_120:
        out.append(
            {"kind": "inside", "offset": 45.0, "seed": 0, "hand_longer": False, "fps": 120.0}
        )
        out.append({"kind": "long", "seconds": 120.0})
    for fam in families:
        out.append({"kind": "split", "family": fam, "seeds": seeds})
    return out


def label(spec: dict) -> str:
    if spec["kind"] == "inside":
        who = "hand 33 s in body 120 s" if not spec["hand_longer"] else "body 33 s in hand 120 s"
        return f"{who} @{spec['offset']:g} s, {spec['fps']:g} fps"
    if spec["kind"] == "long":
        return f"long pair {spec['seconds'] / 60:g} min, 120 fps (one length)"
    return f"split {spec['family']} ({spec['seeds']} seeds)"


def run(spec: dict, tree) -> dict:
    res = LP.run_child(CHILD, json.dumps(spec), tree=tree)
    rows = res["rows"]
    key = "err_ms" if spec["kind"] == "split" else "err"
    err = np.concatenate([np.asarray(r[key]) for r in rows])
    return {
        "cells1": sum(r["cells1"] for r in rows),
        "align_s": sum(r["prepare_s"] + r["align_s"] for r in rows),
        "peak_mb": res["peak_mb"],
        "median": float(np.median(err)),
        "p95": float(np.percentile(err, 95)),
        "unit": "ms" if spec["kind"] == "split" else "frames",
        "shape": rows[0].get("shape"),
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--no-120fps", action="store_true")
    ap.add_argument("--write", action="store_true")
    ap.add_argument("--start", type=int, default=0, help="skip the first START cases")
    ap.add_argument("--families", default=",".join(SPLIT_FAMILIES), help="split families")
    args = ap.parse_args(argv)
    before = LP.baseline_tree(BEFORE, ("engine",), name="ends-before")
    load = os.getloadavg()
    lines = [
        f"Before = `{BEFORE}` (main), after = this branch; each (tree, case) in a fresh "
        f"interpreter, alternating. Load average at start {load[0]:.1f} / {load[1]:.1f} "
        "(2 cores shared).",
        "",
        "| case | pass-1 cells before → after | prepare+align s before → after | "
        "peak MB before → after | timing median / p95 before → after |",
        "|---|---|---|---|---|",
    ]
    for spec in cases(args.seeds, not args.no_120fps, args.families.split(","))[args.start :]:
        b = run(spec, before)
        a = run(spec, None)
        u = a["unit"]
        line = (
            f"| {label(spec)} | {b['cells1']:,} → {a['cells1']:,} "
            f"({a['cells1'] / b['cells1']:.2f}×) | {b['align_s']:.2f} → {a['align_s']:.2f} "
            f"({a['align_s'] / b['align_s']:.2f}×) | {b['peak_mb']:.0f} → {a['peak_mb']:.0f} | "
            f"{b['median']:.1f} / {b['p95']:.1f} → {a['median']:.1f} / {a['p95']:.1f} {u} |"
        )
        print(line, flush=True)
        lines.append(line)
    load = os.getloadavg()
    lines.append("")
    lines.append(f"Load average at the end {load[0]:.1f} / {load[1]:.1f}.")
    text = "\n".join(lines)
    print(text)
    if args.write:
        write_section("Open-end limit for takes of different lengths (issue 13, ends)", text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
