"""Joint roles: which joints of a skeleton are the shoulder, elbow, wrist, hand and fingers.

``find_roles(skeleton)`` reads joint *names* (plus the hierarchy, to break ties)
and returns ``Roles``: per side an ``ArmRoles`` of joint indices, ``None`` where
the rig has no such joint.

What each role means (the joint's *position* is where it sits; its *rotation*
orients the segment below it)
---------------------------------------------------------------------------------
``clavicle``  the collar-bone joint above the shoulder (``RightShoulder`` in
              Mixamo, ``Shoulder_R`` in Bandai, ``RightCollar`` in CMU), optional.
``shoulder``  the joint at the shoulder (gleno-humeral) joint, whose rotation
              orients the upper arm: ``RightArm`` (Mixamo, HumanIK, LAFAN1),
              ``UpperArm_R`` (Bandai), ``right_shoulder`` (SMPL-X),
              ``RightShoulder`` (CMU, where the collar is ``RightCollar``).
``elbow``     the joint whose rotation orients the forearm: ``RightForeArm``,
              ``LowerArm_R``, ``right_elbow``, ``RightElbow``. It sits at the elbow
              in body rigs; in Leap Motion hand takes (gestification) the root
              ``rForeArm`` sits at the *wrist* (no joint marks the elbow).
``wrist``     the joint at the wrist: the root of the hand's subtree, whose local
              rotation (with its descendants) is what splicing transfers.
              ``RightHand`` (Mixamo, HumanIK, LAFAN1, AnimatedDrawings), ``Hand_R``
              (Bandai), ``right_wrist`` (SMPL-X), ``rHand`` (gestification),
              ``WRIST`` (ManipNet), ``RightWrist`` (CMU).
``hand``      the joint whose rotation orients the palm. The wrist itself in every
              rig above except CMU-style ones, where a zero-length ``rhand`` below
              ``RightWrist`` carries the palm. Never a finger joint.
``hand_end``  a joint at the far end of the palm (knuckles / hand tip) when the rig
              has one: ``RFingers`` (CMU), ``RightHandEnd`` (AnimatedDrawings),
              ``RightFingerBase`` (HumanIK); else ``None``.
``<finger>1..3`` per finger (thumb, index, middle, ring, pinky), proximal to distal
              as the rig numbers them (SMPL-X ``index1`` is the knuckle, MCP; the
              thumb's 1 is its CMC). Anatomical names map as thumb CMC/MCP/IP ->
              1/2/3, finger MCP/PIP/DIP -> 1/2/3 (ManipNet). Unnumbered joints
              (CMU ``RThumb``) fill 1, 2, 3 in hierarchy order.
``<finger>_tip``  a joint at the finger tip (Mixamo/HumanIK ``...Index4``, ``Nub``,
              ``End``, ``Tip``), optional.
``<finger>_metacarpal``  a joint inside the palm below joint 1 (HumanIK
              ``RightInHandIndex``, Unreal ``index_metacarpal_r``, digit 0), optional.

The *point* on the back of the hand (METHOD's fourth alignment marker) and a point
on the forearm are given by ``Roles.landmarks(side)`` as (joint, local offset)
pairs, because many rigs have no joint there.

Sides come from name tokens (``Right``/``Left``, ``R``/``L``, ``_r``/``.L``, a
leading ``r``/``l`` as in ``rHand``, ``lhand``). Hand-only rigs whose names carry
no side (ManipNet ``WRIST``) are assigned to ``side_hint`` (callers derive it
from the file name with ``side_from_name``: ``mug1_rightHand.bvh`` -> right);
without a hint they are kept in ``Roles.unsided`` and ``require`` explains how to
give the side.

Overrides: a mapping ``{"right.wrist": "Bip01_R_Hand", "left.index1": null, ...}``
(keys ``<side>.<role>``, role names as in ``ROLE_NAMES``; ``null`` removes a role),
as a dict or a JSON file read by ``load_role_overrides``. Overrides are applied
after the automatic match and always win.
"""

from __future__ import annotations

import difflib
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from engine.base.errors import ParameterError, RoleError
from engine.base.json_text import JsonTextError, parse_json
from engine.model.motion import Skeleton

SIDES = ("right", "left")
FINGERS = ("thumb", "index", "middle", "ring", "pinky")
ARM_ROLES = ("clavicle", "shoulder", "elbow", "wrist", "hand", "hand_end")
FINGER_ROLES = tuple(f"{f}{k}" for f in FINGERS for k in (1, 2, 3))
TIP_ROLES = tuple(f"{f}_tip" for f in FINGERS)
METACARPAL_ROLES = tuple(f"{f}_metacarpal" for f in FINGERS)
ROLE_NAMES = ARM_ROLES + FINGER_ROLES + TIP_ROLES + METACARPAL_ROLES

# --------------------------------------------------------------------------- name tokens

_FINGER_WORDS = {
    "thumb": "thumb",
    "index": "index",
    "middle": "middle",
    "mid": "middle",
    "ring": "ring",
    "pinky": "pinky",
    "pinkie": "pinky",
    "little": "pinky",
}
_SIDE_WORDS = {
    "right": "right",
    "r": "right",
    "rt": "right",
    "left": "left",
    "l": "left",
    "lf": "left",
    "lt": "left",
}
_HELPER_WORDS = {
    "twist",
    "roll",
    "ik",
    "fk",
    "pole",
    "target",
    "share",
    "helper",
    "ctrl",
    "control",
    "aux",
    "prop",
    "weapon",
    "corrective",
}
_TIP_WORDS = {"end", "tip", "nub", "site", "top"}
_METACARPAL_WORDS = {"metacarpal", "meta", "carpal", "in", "palm"}
# finger joint numbers from anatomical joint names (ManipNet ``INDEX_PIP_FE``)
_THUMB_CODES = {"cmc": 1, "mcp": 2, "ip": 3}
_FINGER_CODES = {"cmc": 0, "mcp": 1, "pip": 2, "dip": 3}
# words a glued lower-case token may be made of ("rhand", "lshldr", "righthandindex")
_VOCAB = (
    set(_FINGER_WORDS)
    | set(_HELPER_WORDS)
    | _TIP_WORDS
    | _METACARPAL_WORDS
    | {
        "right",
        "left",
        "hand",
        "wrist",
        "fore",
        "arm",
        "upper",
        "lower",
        "shoulder",
        "shldr",
        "collar",
        "clavicle",
        "elbow",
        "finger",
        "fingers",
        "base",
        "forearm",
        "upperarm",
        "lowerarm",
        "humerus",
        "cmc",
        "mcp",
        "pip",
        "dip",
    }
)

