"""Pass 2 of a pair whose hand take has no forearm: the hand's turning (issue 12).

:func:`engine.splice.pipeline.align_passes` calls :func:`spin_pass_rows` when
:func:`engine.splice.pipeline.hand_lacks_forearm`: D2 (the hand relative to the forearm)
is constant for such a take, so pass 2 compares the hand's angular velocity relative to
the trunk's heading, in the hand's own frame (:mod:`engine.align.hand_spin`).

That signal needs no θ and no heading, so pass 2 searches the whole pass-1 band (with the
same matching points and ends), not only a strip around the pass-1 path: pass 1's sign
costs, which need θ per cell, can lock onto a wrong cycle where the body take spins (a
dancer) and its hand take does not, and a strip around that path could not recover.
"""

from __future__ import annotations

import numpy as np

from engine.align.hand_spin import METRIC, spin_rows, take_spins
from engine.model.kinematics import forward_kinematics
from engine.model.motion import Motion

__all__ = ["METRIC", "spin_pass_rows", "spin_available"]


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
    rows = (spin_rows(b), spin_rows(h))
    features.params["_spin_rows"] = rows
    return rows


def _pad(x: np.ndarray, m: int) -> np.ndarray:
    return np.concatenate([x, np.repeat(x[-1:], m - len(x), axis=0)])
