"""Body parts of any skeleton, found from joint names and the hierarchy.

The mannequin, the skinning and the renderer need to know which joints form the
spine, the head, the arms, the legs, the hands and each finger, and how the
character faces. Skeletons name these differently (``LeftForeArm``,
``left_elbow``, ``LowerArm_L``, ``rForeArm``, ``INDEX_PIP_FE`` ...), so the parts are
found from a few robust names (hand/wrist, foot/ankle, head, finger names, sides)
plus the hierarchy:

* the *chest* is where the two arms branch (deepest common ancestor of the wrists),
  the *pelvis* where the two legs branch; the arm is the chain from the chest to the
  wrist (clavicle, upper arm, elbow), the leg from the pelvis to the ankle;
* joints above the pelvis (a ``root`` or ``joint_Root`` reference node) are not
  part of the body and are not drawn;
* a skeleton with at most one wrist and finger names is a *hand* take.

Everything here works on one world pose in file units (the rest pose by
default, or a captured frame); it need not be upright or a T-pose (LAFAN1's zero
pose lies along +X).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from engine.base.errors import HandSpliceError
from engine.model import rotations as rot
from engine.model.kinematics import rest_positions
from engine.model.motion import Skeleton

FINGERS = ("thumb", "index", "middle", "ring", "pinky")
SIDES = ("left", "right")

_BODY_WORDS = (
    "hand",
    "arm",
    "foot",
    "leg",
    "thumb",
    "index",
    "middle",
    "ring",
    "pinky",
    "finger",
    "shoulder",
    "elbow",
    "wrist",
    "hip",
    "knee",
    "ankle",
    "toe",
    "collar",
    "clavicle",
    "upleg",
    "up",
    "fore",
    "eye",
)
_FINGER_WORDS = {
    "thumb": ("thumb",),
    "index": ("index", "pointer"),
    "middle": ("middle", "mid"),
    "ring": ("ring",),
    "pinky": ("pinky", "pinkie", "little", "small"),
}


def name_tokens(name: str) -> list[str]:
    """Lower-case words of a joint name: ``"LHipJoint"`` -> ``["l", "hip", "joint"]``."""
    base = re.sub(r"^.*[:|]", "", name)  # drop namespaces such as "mixamorig:"
    parts = re.findall(r"[A-Z]+(?=[A-Z][a-z])|[A-Z]?[a-z]+|[A-Z]+|\d+", base)
    return [p.lower() for p in parts]


def name_side(name: str) -> str:
    """``"left"``, ``"right"`` or ``""`` from a joint name (``Shoulder_L``, ``lhand``, ``rThumb1``)."""
    tokens = name_tokens(name)
    if any(t in ("left", "l", "lft") for t in tokens):
        return "left"
    if any(t in ("right", "r", "rt", "rgt") for t in tokens):
        return "right"
    if tokens:
        first = tokens[0]
        if first.startswith("left"):
            return "left"
        if first.startswith("right"):
            return "right"
        for word in _BODY_WORDS:
            if first in ("l" + word, "r" + word):
                return "left" if first[0] == "l" else "right"
    return ""


def finger_of(name: str) -> str:
    """Which finger a joint belongs to by name (``"thumb"``...``"pinky"``), else ``""``."""
    tokens = name_tokens(name)
    joined = "".join(tokens)
    for finger, words in _FINGER_WORDS.items():
        for w in words:
            if w in tokens or (len(w) > 3 and w in joined):
                return finger
    if any(t.startswith(("lthumb", "rthumb")) for t in tokens):
        return "thumb"
    return ""


def _is_hand_name(name: str) -> bool:
    tokens = name_tokens(name)
    joined = "".join(tokens)
    if finger_of(name) or "end" in tokens or "finger" in joined or "tip" in tokens:
        return False
    return "hand" in joined or "wrist" in joined or "palm" in joined


def _is_ankle_name(name: str) -> bool:
    joined = "".join(name_tokens(name))
    return ("foot" in joined or "ankle" in joined) and "toe" not in joined and "end" not in joined


@dataclass(frozen=True)
class HandParts:
    """One hand.

    side : ``"left"``, ``"right"`` or ``""`` (a hand take that does not say)
    wrist : joint index of the hand's root (the wrist or hand joint)
    elbow : joint index where the forearm starts, or ``None`` (hand-only take)
    fingers : {finger name: joint indices, proximal first}, only the fingers found
    other : joints below the wrist that are no named finger (``LFingers``,
        ``RightHandEnd``, a second ``hand`` joint): the mannequin hangs the missing
        fingers on the first of them
    tips : {finger: joint at the finger tip} where the rig has one
    """

    side: str
    wrist: int
    elbow: int | None
    fingers: dict[str, tuple[int, ...]] = field(default_factory=dict)
    other: tuple[int, ...] = ()
    tips: dict[str, int] = field(default_factory=dict)


@dataclass(frozen=True)
class Anatomy:
    """The parts of one skeleton (joint indices) and its rest-pose body frame.

    kind : ``"body"`` (has arms or legs and a trunk) or ``"hand"`` (a hand take)
    pelvis, chest, head : joint indices or ``None``
    spine : joints from the pelvis up to the head, the chest and neck included
    arms : {side: (clavicle or -1, upper arm, elbow, wrist)}
    legs : {side: (hip, knee, ankle, toe joints...)}
    hands : {side: HandParts}; a hand take has one entry (its side or ``""``)
    hidden : joints that are not drawn (reference nodes above the pelvis, joints
        inside the head such as jaw and eyes)
    up, left, forward : (3,) unit vectors of the pose measured (body: pelvis to head,
        the character's left, its facing; hand take: finger direction, thumb side,
        palm normal)
    height : standing height in file units (a hand take: 9.3 hand lengths)
    hand_length : wrist to middle fingertip in file units
    """

    kind: str
    pelvis: int | None
    chest: int | None
    head: int | None
    spine: tuple[int, ...]
    arms: dict[str, tuple[int, int, int, int]]
    legs: dict[str, tuple[int, ...]]
    hands: dict[str, HandParts]
    hidden: frozenset[int]
    up: np.ndarray
    left: np.ndarray
    forward: np.ndarray
    height: float
    hand_length: float

    def hand_joints(self) -> dict[str, int]:
        """{side: wrist joint} of each hand found."""
        return {side: h.wrist for side, h in self.hands.items()}


def _unit(v: np.ndarray, fallback: np.ndarray | None = None) -> np.ndarray:
    n = float(np.linalg.norm(v))
    if n < 1e-12:
        return np.array([0.0, 1.0, 0.0]) if fallback is None else fallback
    return np.asarray(v, dtype=float) / n


def _lca(skeleton: Skeleton, a: int, b: int) -> int | None:
    up_a = skeleton.chain_to_root(a)
    up_b = set(skeleton.chain_to_root(b))
    for j in up_a:
        if j in up_b:
            return j
    return None


def _distinct_chain(chain: list[int], pos: np.ndarray, tol: float) -> list[int]:
    """Drop joints at the same place as the next one (zero-length bones), keeping the last."""
    out: list[int] = []
    for j in chain:
        if out and np.linalg.norm(pos[j] - pos[out[-1]]) <= tol:
            out[-1] = j if j > out[-1] else out[-1]
            continue
        out.append(j)
    return out


def find_anatomy(
    skeleton: Skeleton,
    positions: np.ndarray | None = None,
    rotations: np.ndarray | None = None,
    roles=None,
    side_hint: str | None = None,
) -> Anatomy:
    """Find the body parts of ``skeleton`` (see the module docstring).

    ``positions (J, 3)`` and ``rotations (J, 4)`` are the world pose the body frame
    and sizes are measured in (default: the rest pose). Some files' rest poses are
    not anatomical (Bandai-Namco's shoulders are turned 90 degrees against its
    hips), so the mannequin measures on a captured frame.

    Arms, wrists and fingers come from :func:`engine.model.roles.find_roles` (``roles``,
    or found with ``side_hint`` for hand takes whose names carry no side) where it
    finds them, so the mannequin agrees with the splice (and its overrides).

    Never fails: parts that cannot be found are left out (``None``, empty), and the
    mannequin then draws plain limb segments for the joints not classified.
    """
    pos = rest_positions(skeleton) if positions is None else np.asarray(positions, float)
    if pos.shape != (skeleton.n_joints, 3):
        raise ValueError(
            f"find_anatomy: positions must be ({skeleton.n_joints}, 3), got {pos.shape}"
        )
    n = skeleton.n_joints
    extent = float(np.max(np.ptp(pos, axis=0))) if n > 1 else 1.0
    tol = 1e-6 * max(extent, 1e-9)  # joints closer than this are one place

    wrists, ankles = _wrists_and_ankles(skeleton)
    pelvis, chest, head = _trunk(skeleton, pos, wrists, ankles, tol)
    body = chest is not None or pelvis is not None
    hidden: set[int] = set()
    spine: list[int] = []
    arms: dict[str, tuple[int, int, int, int]] = {}
    legs: dict[str, tuple[int, ...]] = {}
    if body:
        hidden, spine = _hidden_and_spine(skeleton, pelvis, chest, head)
        if chest is not None:
            arms = _arms(skeleton, pos, chest, wrists, tol)
        legs = _legs(skeleton, pos, pelvis, ankles, tol)
    hands = _hands(skeleton, pos, wrists, arms, body, tol)

    if roles is None:
        try:
            from engine.model.roles import find_roles

            roles = find_roles(skeleton, side_hint=side_hint)
        except HandSpliceError:
            roles = None
    if roles is not None:
        _merge_roles(skeleton, pos, roles, hands, arms, body, tol)

    up, left, forward = _body_frame(skeleton, pos, pelvis, head, chest, arms, legs, hands, body)
    hand_length = _hand_length(skeleton, pos, hands, rotations)
    height = _height(skeleton, pos, spine, legs, head, hand_length, body)
    if not np.isfinite(hand_length) or hand_length <= 0:
        hand_length = 0.108 * height
    return Anatomy(
        kind="body" if body else "hand",
        pelvis=pelvis if body else None,
        chest=chest,
        head=head,
        spine=tuple(spine),
        arms=arms,
        legs=legs,
        hands=hands,
        hidden=frozenset(hidden),
        up=up,
        left=left,
        forward=forward,
        height=float(height),
        hand_length=float(hand_length),
    )


def _wrists_and_ankles(skeleton: Skeleton) -> tuple[dict[str, int], dict[str, int]]:
    """The most proximal hand-named and ankle-named joint per side, by joint names; a
    wrist below another wrist is none (CMU: LeftWrist -> lhand)."""
    names, n = skeleton.names, skeleton.n_joints

    def most_proximal(cands: list[int]) -> dict[str, int]:
        found: dict[str, int] = {}
        for j in cands:  # parents come first, so the first per side is the most proximal
            side = name_side(names[j])
            if side and side not in found:
                found[side] = j
        return found

    wrists = most_proximal([j for j in range(n) if _is_hand_name(names[j])])
    ankles = most_proximal([j for j in range(n) if _is_ankle_name(names[j])])
    for side in list(wrists):
        if any(
            a in wrists.values() and a != wrists[side]
            for a in skeleton.chain_to_root(wrists[side])[1:]
        ):
            del wrists[side]
    return wrists, ankles


def _trunk(
    skeleton: Skeleton, pos: np.ndarray, wrists: dict, ankles: dict, tol: float
) -> tuple[int | None, int | None, int | None]:
    """``(pelvis, chest, head)`` joints (None where absent): the chest joins the wrists, the
    pelvis the ankles; an upper body's pelvis is the root of its trunk. No chest and no
    pelvis: a hand take."""
    names, n = skeleton.names, skeleton.n_joints
    chest = _lca(skeleton, wrists["left"], wrists["right"]) if len(wrists) == 2 else None
    pelvis = _lca(skeleton, ankles["left"], ankles["right"]) if len(ankles) == 2 else None
    if chest is not None and chest in wrists.values():
        chest = None
    head = next(
        (
            j
            for j in range(n)
            if "head" in name_tokens(names[j])
            and "end" not in name_tokens(names[j])
            and (chest is None or chest in skeleton.chain_to_root(j))
        ),
        None,
    )
    if chest is None and head is not None and pelvis is not None:
        chest = skeleton.parents[head] if skeleton.parents[head] >= 0 else None
    if (chest is not None or pelvis is not None) and pelvis is None:
        top = chest if chest is not None else head
        pelvis = skeleton.chain_to_root(top)[-1]
        if chest is not None:  # an upper body: the root of the trunk
            for j in reversed(skeleton.chain_to_root(chest)):
                if np.linalg.norm(pos[j] - pos[chest]) > tol:
                    pelvis = j
                    break
    return pelvis, chest, head


def _hidden_and_spine(
    skeleton: Skeleton, pelvis: int, chest: int | None, head: int | None
) -> tuple[set[int], list[int]]:
    """Joints the mannequin does not draw (above the pelvis, below the head) and the spine
    from the pelvis up to the head (or chest)."""
    hidden = set(skeleton.chain_to_root(pelvis)[1:])
    top = head if head is not None else chest
    if top is not None and pelvis in skeleton.chain_to_root(top):
        spine = list(reversed(skeleton.chain_to_root(top)))
        spine = spine[spine.index(pelvis) :]
    else:
        spine = [pelvis]
    if head is not None:
        hidden.update(d for d in skeleton.descendants(head) if d != head)
    return hidden, spine


def _arms(
    skeleton: Skeleton, pos: np.ndarray, chest: int, wrists: dict, tol: float
) -> dict[str, tuple[int, int, int, int]]:
    """``{side: (clavicle or -1, shoulder, elbow, wrist)}`` from the chest down to each
    wrist (joints in one place counted once)."""
    arms = {}
    for side, w in wrists.items():
        chain = skeleton.chain_to_root(w)
        if chest not in chain:
            continue
        chain = list(reversed(chain[: chain.index(chest)]))
        chain = _distinct_chain(chain, pos, tol)
        if len(chain) >= 3:
            clav = chain[-4] if len(chain) >= 4 else -1
            arms[side] = (clav, chain[-3], chain[-2], chain[-1])
    return arms


def _legs(
    skeleton: Skeleton, pos: np.ndarray, pelvis: int, ankles: dict, tol: float
) -> dict[str, tuple[int, ...]]:
    """``{side: (hip, knee, ankle, *toes)}`` from the pelvis down to each ankle."""
    legs = {}
    for side, a in ankles.items():
        chain = skeleton.chain_to_root(a)
        if pelvis not in chain:
            continue
        chain = _distinct_chain(list(reversed(chain[: chain.index(pelvis)])), pos, tol)
        if len(chain) >= 3:
            toes = [d for d in skeleton.descendants(a) if d != a]
            legs[side] = (chain[-3], chain[-2], chain[-1], *toes)
    return legs


def _hands(
    skeleton: Skeleton, pos: np.ndarray, wrists: dict, arms: dict, body: bool, tol: float
) -> dict[str, HandParts]:
    """The hands: at the wrists of a body, or the one hand of a hand take; each with its
    finger chains by name, its other joints and its elbow."""
    names, n = skeleton.names, skeleton.n_joints
    hands: dict[str, HandParts] = {}
    hand_roots = dict(wrists)
    if not body:
        with_fingers = [j for j in range(n) if finger_of(names[j])]
        if with_fingers:
            if len(wrists) == 1:
                root = next(iter(wrists.values()))
            else:
                cands = [j for j in range(n) if _is_hand_name(names[j])]
                root = cands[0] if cands else _lca_many(skeleton, with_fingers)
            hand_roots = {name_side(names[root]) or name_side(names[with_fingers[0]]): root}
    for side, w in hand_roots.items():
        below = [d for d in skeleton.descendants(w) if d != w]
        fingers: dict[str, list[int]] = {}
        other: list[int] = []
        for d in below:
            f = finger_of(names[d])
            if f:
                fingers.setdefault(f, []).append(d)
            elif (
                _is_hand_name(names[d])
                and skeleton.parents[d] == w
                and np.linalg.norm(pos[d] - pos[w]) <= tol
            ):
                continue  # a second hand joint on the wrist (CMU lhand): part of the palm
            else:
                other.append(d)
        # keep only joints whose parent is the wrist, a finger joint of the same finger,
        # or another wrist-level joint: a proper chain per finger
        elbow = None
        up_chain = _distinct_chain(list(reversed(skeleton.chain_to_root(w))), pos, tol)
        if len(up_chain) >= 2 and (not body or side in arms):
            elbow = arms[side][2] if side in arms else up_chain[-2]
        hands[side] = HandParts(
            side, w, elbow, {f: tuple(fingers[f]) for f in FINGERS if f in fingers}, tuple(other)
        )
    return hands


def _merge_roles(
    skeleton: Skeleton,
    pos: np.ndarray,
    roles,
    hands: dict[str, HandParts],
    arms: dict,
    body: bool,
    tol: float,
) -> None:
    """Take wrists, fingers and arm chains from ``roles`` (in place) where it has them."""
    found = {s: roles.side(s) for s in SIDES if roles.side(s).wrist is not None}
    if not body and found and "" in hands:
        del hands[""]  # a hand take given its side by roles (file name hint)
    for side, arm in found.items():
        w = arm.wrist
        fingers: dict[str, tuple[int, ...]] = {}
        for f in FINGERS:
            chain = list(arm.fingers.get(f, []))
            if not chain:
                continue
            meta = arm.metacarpals.get(f)
            if meta is not None and f != "thumb":
                chain = [meta] + chain
            fingers[f] = tuple(chain)
        tips = {f: int(arm.tips[f]) for f in fingers if arm.tips.get(f) is not None}
        other = tuple(j for j in (arm.hand_end, arm.hand) if j is not None and j != w)
        elbow = arm.elbow
        if elbow is not None and np.linalg.norm(pos[elbow] - pos[w]) <= tol:
            elbow = None  # Leap Motion: the forearm joint sits at the wrist
        old = hands.get(side)
        if elbow is None and old is not None:
            elbow = old.elbow
        if not fingers and old is not None:
            fingers, tips = old.fingers, old.tips
        hands[side] = HandParts(side, w, elbow, fingers, other or (old.other if old else ()), tips)
        if body and arm.shoulder is not None and arm.elbow is not None and elbow is not None:
            chain = skeleton.chain_to_root(w)
            if arm.shoulder in chain and arm.elbow in chain:
                clav = arm.clavicle if arm.clavicle in chain else -1
                arms[side] = (-1 if clav is None else clav, arm.shoulder, arm.elbow, w)


def _lca_many(skeleton: Skeleton, joints: list[int]) -> int:
    common = set(skeleton.chain_to_root(joints[0]))
    for j in joints[1:]:
        common &= set(skeleton.chain_to_root(j))
    return max(common) if common else 0


def chain_tip(
    skeleton: Skeleton,
    pos: np.ndarray,
    chain: tuple[int, ...] | list[int],
    fraction: float = 0.8,
    rotations: np.ndarray | None = None,
) -> np.ndarray:
    """Rest position of the tip beyond the last joint of ``chain`` (``(3,)``, file units).

    The last joint's End Site when it plausibly continues the last bone (0.2 to 1.6
    times its length, within 60 degrees of its direction), else the last bone
    continued by ``fraction`` of its length. ``rotations (J, 4)``: world rotations of
    the pose ``pos`` is taken from (End Sites are in the joint's frame); default
    identity (the rest pose).
    """
    last = chain[-1]
    prev = chain[-2] if len(chain) >= 2 else int(skeleton.parents[last])
    bone = pos[last] - pos[prev] if prev >= 0 else np.zeros(3)
    length = float(np.linalg.norm(bone))
    end = skeleton.end_sites.get(last)
    if end is not None and rotations is not None:
        end = rot.rotate(rotations[last], end)
    if end is not None:
        end_len = float(np.linalg.norm(end))
        # exporters write placeholder End Sites (BEAT: 10 cm along +z on every leaf):
        # keep one only if it roughly continues the last bone
        if end_len > 1e-9 and (
            length < 1e-9
            or (
                0.2 * length <= end_len <= 1.6 * length
                and np.dot(end, bone) > 0.5 * end_len * length
            )
        ):
            return pos[last] + end
    return pos[last] + fraction * bone


def finger_base(skeleton: Skeleton, pos: np.ndarray, hand: HandParts, finger: str) -> np.ndarray:
    """Knuckle (MCP) position of ``finger``; the thumb's first joint for the thumb."""
    chain = hand.fingers[finger]
    if finger == "thumb" or len(chain) <= 3:
        return pos[chain[0]]
    return pos[chain[-3]]  # a metacarpal joint first (4-joint chains): the knuckle is 3 up


def _hand_length(
    skeleton: Skeleton,
    pos: np.ndarray,
    hands: dict[str, HandParts],
    rotations: np.ndarray | None = None,
) -> float:
    lengths = []
    for hand in hands.values():
        for f in ("middle", "index", "ring"):
            if f in hand.fingers:
                chain = hand.fingers[f]
                pts = np.vstack(
                    [
                        pos[hand.wrist],
                        pos[list(chain)],
                        chain_tip(skeleton, pos, chain, rotations=rotations),
                    ]
                )
                lengths.append(float(np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1))))
                break
    return float(np.median(lengths)) if lengths else float("nan")


