"""DTW benchmark: engine.dtw against dtaidistance, side by side in one run.

    .venv/bin/python -m benchmarks.bench_dtw            # full run, writes RESULTS.md section "dtw"
    .venv/bin/python -m benchmarks.bench_dtw --quick    # small sizes, prints only

Measures (issue 4):
* time of ``align_features`` (12-D float64, Sakoe-Chiba band 30 %, path
  returned) and of dtaidistance's C ``dtw_ndim.warping_path`` with the same
  window, n = m = 2,000 and 8,000; ns per band cell and the time ratio;
* peak resident memory (VmHWM of a child process) at n = m = 20,000 for
  both;
* ``Aligner`` re-solve after moving one matching point vs. a full solve,
  2,000 x 2,000;
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


def bench_resolve(n: int, reps: int, rng) -> list[dict]:
    """Aligner re-solve vs full solve, 5 matching points every n/6 frames."""
    from engine.dtw import Aligner, Band

    a, b = features(n, rng), features(n, rng)
    xs = [round(n * k / 6) for k in range(1, 6)]
    base = [[x, x, 2] for x in xs]

    def band_for(points):
        return Band.from_constraints(n, n, WIDTH, points)

    full_band = band_for(base)
    solver = Aligner(a, b)
    solver.solve(full_band)  # warm-up
    t_full = []
    for _ in range(reps):
        solver.reset()
        t0 = time.perf_counter()
        solver.solve(full_band)
        t_full.append(time.perf_counter() - t0)
    full = statistics.median(t_full)
    rows = []
    scenarios = ((4, "last point (x = 5n/6)"), (3, "point x = 2n/3"), (2, "middle point (x = n/2)"))
    for k, label in scenarios:
        first_times, drag_times, fractions = [], [], []
        for _ in range(reps):
            solver.reset()
            solver.solve(full_band)
            for step in range(3):  # first edit, then two more moves of the same point
                pts = [list(p) for p in base]
                pts[k][1] += 12 if step % 2 == 0 else -12
                band = band_for(pts)
                t0 = time.perf_counter()
                solver.solve(band)
                dt = time.perf_counter() - t0
                if step == 0:
                    first_times.append(dt)
                else:
                    drag_times.append(dt)
                    fractions.append(solver.last_stats.fraction)
        rows.append(
            {
                "moved": label,
                "x": xs[k],
                "first_s": statistics.median(first_times),
                "drag_s": statistics.median(drag_times),
                "first_ratio": statistics.median(first_times) / full,
                "drag_ratio": statistics.median(drag_times) / full,
                "drag_cells": statistics.median(fractions),
                "full_s": full,
                "cells": full_band.area,
            }
        )
    return rows


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
    full = resolve[0]["full_s"]
    lines += [
        f"**Incremental re-solve** (`Aligner`, n = m = 2,000, {D}-D, band 30 %, five matching "
        f"points every n/6 frames with tolerance 2; {resolve[0]['cells']:,} band cells). Full "
        f"solve {full * 1e3:.1f} ms (median). A point is moved by ±12 hand frames; *first* is the "
        "first edit after a full solve (forward rows from the previous point onwards), *drag* "
        "the median of further moves of the same point (only the two segments beside it):",
        "",
        "| moved point | first edit | ratio | drag | ratio | cells recomputed (drag) |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for r in resolve:
        lines.append(
            f"| {r['moved']} | {r['first_s'] * 1e3:.1f} ms | {r['first_ratio']:.2f} | "
            f"{r['drag_s'] * 1e3:.1f} ms | **{r['drag_ratio']:.2f}** | {r['drag_cells']:.0%} |"
        )
    lines += [
        "",
        "Target: ≤ 0.40 of a full solve for a point in the last third.",
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


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small sizes, print only")
    parser.add_argument("--no-memory", action="store_true", help="skip the 20,000 runs")
    args = parser.parse_args(argv)
    rng = np.random.default_rng(0)
    sizes = ((500, 5), (1000, 5)) if args.quick else ((2000, 41), (8000, 9))
    speed = []
    for n, reps in sizes:
        speed.append(bench_speed(n, reps, rng))
        print(json.dumps(speed[-1]), flush=True)
    resolve = bench_resolve(600 if args.quick else 2000, 5 if args.quick else 25, rng)
    for r in resolve:
        print(json.dumps(r), flush=True)
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
