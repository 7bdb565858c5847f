"""``handsplice splice BODY HAND -o OUT.bvh``: put the hand take's fingers on the body take.

::

    handsplice splice BODY HAND -o OUT.bvh [--side auto|both|right|left]
        [--band 0.3|10s] [--refine-band 0.1|2s] [--match BODY_FRAME:HAND_FRAME[:TOL] ...]
        [--report REPORT.json] [--preview OUT.gif] [--roles MAP.json]
        [--session SESSION.json] [--theta window|trunk|none] [--quiet]

* A marker body (C3D/TRC) has no skeleton to receive fingers: OUT is then the hand
  take retimed to it (one frame per body frame at the body's rate,
  :mod:`engine.splice.retime`), the app's "Spliced BVH" of such a pair, byte for byte.
* ``--side``: ``auto`` (default) splices both hands, aligned jointly, when both takes
  have both, else the side they share; ``both``/``right``/``left`` insist.
* ``--band``, ``--refine-band``: a fraction of the body take (``0.3``) or seconds
  (``10s``); default the paper's 0.3 and 0.1, or a time width when narrower on long
  takes (``--help`` says which; ranges and defaults: :mod:`engine.dtw.constraints`).
* ``--match B:H[:T]``: body frame ``B`` matches frame ``H`` of the hand take (as
  numbered in the hand file, 0-based) within ``T`` hand frames (default 0). Repeat
  for several points; body frames increase, hand frames never decrease.
* ``--roles MAP.json``: joint-role overrides, ``{"body": {"right.wrist": "Name"},
  "hand": {...}}``, or one flat map applied to whichever take has those joints.
* ``--session SESSION.json``: the session file the browser app downloads
  (:mod:`engine.io.session`): side, band widths, global tolerance, matching points
  and role overrides, so an alignment tuned in the app is replayed here on BODY and
  HAND. Its points are in each file's own frames (version 1 files: the alignment grid's).
  A file made on other takes (its stored sha256 or path) is said in one warning line
  (``engine.io.session.foreign_takes``); the splice still runs. Flags given on the
  command line win over the file: ``--side``, ``--band``, ``--refine-band``,
  ``--roles``, and ``--match`` (which replaces all of the file's points).
* ``--report``: REPORT.json (see ``engine.splice.report``): the frame map, both
  passes' paths, costs and bands, the parameters and per-stage times.
* ``--preview OUT.gif`` (or .mp4/.png): a skinned preview of the spliced take.

Progress goes to stderr. Bad input (unreadable file, a pair that cannot be spliced,
infeasible matching points) prints one line and exits with status 2.
"""

from __future__ import annotations

import argparse
import sys
import time

from engine.base.jit import kernels_cached
from engine.cli import output_file


