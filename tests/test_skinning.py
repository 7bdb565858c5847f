"""Two-bone skin weights (Jin & Hahn rule) and linear blend skinning."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.mesh.skinning import (
    Bones,
    SkinnedMesh,
    linear_blend_skinning,
    segment_distances,
    skinning_matrices,
    two_bone_weights,
    vertex_normals,
)
from engine.model import rotations as rot
from engine.model.kinematics import forward_kinematics, rest_positions
from engine.model.motion import Motion, Skeleton


def chain_skeleton(bend_deg: float = 0.0) -> Skeleton:
    """root -> a -> b -> c along +x, unit bones; b's bone bent by ``bend_deg`` about z."""
    a = np.radians(bend_deg)
    return Skeleton(
        names=("root", "a", "b", "c"),
        parents=np.array([-1, 0, 1, 2]),
        offsets=np.array([[0, 0, 0], [1, 0, 0], [1, 0, 0], [np.cos(a), np.sin(a), 0]]),
        channels=(("Xrotation", "Yrotation", "Zrotation"),) * 4,
    )


def chain_bones(sk: Skeleton) -> Bones:
    pos = rest_positions(sk)
    return Bones(pos[:-1], pos[1:], joint=[0, 1, 2], head=[0, 1, 2], tail=[1, 2, 3])


def test_far_vertices_follow_one_bone_and_the_bisector_splits_evenly():
    sk = chain_skeleton()
    bones = chain_bones(sk)
    # a ring of vertices around bone 0 middle, one on the joint plane at x=1, one mid bone 1
    theta = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    ring = np.stack([np.zeros(8), 0.1 * np.cos(theta), 0.1 * np.sin(theta)], 1)
    verts = np.vstack([ring + [0.5, 0, 0], ring + [1.0, 0, 0], ring + [1.5, 0, 0]])
    joints, weights = two_bone_weights(verts, bones, blend=0.5)
    assert np.allclose(weights.sum(1), 1.0)
    mid0, plane, mid1 = weights[:8], weights[8:16], weights[16:]
    assert np.allclose(mid0[:, 0], 1.0) and np.all(joints[:8, 0] == 0)
    assert np.allclose(mid1[:, 0], 1.0) and np.all(joints[16:, 0] == 1)
    # on the bisecting plane of the straight joint: cos = 0 -> 0.5 / 0.5 between joints 0 and 1
    assert np.allclose(plane, 0.5)
    assert set(map(int, np.unique(joints[8:16]))) == {0, 1}


def test_angular_median_of_a_bent_joint():
    """At a 90-degree bend the bisector plane is at 45 degrees: points on it split 50/50,
    points just past it lean to the bone they are on."""
    sk = chain_skeleton(bend_deg=90.0)
    bones = chain_bones(sk)
    # bones 1 (x from 1 to 2) and 2 (from (2,0,0) up +y); joint at (2,0,0)
    median = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)  # unit(u_parent + u_child)
    normal_in_plane = np.array([-1.0, 1.0, 0.0]) / np.sqrt(2)  # lies on the bisecting plane
    on_plane = np.array([2.0, 0, 0]) + 0.1 * normal_in_plane
    toward_child = on_plane + 0.05 * median
    toward_parent = on_plane - 0.05 * median
    joints, weights = two_bone_weights(np.array([on_plane, toward_child, toward_parent]), bones)
    assert np.allclose(weights[0], [0.5, 0.5])
    w_child = {int(j): w for j, w in zip(joints[1], weights[1], strict=True)}
    w_parent = {int(j): w for j, w in zip(joints[2], weights[2], strict=True)}
    assert w_child[2] > 0.5 and w_parent[1] > 0.5


def test_weights_are_exact_jin_hahn_formula():
    sk = chain_skeleton()
    bones = chain_bones(sk)
    rng = np.random.default_rng(3)
    pts = np.array([1.0, 0, 0]) + rng.normal(scale=0.2, size=(50, 3))
    pts[:, 0] = np.clip(pts[:, 0], 0.6, 1.4)  # nearest bone is 0 or 1
    blend = 0.7
    joints, weights = two_bone_weights(pts, bones, blend=blend)
    rel = pts - [1.0, 0, 0]
    cos = rel[:, 0] / np.linalg.norm(rel, axis=1)  # median = +x
    w_child = np.clip(0.5 + cos / (2 * blend), 0, 1)
    got_child = np.where(joints[:, 0] == 1, weights[:, 0], weights[:, 1])
    assert np.allclose(got_child, w_child)


