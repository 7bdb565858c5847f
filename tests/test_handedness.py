"""Handedness (RH / LH / 2H) on constructed phrases with known answers and real takes."""

from __future__ import annotations

import numpy as np
import pytest
from gesture_traj import REST, build, phrase_psh_r

from engine.base.errors import ParameterError
from engine.gesture.handedness import (
    HandednessParameters,
    classify,
    detect_handedness,
    path_length,
)
from engine.gesture.phases import GesturePhases, segment_trajectory

FPS = 60.0


def _phases(right: np.ndarray, left: np.ndarray, fps: float = FPS) -> GesturePhases:
    return GesturePhases(
        hands={"right": segment_trajectory(right, fps), "left": segment_trajectory(left, fps)},
        fps=fps,
        n_frames=len(right),
    )


def _still(n: int) -> np.ndarray:
    return np.repeat(REST[None], n, axis=0)


def test_path_length_and_formula_by_hand():
    line = np.stack([np.linspace(0, 1, 11), np.zeros(11), np.zeros(11)], 1)  # 0.1 m steps
    mask = np.ones(11, dtype=bool)
    assert path_length(line, mask) == pytest.approx(1.0)
    mask[5:] = False
    assert path_length(line, mask) == pytest.approx(0.5)
    # right 1.0 m, left 0.95 m over 10 steps at 10 fps (1 s): 0.05 m/s < 0.12 -> 2H
    left = line * 0.95
    label, lr, ll, d, diff = classify(line, left, np.ones(11, bool), 10.0)
    assert (label, d) == ("2H", 1.0) and diff == pytest.approx(0.05)
    assert lr == pytest.approx(1.0) and ll == pytest.approx(0.95)
    # left 0.8 m: 0.2 m/s -> RH; swapped -> LH
    assert classify(line, line * 0.8, np.ones(11, bool), 10.0)[0] == "RH"
    assert classify(line * 0.8, line, np.ones(11, bool), 10.0)[0] == "LH"
    # the threshold is configurable
    assert classify(line, line * 0.8, np.ones(11, bool), 10.0, threshold=0.25)[0] == "2H"


def test_one_hand_phrase_is_rh_and_mirror_is_lh():
    right, _ = build(phrase_psh_r(), FPS)
    left = _still(len(right))
    (rh,) = detect_handedness(_phases(right, left))
    assert rh.label == "RH" and rh.right_length > 0.3 and rh.left_length < 1e-6
    (lh,) = detect_handedness(_phases(left, right))
    assert lh.label == "LH"
    assert lh.right_length == pytest.approx(rh.left_length)
    assert lh.left_length == pytest.approx(rh.right_length)


def test_both_hands_same_gesture_is_2h():
    right, _ = build(phrase_psh_r(), FPS)
    mirror = right * np.array([-1.0, 1.0, 1.0])  # the left hand mirrors the right
    (both,) = detect_handedness(_phases(right, mirror))
    assert both.label == "2H" and both.difference < 1e-9
    # slightly smaller left strokes stay 2H; a much smaller copy becomes RH
    small = REST + (mirror - REST) * 0.9
    assert detect_handedness(_phases(right, small))[0].label == "2H"
    tiny = REST + (mirror - REST) * 0.3
    assert detect_handedness(_phases(right, tiny))[0].label == "RH"


def test_phrases_of_the_two_hands_are_joined_where_they_overlap():
    right, _ = build(phrase_psh_r(), FPS)
    delay = 3  # the left hand starts 0.05 s later
    late = np.concatenate([_still(delay), right[:-delay]])
    (joint,) = detect_handedness(_phases(right, late))
    assert joint.label == "2H"
    # expressive frames are the union of both hands' strokes
    n_expressive = sum(b - a for a, b in joint.expressive)
    assert n_expressive >= 0.4 * FPS + delay - 2
    # with a long delay the phrases still join, but the hand moving alone dominates
    late = np.concatenate([_still(30), right[:-30]])
    (joint,) = detect_handedness(_phases(right, late))
    assert joint.start < 40 < joint.stop


def test_threshold_parameter_is_validated():
    with pytest.raises(ParameterError, match="threshold"):
        HandednessParameters(threshold=-0.1)
    with pytest.raises(ParameterError, match="mask"):
        classify(np.zeros((5, 3)), np.zeros((5, 3)), np.ones(4, bool), 30.0)
    with pytest.raises(ParameterError, match="expressive"):
        classify(np.zeros((5, 3)), np.zeros((5, 3)), np.zeros(5, bool), 30.0)


@pytest.mark.parametrize(
    "take, want",
    [("2_wave-right-hand", "RH"), ("2_wave-both-hands", "2H"), ("2_raise-up-right-hand", "RH")],
)
def test_real_takes_with_unambiguous_names(bandai, take, want):
    from gesture_traj import swapped_sides

    from engine.gesture.body import find_arms
    from engine.gesture.phases import segment_phases

    motion = bandai(take)
    (phrase,) = detect_handedness(segment_phases(motion))
    assert phrase.label == want
    # mirrored labelling (right and left exchanged): RH <-> LH, 2H stays
    arms = swapped_sides(find_arms(motion.skeleton))
    (mirror,) = detect_handedness(segment_phases(motion, arms=arms))
    assert mirror.label == {"RH": "LH", "LH": "RH", "2H": "2H"}[want]


def test_real_take_units_do_not_matter(bandai):
    from gesture_traj import turned_and_scaled

    from engine.gesture.phases import segment_phases

    take = bandai("2_wave-right-hand")
    (cm,) = detect_handedness(segment_phases(take))
    (mm,) = detect_handedness(segment_phases(turned_and_scaled(take, unit="mm")))
    (inch,) = detect_handedness(segment_phases(turned_and_scaled(take, yaw_deg=-30, unit="in")))
    assert cm.label == mm.label == inch.label == "RH"
    assert cm.right_length == pytest.approx(mm.right_length, rel=1e-6)
    assert cm.right_length == pytest.approx(inch.right_length, rel=1e-6)
    # the wave: the right hand travels metres, the hanging left hand sways a little
    assert cm.right_length > 3.0 and cm.left_length < 0.15 * cm.right_length


def test_literal_rule_reads_an_independent_hold_as_2h(bandai):
    from engine.gesture.phases import segment_phases

    g = segment_phases(bandai("2_raise-up-right-hand"))
    (literal,) = detect_handedness(g, HandednessParameters(hold_span="hold"))
    assert literal.label == "2H" and literal.difference < 0.12
    (wrist,) = detect_handedness(g, HandednessParameters(point="wrist"))
    assert wrist.label == "RH"
