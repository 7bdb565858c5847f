"""C3D reader: labelled 3-D marker trajectories into a ``MarkerSet``.

Reading goes through ezc3d, but only after this module has checked the file's
header itself: ezc3d reads a truncated file silently (fewer frames) and may
misbehave on garbage, so the header's key byte, parameter block, processor type,
frame range, frame rate and the promised data size are validated first.

What is read
------------
- labels: ``POINT:LABELS`` (and ``LABELS2``, ``LABELS3``... beyond 255 markers),
  stripped, as the file spells them (e.g. ``"Daphnee:ASISr"``);
- points: (frames, markers, 3) in the file's units; a sample whose residual is
  negative (the C3D convention for "not seen") is NaN;
- fps: ``POINT:RATE`` (the header's rate when the parameter is absent);
- units: ``POINT:UNITS`` (``"mm"``, ``"cm"``, ``"m"``, ``"in"``; anything else
  gives ``"unknown"``);
- up axis: from ``POINT:Y_SCREEN`` (the axis shown upwards; ``"+Z"`` -> ``"z"``),
  ``"z"`` when absent (the usual lab convention for C3D).
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from engine.errors import MotionFormatError
from engine.motion import MarkerSet, MotionMeta

_BLOCK = 512
_PROCESSORS = {84: "intel", 85: "dec", 86: "mips"}
_UNITS = {"mm": "mm", "millimeters": "mm", "millimetres": "mm", "cm": "cm", "m": "m",
          "meters": "m", "metres": "m", "in": "in", "inch": "in", "inches": "in"}


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
        The file is not a C3D file, its header is inconsistent, it is shorter than
        its header promises (truncated), or ezc3d cannot parse it.
    FileNotFoundError
        ``path`` does not exist.
    """
    path = Path(path)
    raw_size = path.stat().st_size  # FileNotFoundError names the file
    with open(path, "rb") as fh:
        head = fh.read(_BLOCK)
        header = _check_header(path, head, raw_size, fh)
        fh.seek((header["param_block"] - 1) * _BLOCK)
        section = fh.read(header["n_param_blocks"] * _BLOCK)
    # ezc3d can crash or hang on a damaged parameter section: walk it here first
    params = _walk_parameters(path, section, header)
    _check_parameters(path, params, header)

    try:
        import ezc3d

        c3d = ezc3d.c3d(str(path))
    except Exception as exc:  # ezc3d raises OSError/RuntimeError with iostream text
        raise MotionFormatError(path, f"not a readable C3D file ({_first_line(exc)})") from None

    params = c3d["parameters"]
    point = params.get("POINT", {})
    labels = _labels(point)
    data = np.asarray(c3d["data"]["points"], dtype=float)  # (4, M, F)
    if data.ndim != 3 or data.shape[0] < 3:
        raise MotionFormatError(path, f"unexpected point data shape {data.shape}")
    n_markers = data.shape[1]
    if len(labels) < n_markers:  # unlabelled points get a generated name
        labels += [f"M{i + 1:03d}" for i in range(len(labels), n_markers)]
    labels = labels[:n_markers]
    points = np.ascontiguousarray(np.transpose(data[:3], (2, 1, 0)))  # (F, M, 3)
    residuals = c3d["data"].get("meta_points", {}).get("residuals")
    if residuals is not None:
        res = np.asarray(residuals, dtype=float)
        if res.ndim == 3 and res.shape[1:] == data.shape[1:]:
            points[np.transpose(res[0]) < 0] = np.nan

    rate = _param_value(point, "RATE")
    fps = float(rate[0]) if rate is not None and len(rate) else header["rate"]
    if not (np.isfinite(fps) and fps > 0):
        raise MotionFormatError(path, f"POINT:RATE must be a positive number, got {fps}")
    units = _units(_param_value(point, "UNITS"))
    up_axis = _up_axis(_param_value(point, "Y_SCREEN"))
    meta = MotionMeta(units=units, up_axis=up_axis, source=str(path), format="c3d")
    return MarkerSet(labels=tuple(labels), points=points, fps=fps, meta=meta)


# --------------------------------------------------------------------------- header


