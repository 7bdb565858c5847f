"""DTW benchmark: engine.dtw against dtaidistance, side by side in one run.

    .venv/bin/python -m benchmarks.bench_dtw            # full run, writes RESULTS.md section "dtw"
    .venv/bin/python -m benchmarks.bench_dtw --quick    # small sizes, prints only

Measures (issue 4):
* time of ``align_features`` (12-D float64, Sakoe-Chiba band 30 %, path
  returned) and of dtaidistance's C ``dtw_ndim.warping_path`` with the same
  window, n = m = 2,000 and 8,000; ns per band cell and the time ratio;
* peak resident memory (VmHWM of a child process) at n = m = 20,000 for
  both;
* ``Aligner`` initial solve and first / later re-solves after moving one
  matching point (at 5n/6, 2n/3 and n/2) vs. a plain ``align_features``,
  2,000 x 2,000, with the previous incremental scheme side by side;
* JIT warm-up: first call with an empty numba cache, and with a warm cache.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
D = 12
WIDTH = 0.30


def features(n: int, rng: np.random.Generator) -> np.ndarray:
    """Smooth 12-D trajectories (random walks), float64, C-contiguous."""
    return np.cumsum(rng.standard_normal((n, D)), axis=0) * 0.1


def dtai_window(band) -> int:
    """dtaidistance window equal to a square Sakoe-Chiba band (|i - j| <= window - 1)."""
    n = band.n
    return int(band.hi[n // 2] - n // 2) + 1


def check_same_band(band, window: int) -> None:
    n, m = band.n, band.m
    rows = np.arange(n)
    lo = np.maximum(0, rows - window + 1)
    hi = np.minimum(m - 1, rows + window - 1)
    if not (np.array_equal(lo, band.lo) and np.array_equal(hi, band.hi)):
        raise RuntimeError("dtaidistance window does not reproduce the band")


def bench_speed(n: int, reps: int, rng) -> dict:
    from dtaidistance import dtw_ndim

    from engine.dtw import Band, align_features

    a, b = features(n, rng), features(n, rng)
    band = Band.sakoe_chiba(n, n, WIDTH)
    window = dtai_window(band)
    check_same_band(band, window)
    ours = align_features(a, b, band)  # warm-up (JIT, caches)
    _, dist = dtw_ndim.warping_path(a, b, window=window, use_c=True, include_distance=True)
    if not math.isclose(math.sqrt(ours.cost), dist, rel_tol=1e-9):
        raise RuntimeError(f"distance mismatch: {math.sqrt(ours.cost)} vs {dist}")
    t_ours, t_dtai = [], []
    for _ in range(reps):  # interleaved, so load on the shared machine hits both
        t0 = time.perf_counter()
        align_features(a, b, band)
        t_ours.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        dtw_ndim.warping_path(a, b, window=window, use_c=True, include_distance=True)
        t_dtai.append(time.perf_counter() - t0)
    mo, md = statistics.median(t_ours), statistics.median(t_dtai)
    return {
        "n": n,
        "cells": band.area,
        "window": window,
        "ours_s": mo,
        "dtai_s": md,
        "ours_min_s": min(t_ours),
        "dtai_min_s": min(t_dtai),
        "ours_ns": mo / band.area * 1e9,
        "dtai_ns": md / band.area * 1e9,
        "ratio": mo / md,
        "ratio_paired": statistics.median(o / d for o, d in zip(t_ours, t_dtai)),
        "ratio_min": min(t_ours) / min(t_dtai),
        "reps": reps,
    }


RESOLVE_SCENARIOS = (
    (4, "5n/6 (last third)"),
    (3, "2n/3 (last third)"),
    (2, "n/2 (information)"),
)


def bench_resolve(n: int, reps: int, rng) -> dict:
    """Aligner re-solves vs a plain full solve, 5 matching points every n/6 frames.

    The reference is a one-shot ``align_features`` on the same band, timed
    interleaved with the Aligner runs. For each moved point: the *first* edit
    right after the Aligner's initial solve and *later* edits (further drags
    of the same point), with the current Aligner and with the previous scheme
    (``SUFFIX_SHARE = 0``: forward-only initial solve, junction at the end of
    the edited rows) side by side.
    """
    from engine.dtw import Aligner, Band, align_features

    a, b = features(n, rng), features(n, rng)
    xs = [round(n * k / 6) for k in range(1, 6)]
    base = [[x, x, 2] for x in xs]

    def band_for(points):
        return Band.from_constraints(n, n, WIDTH, points)

    full_band = band_for(base)
    moved = {}  # (k, step) -> band: point k moved by +12, -12, +12 hand frames
    for k, _ in RESOLVE_SCENARIOS:
        for step in range(3):
            pts = [list(p) for p in base]
            pts[k][1] += 12 if step % 2 == 0 else -12
            moved[k, step] = band_for(pts)
    solvers = {"new": Aligner(a, b), "old": Aligner(a, b)}
    solvers["old"].SUFFIX_SHARE = 0.0
    for s in solvers.values():  # warm-up (JIT, allocations)
        s.solve(full_band)
        s.solve(moved[4, 0])
    align_features(a, b, full_band)

    t_plain = []
    t_init = {"new": [], "old": []}
    t_edit = {
        (v, k, w): [] for v in solvers for k, _ in RESOLVE_SCENARIOS for w in ("first", "later")
    }
    cells = {key: [] for key in t_edit}
    init_cells = {}
    for _ in range(reps):
        for k, _ in RESOLVE_SCENARIOS:
            t0 = time.perf_counter()
            align_features(a, b, full_band)
            t_plain.append(time.perf_counter() - t0)
            for v, solver in solvers.items():
                solver.reset()
                t0 = time.perf_counter()
                solver.solve(full_band)
                t_init[v].append(time.perf_counter() - t0)
                init_cells[v] = solver.last_stats.fraction
                for step in range(3):
                    band = moved[k, step]
                    t0 = time.perf_counter()
                    solver.solve(band)
                    dt = time.perf_counter() - t0
                    key = (v, k, "first" if step == 0 else "later")
                    t_edit[key].append(dt)
                    cells[key].append(solver.last_stats.fraction)
    plain = statistics.median(t_plain)
    med = statistics.median
    rows = []
    for k, label in RESOLVE_SCENARIOS:
        row = {"moved": label, "x": xs[k]}
        for v in solvers:
            for w in ("first", "later"):
                row[f"{v}_{w}_s"] = med(t_edit[v, k, w])
                row[f"{v}_{w}_ratio"] = med(t_edit[v, k, w]) / plain
                row[f"{v}_{w}_cells"] = med(cells[v, k, w])
        rows.append(row)
    return {
        "n": n,
        "cells": full_band.area,
        "reps": reps,
        "plain_s": plain,
        "init_s": {v: med(t) for v, t in t_init.items()},
        "init_ratio": {v: med(t) / plain for v, t in t_init.items()},
        "init_cells": init_cells,
        "rows": rows,
    }


# ru_maxrss survives exec (a child would report its parent's peak), so the
# children read VmHWM, the high-water mark of their own address space.
HWM = """
def hwm_kb():
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1])
"""

CHILD_OURS = (
    HWM
    + """
