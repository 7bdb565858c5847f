"""Pass-1 sign metric (eqs. 6-7) and pass-2 angle metric (eqs. 8-9) on hand-built cases."""

from __future__ import annotations

import numpy as np
import pytest

from engine.align import metrics as M
from engine.model import rotations as rot


def _arm_markers(frames: int, rng: np.random.Generator, arms: int = 1) -> np.ndarray:
    """Smooth random (F, 4*arms, 3) marker paths (metres): a rigid 4-point hand moving."""
    t = np.arange(frames) / 30.0
    base = np.array([[0.03, 0.0, 0.0], [-0.03, 0.0, 0.0], [0.0, 0.0, -0.12], [0.0, 0.02, 0.08]])
    out = []
    for _ in range(arms):
        freq = rng.uniform(0.5, 1.5, 3)
        phase = rng.uniform(0, 2 * np.pi, 3)
        centre = 0.2 * np.sin(2 * np.pi * freq[None] * t[:, None] + phase[None])
        ang = 0.6 * np.sin(2 * np.pi * 0.7 * t + rng.uniform(0, 6))
        q = rot.from_axis_angle(np.array([0.0, 1.0, 0.0]), ang)
        out.append(centre[:, None, :] + rot.rotate(q[:, None, :], base[None]))
    return np.concatenate(out, axis=1)


def test_derivatives_of_a_sine_match_the_analytic_ones():
    fps = 120.0
    t = np.arange(240) / fps
    x = np.sin(2 * np.pi * t)[:, None]
    v, a = M.derivatives(x, fps, window_s=0.1)
    inner = slice(20, -20)
    assert np.allclose(v[inner, 0], 2 * np.pi * np.cos(2 * np.pi * t[inner]), atol=0.02)
    assert np.allclose(a[inner, 0], -((2 * np.pi) ** 2) * np.sin(2 * np.pi * t[inner]), atol=0.5)


def test_derivatives_of_tiny_takes_and_gaps():
    v, a = M.derivatives(np.zeros((2, 3)), 30.0)
    assert v.shape == (2, 3) and not v.any() and not a.any()
    x = np.linspace(0, 1, 9)[:, None].repeat(3, axis=1)
    x[4] = np.nan  # a capture gap is interpolated, not propagated
    v, _ = M.derivatives(x, 8.0)
    assert np.all(np.isfinite(v)) and np.allclose(v, 1.0, atol=1e-6)


def test_sign_dead_zone():
    s = M.sign_dead_zone(np.array([-2.0, -0.05, 0.0, 0.05, 3.0, np.nan]), 0.1)
    assert s.tolist() == [-1, 0, 0, 0, 1, 0]
    assert s.dtype == np.int8


def test_a_held_hand_reads_zero_and_codes_ignore_amplitude():
    rng = np.random.default_rng(1)
    mk = _arm_markers(150, rng)
    mk[60:100] = mk[60]  # a hold
    mk += rng.normal(scale=1e-4, size=mk.shape)  # sensor noise
    ph = M.phase_features(mk, 30.0)
    held = ph.codes[68:92]
    assert np.count_nonzero(held) <= 0.02 * held.size
    moving = ph.codes[10:50]
    assert np.count_nonzero(moving) > 0.5 * moving.size
    # a shrunken copy (arm moving half as far) gets its own dead zone and the same codes
    small = M.phase_features(0.5 * mk, 30.0)
    assert small.zone.velocity == pytest.approx(0.5 * ph.zone.velocity)
    assert np.mean(small.codes == ph.codes) > 0.99


@pytest.mark.parametrize("alpha_deg", [0.0, 35.0, 120.0, -150.0])
def test_window_theta_recovers_a_vertical_rotation(alpha_deg):
    rng = np.random.default_rng(2)
    mk = _arm_markers(60, rng)
    alpha = np.radians(alpha_deg)
    body = M.phase_features(mk, 30.0)
    hand = M.phase_features(M.rotate_y(mk, -alpha), 30.0)
    for i in (2, 30, 57):
        th = M.window_theta(body, hand, i, i)
        assert np.angle(np.exp(1j * (th - alpha))) == pytest.approx(0.0, abs=1e-5)
    # R_y(θ) turns the hand take back onto the body
    assert np.allclose(M.rotate_y(hand.markers, alpha), mk, atol=1e-9)


def test_pack_codes_cost_equals_sum_of_squared_differences():
    rng = np.random.default_rng(3)
    a = rng.integers(-1, 2, size=(200, 48)).astype(np.int8)
    b = rng.integers(-1, 2, size=(200, 48)).astype(np.int8)
    pa, qa = M.pack_codes(a)
    pb, qb = M.pack_codes(b)
    for k in range(200):
        p, q = np.uint64(pa[k]), np.uint64(qa[k])
        p2, q2 = np.uint64(pb[k]), np.uint64(qb[k])
        fast = M._popcount(p ^ p2) + M._popcount(q ^ q2) + 2 * M._popcount((p & q2) | (q & p2))
        assert int(fast) == int(np.sum((a[k].astype(int) - b[k].astype(int)) ** 2))


