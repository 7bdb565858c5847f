"""BVH (Biovision Hierarchy) reader and writer.

``read_bvh(path) -> Motion`` and ``write_bvh(motion, path)``; ``parse_bvh`` and
``format_bvh`` do the same on text.

What the reader accepts (as real files contain it)
--------------------------------------------------
* Any rotation order per joint, 0, 3 or 6 channels on any joint (also partial sets
  such as ``CHANNELS 1 Zrotation``), several roots, ``End Site`` blocks, tabs,
  CRLF/CR line ends, blank lines, a UTF-8 byte-order mark, ``Frames:``/``Frame Time:``
  with or without extra white space, ``{`` on the ``JOINT`` line.
* Rotations become quaternions ``R = R_a(c0) R_b(c1) R_c(c2)`` in each joint's own
  channel order (``engine.model.rotations.from_euler``). Missing rotation axes count as 0.
* Translations follow ``Motion``: a position channel replaces the matching component
  of the joint's ``OFFSET`` (the convention of Blender, MotionBuilder and the BEAT and
  Bandai files, whose position channels repeat the offsets); other joints keep their
  offset.
* Data rows versus ``Frames:``: the rows actually present are used. More rows than
  ``Frames:`` is accepted; when there is exactly one extra row and the *first* row is
  all zeros (the gestification exporter writes a zero row before the take) that row
  is dropped. Either is said in ``meta.notes`` (as the TRC reader's frame-count note:
  ``hello.bvh: the header says 82 frames, the file has 83 data rows: the first, all
  zeros (the gestification exporter's extra row), was left out``). Fewer rows than
  ``Frames:`` is a truncated file and an error.
* A first or last frame that is a one-frame outlier pose (a tracking glitch: a joint more
  than 90° from both its neighbours, which agree) is said in ``meta.notes``
  (``engine.model.edge_glitch``, the rule and its measurement).
* ``Frame Time`` gives ``fps = 1 / frame_time``, snapped to the nearest integer when
  within 0.05 % of it (``0.0333333`` -> 30, ``.03333`` -> 30; ``0.027`` -> 37.037...).

Metadata (``MotionMeta(format="bvh", source=path)``)
----------------------------------------------------
* Both come from world joint positions (forward kinematics of up to 16 frames spread
  over the take; the rest pose for an empty take).
* ``up_axis``: if the skeleton has a head and feet/ankles/toes (by name), whichever of
  y and z the feet-to-head vector points along most; else, for a body-like skeleton
  of 10+ joints, the one of y and z with the larger median extent; else ``"y"`` (the
  BVH default; hand-only takes).
* ``units``: a size is measured and compared with a human's. Body: the bone-length
  path from the head joint to the farther ankle/foot joint (pose independent; ~1.5 m),
  or without such names the posed joints' largest extent (median over the probed
  frames). Hand-only skeleton (finger names, no leg names): the longest bone path from
  the wrist/hand joint (else the root) to a finger joint (~0.16 m). The unit whose
  metres come nearest by ratio wins if within a factor of 2, else ``"unknown"``;
  bodies choose among m, cm, mm, in and hands among m, dm, cm, mm. On the shared
  captures: BEAT m, Bandai and LAFAN1 cm, gestification (Leap Motion) mm, ManipNet
  dm, AnimatedDrawings fair1 in (as AnimatedDrawings' own configs scale it, 0.025),
  CMU-style (1/0.45 inch, a 25-unit body) unknown.

Errors are ``MotionFormatError`` naming the file and line: missing ``HIERARCHY`` or
``MOTION``, unbalanced braces, duplicate joint names, bad ``OFFSET``/``CHANNELS``,
missing or bad ``Frames:``/``Frame Time:``, rows with the wrong number of values
("expected 96 values, found 93"), non-numeric text, NaN or infinity, truncation,
binary data, text that is not UTF-8, an empty file, numbers Python would read but no
exporter writes (``1_000``, Arabic-Indic or full-width digits: ``engine.io.numbers``),
data rows when no joint has channels, braces in a joint name, and absurd sizes, checked
before anything is allocated (``engine.base.limits``: more than 1,000 joints or 100 levels,
2,000,000 frames, a rate outside 1-10,000 fps, 6 hours, too many poses for the file).

Memory: the data rows are split and converted ``ROWS_PER_CHUNK`` at a time straight into
the pose arrays (``_read_rows``), and ``read_bvh`` frees the file's bytes and text once its
lines exist: reading holds the lines and the take's arrays, never a Python object per
value (a 115 MB, 72,000-frame hand take read after its body take: process peak 0.46 GB
instead of 1.54 GB; issue 13).

Writer precision: data values are written with ``precision`` decimals (default 6,
error <= 5e-7 degrees or file units); offsets and the frame time exactly (shortest
round-trip form). Write -> read reproduces rotations within ~1e-6 degrees and
translations within 5e-7 units. Euler angles are re-derived from the quaternions,
so an angle may come back as an equivalent one (e.g. 190 -> -170 before unwrapping);
per joint and channel the written angles are unwrapped over time (360-degree
jumps removed) so curves stay continuous.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from itertools import chain
from pathlib import Path

import numpy as np

from engine.base import limits
from engine.base.atomic import write_text
from engine.base.errors import MotionFormatError
from engine.base.limits import MAX_ABS_VALUE, MAX_DEPTH, MAX_FRAMES, MAX_JOINTS
from engine.io.numbers import NOT_NUMERIC_RE, NUMBER_RE, WHOLE_RE, parse_rows
from engine.model import rotations as rot
from engine.model.edge_glitch import edge_outlier_notes, edge_outliers
from engine.model.motion import (
    POSITION_CHANNELS,
    ROTATION_CHANNELS,
    UNIT_TO_METERS,
    Motion,
    MotionMeta,
    Skeleton,
)
from engine.model.translations import Translations

_CHANNEL_NAMES = POSITION_CHANNELS + ROTATION_CHANNELS
_CHANNEL_LOOKUP = {c.lower(): c for c in _CHANNEL_NAMES}
_AXIS = {"X": 0, "Y": 1, "Z": 2}
_FRAMES_RE = re.compile(r"^\s*frames\s*:?\s*(\S*)\s*$", re.IGNORECASE)
_FRAME_TIME_RE = re.compile(r"^\s*frame\s+time\s*:?\s*(\S*)\s*$", re.IGNORECASE)
#: data lines per piece of :func:`iter_bvh` (a few MB of text at a time)
FRAMES_PER_PIECE = 2048
#: joint frames whose Euler angles the writer makes at once (``_pose_to_channels``)
EULER_JOINT_FRAMES = 40_000
# numbers are ASCII (engine.io.numbers): float() would also take "1_000" and "\u0663"
_NUMBER_RE, _WHOLE_RE, _NOT_DATA_RE = NUMBER_RE, WHOLE_RE, NOT_NUMERIC_RE


# --------------------------------------------------------------------------- reading


def read_bvh(path: str | Path) -> Motion:
    """Read a BVH file into a ``Motion`` (see the module docstring for what is accepted).

    Raises ``MotionFormatError`` (file and line in the message) for malformed files and
    ``OSError`` when the file cannot be read.
    """
    path = Path(path)
    # no name holds the bytes or the text while the lines are read: each is freed as
    # soon as the next form exists (a 115 MB take is held once, as lines)
    lines, n_chars = _split_lines(_decode(path.read_bytes(), str(path)), str(path))
    return _parse_lines(lines, n_chars, str(path))


def _decode(data: bytes, source: str) -> str:
    """UTF-8 text of a BVH file, or ``MotionFormatError`` for empty/binary/non-UTF-8."""
    if not data.strip():
        raise MotionFormatError.empty(source)
    nul = data.find(b"\x00")
    if nul >= 0:
        line = data.count(b"\n", 0, nul) + 1
        raise MotionFormatError(source, "binary data (NUL byte), not a BVH text file", line=line)
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        line = data.count(b"\n", 0, err.start) + 1
        raise MotionFormatError(
            source,
            f"not UTF-8 text (byte 0x{data[err.start]:02x} at offset {err.start})",
            line=line,
        ) from None
    return text


def parse_bvh(text: str, source: str = "") -> Motion:
    """Parse BVH text into a ``Motion``.

    Parameters
    ----------
    text : str
        The whole file.
    source : str
        File name used in error messages and stored in ``motion.meta.source``.

    Returns
    -------
    Motion
        ``rotations (F, J, 4)`` local unit quaternions, ``translations (F, J, 3)`` in
        file units, ``fps``, ``meta`` with detected ``units`` and ``up_axis``.
    """
    return _parse_lines(*_split_lines(text, source), source)


def _split_lines(text: str, source: str) -> tuple[list[str], int]:
    """The file's lines (any line end) and its length in characters; refuses a NUL."""
    where = source or None
    if text.startswith("\ufeff"):
        text = text[1:]
    if "\x00" in text:
        line = text.count("\n", 0, text.index("\x00")) + 1
        raise MotionFormatError(where, "binary data (NUL byte), not a BVH text file", line=line)
    n_chars = len(text)
    if "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    return text.split("\n"), n_chars


