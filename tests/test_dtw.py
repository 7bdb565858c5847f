"""engine.dtw against plain-Python references, dtaidistance and hand-solved cases."""

from __future__ import annotations

import math

import naive
import numba
import numpy as np
import pytest

from engine.dtw import (
    Aligner,
    Band,
    align,
    align_features,
    cost_image,
    local_cost_image,
    metric_names,
    register_metric,
)
from engine.dtw import kernels as K


def sq_cost(a, b):
    a = np.asarray(a, float).reshape(len(a), -1)
    b = np.asarray(b, float).reshape(len(b), -1)
    return ((a[:, None, :] - b[None, :, :]) ** 2).sum(-1)


def band_of(lo, hi, m):
    return Band(np.asarray(lo), np.asarray(hi), m)


def assert_matches_naive(cost, band, result):
    total, path, _ = naive.dtw_banded(cost, band.lo.tolist(), band.hi.tolist())
    assert result.cost == pytest.approx(total, rel=1e-12, abs=1e-12)
    assert [tuple(p) for p in result.path.tolist()] == path


# ---------------------------------------------------------------------------
# hand-solved cases
# ---------------------------------------------------------------------------
def test_single_cell():
    r = align(np.array([[5.0]]), Band.full(1, 1))
    assert r.cost == 5.0
    assert r.path.tolist() == [[0, 0]]


def test_single_row_and_single_column_take_every_cell():
    row = np.array([[1.0, 2.0, 3.0, 4.0]])
    r = align(row, Band.full(1, 4))
    assert r.cost == 10.0
    assert r.path.tolist() == [[0, 0], [0, 1], [0, 2], [0, 3]]
    r = align(row.T, Band.full(4, 1))
    assert r.cost == 10.0
    assert r.path.tolist() == [[0, 0], [1, 0], [2, 0], [3, 0]]


def test_identical_sequences_align_on_the_diagonal():
    x = np.array([0.0, 1.0, 3.0, 2.0, 0.5])
    r = align_features(x, x, Band.full(5, 5))
    assert r.cost == 0.0
    assert r.path.tolist() == [[i, i] for i in range(5)]


def test_repeated_frame_is_absorbed_by_a_vertical_step():
    body = np.array([0.0, 1.0, 1.0, 2.0])  # body holds frame value 1 twice
    hand = np.array([0.0, 1.0, 2.0])
    r = align_features(body, hand, Band.full(4, 3))
    assert r.cost == 0.0
    assert r.path.tolist() == [[0, 0], [1, 1], [2, 1], [3, 2]]


def test_tie_prefers_diagonal_then_vertical_then_horizontal():
    # cell (1, 2): diagonal (0,1) gamma 2, left (1,1) gamma 2 -> diagonal wins
    cost = np.array([[1.0, 1.0, 9.0], [9.0, 1.0, 1.0]])
    r = align(cost, Band.full(2, 3))
    assert r.cost == 3.0
    assert r.path.tolist() == [[0, 0], [0, 1], [1, 2]]
    # all-equal costs: the diagonal is taken wherever possible
    r = align(np.ones((3, 5)), Band.full(3, 5))
    assert r.path.tolist() == [[0, 0], [0, 1], [0, 2], [1, 3], [2, 4]]


def test_forbidden_cells_are_avoided():
    cost = np.zeros((3, 3))
    cost[1, 1] = np.inf
    r = align(cost, Band.full(3, 3))
    assert r.cost == 0.0
    assert [1, 1] not in r.path.tolist()


# ---------------------------------------------------------------------------
# kernels against the plain-Python reference
# ---------------------------------------------------------------------------
SHAPES = [(1, 1), (1, 7), (7, 1), (2, 2), (40, 3), (3, 40), (70, 90), (91, 64), (33, 35)]


