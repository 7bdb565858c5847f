"""Splice accuracy on split real captures with known truth (issue 5, "Accuracy").

Run: ``.venv/bin/python -m benchmarks.bench_splice_accuracy [--quick]``

Cases come from :mod:`benchmarks.split` (BEAT split; Bandai and LAFAN1
body takes with synthetic finger signals), each with its own seed. Families are
registered in ``FAMILIES`` by the ``@family(name, seeds, note)`` decorator (one
function ``seed -> Case`` each); ``--families a,b`` runs a subset. For each case
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
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from benchmarks._results import write_section
from benchmarks.split import Case, Realism, finger_error, finger_pairs, make_case
from benchmarks.split_rigs import make_rig_case
from engine.dtw import Band, align_features
from engine.dtw import constraints as C
from engine.splice import merge as MG
from engine.splice import pipeline as P
from engine.splice import transfer as TR


@dataclass(frozen=True)
class Family:
    """A family of cases: ``make(seed) -> Case``, how many seeds the table reports
    (``0..seeds-1``) and one line saying what its takes look like."""

    name: str
    make: Callable[[int], Case]
    seeds: int
    note: str
    tuning_seeds: tuple[int, ...] = tuple(range(100, 108))


#: every family of the bench, in table order (add one with :func:`family`)
FAMILIES: dict[str, Family] = {}


def family(name: str, seeds: int, note: str, tuning_seeds=tuple(range(100, 108))):
    """Register ``fn(seed) -> Case`` as a bench family (decorator)."""

    def register(fn: Callable[[int], Case]) -> Callable[[int], Case]:
        FAMILIES[name] = Family(name, fn, seeds, note, tuple(tuning_seeds))
        return fn

    return register


_BASES = ("beat", "bandai", "lafan1")


def _rotating(seed: int, realism: Realism) -> Case:
    """A case of base take ``beat``/``bandai``/``lafan1`` (by seed) with ``realism``."""
    case = make_case(_BASES[seed % 3], seed, realism=realism)
    return case


@family("beat", 20, "BEAT split (captured fingers), clean")
def _beat(seed: int) -> Case:
    return make_case("beat", seed)


@family("bandai", 18, "Bandai-Namco body takes + synthetic fingers, clean")
def _bandai(seed: int) -> Case:
    return make_case("bandai", seed)


@family("lafan1", 12, "20 s LAFAN1 crops + synthetic fingers, clean")
def _lafan1(seed: int) -> Case:
    return make_case("lafan1", seed)


# issue 12: takes that look like two capture sessions. Developed on seeds 200-207 (the
# ``tuning_seeds``); the table reports seeds 0..N-1.
_DEV = tuple(range(200, 208))


@family(
    "untrimmed",
    12,
    "hand take starts 1-2 s earlier and ends 1-2 s later than the body "
    "(BEAT 8.3 s and LAFAN1 20 s takes: the Bandai takes, 3-7 s, are too short to lose 2-4 s)",
    _DEV,
)
def _untrimmed(seed: int) -> Case:
    return make_case(("beat", "lafan1")[seed % 2], seed, realism=Realism(untrimmed_s=(1.0, 2.0)))


@family(
    "noisy",
    12,
    "hand take (glove/optical noise): 2 deg rotation jitter on every joint + "
    "single-frame spikes (1 % of frames, 10-30 deg on half the arm and hand joints)",
    _DEV,
)
def _noisy(seed: int) -> Case:
    return _rotating(seed, Realism(jitter_deg=2.0, spike_rate=0.01))


@family(
    "holds",
    12,
    "holds of 0.3-1 s at 2-3 places (another length in each take), hand "
    "take rushed 1.15x elsewhere",
    _DEV,
)
def _holds(seed: int) -> Case:
    return _rotating(seed, Realism(holds=(2, 3, 0.3, 1.0), rush=1.15))


@family("fps", 12, "body and hand take each at 25/30/50/60/100/120 fps", _DEV)
def _fps(seed: int) -> Case:
    rates = (25.0, 30.0, 50.0, 60.0, 100.0, 120.0)
    return _rotating(seed, Realism(body_fps=rates, hand_fps=rates))


# issue 12 item 4: hand takes from other rigs (benchmarks/split_rigs.py). Body takes at
# 25/30/60/120 fps, hand takes at 25-120 fps (Leap 36-40), either one the faster.
# Developed on seeds 300-303.
_RIG_DEV = tuple(range(300, 304))


@family(
    "left",
    20,
    "left-handed performer (take mirrored, sides swapped): the left hand "
    "only; body 25-120 fps, hand 25-120 fps",
    _RIG_DEV,
)
def _left(seed: int) -> Case:
    return make_rig_case("left", seed)


@family(
    "manipnet",
    20,
    "ManipNet rig: real ManipNet finger capture (4-joint thumb with "
    "THUMB_CMC_AA) on the body's wrist; hand take rooted at a 6-DoF WRIST, no side in "
    "names or file name (side from geometry); odd seeds left; body 25-120 fps, hand "
    "25-120 fps",
    _RIG_DEV,
)
def _manipnet(seed: int) -> Case:
    return make_rig_case("manipnet", seed)


def untrimmed_rig_case(kind: str, seed: int, seconds=(1.0, 2.0)) -> Case:
    """``make_rig_case(kind, seed)`` with its body take cut ``U(seconds)`` s at each end, so
    the hand take starts earlier and ends later than the body, as an untrimmed take from
    another session does (the truth and the reference cut with it)."""
    case = make_rig_case(kind, seed)
    rr = np.random.default_rng([seed, 2])
    fps, n = case.body.fps, case.body.n_frames
    a, b = (int(round(rr.uniform(*seconds) * fps)) for _ in range(2))
    return replace(
        case,
        name=f"{case.name} untrimmed",
        family=f"{kind}-untrimmed",
        body=case.body.frames(a, n - b),
        truth=case.truth[a : n - b],
        reference=case.reference.frames(a, n - b),
        params={**case.params, "untrimmed_s": [a / fps, b / fps]},
    )


#: seeds of the rig families whose base take is long enough to lose 2-4 s (LAFAN1 crops and
#: BEAT; ``split_rigs`` takes its base by ``seed % 3``, and the Bandai takes are 3-7 s)
_LONG_BASE = tuple(s for s in range(30) if s % 3)[:12]


@family(
    "manipnet-untrimmed",
    12,
    "the manipnet family's takes with the body cut 1-2 s at each end (the forearm-less hand "
    "take starts earlier and ends later): the hand-spin pass's open ends",
    _RIG_DEV,
)
def _manipnet_untrimmed(seed: int) -> Case:
    return untrimmed_rig_case("manipnet", _LONG_BASE[seed % len(_LONG_BASE)])


@family(
    "leap",
    20,
    "Leap rig (gestification): rForeArm root at the wrist > rHand > "
    "fingers, millimetres, hand 36-40 fps; odd seeds left; body 25-120 fps",
    _RIG_DEV,
)
def _leap(seed: int) -> Case:
    return make_rig_case("leap", seed)


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
    maps = {
        "handsplice": res.alignment.map,
        "pass1": f.grid_to_hand(MG.merge_path(res.alignment.pass1.path, n, m, blend)),
    }
    band = Band.sakoe_chiba(n, m, C.BAND.resolve(None, n, f.fps))
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
    out = {
        "name": case.name,
        "family": case.family,
        "seconds": seconds,
        "methods": {},
        "frame_ms": 1000.0 / case.body.fps,
    }
    pairs = None
    for name, hmap in maps.items():
        motion = TR.apply_transfer(plan, case.body, case.hand, hmap, res.features.body_fk)
        pairs = pairs or finger_pairs(motion, case.reference)
        err_ms = (np.asarray(hmap) - case.truth) / case.hand.fps * 1000.0
        out["methods"][name] = {
            "timing_ms": np.abs(err_ms),
            "finger_deg": finger_error(motion, case.reference, pairs),
        }
    return out


def summarise(results: list[dict]) -> dict:
    """Per family and method: pooled timing median / p95 (ms), median in body frames,
    mean finger error and left_share = (method - oracle) / (uniform - oracle)."""
    table = {}
    for fam in FAMILIES:
        rs = [r for r in results if r["bench_family"] == fam]
        if not rs:
            continue
        table[fam] = {}
        for meth in METHODS:
            t = np.concatenate([r["methods"][meth]["timing_ms"] for r in rs])
            tf = np.concatenate([r["methods"][meth]["timing_ms"] / r["frame_ms"] for r in rs])
            fe = np.array([r["methods"][meth]["finger_deg"] for r in rs])
            table[fam][meth] = {
                "median_ms": float(np.median(t)),
                "p95_ms": float(np.percentile(t, 95)),
                "median_frames": float(np.median(tf)),
                "finger_deg": float(fe.mean()),
                "cases": len(rs),
            }
        orc, uni = table[fam]["oracle"]["finger_deg"], table[fam]["uniform"]["finger_deg"]
        for meth in METHODS:
            row = table[fam][meth]
            row["left_share"] = (row["finger_deg"] - orc) / max(uni - orc, 1e-9)
    return table


def goals(table: dict, results: list[dict]) -> list[str]:
    lines = []
    for fam, rows in table.items():
        hs, orc = rows["handsplice"], rows["oracle"]
        checks = [
            (
                "median timing error <= 1 body frame",
                hs["median_frames"] <= 1.0,
                f"{hs['median_ms']:.1f} ms = {hs['median_frames']:.2f} body frames",
            ),
            ("95th percentile < 100 ms", hs["p95_ms"] < 100.0, f"{hs['p95_ms']:.1f} ms"),
            ("left_share <= 0.2", hs["left_share"] <= 0.2, f"{hs['left_share']:.3f}"),
            (
                "finger error within 1 deg of the oracle",
                hs["finger_deg"] - orc["finger_deg"] <= 1.0,
                f"{hs['finger_deg']:.2f} vs {orc['finger_deg']:.2f} deg",
            ),
        ]
        for meth in ("pass1", "dtw_positions", "dtw_derivatives", "uniform"):
            b = rows[meth]
            better = (
                hs["median_ms"] < b["median_ms"]
                and hs["p95_ms"] < b["p95_ms"]
                and hs["finger_deg"] < b["finger_deg"]
            )
            checks.append(
                (
                    f"better than {LABELS[meth]} (median, p95 and finger error)",
                    better,
                    f"{b['median_ms']:.1f} / {b['p95_ms']:.1f} ms, {b['finger_deg']:.2f} deg",
                )
            )
        for text, ok, value in checks:
            lines.append(f"| {fam} | {text} | {'met' if ok else '**missed**'} | {value} |")
    return lines


def per_case_wins(results: list[dict]) -> list[str]:
    lines = []
    for fam in FAMILIES:
        rs = [r for r in results if r["bench_family"] == fam]
        if not rs:
            continue
        parts = []
        for meth in ("pass1", "dtw_positions", "dtw_derivatives", "uniform"):
            wins = sum(
                np.mean(r["methods"]["handsplice"]["timing_ms"])
                <= np.mean(r["methods"][meth]["timing_ms"])
                for r in rs
            )
            parts.append(f"{LABELS[meth]} {wins}/{len(rs)}")
        lines.append(
            f"- {fam}: HandSplice's mean timing error is lower on " + ", ".join(parts) + " cases"
        )
    return lines


def markdown(table: dict, results: list[dict], seeds: dict) -> str:
    title = "## Splice accuracy (issue 5)"
    if set(seeds) != set(FAMILIES):
        title += ": families " + ", ".join(seeds)
    out = [
        title,
        "",
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
        "0.05 rad) were chosen on seeds 100-107 (issue-12 families: developed on seeds "
        "200-207, rig families left/manipnet/leap on 300-311); reported seeds: "
        + ", ".join(f"{k} {_seed_text(v)}" for k, v in seeds.items())
        + ". "
        "left_share = (finger error - oracle) / (uniform - oracle).",
        "",
    ]
    for fam, rows in table.items():
        out += [
            f"### {fam} ({rows['handsplice']['cases']} cases)",
            "",
            FAMILIES[fam].note + ".",
            "",
            "| method | timing median (ms) | timing p95 (ms) | left_share | finger error (deg) |",
            "|---|---|---|---|---|",
        ]
        for meth in METHODS:
            r = rows[meth]
            name = f"**{LABELS[meth]}**" if meth == "handsplice" else LABELS[meth]
            out.append(
                f"| {name} | {r['median_ms']:.1f} | {r['p95_ms']:.1f} | "
                f"{r['left_share']:.3f} | {r['finger_deg']:.2f} |"
            )
        out.append("")
    out += ["### Goals", "", "| family | goal | status | value |", "|---|---|---|---|"]
    out += goals(table, results)
    out += ["", "Per case:"] + per_case_wins(results)
    worst = sorted(
        results, key=lambda r: -np.percentile(r["methods"]["handsplice"]["timing_ms"], 95)
    )[:3]
    out += [
        "",
        "Hardest cases (HandSplice p95): "
        + "; ".join(
            f"{r['name']} {np.percentile(r['methods']['handsplice']['timing_ms'], 95):.0f} ms"
            for r in worst
        )
        + ". They are long arm holds during which the synthetic fingers keep "
        "moving (no arm signal can time them) or body takes whose trunk turns and bends while the "
        "hand take's trunk is still.",
    ]
    secs = np.array([r["seconds"] for r in results])
    out += [
        "",
        f"HandSplice alignment time per case (prepare + 2 passes + merge): median "
        f"{np.median(secs) * 1000:.0f} ms, max {secs.max() * 1000:.0f} ms.",
    ]
    return "\n".join(out)


def _seed_text(seeds: list[int]) -> str:
    if seeds and seeds == list(range(seeds[0], seeds[-1] + 1)):
        return f"{seeds[0]}-{seeds[-1]}"
    return ",".join(str(s) for s in seeds)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a few seeds per family, no RESULTS.md")
    ap.add_argument("--tuning", action="store_true", help="run the tuning seeds instead")
    ap.add_argument(
        "--seeds",
        type=int,
        default=0,
        help="only the first N reported seeds of each family (no RESULTS.md)",
    )
    ap.add_argument(
        "--section", default="", help="with --families: write the table to this RESULTS.md section"
    )
    ap.add_argument(
        "--families",
        default="",
        help=f"comma-separated subset of {', '.join(FAMILIES)} (no RESULTS.md)",
    )
    args = ap.parse_args(argv)
    names = [f.strip() for f in args.families.split(",") if f.strip()] or list(FAMILIES)
    unknown = [f for f in names if f not in FAMILIES]
    if unknown:
        ap.error(f"unknown families {unknown}; known: {', '.join(FAMILIES)}")
    seeds = {}
    for f in names:
        fam = FAMILIES[f]
        count = 3 if args.quick else (min(args.seeds, fam.seeds) if args.seeds else fam.seeds)
        seeds[f] = list(fam.tuning_seeds) if args.tuning else list(range(count))
    results = []
    t0 = time.perf_counter()
    for fam, seed_list in seeds.items():
        for seed in seed_list:
            case = FAMILIES[fam].make(seed)
            r = evaluate(case)
            r["bench_family"] = fam
            results.append(r)
            hs = r["methods"]["handsplice"]
            print(
                f"{case.name:45s} median {np.median(hs['timing_ms']):6.1f} ms  p95 "
                f"{np.percentile(hs['timing_ms'], 95):6.1f} ms  fingers "
                f"{hs['finger_deg']:.2f} deg (oracle {r['methods']['oracle']['finger_deg']:.2f})",
                flush=True,
            )
    table = summarise(results)
    md = markdown(table, results, seeds)
    print(md)
    print(f"\n{time.perf_counter() - t0:.0f} s")
    if not (args.quick or args.tuning or args.families or args.seeds):
        write_section("splice_accuracy", md)
    elif args.section and args.families and not (args.quick or args.tuning):
        write_section(args.section, md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