@pytest.mark.parametrize("theta,alpha_deg", [("window", 35.0), ("trunk", 50.0), ("none", 0.0)])
def test_phase_metric_equals_the_reference_when_theta_is_on_a_bin(theta, alpha_deg):
    rng = np.random.default_rng(4)
    mk = _arm_markers(50, rng, arms=2)
    alpha = np.radians(alpha_deg)  # multiples of 5 degrees: quantisation is exact
    body = M.phase_features(mk, 30.0, yaw=np.full(50, alpha))
    hand = M.phase_features(M.rotate_y(mk[::-1], -alpha), 30.0, yaw=np.zeros(50))
    a, b = M.phase_rows(body, hand, theta=theta)
    cols = np.arange(50)
    fast = M.cost_grid(M.splice_phase, a, b, cols, cols)
    ref = M.phase_cost_reference(body, hand, theta=theta)
    if theta == "window":  # θ varies per cell: compare only cells whose θ is near alpha
        th = np.array([[M.window_theta(body, hand, i, j) for j in cols] for i in cols])
        near = np.abs(np.angle(np.exp(1j * (th - alpha)))) < 1e-5  # the anti-diagonal
        assert near.sum() > 0
        assert np.array_equal(fast[near], ref[near])
    else:
        assert np.array_equal(fast, ref)


def test_phase_metric_is_zero_on_identical_takes_and_counts_each_step_once():
    rng = np.random.default_rng(5)
    mk = _arm_markers(40, rng)
    ph = M.phase_features(mk, 30.0)
    a, b = M.phase_rows(ph, ph)
    d = M.cost_grid(M.splice_phase, a, b, np.arange(40), np.arange(40))
    assert np.all(np.diag(d) == 0)
    assert d.max() <= 4 * 24 and d.min() >= 0
    a, b = M.phase_rows(ph, ph, step=2.5)
    d2 = M.cost_grid(M.splice_phase, a, b, np.arange(40), np.arange(40))
    assert np.allclose(d2, d + 2.5)
    # a take moving the opposite way: every nonzero velocity sign disagrees (cost 4 each)
    rev = M.phase_features(-mk, 30.0)
    a, b = M.phase_rows(ph, rev, theta="none")
    d3 = M.cost_grid(M.splice_phase, a, b, np.arange(40), np.arange(40))
    vel = ph.codes.reshape(40, 4, 6)[:, :, :3]
    acc = ph.codes.reshape(40, 4, 6)[:, :, 3:]
    expect = 4 * (np.count_nonzero(vel, axis=(1, 2)) + np.count_nonzero(acc, axis=(1, 2)))
    assert np.array_equal(np.diag(d3), expect)


def test_angle_metric_matches_reference_and_handles_antiparallel_forearms():
    rng = np.random.default_rng(6)
    mk = rng.normal(size=(30, 8, 3))
    body = M.angle_features(mk)
    hand = M.angle_features(rng.normal(size=(25, 8, 3)))
    fast = M.cost_grid(M.splice_angle, body.rows(), hand.rows(), np.arange(30), np.arange(25))
    assert np.allclose(fast, M.angle_cost_reference(body, hand), atol=1e-9)
    f = np.array([[0.0, 0.0, 1.0]])
    h = np.array([[1.0, 0.0, 0.0]])
    b1 = M.AngleFeatures(forearm=f[None], hand=h[None])
    b2 = M.AngleFeatures(forearm=-f[None], hand=h[None])
    got = M.cost_grid(M.splice_angle, b1.rows(), b2.rows(), [0], [0])[0, 0]
    assert got == pytest.approx(M.angle_cost_reference(b1, b2)[0, 0])
    assert 0.0 <= got <= np.pi