def _parse_lines(lines: list[str], n_chars: int, source: str) -> Motion:
    """``parse_bvh`` on the file's lines (``n_chars``: its size, for the limits)."""
    where = source or None
    if not any(s.strip() for s in lines):
        raise MotionFormatError.empty(where)
    skeleton, motion_line = _parse_hierarchy(lines, where)
    fps, rotations, translations, notes = _parse_motion(
        lines, motion_line, skeleton, where, n_chars
    )
    probe = _probe_positions(skeleton, rotations, translations)
    rotating = [
        j for j, c in enumerate(skeleton.channels) if any(x.endswith("rotation") for x in c)
    ]
    glitches = edge_outliers(rotations, skeleton.names, rotating)
    if glitches:
        notes += edge_outlier_notes(Path(source).name if source else "BVH", glitches)
    meta = MotionMeta(
        units=_detect_units(skeleton, probe),
        up_axis=_detect_up_axis(skeleton, probe),
        source=source,
        format="bvh",
        notes=notes,
    )
    return Motion(skeleton, rotations, translations, fps, meta)


def _parse_hierarchy(lines: list[str], where: str | None) -> tuple[Skeleton, int]:
    """Skeleton from the HIERARCHY section; returns it and the index of the MOTION line."""
    return _Hierarchy(where).parse(lines)


