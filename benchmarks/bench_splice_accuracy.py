"""Splice accuracy on split real captures with known truth (issue 5, "Accuracy").

Run: ``.venv/bin/python -m benchmarks.bench_splice_accuracy [--quick]``

Cases come from :mod:`benchmarks.split` (BEAT split; Bandai and LAFAN1
body takes with synthetic finger signals), each with its own seed. For each case
and method we measure

* timing error: ``|map(i) - truth(i)|`` over every body frame, in milliseconds of
  the hand take (pooled per family: median and 95th percentile);
* finger error: mean geodesic angle (degrees) between the spliced take's finger
  joint rotations and the original fingers, over every finger joint and frame.
  The *oracle* is the hand take sampled at the true correspondence (its error is
  the noise and resampling floor).

Methods: HandSplice (two passes, default parameters); pass 1 only; one-pass DTW on
marker positions; one-pass DTW on derivative values (velocity and acceleration);
uniform time scaling. Every DTW method gets the same band (30 %), merge and
smoothing, and the same transfer. The default parameters were chosen on seeds
100-107 (``/tmp``-free: see ``TUNING_SEEDS``); the table reports seeds 0..N-1.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from benchmarks._results import write_section
from benchmarks.split import Case, finger_error, finger_pairs, make_case
from engine.dtw import Band, align_features
from engine.splice import merge as MG
from engine.splice import pipeline as P
from engine.splice import transfer as TR

FAMILIES = {"beat": 20, "bandai": 18, "lafan1": 12}
TUNING_SEEDS = range(100, 108)
METHODS = ["handsplice", "pass1", "dtw_positions", "dtw_derivatives", "uniform", "oracle"]
LABELS = {
    "handsplice": "HandSplice (2 passes)",
    "pass1": "pass 1 only",
    "dtw_positions": "1-pass DTW, positions",
    "dtw_derivatives": "1-pass DTW, derivative values",
    "uniform": "uniform time scaling",
    "oracle": "oracle (true timing)",
}


def method_maps(case: Case) -> tuple[dict[str, np.ndarray], P.SpliceResult, float]:
    """Hand-take frame per body frame for every method, the HandSplice result, its time."""
    t0 = time.perf_counter()
    res = P.splice(case.body, case.hand, transfer_fingers=False)
    seconds = time.perf_counter() - t0
    f = res.features
    n, m = f.n, f.m
    blend = res.alignment.blend
    maps = {"handsplice": res.alignment.map,
            "pass1": f.grid_to_hand(MG.merge_path(res.alignment.pass1.path, n, m, blend))}
    band = Band.sakoe_chiba(n, m, P.BAND)
    pos_b = f.body_markers.reshape(n, -1)
    pos_h = f.hand_markers.reshape(m, -1)
    al = align_features(pos_b, pos_h, band)
    maps["dtw_positions"] = f.grid_to_hand(MG.merge_path(al.path, n, m, blend))
    bp, hp = f.body_phase, f.hand_phase
    der_b = np.concatenate([bp.velocity.reshape(n, -1), 0.1 * bp.acceleration.reshape(n, -1)], 1)
    der_h = np.concatenate([hp.velocity.reshape(m, -1), 0.1 * hp.acceleration.reshape(m, -1)], 1)
    al = align_features(der_b, der_h, band)
    maps["dtw_derivatives"] = f.grid_to_hand(MG.merge_path(al.path, n, m, blend))
    maps["uniform"] = np.linspace(0.0, case.hand.n_frames - 1, n)
    maps["oracle"] = case.truth
    return maps, res, seconds


def evaluate(case: Case) -> dict:
    maps, res, seconds = method_maps(case)
    plan = P.plan_for(res.features)
    out = {"name": case.name, "family": case.family, "seconds": seconds, "methods": {}}
    pairs = None
    for name, hmap in maps.items():
        motion = TR.apply_transfer(plan, case.body, case.hand, hmap, res.features.body_fk)
        pairs = pairs or finger_pairs(motion, case.reference)
        err_ms = (np.asarray(hmap) - case.truth) / case.hand.fps * 1000.0
        out["methods"][name] = {"timing_ms": np.abs(err_ms),
                                "finger_deg": finger_error(motion, case.reference, pairs)}
    return out


def summarise(results: list[dict]) -> dict:
    table = {}
    for fam in FAMILIES:
        rs = [r for r in results if r["family"] == fam]
        if not rs:
            continue
        table[fam] = {}
        for meth in METHODS:
            t = np.concatenate([r["methods"][meth]["timing_ms"] for r in rs])
            fe = np.array([r["methods"][meth]["finger_deg"] for r in rs])
            table[fam][meth] = {"median_ms": float(np.median(t)),
                                "p95_ms": float(np.percentile(t, 95)),
                                "finger_deg": float(fe.mean()),
                                "cases": len(rs)}
    return table


def goals(table: dict, results: list[dict]) -> list[str]:
    lines = []
    for fam, rows in table.items():
        hs, orc = rows["handsplice"], rows["oracle"]
        frame_ms = 1000.0 / 30.0  # every body take here is 30 fps
        checks = [
            (f"median timing error <= 1 body frame ({frame_ms:.0f} ms)",
             hs["median_ms"] <= frame_ms, f"{hs['median_ms']:.1f} ms"),
            ("95th percentile < 100 ms", hs["p95_ms"] < 100.0, f"{hs['p95_ms']:.1f} ms"),
            ("finger error within 1 deg of the oracle", hs["finger_deg"] - orc["finger_deg"] <= 1.0,
             f"{hs['finger_deg']:.2f} vs {orc['finger_deg']:.2f} deg"),
        ]
        for meth in ("pass1", "dtw_positions", "dtw_derivatives", "uniform"):
            b = rows[meth]
            better = (hs["median_ms"] < b["median_ms"] and hs["p95_ms"] < b["p95_ms"]
                      and hs["finger_deg"] < b["finger_deg"])
            checks.append((f"better than {LABELS[meth]} (median, p95 and finger error)", better,
                           f"{b['median_ms']:.1f} / {b['p95_ms']:.1f} ms, "
                           f"{b['finger_deg']:.2f} deg"))
        for text, ok, value in checks:
            lines.append(f"| {fam} | {text} | {'met' if ok else '**missed**'} | {value} |")
    return lines


def per_case_wins(results: list[dict]) -> list[str]:
    lines = []
    for fam in FAMILIES:
        rs = [r for r in results if r["family"] == fam]
        if not rs:
            continue
        parts = []
        for meth in ("pass1", "dtw_positions", "dtw_derivatives", "uniform"):
            wins = sum(np.mean(r["methods"]["handsplice"]["timing_ms"])
                       <= np.mean(r["methods"][meth]["timing_ms"]) for r in rs)
            parts.append(f"{LABELS[meth]} {wins}/{len(rs)}")
        lines.append(f"- {fam}: HandSplice's mean timing error is lower on " + ", ".join(parts)
                     + " cases")
    return lines


def markdown(table: dict, results: list[dict], seeds: dict) -> str:
    out = ["## Splice accuracy (issue 5)", "",
           "Split real captures with known truth (`benchmarks/split.py`): **beat** = the "
           "BEAT take (body + 30 captured finger joints) split into a body take without fingers "
           "and a hand take; **bandai**, **lafan1** = real body-only takes (Bandai-Namco takes, "
           "20 s LAFAN1 crops) carrying a synthetic finger-curl signal of known timing. Hand takes: "
           "smooth random time warp (global 0.85-1.2x, local rate exp(N(0, 0.15-0.3)), ~1 s "
           "correlation), resampled to 60/90/100/120 fps, trunk held still and turned +-60 deg, "
           "shoulder/collar/elbow rotations pulled 30-60 % toward their mean (forearm roll kept), "
           "0.5 deg rotation noise on every joint. Both hands aligned jointly; defaults (band 0.3, "
           "refine band 0.1, θ by eq. 7). Timing error in ms of the hand take (pooled over every "
           "body frame of the family); finger error = mean geodesic angle over finger joints and "
           "frames vs the original fingers. Parameters (merge blend 3 frames, pass-2 step cost "
           "0.05 rad) were chosen on seeds 100-107; reported seeds: "
           + ", ".join(f"{k} 0-{v - 1}" for k, v in seeds.items()) + ".", ""]
    for fam, rows in table.items():
        out += [f"### {fam} ({rows['handsplice']['cases']} cases)", "",
                "| method | timing median (ms) | timing p95 (ms) | finger error (deg) |",
                "|---|---|---|---|"]
        for meth in METHODS:
            r = rows[meth]
            name = f"**{LABELS[meth]}**" if meth == "handsplice" else LABELS[meth]
            out.append(f"| {name} | {r['median_ms']:.1f} | {r['p95_ms']:.1f} | "
                       f"{r['finger_deg']:.2f} |")
        out.append("")
    out += ["### Goals", "", "| family | goal | status | value |", "|---|---|---|---|"]
    out += goals(table, results)
    out += ["", "Per case:"] + per_case_wins(results)
    worst = sorted(results, key=lambda r: -np.percentile(r["methods"]["handsplice"]["timing_ms"],
                                                         95))[:3]
    out += ["", "Hardest cases (HandSplice p95): " + "; ".join(
        f"{r['name']} {np.percentile(r['methods']['handsplice']['timing_ms'], 95):.0f} ms"
        for r in worst) + ". They are long arm holds during which the synthetic fingers keep "
        "moving (no arm signal can time them) or body takes whose trunk turns and bends while the "
        "hand take's trunk is still."]
    secs = np.array([r["seconds"] for r in results])
    out += ["", f"HandSplice alignment time per case (prepare + 2 passes + merge): median "
                f"{np.median(secs) * 1000:.0f} ms, max {secs.max() * 1000:.0f} ms."]
    return "\n".join(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a few seeds per family, no RESULTS.md")
    ap.add_argument("--tuning", action="store_true", help="run the tuning seeds instead")
    args = ap.parse_args(argv)
    seeds = {f: (3 if args.quick else k) for f, k in FAMILIES.items()}
    results = []
    t0 = time.perf_counter()
    for fam, k in seeds.items():
        seed_list = list(TUNING_SEEDS) if args.tuning else list(range(k))
        for seed in seed_list:
            case = make_case(fam, seed)
            r = evaluate(case)
            results.append(r)
            hs = r["methods"]["handsplice"]
            print(f"{case.name:45s} median {np.median(hs['timing_ms']):6.1f} ms  p95 "
                  f"{np.percentile(hs['timing_ms'], 95):6.1f} ms  fingers "
                  f"{hs['finger_deg']:.2f} deg (oracle {r['methods']['oracle']['finger_deg']:.2f})",
                  flush=True)
    table = summarise(results)
    md = markdown(table, results, seeds)
    print(md)
    print(f"\n{time.perf_counter() - t0:.0f} s")
    if not (args.quick or args.tuning):
        write_section("splice_accuracy", md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
