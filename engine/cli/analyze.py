"""``handsplice analyze FILE``: gesture phases, handedness and key poses of a take.

Prints a summary (or JSON with ``--json``); ``--eaf`` and ``--csv`` write the
phase and handedness tiers (atomically) for ELAN or a spreadsheet.
"""

from __future__ import annotations

import argparse

from engine.cli import output_file


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "analyze",
        help="gesture phases, handedness (RH/LH/2H) and key poses of a body take",
        description="Segment each hand into rest, preparation, stroke, hold and retraction, "
        "label each gesture phrase RH, LH or 2H, and find key poses (Jin & Hahn).",
    )
    p.add_argument("file", help="body take (.bvh)")
    p.add_argument(
        "--eaf", type=output_file, metavar="OUT.eaf", help="write ELAN tiers (phases, handedness)"
    )
    p.add_argument(
        "--csv", type=output_file, metavar="OUT.csv", help="write the annotations as CSV"
    )
    p.add_argument("--json", action="store_true", help="print the full result as JSON")
    p.add_argument(
        "--threshold", type=float, default=0.12, help="handedness threshold in m/s (default 0.12)"
    )
    p.add_argument(
        "--hold-speed",
        type=float,
        default=None,
        help="m/s below which a hand is still (default 0.12)",
    )
    p.add_argument(
        "--stroke-accel",
        type=float,
        default=None,
        help="m/s^2, smallest peak acceleration of a stroke (default 1.0)",
    )
    p.add_argument(
        "--rest-radius",
        type=float,
        default=None,
        help="m, distance from the rest position that still counts as rest (0.15)",
    )
    p.add_argument(
        "--reference",
        choices=("shoulder", "pelvis"),
        default=None,
        help="origin of the body frame for the wrist (default shoulder)",
    )
    p.add_argument("--roles", metavar="ROLES.json", help="joint role overrides (JSON)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import json
    from dataclasses import replace

    from engine.base.errors import MotionFormatError
    from engine.cli import load_take
    from engine.gesture.analysis import analyze_take, summary_lines
    from engine.gesture.body import find_arms
    from engine.gesture.handedness import HandednessParameters
    from engine.gesture.phases import PhaseParameters
    from engine.model.motion import Motion

    params = PhaseParameters()
    changes = {
        k: v
        for k, v in (
            ("hold_speed", args.hold_speed),
            ("stroke_accel", args.stroke_accel),
            ("rest_radius", args.rest_radius),
            ("reference", args.reference),
        )
        if v is not None
    }
    params = replace(params, **changes)  # the flags' values, checked before the take is read
    handedness = HandednessParameters(threshold=args.threshold)
    take = load_take(args.file)
    if not isinstance(take, Motion):
        raise MotionFormatError(args.file, "analyze needs a skeletal take (.bvh), not markers")
    overrides = None
    if args.roles:
        from engine.model.roles import load_role_overrides

        overrides = load_role_overrides(args.roles)
    arms = find_arms(take.skeleton, overrides)
    result = analyze_take(take, params, handedness, arms=arms)
    if args.eaf:
        from engine.io.eaf import write_eaf

        write_eaf(args.eaf, result.phases, result.handedness, source=str(args.file))
    if args.csv:
        from engine.io.eaf import write_csv

        write_csv(args.csv, result.phases, result.handedness)
    if args.json:
        print(json.dumps(result.to_dict()))
    else:
        print("\n".join(summary_lines(result)))
    return 0
