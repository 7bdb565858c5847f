"""``handsplice info FILE [--json] [--roles MAP.json] [--side right|left]``.

Prints what a capture file holds: format, frames, fps, duration, joints, units and
up axis, and the joint roles found per side (BVH), or the markers with their gap
percentages (C3D, TRC). ``--json`` prints one JSON object instead (schema below).

JSON keys: ``file``, ``format`` ("bvh", "c3d", "trc"), ``frames``, ``fps``,
``duration_s``, ``units``, ``up_axis``; BVH: ``joints`` {``count``, ``names``},
``roles`` (``Roles.to_dict()``: per side role -> joint name or null, ``fingers``
lists, ``tips``, ``metacarpals``; ``unsided``; ``side_source``), ``sides`` (sides
with a wrist), ``hand_sides`` (sides with finger joints); C3D/TRC: ``markers``
{``count``, ``labels``, ``gap_percent`` (all samples), ``gaps`` {label: percent}},
``roles`` (``MarkerRoles.to_dict()``: per side shoulder, elbow, forearm, wrist_radial,
wrist_ulnar, hand -> label or null; ``unsided``; ``side_source``), ``sides``.
"""

from __future__ import annotations

import argparse
import json
import sys


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "info",
        help="describe a capture file (.bvh, .c3d, .trc)",
        description="Describe a capture file: format, frames, fps, duration, joints, "
        "units, up axis, and the arm/hand joint roles per side.",
    )
    p.add_argument("file", help="a .bvh, .c3d or .trc file")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument(
        "--roles",
        metavar="MAP.json",
        help='joint-role overrides, e.g. {"right.wrist": "Bip01_R_Hand"}',
    )
    p.add_argument(
        "--side",
        choices=["right", "left"],
        help="side of a take whose joint or marker names carry none "
        "(default: from the file name, e.g. mug1_rightHand.bvh)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from engine.cli import load_take
    from engine.model.motion import MarkerSet

    overrides = None
    if args.roles:
        from engine.model.roles import load_role_overrides

        overrides = load_role_overrides(args.roles)
    take = load_take(args.file)
    warn_side(args.file, args.side)
    if isinstance(take, MarkerSet):
        if overrides:
            from engine.base.errors import ParameterError

            raise ParameterError(
                f"--roles applies to skeletal takes (.bvh); {args.file} holds markers"
            )
        report = describe_markers(take, args.file, side=args.side)
    else:
        report = describe_motion(take, args.file, overrides=overrides, side=args.side)
    if args.json:
        json.dump(report, sys.stdout, indent=2)
        sys.stdout.write("\n")
    else:
        sys.stdout.write(format_text(report))
    return 0


def warn_side(path, side) -> None:
    """``--side`` contradicting the file's name: one warning line (the side asked wins)."""
    from engine.cli import warn
    from engine.model.roles import side_name_conflict

    conflict = side_name_conflict(path, side)
    if conflict:
        warn(f"{conflict} (leave --side out to follow the name)")


def describe_motion(motion, path, overrides=None, side=None) -> dict:
    """The ``info`` report of a skeletal take as a JSON-ready dict."""
    from engine.model.roles import SIDES, find_roles, side_from_name

    hint = side or side_from_name(path)
    roles = find_roles(motion.skeleton, overrides=overrides, side_hint=hint)
    return {
        "file": str(path),
        "format": motion.meta.format,
        "frames": motion.n_frames,
        "fps": _number(motion.fps),
        "duration_s": _number(motion.duration),
        "units": motion.meta.units,
        "up_axis": motion.meta.up_axis,
        "notes": list(motion.meta.notes),  # also printed on stderr (engine.cli.load_take)
        "joints": {"count": motion.skeleton.n_joints, "names": list(motion.skeleton.names)},
        "roles": roles.to_dict(),
        "sides": roles.sides_found(),
        "hand_sides": [s for s in SIDES if roles.side(s).has_fingers],
    }


def describe_markers(markers, path, side=None) -> dict:
    """The ``info`` report of a marker take (C3D, TRC) as a JSON-ready dict."""
    import numpy as np

    from engine.model.roles import SIDES, find_marker_roles, side_from_name

    roles = find_marker_roles(markers.labels, side_hint=side or side_from_name(path))

    missing = np.isnan(markers.points).any(axis=2)  # (F, M)
    n = max(markers.n_frames, 1)
    gaps = {
        label: _number(100.0 * missing[:, i].sum() / n, 2) for i, label in enumerate(markers.labels)
    }
    total = 100.0 * missing.sum() / max(missing.size, 1)
    return {
        "file": str(path),
        "format": markers.meta.format,
        "frames": markers.n_frames,
        "fps": _number(markers.fps),
        "duration_s": _number(markers.duration),
        "units": markers.meta.units,
        "up_axis": markers.meta.up_axis,
        "notes": list(markers.meta.notes),  # also printed on stderr (engine.cli.load_take)
        "markers": {
            "count": len(markers.labels),
            "labels": list(markers.labels),
            "gap_percent": _number(total, 2),
            "gaps": gaps,
        },
        "roles": roles.to_dict(),
        "sides": [
            s
            for s in SIDES
            if roles.side(s)["wrist_radial"] is not None or roles.side(s)["wrist_ulnar"] is not None
        ],
    }


def _number(x: float, digits: int = 6) -> float | int:
    x = round(float(x), digits)
    return int(x) if x.is_integer() else x


_ARM_KEYS = ("clavicle", "shoulder", "elbow", "wrist", "hand", "hand_end")


def format_text(report: dict) -> str:
    """Human-readable, aligned text of an ``info`` report."""
    from pathlib import Path

    rows: list[tuple[str, str]] = [
        ("file", Path(report["file"]).name),
        ("format", report["format"].upper()),
        ("frames", str(report["frames"])),
        ("fps", f"{report['fps']:g}"),
        ("duration", f"{report['duration_s']:.3f} s"),
    ]
    units = report["units"]
    up = report["up_axis"]
    if report["format"] == "trc":
        up += " (assumed: TRC does not record it)"
    if "joints" in report:
        rows.append(("joints", str(report["joints"]["count"])))
        rows += [("units", units), ("up axis", up)]
        rows += _role_rows(report)
    else:
        m = report["markers"]
        rows += [
            ("markers", str(m["count"])),
            ("units", units),
            ("up axis", up),
            ("gaps", f"{m['gap_percent']:g}% of samples"),
        ]
        worst = sorted(m["gaps"].items(), key=lambda kv: -kv[1])[:5]
        worst = [f"{k} {v:g}%" for k, v in worst if v > 0]
        if worst:
            rows += [("most gaps", line) for line in _wrap(worst, 72)]
        rows += _marker_role_rows(report["roles"])
        rows += [("labels", line) for line in _wrap(m["labels"], 72)]
    width = max(len(k) for k, _ in rows) + 2
    out = []
    previous = None
    for key, value in rows:
        shown = key if key != previous else ""
        out.append(f"{shown:<{width}}{value}".rstrip())
        previous = key
    return "\n".join(out) + "\n"


def _role_rows(report: dict) -> list[tuple[str, str]]:
    roles = report["roles"]
    rows = []
    for side in ("right", "left"):
        arm = roles[side]
        found = [f"{k}={arm[k]}" for k in _ARM_KEYS if arm[k] is not None]
        if not found and not any(arm["fingers"].values()):
            rows.append((f"{side} arm", "none found"))
            continue
        source = roles["side_source"].get(side)
        if source and source != "names":
            found.append(f"(side from {'the file name/--side' if source == 'hint' else source})")
        rows += [(f"{side} arm", line) for line in _wrap(found, 72)]
        fingers = [f"{f}[{' '.join(js)}]" for f, js in arm["fingers"].items() if js]
        tips = [f"{f}={j}" for f, j in arm["tips"].items() if j]
        rows += [(f"{side} fingers", line) for line in _wrap(fingers or ["none"], 72)]
        if tips:
            rows += [(f"{side} tips", line) for line in _wrap(tips, 72)]
    if roles.get("unsided"):
        arm = roles["unsided"]
        found = [f"{k}={arm[k]}" for k in _ARM_KEYS if arm[k] is not None]
        fingers = [f"{f}[{' '.join(js)}]" for f, js in arm["fingers"].items() if js]
        rows += [("no side", line) for line in _wrap(found + fingers, 72)]
        rows.append(("", "(names carry no side: pass --side right|left)"))
    return rows


def _marker_role_rows(roles: dict) -> list[tuple[str, str]]:
    rows = []
    for key in ("right", "left", "unsided"):
        found = roles.get(key) or {}
        items = [f"{r}={n}" for r, n in found.items() if n is not None]
        if key == "unsided" and not items:
            continue
        label = "no side" if key == "unsided" else f"{key} arm"
        source = roles["side_source"].get(key) if key != "unsided" else None
        if items and source == "hint":
            items.append("(side from the file name/--side)")
        rows += [(label, line) for line in _wrap(items or ["none found"], 72)]
    if roles.get("unsided") and any(roles["unsided"].values()):
        rows.append(("", "(labels carry no side: pass --side right|left)"))
    return rows


def _wrap(items: list[str], width: int) -> list[str]:
    lines, cur = [], ""
    for item in items:
        if cur and len(cur) + 1 + len(item) > width:
            lines.append(cur)
            cur = item
        else:
            cur = f"{cur} {item}" if cur else item
    if cur or not lines:
        lines.append(cur)
    return lines
