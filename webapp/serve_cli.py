"""``handsplice serve``: run the browser app (Panel on a Bokeh server).

This subcommand lives with the app (the engine never imports the web layer); the
engine's CLI finds it by name at run time (``engine.cli.PLUGINS``).

Listens on 127.0.0.1 by default; ``--address 0.0.0.0`` exposes it on every
interface (explicit opt-in). ``handsplice serve BODY HAND`` opens the user's own
takes from disk (any size the engine reads; nothing is uploaded): the pair is read
and prepared before the app's server listens, and is the page's default pair; meanwhile a
light page on the same port says what the warm-up does and turns into the app when it is
ready (:mod:`webapp.warm_page`). Never opens a browser; prints the URL. Every
browser session builds its own page and session state, so several users (or
tabs) never share matching points or parameters.
"""

from __future__ import annotations

import argparse
import dataclasses
import gc
import logging
import traceback
from pathlib import Path

from engine.base.limits import MAX_SESSION_BYTES, MAX_UPLOAD_BYTES

#: the largest websocket message the server accepts: an upload chunk (1 MiB) or a
#: session file sent whole (base64: 4/3 of MAX_SESSION_BYTES), with room to spare
WEBSOCKET_MAX_MESSAGE = 16 * 1024 * 1024 + 2 * MAX_SESSION_BYTES


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "serve",
        help="serve the browser app (cost matrix, matching points, previews)",
        description="Serve the HandSplice browser app. Listens on localhost unless --address "
        "says otherwise; never opens a browser.",
    )
    p.add_argument(
        "body",
        nargs="?",
        type=Path,
        default=None,
        help="your body take (.bvh, .c3d or .trc), opened from disk; with HAND",
    )
    p.add_argument(
        "hand",
        nargs="?",
        type=Path,
        default=None,
        help="your hand take (.bvh), opened from disk; with BODY",
    )
    p.add_argument(
        "--side",
        choices=("right", "left"),
        default=None,
        help="which hand of BODY HAND to align and splice (default: the side HAND's file "
        "name says, e.g. mug1_rightHand.bvh, else right)",
    )
    p.add_argument("--port", type=int, default=5006, help="TCP port (default 5006; 0 = any free)")
    p.add_argument(
        "--address",
        default="127.0.0.1",
        help="interface to listen on (default 127.0.0.1; 0.0.0.0 = all interfaces)",
    )
    p.add_argument(
        "--show-url",
        action="store_true",
        help="print the app URL (and the demo pair's URL) once the server listens",
    )
    p.add_argument(
        "--sample",
        default=None,
        metavar="NAME",
        help="sample pair opened by default (a name from sample_data/samples.json)",
    )
    p.add_argument(
        "--sample-dir",
        type=Path,
        default=None,
        metavar="DIR",
        help="folder of sample pairs with its samples.json (default: the bundled sample_data)",
    )
    p.add_argument(
        "--upload-dir",
        type=Path,
        default=None,
        metavar="DIR",
        help="where uploaded takes are stored by content hash (default ./uploads)",
    )
    p.add_argument(
        "--max-upload-mb",
        type=float,
        default=MAX_UPLOAD_BYTES / 2**20,
        help="largest accepted upload in MiB (default "
        f"{MAX_UPLOAD_BYTES / 2**20:g}, engine.base.limits.MAX_UPLOAD_BYTES)",
    )
    p.add_argument(
        "--no-warm",
        action="store_true",
        help="do not precompute the demo pair before accepting connections",
    )
    p.set_defaults(func=run)


def _check_args(args: argparse.Namespace) -> None:
    if not 0 <= args.port <= 65535:
        raise ValueError(f"--port: expected 0..65535, got {args.port}")
    if args.max_upload_mb <= 0:
        raise ValueError(f"--max-upload-mb: expected a positive size, got {args.max_upload_mb}")
    if (args.body is None) != (args.hand is None):
        raise ValueError("serve: expected both BODY and HAND takes (or neither)")
    if args.body is not None and args.sample is not None:
        raise ValueError(
            "serve: --sample and BODY HAND both choose the pair opened first; give one"
        )
    for what, path in (("BODY", args.body), ("HAND", args.hand)):
        if path is None:
            continue
        if not path.is_file():
            raise ValueError(f"{what} {path}: no such file")
        if path.suffix.lower() not in (".bvh", ".c3d", ".trc"):
            raise ValueError(f"{what} {path.name}: expected a .bvh, .c3d or .trc file")


