"""``handsplice render FILE -o OUT.{png,gif,mp4,glb}``: skinned previews of a take.

::

    handsplice render FILE -o OUT.{png,gif,mp4,glb} [--frames A:B] [--frame N]
        [--compare OTHER.bvh] [--view single|side-by-side|overlay] [--trails]
        [--size WxH] [--camera front|side|three-quarter|hands] [--fps F]
        [--roles MAP.json] [--side right|left]

* ``.png``: one frame (``--frame N``, default 0), or with ``--frames A:B`` a contact
  sheet of up to 12 frames of the range. ``.gif``/``.mp4``: the range (default the
  whole take) at ``--fps`` (default the take's rate, at most 30).
* ``.glb``: the take in 3D (glTF 2.0 binary: the skinned mannequin with its
  animation, ``engine.export.glb``) for Blender and browser glTF viewers; the range
  ``--frames`` (default all) at the take's own rate.
* ``--compare OTHER``: FILE and OTHER side by side (frames matched by time), or
  with ``--view overlay`` OTHER's stick figure over FILE's skinned mannequin.
* ``--trails``: both hands' paths over the range, coloured by gesture phase
  (``engine.gesture.phases``) when the phases can be found, else per hand.

The output is written atomically (a temporary file renamed into place). Bad
input (unreadable file, bad option) prints one line and exits with status 2.
"""

from __future__ import annotations

import argparse
import sys

from engine.cli import output_file

