"""Exceptions raised at the engine's boundary.

Every message names the file, line or field and what was expected, so the CLI
can print it on one line and exit with status 2.
"""

from __future__ import annotations

from pathlib import Path

MAX_MESSAGE_CHARS = 300  # a message quotes a file's text; a 5,000-digit token is clipped


def first_line(text: object, limit: int = MAX_MESSAGE_CHARS) -> str:
    """The first line of ``text`` (stripped), at most ``limit`` characters, a clipped one
    ending in an ellipsis: what every front shows of an error (the CLI's one line, a batch
    summary cell, the page's refusal box)."""
    lines = str(text).strip().splitlines()
    line = lines[0].strip() if lines else ""
    return line if len(line) <= limit else line[: limit - 1] + "…"


class HandSpliceError(Exception):
    """Base class: a user-facing problem with input or parameters (CLI exit 2)."""


class Cancelled(Exception):  # noqa: N818 (what happened, not an error)
    """Work given up because its result is no longer wanted: ``cancelled()`` said so (the
    app's trust assessment of an alignment that a newer edit replaces)."""


def check_cancelled(cancelled) -> None:
    """Raise :class:`Cancelled` when ``cancelled`` (a callable or None) says so."""
    if cancelled is not None and cancelled():
        raise Cancelled("no longer wanted")


def run_cancellable(fn, *args, **kwargs):
    """``fn(*args, **kwargs)``; a :class:`Cancelled` it raises comes out as a new one that
    holds none of ``fn``'s frames.

    An exception keeps its traceback, and the traceback every frame it passed through with
    their local arrays: a worker's future that stores the exception kept a given-up
    splice's output (the spliced take's rotations, 81 MB at 10 minutes) or a trust sweep's
    blocks for as long as the future lived (the app keeps it until the edit's path is drawn),
    under the next edit's solve. Used for work submitted to a pool that may be given up."""
    try:
        return fn(*args, **kwargs)
    except Cancelled as exc:
        message = str(exc)  # the exception and its frames go when this block ends
    raise Cancelled(message)


class MotionFormatError(HandSpliceError, ValueError):
    """A capture file does not follow its format.

    ``str(err)`` reads ``walk.bvh line 212: expected 96 values, found 93``.
    """

    def __init__(self, path: str | Path | None, message: str, line: int | None = None):
        self.path = None if path is None else str(path)
        self.line = line
        self.detail = message = first_line(message)
        where = Path(self.path).name if self.path else "<input>"
        if line is not None:
            where = f"{where} line {line}"
        super().__init__(f"{where}: {message}")

    @classmethod
    def empty(cls, path: str | Path | None) -> MotionFormatError:
        """The one refusal of a take file with nothing in it (no bytes; a text take of
        blank lines): ``empty.bvh: the file is empty``, from every reader and front (the
        CLI, the page's upload fields)."""
        return cls(path, "the file is empty")


class RoleError(HandSpliceError, KeyError):
    """A joint role (e.g. right wrist) cannot be found in a skeleton."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


class SideError(RoleError):
    """A take has no arm or hand on the side asked for; ``found``: the sides it has
    (``("right",)``), so a caller can offer the other one."""

    def __init__(self, message: str, found=()):
        super().__init__(message)
        self.found = tuple(found)


class ParameterError(HandSpliceError, ValueError):
    """A parameter (band width, matching point, option) is out of range."""
