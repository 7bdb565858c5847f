"""TRC reader (Motion Analysis "track row column" marker files) into a ``MarkerSet``.

Layout (tab-separated; comma-separated files such as pyomeca's are accepted too)::

    PathFileType  4  (X/Y/Z)  walk.trc
    DataRate  CameraRate  NumFrames  NumMarkers  Units  OrigDataRate  ...
    100       100         652        51          mm     100           ...
    Frame#  Time  ASISl        ASISr   ...
            X1  Y1  Z1  X2  Y2  Z2  ...
    (optional blank line)
    1   0.00  733.70  80.98  191.87  ...

- fps is ``DataRate`` (``CameraRate`` when DataRate is missing);
- units from ``Units`` (``mm``, ``cm``, ``m``, ``in``; else ``"unknown"``);
- an empty field, or ``NaN`` text, is a gap and reads as NaN;
- a data row must hold ``2 + 3 * markers`` fields (extra trailing empty fields
  are ignored); anything else is an error naming the line;
- the number of data rows wins over ``NumFrames`` (exports cut short keep their
  header; pyomeca's ``markers.trc`` declares 652 frames and holds 93); when they
  differ, ``meta.notes`` says so (``"markers.trc: the header says 652 frames, 93
  were read"``), which the command line and the app show;
- TRC does not record an up axis: ``up_axis`` defaults to ``"y"`` (OpenSim's
  convention); pass ``up_axis="z"`` for Vicon-style Z-up data.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from engine.base import limits
from engine.base.errors import MotionFormatError
from engine.base.limits import MAX_ABS_VALUE, MAX_FRAMES, MAX_MARKERS
from engine.io.numbers import is_non_finite, is_number
from engine.model.motion import MarkerSet, MotionMeta

_UNITS = {
    "mm": "mm",
    "millimeters": "mm",
    "cm": "cm",
    "m": "m",
    "meters": "m",
    "in": "in",
    "inches": "in",
}
_GAP_TEXT = {"", "nan", "-nan", "+nan"}


def read_trc(path: str | Path, up_axis: str = "y") -> MarkerSet:
    """Read a TRC file.

    Parameters
    ----------
    path : str or Path
        A ``.trc`` file.
    up_axis : ``"y"`` or ``"z"``
        Recorded in ``meta.up_axis``; the file itself does not say.

    Returns
    -------
    MarkerSet
        ``labels`` (M,) from the marker-name row, ``points`` (F, M, 3) float in
        ``meta.units`` with NaN gaps, ``fps`` from ``DataRate``.

    Raises
    ------
    MotionFormatError
        Binary content, a missing or malformed header, a data row with the wrong
        number of fields or a non-numeric value (the message names the line).
    FileNotFoundError
        ``path`` does not exist.
    """
    path = Path(path)
    if up_axis not in ("y", "z"):
        raise ValueError(f"up_axis must be 'y' or 'z', got {up_axis!r}")
    raw = path.read_bytes()
    return parse_trc(raw, source=path, up_axis=up_axis)


def parse_trc(data: bytes | str, source: str | Path = "<input>", up_axis: str = "y") -> MarkerSet:
    """Parse TRC text (see ``read_trc``); ``source`` names it in errors and ``meta``."""
    text = _decode(data, source)
    lines = text.splitlines()
    if len(lines) < 5:
        raise MotionFormatError(
            source,
            f"not a TRC file: {len(lines)} lines, the header alone needs 5",
            line=len(lines) or None,
        )
    first = lines[0]
    if not first.lower().startswith("pathfiletype"):
        raise MotionFormatError(
            source,
            f"not a TRC file: first line starts {first[:30]!r}, expected 'PathFileType'",
            line=1,
        )
    sep = "\t" if "\t" in first else ","

    keys = [k.strip() for k in lines[1].split(sep)]
    values = [v.strip() for v in lines[2].split(sep)]
    header = {k: (values[i] if i < len(values) else "") for i, k in enumerate(keys) if k}
    fps = _header_number(header, ("DataRate", "CameraRate"), source)
    units = _UNITS.get(header.get("Units", "").lower(), "unknown")
    declared_markers = header.get("NumMarkers", "")

    name_fields = [f.strip() for f in lines[3].split(sep)]
    if len(name_fields) < 2 or name_fields[0].lower() not in ("frame#", "frame"):
        raise MotionFormatError(
            source,
            f"expected the marker-name row 'Frame#, Time, names...', found {lines[3][:40]!r}",
            line=4,
        )
    labels = _marker_names(name_fields, source)
    if len(labels) > MAX_MARKERS:
        raise MotionFormatError(
            source,
            f"{len(labels):,} markers is more than {MAX_MARKERS:,}; refusing an absurd file",
            line=4,
        )
    if declared_markers:
        if not (
            is_number(declared_markers)
            and float(declared_markers).is_integer()
            and float(declared_markers) <= MAX_MARKERS
        ):
            raise MotionFormatError(
                source, f"NumMarkers is {declared_markers[:40]!r}, expected a whole number", line=3
            )
        n_declared = int(float(declared_markers))
        if n_declared != len(labels):
            raise MotionFormatError(
                source,
                f"header says {n_declared} markers (NumMarkers) but "
                f"the name row lists {len(labels)}",
                line=4,
            )

    n_fields = 2 + 3 * len(labels)
    rows: list[list[float]] = []
    for number, line in enumerate(lines[5:], start=6):
        if not line.strip(sep + " \r"):
            continue  # blank separator line(s)
        fields = line.split(sep)
        while len(fields) > n_fields and not fields[-1].strip():
            fields.pop()
        if len(fields) != n_fields:
            hint = " (file cut short?)" if number == len(lines) else ""
            raise MotionFormatError(
                source,
                f"expected {n_fields} values (Frame#, Time, 3 x "
                f"{len(labels)} markers), found {len(fields)}{hint}",
                line=number,
            )
        if len(rows) >= MAX_FRAMES:
            raise MotionFormatError(
                source, f"more than {MAX_FRAMES:,} data rows; refusing an absurd take", line=number
            )
        rows.append(_row_values(fields, number, labels, source))
    if not rows:
        raise MotionFormatError(source, "no data rows after the header", line=len(lines))
    limits.check_take(source, len(rows), fps, len(labels), 3 * len(labels), len(text))
    table = np.asarray(rows, dtype=float)
    points = table[:, 2:].reshape(len(rows), len(labels), 3)
    notes = _frame_count_notes(header.get("NumFrames", ""), len(rows), source)
    meta = MotionMeta(units=units, up_axis=up_axis, source=str(source), format="trc", notes=notes)
    return MarkerSet(labels=tuple(labels), points=points, fps=fps, meta=meta)


def _frame_count_notes(declared: str, n_read: int, source) -> tuple[str, ...]:
    """A note when the header's ``NumFrames`` is not the number of data rows read (a
    file cut short, or a header never updated); none when the header gives no count."""
    if not (is_number(declared) and float(declared).is_integer()):
        return ()
    n_declared = int(float(declared))
    if n_declared == n_read:
        return ()
    name = Path(str(source)).name
    return (f"{name}: the header says {n_declared} frames, {n_read} were read",)


def _decode(data: bytes | str, source) -> str:
    if isinstance(data, str):
        return data
    if b"\x00" in data[:4096]:
        at = data.index(b"\x00")
        raise MotionFormatError(source, f"binary data (NUL byte at offset {at}), expected TRC text")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        sample = data[:4096]
        printable = sum(1 for b in sample if b in (9, 10, 13) or 32 <= b < 127)
        if printable >= 0.95 * len(sample):  # a Latin-1 marker name, say
            return data.decode("latin-1")
        raise MotionFormatError(
            source,
            f"binary data (byte 0x{data[exc.start]:02x} at offset {exc.start}), expected TRC text",
        ) from None


def _header_number(header: dict, keys: tuple[str, ...], source) -> float:
    for key in keys:
        text = header.get(key, "")
        if not text:
            continue
        if not (is_number(text) or is_non_finite(text)):
            raise MotionFormatError(source, f"{key} is {text[:40]!r}, expected a number", line=3)
        value = float(text)
        if not (math.isfinite(value) and value > 0):
            raise MotionFormatError(
                source, f"{key} must be a positive number, got {text[:40]}", line=3
            )
        return limits.check_rate(value, source, line=3, field=key)
    raise MotionFormatError(source, f"header has no {' or '.join(keys)}", line=2)


def _marker_names(fields: list[str], source) -> list[str]:
    """Names sit at columns 2, 5, 8, ... of the name row (blanks between them)."""
    body = fields[2:]
    while body and not body[-1]:
        body.pop()
    labels: list[str] = []
    for i in range(0, len(body), 3):
        name = body[i]
        if not name:
            raise MotionFormatError(source, f"marker name missing in column {i + 3}", line=4)
        labels.append(name)
    if not labels:
        raise MotionFormatError(source, "the name row lists no markers", line=4)
    return labels


def _row_values(fields: list[str], number: int, labels: list[str], source) -> list[float]:
    out: list[float] = []
    for col, field in enumerate(fields):
        text = field.strip()
        if text.lower() in _GAP_TEXT:
            if col < 2 and not text:
                what = "Frame#" if col == 0 else "Time"
                raise MotionFormatError(source, f"{what} is empty", line=number)
            out.append(math.nan)
            continue
        if not (is_number(text) or is_non_finite(text)):
            raise MotionFormatError(
                source, f"{_column_name(col, labels)}: {text[:20]!r} is not a number", line=number
            )
        value = float(text)
        if not math.isfinite(value):
            raise MotionFormatError(
                source, f"{_column_name(col, labels)}: {text[:20]!r} is not finite", line=number
            )
        if abs(value) > MAX_ABS_VALUE:
            raise MotionFormatError(
                source,
                f"{_column_name(col, labels)}: {text[:20]!r} is beyond "
                f"+-{MAX_ABS_VALUE:g}; refusing an absurd value",
                line=number,
            )
        out.append(value)
    return out


def _column_name(col: int, labels: list[str]) -> str:
    if col == 0:
        return "Frame#"
    if col == 1:
        return "Time"
    marker, axis = divmod(col - 2, 3)
    return f"{labels[marker]} {'XYZ'[axis]}"