def _closed_session_error(exc: BaseException | None) -> bool:
    """A closed tab's late message: bokeh's ``assert self._session is not None`` in
    ``ServerConnection.session``, raised when a message (or the close itself) arrives
    after the tab's session was discarded. The tab is gone: nothing to handle, nothing a
    user could act on."""
    if not isinstance(exc, AssertionError):
        return False
    frames = traceback.extract_tb(exc.__traceback__)
    last = frames[-1] if frames else None
    return bool(last and last.name == "session" and last.filename.endswith("connection.py"))


class _ClosedSessionMessages(logging.Filter):
    """Drops the log records of a closed tab's late messages (:func:`_closed_session_error`),
    whichever logger reports them (bokeh's "error handling message", tornado's uncaught
    exception in a websocket callback); every other error is kept."""

    def filter(self, record: logging.LogRecord) -> bool:
        return not _closed_session_error(record.exc_info[1] if record.exc_info else None)


def _drop_closed_websocket_writes(loop, context: dict) -> None:
    """asyncio exception handler: a browser tab that closed while the server was still
    sending to it leaves un-awaited tornado write tasks failing with ``WebSocketClosedError``
    (bokeh already logs a one-line warning for it), or a late message failing on its
    discarded session; drop those, report everything else."""
    from tornado.iostream import StreamClosedError
    from tornado.websocket import WebSocketClosedError

    exc = context.get("exception")
    if isinstance(exc, WebSocketClosedError | StreamClosedError) or _closed_session_error(exc):
        return
    loop.default_exception_handler(context)


def _open_local(pair):
    """Read and prepare a pair named on the command line (cached for the first page); the
    ``webapp.backend.Prepared``."""
    from webapp import backend

    return backend.prepare(pair.body, pair.hand, pair.side)


def _named_side(hand_path) -> tuple[str | None, str | None]:
    """(side, warning) for ``serve BODY HAND`` without ``--side`` whose hand file's name says
    a side: the rule of every front (``engine.model.roles.hand_file_side``: joint names over
    the file name). A hand the reader refuses is left to the pair's own opening (one line)."""
    from engine.base.errors import HandSpliceError
    from engine.io import load_take
    from engine.model.motion import Motion
    from engine.model.roles import hand_file_side

    try:
        take = load_take(hand_path)
    except (HandSpliceError, ValueError, OSError):
        take = None
    skeleton = take.skeleton if isinstance(take, Motion) else None
    named = hand_file_side(Path(hand_path).name, skeleton)
    return named.side, named.warning


def unnamed_side(pair, side_arg: str | None, hand):
    """``pair`` (``serve BODY HAND``'s, its hand take ``hand`` as read) with the warning a
    hand take gets when neither its file name nor its joint names carry a side
    (``engine.model.hand_side.unnamed_side_warning``, the rule of ``splice`` and of the
    page's uploads): said on the console, kept in ``pair.extra["unnamed_side"]`` for the
    page (stranger 13: a side-less hand served from disk went on the right arm, unsaid).
    ``side_arg``: the ``--side`` given (none: nothing is said when the name gives the
    side)."""

    from engine.cli import warn
    from engine.model.hand_side import unnamed_side_warning
    from engine.model.motion import Motion
    from engine.model.roles import side_from_name

    if side_arg is not None or side_from_name(pair.hand) is not None:
        return pair
    if not isinstance(hand, Motion):
        return pair
    console = unnamed_side_warning(pair.hand.name, hand, pair.side, "pass --side {side}")
    if not console:
        return pair
    warn(console)
    page = unnamed_side_warning(pair.hand.name, hand, pair.side, "choose Side {side}")
    return dataclasses.replace(pair, extra={**pair.extra, "unnamed_side": page})


def sample_url(url: str, sample: str) -> str:
    """The page's URL opening ``sample``; a pair opened from disk is named "BODY + HAND",
    whose spaces and "+" a query must escape."""
    from urllib.parse import quote

    return f"{url}?sample={quote(sample, safe='')}"


