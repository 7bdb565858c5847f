"""A procedural mannequin for any skeleton, built at its rest pose.

``build_mannequin(skeleton) -> SkinnedMesh``: tapered capsules for the limbs, an
elliptic swept torso, a head with a nose (so facing reads), feet, and hands with
a palm and one capsule per phalanx (alternating shades, so finger motion reads
in a small image). Skeletons without finger joints get rigid procedural fingers
on the hand joint (or on a generic ``LFingers``/``HandEnd`` joint when there is
one), so every character has hands. Hand-only takes get a forearm stub.

Sizes are fractions of the standing height ``H`` (or of the hand length for
fingers) from :func:`engine.mesh.anatomy.find_anatomy`, so any unit works.
Weights: two bones per vertex by the Jin & Hahn rule
(:func:`engine.mesh.skinning.two_bone_weights`), each piece owned by the bone
that generated it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from engine.mesh.anatomy import (
    FINGERS,
    Anatomy,
    HandParts,
    chain_tip,
    find_anatomy,
    finger_base,
    palm_normal,
)
from engine.mesh.skinning import Bones, SkinnedMesh, two_bone_weights, vertex_normals
from engine.model import rotations as rot
from engine.model.kinematics import forward_kinematics, rest_positions
from engine.model.motion import Motion, Skeleton

PART_NAMES = ("body", "head", "left_hand", "right_hand", "hand")

# colours (linear RGB in [0, 1])
BODY = (0.34, 0.42, 0.55)
BODY_LEFT = (0.28, 0.42, 0.62)
BODY_RIGHT = (0.46, 0.40, 0.50)
SKIN = (0.93, 0.74, 0.60)
PHALANX = ((0.86, 0.62, 0.48), (0.95, 0.78, 0.64), (0.99, 0.88, 0.78))
NOSE = (0.85, 0.58, 0.46)


def _unit(v, fallback=None) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    n = float(np.linalg.norm(v))
    if n < 1e-12:
        return np.array([1.0, 0.0, 0.0]) if fallback is None else np.asarray(fallback, float)
    return v / n


def _perpendicular(t: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Unit vector perpendicular to ``t``, as close to ``ref`` as possible."""
    x = ref - np.dot(ref, t) * t
    if np.linalg.norm(x) < 1e-6 * max(np.linalg.norm(ref), 1e-12):
        alt = np.eye(3)[np.argmin(np.abs(t))]
        x = alt - np.dot(alt, t) * t
    return _unit(x)