_CAMEL = re.compile(r"[A-Z]+(?=[A-Z][a-z])|[A-Z]?[a-z]+|[A-Z]+|\d+")


def name_tokens(name: str) -> list[str]:
    """Lower-case word tokens of a joint name, namespace removed.

    ``"mixamorig:RightHandIndex1"`` -> ``["right", "hand", "index", "1"]``,
    ``"Hand_R"`` -> ``["hand", "r"]``, ``"lhand"`` -> ``["l", "hand"]``.
    """
    base = re.split(r"[:|]", name)[-1]
    out: list[str] = []
    for part in _CAMEL.findall(base):
        token = part.lower()
        if token.isdigit() or token in _VOCAB or token in _SIDE_WORDS:
            out.append(token)
        else:
            out.extend(_segment(token) or [token])
    return out


def _segment(token: str) -> list[str] | None:
    """Split a glued token into vocabulary words, allowing one leading side letter."""
    for lead in ("", "r", "l"):
        if lead and not token.startswith(lead):
            continue
        words = _segment_vocab(token[len(lead) :])
        if words:
            return ([lead] if lead else []) + words
    return None


def _segment_vocab(text: str) -> list[str] | None:
    if not text:
        return None
    best: list[list[str] | None] = [None] * (len(text) + 1)
    best[0] = []
    for end in range(1, len(text) + 1):
        for start in range(end):
            prev = best[start]
            if prev is not None and text[start:end] in _VOCAB:
                cand = prev + [text[start:end]]
                if best[end] is None or len(cand) < len(best[end]):
                    best[end] = cand
    return best[len(text)]


@dataclass(frozen=True)
class _Label:
    """What a joint's name says about it."""

    side: str | None  # "right", "left" or None
    part: str | None  # clavicle, shoulder, arm, elbow, wrist, hand_end, finger
    finger: str | None = None
    number: int | None = None  # finger joint number from a digit or anatomical code
    numbered_by: str = ""  # "digit", "code" or ""
    tip: bool = False
    metacarpal: bool = False


def _label(name: str) -> _Label:
    tokens = name_tokens(name)
    sides = {_SIDE_WORDS[t] for t in tokens if t in _SIDE_WORDS}
    side = sides.pop() if len(sides) == 1 else None
    words = set(tokens)
    if words & _HELPER_WORDS:
        return _Label(side, None)
    finger = next((_FINGER_WORDS[t] for t in tokens if t in _FINGER_WORDS), None)
    if finger is None and "finger" in words:
        finger = _biped_finger(tokens)
        if finger is None:  # "RFingers", "RightFingerBase": the hand's far end
            return _Label(side, "hand_end")
        return _biped_label(side, tokens, finger)
    if finger is None and "fingers" in words:
        return _Label(side, "hand_end")
    if finger is not None:
        return _finger_label(side, tokens, finger)
    if "hand" in words and words & _TIP_WORDS:
        return _Label(side, "hand_end")
    if "wrist" in words or "hand" in words:
        return _Label(side, "wrist")
    has_arm = "arm" in words
    if (
        "forearm" in words
        or "lowerarm" in words
        or "elbow" in words
        or (has_arm and ("fore" in words or "lower" in words))
    ):
        return _Label(side, "elbow")
    if "upperarm" in words or "humerus" in words or (has_arm and "upper" in words) or has_arm:
        return _Label(side, "arm")
    if "shoulder" in words or "shldr" in words:
        return _Label(side, "shoulder")
    if "collar" in words or "clavicle" in words:
        return _Label(side, "clavicle")
    return _Label(side, None)


def _finger_label(side, tokens: list[str], finger: str) -> _Label:
    words = set(tokens)
    digits = [t for t in tokens if t.isdigit()]
    codes = _THUMB_CODES if finger == "thumb" else _FINGER_CODES
    code = next((codes[t] for t in tokens if t in codes), None)
    if words & _TIP_WORDS:
        return _Label(side, "finger", finger, tip=True)
    if words & _METACARPAL_WORDS or code == 0:
        return _Label(side, "finger", finger, metacarpal=True)
    if code is not None:
        return _Label(side, "finger", finger, number=code, numbered_by="code")
    if digits:
        number = int(digits[-1])
        if number == 0:
            return _Label(side, "finger", finger, metacarpal=True)
        return _Label(side, "finger", finger, number=number, numbered_by="digit")
    return _Label(side, "finger", finger)


def _biped_finger(tokens: list[str]) -> str | None:
    """3ds Max Biped ``Bip01 R Finger12``: first digit after 'finger' is the finger (0 thumb)."""
    i = tokens.index("finger")
    if i + 1 < len(tokens) and tokens[i + 1].isdigit() and tokens[i + 1][0] in "01234":
        return FINGERS[int(tokens[i + 1][0])]
    return None


def _biped_label(side, tokens: list[str], finger: str) -> _Label:
    digits = tokens[tokens.index("finger") + 1]
    if set(tokens) & _TIP_WORDS:
        return _Label(side, "finger", finger, tip=True)
    number = 1 + (int(digits[1]) if len(digits) > 1 else 0)  # Finger1, Finger11, Finger12
    return _Label(side, "finger", finger, number=number, numbered_by="digit")


#: a file name's whole tokens (split on ``_ - . space``) that say a side: the labs' ``RH``/``LH``
_FILE_SIDE_TOKENS = {"rh": "right", "lh": "left"}


