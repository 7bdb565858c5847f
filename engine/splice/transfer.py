"""Transfer the hand take's wrist and finger rotations onto the body skeleton (METHOD.md §6).

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
:func:`engine.features.hand_frame`, a finger joint's from its bone and the hand's
dorsal axis) and a relative rotation ``R_A`` between two joints of the hand take
becomes ``U_parent R_A U_child^T`` with ``U = F_body F_hand^T``. Two takes of the
same rig get ``U = I`` (rotations copied exactly); different axes (z-up/y-up),
units, rest poses and joint orientations are absorbed by ``U``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from engine import rotations as rot
from engine.errors import RoleError
from engine.fastkin import (
    continuous_inplace,
    forward_kinematics,
    normalize_inplace,
    qmul,
    qmul_conj,
    sample,
)
from engine.features import HAND_TO_FOREARM, HandFrame
from engine.kinematics import rest_positions
from engine.motion import Motion, Skeleton
from engine.roles import FINGERS


@dataclass(frozen=True)
class FingerMap:
    """One body finger joint driven by the hand take.

    body : body joint index; hand : hand-take joint index
    body_parent, hand_parent : the previous matched joints (hand joints for joint 1)
    u_parent, u_child : (4,) quaternions ``U`` for the parent and the joint
    """

    body: int
    hand: int
    body_parent: int
    hand_parent: int
    u_parent: np.ndarray
    u_child: np.ndarray


@dataclass(frozen=True)
class SidePlan:
    """How one side is transferred."""

    side: str
    body_frame: HandFrame
    hand_frame: HandFrame
    u_hand: np.ndarray  # (4,) quaternion F_body F_hand^T of the hand frames
    wrist: bool  # transfer the wrist rotation
    mapped: tuple[FingerMap, ...]
    grafted: tuple[tuple[int, int], ...]  # (new body joint, hand-take joint)
    scale: float  # hand-take file units -> body file units for grafted offsets


@dataclass(frozen=True)
class TransferPlan:
    """Output skeleton (body + grafted fingers) and the per-side plans."""

    skeleton: Skeleton
    sides: tuple[SidePlan, ...]
    n_body_joints: int
    notes: tuple[str, ...] = field(default_factory=tuple)


def _unit(v):
    n = float(np.linalg.norm(v))
    return v / n if n > 1e-12 else v


def _joint_frame(rest: np.ndarray, skeleton: Skeleton, j: int, dorsal: np.ndarray,
                 fallback_along: np.ndarray, side: str) -> np.ndarray:
    """(3, 3) rest anatomical frame of joint ``j``: bone direction, radial, dorsal."""
    kids = skeleton.children(j)
    along = None
    for c in kids:
        v = rest[c] - rest[j]
        if np.linalg.norm(v) > 1e-9:
            along = _unit(v)
            break
    if along is None and j in skeleton.end_sites and np.linalg.norm(skeleton.end_sites[j]) > 1e-9:
        along = _unit(np.asarray(skeleton.end_sites[j], dtype=float))
    if along is None:
        p = skeleton.parents[j]
        v = rest[j] - rest[p] if p >= 0 else np.zeros(3)
        along = _unit(v) if np.linalg.norm(v) > 1e-9 else fallback_along
    n = dorsal - along * np.dot(dorsal, along)
    if np.linalg.norm(n) < 1e-6:  # bone along the dorsal axis: use the radial side instead
        n = np.cross(along, fallback_along)
        if np.linalg.norm(n) < 1e-6:
            n = np.cross(along, [1.0, 0.0, 0.0]) if abs(along[0]) < 0.9 else np.cross(along, [0, 1.0, 0])
    n = _unit(n)
    radial = np.cross(n, along) if side == "right" else np.cross(along, n)
    return np.column_stack([along, _unit(radial), n])


def _quat(m: np.ndarray) -> np.ndarray:
    return rot.from_matrix(m)


def plan_transfer(body: Motion, hand: Motion, body_roles, hand_roles,
                  body_frames: dict[str, HandFrame], hand_frames: dict[str, HandFrame],
                  sides: tuple[str, ...]) -> TransferPlan:
    """Decide, per side, which body joints the hand take drives and what to graft.

    Raises ``RoleError`` when the hand take has no finger joints on a side.
    """
    sk_b, sk_h = body.skeleton, hand.skeleton
    rest_b, rest_h = rest_positions(sk_b), rest_positions(sk_h)
    names = list(sk_b.names)
    parents = list(sk_b.parents)
    offsets = [o for o in sk_b.offsets]
    channels = list(sk_b.channels)
    end_sites = dict(sk_b.end_sites)
    plans = []
    notes = []
    for side in sides:
        fb, fh = body_frames[side], hand_frames[side]
        arm_b, arm_h = body_roles.side(side), hand_roles.side(side)
        if not any(arm_h.fingers[f] for f in FINGERS):
            raise RoleError(f"{side} hand of {_src(hand)}: no finger joints to transfer")
        u_hand_m = fb.basis @ fh.basis.T
        u_hand = _quat(u_hand_m)
        # the wrist's rotation relative to the forearm means something only when the hand
        # take measured a forearm (an elbow joint away from the wrist). Leap takes put the
        # whole hand orientation on a forearm joint sitting at the wrist (the wrist's own
        # rotation is always identity) and ManipNet has no forearm: the body keeps its wrist.
        wrist = fh.elbow_apart
        if not wrist:
            notes.append(f"{side}: the hand take has no measured forearm (no elbow joint away "
                         "from the wrist); the body keeps its own wrist rotation")
        hand_b, hand_h = fb.hand_joint, fh.hand_joint
        mapped: list[FingerMap] = []
        grafted: list[tuple[int, int]] = []
        size = graft_scale(fb, fh)
        for finger in FINGERS:
            hj = [j for j in arm_h.fingers[finger] if hand_h in sk_h.chain_to_root(j)]
            if not hj:
                continue
            bj = [j for j in arm_b.fingers[finger] if hand_b in sk_b.chain_to_root(j)]
            if bj:
                num_h = dict(zip(arm_h.numbers[finger], arm_h.fingers[finger], strict=True))
                num_b = dict(zip(arm_b.numbers[finger], arm_b.fingers[finger], strict=True))
                prev_b, prev_h = hand_b, hand_h
                u_prev = u_hand
                for k in sorted(num_b):
                    if k not in num_h:
                        break
                    b, h = num_b[k], num_h[k]
                    if prev_h not in sk_h.chain_to_root(h):
                        break
                    frame_b = _joint_frame(rest_b, sk_b, b, fb.dorsal, fb.along, side)
                    frame_h = _joint_frame(rest_h, sk_h, h, fh.dorsal, fh.along, side)
                    u_child = _quat(frame_b @ frame_h.T)
                    mapped.append(FingerMap(b, h, prev_b, prev_h, u_prev, u_child))
                    prev_b, prev_h, u_prev = b, h, u_child
                continue
            # graft the hand take's subtree of this finger under the body's hand joint
            root = hj[0]
            chain = sk_h.chain_to_root(root)
            top = chain[chain.index(hand_h) - 1] if hand_h in chain else root
            sub = sk_h.descendants(top)
            new_index = {}
            order = _rotation_order(sk_b, fb.wrist)
            for a in sub:
                p = sk_h.parents[a]
                if a == top:
                    parent_new = hand_b
                    off_h = rest_h[a] - rest_h[hand_h]
                else:
                    parent_new = new_index[p]
                    off_h = sk_h.offsets[a]
                name = _graft_name(sk_b.names[fb.wrist], finger, arm_h, a, sk_h.names[a], names)
                new_index[a] = len(names)
                names.append(name)
                parents.append(parent_new)
                offsets.append(size * (u_hand_m @ np.asarray(off_h, dtype=float)))
                channels.append(tuple(f"{c}rotation" for c in order))
                if a in sk_h.end_sites:
                    end_sites[new_index[a]] = size * (u_hand_m @ np.asarray(sk_h.end_sites[a]))
                grafted.append((new_index[a], a))
        plans.append(SidePlan(side=side, body_frame=fb, hand_frame=fh, u_hand=u_hand,
                              wrist=bool(wrist), mapped=tuple(mapped), grafted=tuple(grafted),
                              scale=size))
    skeleton = Skeleton(names=tuple(names), parents=np.array(parents), offsets=np.array(offsets),
                        channels=tuple(channels), end_sites=end_sites)
    return TransferPlan(skeleton=skeleton, sides=tuple(plans), n_body_joints=sk_b.n_joints,
                        notes=tuple(notes))


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


def _graft_name(wrist_name: str, finger: str, arm_h, joint: int, hand_name: str,
                taken: list[str]) -> str:
    base = None
    for k, j in zip(arm_h.numbers[finger], arm_h.fingers[finger], strict=True):
        if j == joint:
            base = f"{wrist_name}_{finger}{k}"
    if base is None:
        base = f"{wrist_name}_{finger}_{hand_name}"
    name, c = base, 2
    while name in taken:
        name = f"{base}_{c}"
        c += 1
    return name


def _conj_u(u: np.ndarray, r: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``u * r * v^-1`` broadcast over frames (``u``, ``v`` (4,) or (K, 4))."""
    return qmul(qmul(u, r), rot.conjugate(v))