def test_second_bone_must_be_adjacent():
    """Two parallel fingers 1 cm apart: a vertex on finger A never takes weight from B."""
    bones = Bones(
        start=[[0, 0, 0], [1, 0, 0], [0, 0.02, 0], [1, 0.02, 0]],
        end=[[1, 0, 0], [2, 0, 0], [1, 0.02, 0], [2, 0.02, 0]],
        joint=[0, 1, 2, 3],
        head=[0, 1, 2, 3],
        tail=[1, -1, 3, -1],
    )
    verts = np.array([[0.5, 0.009, 0.0], [1.5, 0.009, 0.0], [0.99, 0.009, 0.0]])
    joints, weights = two_bone_weights(verts, bones)
    used = {int(j) for j, w in zip(joints.ravel(), weights.ravel(), strict=True) if w > 0}
    assert used <= {0, 1}


def test_owner_and_rigid_override_nearest():
    """The owner bone wins over the nearest one (a hand hanging by the thigh)."""
    bones = Bones(
        start=[[0, 0, 0], [1, 0, 0], [0, 0.02, 0], [1, 0.02, 0]],
        end=[[1, 0, 0], [2, 0, 0], [1, 0.02, 0], [2, 0.02, 0]],
        joint=[0, 1, 2, 3],
        head=[0, 1, 2, 3],
        tail=[1, -1, 3, -1],
    )
    v = np.array([[0.5, 0.018, 0.0], [0.5, 0.018, 0.0], [0.5, 0.018, 0.0]])
    joints, weights = two_bone_weights(
        v, bones, owner=np.array([0, -1, -1]), rigid_joint=np.array([-1, -1, 3])
    )
    assert joints[0, 0] == 0 and weights[0, 0] == 1.0  # owner: finger A, though B is nearer
    assert joints[1, 0] == 2 and weights[1, 0] == 1.0  # nearest: finger B
    assert np.all(joints[2] == 3) and np.allclose(weights[2], [1.0, 0.0])  # rigid


def test_invalid_inputs_raise():
    bones = chain_bones(chain_skeleton())
    with pytest.raises(ValueError, match="vertices must be"):
        two_bone_weights(np.zeros((3, 2)), bones)
    with pytest.raises(ValueError, match="blend"):
        two_bone_weights(np.zeros((3, 3)), bones, blend=0.0)
    with pytest.raises(ValueError, match="owner"):
        two_bone_weights(np.zeros((3, 3)), bones, owner=np.array([0, 9, 0]))
    with pytest.raises(ValueError, match="entries"):
        Bones(np.zeros((2, 3)), np.ones((2, 3)), joint=[0], head=[0, 1], tail=[1, 2])


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n_bones=st.integers(1, 6), blend=st.floats(0.05, 1.0))
def test_weights_sum_to_one_and_lie_in_unit_interval(seed, n_bones, blend):
    rng = np.random.default_rng(seed)
    # a random tree of bones: each starts at the end of an earlier one
    start, end, head, tail = [np.zeros(3)], [rng.normal(size=3)], [0], [1]
    for b in range(1, n_bones):
        parent = int(rng.integers(0, b))
        start.append(end[parent])
        end.append(end[parent] + rng.normal(size=3))
        head.append(tail[parent])
        tail.append(b + 1)
    bones = Bones(np.array(start), np.array(end), joint=np.arange(n_bones), head=head, tail=tail)
    verts = rng.normal(scale=2.0, size=(200, 3))
    joints, weights = two_bone_weights(verts, bones, blend=blend)
    assert np.all(weights >= 0) and np.all(weights <= 1)
    assert np.allclose(weights.sum(axis=1), 1.0)
    assert np.all(weights[:, 0] >= weights[:, 1])
    assert np.all((joints >= 0) & (joints < n_bones))


