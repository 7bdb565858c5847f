"""Multi-resolution pass 1 (issue 13, ``engine.splice.coarse``) beside a reference tree.

Run: ``.venv/bin/python -m benchmarks.bench_coarse_pass1 --accuracy [--families fps,left]``
and ``--drag`` (prints; the tables of ``benchmarks/RESULTS.md`` *Multi-resolution pass 1*
were made with this code).

* ``--accuracy``: every case of the accuracy families (``bench_splice_accuracy``), one
  child process per code: the reference (``--ref``, default ``1c2dad1``: main before this
  work, from ``git archive``) splices with its pass 1; this checkout three ways in one
  process (coarse off, i.e. the reference's path; coarse + fine pass 1, the default;
  coarse without the fine pass, pass 2 around the upsampled coarse path). Timing error
  |map - truth| in ms per body frame, median / p95 per family; merged maps identical to
  the reference's. (No CPU column: the first ``align_passes`` of a case fills the
  features' caches, so later modes of one process read cheaper; speed is ``--drag``'s and
  the 2-minute stage figures'.)
* ``--drag``: ``webapp.backend.solve`` per edit on the 2-minute pair
  (``long_pairs.pair_files(120)``), a lone matching point at mid-take dragged by
  ±12/±24 grid frames, the full-rate pass 1 (``features.coarse = None``, the reference's
  solve) and the multi-resolution one taking turns drag by drag in one process: CPU
  (process time, all threads) and wall per edit, cells recomputed, same map and pass 2.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np

from benchmarks import long_pairs as LP

FAMILIES = "fps,left,manipnet,leap,lafan1"

CHILD_ACCURACY = r"""
import sys, time, numpy as np
from benchmarks.bench_splice_accuracy import FAMILIES
from engine.splice import pipeline as P
try:
    from engine.splice import coarse as CO
except ImportError:
    CO = None
out, fams, seeds = sys.argv[1], sys.argv[2].split(","), int(sys.argv[3])
store = {}
for fam in fams:
    F = FAMILIES[fam]
    for seed in range(min(F.seeds, seeds) if seeds > 0 else F.seeds):
        case = F.make(seed)
        f = P.prepare(case.body, case.hand)
        cr = getattr(f, "coarse", None)
        for mode in (["full"] if CO is None else ["full", "multi", "nofine"]):
            if CO is not None:
                f.coarse = None if mode == "full" else cr
                CO.FINE_PASS = mode != "nofine"
            c0 = time.process_time()
            a = P.align_passes(f)
            cpu = time.process_time() - c0
            key = f"{fam}/{seed}/{mode}"
            store[key + "/map"] = np.asarray(a.map)
            store[key + "/err"] = np.abs(np.asarray(a.map) - case.truth) / case.hand.fps * 1000.0
            store[key + "/meta"] = np.array([case.body.fps, case.hand.fps, cpu])
        if CO is not None:
            CO.FINE_PASS = True
