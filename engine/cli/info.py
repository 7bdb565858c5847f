"""``handsplice info FILE [--json] [--roles MAP.json] [--side right|left]``.

Prints what a capture file holds: format, frames, fps, duration, joints, units and
up axis, and the joint roles found per side (BVH), or the markers with their gap
percentages (C3D, TRC); of a GLB (the app's or ``render``'s 3D export, any binary glTF
2.0), its skin, animations and the skin's joints with their roles. Each finger is listed
with its whole chain (a joint between the numbered ones, such as the ``THUMB_CMC_AA`` a
splice inserts, too). ``--json`` prints one JSON object instead (schema below).

JSON keys: ``file``, ``format`` ("bvh", "c3d", "trc"), ``frames``, ``fps``,
``duration_s``, ``units``, ``up_axis``; BVH: ``joints`` {``count``, ``names``},
``roles`` (``Roles.to_dict()``: per side role -> joint name or null, ``fingers``
lists, ``tips``, ``metacarpals``; ``unsided``; ``side_source``), ``sides`` (sides
with a wrist), ``hand_sides`` (sides with finger joints), ``finger_chains`` (per side
and ``unsided``: finger -> every joint name of its chain); GLB: as BVH (``format``
"glb", ``units`` "m", ``up_axis`` "y") plus ``generator``, ``nodes``, ``skin``
{``meshes``, ``vertices``}, ``animations`` [{``name``, ``channels``, ``frames``, ``fps``}]
(the frames are the first animation's); C3D/TRC: ``markers``
{``count``, ``labels``, ``gap_percent`` (all samples), ``gaps`` {label: percent}},
``roles`` (``MarkerRoles.to_dict()``: per side shoulder, elbow, forearm, wrist_radial,
wrist_ulnar, hand -> label or null; ``unsided``; ``side_source``), ``sides``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "info",
        help="describe a capture file (.bvh, .c3d, .trc) or a 3D export (.glb)",
        description="Describe a capture file: format, frames, fps, duration, joints, "
        "units, up axis, and the arm/hand joint roles per side; or a GLB (the app's or "
        "render's 3D export): its skin, animation, joints and their roles.",
    )
    p.add_argument("file", help="a .bvh, .c3d or .trc file, or a .glb")
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
    if str(args.file).lower().endswith(".glb"):  # a 3D export (the app's, render's)
        report = describe_glb(args.file, overrides=overrides, side=args.side)
        warn_side(args.file, args.side)
    else:
        take = load_take(args.file)
        warn_side(args.file, args.side, take)
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


def warn_side(path, side, take=None) -> None:
    """``--side`` contradicting the file's name: one warning line (the side asked wins).
    ``take``: the take as read; when its joint names contradict the file name (the one rule,
    ``engine.model.roles.hand_file_side``) and no side, or their side, is asked for, the
    warning is theirs."""
    from engine.cli import warn
    from engine.model.motion import Motion
    from engine.model.roles import hand_file_side, side_name_conflict

    if isinstance(take, Motion):
        named = hand_file_side(Path(str(path)).name, take.skeleton)
        if named.warning and side in (None, "auto", named.side):
            warn(named.warning)
            return
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
        "finger_chains": finger_chains(motion.skeleton, roles),
        "sides": roles.sides_found(),
        "hand_sides": [s for s in SIDES if roles.side(s).has_fingers],
        "geometry_side": _geometry_side(motion, roles),
    }


def _geometry_side(motion, roles) -> dict | None:
    """For a hand take whose names carry no side: the side ``splice`` without ``--side``
    takes it as (its geometry: ``engine.model.hand_side.sided_roles``'s rule,
    :func:`~engine.model.hand_side.geometric_side`), ``{"side": "right"|"left"|None,
    "reason": ...}``; None when the names give the side."""
    from engine.model.hand_side import geometric_side

    arm = roles.unsided
    if arm is None or not arm.has_fingers:
        return None
    vote = geometric_side(motion, arm)
    return {"side": vote.side, "reason": vote.reason}


def finger_chains(skeleton, roles) -> dict:
    """Per side (and ``unsided``) each finger's whole chain of joint names under the hand,
    proximal first (``ArmRoles.finger_chain``: metacarpal, the numbered joints, any joint
    between them such as a splice's inserted ``THUMB_CMC_AA``, the tip); ``[]`` for a
    finger the arm lacks. The role joints alone are in ``roles``."""
    from engine.model.roles import FINGERS, SIDES

    arms = {side: roles.side(side) for side in SIDES}
    if roles.unsided is not None:
        arms["unsided"] = roles.unsided
    return {
        key: {
            f: [skeleton.names[j] for j in arm.finger_chain(skeleton, f) or arm.fingers[f]]
            for f in FINGERS
        }
        for key, arm in arms.items()
    }


def describe_glb(path, overrides=None, side=None) -> dict:
    """The ``info`` report of a GLB (``engine.io.glb``): its skin's joints and roles as a
    BVH's, the first animation's frames, and ``skin`` {``meshes``, ``vertices``} and
    ``animations`` [{``name``, ``channels``, ``frames``, ``fps``}]. Units metres, Y up
    (glTF's)."""
    from engine.io.glb import read_glb_summary
    from engine.model.roles import SIDES, find_roles, side_from_name

    glb = read_glb_summary(path)
    first = glb.animations[0] if glb.animations else None
    frames, fps = (first.frames, first.fps) if first is not None else (0, 0.0)
    report = {
        "file": str(path),
        "format": "glb",
        "generator": glb.generator,
        "frames": frames,
        "fps": _number(fps),
        "duration_s": _number(frames / fps if fps > 0 else 0.0),
        "units": "m",
        "up_axis": "y",
        "notes": [],
        "nodes": glb.nodes,
        "skin": {"meshes": glb.skinned_meshes, "vertices": glb.skinned_vertices},
        "animations": [
            {"name": a.name, "channels": a.channels, "frames": a.frames, "fps": _number(a.fps)}
            for a in glb.animations
        ],
    }
    sk = glb.skeleton
    if sk is None:
        return {**report, "joints": {"count": 0, "names": []}}
    roles = find_roles(sk, overrides=overrides, side_hint=side or side_from_name(path))
    return {
        **report,
        "joints": {"count": sk.n_joints, "names": list(sk.names)},
        "roles": roles.to_dict(),
        "finger_chains": finger_chains(sk, roles),
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
    if report["format"] == "glb":
        rows[1] = ("format", "GLB (binary glTF 2.0)")
        rows += _glb_rows(report)
        rows += [("units", units), ("up axis", up)]
        if "roles" in report:
            rows += _role_rows(report)
    elif "joints" in report:
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
        fingers = _finger_items(report, side)
        tips = [f"{f}={j}" for f, j in arm["tips"].items() if j]
        rows += [(f"{side} fingers", line) for line in _wrap(fingers or ["none"], 72)]
        if tips:
            rows += [(f"{side} tips", line) for line in _wrap(tips, 72)]
    if roles.get("unsided"):
        arm = roles["unsided"]
        found = [f"{k}={arm[k]}" for k in _ARM_KEYS if arm[k] is not None]
        fingers = _finger_items(report, "unsided")
        rows += [("no side", line) for line in _wrap(found + fingers, 72)]
        guess = report.get("geometry_side") or {}
        if guess.get("side"):
            rows.append(
                (
                    "",
                    f"(names carry no side: splice without --side takes it as the "
                    f"{guess['side']} hand, the hand its geometry forms; pass --side "
                    "right|left to choose)",
                )
            )
        elif guess:
            rows.append(
                (
                    "",
                    f"(names carry no side; its geometry does not tell "
                    f"({guess['reason']}): pass --side right|left)",
                )
            )
        else:
            rows.append(("", "(names carry no side: pass --side right|left)"))
    return rows


def _glb_rows(report: dict) -> list[tuple[str, str]]:
    """A GLB's joints, skin and animations (``describe_glb``)."""
    joints = report["joints"]["count"]
    skin = report["skin"]
    rows = [("joints", f"{joints} (the skin's)" if joints else "none (the file has no skin)")]
    if skin["meshes"]:
        meshes = ", ".join(skin["meshes"])
        rows.append(("skin", f"{meshes}: {skin['vertices']:,} vertices on {joints} joints"))
    else:
        rows.append(("skin", "no skinned mesh"))
    for a in report["animations"] or [None]:
        if a is None:
            rows.append(("animation", "none"))
            continue
        rate = f" at {a['fps']:g} fps" if a["fps"] else ""
        rows.append(
            ("animation", f"{a['name']}: {a['channels']} channels, {a['frames']} frames{rate}")
        )
    rows.append(("nodes", str(report["nodes"])))
    return rows


def _finger_items(report: dict, side: str) -> list[str]:
    """``thumb[j1 j2 ...]`` per finger of ``side``: its whole chain (``finger_chains``)."""
    arm = report["roles"][side]
    chains = report.get("finger_chains", {}).get(side) or arm["fingers"]
    return [f"{f}[{' '.join(chains[f] or js)}]" for f, js in arm["fingers"].items() if js]


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
