"""Readers and writers for capture files.

``load_take(path)`` reads any supported take by its extension:

- ``.bvh`` -> ``Motion`` (``engine.io.bvh.read_bvh``)
- ``.c3d`` -> ``MarkerSet`` (``engine.io.c3d.read_c3d``)
- ``.trc`` -> ``MarkerSet`` (``engine.io.trc.read_trc``)

Readers are imported on first use so importing ``engine.io`` stays light.
"""

from __future__ import annotations

from pathlib import Path

from engine.base.errors import MotionFormatError
from engine.model.motion import MarkerSet, Motion

EXTENSIONS = (".bvh", ".c3d", ".trc")


def take_format(path: str | Path) -> str:
    """``"bvh"``, ``"c3d"`` or ``"trc"`` from the file name (case-insensitive).

    Raises ``MotionFormatError`` for any other extension.
    """
    suffix = Path(path).suffix.lower()
    if suffix not in EXTENSIONS:
        shown = suffix or "no extension"
        raise MotionFormatError(path, f"unknown file type ({shown}): expected .bvh, .c3d or .trc")
    return suffix[1:]


def load_take(path: str | Path) -> Motion | MarkerSet:
    """Read a capture file: a BVH gives a ``Motion``, a C3D or TRC a ``MarkerSet``.

    Raises
    ------
    MotionFormatError
        Unknown extension, a directory, an empty file (``MotionFormatError.empty``), or
        a file that breaks its format (the message names the file and, for text
        formats, the line).
    FileNotFoundError
        The file does not exist (``str(err)`` names the path).
    """
    path = Path(path)
    kind = take_format(path)
    if not path.exists():
        raise FileNotFoundError(2, "no such file", str(path))
    if path.is_dir():
        raise MotionFormatError(path, "is a folder, expected a .bvh, .c3d or .trc file")
    if path.is_file() and path.stat().st_size == 0:  # one wording for every format
        raise MotionFormatError.empty(path)
    if kind == "bvh":
        from engine.io.bvh import read_bvh

        return read_bvh(path)
    if kind == "c3d":
        from engine.io.c3d import read_c3d

        return read_c3d(path)
    from engine.io.trc import read_trc

    return read_trc(path)
