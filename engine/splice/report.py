"""REPORT.json: what a splice did, for people and for tools.

Keys (all frame numbers 0-based):

``version``            report format version (1)
``body``, ``hand``     ``{"file", "frames", "fps"}`` of the inputs; ``output``: path or null
``sides``              sides spliced (``["right", "left"]`` when both hands aligned jointly)
``map``                for every body frame, the matched frame of the original hand take
                       (float; fractional frames are slerped)
``map_seconds``        the same in seconds of the hand take
``grid``               ``{"fps", "hand_frames"}``: the alignment grid (hand take resampled to
                       the body's rate); paths, bands, points and ``warp`` use its columns
``warp``               ``map`` in grid columns
``pass1``, ``pass2``   ``{"path": [[body, grid hand], ...], "cost", "band": {"lo", "hi",
                       "cells"}, "metric", "seconds"}``; pass 2 adds ``"radius"`` and the
                       trunk ``headings_deg`` removed from each take (``body``: list or
                       constant, ``hand``)
``parameters``         band, refine_band, points (grid units and as given), theta, n_bins,
                       smoothing_s, dead_zone, step1, step2, blend
``overlap``            ``{"body": [first, last], "hand": [first, last]}``: the frames the
                       alignment matches (hand: frames of the original hand take); with open
                       ends (the default) either take may begin earlier or end later
``unmatched_body``     ``[[first, last], ...]`` body frame ranges outside the overlap: no timing
                       is invented there, the fingers hold the first / last matched hand pose
                       (eased in and out over a short blend)
``timings_s``          seconds per stage (prepare, pass1, pass2, merge, transfer, total)
``transfer``           per side: wrist transferred or kept, finger joints driven, joints
                       grafted (names), graft scale; ``notes``
``uncertainty_ms``     for every body frame, how far (ms of the hand take) the matched hand
                       time could move at little extra cost (``engine.splice.uncertainty``)
``strokes``            the body take's gesture strokes: ``{"start", "end", "uncertainty_ms",
                       "verdict"}`` (verdict ``ok`` < 50 ms, ``check`` <= 100 ms, ``desync``;
                       in a pair not pinned: ``typical``/``check``/``desync`` for up to 50,
                       up to 100, more ms above its typical level; ``unmatched``: outside
                       the overlap)
``suggested_points``   ``[[body frame, hand frame], ...]``: the least certain places, with the
                       hand frame matched there now: where a matching point helps most
``desync``             ``{"threshold_ms", "typical_ms", "pinned", "summary"}``: the pair's
                       typical uncertainty (median over matched frames), whether it is at
                       most the threshold, and the one-line summary the CLI prints
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from engine.base.atomic import write_text
from engine.dtw import constraints as C

VERSION = 1


def _round(x, nd: int = 4) -> list:
    return [round(float(v), nd) for v in np.asarray(x, dtype=float).ravel()]


def _band(band) -> dict:
    return {
        "lo": [int(v) for v in band.lo],
        "hi": [int(v) for v in band.hi],
        "cells": int(band.area),
    }


def _headings(h: np.ndarray):
    h = np.degrees(np.asarray(h, dtype=float))
    if h.size and np.allclose(h, h[0]):
        return round(float(h[0]), 3)
    return _round(h, 3)


def build_report(
    result, body_path=None, hand_path=None, output_path=None, points_given=None, assessment=None
) -> dict:
    """The REPORT.json dictionary of a :class:`engine.splice.pipeline.SpliceResult`.

    assessment : engine.splice.uncertainty.Assessment, optional (adds the trust keys)
    """
    f, a = result.features, result.alignment
    report = {
        "version": VERSION,
        "body": {
            "file": str(body_path or f.body.meta.source),
            "frames": int(f.n),
            "fps": float(f.fps),
        },
        "hand": {
            "file": str(hand_path or f.hand.meta.source),
            "frames": int(f.m_hand),
            "fps": float(f.hand_fps),
        },
        "output": None if output_path is None else str(output_path),
        "sides": list(f.sides),
        "map": _round(a.map),
        "map_seconds": _round(np.asarray(a.map) / f.hand_fps, 5),
        "grid": {"fps": float(f.fps), "hand_frames": int(f.m)},
        "warp": _round(a.warp),
        "pass1": {
            "path": np.asarray(a.pass1.path).tolist(),
            "cost": float(a.pass1.cost),
            "band": _band(a.pass1.band),
            "metric": a.pass1.metric,
            "seconds": round(a.pass1.seconds, 6),
        },
        "pass2": {
            "path": np.asarray(a.pass2.path).tolist(),
            "cost": float(a.pass2.cost),
            "band": _band(a.pass2.band),
            "metric": a.pass2.metric,
            "seconds": round(a.pass2.seconds, 6),
            "radius": int(a.radius),
            "headings_deg": {"body": _headings(a.body_heading), "hand": _headings(a.hand_heading)},
        },
        "parameters": {
            "band": a.band,
            "refine_band": a.refine_band,
            "points": [[int(x), int(y), float(t)] for x, y, t in a.points],
            "points_given": None if points_given is None else [list(p) for p in points_given],
            "blend": a.blend,
            **{k: v for k, v in f.params.items() if not k.startswith("_")},
        },
        "timings_s": {k: round(float(v), 6) for k, v in result.timings.items()},
    }
    (b0, b1), (h0, h1) = a.overlap
    hand_ends = f.grid_to_hand(np.array([h0, h1], dtype=float))
    report["overlap"] = {
        "body": [int(b0), int(b1)],
        "hand": [int(np.floor(hand_ends[0] + 1e-6)), int(np.ceil(hand_ends[1] - 1e-6))],
    }
    report["unmatched_body"] = [[int(x), int(y)] for x, y in a.unmatched_body]
    report["parameters"]["ends"] = a.ends
    report["parameters"]["max_unmatched_s"] = a.max_unmatched_s
    report["parameters"]["skip"] = {"pass1": a.pass1.ends.skip, "pass2": a.pass2.ends.skip}
    plan = f.params.get("_plan")
    if plan is not None:
        sk = plan.skeleton
        report["transfer"] = {
            "sides": {
                sp.side: {
                    "wrist": sk.names[plan.out(sp.body_frame.wrist)] if sp.wrist else None,
                    "fingers": [sk.names[m.body] for m in sp.mapped],
                    "grafted": [sk.names[new] for new, _ in sp.grafted],
                    "inserted": [sk.names[new] for new in sp.inserted],
                    "graft_scale": round(float(sp.scale), 6),
                    "body_dorsal_from": sp.body_frame.dorsal_source,
                    "hand_dorsal_from": sp.hand_frame.dorsal_source,
                }
                for sp in plan.sides
            },
            "notes": list(plan.notes),
        }
    if assessment is not None:
        report.update(assessment.report_fields())
    return report


#: what a user can do about unmatched ends (every frame matched; a longer limit), by front:
#: the command line's flags, or the page's words for them (it has no control for either);
#: ``unmatched_summary(..., front=)`` picks one
REMEDIES = {
    "cli": (
        "--ends fixed matches every frame",
        "--max-unmatched SECONDS allows longer unmatched ends",
    ),
    "page": (
        "the command line's --ends fixed matches every frame",
        f"a larger '{C.MAX_UNMATCHED_LABEL}' (under the band widths) allows longer unmatched ends",
    ),
}


def unmatched_summary(
    ranges,
    fps: float,
    limit: int | None = None,
    limit_given: bool = False,
    front: str = "cli",
    retimed: bool = False,
) -> str:
    """One sentence on the body frames the alignment leaves without hand timing (open ends:
    a take begins earlier or ends later than the other), or "" when every body frame is
    matched. ``ranges``: ``[(first, last), ...]`` body frames (``unmatched_body``); ``fps``:
    the body take's rate (frames per second); ``limit``: the open-end limit, body frames
    per end (``SpliceAlignment.unmatched_limit``; ``limit_given``: set by
    ``--max-unmatched`` rather than the default, ``constraints.UNMATCHED_DEFAULT``). An end as long
    as the limit was cut there by the rule, not by the data, and the sentence says so.
    ``retimed``: a marker body (no fingers of its own): the output is the hand take retimed
    to it, which holds its nearest matched frame there."""
    ranges = [(int(a), int(b)) for a, b in ranges]
    if not ranges:
        return ""
    frames = sum(b - a + 1 for a, b in ranges)
    spans = ", ".join(f"{a}-{b}" if b > a else f"{a}" for a, b in ranges)
    holds = (
        "the retimed hand take holds its nearest matched frame there"
        if retimed
        else "the fingers hold the nearest matched pose there"
    )
    text = (
        f"body frames {spans} ({frames / float(fps):.1f} s) have no hand match: {holds} "
        f"({REMEDIES[front][0]})"
    )
    capped = limit is not None and limit > 0 and any(b - a + 1 >= limit for a, b in ranges)
    if capped:
        rule = "--max-unmatched" if limit_given else C.UNMATCHED_DEFAULT
        text += (
            f"; {limit} frames ({limit / float(fps):.1f} s) at an end is the open-end limit "
            f"({rule}), so the takes may overlap less than this: {REMEDIES[front][1]}"
        )
    return text


def dumps(report: dict) -> str:
    """JSON text with one top-level key per line (long arrays stay on their line)."""
    items = [
        f"  {json.dumps(k)}: {json.dumps(v, separators=(', ', ': '))}" for k, v in report.items()
    ]
    return "{\n" + ",\n".join(items) + "\n}\n"


def write_report(path: str | Path, report: dict) -> None:
    """Write ``report`` as JSON (atomically)."""
    write_text(path, dumps(report))
