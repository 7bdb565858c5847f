"""What a marker body (C3D/TRC) and a skeletal hand give: the hand take retimed.

A marker take has no skeleton to receive fingers, so no spliced take exists for it.
What the alignment does give is the hand take played in the body's time: hand frame
``map[i]`` at body frame ``i`` (rotations slerped, translations interpolated), one
frame per body frame at the body's frame rate. Loaded beside the markers in an
animation tool, its fingers move with the body's arm.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from engine.base.errors import HandSpliceError
from engine.model import kinematics
from engine.model.motion import Motion


def retimed_hand(hand: Motion, hand_frames: np.ndarray, fps: float) -> Motion:
    """``hand`` sampled at fractional frames ``hand_frames`` (n,) of its own numbering;
    the result has ``n`` frames at ``fps`` (the body take's rate)."""
    if not isinstance(hand, Motion):
        name = Path(getattr(hand.meta, "source", "") or "the hand take").name
        raise HandSpliceError(
            f"{name}: holds markers; a marker take has no finger rotations "
            "to give: the hand take must be a skeletal take (.bvh)"
        )
    frames = np.asarray(hand_frames, dtype=float)
    rotations, translations = kinematics.sample(hand, frames)
    source = Path(hand.meta.source).name if hand.meta.source else "hand take"
    return Motion(
        hand.skeleton,
        rotations,
        translations,
        float(fps),
        replace(hand.meta, source=f"{source} retimed to the body", format="derived"),
    )


def splice_takes(body, hand, **options):
    """``engine.splice.pipeline.splice`` of any pair the fronts accept: a skeletal body
    gets the hand take's wrist and fingers; a marker body (C3D/TRC) has no skeleton to
    receive them, so ``result.motion`` is then the hand take retimed to it
    (:func:`retimed_hand`). One rule for ``handsplice splice`` and ``handsplice batch``
    (the app's backend does the same per edit). Returns ``(result, retimed)``;
    ``HandSpliceError`` for a marker hand (no finger rotations to give)."""
    from engine.splice import pipeline

    retimed = pipeline.marker_body(body)
    pipeline.require_skeletal(body, hand, marker_body_ok=True)
    result = pipeline.splice(body, hand, transfer_fingers=not retimed, **options)
    if retimed:
        result.motion = retimed_hand(hand, result.alignment.map, result.features.fps)
    return result, retimed
