"""Key poses (Jin & Hahn): distance map, contrast enhancement, stepwise search."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import uniform_filter

from engine.base.errors import ParameterError
from engine.gesture.keyposes import (
    KeyPoseParameters,
    find_key_poses,
    pose_distance_map,
)

FPS = 30.0


def _arm(tip_x: np.ndarray, elbow_scale: float = 0.5) -> np.ndarray:
    """(F, 4, 3) shoulder, elbow, wrist, tip with the forearm swinging sideways."""
    n = len(tip_x)
    pts = np.zeros((n, 4, 3))
    pts[:, 0] = [0.2, 1.4, 0.0]
    pts[:, 1] = [0.25, 1.1, 0.1]
    pts[:, 2] = [0.25, 1.1, 0.1] + np.stack([elbow_scale * tip_x, 0.25 + 0 * tip_x, 0 * tip_x], 1)
    pts[:, 3] = pts[:, 2] + np.stack([0.5 * tip_x, 0.1 + 0 * tip_x, 0 * tip_x], 1)
    return pts


def test_map_is_the_weighted_joint_distance():
    rng = np.random.default_rng(1)
    pts = rng.normal(size=(40, 4, 3))
    params = KeyPoseParameters(joint_weights=(1.0, 2.0, 0.5, 3.0), contrast_threshold=0.0)
    raw, enh, frames = pose_distance_map(pts, FPS, params)
    w = np.array(params.joint_weights)
    want = sum(w[t] * np.linalg.norm(pts[:, None, t] - pts[None, :, t], axis=-1) for t in range(4))
    np.testing.assert_allclose(raw, want, rtol=1e-5)
    np.testing.assert_allclose(enh, raw)
    assert np.all(np.diag(raw) == 0) and np.allclose(raw, raw.T)
    assert frames.tolist() == list(range(40))


def test_contrast_is_raised_only_where_the_local_mean_is_low():
    t = np.arange(120) / FPS
    tip = np.where(t < 2, 0.3 * np.sin(2 * np.pi * t), 0.01 * np.sin(2 * np.pi * 3 * t))
    params = KeyPoseParameters()
    raw, enh, _ = pose_distance_map(_arm(tip), FPS, params)
    half = int(round(0.5 * params.contrast_window_s * FPS))
    mean = uniform_filter(raw.astype(float), 2 * half + 1, mode="nearest")
    gain = np.where(
        mean < params.contrast_threshold,
        np.minimum(params.contrast_threshold / mean, params.max_gain),
        1.0,
    )
    np.testing.assert_allclose(enh, raw * gain, rtol=1e-4, atol=1e-7)
    assert np.all(enh >= raw - 1e-6)
    assert enh[100, 110] > 2 * raw[100, 110]  # the small late motion is amplified
    assert enh[10, 20] == pytest.approx(raw[10, 20])  # the big early swing is not


def test_key_frames_land_on_the_swing_extremes():
    t = np.arange(150) / FPS
    tip = 0.3 * np.sin(2 * np.pi * 0.8 * t)  # extremes every 0.625 s = 18.75 frames
    key = find_key_poses(_arm(tip), FPS)
    extremes = 18.75 / 2 + 18.75 * np.arange(8)
    extremes = extremes[extremes < 145]
    assert len(key.frames) == len(extremes)
    assert np.max(np.abs(key.frames - extremes)) <= 1.0
    assert key.distance_map.shape == (150, 150)


def test_small_finger_driven_motion_needs_the_contrast_enhancement():
    t = np.arange(150) / FPS
    tip = 0.02 * np.sin(2 * np.pi * 0.8 * t)  # 2 cm: below the prominence of the raw map
    pts = _arm(tip, elbow_scale=0.0)
    plain = find_key_poses(pts, FPS, KeyPoseParameters(contrast_threshold=0.0), with_map=False)
    assert len(plain.frames) == 0
    enhanced = find_key_poses(
        pts, FPS, KeyPoseParameters(joint_weights=(1, 1, 1, 4)), with_map=False
    )
    assert len(enhanced.frames) >= 5
    # a truly static arm has no key poses, enhanced or not
    still = find_key_poses(_arm(np.zeros(100)), FPS, with_map=False)
    assert len(still.frames) == 0


def test_long_takes_get_a_strided_map_and_the_same_keys():
    t = np.arange(400) / FPS
    pts = _arm(0.3 * np.sin(2 * np.pi * 0.5 * t))
    full = find_key_poses(pts, FPS)
    strided = find_key_poses(pts, FPS, KeyPoseParameters(max_map_frames=100))
    assert strided.distance_map.shape == (100, 100)
    np.testing.assert_array_equal(strided.map_frames, np.arange(0, 400, 4))
    np.testing.assert_allclose(strided.distance_map, full.distance_map[::4, ::4], rtol=1e-5)
    np.testing.assert_array_equal(full.frames, strided.frames)


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(joint_weights=(1, -1, 1)),
        dict(max_gain=0.5),
        dict(contrast_window_s=0),
        dict(min_prominence=-1),
    ],
)
def test_bad_parameters_name_the_field(kwargs):
    with pytest.raises(ParameterError, match=next(iter(kwargs))):
        KeyPoseParameters(**kwargs)


def test_bad_points_shape_is_an_error():
    with pytest.raises(ParameterError, match="points"):
        find_key_poses(np.zeros((10, 3, 3)), FPS)
    # other point sets work with one weight per point
    five = find_key_poses(np.zeros((10, 5, 3)), FPS, KeyPoseParameters(joint_weights=(1,) * 5))
    assert five.frames.tolist() == []


@pytest.mark.parametrize(
    "take, side",
    [
        ("2_wave-right-hand", "right"),
        ("2_wave-both-hands", "right"),
        ("2_wave-both-hands", "left"),
        ("1_byebye", "right"),
    ],
)
def test_key_poses_of_real_waves_land_on_the_swing_extremes(take, side):
    """Within the wave (the stroke), key frames sit on the extremes of the hand tip's
    swing (projected on its main direction) within one frame, and after the first
    key nearly every extreme gets a key."""
    from conftest import MOCAP
    from scipy.signal import find_peaks

    from engine.gesture.body import arm_paths
    from engine.gesture.keyposes import key_poses
    from engine.gesture.phases import Phase, segment_phases
    from engine.io.bvh import read_bvh

    motion = read_bvh(MOCAP / "bandai-namco" / f"dataset-{take}_normal_001.bvh")
    paths = arm_paths(motion)
    keys = key_poses(motion, side, paths=paths).frames
    stroke = np.flatnonzero(segment_phases(motion).labels(side) == Phase.STROKE)
    a, b = stroke[0], stroke[-1]
    tip = paths.points[side][:, 3] - paths.points[side][:, 0]
    main = np.linalg.svd(tip[a:b] - tip[a:b].mean(0), full_matrices=False)[2][0]
    x = tip @ main
    ext = np.sort(np.r_[find_peaks(x, prominence=0.02)[0], find_peaks(-x, prominence=0.02)[0]])
    ext = ext[(ext >= a) & (ext <= b)]
    inside = keys[(keys >= a) & (keys <= b)]
    assert len(inside) >= 10
    off = np.array([np.min(np.abs(ext - k)) for k in inside[1:]])
    assert np.all(off <= 1)
    later = ext[ext > inside[0]]
    found = np.array([np.min(np.abs(inside - e)) <= 1 for e in later])
    assert found.mean() >= 0.75


def test_key_pose_of_raise_up_is_the_top():
    from conftest import MOCAP

    from engine.gesture.body import arm_paths
    from engine.gesture.keyposes import key_poses
    from engine.io.bvh import read_bvh

    motion = read_bvh(MOCAP / "bandai-namco" / "dataset-2_raise-up-right-hand_normal_001.bvh")
    paths = arm_paths(motion)
    key = key_poses(motion, "right", paths=paths)
    height = paths.points["right"][:, 3, 1]
    assert len(key.frames) >= 1
    assert abs(int(key.frames[0]) - int(np.argmax(height))) <= 3
    assert key.distance_map.shape == (motion.n_frames, motion.n_frames)