def side_from_name(text: str | Path) -> str | None:
    """``"right"``/``"left"`` if a file name says so (``mug1_rightHand.bvh``,
    ``gloves_RH_mug.bvh``: ``RH``/``LH`` only as a whole token between ``_ - . space``, so
    ``birch.bvh`` says nothing), else None (also when it names both sides)."""
    stem = Path(str(text)).stem
    sides = {_SIDE_WORDS[t] for t in name_tokens(stem) if t in ("right", "left")}
    sides |= {
        _FILE_SIDE_TOKENS[t] for t in re.split(r"[_\-. ]+", stem.lower()) if t in _FILE_SIDE_TOKENS
    }
    return sides.pop() if len(sides) == 1 else None


@dataclass(frozen=True)
class HandFileSide:
    """The side a hand take's names give: ``side`` (None: its file name says none) and
    ``warning`` (one line, or None) when its file name contradicts its joint names."""

    side: str | None
    warning: str | None = None


def hand_file_side(text: str | Path, skeleton: Skeleton | None) -> HandFileSide:
    """The side the file name ``text`` gives a hand take whose joints are ``skeleton``
    (None: a take with no joints read, markers say: the name's side, silently).

    The one rule for a file name against joint names (the CLI, ``batch``, ``serve`` and the
    page): joint names are stronger evidence than a file name. When the name says one side
    and the joint names carry hands of the other side only (gestification's ``rHand``,
    ``rIndex1`` saved as ``pointing_left_hand.bvh``), the side is the joints', with a
    warning naming the file; otherwise it is the name's (:func:`side_from_name`), silently.
    """
    named = side_from_name(text)
    if named is None or skeleton is None:
        return HandFileSide(named)
    roles = find_roles(skeleton)
    by_joints = [s for s in roles.sides_found() if roles.side_source.get(s) == "names"]
    if not by_joints or named in by_joints:
        return HandFileSide(named)
    side = by_joints[0]
    return HandFileSide(
        side,
        f"{Path(str(text)).name}: the file name says {named} but its joint names are a "
        f"{side} hand ({roles.name(roles.side(side).wrist)}); taking it as the {side} hand",
    )


def side_name_conflict(text: str | Path, side: str | None) -> str | None:
    """The one-line warning when ``side`` (``--side``, the page's Side) contradicts the
    side a file's name says (``mug1_rightHand.bvh`` taken as left), else None. The side
    asked for is used; the warning says so (a mirrored-wrong hand is easy to miss)."""
    named = side_from_name(text)
    if side not in SIDES or named is None or named == side:
        return None
    return (
        f"{Path(str(text)).name}: the file name says {named} but the side asked for is "
        f"{side}; taking it as the {side} hand"
    )


# --------------------------------------------------------------------------- results


@dataclass(frozen=True)
class ArmRoles:
    """Joint indices for one arm; ``None`` (or an empty list) where the rig has none.

    ``fingers[f]`` lists the joints 1..3 of finger ``f`` that exist, proximal first
    (``fingers["thumb"] == [j1]`` for a one-joint thumb). ``tips`` and
    ``metacarpals`` map each finger to a joint index or None.
    """

    clavicle: int | None = None
    shoulder: int | None = None
    elbow: int | None = None
    wrist: int | None = None
    hand: int | None = None
    hand_end: int | None = None
    fingers: dict[str, list[int]] = field(default_factory=lambda: {f: [] for f in FINGERS})
    tips: dict[str, int | None] = field(default_factory=lambda: {f: None for f in FINGERS})
    metacarpals: dict[str, int | None] = field(default_factory=lambda: {f: None for f in FINGERS})
    # finger joint number of each entry of fingers[f] (1..3), for get("index2")
    numbers: dict[str, list[int]] = field(default_factory=lambda: {f: [] for f in FINGERS})

    def get(self, role: str) -> int | None:
        """Joint index of ``role`` (a name from ``ROLE_NAMES``), or None."""
        _check_role(role)
        if role in ARM_ROLES:
            return getattr(self, role)
        if role.endswith("_tip"):
            return self.tips[role[:-4]]
        if role.endswith("_metacarpal"):
            return self.metacarpals[role[:-11]]
        finger, number = role[:-1], int(role[-1])
        for j, k in zip(self.fingers[finger], self.numbers[finger], strict=True):
            if k == number:
                return j
        return None

    def flat(self) -> dict[str, int | None]:
        """``{role: joint index or None}`` for every name in ``ROLE_NAMES``."""
        return {role: self.get(role) for role in ROLE_NAMES}

    @property
    def has_fingers(self) -> bool:
        return any(self.fingers[f] for f in FINGERS)

    @property
    def has_shoulder(self) -> bool:
        """A shoulder or clavicle above the elbow: an arm of a body rig. A hand take's arm
        (a forearm, the hand and its fingers) has neither, and cannot be a body's arm."""
        return self.shoulder is not None or self.clavicle is not None

    def finger_chain(self, sk: Skeleton, finger: str, hand_joint: int | None = None) -> list[int]:
        """Every joint of ``finger``'s chain below ``hand_joint`` (default this arm's hand
        joint, else its wrist), proximal first: from the joint below the hand (metacarpal,
        unnamed or joint 1) to the deepest role joint (tip, else the last numbered one),
        then on through single children (unnamed tips). Joints between the numbered ones
        (ManipNet's ``THUMB_CMC_AA``, a splice's inserted joints) are in it; ``[]`` when
        the finger has no joint under ``hand_joint``."""
        if hand_joint is None:
            hand_joint = self.hand if self.hand is not None else self.wrist
        if hand_joint is None:
            return []
        named = [j for j in self.fingers[finger] if hand_joint in sk.chain_to_root(j)]
        if not named:
            return []
        last = named[-1]
        tip = self.tips[finger]
        if tip is not None and last in sk.chain_to_root(tip):
            last = tip
        while len(sk.children(last)) == 1:
            last = sk.children(last)[0]
        path = sk.chain_to_root(last)
        return path[: path.index(hand_joint)][::-1]

    @property
    def found(self) -> bool:
        """True when any role is present."""
        return any(v is not None for v in self.flat().values())

    def joints(self) -> list[int]:
        """Every joint index holding a role, sorted."""
        return sorted({v for v in self.flat().values() if v is not None})


