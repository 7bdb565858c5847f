"""Helpers for the gesture tests: constructed paths (``engine.gesture.constructed``)
and transformed real takes."""

from __future__ import annotations

import numpy as np

from engine.gesture.constructed import REST, build, phrase_psh_r, smoothstep

__all__ = ["REST", "build", "phrase_psh_r", "smoothstep", "turned_and_scaled", "swapped_sides"]


def turned_and_scaled(motion, yaw_deg: float = 90.0, shift=(3.0, 0.0, -2.0), unit: str = "mm"):
    """The same take turned about the up axis, moved, and stored in other units.

    The body-relative analysis must not change (metres, pelvis yaw removed).
    """
    from dataclasses import replace

    from engine.model import rotations as rot
    from engine.model.motion import UNIT_TO_METERS, MotionMeta

    up = np.zeros(3)
    up[2 if motion.meta.up_axis == "z" else 1] = 1.0
    q = rot.from_axis_angle(up, np.radians(yaw_deg))
    factor = motion.meters_per_unit / UNIT_TO_METERS[unit]
    rots = motion.rotations.copy()
    rots[:, 0] = rot.multiply(q, rots[:, 0])
    trans = motion.translations * factor
    trans[:, 0] = rot.rotate(q, trans[:, 0]) + np.asarray(shift) / UNIT_TO_METERS[unit]
    sk = replace(
        motion.skeleton,
        offsets=motion.skeleton.offsets * factor,
        end_sites={j: v * factor for j, v in motion.skeleton.end_sites.items()},
    )
    meta = MotionMeta(
        units=unit,
        up_axis=motion.meta.up_axis,
        source=motion.meta.source,
        format=motion.meta.format,
    )
    return replace(motion, skeleton=sk, rotations=rots, translations=trans, meta=meta)


def swapped_sides(arms):
    """``BodyArms`` with right and left exchanged (a mirrored labelling)."""
    from dataclasses import replace

    return replace(
        arms,
        arms={
            "right": replace(arms.arms["left"], side="right"),
            "left": replace(arms.arms["right"], side="left"),
        },
    )