class _Hierarchy:
    """The HIERARCHY section's reader: one method per keyword, the open blocks on a stack.

    A joint's block is ``(label, joint index, line opened)``; an End Site's block has the
    index ``-1 - joint`` (negative). ``pending`` is a block declared whose ``{`` has not
    been seen yet. Every refusal is a MotionFormatError with the file's line number.
    """

    def __init__(self, where: str | None):
        self.where = where
        self.names: list[str] = []
        self.parents: list[int] = []
        self.offsets: list[np.ndarray | None] = []
        self.channels: list[tuple[str, ...]] = []
        self.end_sites: dict[int, np.ndarray] = {}
        self.seen: dict[str, int] = {}
        self.stack: list[tuple[str, int, int]] = []
        self.pending: tuple[str, int, int] | None = None
        self.end_offset: np.ndarray | None = None

    def fail(self, msg: str, i: int) -> MotionFormatError:
        return MotionFormatError(self.where, msg, line=i + 1)

    def parse(self, lines: list[str]) -> tuple[Skeleton, int]:
        started = False
        for i, raw in enumerate(lines):
            tokens = raw.split()
            if not tokens:
                continue
            if not started:
                if tokens[0].upper() != "HIERARCHY":
                    raise self.fail(
                        f"expected 'HIERARCHY' as the first word, found {tokens[0][:40]!r}", i
                    )
                started = True
                tokens = tokens[1:]
                if not tokens:
                    continue
            if tokens[0].upper() == "MOTION":
                return self._finish(i), i
            k = 0
            while k < len(tokens):
                k = self._token(tokens, k, i)
        last = len(lines)
        if not started:
            raise MotionFormatError(self.where, "no 'HIERARCHY' section", line=1)
        if self.stack or self.pending is not None:
            raise MotionFormatError(
                self.where,
                "file ends inside the HIERARCHY (unbalanced braces, truncated?)",
                line=last,
            )
        raise MotionFormatError(self.where, "no 'MOTION' section after the HIERARCHY", line=last)

    def _finish(self, i: int) -> Skeleton:
        """The skeleton, at the MOTION line ``i`` (every block closed)."""
        if self.pending is not None:
            raise self.fail(
                f"'{{' missing after {self.pending[0]} declared on line {self.pending[2] + 1}", i
            )
        if self.stack:
            raise self.fail(
                f"unbalanced braces: block opened on line {self.stack[-1][2] + 1} is not "
                f"closed before MOTION",
                i,
            )
        if not self.names:
            raise self.fail("no ROOT joint before MOTION", i)
        return _make_skeleton(self.names, self.parents, self.offsets, self.channels, self.end_sites)

    def _token(self, tokens: list[str], k: int, i: int) -> int:
        """Read the keyword at ``tokens[k]`` of line ``i``; the index of the next one."""
        tok = tokens[k]
        up = tok.upper()
        if self.pending is not None and tok != "{":
            raise self.fail(f"expected '{{' after {self.pending[0]}, found {tok[:40]!r}", i)
        if up in ("ROOT", "JOINT"):
            return self._joint(tokens, k, i, up)
        if up == "END":
            return self._end_site(tokens, k, i)
        if tok == "{":
            return self._open(k, i)
        if tok == "}":
            return self._close(k, i)
        if up == "OFFSET":
            return self._offset(tokens, k, i)
        if up == "CHANNELS":
            return self._channels(tokens, k, i)
        if up == "HIERARCHY":
            raise self.fail("second 'HIERARCHY'", i)
        raise self.fail(
            f"unexpected {tok[:40]!r} in HIERARCHY (expected ROOT, JOINT, End Site, "
            f"OFFSET, CHANNELS, braces or MOTION)",
            i,
        )

    def _joint(self, tokens: list[str], k: int, i: int, up: str) -> int:
        """``ROOT name`` / ``JOINT name`` (the name is the rest of the line, a trailing
        ``{`` opens its block)."""
        rest = tokens[k + 1 :]
        if rest and rest[-1] == "{":
            rest = rest[:-1]
            k = len(tokens) - 1  # the "{" is handled next
        else:
            k = len(tokens)
        name = " ".join(rest)
        if name.endswith("{") and name.count("{") == 1 and "}" not in name:
            name = name[:-1].rstrip()  # "JOINT Chest{": the brace opens the block
            brace = True
        else:
            brace = False
        self._check_joint(name, i, up)
        stack = self.stack
        self.seen[name] = i
        self.names.append(name)
        self.parents.append(stack[-1][1] if stack else -1)
        self.offsets.append(None)
        self.channels.append(())
        self.pending = (f"{up} {name}", len(self.names) - 1, i)
        if brace:
            stack.append((self.pending[0], self.pending[1], i))
            self.pending = None
        return k

    def _check_joint(self, name: str, i: int, up: str) -> None:
        """Refuse a joint that is unnamed, misplaced, a duplicate or one too many."""
        if not name:
            raise self.fail(f"{up} without a joint name", i)
        if "{" in name or "}" in name:
            raise self.fail(
                f"joint name {name[:40]!r} contains a brace (a joint name is "
                "the text after ROOT/JOINT, without braces)",
                i,
            )
        if len(self.stack) >= MAX_DEPTH:
            raise self.fail(
                f"joint {name[:40]!r} is nested more than {MAX_DEPTH} deep; "
                "refusing an absurd skeleton",
                i,
            )
        if up == "ROOT" and self.stack:
            raise self.fail(f"ROOT {name!r} inside another joint's block", i)
        if up == "JOINT" and (not self.stack or self.stack[-1][1] < 0):
            raise self.fail(f"JOINT {name!r} outside a joint block", i)
        if name in self.seen:
            raise self.fail(
                f"duplicate joint name {name!r} (first on line {self.seen[name] + 1})", i
            )
        if len(self.names) >= MAX_JOINTS:
            raise self.fail(f"more than {MAX_JOINTS} joints; refusing an absurd skeleton", i)

    def _end_site(self, tokens: list[str], k: int, i: int) -> int:
        if k + 1 >= len(tokens) or tokens[k + 1].upper() != "SITE":
            raise self.fail("expected 'End Site'", i)
        if not self.stack or self.stack[-1][1] < 0:
            raise self.fail("End Site outside a joint block", i)
        self.pending = ("End Site", self.stack[-1][1], i)
        self.end_offset = None
        return k + 2

    def _open(self, k: int, i: int) -> int:
        if self.pending is None:
            raise self.fail("unexpected '{'", i)
        label, idx, _ = self.pending
        # End Site of joint idx: -1 - idx < 0
        self.stack.append((label, -1 - idx if label == "End Site" else idx, i))
        self.pending = None
        return k + 1

    def _close(self, k: int, i: int) -> int:
        if not self.stack:
            raise self.fail("unbalanced braces: '}' without an open block", i)
        label, idx, opened = self.stack.pop()
        if idx < 0:
            if self.end_offset is None:
                raise self.fail(f"End Site opened on line {opened + 1} has no OFFSET", i)
            self.end_sites[-1 - idx] = self.end_offset
            self.end_offset = None
        elif self.offsets[idx] is None:
            raise self.fail(f"{label} (line {opened + 1}) has no OFFSET", i)
        return k + 1

    def _offset(self, tokens: list[str], k: int, i: int) -> int:
        if not self.stack:
            raise self.fail("OFFSET outside a joint block", i)
        vals = tokens[k + 1 : k + 4]
        if len(vals) != 3:
            raise self.fail(f"OFFSET needs 3 numbers, found {len(vals)}", i)
        off = _finite_numbers(vals, self.where, i, "OFFSET")
        idx = self.stack[-1][1]
        if idx < 0:
            self.end_offset = off
        else:
            self.offsets[idx] = off
        return k + 4

    def _channels(self, tokens: list[str], k: int, i: int) -> int:
        if not self.stack or self.stack[-1][1] < 0:
            raise self.fail("CHANNELS outside a joint block", i)
        if k + 1 >= len(tokens):
            raise self.fail("CHANNELS without a count", i)
        if not _WHOLE_RE.fullmatch(tokens[k + 1]) or len(tokens[k + 1]) > 3:
            raise self.fail(
                f"CHANNELS count must be a whole number 0-6, found {tokens[k + 1][:40]!r}", i
            )
        n = int(tokens[k + 1])
        listed = tokens[k + 2 : k + 2 + n]
        if n < 0 or n > 6 or len(listed) != n:
            raise self.fail(
                f"CHANNELS {tokens[k + 1]} lists {len(tokens) - k - 2} channel "
                f"names (expected a count of 0-6 matching the names)",
                i,
            )
        chans: list[str] = []
        for c in listed:
            canon = _CHANNEL_LOOKUP.get(c.lower())
            if canon is None:
                raise self.fail(
                    f"unknown channel {c[:40]!r} (expected one of {', '.join(_CHANNEL_NAMES)})",
                    i,
                )
            if canon in chans:
                raise self.fail(f"channel {canon} listed twice", i)
            chans.append(canon)
        self.channels[self.stack[-1][1]] = tuple(chans)
        return k + 2 + n


