"""Takes that look like two capture sessions (issue 12): untrimmed ends, noise, holds."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.split import Realism, make_case
from engine.splice import merge as MG
from engine.splice import pipeline as P
from engine.splice.report import build_report


def _timing_ms(case, result):
    return np.abs(result.alignment.map - case.truth) / case.hand.fps * 1000.0


def test_noisy_pair_within_one_frame_of_its_clean_twin():
    """2 deg jitter on every joint and single-frame spikes in the hand take cost at most
    one body frame of median timing against the same pair without noise."""
    clean = make_case("beat", 204, realism=Realism())
    noisy = make_case("beat", 204, realism=Realism(jitter_deg=2.0, spike_rate=0.01))
    np.testing.assert_allclose(clean.truth, noisy.truth)  # the same warp: a twin
    assert not np.allclose(clean.hand.rotations, noisy.hand.rotations)
    e_clean = _timing_ms(clean, P.splice(clean.body, clean.hand, transfer_fingers=False))
    e_noisy = _timing_ms(noisy, P.splice(noisy.body, noisy.hand, transfer_fingers=False))
    frame_ms = 1000.0 / clean.body.fps
    assert np.median(e_noisy) <= np.median(e_clean) + frame_ms
    assert np.median(e_noisy) <= frame_ms


def test_open_ends_match_an_untrimmed_hand_take():
    """The hand take starts 1-2 s earlier and ends 1-2 s later: open ends (the default)
    find where the body take begins in it; fixed ends squeeze the extra seconds in."""
    case = make_case("beat", 200, realism=Realism(untrimmed_s=(1.0, 2.0)))
    opened = P.splice(case.body, case.hand, transfer_fingers=False)
    fixed = P.splice(case.body, case.hand, transfer_fingers=False, ends="fixed")
    e_open, e_fixed = _timing_ms(case, opened), _timing_ms(case, fixed)
    assert np.percentile(e_open, 95) < 0.5 * np.percentile(e_fixed, 95)
    assert np.median(e_open) <= 1000.0 / case.body.fps
    f, a = opened.features, opened.alignment
    (b0, b1), (h0, h1) = a.overlap
    truth_grid = f.hand_to_grid(case.truth[[0, -1]])
    # the overlap's hand ends within half a second of the truth (a still arm at an end
    # leaves a few frames ambiguous)
    assert abs(h0 - truth_grid[0]) <= 0.5 * f.fps and abs(h1 - truth_grid[1]) <= 0.5 * f.fps
    assert tuple(fixed.alignment.pass2.path[0]) == (0, 0)
    rep = build_report(opened)
    assert rep["overlap"]["body"] == [b0, b1] and rep["parameters"]["ends"] == "open"
    assert rep["overlap"]["hand"][0] == pytest.approx(f.grid_to_hand(h0), abs=1)


def test_body_frames_outside_the_overlap_hold_the_matched_pose():
    """A body take longer than the hand take: the body frames before / after the overlap
    get the first / last matched hand frame (no invented timing) and are listed."""
    case = make_case("beat", 200)
    hand = case.hand.frames(int(1.5 * case.hand.fps), case.hand.n_frames - int(1.5 * case.hand.fps))
    res = P.splice(case.body, hand, transfer_fingers=False)
    a = res.alignment
    (b0, b1), _ = a.overlap
    assert b0 > 0 and b1 < res.features.n - 1
    assert a.unmatched_body == [(0, b0 - 1), (b1 + 1, res.features.n - 1)]
    raw = MG.median_warp(a.pass2.path, res.features.n)
    assert np.all(raw[:b0] == raw[b0]) and np.all(raw[b1:] == raw[b1])
    assert np.all(np.diff(a.map) >= 0)
    with pytest.raises(ValueError, match="ends: expected fixed or open"):
        P.splice(case.body, hand, transfer_fingers=False, ends="loose")
    with pytest.raises(ValueError, match="max_unmatched_s: expected"):
        P.splice(case.body, hand, transfer_fingers=False, max_unmatched_s=-1)


def test_holds_are_straightened_boundary_to_boundary():
    """A body hold of 30 frames matched to a hand hold of 10: inside, the DTW path is
    arbitrary (here diagonal then flat); the warp runs straight from entry to exit."""
    warp = np.concatenate(
        [np.arange(50.0), 50 + np.minimum(np.arange(30.0), 10), 61 + np.arange(20.0)]
    )
    out = MG.straighten_holds(warp, [(50, 79)], [(50, 60)], slack=3)
    np.testing.assert_allclose(out[50:80], 50 + np.arange(30) * 10 / 29)
    np.testing.assert_array_equal(out[:50], warp[:50])
    # holds that the warp does not match to each other stay as they are
    np.testing.assert_array_equal(MG.straighten_holds(warp, [(50, 79)], [(90, 99)], 3), warp)
    assert MG.still_runs(
        np.r_[np.ones(5), np.zeros(12), 1.0, np.zeros(3), np.ones(4)], 0.5, 10
    ) == [(5, 20)]


def test_app_shades_the_unmatched_ends():
    from webapp.views.cost_matrix import _unmatched_quads

    path = np.array([[0, 5], [1, 6], [2, 7], [3, 7]])
    q = _unmatched_quads(path, 6, 9)
    # body rows 4..5 after the overlap; hand columns 0..4 before and 8 after it
    assert list(zip(q["left"], q["right"], q["bottom"], q["top"], strict=True)) == [
        (3.5, 5.5, -0.5, 8.5),
        (-0.5, 5.5, -0.5, 4.5),
        (-0.5, 5.5, 7.5, 8.5),
    ]
    assert _unmatched_quads(np.array([[0, 0], [5, 8]]), 6, 9)["left"] == []


def test_pass1_row_kernel_with_open_ends_equals_the_cost_matrix():
    """The pass-1 row kernel (engine.align.phase_kernel) honours open ends exactly as the plain
    kernels do on the tabulated local costs."""
    from engine.align import metrics as M
    from engine.dtw import Band, Ends, align, align_features

    case = make_case("bandai", 4)
    f = P.prepare(case.body, case.hand)
    a, b = f.pass1_rows
    cost = M.cost_grid(M.splice_phase, a, b, np.arange(f.n), np.arange(f.m))
    band = Band.from_constraints(f.n, f.m, 0.4, [(0, 12, 2)], open_ends=True)
    for ends in (Ends(f.n // 2, f.m // 2, 7.5), Ends(10, 30, 0.0)):
        got = align_features(a, b, band, metric="splice_phase", ends=ends)
        ref = align(cost, band, ends)
        assert got.cost == pytest.approx(ref.cost, rel=1e-9)
        np.testing.assert_array_equal(got.path, ref.path)