def test_segment_distances_match_brute_force():
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(4, 3)), rng.normal(size=(4, 3))
    p = rng.normal(size=(30, 3))
    d = segment_distances(p, a, b)
    t = np.linspace(0, 1, 20001)
    for k in range(4):
        line = a[k] + t[:, None] * (b[k] - a[k])
        brute = np.min(np.linalg.norm(p[:, None] - line[None], axis=2), axis=1)
        assert np.allclose(d[:, k], brute, atol=1e-3)


def _random_motion(sk: Skeleton, n_frames: int, rng) -> Motion:
    axis = rng.normal(size=(n_frames, sk.n_joints, 3))
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    rots = rot.from_axis_angle(axis, rng.uniform(-1.5, 1.5, size=(n_frames, sk.n_joints)))
    trans = np.broadcast_to(sk.offsets, (n_frames, sk.n_joints, 3)).copy()
    trans[:, 0] = rng.normal(size=(n_frames, 3))
    return Motion(sk, rots, trans, 30.0)


def test_skinning_the_bind_pose_reproduces_the_mesh():
    sk = chain_skeleton(bend_deg=30.0)
    rng = np.random.default_rng(1)
    verts = rng.normal(scale=0.3, size=(100, 3)) + [1.5, 0, 0]
    joints, weights = two_bone_weights(verts, chain_bones(sk))
    normals = rng.normal(size=(100, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    rest = rest_positions(sk)
    mats = skinning_matrices(rest, rot.identity((sk.n_joints,)), rest)
    out, n_out = linear_blend_skinning(verts, normals, joints, weights, mats)
    assert np.allclose(out, verts, atol=1e-12) and np.allclose(n_out, normals, atol=1e-12)
    # a captured frame as the bind pose: posing at that same frame is the identity
    motion = _random_motion(sk, 3, rng)
    pos, wrot = forward_kinematics(motion)
    mats = skinning_matrices(pos[2], wrot[2], pos[2], wrot[2])
    out, _ = linear_blend_skinning(verts, None, joints, weights, mats)
    assert np.allclose(out, verts, atol=1e-10)


def test_rigid_vertices_move_with_their_joint():
    sk = chain_skeleton()
    rng = np.random.default_rng(2)
    motion = _random_motion(sk, 5, rng)
    pos, wrot = forward_kinematics(motion)
    rest = rest_positions(sk)
    local = np.array([[0.3, 0.1, -0.2], [0.7, -0.1, 0.05]])  # offsets from joint 1 at rest
    verts = rest[1] + local
    joints = np.array([[1, 1], [1, 1]])
    weights = np.array([[1.0, 0.0], [1.0, 0.0]])
    for f in range(5):
        mats = skinning_matrices(pos[f], wrot[f], rest)
        out, _ = linear_blend_skinning(verts, None, joints, weights, mats)
        expected = pos[f, 1] + rot.rotate(wrot[f, 1], local)
        assert np.allclose(out, expected, atol=1e-12)


def test_skinned_mesh_validates_shapes():
    v = np.zeros((3, 3))
    with pytest.raises(ValueError, match="normals"):
        SkinnedMesh(
            v,
            [[0, 1, 2]],
            np.zeros((2, 3)),
            np.ones((3, 4)),
            np.zeros((3, 2)),
            np.ones((3, 2)) / 2,
            np.zeros((1, 3)),
            rot.identity((1,)),
        )
    with pytest.raises(ValueError, match="joint that does not exist"):
        SkinnedMesh(
            v,
            [[0, 1, 2]],
            np.zeros((3, 3)),
            np.ones((3, 4)),
            np.full((3, 2), 4),
            np.ones((3, 2)) / 2,
            np.zeros((1, 3)),
            rot.identity((1,)),
        )
    with pytest.raises(ValueError, match="face"):
        SkinnedMesh(
            v,
            [[0, 1, 7]],
            np.zeros((3, 3)),
            np.ones((3, 4)),
            np.zeros((3, 2)),
            np.ones((3, 2)) / 2,
            np.zeros((1, 3)),
            rot.identity((1,)),
        )


def test_vertex_normals_of_a_box_point_outwards():
    import trimesh

    box = trimesh.creation.box()
    n = vertex_normals(np.asarray(box.vertices), np.asarray(box.faces))
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
    assert np.all(np.einsum("vi,vi->v", n, box.vertices) > 0)
