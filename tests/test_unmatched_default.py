"""The default open-end limit for takes of different lengths (issue 13, real takes).

A short take recorded during a long one (a 33 s hand take inside a 2-minute body take)
must be able to match any stretch of the long one: the default limit lets each end of
the longer take stay unmatched for the length difference plus half the shorter take, and
pass 1's band holds every such placement (``engine.splice.end_band.inside_band``). With
half the shorter take at each end (the old default) the hand had to span at least
2 min - 33 s of the body take."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.split import inside_case
from engine.dtw import Band
from engine.dtw import constraints as C
from engine.splice import pipeline as P
from engine.splice.end_band import inside_band, open_end_band
from engine.splice.report import unmatched_summary


def test_the_default_limit_adds_the_length_difference_to_the_longer_take():
    # 120 s body, 33 s hand at 30 fps: the body may leave 87 s + 16.5 s at an end
    assert C.unmatched_limits(3600, 990, 30.0) == (2610 + 495, 495)
    # the other order: the hand take is the longer one
    assert C.unmatched_limits(990, 3600, 30.0) == (495, 2610 + 495)
    # equal lengths: half the take, as before
    assert C.unmatched_limits(300, 300, 30.0) == (150, 150)
    # given seconds hold for both takes, below each take's length
    assert C.unmatched_limits(3600, 990, 30.0, 2.0) == (60, 60)
    assert C.unmatched_limits(3600, 990, 30.0, 100.0) == (3000, 989)
    assert P.unmatched_limits(3600, 990, 30.0, None) == C.unmatched_limits(3600, 990, 30.0)


@pytest.mark.parametrize("n, m", [(3600, 990), (990, 3600)])
def test_pass_one_band_holds_every_placement_of_the_shorter_take(n, m):
    width = 14.2 * 30.0 / n  # the default time width of a 2-minute take (1.5 s sqrt(T))
    paper = Band.from_constraints(n, m, width, open_ends=True)
    wide = open_end_band(paper, width, C.unmatched_limits(n, m, 30.0), fps=30.0)
    short = min(n, m)
    for d in np.linspace(0, abs(n - m), 7).astype(int):  # slope-1 paths, offset d
        k = np.arange(short)
        rows, cols = (k + d, k) if n > m else (k, k + d)
        assert np.all((wide.lo[rows] <= cols) & (cols <= wide.hi[rows])), d
    # the old band left most of them out
    k = np.arange(short)
    rows, cols = (k + abs(n - m), k) if n > m else (k, k + abs(n - m))
    assert not np.all((paper.lo[rows] <= cols) & (cols <= paper.hi[rows]))
    # it costs at most the shorter take times (difference + the band's reach) cells
    reach = width * n / np.sqrt(2.0)
    assert wide.area <= paper.area + short * (abs(n - m) + 2 * reach + 2)


def test_takes_of_one_length_or_a_small_limit_add_no_placements():
    assert inside_band(300, 300, 0.3, (150, 150)) is None
    # a 2 s limit cannot place a 33 s take inside a 120 s one
    assert inside_band(3600, 990, 0.1, (60, 60)) is None


def _errors(case, **kw):
    result = P.splice(case.body, case.hand, transfer_fingers=False, **kw)
    inside = np.isfinite(case.truth)
    return np.abs(result.alignment.map[inside] - case.truth[inside]), result


@pytest.mark.parametrize(
    "offset_s, seed, hand_longer", [(80.0, 1, False), (10.0, 2, True)], ids=["body", "hand"]
)
def test_a_short_real_take_inside_a_long_one_is_timed_within_frames(
    offset_s, seed, hand_longer, mocap_dir
):
    """LAFAN1 (real capture, 30 fps): a 33 s stretch from ``offset_s`` of a 2-minute take,
    re-timed as a hand take (or the body take, when the hand take is the long one). The
    old default (half the shorter take) spread it over most of the long take: p95 error
    386 frames (body longer) and 1872 frames (hand longer); the new one is within frames."""
    case = inside_case(120.0, 33.0, offset_s, seed=seed, hand_longer=hand_longer, mocap=mocap_dir)
    err, result = _errors(case)
    assert np.median(err) <= 1.0 and np.percentile(err, 95) <= 5.0, (
        np.median(err),
        np.percentile(err, 95),
    )
    (b0, b1), _ = result.alignment.overlap
    truth_rows = np.flatnonzero(np.isfinite(case.truth))
    # the overlap ends within 0.5 s of the stretch (its last frames are near-still)
    assert abs(b0 - truth_rows[0]) <= 15 and abs(b1 - truth_rows[-1]) <= 15
    if not hand_longer:  # the body's unmatched ends are the data's, not the limit's
        limit = result.alignment.unmatched_limit(case.body.fps)
        ranges = result.alignment.unmatched_body
        assert all(b - a + 1 < limit for a, b in ranges)
        assert "open-end limit" not in unmatched_summary(ranges, case.body.fps, limit)


def test_the_cli_help_and_the_unmatched_sentence_name_the_default_rule(capsys):
    from engine.cli import main

    with pytest.raises(SystemExit):
        main(["splice", "--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    assert f"(default: {C.UNMATCHED_DEFAULT})" in help_text
    text = unmatched_summary([(0, 3104)], 30.0, 3105)
    assert f"open-end limit ({C.UNMATCHED_DEFAULT})" in text
    assert "--max-unmatched SECONDS allows longer unmatched ends" in text


def test_a_band_over_the_cell_limit_names_max_unmatched(mocap_dir, monkeypatch):
    """The placements cost min(n, m) x |n - m| cells: where that passes the cell limit the
    refusal says why and which option narrows it, and --max-unmatched does."""
    from engine.base import limits
    from engine.base.errors import ParameterError

    case = inside_case(120.0, 33.0, 45.0, seed=0, mocap=mocap_dir)
    f = P.prepare(case.body, case.hand)
    monkeypatch.setattr(limits, "MAX_BAND_CELLS", 2_500_000)
    with pytest.raises(ParameterError, match=r"differ by 87\.0 s .* --max-unmatched SECONDS"):
        P.align_passes(f)
    a = P.align_passes(f, max_unmatched_s=5.0)
    assert a.pass1.band.area <= 2_500_000
