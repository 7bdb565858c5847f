"""Two-bone skin weights (Jin & Hahn 2005, §3) and linear blend skinning.

Weights
-------
Jin & Hahn weight every vertex to its two nearest bones: "for every vertex, we
choose the shortest and second shortest distance skeleton as weight calculation
candidate. The dot product of the angular median vector and vertex to skeleton
joint vector is used to calculate the weight for each skeleton", with
``0 <= w1, w2 <= 1`` and ``w1 + w2 = 1``. Here:

1. ``b1`` is the bone nearest to the vertex (point-to-segment distance), or the bone
   that generated it when the caller knows (the mannequin does: a hand hanging
   beside the thigh must not follow the leg).
2. ``b2`` is the nearest bone *adjacent* to ``b1`` (sharing its start or end joint)
   and driven by another joint. Restricting the second candidate to neighbours
   keeps neighbouring fingers, or an arm lying against the torso, from blending
   into each other, which the paper's hand-picked meshes did not need.
3. At the shared joint ``J``, the angular median ``m`` is the bisector of the two
   bone directions, ``m = unit(u_parent + u_child)`` (both pointing along the
   chain, towards the child bone). The plane through ``J`` normal to ``m`` halves
   the angle between the bones. With ``c = m . (v - J) / |v - J|`` (the dot product
   of the angular median and the vertex-to-joint vector),
   ``w_child = clip(0.5 + c / (2 * blend), 0, 1)`` and ``w_parent = 1 - w_child``.
   ``blend = 1`` is the plain ``(1 + c) / 2``; smaller values confine the blend to a
   narrower cone around the bisecting plane (0.5: vertices more than 30 degrees
   off the plane are rigid).

Skinning
--------
Linear blend skinning from a bind pose (the rest pose, whose world rotations are
identity, or a captured frame): ``v' = sum_k w_k (R_k v + t_k)`` with
``R_k = Q_k B_k^T`` (``Q_k`` the posed and ``B_k`` the bind world rotation of joint
``k``) and ``t_k = p_k - R_k b_k`` (``p_k``, ``b_k`` its posed and bind world
positions). Normals use the blended linear part, renormalised.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from engine.model import rotations as rot


@dataclass(frozen=True)
class Bones:
    """Bone segments for weighting, in rest-pose file units.

    start, end : (B, 3) float
        Segment end points.
    joint : (B,) int
        The joint whose transform moves the bone (its start joint).
    head, tail : (B,) int
        Joint ids at the start and the end, used only to find neighbours: bones
        ``a`` and ``b`` are adjacent when ``tail[a] == head[b]`` (``b`` continues
        ``a``). ``tail`` is -1 for a tip segment (a leaf to its End Site, a
        mannequin's palm). Joints at the same place (zero-length bones) should be
        given the same id.
    """

    start: np.ndarray
    end: np.ndarray
    joint: np.ndarray
    head: np.ndarray
    tail: np.ndarray

    def __post_init__(self) -> None:
        start = np.asarray(self.start, dtype=float).reshape(-1, 3)
        n = start.shape[0]
        object.__setattr__(self, "start", start)
        object.__setattr__(self, "end", np.asarray(self.end, dtype=float).reshape(n, 3))
        for name in ("joint", "head", "tail"):
            arr = np.asarray(getattr(self, name), dtype=np.int64).reshape(-1)
            if arr.shape != (n,):
                raise ValueError(f"bones: {name} must have {n} entries, got {arr.shape}")
            object.__setattr__(self, name, arr)

    @property
    def n_bones(self) -> int:
        return int(self.start.shape[0])

    def neighbours(self) -> np.ndarray:
        """(B, K) indices of the bones adjacent to each bone and driven by another
        joint, padded with -1."""
        lists = []
        for b in range(self.n_bones):
            adj = [
                m
                for m in range(self.n_bones)
                if m != b
                and self.joint[m] != self.joint[b]
                and (
                    (self.tail[b] >= 0 and self.tail[b] == self.head[m])
                    or (self.tail[m] >= 0 and self.tail[m] == self.head[b])
                )
            ]
            lists.append(adj)
        k = max([len(a) for a in lists] + [1])
        out = np.full((self.n_bones, k), -1, dtype=np.int64)
        for b, adj in enumerate(lists):
            out[b, : len(adj)] = adj
        return out

    def concat(self, other: Bones) -> Bones:
        return Bones(
            np.vstack([self.start, other.start]),
            np.vstack([self.end, other.end]),
            np.concatenate([self.joint, other.joint]),
            np.concatenate([self.head, other.head]),
            np.concatenate([self.tail, other.tail]),
        )


def segment_distances(points: np.ndarray, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """(V, B) distances from ``points (V, 3)`` to segments ``start, end (B, 3)``."""
    d = end - start  # (B, 3)
    len2 = np.einsum("bi,bi->b", d, d)
    rel = points[:, None, :] - start[None, :, :]  # (V, B, 3)
    t = np.einsum("vbi,bi->vb", rel, d) / np.where(len2 > 0, len2, 1.0)
    t = np.clip(t, 0.0, 1.0)
    closest = rel - t[..., None] * d[None]
    return np.sqrt(np.einsum("vbi,vbi->vb", closest, closest))


def two_bone_weights(
    vertices: np.ndarray,
    bones: Bones,
    owner: np.ndarray | None = None,
    blend: float | np.ndarray = 0.5,
    rigid_joint: np.ndarray | None = None,
    chunk: int = 8192,
) -> tuple[np.ndarray, np.ndarray]:
    """Two joints and two weights per vertex by the Jin & Hahn rule (module docstring).

    Parameters
    ----------
    vertices : (V, 3) float, rest pose, file units
    bones : Bones
    owner : (V,) int, optional
        Bone that generated each vertex (``b1``); -1 (or absent) picks the nearest bone.
    blend : float or (V,) float in (0, 1]
        Width of the blend cone (1: ``w = (1 + cos) / 2``).
    rigid_joint : (V,) int, optional
        Where >= 0, the vertex follows that joint alone (weights ``(1, 0)``).

    Returns
    -------
    joints : (V, 2) int, the larger weight first
    weights : (V, 2) float, each in [0, 1], rows sum to 1
    """
    vertices = np.asarray(vertices, dtype=float)
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise ValueError(f"two_bone_weights: vertices must be (V, 3), got {vertices.shape}")
    n_v = vertices.shape[0]
    if bones.n_bones == 0:
        raise ValueError("two_bone_weights: the skeleton has no bones to weight to")
    owner = np.full(n_v, -1, np.int64) if owner is None else np.asarray(owner, np.int64)
    if owner.shape != (n_v,):
        raise ValueError(f"two_bone_weights: owner must be ({n_v},), got {owner.shape}")
    if np.any(owner >= bones.n_bones):
        raise ValueError("two_bone_weights: owner names a bone that does not exist")
    blend = np.broadcast_to(np.asarray(blend, dtype=float), (n_v,))
    if np.any(~(blend > 0)) or np.any(blend > 1):
        raise ValueError("two_bone_weights: blend must lie in (0, 1]")
    neigh = bones.neighbours()
    direction = bones.end - bones.start
    unit = direction / np.maximum(np.linalg.norm(direction, axis=1, keepdims=True), 1e-12)

    joints = np.zeros((n_v, 2), dtype=np.int64)
    weights = np.zeros((n_v, 2), dtype=float)
    for lo in range(0, n_v, chunk):
        hi = min(n_v, lo + chunk)
        v = vertices[lo:hi]
        dist = segment_distances(v, bones.start, bones.end)
        b1 = np.where(owner[lo:hi] >= 0, owner[lo:hi], np.argmin(dist, axis=1))
        cand = neigh[b1]  # (n, K)
        cand_d = np.where(cand >= 0, np.take_along_axis(dist, np.maximum(cand, 0), 1), np.inf)
        k = np.argmin(cand_d, axis=1)
        b2 = cand[np.arange(len(b1)), k]
        has2 = b2 >= 0
        b2s = np.where(has2, b2, b1)
        # is b2 the child of b1 (b2 starts where b1 ends) or its parent?
        child_is_b2 = has2 & (bones.tail[b1] >= 0) & (bones.tail[b1] == bones.head[b2s])
        parent = np.where(child_is_b2, b1, b2s)
        child = np.where(child_is_b2, b2s, b1)
        joint_pos = bones.start[child]
        median = unit[parent] + unit[child]
        norm = np.linalg.norm(median, axis=1, keepdims=True)
        median = np.where(norm > 1e-9, median / np.maximum(norm, 1e-12), unit[child])
        rel = v - joint_pos
        rel_n = np.linalg.norm(rel, axis=1)
        cos = np.einsum("vi,vi->v", median, rel) / np.maximum(rel_n, 1e-12)
        cos = np.where(rel_n > 1e-12, cos, 0.0)
        w_child = np.clip(0.5 + cos / (2.0 * blend[lo:hi]), 0.0, 1.0)
        w1 = np.where(child_is_b2, 1.0 - w_child, w_child)
        w1 = np.where(has2, w1, 1.0)
        j1 = bones.joint[b1]
        j2 = bones.joint[b2s]
        swap = w1 < 0.5
        joints[lo:hi, 0] = np.where(swap, j2, j1)
        joints[lo:hi, 1] = np.where(swap, j1, j2)
        weights[lo:hi, 0] = np.where(swap, 1.0 - w1, w1)
        weights[lo:hi, 1] = 1.0 - weights[lo:hi, 0]
    if rigid_joint is not None:
        rigid_joint = np.asarray(rigid_joint, dtype=np.int64)
        fixed = rigid_joint >= 0
        joints[fixed, 0] = rigid_joint[fixed]
        joints[fixed, 1] = rigid_joint[fixed]
        weights[fixed] = (1.0, 0.0)
    return joints, weights


def skinning_matrices(
    world_pos: np.ndarray,
    world_rot: np.ndarray,
    bind_pos: np.ndarray,
    bind_rot: np.ndarray | None = None,
) -> np.ndarray:
    """Per-joint ``[R | t]`` (..., J, 3, 4) taking bind-pose points to the posed frame.

    world_pos : (..., J, 3), world_rot : (..., J, 4) from forward kinematics;
    bind_pos : (J, 3) and bind_rot : (J, 4) world joint positions and rotations of
    the bind pose (``None``: identity, the rest pose).
    """
    r = rot.to_matrix(np.asarray(world_rot, dtype=float))
    if bind_rot is not None:
        r = r @ np.swapaxes(rot.to_matrix(np.asarray(bind_rot, dtype=float)), -1, -2)
    t = np.asarray(world_pos, dtype=float) - np.einsum("...ij,...j->...i", r, bind_pos)
    return np.concatenate([r, t[..., None]], axis=-1)


def linear_blend_skinning(
    vertices: np.ndarray,
    normals: np.ndarray | None,
    joints: np.ndarray,
    weights: np.ndarray,
    matrices: np.ndarray,
) -> tuple[np.ndarray, np.ndarray | None]:
    """Skin rest ``vertices (V, 3)`` (and ``normals``) with ``matrices (J, 3, 4)``.

    ``joints (V, K)`` and ``weights (V, K)``; returns posed vertices ``(V, 3)`` and unit
    normals ``(V, 3)`` (``None`` when no normals are given).
    """
    m = np.einsum("vk,vkij->vij", weights, matrices[joints])  # (V, 3, 4) blended
    out = np.einsum("vij,vj->vi", m[:, :, :3], vertices) + m[:, :, 3]
    if normals is None:
        return out, None
    n = np.einsum("vij,vj->vi", m[:, :, :3], normals)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    return out, n


@dataclass(frozen=True)
class SkinnedMesh:
    """A triangle mesh bound to a skeleton in a bind pose.

    vertices : (V, 3) float, bind pose, file units (the skeleton's world frame)
    faces : (T, 3) int
    normals : (V, 3) float, unit
    colors : (V, 4) float in [0, 1] (RGBA)
    joints : (V, 2) int, weights : (V, 2) float (two-bone weights, rows sum to 1)
    bind_positions : (J, 3) float, world joint positions of the bind pose
    bind_rotations : (J, 4) float, their world rotations (identity: the rest pose)
    part : (V,) int, index into ``part_names`` (e.g. ``"body"``, ``"left_hand"``)
    part_names : tuple of str
    """

    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    colors: np.ndarray
    joints: np.ndarray
    weights: np.ndarray
    bind_positions: np.ndarray
    bind_rotations: np.ndarray
    part: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    part_names: tuple[str, ...] = ("body",)

    def __post_init__(self) -> None:
        v = np.asarray(self.vertices, dtype=float)
        n = v.shape[0]
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "faces", np.asarray(self.faces, dtype=np.int64))
        object.__setattr__(self, "normals", np.asarray(self.normals, dtype=float))
        object.__setattr__(self, "colors", np.asarray(self.colors, dtype=float))
        object.__setattr__(self, "joints", np.asarray(self.joints, dtype=np.int64))
        object.__setattr__(self, "weights", np.asarray(self.weights, dtype=float))
        object.__setattr__(
            self, "bind_positions", np.asarray(self.bind_positions, dtype=float).reshape(-1, 3)
        )
        object.__setattr__(
            self, "bind_rotations", np.asarray(self.bind_rotations, dtype=float).reshape(-1, 4)
        )
        if self.bind_rotations.shape[0] != self.bind_positions.shape[0]:
            raise ValueError(
                f"skinned mesh: bind_rotations {self.bind_rotations.shape} do not "
                f"match bind_positions {self.bind_positions.shape}"
            )
        part = np.asarray(self.part, dtype=np.int64)
        object.__setattr__(self, "part", part if part.size else np.zeros(n, np.int64))
        for name, shape in (("normals", (n, 3)), ("colors", (n, 4)), ("part", (n,))):
            if getattr(self, name).shape != shape:
                raise ValueError(
                    f"skinned mesh: {name} must be {shape}, got {getattr(self, name).shape}"
                )
        if self.joints.shape != self.weights.shape or self.joints.shape[0] != n:
            raise ValueError(
                f"skinned mesh: joints {self.joints.shape} and weights "
                f"{self.weights.shape} must both be ({n}, K)"
            )
        if self.joints.size and (
            self.joints.min() < 0 or self.joints.max() >= self.bind_positions.shape[0]
        ):
            raise ValueError("skinned mesh: a vertex is bound to a joint that does not exist")
        if self.faces.size and (self.faces.min() < 0 or self.faces.max() >= n):
            raise ValueError("skinned mesh: a face refers to a vertex that does not exist")

    @property
    def n_vertices(self) -> int:
        return int(self.vertices.shape[0])

    def pose(self, world_pos: np.ndarray, world_rot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Posed vertices and normals ``(V, 3)`` for one frame's world joint positions
        ``(J, 3)`` and rotations ``(J, 4)`` (``forward_kinematics`` output)."""
        mats = skinning_matrices(world_pos, world_rot, self.bind_positions, self.bind_rotations)
        verts, normals = linear_blend_skinning(
            self.vertices, self.normals, self.joints, self.weights, mats
        )
        return verts, normals

    def part_mask(self, *names: str) -> np.ndarray:
        """(V,) bool: vertices whose part is one of ``names``."""
        ids = [i for i, p in enumerate(self.part_names) if p in names]
        return np.isin(self.part, ids)

    def to_trimesh(self, vertices: np.ndarray | None = None):
        """A ``trimesh.Trimesh`` of the bind-pose (or given) vertices with vertex colours."""
        import trimesh

        return trimesh.Trimesh(
            vertices=self.vertices if vertices is None else vertices,
            faces=self.faces,
            vertex_colors=(np.clip(self.colors, 0, 1) * 255).astype(np.uint8),
            process=False,
        )


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals ``(V, 3)`` of a triangle mesh."""
    tri = vertices[faces]
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n = len(vertices)
    vn = np.zeros_like(vertices)
    for c in range(3):
        vn[:, c] = sum(np.bincount(faces[:, k], weights=fn[:, c], minlength=n) for k in range(3))
    norm = np.linalg.norm(vn, axis=1, keepdims=True)
    return np.where(norm > 0, vn / np.where(norm > 0, norm, 1.0), np.array([0.0, 1.0, 0.0]))