def _path(pos: np.ndarray, chain: list[int] | tuple[int, ...]) -> float:
    if len(chain) < 2:
        return 0.0
    return float(np.sum(np.linalg.norm(np.diff(pos[list(chain)], axis=0), axis=1)))


def _height(skeleton, pos, spine, legs, head, hand_length, body) -> float:
    if not body:
        return 9.3 * hand_length if np.isfinite(hand_length) else float(np.max(np.ptp(pos, 0)))
    trunk = _path(pos, spine)
    if legs:
        leg = max(_path(pos, (spine[0], *leg[:3])) for leg in legs.values())
        if trunk > 0:
            return (trunk + leg) * 1.12
        return leg * 2.1
    if trunk > 0:
        return trunk * 2.9
    return float(np.max(np.ptp(pos, 0)))


def _body_frame(skeleton, pos, pelvis, head, chest, arms, legs, hands, body):
    if body:
        top = head if head is not None else chest
        up = _unit(pos[top] - pos[pelvis]) if top is not None and top != pelvis else None
        left = None
        if len(arms) == 2:
            left = pos[arms["left"][1]] - pos[arms["right"][1]]
        elif len(legs) == 2:
            left = pos[legs["left"][0]] - pos[legs["right"][0]]
        if up is None and len(legs) == 2:
            up = _unit(pos[pelvis] - 0.5 * (pos[legs["left"][2]] + pos[legs["right"][2]]))
        up = up if up is not None else np.array([0.0, 1.0, 0.0])
        if left is None:
            left = np.array([1.0, 0.0, 0.0]) if abs(up[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
        left = _unit(left - np.dot(left, up) * up)
        return up, left, np.cross(left, up)
    # a hand: up = finger direction, left = towards the thumb, forward = palm normal
    hand = next(iter(hands.values()), None)
    if hand is None or not hand.fingers:
        return np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])
    bases = {f: finger_base(skeleton, pos, hand, f) for f in hand.fingers}
    mid = np.mean([b for f, b in bases.items() if f != "thumb"] or list(bases.values()), axis=0)
    up = _unit(mid - pos[hand.wrist])
    if "index" in bases and "pinky" in bases:
        across = bases["index"] - bases["pinky"]
    elif "thumb" in bases:
        across = bases["thumb"] - mid
    else:
        across = np.array([1.0, 0.0, 0.0])
    left = _unit(across - np.dot(across, up) * up, _unit(np.cross(up, [0.0, 0.0, 1.0])))
    return up, left, palm_normal(skeleton, pos, hand, up, left)


def palm_normal(
    skeleton: Skeleton,
    pos: np.ndarray,
    hand: HandParts,
    finger_dir: np.ndarray,
    thumb_side: np.ndarray,
) -> np.ndarray:
    """Unit normal of the palm (pointing out of the palm) in pose ``pos``.

    From the way the fingers bend when they bend visibly (fingers flex towards the
    palm), else from the hand's side: ``thumb_side x finger_dir`` for a right hand,
    mirrored for a left one (a hand take that does not say counts as right).
    """
    normal = np.cross(thumb_side, finger_dir)
    normal = _unit(normal)
    if hand.side == "left":
        normal = -normal
    flex, scale = 0.0, 0.0
    for f in ("index", "middle", "ring", "pinky"):
        chain = hand.fingers.get(f, ())
        if len(chain) >= 2:
            base = pos[chain[0]]
            rel = pos[list(chain[1:])] - base
            flex += float(np.sum(rel @ normal))
            scale += float(np.sum(np.linalg.norm(rel, axis=1)))
    if scale > 0 and abs(flex) > 0.08 * scale:
        return normal if flex > 0 else -normal
    return normal