def sweep(
    centers: np.ndarray,
    half_a: np.ndarray,
    half_b: np.ndarray,
    lateral: np.ndarray,
    n_around: int = 12,
    n_cap: int = 3,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A closed tube along ``centers (n, 3)`` with elliptic cross-sections and round caps.

    ``half_a (n,)`` is the half-width along ``lateral`` (projected perpendicular to the
    tube), ``half_b (n,)`` the half-width across. Returns vertices ``(V, 3)``, faces
    ``(T, 3)`` and, per vertex, the index of the centre point it belongs to.
    """
    centers = np.asarray(centers, dtype=float)
    n = len(centers)
    half_a = np.broadcast_to(np.asarray(half_a, float), (n,))
    half_b = np.broadcast_to(np.asarray(half_b, float), (n,))
    if n < 2:
        raise ValueError("sweep: needs at least two centre points")
    tang = np.empty_like(centers)
    tang[0] = centers[1] - centers[0]
    tang[-1] = centers[-1] - centers[-2]
    if n > 2:
        tang[1:-1] = centers[2:] - centers[:-2]
    tang = np.array([_unit(t, tang[0]) for t in tang])
    # ring list: (centre, tangent, a, b, source index), caps by quarter circles
    rings = []
    angles = np.linspace(0.0, 0.5 * np.pi, n_cap + 2)[1:-1]
    r0 = 0.5 * (half_a[0] + half_b[0])
    for phi in angles[::-1]:
        rings.append(
            (
                centers[0] - tang[0] * r0 * np.sin(phi),
                tang[0],
                half_a[0] * np.cos(phi),
                half_b[0] * np.cos(phi),
                0,
            )
        )
    for i in range(n):
        rings.append((centers[i], tang[i], half_a[i], half_b[i], i))
    r1 = 0.5 * (half_a[-1] + half_b[-1])
    for phi in angles:
        rings.append(
            (
                centers[-1] + tang[-1] * r1 * np.sin(phi),
                tang[-1],
                half_a[-1] * np.cos(phi),
                half_b[-1] * np.cos(phi),
                n - 1,
            )
        )
    theta = np.linspace(0.0, 2 * np.pi, n_around, endpoint=False)
    cos_t, sin_t = np.cos(theta), np.sin(theta)
    verts, src = [], []
    for c, t, a, b, i in rings:
        x = _perpendicular(t, lateral)
        y = np.cross(t, x)
        verts.append(c + a * cos_t[:, None] * x + b * sin_t[:, None] * y)
        src.append(np.full(n_around, i))
    n_rings = len(rings)
    pole0 = centers[0] - tang[0] * r0
    pole1 = centers[-1] + tang[-1] * r1
    verts = np.vstack(verts + [pole0[None], pole1[None]])
    src = np.concatenate(src + [np.array([0, n - 1])])
    faces = []
    k = np.arange(n_around)
    k1 = (k + 1) % n_around
    for r in range(n_rings - 1):
        a0, a1 = r * n_around + k, r * n_around + k1
        b0, b1 = (r + 1) * n_around + k, (r + 1) * n_around + k1
        faces.append(np.stack([a0, b0, b1], 1))
        faces.append(np.stack([a0, b1, a1], 1))
    p0, p1 = n_rings * n_around, n_rings * n_around + 1
    faces.append(np.stack([np.full(n_around, p0), k, k1], 1))
    last = (n_rings - 1) * n_around
    faces.append(np.stack([np.full(n_around, p1), last + k1, last + k], 1))
    faces = np.vstack(faces)
    # orient outwards: the first side face's normal should point away from the axis
    tri = verts[faces[0]]
    fn = np.cross(tri[1] - tri[0], tri[2] - tri[0])
    if np.dot(fn, tri.mean(0) - rings[0][0]) < 0:
        faces = faces[:, ::-1]
    return verts, faces, src


@dataclass
class _Builder:
    """Collects pieces: geometry plus, per vertex, owner bone / rigid joint / colour."""

    verts: list = field(default_factory=list)
    faces: list = field(default_factory=list)
    owner: list = field(default_factory=list)
    rigid: list = field(default_factory=list)
    colors: list = field(default_factory=list)
    part: list = field(default_factory=list)
    blend: list = field(default_factory=list)
    count: int = 0

    def add(self, verts, faces, color, part, owner=-1, rigid=-1, blend=0.5):
        n = len(verts)
        self.verts.append(verts)
        self.faces.append(faces + self.count)
        self.owner.append(np.broadcast_to(np.asarray(owner, np.int64), (n,)))
        self.rigid.append(np.full(n, rigid, np.int64))
        rgba = np.broadcast_to(np.asarray(color, float), (n, len(color)))
        if rgba.shape[1] == 3:
            rgba = np.hstack([rgba, np.ones((n, 1))])
        self.colors.append(rgba)
        self.part.append(np.full(n, PART_NAMES.index(part), np.int64))
        self.blend.append(np.full(n, blend))
        self.count += n

    def capsule(
        self,
        p0,
        p1,
        r0,
        r1,
        lateral,
        color,
        part,
        owner=-1,
        rigid=-1,
        blend=0.5,
        n_around=12,
        n_along=3,
        n_cap=3,
        flatten=1.0,
    ):
        p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
        if np.linalg.norm(p1 - p0) < 1e-9 * max(r0, 1e-12):
            p1 = p0 + np.asarray(lateral) * 1e-3 * r0  # degenerate: a sphere
        s = np.linspace(0.0, 1.0, n_along + 1)
        centers = p0[None] * (1 - s[:, None]) + p1[None] * s[:, None]
        radii = r0 * (1 - s) + r1 * s
        v, f, _ = sweep(centers, radii, radii * flatten, lateral, n_around, n_cap)
        self.add(v, f, color, part, owner, rigid, blend)


def _hand_part(side: str) -> str:
    return {"left": "left_hand", "right": "right_hand"}.get(side, "hand")


def _limb_color(side: str):
    return {"left": BODY_LEFT, "right": BODY_RIGHT}.get(side, BODY)


def skeleton_bones(
    skeleton: Skeleton, anatomy: Anatomy, pos: np.ndarray, rotations: np.ndarray | None = None
) -> tuple[Bones, dict[tuple[int, int], int], np.ndarray]:
    """The skeleton's bones for weighting (hidden joints left out), a map
    ``(start joint, end joint or -1) -> bone index`` and each joint's id for adjacency
    (joints at the same place as their parent share the parent's id)."""
    n = skeleton.n_joints
    extent = float(np.max(np.ptp(pos, axis=0))) if n > 1 else 1.0
    tol = 1e-6 * max(extent, 1e-9)
    canon = np.arange(n)
    for j in range(n):
        p = skeleton.parents[j]
        if p >= 0 and np.linalg.norm(pos[j] - pos[p]) <= tol:
            canon[j] = canon[p]
    start, end, joint, head, tail, index = [], [], [], [], [], {}
    for j in range(n):
        p = int(skeleton.parents[j])
        if p < 0 or p in anatomy.hidden or j in anatomy.hidden:
            continue
        if np.linalg.norm(pos[j] - pos[p]) <= tol:
            continue
        index[(p, j)] = len(start)
        start.append(pos[p])
        end.append(pos[j])
        joint.append(p)
        head.append(canon[p])
        tail.append(canon[j])
    for j in range(n):
        if (
            j in anatomy.hidden
            or skeleton.children(j)
            and any(c not in anatomy.hidden for c in skeleton.children(j))
        ):
            continue
        if skeleton.parents[j] < 0:
            continue
        tip = chain_tip(skeleton, pos, [int(skeleton.parents[j]), j], rotations=rotations)
        if np.linalg.norm(tip - pos[j]) <= tol:
            continue
        index[(j, -1)] = len(start)
        start.append(pos[j])
        end.append(tip)
        joint.append(j)
        head.append(canon[j])
        tail.append(-1)
    bones = Bones(np.reshape(start, (-1, 3)), np.reshape(end, (-1, 3)), joint, head, tail)
    return bones, index, canon


def build_mannequin(
    skeleton: Skeleton,
    anatomy: Anatomy | None = None,
    detail: float = 1.0,
    pose: tuple[np.ndarray, np.ndarray] | None = None,
) -> SkinnedMesh:
    """A skinned mannequin for ``skeleton``, built and bound in a pose.

    Parameters
    ----------
    skeleton : Skeleton
    anatomy : Anatomy, optional
        Body parts; found with :func:`find_anatomy` (in the same pose) when not given.
    pose : (positions (J, 3), rotations (J, 4)), optional
        World joint positions (file units) and rotations of the bind pose, e.g. one
        frame of ``forward_kinematics``. Default: the rest pose. Use a captured frame
        when the file's rest pose is not anatomical (see :mod:`engine.mesh.anatomy`);
        :func:`mannequin_for` does.
    detail : float
        Scales the number of vertices around each tube (1.0: 12 around limbs, 8
        around phalanges; about 4,300 vertices and 8,400 triangles for a body with
        fingers).

    Returns
    -------
    SkinnedMesh in the bind pose (world frame, file units), parts ``body``,
    ``head``, ``left_hand``, ``right_hand`` (or ``hand`` for a hand take).
    """
    if skeleton.n_joints < 2:
        raise ValueError(
            f"build_mannequin: a skeleton needs at least 2 joints, got {skeleton.n_joints}"
        )
    pos, rots = _bind_pose(skeleton, pose)
    anatomy = anatomy or find_anatomy(skeleton, pos, rots)
    bones, bone_of, canon = skeleton_bones(skeleton, anatomy, pos, rots)

    def tip_of(chain, fraction: float = 0.8) -> np.ndarray:
        return chain_tip(skeleton, pos, chain, fraction, rotations=rots)

    extra = _ExtraBones(bones.n_bones, canon)
    nar = max(6, int(round(12 * detail)))  # vertices around a limb
    b = _Builder()
    drawn: set[int] = set()  # bone indices already covered by a piece

    if anatomy.kind == "body":
        _torso(b, skeleton, anatomy, pos, bones, bone_of, drawn, nar)
        _head(b, skeleton, anatomy, pos, bone_of, drawn, nar)
        for side, leg in anatomy.legs.items():
            _leg(b, skeleton, anatomy, pos, bone_of, drawn, side, leg, nar, tip_of)
        for side, arm in anatomy.arms.items():
            _arm(b, skeleton, anatomy, pos, bone_of, drawn, side, arm, nar)
    for hand in anatomy.hands.values():
        _hand(b, skeleton, anatomy, pos, bones, bone_of, drawn, hand, nar, extra.add, tip_of)
    _leftover_segments(b, skeleton, anatomy, pos, bones, bone_of, drawn, nar)

    if not b.verts:
        raise ValueError("build_mannequin: found nothing to draw in this skeleton")
    return _skinned(b, extra.joined(bones), skeleton, pos, rots)


def _bind_pose(skeleton: Skeleton, pose) -> tuple[np.ndarray, np.ndarray | None]:
    """``(positions (J, 3), rotations (J, 4) or None)`` of the bind pose: ``pose``, checked,
    or the rest pose (no rotations)."""
    if pose is None:
        return rest_positions(skeleton), None
    pos = np.asarray(pose[0], dtype=float)
    rots = np.asarray(pose[1], dtype=float)
    if pos.shape != (skeleton.n_joints, 3) or rots.shape != (skeleton.n_joints, 4):
        raise ValueError(
            f"build_mannequin: pose must be ({skeleton.n_joints}, 3) positions "
            f"and ({skeleton.n_joints}, 4) rotations, got {pos.shape}, "
            f"{rots.shape}"
        )
    return pos, rots


class _ExtraBones:
    """Bones that are not in the skeleton (a palm), each moved by a joint; numbered after
    the skeleton's ``n_bones`` bones."""

    def __init__(self, n_bones: int, canon):
        self.n_bones = n_bones
        self.canon = canon
        self.start: list = []
        self.end: list = []
        self.joint: list = []
        self.head: list = []

    def add(self, p0, p1, joint) -> int:
        """A bone from ``p0`` to ``p1`` (file units) moved by ``joint``; its index."""
        self.start.append(p0)
        self.end.append(p1)
        self.joint.append(joint)
        self.head.append(self.canon[joint])
        return self.n_bones + len(self.start) - 1

    def joined(self, bones: Bones) -> Bones:
        """``bones`` followed by these."""
        if not self.start:
            return bones
        return bones.concat(
            Bones(
                np.reshape(self.start, (-1, 3)),
                np.reshape(self.end, (-1, 3)),
                self.joint,
                self.head,
                np.full(len(self.start), -1),
            )
        )


def _arm(b: _Builder, skeleton, anatomy: Anatomy, pos, bone_of, drawn, side, arm, nar):
    """Clavicle, upper arm and forearm capsules of one arm ``(clavicle or -1, shoulder,
    elbow, wrist)``, sized by the body's height."""
    h, fwd = anatomy.height, anatomy.forward
    clav, upper, elbow, wrist = arm
    col = _limb_color(side)
    if clav >= 0:
        for j0, j1 in _path_bones(skeleton, clav, upper):
            if (j0, j1) in bone_of:
                k = bone_of[(j0, j1)]
                b.capsule(
                    pos[j0],
                    pos[j1],
                    0.032 * h,
                    0.034 * h,
                    fwd,
                    col,
                    "body",
                    owner=k,
                    n_around=nar,
                )
                drawn.add(k)
    segments = (((upper, elbow), (0.033, 0.026)), ((elbow, wrist), (0.025, 0.019)))
    _limb_capsules(b, skeleton, pos, bone_of, segments, h, fwd, col, nar, drawn)


def _leftover_segments(b: _Builder, skeleton, anatomy: Anatomy, pos, bones, bone_of, drawn, nar):
    """Plain thin segments for every bone no piece drew (extra joints, unusual skeletons),
    except inside the hands."""
    radius = 0.018 * anatomy.height if anatomy.kind == "body" else 0.05 * anatomy.hand_length
    hand_joints = set()
    for hand in anatomy.hands.values():
        hand_joints.update(skeleton.descendants(hand.wrist))
    for (j0, j1), k in bone_of.items():
        if k in drawn or j0 in hand_joints:
            continue
        p1 = pos[j1] if j1 >= 0 else bones.end[k]
        b.capsule(
            pos[j0], p1, radius, radius * 0.9, anatomy.up, BODY, "body", owner=k, n_around=nar
        )


def _skinned(b: _Builder, bones: Bones, skeleton: Skeleton, pos, rots) -> SkinnedMesh:
    """The built pieces as one mesh with two-bone weights, bound in ``pos``/``rots``."""
    verts = np.vstack(b.verts)
    faces = np.vstack(b.faces)
    owner = np.concatenate(b.owner)
    rigid = np.concatenate(b.rigid)
    joints, weights = two_bone_weights(
        verts, bones, owner=owner, blend=np.concatenate(b.blend), rigid_joint=rigid
    )
    return SkinnedMesh(
        vertices=verts,
        faces=faces,
        normals=vertex_normals(verts, faces),
        colors=np.vstack(b.colors),
        joints=joints,
        weights=weights,
        bind_positions=pos,
        bind_rotations=rot.identity((skeleton.n_joints,)) if rots is None else rots,
        part=np.concatenate(b.part),
        part_names=PART_NAMES,
    )


def mannequin_for(motion: Motion, frame: int = 0, detail: float = 1.0) -> SkinnedMesh:
    """The mannequin of ``motion``'s skeleton, bound in its captured frame ``frame``."""
    if motion.n_frames == 0:
        return build_mannequin(motion.skeleton, detail=detail)
    if not -motion.n_frames <= frame < motion.n_frames:
        raise IndexError(f"mannequin_for: frame {frame} outside 0..{motion.n_frames - 1}")
    frame %= motion.n_frames
    pos, rots = forward_kinematics(motion, frame, frame + 1)
    return build_mannequin(motion.skeleton, detail=detail, pose=(pos[0], rots[0]))


def _limb_capsules(b, skeleton, pos, bone_of, segments, h, fwd, col, nar, drawn) -> None:
    """A capsule on every bone between each segment's joints ``((j0, j1), (r0, r1))``,
    radii ``r0``/``r1`` in units of the body height ``h``; the bones drawn go in ``drawn``."""
    for (j0, j1), (r0, r1) in segments:
        for a0, a1 in _path_bones(skeleton, j0, j1):
            if (a0, a1) in bone_of:
                k = bone_of[(a0, a1)]
                b.capsule(
                    pos[a0],
                    pos[a1],
                    r0 * h,
                    r1 * h,
                    fwd,
                    col,
                    "body",
                    owner=k,
                    n_around=nar,
                    n_along=4,
                )
                drawn.add(k)


def _path_bones(skeleton: Skeleton, top: int, bottom: int) -> list[tuple[int, int]]:
    """(parent, child) pairs on the hierarchy path from ``top`` down to ``bottom``."""
    chain = skeleton.chain_to_root(bottom)
    if top not in chain:
        return []
    chain = chain[: chain.index(top) + 1][::-1]
    return list(zip(chain[:-1], chain[1:], strict=True))


def _torso(b: _Builder, skeleton, anatomy: Anatomy, pos, bones: Bones, bone_of, drawn, nar):
    h = anatomy.height
    spine = list(anatomy.spine)
    if anatomy.chest is not None and anatomy.chest in spine:
        top_i = spine.index(anatomy.chest) + (
            1 if spine.index(anatomy.chest) + 1 < len(spine) else 0
        )
    else:
        top_i = len(spine) - 1
    if anatomy.head is not None and spine[top_i] == anatomy.head and top_i > 0:
        top_i -= 1
    trunk = spine[: top_i + 1]
    up, left = anatomy.up, anatomy.left
    pelvis = pos[trunk[0]]
    if len(trunk) >= 2:
        pts = pos[trunk]
    else:
        pts = np.vstack([pelvis, pelvis + 0.3 * h * up])
    # extend below the pelvis joint to cover the hips
    pts = np.vstack([pelvis - 0.05 * h * up, pts])
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(seg)])
    total = arc[-1] if arc[-1] > 0 else 1.0
    s = np.linspace(0.0, 1.0, 12)
    centers = np.stack([np.interp(s * total, arc, pts[:, k]) for k in range(3)], 1)
    # widths: hips, waist, chest, shoulder line
    hip_half = 0.1 * h
    if len(anatomy.legs) == 2:
        span = np.linalg.norm(pos[anatomy.legs["left"][0]] - pos[anatomy.legs["right"][0]])
        hip_half = float(np.clip(0.5 * span * 1.65, 0.075 * h, 0.12 * h))
    chest_half = 0.1 * h
    if len(anatomy.arms) == 2:
        span = np.linalg.norm(pos[anatomy.arms["left"][1]] - pos[anatomy.arms["right"][1]])
        chest_half = float(np.clip(0.5 * span * 0.78, 0.075 * h, 0.12 * h))
    key_s = np.array([0.0, 0.18, 0.45, 0.75, 0.93, 1.0])
    key_w = np.array(
        [
            0.8 * hip_half,
            hip_half,
            0.82 * chest_half,
            chest_half,
            0.92 * chest_half,
            0.6 * chest_half,
        ]
    )
    key_d = np.array([0.055, 0.068, 0.058, 0.068, 0.06, 0.045]) * h
    half_a = np.interp(s, key_s, key_w)
    half_b = np.interp(s, key_s, key_d)
    v, f, _ = sweep(centers, half_a, half_b, left, n_around=max(12, int(nar * 1.5)), n_cap=2)
    # owner: nearest spine bone
    spine_bones = [
        bone_of[(a, c)] for a, c in zip(spine[:-1], spine[1:], strict=True) if (a, c) in bone_of
    ]
    if anatomy.head is not None and spine_bones and spine[-1] == anatomy.head:
        spine_bones = spine_bones[:-1] or spine_bones  # the neck-to-head bone: not the trunk
    if spine_bones:
        from engine.mesh.skinning import segment_distances

        d = segment_distances(v, bones.start[spine_bones], bones.end[spine_bones])
        owner = np.asarray(spine_bones)[np.argmin(d, axis=1)]
        b.add(v, f, BODY, "body", owner=owner, blend=0.8)
        drawn.update(spine_bones)
    else:
        b.add(v, f, BODY, "body", rigid=trunk[0])
    # bones from the pelvis to the hips and from the chest to the clavicles are inside
    for leg in anatomy.legs.values():
        for pair in _path_bones(skeleton, anatomy.pelvis, leg[0]):
            if pair in bone_of:
                drawn.add(bone_of[pair])
    if anatomy.chest is not None:
        for arm in anatomy.arms.values():
            first = arm[0] if arm[0] >= 0 else arm[1]
            for pair in _path_bones(skeleton, anatomy.chest, first):
                if pair in bone_of:
                    drawn.add(bone_of[pair])