def _make_skeleton(names, parents, offsets, channels, end_sites) -> Skeleton:
    return Skeleton(
        names=tuple(names),
        parents=np.array(parents, dtype=np.int64),
        offsets=np.array(offsets, dtype=float).reshape(-1, 3),
        channels=tuple(channels),
        end_sites=end_sites,
    )


def _finite_numbers(vals: list[str], where: str | None, i: int, field: str) -> np.ndarray:
    bad = next((v for v in vals if not _NUMBER_RE.fullmatch(v)), None)
    if bad is not None:
        raise MotionFormatError(where, f"{field}: {bad[:40]!r} is not a number", line=i + 1)
    out = np.array([float(v) for v in vals])
    if not np.all(np.isfinite(out)):
        bad = vals[int(np.flatnonzero(~np.isfinite(out))[0])]
        raise MotionFormatError(where, f"{field}: {bad[:40]!r} is not a finite number", line=i + 1)
    if np.abs(out).max(initial=0.0) > MAX_ABS_VALUE:
        bad = vals[int(np.argmax(np.abs(out)))]
        raise MotionFormatError(
            where,
            f"{field}: {bad[:40]!r} is beyond +-{MAX_ABS_VALUE:g}; refusing an absurd value",
            line=i + 1,
        )
    return out


def _parse_motion(
    lines: list[str], motion_line: int, skeleton: Skeleton, where: str | None, text_bytes: int = 0
) -> tuple[float, np.ndarray, Translations | np.ndarray, tuple[str, ...]]:
    """fps, local quaternions ``(F, J, 4)`` and translations ``(F, J, 3)`` of the MOTION
    section (``_read_rows``), and the reader's notes (``_frame_count_notes``).

    The header's frame count, the rate and the poses they ask for are checked against
    ``engine.base.limits`` before any row is read (``text_bytes``: the size of the file).
    """
    n_values = sum(len(c) for c in skeleton.channels)
    i = motion_line + 1
    rest = lines[motion_line].split()[1:]
    if rest:
        raise MotionFormatError(
            where, f"unexpected {rest[0][:40]!r} after MOTION", line=motion_line + 1
        )

    def next_content(i: int, expected: str) -> int:
        while i < len(lines) and not lines[i].strip():
            i += 1
        if i >= len(lines):
            raise MotionFormatError(
                where, f"file ends before '{expected}' (truncated?)", line=len(lines)
            )
        return i

    i = next_content(i, "Frames:")
    m = _FRAMES_RE.match(lines[i])
    if not m:
        raise MotionFormatError(
            where, f"expected 'Frames: N', found {lines[i].strip()[:40]!r}", line=i + 1
        )
    if m.group(1).startswith("-") and _WHOLE_RE.fullmatch(m.group(1)[1:]):
        raise MotionFormatError(where, f"Frames: {m.group(1)[:40]} is negative", line=i + 1)
    if not _WHOLE_RE.fullmatch(m.group(1)):
        raise MotionFormatError(
            where, f"Frames: {m.group(1)[:40]!r} is not a whole number", line=i + 1
        )
    n_frames = int(m.group(1)[:40])  # more digits than 40 are far beyond the limit anyway
    if n_frames > MAX_FRAMES:
        raise MotionFormatError(
            where,
            f"Frames: {n_frames} is more than {MAX_FRAMES:,}; refusing an absurd take",
            line=i + 1,
        )
    frames_line = i
    i = next_content(i + 1, "Frame Time:")
    m = _FRAME_TIME_RE.match(lines[i])
    if not m:
        raise MotionFormatError(
            where, f"expected 'Frame Time: seconds', found {lines[i].strip()[:40]!r}", line=i + 1
        )
    frame_time = float(m.group(1)) if _NUMBER_RE.fullmatch(m.group(1)) else float("nan")
    if not (np.isfinite(frame_time) and frame_time > 0):
        raise MotionFormatError(
            where,
            f"Frame Time: {m.group(1)[:40]!r} is not a positive number of seconds",
            line=i + 1,
        )
    fps = _snap_fps(1.0 / frame_time)
    limits.check_rate(fps, where, line=i + 1, field=f"Frame Time: {m.group(1)[:40]}")
    first_data = i + 1
    limits.check_take(
        where, n_frames, fps, skeleton.n_joints, n_values, text_bytes, line=frames_line + 1
    )

    # data rows: every non-blank line after Frame Time
    row_lines = [k for k in range(first_data, len(lines)) if lines[k].strip()]
    if n_values == 0:  # no channels at all: the pose is the rest pose, rows must be empty
        if row_lines:
            raise MotionFormatError(
                where,
                f"data row {lines[row_lines[0]].strip()[:40]!r} but no joint has "
                "channels (CHANNELS 0 everywhere: expected no values)",
                line=row_lines[0] + 1,
            )
        rotations, translations = _channels_to_pose(skeleton, np.zeros((n_frames, 0)))
        return fps, rotations, translations, ()
    if len(row_lines) > MAX_FRAMES + 1:
        raise MotionFormatError(
            where,
            f"more than {MAX_FRAMES:,} data rows; refusing an absurd take",
            line=row_lines[MAX_FRAMES] + 1,
        )
    limits.check_take(
        where,
        len(row_lines),
        fps,
        skeleton.n_joints,
        n_values,
        text_bytes,
        line=row_lines[-1] + 1 if row_lines else first_data,
    )
    short = None  # after a fault in the rows' values, before their conversion
    if len(row_lines) < n_frames:
        last = row_lines[-1] + 1 if row_lines else first_data
        short = MotionFormatError(
            where,
            f"Frames: {n_frames} (line {frames_line + 1}) but the file ends after "
            f"{len(row_lines)} data rows (truncated?)",
            line=last,
        )
    rotations, translations, first_zero = _read_rows(lines, row_lines, skeleton, where, short)
    if short is not None:
        raise short
    dropped = len(row_lines) == n_frames + 1 and first_zero
    if dropped:  # gestification: a zero row before the take
        rotations, translations = rotations[1:], translations.frames(1)
    return (
        fps,
        rotations,
        translations,
        _frame_count_notes(n_frames, len(row_lines), dropped, where),
    )