@pytest.mark.parametrize("n,m", SHAPES)
@pytest.mark.parametrize("kind", ["full", "sakoe", "narrow", "points"])
def test_matrix_and_feature_kernels_equal_naive(n, m, kind):
    rng = np.random.default_rng(n * 1000 + m)
    a = rng.standard_normal((n, 3))
    b = rng.standard_normal((m, 3))
    if kind == "full":
        band = Band.full(n, m)
    elif kind == "sakoe":
        band = Band.sakoe_chiba(n, m, 0.3)
    elif kind == "narrow":
        band = Band.sakoe_chiba(n, m, 0.0)  # a staircase a cell or two wide
    else:
        x = n // 2
        pts = [(x, min(m - 1, m // 3), 1)] if 0 < x < n - 1 else []
        band = Band.from_constraints(n, m, 0.5, pts)
    cost = sq_cost(a, b)
    r_matrix = align(cost, band)
    r_features = align_features(a, b, band)
    assert_matches_naive(cost, band, r_matrix)
    assert_matches_naive(cost, band, r_features)
    assert r_matrix.band is band


def test_band_one_cell_wide_forces_the_path():
    rng = np.random.default_rng(1)
    path = np.array([[0, 0], [0, 1], [1, 2], [2, 2], [3, 3], [3, 4], [4, 5]])
    band = Band.around_path(path, 5, 6, radius=0)
    assert band.area == len(path)
    cost = rng.random((5, 6))
    r = align(cost, band)
    assert r.path.tolist() == path.tolist()
    assert r.cost == pytest.approx(cost[path[:, 0], path[:, 1]].sum())


def test_wide_rows_use_the_pair_kernel_and_still_match():
    # rows wider than PAIR_MIN_WIDTH with odd row counts and shifting bands
    assert K.PAIR_MIN_WIDTH < 60
    rng = np.random.default_rng(7)
    for n, m, width in ((121, 130, 0.9), (64, 200, 0.7), (150, 90, 1.2)):
        cost = rng.random((n, m))
        band = Band.sakoe_chiba(n, m, width)
        assert_matches_naive(cost, band, align(cost, band))


def test_brute_force_minimum_on_tiny_bands():
    rng = np.random.default_rng(3)
    for n, m in ((3, 4), (4, 4), (5, 3), (4, 6)):
        cost = rng.integers(0, 5, size=(n, m)).astype(float)
        band = Band.from_constraints(n, m, 0.8, [])
        best = min(naive.path_cost(cost, p) for p in naive.all_paths(band.lo, band.hi, m))
        r = align(cost, band)
        assert r.cost == best
        assert naive.path_cost(cost, r.path) == best


def test_euclidean_and_registered_metric_equal_naive():
    rng = np.random.default_rng(5)
    a = rng.standard_normal((20, 4))
    b = rng.standard_normal((26, 4))
    band = Band.sakoe_chiba(20, 26, 0.4)
    r = align_features(a, b, band, metric="euclidean")
    cost = naive.local_cost_matrix(a, b, "euclidean")
    assert_matches_naive(cost, band, r)

    @numba.njit
    def cityblock(x, y):
        s = 0.0
        for d in range(x.shape[0]):
            s += abs(x[d] - y[d])
        return s

    name = "test_cityblock"
    if name not in metric_names():
        register_metric(name, cityblock)
    r = align_features(a, b, band, metric=name)
    cost = naive.local_cost_matrix(a, b, lambda x, y: float(np.abs(x - y).sum()))
    assert_matches_naive(cost, band, r)
    # a numba function works unregistered too
    assert align_features(a, b, band, metric=cityblock).cost == pytest.approx(r.cost)


def test_metric_registry_rejects_bad_entries():
    with pytest.raises(TypeError, match="numba.njit"):
        register_metric("plain_python", lambda x, y: 0.0)
    with pytest.raises(ValueError, match="already registered"):
        register_metric("sqeuclidean", K.euclidean)
    with pytest.raises(ValueError, match="unknown metric 'nope'"):
        align_features(np.zeros(3), np.zeros(3), Band.full(3, 3), metric="nope")


# ---------------------------------------------------------------------------
# NaN, infinity and validation
# ---------------------------------------------------------------------------
def test_nan_inside_band_is_rejected_naming_the_cell():
    cost = np.ones((6, 6))
    cost[3, 4] = np.nan
    with pytest.raises(ValueError, match=r"body frame 3, hand frame 4"):
        align(cost, Band.full(6, 6))


def test_nan_outside_band_is_never_read():
    cost = np.ones((6, 6))
    cost[0, 5] = np.nan
    r = align(cost, Band.sakoe_chiba(6, 6, 0.2))
    assert r.cost == 6.0


def test_nan_in_features_names_frame_and_dimension():
    a = np.zeros((8, 3))
    b = np.zeros((9, 3))
    a[5, 2] = np.nan
    with pytest.raises(
        ValueError, match=r"body frame 5, hand frame \d+; a\[5\] has NaN in dimension\(s\) \[2\]"
    ):
        align_features(a, b, Band.full(8, 9))


def test_negative_infinity_is_rejected_and_all_blocked_band_raises():
    cost = np.ones((4, 4))
    cost[2, 2] = -np.inf
    with pytest.raises(ValueError, match="finite or \\+inf"):
        align(cost, Band.full(4, 4))
    cost = np.ones((4, 4))
    cost[2, :] = np.inf
    with pytest.raises(ValueError, match="infinite local cost"):
        align(cost, Band.full(4, 4))


def test_shape_and_type_validation():
    with pytest.raises(ValueError, match=r"shape \(3, 4\) but the band is for 3 x 5"):
        align(np.ones((3, 4)), Band.full(3, 5))
    with pytest.raises(ValueError, match="2-D"):
        align(np.ones(4), Band.full(1, 4))
    with pytest.raises(ValueError, match="3 values per frame but b have 2"):
        align_features(np.ones((3, 3)), np.ones((4, 2)), Band.full(3, 4))
    with pytest.raises(TypeError, match="Band"):
        align(np.ones((2, 2)), None)
    with pytest.raises(ValueError, match="real numbers"):
        align(np.array([["a", "b"]]), Band.full(1, 2))


# ---------------------------------------------------------------------------
# dtaidistance: distance and path cost on Sakoe-Chiba windows
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("n,m,window", [(50, 50, 6), (60, 45, 20), (45, 60, 20), (80, 80, 80)])
def test_equals_dtaidistance_1d(n, m, window):
    from dtaidistance import dtw

    rng = np.random.default_rng(n + m + window)
    s1 = np.cumsum(rng.standard_normal(n))
    s2 = np.cumsum(rng.standard_normal(m))
    lo, hi = naive.dtaidistance_window_band(n, m, window)
    band = band_of(lo, hi, m)
    r = align_features(s1, s2, band)
    assert math.sqrt(r.cost) == pytest.approx(dtw.distance_fast(s1, s2, window=window), rel=1e-12)
    path = dtw.warping_path(s1, s2, window=window, use_c=True)
    path_cost = sum((s1[i] - s2[j]) ** 2 for i, j in path)
    assert r.cost == pytest.approx(path_cost, rel=1e-12)
    assert [tuple(p) for p in r.path.tolist()] == [tuple(p) for p in path]


@pytest.mark.parametrize("n", [40, 101])
def test_sakoe_chiba_equals_dtaidistance_ndim(n):
    from dtaidistance import dtw_ndim

    rng = np.random.default_rng(n)
    a = rng.standard_normal((n, 12))
    b = rng.standard_normal((n, 12))
    band = Band.sakoe_chiba(n, n, 0.3)
    half = 0.3 * n * math.sqrt(2) / 2
    window = math.floor(half) + 1
    assert band == band_of(*naive.dtaidistance_window_band(n, n, window), n)
    r = align_features(a, b, band)
    path, dist = dtw_ndim.warping_path(a, b, window=window, use_c=True, include_distance=True)
    assert math.sqrt(r.cost) == pytest.approx(dist, rel=1e-12)
    assert r.cost == pytest.approx(sum(((a[i] - b[j]) ** 2).sum() for i, j in path), rel=1e-12)


# ---------------------------------------------------------------------------
# Aligner (incremental)
# ---------------------------------------------------------------------------
def test_aligner_reuses_rows_and_equals_full_solves():
    rng = np.random.default_rng(11)
    n, m = 240, 200
    a = rng.standard_normal((n, 4))
    b = rng.standard_normal((m, 4))
    points = [[60, 50, 2], [120, 100, 0], [180, 150, 3]]
    solver = Aligner(a, b)
    band = Band.from_constraints(n, m, 0.3, points)
    first = solver.solve(band)
    stats = solver.last_stats
    assert stats.forward_rows == (0, n)  # a full solve runs forward over every row ...
    suffix = band.area - band.start[stats.backward_rows[0]]
    assert stats.cells_computed == band.area + suffix  # ... plus the backward last third
    assert suffix == pytest.approx(band.area / 3, rel=0.05)
    plain = align_features(a, b, band)
    assert first.cost == pytest.approx(plain.cost, rel=1e-12)
    assert first.path.tolist() == plain.path.tolist()
    for y in (104, 110, 95, 100):  # drag the middle point
        points[1][1] = y
        band = Band.from_constraints(n, m, 0.3, points)
        r = solver.solve(band)
        full = align_features(a, b, band)
        assert r.cost == pytest.approx(full.cost, rel=1e-12)
        assert r.path.tolist() == full.path.tolist()
        stats = solver.last_stats
        assert stats.forward_rows[0] > 50  # rows before the previous point are reused
    assert stats.cells_computed < 0.6 * band.area  # after the first drag: two segments only
    assert solver.solve(band) is r  # unchanged band: nothing recomputed
    assert solver.last_stats.cells_computed == 0


SLACK = 2 * Aligner.GAMMA_EVERY + 4  # rows a pass may redo to resume from a stored row


def _even_points(n, count=5, tol=2):
    return [
        [round(n * k / (count + 1)), round(n * k / (count + 1)), tol] for k in range(1, count + 1)
    ]


def _segment_cells(band, r0, r1):
    """Band cells in rows r0..r1 (the rows an edit must recompute)."""
    return int(band.start[r1 + 1] - band.start[r0])


@pytest.mark.parametrize("k", [2, 3, 4])  # points at n/2, 2n/3, 5n/6
def test_aligner_first_edit_recomputes_only_the_two_segments(k):
    rng = np.random.default_rng(13 + k)
    n = 300
    a = rng.standard_normal((n, 3))
    b = rng.standard_normal((n, 3))
    points = _even_points(n)
    xs = [p[0] for p in points]
    solver = Aligner(a, b)
    solver.solve(Band.from_constraints(n, n, 0.3, points))
    for step, dy in enumerate((6, -5, 9)):  # first edit, then further drags
        points[k][1] = xs[k] + dy
        band = Band.from_constraints(n, n, 0.3, points)
        r = solver.solve(band)
        full = align_features(a, b, band)
        assert r.cost == pytest.approx(full.cost, rel=1e-12)
        assert r.path.tolist() == full.path.tolist()
        stats = solver.last_stats
        r0, r1 = xs[k - 1] + 1, xs[k + 1] if k + 1 < len(xs) else n - 1
        # the point's two segments, plus the few rows back to a stored γ row
        assert stats.cells_computed <= _segment_cells(band, r0, r1) + SLACK * n, (step, stats)
        assert stats.cells_computed <= 0.4 * band.area, (step, stats)
        assert stats.forward_rows[0] >= r0 - SLACK and stats.backward_rows[1] <= r1 + SLACK


def test_aligner_switching_points_and_adding_one_stays_exact_and_cheap():
    rng = np.random.default_rng(17)
    n, m = 300, 280
    cost = rng.random((n, m))
    points = [[50, 45, 2], [100, 92, 1], [150, 140, 2], [200, 186, 0], [250, 232, 2]]
    solver = Aligner.from_cost(cost)
    solver.solve(Band.from_constraints(n, m, 0.3, points))

    def edit(pts):
        band = Band.from_constraints(n, m, 0.3, pts)
        r = solver.solve(band)
        assert_matches_naive(cost, band, r)
        return solver.last_stats, band

    # the last point, then the one before it, then the last again: each a first edit
    for k, y in ((4, 240), (3, 190), (4, 228), (3, 183)):
        points[k][1] = y
        stats, band = edit(points)
        r0 = points[k - 1][0] + 1
        r1 = points[k + 1][0] if k + 1 < len(points) else n - 1
        assert stats.cells_computed <= _segment_cells(band, r0, r1) + SLACK * m
    # a new point between the last two, then dragging it: only the segment it splits
    points.insert(4, [225, 210, 1])
    for y in (210, 215, 205):
        points[4][1] = y
        stats, band = edit(points)
        assert stats.cells_computed <= _segment_cells(band, 201, 250) + SLACK * m
    # an early point (its first edit reaches back to the junction, later drags stay
    # local), then one in the last third again: exact
    for step, y in enumerate((40, 50, 44)):
        points[0][1] = y
        stats, band = edit(points)
        if step:
            assert stats.cells_computed <= _segment_cells(band, 0, 100) + SLACK * m
    points[5][1] = 236
    _, band = edit(points)
    gamma = solver.cumulative_cost().dense()
    assert gamma[n - 1, m - 1] == pytest.approx(solver.solve(band).cost, rel=1e-12)


def test_cumulative_cost_stays_exact_across_edits_and_checkpoints():
    rng = np.random.default_rng(23)
    n, m = 90, 80
    cost = rng.random((n, m))
    points = [[30, 25, 1], [60, 52, 2]]
    solver = Aligner.from_cost(cost)
    for step, y in enumerate((52, 58, 47, 55)):
        points[1][1] = y
        band = Band.from_constraints(n, m, 0.4, points)
        r = solver.solve(band)
        assert_matches_naive(cost, band, r)
        if step >= 1:  # view in use from the second solve on
            _, _, gamma = naive.dtw_banded(cost, band.lo.tolist(), band.hi.tolist())
            dense = solver.cumulative_cost().dense()
            got = np.array([dense[i, j] for i, j in gamma])
            np.testing.assert_allclose(got, list(gamma.values()), rtol=1e-12)


def test_aligner_full_rewrite_is_a_full_solve_again():
    rng = np.random.default_rng(19)
    n, m = 120, 100
    cost = rng.random((n, m))
    solver = Aligner.from_cost(cost)
    solver.solve(Band.sakoe_chiba(n, m, 0.3))
    band = Band.sakoe_chiba(n, m, 0.5)  # every row changes: nothing to reuse
    r = solver.solve(band)
    assert solver.last_stats.forward_rows == (0, n)
    assert solver.last_stats.backward_rows[1] == n
    assert_matches_naive(cost, band, r)
    band = Band.from_constraints(n, m, 0.5, [(100, 80, 1)])  # then a cheap edit at the end
    r = solver.solve(band)
    assert_matches_naive(cost, band, r)
    assert solver.last_stats.forward_rows[0] > 0


def test_aligner_from_cost_and_cumulative_cost_after_edits():
    rng = np.random.default_rng(12)
    n, m = 70, 60
    cost = rng.random((n, m))
    solver = Aligner.from_cost(cost)
    band = Band.from_constraints(n, m, 0.5, [(20, 15, 1), (50, 40, 1)])
    solver.solve(band)
    band = Band.from_constraints(n, m, 0.5, [(20, 18, 1), (50, 40, 1)])
    r = solver.solve(band)
    assert_matches_naive(cost, band, r)
    _, _, gamma = naive.dtw_banded(cost, band.lo.tolist(), band.hi.tolist())
    dense = solver.cumulative_cost().dense()
    for (i, j), value in gamma.items():
        assert dense[i, j] == pytest.approx(value, rel=1e-12)
    assert np.isnan(dense[~band.mask()]).all()


def test_aligner_nan_error_then_recovers():
    cost = np.ones((30, 30))
    cost[25, 25] = np.nan
    solver = Aligner.from_cost(cost)
    with pytest.raises(ValueError, match="body frame 25, hand frame 25"):
        solver.solve(Band.full(30, 30))
    # a band avoiding the NaN works, reusing the valid rows
    band = Band.from_constraints(30, 30, None, [(25, 20, 0)])
    r = solver.solve(band)
    assert r.cost == 30 + 5  # 25 rows to (25, 20), then reach column 29 by row 29 -> extra steps
    assert_matches_naive(np.nan_to_num(cost, nan=1.0), band, r)


def test_aligner_rejects_mismatched_band():
    solver = Aligner(np.zeros((5, 2)), np.zeros((6, 2)))
    with pytest.raises(ValueError, match="5 x 6"):
        solver.solve(Band.full(6, 6))
    with pytest.raises(RuntimeError, match="solve"):
        solver.cumulative_cost()


# ---------------------------------------------------------------------------
# views
# ---------------------------------------------------------------------------
def block_reduce(dense, rpp, cpp, reduce):
    n, m = dense.shape
    h, w = -(-n // rpp), -(-m // cpp)
    out = np.full((h, w), np.nan)
    for r in range(h):
        for c in range(w):
            block = dense[r * rpp : (r + 1) * rpp, c * cpp : (c + 1) * cpp]
            vals = block[~np.isnan(block)]
            if vals.size:
                out[r, c] = vals.mean() if reduce == "mean" else vals.min()
    return out


@pytest.mark.parametrize("reduce", ["mean", "min"])
def test_cost_images_equal_block_reduction(reduce):
    rng = np.random.default_rng(21)
    a = rng.standard_normal((53, 5))
    b = rng.standard_normal((47, 5))
    cost = sq_cost(a, b)
    img = local_cost_image(a, b, max_size=(10, 8), reduce=reduce)
    assert (img.rows_per_pixel, img.cols_per_pixel) == (6, 6)
    assert img.image.shape == (9, 8)
    np.testing.assert_allclose(img.image, block_reduce(cost, 6, 6, reduce), rtol=1e-12)
    band = Band.sakoe_chiba(53, 47, 0.2)
    masked = np.where(band.mask(), cost, np.nan)
    img = local_cost_image(a, b, max_size=(10, 8), reduce=reduce, band=band)
    np.testing.assert_allclose(img.image, block_reduce(masked, 6, 6, reduce), rtol=1e-12)
    img2 = cost_image(cost, max_size=(10, 8), reduce=reduce, band=band)
    np.testing.assert_allclose(img2.image, img.image, rtol=1e-12)
    assert img.to_pixels([[0, 0], [52, 46]]).tolist() == [[0, 0], [8, 7]]


def test_cumulative_cost_image_and_row_access():
    rng = np.random.default_rng(22)
    cost = rng.random((40, 30))
    band = Band.sakoe_chiba(40, 30, 0.3)
    solver = Aligner.from_cost(cost)
    solver.solve(band)
    values = solver.cumulative_cost()
    dense = values.dense()
    np.testing.assert_allclose(values.image((5, 5)).image, block_reduce(dense, 8, 6, "mean"))
    cols, vals = values.row(10)
    assert cols[0] == band.lo[10] and cols[-1] == band.hi[10]
    np.testing.assert_array_equal(vals, dense[10, cols])


def test_views_validate_arguments():
    with pytest.raises(ValueError, match="reduce"):
        local_cost_image(np.zeros(4), np.zeros(4), reduce="max")
    with pytest.raises(ValueError, match="max_size"):
        local_cost_image(np.zeros(4), np.zeros(4), max_size=(0, 4))