np.savez_compressed(out, **store)
print("{}")
"""


def accuracy(ref: str, families: str, seeds: int) -> str:
    folder = Path(tempfile.mkdtemp(prefix="coarse1-acc-"))
    load0 = os.getloadavg()[0]
    ref_p, now_p = folder / "ref.npz", folder / "now.npz"
    LP.run_child(
        CHILD_ACCURACY,
        str(ref_p),
        families,
        str(seeds),
        tree=LP.baseline_tree(ref, ("engine", "benchmarks", "sample_data"), name="coarse1-ref"),
    )
    LP.run_child(CHILD_ACCURACY, str(now_p), families, str(seeds))
    return accuracy_table(np.load(ref_p), np.load(now_p), families.split(","), ref, load0)


def accuracy_table(main, now, fams, ref: str, load0: float) -> str:
    lines = [
        f"| family | cases (body > 30 fps) | `{ref}`: median / p95 ms | now: median / p95 ms | "
        "now without the fine pass 1: median / p95 ms | merged map identical to "
        f"`{ref}`: now / without fine pass |",
        "|---|---|---|---|---|---|",
    ]
    notes = []
    for fam in fams:
        seeds = sorted({int(k.split("/")[1]) for k in now.files if k.startswith(fam + "/")})
        errs: dict[str, list] = {"main": [], "multi": [], "nofine": []}
        same = {"multi": 0, "nofine": 0}
        fast = 0
        for s in seeds:
            mm = main[f"{fam}/{s}/full/map"]
            fast += now[f"{fam}/{s}/multi/meta"][0] > 30.5
            for mode, z, key in (
                ("main", main, "full"),
                ("multi", now, "multi"),
                ("nofine", now, "nofine"),
            ):
                errs[mode].append(z[f"{fam}/{s}/{key}/err"])
            for mode in ("multi", "nofine"):
                mp = now[f"{fam}/{s}/{mode}/map"]
                if np.array_equal(mm, mp):
                    same[mode] += 1
                    continue
                e0, e1 = main[f"{fam}/{s}/full/err"], now[f"{fam}/{s}/{mode}/err"]
                meta = now[f"{fam}/{s}/{mode}/meta"]
                notes.append(
                    f"{fam} seed {s} ({mode}; body {meta[0]:g} fps, hand {meta[1]:g} fps): "
                    f"map differs by up to {np.max(np.abs(mm - mp)):.1f} hand frames, error "
                    f"median {np.median(e0):.1f} -> {np.median(e1):.1f} ms, p95 "
                    f"{np.percentile(e0, 95):.1f} -> {np.percentile(e1, 95):.1f} ms"
                )

        def st(mode, errs=errs):
            e = np.concatenate(errs[mode])
            return f"{np.median(e):.1f} / {np.percentile(e, 95):.1f}"

        n = len(seeds)
        lines.append(
            f"| {fam} | {n} ({fast}) | {st('main')} | {st('multi')} | {st('nofine')} | "
            f"{same['multi']}/{n} / {same['nofine']}/{n} |"
        )
    lines += ["", "Maps that differ from the reference's:", ""]
    lines += [f"- {t}" for t in notes] or ["- none"]
    lines += [
        "",
        f"Load average (1 min) {load0:.1f} at the start, {os.getloadavg()[0]:.1f} at the end.",
    ]
    return "\n".join(lines)


def drag(drags: int) -> str:
    import time

    from engine.splice import coarse as CO  # noqa: F401  (this checkout only)
    from webapp import backend

    body_p, hand_p, _ = LP.pair_files(120.0, 120.0)
    load0 = os.getloadavg()
    prep = backend.prepare(body_p, hand_p, "auto")
    f = prep.features
    cr = f.coarse
    sols = {}
    for mode in ("full", "multi"):
        f.coarse = None if mode == "full" else cr
        sols[mode] = backend.solve(prep, None, None, [])
    x = f.n // 2
    y0 = int(sols["full"].cache["engine"].warp[x])
    rec: dict[str, list] = {"full": [], "multi": []}
    same = 0
    for d in range(drags):
        pts = [(x, y0 + (12, -12)[d % 2] * (1 + d // 4), 0.0)]
        for mode in ("full", "multi") if d % 2 == 0 else ("multi", "full"):
            f.coarse = None if mode == "full" else cr
            c0, t0 = time.process_time(), time.perf_counter()
            sols[mode] = backend.solve(prep, None, None, pts, previous=sols[mode])
            cpu, wall = time.process_time() - c0, time.perf_counter() - t0
            e = sols[mode].cache["engine"]
            cc = e.pass1.coarse
            cells = e.pass1.solver.last_stats.cells_computed
            coarse_cells = cc.solver.last_stats.cells_computed if cc is not None else 0
            rec[mode].append((cpu, wall, cells, coarse_cells))
        a, b = sols["full"].cache["engine"], sols["multi"].cache["engine"]
        same += bool(np.array_equal(a.map, b.map) and np.array_equal(a.pass2.path, b.pass2.path))
        print(
            json.dumps({"drag": d, "full": rec["full"][-1], "multi": rec["multi"][-1]}), flush=True
        )
    lines = [
        "| pass 1 | CPU per edit, median / max | wall per edit, median | pass-1 cells recomputed "
        "per edit, median (fine + coarse) |",
        "|---|---|---|---|",
    ]
    for mode, label in (("full", "full rate (as `1c2dad1`)"), ("multi", "multi-resolution")):
        r = rec[mode]
        lines.append(
            f"| {label} | {statistics.median(x[0] for x in r) * 1000:.0f} / "
            f"{max(x[0] for x in r) * 1000:.0f} ms | {statistics.median(x[1] for x in r) * 1000:.0f} ms | "
            f"{statistics.median(x[2] for x in r):,.0f} + {statistics.median(x[3] for x in r):,.0f} |"
        )
    lines += [
        "",
        f"Same merged map and pass-2 path after {same} of {drags} drags. Load average "
        f"{load0[0]:.1f} at the start, {os.getloadavg()[0]:.1f} at the end.",
    ]
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--accuracy", action="store_true")
    ap.add_argument("--drag", action="store_true")
    ap.add_argument("--ref", default="1c2dad1")
    ap.add_argument("--families", default=FAMILIES)
    ap.add_argument("--seeds", type=int, default=0, help="at most this many seeds a family")
    ap.add_argument("--drags", type=int, default=8)
    args = ap.parse_args(argv)
    if args.accuracy:
        print(accuracy(args.ref, args.families, args.seeds))
    if args.drag:
        print(drag(args.drags))
    if not (args.accuracy or args.drag):
        ap.error("--accuracy and/or --drag")
    return 0


if __name__ == "__main__":
    sys.exit(main())
