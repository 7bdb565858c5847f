"""``handsplice`` command line: one thin module per subcommand.

Each module in ``SUBCOMMANDS`` defines ``add_parser(subparsers)`` that registers
its parser and sets ``func=run`` (``run(args) -> int``). Heavy imports (numba,
pyrender, panel) stay inside ``run`` so ``handsplice info`` starts fast.

Errors: a ``HandSpliceError`` / ``ValueError`` / ``OSError`` is bad input and
prints one line ``handsplice: error: ...`` with exit status 2, as do ``MemoryError``
and ``RecursionError`` (input beyond what ``engine.base.limits`` refuses up front, one line,
never a traceback); anything else is
a bug, printed on one line with exit status 1 (``--debug`` shows the traceback).
A refusal of a flag's value names the flag as typed (``--max-unmatched: expected ...``),
not the engine's name of the value (``max_unmatched_s``): :func:`flag_for` is the one rule.

Notes: what a reader accepted but a user should know (``meta.notes``, e.g. a TRC cut
short) is printed on stderr as ``handsplice: note: ...`` once the command has finished
(:func:`load_take`); it does not change the exit status.
"""

from __future__ import annotations

import argparse
import importlib
import re
import sys

from engine import __version__
from engine.base.errors import HandSpliceError, first_line

# module names under engine.cli, in the order shown by --help
SUBCOMMANDS = ["info", "splice", "analyze", "synthesize", "render", "batch"]
#: subcommands that live in other packages, imported by name when the parser is built
#: (no static import: the engine never depends on the web app; without the app installed
#: the subcommand is simply absent)
PLUGINS = {"serve": "webapp.serve_cli"}


#: the engine's names of values set by a flag not spelled ``--`` + the name with ``-`` for
#: ``_`` (as ``refine_band`` is by ``--refine-band``, ``pair_seconds`` by ``--pair-seconds``)
FLAG_NAMES = {"max_unmatched_s": "--max-unmatched"}


def flag_for(name: str) -> str:
    """The flag that sets the value the engine calls ``name`` (``max_unmatched_s`` ->
    ``--max-unmatched``, ``refine_band`` -> ``--refine-band``)."""
    return FLAG_NAMES.get(name, "--" + name.replace("_", "-"))


def named_as_typed(message: str, argv: list[str]) -> str:
    """``message`` with the engine's name of the value it refuses (its first word:
    ``max_unmatched_s: expected ...``, ``size 0x0: ...``) replaced by that value's flag
    where the command line gives that flag (``--max-unmatched: expected ...``): the user
    reads the flag they typed. A message about anything else (a file, a flag not given) is
    left as it is."""
    match = re.match(r"([a-z][a-z0-9_]*)(?=[: ])", message)
    if match is None:
        return message
    flag = flag_for(match.group(1))
    typed = {a.split("=", 1)[0] for a in argv if a.startswith("--") and len(a) > 2}
    if any(flag.startswith(t) for t in typed):  # argparse takes unique prefixes too
        return flag + message[match.end() :]
    return message


def output_file(text: str) -> str:
    """An output file's argument (argparse ``type``): its folder must exist, so that a typo
    in the folder is refused at once instead of silently creating a new folder."""
    from pathlib import Path

    folder = Path(text).expanduser().parent
    if not folder.is_dir():
        raise argparse.ArgumentTypeError(
            f"{text}: the folder {folder} does not exist (create it first)"
        )
    return text


#: reader notes of the takes this command read, printed once it has finished
_NOTES: list[str] = []


def load_take(path):
    """``engine.io.load_take(path)`` for a command. The reader's notes (``meta.notes``,
    e.g. a TRC whose header promises more frames than it holds) are printed on stderr,
    one line each, ``handsplice: note: ...``, when the command finishes without an error
    (a note is not an error: the exit status stays 0; a command that refuses the file
    prints its one error line only)."""
    from engine.io import load_take as read

    take = read(path)
    _NOTES.extend(n for n in take.meta.notes if n not in _NOTES)
    return take


def warn(text: str) -> None:
    """One warning line on stderr at once (``handsplice: warning: ...``); not an error."""
    print(f"handsplice: warning: {text}", file=sys.stderr, flush=True)


def _print_notes() -> None:
    for note in _NOTES:
        print(f"handsplice: note: {note}", file=sys.stderr)
    _NOTES.clear()


class _Parser(argparse.ArgumentParser):
    """Every subcommand's argument errors in the README's one-line form, exit status 2:
    ``handsplice: error: -o/--output: o/x.bvh: the folder o does not exist ...`` (not
    argparse's ``handsplice splice: error: argument -o/--output: ...``)."""

    def error(self, message: str) -> None:  # argparse's own exit status is already 2
        message = re.sub(r"^argument ([^:]+): ", r"\1: ", " ".join(message.split()))
        # a value that starts with "-" (--size -5x10, --frames -9:) is taken for a flag
        missing = re.fullmatch(r"(?:\S+/)?(--\S+): expected one argument", message)
        if missing:
            flag = missing.group(1)
            message = f"{flag}: expected a value (one that starts with '-' goes as {flag}=VALUE)"
        self.exit(2, f"handsplice: error: {first_line(message)}\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="handsplice", description="Splice hand motion onto body motion capture.")
    parser.add_argument("--version", action="version", version=f"handsplice {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks for errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name in SUBCOMMANDS:
        importlib.import_module(f"engine.cli.{name}").add_parser(sub)
    for module_name in PLUGINS.values():
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as exc:
            if exc.name is not None and module_name.startswith(exc.name):
                continue  # that package is not installed: no such subcommand
            raise
        module.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help(sys.stderr)
        return 2
    from engine.base.atomic import Terminated, handle_termination

    if args.command != "serve":  # the server keeps its own signal handling (tornado)
        handle_termination()  # SIGTERM unwinds like Ctrl-C: temporary outputs are removed
    _NOTES.clear()
    try:
        code = int(args.func(args) or 0)
        _print_notes()
        return code
    except KeyboardInterrupt as exc:
        terminated = isinstance(exc, Terminated)
        print(f"handsplice: {'terminated' if terminated else 'interrupted'}", file=sys.stderr)
        return 143 if terminated else 130
    except (HandSpliceError, ValueError, OSError, KeyError) as exc:
        if args.debug:
            raise
        msg = first_line(exc) or type(exc).__name__
        if isinstance(exc, OSError) and getattr(exc, "filename", None):
            msg = f"{exc.filename}: {exc.strerror or msg}"
        elif not isinstance(exc, OSError | KeyError):  # a file's errors start with its name
            msg = named_as_typed(msg, argv)
        print(f"handsplice: error: {msg}", file=sys.stderr)
        return 2
    except (MemoryError, RecursionError) as exc:  # input beyond what engine.base.limits foresaw
        if args.debug:
            raise
        what = "memory" if isinstance(exc, MemoryError) else "nesting depth"
        detail = first_line(exc) or type(exc).__name__
        print(
            f"handsplice: error: the input needs more {what} than this machine allows "
            f"({detail}); refusing it",
            file=sys.stderr,
        )
        return 2
    except Exception as exc:  # a bug: still one line unless --debug
        if args.debug:
            raise
        print(
            f"handsplice: internal error: {type(exc).__name__}: {first_line(exc)} "
            "(rerun with --debug)",
            file=sys.stderr,
        )
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
