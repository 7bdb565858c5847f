"""Gesture annotations as ELAN ``.eaf`` tiers (pympi-ling) and CSV, both ways.

Tiers written (times in milliseconds, ``round(frame * 1000 / fps)``):

* ``Phase RH`` and ``Phase LH``: one annotation per non-rest phase segment of
  the right / left hand, value ``preparation``, ``stroke``, ``hold`` or
  ``retraction``; gaps are rest.
* ``Handedness``: one annotation per (joint) gesture phrase, value ``RH``,
  ``LH`` or ``2H``.

Header properties ``fps``, ``frames`` and ``source`` let ``read_eaf`` convert
times back to frames exactly (``round(ms * fps / 1000)``; exact for fps <= 1000).
``read_eaf`` accepts a human's corrections: values may be the words above, their
letters ``P S H R`` or ``rest``, in any case; ``rest`` or a gap is REST.

CSV (``write_csv`` / ``read_csv``): one row per annotation,
``tier,start_frame,stop_frame,start_s,stop_s,value`` with the same tier names.

``phase_constraints`` turns two annotated takes (body and hand) into DTW matching
points ``(body_frame, hand_frame, tolerance)`` at corresponding phase boundaries,
the input of ``engine.dtw`` band constraints.
"""

from __future__ import annotations

import csv
import io
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from engine.base.atomic import atomic_path, write_text
from engine.base.errors import MotionFormatError, ParameterError
from engine.base.limits import MAX_DURATION_S, MAX_EAF_BYTES, MAX_FRAMES, check_rate
from engine.gesture.phases import GesturePhases, Phase, PhaseSegment
from engine.io.numbers import is_number, is_whole

PHASE_TIERS = {"right": "Phase RH", "left": "Phase LH"}
HANDEDNESS_TIER = "Handedness"
CSV_HEADER = ("tier", "start_frame", "stop_frame", "start_s", "stop_s", "value")

_WORDS = {
    Phase.PREPARATION: "preparation",
    Phase.STROKE: "stroke",
    Phase.HOLD: "hold",
    Phase.RETRACTION: "retraction",
    Phase.REST: "rest",
}
_PARSE = {w: p for p, w in _WORDS.items()} | {p.letter.lower(): p for p in Phase if p != Phase.REST}
_HANDEDNESS_VALUES = ("RH", "LH", "2H")


@dataclass(frozen=True)
class GestureAnnotations:
    """Annotations read back from ELAN or CSV.

    Attributes
    ----------
    fps : float
    n_frames : int or None
        From the file's ``frames`` property, or the end of the last annotation.
    phases : dict side -> tuple of PhaseSegment (non-rest segments only)
    handedness : tuple of (start, stop, label)
    source : str
    """

    fps: float
    n_frames: int | None
    phases: dict[str, tuple[PhaseSegment, ...]] = field(default_factory=dict)
    handedness: tuple[tuple[int, int, str], ...] = ()
    source: str = ""

    def labels(self, side: str, n_frames: int | None = None) -> np.ndarray:
        """(F,) uint8 per-frame ``Phase`` codes of one hand (REST where unannotated)."""
        n = n_frames or self.n_frames or max((s.stop for s in self.phases.get(side, ())), default=0)
        return labels_from_segments(self.phases.get(side, ()), n)


def labels_from_segments(segments, n_frames: int) -> np.ndarray:
    """(F,) uint8 labels from segments (frames outside every segment are REST)."""
    labels = np.zeros(int(n_frames), dtype=np.uint8)
    for s in segments:
        labels[max(0, s.start) : min(n_frames, s.stop)] = int(s.phase)
    return labels


def _rows(phases: GesturePhases, handedness) -> list[tuple[str, int, int, str]]:
    rows = []
    for side, tier in PHASE_TIERS.items():
        hand = phases.hands.get(side)
        if hand is None:
            continue
        rows.extend(
            (tier, s.start, s.stop, _WORDS[s.phase]) for s in hand.segments if s.phase != Phase.REST
        )
    for h in handedness or ():
        rows.append((HANDEDNESS_TIER, int(h.start), int(h.stop), str(h.label)))
    return rows


def _ms(frame: int, fps: float) -> int:
    return int(round(frame * 1000.0 / fps))