@dataclass(frozen=True, eq=False)
class Landmark:
    """A point fixed in a joint's frame: ``offset`` (3,) in the joint's local axes,
    file units. ``source`` says how it was derived (``"joint"``, ``"hand_end joint"``,
    ``"finger bases"``, ``"end site"``, ``"estimated ..."``)."""

    joint: int
    offset: np.ndarray
    source: str


@dataclass(frozen=True, eq=False)
class Roles:
    """Roles of one skeleton per side. See the module docstring for the meanings.

    ``right``/``left`` are ``ArmRoles``; ``unsided`` holds the roles of a hand-only
    rig whose names carry no side when no ``side_hint`` was given (else None).
    ``side_source[side]`` is ``"names"``, ``"hint"``, ``"override"`` or ``""``.
    """

    skeleton: Skeleton
    right: ArmRoles
    left: ArmRoles
    unsided: ArmRoles | None = None
    side_source: dict[str, str] = field(default_factory=dict)

    def side(self, side: str) -> ArmRoles:
        """``ArmRoles`` of ``"right"`` or ``"left"``."""
        if side not in SIDES:
            raise ParameterError(f"side must be 'right' or 'left', got {side!r}")
        return self.right if side == "right" else self.left

    def get(self, side: str, role: str) -> int | None:
        """Joint index of ``role`` on ``side``, or None."""
        return self.side(side).get(role)

    def name(self, joint: int | None) -> str | None:
        return None if joint is None else self.skeleton.names[joint]

    def sides_found(self) -> list[str]:
        """Sides that have a wrist."""
        return [s for s in SIDES if self.side(s).wrist is not None]

    @property
    def looks_like_hand_take(self) -> bool:
        """The rig has hands (a wrist or fingers, sided or not) and none has a shoulder
        or clavicle above its elbow (``ArmRoles.has_shoulder``): a hand take, which the
        splice refuses as the body take unless a role override names its shoulder."""
        arms = [
            arm
            for arm in (self.right, self.left, self.unsided)
            if arm is not None and (arm.wrist is not None or arm.has_fingers)
        ]
        return bool(arms) and not any(arm.has_shoulder for arm in arms)

    @property
    def looks_like_body_take(self) -> bool:
        """No hand of the rig has finger joints (sided or not: ``ArmRoles.has_fingers``): a
        body take without fingers (Bandai, LAFAN1), or a rig without hands, which the splice
        refuses as the hand take (it has no fingers to give) unless a role override names
        them. A body with fingers (BEAT) is not one: its fingers can be spliced."""
        arms = (self.right, self.left, self.unsided)
        return not any(arm.has_fingers for arm in arms if arm is not None)

    def require(self, side: str, role: str) -> int:
        """Joint index of ``role`` on ``side``; ``RoleError`` naming the nearest
        joint names when the rig has none."""
        joint = self.get(side, role)
        if joint is not None:
            return joint
        label = role.replace("_", " ")
        if self.unsided is not None and self.unsided.get(role) is not None:
            raise RoleError(
                f"{side} {label}: this skeleton's hand joints carry no side "
                f"({self.skeleton.names[self.unsided.get(role)]}); give the side "
                f'(side_hint / --side {side}) or a roles file {{"{side}.{role}": "NAME"}}'
            )
        near = nearest_names(self.skeleton.names, side, role)
        hint = f"nearest names: {', '.join(near)}" if near else "no similar names"
        raise RoleError(
            f"{side} {label}: no joint found among {self.skeleton.n_joints} joints ({hint}); "
            f'map it with a roles file {{"{side}.{role}": "NAME"}}'
        )

    def chain(self, side: str, start: str = "shoulder", fingers: bool = True) -> list[int]:
        """Joint indices from ``start`` (a role: clavicle, shoulder, elbow or wrist) down
        the hierarchy to the wrist, every joint on the way (twist joints included),
        then, with ``fingers``, every joint below the wrist in index order.

        Starts at the highest present role at or below ``start``; ``RoleError`` if the
        side has no wrist.
        """
        arm = self.side(side)
        wrist = self.require(side, "wrist")
        order = ("clavicle", "shoulder", "elbow", "wrist")
        if start not in order:
            raise ParameterError(f"chain start must be one of {', '.join(order)}, got {start!r}")
        top = next(j for r in order[order.index(start) :] if (j := getattr(arm, r)) is not None)
        path = self.skeleton.chain_to_root(wrist)
        if top not in path:
            path = [wrist]
        else:
            path = path[: path.index(top) + 1]
        joints = path[::-1]
        if fingers:
            joints += self.skeleton.descendants(wrist)[1:]
        return joints

    def landmarks(self, side: str) -> dict[str, Landmark]:
        """Points for alignment markers, each fixed in one joint's frame (rest pose).

        ``"wrist"``: the wrist joint's origin.
        ``"hand"``: a point on the back of the hand near the knuckles: the
        ``hand_end`` joint; else the rest position of the middle finger's joint 1
        (mean of the other fingers' joint 1 without it) in the ``hand`` frame; else
        the ``hand`` joint's End Site if it has length; else estimated 0.4 forearm
        lengths beyond the wrist along the forearm (``source`` starts "estimated").
        ``"forearm"``: the middle of the forearm in the ``elbow`` frame when the elbow
        joint sits apart from the wrist; else (Leap ``rForeArm`` at the wrist, or no
        elbow joint) estimated 1.25 hand lengths back from the wrist, opposite the hand
        point, in the elbow frame (the wrist's when there is no elbow joint).

        Offsets are in file units. ``RoleError`` if the side has no wrist.
        """
        arm = self.side(side)
        wrist = self.require(side, "wrist")
        sk = self.skeleton
        hand = arm.hand if arm.hand is not None else wrist
        out = {"wrist": Landmark(wrist, np.zeros(3), "joint")}
        scale = _skeleton_scale(sk)
        forearm_vec = None  # rest vector elbow -> wrist
        if arm.elbow is not None and arm.elbow in sk.chain_to_root(wrist):
            vec = _rest_vector(sk, arm.elbow, wrist)
            if np.linalg.norm(vec) > 1e-6 * scale:
                forearm_vec = vec
        hand_point = self._hand_point(arm, hand, forearm_vec, scale)
        if hand_point is not None:
            out["hand"] = hand_point
        if forearm_vec is not None:
            out["forearm"] = Landmark(arm.elbow, 0.5 * forearm_vec, "elbow-wrist midpoint")
        elif hand_point is not None:
            # hand point relative to the wrist at rest, then back along it
            knuckle = _rest_vector(sk, wrist, hand_point.joint) + hand_point.offset
            base = arm.elbow if arm.elbow in sk.chain_to_root(wrist) else wrist
            offset = -1.25 * knuckle + (_rest_vector(sk, base, wrist) if base != wrist else 0.0)
            out["forearm"] = Landmark(
                base,
                np.asarray(offset, dtype=float),
                "estimated: 1.25 hand lengths back from the wrist",
            )
        return out

    def _hand_point(self, arm: ArmRoles, hand: int, forearm_vec, scale: float):
        sk = self.skeleton
        if arm.hand_end is not None:
            return Landmark(arm.hand_end, np.zeros(3), "hand_end joint")
        firsts = [
            arm.fingers[f][0]
            for f in ("middle", "index", "ring", "pinky")
            if arm.fingers[f] and arm.numbers[f][0] == 1
        ]
        if arm.fingers["middle"] and arm.numbers["middle"][0] == 1:
            firsts = [arm.fingers["middle"][0]]
        firsts = [j for j in firsts if hand in sk.chain_to_root(j)]
        if firsts:
            vec = np.mean([_rest_vector(sk, hand, j) for j in firsts], axis=0)
            if np.linalg.norm(vec) > 1e-6 * scale:
                return Landmark(hand, vec, "finger bases")
        end = sk.end_sites.get(hand)
        if end is not None and np.linalg.norm(end) > 1e-6 * scale:
            return Landmark(hand, np.asarray(end, dtype=float), "end site")
        if forearm_vec is not None:
            return Landmark(
                hand, 0.4 * forearm_vec, "estimated: 0.4 forearm lengths beyond the wrist"
            )
        return None

    def to_dict(self, indices: bool = False) -> dict:
        """JSON-ready roles: joint names (or indices with ``indices=True``), None where
        absent, per side, plus ``"unsided"`` and ``"side_source"``."""

        def arm_dict(arm: ArmRoles) -> dict:
            conv = (lambda j: j) if indices else self.name
            out: dict = {r: conv(getattr(arm, r)) for r in ARM_ROLES}
            out["fingers"] = {f: [conv(j) for j in arm.fingers[f]] for f in FINGERS}
            out["tips"] = {f: conv(arm.tips[f]) for f in FINGERS}
            out["metacarpals"] = {f: conv(arm.metacarpals[f]) for f in FINGERS}
            return out

        return {
            "right": arm_dict(self.right),
            "left": arm_dict(self.left),
            "unsided": None if self.unsided is None else arm_dict(self.unsided),
            "side_source": {s: self.side_source.get(s, "") for s in SIDES},
        }


