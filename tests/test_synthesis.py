"""Hand synthesis: easings, pose library, coupling, speed matching, and skeletons."""

from __future__ import annotations

import numpy as np
import pytest

from engine.errors import ParameterError
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
        seg = out[a:b + 1, 2, 1]
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
    x = (2 * t**3 - 3 * t**2 + 1) * x0 + (t**3 - 2 * t**2 + t) * m0 + (-2 * t**3 + 3 * t**2) * x1 \
        + (t**3 - t**2) * m1
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
