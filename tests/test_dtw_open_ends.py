"""Open-end DTW (engine.dtw.Ends): exact against the plain reference in tests/naive.py."""

from __future__ import annotations

import naive
import numpy as np
import pytest

from engine.base.errors import ParameterError
from engine.dtw import Aligner, Band, align, align_features
from engine.dtw import kernels as K
from engine.dtw.align import Ends, check_ends, ends_through_points


def _random_case(rng, n, m, ties):
    cost = rng.random((n, m))
    if ties:
        cost = np.round(cost * 2)  # many equal paths: the tie order must match too
    return cost


def _points(rng, n, m, k):
    xs = np.sort(rng.choice(n, k, replace=False))
    ys = np.sort(rng.choice(m, k, replace=False))
    return [(int(x), int(y), int(rng.integers(0, 5))) for x, y in zip(xs, ys, strict=True)]


def _naive(cost, band, ends):
    return naive.dtw_banded_open(
        cost.tolist(),
        band.lo.tolist(),
        band.hi.tolist(),
        ends.skip,
        ends.body,
        ends.hand,
        ends.end_body,
        ends.end_hand,
    )


@pytest.mark.parametrize("seed", range(6))
def test_open_ends_exact_on_random_bands_with_points(seed):
    rng = np.random.default_rng(seed)
    checked = 0
    for trial in range(60):
        n, m = int(rng.integers(2, 45)), int(rng.integers(2, 45))
        cost = _random_case(rng, n, m, ties=trial % 2 == 0)
        ends = Ends(
            int(rng.integers(0, n)), int(rng.integers(0, m)), float(rng.choice([0.0, 0.2, 0.5]))
        )
        pts = _points(rng, n, m, int(rng.integers(0, min(n, m, 3) + 1)))
        try:
            band = Band.from_constraints(n, m, float(rng.uniform(0.0, 1.0)), pts, open_ends=True)
            check_ends(band, ends)
        except ParameterError:
            continue
        total, path = _naive(cost, band, ends)
        if not np.isfinite(total):
            continue
        got = align(cost, band, ends)
        assert got.cost == pytest.approx(total, abs=1e-9)
        assert [tuple(c) for c in got.path.tolist()] == path
        assert naive.is_open_path(got.path.tolist(), n, m, ends.body, ends.hand)
        checked += 1
    assert checked > 20