def _frame(ms: float, fps: float) -> int:
    return int(round(ms * fps / 1000.0))


def write_eaf(
    path: str | Path,
    phases: GesturePhases,
    handedness=(),
    source: str = "",
    media: str | None = None,
) -> None:
    """Write phases (and handedness) as an ELAN file, atomically.

    Parameters
    ----------
    path : output ``.eaf``
    phases : GesturePhases
    handedness : sequence of ``PhraseHandedness`` (``.start``, ``.stop``, ``.label``)
    source : the capture file's name, stored as a header property
    media : optional media file to link (e.g. a rendered video)
    """
    from xml.etree.ElementTree import ElementTree

    from pympi.Elan import Eaf, to_adocument

    eaf = Eaf(author="handsplice")
    eaf.add_property("fps", repr(float(phases.fps)))
    eaf.add_property("frames", str(int(phases.n_frames)))
    if source:
        eaf.add_property("source", str(source))
    if media:
        eaf.add_linked_file(str(media))
    for tier in (*PHASE_TIERS.values(), HANDEDNESS_TIER):
        eaf.add_tier(tier)
    for tier, a, b, value in _rows(phases, handedness):
        start, stop = _ms(a, phases.fps), _ms(b, phases.fps)
        if stop > start:
            eaf.add_annotation(tier, start, stop, value)
    if "default" in eaf.get_tier_names() and not eaf.get_annotation_data_for_tier("default"):
        eaf.remove_tier("default")
    # pympi's to_eaf renames an existing file to NAME.bak before writing, and the
    # temporary file exists already: write the document ourselves (no .bak left behind)
    document = to_adocument(eaf, True)
    with atomic_path(path) as tmp:
        ElementTree(document).write(str(tmp), xml_declaration=True, encoding="UTF-8")


def _parse_phase(value: str, where: str) -> Phase:
    key = str(value).strip().lower()
    if key not in _PARSE:
        raise MotionFormatError(
            where,
            f"unknown phase {value!r}; expected one of "
            "preparation, stroke, hold, retraction, rest (or P/S/H/R)",
        )
    return _PARSE[key]


def _parse_handedness(value: str, where: str) -> str:
    key = str(value).strip().upper()
    if key not in _HANDEDNESS_VALUES:
        raise MotionFormatError(where, f"unknown handedness {value!r}; expected RH, LH or 2H")
    return key


def _collect(path: str, fps: float, n_frames: int | None, rows, source: str) -> GestureAnnotations:
    phases: dict[str, list[PhaseSegment]] = {side: [] for side in PHASE_TIERS}
    hands: list[tuple[int, int, str]] = []
    side_of = {t.lower(): s for s, t in PHASE_TIERS.items()}
    for tier, a, b, value, where in rows:
        if b <= a:
            continue
        if tier.lower() in side_of:
            ph = _parse_phase(value, where)
            if ph != Phase.REST:
                phases[side_of[tier.lower()]].append(PhaseSegment(ph, a, b))
        elif tier.lower() == HANDEDNESS_TIER.lower():
            hands.append((a, b, _parse_handedness(value, where)))
    out = {s: tuple(sorted(v, key=lambda s: s.start)) for s, v in phases.items()}
    for side, segs in out.items():
        for prev, nxt in zip(segs, segs[1:]):
            if nxt.start < prev.stop:
                raise MotionFormatError(
                    path,
                    f"tier {PHASE_TIERS[side]!r}: annotations overlap at "
                    f"frames {nxt.start}-{prev.stop}",
                )
    if n_frames is None:
        ends = [s.stop for v in out.values() for s in v] + [h[1] for h in hands]
        n_frames = max(ends) if ends else None
    return GestureAnnotations(
        fps=float(fps),
        n_frames=n_frames,
        phases=out,
        handedness=tuple(sorted(hands)),
        source=source,
    )


