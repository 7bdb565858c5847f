"""Split pairs whose hand take comes from another rig (issue 12 item 4's bench families).

Built like :func:`benchmarks.split.make_case` (a full take with fingers, split into a
body take without fingers and a re-timed hand take with known truth), then the hand take
is turned into the rig of a real hand capture:

* ``left``: a left-handed performer. The full take is mirrored (``x -> -x``) and its
  joint names' sides swapped, so the right arm's gestures are made by the left arm; the
  hand take keeps only the left hand's fingers (one side spliced: the left).
* ``manipnet``: ManipNet's rig (odd seeds: the left hand, of a left-handed performer). The body take's own finger motion is the real ManipNet
  capture (``mug1_{right,left}Hand.bvh``, mirrored back from Unity's left-handed axes),
  grafted under one wrist: 16 finger joints, a 4-joint thumb with ``THUMB_CMC_AA``. The
  hand take is the wrist's subtree only, rooted at a 6-DoF ``WRIST``, joints named as
  ManipNet names them and a file name without a side (``hand.bvh``): the side comes
  from the hand's geometry.
* ``leap``: the Leap Motion rig of the gestification takes (odd seeds: left): the synthetic fingers of one
  hand below a zero-length ``rHand``/``lHand`` under a 6-DoF ``rForeArm``/``lForeArm``
  root sitting at the wrist (carrying the hand's orientation), in millimetres, at
  36-40 fps.

Every family draws the body take's rate from 25/30/60/120 fps (the capture resampled)
and the hand take's from 25/30/60/90/120 fps (Leap: 36-40), so either may be the
faster. ``make_rig_case(kind, seed)`` returns a :class:`benchmarks.split.Case`; the reference
is the full take at body frames, whose finger joint names are the ones the splice gives
the grafted fingers.
"""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np

from benchmarks.split import MOCAP, Case, base_take, make_hand_take, strip_fingers, subset
from engine.align.features import hand_frame
from engine.io.bvh import read_bvh
from engine.model.hand_side import mirror_take
from engine.model.kinematics import resample
from engine.model.motion import Motion, Skeleton
from engine.model.roles import FINGERS, find_roles
from engine.splice import transfer as TR

RIG_KINDS = ("left", "manipnet", "leap")
MANIPNET = {"right": "manipnet/mug1_rightHand.bvh", "left": "manipnet/mug1_leftHand.bvh"}
_BASES = ("bandai", "lafan1", "beat")
#: body take frame rates (the capture is resampled first); hand takes: :func:`_params`
BODY_FPS = (25.0, 30.0, 60.0, 120.0)
HAND_FPS = (25.0, 30.0, 60.0, 90.0, 120.0)
LEAP_FPS = (36.0, 38.0, 40.0)

_SWAP = [
    (re.compile(p), r)
    for p, r in (
        (r"Right", "Left"),
        (r"Left", "Right"),
        (r"right", "left"),
        (r"left", "right"),
        (r"(?<=_)R(?=_|\d|$)", "L"),
        (r"(?<=_)L(?=_|\d|$)", "R"),
        (r"^R(?=[A-Z_])", "L"),
        (r"^L(?=[A-Z_])", "R"),
        (r"^r(?=[A-Z])", "l"),
        (r"^l(?=[A-Z])", "r"),
    )
]


def swap_side_name(name: str) -> str:
    """``RightHand`` <-> ``LeftHand``, ``Hand_R`` <-> ``Hand_L``, ``right_wrist`` <->
    ``left_wrist``, ``rHand`` <-> ``lHand`` (one pass: each side word swapped once)."""
    out, i = [], 0
    while i < len(name):
        for pattern, repl in _SWAP:
            m = pattern.match(name, i)
            if m and m.end() > i:
                out.append(repl)
                i = m.end()
                break
        else:
            out.append(name[i])
            i += 1
    return "".join(out)


def left_handed(full: Motion) -> Motion:
    """The take performed by its mirror image: mirrored, joint names' sides swapped."""
    m = mirror_take(full)
    sk = m.skeleton
    return replace(m, skeleton=replace(sk, names=tuple(swap_side_name(n) for n in sk.names)))


