"""Arm joints of a take in a body frame, in metres (shared by phases, handedness,
key poses and synthesis).

Body frame, per frame: origin at the pelvis (or a shoulder), axes
``x`` = toward the body's left, ``y`` = up, ``z`` = forward (right-handed). The
heading is the pelvis's yaw: the pelvis's world rotation applied to the rest
pose's right-to-left shoulder line, projected on the ground plane. Removing it
and the root translation leaves the arm's motion relative to the body, so
walking and turning do not look like gestures (Jin & Hahn §4, docs/method.md §7-8).

Units: ``Motion.meters_per_unit`` when the file's units are known; otherwise the
scale that makes the rest arm (shoulder to wrist) 0.55 m long.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from engine.base.errors import RoleError
from engine.model import rotations as rot
from engine.model.motion import Motion, Skeleton

SIDES = ("right", "left")
FINGERS = ("thumb", "index", "middle", "ring", "pinky")
ARM_LENGTH_M = 0.55  # shoulder to wrist, adult, used only when a file's units are unknown
HAND_PER_FOREARM = 0.75  # hand length (wrist to fingertip) over forearm length


@dataclass(frozen=True)
class ArmJoints:
    """Joint indices of one arm.

    ``hand`` is the joint orienting the palm (the wrist in most rigs);
    ``fingers[f]`` lists finger ``f``'s joints palm out and ``numbers[f]`` their
    anatomical numbers (1 = MCP / thumb CMC, 2 = PIP / MCP, 3 = DIP / IP);
    ``tip`` is ``(joint, offset in its rest frame)`` of the hand tip.
    """

    side: str
    shoulder: int
    elbow: int
    wrist: int
    hand: int | None = None
    fingers: dict[str, tuple[int, ...]] = field(default_factory=dict)
    numbers: dict[str, tuple[int, ...]] = field(default_factory=dict)
    tip: tuple[int, np.ndarray] | None = None

    @property
    def has_fingers(self) -> bool:
        return any(len(v) for v in self.fingers.values())


@dataclass(frozen=True)
class BodyArms:
    """The arms of a skeleton and its pelvis (the heading reference)."""

    arms: dict[str, ArmJoints]
    pelvis: int


def _pelvis_index(skeleton: Skeleton) -> int:
    """The first joint from the root that branches (legs and spine), else the root."""
    for j in range(skeleton.n_joints):
        if len(skeleton.children(j)) >= 2:
            return j
    return 0


def arms_from_roles(roles, sides=SIDES) -> BodyArms:
    """``BodyArms`` from ``engine.model.roles.Roles``; ``RoleError`` names a missing joint."""
    sk = roles.skeleton
    arms = {}
    for side in sides:
        part = roles.side(side)
        wrist = roles.require(side, "wrist")
        shoulder = roles.require(side, "shoulder")
        elbow = roles.require(side, "elbow")
        fingers = {f: tuple(int(j) for j in part.fingers[f]) for f in FINGERS}
        numbers = {f: tuple(int(k) for k in part.numbers[f]) for f in FINGERS}
        tip = None
        if not any(fingers.values()):
            mark = roles.landmarks(side).get("hand")
            if mark is not None:
                tip = (int(mark.joint), np.asarray(mark.offset, dtype=float))
        arms[side] = ArmJoints(
            side,
            int(shoulder),
            int(elbow),
            int(wrist),
            None if part.hand is None else int(part.hand),
            fingers,
            numbers,
            tip,
        )
    return BodyArms(arms, _pelvis_index(sk))


def find_arms(skeleton: Skeleton, overrides=None) -> BodyArms:
    """Both arms of a full-body skeleton, from ``engine.model.roles.find_roles``.

    Raises ``RoleError`` (naming the nearest joint names) when an arm joint is missing.
    """
    from engine.model.roles import find_roles

    return arms_from_roles(find_roles(skeleton, overrides))


def metres_per_unit(motion: Motion, arms: BodyArms) -> float:
    """Metres per file unit (see module docstring)."""
    if motion.meta.units in ("m", "dm", "cm", "mm", "in"):
        return motion.meters_per_unit
    from engine.model.kinematics import rest_positions

    rest = rest_positions(motion.skeleton)
    arm = arms.arms["right"]
    length = np.linalg.norm(rest[arm.elbow] - rest[arm.shoulder]) + np.linalg.norm(
        rest[arm.wrist] - rest[arm.elbow]
    )
    return ARM_LENGTH_M / length if length > 0 else 1.0


@dataclass(frozen=True)
class ArmPaths:
    """Arm points of a take in the body frame.

    Attributes
    ----------
    points : dict side -> (F, 4, 3) float, metres
        Shoulder, elbow, wrist and hand tip, relative to the pelvis (body frame).
    scale : float, metres per file unit
    fps : float
    """

    points: dict[str, np.ndarray]
    scale: float
    fps: float

    def wrist(self, side: str, reference: str = "shoulder") -> np.ndarray:
        """(F, 3) wrist path relative to the same-side shoulder or the pelvis."""
        p = self.points[side]
        return p[:, 2] - p[:, 0] if reference == "shoulder" else p[:, 2].copy()


def _tip_local(skeleton: Skeleton, arm: ArmJoints, rest: np.ndarray) -> tuple[int, np.ndarray]:
    """Joint and local offset (its rest frame) of the hand tip: the middle (else index)
    finger's last joint continued by its End Site length along the last bone; else
    the roles' hand landmark; else 0.75 forearm lengths beyond the wrist."""
    chain = arm.fingers.get("middle") or arm.fingers.get("index") or ()
    if chain:
        last = chain[-1]
        bone = rest[last] - rest[skeleton.parents[last]]
        site = skeleton.end_sites.get(last)
        if site is not None and np.linalg.norm(bone) > 0:
            # End Sites are often placeholders: keep their length, not their direction
            length = min(float(np.linalg.norm(site)), float(np.linalg.norm(bone)))
            return last, bone / np.linalg.norm(bone) * length
        return last, np.zeros(3)
    if arm.tip is not None:
        return arm.tip
    return arm.wrist, (rest[arm.wrist] - rest[arm.elbow]) * HAND_PER_FOREARM