class _WidthAction(argparse.Action):
    """Stores a band width's text; its help ends with the default as
    ``engine.dtw.constraints`` applies it (``WidthRule.default_text`` of ``rule``), read
    only when the help is shown (the engine's import loads numba: not on every start)."""

    def __init__(self, *args, rule: str, **kwargs):
        self.rule = rule
        super().__init__(*args, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        setattr(namespace, self.dest, values)

    @property
    def help(self) -> str:
        from engine.dtw import constraints

        return f"{self._help}; {getattr(constraints, self.rule).default_text}"

    @help.setter
    def help(self, text: str) -> None:
        self._help = text


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "splice",
        help="splice a hand take's wrists and fingers onto a body take",
        description="Align a hand take to a body take with two-pass DTW (Majkowska et al. "
        "2006) and write the body take with the hand take's wrists and fingers.",
    )
    p.add_argument(
        "body",
        help="body take (.bvh); a marker take (.c3d/.trc) has no skeleton to receive "
        "fingers: OUT is then the hand take retimed to it",
    )
    p.add_argument("hand", help="hand take with finger joints (.bvh)")
    p.add_argument(
        "-o", "--output", required=True, type=output_file, metavar="OUT.bvh", help="spliced take"
    )
    p.add_argument(
        "--side",
        default=None,
        choices=["auto", "both", "right", "left"],
        help="hands to splice (default auto: both when both takes have both)",
    )
    p.add_argument(
        "--band",
        default=None,
        metavar="W1",
        action=_WidthAction,
        rule="BAND",
        help="pass-1 band width: fraction of the body take (0.3) or seconds (10s)",
    )
    p.add_argument(
        "--refine-band",
        default=None,
        metavar="W2",
        action=_WidthAction,
        rule="REFINE_BAND",
        help="pass-2 band width around the pass-1 path, the same forms",
    )
    p.add_argument(
        "--match",
        action="append",
        default=[],
        metavar="BODY:HAND[:TOL]",
        help="matching point: body frame, hand frame, tolerance in hand frames",
    )
    p.add_argument(
        "--report", type=output_file, metavar="REPORT.json", help="write the alignment report"
    )
    p.add_argument(
        "--preview", type=output_file, metavar="OUT.gif", help="render a preview (.gif, .mp4, .png)"
    )
    p.add_argument("--roles", metavar="MAP.json", help="joint-role overrides")
    p.add_argument(
        "--session",
        metavar="SESSION.json",
        help="the browser app's session file (side, bands, tolerance, matching "
        "points, roles); flags given here override it",
    )
    p.add_argument(
        "--theta",
        default="window",
        choices=["window", "trunk", "none"],
        help="vertical-axis rotation of pass 1: eq. 7 window (default), trunk "
        "heading difference, or none",
    )
    p.add_argument(
        "--ends",
        default="open",
        choices=["open", "fixed"],
        help="open (default): either take may begin earlier or end later than the "
        "other; fixed: first frames match and last frames match (the paper)",
    )
    p.add_argument(
        "--max-unmatched",
        default=None,
        metavar="SECONDS",
        help="open ends: seconds of each take that may stay unmatched at each end "
        # constraints.UNMATCHED_DEFAULT, written out: the parser is built without
        # importing engine.dtw (numba); tests/test_unmatched_default.py holds them equal
        "(default: half the shorter take, plus the length difference for the longer one)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    p.set_defaults(func=run)


def split_roles(mapping: dict, body, hand) -> tuple[dict | None, dict | None]:
    """Role overrides per take from a ``--roles`` map (see the module docstring)."""
    from engine.base.errors import ParameterError
    from engine.model.roles import normalize_overrides

    if not isinstance(mapping, dict):
        raise ParameterError("--roles: expected a JSON object")
    if set(mapping) & {"body", "hand"}:
        extra = set(mapping) - {"body", "hand"}
        if extra:
            raise ParameterError(f"--roles: unexpected keys {sorted(extra)} beside body/hand")
        return mapping.get("body") or None, mapping.get("hand") or None
    flat = normalize_overrides(mapping, "--roles")
    names = {v for v in flat.values() if v is not None}
    out = []
    for take in (body, hand):
        joints = set(getattr(getattr(take, "skeleton", None), "names", ()))
        out.append(flat if names and names <= joints else None)
    if names and out == [None, None]:
        raise ParameterError(
            "--roles: no take has all the joints named in the map; "
            'use {"body": {...}, "hand": {...}}'
        )
    return out[0], out[1]


class _Progress:
    """Stage lines on stderr: ``splice: pass 1 ... 0.12 s``."""

    def __init__(self, quiet: bool):
        self.quiet = quiet
        self.start: dict[str, float] = {}

    def __call__(self, stage: str, fraction: float) -> None:
        if self.quiet:
            return
        now = time.perf_counter()
        if fraction <= 0.0:
            self.start[stage] = now
            print(f"splice: {stage} ...", file=sys.stderr, flush=True)
        elif fraction >= 1.0:
            t = now - self.start.get(stage, now)
            print(f"splice: {stage} done ({t:.2f} s)", file=sys.stderr, flush=True)


def _took(wall_s: float, splice_s: float) -> str:
    """What the user waited for, and what the splice stage of it was: ``14.80 s in all
    (splice 3.02 s; the rest: reading the takes, the trust assessment, writing)``."""
    return (
        f"{wall_s:.2f} s in all (splice {splice_s:.2f} s; the rest: reading the takes, "
        "the trust assessment, writing)"
    )


def _point_source(exc, args) -> Exception:
    """A matching point's refusal (engine.dtw.constraints' text) with where the point came
    from: ``--match 80:20: matching point 2 (body 80, hand 20): ...`` or the session file's
    name; any other refusal as it is."""
    from pathlib import Path

    from engine.base.errors import ParameterError

    if exc.index is None:
        return exc
    if args.match and exc.index < len(args.match):
        return ParameterError(f"--match {str(args.match[exc.index])[:40]}: {exc}")
    if getattr(args, "session", None):
        return ParameterError(f"{Path(args.session).name}: {exc}")
    return exc


def _warn_foreign_session(spec, args, session_points: bool) -> None:
    """One warning line when the ``--session`` file names other takes than BODY and HAND
    (``engine.io.session.foreign_takes``, the one rule); ``session_points``: its matching
    points are the ones applied (no ``--match``)."""
    from pathlib import Path

    from engine.cli import warn
    from engine.io.session import foreign_takes, foreign_takes_warning

    source = Path(args.session)
    text = foreign_takes_warning(
        source.name,
        foreign_takes(spec, args.body, args.hand, source.parent),
        session_points,
    )
    if text:
        warn(text)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from engine.base.atomic import write_texts
    from engine.base.errors import ParameterError
    from engine.cli import load_take
    from engine.dtw import constraints as C
    from engine.io.bvh import iter_bvh
    from engine.splice import pipeline

    started = time.perf_counter()  # the whole wait: reading, splice, trust and writing
    out = Path(args.output)
    if out.suffix.lower() != ".bvh":
        raise ParameterError(f"{out.name}: the output must be a .bvh file")
    spec = None
    if getattr(args, "session", None):
        from engine.io.session import read_session

        spec = read_session(args.session)
    args.side = args.side or (spec.side if spec else "auto")
    band = C.BAND.parse(args.band)
    refine_band = C.REFINE_BAND.parse(args.refine_band)
    C.parse_ends(args.ends)  # refused before any file is read, as the widths are
    args.max_unmatched = C.parse_max_unmatched(args.max_unmatched)  # "20", "20s"
    if spec is not None and args.max_unmatched is None:  # the page's limit, if it set one
        args.max_unmatched = spec.max_unmatched_s
    if spec is not None:
        band = band if band is not None else spec.band
        refine_band = refine_band if refine_band is not None else spec.refine_band
    if args.preview:
        suffix = Path(args.preview).suffix.lower()
        if suffix not in (".gif", ".mp4", ".png"):
            raise ParameterError(f"--preview {args.preview}: expected a .gif, .mp4 or .png file")
    try:
        points = [p.resolved(0.0) for p in C.parse_points(list(args.match))]
    except C.ConstraintError as exc:
        raise _point_source(exc, args) from None
    # --match points are hand-file frames; so are a session file's since version 2 (version
    # 1 files hold alignment-grid frames)
    hand_points = bool(points) or spec is None or spec.hand_frames == "file"
    if not points and spec is not None:
        points = spec.constraint_points()

    body = load_take(args.body)
    hand = load_take(args.hand)
    if spec is not None:  # a session made on other takes: its points are theirs (stranger 14)
        _warn_foreign_session(spec, args, session_points=not args.match and bool(points))
    from engine.cli.info import warn_side

    warn_side(args.hand, args.side, hand)  # a right-named hand spliced as left: say so
    # a marker body (C3D/TRC) has no skeleton to receive fingers: OUT is then the hand take
    # retimed to it (engine.splice.retime), as the app's download of such a pair
    retimed = pipeline.marker_body(body)
    pipeline.require_skeletal(body, hand, marker_body_ok=True)
    if args.side not in ("right", "left"):
        from engine.cli import warn
        from engine.model.hand_side import unnamed_side_warning

        guessed = unnamed_side_warning(Path(args.hand).name, hand, None, "pass --side {side}")
        if guessed:  # a side from the geometry alone: say it, with the flag that overrides it
            warn(guessed)
    body_roles = hand_roles = None
    if args.roles:
        from engine.model.roles import read_roles_json

        mapping = read_roles_json(args.roles)
        body_roles, hand_roles = split_roles(mapping, body, hand)
    elif spec is not None and spec.roles:
        body_roles, hand_roles = split_roles(spec.roles, body, hand)
    if hand_points:  # in the files' own frames, before the long work
        try:
            C.check_points(
                points,
                body.n_frames,
                hand.n_frames,
                open_ends=C.parse_ends(args.ends) == "open",
                grid_scale=body.fps / hand.fps,
            )
        except C.ConstraintError as exc:
            raise _point_source(exc, args) from None

    from engine.splice.report import build_report, dumps

    progress = _Progress(args.quiet)
    if not args.quiet and not kernels_cached():  # else pass 1 seemed to take a minute
        print(
            "splice: first run on this machine: compiling the kernels (about a minute, "
            "counted in the first stages' times; later runs reuse them)",
            file=sys.stderr,
            flush=True,
        )
    from engine.splice.retime import splice_takes

    result, retimed = splice_takes(
        body,
        hand,
        side=args.side,
        band=band,
        refine_band=refine_band,
        points=points,
        hand_points=hand_points,
        theta=args.theta,
        body_roles=body_roles,
        hand_roles=hand_roles,
        progress=progress,
        ends=args.ends,
        max_unmatched_s=args.max_unmatched,
    )
    from engine.trust import assess_splice

    progress("trust", 0.0)
    trust = assess_splice(result.features, result.alignment)
    progress("trust", 1.0)
    progress("write", 0.0)
    # the spliced take and its report are one result: both replaced, or neither; the take's
    # text is written piece by piece (a 10-minute take's text held whole is ~0.75 GB)
    outputs = [(out, iter_bvh(result.motion))]
    if args.report:
        outputs.append(
            (
                Path(args.report),
                dumps(
                    build_report(
                        result, args.body, args.hand, out, points_given=points, assessment=trust
                    )
                ),
            )
        )
    write_texts(outputs)
    progress("write", 1.0)
    if args.preview:
        _preview(result.motion, args.preview, args.quiet)
    if not args.quiet:
        sides = " and ".join(result.features.sides)
        from engine.splice.report import unmatched_summary

        fps = result.features.fps
        what = (
            f"the hand take retimed to the marker body, {sides} side"
            if retimed
            else f"{sides} hand{'s' if len(result.features.sides) > 1 else ''}"
        )
        print(
            f"wrote {out} ({result.features.n} frames = {result.features.n / fps:.2f} s at "
            f"{fps:g} fps, {what}; "
            f"{_took(time.perf_counter() - started, result.timings['total'])})",
            file=sys.stderr,
        )
        a = result.alignment
        unmatched = unmatched_summary(
            a.unmatched_body,
            fps,
            a.unmatched_limit(fps),
            a.max_unmatched_s is not None,
            retimed=retimed,
        )
        if unmatched:
            print(f"splice: {unmatched}", file=sys.stderr)
        print(f"splice: {trust.summary}", file=sys.stderr)
    return 0


def _preview(motion, path: str, quiet: bool) -> None:
    from engine.base.errors import HandSpliceError

    try:
        from engine.render.offscreen import Preview
        from engine.render.video import progress_printer, render_to_file
    except ImportError as err:
        raise HandSpliceError(
            f"--preview: the renderer is not available ({err}); the spliced "
            "take was written, render it later with handsplice render"
        ) from None
    preview = Preview([motion], labels=["spliced"])
    try:
        progress = None if quiet else progress_printer(f"preview {path}")
        render_to_file(preview, path, progress=progress)
    finally:
        preview.close()