def test_open_ends_adversarial_bands():
    """Tolerance-only bands, zero-width bands, points on the first and last body frame,
    +inf cells, a one-row and a one-column matrix."""
    rng = np.random.default_rng(7)
    cases = []
    for n, m in ((1, 9), (9, 1), (2, 2), (30, 12), (12, 30), (40, 40)):
        cost = _random_case(rng, n, m, ties=True)
        cases.append((cost, Band.full(n, m)))
    cost = rng.random((30, 40))
    cost[10:14, :] = np.inf
    cost[10:14, 20:25] = 1.0  # a gate every path must pass
    cases.append((cost, Band.full(30, 40)))
    cases.append(
        (rng.random((30, 40)), Band.from_constraints(30, 40, 0.0, [(0, 7, 0)], open_ends=True))
    )
    cases.append(
        (
            rng.random((30, 40)),
            Band.from_constraints(30, 40, None, [(0, 5, 1), (29, 30, 2)], open_ends=True),
        )
    )
    cases.append(
        (
            rng.random((30, 40)),
            Band.from_constraints(30, 40, 0.05, [(12, 20, 0), (13, 21, 0)], open_ends=True),
        )
    )
    for cost, band in cases:
        n, m = cost.shape
        for ends in (Ends(), Ends(n - 1, m - 1, 0.0), Ends(n // 2, m // 2, 0.3), Ends(3, 9, 1.0)):
            try:
                check_ends(band, ends)
            except ParameterError:
                continue
            total, path = _naive(cost, band, ends)
            if not np.isfinite(total):
                with pytest.raises(ParameterError):
                    align(cost, band, ends)
                continue
            got = align(cost, band, ends)
            assert got.cost == pytest.approx(total, abs=1e-9)
            assert [tuple(c) for c in got.path.tolist()] == path


def test_point_on_first_body_frame_sets_the_start():
    rng = np.random.default_rng(3)
    cost = rng.random((50, 60))
    band = Band.from_constraints(50, 60, 0.4, [(0, 9, 0)], open_ends=True)
    got = align(cost, band, Ends(25, 25, 0.1))
    assert tuple(got.path[0]) == (0, 9)
    with pytest.raises(ParameterError, match="starts at"):
        Band.from_constraints(50, 60, 0.4, [(0, 9, 0)])  # fixed ends: (0, 0) is forced


def test_fixed_limits_equal_the_fixed_solver():
    rng = np.random.default_rng(11)
    a, b = rng.random((80, 4)), rng.random((95, 4))
    band = Band.from_constraints(80, 95, 0.3, [(40, 50, 3)])
    fixed = align_features(a, b, band)
    zero = align_features(a, b, band, ends=Ends(0, 0, 5.0))
    assert fixed.cost == zero.cost
    np.testing.assert_array_equal(fixed.path, zero.path)
    reference, path = naive.dtw_banded(naive.local_cost_matrix(a, b), band.lo, band.hi)[:2]
    assert fixed.cost == pytest.approx(reference)


def test_forced_ends_equal_the_fixed_result():
    """Open ends whose start and end are forced (points at the corners pin the hand
    frame on the first and last body frames; no body frame may stay unmatched) give
    the fixed-end path and cost in the same band, on the matrix and on its transpose."""
    rng = np.random.default_rng(5)
    for _ in range(10):
        n, m = int(rng.integers(20, 70)), int(rng.integers(20, 70))
        cost = _random_case(rng, n, m, ties=bool(rng.integers(0, 2)))
        mid = (n // 2, m // 2, 2)
        pts = [(0, 0, 0), mid, (n - 1, m - 1, 0)]
        fixed = align(cost, Band.from_constraints(n, m, 0.5, pts))
        forced = Band.from_constraints(n, m, 0.5, pts, open_ends=True)
        got = align(cost, forced, Ends(0, m // 2, 0.0))
        assert got.cost == pytest.approx(fixed.cost, abs=1e-12)
        np.testing.assert_array_equal(got.path, fixed.path)
        # transposed, tolerance-only band, a skip cost
        cost_t = np.ascontiguousarray(cost.T)
        corners = [(0, 0, 0), (m - 1, n - 1, 0)]
        fixed_t = align(cost_t, Band.from_constraints(m, n, None, corners))
        forced_t = Band.from_constraints(m, n, None, corners, open_ends=True)
        got_t = align(cost_t, forced_t, Ends(0, n // 2, 0.3))
        assert got_t.cost == pytest.approx(fixed_t.cost, abs=1e-12)
        np.testing.assert_array_equal(got_t.path, fixed_t.path)


def _solves_as_the_reference(solver, cost, band, ends) -> bool:
    """``solver.solve(band, ends)`` gives the reference's cost and an open path of that
    cost (its cells plus ``skip`` per unmatched frame); False (nothing solved) when the
    reference finds no path in ``band``."""
    n, m = len(cost), len(cost[0])
    total, _ = naive.dtw_banded_open(
        cost, band.lo.tolist(), band.hi.tolist(), ends.skip, ends.body, ends.hand
    )
    if not np.isfinite(total):
        return False
    got = solver.solve(band, ends)
    p = got.path
    assert naive.is_open_path(p.tolist(), n, m, ends.body, ends.hand)
    unmatched = int(p[0].sum()) + (n - 1 - int(p[-1, 0])) + (m - 1 - int(p[-1, 1]))
    assert got.cost == pytest.approx(total, abs=1e-8)
    assert naive.path_cost(cost, p.tolist()) + ends.skip * unmatched == pytest.approx(
        total, abs=1e-8
    )
    return True


def test_incremental_open_ends_exact_across_edits():
    rng = np.random.default_rng(2)
    for trial in range(12):
        n, m = int(rng.integers(40, 110)), int(rng.integers(40, 110))
        a, b = rng.random((n, 3)), rng.random((m, 3))
        if trial % 2:
            a, b = np.round(a * 2), np.round(b * 2)
        cost = np.array(naive.local_cost_matrix(a.tolist(), b.tolist()))
        ends = Ends(
            int(rng.integers(0, n // 2)),
            int(rng.integers(0, m // 2)),
            float(rng.choice([0.0, 0.1, 0.3])),
        )
        solver = Aligner(a, b)
        for _ in range(5):
            pts = _points(rng, n, m, int(rng.integers(0, 3)))
            try:
                band = Band.from_constraints(
                    n, m, float(rng.uniform(0.3, 1.0)), pts, open_ends=True
                )
                check_ends(band, ends)
            except ParameterError:
                continue
            _solves_as_the_reference(solver, cost, band, ends)
        # switching back to fixed ends recomputes: the fixed result again
        band = Band.sakoe_chiba(n, m, 0.5)
        assert solver.solve(band).cost == pytest.approx(align_features(a, b, band).cost)


def test_bad_ends_are_one_line_errors():
    with pytest.raises(ParameterError, match="body must be a whole number"):
        Ends(-1, 0, 0.0)
    with pytest.raises(ParameterError, match="skip must be"):
        Ends(0, 0, float("nan"))
    band = Band.from_constraints(30, 40, 0.2, [(0, 9, 0)], open_ends=True)
    with pytest.raises(ParameterError, match="at most 3 hand frames"):
        align(np.zeros((30, 40)), band, Ends(3, 3, 0.0))


def test_incremental_open_ends_exact_when_points_sit_on_the_first_or_last_body_frame():
    """A point on the first or last body frame narrows the band's edge row, where an open
    path starts or ends. The solver that keeps its rows gives the reference path after
    every such edit (it once joined stale rows there: a cheaper path that ended inside
    the matrix, or an error)."""
    rng = np.random.default_rng(7)
    edits = 0
    for _ in range(40):
        n, m = int(rng.integers(20, 80)), int(rng.integers(20, 80))
        a, b = rng.random((n, 3)), rng.random((m, 3))
        cost = np.array(naive.local_cost_matrix(a.tolist(), b.tolist()))
        ends = Ends(n // 2, m // 2, float(rng.choice([0.1, 0.3])))
        solver = Aligner(a, b)
        solver.solve(Band.from_constraints(n, m, 0.3, [], open_ends=True), ends)
        for _ in range(3):
            x = int(rng.choice([0, n - 1]))
            pts = [(x, int(rng.integers(0, m)), int(rng.integers(0, 3)))]
            if rng.integers(0, 2):
                pts = sorted(pts + [(int(rng.integers(1, n - 1)), int(rng.integers(0, m)), 2)])
            try:
                band = Band.from_constraints(n, m, 0.3, pts, open_ends=True)
                check_ends(band, ends)
            except ParameterError:
                continue
            edits += _solves_as_the_reference(solver, cost, band, ends)
    assert edits > 40


def _forward_rows(cost, band, ends):
    """``(backpointers, γ of every band cell, γ(i, m-1) by row)`` of a forward pass over
    every row of ``band`` (``kernels.forward_matrix``)."""
    n, m = cost.shape
    bp = np.empty(band.area, np.uint8)
    gamma = np.empty(band.area)
    last_col = np.full(n, np.inf)
    bad, _ = K.forward_matrix(
        cost, band.lo, band.hi, band.start, 0, n, bp, gamma, 1, ends.array(), last_col,
        np.full(m, np.inf),
    )  # fmt: skip
    assert bad == -1
    return bp, gamma, last_col


def test_join_at_every_row_when_the_first_body_frame_starts_off_column_0():
    """``kernels.join_path`` joins forward rows ``0..J`` and backward rows ``J+1..n-1`` of an
    open-ends band whose first row does not reach column 0 (a matching point on the first
    body frame) at every junction row ``J``, row 0 included: the reference's total and an
    open path of that cost. (It took the matrix width from the reversed band's last row,
    which is row 0: ``lo[0]`` columns short, so it read β of the wrong cells and returned
    paths cheaper than the optimum that ended inside the matrix.)"""
    rng = np.random.default_rng(13)
    checked = 0
    for _ in range(30):
        n, m = int(rng.integers(3, 30)), int(rng.integers(4, 30))
        cost = _random_case(rng, n, m, ties=bool(rng.integers(0, 2)))
        ends = Ends(n // 2, m // 2, float(rng.choice([0.0, 0.1, 0.3])))
        try:
            band = Band.from_constraints(
                n, m, float(rng.uniform(0.2, 1.0)), [(0, int(rng.integers(1, m // 2 + 1)), 0)],
                open_ends=True,
            )  # fmt: skip
            check_ends(band, ends)
        except ParameterError:
            continue
        assert band.lo[0] > 0
        total, _ = _naive(cost, band, ends)
        if not np.isfinite(total):
            continue
        rband = band.reversed()
        bp, gamma, fcol = _forward_rows(cost, band, ends)
        rbp, rgamma, rcol = _forward_rows(np.ascontiguousarray(cost[::-1, ::-1]), rband, ends)
        for J in range(n - 1):
            got, path = K.join_path(
                gamma, bp, band.lo, band.hi, band.start,
                rgamma, rbp, rband.lo, rband.hi, rband.start, J, ends.array(), fcol, rcol,
            )  # fmt: skip
            assert got == pytest.approx(total, abs=1e-9), J
            assert naive.is_open_path(path.tolist(), n, m, ends.body, ends.hand), J
            unmatched = int(path[0].sum()) + (n - 1 - int(path[-1, 0])) + (m - 1 - int(path[-1, 1]))
            assert naive.path_cost(cost, path.tolist()) + ends.skip * unmatched == pytest.approx(
                total, abs=1e-9
            )
            checked += 1
    assert checked > 100


def _visits(path, x: int, y: float, tol: float) -> bool:
    """The path crosses body frame ``x`` within ``y ± tol``."""
    cols = [int(j) for i, j in path if int(i) == x]
    return bool(cols) and min(cols) <= y + tol and max(cols) >= y - tol


@pytest.mark.parametrize("seed", range(3))
def test_start_and_end_limits_of_their_own_exact_in_both_directions(seed):
    """Ends with the end's own limits (``body_end``/``hand_end``): the forward solve and the
    incremental solver (its backward rows read the reversed ends, joined at a row between)
    give the plain reference's path; the reversed ends swap start and end."""
    e = Ends(3, 4, 0.5, 7, 1)
    assert (e.end_body, e.end_hand) == (7, 1) and e.reversed() == Ends(7, 1, 0.5, 3, 4)
    assert Ends(3, 4, 0.5, 3, 4) == Ends(3, 4, 0.5) and Ends(0, 0, 0.0, 0, 0).fixed
    assert list(e.array()) == [0.5, 3.0, 4.0, 7.0, 1.0] and not Ends(0, 0, 0.0, 2).fixed
    rng = np.random.default_rng(100 + seed)
    checked = 0
    for trial in range(30):
        n, m = int(rng.integers(30, 90)), int(rng.integers(30, 90))
        a, b = rng.random((n, 3)), rng.random((m, 3))
        if trial % 2:
            a, b = np.round(a * 2), np.round(b * 2)
        cost = np.array(naive.local_cost_matrix(a.tolist(), b.tolist()))
        ends = Ends(
            *(int(rng.integers(0, k // 2)) for k in (n, m)),
            float(rng.choice([0.0, 0.1, 0.3])),
            *(int(rng.integers(0, k // 2)) for k in (n, m)),
        )
        try:
            band = Band.from_constraints(n, m, float(rng.uniform(0.3, 1.0)), [], open_ends=True)
            check_ends(band, ends)
        except ParameterError:
            continue
        total, path = _naive(cost, band, ends)
        if not np.isfinite(total):
            continue
        for got in (align(cost, band, ends), Aligner(a, b).solve(band, ends)):
            assert got.cost == pytest.approx(total, abs=1e-9)
            assert [tuple(c) for c in got.path.tolist()] == path
        checked += 1
    assert checked > 10


def test_a_point_on_the_hand_takes_first_or_last_frame_pins_that_end():
    """Stranger 14 F1: ``--match 60:0`` started the hand at body frame 102 (the open start
    skipped the point's row, where the band's clip holds); a point whose window reaches the
    last hand frame was skipped at the end likewise. ``ends_through_points`` keeps every
    point's row on the path; without such a point it changes nothing."""
    rng = np.random.default_rng(7)
    n, m = 120, 60
    a, b = rng.random((n, 2)), rng.random((m, 2))
    b[[0, m - 1]] += 2.0  # matching anything to the hand's first and last frames is costly:
    cost = np.array(naive.local_cost_matrix(a.tolist(), b.tolist()))  # a free open end
    # would rather skip the points' rows
    ends = Ends(n // 2, m // 2, 0.1)
    assert ends_through_points(ends, [(40, 20, 2)], n, m) is ends  # nothing to pin
    missed = 0  # cases whose points the unpinned ends skip (the bug, as it was)
    for pts in ([(50, 0, 0)], [(100, 59, 0)], [(30, 1, 3), (90, 59, 0)], [(10, 5, 0), (80, 57, 4)]):
        band = Band.from_constraints(n, m, 0.6, pts, open_ends=True)
        loose = align(cost, band, ends)
        missed += not all(_visits(loose.path.tolist(), *p) for p in pts)
        pinned = ends_through_points(ends, pts, n, m)
        got = align(cost, band, pinned)
        assert all(_visits(got.path.tolist(), *p) for p in pts), (pts, got.path[[0, -1]])
        total, path = _naive(cost, band, pinned)
        assert got.cost == pytest.approx(total) and [tuple(c) for c in got.path.tolist()] == path
        assert Aligner(a, b).solve(band, pinned).cost == pytest.approx(total)
    assert missed >= 2
