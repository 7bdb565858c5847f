"""Merging and smoothing (docs/method.md §5): a DTW path -> a monotone warp ``w(i)``.

The path may match one body frame ``i`` to several hand frames. The paper takes,
per body frame, the median position of each marker over those hand frames; for
joint rotations we take the **median hand frame index** (one time per body frame,
so every joint is sampled at the same instant and the hand pose stays a pose that
was captured). The medians are non-decreasing because the path is monotone.

Where ``w`` jumps (a run of body frames mapped to one hand frame, then a jump),
the jump is blended over a window: ``w`` is smoothed with a Gaussian of
``blend`` frames (standard deviation), which keeps it non-decreasing (the ends are
padded by point reflection, so a steady rate stays exactly steady up to the ends). The hand
take is then sampled at ``w(i)`` with slerp between the two nearest hand frames
(:func:`engine.model.kinematics.sample`), so rotations are blended along the arc.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d

from engine.base.errors import ParameterError

#: default blend window (Gaussian standard deviation, seconds): 3 body frames at 30 fps,
#: the rate it was chosen at (issue 5); a time, so that a 120 fps take is smoothed over
#: the same 0.1 s (12 frames) and not over a quarter of it (issue 13: the 2-minute
#: 120 fps pair's median timing error 1.22 -> 0.99 frames)
BLEND_S = 0.1
#: the blend in frames at 30 fps (callers that give frames explicitly)
BLEND_FRAMES = 3.0


def blend_frames(fps: float) -> float:
    """The default blend (Gaussian σ) in frames of a take at ``fps``: ``BLEND_S * fps``."""
    return BLEND_S * float(fps)


def median_warp(path: np.ndarray, n: int) -> np.ndarray:
    """Median matched column per row of ``path (k, 2)``: ``(n,)`` float, non-decreasing.

    The path visits a run of rows ``i0..i1`` (every row with fixed ends; an open-end
    path may start below row 0 or end above row ``n-1``). Rows before ``i0`` hold the
    first matched column and rows after ``i1`` the last one: no timing is invented
    outside the overlap, the hand pose holds (``smooth_warp`` eases into it).
    """
    path = np.asarray(path, dtype=np.int64).reshape(-1, 2)
    if len(path) == 0:
        raise ParameterError("merge: the path is empty")
    rows, cols = path[:, 0], path[:, 1]
    if rows.min() < 0 or rows.max() > n - 1 or np.any(np.diff(rows) < 0):
        raise ParameterError(f"merge: the path must visit rows within 0..{n - 1} in order")
    i0, i1 = int(rows[0]), int(rows[-1])
    if i0 > 0 or i1 < n - 1:
        inner = median_warp(path - np.array([i0, 0]), i1 - i0 + 1)
        return np.concatenate([np.full(i0, inner[0]), inner, np.full(n - 1 - i1, inner[-1])])
    # rows are sorted: each row's columns are a contiguous sorted run
    starts = np.searchsorted(rows, np.arange(n), side="left")
    stops = np.searchsorted(rows, np.arange(n), side="right")
    if np.any(stops <= starts):
        missing = int(np.flatnonzero(stops <= starts)[0])
        raise ParameterError(f"merge: the path skips body frame {missing}")
    lo = cols[starts]
    hi = cols[stops - 1]
    return 0.5 * (lo + hi).astype(float)  # median of a run of consecutive columns


def smooth_warp(warp: np.ndarray, blend: float = BLEND_FRAMES, m: int | None = None) -> np.ndarray:
    """Blend jumps of a non-decreasing warp over a Gaussian window of ``blend`` frames.

    The result stays non-decreasing and inside ``[0, m-1]`` when ``m`` is given.
    ``blend = 0`` returns the warp unchanged.
    """
    w = np.asarray(warp, dtype=float)
    if blend < 0 or not np.isfinite(blend):
        raise ParameterError(f"merge: blend must be >= 0 frames, got {blend}")
    if blend > 0 and len(w) > 1:
        # point reflection at both ends keeps straight stretches straight (no pull toward
        # the end values, which plain edge padding would add) and keeps w non-decreasing
        k = min(len(w) - 1, int(np.ceil(4 * blend)))
        head = 2 * w[0] - w[1 : k + 1][::-1]
        tail = 2 * w[-1] - w[-k - 1 : -1][::-1]
        padded = np.concatenate([head, w, tail])
        w = gaussian_filter1d(padded, blend, mode="nearest")[k : k + len(w)]
    w = np.maximum.accumulate(w)
    if m is not None:
        w = np.clip(w, 0.0, m - 1)
    return w


def merge_path(path: np.ndarray, n: int, m: int, blend: float = BLEND_FRAMES) -> np.ndarray:
    """The warp ``w (n,)``: hand frame (DTW grid units, float) for every body frame."""
    return smooth_warp(median_warp(path, n), blend, m)


def still_runs(
    speed: np.ndarray, threshold: float, min_frames: int, gap: int = 2
) -> list[tuple[int, int]]:
    """Runs ``[first, last]`` of at least ``min_frames`` frames with ``speed < threshold``
    (runs apart by at most ``gap`` moving frames, a noise blip, are joined)."""
    still = np.asarray(speed) < threshold
    moving = np.flatnonzero(~still)
    if moving.size:  # fill short interruptions between still frames
        edges = np.diff(np.concatenate([[0], (~still).astype(np.int8), [0]]))
        for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True):
            if b - a <= gap and a > 0 and b < still.size:
                still[a:b] = True
    edges = np.diff(np.concatenate([[0], still.astype(np.int8), [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return [(int(a), int(b) - 1) for a, b in zip(starts, stops, strict=True) if b - a >= min_frames]


def straighten_holds(warp: np.ndarray, body_holds, hand_holds, slack: float, keep=()) -> np.ndarray:
    """The warp made linear across holds matched to holds (METHOD: holds).

    In a hold both takes are still, every cell of the rectangle costs the same and the
    DTW path inside it is arbitrary (diagonal, then a vertical or horizontal run): the
    timing inside and the exit from the hold are left to chance. Where a body hold
    ``[b0, b1]`` is matched to a hand hold ``[h0, h1]`` (the warp enters within
    ``slack`` frames of ``h0`` and leaves within ``slack`` of ``h1``), the hold
    boundaries are matched to each other and the warp runs straight between them.
    ``warp (n,)`` grid columns per body frame (unsmoothed); returns a new array.
    ``keep``: body frames (the user's matching points) whose matched column stays as it
    is: the straight run bends there (a point inside a hold is met, not overridden).
    """
    kept = sorted({int(k) for k in keep})
    w = np.asarray(warp, dtype=float).copy()
    for b0, b1 in body_holds:
        if b1 <= b0:
            continue
        for h0, h1 in hand_holds:
            if abs(w[b0] - h0) <= slack and abs(w[b1] - h1) <= slack and h1 > h0:
                inside = [k for k in kept if b0 < k < b1]
                knots = [b0, *inside, b1]
                cols = [float(h0), *(w[k] for k in inside), float(h1)]
                w[b0 : b1 + 1] = np.interp(np.arange(b0, b1 + 1), knots, cols)
                break
    return np.maximum.accumulate(w)


def grid_to_hand_frames(
    warp: np.ndarray, body_fps: float, hand_fps: float, hand_frames: int
) -> np.ndarray:
    """Grid columns (hand resampled to the body's rate) -> frames of the original hand take."""
    t = np.asarray(warp, dtype=float) * (hand_fps / body_fps)
    return np.clip(t, 0.0, hand_frames - 1)


def hand_frames_to_grid(frames: np.ndarray, body_fps: float, hand_fps: float) -> np.ndarray:
    """Frames of the original hand take -> grid columns (float)."""
    return np.asarray(frames, dtype=float) * (body_fps / hand_fps)
