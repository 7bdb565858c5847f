"""``handsplice synthesize BODY -o OUT.bvh``: give a body take moving fingers.

Either from a hand clip (``--clip``, speed-matched to the body's key poses,
flexion optionally scaled with ``--warp``) or from library poses at frames
(``--poses fist@0 open@30 ...``, interpolated with ``--easing``). Without
either, both hands hold the relaxed pose. A body without finger joints gets the
fingers of a procedural hand grafted under each wrist (``--no-graft`` refuses).
"""

from __future__ import annotations

import argparse

from engine.cli import output_file


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "synthesize",
        help="add finger motion to a body take from a hand clip or key poses",
        description="Add finger motion to a body take (fingers are grafted if it has none): "
        "from a hand clip "
        "aligned to the body's key poses (Jin & Hahn), or by interpolating library poses "
        "(relaxed, fist, open, point, ok, one..five) placed at frames.",
    )
    p.add_argument("body", help="body take with finger joints (.bvh)")
    p.add_argument(
        "-o", "--output", required=True, type=output_file, metavar="OUT.bvh", help="output BVH"
    )
    src = p.add_mutually_exclusive_group()
    src.add_argument("--clip", metavar="HAND.bvh", help="hand clip to align to the body")
    src.add_argument(
        "--poses",
        nargs="+",
        metavar="POSE@FRAME",
        help="library poses at body frames, e.g. relaxed@0 fist@30 open@-1",
    )
    p.add_argument(
        "--easing",
        choices=("hermite", "gaussian", "linear"),
        default="hermite",
        help="interpolation between poses (default hermite)",
    )
    p.add_argument(
        "--side",
        choices=("right", "left", "both"),
        default=None,
        help="hand(s) to animate (default: both for --poses, right for --clip)",
    )
    p.add_argument(
        "--warp",
        type=float,
        default=1.0,
        help="scale the clip's finger flexion by this factor (default 1)",
    )
    p.add_argument(
        "--no-graft",
        action="store_true",
        help="fail on a body without finger joints instead of grafting a hand",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from engine.base.errors import MotionFormatError, ParameterError
    from engine.cli import load_take
    from engine.gesture.synthesis import (
        check_warp,
        parse_pose_keys,
        synthesize_from_clip,
        synthesize_from_poses,
    )
    from engine.io.bvh import write_bvh
    from engine.model.motion import Motion

    # the flags' values are checked before a take is read (a long take takes seconds)
    check_warp(args.warp)
    if args.poses:
        parse_pose_keys(args.poses, None)  # their frames against the take once it is read
    body = load_take(args.body)
    if not isinstance(body, Motion):
        raise MotionFormatError(args.body, "synthesize needs a skeletal body take (.bvh)")
    if args.clip:
        if args.side == "both":
            raise ParameterError("--side both: a clip drives one hand; run twice for two")
        clip = load_take(args.clip)
        if not isinstance(clip, Motion):
            raise MotionFormatError(args.clip, "the hand clip must be a skeletal take (.bvh)")
        side = args.side or "right"
        result = synthesize_from_clip(body, clip, side, factor=args.warp, graft=not args.no_graft)
        keys = result.key_frames[side]
        how = f"clip {args.clip} on the {side} hand, {len(keys)} body key frames"
    else:
        if args.warp != 1.0:
            raise ParameterError("--warp applies to --clip only")
        sides = ("right", "left") if args.side in (None, "both") else (args.side,)
        poses = args.poses or ["relaxed@0"]
        result = synthesize_from_poses(
            body, poses, sides=sides, easing=args.easing, graft=not args.no_graft
        )
        how = f"{len(poses)} key poses ({args.easing}) on {' and '.join(sides)}"
    added = result.motion.skeleton.n_joints - body.skeleton.n_joints
    if added:
        how += f", {added} finger joints grafted"
    write_bvh(result.motion, args.output)
    print(f"wrote {args.output}: {body.n_frames} frames, {how}")
    return 0
