"""Gesture phases: constructed wrist paths with known phases, and real takes."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import MOCAP
from gesture_traj import REST, build, phrase_psh_r

from engine.base.errors import ParameterError
from engine.gesture.phases import (
    Phase,
    PhaseParameters,
    derivatives,
    fill_gaps,
    segment_trajectory,
)

SCRIPTS = {
    "PSHR": phrase_psh_r(),
    "PHR": [
        ("rest", 0.5),
        ("prep", 0.5, (0.1, 0.0, 0.3)),
        ("hold", 0.8),
        ("retract", 0.5, None),
        ("rest", 0.5),
    ],
    "PSR": [
        ("rest", 0.5),
        ("prep", 0.5, (0.1, 0.0, 0.3)),
        ("stroke", 0.15, (0.3, 0.0, 0.3)),
        ("stroke", 0.15, (0.1, 0.0, 0.3)),
        ("stroke", 0.15, (0.3, 0.0, 0.3)),
        ("retract", 0.5, None),
        ("rest", 0.5),
    ],
}


def test_phase_codes_are_the_agreed_integers():
    assert [int(p) for p in Phase] == [0, 1, 2, 3, 4]
    assert [p.name for p in Phase] == ["REST", "PREPARATION", "STROKE", "HOLD", "RETRACTION"]
    assert "".join(p.letter for p in Phase) == "-PSHR"


@pytest.mark.parametrize("pattern", sorted(SCRIPTS))
@pytest.mark.parametrize("fps", [30.0, 120.0])
def test_constructed_phrase_is_recovered(pattern, fps):
    pos, truth = build(SCRIPTS[pattern], fps=fps)
    hand = segment_trajectory(pos, fps)
    assert [p.pattern for p in hand.phrases] == [pattern]
    assert np.mean(hand.labels == truth) > 0.93
    # boundaries within 0.1 s of the constructed ones
    for phase in (Phase.PREPARATION, Phase.RETRACTION):
        got = np.flatnonzero(hand.labels == phase)
        want = np.flatnonzero(truth == phase)
        assert abs(got[0] - want[0]) <= 0.1 * fps and abs(got[-1] - want[-1]) <= 0.1 * fps
    np.testing.assert_allclose(hand.rest_position, REST, atol=0.01)


def test_two_phrases_separated_by_rest_and_noise_tolerated():
    rng = np.random.default_rng(5)
    pos, truth = build(phrase_psh_r() + phrase_psh_r()[1:], fps=60.0)
    pos = pos + rng.normal(scale=0.001, size=pos.shape)  # 1 mm capture noise
    hand = segment_trajectory(pos, 60.0)
    assert [p.pattern for p in hand.phrases] == ["PSHR", "PSHR"]
    assert np.mean(hand.labels == truth) > 0.9
    # segments tile the take and agree with the labels
    assert hand.segments[0].start == 0 and hand.segments[-1].stop == len(pos)
    for a, b in zip(hand.segments, hand.segments[1:]):
        assert a.stop == b.start and a.phase != b.phase
    for s in hand.segments:
        assert np.all(hand.labels[s.start : s.stop] == s.phase)


def test_expressive_phase_is_strokes_or_independent_hold():
    hand = segment_trajectory(build(SCRIPTS["PSHR"])[0], 60.0)
    mask = hand.expressive_mask()
    assert np.all(hand.labels[mask] == Phase.STROKE)
    hold = segment_trajectory(build(SCRIPTS["PHR"])[0], 60.0)
    assert np.all(hold.labels[hold.expressive_mask()] == Phase.HOLD)
    assert hold.expressive_mask().sum() > 0.6 * 60


def test_fidgeting_at_rest_is_rest():
    t = np.arange(0, 3, 1 / 60)
    pos = REST + 0.03 * np.stack([np.sin(2 * np.pi * 2 * t), 0 * t, np.cos(2 * np.pi * 2 * t)], 1)
    hand = segment_trajectory(pos, 60.0)
    assert hand.phrases == () and np.all(hand.labels == Phase.REST)


def test_thresholds_are_tunable():
    pos, _ = build(SCRIPTS["PSHR"])
    # a hold speed above every movement makes the whole take still
    still = segment_trajectory(pos, 60.0, PhaseParameters(hold_speed=50.0))
    assert set(np.unique(still.labels)) <= {Phase.REST, Phase.HOLD}
    # a huge stroke threshold turns the beat strokes into preparation / retraction
    default = segment_trajectory(pos, 60.0)
    soft = segment_trajectory(pos, 60.0, PhaseParameters(stroke_accel=1e4))
    assert (soft.labels == Phase.STROKE).sum() < (default.labels == Phase.STROKE).sum()
    assert soft.phrases and all(p.expressive_segments() for p in soft.phrases)
    # an explicit rest position far from the hand: no frame is rest
    far = segment_trajectory(pos, 60.0, rest_position=np.array([1.0, 1.0, 1.0]))
    assert not np.any(far.labels == Phase.REST)


def test_nan_gaps_are_filled_and_derivatives_are_correct():
    pos, _ = build(SCRIPTS["PHR"])
    gappy = pos.copy()
    gappy[100:104] = np.nan
    assert np.all(np.isfinite(fill_gaps(gappy)))
    a = segment_trajectory(pos, 60.0)
    b = segment_trajectory(gappy, 60.0)
    assert np.mean(a.labels == b.labels) > 0.97
    t = np.arange(200) / 100.0
    line = np.stack([t**2, 3 * t, 0 * t], 1)
    _, vel, acc = derivatives(line, 100.0, 0.1)
    np.testing.assert_allclose(vel[:, 0], 2 * t, atol=1e-9)
    np.testing.assert_allclose(acc[:, 0], 2.0, atol=1e-6)


@pytest.mark.parametrize(
    "kwargs",
    [dict(hold_speed=0), dict(valley_depth=1.5), dict(reference="head"), dict(min_hold_s=-1)],
)
def test_bad_parameters_name_the_field(kwargs):
    with pytest.raises(ParameterError, match=next(iter(kwargs))):
        PhaseParameters(**kwargs)


def test_bad_trajectory_shape_is_an_error():
    with pytest.raises(ParameterError, match="positions"):
        segment_trajectory(np.zeros((10, 2)), 30.0)
    # a one-frame take is valid and at rest
    one = segment_trajectory(np.zeros((1, 3)), 30.0)
    assert one.labels.tolist() == [0]


def test_wave_right_hand_phases(bandai):
    from engine.gesture.phases import segment_phases

    g = segment_phases(bandai("2_wave-right-hand"))
    assert [p.pattern for p in g.hands["right"].phrases] == ["PSR"]
    assert g.hands["left"].phrases == ()  # the left arm hangs (it sways a little)
    labels = g.labels("right")
    # the wave (≈ frames 20-160 of 187) is one stroke; raising and lowering around it
    strokes = np.flatnonzero(labels == Phase.STROKE)
    assert 12 <= strokes[0] <= 30 and 150 <= strokes[-1] <= 170
    assert labels[5] == Phase.PREPARATION and labels[175] == Phase.RETRACTION
    np.testing.assert_allclose(g.hands["right"].rest_position[1], -0.45, atol=0.05)  # arm hanging


def test_wave_both_hands_and_raise_up(bandai):
    from engine.gesture.phases import segment_phases

    g = segment_phases(bandai("2_wave-both-hands"))
    r, left = g.labels("right") == Phase.STROKE, g.labels("left") == Phase.STROKE
    assert [p.pattern for p in g.hands["right"].phrases] == ["PSR"]
    assert [p.pattern for p in g.hands["left"].phrases] == ["PSR"]
    assert (r & left).sum() > 0.9 * max(r.sum(), left.sum())
    up = segment_phases(bandai("2_raise-up-right-hand"))
    assert [p.pattern for p in up.hands["right"].phrases] == ["PHR"]  # an independent hold
    hold = np.flatnonzero(up.labels("right") == Phase.HOLD)
    height = up.hands["right"].positions[:, 1]
    assert height[hold].min() > height.max() - 0.05  # held at the top


def test_phases_ignore_units_heading_and_travel(bandai):
    from gesture_traj import turned_and_scaled

    from engine.gesture.phases import segment_phases

    take = bandai("1_call")
    a = segment_phases(take)
    b = segment_phases(turned_and_scaled(take, yaw_deg=120.0, unit="mm"))
    for side in ("right", "left"):
        np.testing.assert_array_equal(a.labels(side), b.labels(side))
        np.testing.assert_allclose(a.hands[side].positions, b.hands[side].positions, atol=1e-6)


GRAMMAR = r"P?[SH]+R?"


@pytest.mark.parametrize(
    "path",
    sorted(p.name for p in (MOCAP / "lafan1").glob("*.bvh"))
    + ["../beat/1_wayne_0_1_1.bvh", "../animated-drawings/fair1_dab.bvh"],
)
def test_every_phrase_of_real_takes_follows_the_grammar(path):
    import re

    from engine.gesture.phases import segment_phases
    from engine.io.bvh import read_bvh

    g = segment_phases(read_bvh(MOCAP / "lafan1" / path))
    for hand in g.hands.values():
        assert len(hand.labels) == g.n_frames
        for phrase in hand.phrases:
            assert re.fullmatch(GRAMMAR, phrase.pattern), phrase.pattern
            assert phrase.expressive_segments()
            np.testing.assert_array_equal(
                hand.labels[phrase.start : phrase.stop] != Phase.REST, True
            )


def test_random_paths_follow_the_grammar():
    from hypothesis import given, settings
    from hypothesis import strategies as st

    @settings(max_examples=40, deadline=None)
    @given(st.integers(0, 2**32 - 1), st.integers(2, 400), st.sampled_from([24.0, 30.0, 120.0]))
    def check(seed, n, fps):
        import re

        rng = np.random.default_rng(seed)
        steps = rng.normal(scale=rng.uniform(0.001, 0.05), size=(n, 3))
        pos = REST + np.cumsum(steps, axis=0)
        hand = segment_trajectory(pos, fps)
        assert hand.labels.shape == (n,) and set(np.unique(hand.labels)) <= set(range(5))
        assert sum(s.n_frames for s in hand.segments) == n
        for phrase in hand.phrases:
            assert re.fullmatch(GRAMMAR, phrase.pattern), phrase.pattern

    check()