def arm_paths(motion: Motion, arms: BodyArms | None = None) -> ArmPaths:
    """Shoulder, elbow, wrist and hand tip of both arms in the body frame, metres.

    Parameters
    ----------
    motion : Motion, a full-body take
    arms : BodyArms, found with ``find_arms`` when omitted

    Returns
    -------
    ArmPaths
    """
    from engine.model.kinematics import forward_kinematics, rest_positions

    arms = arms or find_arms(motion.skeleton)
    sk = motion.skeleton
    if motion.n_frames == 0:
        raise RoleError(f"{motion.meta.source or 'take'}: no frames to analyse")
    pos, wrot = forward_kinematics(motion)
    rest = rest_positions(sk)
    scale = metres_per_unit(motion, arms)
    up = 2 if motion.meta.up_axis == "z" else 1
    up_vec = np.zeros(3)
    up_vec[up] = 1.0

    lr = rest[arms.arms["left"].shoulder] - rest[arms.arms["right"].shoulder]
    left = rot.rotate(wrot[:, arms.pelvis], lr)
    left -= left[:, up : up + 1] * up_vec  # onto the ground plane
    norm = np.linalg.norm(left, axis=1, keepdims=True)
    # degenerate (pelvis pitched 90 degrees): fall back to the current shoulder line
    bad = norm[:, 0] < 1e-9 * max(np.linalg.norm(lr), 1e-12)
    if bad.any():
        cur = pos[bad][:, arms.arms["left"].shoulder] - pos[bad][:, arms.arms["right"].shoulder]
        cur -= cur[:, up : up + 1] * up_vec
        left[bad] = cur
        norm = np.linalg.norm(left, axis=1, keepdims=True)
    left = left / np.where(norm > 0, norm, 1.0)
    forward = np.cross(left, up_vec)
    basis = np.stack([left, np.broadcast_to(up_vec, left.shape), forward], axis=1)  # (F, 3, 3)

    origin = pos[:, arms.pelvis]
    points = {}
    for side, arm in arms.arms.items():
        tip_joint, tip_off = _tip_local(sk, arm, rest)
        tip = pos[:, tip_joint] + rot.rotate(wrot[:, tip_joint], tip_off)
        world = np.stack([pos[:, arm.shoulder], pos[:, arm.elbow], pos[:, arm.wrist], tip], axis=1)
        rel = world - origin[:, None]
        points[side] = np.einsum("fij,fkj->fki", basis, rel) * scale
    return ArmPaths(points=points, scale=float(scale), fps=float(motion.fps))