def _frame_count_notes(
    n_frames: int, n_rows: int, dropped_first: bool, source: str | None
) -> tuple[str, ...]:
    """A note when the file holds more data rows than its ``Frames:`` says (fewer is an
    error): the zero row left out (``dropped_first``), or every row used; none when they
    agree. The file is named as the TRC reader's note names it (its file name)."""
    if n_rows <= n_frames:
        return ()
    name = Path(source).name if source else "BVH"
    said = f"{name}: the header says {n_frames} frames, the file has {n_rows} data rows"
    if dropped_first:
        return (
            f"{said}: the first, all zeros (the gestification exporter's extra row), was left out",
        )
    return (f"{said}: all {n_rows} were read",)


#: data rows read (split, converted, turned into poses) at a time: the reader's memory
#: beyond the take's own arrays follows this, not the file (issue 13: 72,000-frame takes)
ROWS_PER_CHUNK = 2048


class _RowTrouble(Exception):
    """A chunk of data rows is not clean; the whole data section is then explained
    (``_explain_rows``) so that the error is the one the file's first fault gives."""


def _read_rows(
    lines: list[str],
    row_lines: list[int],
    skeleton: Skeleton,
    where: str | None,
    short: MotionFormatError | None = None,
) -> tuple[np.ndarray, Translations, bool]:
    """Local quaternions ``(R, J, 4)`` and translations ``(R, J, 3)`` of the ``R`` data
    rows ``lines[row_lines]``, and whether the first row is all zeros. The translations
    are a :class:`Translations`: a joint without position channels (its OFFSET every
    frame), or whose position channels never change, is stored once.

    Rows are split and converted ``ROWS_PER_CHUNK`` at a time straight into the pose
    arrays: no list of every value, no ``(R, C)`` copy of the whole take. A chunk with
    any fault (a character no number has, a wrong count, text float() refuses, a value
    not finite or absurd) sends the whole section to ``_explain_rows``, which raises the
    error of the file's first fault in the order the checks always ran (``short``, the
    error of a file with fewer rows than its ``Frames:``, comes after the counts).
    """
    n_values = sum(len(c) for c in skeleton.channels)
    n_rows = len(row_lines)
    n_joints = skeleton.n_joints
    rotations = np.empty((n_rows, n_joints, 4))
    # only joints with position channels can move: the others keep their OFFSET, stored once
    moving = [j for j in range(n_joints) if skeleton.has_position_channels(j)]
    positions = np.empty((n_rows, len(moving), 3))
    first_zero = False
    try:
        for start in range(0, n_rows, ROWS_PER_CHUNK):
            block = _chunk_values(lines, row_lines[start : start + ROWS_PER_CHUNK], n_values)
            if start == 0 and n_rows:
                first_zero = not block[0].any()
            stop = start + block.shape[0]
            rotations[start:stop], trans = _channels_to_pose(skeleton, block)
            positions[start:stop] = trans[:, moving]
            del block, trans
    except _RowTrouble:
        del rotations, positions
        raise _explain_rows(lines, row_lines, n_values, where, short) from None
    translations = Translations(skeleton.offsets, moving, positions).compact()
    return rotations, translations, first_zero


def _chunk_values(lines: list[str], chunk: list[int], n_values: int) -> np.ndarray:
    """``(len(chunk), n_values)`` float64 values of the rows ``lines[chunk]``, or
    ``_RowTrouble`` if any of them is not clean."""
    text = "\n".join([lines[k] for k in chunk])
    block = parse_rows(text, len(chunk), n_values)  # the clean ASCII rows of every exporter
    if block is None:  # anything else: read as before (a clean file with other white space)
        if _NOT_DATA_RE.search(text):
            raise _RowTrouble
        block = _split_values(lines, chunk, n_values)
    del text
    if not np.isfinite(block).all() or (block.size and np.abs(block).max() > MAX_ABS_VALUE):
        raise _RowTrouble
    return block.reshape(len(chunk), n_values)


def _split_values(lines: list[str], chunk: list[int], n_values: int) -> np.ndarray:
    """The values of rows ``lines[chunk]`` split and converted one by one (``float()``'s
    white space and numbers), or ``_RowTrouble``."""
    rows = [lines[k].split() for k in chunk]
    if any(len(r) != n_values for r in rows):
        raise _RowTrouble
    try:
        block = np.array(list(chain.from_iterable(rows)), dtype=float)
    except ValueError:
        raise _RowTrouble from None
    del rows
    return block


