"""Transfer the hand take's wrist and finger rotations onto the body skeleton (docs/method.md §6).

The body keeps every joint down to the forearm. Per spliced side:

* **Wrist**: the hand's orientation relative to the forearm in the hand take,
  ``R = G_hand(forearm)^-1 G_hand(hand)`` (world rotations, so twist joints in
  between count), is given to the body's hand relative to its own forearm, when
  the hand take measured a forearm (an elbow joint away from the wrist). A hand take
  rooted at the wrist (ManipNet ``WRIST``) or at a forearm joint sitting on the wrist
  (Leap ``rForeArm``, whose ``rHand`` rotation is always the identity) has no
  forearm: the body keeps its own wrist rotation.
* **Fingers** the body has (matched by role: finger and joint number): the
  rotation of each finger joint relative to the previous matched joint (the hand
  joint for joint 1).
* **Fingers** the body lacks: the hand take's whole finger subtree is grafted
  under the body's hand joint, offsets turned into the body's axes and scaled to
  the body's hand size (forearm length ratio; palm length / 0.36 for rigs without
  an elbow), named ``<body wrist>_<finger><k>``.

Rotations move between rigs *relative to the rest pose*: each joint gets a rest
anatomical frame ``F`` (columns: bone direction, radial, dorsal; the hand's from
:func:`engine.align.features.hand_frame`, a finger joint's from its bone and the hand's
dorsal axis) and a relative rotation ``R_A`` between two joints of the hand take
becomes ``U_parent R_A U_child^T`` with ``U = F_body F_hand^T``. Two takes of the
same rig get ``U = I`` (rotations copied exactly); different axes (z-up/y-up),
units, rest poses and joint orientations are absorbed by ``U``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from engine.align.features import HAND_TO_FOREARM, HandFrame
from engine.base.errors import RoleError, check_cancelled
from engine.model import rotations as rot
from engine.model.fastkin import (
    continuous_inplace,
    forward_kinematics,
    normalize_inplace,
    place_body,
    qmul,
    qmul_conj,
    sample_rotations,
    world_rotations,
)
from engine.model.kinematics import rest_positions
from engine.model.motion import Motion, Skeleton
from engine.model.roles import FINGERS
from engine.model.translations import Translations


@dataclass(frozen=True)
class FingerMap:
    """One output finger joint driven by the hand take (a body joint or one inserted).

    body : output joint index; hand : hand-take joint index
    body_parent, hand_parent : the previous driven joints (the hand joints above joint 1)
    u_parent, u_child : (4,) quaternions ``U`` for the parent and the joint
    between : output indices of body joints between ``body_parent`` and ``body`` (twist
        joints the hand take lacks: they keep the body's rotations), root side first
    """

    body: int
    hand: int
    body_parent: int
    hand_parent: int
    u_parent: np.ndarray
    u_child: np.ndarray
    between: tuple[int, ...] = ()


@dataclass(frozen=True)
class SidePlan:
    """How one side is transferred. Joint indices of ``body_frame`` are the body take's;
    ``TransferPlan.body_index`` turns them into output indices."""

    side: str
    body_frame: HandFrame
    hand_frame: HandFrame
    u_hand: np.ndarray  # (4,) quaternion F_body F_hand^T of the hand frames
    wrist: bool  # transfer the wrist rotation
    mapped: tuple[FingerMap, ...]  # body finger joints and joints inserted in their chains
    grafted: tuple[tuple[int, int], ...]  # (new output joint, hand-take joint)
    scale: float  # hand-take file units -> body file units for grafted offsets
    inserted: tuple[int, ...] = ()  # output joints inserted in the body's finger chains


@dataclass(frozen=True)
class TransferPlan:
    """Output skeleton (body + inserted and grafted finger joints) and the per-side plans.

    ``body_index[j]`` is the output index of body joint ``j`` (body joints keep their
    order; a joint inserted above a body finger joint comes just before it).
    """

    skeleton: Skeleton
    sides: tuple[SidePlan, ...]
    n_body_joints: int
    notes: tuple[str, ...] = field(default_factory=tuple)
    body_index: np.ndarray | None = None

    def out(self, body_joint: int) -> int:
        """Output index of a body joint."""
        return int(body_joint if self.body_index is None else self.body_index[body_joint])


def _unit(v):
    n = float(np.linalg.norm(v))
    return v / n if n > 1e-12 else v


def _bone_along(rest: np.ndarray, skeleton: Skeleton, j: int) -> np.ndarray | None:
    """Unit rest direction of the bone below ``j``: to the first descendant (first child
    first) that sits away from it, else along the End Site of ``j`` or of a zero-length
    descendant; None when there is none."""
    stack = list(reversed(skeleton.children(j)))
    while stack:
        c = stack.pop()
        v = rest[c] - rest[j]
        if np.linalg.norm(v) > 1e-9:
            return _unit(v)
        stack.extend(reversed(skeleton.children(c)))
    for k in [j] + skeleton.descendants(j)[1:]:
        end = skeleton.end_sites.get(k)
        if end is not None and np.linalg.norm(rest[k] - rest[j] + end) > 1e-9:
            return _unit(rest[k] - rest[j] + np.asarray(end, dtype=float))
    return None


def _joint_frame(
    rest: np.ndarray,
    skeleton: Skeleton,
    j: int,
    dorsal: np.ndarray,
    fallback_along: np.ndarray,
    side: str,
) -> np.ndarray:
    """(3, 3) rest anatomical frame of joint ``j``: bone direction, radial, dorsal."""
    along = _bone_along(rest, skeleton, j)
    if along is None:
        p = skeleton.parents[j]
        while p >= 0 and np.linalg.norm(rest[j] - rest[p]) <= 1e-9:
            p = skeleton.parents[p]
        v = rest[j] - rest[p] if p >= 0 else np.zeros(3)
        along = _unit(v) if np.linalg.norm(v) > 1e-9 else fallback_along
    n = dorsal - along * np.dot(dorsal, along)
    if np.linalg.norm(n) < 1e-6:  # bone along the dorsal axis: use the radial side instead
        n = np.cross(along, fallback_along)
        if np.linalg.norm(n) < 1e-6:
            n = (
                np.cross(along, [1.0, 0.0, 0.0])
                if abs(along[0]) < 0.9
                else np.cross(along, [0, 1.0, 0])
            )
    n = _unit(n)
    radial = np.cross(n, along) if side == "right" else np.cross(along, n)
    return np.column_stack([along, _unit(radial), n])


def _quat(m: np.ndarray) -> np.ndarray:
    return rot.from_matrix(m)


def _anchors(sk: Skeleton, arm, finger: str, chain: list[int]) -> dict[int, int]:
    """Role number -> joint on ``chain``: metacarpal 0, joints 1..3, tip 4."""
    out = {
        k: j for k, j in zip(arm.numbers[finger], arm.fingers[finger], strict=True) if j in chain
    }
    if arm.metacarpals[finger] in chain:
        out[0] = arm.metacarpals[finger]
    if arm.tips[finger] in chain:
        out[4] = arm.tips[finger]
    return out


class _Builder:
    """The output skeleton under construction: body joints (keys ``("b", j)``) and new
    joints (``("n", k)``), each with a parent key, offset, channels and End Site."""

    def __init__(self, sk: Skeleton):
        self.parent = {
            ("b", j): (("b", int(p)) if p >= 0 else None) for j, p in enumerate(sk.parents)
        }
        self.offset = {("b", j): np.asarray(sk.offsets[j], dtype=float) for j in range(sk.n_joints)}
        self.name = {("b", j): sk.names[j] for j in range(sk.n_joints)}
        self.channels = {("b", j): sk.channels[j] for j in range(sk.n_joints)}
        self.end = {("b", j): v for j, v in sk.end_sites.items()}
        self.n_body = sk.n_joints
        self.new_keys: list[tuple[str, int]] = []
        self.taken = list(sk.names)

    def add(self, name: str, parent, offset, channels) -> tuple[str, int]:
        key = ("n", len(self.new_keys))
        self.new_keys.append(key)
        self.parent[key] = parent
        self.offset[key] = np.asarray(offset, dtype=float)
        self.name[key] = name
        self.channels[key] = channels
        self.taken.append(name)
        return key

    def build(self) -> tuple[Skeleton, dict]:
        """(skeleton, key -> output index); a joint that gained children here loses a
        zero-length End Site (Blender draws one as a stub)."""
        order: list = []
        placed: set = set()

        def emit(key):
            todo = []
            while key is not None and key not in placed:
                todo.append(key)
                key = self.parent[key]
            for k in reversed(todo):
                placed.add(k)
                order.append(k)

        for j in range(self.n_body):
            emit(("b", j))
        for key in self.new_keys:
            emit(key)
        index = {k: i for i, k in enumerate(order)}
        parents = [index[self.parent[k]] if self.parent[k] is not None else -1 for k in order]
        with_new_kids = {self.parent[k] for k in self.new_keys}
        ends = {}
        for k, v in self.end.items():
            if k in with_new_kids and k[0] == "b":
                continue  # fingers now hang here: the old End Site would be a stub
            ends[index[k]] = np.asarray(v, dtype=float)
        skeleton = Skeleton(
            names=tuple(self.name[k] for k in order),
            parents=np.array(parents),
            offsets=np.array([self.offset[k] for k in order]),
            channels=tuple(self.channels[k] for k in order),
            end_sites=ends,
        )
        return skeleton, index


def plan_transfer(
    body: Motion,
    hand: Motion,
    body_roles,
    hand_roles,
    body_frames: dict[str, HandFrame],
    hand_frames: dict[str, HandFrame],
    sides: tuple[str, ...],
) -> TransferPlan:
    """Decide, per side, which body joints the hand take drives and what to insert or graft.

    Every joint of the hand take's finger chains is carried: a joint matched by role
    (metacarpal, 1..3, tip) drives the body's joint; a joint the body's finger lacks
    (ManipNet ``THUMB_CMC_AA``, twist or extra joints) is inserted in the body's chain
    (on the body's bone, at the hand take's share of the chain length) or, past the
    body's last joint, appended; a finger the body lacks is grafted whole.

    Raises ``RoleError`` when the hand take has no finger joints on a side.
    """
    sk_b, sk_h = body.skeleton, hand.skeleton
    rest_h = rest_positions(sk_h)
    bld = _Builder(sk_b)
    drafts = []
    notes = []
    for side in sides:
        fb, fh = body_frames[side], hand_frames[side]
        arm_b, arm_h = body_roles.side(side), hand_roles.side(side)
        if not any(arm_h.fingers[f] for f in FINGERS):
            raise RoleError(f"{side} hand of {_src(hand)}: no finger joints to transfer")
        u_hand_m = fb.basis @ fh.basis.T
        # the wrist's rotation relative to the forearm means something only when the hand
        # take measured a forearm (an elbow joint away from the wrist). Leap takes put the
        # whole hand orientation on a forearm joint sitting at the wrist (the wrist's own
        # rotation is always identity) and ManipNet has no forearm: the body keeps its wrist.
        wrist = fh.elbow_apart
        if not wrist:
            notes.append(
                f"{side}: the hand take has no measured forearm (no elbow joint away "
                "from the wrist); the body keeps its own wrist rotation"
            )
        hand_b, hand_h = fb.hand_joint, fh.hand_joint
        driven: list[tuple] = []  # (body key, hand joint, body parent key, hand parent)
        grafted: list[tuple] = []  # (new key, hand joint)
        inserted: list[tuple] = []
        size = graft_scale(fb, fh)
        order = _rotation_order(sk_b, fb.wrist)
        wrist_name = sk_b.names[fb.wrist]
        for finger in FINGERS:
            chain_h = arm_h.finger_chain(sk_h, finger, hand_h)
            if not chain_h:
                continue
            chain_b = arm_b.finger_chain(sk_b, finger, hand_b)
            if chain_b:
                _carry_chain(
                    bld,
                    sk_b,
                    sk_h,
                    rest_h,
                    finger,
                    arm_b,
                    arm_h,
                    chain_b,
                    chain_h,
                    hand_b,
                    hand_h,
                    wrist_name,
                    size,
                    u_hand_m,
                    driven,
                    inserted,
                )
                continue
            # graft the hand take's subtree of this finger under the body's hand joint
            top = chain_h[0]
            new_index = {}
            for a in sk_h.descendants(top):
                if a == top:
                    parent_new = ("b", hand_b)
                    off_h = rest_h[a] - rest_h[hand_h]
                else:
                    parent_new = new_index[sk_h.parents[a]]
                    off_h = sk_h.offsets[a]
                name = _graft_name(wrist_name, finger, arm_h, a, sk_h.names[a], bld.taken)
                key = bld.add(
                    name,
                    parent_new,
                    size * (u_hand_m @ np.asarray(off_h, float)),
                    tuple(f"{c}rotation" for c in order),
                )
                new_index[a] = key
                if a in sk_h.end_sites:
                    bld.end[key] = size * (u_hand_m @ np.asarray(sk_h.end_sites[a]))
                grafted.append((key, a))
        drafts.append((side, fb, fh, u_hand_m, bool(wrist), driven, grafted, inserted, size))
    skeleton, index = bld.build()
    rest_o = rest_positions(skeleton)
    body_index = np.array([index[("b", j)] for j in range(sk_b.n_joints)])
    plans = []
    for side, fb, fh, u_hand_m, wrist, driven, grafted, inserted, size in drafts:
        u_hand = _quat(u_hand_m)
        frames_u = {}
        mapped = []
        for key, h, parent_key, h_parent in driven:
            b = index[key]
            frame_b = _joint_frame(rest_o, skeleton, b, fb.dorsal, fb.along, side)
            frame_h = _joint_frame(rest_h, sk_h, h, fh.dorsal, fh.along, side)
            u_child = _quat(frame_b @ frame_h.T)
            frames_u[key] = u_child
            u_parent = frames_u.get(parent_key, u_hand)
            bp = index[parent_key]
            between = []
            j = int(skeleton.parents[b])
            while j != bp and j >= 0:
                between.append(j)
                j = int(skeleton.parents[j])
            mapped.append(FingerMap(b, h, bp, h_parent, u_parent, u_child, tuple(between[::-1])))
        plans.append(
            SidePlan(
                side=side,
                body_frame=fb,
                hand_frame=fh,
                u_hand=u_hand,
                wrist=wrist,
                mapped=tuple(mapped),
                grafted=tuple((index[k], a) for k, a in grafted),
                scale=size,
                inserted=tuple(index[k] for k in inserted),
            )
        )
        n_ins = len(inserted)
        if n_ins:
            notes.append(
                f"{side}: {n_ins} finger joint{'s' if n_ins > 1 else ''} of the hand "
                f"take the body lacks inserted in its finger chains: "
                + ", ".join(skeleton.names[index[k]] for k in inserted)
            )
    return TransferPlan(
        skeleton=skeleton,
        sides=tuple(plans),
        n_body_joints=sk_b.n_joints,
        notes=tuple(notes),
        body_index=body_index,
    )


def _carry_chain(
    bld: _Builder,
    sk_b: Skeleton,
    sk_h: Skeleton,
    rest_h: np.ndarray,
    finger: str,
    arm_b,
    arm_h,
    chain_b: list[int],
    chain_h: list[int],
    hand_b: int,
    hand_h: int,
    wrist_name: str,
    size: float,
    u_hand_m: np.ndarray,
    driven: list,
    inserted: list,
) -> None:
    """Drive the body's finger chain with every joint of the hand take's chain.

    Matched joints (same role number, in order along both chains) drive body joints.
    Hand joints between two matched ones go in new joints on the body's bone above the
    next matched body joint, at the hand chain's length fractions (so the chord from one
    matched joint to the next keeps the hand take's direction); hand joints past the
    last matched one are appended below it. Appends (body key, hand joint, body parent
    key, hand parent) to ``driven`` and new keys to ``inserted``.
    """
    anc_h = _anchors(sk_h, arm_h, finger, chain_h)
    anc_b = _anchors(sk_b, arm_b, finger, chain_b)
    pairs = []
    for k in sorted(set(anc_h) & set(anc_b)):
        h, b = anc_h[k], anc_b[k]
        if pairs and (
            chain_h.index(h) <= chain_h.index(pairs[-1][0])
            or chain_b.index(b) <= chain_b.index(pairs[-1][1])
        ):
            continue
        pairs.append((h, b))
    if not pairs:
        return
    chans = sk_b.channels[chain_b[0]]
    rot_chans = tuple(c for c in chans if c.endswith("rotation")) or (
        "Zrotation",
        "Xrotation",
        "Yrotation",
    )
    prev_key, prev_h = ("b", hand_b), hand_h
    for h, b in pairs:
        extras = chain_h[chain_h.index(prev_h) + 1 if prev_h in chain_h else 0 : chain_h.index(h)]
        key_b = ("b", b)
        if extras:
            lengths = np.array(
                [np.linalg.norm(rest_h[e] - rest_h[sk_h.parents[e]]) for e in extras + [h]]
            )
            total = float(lengths.sum())
            frac = np.cumsum(lengths) / total if total > 1e-12 else np.zeros(lengths.size)
            bone = bld.offset[key_b]
            parent, done = bld.parent[key_b], 0.0
            for e, f in zip(extras, frac[:-1], strict=True):
                name = _unique(f"{sk_b.names[b]}_{sk_h.names[e]}", bld.taken)
                key = bld.add(name, parent, (f - done) * bone, rot_chans)
                driven.append((key, e, prev_key, prev_h))
                inserted.append(key)
                prev_key, prev_h, parent, done = key, e, key, f
            bld.parent[key_b] = parent
            bld.offset[key_b] = (1.0 - done) * bone
        driven.append((key_b, h, prev_key, prev_h))
        prev_key, prev_h = key_b, h
    # hand joints past the last matched one: appended below it
    for e in chain_h[chain_h.index(prev_h) + 1 :]:
        name = _unique(f"{wrist_name}_{finger}_{sk_h.names[e]}", bld.taken)
        key = bld.add(
            name, prev_key, size * (u_hand_m @ np.asarray(sk_h.offsets[e], float)), rot_chans
        )
        if e in sk_h.end_sites:
            bld.end[key] = size * (u_hand_m @ np.asarray(sk_h.end_sites[e], float))
        driven.append((key, e, prev_key, prev_h))
        inserted.append(key)
        prev_key, prev_h = key, e


def _unique(base: str, taken: list[str]) -> str:
    name, c = base, 2
    while name in taken:
        name = f"{base}_{c}"
        c += 1
    return name


def graft_scale(body: HandFrame, hand: HandFrame) -> float:
    """Hand-take file units -> body file units for grafted offsets, scaled to the body's hand.

    Both rigs with a real forearm: the ratio of forearm lengths (1 for the same rig).
    Otherwise the ratio of hand lengths (wrist to middle finger tip), the body's measured
    from its own fingers or estimated as 0.72 forearm lengths.
    """
    if body.elbow_apart and hand.elbow_apart:
        return body.forearm_length / hand.forearm_length
    if not hand.hand_length:
        return body.forearm_length / hand.forearm_length
    target = body.hand_length or HAND_TO_FOREARM * body.forearm_length
    return target / hand.hand_length


def _src(motion: Motion) -> str:
    from pathlib import Path

    return Path(motion.meta.source).name if motion.meta.source else "the hand take"


def _rotation_order(sk: Skeleton, j: int) -> str:
    return sk.rotation_order(j)


def _graft_name(
    wrist_name: str, finger: str, arm_h, joint: int, hand_name: str, taken: list[str]
) -> str:
    base = None
    for k, j in zip(arm_h.numbers[finger], arm_h.fingers[finger], strict=True):
        if j == joint:
            base = f"{wrist_name}_{finger}{k}"
    if base is None:
        base = f"{wrist_name}_{finger}_{hand_name}"
    return _unique(base, taken)


def _conj_u(u: np.ndarray, r: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``u * r * v^-1`` broadcast over frames (``u``, ``v`` (4,) or (K, 4))."""
    return qmul(qmul(u, r), rot.conjugate(v))


#: frames per block in :func:`apply_transfer` (bounds its temporaries: about 2 MB per
#: 100 hand joints per 1,000 frames and array)
TRANSFER_CHUNK = 2048


def apply_transfer(
    plan: TransferPlan,
    body: Motion,
    hand: Motion,
    hand_times: np.ndarray,
    body_fk=None,
    cancelled=None,
) -> Motion:
    """The spliced take: ``body`` with the hand take sampled at ``hand_times``.

    Parameters
    ----------
    plan : TransferPlan from :func:`plan_transfer`
    body, hand : Motion
    hand_times : (n,) float
        Frame of the original hand take for every body frame (the merged warp).
    body_fk : (positions or None, rotations), optional
        Forward kinematics of the body take (reused from the features; only the world
        rotations ``(n, J, 4)`` are read).
    cancelled : callable or None
        Asked before each block of ``TRANSFER_CHUNK`` frames; once it returns True the
        transfer stops with ``engine.base.errors.Cancelled`` (the app gives up a preview's
        splice of a long take when a newer edit is being solved: 0.7 s of CPU at
        72,000 frames that would share the cores with that edit's solve).

    Returns a Motion on ``plan.skeleton`` at the body's frame rate and units.

    Memory: the output's rotations and its moving joints' translations (the body's
    moving joints: the root's path; the others stored once) plus temporaries for
    ``TRANSFER_CHUNK`` frames at a time (sampling, forward kinematics of the hand
    take, relative rotations); every step is per frame except the sign continuity of
    the quaternions, done in place at the end.
    """
    n = body.n_frames
    t = np.asarray(hand_times, dtype=float)
    if t.shape != (n,):
        raise ValueError(f"transfer: hand_times must have {n} entries, got {t.shape}")
    g_b = body_fk[1] if body_fk is not None else None
    jn = plan.skeleton.n_joints
    nb = plan.n_body_joints
    rots = np.empty((n, jn, 4))
    # only the body's moving joints move in the output (the others keep their offsets):
    # their frames are kept, the rest once (Translations)
    bi = np.arange(nb) if plan.body_index is None else np.asarray(plan.body_index)
    moving = bi[body.translations.joints]
    order = np.argsort(moving)
    moving = moving[order]
    positions = np.empty((n, moving.size, 3))
    fixed = np.asarray(plan.skeleton.offsets, dtype=float)
    used = hand_joints_read(plan, hand.skeleton)
    for f0 in range(0, n, TRANSFER_CHUNK):
        check_cancelled(cancelled)
        f1 = min(n, f0 + TRANSFER_CHUNK)
        if g_b is None:
            gb = forward_kinematics(body.frames(f0, f1))[1]
        else:
            gb = g_b[f0:f1]
        trans = np.empty((f1 - f0, jn, 3))
        _transfer_block(plan, body, hand, t[f0:f1], gb, f0, f1, rots[f0:f1], trans, nb, used)
        positions[f0:f1] = trans[:, moving]
        if f0 == 0:
            fixed = trans[0].copy()
        del trans
    continuous_inplace(rots)
    translations = Translations(fixed, moving, positions)
    return Motion(plan.skeleton, rots, translations, body.fps, replace(body.meta, format="derived"))


def hand_joints_read(plan: TransferPlan, hand_skeleton: Skeleton) -> np.ndarray:
    """Hand-take joints whose rotations :func:`apply_transfer` reads (local or world), with
    every ancestor (world rotations need them), ascending (parents first)."""
    wanted: set[int] = set()
    for sp in plan.sides:
        fh = sp.hand_frame
        if sp.wrist:
            wanted |= {fh.forearm_joint, fh.hand_joint}
        for fm in sp.mapped:
            wanted |= {fm.hand_parent, fm.hand}
        if sp.grafted:
            wanted |= {fh.hand_joint} | {g[1] for g in sp.grafted}
    used: set[int] = set()
    for j in wanted:
        used.update(hand_skeleton.chain_to_root(j))
    return np.array(sorted(used), dtype=np.int64)


def _transfer_block(
    plan: TransferPlan,
    body: Motion,
    hand: Motion,
    t: np.ndarray,
    g_b: np.ndarray,
    f0: int,
    f1: int,
    rots: np.ndarray,
    trans: np.ndarray,
    nb: int,
    used: np.ndarray,
) -> None:
    """Body frames ``f0..f1-1`` of :func:`apply_transfer` into ``rots``/``trans`` (views).

    Body joint ``j`` is output joint ``plan.body_index[j]`` (joints inserted in finger
    chains sit between body joints). ``used``: :func:`hand_joints_read` (only those hand
    joints are sampled and chained: rotations, no positions)."""
    n = f1 - f0
    sk_o = plan.skeleton
    col = np.full(hand.skeleton.n_joints, -1, dtype=np.int64)
    col[used] = np.arange(used.size)
    parents = np.asarray(hand.skeleton.parents)[used]
    h_local = sample_rotations(hand, t, used)
    g_h = world_rotations(h_local, np.where(parents >= 0, col[np.maximum(parents, 0)], -1))
    body_rot = body.rotations[f0:f1]
    bi = np.arange(nb) if plan.body_index is None else np.asarray(plan.body_index)
    # identity quaternions and rest offsets, then the body's joints; a body joint below an
    # inserted one keeps its motion less the inserted offset
    delta = sk_o.offsets[bi] - body.skeleton.offsets
    place_body(rots, trans, body_rot, body.translations[f0:f1], sk_o.offsets, delta, bi)
    sk_b = body.skeleton
    for sp in plan.sides:
        fb, fh = sp.body_frame, sp.hand_frame
        u = sp.u_hand
        if sp.wrist:
            r_rel = qmul_conj(g_h[:, col[fh.forearm_joint]], g_h[:, col[fh.hand_joint]])
            desired = qmul(g_b[:, fb.forearm_joint], _conj_u(u, r_rel, u))
            parent = sk_b.parents[fb.wrist]
            local = qmul_conj(g_b[:, parent], desired) if parent >= 0 else desired
            if fb.hand_joint != fb.wrist:  # palm carried by a joint below the wrist (CMU)
                between = rot.identity((n,))
                for j in sk_b.chain_to_root(fb.hand_joint)[:-1]:
                    if j == fb.wrist:
                        break
                    between = qmul(body_rot[:, j], between)
                local = qmul(local, rot.conjugate(between))
            rots[:, bi[fb.wrist]] = local
        if sp.mapped:
            hp = col[[fm.hand_parent for fm in sp.mapped]]
            hj = col[[fm.hand for fm in sp.mapped]]
            r_rel = qmul_conj(g_h[:, hp], g_h[:, hj])
            u_p = np.stack([fm.u_parent for fm in sp.mapped])
            u_c = np.stack([fm.u_child for fm in sp.mapped])
            desired = _conj_u(u_p, r_rel, u_c)
            for k, fm in enumerate(sp.mapped):
                # body joints between the driven parent and this joint keep their rotations
                between = None
                for j in fm.between:
                    between = rots[:, j] if between is None else qmul(between, rots[:, j])
                rots[:, fm.body] = (
                    desired[:, k] if between is None else qmul_conj(between, desired[:, k])
                )
        if sp.grafted:
            new = np.array([g[0] for g in sp.grafted])
            src = col[np.array([g[1] for g in sp.grafted])]
            top = sk_o.parents[new] == bi[fb.hand_joint]
            r_rel = h_local[:, src].copy()
            if top.any():
                r_rel[:, top] = qmul_conj(g_h[:, [col[fh.hand_joint]]], g_h[:, src[top]])
            rots[:, new] = _conj_u(u, r_rel, u)
    normalize_inplace(rots)  # rots is a contiguous block of frames of the output
