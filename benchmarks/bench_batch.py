"""Long takes and batch throughput (issue 9).

    .venv/bin/python -m benchmarks.bench_batch            # full run, writes RESULTS.md "batch"
    .venv/bin/python -m benchmarks.bench_batch --quick    # small sizes, prints only

Measures
* **A 14,400 x 14,400 splice** (2 minutes at 120 fps): the LAFAN1 take
  ``multipleActions1_subject1`` resampled from 30 to 120 fps and cut to 14,400
  frames is the body; the hand take is the same performance with synthetic fingers
  (``benchmarks.split.add_fingers``) re-timed by a smooth random warp, arms
  shrunk, trunk still, noise (``make_hand_take``), also 14,400 frames at 120 fps.
  Both are written to BVH and read back, as a user's files would be. Each splice
  runs in a fresh child process (after a small warm-up splice for the JIT); the
  child reports wall time per stage and its peak resident memory
  (``resource.getrusage(RUSAGE_SELF).ru_maxrss``) before and after the splice.
* **Memory against band area**: the same pair at several band widths and lengths;
  the extra peak memory of the splice divided by the DTW band cells (pass 1 + pass 2)
  should stay about constant if memory is proportional to band area, and far below
  ``n * m`` cells.
* **Batch throughput**: ``engine.jobs.batch.run_batch`` on 8 pairs (10 s LAFAN1-derived
  pairs at 120 fps, 1,200 x 1,200 frames, thumbnails rendered), 1 and 2 worker
  processes (embedded LocalCluster; cluster start-up included in the wall time).
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
FPS = 120.0
LONG = 14_400
SOURCE = "lafan1/multipleActions1_subject1.bvh"
SOURCES = ["lafan1/multipleActions1_subject1.bvh", "lafan1/dance1_subject1.bvh"]


# ---------------------------------------------------------------- inputs


def make_pair(
    folder: Path, frames: int, seed: int, source: str = SOURCE, start_s: float = 0.0
) -> tuple[Path, Path]:
    """Write ``body.bvh`` / ``hand.bvh`` of ``frames`` frames at 120 fps (module docstring)."""
    from benchmarks.split import MOCAP, add_fingers, make_hand_take
    from engine.io.bvh import read_bvh, write_bvh
    from engine.model.kinematics import resample

    rng = np.random.default_rng(seed)
    take = resample(read_bvh(MOCAP / source), FPS)
    first = int(round(start_s * FPS))
    if first + frames > take.n_frames:
        raise ValueError(
            f"{source} has {take.n_frames} frames at {FPS:g} fps, {first + frames} needed"
        )
    body = take.frames(first, first + frames)
    full = add_fingers(body, rng)
    hand, _, _ = make_hand_take(
        full, rng, fps=FPS, scale=1.0, warp_sigma=0.15, shrink=0.3, yaw_deg=15.0, noise_deg=0.5
    )
    hand = hand.frames(0, min(frames, hand.n_frames))
    folder.mkdir(parents=True, exist_ok=True)
    body_path, hand_path = folder / "body.bvh", folder / "hand.bvh"
    write_bvh(body, body_path)
    write_bvh(hand, hand_path)
    return body_path, hand_path


# ---------------------------------------------------------------- one splice in a child


def _rss_mb(field: str) -> float:
    """``VmRSS`` / ``VmHWM`` (peak) of this process in MB, from /proc/self/status."""
    with open("/proc/self/status", encoding="ascii") as fh:
        for line in fh:
            if line.startswith(field + ":"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def _trim() -> None:
    """Give freed heap memory back to the OS so RSS counts live memory only (glibc)."""
    try:
        import ctypes

        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass


def _reset_peak() -> bool:
    """Reset the peak-RSS counter to the current RSS (Linux >= 4.0: clear_refs 5)."""
    try:
        with open("/proc/self/clear_refs", "w", encoding="ascii") as fh:
            fh.write("5")
        return True
    except OSError:
        return False


def child_splice(
    body_path: str, hand_path: str, band: float, refine_band: float, frames: int | None
) -> dict:
    """Runs in the child: warm-up, then one timed splice, stage by stage.

    Memory per stage: the peak RSS is reset before each stage (``clear_refs``), so a
    stage's *extra* memory is its peak RSS minus the RSS it started from; this
    counts numba's allocations too (tracemalloc would not).
    """
    from engine.io import load_take
    from engine.splice import pipeline

    body = load_take(body_path)
    hand = load_take(hand_path)
    if frames:
        body, hand = body.frames(0, frames), hand.frames(0, frames)
    pipeline.splice(body.frames(0, 240), hand.frames(0, 240), band=band, refine_band=refine_band)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # KiB on Linux
    stages: dict[str, dict] = {}
    can_reset = _reset_peak()

    def stage(name: str, fn):
        gc.collect()
        _trim()
        start_rss = _rss_mb("VmRSS")
        _reset_peak()
        t = time.perf_counter()
        out = fn()
        stages[name] = {
            "seconds": time.perf_counter() - t,
            "start_mb": start_rss,
            "peak_mb": _rss_mb("VmHWM"),
        }
        return out

    t0 = time.perf_counter()
    feats = stage("prepare", lambda: pipeline.prepare(body, hand))
    al = stage(
        "passes",
        lambda: pipeline.align_passes(feats, band=band, refine_band=refine_band, incremental=False),
    )
    motion = stage("transfer", lambda: pipeline.transfer(feats, al))
    seconds = time.perf_counter() - t0
    return {
        "n": feats.n,
        "m": feats.m,
        "band": band,
        "refine_band": refine_band,
        "cells1": int(al.pass1.band.area),
        "cells2": int(al.pass2.band.area),
        "seconds": seconds,
        "stages": stages,
        "stage_memory": can_reset,
        "timings": {
            "prepare": stages["prepare"]["seconds"],
            "pass1": al.timings["pass1"],
            "pass2": al.timings["pass2"],
            "merge": al.timings["merge"],
            "transfer": stages["transfer"]["seconds"],
        },
        "peak_before_mb": before,
        "peak_mb": max(before, *(s["peak_mb"] for s in stages.values())),
        "out_frames": motion.n_frames,
    }


def run_child(
    body: Path, hand: Path, band: float, refine_band: float, frames: int | None = None
) -> dict:
    cmd = [
        sys.executable,
        "-m",
        "benchmarks.bench_batch",
        "--child",
        str(body),
        str(hand),
        "--band",
        str(band),
        "--refine-band",
        str(refine_band),
    ]
    if frames:
        cmd += ["--frames", str(frames)]
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=1800)
    if proc.returncode != 0:
        raise RuntimeError(f"child failed ({proc.returncode}): {proc.stderr[-2000:]}")
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    out["children_peak_mb"] = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0
    return out


# ---------------------------------------------------------------- batch throughput


def make_batch(folder: Path, pairs: int, frames: int) -> Path:
    rows = ["body,hand,side,name"]
    for k in range(pairs):
        source = SOURCES[k % len(SOURCES)]
        start = 5.0 + 30.0 * (k // len(SOURCES))
        b, h = make_pair(folder / f"pair{k}", frames, seed=100 + k, source=source, start_s=start)
        rows.append(f"{b.relative_to(folder)},{h.relative_to(folder)},both,pair{k}")
    manifest = folder / "manifest.csv"
    manifest.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return manifest


def run_throughput(manifest: Path, workers: int, out: Path) -> dict:
    """One batch run on a fresh LocalCluster; start-up timed apart from the pairs."""
    from distributed import Client

    from engine.jobs.batch import local_cluster, run_batch

    t0 = time.perf_counter()
    cluster = local_cluster(workers)
    client = Client(cluster)
    startup = time.perf_counter() - t0
    try:
        t1 = time.perf_counter()
        result = run_batch(manifest, out, thumbnails="render", progress=None, client=client)
        pairs_s = time.perf_counter() - t1
    finally:
        client.close()
        cluster.close()
    if result.count("done") != len(result.records):
        bad = [r for r in result.records if r["status"] != "done"]
        raise RuntimeError(f"batch pairs failed: {bad[:2]}")
    per_pair = [float(r["seconds"]) for r in result.records]
    wall = startup + pairs_s
    n = len(result.records)
    return {
        "workers": workers,
        "pairs": n,
        "startup": startup,
        "pairs_s": pairs_s,
        "wall": wall,
        "pairs_per_min": 60.0 * n / wall,
        "pairs_per_min_running": 60.0 * n / pairs_s,
        "median_pair_s": float(np.median(per_pair)),
        "processes": len({r["worker"] for r in result.records}),
        "thumbnails": sorted({r["thumbnail_kind"] for r in result.records}),
    }


# ---------------------------------------------------------------- report


def fmt_mb(x: float) -> str:
    return f"{x:,.0f} MB"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small sizes, print only")
    ap.add_argument("--child", nargs=2, metavar=("BODY", "HAND"), help=argparse.SUPPRESS)
    ap.add_argument("--band", type=float, default=0.3, help=argparse.SUPPRESS)
    ap.add_argument("--refine-band", type=float, default=0.1, help=argparse.SUPPRESS)
    ap.add_argument("--frames", type=int, default=None, help=argparse.SUPPRESS)
    ap.add_argument("--skip-throughput", action="store_true")
    args = ap.parse_args()
    if args.child:
        print(
            json.dumps(
                child_splice(args.child[0], args.child[1], args.band, args.refine_band, args.frames)
            )
        )
        return 0

    long_n = 2_400 if args.quick else LONG
    series = (
        [(long_n, 0.3), (long_n, 0.1), (long_n // 2, 0.3)]
        if args.quick
        else [(LONG, 0.3), (LONG, 0.2), (LONG, 0.1), (LONG // 2, 0.3), (LONG // 4, 0.3)]
    )
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="bench-batch-") as tmp:
        tmp = Path(tmp)
        t0 = time.perf_counter()
        body, hand = make_pair(tmp / "long", long_n, seed=7)
        print(
            f"long pair {long_n} x {long_n} written in {time.perf_counter() - t0:.1f} s; "
            f"{body.stat().st_size / 2**20:.1f} + {hand.stat().st_size / 2**20:.1f} MiB BVH",
            flush=True,
        )
        runs = []
        for n, band in series:
            r = run_child(body, hand, band, 0.1, frames=None if n == long_n else n)
            runs.append(r)
            print(
                f"n={r['n']} m={r['m']} band={band}: {r['seconds']:.2f} s, peak "
                f"{r['peak_mb']:.0f} MB (before splice {r['peak_before_mb']:.0f} MB), "
                f"cells {r['cells1'] + r['cells2']:,} {r['timings']}",
                flush=True,
            )
        throughput = []
        if not args.skip_throughput:
            pairs, frames = (4, 600) if args.quick else (8, 3_600)
            manifest = make_batch(tmp / "batch", pairs, frames)
            for workers in (1, 2):
                r = run_throughput(manifest, workers, tmp / f"out{workers}")
                r["frames"] = frames
                throughput.append(r)
                print(
                    f"batch {pairs} pairs of {frames} frames, {workers} worker(s): "
                    f"{r['wall']:.1f} s, {r['pairs_per_min']:.1f} pairs/min, "
                    f"median pair {r['median_pair_s']:.1f} s, start-up {r['startup']:.1f} s",
                    flush=True,
                )
    load_after = os.getloadavg()[0]
    if args.quick:
        return 0
    write_section("batch", report(runs, throughput, load, load_after))
    return 0


def _extra(r: dict, name: str) -> float:
    st = r["stages"][name]
    return st["peak_mb"] - st["start_mb"]


def report(runs: list[dict], throughput: list[dict], load: float, load_after: float) -> str:
    main_run = runs[0]
    n, m = main_run["n"], main_run["m"]
    lines = [
        "## Batch and long takes (`benchmarks/bench_batch.py`)",
        "",
        f"**{n:,} x {m:,} splice** (2 min at 120 fps: LAFAN1 `multipleActions1_subject1` "
        "resampled 30 -> 120 fps as the body; the same performance with synthetic fingers, "
        "re-timed, arms shrunk, trunk still, as the hand; BVH files read back; both hands; "
        "band 0.3, refine band 0.1; a fresh process after a 240-frame warm-up splice):",
        "",
        f"- wall time **{main_run['seconds']:.1f} s** ("
        + ", ".join(f"{k} {v:.2f} s" for k, v in main_run["timings"].items())
        + ")",
        f"- peak resident memory of the process **{fmt_mb(main_run['peak_mb'])}** "
        f"({fmt_mb(main_run['peak_before_mb'])} before the splice: interpreter, numpy/numba, "
        "both takes, warm-up)",
        f"- the full matrix would be {n * m:,} cells ({n * m / 2**20:,.0f} MB at 1 byte per "
        f"cell, {n * m * 8 / 2**30:,.1f} GB as float64); the pass-1 band holds "
        f"{main_run['cells1']:,} cells ({main_run['cells1'] / (n * m):.0%})",
        "",
        "**Memory by stage against band area.** Each row is a fresh child process; before "
        "each stage the peak-RSS counter is reset (`/proc/self/clear_refs`), so *extra* is "
        "the stage's peak RSS minus the RSS it started from (numba allocations included). "
        "The passes run one after the other, so their peak follows the larger band "
        "(pass 1).",
        "",
        "| n x m | band | pass-1 cells | pass-2 cells | time | process peak | prepare extra "
        "| passes extra | passes bytes per pass-1 cell | transfer extra |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in runs:
        big = max(r["cells1"], r["cells2"])
        lines.append(
            f"| {r['n']:,} x {r['m']:,} | {r['band']:g} | {r['cells1']:,} | {r['cells2']:,} | "
            f"{r['seconds']:.1f} s | {fmt_mb(r['peak_mb'])} | {fmt_mb(_extra(r, 'prepare'))} | "
            f"{fmt_mb(_extra(r, 'passes'))} | {_extra(r, 'passes') * 2**20 / big:.2f} | "
            f"{fmt_mb(_extra(r, 'transfer'))} |"
        )
    per_cell = [
        _extra(r, "passes") * 2**20 / max(r["cells1"], r["cells2"])
        for r in runs
        if max(r["cells1"], r["cells2"]) > 10_000_000
    ]
    longs = [r for r in runs if r["n"] == n]
    stage_max = {
        name: max(_extra(r, name) for r in longs) for name in ("prepare", "passes", "transfer")
    }
    top = max(stage_max, key=stage_max.get)
    lines += [
        "",
        f"The alignment (both DTW passes) grows with band area: "
        f"{min(per_cell):.2f}-{max(per_cell):.2f} bytes per cell of the larger band across "
        "band widths and lengths (bands over 10 M cells), never the full matrix. At "
        f"{n:,} frames the largest stage is *{top}* ({stage_max[top]:,.0f} MB extra); "
        f"features (prepare, {stage_max['prepare']:,.0f} MB) and transfer "
        f"({stage_max['transfer']:,.0f} MB) grow with the take's length, not with the band, "
        "so the process peak barely moves between band 0.1 and 0.3.",
    ]
    if throughput:
        t = throughput
        lines += [
            "",
            f"**Batch throughput** (`engine.jobs.batch.run_batch`, {t[0]['pairs']} pairs of 30 s "
            f"LAFAN1-derived takes at 120 fps ({t[0]['frames']:,} x {t[0]['frames']:,} frames), "
            "both hands, BVH in and out, rendered thumbnails, embedded "
            "LocalCluster(processes=True, threads_per_worker=1)):",
            "",
            "| workers | cluster start-up | pairs | wall incl. start-up | pairs per minute | "
            "pairs per minute once running | median pair |",
            "|---|---|---|---|---|---|---|",
        ]
        for r in t:
            lines.append(
                f"| {r['workers']} | {r['startup']:.1f} s | {r['pairs_s']:.1f} s | "
                f"{r['wall']:.1f} s | {r['pairs_per_min']:.1f} | "
                f"{r['pairs_per_min_running']:.1f} | {r['median_pair_s']:.1f} s |"
            )
        if len(t) == 2:
            speedup = t[1]["pairs_per_min"] / t[0]["pairs_per_min"]
            lines += [
                "",
                f"2 workers / 1 worker: {speedup:.2f}x pairs per minute "
                f"({t[1]['pairs_per_min_running'] / t[0]['pairs_per_min_running']:.2f}x "
                f"once running) on {os.cpu_count()} cores. "
                + (
                    "Two worker processes use both cores; the rest is the scheduler, "
                    "file reading and thumbnails, which share the same cores."
                    if speedup > 1.2
                    else "Under load a second worker process competes for the same busy "
                    "cores, so the speed-up is small or absent."
                ),
            ]
    lines += [
        "",
        f"Load average (1 min) {load:.1f} at the start, {load_after:.1f} at the end "
        f"({os.cpu_count()} cores, shared with other work): timings are noisy.",
    ]
    return "\n".join(lines)


def write_section(name: str, text: str) -> None:
    from benchmarks._results import write_section as ws

    ws(name, text)


if __name__ == "__main__":
    sys.exit(main())