def _explain_rows(
    lines: list[str],
    row_lines: list[int],
    n_values: int,
    where: str | None,
    short: MotionFormatError | None = None,
) -> MotionFormatError:
    """The error for data rows ``_read_rows`` found a fault in, checked in this order
    over the whole section: a character no number has (the first value that is not a
    number), a row with the wrong number of values, ``short``, a value float() refuses, a value
    not finite, the largest value beyond ``MAX_ABS_VALUE``. Chunked like the reader."""
    chunks = [row_lines[s : s + ROWS_PER_CHUNK] for s in range(0, len(row_lines), ROWS_PER_CHUNK)]
    if any(_NOT_DATA_RE.search("\n".join([lines[k] for k in c])) for c in chunks):
        return _locate_bad_number(lines, row_lines, where)
    for k in row_lines:
        found = len(lines[k].split())
        if found != n_values:
            extra = " (truncated?)" if k == row_lines[-1] and found < n_values else ""
            return MotionFormatError(
                where, f"expected {n_values} values, found {found}{extra}", line=k + 1
            )
    if short is not None:
        return short
    worst, worst_at = -1.0, None
    for c in chunks:
        rows = [lines[k].split() for k in c]
        try:
            block = np.array([v for r in rows for v in r], dtype=float).reshape(len(c), n_values)
        except ValueError:
            return _locate_bad_number(lines, row_lines, where)
        finite = np.isfinite(block)
        if not finite.all():
            r, col = (int(x[0]) for x in np.nonzero(~finite))
            return MotionFormatError(
                where,
                f"value {col + 1} is {rows[r][col]!r}; expected a finite number",
                line=c[r] + 1,
            )
        if block.size:
            r, col = (int(x) for x in np.unravel_index(np.argmax(np.abs(block)), block.shape))
            if abs(block[r, col]) > worst:
                worst, worst_at = abs(block[r, col]), (c[r], col, rows[r][col])
    if worst_at is not None and worst > MAX_ABS_VALUE:
        k, col, text = worst_at
        return MotionFormatError(
            where,
            f"value {col + 1} is {text[:40]!r}; beyond +-{MAX_ABS_VALUE:g}, "
            "refusing an absurd value",
            line=k + 1,
        )
    return MotionFormatError(where, "a data row could not be read", line=row_lines[0] + 1)


def _locate_bad_number(
    lines: list[str], row_lines: list[int], where: str | None
) -> MotionFormatError:
    """The error for the first value that is not a number (slow path)."""
    for k in row_lines:
        for c, v in enumerate(lines[k].split()):
            if not _NUMBER_RE.fullmatch(v):
                return MotionFormatError(
                    where, f"value {c + 1} is {v[:40]!r}; expected a finite number", line=k + 1
                )
    return MotionFormatError(where, "a data value is not a number", line=row_lines[0] + 1)


def _snap_fps(fps: float) -> float:
    if not np.isfinite(fps):
        return float(fps)
    near = round(fps)
    if near > 0 and abs(fps - near) <= 5e-4 * near:
        return float(near)
    return float(fps)


def _full_order(chans: tuple[str, ...]) -> str:
    """Rotation axes in file order, completed with the missing axes (angle 0)."""
    present = "".join(c[0] for c in chans if c in ROTATION_CHANNELS)
    return present + "".join(a for a in "XYZ" if a not in present)


