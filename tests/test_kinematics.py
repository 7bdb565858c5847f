"""Forward kinematics and resampling against independent computations."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from conftest import MOCAP

from engine.io.bvh import parse_bvh, read_bvh
from engine.model import rotations as rot
from engine.model.kinematics import (
    end_site_positions,
    forward_kinematics,
    resample,
    rest_positions,
    sample,
)
from engine.model.motion import Motion, Skeleton

ORDERS = ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"]


def _axis_matrix(axis: str, deg: float) -> np.ndarray:
    a = np.radians(deg)
    c, s = np.cos(a), np.sin(a)
    return {
        "X": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]),
        "Y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
        "Z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]),
    }[axis]


# ----------------------------------------------------------------- a hand-built arm

ARM = """HIERARCHY
ROOT shoulder
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT elbow
  {
    OFFSET 3 0 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    JOINT wrist
    {
      OFFSET 2 0 0
      CHANNELS 3 Zrotation Xrotation Yrotation
      End Site
      {
        OFFSET 1 0 0
      }
    }
  }
}
MOTION
Frames: 4
Frame Time: 0.1
1 2 3 0 0 0 0 0 0 0 0 0
1 2 3 90 0 0 -90 0 0 0 0 90
1 2 3 0 90 0 90 0 0 0 0 0
1 2 3 90 90 0 0 0 0 0 0 90
"""

# worked out by hand (upper arm 3, forearm 2, hand 1; shoulder at (1, 2, 3)):
# frame 0: straight along +x.
# frame 1: Rz(90) turns the upper arm to +y: elbow (1,5,3); the elbow's Rz(-90) undoes it,
#          forearm along +x: wrist (3,5,3); the wrist's Ry(90) turns the hand x -> -z.
# frame 2: Rx(90) leaves x alone: elbow (4,2,3); the elbow's world rotation Rx(90) Rz(90)
#          turns the forearm x -> y -> z: wrist (4,2,5), and the hand likewise: tip (4,2,6).
# frame 3: R = Rz(90) Rx(90): x -> x -> y: elbow (1,5,3), wrist (1,7,3); hand
#          Rz Rx Ry(90): x -> -z -> +y -> -x: tip (0,7,3).
ARM_POSITIONS = np.array(
    [
        [[1, 2, 3], [4, 2, 3], [6, 2, 3]],
        [[1, 2, 3], [1, 5, 3], [3, 5, 3]],
        [[1, 2, 3], [4, 2, 3], [4, 2, 5]],
        [[1, 2, 3], [1, 5, 3], [1, 7, 3]],
    ],
    dtype=float,
)
ARM_TIPS = np.array([[7, 2, 3], [3, 5, 2], [4, 2, 6], [0, 7, 3]], dtype=float)


def test_arm_joint_positions_by_hand():
    m = parse_bvh(ARM, "arm.bvh")
    pos, _ = forward_kinematics(m)
    np.testing.assert_allclose(pos, ARM_POSITIONS, atol=1e-12)


def test_arm_end_site_by_hand():
    m = parse_bvh(ARM, "arm.bvh")
    pos, wrot = forward_kinematics(m)
    tips = end_site_positions(m, pos, wrot)
    assert list(tips) == [2]
    np.testing.assert_allclose(tips[2], ARM_TIPS, atol=1e-12)


def test_arm_world_rotations_are_matrix_products():
    m = parse_bvh(ARM, "arm.bvh")
    _, wrot = forward_kinematics(m)
    rz, rx, ry = _axis_matrix("Z", 90), _axis_matrix("X", 90), _axis_matrix("Y", 90)
    np.testing.assert_allclose(rot.to_matrix(wrot[3, 0]), rz @ rx, atol=1e-12)
    np.testing.assert_allclose(rot.to_matrix(wrot[3, 2]), rz @ rx @ ry, atol=1e-12)
    np.testing.assert_allclose(rot.to_matrix(wrot[1, 1]), np.eye(3), atol=1e-12)


def test_arm_built_without_the_reader():
    sk = Skeleton(
        ["shoulder", "elbow", "wrist"],
        [-1, 0, 1],
        [[0, 0, 0], [3, 0, 0], [2, 0, 0]],
        [(), (), ()],
        {2: np.array([1.0, 0, 0])},
    )
    q = rot.identity((1, 3))
    q[0, 0] = rot.from_axis_angle(np.array([0, 0, 1.0]), np.pi / 2)
    q[0, 1] = rot.from_axis_angle(np.array([0, 0, 1.0]), -np.pi / 2)
    q[0, 2] = rot.from_axis_angle(np.array([0, 1.0, 0]), np.pi / 2)
    t = np.array([[[1, 2, 3], [3, 0, 0], [2, 0, 0]]], dtype=float)
    m = Motion(sk, q, t, 10.0)
    pos, wrot = forward_kinematics(m)
    np.testing.assert_allclose(pos[0], ARM_POSITIONS[1], atol=1e-12)
    np.testing.assert_allclose(end_site_positions(m, pos, wrot)[2][0], ARM_TIPS[1], atol=1e-12)


# ----------------------------------------------------------------- rotation orders


def _chain_text(order: str, angles: np.ndarray, offsets: np.ndarray, root: np.ndarray) -> str:
    """A chain with every joint in ``order``; ``angles (F, J, 3)`` in that order."""
    n = len(offsets)
    rots = " ".join(f"{a}rotation" for a in order)
    lines = ["HIERARCHY"]
    for j in range(n):
        kw = "ROOT" if j == 0 else "JOINT"
        chans = (
            f"CHANNELS 6 Xposition Yposition Zposition {rots}" if j == 0 else f"CHANNELS 3 {rots}"
        )
        lines += [
            f"{kw} j{j}",
            "{",
            "OFFSET " + " ".join(repr(float(v)) for v in offsets[j]),
            chans,
        ]
    lines += ["End Site", "{", "OFFSET 0 0 1", "}"] + ["}"] * n
    lines += ["MOTION", f"Frames: {len(angles)}", "Frame Time: 0.1"]
    for f in range(len(angles)):
        vals = list(root[f]) + list(angles[f].ravel())
        lines.append(" ".join(repr(float(v)) for v in vals))
    return "\n".join(lines) + "\n"


def test_same_rotation_in_six_orders_gives_same_world_positions():
    rng = np.random.default_rng(7)
    n, frames = 5, 6
    offsets = rng.uniform(-2, 2, (n, 3))
    root = rng.uniform(-10, 10, (frames, 3))
    q = rot.normalize(rng.normal(size=(frames, n, 4)))
    # independent reference: 4x4-free matrix FK straight from the quaternions' matrices
    mats = rot.to_matrix(q)
    expect = np.zeros((frames, n, 3))
    for f in range(frames):
        world, p = np.eye(3), root[f]
        for j in range(n):
            p = p + world @ offsets[j] if j else p
            world = world @ mats[f, j]
            expect[f, j] = p
    results = []
    for order in ORDERS:
        angles = rot.to_euler(q, order)
        m = parse_bvh(_chain_text(order, angles, offsets, root), f"{order}.bvh")
        assert m.skeleton.rotation_order(1) == order
        pos, wrot = forward_kinematics(m)
        np.testing.assert_allclose(pos, expect, atol=1e-9, err_msg=order)
        results.append(wrot)
    for wrot in results[1:]:
        assert rot.angle_between(wrot, results[0]).max() < 1e-9


def test_angles_in_one_order_differ_from_another():
    # guards the test above: the orders really are different conventions
    a = np.array([30.0, 40.0, 50.0])
    assert rot.angle_between(rot.from_euler(a, "ZXY"), rot.from_euler(a, "XYZ")) > 1.0


# ----------------------------------------------------------------- real files

REAL_FK = [
    MOCAP / "beat" / "1_wayne_0_1_1.bvh",  # 6 channels on every joint
    MOCAP / "lafan1" / "dance1_subject1.bvh",
    MOCAP / "gestification" / "hello-world.bvh",
    MOCAP / "animated-drawings" / "cmu1_jumping_jacks.bvh",
    MOCAP / "manipnet" / "mug1_rightHand.bvh",
]


def _text_fk(path, frame_rows: list[int]) -> np.ndarray:
    """World positions from the raw text with 4x4 homogeneous matrices (no engine code)."""
    lines = path.read_text().splitlines()
    names, parents, offsets, chans, stack = [], [], [], [], []
    last = None
    i = 0
    while not lines[i].strip().startswith("MOTION"):
        tok = lines[i].split()
        if tok and tok[0] in ("ROOT", "JOINT"):
            names.append(tok[1])
            parents.append(stack[-1] if stack else -1)
            last = len(names) - 1
        elif tok and tok[0] == "End":
            last = None
        elif tok and tok[0] == "{":
            stack.append(last if last is not None else -2)
        elif tok and tok[0] == "}":
            stack.pop()
        elif tok and tok[0] == "OFFSET" and stack[-1] >= 0 and len(offsets) < len(names):
            offsets.append([float(v) for v in tok[1:4]])
        elif tok and tok[0] == "CHANNELS":
            chans.append(tok[2:])
        i += 1
    rows = [ln.split() for ln in lines[i + 3 :] if ln.strip()]
    out = []
    for r in frame_rows:
        vals = [float(v) for v in rows[r]]
        col, world = 0, []
        for j in range(len(names)):
            local = np.eye(4)
            local[:3, 3] = offsets[j]
            for c in chans[j]:
                if c.endswith("position"):
                    local[:3, 3]["XYZ".index(c[0])] = vals[col]
                else:
                    rm = np.eye(4)
                    rm[:3, :3] = _axis_matrix(c[0], vals[col])
                    local = local @ rm
                col += 1
            world.append(local if parents[j] < 0 else world[parents[j]] @ local)
        out.append([w[:3, 3] for w in world])
    return np.array(out)


@pytest.mark.parametrize("path", REAL_FK, ids=lambda p: p.name)
def test_fk_of_real_file_matches_homogeneous_matrices(path):
    m = read_bvh(path)
    skip = 1 if path.parent.name == "gestification" else 0  # its leading zero row
    frames = [0, m.n_frames // 2, m.n_frames - 1]
    expect = _text_fk(path, [f + skip for f in frames])
    pos, _ = forward_kinematics(m)
    scale = np.abs(expect).max()
    np.testing.assert_allclose(pos[frames], expect, atol=1e-10 * scale)


@pytest.mark.parametrize("path", REAL_FK, ids=lambda p: p.name)
def test_rest_frame_fk_equals_rest_positions(path):
    sk = read_bvh(path).skeleton
    pos, wrot = forward_kinematics(Motion.rest(sk, n_frames=2))
    np.testing.assert_allclose(pos[0], rest_positions(sk), atol=1e-12)
    np.testing.assert_allclose(pos[1], rest_positions(sk), atol=1e-12)
    np.testing.assert_allclose(wrot, rot.identity(wrot.shape[:2]), atol=0)


def test_frame_ranges_match_the_full_take():
    m = read_bvh(MOCAP / "beat" / "1_wayne_0_1_1.bvh")
    pos, wrot = forward_kinematics(m)
    p2, r2 = forward_kinematics(m, 100, 140)
    np.testing.assert_array_equal(p2, pos[100:140])
    np.testing.assert_array_equal(r2, wrot[100:140])
    p3, _ = forward_kinematics(m.frames(240))
    np.testing.assert_array_equal(p3, pos[240:])
    assert forward_kinematics(m, 5, 5)[0].shape == (0, m.skeleton.n_joints, 3)


# ----------------------------------------------------------------- resampling


@pytest.fixture(scope="module")
def beat():
    return read_bvh(MOCAP / "beat" / "1_wayne_0_1_1.bvh")


def test_resample_up_and_back_returns_the_original(beat):
    up = resample(beat, 120.0)
    assert up.fps == 120.0
    assert up.n_frames == (beat.n_frames - 1) * 4 + 1
    back = resample(up, 30.0)
    assert back.n_frames == beat.n_frames
    assert rot.angle_between(back.rotations, beat.rotations).max() < 1e-9
    np.testing.assert_allclose(back.translations, beat.translations, atol=1e-12)


def test_resample_midpoints_are_slerp_midpoints(beat):
    up = resample(beat, 60.0)
    q0, q1 = beat.rotations[:-1], beat.rotations[1:]
    # independent midpoint: the normalised sum on the shorter arc
    sign = np.where(np.sum(q0 * q1, axis=-1, keepdims=True) < 0, -1.0, 1.0)
    mid = q0 + sign * q1
    mid /= np.linalg.norm(mid, axis=-1, keepdims=True)
    assert rot.angle_between(up.rotations[1::2], mid).max() < 1e-9
    np.testing.assert_allclose(
        up.translations[1::2], 0.5 * (beat.translations[:-1] + beat.translations[1:]), atol=1e-12
    )
    # the midpoint is halfway in angle between its neighbours
    np.testing.assert_allclose(
        rot.angle_between(up.rotations[1::2], q0), 0.5 * rot.angle_between(q0, q1), atol=1e-7
    )


def test_resample_keeps_duration_and_endpoints():
    m = read_bvh(MOCAP / "gestification" / "hello-world.bvh")  # 37.037 fps
    out = resample(m, 30.0)
    span_in = (m.n_frames - 1) / m.fps
    span_out = (out.n_frames - 1) / out.fps
    assert abs(span_out - span_in) <= 0.5 / out.fps
    assert rot.angle_between(out.rotations[0], m.rotations[0]).max() < 1e-12
    np.testing.assert_allclose(out.translations[0], m.translations[0])


def test_sample_clips_and_interpolates(beat):
    rots, trans = sample(beat, np.array([-3.0, 0.0, 2.25, beat.n_frames + 5.0]))
    assert rot.angle_between(rots[0], beat.rotations[0]).max() < 1e-12
    assert rot.angle_between(rots[3], beat.rotations[-1]).max() < 1e-12
    np.testing.assert_allclose(trans[2], 0.75 * beat.translations[2] + 0.25 * beat.translations[3])
    expect = rot.slerp(beat.rotations[2], beat.rotations[3], np.full(beat.skeleton.n_joints, 0.25))
    assert rot.angle_between(rots[2], expect).max() < 1e-12


def test_resample_rejects_bad_rates_and_handles_empty(beat):
    for bad in (0.0, -30.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="fps"):
            resample(beat, bad)
    empty = beat.frames(0, 0)
    assert resample(empty, 60.0).n_frames == 0
    with pytest.raises(ValueError, match="no frames"):
        sample(empty, np.array([0.0]))
    with pytest.raises(ValueError, match="finite"):
        sample(beat, np.array([np.nan]))


def test_slerp_endpoints_and_hemisphere():
    rng = np.random.default_rng(3)
    a = rot.normalize(rng.normal(size=(50, 4)))
    b = rot.normalize(rng.normal(size=(50, 4)))
    assert rot.angle_between(rot.slerp(a, b, np.zeros(50)), a).max() < 1e-12
    assert rot.angle_between(rot.slerp(a, b, np.ones(50)), b).max() < 1e-9
    # -b is the same rotation: the path must not change
    assert (
        rot.angle_between(
            rot.slerp(a, -b, np.full(50, 0.3)), rot.slerp(a, b, np.full(50, 0.3))
        ).max()
        < 1e-9
    )


def test_to_euler_inverts_from_euler_at_gimbal_lock():
    rng = np.random.default_rng(11)
    for order in ORDERS:
        e = rng.uniform(-180, 180, (200, 3))
        e[:, 1] = rng.choice([-90.0, 90.0, 90 - 1e-9, -90 + 1e-7], 200)
        q = rot.from_euler(e, order)
        back = rot.to_euler(q, order)
        assert np.abs(back[:, 1]).max() <= 90 + 1e-6
        assert rot.angle_between(rot.from_euler(back, order), q).max() < 1e-9, order


def test_motion_frames_slice_is_a_motion(beat):
    part = beat.frames(10, 20)
    assert part.n_frames == 10 and part.fps == beat.fps
    assert replace(part).skeleton is beat.skeleton
