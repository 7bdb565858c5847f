"""Band construction: eqs. 4-5, matching points, widening, errors."""

from __future__ import annotations

import math

import naive
import numpy as np
import pytest

from engine.base.errors import ParameterError
from engine.dtw import Band, align, check_path


def test_sakoe_chiba_half_width_follows_method():
    n, m, width = 100, 60, 0.3
    band = Band.sakoe_chiba(n, m, width)
    lam = width * n * math.hypot(n, m) / (2 * n)  # Λ = W sqrt(n² + m²) / (2n)
    for i in (30, 50, 70):
        c = (i + 1) * m / n - 1
        assert band.lo[i] == math.ceil(c - lam)
        assert band.hi[i] == math.floor(c + lam)
    assert band == Band.from_constraints(n, m, width, [])
    lo, hi = naive.constraint_band(n, m, width, [])
    assert band == Band(np.array(lo), np.array(hi), m)


def test_from_constraints_equals_formula_where_no_widening_is_needed():
    n, m = 120, 90
    points = [(30, 20, 2), (70, 55, 0), (100, 70, 5)]
    band = Band.from_constraints(n, m, 0.3, points)
    lo, hi = naive.trim(*naive.constraint_band(n, m, 0.3, points))
    assert band.lo.tolist() == lo and band.hi.tolist() == hi
    assert (band.lo[70], band.hi[70]) == (55, 55)  # tol 0: the point's row is the point
    assert (band.lo[30], band.hi[30]) == (18, 22)
    assert band.lo[31] >= 18 and band.hi[29] <= 22  # segment clips [y_{k-1}-T, y_k+T]


def test_tolerance_zero_point_is_on_the_optimal_path_even_against_the_cost():
    n = m = 40
    cost = np.ones((n, m))
    cost[np.arange(n), np.arange(m)] = 0.0  # the diagonal is free
    r = align(cost, Band.from_constraints(n, m, 0.3, [(20, 26, 0)]))
    assert [20, 26] in r.path.tolist()
    assert r.path[r.path[:, 0] == 20, 1].tolist() == [26]
    r = align(cost, Band.from_constraints(n, m, 0.3, [(20, 26, 3)]))
    cols = r.path[r.path[:, 0] == 20, 1]
    assert cols.min() >= 23 and cols.max() <= 29
    assert 23 in cols  # as close to the free diagonal as the tolerance allows


def test_narrow_steep_band_is_widened_to_a_minimal_staircase():
    band = Band.sakoe_chiba(10, 100, 0.0)
    assert band.area == 100  # every path needs at least max(n, m) cells
    assert (band.widths >= 1).all()
    band = Band.from_constraints(50, 50, 0.0, [(10, 40, 0)])
    assert naive.band_is_feasible(band.lo.tolist(), band.hi.tolist(), 50)
    # a staircase through the point plus at most the two cells around the centre line per row
    assert band.area <= 50 + 50 + 50
    assert (band.lo[10], band.hi[10]) == (40, 40)


def test_width_none_gives_only_the_tolerance_clips():
    band = Band.from_constraints(20, 20, None, [(10, 5, 1)])
    assert (band.lo[10], band.hi[10]) == (4, 6)
    assert band.hi[:10].max() == 6 and band.lo[11:].min() == 4
    assert band.lo[0] == 0 and band.hi[-1] == 19


@pytest.mark.parametrize(
    "points,message",
    [
        (
            [(5, 5), (3, 7)],
            r"^matching point 2 \(body 3, hand 7\): body frame 3 is not after matching point "
            r"1's body frame 5",
        ),
        (
            [(5, 5), (5, 5)],
            r"^matching point 2 \(body 5, hand 5\): the same frames as matching point 1 "
            r"\(body 5, hand 5\)",
        ),
        ([(5, 5), (5, 8)], r"^matching point 2 .* same body frame as matching point 1 \(body 5,"),
        (
            [(5, 9), (8, 4)],
            r"^matching point 2 \(body 8, hand 4\): hand frame 4 is before matching point 1's "
            r"hand frame 9",
        ),
        (
            [(25, 3)],
            r"^matching point 1 \(body 25, hand 3\): outside the 20 x 20 matrix; expected body "
            r"frames 0 to 19 and hand frames 0 to 19$",
        ),
        ([(3, -1)], r"^matching point 1 \(body 3, hand -1\): outside"),
        ([(3, 4, -1)], r"^matching point 1 \(body 3, hand 4\): expected a tolerance of at least 0"),
        ([(3.5, 4)], r"^matching point 1 \(body 3.5, hand 4\): expected whole body and hand"),
        ([(0, 6, 2)], r"^matching point 1 \(body 0, hand 6\): .*starts at \(0, 0\).*at least 6$"),
        ([(19, 10, 3)], r"ends at \(19, 19\).*at least 9$"),
        (
            [(5, 5), (6, 9)],
            r"^matching point 2 \(body 6, hand 9\): on the body frame after matching point 1 "
            r"\(body 5, hand 5\), but their hand frames 5 and 9 are more than one step apart",
        ),
        ([(5,)], r"^matching point 1: expected \(body, hand\) or \(body, hand, tolerance\)"),
    ],
)
def test_invalid_points_raise_naming_the_point(points, message):
    with pytest.raises(ParameterError, match=message):
        Band.from_constraints(20, 20, 0.3, points)


