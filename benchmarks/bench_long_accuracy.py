"""Timing accuracy of the merge blend in seconds (issue 13), beside the blend in frames.

Run: ``.venv/bin/python -m benchmarks.bench_long_accuracy [--seeds 6] [--families fps,left]
[--no-10min] [--write]``

The merge smooths the warp with a Gaussian of ``blend`` body frames. It was chosen at
30 fps as 3 frames (issue 5); 0.1 s is the same smoothing at 30 fps and 12 frames at
120 fps. *frames* = ``blend=3.0`` (main before issue 13's engine work), *seconds* = the
default now (``engine.splice.merge.blend_frames(fps)``); both alignments in the same
process on the same features, so only the blend differs.

* Short families of ``bench_splice_accuracy`` whose bodies are not all at 30 fps (fps,
  left, manipnet, leap: bodies at 25-120 fps) and lafan1 (30 fps, unchanged by design),
  seeds ``0..N-1``: pooled timing error in ms of the hand take (median, p95).
* The long pairs of ``benchmarks.long_pairs`` (2 and 10 minutes at 120 fps, BVH read
  back): median / p95 timing error in hand frames.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from benchmarks import long_pairs as LP
from benchmarks._results import write_section
from benchmarks.bench_splice_accuracy import FAMILIES
from engine.splice import pipeline as P

OLD_BLEND_FRAMES = 3.0
SHORT_FAMILIES = ("lafan1", "fps", "left", "manipnet", "leap")


def _maps(body, hand) -> tuple[np.ndarray, np.ndarray, float]:
    """Hand frame per body frame with the blend in frames and in seconds, and the fps."""
    f = P.prepare(body, hand)
    old = P.align_passes(f, blend=OLD_BLEND_FRAMES)
    new = P.align_passes(f)
    return np.asarray(old.map), np.asarray(new.map), f.fps


def short_families(families, seeds: int) -> list[dict]:
    rows = []
    for name in families:
        fam = FAMILIES[name]
        errs = {"frames": [], "seconds": []}
        rates = set()
        for seed in range(min(seeds, fam.seeds)):
            case = fam.make(seed)
            old, new, fps = _maps(case.body, case.hand)
            rates.add(round(fps))
            for key, hmap in (("frames", old), ("seconds", new)):
                errs[key].append(np.abs(hmap - case.truth) / case.hand.fps * 1000.0)
        row = {"family": name, "cases": min(seeds, fam.seeds), "body_fps": sorted(rates)}
        for key, parts in errs.items():
            e = np.concatenate(parts)
            row[key] = (float(np.median(e)), float(np.percentile(e, 95)))
        rows.append(row)
        print(row, flush=True)
    return rows


def long_pairs(lengths) -> list[dict]:
    from engine.io.bvh import read_bvh

    rows = []
    for seconds in lengths:
        body_p, hand_p, truth_p = LP.pair_files(seconds)
        body, hand, truth = read_bvh(body_p), read_bvh(hand_p), np.load(truth_p)
        old, new, _ = _maps(body, hand)
        row = {"pair": f"{seconds / 60:g} min ({body.n_frames:,} x {hand.n_frames:,})"}
        for key, hmap in (("frames", old), ("seconds", new)):
            e = np.abs(hmap - truth)
            row[key] = (float(np.median(e)), float(np.percentile(e, 95)))
        rows.append(row)
        print(row, flush=True)
        del body, hand
    return rows


def report(short, longs, load) -> str:
    out = [
        "## Timing accuracy: the merge blend in seconds (issue 13, `benchmarks/bench_long_accuracy.py`)",
        "",
        "The merge's Gaussian (σ) was 3 body frames, chosen at 30 fps; it is now 0.1 s "
        "(`engine.splice.merge.BLEND_S`: 3 frames at 30 fps, 12 at 120 fps). *frames* = "
        "`blend=3` (main before this change), *seconds* = the default now; both on the "
        "same features in the same process (only the blend differs). Default bands.",
        "",
    ]
    if longs:
        out += [
            "| long pair (120 fps) | frames: median / p95 (hand frames) | seconds: median / p95 |",
            "|---|---|---|",
        ]
        for r in longs:
            out.append(
                f"| {r['pair']} | {r['frames'][0]:.2f} / {r['frames'][1]:.2f} | "
                f"**{r['seconds'][0]:.2f}** / {r['seconds'][1]:.2f} |"
            )
        out.append("")
    if short:
        out += [
            "| family | cases | body fps | frames: median / p95 (ms) | seconds: median / p95 (ms) |",
            "|---|---|---|---|---|",
        ]
        for r in short:
            fps = ", ".join(str(x) for x in r["body_fps"])
            out.append(
                f"| {r['family']} | {r['cases']} | {fps} | {r['frames'][0]:.1f} / "
                f"{r['frames'][1]:.1f} | {r['seconds'][0]:.1f} / {r['seconds'][1]:.1f} |"
            )
        out.append("")
    out.append(
        f"Load average (1 min) {load[0]:.1f} at the start, {load[1]:.1f} at the end "
        "(2 cores shared by five sessions); accuracy does not depend on it."
    )
    return "\n".join(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=6, help="seeds 0..N-1 of each short family")
    ap.add_argument("--families", default=",".join(SHORT_FAMILIES))
    ap.add_argument("--no-10min", action="store_true")
    ap.add_argument("--no-long", action="store_true")
    ap.add_argument("--write", action="store_true", help="write the section of RESULTS.md")
    args = ap.parse_args(argv)
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    lengths = [] if args.no_long else ([120.0] if args.no_10min else [120.0, 600.0])
    longs = long_pairs(lengths)
    fams = [f for f in args.families.split(",") if f]
    short = short_families(fams, args.seeds)
    md = report(short, longs, (load0, os.getloadavg()[0]))
    print(md)
    print(f"({time.perf_counter() - t0:.0f} s)")
    if args.write:
        write_section("long_accuracy", md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