def test_angle_metric_is_zero_for_a_turned_copy_and_sees_forearm_roll():
    rng = np.random.default_rng(7)
    mk = _arm_markers(20, rng)
    body = M.angle_features(mk)
    # the arm swung (turned about an axis across the forearm): R undoes the swing exactly
    f0 = body.forearm[:, 0]
    across = np.cross(f0, _unit(rng.normal(size=3)))
    across /= np.linalg.norm(across, axis=1, keepdims=True)
    q = rot.from_axis_angle(across, np.full(20, 1.1))
    swung = M.angle_features(rot.rotate(q[:, None, :], mk))
    d = M.cost_grid(M.splice_angle, body.rows(), swung.rows(), np.arange(20), np.arange(20))
    assert np.allclose(np.diag(d), 0.0, atol=1e-7)
    assert np.allclose(
        np.diag(
            M.cost_grid(M.splice_angle, body.rows(), body.rows(), np.arange(20), np.arange(20))
        ),
        0.0,
        atol=1e-7,
    )
    # roll the hand vector about the forearm by 30 deg: the cost is the roll's effect
    f, h = body.forearm[:, 0], body.hand[:, 0]
    roll = rot.from_axis_angle(f, np.full(20, np.radians(30.0)))
    rolled = M.AngleFeatures(forearm=body.forearm, hand=rot.rotate(roll, h)[:, None])
    d = M.cost_grid(M.splice_angle, body.rows(), rolled.rows(), np.arange(20), np.arange(20))
    perp = np.linalg.norm(h - f * np.sum(h * f, 1, keepdims=True), axis=1)
    expect = np.arccos(np.clip(1 - perp**2 * (1 - np.cos(np.radians(30.0))), -1, 1))
    assert np.allclose(np.diag(d), expect, atol=1e-6)


def test_two_arms_sum():
    rng = np.random.default_rng(8)
    mk = _arm_markers(30, rng, arms=2)
    other = _arm_markers(30, np.random.default_rng(9), arms=2)
    both = M.cost_grid(
        M.splice_angle,
        M.angle_features(mk).rows(),
        M.angle_features(other).rows(),
        np.arange(30),
        np.arange(30),
    )
    parts = sum(
        M.cost_grid(
            M.splice_angle,
            M.angle_features(mk[:, s]).rows(),
            M.angle_features(other[:, s]).rows(),
            np.arange(30),
            np.arange(30),
        )
        for s in (slice(0, 4), slice(4, 8))
    )
    assert np.allclose(both, parts)
    b2 = M.phase_features(mk, 30.0)
    h2 = M.phase_features(other, 30.0)
    a, b = M.phase_rows(b2, h2, theta="none")
    full = M.cost_grid(M.splice_phase, a, b, np.arange(30), np.arange(30))
    total = 0
    for s in (slice(0, 4), slice(4, 8)):
        bs = M.PhaseFeatures(
            **{**b2.__dict__, "codes": b2.codes.reshape(30, 8, 6)[:, s].reshape(30, -1), "arms": 1}
        )
        hs = M.phase_features(other[:, s], 30.0)
        hs = M.PhaseFeatures(
            **{
                **hs.__dict__,
                "zone": h2.zone,
                "codes": h2.codes.reshape(30, 8, 6)[:, s].reshape(30, -1),
                "velocity": h2.velocity[:, s],
                "acceleration": h2.acceleration[:, s],
            }
        )
        total = total + M.phase_cost_reference(bs, hs, theta="none")
    assert np.array_equal(full, total)


def test_bad_inputs_raise():
    from engine.base.errors import ParameterError

    with pytest.raises(ParameterError, match="4\\*arms"):
        M.phase_features(np.zeros((10, 3, 3)), 30.0)
    with pytest.raises(ParameterError, match="theta"):
        ph = M.phase_features(np.zeros((10, 4, 3)), 30.0)
        M.phase_rows(ph, ph, theta="sideways")
    with pytest.raises(ParameterError, match="yaw"):
        M.phase_rows(ph, ph, theta="trunk")
    with pytest.raises(ParameterError, match="fps"):
        M.derivatives(np.zeros((10, 3)), 0.0)


def _unit(v):
    return v / np.linalg.norm(v)


def test_packed_rotated_codes_equal_the_numpy_ones():
    rng = np.random.default_rng(10)
    ph = M.phase_features(_arm_markers(40, rng, arms=2), 30.0)
    p, q = M.rotated_packed_codes(ph, 36)
    rp, rq = M.pack_codes(M.rotated_codes(ph, 36))
    assert np.array_equal(p, rp) and np.array_equal(q, rq)


def test_fast_kinematics_match_the_reference():
    from conftest import MOCAP

    from engine.io.bvh import read_bvh
    from engine.model import fastkin
    from engine.model.kinematics import forward_kinematics

    take = read_bvh(MOCAP / "beat/1_wayne_0_1_1.bvh")
    p0, r0 = forward_kinematics(take)
    p1, r1 = fastkin.forward_kinematics(take)
    assert np.allclose(p0, p1, atol=1e-10) and np.allclose(r0, r1, atol=1e-12)
    a, b = r0[:, 3], r0[:, 7]
    assert np.allclose(fastkin.qmul(a, b), rot.multiply(a, b))
    assert np.allclose(fastkin.qmul_conj(a, b), rot.multiply(rot.conjugate(a), b))
    flipped = r0[:, 5] * np.where(np.arange(len(r0)) % 3 == 0, -1.0, 1.0)[:, None]
    assert np.allclose(fastkin.continuous(flipped), rot.make_continuous(flipped))