def _head(b: _Builder, skeleton, anatomy: Anatomy, pos, bone_of, drawn, nar):
    h = anatomy.height
    up, left, fwd = anatomy.up, anatomy.left, anatomy.forward
    spine = list(anatomy.spine)
    head = anatomy.head
    if head is None:
        return
    # neck: from the last trunk joint below the head to the head joint
    neck_top = pos[head]
    below = [j for j in spine[:-1] if j != head]
    for a, c in zip(spine[:-1], spine[1:], strict=True):
        if (a, c) in bone_of and (
            c == head or (anatomy.chest is not None and spine.index(a) > spine.index(anatomy.chest))
        ):
            k = bone_of[(a, c)]
            b.capsule(
                pos[a], pos[c], 0.03 * h, 0.028 * h, left, BODY, "body", owner=k, n_around=nar
            )
            drawn.add(k)
    if not below:
        return
    center = neck_top + 0.055 * h * up
    n_lat, n_long = max(10, nar + 4), max(8, nar)
    theta = np.linspace(0, np.pi, n_long + 1)[1:-1]
    phi = np.linspace(0, 2 * np.pi, n_lat, endpoint=False)
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    sp, cp = np.sin(phi)[None], np.cos(phi)[None]
    ax = (0.058 * h, 0.072 * h, 0.066 * h)  # left-right, up, front-back half axes
    ring = (
        ct[..., None] * ax[1] * up
        + (st * cp)[..., None] * ax[0] * left
        + (st * sp)[..., None] * ax[2] * fwd
    )
    verts = np.vstack([center + ax[1] * up, (center + ring).reshape(-1, 3), center - ax[1] * up])
    faces = []
    k = np.arange(n_lat)
    k1 = (k + 1) % n_lat
    faces.append(np.stack([np.zeros(n_lat, int), 1 + k1, 1 + k], 1))
    for r in range(len(theta) - 1):
        a0, a1 = 1 + r * n_lat + k, 1 + r * n_lat + k1
        b0, b1 = 1 + (r + 1) * n_lat + k, 1 + (r + 1) * n_lat + k1
        faces += [np.stack([a0, b1, b0], 1), np.stack([a0, a1, b1], 1)]
    last = 1 + (len(theta) - 1) * n_lat
    faces.append(np.stack([np.full(n_lat, len(verts) - 1), last + k, last + k1], 1))
    faces = np.vstack(faces)
    tri = verts[faces[0]]
    if np.dot(np.cross(tri[1] - tri[0], tri[2] - tri[0]), tri.mean(0) - center) < 0:
        faces = faces[:, ::-1]
    b.add(verts, faces, SKIN, "head", rigid=head)
    # the nose says where the face is
    nose0 = center + 0.058 * h * fwd - 0.005 * h * up
    b.capsule(
        nose0,
        nose0 + 0.022 * h * fwd - 0.01 * h * up,
        0.014 * h,
        0.01 * h,
        up,
        NOSE,
        "head",
        rigid=head,
        n_around=8,
        n_along=1,
        n_cap=2,
    )
    for (a, _c), kk in bone_of.items():
        if a == head or a in anatomy.hidden:
            drawn.add(kk)


