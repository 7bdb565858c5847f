"""Which hand a skeleton's fingers form, from their geometry; mirroring a take.

A right and a left hand are mirror images: with ``a`` = wrist -> index knuckle and
``b`` = wrist -> little-finger knuckle (ring when there is no little finger), the
palm normal ``n = a x b`` points to the *palm* side of a right hand and to the back
of a left one (in right-handed axes, whatever the rig's up axis, units or rest pose).
Two cues say where the palm is, frame by frame:

* the thumb: its joints lie on the palm side of the knuckle plane (opposition);
* the fingers: they flex toward the palm, so their distal joints lie on the palm side
  of their knuckles.

Each cue is the signed distance along ``n`` divided by the knuckle distance ``|a|``
(unitless), per frame. The side is ``"right"`` when both cues are positive in most
frames, ``"left"`` when both are negative; anything else (cues disagreeing, a flat
hand that never flexes, no thumb and no flexion) is undecided.

Captures exported from left-handed engines (Unity: ManipNet's ``mug1_rightHand.bvh``)
read as the *other* hand in BVH's right-handed axes; :func:`mirror_take` turns such a
take into the hand it was (reflection across the file's ``x = 0`` plane). ManipNet's own
viewer (``Data/SimpleVisualizer``) applies the files' offsets and ``AngleAxis`` rotations
as they are in Unity's left-handed axes. Nothing inside a hand take tells its axes'
handedness (a mirrored left hand is a right hand in every measure), so a side that only
the geometry gives is always said, with how to give the other one
(:func:`unnamed_side_warning`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from engine.model.fastkin import forward_kinematics
from engine.model.motion import Motion, Skeleton

#: frames sampled (evenly) to measure the cues
MAX_FRAMES = 400
#: a cue's median must be at least this far from 0 (fraction of the knuckle distance)
MIN_CUE = 0.02
#: and this share of the frames must agree with its sign
MIN_AGREE = 0.7


@dataclass(frozen=True)
class SideVote:
    """What a hand's geometry says: ``side`` (``"right"``, ``"left"`` or None) and why.

    thumb, curl : median cue values (None when the rig has no such joints)
    thumb_agree, curl_agree : share of frames whose cue has the median's sign
    reason : one phrase for messages
    """

    side: str | None
    thumb: float | None
    curl: float | None
    thumb_agree: float
    curl_agree: float
    reason: str


def _cue(values: np.ndarray) -> tuple[float, float]:
    med = float(np.median(values))
    agree = float(np.mean(np.sign(values) == np.sign(med))) if med != 0 else 0.0
    return med, agree


def geometric_side(motion: Motion, arm, fk=None) -> SideVote:
    """The side whose hand ``arm``'s fingers form (see the module docstring).

    Parameters
    ----------
    motion : Motion holding the hand
    arm : ``engine.model.roles.ArmRoles`` of that hand (wrist and finger roles; its side is
        not used, so the unsided roles of a hand-only rig work)
    fk : (positions (F, J, 3), rotations) of ``motion``, optional (reused)
    """
    sk = motion.skeleton
    wrist = arm.wrist
    index = arm.fingers.get("index", [])
    outer = arm.fingers.get("pinky", []) or arm.fingers.get("ring", [])
    if wrist is None or not index or not outer:
        return SideVote(
            None, None, None, 0.0, 0.0, "no wrist with index and little (or ring) finger joints"
        )
    if fk is None:
        step = max(1, motion.n_frames // MAX_FRAMES)
        pos = forward_kinematics(
            replace(
                motion,
                rotations=motion.rotations[::step],
                translations=motion.translations.frames(None, None, step),
            )
        )[0]
    else:
        pos = fk[0]
        pos = pos[:: max(1, pos.shape[0] // MAX_FRAMES)]
    w = pos[:, wrist]
    a = pos[:, index[0]] - w
    b = pos[:, outer[0]] - w
    n = np.cross(a, b)
    knuckles = np.linalg.norm(a, axis=-1)
    ok = (np.linalg.norm(n, axis=-1) > 1e-9) & (knuckles > 1e-12)
    if not ok.any():
        return SideVote(None, None, None, 0.0, 0.0, "the knuckles lie on a line with the wrist")
    n = n[ok] / np.linalg.norm(n[ok], axis=-1, keepdims=True)
    pos, w, knuckles = pos[ok], w[ok], knuckles[ok]

    thumb = curl = None
    thumb_agree = curl_agree = 0.0
    if arm.fingers.get("thumb"):
        joints = sk.descendants(arm.fingers["thumb"][0])
        d = np.sum(n * (pos[:, joints].mean(axis=1) - w), axis=-1) / knuckles
        thumb, thumb_agree = _cue(d)
    cues = []
    for f in ("index", "middle", "ring", "pinky"):
        js = arm.fingers.get(f, [])
        if not js:
            continue
        distal = sk.descendants(js[0])[1:]
        if distal:
            cues.append(np.sum(n * (pos[:, distal].mean(axis=1) - pos[:, js[0]]), axis=-1))
    if cues:
        curl, curl_agree = _cue(np.mean(cues, axis=0) / knuckles)

    votes = []
    for value, agree in ((thumb, thumb_agree), (curl, curl_agree)):
        if value is not None and abs(value) >= MIN_CUE and agree >= MIN_AGREE:
            votes.append("right" if value > 0 else "left")
        elif value is not None and abs(value) >= 2 * MIN_CUE and agree >= 0.55:
            votes.append("right?" if value > 0 else "left?")
    strong = {v for v in votes if not v.endswith("?")}
    weak = {v.rstrip("?") for v in votes}
    if len(strong) == 1 and weak <= strong:
        side = strong.pop()
        return SideVote(
            side,
            thumb,
            curl,
            thumb_agree,
            curl_agree,
            f"thumb and finger flexion lie on the palm side of a {side} hand",
        )
    if len(strong) > 1 or len(weak) > 1:
        reason = "the thumb and the finger flexion point to different sides"
    else:
        reason = "the thumb and the fingers stay too close to the palm plane"
    return SideVote(None, thumb, curl, thumb_agree, curl_agree, reason)


def _both_cues(vote: SideVote) -> bool:
    """Thumb and finger flexion both clearly on the same side."""
    return all(
        v is not None and abs(v) >= MIN_CUE and a >= MIN_AGREE
        for v, a in ((vote.thumb, vote.thumb_agree), (vote.curl, vote.curl_agree))
    )


def mirror_skeleton(sk: Skeleton, axis: int = 0) -> Skeleton:
    """``sk`` reflected across the plane ``axis = 0`` (offsets and End Sites)."""
    flip = np.ones(3)
    flip[axis] = -1.0
    return Skeleton(
        names=sk.names,
        parents=sk.parents,
        offsets=sk.offsets * flip,
        channels=sk.channels,
        end_sites={j: np.asarray(v, dtype=float) * flip for j, v in sk.end_sites.items()},
    )


def mirror_take(motion: Motion, axis: int = 0) -> Motion:
    """The take reflected across the plane ``axis = 0`` of its file axes.

    Positions ``p -> M p`` with ``M`` = diag(-1, 1, 1) (for ``axis = 0``); every rotation
    ``R -> M R M``, for a quaternion (w, x, y, z): the components of the two other axes
    change sign. Forward kinematics of the result is the mirror image of the original;
    a right hand becomes a left hand. Names are kept.
    """
    if axis not in (0, 1, 2):
        raise ValueError(f"mirror_take: axis must be 0, 1 or 2, got {axis!r}")
    flip = np.ones(3)
    flip[axis] = -1.0
    qflip = np.concatenate([[1.0], -flip])  # keep w and the mirror axis, flip the others
    return replace(
        motion,
        skeleton=mirror_skeleton(motion.skeleton, axis),
        rotations=motion.rotations * qflip,
        translations=motion.translations.scaled(flip),
    )


# --------------------------------------------------------------------------------------------
# sides of a pair (used by engine.splice.pipeline)
# --------------------------------------------------------------------------------------------


def sided_roles(take: Motion, roles, side: str | None = None):
    """``roles`` of a hand-only rig whose names carry no side, given one.

    ``roles.unsided`` (names and file name silent) goes to ``side`` when it is
    ``"right"``/``"left"`` (``--side``), else to the side its geometry shows
    (:func:`geometric_side`); ``side_source`` says ``"hint"`` or ``"geometry"``. Roles
    with a side, or that geometry cannot decide, come back unchanged (the caller's
    error then names ``--side``: :func:`undecided_message`).
    """
    from engine.model.roles import find_roles

    arm = getattr(roles, "unsided", None)
    if arm is None or not arm.has_fingers:
        return roles
    if side in ("right", "left"):
        source = "hint"
    else:
        vote = geometric_side(take, arm)
        if vote.side is None:
            return roles
        side, source = vote.side, "geometry"
    out = find_roles(take.skeleton, side_hint=side)
    out.side_source[side] = source
    return out


def undecided_message(take_name: str, take: Motion, roles) -> str | None:
    """The one-line error for a hand take whose side nothing tells, else None."""
    arm = getattr(roles, "unsided", None)
    if arm is None or not arm.has_fingers:
        return None
    vote = geometric_side(take, arm)
    return (
        f"{take_name}: cannot tell which hand this is: its joint names and file name carry "
        f"no side and its geometry is ambiguous ({vote.reason}); give it with --side right "
        f"or --side left"
    )


#: why a side read from a hand's geometry alone may be the wrong one (every message says it)
AXES_CAVEAT = (
    "a take written in left-handed axes (a Unity export, as ManipNet's) forms the other hand"
)


def unnamed_side_warning(take_name: str, take: Motion, side: str | None, fix: str) -> str | None:
    """The one-line warning for a hand take whose file name and joint names carry no side,
    spliced as ``side`` (None: the side its geometry forms, as the CLI without ``--side``
    does), else None.

    The geometry (:func:`geometric_side`) tells which hand the fingers form *in the file's
    axes*; whether the file's axes are right-handed, as BVH's are meant to be, nothing in
    a hand take tells (a mirror image of a left hand is a right hand in every measure), and
    real takes are not (ManipNet's files are read by its own Unity viewer in Unity's
    left-handed axes: its ``mug1_rightHand`` forms a left hand here). So a side that no name
    gives is never silent. ``fix`` words how to give the other side: ``"pass --side {side}"``
    (``{side}`` is filled with the other side) or ``"choose Side {side}"``. Returns None
    when the names give the side, when the take has no unsided fingers, and when ``side``
    is None and the geometry is undecided (the caller refuses: :func:`undecided_message`).
    """
    from engine.model.roles import find_roles, side_from_name

    if side_from_name(take_name) is not None:
        return None
    arm = find_roles(take.skeleton).unsided
    if arm is None or not arm.has_fingers:
        return None
    vote = geometric_side(take, arm)
    if side is None:
        if vote.side is None:
            return None
        side = vote.side
        how = f"spliced as the {side} hand, the hand its geometry forms in the file's axes"
    elif vote.side is None:
        how = f"spliced as the {side} hand (the side given); its geometry does not tell ({vote.reason})"
    elif vote.side == side:
        how = f"spliced as the {side} hand (the side given), the hand its geometry forms in the file's axes"
    elif not _both_cues(vote):  # match_chirality mirrors on clear evidence only
        how = (
            f"spliced as the {side} hand (the side given); its geometry leans to a "
            f"{vote.side} hand in the file's axes (one cue only: not mirrored)"
        )
    else:  # match_chirality mirrors it
        how = (
            f"spliced as the {side} hand (the side given), mirrored: its geometry forms a "
            f"{vote.side} hand in the file's axes"
        )
    other = "left" if side == "right" else "right"
    return (
        f"{take_name}: its file name and joint names carry no side; {how}; "
        f"{AXES_CAVEAT}: if it is the {other} hand, {fix.format(side=other)}"
    )


def match_chirality(
    body, hand: Motion, body_roles, hand_roles, sides, body_fk=None, hand_fk=None
) -> tuple[Motion, list[str]]:
    """The hand take, mirrored when its fingers form the other hand than the body expects.

    For each spliced side the body expects a hand of that side (or, when the body has
    fingers there, the hand its own fingers form). When every spliced side's hand in the
    hand take forms the other hand, clearly (thumb and flexion both agree), the take was written in left-handed axes
    (a Unity export) and is mirrored (:func:`mirror_take`); a note says so. Returns
    (hand take, notes).
    """
    notes: list[str] = []
    flips = []
    for s in sides:
        vote = geometric_side(hand, hand_roles.side(s), hand_fk)
        if vote.side is None or not _both_cues(vote):  # mirror only on clear evidence
            return hand, notes
        expected = s
        if isinstance(body, Motion) and body_roles.side(s).has_fingers:
            own = geometric_side(body, body_roles.side(s), body_fk).side
            expected = own or s
        flips.append(vote.side != expected)
    if flips and all(flips):
        what = " and ".join(
            f"its {s} hand forms a {'left' if s == 'right' else 'right'} hand" for s in sides
        )
        notes.append(
            f"the hand take was mirrored: {what} (a capture exported in left-handed "
            "axes, e.g. from Unity)"
        )
        return mirror_take(hand), notes
    return hand, notes