def _channels_to_pose(skeleton: Skeleton, data: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Local quaternions ``(F, J, 4)`` and translations ``(F, J, 3)`` from ``(F, C)`` data."""
    n_frames = data.shape[0]
    n_joints = skeleton.n_joints
    translations = np.broadcast_to(skeleton.offsets, (n_frames, n_joints, 3)).copy()
    rotations = rot.identity((n_frames, n_joints))
    groups: dict[str, tuple[list[int], list[np.ndarray]]] = {}
    col = 0
    for j, chans in enumerate(skeleton.channels):
        order = _full_order(chans)
        angles = None
        for c in chans:
            if c in POSITION_CHANNELS:
                translations[:, j, _AXIS[c[0]]] = data[:, col]
            else:
                if angles is None:
                    angles = np.zeros((n_frames, 3))
                angles[:, order.index(c[0])] = data[:, col]
            col += 1
        if angles is not None:
            js, arrs = groups.setdefault(order, ([], []))
            js.append(j)
            arrs.append(angles)
    for order, (js, arrs) in groups.items():
        rotations[:, js] = rot.from_euler(np.stack(arrs, axis=1), order)
    return rotations, translations


# --------------------------------------------------------------------------- metadata

_BODY_WORDS = ("foot", "ankle", "toe", "knee", "leg", "hip", "thigh", "shin")
_HAND_WORDS = ("thumb", "index", "middle", "ring", "pinky", "little", "finger")
# size in metres of what _skeleton_size measures, and the units considered (nobody records
# bodies in decimetres; ManipNet's hands are)
_HUMAN_SIZE = {
    "body": (1.5, ("m", "cm", "mm", "in")),  # head to ankle/foot joint along the bones
    "hand": (0.16, ("m", "dm", "cm", "mm")),  # wrist to the farthest finger joint
}
_UNIT_TOLERANCE = 2.0  # accept the nearest unit within this factor, else "unknown"


def _kind(skeleton: Skeleton) -> str:
    """``"hand"`` for a skeleton with finger names and no leg names, else ``"body"``."""
    low = [n.lower() for n in skeleton.names]
    if any(w in n for n in low for w in _BODY_WORDS):
        return "body"
    if any(w in n for n in low for w in _HAND_WORDS):
        return "hand"
    return "body"


def _probe_positions(
    skeleton: Skeleton, rotations: np.ndarray, translations: np.ndarray
) -> np.ndarray:
    """World joint positions ``(S, J, 3)`` of up to 16 frames spread over the take."""
    from engine.model.kinematics import (  # kinematics imports motion
        forward_kinematics,
        rest_positions,
    )

    n_frames = rotations.shape[0]
    if n_frames == 0:
        return rest_positions(skeleton)[None]
    pick = np.unique(np.linspace(0, n_frames - 1, min(n_frames, 16)).round().astype(int))
    probe = Motion(skeleton, rotations[pick], translations[pick], 30.0)
    return forward_kinematics(probe)[0]


def _bone_path(skeleton: Skeleton, a: int, b: int) -> float:
    """Sum of bone lengths (offset norms) on the tree path between joints ``a`` and ``b``."""
    lengths = np.linalg.norm(skeleton.offsets, axis=1)
    up_a, up_b = skeleton.chain_to_root(a), skeleton.chain_to_root(b)
    common = set(up_a) & set(up_b)
    return float(sum(lengths[j] for j in up_a + up_b if j not in common))


def _skeleton_size(skeleton: Skeleton, pos: np.ndarray) -> tuple[float, str]:
    """A size in file units and the kind it measures: ``"body"`` or ``"hand"``."""
    low = [n.lower() for n in skeleton.names]
    if _kind(skeleton) == "hand":
        start = next((j for j, n in enumerate(low) if "wrist" in n or "hand" in n), 0)
        below = skeleton.descendants(start)
        return max(_bone_path(skeleton, start, j) for j in below), "hand"
    head = [j for j, n in enumerate(low) if "head" in n and "end" not in n]
    feet = [j for j, n in enumerate(low) if "foot" in n or "ankle" in n]
    if head and feet:
        return max(_bone_path(skeleton, head[0], f) for f in feet), "body"
    return float(np.median((pos.max(axis=1) - pos.min(axis=1)).max(axis=1))), "body"


def _detect_units(skeleton: Skeleton, pos: np.ndarray) -> str:
    """Unit whose metres best explain the skeleton's size (see module docstring)."""
    size, kind = _skeleton_size(skeleton, pos)
    if not (np.isfinite(size) and size > 0):
        return "unknown"
    expected_m, candidates = _HUMAN_SIZE[kind]
    best, best_ratio = "unknown", np.inf
    for unit in candidates:
        ratio = abs(np.log(size * UNIT_TO_METERS[unit] / expected_m))
        if ratio < best_ratio:
            best, best_ratio = unit, ratio
    return best if best_ratio <= np.log(_UNIT_TOLERANCE) else "unknown"


def _detect_up_axis(skeleton: Skeleton, pos: np.ndarray) -> str:
    """``"y"`` or ``"z"`` from the posed skeleton (see module docstring)."""
    low = [n.lower() for n in skeleton.names]
    head = [j for j, n in enumerate(low) if "head" in n and "end" not in n]
    feet = [j for j, n in enumerate(low) if any(w in n for w in ("foot", "ankle", "toe"))]
    if head and feet:
        up = np.mean(pos[:, head], axis=(0, 1)) - np.mean(pos[:, feet], axis=(0, 1))
        return "y" if abs(up[1]) >= abs(up[2]) else "z"
    if _kind(skeleton) == "body" and skeleton.n_joints >= 10:
        extent = np.median(pos.max(axis=1) - pos.min(axis=1), axis=0)
        return "y" if extent[1] >= extent[2] else "z"
    return "y"


# --------------------------------------------------------------------------- writing


def iter_bvh(motion: Motion, precision: int = 6, frames: int = FRAMES_PER_PIECE) -> Iterator[str]:
    """BVH text for ``motion`` in pieces: the header, then ``frames`` data lines at a time
    (``"".join`` of the pieces is :func:`format_bvh`). A long take's text is never held
    whole: written piece by piece (``engine.base.atomic.write_text``) a 72,000-frame take
    needs a few MB for its text instead of the text, its lines and a Python float per
    channel value (~0.75 GB at 10 minutes, 120 fps, 52 joints).

    The checks below run when this is called, before the first piece.

    Channel values are written with ``precision`` decimals (default 6: errors up to
    5e-7 degrees or file units); offsets and the frame time in shortest round-trip form.
    Euler angles come from ``to_euler`` in each joint's channel order, unwrapped over
    time. Joints are written depth first (children in index order), which is the
    skeleton's own order for every skeleton read from BVH; a skeleton in another
    order comes back from ``read_bvh`` in depth-first order.

    Raises ``ValueError`` if a joint rotates or moves without channels to hold it (more
    than 1e-6 degrees, or 1e-9 of the skeleton's size away from its OFFSET), or if a
    joint name cannot be written (empty, line breaks, tabs, braces, repeated).
    """
    if not (isinstance(precision, int | np.integer) and 0 <= precision <= 17):
        raise ValueError(f"format_bvh: precision must be an integer 0..17, got {precision!r}")
    sk = motion.skeleton
    _check_names(sk)
    _check_representable(motion)
    children: dict[int, list[int]] = {}
    for j, p in enumerate(sk.parents):
        children.setdefault(int(p), []).append(j)
    out: list[str] = ["HIERARCHY"]
    order: list[int] = []
    # iterative depth-first walk: ("open", j, depth) writes the header and children,
    # ("close", j, depth) writes the End Site and the closing brace
    stack: list[tuple[str, int, int]] = [("open", r, 0) for r in reversed(children.get(-1, []))]
    while stack:
        what, j, depth = stack.pop()
        ind = "\t" * depth
        if what == "open":
            order.append(j)
            kw = "ROOT" if sk.parents[j] < 0 else "JOINT"
            chans = sk.channels[j]
            out.append(f"{ind}{kw} {sk.names[j]}")
            out.append(f"{ind}{{")
            out.append(f"{ind}\tOFFSET {_exact3(sk.offsets[j])}")
            out.append(f"{ind}\tCHANNELS {len(chans)}" + "".join(f" {c}" for c in chans))
            stack.append(("close", j, depth))
            stack.extend(("open", c, depth + 1) for c in reversed(children.get(j, [])))
        else:
            if j in sk.end_sites:
                out.append(f"{ind}\tEnd Site")
                out.append(f"{ind}\t{{")
                out.append(f"{ind}\t\tOFFSET {_exact3(sk.end_sites[j])}")
                out.append(f"{ind}\t}}")
            out.append(f"{ind}}}")
    out.append("MOTION")
    out.append(f"Frames: {motion.n_frames}")
    out.append(f"Frame Time: {_exact(1.0 / motion.fps)}")
    data = _pose_to_channels(motion, order)
    return _pieces("\n".join(out) + "\n", data, precision, max(1, int(frames)))


def _pieces(header: str, data: np.ndarray, precision: int, frames: int) -> Iterator[str]:
    yield header
    fmt = " ".join([f"%.{precision}f"] * data.shape[1])
    for a in range(0, data.shape[0], frames):
        if data.shape[1]:
            yield "\n".join(fmt % tuple(row) for row in data[a : a + frames].tolist()) + "\n"
        else:  # no channels anywhere: one empty data row per frame (the reader counts Frames:)
            yield "\n" * min(frames, data.shape[0] - a)


def format_bvh(motion: Motion, precision: int = 6) -> str:
    """BVH text for ``motion``.

    Channel values are written with ``precision`` decimals (default 6: errors up to
    5e-7 degrees or file units); offsets and the frame time in shortest round-trip form.
    Euler angles come from ``to_euler`` in each joint's channel order, unwrapped over
    time. Joints are written depth first (children in index order), which is the
    skeleton's own order for every skeleton read from BVH; a skeleton in another
    order comes back from ``read_bvh`` in depth-first order.

    Raises ``ValueError`` if a joint rotates or moves without channels to hold it (more
    than 1e-6 degrees, or 1e-9 of the skeleton's size away from its OFFSET), or if a
    joint name cannot be written (empty, line breaks, tabs, braces, repeated).
    """
    return "".join(iter_bvh(motion, precision))


def _check_names(sk: Skeleton) -> None:
    seen: set[str] = set()
    for name in sk.names:
        if not name or name != " ".join(name.split()) or "{" in name or "}" in name:
            raise ValueError(
                f"format_bvh: joint name {name!r} cannot be written to BVH (empty, "
                f"tabs, line breaks, outer or double spaces, or braces)"
            )
        if name in seen:
            raise ValueError(f"format_bvh: joint name {name!r} is used twice")
        seen.add(name)


def write_bvh(motion: Motion, path: str | Path, precision: int = 6) -> None:
    """Write ``motion`` to ``path`` as BVH, atomically (see ``format_bvh``), piece by piece
    (:func:`iter_bvh`)."""
    write_text(path, iter_bvh(motion, precision=precision))


def _exact(x: float) -> str:
    return np.format_float_positional(float(x), trim="-")


def _exact3(v: np.ndarray) -> str:
    return " ".join(_exact(x) for x in v)


def _wrap180(deg: np.ndarray) -> np.ndarray:
    return (np.asarray(deg) + 180.0) % 360.0 - 180.0


def _channel_euler(q: np.ndarray, chans: tuple[str, ...]) -> np.ndarray:
    """Euler angles ``(..., 3)`` in the joint's completed order (see ``_full_order``).

    With fewer than 3 rotation channels the missing (last) axes must come out near 0;
    of the two Tait-Bryan solutions ``(a, b, c)`` and ``(a+180, 180-b, c+180)`` the one
    with the smaller missing angles is taken (a 2-axis joint bent past 90 degrees).
    """
    n_rot = sum(c in ROTATION_CHANNELS for c in chans)
    e = rot.to_euler(q, _full_order(chans))
    if n_rot == 2:
        alt = np.stack(
            [_wrap180(e[..., 0] + 180.0), 180.0 - e[..., 1], _wrap180(e[..., 2] + 180.0)], axis=-1
        )
        use_alt = np.abs(_wrap180(e[..., 2])) > 90.0
        e = np.where(use_alt[..., None], alt, e)
    return e


def _check_representable(motion: Motion) -> None:
    sk = motion.skeleton
    if motion.n_frames == 0:
        return
    scale = max(float(np.abs(sk.offsets).max(initial=0.0)), 1.0)
    identity = rot.identity()
    for j, chans in enumerate(sk.channels):
        n_rot = sum(c in ROTATION_CHANNELS for c in chans)
        if n_rot < 3:
            q = motion.rotations[:, j]
            if n_rot == 0:
                err = float(rot.angle_between(q, identity).max())
            else:
                missing = _wrap180(_channel_euler(q, chans)[:, n_rot:])
                err = float(np.abs(missing).max())
            if err > 1e-6:
                raise ValueError(
                    f"format_bvh: joint {sk.names[j]!r} rotates up to {err:.3g} degrees about "
                    f"axes it has no channels for ({' '.join(chans) or 'no channels'})"
                )
        for a, c in enumerate(POSITION_CHANNELS):
            if c not in chans:
                dev = float(np.abs(motion.translations[:, j, a] - sk.offsets[j, a]).max())
                if dev > 1e-9 * scale:
                    raise ValueError(
                        f"format_bvh: joint {sk.names[j]!r} moves {dev:.3g} units along "
                        f"{c[0]} from its OFFSET but has no {c} channel"
                    )


def _pose_to_channels(motion: Motion, order: list[int]) -> np.ndarray:
    """``(F, C)`` channel values, joints in ``order``, channels in file order.

    Rotation channels are made a few joints at a time (:data:`EULER_JOINT_FRAMES` joint
    frames per call; each joint's angles are its own, unwrapped over time): the Euler
    conversion's intermediates are ~200 bytes a joint a frame, 0.75 GB for a 52-joint
    take of 72,000 frames if made for all joints at once."""
    sk = motion.skeleton
    n_frames = motion.n_frames
    column: dict[tuple[int, str], int] = {}  # (joint, channel) -> column of the data
    for j in order:
        for c in sk.channels[j]:
            column[(j, c)] = len(column)
    data = np.empty((n_frames, len(column)))
    # joints grouped by (completed order, number of rotation channels): one call each
    groups: dict[tuple[tuple[str, ...], str], list[int]] = {}
    for j, chans in enumerate(sk.channels):
        rot_chans = tuple(c for c in chans if c in ROTATION_CHANNELS)
        if rot_chans and (j, chans[0]) in column:
            groups.setdefault((rot_chans, _full_order(chans)), []).append(j)
    step = max(1, EULER_JOINT_FRAMES // max(n_frames, 1))
    for (rot_chans, rot_order), joints in groups.items():
        for k0 in range(0, len(joints), step):
            js = joints[k0 : k0 + step]
            e = _channel_euler(motion.rotations[:, js], rot_chans)  # (F, len(js), 3)
            if n_frames > 1:
                e = np.unwrap(e, period=360.0, axis=0)
            for k, j in enumerate(js):
                for c in rot_chans:
                    data[:, column[(j, c)]] = e[:, k, rot_order.index(c[0])]
    for j in order:
        for c in sk.channels[j]:
            if c in POSITION_CHANNELS:
                data[:, column[(j, c)]] = motion.translations[:, j, _AXIS[c[0]]]
    return data