import json, sys, time
import numpy as np
from benchmarks.bench_dtw import features, WIDTH
from engine.dtw import Band, align_features
n = int(sys.argv[1])
rng = np.random.default_rng(1)
a, b = features(n, rng), features(n, rng)
align_features(a[:50], b[:50], Band.sakoe_chiba(50, 50, WIDTH))  # JIT before the baseline
band = Band.sakoe_chiba(n, n, WIDTH)
base = hwm_kb()
t0 = time.perf_counter()
r = align_features(a, b, band)
dt = time.perf_counter() - t0
peak = hwm_kb()
print(json.dumps({"base_kb": base, "peak_kb": peak, "seconds": dt, "cells": band.area,
                  "path": len(r.path), "distance": float(np.sqrt(r.cost))}))
"""
)

CHILD_DTAI = (
    HWM
    + """
import json, sys, time
import numpy as np
from benchmarks.bench_dtw import features, dtai_window, WIDTH
from engine.dtw import Band
from dtaidistance import dtw_ndim
n = int(sys.argv[1])
rng = np.random.default_rng(1)
a, b = features(n, rng), features(n, rng)
dtw_ndim.warping_path(a[:50], b[:50], window=10, use_c=True)
window = dtai_window(Band.sakoe_chiba(n, n, WIDTH))
base = hwm_kb()
t0 = time.perf_counter()
path, d = dtw_ndim.warping_path(a, b, window=window, use_c=True, include_distance=True)
dt = time.perf_counter() - t0
peak = hwm_kb()
print(json.dumps({"base_kb": base, "peak_kb": peak, "seconds": dt, "path": len(path),
                  "distance": float(d)}))
