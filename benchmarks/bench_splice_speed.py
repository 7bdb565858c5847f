"""Splice engine speed and memory (issues 5 and 13), each beside today's code in the same run.

Run: ``.venv/bin/python -m benchmarks.bench_splice_speed [--quick] [--no-10min]``

* **569-frame pair** (the size of the paper's "Directions", 10.95 s in Matlab): a
  LAFAN1 crop (30 fps) with synthetic fingers, split into a body and a hand take
  (``benchmarks.split``). Engine time = prepare + pass 1 + pass 2 + merge +
  transfer, warm, median of 10 calls. Goal < 50 ms.
* **Pass-1 kernel**: ns per band cell of the pass-1 DTW (``splice_phase`` metric, its
  row kernel now) on the 2-minute pair's rows, 30 % band, beside today's per-cell
  kernel (``engine/align/metrics.py`` as at ``long_pairs.BASELINE``, loaded from git) and a
  plain DTW of 1-D features (the recurrence alone); same cost and path checked.
  CPU time (``thread_time``): the machine is shared, wall time is noise.
* **2-minute and 10-minute pairs at 120 fps** (14,400 and 72,000 frames,
  ``long_pairs.make_long_pair``: real LAFAN1 captures played in turn, the hand take
  re-timed by a smooth random warp; BVH files read back as the CLI does). Each run is
  a fresh child process: read both files, warm-up splice of a 600-frame crop (JIT),
  then one timed ``pipeline.splice`` (engine stages: prepare, passes, merge,
  transfer; writing the output is not counted). Today's code runs the same script
  from ``git archive BASELINE``. Bands: the paper's 30 % (refine 10 %) and a time band
  of ±4 s (refine ±4/3 s, the paper's ratio), or wider when the pair's true drift
  needs it. Peak = VmHWM of the child (whole process: interpreter, libraries, both
  takes, warm-up). Accuracy: median |warp − truth| in hand frames.
* ``--engine``: only the 2- and 10-minute pairs with default bands, beside
  :data:`ENGINE_BASE` (the chunked BVH reader and the blend in seconds), with the peak
  while reading and while splicing apart (section ``splice_speed_engine``).
* ``--pass1``: pass 1's row kernel (``engine/align/phase_kernel.py``) as at
  :data:`STAGE_BASE` beside this checkout's, both on the 2-minute splice's own pass-1 rows,
  band and open ends: CPU ns per band cell of the forward pass (interleaved runs), the
  backpointers, last row/column and total compared (section ``splice_speed_pass1``).
* ``--pass1-problems``: the same comparison on each problem pass 1 of the 2-minute splice
  solves (the coarse band, the fine band around the coarse path, and the W1 band at full
  rate), ``prepare`` included and timed apart (section ``splice_speed_pass1_problems``;
  ``HANDSPLICE_STAGE_BASE`` names the *before* code).
* ``--stages``: CPU time of every engine stage of the 2-minute (and 10-minute) splice,
  warm (median of :data:`STAGE_SPLICES` splices per child process, children of both codes
  alternately), beside :data:`STAGE_BASE`; the spliced take's bytes and the pass-1 and
  pass-2 paths compared (section ``splice_speed_stages``).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import statistics
import subprocess
import sys
import time

import numpy as np

from benchmarks import long_pairs as LP
from benchmarks._results import write_section

PAPER_569_S = 10.95
TIME_BAND_S = 4.0
#: the code before the pass-2 row kernel (main when that work began): ``--pass2``'s "before"
PASS2_BASE = os.environ.get("HANDSPLICE_PASS2_BASE", "3539261")
#: main when issue 13's reader and merge work began: ``--engine``'s "before"
ENGINE_BASE = os.environ.get("HANDSPLICE_ENGINE_BASE", "46e6d22")
#: main when the last engine-stage work (pass1e) began: ``--stages``' and ``--pass1``'s
#: "before" (earlier steps compared with ``b3485ff``, ``d94916c``, ``6b1b359``, ``efbcb40``)
STAGE_BASE = os.environ.get("HANDSPLICE_STAGE_BASE", "cbd2ea7")
#: timed splices per child process in ``--stages`` (the first warm one included)
STAGE_SPLICES = 3

#: ``--stages`` child: the pipeline's stage clocks read CPU time (``time.process_time``,
#: the process's threads together) instead of wall time: the module's ``time`` is
#: swapped for a namespace whose ``perf_counter`` is ``process_time``
CHILD_STAGES = r"""
import hashlib, json, statistics, sys, time, types
import numpy as np
from engine.io.bvh import read_bvh, format_bvh
from engine.splice import pipeline as P
P.time = types.SimpleNamespace(perf_counter=time.process_time)
body_p, hand_p, reps = sys.argv[1], sys.argv[2], int(sys.argv[3])
body, hand = read_bvh(body_p), read_bvh(hand_p)
P.splice(body.frames(0, 600), hand.frames(0, 600))
def hwm_mb():
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
with open("/proc/self/clear_refs", "w") as fh:
    fh.write("5")  # the peak counter from here: the splices only
runs = []
for _ in range(reps):
    c0 = time.process_time()
    r = P.splice(body, hand)
    cpu = time.process_time() - c0
    runs.append(dict(r.timings, cpu=cpu))
keys = ["cpu", "prepare", "prepare.markers", "prepare.features", "pass1", "pass2", "merge",
        "transfer"]
a = r.alignment
digest = lambda x: hashlib.sha256(np.ascontiguousarray(x).tobytes()).hexdigest()[:16]
print(json.dumps({"frames": [body.n_frames, hand.n_frames], "reps": reps,
                  "stages": {k: statistics.median(x[k] for x in runs) for k in keys},
                  "all": [x["cpu"] for x in runs], "peak_splice_mb": hwm_mb(),
                  "path1": digest(a.pass1.path), "path2": digest(a.pass2.path),
                  "map": digest(np.asarray(a.map)),
                  "bvh": hashlib.sha256(format_bvh(r.motion).encode()).hexdigest()[:16]}))
