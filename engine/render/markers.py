"""A picture of a marker take (C3D/TRC) at one frame: dots seen from the front.

Marker takes have no skeleton, so no mannequin: the preview draws their markers,
y up, in a frame fixed over the whole take (so motion reads as motion), with the
markers the alignment uses highlighted. Pure numpy + Pillow, no OpenGL.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from engine.align.features import to_y_up
from engine.model.motion import MarkerSet

BACKGROUND = (246, 247, 249)
DOT = (120, 128, 140)
HIGHLIGHT = (230, 110, 20)


def marker_image(
    markers: MarkerSet,
    frame: int,
    size: tuple[int, int] = (320, 360),
    highlight=(),
    label: str | None = None,
) -> np.ndarray:
    """``(H, W, 3) uint8``: the markers of ``frame`` seen from the front (x right, y up).

    ``highlight``: marker indices drawn larger and in orange (the arm the alignment
    uses). ``label``: a caption (default: the file name).
    """
    from PIL import Image, ImageDraw

    w, h = int(size[0]), int(size[1])
    pts = to_y_up(markers.points * markers.meters_per_unit, markers.meta.up_axis)
    i = int(np.clip(frame, 0, markers.n_frames - 1))
    finite = pts[np.isfinite(pts).all(axis=-1)]
    if finite.size:
        lo = np.percentile(finite, 1, axis=0)
        hi = np.percentile(finite, 99, axis=0)
    else:
        lo, hi = np.zeros(3), np.ones(3)
    span = max(float(hi[0] - lo[0]), float(hi[1] - lo[1]), 1e-6)
    margin = 28
    scale = min(w - 2 * margin, h - 2 * margin - 16) / span
    cx, cy = 0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])
    img = Image.new("RGB", (w, h), BACKGROUND)
    draw = ImageDraw.Draw(img)
    marked = set(int(k) for k in highlight)
    order = sorted(range(len(markers.labels)), key=lambda k: k in marked)
    for k in order:
        p = pts[i, k]
        if not np.isfinite(p).all():
            continue
        x = w / 2 + (p[0] - cx) * scale
        y = (h + 16) / 2 - (p[1] - cy) * scale
        r, color = (4, HIGHLIGHT) if k in marked else (2.5, DOT)
        draw.ellipse((x - r, y - r, x + r, y + r), fill=color)
    caption = label if label is not None else (Path(markers.meta.source).name or "markers")
    draw.text((8, 6), f"{caption} - markers, frame {i}", fill=(30, 30, 30))
    return np.asarray(img, dtype=np.uint8)