# --------------------------------------------------------------------------- matching


def find_roles(
    skeleton: Skeleton, overrides: dict | None = None, side_hint: str | None = None
) -> Roles:
    """Find the arm and finger roles of ``skeleton`` from its joint names.

    Parameters
    ----------
    skeleton : Skeleton
    overrides : dict, optional
        ``{"right.wrist": "JointName" or None, ...}`` (or nested
        ``{"right": {"wrist": ...}}``); applied last, always win. Unknown keys or
        joint names raise ``ParameterError`` / ``RoleError``.
    side_hint : ``"right"``, ``"left"`` or None
        Side for joints whose names carry none (hand-only rigs such as ManipNet).
        Ignored for joints whose names say their side.

    Returns
    -------
    Roles
    """
    if side_hint is not None and side_hint not in SIDES:
        raise ParameterError(f"side_hint must be 'right', 'left' or None, got {side_hint!r}")
    labels = [_label(n) for n in skeleton.names]
    depth = _depths(skeleton)
    arms: dict[str, ArmRoles] = {}
    source: dict[str, str] = {}
    for side in SIDES:
        idx = [j for j, lab in enumerate(labels) if lab.side == side and lab.part]
        arms[side] = _match_arm(skeleton, labels, depth, idx)
        source[side] = "names" if arms[side].found else ""
    unsided_idx = [j for j, lab in enumerate(labels) if lab.side is None and lab.part]
    unsided = None
    if unsided_idx:
        candidate = _match_arm(skeleton, labels, depth, unsided_idx)
        if candidate.wrist is not None or candidate.has_fingers:
            if side_hint is not None and not arms[side_hint].found:
                arms[side_hint] = candidate
                source[side_hint] = "hint"
            elif not any(arms[s].found for s in SIDES):
                unsided = candidate
    if overrides:
        _apply_overrides(skeleton, arms, source, normalize_overrides(overrides))
    return Roles(skeleton, arms["right"], arms["left"], unsided, source)


def _depths(sk: Skeleton) -> np.ndarray:
    depth = np.zeros(sk.n_joints, dtype=np.int64)
    for j in range(sk.n_joints):
        p = sk.parents[j]
        depth[j] = depth[p] + 1 if p >= 0 else 0
    return depth


def _ancestors(sk: Skeleton, j: int) -> set[int]:
    return set(sk.chain_to_root(j)[1:])