"""
)


def run_child(code: str, *args: str, env: dict | None = None) -> dict:
    out = subprocess.run(
        [sys.executable, "-c", code, *args],
        cwd=ROOT,
        env={**os.environ, **(env or {})},
        capture_output=True,
        text=True,
        check=False,
    )
    if out.returncode != 0:
        raise RuntimeError(f"child failed ({out.returncode}): {out.stderr[-2000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


CHILD_WARMUP = """
import json, time
t0 = time.perf_counter()
import numba
import numpy as np
from engine.dtw import Aligner, Band, align, align_features, local_cost_image
t1 = time.perf_counter()
a = np.random.default_rng(0).standard_normal((300, 12)); b = a[::-1].copy()
band = Band.sakoe_chiba(300, 300, 0.3)
t2 = time.perf_counter(); align_features(a, b, band); t3 = time.perf_counter()
align(np.ones((30, 30)), Band.full(30, 30)); t4 = time.perf_counter()
s = Aligner(a, b); s.solve(band); s.solve(Band.from_constraints(300, 300, 0.3, [(150, 140, 2)]))
s.cumulative_cost().image((64, 64)); local_cost_image(a, b, max_size=(64, 64)); t5 = time.perf_counter()
@numba.njit
def l1(x, y):
    s = 0.0
    for d in range(x.shape[0]):
        s += abs(x[d] - y[d])
    return s
t6 = time.perf_counter(); align_features(a, b, band, metric=l1); t7 = time.perf_counter()
print(json.dumps({"import": t1 - t0, "align_features": t3 - t2, "align": t4 - t3,
                  "aligner_views": t5 - t4, "custom_metric": t7 - t6}))