def read_eaf(path: str | Path, fps: float | None = None) -> GestureAnnotations:
    """Read phase and handedness tiers from an ELAN file.

    ``fps`` converts milliseconds to frames; when omitted the file's ``fps``
    header property is used (files written by ``write_eaf`` have it).

    Raises ``FileNotFoundError`` for a missing file, ``ParameterError`` when the frame
    rate is neither given nor in the file, and ``MotionFormatError`` (file named) for
    every damaged file: XML that is not ELAN, an ``fps`` or ``frames`` property that is
    not a number in range, annotations with missing or absurd times, unknown values.
    """
    from pympi.Elan import Eaf

    path = str(path)
    name = Path(path).name
    if not Path(path).is_file():
        raise FileNotFoundError(2, "No such file", path)
    if Path(path).stat().st_size > MAX_EAF_BYTES:
        raise MotionFormatError(
            path, f"more than {MAX_EAF_BYTES:,} bytes; refusing an absurd annotation file"
        )
    try:
        with warnings.catch_warnings():  # "unknown version of ELAN spec": newer ELAN, readable
            warnings.simplefilter("ignore", UserWarning)
            eaf = Eaf(path)
        props = {str(k): str(v) for k, v in eaf.get_properties()}
    except (Exception, RecursionError) as exc:  # pympi raises bare exceptions on bad XML
        raise MotionFormatError(
            path, f"not a readable ELAN file ({type(exc).__name__}: {_first_line(exc)})"
        ) from None
    if fps is None:
        if "fps" not in props:
            raise ParameterError(f"{name}: no 'fps' property; pass the take's frame rate")
        fps = check_rate(_property_number(path, "fps", props["fps"]), path, field="property 'fps'")
    if not (np.isfinite(fps) and fps > 0):
        raise ParameterError(f"{name}: fps must be positive, got {fps!r}")
    check_rate(fps, path, field="fps")
    n_frames = None
    if "frames" in props:
        text = props["frames"].strip()
        if not (is_whole(text) and int(text[:20]) <= MAX_FRAMES):
            raise MotionFormatError(
                path,
                f"property 'frames' is {text[:40]!r}; expected a whole number up to {MAX_FRAMES:,}",
            )
        n_frames = int(text)
    max_ms = MAX_DURATION_S * 1000.0
    rows = []
    try:
        tiers = list(eaf.get_tier_names())
        for tier in tiers:
            for ann in eaf.get_annotation_data_for_tier(tier):
                start, stop, value = ann[0], ann[1], ann[2]
                where = f"{name} tier {str(tier)[:40]!r} at {start} ms"
                if not all(
                    isinstance(t, int | float) and np.isfinite(t) and 0 <= t <= max_ms
                    for t in (start, stop)
                ):
                    raise MotionFormatError(
                        path,
                        f"tier {str(tier)[:40]!r}: annotation time "
                        f"{start!r}-{stop!r} ms is not a time within "
                        f"{MAX_DURATION_S / 3600:g} hours",
                    )
                rows.append(
                    (
                        str(tier),
                        _frame(start, fps),
                        _frame(stop, fps),
                        "" if value is None else str(value),
                        where,
                    )
                )
    except MotionFormatError:
        raise
    except (Exception, RecursionError) as exc:  # time slots, references pympi cannot resolve
        raise MotionFormatError(
            path, f"damaged ELAN annotations ({type(exc).__name__}: {_first_line(exc)})"
        ) from None
    return _collect(path, fps, n_frames, rows, props.get("source", ""))


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0][:120] if text else "no detail"


def _property_number(path: str, key: str, text: str) -> float:
    text = text.strip()
    if not is_number(text):
        raise MotionFormatError(path, f"property {key!r} is {text[:40]!r}; expected a number")
    return float(text)


