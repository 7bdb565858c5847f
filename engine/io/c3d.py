"""C3D reader: labelled 3-D marker trajectories into a ``MarkerSet``.

A small, self-contained reader of the C3D layout (header block, parameter
section, point data), written with bounds checks everywhere: ezc3d (used by the
tests as the reference reader) segfaults or hangs on some damaged parameter
sections and silently reads truncated files, which a server accepting uploads
cannot afford. Intel (little-endian), DEC (VAX floats) and MIPS (big-endian)
files, integer and float point data are supported.

What is read
------------
- labels: ``POINT:LABELS`` (and ``LABELS2``, ``LABELS3``... beyond 255 markers),
  stripped, as the file spells them (e.g. ``"Daphnee:ASISr"``); unlabelled
  points are named ``M001``...;
- points: (frames, markers, 3) in the file's units (integer data times
  ``POINT:SCALE``); a sample whose residual word is negative (the C3D convention
  for "not seen") is NaN;
- fps: ``POINT:RATE`` (the header's rate when the parameter is absent);
- units: ``POINT:UNITS`` (``"mm"``, ``"cm"``, ``"m"``, ``"in"``; anything else
  gives ``"unknown"``);
- up axis: from ``POINT:Y_SCREEN`` (the axis shown upwards; ``"+Z"`` -> ``"z"``),
  ``"z"`` when absent or not Y/Z (the usual lab convention for C3D).
Analog channels are not read.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from engine.base import limits
from engine.base.errors import MotionFormatError
from engine.base.limits import MAX_ABS_VALUE, MAX_FRAMES, MAX_MARKERS
from engine.model.motion import MarkerSet, MotionMeta

_BLOCK = 512
_PROCESSORS = {84: "intel", 85: "dec", 86: "mips"}
_UNITS = {
    "mm": "mm",
    "millimeters": "mm",
    "millimetres": "mm",
    "cm": "cm",
    "m": "m",
    "meters": "m",
    "metres": "m",
    "in": "in",
    "inch": "in",
    "inches": "in",
}


def read_c3d(path: str | Path) -> MarkerSet:
    """Read the 3-D points of a C3D file.

    Parameters
    ----------
    path : str or Path
        A ``.c3d`` file.

    Returns
    -------
    MarkerSet
        ``labels`` (M,), ``points`` (F, M, 3) float in the file's units with NaN
        where a marker was not seen (residual < 0), ``fps`` from ``POINT:RATE``,
        ``meta`` = ``MotionMeta(units, up_axis, source=str(path), format="c3d")``.

    Raises
    ------
    MotionFormatError
        The file is not a C3D file, its header or parameter section is damaged or
        inconsistent, or it is shorter than its header promises (truncated).
    FileNotFoundError
        ``path`` does not exist.
    """
    path = Path(path)
    raw = path.read_bytes()
    return parse_c3d(raw, source=path)


def parse_c3d(raw: bytes, source: str | Path = "<input>") -> MarkerSet:
    """Parse the bytes of a C3D file (see ``read_c3d``); ``source`` names it in errors."""
    header = _check_header(source, raw)
    start = (header["param_block"] - 1) * _BLOCK
    section = raw[start : start + header["n_param_blocks"] * _BLOCK]
    params = _walk_parameters(source, section, header)
    _check_parameters(source, params, header)
    reader = _ParamReader(params, header)

    n_points = header["n_points"]
    n_frames = _frame_count(source, reader, header, len(raw))
    if n_frames > MAX_FRAMES or n_points > MAX_MARKERS:
        raise MotionFormatError(
            source,
            f"{n_frames:,} frames of {n_points:,} markers is more than "
            f"{MAX_FRAMES:,} frames or {MAX_MARKERS:,} markers; "
            "refusing an absurd take",
        )
    scale = reader.float("POINT", "SCALE", header["scale"])
    if not np.isfinite(scale):
        raise MotionFormatError(source, f"POINT:SCALE is {scale}, expected a finite number")
    is_float = scale < 0
    value_bytes = 4 if is_float else 2
    per_frame = n_points * 4 + header["n_analog"]
    offset = (header["data_start"] - 1) * _BLOCK
    needed = offset + n_frames * per_frame * value_bytes
    if len(raw) < needed:
        have = (len(raw) - offset) // max(per_frame * value_bytes, 1)
        raise MotionFormatError(
            source,
            f"truncated C3D file (or damaged header): {n_frames} frames need {needed} "
            f"bytes, the file has {len(raw)} (about {max(have, 0)} frames)",
        )
    fps = reader.float("POINT", "RATE", header["rate"])
    if not (np.isfinite(fps) and fps > 0):
        raise MotionFormatError(source, f"POINT:RATE must be a positive number, got {fps}")
    limits.check_rate(fps, source, field="POINT:RATE")
    limits.check_take(source, n_frames, fps, n_points, 3 * n_points, len(raw), what="markers")
    data = raw[offset:needed]
    if is_float:
        values = _floats(data, header["processor"], header["endian"])
    else:
        values = np.frombuffer(data, dtype=np.dtype(header["endian"] + "i2")).astype(float)
    values = values.reshape(n_frames, per_frame)[:, : n_points * 4].reshape(n_frames, n_points, 4)
    points = values[:, :, :3].copy()
    if not is_float:
        points *= abs(scale)
    points[values[:, :, 3] < 0] = np.nan
    seen = points[~np.isnan(points)]
    if not np.isfinite(seen).all():
        raise MotionFormatError(source, "point data holds infinite values")
    if seen.size and np.abs(seen).max() > MAX_ABS_VALUE:
        raise MotionFormatError(
            source, f"point data holds values beyond +-{MAX_ABS_VALUE:g}; refusing an absurd take"
        )

    labels = reader.labels()
    if len(labels) < n_points:
        labels += [f"M{i + 1:03d}" for i in range(len(labels), n_points)]
    labels = labels[:n_points]
    units = _UNITS.get(reader.text("POINT", "UNITS").lower(), "unknown")
    up = reader.text("POINT", "Y_SCREEN").lower().lstrip("+-")
    up_axis = up if up in ("y", "z") else "z"  # MotionMeta knows y-up and z-up only
    meta = MotionMeta(units=units, up_axis=up_axis, source=str(source), format="c3d")
    return MarkerSet(labels=tuple(labels), points=points, fps=float(fps), meta=meta)


def _frame_count(source, reader: _ParamReader, header: dict, size: int) -> int:
    first, last = header["first"], header["last"]
    if last != 0xFFFF:
        if last < first:
            raise MotionFormatError(
                source, f"bad C3D header: last frame {last} before first frame {first}"
            )
        return last - first + 1
    # long takes: the 16-bit header overflows; TRIAL:ACTUAL_*_FIELD hold 32-bit numbers
    start = reader.uint32("TRIAL", "ACTUAL_START_FIELD")
    end = reader.uint32("TRIAL", "ACTUAL_END_FIELD")
    if start is None or end is None or end < start:
        raise MotionFormatError(
            source,
            "C3D header frame count overflows and TRIAL:ACTUAL_START_FIELD/END_FIELD are missing",
        )
    return end - start + 1


def _floats(data: bytes, processor: str, endian: str) -> np.ndarray:
    with np.errstate(invalid="ignore"):  # signalling-NaN bit patterns in damaged data
        return _floats_raw(data, processor, endian)


def _floats_raw(data: bytes, processor: str, endian: str) -> np.ndarray:
    if processor == "dec":  # VAX F-float: swap the 16-bit halves, exponent bias 2 higher
        halves = np.frombuffer(data, dtype="<u2").reshape(-1, 2)[:, ::-1].copy()
        return halves.view("<f4").ravel().astype(float) / 4.0
    return np.frombuffer(data, dtype=np.dtype(endian + "f4")).astype(float)


# --------------------------------------------------------------------------- header


def _check_header(path, raw: bytes) -> dict:
    """Validate the 512-byte header and the parameter block start; return key numbers."""
    size = len(raw)
    if size < _BLOCK:
        raise MotionFormatError(
            path, f"not a C3D file: {size} bytes, shorter than the {_BLOCK}-byte header"
        )
    head = raw[:_BLOCK]
    if head[1] != 0x50:
        raise MotionFormatError(
            path, f"not a C3D file: header byte 2 is 0x{head[1]:02x}, expected 0x50"
        )
    param_block = head[0]
    if param_block < 2:
        raise MotionFormatError(
            path, f"bad C3D header: parameter block {param_block}, expected 2 or more"
        )
    at = (param_block - 1) * _BLOCK
    if size < at + 4:
        raise MotionFormatError(
            path,
            f"truncated C3D file: parameter block {param_block} lies beyond the end ({size} bytes)",
        )
    phead = raw[at : at + 4]
    processor = _PROCESSORS.get(phead[3])
    if processor is None:
        raise MotionFormatError(
            path,
            f"bad C3D parameter block: processor type {phead[3]}, "
            "expected 84 (Intel), 85 (DEC) or 86 (MIPS)",
        )
    n_param_blocks = phead[2]
    endian = ">" if processor == "mips" else "<"
    words = struct.unpack(endian + "12H", head[:24])
    n_points, n_analog = words[1], words[2]
    first, last = words[3], words[4]
    data_start = words[8]
    scale = _header_float(head[12:16], processor, endian)
    rate = _header_float(head[20:24], processor, endian)
    if n_param_blocks < 1:
        raise MotionFormatError(path, "bad C3D parameter block: it declares 0 parameter blocks")
    if size < at + n_param_blocks * _BLOCK:
        raise MotionFormatError(
            path,
            f"truncated C3D file: {size} bytes, the parameter "
            f"section needs {at + n_param_blocks * _BLOCK}",
        )
    if data_start < param_block + n_param_blocks:
        raise MotionFormatError(
            path,
            f"bad C3D header: data starts at block {data_start}, "
            f"inside the parameter section (blocks {param_block}.."
            f"{param_block + n_param_blocks - 1})",
        )
    if not np.isfinite(scale) or scale == 0:
        raise MotionFormatError(path, f"bad C3D header: point scale {scale}")
    return {
        "n_points": n_points,
        "n_analog": n_analog,
        "first": first,
        "last": last,
        "rate": rate,
        "processor": processor,
        "endian": endian,
        "param_block": param_block,
        "n_param_blocks": n_param_blocks,
        "data_start": data_start,
        "scale": scale,
    }


def _header_float(b: bytes, processor: str, endian: str) -> float:
    if processor == "dec":  # VAX F-float: swap 16-bit halves, exponent bias 2 higher
        value = struct.unpack("<f", b[2:4] + b[0:2])[0] / 4.0
    else:
        value = struct.unpack(endian + "f", b)[0]
    return float(value)


# --------------------------------------------------------------------------- parameters

_TYPE_SIZES = {-1: 1, 1: 1, 2: 2, 4: 4}


def _walk_parameters(path: Path, section: bytes, header: dict) -> dict[str, dict[str, tuple]]:
    """Walk the parameter section's linked entries with bounds checks.

    Returns ``{group name: {parameter name: (type, dims, raw bytes)}}``. Raises
    MotionFormatError at the first entry that does not fit the format.
    """
    endian = header["endian"]
    base = (header["param_block"] - 1) * _BLOCK  # file offset of the section, for messages
    end = len(section)
    groups: dict[int, str] = {}
    entries: list[tuple[int, str, int, tuple, bytes]] = []
    pos = 4

    def bad(at: int, what: str) -> MotionFormatError:
        return MotionFormatError(path, f"damaged C3D parameter section at byte {base + at}: {what}")

    while pos + 2 <= end:
        nchar = struct.unpack("b", section[pos : pos + 1])[0]
        gid = struct.unpack("b", section[pos + 1 : pos + 2])[0]
        if nchar == 0 or gid == 0:
            break  # end of the section
        name_end = pos + 2 + abs(nchar)
        if name_end + 2 > end:
            raise bad(pos, "entry runs past the end of the section")
        name_bytes = section[pos + 2 : name_end]
        if not all(32 < b < 127 for b in name_bytes):
            raise bad(pos, f"entry name {name_bytes!r} is not ASCII")
        name = name_bytes.decode("ascii").upper()
        offset = struct.unpack(endian + "h", section[name_end : name_end + 2])[0]
        body = name_end + 2
        nxt = name_end + offset if offset > 0 else end
        if offset < 0 or nxt > end:
            raise bad(pos, f"{name}: link to the next entry ({offset}) points outside the section")
        if offset > 0 and nxt <= body:
            raise bad(pos, f"{name}: link to the next entry ({offset}) does not move forward")
        if gid < 0:
            if body + 1 > nxt or body + 1 + section[body] > nxt:
                raise bad(pos, f"group {name}: description runs past the entry")
            groups[-gid] = name
        else:
            if body + 2 > nxt:
                raise bad(pos, f"parameter {name}: type and dimensions run past the entry")
            ptype = struct.unpack("b", section[body : body + 1])[0]
            if ptype not in _TYPE_SIZES:
                raise bad(pos, f"parameter {name}: type {ptype}, expected -1, 1, 2 or 4")
            ndims = section[body + 1]
            if ndims > 7 or body + 2 + ndims > nxt:
                raise bad(pos, f"parameter {name}: {ndims} dimensions do not fit the entry")
            dims = tuple(section[body + 2 : body + 2 + ndims])
            n_bytes = (
                _TYPE_SIZES[ptype] * int(np.prod(dims, dtype=np.int64))
                if dims
                else _TYPE_SIZES[ptype]
            )
            data_at = body + 2 + ndims
            desc_at = data_at + n_bytes
            if desc_at + 1 > nxt or desc_at + 1 + section[desc_at] > nxt:
                raise bad(
                    pos,
                    f"parameter {name}: {n_bytes} data bytes and the description "
                    "do not fit the entry",
                )
            entries.append((gid, name, ptype, dims, section[data_at : data_at + n_bytes]))
        if offset == 0:
            break
        pos = nxt
    out: dict[str, dict[str, tuple]] = {name: {} for name in groups.values()}
    for gid, name, ptype, dims, data in entries:
        if gid not in groups:
            raise MotionFormatError(
                path,
                f"damaged C3D parameter section: parameter {name} "
                f"belongs to group {gid}, which is not defined",
            )
        out[groups[gid]][name] = (ptype, dims, data)
    return out


def _int_param(params: dict, group: str, name: str, endian: str) -> int | None:
    entry = params.get(group, {}).get(name)
    if entry is None or entry[0] not in (1, 2) or not entry[2]:
        return None
    fmt = "B" if entry[0] == 1 else endian + "H"
    return int(struct.unpack(fmt, entry[2][: _TYPE_SIZES[entry[0]]])[0])


def _check_parameters(path: Path, params: dict, header: dict) -> None:
    """Cross-check the parameters that drive reading against the header."""
    if "POINT" not in params:
        raise MotionFormatError(path, "C3D file has no POINT parameter group")
    used = _int_param(params, "POINT", "USED", header["endian"])
    if used is None:
        raise MotionFormatError(path, "C3D file has no POINT:USED parameter")
    if used != header["n_points"]:
        raise MotionFormatError(
            path, f"C3D header says {header['n_points']} points but POINT:USED is {used}"
        )
    start = _int_param(params, "POINT", "DATA_START", header["endian"])
    if start is not None and start != header["data_start"]:
        raise MotionFormatError(
            path,
            f"C3D header says data starts at block "
            f"{header['data_start']} but POINT:DATA_START is {start}",
        )
    labels = params["POINT"].get("LABELS")
    if used and (labels is None or labels[0] != -1):
        raise MotionFormatError(path, "C3D POINT:LABELS is missing or not text")


class _ParamReader:
    """Typed access to the walked parameters (endianness and DEC floats handled)."""

    def __init__(self, params: dict, header: dict):
        self.params = params
        self.endian = header["endian"]
        self.processor = header["processor"]

    def _entry(self, group: str, name: str):
        return self.params.get(group, {}).get(name)

    def float(self, group: str, name: str, default: float) -> float:
        entry = self._entry(group, name)
        if entry is None or entry[0] != 4 or len(entry[2]) < 4:
            return default
        return _header_float(entry[2][:4], self.processor, self.endian)

    def uint32(self, group: str, name: str) -> int | None:
        """Two 16-bit words (low, high) as one number (TRIAL:ACTUAL_END_FIELD)."""
        entry = self._entry(group, name)
        if entry is None or entry[0] != 2 or len(entry[2]) < 4:
            return None
        lo, hi = struct.unpack(self.endian + "2H", entry[2][:4])
        return lo + (hi << 16)

    def text(self, group: str, name: str) -> str:
        entry = self._entry(group, name)
        if entry is None or entry[0] != -1:
            return ""
        return entry[2].decode("latin-1").strip().strip("\x00").strip()

    def strings(self, group: str, name: str) -> list[str] | None:
        entry = self._entry(group, name)
        if entry is None or entry[0] != -1:
            return None
        dims, data = entry[1], entry[2]
        if len(dims) < 2:
            return [data.decode("latin-1").strip()] if dims else []
        width = dims[0]
        count = len(data) // width if width else 0
        return [
            data[i * width : (i + 1) * width].decode("latin-1").replace("\x00", " ").strip()
            for i in range(count)
        ]

    def labels(self) -> list[str]:
        labels: list[str] = self.strings("POINT", "LABELS") or []
        for i in range(2, 100):
            more = self.strings("POINT", f"LABELS{i}")
            if more is None:
                break
            labels.extend(more)
        return labels