"""

CHILD = r"""
import json, sys, time
import numpy as np
def hwm_kb():
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1])
def rss_kb():
    for line in open("/proc/self/status"):
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
from engine.io.bvh import read_bvh
from engine.splice import pipeline as P
body_p, hand_p, truth_p = sys.argv[1:4]
band, refine = [None if v == "default" else float(v) for v in sys.argv[4:6]]
t0 = time.perf_counter()
body, hand = read_bvh(body_p), read_bvh(hand_p)
read_s = time.perf_counter() - t0
P.splice(body.frames(0, 600), hand.frames(0, 600), band=band, refine_band=refine)
hwm_read = hwm_kb()
rss0 = rss_kb()
with open("/proc/self/clear_refs", "w") as fh:
    fh.write("5")
t0, c0 = time.perf_counter(), time.process_time()
r = P.splice(body, hand, band=band, refine_band=refine)
wall, cpu = time.perf_counter() - t0, time.process_time() - c0
peak = hwm_kb()
truth = np.load(truth_p)
err = np.abs(np.asarray(r.alignment.map) - truth)
print(json.dumps({"frames": [body.n_frames, hand.n_frames], "read_s": read_s, "wall_s": wall,
                  "cpu_s": cpu, "stages": r.timings, "rss_before_mb": rss0 / 1024,
                  "peak_read_mb": hwm_read / 1024, "peak_splice_mb": peak / 1024,
                  "peak_mb": max(hwm_read, peak) / 1024,
                  "cells": [int(r.alignment.pass1.band.area), int(r.alignment.pass2.band.area)],
                  "err_median": float(np.median(err)), "err_p95": float(np.percentile(err, 95))}))
"""


def make_pair(n: int, fps: float, seed: int = 0):
    """A LAFAN1 crop of ``n`` frames at ``fps`` split into (body, hand) (the short pair)."""
    from benchmarks.split import MOCAP, add_fingers, make_hand_take, strip_fingers
    from engine.io.bvh import read_bvh
    from engine.model.kinematics import resample
    from engine.model.roles import find_roles

    base = read_bvh(MOCAP / "lafan1/multipleActions1_subject1.bvh")
    if fps != base.fps:
        base = resample(base, fps)
    base = base.frames(0, n)
    rng = np.random.default_rng(seed)
    full = add_fingers(base, rng)
    roles = find_roles(full.skeleton)
    body = strip_fingers(full, roles)
    hand, _, _ = make_hand_take(
        full,
        rng,
        fps=fps,
        scale=1.0,
        warp_sigma=0.2,
        shrink=0.6,
        yaw_deg=20.0,
        noise_deg=0.5,
        roles=roles,
    )
    return body, hand


def bench_short(reps: int) -> dict:
    from engine.splice import pipeline as P

    body, hand = make_pair(569, 30.0)
    t0 = time.perf_counter()
    P.splice(body, hand)
    cold = time.perf_counter() - t0
    runs, stages = [], []
    for _ in range(reps):
        t0 = time.perf_counter()
        r = P.splice(body, hand)
        runs.append(time.perf_counter() - t0)
        stages.append(r.timings)
    return {
        "frames": [body.n_frames, hand.n_frames],
        "warm_s": float(np.median(runs)),
        "cold_s": cold,
        "stages": {k: float(np.median([s[k] for s in stages])) for k in stages[0]},
    }


def _old_metrics(ref: str = LP.BASELINE):
    """engine/align/metrics.py as at ``ref``, imported as a separate module."""
    src = subprocess.run(
        ["git", "show", f"{ref}:engine/align/metrics.py"],
        cwd=LP.ROOT,
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    path = LP.CACHE / f"old_metrics_{ref}.py"
    LP.CACHE.mkdir(parents=True, exist_ok=True)
    if not path.exists() or path.read_text() != src:
        path.write_text(src)
    name = f"old_metrics_{ref}"
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod  # dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


def bench_pass1_kernel(body_p, hand_p, reps: int) -> dict:
    """ns per band cell of pass 1: the row kernel, today's per-cell kernel, DTW alone."""
    from engine.dtw import Band, align_features, register_metric
    from engine.io.bvh import read_bvh
    from engine.splice import pipeline as P

    old = _old_metrics()
    register_metric("splice_phase_baseline", old.splice_phase, replace=True)
    feats = P.prepare(read_bvh(body_p), read_bvh(hand_p))
    a, b = feats.pass1_rows
    oa, ob = old.phase_rows(
        feats.body_phase,
        feats.hand_phase,
        theta=feats.theta,
        n_bins=feats.n_bins,
        yaw_offset=feats.yaw_offset,
        step=feats.params["step1"],
    )
    band = Band.from_constraints(feats.n, feats.m, 0.3, [])
    rng = np.random.default_rng(0)
    x, y = rng.standard_normal((feats.n, 1)), rng.standard_normal((feats.m, 1))
    runs = {
        "new": lambda: align_features(a, b, band, metric="splice_phase"),
        "old": lambda: align_features(oa, ob, band, metric="splice_phase_baseline"),
        "dtw": lambda: align_features(x, y, band),
    }
    res = {k: f() for k, f in runs.items()}  # warm-up (JIT) and results
    same_path = bool(np.array_equal(res["new"].path, res["old"].path))
    times = {k: [] for k in runs}
    for _ in range(reps):  # interleaved: load on the shared machine hits all three
        for k, f in runs.items():
            c0 = time.thread_time()
            f()
            times[k].append(time.thread_time() - c0)
    ns = {k: statistics.median(v) / band.area * 1e9 for k, v in times.items()}
    ratio = statistics.median(n / o for n, o in zip(times["new"], times["old"]))
    return {
        "cells": band.area,
        "ns": ns,
        "ratio": ratio,
        "same_path": same_path,
        "cost_new": res["new"].cost,
        "cost_old": res["old"].cost,
        "reps": reps,
    }