def _at_body_rate(full: Motion, seed: int) -> Motion:
    """The full take resampled to a body frame rate drawn from :data:`BODY_FPS` (its own
    random stream, so the other draws of a seed do not change)."""
    fps = float(np.random.default_rng([seed, 2]).choice(BODY_FPS))
    return full if fps == full.fps else resample(full, fps)


def _params(rng: np.random.Generator, fps_choices=HAND_FPS) -> dict:
    return {
        "fps": float(rng.choice(fps_choices)),
        "scale": float(rng.uniform(0.85, 1.2)),
        "warp_sigma": float(rng.uniform(0.15, 0.3)),
        "shrink": float(rng.uniform(0.4, 0.7)),
        "yaw_deg": float(rng.uniform(-60.0, 60.0)),
        "noise_deg": 0.5,
    }


def _split(full: Motion, rng, params: dict) -> tuple[Motion, Motion, np.ndarray]:
    roles = find_roles(full.skeleton)
    body = strip_fingers(full, roles)
    body = replace(body, meta=replace(body.meta, source=f"{full.meta.source}#body"))
    hand, hand_t, orig_t = make_hand_take(full, rng, roles=roles, **params)
    truth = np.interp(np.arange(body.n_frames) / body.fps, orig_t, hand_t) * hand.fps
    return body, hand, truth


def _only_wrist_subtree(hand: Motion, wrist: int) -> Motion:
    """The hand take cut to ``wrist``'s subtree (the wrist becomes a 6-DoF root)."""
    keep = np.zeros(hand.skeleton.n_joints, dtype=bool)
    keep[hand.skeleton.descendants(wrist)] = True
    return subset(hand, keep)


def _renamed(
    motion: Motion, names: dict[str, str], source: str, units: str | None = None
) -> Motion:
    sk = motion.skeleton
    meta = replace(motion.meta, source=source, units=units or motion.meta.units)
    return replace(
        motion, skeleton=replace(sk, names=tuple(names.get(n, n) for n in sk.names)), meta=meta
    )


def left_case(seed: int, mocap: str | Path | None = None) -> Case:
    rng = np.random.default_rng(seed)
    full, name = base_take(_BASES[seed % 3], seed, rng, mocap=mocap)
    full = _at_body_rate(left_handed(full), seed)
    params = _params(rng)
    body, hand, truth = _split(full, rng, params)
    roles = find_roles(hand.skeleton)
    right = roles.right.wrist
    if right is not None:  # the hand take carries the left hand's fingers only
        keep = np.ones(hand.skeleton.n_joints, dtype=bool)
        keep[hand.skeleton.descendants(right)[1:]] = False
        hand = subset(hand, keep)
    return Case(
        name=f"left:{name}",
        family="left",
        seed=seed,
        body=body,
        hand=hand,
        truth=truth,
        reference=full,
        params={**params, "side": "left"},
    )


def _manipnet_fingers(body: Motion, side: str, rng, mocap) -> tuple[Motion, dict[str, str]]:
    """``body`` (no fingers) with ManipNet's captured fingers grafted under ``side``'s
    wrist (a random stretch of the capture at the body's frame times); and the grafted
    names -> ManipNet names."""
    root = Path(mocap) if mocap is not None else MOCAP
    manip = mirror_take(read_bvh(root / MANIPNET[side]))  # Unity's axes -> right-handed
    span = (body.n_frames - 1) / body.fps * manip.fps
    start = float(rng.uniform(0.0, max(manip.n_frames - 1 - span, 0.0)))
    times = np.minimum(start + np.arange(body.n_frames) * manip.fps / body.fps, manip.n_frames - 1)
    rb = find_roles(body.skeleton)
    rm = find_roles(manip.skeleton, side_hint=side)
    plan = TR.plan_transfer(
        body,
        manip,
        rb,
        rm,
        {side: hand_frame(body, rb, side)},
        {side: hand_frame(manip, rm, side)},
        (side,),
    )
    full = TR.apply_transfer(plan, body, manip, times)
    full = replace(full, meta=replace(full.meta, source=body.meta.source, format="bvh"))
    names = {
        plan.skeleton.names[new]: manip.skeleton.names[src] for new, src in plan.sides[0].grafted
    }
    names[body.skeleton.names[plan.sides[0].body_frame.wrist]] = "WRIST"
    return full, names