def _leg(b: _Builder, skeleton, anatomy: Anatomy, pos, bone_of, drawn, side, leg, nar, tip_of):
    h = anatomy.height
    hip, knee, ankle = leg[:3]
    col = _limb_color(side)
    left, up, fwd = anatomy.left, anatomy.up, anatomy.forward
    segments = (((hip, knee), (0.05, 0.036)), ((knee, ankle), (0.034, 0.023)))
    _limb_capsules(b, skeleton, pos, bone_of, segments, h, fwd, col, nar, drawn)
    # foot: ankle -> toes -> tip, flattened, a little heel behind the ankle
    toes = [t for t in leg[3:] if skeleton.parents[t] in (ankle, *leg[3:])]
    chain = [ankle] + toes
    tip = tip_of(chain, fraction=0.6) if toes else None
    pts = [pos[j] for j in chain]
    if tip is not None:
        pts.append(tip)
    if len(pts) < 2:
        direction = _unit(fwd - 0.3 * up)
        pts.append(pos[ankle] + 0.13 * h * direction)
    foot_len = float(np.sum(np.linalg.norm(np.diff(np.asarray(pts), axis=0), axis=1)))
    foot_len = float(np.clip(foot_len, 0.08 * h, 0.16 * h))
    for idx in range(len(pts) - 1):
        j0 = chain[idx]
        j1 = chain[idx + 1] if idx + 1 < len(chain) else -1
        k = bone_of.get((j0, j1))
        p0, p1 = np.asarray(pts[idx]), np.asarray(pts[idx + 1])
        if idx == 0:
            p0 = p0 - 0.25 * foot_len * _unit(p1 - p0)  # heel
        r0 = 0.026 * h if idx == 0 else 0.021 * h
        r1 = 0.022 * h if idx == 0 else 0.016 * h
        b.capsule(
            p0,
            p1,
            r0,
            r1,
            left,
            col,
            "body",
            owner=-1 if k is None else k,
            rigid=j0 if k is None else -1,
            n_around=nar,
            flatten=0.7,
        )
        if k is not None:
            drawn.add(k)
    for t in toes:
        for (a, _c), kk in bone_of.items():
            if a == t:
                drawn.add(kk)