"""


def bench_warmup() -> dict:
    with tempfile.TemporaryDirectory() as cache:
        env = {"NUMBA_CACHE_DIR": cache}
        cold = run_child(CHILD_WARMUP, env=env)
        warm = run_child(CHILD_WARMUP, env=env)
    return {"cold": cold, "warm": warm}


def fmt_mb(kb: float) -> str:
    return f"{kb / 1024:,.0f} MB"


def report(speed, resolve, memory, warmup) -> str:
    lines = [
        "## DTW (engine.dtw vs dtaidistance)",
        "",
        f"`align_features` (numba, {D}-D float64, Sakoe–Chiba band W = 30 % of n, path returned) "
        "against dtaidistance "
        "`dtw_ndim.warping_path(use_c=True)` with the window giving exactly the same band "
        "(checked cell by cell, same distance). Each size ran both alternately "
        "(a paired ratio compares the two runs of one repetition) "
        f"({speed[0]['reps']}/{speed[-1]['reps']} repetitions); median times.",
        "",
        "| n = m | band cells | engine.dtw | dtaidistance | ns/cell ours | ns/cell dtai | "
        "ratio of medians | median of paired ratios | ratio of best |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for s in speed:
        lines.append(
            f"| {s['n']:,} | {s['cells']:,} | {s['ours_s'] * 1e3:.1f} ms | "
            f"{s['dtai_s'] * 1e3:.1f} ms | {s['ours_ns']:.2f} | {s['dtai_ns']:.2f} | "
            f"**{s['ratio']:.2f}** | {s['ratio_paired']:.2f} | {s['ratio_min']:.2f} |"
        )
    lines += ["", "Target: ratio ≤ 0.5 at 2,000 and 8,000.", ""]
    if memory:
        o, d = memory["ours"], memory["dtai"]
        lines += [
            f"**Peak memory, n = m = {memory['n']:,}, band 30 % ({o['cells']:,} cells), path "
            "returned** — VmHWM (peak resident set) of a fresh child process (whole process: Python, numpy, "
            "numba, the two 20,000 × 12 feature arrays), before the call and at its end:",
            "",
            "| | before call | peak | added by the call | time |",
            "|---|---:|---:|---:|---:|",
            f"| engine.dtw `align_features` | {fmt_mb(o['base_kb'])} | **{fmt_mb(o['peak_kb'])}** | "
            f"{fmt_mb(o['peak_kb'] - o['base_kb'])} | {o['seconds']:.2f} s |",
            f"| dtaidistance `warping_path` | {fmt_mb(d['base_kb'])} | {fmt_mb(d['peak_kb'])} | "
            f"{fmt_mb(d['peak_kb'] - d['base_kb'])} | {d['seconds']:.2f} s |",
            "",
            f"Same distance: {o['distance']:.6f} vs {d['distance']:.6f}. engine.dtw stores one "
            "byte per band cell (backpointers) and two rows of doubles; target: peak < 1 GB.",
            "",
        ]
    rs = resolve
    lines += [
        f"**Incremental re-solve** (`Aligner`, n = m = {rs['n']:,}, {D}-D, band 30 %, five "
        f"matching points every n/6 frames with tolerance 2; {rs['cells']:,} band cells). "
        f"Reference: a plain one-shot `align_features` on the same band, "
        f"{rs['plain_s'] * 1e3:.2f} ms (median of {rs['reps'] * len(rs['rows'])}, interleaved "
        "with the Aligner runs). Every ratio below is time / that reference. A point is moved "
        "by ±12 hand frames; *first* = the first edit right after the Aligner's initial solve, "
        "*later* = two further drags of the same point (median). *now*: the current Aligner "
        "(initial solve forward over every row, exactly `align_features`'s path, plus the "
        "backward rows of the band's last third by cells; after an edit the junction row "
        "stays inside the edited rows, nearest the last third). *before*: the previous scheme "
        "in the same run, i.e. the same solver with `SUFFIX_SHARE = 0` (forward-only initial "
        "solve, junction at the end of the edited rows; today's kernels and γ checkpoints).",
        "",
        "| | now | before |",
        "|---|---:|---:|",
        f"| Aligner initial solve / plain `align_features` | "
        f"**{rs['init_ratio']['new']:.2f}** ({rs['init_s']['new'] * 1e3:.2f} ms, "
        f"{rs['init_cells']['new']:.0%} of the band's cells) | "
        f"{rs['init_ratio']['old']:.2f} ({rs['init_s']['old'] * 1e3:.2f} ms, "
        f"{rs['init_cells']['old']:.0%}) |",
        "",
        "| moved point | first edit, now | later, now | first edit, before | later, before |",
        "|---|---:|---:|---:|---:|",
    ]
    for r in rs["rows"]:
        cells_now = f"{r['new_first_cells']:.0%} / {r['new_later_cells']:.0%}"
        lines.append(
            f"| {r['moved']} (x = {r['x']}) | **{r['new_first_ratio']:.2f}** "
            f"({r['new_first_s'] * 1e3:.2f} ms) | **{r['new_later_ratio']:.2f}** | "
            f"{r['old_first_ratio']:.2f} | {r['old_later_ratio']:.2f} |"
        )
        r["cells_text"] = cells_now
    lines += [
        "",
        "Band cells recomputed (first / later edit), now: "
        + "; ".join(f"{r['moved']}: {r['cells_text']}" for r in rs["rows"])
        + "; before: "
        + "; ".join(
            f"{r['moved']}: {r['old_first_cells']:.0%} / {r['old_later_cells']:.0%}"
            for r in rs["rows"]
        )
        + ".",
        "",
        "Target: ≤ 0.40 of a full solve for a point in the last third. Choice: the initial "
        "solve pays for the backward rows of the last third (1.33x the cells of a plain solve, "
        "time ratio above) so that the *first* edit of any point in the last third recomputes "
        "only its two segments; `Aligner.SUFFIX_SHARE = 0` gives the previous cheaper initial "
        "solve with the slower first edits of the *before* column. Not covered: after dragging "
        "a point in the first two thirds, the first edit of a point in the last third also "
        "recomputes the forward rows between the two (they depend on the earlier edit), e.g. "
        "n/6 then 5n/6: two thirds of the band's cells, once; further drags are again two "
        "segments. Results equal a full solve (tests compare cost and path with "
        "`align_features` / the naive reference after first and later edits).",
        "",
        "**JIT warm-up** (fresh process; cold = empty numba cache, warm = cache on disk):",
        "",
        "| step | cold | warm |",
        "|---|---:|---:|",
    ]
    labels = {
        "import": "import engine.dtw",
        "align_features": "first align_features (300 × 300)",
        "align": "first align (cost matrix)",
        "aligner_views": "Aligner solve + re-solve + views",
        "custom_metric": "align_features with a new numba metric (never cached)",
    }
    for key, label in labels.items():
        lines.append(f"| {label} | {warmup['cold'][key]:.2f} s | {warmup['warm'][key]:.2f} s |")
    lines += [
        "",
        "Machine shared with other jobs (2 cores): times are medians of interleaved runs; "
        "the ratios are the meaningful figures.",
    ]
    return "\n".join(lines)


# ---------------------------------------------------------------------------
# long takes: the engine side of an app edit (issue 13)
# ---------------------------------------------------------------------------
CHILD_EDITS = r"""
import json, sys, time
import numpy as np
def status(key):
    for line in open("/proc/self/status"):
        if line.startswith(key):
            return int(line.split()[1]) / 1024
