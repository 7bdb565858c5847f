"""Alignment markers from skeletons (virtual markers by FK) and from marker sets."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from conftest import MOCAP

from benchmarks.split import strip_fingers
from engine.align import features as FE
from engine.base.errors import RoleError
from engine.io import load_take
from engine.io.bvh import read_bvh
from engine.model import rotations as rot
from engine.model.motion import Motion, Skeleton
from engine.model.roles import find_roles


@pytest.fixture(scope="module")
def beat():
    return read_bvh(MOCAP / "beat/1_wayne_0_1_1.bvh")


def test_same_rig_with_and_without_fingers_gets_the_same_hand_frame(beat):
    roles = find_roles(beat.skeleton)
    body = strip_fingers(beat, roles)
    broles = find_roles(body.skeleton)
    for side in ("right", "left"):
        with_f = FE.hand_frame(beat, roles, side)
        without = FE.hand_frame(body, broles, side)
        assert with_f.dorsal_source == "fingers"
        assert without.dorsal_source == "elbow flexion"
        assert np.allclose(with_f.basis, without.basis, atol=1e-12)
        assert np.allclose(with_f.basis.T @ with_f.basis, np.eye(3), atol=1e-12)
        # (along, radial, dorsal): right-handed for a right hand, mirrored for a left one
        assert np.linalg.det(with_f.basis) == pytest.approx(1.0 if side == "right" else -1.0)
        # the markers agree too (same rig, same offsets)
        a = FE.motion_markers(beat, side, roles, frame=with_f).markers
        b = FE.motion_markers(body, side, broles, frame=without).markers
        assert np.allclose(a, b, atol=1e-9)


def test_markers_are_metres_y_up_and_shoulder_relative(beat):
    roles = find_roles(beat.skeleton)
    ref = FE.motion_markers(beat, "right", roles)
    assert ref.markers.shape == (beat.n_frames, 4, 3) and ref.shoulder_subtracted
    # forearm marker half a forearm (~13 cm) from the wrist, wrist markers ~6 cm apart
    centre = 0.5 * (ref.markers[:, 0] + ref.markers[:, 1])
    assert np.allclose(np.linalg.norm(ref.markers[:, 2] - centre, axis=1), 0.13, atol=0.01)
    assert np.allclose(
        np.linalg.norm(ref.markers[:, 0] - ref.markers[:, 1], axis=1), 0.062, atol=0.005
    )
    # the same take in centimetres, z up, walking 1 m sideways: identical markers
    to_z = rot.from_axis_angle(np.array([1.0, 0.0, 0.0]), np.pi / 2)  # y-up -> z-up
    sk = beat.skeleton
    zsk = Skeleton(
        sk.names,
        sk.parents,
        100 * rot.rotate(to_z, sk.offsets),
        sk.channels,
        {j: 100 * rot.rotate(to_z, v) for j, v in sk.end_sites.items()},
    )
    rots = rot.multiply(rot.multiply(to_z, beat.rotations), rot.conjugate(to_z))
    trans = 100 * rot.rotate(to_z, beat.translations)
    roots = np.flatnonzero(sk.parents < 0)
    trans[:, roots, 0] += np.linspace(0, 100, beat.n_frames)[:, None]
    zup = Motion(zsk, rots, trans, beat.fps, replace(beat.meta, units="cm", up_axis="z"))
    got = FE.motion_markers(zup, "right", find_roles(zsk))
    assert np.allclose(got.markers, ref.markers, atol=1e-9)


def test_hand_take_resampled_to_the_body_rate():
    hand = read_bvh(MOCAP / "gestification/gesture-pointing.bvh")
    roles = find_roles(hand.skeleton)
    native = FE.motion_markers(hand, "right", roles)
    at30 = FE.motion_markers(hand, "right", roles, fps=30.0)
    assert not native.shoulder_subtracted  # Leap takes have no shoulder
    assert at30.fps == 30.0
    assert at30.n_frames == int(round((hand.n_frames - 1) * 30.0 / hand.fps)) + 1
    # one second in: the native samples, low-passed (anti-aliasing), interpolated linearly
    from scipy.ndimage import gaussian_filter1d

    smooth = gaussian_filter1d(native.markers, 0.5 * hand.fps / 30.0, axis=0, mode="nearest")
    k = 1.0 * hand.fps
    expect = smooth[int(k)] * (1 - k % 1) + smooth[int(k) + 1] * (k % 1)
    assert np.allclose(at30.markers[30], expect, atol=1e-12)
    # and the slow motion is kept: within 2 mm of plain interpolation
    plain = native.markers[int(k)] * (1 - k % 1) + native.markers[int(k) + 1] * (k % 1)
    assert np.abs(at30.markers[30] - plain).max() < 2e-3


def test_resampling_does_not_alias_jitter():
    """A 50 Hz jitter at 120 fps (above 30 fps's Nyquist) must not fold into a slow
    wobble at 30 fps; the slow 1 Hz motion passes."""
    t = np.arange(1200) / 120.0
    slow = np.sin(2 * np.pi * 1.0 * t)
    jitter = 0.2 * np.sin(2 * np.pi * 50.0 * t + 0.3)
    out = FE.resample_points((slow + jitter)[:, None], 120.0, 30.0)[:, 0]
    t30 = np.arange(len(out)) / 30.0
    resid = out - np.sin(2 * np.pi * 1.0 * t30)
    plain = (slow + jitter)[::4] - np.sin(2 * np.pi * 1.0 * t30[:300])  # no filter
    assert np.abs(plain).max() > 0.15  # aliasing without a filter
    assert np.abs(resid[5:-5]).max() < 0.05


def test_despike_removes_single_frame_spikes_and_keeps_motion():
    rng = np.random.default_rng(0)
    t = np.arange(300) / 60.0
    clean = np.stack([np.sin(t), np.cos(2 * t), 0.1 * t], axis=1)[:, None, :]  # (F, 1, 3)
    noisy = clean + rng.normal(0, 0.002, clean.shape)
    spiky = noisy.copy()
    spikes = [40, 41 + 60, 200]
    spiky[spikes] += 0.3
    out = FE.despike(spiky)
    assert np.abs(out - clean).max() < 0.05  # a spike frame takes a neighbour's value
    untouched = np.setdiff1d(np.arange(300), spikes)
    assert np.mean(np.all(out[untouched] == spiky[untouched], axis=(1, 2))) > 0.95


def test_resample_points_keeps_the_duration():
    x = np.arange(11, dtype=float)[:, None]
    y = FE.resample_points(x, 10.0, 20.0)
    assert y.shape == (21, 1) and np.allclose(y[:, 0], np.arange(21) / 2)


@pytest.mark.parametrize(
    "path,source",
    [
        ("manipnet/mug1_rightHand.bvh", "fingers"),
        ("gestification/hello-world.bvh", "fingers"),
        ("lafan1/dance1_subject1.bvh", "elbow flexion"),
        ("animated-drawings/fair1_wave_hello.bvh", "elbow flexion"),
    ],
)
def test_hand_frames_of_real_rigs(path, source):
    from engine.model.roles import side_from_name

    take = read_bvh(MOCAP / path)
    roles = find_roles(take.skeleton, side_hint=side_from_name(path))
    fr = FE.hand_frame(take, roles, roles.sides_found()[0])
    assert fr.dorsal_source == source
    assert np.allclose(fr.basis.T @ fr.basis, np.eye(3), atol=1e-9)
    length_m = fr.forearm_length * take.meters_per_unit
    assert 0.1 < length_m < 0.4


def test_marker_set_markers_from_pyomeca():
    take = load_take(MOCAP / "pyomeca/markers_analogs.c3d")
    am = FE.marker_set_markers(take, "right", fps=50.0)
    assert am.shoulder_subtracted and am.fps == 50.0
    assert am.markers.shape[1:] == (4, 3)
    wrist_width = np.nanmedian(np.linalg.norm(am.markers[:, 0] - am.markers[:, 1], axis=1))
    assert 0.02 < wrist_width < 0.1  # metres: styloids a few cm apart
    assert FE.take_sides(take) == ["right", "left"]  # one unsided arm serves either side


def test_a_take_without_a_wrist_is_a_role_error():
    take = read_bvh(MOCAP / "bandai-namco/dataset-1_bye_normal_001.bvh")
    roles = find_roles(take.skeleton, overrides={"right.wrist": None})
    with pytest.raises(RoleError, match="right wrist"):
        FE.hand_frame(take, roles, "right")


def test_trunk_yaw_follows_a_turn(beat):
    roles = find_roles(beat.skeleton)
    y0 = FE.skeleton_yaw(beat, roles)
    turn = rot.from_axis_angle(np.array([0.0, 1.0, 0.0]), 0.5)
    rots = beat.rotations.copy()
    rots[:, 0] = rot.multiply(turn, rots[:, 0])
    trans = beat.translations.copy()
    trans[:, 0] = rot.rotate(turn, trans[:, 0])
    y1 = FE.skeleton_yaw(replace(beat, rotations=rots, translations=trans), roles)
    assert np.allclose(np.angle(np.exp(1j * (y1 - y0))), 0.5, atol=1e-9)