def test_consecutive_points_within_tolerance_are_fine():
    band = Band.from_constraints(20, 20, 0.3, [(5, 5, 1), (6, 8, 1)])
    assert naive.band_is_feasible(band.lo.tolist(), band.hi.tolist(), 20)


def test_width_validation():
    for bad in (-0.1, float("nan"), "wide"):
        with pytest.raises(ParameterError, match="width"):
            Band.sakoe_chiba(10, 10, bad)
    with pytest.raises(ParameterError, match="positive whole number"):
        Band.sakoe_chiba(0, 10, 0.3)


@pytest.mark.parametrize(
    "lo,hi,m,message",
    [
        ([1, 1], [2, 2], 3, "row 0 starts at column 1"),
        ([0, 0], [1, 1], 3, "row 1 ends at column 1"),
        ([0, 3], [1, 4], 5, "row 1 starts at column 3 but row 0 ends at column 1"),
        (
            [0, 2, 0, 0],
            [2, 2, 1, 2],
            3,
            "row 2 ends at column 1, but row 1 already starts at column 2",
        ),
        ([0, 0], [3, 5], 5, r"row 0: columns 0..3 are not a range inside 0..4|row 1"),
        ([0, 2], [1, 1], 3, "not a range"),
    ],
)
def test_infeasible_bands_are_rejected_with_the_row(lo, hi, m, message):
    with pytest.raises(ParameterError, match=message):
        Band(np.array(lo), np.array(hi), m)


def test_unusable_cells_are_trimmed_and_arrays_are_read_only():
    band = Band(np.array([0, 0, 3, 1]), np.array([4, 3, 4, 4]), 5)
    assert band.lo.tolist() == [0, 0, 3, 3]
    assert band.hi.tolist() == [3, 3, 4, 4]  # (0, 4) cannot lead on to row 1
    assert band.start.tolist() == [0, 4, 8, 10, 12]
    with pytest.raises(ValueError):
        band.lo[0] = 1


def test_contains_check_fits_and_reversed():
    band = Band.sakoe_chiba(30, 20, 0.2)
    mask = band.mask()
    ii, jj = np.meshgrid(np.arange(30), np.arange(20), indexing="ij")
    assert (band.contains(ii, jj) == mask).all()
    assert band.contains(-1, 0) is False
    band.check_fits((30, 20))
    with pytest.raises(ParameterError, match="30 x 20"):
        band.check_fits((20, 30))
    assert (band.reversed().mask() == mask[::-1, ::-1]).all()
    assert band.reversed().reversed() == band


def test_around_path_and_intersect():
    path = np.array([[0, 0], [1, 1], [2, 1], [3, 2], [4, 3]])
    band = Band.around_path(path, 5, 4, radius=1)
    assert band.lo.tolist() == [0, 0, 0, 0, 1]
    assert band.hi.tolist() == [2, 2, 3, 3, 3]
    narrow = Band.around_path(path, 5, 4, radius=0)
    assert narrow.intersect(band) == narrow
    with_points = Band.around_path(path, 5, 4, radius=1, points=[(2, 1, 0)])
    assert (with_points.lo[2], with_points.hi[2]) == (1, 1)
    with pytest.raises(ParameterError, match="not within 0 frames of the path.*row 2"):
        Band.around_path(path, 5, 4, radius=0, points=[(2, 3, 0)])
    with pytest.raises(ParameterError, match="share no cell in row"):
        Band.full(5, 4).intersect(
            Band(np.array([0, 0, 3, 3, 3]), np.array([0, 3, 3, 3, 3]), 4)
        ).intersect(Band(np.array([0, 0, 0, 0, 0]), np.array([1, 1, 1, 1, 3]), 4))


def test_check_path_rejects_bad_paths():
    with pytest.raises(ParameterError, match="from \\(0, 0\\) to \\(2, 2\\)"):
        check_path([[0, 0], [1, 1]], 3, 3)
    with pytest.raises(ParameterError, match="step 0 from \\(0, 0\\) to \\(2, 2\\)"):
        check_path([[0, 0], [2, 2]], 3, 3)
    with pytest.raises(ParameterError, match="\\(k, 2\\)"):
        check_path(np.zeros((3, 3)), 3, 3)
