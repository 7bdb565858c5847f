"""Pass 2 of a pair whose hand take has no forearm: the hand's turning (issue 12).

:func:`engine.splice.pipeline.align_passes` calls :func:`spin_pass_rows` when
:func:`engine.splice.pipeline.hand_lacks_forearm`: D2 (the hand relative to the forearm)
is constant for such a take, so pass 2 compares the hand's angular velocity relative to
the trunk's heading, in the hand's own frame (:mod:`engine.align.hand_spin`).

That signal needs no θ and no heading, so pass 2 searches the whole pass-1 band (with the
same matching points and ends), not only a strip around the pass-1 path: pass 1's sign
costs, which need θ per cell, can lock onto a wrong cycle where the body take spins (a
dancer) and its hand take does not, and a strip around that path could not recover.

The first and last :data:`EDGE_TAPER_S` of each take's rows are tapered to zero
(:func:`taper_edges`): the angular velocity there comes from a one-sided fit (the
Savitzky-Golay window runs off the take) and its noise is amplified, so before the
taper a corner cell cost several times a matched one, and the path cut 2-12 frames
off the start and end of co-extensive takes (issue 17: the maps of the forearm-less
rigs started ~50 ms late and ended 50-75 ms early on average).
"""

from __future__ import annotations

import numpy as np

from engine.align.hand_spin import METRIC, WINDOW_S, spin_rows, take_spins
from engine.model.kinematics import forward_kinematics
from engine.model.motion import Motion

__all__ = ["METRIC", "EDGE_TAPER_S", "spin_pass_rows", "spin_available", "taper_edges"]

#: seconds at each end of a take over which the spin rows are tapered to zero: the
#: angular velocity's Savitzky-Golay window (the reach of its one-sided fit at an end)
EDGE_TAPER_S = WINDOW_S


def spin_available(features) -> bool:
    """Both takes skeletal, with the hand frames of every spliced side."""
    return (
        isinstance(features.body, Motion)
        and isinstance(features.hand, Motion)
        and features.body_fk is not None
        and all(s in features.body_frames and s in features.hand_frames for s in features.sides)
    )


def spin_pass_rows(features) -> tuple[np.ndarray, np.ndarray]:
    """``(body (n, 3A), hand (m, 3A))`` rows of the spin signal, hand on the alignment
    grid; cached on ``features.params`` (they depend on the pair only)."""
    cache = features.params.get("_spin_rows")
    if cache is not None:
        return cache
    body, hand = features.body, features.hand
    sides = features.sides
    b = take_spins(
        features.body_fk[1],
        features.body_frames,
        sides,
        features.fps,
        body.meta.up_axis,
        features.body_phase.yaw,
    )
    hand_yaw = None
    if features.hand_has_yaw and features.hand_phase.yaw is not None:
        # the hand take's heading is on the grid: back to the hand's own frame times
        grid_t = np.arange(features.m) / features.fps
        hand_yaw = np.interp(np.arange(hand.n_frames) / hand.fps, grid_t, features.hand_phase.yaw)
    _, wrot = forward_kinematics(hand)
    h = take_spins(
        wrot,
        features.hand_frames,
        sides,
        float(hand.fps),
        hand.meta.up_axis,
        hand_yaw,
        target_fps=features.fps,
    )
    h = [x[: features.m] if len(x) >= features.m else _pad(x, features.m) for x in h]
    rows = (
        taper_edges(spin_rows(b), features.fps, EDGE_TAPER_S),
        taper_edges(spin_rows(h), features.fps, EDGE_TAPER_S),
    )
    features.params["_spin_rows"] = rows
    return rows


def taper_edges(rows: np.ndarray, fps: float, seconds: float) -> np.ndarray:
    """``rows (F, C)`` with the first and last ``seconds`` scaled by a linear ramp from
    0 at the take's end frame to 1 inside (a new array; at least one frame is tapered,
    at most a third of the take at each end; none when ``seconds <= 0``).

    Both takes' ends then cost little against each other, and nothing against a still
    stretch, so an end is not cut for its edge noise; a true unmatched end (one take
    starting earlier) stays one: beyond the ramp its frames cost what they did."""
    rows = np.asarray(rows, dtype=np.float64)
    f = len(rows)
    k = min(max(1, int(round(seconds * fps))), f // 3)
    if seconds <= 0 or k < 1:
        return rows.copy()
    ramp = np.ones(f)
    edge = np.arange(k) / k
    ramp[:k] = edge
    ramp[f - k :] = np.minimum(ramp[f - k :], edge[::-1])
    return np.ascontiguousarray(rows * ramp[:, None])


def _pad(x: np.ndarray, m: int) -> np.ndarray:
    return np.concatenate([x, np.repeat(x[-1:], m - len(x), axis=0)])