VIEW_CHOICES = ("single", "side-by-side", "overlay")


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "render",
        help="render a take as a skinned preview (.png, .gif, .mp4) or 3D file (.glb)",
        description="Render a take (or two, compared) with a procedural skinned mannequin: "
        "a PNG frame or contact sheet, a GIF or an MP4; or export it in 3D as "
        "a GLB (glTF 2.0, skinned and animated).",
    )
    p.add_argument("file", help="a .bvh take")
    p.add_argument(
        "-o",
        "--output",
        required=True,
        type=output_file,
        metavar="OUT",
        help="output file: .png (frame or contact sheet), .gif, .mp4 or .glb (3D)",
    )
    p.add_argument("--frames", metavar="A:B", help="frame range, Python slice (B exclusive)")
    p.add_argument("--frame", type=int, metavar="N", help="the frame of a .png (default 0)")
    p.add_argument("--compare", metavar="OTHER", help="a second take to compare with FILE")
    p.add_argument(
        "--view",
        choices=VIEW_CHOICES,
        help="single, side-by-side (default with --compare) or overlay "
        "(OTHER's stick figure over FILE)",
    )
    p.add_argument(
        "--trails", action="store_true", help="draw both hands' trails, coloured by gesture phase"
    )
    p.add_argument("--size", default="640x480", metavar="WxH", help="pixels (default 640x480)")
    p.add_argument(
        "--camera",
        default="three-quarter",
        choices=("front", "side", "three-quarter", "hands"),
        help="view direction; hands: a close-up of both hands",
    )
    p.add_argument(
        "--fps", type=float, help="frame rate of a .gif/.mp4 (default the take's, at most 30)"
    )
    p.add_argument("--roles", metavar="MAP.json", help="joint-role overrides for FILE")
    p.add_argument(
        "--side",
        choices=["right", "left"],
        help="side of a hand-only take whose joint names carry none",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from engine.base.errors import ParameterError
    from engine.render.offscreen import parse_size
    from engine.render.video import (
        FORMATS,
        check_frame,
        frame_range,
        parse_frames,
        progress_printer,
        render_to_file,
    )

    out = Path(args.output)
    if out.suffix.lower() == ".glb":
        return _export_glb(args, out)
    if out.suffix.lower() not in FORMATS:
        raise ParameterError(f"{out.name}: output must end in {', '.join(FORMATS)} or .glb")
    if args.frame is not None and out.suffix.lower() != ".png":
        raise ParameterError(
            f"--frame picks the frame of a .png; use --frames A:B for a {out.suffix} clip"
        )
    # every flag value is checked before a take is read (a long take takes seconds)
    size = parse_size(args.size)
    if args.fps is not None and not args.fps > 0:
        raise ParameterError(f"--fps {args.fps}: must be positive")
    if args.frame is not None:
        check_frame(args.frame)  # beyond the take: refused once it is read
    if args.frames:
        parse_frames(args.frames)
    view = args.view or ("side-by-side" if args.compare else "single")
    if view != "single" and not args.compare:
        raise ParameterError(f"--view {view} needs --compare OTHER")

    takes, labels = [_load(args.file)], [Path(args.file).stem]
    if args.frame is not None:
        check_frame(args.frame, takes[0].n_frames)  # before the preview is built
    if args.compare:
        takes.append(_load(args.compare))
        labels.append(Path(args.compare).stem)
    roles = [_roles(args, takes[0])] + [None] * (len(takes) - 1)

    from engine.render.offscreen import Preview

    preview = Preview(takes, labels=labels, size=size, roles=roles)
    try:
        frames = frame_range(preview.n_frames, args.frames) if args.frames else None
        phases = _phases(takes[0]) if args.trails else None
        kwargs = dict(
            view=view.replace("-", "_"),
            camera=args.camera,
            size=size,
            trails=args.trails,
            phases=phases,
        )
        if args.trails and frames is not None:
            kwargs["trail_range"] = (frames.start, frames.stop) if frames.step == 1 else None
        progress = None if args.quiet else progress_printer(f"render {out.name}")
        render_to_file(
            preview, out, frames=frames, frame=args.frame, fps=args.fps, progress=progress, **kwargs
        )
    finally:
        preview.close()
    if not args.quiet:
        print(f"wrote {out}", file=sys.stderr)
    return 0


def _export_glb(args: argparse.Namespace, out) -> int:
    """``-o OUT.glb``: the take in 3D; the picture options do not apply."""
    from engine.base.errors import ParameterError
    from engine.export.glb import write_glb
    from engine.render.video import frame_range, parse_frames

    for flag, given in (
        ("--frame", args.frame is not None),
        ("--compare", args.compare),
        ("--view", args.view),
        ("--trails", args.trails),
        ("--fps", args.fps is not None),
    ):
        if given:
            raise ParameterError(
                f"{flag} does not apply to a .glb (a 3D file of one take at "
                "its own rate); use --frames A:B to cut it"
            )
    if args.frames:
        parse_frames(args.frames)  # before the take is read
    take = _load(args.file)
    frames = frame_range(take.n_frames, args.frames) if args.frames else None
    if frames is not None and frames.step != 1:
        raise ParameterError(f"--frames {args.frames}: a .glb needs consecutive frames")
    write_glb(take, out, roles=_roles(args, take), frames=frames)
    if not args.quiet:
        print(f"wrote {out}", file=sys.stderr)
    return 0


def _load(path: str):
    from engine.base.errors import ParameterError
    from engine.cli import load_take
    from engine.model.motion import Motion

    take = load_take(path)
    if not isinstance(take, Motion):
        raise ParameterError(f"{path}: holds markers; render needs a skeletal take (.bvh)")
    if take.n_frames == 0:
        raise ParameterError(f"{path}: has no frames to render")
    return take


def _roles(args, motion):
    if not (args.roles or args.side):
        return None
    from engine.model.roles import find_roles, load_role_overrides, side_from_name

    overrides = load_role_overrides(args.roles) if args.roles else None
    hint = args.side or side_from_name(args.file)
    return find_roles(motion.skeleton, overrides=overrides, side_hint=hint)


def _phases(motion):
    """Gesture phases of a body take for the trail colours, or None (per-hand colours)."""
    from engine.base.errors import HandSpliceError

    try:
        from engine.gesture.phases import segment_phases

        return segment_phases(motion)
    except (HandSpliceError, ValueError, KeyError, ImportError):
        return None