def manipnet_case(seed: int, mocap: str | Path | None = None) -> Case:
    rng = np.random.default_rng(seed)
    side = ("right", "left")[seed % 2]
    full, name = base_take(_BASES[seed % 3], seed, rng, mocap=mocap)
    if side == "left":  # the gesturing arm makes the left hand's motion
        full = left_handed(full)
    full = _at_body_rate(full, seed)
    full, names = _manipnet_fingers(strip_fingers(full), side, rng, mocap)
    params = _params(rng)
    body, hand, truth = _split(full, rng, params)
    wrist = find_roles(hand.skeleton).side(side).wrist
    hand = _renamed(_only_wrist_subtree(hand, wrist), names, "manipnet/hand.bvh")
    return Case(
        name=f"manipnet-{side}:{name}",
        family="manipnet",
        seed=seed,
        body=body,
        hand=hand,
        truth=truth,
        reference=full,
        params={**params, "side": side},
    )


def leap_case(seed: int, mocap: str | Path | None = None) -> Case:
    rng = np.random.default_rng(seed)
    side = ("right", "left")[seed % 2]
    full, name = base_take(_BASES[seed % 3], seed, rng, mocap=mocap)
    if side == "left":
        full = left_handed(full)
    full = _at_body_rate(full, seed)
    params = _params(rng, LEAP_FPS)
    body, hand, truth = _split(full, rng, params)
    roles = find_roles(hand.skeleton)
    arm = roles.side(side)
    cut = _only_wrist_subtree(hand, arm.wrist)
    hand = _leap_rig(cut, side, roles, hand.skeleton)
    return Case(
        name=f"leap-{side}:{name}",
        family="leap",
        seed=seed,
        body=body,
        hand=hand,
        truth=truth,
        reference=full,
        params={**params, "side": side},
    )


def _leap_rig(cut: Motion, side: str, roles, full_sk: Skeleton) -> Motion:
    """A wrist-rooted hand take as a Leap rig: ``rForeArm`` (6 DoF, at the wrist, carrying
    the hand's orientation) > ``rHand`` (zero length, identity) > fingers ``rIndex1``...,
    millimetres."""
    p = side[0]
    sk = cut.skeleton
    arm = roles.side(side)
    names = {}
    for f in FINGERS:
        for k, j in zip(arm.numbers[f], arm.fingers[f], strict=True):
            names[full_sk.names[j]] = f"{p}{f.title()}{k}"
    new_names = [f"{p}ForeArm", f"{p}Hand"] + [names.get(n, n) for n in sk.names[1:]]
    parents = [-1, 0] + [int(q) + 1 for q in sk.parents[1:]]
    k = cut.meters_per_unit / 0.001
    offsets = np.vstack([sk.offsets[:1], np.zeros((1, 3)), sk.offsets[1:]]) * k
    channels = (
        ("Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation"),
        ("Zrotation", "Yrotation", "Xrotation"),
    ) + tuple(sk.channels[1:])
    ends = {j + 1: np.asarray(v, dtype=float) * k for j, v in sk.end_sites.items() if j > 0}
    skel = Skeleton(
        names=tuple(new_names),
        parents=np.array(parents),
        offsets=offsets,
        channels=channels,
        end_sites=ends,
    )
    f = cut.n_frames
    rots = np.concatenate(
        [cut.rotations[:, :1], np.tile([1.0, 0, 0, 0], (f, 1, 1)), cut.rotations[:, 1:]], axis=1
    )
    trans = (
        np.concatenate(
            [cut.translations[:, :1], np.zeros((f, 1, 3)), cut.translations[:, 1:]], axis=1
        )
        * k
    )
    meta = replace(cut.meta, units="mm", source=f"gestification/{p}-hand-take.bvh")
    return Motion(skel, rots, trans, cut.fps, meta)


def make_rig_case(kind: str, seed: int, mocap: str | Path | None = None) -> Case:
    """One seeded case of ``kind`` (:data:`RIG_KINDS`)."""
    if kind == "left":
        return left_case(seed, mocap)
    if kind == "manipnet":
        return manipnet_case(seed, mocap)
    if kind == "leap":
        return leap_case(seed, mocap)
    raise ValueError(f"unknown rig family {kind!r}; known: {', '.join(RIG_KINDS)}")