def _hand(
    b: _Builder,
    skeleton,
    anatomy: Anatomy,
    pos,
    bones: Bones,
    bone_of,
    drawn,
    hand: HandParts,
    nar,
    virtual_bone,
    tip_of,
):
    """Palm, fingers (articulated where the skeleton has them) and, for a hand take,
    a forearm stub."""
    part = _hand_part(hand.side)
    w = hand.wrist
    palm = _palm_frame(skeleton, anatomy, pos, hand, tip_of)
    _palm_mesh(b, skeleton, pos, bones, bone_of, drawn, hand, nar, virtual_bone, palm, part)
    nf = max(6, int(round(8 * (nar / 12))))
    _articulated_fingers(b, skeleton, anatomy, pos, bone_of, drawn, hand, tip_of, palm, part, nf)
    if not palm.named and any(f not in hand.fingers for f in ("index", "middle", "ring", "pinky")):
        _procedural_fingers(b, anatomy, pos, bone_of, drawn, hand, palm, part, nf)
    # a hand take: a forearm stub behind the wrist
    if anatomy.kind == "hand":
        back = pos[w] - 1.2 * anatomy.hand_length * palm.hand_dir
        b.capsule(
            pos[w],
            back,
            1.9 * palm.radius,
            2.6 * palm.radius,
            palm.normal,
            BODY,
            "body",
            rigid=w,
            n_around=nar,
            n_along=2,
        )
    # bones of this hand not drawn as fingers (e.g. a forearm joint at the wrist)
    for (a, c), k in bone_of.items():
        if a in skeleton.descendants(w) and k not in drawn and c in hand.other:
            drawn.add(k)


