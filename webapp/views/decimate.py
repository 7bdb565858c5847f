"""Polylines thinned to screen resolution, drawn the same (M4: first, min, max, last).

The matrix's band edges and paths have one vertex per body frame (or per path step):
72,000+ on a 10-minute take at 120 fps, on a plot 560 pixels wide. Sending them whole
costs megabytes per edit and draws nothing more. M4 (Jugel et al., "M4: a
visualization-oriented time series data aggregation", VLDB 2014) keeps, of the vertices
falling in one pixel column, the first, the last and those with the smallest and largest
value: the line drawn through them covers exactly the pixels the full line covers (a
line through many vertices within one column is a vertical run from its min to its max,
entered at the first and left at the last). A path that is monotone in both axes keeps
only its first and last vertex per column (its min and max), so at most two a column.

Columns follow the visible range: inside it ``columns`` per plot width (a zoomed-in view
gets every frame once a column is narrower than a frame), outside it the whole take's
resolution, so a pan shows a coarse line only until the view's own arrives.
"""

from __future__ import annotations

import numpy as np

#: columns per screen pixel (2: sharp on a display of device pixel ratio 2)
OVERSAMPLE = 2


def column_ids(
    x: np.ndarray, visible: tuple[float, float], extent: float, pixels: int
) -> np.ndarray:
    """``(N,)`` int64 screen column of each vertex; equal ids run in one column.

    ``x``: ``(N,)`` non-decreasing data x (frames); ``visible``: the plot's ``(x0, x1)``;
    ``extent``: the whole take's width in frames; ``pixels``: the plot's width in screen
    pixels. Columns are ``(x1 - x0) / (pixels · OVERSAMPLE)`` frames wide inside the view,
    ``extent / (pixels · OVERSAMPLE)`` outside it; ids of the three parts never collide.
    """
    x = np.asarray(x, dtype=np.float64)
    cols = max(int(pixels), 1) * OVERSAMPLE
    x0, x1 = float(min(visible)), float(max(visible))
    fine = max((x1 - x0) / cols, 1e-9)
    coarse = max(float(extent) / cols, fine)
    part = np.searchsorted([x0, x1], x, side="right")  # 0 left of the view, 1 in it, 2 right
    ids = np.where(part == 1, np.floor((x - x0) / fine), np.floor(x / coarse)).astype(np.int64)
    # the parts as the high digits: a column of one part never continues into another's
    span = int(ids.max() - ids.min()) + 1 if len(ids) else 1
    return part.astype(np.int64) * span + (ids - (ids.min() if len(ids) else 0))


def m4_indices(ids: np.ndarray, *values: np.ndarray) -> np.ndarray:
    """``(K,)`` sorted indices to keep: per run of equal ``ids``, its first and last vertex
    and, for each of ``values`` (``(N,)`` each), its smallest and largest one (NaN never
    chosen as an extreme)."""
    ids = np.asarray(ids)
    n = len(ids)
    if n <= 2:
        return np.arange(n)
    starts = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]])
    if len(starts) * 4 >= n:  # nothing to gain: every vertex goes
        return np.arange(n)
    ends = np.r_[starts[1:], n] - 1
    group = np.repeat(np.arange(len(starts)), np.diff(np.r_[starts, n]))
    keep = [starts, ends]
    for v in values:
        v = np.asarray(v, dtype=np.float64)
        for fill, reduce in ((np.inf, np.minimum), (-np.inf, np.maximum)):
            w = np.where(np.isnan(v), fill, v)
            extreme = reduce.reduceat(w, starts)
            hit = np.flatnonzero(w == extreme[group])
            first = np.r_[True, group[hit][1:] != group[hit][:-1]]
            keep.append(hit[first])
    return np.unique(np.concatenate(keep))


def thin(
    x: np.ndarray,
    ys: dict[str, np.ndarray],
    visible: tuple[float, float],
    extent: float,
    pixels: int,
) -> dict[str, np.ndarray]:
    """``{"x": x[k], **{name: y[k]}}`` for the kept vertices ``k`` of the polylines
    ``(x, y)`` that share ``x`` (see the module docstring); dtypes are kept."""
    x = np.asarray(x)
    keep = kept(x, list(ys.values()), visible, extent, pixels)
    return {"x": x[keep], **{k: np.asarray(v)[keep] for k, v in ys.items()}}


def kept(x, values: list, visible: tuple[float, float], extent: float, pixels: int):
    """``(K,)`` indices of the vertices :func:`thin` keeps."""
    return m4_indices(column_ids(x, visible, extent, pixels), *values)
