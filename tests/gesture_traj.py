"""Constructed wrist paths with known gesture phases (shared by the gesture tests
and benchmarks/bench_handedness.py).

A script is a list of steps; each step moves the wrist (body frame, metres, y up)
with a smoothstep from where it is to a target, or holds it, and records the
phase it was built to be. Speeds and accelerations are those of real gestures
(0.5-2 m/s, strokes several times the preparation's acceleration).
"""

from __future__ import annotations

import numpy as np

from engine.gesture.phases import Phase

REST = np.array([0.0, -0.5, 0.05])  # wrist below the shoulder, arm hanging


def smoothstep(u: np.ndarray) -> np.ndarray:
    u = np.clip(u, 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


def build(script, fps: float = 60.0, start=REST) -> tuple[np.ndarray, np.ndarray]:
    """Positions (F, 3) and the phase labels (F,) a script was built with.

    Steps: ``("rest", seconds)``, ``("hold", seconds)``, and
    ``(phase, seconds, target)`` for phase in ``"prep"``, ``"stroke"``,
    ``"retract"`` (``target`` a 3-vector, or None for the rest position).
    """
    names = {"rest": Phase.REST, "hold": Phase.HOLD, "prep": Phase.PREPARATION,
             "stroke": Phase.STROKE, "retract": Phase.RETRACTION}
    pos = [np.asarray(start, dtype=float)]
    labels = []
    here = np.asarray(start, dtype=float)
    for step in script:
        kind, seconds = step[0], step[1]
        n = int(round(seconds * fps))
        if kind in ("rest", "hold"):
            pts = np.repeat(here[None], n, axis=0)
        else:
            target = REST if step[2] is None else np.asarray(step[2], dtype=float)
            u = smoothstep(np.arange(1, n + 1) / n)[:, None]
            pts = here + (target - here) * u
            here = target
        pos.extend(pts)
        labels.extend([names[kind]] * n)
    labels = [labels[0]] + labels
    return np.asarray(pos), np.asarray(labels, dtype=np.uint8)


def phrase_psh_r(space=(0.1, -0.1, 0.35), beat=(0.1, -0.3, 0.35)) -> list:
    """rest, preparation, two beat strokes, hold, retraction, rest."""
    return [("rest", 0.6), ("prep", 0.5, space), ("stroke", 0.2, beat), ("stroke", 0.2, space),
            ("hold", 0.5), ("retract", 0.6, None), ("rest", 0.6)]


def turned_and_scaled(motion, yaw_deg: float = 90.0, shift=(3.0, 0.0, -2.0), unit: str = "mm"):
    """The same take turned about the up axis, moved, and stored in other units.

    The body-relative analysis must not change (metres, pelvis yaw removed).
    """
    from dataclasses import replace

    from engine import rotations as rot
    from engine.motion import UNIT_TO_METERS, MotionMeta

    up = np.zeros(3)
    up[2 if motion.meta.up_axis == "z" else 1] = 1.0
    q = rot.from_axis_angle(up, np.radians(yaw_deg))
    factor = motion.meters_per_unit / UNIT_TO_METERS[unit]
    rots = motion.rotations.copy()
    rots[:, 0] = rot.multiply(q, rots[:, 0])
    trans = motion.translations * factor
    trans[:, 0] = rot.rotate(q, trans[:, 0]) + np.asarray(shift) / UNIT_TO_METERS[unit]
    sk = replace(motion.skeleton, offsets=motion.skeleton.offsets * factor,
                 end_sites={j: v * factor for j, v in motion.skeleton.end_sites.items()})
    meta = MotionMeta(units=unit, up_axis=motion.meta.up_axis, source=motion.meta.source,
                      format=motion.meta.format)
    return replace(motion, skeleton=sk, rotations=rots, translations=trans, meta=meta)


def swapped_sides(arms):
    """``BodyArms`` with right and left exchanged (a mirrored labelling)."""
    from dataclasses import replace

    return replace(arms, arms={"right": replace(arms.arms["left"], side="right"),
                               "left": replace(arms.arms["right"], side="left")})