def _module_at(ref: str, path: str, name: str):
    """The module ``path`` (e.g. ``engine/align/phase_kernel.py``) as at ``ref``, imported
    under ``name`` (numba caches it by its own file)."""
    src = subprocess.run(
        ["git", "show", f"{ref}:{path}"], cwd=LP.ROOT, capture_output=True, text=True, check=True
    ).stdout
    file = LP.CACHE / f"{name}.py"
    LP.CACHE.mkdir(parents=True, exist_ok=True)
    if not file.exists() or file.read_text() != src:
        file.write_text(src)
    spec = importlib.util.spec_from_file_location(name, file)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


def _pass1_ab(old_k, now_k, a, b, band, ends, reps: int) -> dict:
    """CPU time of two pass-1 row kernels (modules ``old_k``, ``now_k``: ``prepare`` then
    ``forward``) on one problem, interleaved; the backpointers, last row/column and total
    compared."""
    n, m = band.n, band.m
    gamma = np.empty(1)

    def run(mod):
        state = mod.prepare(a, b)
        bp = np.empty(band.area, np.uint8)
        last_col, last_row = np.empty(n), np.empty(m)
        bad, total = mod.forward(
            state, band.lo, band.hi, band.start, 0, n, bp, gamma, 0, ends, last_col, last_row
        )
        return bad, total, bp, last_col, last_row

    res = {"old": run(old_k), "now": run(now_k)}
    same = res["old"][:2] == res["now"][:2] and all(
        np.array_equal(x, y) for x, y in zip(res["old"][2:], res["now"][2:])
    )
    del res
    times = {"old": [], "now": []}
    prep = {"old": [], "now": []}
    for _ in range(reps):
        for k, mod in (("old", old_k), ("now", now_k)):
            c0 = time.thread_time()
            mod.prepare(a, b)
            prep[k].append(time.thread_time() - c0)
            c0 = time.thread_time()
            run(mod)
            times[k].append(time.thread_time() - c0)
    return {
        "cells": int(band.area),
        "frames": [n, m],
        "ns": {k: statistics.median(v) / band.area * 1e9 for k, v in times.items()},
        "ns_min": {k: min(v) / band.area * 1e9 for k, v in times.items()},
        "prepare_ms": {k: statistics.median(v) * 1e3 for k, v in prep.items()},
        "s": {k: statistics.median(v) for k, v in times.items()},
        "ratio": statistics.median(x / y for x, y in zip(times["now"], times["old"])),
        "same": bool(same),
        "reps": reps,
    }


def bench_pass1_rows(body_p, hand_p, reps: int) -> dict:
    """CPU ns per band cell of pass 1's forward pass (row kernel at :data:`STAGE_BASE` and
    now) on the 2-minute splice's own rows, W1 band and open ends; same outputs checked."""
    from engine.align import phase_kernel as now_k
    from engine.io.bvh import read_bvh
    from engine.splice import pipeline as P

    old_k = _module_at(STAGE_BASE, "engine/align/phase_kernel.py", f"old_phase_kernel_{STAGE_BASE}")
    r = P.splice(read_bvh(body_p), read_bvh(hand_p))
    p1 = r.alignment.pass1
    return _pass1_ab(old_k, now_k, *p1.rows, p1.band, p1.ends.array(), reps)


def bench_pass1_problems(body_p, hand_p, reps: int) -> dict:
    """:func:`_pass1_ab` on each problem pass 1 of the 2-minute splice solves: the coarse
    band (multi-resolution pass 1's first step), the fine band around it, and the whole W1
    band at full rate (pass 1 without the coarse step, ``--pass1``'s problem)."""
    from engine.align import phase_kernel as now_k
    from engine.io.bvh import read_bvh
    from engine.splice import pipeline as P

    old_k = _module_at(STAGE_BASE, "engine/align/phase_kernel.py", f"old_phase_kernel_{STAGE_BASE}")
    feats = P.prepare(read_bvh(body_p), read_bvh(hand_p))
    p1 = P.align_passes(feats).pass1
    co = p1.coarse
    ends = p1.ends.array()
    problems = {
        "coarse": (*feats.coarse.rows, co.band, co.ends.array()),
        "fine": (*p1.rows, co.fine_band, ends),
        "W1, full rate": (*p1.rows, p1.band, ends),
    }
    return {name: _pass1_ab(old_k, now_k, *pr, reps) for name, pr in problems.items()}