def _match_arm(sk: Skeleton, labels: list[_Label], depth: np.ndarray, idx: list[int]) -> ArmRoles:
    by_part: dict[str, list[int]] = {}
    for j in idx:
        by_part.setdefault(labels[j].part, []).append(j)

    def shallowest(js):
        return min(js, key=lambda j: (depth[j], j)) if js else None

    def deepest(js):
        return max(js, key=lambda j: (depth[j], -j)) if js else None

    finger_joints = by_part.get("finger", [])
    wrists = by_part.get("wrist", [])
    # prefer wrist candidates that hold the fingers, then the one nearest the root
    if finger_joints and wrists:
        holding = [w for w in wrists if any(w in _ancestors(sk, f) for f in finger_joints)]
        wrists_ranked = holding or wrists
    else:
        wrists_ranked = wrists
    wrist = shallowest(wrists_ranked)

    hand = wrist
    if wrist is not None:  # zero-length wrist/hand joints below the wrist carry the palm
        scale = _skeleton_scale(sk)
        for w in sorted(wrists, key=lambda j: depth[j]):
            if (
                w != wrist
                and wrist in _ancestors(sk, w)
                and np.linalg.norm(_rest_vector(sk, wrist, w)) <= 1e-6 * scale
            ):
                hand = w

    def below_wrist(js):
        if wrist is None:
            return list(js)
        return [j for j in js if wrist in _ancestors(sk, j)]

    hand_end = shallowest(below_wrist(by_part.get("hand_end", [])))

    above = _ancestors(sk, wrist) if wrist is not None else None
    elbows = by_part.get("elbow", [])
    elbow = deepest([j for j in elbows if above is None or j in above]) if elbows else None
    if elbow is None and above is None:
        elbow = shallowest(elbows)

    anchor = elbow if elbow is not None else wrist
    upper = _ancestors(sk, anchor) if anchor is not None else None

    def ancestors_only(js):
        return [j for j in js if upper is None or j in upper]

    arm_kind = ancestors_only(by_part.get("arm", []))
    shoulder_kind = ancestors_only(by_part.get("shoulder", []))
    shoulder = deepest(arm_kind) if arm_kind else deepest(shoulder_kind)
    clavicle = None
    if shoulder is not None:
        above_shoulder = _ancestors(sk, shoulder)
        collars = [j for j in by_part.get("clavicle", []) + shoulder_kind if j in above_shoulder]
        clavicle = deepest(collars)

    fingers, numbers, tips, metacarpals = _match_fingers(
        sk, labels, depth, below_wrist(finger_joints)
    )
    return ArmRoles(
        clavicle=clavicle,
        shoulder=shoulder,
        elbow=elbow,
        wrist=wrist,
        hand=hand,
        hand_end=hand_end,
        fingers=fingers,
        tips=tips,
        metacarpals=metacarpals,
        numbers=numbers,
    )


def _match_fingers(sk, labels, depth, joints):
    fingers = {f: [] for f in FINGERS}
    numbers = {f: [] for f in FINGERS}
    tips: dict[str, int | None] = {f: None for f in FINGERS}
    metacarpals: dict[str, int | None] = {f: None for f in FINGERS}
    for f in FINGERS:
        mine = sorted((j for j in joints if labels[j].finger == f), key=lambda j: (depth[j], j))
        slots: dict[int, int] = {}
        unnumbered: list[int] = []
        for j in mine:
            lab = labels[j]
            if lab.tip:
                tips[f] = tips[f] if tips[f] is not None else j
            elif lab.metacarpal:
                metacarpals[f] = metacarpals[f] if metacarpals[f] is not None else j
            elif lab.number is not None and 1 <= lab.number <= 3:
                slots.setdefault(lab.number, j)  # a repeated number: the proximal one
            elif lab.number is not None and lab.number >= 4:
                if not sk.children(j) and tips[f] is None:  # Mixamo/HumanIK "Index4"
                    tips[f] = j
            elif lab.number is None:
                unnumbered.append(j)
        for j in unnumbered:  # fill the free numbers in hierarchy order
            free = [k for k in (1, 2, 3) if k not in slots]
            if free:
                slots[free[0]] = j
            elif tips[f] is None and not sk.children(j):
                tips[f] = j
        order = sorted(slots)
        fingers[f] = [slots[k] for k in order]
        numbers[f] = order
    return fingers, numbers, tips, metacarpals


# --------------------------------------------------------------------------- overrides


def normalize_overrides(overrides: dict, source: str = "roles") -> dict[str, str | None]:
    """Flatten and check an override mapping: ``{"right.wrist": "Name" or None}``.

    Accepts flat ``"side.role"`` keys or nested ``{"right": {"wrist": ...}}``.
    ``ParameterError`` names the bad key or value.
    """
    if not isinstance(overrides, dict):
        raise ParameterError(
            f'{source}: expected an object {{"right.wrist": "NAME"}}, '
            f"got {type(overrides).__name__}"
        )
    flat: dict[str, str | None] = {}
    for key, value in overrides.items():
        if key in SIDES and isinstance(value, dict):
            for role, name in value.items():
                flat[f"{key}.{role}"] = name
        else:
            flat[str(key)] = value
    for key, value in flat.items():
        side, _, role = key.partition(".")
        if side not in SIDES or role not in ROLE_NAMES:
            close = difflib.get_close_matches(role or side, ROLE_NAMES, n=3)
            hint = (
                f" (did you mean {', '.join(f'{side}.{c}' for c in close)}?)"
                if close and side in SIDES
                else ""
            )
            raise ParameterError(
                f"{source}: key {key!r} is not '<right|left>.<role>' with a role "
                f"from: {', '.join(ARM_ROLES)}, thumb1..pinky3, <finger>_tip, "
                f"<finger>_metacarpal{hint}"
            )
        if value is not None and not isinstance(value, str):
            raise ParameterError(f"{source}: {key}: expected a joint name or null, got {value!r}")
    return flat


def load_role_overrides(path: str | Path) -> dict[str, str | None]:
    """Read a JSON roles file ``{"right.wrist": "Bip01_R_Hand", ...}``.

    Raises ``FileNotFoundError`` for a missing file and ``ParameterError`` naming
    the file and line for invalid JSON or keys.
    """
    path = Path(path)
    return normalize_overrides(read_roles_json(path), source=path.name)