@dataclass(frozen=True)
class _Palm:
    """Where a hand's palm lies in the bind pose (model units).

    ``knuckle (3,)`` the knuckles' centre; ``hand_dir (3,)`` wrist to knuckles, unit;
    ``across (3,)`` unit, across the knuckles (perpendicular to ``hand_dir``);
    ``normal (3,)`` the palm's normal, unit; ``span`` the knuckles' width; ``radius``
    a finger's; ``named`` the long fingers the skeleton has (thumb excluded)."""

    knuckle: np.ndarray
    hand_dir: np.ndarray
    across: np.ndarray
    normal: np.ndarray
    span: float
    radius: float
    named: tuple[str, ...]


def _palm_frame(skeleton, anatomy: Anatomy, pos, hand: HandParts, tip_of) -> _Palm:
    """The palm from the finger bases, or (no long fingers) from the wrist's other
    children and the forearm."""
    w = hand.wrist
    lh = anatomy.hand_length
    named = [f for f in FINGERS if f in hand.fingers and f != "thumb"]
    if hand.elbow is not None:
        fore_dir = _unit(pos[w] - pos[hand.elbow])
    else:
        fore_dir = None
    if named:
        bases = {f: finger_base(skeleton, pos, hand, f) for f in hand.fingers}
        knuckle = np.mean([bases[f] for f in named], axis=0)
        hand_dir = _unit(knuckle - pos[w], fore_dir)
        if "index" in bases and "pinky" in bases and len(named) >= 2:
            across = bases["index"] - bases["pinky"]
            span = float(np.linalg.norm(across))
        elif len(named) >= 2:
            across = bases[named[0]] - bases[named[-1]]
            span = (
                float(np.linalg.norm(across))
                * 3
                / max(1, FINGERS.index(named[-1]) - FINGERS.index(named[0]))
            )
        else:
            across, span = anatomy.forward, 0.3 * lh
        across = _perpendicular(hand_dir, across)
        span = float(np.clip(span, 0.2 * lh, 0.45 * lh))
        radius = float(np.clip(0.16 * span, 0.035 * lh, 0.06 * lh))
    else:
        anchor_dir = None
        for o in hand.other:
            d = pos[o] - pos[w]
            if np.linalg.norm(d) > 1e-6 * lh:
                anchor_dir = _unit(d)
                break
            tip = tip_of([w, o])
            if np.linalg.norm(tip - pos[o]) > 1e-6 * lh:
                anchor_dir = _unit(tip - pos[o])
                break
        hand_dir = (
            anchor_dir
            if anchor_dir is not None
            else (fore_dir if fore_dir is not None else anatomy.up)
        )
        across = _perpendicular(hand_dir, anatomy.forward)
        knuckle = pos[w] + 0.45 * lh * hand_dir
        span = 0.36 * lh
        radius = 0.045 * lh
    # palm normal, from the finger flexion or the thumb side and the side of the body
    normal = palm_normal(skeleton, pos, hand, hand_dir, across)
    return _Palm(knuckle, hand_dir, across, normal, span, radius, tuple(named))