def report_pass1_problems(res: dict, load, tag: str = "pass1ns") -> str:
    """The ``--pass1-problems`` section (``tag``: the step named in its title)."""
    lines = [
        f"## Splice speed: pass 1 per band cell on the splice's own problems ({tag}, issue 13)",
        "",
        f"*before* = `engine/align/phase_kernel.py` at `{STAGE_BASE}`, *now* = this checkout's, "
        "both in this process (`bench_splice_speed --pass1-problems`), on the problems pass 1 "
        "of the 2-minute splice (14,400 x 14,400 frames, default band) solves: the coarse band "
        "(every 4th frame), the fine band around the coarse path, and the whole W1 band at full "
        "rate (pass 1 without the coarse step; `--pass1`'s problem). Each run = `prepare` "
        "(the rows unpacked and checked) + the forward pass, CPU time (`thread_time`), "
        f"{next(iter(res.values()))['reps']} interleaved runs of each code.",
        "",
        "| problem | band cells | before: ns per cell, median / min | now: median / min "
        "| now / before | prepare before / now (ms) | same outputs |",
        "|---|---:|---:|---:|---:|---:|---|",
    ]
    for name, k in res.items():
        lines.append(
            f"| {name} | {k['cells']:,} | {k['ns']['old']:.2f} / {k['ns_min']['old']:.2f} | "
            f"**{k['ns']['now']:.2f}** / {k['ns_min']['now']:.2f} | **{k['ratio']:.2f}** | "
            f"{k['prepare_ms']['old']:.1f} / {k['prepare_ms']['now']:.1f} | {k['same']} |"
        )
    co, fi = res["coarse"], res["fine"]
    cells = co["cells"] + fi["cells"]
    old = (co["s"]["old"] + fi["s"]["old"]) / cells * 1e9
    now = (co["s"]["now"] + fi["s"]["now"]) / cells * 1e9
    lines += [
        "",
        f"Pass 1 as the splice runs it (coarse + fine, {cells:,} cells; medians): "
        f"before {old:.2f}, now **{now:.2f}** ns per band cell ({now / old:.2f}). "
        "*Same outputs* = backpointers of every band cell, last row and column, total.",
        "",
        f"Load average (1 min) {load[0]:.1f} at the start, {load[1]:.1f} at the end "
        "(2 cores, shared). Target (issue 13): ≤ 5 ns per band cell.",
        "",
        "Notes on what changed are written by hand under the figures (a re-run rewrites the "
        "whole section: carry them over from `git log -p benchmarks/RESULTS.md`).",
    ]
    return "\n".join(lines)


def report_pass1(k, load, tag: str = "") -> str:
    """The ``--pass1`` section (``tag`` unused: its title names no step)."""
    return "\n".join(
        [
            "## Splice speed: the pass-1 row kernel (issue 13)",
            "",
            f"*before* = `engine/align/phase_kernel.py` at `{STAGE_BASE}`, *now* = this "
            "checkout's, both in this process (`bench_splice_speed --pass1`), on the 2-minute "
            f"pair's own pass-1 rows, band and open ends ({k['frames'][0]:,} x "
            f"{k['frames'][1]:,} frames, {k['cells']:,} band cells): the forward pass with its "
            "row preparation, CPU time (`thread_time`) per band cell, "
            f"{k['reps']} interleaved runs of each.",
            "",
            "| kernel | ns per band cell, median | min |",
            "|---|---:|---:|",
            f"| before | {k['ns']['old']:.2f} | {k['ns_min']['old']:.2f} |",
            f"| now | **{k['ns']['now']:.2f}** | {k['ns_min']['now']:.2f} |",
            "",
            f"Now / before: **{k['ratio']:.2f}** (median of paired ratios). Same backpointers "
            f"(every band cell), last row and column, and total: {k['same']}.",
            "",
            f"Load average (1 min) {load[0]:.1f} at the start, {load[1]:.1f} at the end "
            "(2 cores, shared). Target (issue 13): ≤ 5 ns per band cell.",
            "",
            "**What changed** (`engine/align/phase_kernel.py`, same operands in the same "
            "order): written by hand under the figures (a re-run rewrites the whole section: "
            "carry the notes over from `git log -p benchmarks/RESULTS.md`).",
        ]
    )


def bench_pass2_kernel(body_p, hand_p, reps: int) -> dict:
    """ns per band cell of pass 2 (both solves' kind: the open-ends solve of the splice) on
    the pair's real pass-2 rows and band: the row kernel now, and the per-cell
    ``splice_angle`` of ``engine/align/metrics.py`` as at :data:`PASS2_BASE` (its own rows);
    same path and cost checked."""
    from engine.dtw import align_features, register_metric
    from engine.io.bvh import read_bvh
    from engine.splice import pipeline as P

    old = _old_metrics(PASS2_BASE)
    register_metric("splice_angle_before", old.splice_angle, replace=True)
    feats = P.prepare(read_bvh(body_p), read_bvh(hand_p))
    res = P.align_passes(feats)
    a, b = res.pass2.rows
    band, ends = res.pass2.band, res.pass2.ends
    step = feats.params.get("step2", 0.0)
    oa = old.angle_features(feats.body_markers, -res.body_heading).rows(step)
    ob = old.angle_features(feats.hand_markers, -res.hand_heading).rows()
    runs = {
        "new": lambda: align_features(a, b, band, metric="splice_angle", ends=ends),
        "old": lambda: align_features(oa, ob, band, metric="splice_angle_before", ends=ends),
    }
    out = {k: f() for k, f in runs.items()}  # warm-up (JIT) and results
    times = {k: [] for k in runs}
    for _ in range(reps):  # interleaved
        for k, f in runs.items():
            c0 = time.thread_time()
            f()
            times[k].append(time.thread_time() - c0)
    return {
        "cells": int(band.area),
        "ns": {k: statistics.median(v) / band.area * 1e9 for k, v in times.items()},
        "ratio": statistics.median(n / o for n, o in zip(times["new"], times["old"])),
        "same_path": bool(np.array_equal(out["new"].path, out["old"].path)),
        "cost_new": float(out["new"].cost),
        "cost_old": float(out["old"].cost),
        "reps": reps,
    }