def format_csv(phases: GesturePhases, handedness=()) -> str:
    """The CSV text (see module docstring)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_HEADER)
    for tier, a, b, value in _rows(phases, handedness):
        w.writerow((tier, a, b, f"{a / phases.fps:.6f}", f"{b / phases.fps:.6f}", value))
    return buf.getvalue()


def write_csv(path: str | Path, phases: GesturePhases, handedness=()) -> None:
    """Write phases (and handedness) as CSV, atomically."""
    write_text(path, format_csv(phases, handedness))


def read_csv(path: str | Path, fps: float | None = None) -> GestureAnnotations:
    """Read a CSV written by ``write_csv`` (or edited by hand; frames win over seconds).

    ``fps`` is only needed when the frame columns are empty; otherwise it is
    derived from the rows.
    """
    path = str(path)
    text = Path(path).read_text(encoding="utf-8")
    reader = csv.reader(io.StringIO(text))
    header = next(reader, None)
    if header is None or tuple(h.strip() for h in header) != CSV_HEADER:
        raise MotionFormatError(path, f"expected the header {','.join(CSV_HEADER)}", line=1)
    rows = []
    fps_seen = []
    for lineno, rec in enumerate(reader, start=2):
        if not rec or all(not c.strip() for c in rec):
            continue
        if len(rec) != len(CSV_HEADER):
            raise MotionFormatError(
                path, f"expected {len(CSV_HEADER)} fields, found {len(rec)}", line=lineno
            )
        tier, a, b, sa, sb, value = (c.strip() for c in rec)
        try:
            if a and b:
                fa, fb = int(a), int(b)
                if float(sb) > 0:
                    fps_seen.append((float(sb), fb / float(sb)))
            else:
                if not fps:
                    raise ParameterError(f"{Path(path).name} line {lineno}: no frames; pass fps")
                fa, fb = _frame(float(sa) * 1000, fps), _frame(float(sb) * 1000, fps)
        except ValueError:
            raise MotionFormatError(path, "start/stop must be numbers", line=lineno) from None
        rows.append((tier, fa, fb, value, f"{Path(path).name} line {lineno}"))
    if fps is None:
        # from the latest stop: the most precise ratio of frames to rounded seconds
        fps = max(fps_seen)[1] if fps_seen else 30.0
    return _collect(path, fps, None, rows, "")


# ---------------------------------------------------------------------------
# Phase boundaries as splicing constraints


def phase_boundaries(segments) -> list[tuple[int, Phase, Phase]]:
    """Frames where the phase changes: ``(frame, phase_before, phase_after)``.

    ``segments`` may skip rest (gaps count as REST).
    """
    out = []
    current, pos = Phase.REST, 0
    for s in sorted(segments, key=lambda s: s.start):
        if s.start > pos and current != Phase.REST:
            out.append((pos, current, Phase.REST))
            current = Phase.REST
        if s.phase != current and s.start > 0:
            out.append((s.start, current, s.phase))
        current, pos = s.phase, s.stop
    if current != Phase.REST:
        out.append((pos, current, Phase.REST))
    return out


def phase_constraints(
    body_segments,
    hand_segments,
    tolerance: int = 0,
    n_body: int | None = None,
    n_hand: int | None = None,
) -> list[tuple[int, int, int]]:
    """DTW matching points from corresponding phase boundaries of two annotated takes.

    Boundaries are matched in order by their type (phase before -> phase after)
    with a longest-common-subsequence, so an extra phase in one take does not shift
    the others. Returns ``[(body_frame, hand_frame, tolerance), ...]``, strictly
    increasing in both frames, leaving out the takes' first and last frames (the
    path's fixed ends) when ``n_body``/``n_hand`` are given.
    """
    if tolerance < 0:
        raise ParameterError(f"tolerance: expected frames >= 0, got {tolerance!r}")
    a = phase_boundaries(body_segments)
    b = phase_boundaries(hand_segments)
    n, m = len(a), len(b)
    lcs = np.zeros((n + 1, m + 1), dtype=np.int64)
    for i in range(n - 1, -1, -1):
        for j in range(m - 1, -1, -1):
            if a[i][1:] == b[j][1:]:
                lcs[i, j] = lcs[i + 1, j + 1] + 1
            else:
                lcs[i, j] = max(lcs[i + 1, j], lcs[i, j + 1])
    out: list[tuple[int, int, int]] = []
    i = j = 0
    while i < n and j < m:
        if a[i][1:] == b[j][1:]:
            x, y = a[i][0], b[j][0]
            inside = (n_body is None or 0 < x < n_body - 1) and (
                n_hand is None or 0 < y < n_hand - 1
            )
            if inside and (not out or (x > out[-1][0] and y > out[-1][1])):
                out.append((int(x), int(y), int(tolerance)))
            i += 1
            j += 1
        elif lcs[i + 1, j] >= lcs[i, j + 1]:
            i += 1
        else:
            j += 1
    return out