def _palm_mesh(b, skeleton, pos, bones, bone_of, drawn, hand, nar, virtual_bone, palm, part):
    """The palm: owned by the wrist's bones towards the fingers, or a virtual palm bone."""
    w = hand.wrist
    s = np.linspace(0.0, 1.0, 5)
    centers = pos[w][None] + (palm.knuckle - pos[w])[None] * (s[:, None] - 0.02)
    half_a = (0.5 * palm.span + 0.6 * palm.radius) * (0.72 + 0.28 * s)  # wider at the knuckles
    half_b = 0.95 * palm.radius * (1.05 - 0.15 * s)
    v, f, _ = sweep(centers, half_a, half_b, palm.across, n_around=max(12, nar + 2), n_cap=2)
    wrist_bones = [
        k
        for (a, c), k in bone_of.items()
        if a == w or (skeleton.parents[w] >= 0 and a in _same_place(skeleton, pos, w))
    ]
    finger_joints = {j for chain in hand.fingers.values() for j in chain}
    wrist_bones = [
        k
        for k in wrist_bones
        if _bone_child(bone_of, k) in finger_joints or _bone_child(bone_of, k) in hand.other
    ]
    if wrist_bones:
        from engine.mesh.skinning import segment_distances

        d = segment_distances(v, bones.start[wrist_bones], bones.end[wrist_bones])
        owner = np.asarray(wrist_bones)[np.argmin(d, axis=1)]
        b.add(v, f, SKIN, part, owner=owner, blend=0.6)
        for k in wrist_bones:
            if _bone_child(bone_of, k) not in (hand.fingers.get("thumb", ()) or ()):
                drawn.add(k)
    else:
        kv = virtual_bone(pos[w], palm.knuckle, w)
        b.add(v, f, SKIN, part, owner=kv, blend=0.6)


