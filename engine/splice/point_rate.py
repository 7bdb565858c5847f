"""A matching point's reach past its own cell: the warp near a point runs at the local rate.

A user's matching point pins one cell of each pass (``engine.dtw.constraints``); the
path through it is the cheapest path forced through that cell, and where the costs
prefer another route it reaches the pinned cell by a horizontal or vertical run right
beside it and leaves it the same way (a kink: hand frames held or skipped, then the old
route again). Real timing near a point is smooth: the hand take runs at about the
local rate on both sides of it. So near each point the warp is drawn toward the
straight line through the point at the warp's own mean rate around it, with a weight
that is 1 on the point's row and falls off as a Gaussian of :data:`REACH_S`; frames
farther off keep the passes' timing.

Measured on the accuracy bench's hard families (issue 17, ``benchmarks/
bench_uncertainty.py``): the share of frames off by more than the goal's p95 within
0.1-0.25 s of the top suggested point fell from 23 % to 12 % (about 38 % before any
point); the p95 of those families with the point placed, see RESULTS.md.
"""

from __future__ import annotations

import numpy as np

#: Gaussian σ (seconds) of the pull toward the point's rate line
REACH_S = 0.2
#: half-window (seconds) over which the warp's mean rate around a point is measured
RATE_S = 0.5


def rate_lines(
    warp: np.ndarray,
    rows,
    fps: float,
    matched: tuple[int, int] | None = None,
    reach_s: float = REACH_S,
    rate_s: float = RATE_S,
) -> np.ndarray:
    """``warp`` drawn toward each point's rate line near the point.

    Parameters
    ----------
    warp : (n,) float, grid columns per body frame (non-decreasing), already through
        the points (the row of each point holds its matched column)
    rows : body frames (ints) of the matching points
    fps : body frame rate (frames per second)
    matched : (first, last) body frame the path matches (open ends); rows outside
        hold the first / last matched column and are left as they are
    reach_s, rate_s : :data:`REACH_S`, :data:`RATE_S` (seconds)

    Returns a new (n,) non-decreasing array; each point's row keeps its value, and a
    point's pull stops at the neighbouring points (their rows keep theirs too).
    """
    w = np.asarray(warp, dtype=float).copy()
    n = len(w)
    kept = sorted({int(x) for x in rows if 0 <= int(x) < n})
    if n < 3 or not kept or reach_s <= 0:
        return w
    sigma = max(reach_s * float(fps), 1e-9)
    half = max(int(round(rate_s * float(fps))), 1)
    source = w.copy()
    out = w.copy()
    first, last = matched if matched is not None else (0, n - 1)
    bounds = [first - 1, *kept, last + 1]
    for k, x in enumerate(kept):
        if not first <= x <= last:
            continue
        a, b = max(first, x - half), min(last, x + half)
        rate = (source[b] - source[a]) / max(b - a, 1)
        lo = max(bounds[k] + 1, first)  # up to the neighbouring points
        hi = min(bounds[k + 2] - 1, last)
        i = np.arange(lo, hi + 1)
        line = source[x] + (i - x) * rate
        weight = np.exp(-0.5 * ((i - x) / sigma) ** 2)
        floor = source[bounds[k]] if k > 0 else source[first]
        ceiling = source[bounds[k + 2]] if k + 1 < len(kept) else source[last]
        out[lo : hi + 1] = np.clip(
            weight * line + (1.0 - weight) * out[lo : hi + 1], floor, ceiling
        )
    out[kept] = source[kept]
    return np.maximum.accumulate(out)