def run(args: argparse.Namespace) -> int:
    _check_args(args)
    from webapp import heap

    heap.give_back_large_blocks()  # an edit's freed arrays leave the server (RESULTS: tenmin2)
    import panel as pn

    from webapp import config, served_files
    from webapp.app import ConsoleStages, create_app, warm_up
    from webapp.launch import free_port
    from webapp.warm_page import WarmPage

    if args.sample_dir is not None and not (args.sample_dir / "samples.json").is_file():
        raise ValueError(f"--sample-dir: {args.sample_dir} has no samples.json")
    host = "127.0.0.1" if args.address in ("0.0.0.0", "::", "") else args.address
    if args.port == 0:  # pick the port now so the websocket origin check can name it
        args.port = free_port(args.address)
    url = f"http://{host}:{args.port}/"
    stages = warm = None
    if not args.no_warm:
        try:  # a light page on the app's port until the app listens (stranger 11 F3)
            warm = WarmPage(args.address, args.port)
        except OSError as exc:
            raise ValueError(f"--port {args.port}: cannot listen ({exc.strerror or exc})") from None
        print(
            "HandSplice: warming up (reading the takes, aligning, compiling; a minute or two "
            "the first time, longer for long takes; each stage is listed below) ...",
            flush=True,
        )
        print(f"HandSplice: {url} shows the warm-up meanwhile, then the app", flush=True)
        stages = ConsoleStages()  # stage lines on stderr until the server listens
        stages.also = warm.note
    try:
        local = None
        if args.body is not None:
            from engine.cli.info import warn_side
            from engine.model.roles import side_from_name
            from webapp import backend

            warn_side(args.hand, args.side)  # a right-named hand served as left: say so
            side, contradiction = args.side, None
            if side is None and side_from_name(args.hand) is not None:
                side, contradiction = _named_side(args.hand)
            side = side or "right"
            local = config.local_pair(args.body, args.hand, side)
            if contradiction:  # said on the console and, for this pair, in the page
                from engine.cli import warn

                warn(contradiction)
                local = dataclasses.replace(
                    local, extra={**local.extra, "name_side": contradiction}
                )
            with backend.stages_to(stages):
                prepared = _open_local(local)  # a take the engine refuses: one line, exit 2
            # the hand take as read for the pair (not read a second time)
            local = unnamed_side(local, args.side, prepared.hand)
        cfg = config.configure(
            sample_dir=args.sample_dir,
            default_sample=args.sample,
            upload_dir=args.upload_dir,
            max_upload_bytes=int(args.max_upload_mb * 1024 * 1024),
            local=local,
        )
        if stages is not None:
            warm_up(cfg, progress=stages)
    except BaseException:
        if stages is not None:
            stages.close(done=False)
        if warm is not None:
            warm.close()
        raise
    if stages is not None:
        stages.close()
    if warm is not None:
        warm.close()  # the port is the app's now: its page reloads into the app
    server = pn.serve(
        {"/": create_app},
        port=args.port,
        address=args.address,
        # 0.0.0.0 is an explicit opt-in to remote access: accept any Host header then
        websocket_origin="*"
        if args.address in ("0.0.0.0", "::")
        else [f"{host}:{args.port}", f"localhost:{args.port}", f"127.0.0.1:{args.port}"],
        show=False,
        start=False,
        title="HandSplice",
        verbose=False,
        # uploads come in chunks (webapp.views.dropper.CHUNK_BYTES); no message is larger
        # than a chunk or a session file (base64), so the limit stays small
        websocket_max_message_size=WEBSOCKET_MAX_MESSAGE,
        http_server_kwargs={"max_buffer_size": WEBSOCKET_MAX_MESSAGE},
        # large downloads (the spliced BVH/GLB) are fetched over plain HTTP from the
        # server's disk, not sent base64 in a Bokeh property (webapp.served_files)
        extra_patterns=[served_files.ROUTE],
    )
    # what start-up made (modules, compiled kernels, the warm-up's pair) lives as long as the
    # server: left out of every later collection (Panel collects after each closed tab; a
    # full collection walked all of it, about 12 % of the server's time during page loads)
    gc.collect()
    gc.freeze()
    print(f"HandSplice app: {url}", flush=True)
    if local is not None:
        print(f"your pair:      {local.body} + {local.hand} ({local.side} hand)", flush=True)
    if args.show_url and cfg.default_sample:
        # the pair the page opens first: the user's own (serve BODY HAND), else the demo
        ours = local is not None and cfg.default_sample == local.name
        label = "your pair's link:" if ours else "demo pair:     "
        print(f"{label} {sample_url(url, cfg.default_sample)}", flush=True)
    print("press Ctrl+C to stop", flush=True)
    try:
        server.start()
        server.io_loop.asyncio_loop.set_exception_handler(_drop_closed_websocket_writes)
        closed = _ClosedSessionMessages()
        for name in ("bokeh.server.protocol_handler", "tornado.application", "tornado.general"):
            logging.getLogger(name).addFilter(closed)
        server.io_loop.start()
    finally:
        server.stop()
    return 0