def _articulated_fingers(b, skeleton, anatomy, pos, bone_of, drawn, hand, tip_of, palm, part, nf):
    """A capsule per phalanx of every finger the skeleton has (metacarpals of the long
    fingers lie inside the palm; the thumb's is drawn from the wrist)."""
    w = hand.wrist
    lh = anatomy.hand_length
    radius = palm.radius
    for finger, chain in hand.fingers.items():
        r = radius * (1.12 if finger == "thumb" else 1.0)
        tip_joint = hand.tips.get(finger)
        pts = [pos[j] for j in chain] + [pos[tip_joint] if tip_joint is not None else tip_of(chain)]
        joints_ = list(chain) + [-1 if tip_joint is None else tip_joint]
        start_i = 0
        if finger != "thumb" and len(chain) > 3:
            start_i = len(chain) - 3  # metacarpal joints lie inside the palm
        n_ph = len(pts) - 1 - start_i
        for i in range(start_i, len(pts) - 1):
            j0, j1 = joints_[i], joints_[i + 1]
            if np.linalg.norm(pts[i + 1] - pts[i]) < 1e-6 * lh:
                continue
            k = bone_of.get((j0, j1))
            if k is None and j1 >= 0:  # a joint between the two (ManipNet THUMB_CMC_AA)
                k = bone_of.get((int(skeleton.parents[j1]), j1))
            level = i - start_i
            taper0 = 1.0 - 0.08 * level
            taper1 = taper0 - (0.14 if i == len(pts) - 2 else 0.08)
            shade = PHALANX[min(level + (3 - n_ph if n_ph < 3 else 0), 2)]
            b.capsule(
                pts[i],
                pts[i + 1],
                r * taper0,
                r * taper1,
                palm.normal,
                shade,
                part,
                owner=-1 if k is None else k,
                rigid=j0 if k is None else -1,
                blend=0.3,
                n_around=nf,
                n_along=1,
                n_cap=2,
            )
            if k is not None:
                drawn.add(k)
        if finger == "thumb" and (w, chain[0]) in bone_of:
            k = bone_of[(w, chain[0])]
            if k not in drawn:  # the thumb's metacarpal from the wrist
                b.capsule(
                    pos[w] + 0.15 * (pts[0] - pos[w]),
                    pts[0],
                    r * 1.1,
                    r * 1.05,
                    palm.normal,
                    SKIN,
                    part,
                    owner=k,
                    blend=0.3,
                    n_around=nf,
                    n_along=1,
                    n_cap=2,
                )
                drawn.add(k)


def _procedural_fingers(b, anatomy, pos, bone_of, drawn, hand, frame: _Palm, part, nf):
    """Relaxed fingers (and a thumb) where the skeleton has no long fingers at all: rigid
    on the wrist's other child (or the wrist)."""
    w = hand.wrist
    lh = anatomy.hand_length
    knuckle, span, radius = frame.knuckle, frame.span, frame.radius
    across, hand_dir, palm = frame.across, frame.hand_dir, frame.normal
    missing = [f for f in ("index", "middle", "ring", "pinky") if f not in hand.fingers]
    anchor = hand.other[0] if hand.other else w
    lengths = {"index": 0.37, "middle": 0.41, "ring": 0.38, "pinky": 0.3}
    offsets = {"index": 0.75, "middle": 0.25, "ring": -0.25, "pinky": -0.75}
    for f in missing:
        base = knuckle + offsets[f] * (span * 0.95 - 2 * radius) * across
        length = lengths[f] * lh
        d = hand_dir
        p = base
        for level, frac in enumerate((0.45, 0.3, 0.25)):
            d = _unit(d + 0.12 * palm)  # a relaxed curl
            q = p + frac * length * d
            taper0 = 1.0 - 0.08 * level
            b.capsule(
                p,
                q,
                radius * taper0,
                radius * (taper0 - (0.14 if level == 2 else 0.08)),
                palm,
                PHALANX[level],
                part,
                rigid=anchor,
                n_around=nf,
                n_along=1,
                n_cap=2,
            )
            p = q
    if "thumb" not in hand.fingers:
        p = pos[w] + 0.12 * lh * hand_dir + 0.12 * lh * across + 0.03 * lh * palm
        d = _unit(0.6 * hand_dir + 0.6 * across + 0.3 * palm)
        for level, frac in enumerate((0.14, 0.11, 0.1)):
            q = p + frac * lh * d
            b.capsule(
                p,
                q,
                radius * 1.15 * (1 - 0.08 * level),
                radius * 1.15 * (0.92 - 0.08 * level - (0.08 if level == 2 else 0)),
                palm,
                PHALANX[level],
                part,
                rigid=w,
                n_around=nf,
                n_along=1,
                n_cap=2,
            )
            d = _unit(d + 0.15 * hand_dir)
            p = q
    for o in hand.other:
        for (a, c), kk in bone_of.items():
            if a == o or c == o:
                drawn.add(kk)


def _same_place(skeleton: Skeleton, pos: np.ndarray, j: int) -> set[int]:
    """Joints at the same rest position as ``j`` along its chain (zero-length bones)."""
    out = {j}
    tol = 1e-9 + 1e-6 * float(np.max(np.ptp(pos, axis=0)))
    for c in skeleton.descendants(j):
        if np.linalg.norm(pos[c] - pos[j]) <= tol:
            out.add(c)
    return out


def _bone_child(bone_of: dict[tuple[int, int], int], k: int) -> int:
    for (_a, c), kk in bone_of.items():
        if kk == k:
            return c
    return -1