def read_roles_json(path: str | Path):
    """The JSON value of a roles file, unchecked (``load_role_overrides`` checks it).

    Raises ``FileNotFoundError`` for a missing file and ``ParameterError`` naming the
    file (and line) for a file over ``engine.base.limits.MAX_ROLES_BYTES``, text that is not
    UTF-8, invalid JSON, or JSON nested too deeply to be a roles map.
    """
    from engine.base.limits import MAX_ROLES_BYTES

    path = Path(path)
    with open(path, "rb") as f:
        raw = f.read(MAX_ROLES_BYTES + 1)
    if len(raw) > MAX_ROLES_BYTES:
        raise ParameterError(
            f"{path.name}: more than {MAX_ROLES_BYTES:,} bytes; a roles map is a small JSON object"
        )
    try:
        return parse_json(raw, finite=False)
    except JsonTextError as exc:
        raise ParameterError(
            f'{path.name}: {exc.detail}; a roles map is {{"right.wrist": "JointName", ...}}'
        ) from None


def _apply_overrides(
    sk: Skeleton, arms: dict[str, ArmRoles], source: dict[str, str], flat: dict[str, str | None]
) -> None:
    for side in SIDES:
        mine = {k.partition(".")[2]: v for k, v in flat.items() if k.startswith(side + ".")}
        if not mine:
            continue
        arm = arms[side]
        values = {r: getattr(arm, r) for r in ARM_ROLES}
        fingers = {f: dict(zip(arm.numbers[f], arm.fingers[f], strict=True)) for f in FINGERS}
        tips, metacarpals = dict(arm.tips), dict(arm.metacarpals)
        for role, name in mine.items():
            joint = None if name is None else _joint_by_name(sk, name, side, role)
            if role in ARM_ROLES:
                values[role] = joint
                if role == "wrist" and mine.get("hand", "") == "":  # hand follows the wrist
                    values["hand"] = joint
            elif role.endswith("_tip"):
                tips[role[:-4]] = joint
            elif role.endswith("_metacarpal"):
                metacarpals[role[:-11]] = joint
            else:
                f, k = role[:-1], int(role[-1])
                if joint is None:
                    fingers[f].pop(k, None)
                else:
                    fingers[f][k] = joint
        arms[side] = ArmRoles(
            **values,
            fingers={f: [fingers[f][k] for k in sorted(fingers[f])] for f in FINGERS},
            numbers={f: sorted(fingers[f]) for f in FINGERS},
            tips=tips,
            metacarpals=metacarpals,
        )
        source[side] = "override"


def _joint_by_name(sk: Skeleton, name: str, side: str, role: str) -> int:
    if name in sk.names:
        return sk.names.index(name)
    lowered = [n.lower() for n in sk.names]
    if name.lower() in lowered:
        return lowered.index(name.lower())
    near = difflib.get_close_matches(name, sk.names, n=5, cutoff=0.5)
    hint = f"nearest names: {', '.join(near)}" if near else "no similar names"
    raise RoleError(f"{side}.{role}: the skeleton has no joint named {name!r} ({hint})")


# --------------------------------------------------------------------------- helpers

_ROLE_SPELLINGS = {
    "clavicle": ["Shoulder", "Collar", "Clavicle"],
    "shoulder": ["Arm", "UpperArm", "Shoulder"],
    "elbow": ["ForeArm", "LowerArm", "Elbow"],
    "wrist": ["Hand", "Wrist"],
    "hand": ["Hand", "Wrist"],
    "hand_end": ["HandEnd", "Fingers", "FingerBase"],
}


def nearest_names(
    names: tuple[str, ...] | list[str], side: str, role: str, n: int = 5
) -> list[str]:
    """The joint names most like ``role`` on ``side`` (for error messages)."""
    _check_role(role)
    if role in _ROLE_SPELLINGS:
        words = _ROLE_SPELLINGS[role]
    else:
        finger = next(f for f in FINGERS if role.startswith(f))
        suffix = role[len(finger) :].lstrip("_")
        words = [f"Hand{finger.title()}{suffix}", f"{finger.title()}{suffix}"]
    s, s1 = side.title(), side[0].upper()
    spellings = {
        w2.lower()
        for w in words
        for w2 in (f"{s}{w}", f"{w}_{s1}", f"{s1}_{w}", f"{side[0]}{w}", f"{side}_{w}")
    }
    scored = []
    for name in names:
        flat = re.sub(r"[^a-z0-9]", "", re.split(r"[:|]", name)[-1].lower())
        score = max(difflib.SequenceMatcher(None, flat, sp).ratio() for sp in spellings)
        scored.append((score, name))
    scored.sort(key=lambda t: -t[0])
    return [name for score, name in scored[:n] if score >= 0.3]


def _check_role(role: str) -> None:
    if role not in ROLE_NAMES:
        close = difflib.get_close_matches(role, ROLE_NAMES, n=3)
        hint = f" (did you mean {', '.join(close)}?)" if close else ""
        raise ParameterError(
            f"unknown role {role!r}{hint}; roles: {', '.join(ARM_ROLES)}, "
            "thumb1..pinky3, <finger>_tip, <finger>_metacarpal"
        )


def _rest_vector(sk: Skeleton, a: int, b: int) -> np.ndarray:
    """Rest-pose vector from joint ``a`` to its descendant ``b`` (file units).

    At rest every local rotation is the identity, so this is both the world vector
    and the vector in ``a``'s (and ``b``'s) frame.
    """
    vec = np.zeros(3)
    j = b
    while j != a:
        if j < 0:
            raise ValueError(f"joint {sk.names[a]!r} is not above {sk.names[b]!r}")
        vec += sk.offsets[j]
        j = int(sk.parents[j])
    return vec


def _skeleton_scale(sk: Skeleton) -> float:
    """A length to compare offsets with: the largest non-root offset (at least 1e-12)."""
    if sk.n_joints < 2:
        return 1.0
    return max(float(np.linalg.norm(sk.offsets[1:], axis=1).max()), 1e-12)


# --------------------------------------------------------------------------- marker sets