#: frames per block in :func:`apply_transfer` (bounds its temporaries: about 2 MB per
#: 100 hand joints per 1,000 frames and array)
TRANSFER_CHUNK = 2048


def apply_transfer(plan: TransferPlan, body: Motion, hand: Motion, hand_times: np.ndarray,
                   body_fk=None) -> Motion:
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

    Returns a Motion on ``plan.skeleton`` at the body's frame rate and units.

    Memory: the output's rotations and translations plus temporaries for
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
    trans = np.empty((n, jn, 3))
    for f0 in range(0, n, TRANSFER_CHUNK):
        f1 = min(n, f0 + TRANSFER_CHUNK)
        if g_b is None:
            gb = forward_kinematics(body.frames(f0, f1))[1]
        else:
            gb = g_b[f0:f1]
        _transfer_block(plan, body, hand, t[f0:f1], gb, f0, f1, rots[f0:f1], trans[f0:f1], nb)
    continuous_inplace(rots)
    return Motion(plan.skeleton, rots, trans, body.fps,
                  replace(body.meta, format="derived"))


def _transfer_block(plan: TransferPlan, body: Motion, hand: Motion, t: np.ndarray,
                    g_b: np.ndarray, f0: int, f1: int, rots: np.ndarray, trans: np.ndarray,
                    nb: int) -> None:
    """Body frames ``f0..f1-1`` of :func:`apply_transfer` into ``rots``/``trans`` (views)."""
    n = f1 - f0
    jn = plan.skeleton.n_joints
    h_local, h_trans = sample(hand, t)
    h_motion = replace(hand, rotations=h_local, translations=h_trans, fps=body.fps)
    _, g_h = forward_kinematics(h_motion)
    body_rot = body.rotations[f0:f1]
    rots[:, :nb] = body_rot
    trans[:, :nb] = body.translations[f0:f1]
    rots[:, nb:] = rot.identity((n, jn - nb))
    trans[:, nb:] = plan.skeleton.offsets[nb:]
    sk_b = body.skeleton
    for sp in plan.sides:
        fb, fh = sp.body_frame, sp.hand_frame
        u = sp.u_hand
        if sp.wrist:
            r_rel = qmul_conj(g_h[:, fh.forearm_joint], g_h[:, fh.hand_joint])
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
            rots[:, fb.wrist] = local
        if sp.mapped:
            hp = [fm.hand_parent for fm in sp.mapped]
            hj = [fm.hand for fm in sp.mapped]
            r_rel = qmul_conj(g_h[:, hp], g_h[:, hj])
            u_p = np.stack([fm.u_parent for fm in sp.mapped])
            u_c = np.stack([fm.u_child for fm in sp.mapped])
            desired = _conj_u(u_p, r_rel, u_c)
            for k, fm in enumerate(sp.mapped):
                # body joints between the matched parent and this joint keep their rotations
                between = None
                j = sk_b.parents[fm.body]
                while j != fm.body_parent and j >= 0:
                    between = body_rot[:, j] if between is None else \
                        qmul(body_rot[:, j], between)
                    j = sk_b.parents[j]
                rots[:, fm.body] = desired[:, k] if between is None else \
                    qmul_conj(between, desired[:, k])
        if sp.grafted:
            new = np.array([g[0] for g in sp.grafted])
            src = np.array([g[1] for g in sp.grafted])
            top = plan.skeleton.parents[new] == fb.hand_joint
            r_rel = h_local[:, src].copy()
            if top.any():
                r_rel[:, top] = qmul_conj(g_h[:, [fh.hand_joint]], g_h[:, src[top]])
            rots[:, new] = _conj_u(u, r_rel, u)
    normalize_inplace(rots)  # rots is a contiguous block of frames of the output