def bench_long_default(seconds: float, fps: float, before, reps: int, drift_band=False) -> dict:
    """Splices of the ``seconds`` pair with the default bands (or, ``drift_band``, the time
    band of :func:`time_band` that covers the pair's true drift), the code at
    :data:`PASS2_BASE` and now alternately (fresh child each)."""
    files = LP.pair_files(seconds, fps)
    truth = np.load(files[2])
    n = truth.shape[0]
    label, band, refine = "default", "default", "default"
    if drift_band:
        label, band, refine = time_band(n, fps, LP.drift_seconds(truth, n, fps))
    out = {"seconds": seconds, "n": n, "runs": []}
    for _ in range(reps):
        for code, tree in (("before", before), ("now", None)):
            r = long_run(files, str(band), str(refine), tree)
            r.update(code=code, band=label)
            print(json.dumps(r), flush=True)
            out["runs"].append(r)
    return out


def report_pass2(kernel, longs) -> str:
    k = kernel
    lines = [
        "## Splice speed: the pass-2 row kernel (issue 13)",
        "",
        f"*before* = the engine at `{PASS2_BASE}` (main before the pass-2 kernel), *now* = "
        "this branch, in the same run (`bench_splice_speed --pass2`). Machine shared "
        "(2 cores, other sessions): CPU time and ratios are the figures to read.",
        "",
        f"**Pass-2 kernel**, 2-minute pair (14,400 x 14,400 at 120 fps), the splice's own "
        f"pass-2 band and open ends ({k['cells']:,} cells), CPU time per band cell, median "
        f"of {k['reps']} interleaved runs:",
        "",
        "| kernel | ns per band cell |",
        "|---|---:|",
        f"| before: per-cell `splice_angle` (rotate by cross products, libm arccos) | "
        f"{k['ns']['old']:.1f} |",
        f"| now: row kernel (`engine/align/angle_kernel.py`: dot products of per-frame vectors, "
        f"vectorised fdlibm arccos) | **{k['ns']['new']:.1f}** |",
        "",
        f"Now / before: **{k['ratio']:.2f}** (median of paired ratios); same path: "
        f"{k['same_path']}; cost {k['cost_new']:.9f} vs {k['cost_old']:.9f}.",
        "",
        "**Whole splices, default bands** (pass 1 W1 = 1.5 s x sqrt(T), pass 2 W2 = 2 s; "
        "BVH read back; one fresh child process per run after a 600-frame warm-up splice; "
        "engine stages prepare + passes + merge + transfer; peak = VmHWM of the process):",
        "",
        "| pair | band | code | wall | CPU | prepare / pass 1 / pass 2 / merge / transfer (wall, "
        "s) | pass-1 / pass-2 cells | peak | timing error median / p95 (frames) |",
        "|---|---|---|---:|---:|---|---|---:|---|",
    ]
    for lg in longs:
        for r in lg["runs"]:
            st = r["stages"]
            lines.append(
                f"| {lg['seconds'] / 60:g} min ({r['frames'][0]:,} x {r['frames'][1]:,}) | "
                f"{r['band']} | {r['code']} | {r['wall_s']:.2f} s | {r['cpu_s']:.2f} s | "
                f"{st['prepare']:.2f} / {st['pass1']:.2f} / {st['pass2']:.2f} / "
                f"{st['merge']:.2f} / {st['transfer']:.2f} | "
                f"{r['cells'][0] / 1e6:.1f} M / {r['cells'][1] / 1e6:.1f} M | "
                f"{r['peak_mb']:.0f} MB | {r['err_median']:.2f} / {r['err_p95']:.2f} |"
            )
    lines.append("")
    for lg in longs:
        by = {c: [r for r in lg["runs"] if r["code"] == c] for c in ("before", "now")}
        if by["before"] and by["now"]:
            cpu = statistics.median(
                n["cpu_s"] / b["cpu_s"] for b, n in zip(by["before"], by["now"])
            )
            p2 = statistics.median(
                n["stages"]["pass2"] / b["stages"]["pass2"] for b, n in zip(by["before"], by["now"])
            )
            nw, bf = by["now"][0], by["before"][0]
            lines.append(
                f"- {lg['seconds'] / 60:g} min: now / before CPU time **{cpu:.2f}**, pass-2 "
                f"wall {p2:.2f}; peak {nw['peak_mb']:.0f} vs {bf['peak_mb']:.0f} MB, of which "
                f"while splicing (peak counter reset after reading) {nw['peak_splice_mb']:.0f} "
                f"vs {bf['peak_splice_mb']:.0f} MB, while reading the two BVH files "
                f"{nw['peak_read_mb']:.0f} vs {bf['peak_read_mb']:.0f} MB."
            )
    lines += [
        "",
        "The 10-minute pair runs with a time band covering its true drift (±6 s, refine ±2 s), "
        "as in the runs before the default pass-1 band was capped to fit "
        "`engine.base.limits.MAX_BAND_CELLS` (36.7 s = 438.8 M cells was refused; now 14.7 s).",
        "",
        "Goals (issue 13): 2-minute pair ≤ 1.0 s warm, peak ≤ 600 MB, median timing error ≤ 1 "
        "frame; 10-minute pair ≤ 10 s, peak ≤ 1.5 GB.",
    ]
    return "\n".join(lines)