MARKER_ROLES = ("shoulder", "elbow", "forearm", "wrist_radial", "wrist_ulnar", "hand")
# label (upper case, namespace removed) -> role; earlier entries win within a role.
# Plug-in Gait (RSHO, RELB, RFRA, RWRA, RWRB, RFIN, with an R/L side prefix), pyomeca /
# ISB-style anatomical names (ACRO_tip, EPICl, LARMl, STYLr, STYLu, LATH) and CAST-style
# short names (LE, RS, US, MCP2).
_MARKER_NAMES = {
    "shoulder": ("SHO", "ACRO_TIP", "ACRO", "ACR", "ACROMION", "AC"),
    "elbow": ("ELB", "EPICL", "LE", "LEL", "EL", "EPL", "ELBOW", "EPICM", "ME"),
    "forearm": ("FRA", "LARML", "LARMM", "LARM_ANT", "LARM_ELB", "FA", "FOREARM"),
    "wrist_radial": ("WRA", "STYLR", "RS", "RSP", "RADIAL_STYLOID"),
    "wrist_ulnar": ("WRB", "STYLU", "US", "USP", "ULNAR_STYLOID"),
    "hand": ("FIN", "LATH", "MCP2", "MH2", "MEDH", "MCP5", "HAND"),
}
_MARKER_VOCAB = {name: role for role, names in _MARKER_NAMES.items() for name in names}
_MARKER_RANK = {name: rank for names in _MARKER_NAMES.values() for rank, name in enumerate(names)}
_SIDED_LABEL = (re.compile(r"^(R|L|RIGHT|LEFT)[_ .-]?(.+)$"), re.compile(r"^(.+?)[_ .-](R|L)$"))


@dataclass(frozen=True, eq=False)
class MarkerRoles:
    """Marker indices per side for the alignment markers of docs/method.md (a marker set's
    counterpart of ``Roles``): ``shoulder``, ``elbow``, ``forearm``, ``wrist_radial``,
    ``wrist_ulnar``, ``hand`` (back of the hand, 2nd metacarpal head), None if absent.
    ``unsided`` holds the roles of labels that carry no side when no hint was given."""

    labels: tuple[str, ...]
    right: dict[str, int | None]
    left: dict[str, int | None]
    unsided: dict[str, int | None] | None = None
    side_source: dict[str, str] = field(default_factory=dict)

    def side(self, side: str) -> dict[str, int | None]:
        if side not in SIDES:
            raise ParameterError(f"side must be 'right' or 'left', got {side!r}")
        return self.right if side == "right" else self.left

    def require(self, side: str, role: str) -> int:
        """Marker index of ``role`` on ``side``; ``RoleError`` naming similar labels."""
        if role not in MARKER_ROLES:
            raise ParameterError(f"unknown marker role {role!r}; roles: {', '.join(MARKER_ROLES)}")
        index = self.side(side)[role]
        if index is not None:
            return index
        if self.unsided is not None and self.unsided.get(role) is not None:
            raise RoleError(
                f"{side} {role.replace('_', ' ')}: the marker labels carry no side "
                f"({self.labels[self.unsided[role]]}); give the side (--side {side})"
            )
        near = difflib.get_close_matches(
            role.upper(), [lab.upper() for lab in self.labels], n=5, cutoff=0.3
        )
        hint = f"nearest labels: {', '.join(near)}" if near else "no similar labels"
        raise RoleError(
            f"{side} {role.replace('_', ' ')}: no marker found among "
            f"{len(self.labels)} labels ({hint})"
        )

    def to_dict(self) -> dict:
        def names(d):
            return (
                None
                if d is None
                else {r: (None if d[r] is None else self.labels[d[r]]) for r in MARKER_ROLES}
            )

        return {
            "right": names(self.right),
            "left": names(self.left),
            "unsided": names(self.unsided),
            "side_source": {s: self.side_source.get(s, "") for s in SIDES},
        }


def find_marker_roles(labels, side_hint: str | None = None) -> MarkerRoles:
    """Alignment-marker roles of a marker set from its labels.

    Labels are read without a ``Subject:`` namespace, case-insensitively; a side comes
    from an ``R``/``L``/``Right``/``Left`` prefix or an ``_R``/``_L`` suffix (Plug-in
    Gait ``RWRA``). Labels without a side (pyomeca ``STYLr``, ``ACRO_tip``) go to
    ``side_hint``, else to ``unsided``. Within a role the conventional marker wins
    (lateral epicondyle over medial, ``LATH`` over ``MEDH``).
    """
    if side_hint is not None and side_hint not in SIDES:
        raise ParameterError(f"side_hint must be 'right', 'left' or None, got {side_hint!r}")
    labels = tuple(str(lab) for lab in labels)
    found: dict[str, dict[str, tuple[int, int]]] = {"right": {}, "left": {}, "": {}}
    for i, label in enumerate(labels):
        key = re.split(r"[:|]", label)[-1].strip().upper()
        side, name = "", key
        if key not in _MARKER_VOCAB:
            for pattern in _SIDED_LABEL:
                m = pattern.match(key)
                if not m:
                    continue
                a, b = m.groups()
                side_word, rest = (a, b) if pattern is _SIDED_LABEL[0] else (b, a)
                if rest in _MARKER_VOCAB:
                    side, name = ("right" if side_word[0] == "R" else "left"), rest
                    break
        role = _MARKER_VOCAB.get(name)
        if role is None:
            continue
        rank = _MARKER_RANK[name]
        if role not in found[side] or rank < found[side][role][0]:
            found[side][role] = (rank, i)

    def as_dict(d):
        return {r: (d[r][1] if r in d else None) for r in MARKER_ROLES}

    sides = {s: as_dict(found[s]) for s in SIDES}
    source = {s: "names" if found[s] else "" for s in SIDES}
    unsided = None
    if found[""]:
        if side_hint is not None and not found[side_hint]:
            sides[side_hint] = as_dict(found[""])
            source[side_hint] = "hint"
        elif not found["right"] and not found["left"]:
            unsided = as_dict(found[""])
    return MarkerRoles(labels, sides["right"], sides["left"], unsided, source)
