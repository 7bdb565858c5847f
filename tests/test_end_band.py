"""Pass 1's band with open ends leaves room for the unmatched ends (engine.splice.end_band)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from benchmarks.split import Realism, make_case
from engine.dtw import Band
from engine.splice import pipeline as P
from engine.splice.end_band import inside_band, open_end_band


def _inside(band: Band, path: np.ndarray) -> bool:
    i, j = path[:, 0], path[:, 1]
    return bool(np.all((band.lo[i] <= j) & (j <= band.hi[i])))


def _with_placements(paper: Band, width: float, limits) -> Band:
    """``paper`` and the slope-1 placements of the shorter take (``inside_band``): the band
    the widening for unmatched ends starts from when the takes' lengths differ."""
    inside = inside_band(paper.n, paper.m, width, limits)
    if inside is None:
        return paper
    rows = inside[0] <= inside[1]
    lo = np.where(rows, np.minimum(paper.lo, inside[0]), paper.lo)
    hi = np.where(rows, np.maximum(paper.hi, inside[1]), paper.hi)
    return Band(lo, hi, paper.m, open_ends=True)


def _line(n, j0, j1):
    i = np.arange(n)
    return np.column_stack([i, np.round(j0 + (j1 - j0) * i / (n - 1)).astype(np.int64)])


@pytest.mark.parametrize("n,m", [(150, 240), (300, 310), (400, 260)])
def test_straight_paths_with_ends_up_to_twice_the_half_width_fit(n, m):
    """The hand take starts s and ends e frames beyond the body take's (s, e <= 2Λ): the
    paper's strip leaves such paths out once s or e exceeds Λ, the widened band holds them."""
    width = 0.3
    lam = width * math.sqrt(n * n + m * m) / 2
    paper = Band.from_constraints(n, m, width, open_ends=True)
    wide = open_end_band(paper, width, (n // 2, m // 2))
    assert np.all(wide.lo <= paper.lo) and np.all(wide.hi >= paper.hi)
    s = e = int(1.9 * lam)
    for j0, j1 in ((s, m - 1 - e), (s, m - 1), (0, m - 1 - e)):
        if j1 <= j0:
            continue
        path = _line(n, j0, j1)
        assert _inside(wide, path)
    assert not _inside(paper, _line(n, s, m - 1 - e))
    # the middle row is not widened beyond the shorter take's slope-1 placements (none
    # when the takes last as long): the band grows by about half its area, not more
    base = _with_placements(paper, width, (n // 2, m // 2))
    assert wide.lo[n // 2] == base.lo[n // 2] and wide.hi[n // 2] == base.hi[n // 2]
    assert wide.area <= base.area + 0.6 * paper.area


def test_the_widening_stays_within_the_unmatched_limits():
    n, m = 200, 220
    paper = Band.from_constraints(n, m, 0.3, open_ends=True)
    wide = open_end_band(paper, 0.3, (5, 5))
    assert np.all(wide.hi - paper.hi <= 5 * m / n + 6) and np.all(paper.lo - wide.lo <= 11)
    assert open_end_band(paper, 0.3, (0, 0)) == paper


def test_matching_points_keep_their_clips():
    n, m = 200, 260
    pts = [(0, 40, 0.0), (100, 150, 2.0)]
    paper = Band.from_constraints(n, m, 0.3, pts, open_ends=True)
    wide = open_end_band(paper, 0.3, (n // 2, m // 2), pts)
    assert wide.lo[0] == wide.hi[0] == 40
    assert 148 <= wide.lo[100] <= wide.hi[100] <= 152


def test_an_untrimmed_pair_whose_ends_lie_outside_the_papers_strip():
    """BEAT, hand take 1-2 s longer at each end of a 5 s body take: the true ends lie
    outside the paper's 30 % strip; with the widened band pass 1 finds them and pass 2
    keeps the fingers on time (p95 under 100 ms)."""
    case = make_case("beat", 202, realism=Realism(untrimmed_s=(1.0, 2.0)))
    res = P.splice(case.body, case.hand, transfer_fingers=False)
    f = res.features
    truth = f.hand_to_grid(case.truth)
    paper = Band.from_constraints(f.n, f.m, res.alignment.band, open_ends=True)
    assert not (paper.lo[0] <= truth[0] <= paper.hi[0])
    err = np.abs(res.alignment.map - case.truth) / case.hand.fps * 1000.0
    assert np.percentile(err, 95) < 100.0
    assert np.median(err) <= 1000.0 / case.body.fps


def test_long_takes_get_a_few_seconds_of_room_not_half_the_band():
    """A 2-minute pair at 30 fps with a 30 % band: the widening is capped at MAX_ROOM_S
    seconds and tapers within TAPER_WIDTHS times that, so pass 1 grows by ~10 %, not 40 %."""
    from engine.splice.end_band import MAX_ROOM_S, TAPER_WIDTHS

    fps, n, m = 30.0, 3600, 3700
    paper = Band.from_constraints(n, m, 0.3, open_ends=True)
    wide = open_end_band(paper, 0.3, (n // 2, m // 2), fps=fps)
    room = MAX_ROOM_S * fps
    assert np.all(wide.hi - paper.hi <= 2 * room + 1)
    assert wide.hi[0] - paper.hi[0] >= room - 1
    middle = slice(int(TAPER_WIDTHS * room * n / m) + 2, n - int(TAPER_WIDTHS * room * n / m) - 2)
    base = _with_placements(paper, 0.3, (n // 2, m // 2))  # 100 frames longer: ~6 %
    assert np.array_equal(wide.lo[middle], base.lo[middle])
    assert wide.area <= base.area + 0.15 * paper.area