from engine.io.bvh import read_bvh
from engine.splice import pipeline as P
body_p, hand_p, truth_p = sys.argv[1:4]
band, refine, n_points, n_edits = float(sys.argv[4]), float(sys.argv[5]), int(sys.argv[6]), int(sys.argv[7])
body, hand = read_bvh(body_p), read_bvh(hand_p)
truth = np.load(truth_p)
def points(n, m, tr, shift=0):
    xs = [round(n * (k + 1) / (n_points + 1)) for k in range(n_points)]
    pts = [[x, int(min(m - 1, round(tr[x]))), 2] for x in xs]
    pts[n_points // 2][1] += shift
    return pts
# warm-up (JIT): the same calls on a crop
wb, wh = body.frames(0, 1200), hand.frames(0, 1200)
wf = P.prepare(wb, wh)
wr = P.align_passes(wf, band=band, refine_band=refine, points=points(wf.n, wf.m, truth), incremental=True)
P.align_passes(wf, band=band, refine_band=refine, points=points(wf.n, wf.m, truth, 12), previous=wr, incremental=True)
feats = P.prepare(body, hand)
rss0 = status("VmRSS:")
t0, c0 = time.perf_counter(), time.process_time()
res = P.align_passes(feats, band=band, refine_band=refine, points=points(feats.n, feats.m, truth), incremental=True)
init = (time.perf_counter() - t0, time.process_time() - c0)
rss1 = status("VmRSS:")
walls, cpus, pass1 = [], [], []
for k in range(n_edits):
    shift = 12 if k % 2 == 0 else -12
    t0, c0 = time.perf_counter(), time.process_time()
    res = P.align_passes(feats, band=band, refine_band=refine, points=points(feats.n, feats.m, truth, shift), previous=res, incremental=True)
    walls.append(time.perf_counter() - t0)
    cpus.append(time.process_time() - c0)
    pass1.append(res.pass1.solver.last_stats.seconds)
rss2 = status("VmRSS:")
print(json.dumps({"n": feats.n, "m": feats.m, "cells": [int(res.pass1.band.area), int(res.pass2.band.area)],
                  "init_wall": init[0], "init_cpu": init[1], "edit_wall": walls, "edit_cpu": cpus,
                  "edit_pass1": pass1, "rss_features_mb": rss0, "rss_after_solve_mb": rss1,
                  "rss_after_edits_mb": rss2, "hwm_mb": status("VmHWM:")}))
"""


def bench_long_edits(seconds_list=(120.0, 600.0), n_points: int = 9, n_edits: int = 10) -> list:
    """Engine time of one app edit (move the middle of ``n_points`` matching points by
    ±12 frames; ``pipeline.align_passes`` with the previous result: incremental pass 1 and
    pass 2, merge) on long pairs with a time band, now and at the baseline."""
    from benchmarks import long_pairs as LP
    from benchmarks.bench_splice_speed import time_band

    baseline = LP.baseline_tree()
    out = []
    for seconds in seconds_list:
        files = LP.pair_files(seconds)
        truth = np.load(files[2])
        n = truth.shape[0]
        label, band, refine = time_band(n, 120.0, LP.drift_seconds(truth, n, 120.0))
        for code, tree in (("today", baseline), ("now", None)):
            r = LP.run_child(
                CHILD_EDITS,
                *map(str, files),
                str(band),
                str(refine),
                str(n_points),
                str(n_edits),
                tree=tree,
            )
            r.update(code=code, band=label, seconds=seconds)
            print(json.dumps(r), flush=True)
            out.append(r)
    return out


def report_long_edits(rows) -> str:
    from benchmarks import long_pairs as LP

    lines = [
        "**Edits on long takes** (issue 13): the engine side of moving one matching point in "
        "the app: `pipeline.align_passes` with the previous result (incremental pass 1 and "
        "pass 2 `Aligner`s, merge), 9 points on the true path (tolerance 2), the middle one "
        "moved ±12 frames ten times; long pairs of `benchmarks/long_pairs.py` (real LAFAN1 "
        "captures in turn, re-timed hand take), time band. *today* = the same script on the "
        f"engine at `{LP.BASELINE}` (`HANDSPLICE_BASELINE`), in the same run. Memory: resident "
        "set after the features, after the "
        "first solve, after the edits (the solvers' stores).",
        "",
        "| pair | band (pass 1 / 2 cells) | code | first solve (CPU) | edit p50 / p95 wall | "
        "edit p50 / p95 CPU | of which pass 1 (p50) | RSS features → solved → edited |",
        "|---|---|---|---:|---:|---:|---:|---|",
    ]
    for r in rows:
        w, c = np.array(r["edit_wall"]), np.array(r["edit_cpu"])
        lines.append(
            f"| {r['seconds'] / 60:g} min ({r['n']:,} frames) | {r['band']} "
            f"({r['cells'][0] / 1e6:.1f} M / {r['cells'][1] / 1e6:.1f} M) | {r['code']} | "
            f"{r['init_cpu']:.2f} s | {np.median(w) * 1e3:.0f} / {np.percentile(w, 95) * 1e3:.0f} ms | "
            f"**{np.median(c) * 1e3:.0f} / {np.percentile(c, 95) * 1e3:.0f} ms** | "
            f"{np.median(r['edit_pass1']) * 1e3:.0f} ms | {r['rss_features_mb']:.0f} → "
            f"{r['rss_after_solve_mb']:.0f} → {r['rss_after_edits_mb']:.0f} MB |"
        )
    lines += [
        "",
        "Goals (issue 13, the app's whole drag → new path): ≤ 150 ms p95 at 2 minutes, "
        "≤ 300 ms at 10 minutes; this is the engine's share. An edit recomputes the rows of "
        "the two segments beside the moved point (here 2/10 of the take) in both passes.",
    ]
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small sizes, print only")
    parser.add_argument("--no-memory", action="store_true", help="skip the 20,000 runs")
    parser.add_argument(
        "--long-edits",
        action="store_true",
        help="only the long-take edit runs (RESULTS.md section dtw_long_edits)",
    )
    parser.add_argument(
        "--minutes",
        type=float,
        nargs="+",
        default=[2.0, 10.0],
        help="pair lengths for --long-edits",
    )
    args = parser.parse_args(argv)
    if args.long_edits:
        text = report_long_edits(bench_long_edits(tuple(60.0 * x for x in args.minutes)))
        print(text)
        from benchmarks._results import write_section

        write_section("dtw_long_edits_" + "_".join(f"{x:g}min" for x in args.minutes), text)
        return 0
    rng = np.random.default_rng(0)
    sizes = ((500, 5), (1000, 5)) if args.quick else ((2000, 41), (8000, 9))
    speed = []
    for n, reps in sizes:
        speed.append(bench_speed(n, reps, rng))
        print(json.dumps(speed[-1]), flush=True)
    resolve = bench_resolve(600 if args.quick else 2000, 5 if args.quick else 25, rng)
    print(json.dumps(resolve), flush=True)
    memory = None
    if not (args.quick or args.no_memory):
        n = 20000
        memory = {
            "n": n,
            "ours": run_child(CHILD_OURS, str(n)),
            "dtai": run_child(CHILD_DTAI, str(n)),
        }
        print(json.dumps(memory), flush=True)
    warmup = bench_warmup()
    print(json.dumps(warmup), flush=True)
    text = report(speed, resolve, memory, warmup)
    print(text)
    if not args.quick:
        from benchmarks._results import write_section

        write_section("dtw", text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
