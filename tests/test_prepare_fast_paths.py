"""The splice's prepare stage, made cheaper (issue 13), gives the same values as before.

Each fast path is compared with the slower reference it replaced, on real captures:
the median of three (despike), the hand take's sign codes for every θ bin (bins in the
inner loop), the eq.-7 windows built only for the asked frames, and the hand-side vote
with the numba forward kinematics.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from conftest import MOCAP

from engine.align import features as FE
from engine.align import metrics as M
from engine.io.bvh import read_bvh
from engine.model import kinematics
from engine.model.hand_side import MAX_FRAMES, geometric_side
from engine.model.roles import find_roles


def _markers(path: str, sides=("right", "left")) -> np.ndarray:
    take = read_bvh(MOCAP / path)
    roles = find_roles(take.skeleton)
    frames = {s: FE.hand_frame(take, roles, s) for s in sides}
    mk, _, _ = FE.take_markers(take, roles, frames)
    return np.concatenate([mk[s] for s in sides], axis=1), take.fps


def test_median3_is_numpys_median_bit_for_bit():
    mk, _ = _markers("beat/1_wayne_0_1_1.bvh")
    a, b, c = mk[:-2], mk[1:-1], mk[2:]
    a = a.copy()
    a[5, 1, 0] = np.nan  # a gap: NaN as numpy gives it
    ref = np.median(np.stack([a, b, c]), axis=0)
    got = FE.median3(a, b, c)
    assert np.array_equal(ref, got, equal_nan=True)
    assert np.isnan(got[5, 1, 0]) and not np.isnan(got[6, 1, 0])


@pytest.mark.parametrize("zone", ["own", "none"])
def test_rotated_codes_of_a_real_take_equal_the_numpy_ones(zone):
    mk, fps = _markers("beat/1_wayne_0_1_1.bvh")
    ph = M.phase_features(mk, fps)
    if zone == "none":  # no dead zone: exact zeros read 0, every other value its sign
        ph = replace(ph, zone=M.DeadZone(velocity=0.0, acceleration=0.0))
    p, q = M.rotated_packed_codes(ph, M.THETA_BINS)
    rp, rq = M.pack_codes(M.rotated_codes(ph, M.THETA_BINS))
    assert np.array_equal(p, rp) and np.array_equal(q, rq)
    assert len(np.unique(p[:, 0])) > 10  # real motion: the codes vary


def _whole_take_windows(markers: np.ndarray) -> np.ndarray:
    """The eq.-7 windows of every frame as phase_features stored them before (F, 2WK)."""
    f = markers.shape[0]
    idx = np.clip(np.arange(f)[:, None] + np.arange(-2, 3)[None, :], 0, f - 1)
    x = markers[idx, :, 0].reshape(f, -1)
    z = markers[idx, :, 2].reshape(f, -1)
    x = x - x.mean(axis=1, keepdims=True)
    z = z - z.mean(axis=1, keepdims=True)
    return np.concatenate([x, z], axis=1).astype(np.float32)


def test_theta_windows_of_asked_frames_equal_the_whole_takes():
    mk, fps = _markers("beat/1_wayne_0_1_1.bvh")
    whole = _whole_take_windows(mk)
    frames = np.array([0, 1, 2, 100, mk.shape[0] - 2, mk.shape[0] - 1])
    assert np.array_equal(M._theta_windows(mk, frames), whole[frames])
    grid = frames.reshape(2, 3)
    assert np.array_equal(M._theta_windows(mk, grid), whole[grid])
    # θ of one cell and of a vector of cells agree (both from the asked windows)
    ph = M.phase_features(mk, fps)
    hand = M.phase_features(mk[::-1].copy(), fps)
    i, j = np.array([3, 50, 200]), np.array([7, 40, 10])
    vec = M.cell_theta_window(ph, hand, i, j)
    one = [M.window_theta(ph, hand, int(a), int(b)) for a, b in zip(i, j, strict=True)]
    assert np.allclose(vec, one, rtol=0, atol=1e-12)


@pytest.mark.parametrize("path", ["beat/1_wayne_0_1_1.bvh", "gestification/indexical.bvh"])
def test_hand_side_vote_is_the_same_with_numba_kinematics(path):
    take = read_bvh(MOCAP / path)
    roles = find_roles(take.skeleton)
    step = max(1, take.n_frames // MAX_FRAMES)
    sub = replace(take, rotations=take.rotations[::step], translations=take.translations[::step])
    ref_pos = kinematics.forward_kinematics(sub)[0]  # numpy FK, as the vote used before
    votes = 0
    for side in ("right", "left"):
        arm = roles.side(side)
        if arm.wrist is None:
            continue
        fast = geometric_side(take, arm)
        ref = geometric_side(sub, arm, fk=(ref_pos, None))  # the same frames, numpy FK
        assert fast.side == ref.side and fast.reason == ref.reason
        for name in ("thumb", "curl", "thumb_agree", "curl_agree"):
            a, b = getattr(fast, name), getattr(ref, name)
            assert (a is None) == (b is None)
            if a is not None:
                assert a == pytest.approx(b, abs=1e-9)
        votes += fast.side is not None
    assert votes >= 1


def test_marker_offsets_turned_by_numba_equal_the_numpy_rotation():
    """``fastkin.rotate_offset`` (virtual markers) gives ``rotations.rotate``'s floats."""
    from engine.model import rotations
    from engine.model.fastkin import forward_kinematics, rotate_offset

    take = read_bvh(MOCAP / "beat/1_wayne_0_1_1.bvh")
    _, wrot = forward_kinematics(take)
    offsets = np.r_[take.skeleton.offsets[1:], [[0.0, 0.0, 0.0], [1e-9, -3.5, 1e6]]]
    for j, off in enumerate(offsets):
        q = wrot[:, j % wrot.shape[1]]
        assert np.array_equal(rotate_offset(q, off), rotations.rotate(q, off)), j


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_raw_windows_by_numba_equal_the_numpy_copy(dtype):
    """The eq.-7 windows of the pass-1 rows (``metrics._raw_windows``, numba) are the numpy
    slices they replaced, in the markers' dtype, frames clipped at both ends."""
    mk, _ = _markers("beat/1_wayne_0_1_1.bvh")
    mk = mk.astype(dtype)
    f, k, _ = mk.shape
    half, wk = M.THETA_WINDOW // 2, M.THETA_WINDOW * k
    ref = np.zeros((f, 2 * wk))
    cx, cz = float(np.mean(mk[:, :, 0])), float(np.mean(mk[:, :, 2]))
    for w in range(M.THETA_WINDOW):
        idx = np.clip(np.arange(f) + (w - half), 0, f - 1)
        ref[:, w * k : (w + 1) * k] = mk[idx, :, 0] - cx
        ref[:, wk + w * k : wk + (w + 1) * k] = mk[idx, :, 2] - cz
    got = np.zeros((f, 2 * wk + 3))[:, 1:-2]  # a view into wider rows, as phase_rows passes
    M._raw_windows(mk, got)
    assert np.array_equal(got, ref)