def report_engine(longs, load) -> str:
    """The ``--engine`` section: whole splices beside :data:`ENGINE_BASE`."""
    lines = [
        "## Splice speed and memory: the chunked BVH reader and the blend in seconds (issue 13)",
        "",
        f"*before* = the engine at `{ENGINE_BASE}` (main when this work began), *now* = this "
        "branch, alternately in the same run (`bench_splice_speed --engine`), default bands "
        "(pass 1 W1 = 1.5 s x sqrt(T) capped to the cell limit, pass 2 W2 = 2 s). Each run "
        "is a fresh child process: read both BVH files, a 600-frame warm-up splice, then one "
        "timed `pipeline.splice` (prepare + passes + merge + transfer). Peak = VmHWM of the "
        "process; *reading* = its peak after reading both files and the warm-up, "
        "*splicing* = the peak counter reset (`/proc/self/clear_refs`) before the timed "
        "splice. Timing error: |map - truth| in hand frames.",
        "",
        "| pair | code | read (wall) | splice wall | splice CPU | prepare / pass 1 / pass 2 / "
        "merge / transfer (wall, s) | pass-1 / pass-2 cells | peak reading | peak splicing | "
        "peak | timing error median / p95 (frames) |",
        "|---|---|---:|---:|---:|---|---|---:|---:|---:|---|",
    ]
    for lg in longs:
        for r in lg["runs"]:
            st = r["stages"]
            lines.append(
                f"| {lg['seconds'] / 60:g} min ({r['frames'][0]:,} x {r['frames'][1]:,}) | "
                f"{r['code']} | {r['read_s']:.1f} s | {r['wall_s']:.2f} s | {r['cpu_s']:.2f} s | "
                f"{st['prepare']:.2f} / {st['pass1']:.2f} / {st['pass2']:.2f} / "
                f"{st['merge']:.2f} / {st['transfer']:.2f} | "
                f"{r['cells'][0] / 1e6:.1f} M / {r['cells'][1] / 1e6:.1f} M | "
                f"{r['peak_read_mb']:.0f} MB | {r['peak_splice_mb']:.0f} MB | "
                f"**{r['peak_mb']:.0f} MB** | {r['err_median']:.2f} / {r['err_p95']:.2f} |"
            )
    lines.append("")
    for lg in longs:
        by = {c: [r for r in lg["runs"] if r["code"] == c] for c in ("before", "now")}
        if by["before"] and by["now"]:
            ratio = {
                k: statistics.median(n[k] / b[k] for b, n in zip(by["before"], by["now"]))
                for k in ("cpu_s", "read_s", "peak_mb", "peak_read_mb")
            }
            lines.append(
                f"- {lg['seconds'] / 60:g} min, now / before: process peak **{ratio['peak_mb']:.2f}**, "
                f"peak while reading {ratio['peak_read_mb']:.2f}, reading time "
                f"{ratio['read_s']:.2f}, splice CPU time {ratio['cpu_s']:.2f}."
            )
    lines += [
        "",
        f"Load average (1 min) {load[0]:.1f} at the start, {load[1]:.1f} at the end, on 2 cores "
        "shared by five sessions and a fresh-machine check: wall times are several times the "
        "CPU times; read the ratios and the CPU times.",
        "",
        "Goals (issue 13): 2-minute pair ≤ 1.0 s warm, peak ≤ 600 MB, median timing error ≤ 1 "
        "frame; 10-minute pair ≤ 10 s, peak ≤ 1.5 GB.",
    ]
    return "\n".join(lines)


STAGE_KEYS = ("prepare.markers", "prepare.features", "pass1", "pass2", "merge", "transfer")


def bench_stages(seconds: float, fps: float, before, children: int) -> dict:
    """CPU time per stage of the ``seconds`` pair, default bands: ``children`` child
    processes of each code, alternately, :data:`STAGE_SPLICES` warm splices in each."""
    body_p, hand_p, _ = LP.pair_files(seconds, fps)
    out = {"seconds": seconds, "runs": []}
    for _ in range(children):
        for code, tree in (("before", before), ("now", None)):
            r = LP.run_child(CHILD_STAGES, str(body_p), str(hand_p), str(STAGE_SPLICES), tree=tree)
            r.update(code=code)
            print(json.dumps(r), flush=True)
            out["runs"].append(r)
    return out


def _peak(runs) -> str:
    """Largest VmHWM of the children while splicing (MB), or a dash (older children)."""
    peaks = [r["peak_splice_mb"] for r in runs if "peak_splice_mb" in r]
    return f"{max(peaks):.0f} MB" if peaks else "–"