def _check_header(path: Path, head: bytes, size: int, fh) -> dict:
    """Validate the 512-byte header and the promised file size; return key numbers."""
    if len(head) < _BLOCK:
        raise MotionFormatError(path, f"not a C3D file: {size} bytes, shorter than the "
                                      f"{_BLOCK}-byte header")
    if head[1] != 0x50:
        raise MotionFormatError(path, f"not a C3D file: header byte 2 is 0x{head[1]:02x}, "
                                      "expected 0x50")
    param_block = head[0]
    if param_block < 2:
        raise MotionFormatError(path, f"bad C3D header: parameter block {param_block}, "
                                      "expected 2 or more")
    fh.seek((param_block - 1) * _BLOCK)
    phead = fh.read(4)
    if len(phead) < 4:
        raise MotionFormatError(path, f"truncated C3D file: parameter block {param_block} "
                                      f"lies beyond the end ({size} bytes)")
    processor = _PROCESSORS.get(phead[3])
    if processor is None:
        raise MotionFormatError(path, f"bad C3D parameter block: processor type {phead[3]}, "
                                      "expected 84 (Intel), 85 (DEC) or 86 (MIPS)")
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
    if data_start < param_block + n_param_blocks:
        raise MotionFormatError(path, f"bad C3D header: data starts at block {data_start}, "
                                      f"inside the parameter section (blocks {param_block}.."
                                      f"{param_block + n_param_blocks - 1})")
    if size < (param_block - 1 + n_param_blocks) * _BLOCK:
        raise MotionFormatError(path, f"truncated C3D file: {size} bytes, the parameter "
                                      f"section needs {(param_block - 1 + n_param_blocks) * _BLOCK}")
    if last >= first and last != 0xFFFF:  # 65535 means "see POINT:FRAMES"
        n_frames = last - first + 1
        value_bytes = 4 if scale < 0 else 2
        per_frame = (n_points * 4 + n_analog) * value_bytes
        needed = (data_start - 1) * _BLOCK + n_frames * per_frame
        if size < needed:
            have = max(0, (size - (data_start - 1) * _BLOCK) // per_frame) if per_frame else 0
            raise MotionFormatError(
                path, f"truncated C3D file (or damaged header): header promises {n_frames} frames "
                      f"({needed} bytes), "
                      f"file has {size} bytes (about {have} frames)")
    return {"n_points": n_points, "n_analog": n_analog, "rate": rate, "processor": processor,
            "endian": endian, "param_block": param_block, "n_param_blocks": n_param_blocks,
            "data_start": data_start, "scale": scale}


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
        nchar = struct.unpack("b", section[pos:pos + 1])[0]
        gid = struct.unpack("b", section[pos + 1:pos + 2])[0]
        if nchar == 0 or gid == 0:
            break  # end of the section
        name_end = pos + 2 + abs(nchar)
        if name_end + 2 > end:
            raise bad(pos, "entry runs past the end of the section")
        name_bytes = section[pos + 2:name_end]
        if not all(32 < b < 127 for b in name_bytes):
            raise bad(pos, f"entry name {name_bytes!r} is not ASCII")
        name = name_bytes.decode("ascii").upper()
        offset = struct.unpack(endian + "h", section[name_end:name_end + 2])[0]
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
            ptype = struct.unpack("b", section[body:body + 1])[0]
            if ptype not in _TYPE_SIZES:
                raise bad(pos, f"parameter {name}: type {ptype}, expected -1, 1, 2 or 4")
            ndims = section[body + 1]
            if ndims > 7 or body + 2 + ndims > nxt:
                raise bad(pos, f"parameter {name}: {ndims} dimensions do not fit the entry")
            dims = tuple(section[body + 2:body + 2 + ndims])
            n_bytes = _TYPE_SIZES[ptype] * int(np.prod(dims, dtype=np.int64)) if dims else \
                _TYPE_SIZES[ptype]
            data_at = body + 2 + ndims
            desc_at = data_at + n_bytes
            if desc_at + 1 > nxt or desc_at + 1 + section[desc_at] > nxt:
                raise bad(pos, f"parameter {name}: {n_bytes} data bytes and the description "
                               "do not fit the entry")
            entries.append((gid, name, ptype, dims, section[data_at:data_at + n_bytes]))
        if offset == 0:
            break
        pos = nxt
    out: dict[str, dict[str, tuple]] = {name: {} for name in groups.values()}
    for gid, name, ptype, dims, data in entries:
        if gid not in groups:
            raise MotionFormatError(path, f"damaged C3D parameter section: parameter {name} "
                                          f"belongs to group {gid}, which is not defined")
        out[groups[gid]][name] = (ptype, dims, data)
    return out


def _int_param(params: dict, group: str, name: str, endian: str) -> int | None:
    entry = params.get(group, {}).get(name)
    if entry is None or entry[0] not in (1, 2) or not entry[2]:
        return None
    fmt = "B" if entry[0] == 1 else endian + "H"
    return int(struct.unpack(fmt, entry[2][:_TYPE_SIZES[entry[0]]])[0])


def _check_parameters(path: Path, params: dict, header: dict) -> None:
    """Cross-check the parameters that drive reading against the header."""
    if "POINT" not in params:
        raise MotionFormatError(path, "C3D file has no POINT parameter group")
    used = _int_param(params, "POINT", "USED", header["endian"])
    if used is None:
        raise MotionFormatError(path, "C3D file has no POINT:USED parameter")
    if used != header["n_points"]:
        raise MotionFormatError(path, f"C3D header says {header['n_points']} points but "
                                      f"POINT:USED is {used}")
    start = _int_param(params, "POINT", "DATA_START", header["endian"])
    if start is not None and start != header["data_start"]:
        raise MotionFormatError(path, f"C3D header says data starts at block "
                                      f"{header['data_start']} but POINT:DATA_START is {start}")
    labels = params["POINT"].get("LABELS")
    if used and (labels is None or labels[0] != -1):
        raise MotionFormatError(path, "C3D POINT:LABELS is missing or not text")



def _param_value(group: dict, name: str):
    entry = group.get(name)
    if not isinstance(entry, dict):
        return None
    return entry.get("value")


def _labels(point: dict) -> list[str]:
    labels: list[str] = []
    for key in ["LABELS"] + [f"LABELS{i}" for i in range(2, 100)]:
        value = _param_value(point, key)
        if value is None:
            if key != "LABELS":
                break
            continue
        labels.extend(str(v).strip() for v in value)
    return labels


def _units(value) -> str:
    if value is None or not len(value):
        return "unknown"
    return _UNITS.get(str(value[0]).strip().lower(), "unknown")


def _up_axis(value) -> str:
    if value is None or not len(value):
        return "z"
    text = str(value[0]).strip().lower().lstrip("+-")
    return text if text in ("y", "z") else "z"  # MotionMeta knows y-up and z-up only


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__
