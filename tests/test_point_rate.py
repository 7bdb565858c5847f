"""A matching point's reach past its own cell (issue 17): near a point the warp runs at
the local rate (``engine.splice.point_rate``), in the engine's splice itself."""

import numpy as np

from engine.splice import pipeline as P
from engine.splice import point_rate as PR


def _kinked(n: int = 120, x: int = 60) -> np.ndarray:
    """A rate-1 warp that reaches the point (x, x) by a vertical run (the hand held for
    10 frames) and a jump: how a DP path forced through a cell the costs disliked looks."""
    w = np.arange(n, dtype=float)
    w[x - 10 : x] = x - 10
    return w


def test_the_kink_beside_a_point_is_drawn_to_the_points_rate_line():
    w = _kinked()
    out = PR.rate_lines(w, [60], fps=30.0)
    assert out[60] == w[60]  # the point's row keeps its column
    assert np.all(np.diff(out) >= 0)
    before = np.abs(w[50:60] - np.arange(50, 60)).mean()
    after = np.abs(out[50:60] - np.arange(50, 60)).mean()
    assert after < 0.5 * before
    # far from the point the passes' timing is kept
    np.testing.assert_allclose(out[:35], w[:35], atol=1e-6)
    np.testing.assert_allclose(out[90:], w[90:], atol=1e-6)


def test_the_pull_stops_at_a_neighbouring_point_and_outside_the_matched_rows():
    w = _kinked()
    out = PR.rate_lines(w, [60, 55], fps=30.0, matched=(40, 119))
    assert out[55] == w[55] and out[60] == w[60]
    assert np.all(np.diff(out) >= 0)
    np.testing.assert_array_equal(out[:40], w[:40])  # unmatched rows hold as they were
    assert np.array_equal(PR.rate_lines(w, [], fps=30.0), w)


def test_a_true_point_fixes_the_timing_around_it_not_only_its_own_row():
    """A real split pair (the bench's Leap rig, seed 8): the top suggested point placed at
    its true hand frame. The DP path reaches the pinned cell by a run beside it; with the
    warp drawn to the point's rate line the frames within 0.25 s of the point are off by
    under 25 ms on average (40 ms with the point's row alone) and the take's p95 timing
    error falls by more than 20 % (0 % with the point's row alone)."""
    from benchmarks.bench_splice_accuracy import FAMILIES
    from engine.trust import assess_splice

    case = FAMILIES["leap"].make(8)
    res = P.splice(case.body, case.hand, transfer_fingers=False)
    ms = 1000.0 / case.hand.fps
    before = np.abs(res.alignment.map - case.truth) * ms
    at = int(assess_splice(res.features, res.alignment).suggestions[0][0])
    hand = int(round(float(case.truth[at])))
    fixed = P.splice(
        case.body, case.hand, transfer_fingers=False, hand_points=True, points=[(at, hand, 0)]
    )
    after = np.abs(fixed.alignment.map - case.truth) * ms
    near = np.abs(np.arange(len(after)) - at) <= 0.25 * case.body.fps
    assert after[near].mean() < 25.0
    assert np.percentile(after, 95) < 0.8 * np.percentile(before, 95)