def report_stages(longs, load) -> str:
    """The ``--stages`` section: CPU time per stage beside :data:`STAGE_BASE`."""
    lines = [
        "## Splice speed: CPU time per engine stage (issue 13)",
        "",
        f"*before* = the engine at `{STAGE_BASE}` (main when this work began), *now* = this "
        "branch, child processes of both codes alternately (`bench_splice_speed --stages`), "
        "default bands. Each child reads both BVH files, splices a 600-frame crop (JIT), then "
        f"times {STAGE_SPLICES} whole splices; the figures are the median of those warm "
        "splices, then the median over the children of one code. CPU time "
        "(`time.process_time`, all threads; the pipeline's stage clocks switched to it in the "
        "child): the machine is shared, wall time is noise. *prepare* = markers (FK, virtual "
        "markers, hand-side vote, resampling) + features (derivatives, dead zones, sign codes "
        "for every θ bin, pass-1 rows).",
        "",
        "| pair | code | children | splice CPU | markers | features | pass 1 | pass 2 | merge | "
        "transfer | peak splicing | same paths and output |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    for lg in longs:
        by = {c: [r for r in lg["runs"] if r["code"] == c] for c in ("before", "now")}
        ref = by["before"][0] if by["before"] else None
        for code, runs in by.items():
            if not runs:
                continue
            med = {k: statistics.median(r["stages"][k] for r in runs) for k in ("cpu", *STAGE_KEYS)}
            same = all(
                ref is not None and all(r[k] == ref[k] for k in ("path1", "path2", "map", "bvh"))
                for r in runs
            )
            r0 = runs[0]
            lines.append(
                f"| {lg['seconds'] / 60:g} min ({r0['frames'][0]:,} x {r0['frames'][1]:,}) | "
                f"{code} | {len(runs)} | **{med['cpu']:.3f} s** | "
                + " | ".join(f"{med[k]:.3f}" for k in STAGE_KEYS)
                + f" | {_peak(runs)} | {'yes' if same else 'NO'} (bvh {r0['bvh']}) |"
            )
        if by["before"] and by["now"]:
            ratio = {
                k: statistics.median(
                    n["stages"][k] / b["stages"][k] for b, n in zip(by["before"], by["now"])
                )
                for k in ("cpu", *STAGE_KEYS)
            }
            lines.append(
                f"| | now / before | | **{ratio['cpu']:.2f}** | "
                + " | ".join(f"{ratio[k]:.2f}" for k in STAGE_KEYS)
                + " | | |"
            )
    lines += [
        "",
        "*Same* = the pass-1 and pass-2 paths, the merged map and the spliced BVH text "
        "(`format_bvh`) hash the same as the before code's. *Peak splicing* = VmHWM of the "
        "child with the counter reset (`/proc/self/clear_refs`) after reading and the "
        "warm-up: the timed splices' peak, with both takes loaded and the previous splice's "
        "result still held while the next one runs (largest over the children; compare "
        "codes, not with the `--engine` section's single splice).",
        "",
        f"Load average (1 min) {load[0]:.1f} at the start, {load[1]:.1f} at the end (2 cores, "
        "shared).",
        "",
        "Checked the same: "
        f"`benchmarks/splice_same_output.py --ref {STAGE_BASE}` (five real pairs: paths, "
        "costs, merged map, notes, spliced BVH bytes) and the table's last column. What "
        "changed in each step: written by hand under the figures (a re-run rewrites the "
        "whole section: carry the notes over from `git log -p benchmarks/RESULTS.md`).",
        "",
        "Goals (issue 13): 2-minute pair ≤ 1.0 s warm; 10-minute pair ≤ 10 s.",
    ]
    return "\n".join(lines)


def long_run(files, band, refine, tree=None) -> dict:
    body_p, hand_p, truth_p = files
    return LP.run_child(
        CHILD, str(body_p), str(hand_p), str(truth_p), str(band), str(refine), tree=tree
    )


def bench_long(seconds: float, fps: float, bands: list[tuple[str, float, float]], baseline) -> dict:
    files = LP.pair_files(seconds, fps)
    truth = np.load(files[2])
    n = truth.shape[0]
    out = {"seconds": seconds, "n": n, "drift_s": LP.drift_seconds(truth, n, fps), "runs": []}
    for label, band, refine in bands:
        for code, tree in (("today", baseline), ("now", None)):
            r = long_run(files, band, refine, tree)
            r.update(code=code, band=label, band_fraction=band, refine_fraction=refine)
            print(json.dumps(r), flush=True)
            out["runs"].append(r)
    return out


def time_band(n: int, fps: float, drift_s: float) -> tuple[str, float, float]:
    half = max(TIME_BAND_S, float(np.ceil(drift_s * 1.25)))
    return (
        f"±{half:g} s",
        LP.band_fraction(n, n, fps, half),
        LP.band_fraction(n, n, fps, half / 3.0),
    )


def report(short, kernel, longs) -> str:
    def ok(flag):
        return "met" if flag else "**missed**"

    k = kernel
    lines = [
        "## Splice speed (issues 5 and 13)",
        "",
        "Engine time = prepare (FK, virtual markers, dead zones, sign codes for 72 θ bins) + "
        "pass 1 (sign metric with θ per cell) + pass 2 (band around the pass-1 path, angle "
        "metric) + merge + transfer; both hands aligned jointly. *today* = the same script "
        f"run on the engine as at `{LP.BASELINE}` (`git archive`), in the same run.",
        "",
        f"**569-frame pair** (LAFAN1 crop, 30 fps), warm median of {short['reps']}: "
        f"{short['warm_s'] * 1000:.1f} ms (goal < 50 ms: {ok(short['warm_s'] < 0.05)}; the "
        f"paper's Matlab 10.95 s); first call in the process {short['cold_s']:.2f} s.",
        "",
        f"**Pass-1 kernel**, 2-minute pair, 30 % band ({k['cells']:,} cells), CPU time per band "
        f"cell, median of {k['reps']} interleaved runs:",
        "",
        "| kernel | ns per band cell |",
        "|---|---:|",
        f"| today: per-cell `splice_phase` (θ dot product + atan2 per cell) | {k['ns']['old']:.1f} |",
        f"| now: row kernel (`engine/align/phase_kernel.py`) | **{k['ns']['new']:.1f}** |",
        f"| the DTW recurrence alone (1-D squared distance) | {k['ns']['dtw']:.1f} |",
        "",
        f"Now / today: **{k['ratio']:.3f}** (median of paired ratios); same path: "
        f"{k['same_path']}; cost {k['cost_new']:.0f} vs {k['cost_old']:.0f}. Target ≤ 5 ns per "
        "cell on the machine where today's kernel took about 42 ns: the ratio says "
        f"{42 * k['ratio']:.1f} ns there.",
        "",
        "**Long pairs** (120 fps, BVH read back; one fresh process per run; wall and CPU "
        "time of the engine stages; peak = VmHWM of the process):",
        "",
        "| pair | band (pass 1 / pass 2 cells) | code | wall | CPU | prepare / pass 1 / pass 2 / "
        "transfer (wall, s) | peak | timing error median / p95 (frames) |",
        "|---|---|---|---:|---:|---|---:|---|",
    ]
    for lg in longs:
        for r in lg["runs"]:
            st = r["stages"]
            lines.append(
                f"| {lg['seconds'] / 60:g} min ({r['frames'][0]:,} x {r['frames'][1]:,}) | "
                f"{r['band']} ({r['cells'][0] / 1e6:.1f} M / {r['cells'][1] / 1e6:.1f} M) | "
                f"{r['code']} | {r['wall_s']:.2f} s | {r['cpu_s']:.2f} s | "
                f"{st['prepare']:.2f} / {st['pass1']:.2f} / {st['pass2']:.2f} / "
                f"{st['transfer']:.2f} | {r['peak_mb']:.0f} MB | "
                f"{r['err_median']:.2f} / {r['err_p95']:.2f} |"
            )
    lines += [""]
    for lg in longs:
        lines.append(
            f"- {lg['seconds'] / 60:g}-minute pair: the true path strays up to "
            f"{lg['drift_s']:.1f} s from the band's centre line."
        )
    lines += [
        "",
        "Goals (issue 13): 2-minute pair ≤ 1.0 s warm, peak ≤ 600 MB, median timing error "
        "≤ 1 frame; 10-minute pair ≤ 10 s, peak ≤ 1.5 GB. The 10-minute pair runs with the "
        "time band only: a 30 % band there has 2 G cells (2 GB of backpointers alone). The "
        "machine is shared (2 cores, other jobs): CPU time is the steadier figure.",
    ]
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="30-second pair only, prints only")
    ap.add_argument("--no-10min", action="store_true")
    ap.add_argument("--reps", type=int, default=5, help="pass-1 kernel repetitions")
    ap.add_argument(
        "--pass2",
        action="store_true",
        help="only the pass-2 kernel and default-band splices beside PASS2_BASE "
        "(section splice_speed_pass2)",
    )
    ap.add_argument("--long-reps", type=int, default=1, help="--pass2: runs of each code")
    ap.add_argument(
        "--engine",
        action="store_true",
        help="only default-band splices of the long pairs beside ENGINE_BASE "
        "(section splice_speed_engine)",
    )
    ap.add_argument(
        "--stages",
        action="store_true",
        help="only CPU time per engine stage of the long splices beside STAGE_BASE "
        "(section splice_speed_stages)",
    )
    ap.add_argument(
        "--pass1",
        action="store_true",
        help="only pass 1's row kernel beside STAGE_BASE's (section splice_speed_pass1)",
    )
    ap.add_argument(
        "--pass1-problems",
        action="store_true",
        help="only pass 1's row kernel beside STAGE_BASE's on the splice's coarse, fine and "
        "W1 problems (section splice_speed_pass1_problems)",
    )
    ap.add_argument(
        "--tag",
        help="--pass1/--pass1-problems: write section splice_speed_pass1[_problems]_TAG, titled "
        "by TAG (an earlier step's section and its notes stay)",
    )
    args = ap.parse_args(argv)
    fps = 120.0
    # the two pass-1 kernel benches: (flag, bench, report, RESULTS section)
    for chosen, bench, report, section in (
        (args.pass1_problems, bench_pass1_problems, report_pass1_problems, "_problems"),
        (args.pass1, bench_pass1_rows, report_pass1, ""),
    ):
        if chosen:
            load0 = os.getloadavg()[0]
            files = LP.pair_files(120.0, fps)
            res = bench(files[0], files[1], max(args.reps, 1))
            print(json.dumps(res), flush=True)
            load = (load0, os.getloadavg()[0])
            text = report(res, load, args.tag) if args.tag else report(res, load)
            print(text)
            tail = f"_{args.tag}" if args.tag else ""
            write_section(f"splice_speed_pass1{section}{tail}", text)
            return 0
    if args.stages:
        load0 = os.getloadavg()[0]
        before = LP.baseline_tree(STAGE_BASE)
        longs = [bench_stages(120.0, fps, before, max(args.long_reps, 2))]
        if not args.no_10min:
            longs.append(bench_stages(600.0, fps, before, 1))
        text = report_stages(longs, (load0, os.getloadavg()[0]))
        print(text)
        write_section("splice_speed_stages", text)
        return 0
    if args.engine:
        load0 = os.getloadavg()[0]
        before = LP.baseline_tree(ENGINE_BASE)
        longs = [bench_long_default(120.0, fps, before, args.long_reps)]
        if not args.no_10min:
            longs.append(bench_long_default(600.0, fps, before, 1))
        text = report_engine(longs, (load0, os.getloadavg()[0]))
        print(text)
        write_section("splice_speed_engine", text)
        return 0
    if args.pass2:
        files = LP.pair_files(120.0, fps)
        kernel2 = bench_pass2_kernel(files[0], files[1], max(args.reps, 1))
        print(json.dumps(kernel2), flush=True)
        before = LP.baseline_tree(PASS2_BASE)
        longs = [bench_long_default(120.0, fps, before, args.long_reps)]
        if not args.no_10min:
            longs.append(bench_long_default(600.0, fps, before, 1, drift_band=True))
        text = report_pass2(kernel2, longs)
        print(text)
        write_section("splice_speed_pass2", text)
        return 0
    short = bench_short(3 if args.quick else 10)
    short["reps"] = 3 if args.quick else 10
    print(json.dumps(short), flush=True)
    baseline = LP.baseline_tree()
    seconds = 30.0 if args.quick else 120.0
    files = LP.pair_files(seconds, fps)
    kernel = bench_pass1_kernel(files[0], files[1], 3 if args.quick else args.reps)
    print(json.dumps(kernel), flush=True)
    truth = np.load(files[2])
    n = truth.shape[0]
    bands = [("30 %", 0.3, 0.1), time_band(n, fps, LP.drift_seconds(truth, n, fps))]
    longs = [bench_long(seconds, fps, bands, baseline)]
    if not (args.quick or args.no_10min):
        files10 = LP.pair_files(600.0, fps)
        t10 = np.load(files10[2])
        longs.append(
            bench_long(
                600.0,
                fps,
                [time_band(t10.shape[0], fps, LP.drift_seconds(t10, t10.shape[0], fps))],
                baseline,
            )
        )
    text = report(short, kernel, longs)
    print(text)
    if not args.quick:
        write_section("splice_speed", text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
