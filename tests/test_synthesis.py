"""Hand synthesis: easings, pose library, coupling, speed matching, and skeletons."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import MOCAP

from engine.base.errors import ParameterError
from engine.gesture.synthesis import (
    DIP_PER_PIP,
    EASINGS,
    HAND_POSES,
    couple_dip,
    gaussian_step,
    get_pose,
    interpolate_keys,
    key_weights,
    solve_hermite_time,
    speed_matched_warp,
    warp_flexion,
)


def test_library_has_the_named_poses_and_the_dip_coupling():
    names = {"relaxed", "fist", "open", "point", "ok", "one", "two", "three", "four", "five"}
    assert names <= set(HAND_POSES)
    for pose in HAND_POSES.values():
        a = pose.angles
        assert a.shape == (5, 3)
        np.testing.assert_allclose(a[1:, 2], DIP_PER_PIP * a[1:, 1])
    assert get_pose("FIST").angles[1:, 1].min() > 80  # curled fingers
    assert np.all(get_pose("open").angles == 0)
    # counting: the number of extended fingers (PIP < 10 degrees) among all five
    for n, name in enumerate(("one", "two", "three", "four", "five"), start=1):
        ext = get_pose(name).angles[:, 1] < 10
        assert ext.sum() == n, name
    with pytest.raises(ParameterError, match="fist"):
        get_pose("claw")


@pytest.mark.parametrize("easing", EASINGS)
def test_interpolation_hits_the_keys_and_holds_outside(easing):
    keys = [10, 30, 45, 80]
    vals = np.array([get_pose(n).angles for n in ("open", "fist", "point", "relaxed")])
    out = interpolate_keys(100, keys, vals, easing)
    assert out.shape == (100, 5, 3)
    for k, v in zip(keys, vals):
        np.testing.assert_allclose(out[k], v, atol=1e-9)
    np.testing.assert_allclose(out[:10], vals[0][None].repeat(10, 0))
    np.testing.assert_allclose(out[80:], vals[-1][None].repeat(20, 0))
    # DIP = 2/3 PIP on every frame, for every easing
    np.testing.assert_allclose(out[:, 1:, 2], DIP_PER_PIP * out[:, 1:, 1], atol=1e-9)
    # within each interval the angle moves monotonically between the two keys
    for (a, b), (va, vb) in zip(zip(keys, keys[1:]), zip(vals, vals[1:])):
        seg = out[a : b + 1, 2, 1]
        d = np.diff(seg) * np.sign(vb[2, 1] - va[2, 1])
        assert np.all(d >= -1e-9)


@pytest.mark.parametrize("easing", ["hermite", "gaussian"])
def test_smooth_easings_have_no_velocity_jumps(easing):
    keys = np.array([0.0, 20.0, 70.0, 90.0]) * 10  # fine sampling: 10 samples per frame
    vals = np.array([0.0, 90.0, 10.0, 60.0])
    y = interpolate_keys(901, keys, vals, easing)
    v = np.diff(y)
    peak = np.abs(v).max()
    # the velocity changes by a small fraction of its peak between samples everywhere,
    # including across the keys (zero velocity on both sides of a key)
    assert np.abs(np.diff(v)).max() < 0.02 * peak
    for k in keys[1:-1].astype(int):
        assert abs(v[k - 1]) < 0.01 * peak and abs(v[k]) < 0.01 * peak
    # linear easing does jump at keys
    lin = np.diff(interpolate_keys(901, keys, vals, "linear"))
    assert np.abs(np.diff(lin)).max() > 0.5 * np.abs(lin).max()


def test_hermite_solves_the_time_cubic():
    x0, x1, m0, m1 = 2.0, 7.0, 9.0, 2.0
    t = np.linspace(0, 1, 2001)
    x = (
        (2 * t**3 - 3 * t**2 + 1) * x0
        + (t**3 - 2 * t**2 + t) * m0
        + (-2 * t**3 + 3 * t**2) * x1
        + (t**3 - t**2) * m1
    )
    np.testing.assert_allclose(solve_hermite_time(x0, x1, m0, m1, x), t, atol=1e-10)
    # equal key spacing gives a linear x(t): the Hermite easing is the smoothstep
    y = interpolate_keys(21, [0, 10, 20], [0.0, 1.0, 0.0], "hermite")
    u = np.r_[np.arange(11) / 10, 1 - np.arange(1, 11) / 10]
    np.testing.assert_allclose(y, 3 * u**2 - 2 * u**3, atol=1e-12)


def test_gaussian_step_shape():
    u = np.linspace(0, 1, 1001)
    s = gaussian_step(u)
    assert s[0] == pytest.approx(0) and s[-1] == pytest.approx(1) and s[500] == pytest.approx(0.5)
    assert np.all(np.diff(s) >= 0)
    ds = np.gradient(s, u)
    assert abs(ds[0]) < 0.01 and abs(ds[-1]) < 0.01


def test_key_frame_validation():
    with pytest.raises(ParameterError, match="increasing"):
        interpolate_keys(10, [5, 3], np.zeros((2, 5, 3)))
    with pytest.raises(ParameterError, match="easing"):
        key_weights(10, [0, 5], "cubic")
    with pytest.raises(ParameterError, match="2 key frames but 3"):
        interpolate_keys(10, [0, 5], np.zeros((3, 5, 3)))
    one = interpolate_keys(5, [2], get_pose("fist").angles[None])
    np.testing.assert_allclose(one, get_pose("fist").angles[None].repeat(5, 0))


def test_warp_and_coupling():
    a = get_pose("relaxed").angles
    np.testing.assert_allclose(warp_flexion(a, 1.5), 1.5 * a)
    with pytest.raises(ParameterError, match="factor"):
        warp_flexion(a, -1)
    b = a.copy()
    b[1:, 2] = np.nan
    b[0, 2] = np.nan
    c = couple_dip(b)
    np.testing.assert_allclose(c[1:, 2], DIP_PER_PIP * a[1:, 1])
    assert np.isnan(c[0, 2])  # the thumb is not coupled


def test_speed_matched_warp_maps_keys_to_cycle_ends():
    body_keys = [10, 40, 100]
    clip_keys = [5, 25, 45]
    w = speed_matched_warp(body_keys, clip_keys, 130, 60, 30.0, 60.0)
    assert w.shape == (130,)
    # key poses land on the clip's cycle boundaries
    assert w[10] == pytest.approx(5) and w[39] < 25 and w[100] == pytest.approx(45)
    # uniform speed inside each interval: 20 clip frames over 30 then 60 body frames
    np.testing.assert_allclose(np.diff(w[10:40]), 20 / 30)
    np.testing.assert_allclose(np.diff(w[40:100]), 20 / 60)
    # outside the keys the clip runs at its own speed (2 clip frames per body frame)
    np.testing.assert_allclose(np.diff(w[8:11]), 2.0)
    assert w[0] == 0.0  # clamped to the clip
    np.testing.assert_allclose(np.diff(w[100:108]), 2.0)
    assert w.min() >= 0 and w.max() <= 59
    # more body intervals than clip cycles: the cycles repeat
    w = speed_matched_warp([0, 10, 20, 30], [0, 8, 16], 31, 17, 30.0, 30.0)
    assert w[20] == pytest.approx(0.0) and w[25] == pytest.approx(4.0)
    with pytest.raises(ParameterError, match="clip key frames"):
        speed_matched_warp([0, 10], [5], 20, 20, 30.0, 30.0)


# ---------------------------------------------------------------------------
# On real skeletons

BEAT = MOCAP / "beat" / "1_wayne_0_1_1.bvh"
CLENCH = MOCAP / "gestification" / "clenching.bvh"


@pytest.fixture(scope="module")
def beat():
    from engine.io.bvh import read_bvh

    return read_bvh(BEAT)


def _tips_in_wrist_frame(motion, rig):
    from engine.model import rotations as rot
    from engine.model.kinematics import forward_kinematics

    pos, wrot = forward_kinematics(motion)
    last = [int(rig.joints[f][rig.joints[f] >= 0][-1]) for f in range(5)]
    rel = pos[:, last] - pos[:, [rig.wrist]]
    inv = rot.conjugate(wrot[:, rig.wrist])[:, None]
    return rot.rotate(np.broadcast_to(inv, rel.shape[:2] + (4,)), rel) * motion.meters_per_unit


def test_flexion_axes_curl_fingers_into_the_palm(beat):
    from engine.gesture.synthesis import apply_flexion, extract_flexion, hand_rig

    for side in ("right", "left"):
        rig = hand_rig(beat.skeleton, side)
        assert rig.n_joints == 15
        rest = beat.frames(0, 1)
        open_ = apply_flexion(rest, rig, get_pose("open").angles[None])
        fist = apply_flexion(rest, rig, get_pose("fist").angles[None])
        t_open, t_fist = _tips_in_wrist_frame(open_, rig)[0], _tips_in_wrist_frame(fist, rig)[0]
        # fingertips come closer to the wrist and move to the palm side
        assert np.all(np.linalg.norm(t_fist[1:], axis=1) < 0.8 * np.linalg.norm(t_open[1:], axis=1))
        assert np.all((t_fist[1:] - t_open[1:]) @ rig.palm_normal > 0.02)
        # the captured BEAT fingers read as mostly flexed (positive) angles
        cap = extract_flexion(beat, rig)
        assert np.nanmean(cap[:, 1:, 1]) > 10
        # apply then extract is exact
        np.testing.assert_allclose(
            extract_flexion(fist, rig)[0], get_pose("fist").angles, atol=1e-9
        )


@pytest.mark.parametrize("easing", ["hermite", "gaussian"])
def test_pose_synthesis_is_smooth_and_coupled(beat, easing):
    from engine.gesture.synthesis import extract_flexion, hand_rig, synthesize_from_poses

    keys = ["relaxed@0", "fist@40", "point@100", "ok@160", "five@-1"]
    out = synthesize_from_poses(beat, keys, easing=easing)
    rig = hand_rig(beat.skeleton, "right")
    got = extract_flexion(out.motion, rig)
    for frame, name in [(0, "relaxed"), (40, "fist"), (100, "point"), (160, "ok"), (249, "five")]:
        np.testing.assert_allclose(got[frame], get_pose(name).angles, atol=1e-9)
    np.testing.assert_allclose(got[:, 1:, 2], DIP_PER_PIP * got[:, 1:, 1], atol=1e-9)

    # fingertip velocity (wrist frame) has no jumps: frame-to-frame change of velocity
    # stays a small fraction of the peak speed (the linear easing jumps by far more)
    def jerkiness(motion):
        v = np.diff(_tips_in_wrist_frame(motion, rig), axis=0)
        return np.abs(np.diff(v, axis=0)).max() / np.abs(v).max()

    assert jerkiness(out.motion) < 0.25
    linear = synthesize_from_poses(beat, keys, easing="linear")
    assert jerkiness(linear.motion) > 1.5 * jerkiness(out.motion)
    # the body is untouched
    body = [j for j in range(beat.skeleton.n_joints) if j not in set(rig.joints.ravel())]
    left = hand_rig(beat.skeleton, "left")
    body = [j for j in body if j not in set(left.joints.ravel())]
    np.testing.assert_array_equal(out.motion.rotations[:, body], beat.rotations[:, body])


def test_finger_less_bodies_get_grafted_fingers():
    from engine.base.errors import RoleError
    from engine.gesture.synthesis import (
        extract_flexion,
        graft_fingers,
        hand_rig,
        synthesize_from_poses,
    )
    from engine.io.bvh import read_bvh
    from engine.model.kinematics import forward_kinematics
    from engine.model.roles import find_roles

    body = read_bvh(MOCAP / "bandai-namco" / "dataset-2_wave-right-hand_normal_001.bvh").frames(
        0, 40
    )
    with pytest.raises(RoleError, match="no finger joints"):
        synthesize_from_poses(body, ["fist@0"], graft=False)
    with pytest.raises(ParameterError, match="POSE@FRAME"):
        synthesize_from_poses(body, ["fist"])
    grafted = graft_fingers(body)
    n = body.skeleton.n_joints
    assert grafted.skeleton.n_joints == n + 30
    # the body itself does not move
    np.testing.assert_allclose(forward_kinematics(grafted)[0][:, :n], forward_kinematics(body)[0])
    roles = find_roles(grafted.skeleton)
    for side in ("right", "left"):
        rig = hand_rig(grafted.skeleton, side, roles)
        assert rig.n_joints == 15
        # a hand about 0.7 forearm lengths long (scaled to this body, in its cm units)
        pos = forward_kinematics(grafted.frames(0, 1))[0][0]
        forearm = np.linalg.norm(pos[roles.side(side).wrist] - pos[roles.side(side).elbow])
        middle = rig.joints[2]
        reach = np.linalg.norm(pos[middle[2]] - pos[rig.wrist])
        assert 0.45 < reach / forearm < 0.9
    out = synthesize_from_poses(body, ["open@0", "fist@39"])
    rig = hand_rig(out.motion.skeleton, "right")
    np.testing.assert_allclose(
        extract_flexion(out.motion, rig)[39], get_pose("fist").angles, atol=1e-9
    )
    t_open = _tips_in_wrist_frame(out.motion.frames(0, 1), rig)[0]
    t_fist = _tips_in_wrist_frame(out.motion.frames(39, 40), rig)[0]
    assert np.all(np.linalg.norm(t_fist[1:], axis=1) < 0.8 * np.linalg.norm(t_open[1:], axis=1))


def test_clip_synthesis_matches_speed_and_end_poses(beat):
    from engine.gesture.synthesis import (
        clip_key_frames,
        extract_flexion,
        hand_rig,
        synthesize_from_clip,
    )
    from engine.io.bvh import read_bvh
    from engine.model.roles import find_roles

    clip = read_bvh(CLENCH)
    clip_rig = hand_rig(clip.skeleton, "right", find_roles(clip.skeleton))
    ckeys = clip_key_frames(clip, clip_rig)
    assert ckeys[0] == 0 and ckeys[-1] == clip.n_frames - 1 and len(ckeys) >= 3
    bkeys = [0, 50, 120, 200, 249]
    out = synthesize_from_clip(beat, clip, "right", body_keys=bkeys, clip_keys=ckeys)
    rig = hand_rig(beat.skeleton, "right")
    src = extract_flexion(clip, clip_rig)
    got = extract_flexion(out.motion, rig)
    n_cycles = len(ckeys) - 1
    for k, b in enumerate(bkeys[:-1]):  # each body key plays the start of a clip cycle
        want = src[ckeys[k % n_cycles]]
        np.testing.assert_allclose(got[b][np.isfinite(want)], want[np.isfinite(want)], atol=1e-6)
    # uniform speed inside an interval
    t = out.clip_time["right"]
    np.testing.assert_allclose(np.diff(t[50:120]), np.diff(t[50:120]).mean(), rtol=1e-9)
    # the left hand keeps its captured motion; warping scales the flexion
    left = hand_rig(beat.skeleton, "left").joints
    np.testing.assert_array_equal(
        out.motion.rotations[:, left[left >= 0]], beat.rotations[:, left[left >= 0]]
    )
    half = synthesize_from_clip(beat, clip, "right", factor=0.5, body_keys=bkeys, clip_keys=ckeys)
    np.testing.assert_allclose(extract_flexion(half.motion, rig), 0.5 * got, atol=1e-6)


def test_synthesized_take_survives_a_bvh_round_trip(beat, tmp_path):
    from engine.gesture.synthesis import extract_flexion, hand_rig, synthesize_from_poses
    from engine.io.bvh import read_bvh, write_bvh

    out = synthesize_from_poses(beat.frames(0, 60), ["open@0", "fist@59"], sides=("left",))
    write_bvh(out.motion, tmp_path / "hands.bvh")
    back = read_bvh(tmp_path / "hands.bvh")
    rig = hand_rig(back.skeleton, "left")
    np.testing.assert_allclose(extract_flexion(back, rig), out.angles["left"], atol=1e-4)
