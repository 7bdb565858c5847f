"""Procedural mannequin, body-part finding and user-mesh binding, on real skeletons."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import mocap_files

from engine.io.bvh import read_bvh
from engine.mesh import bind_mesh, build_mannequin, find_anatomy, load_mesh, mannequin_for
from engine.mesh.bind import MeshFormatError
from engine.model import rotations as rot
from engine.model.kinematics import forward_kinematics
from engine.model.motion import Motion, MotionMeta, Skeleton
from engine.model.roles import side_from_name

ALL_BVH = mocap_files()
FINGERS = ("thumb", "index", "middle", "ring", "pinky")


def humanoid(fingers: bool = True) -> Skeleton:
    """A hand-built T-pose humanoid (Y-up, centimetres), Mixamo-like names."""
    names, parents, offsets = [], [], []

    def add(name, parent, off):
        names.append(name)
        parents.append(-1 if parent is None else names.index(parent))
        offsets.append(off)

    add("Hips", None, [0, 95, 0])
    add("Spine", "Hips", [0, 10, 0])
    add("Chest", "Spine", [0, 20, 0])
    add("Neck", "Chest", [0, 20, 0])
    add("Head", "Neck", [0, 10, 0])
    for side, s in (("Left", 1), ("Right", -1)):
        add(f"{side}Shoulder", "Chest", [s * 5, 15, 0])
        add(f"{side}Arm", f"{side}Shoulder", [s * 13, 0, 0])
        add(f"{side}ForeArm", f"{side}Arm", [s * 28, 0, 0])
        add(f"{side}Hand", f"{side}ForeArm", [s * 25, 0, 0])
        if fingers:
            for f, z in zip(FINGERS, (4, 3, 1, -1, -3), strict=True):
                base = [s * (3 if f == "thumb" else 9), 0, z]
                add(f"{side}Hand{f.title()}1", f"{side}Hand", base)
                add(f"{side}Hand{f.title()}2", f"{side}Hand{f.title()}1", [s * 4, 0, 0])
                add(f"{side}Hand{f.title()}3", f"{side}Hand{f.title()}2", [s * 3, 0, 0])
        add(f"{side}UpLeg", "Hips", [s * 9, -5, 0])
        add(f"{side}Leg", f"{side}UpLeg", [0, -42, 0])
        add(f"{side}Foot", f"{side}Leg", [0, -42, 0])
        add(f"{side}ToeBase", f"{side}Foot", [0, -6, 12])
    return Skeleton(
        names,
        np.array(parents),
        np.array(offsets, float),
        [("Zrotation", "Xrotation", "Yrotation")] * len(names),
    )


def test_hand_built_humanoid_has_all_parts():
    sk = humanoid()
    a = find_anatomy(sk)
    assert a.kind == "body"
    assert set(a.arms) == set(a.legs) == set(a.hands) == {"left", "right"}
    assert sk.names[a.head] == "Head" and sk.names[a.pelvis] == "Hips"
    assert sk.names[a.chest] == "Chest"
    for side in ("left", "right"):
        assert set(a.hands[side].fingers) == set(FINGERS)
    assert np.allclose(a.up, [0, 1, 0], atol=0.05)
    assert np.allclose(a.left, [1, 0, 0], atol=0.05)
    assert np.allclose(a.forward, [0, 0, 1], atol=0.05)  # left x up
    assert 150 < a.height < 200  # centimetres


def test_mannequin_of_hand_built_humanoid():
    sk = humanoid()
    mesh = build_mannequin(sk)
    assert mesh.n_vertices > 2000 and len(mesh.faces) > 4000
    for part in ("body", "head", "left_hand", "right_hand"):
        assert mesh.part_mask(part).sum() > 100, part
    # the mesh spans the skeleton: feet near the floor, head above the neck
    lo, hi = mesh.vertices.min(0), mesh.vertices.max(0)
    assert lo[1] < 8 and hi[1] > 170
    # the hands sit at the ends of the arms (x beyond the wrists), not on the torso
    left = mesh.vertices[mesh.part_mask("left_hand")]
    assert left[:, 0].min() > 40 and left[:, 0].max() > 70
    # weights are valid two-bone weights
    assert np.allclose(mesh.weights.sum(1), 1) and mesh.weights.min() >= 0


def test_finger_rotation_moves_only_hand_vertices():
    sk = humanoid()
    mesh = build_mannequin(sk)
    motion = Motion.rest(sk, n_frames=2)
    rots = motion.rotations.copy()
    for f in ("index", "middle", "ring", "pinky"):
        for k in (1, 2, 3):
            j = sk.index(f"RightHand{f.title()}{k}")
            rots[1, j] = rot.from_axis_angle(np.array([0.0, 0.0, 1.0]), np.radians(60))
    moved = Motion(sk, rots, motion.translations, 30.0)
    pos, wrot = forward_kinematics(moved)
    v0, _ = mesh.pose(pos[0], wrot[0])
    v1, _ = mesh.pose(pos[1], wrot[1])
    shift = np.linalg.norm(v1 - v0, axis=1)
    assert np.allclose(v0, mesh.vertices)  # rest pose reproduces the rest mesh
    moving = shift > 1e-6
    assert moving.sum() > 50
    assert np.all(mesh.part_mask("right_hand")[moving])  # nothing outside the right hand
    assert shift.max() > 3.0  # centimetres: the finger tips swing visibly


@pytest.mark.parametrize("path", ALL_BVH, ids=[p.name for p in ALL_BVH])
def test_every_real_skeleton_gives_a_mannequin(path):
    motion = read_bvh(path)
    mesh = mannequin_for(motion.frames(0, 2))
    anatomy = find_anatomy(motion.skeleton, side_hint=side_from_name(path))
    assert mesh.n_vertices > 500
    assert mesh.faces.max() < mesh.n_vertices
    assert np.all(np.isfinite(mesh.vertices))
    assert np.allclose(mesh.weights.sum(1), 1.0) and mesh.weights.min() >= 0
    assert mesh.weights.max() <= 1.0
    assert np.allclose(np.linalg.norm(mesh.normals, axis=1), 1.0)
    # skinning the bind frame reproduces the mesh
    pos, wrot = forward_kinematics(motion, 0, 1)
    posed, _ = mesh.pose(pos[0], wrot[0])
    scale = np.ptp(mesh.vertices, axis=0).max()
    assert np.abs(posed - mesh.vertices).max() < 1e-9 * scale
    if anatomy.kind == "body":
        # a person with hands: head, both hands with fingers (procedural where missing)
        assert set(anatomy.hands) == {"left", "right"}
        assert mesh.part_mask("head").sum() > 50
        for side in ("left_hand", "right_hand"):
            assert mesh.part_mask(side).sum() > 300, side
        # proportions: height to hand length as for a person
        assert 6 < anatomy.height / anatomy.hand_length < 14
    else:
        assert len(anatomy.hands) == 1
        hand = next(iter(anatomy.hands.values()))
        assert set(hand.fingers) == set(FINGERS)
        assert mesh.part_mask("left_hand", "right_hand", "hand").sum() > 300


def test_rest_pose_that_is_not_anatomical_is_measured_on_a_frame():
    """Bandai-Namco's zero pose lies along +x with the shoulders turned against the
    hips; measured on a captured frame the body is upright (+y) and faces sideways
    of its left."""
    path = next(p for p in ALL_BVH if p.name.startswith("dataset-1_bye"))
    motion = read_bvh(path)
    pos, wrot = forward_kinematics(motion, 0, 1)
    a = find_anatomy(motion.skeleton, pos[0], wrot[0])
    assert a.up[1] > 0.9
    assert abs(np.dot(a.left, a.up)) < 1e-9 and abs(a.forward[1]) < 0.2


def test_bind_a_user_mesh_from_file(tmp_path):
    import trimesh

    sk = humanoid(fingers=False)
    # a crude "user mesh": one long box along the arms and a box for the body
    arms = trimesh.creation.box(extents=[140, 8, 8])
    arms.apply_translation([0, 140, 0])
    body = trimesh.creation.box(extents=[30, 80, 20])
    body.apply_translation([0, 110, 0])
    path = tmp_path / "user.obj"
    trimesh.util.concatenate([arms, body]).export(path)
    mesh = bind_mesh(path, sk)
    assert np.allclose(mesh.weights.sum(1), 1.0) and mesh.weights.min() >= 0
    assert np.allclose(mesh.pose(*_rest(sk))[0], mesh.vertices)
    # raise the left arm: the left end of the box follows, the body box does not
    motion = Motion.rest(sk)
    rots = motion.rotations.copy()
    rots[0, sk.index("LeftArm")] = rot.from_axis_angle(np.array([0, 0, 1.0]), np.radians(80))
    pos, wrot = forward_kinematics(Motion(sk, rots, motion.translations, 30.0))
    posed, _ = mesh.pose(pos[0], wrot[0])
    tip = np.argmax(mesh.vertices[:, 0])
    assert posed[tip, 1] > mesh.vertices[tip, 1] + 40
    low = mesh.vertices[:, 1] < 100
    assert np.allclose(posed[low], mesh.vertices[low])


def test_bind_fit_and_errors(tmp_path):
    import trimesh

    sk = humanoid(fingers=False)
    tall = trimesh.creation.box(extents=[0.5, 2.0, 0.3])  # metres, floating
    tall.apply_translation([3.0, 7.0, 0.0])
    mesh = bind_mesh(tall, sk, fit=True)
    lo, hi = mesh.vertices.min(0), mesh.vertices.max(0)
    joints_y = mesh.bind_positions[:, 1]
    assert 1.0 < (hi[1] - lo[1]) / np.ptp(joints_y) < 1.15  # a little beyond head and feet
    assert lo[1] < joints_y.min() and abs(0.5 * (lo[0] + hi[0])) < 1.0
    with pytest.raises(FileNotFoundError):
        load_mesh(tmp_path / "missing.obj")
    bad = tmp_path / "bad.xyz"
    bad.write_text("nothing")
    with pytest.raises(MeshFormatError, match="unsupported mesh format"):
        load_mesh(bad)
    empty = tmp_path / "empty.obj"
    empty.write_text("# no faces\nv 0 0 0\n")
    with pytest.raises(MeshFormatError, match="bad|no triangles|cannot read"):
        load_mesh(empty)


def test_mannequin_rejects_bad_pose():
    sk = humanoid()
    with pytest.raises(ValueError, match="pose must be"):
        build_mannequin(sk, pose=(np.zeros((3, 3)), np.zeros((3, 4))))
    tiny = Skeleton(["a"], np.array([-1]), np.zeros((1, 3)), [()])
    with pytest.raises(ValueError, match="at least 2 joints"):
        build_mannequin(tiny)


def test_units_do_not_change_the_shape():
    """The same skeleton in metres and centimetres gives the same mannequin, scaled."""
    sk = humanoid()
    sk_m = Skeleton(sk.names, sk.parents, sk.offsets / 100.0, sk.channels)
    a, b = build_mannequin(sk), build_mannequin(sk_m)
    assert np.allclose(a.vertices / 100.0, b.vertices, atol=1e-9)
    assert np.allclose(_dense(a), _dense(b), atol=1e-9)


def _dense(mesh) -> np.ndarray:
    """(V, J) weight matrix (the order of a vertex's two joints does not matter)."""
    out = np.zeros((mesh.n_vertices, mesh.bind_positions.shape[0]))
    for k in range(mesh.joints.shape[1]):
        np.add.at(out, (np.arange(mesh.n_vertices), mesh.joints[:, k]), mesh.weights[:, k])
    return out


def _rest(sk):
    motion = Motion.rest(sk, meta=MotionMeta(units="cm"))
    pos, wrot = forward_kinematics(motion)
    return pos[0], wrot[0]
