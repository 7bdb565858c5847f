"""An exact forward-only re-solve keeps the rows that settle (issue 13, drag31).

With costs and open-end skips on ``engine.dtw.fixed``'s grid, an edit's forward rows stop
at the first row whose γ is the old row's plus one constant; the later rows are the old
ones plus that constant (``Aligner._forward_settling``). The result must be a fresh
solve's: path (ties included), cost, and every stored γ.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from engine.base.errors import ParameterError
from engine.dtw import Aligner, Band, align, fixed
from engine.dtw.align import Ends


def _band(n, m, points, is_open):
    return Band.from_constraints(n, m, 0.6, points, open_ends=is_open)


def _check_edit(solver, cost, band, ends):
    """The solver's forward-only re-solve equals a fresh solve: path, cost, every γ."""
    got = solver.solve(band, ends, forward_only=True)
    full = align(cost, band, ends)
    assert np.array_equal(got.path, full.path)
    assert got.cost == full.cost
    fresh = Aligner.from_cost(cost)
    fresh.solve(band, ends)
    # the edited solver keeps γ of every row (cumulative_cost() was asked before the
    # edits), so this compares the kept rows, shifted by the constant, not recomputed ones
    assert np.array_equal(solver.cumulative_cost().values, fresh.cumulative_cost().values)
    return solver.last_stats


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 2**31 - 1),
    n=st.integers(24, 90),
    m=st.integers(24, 90),
    skip=st.sampled_from([None, 0.0, 0.5, 1.25]),
    moves=st.lists(st.integers(-5, 5), min_size=2, max_size=5),
)
def test_settled_re_solves_equal_fresh_solves(seed, n, m, skip, moves):
    """An earlier point dragged before a fixed later one (the rows after the later point
    keep their band): every edit gives the fresh solve's path, cost and γ."""
    rng = np.random.default_rng(seed)
    cost = np.round(rng.random((n, m)) * 3)  # whole numbers: many ties
    ends = Ends() if skip is None else Ends(n // 4, m // 4, skip)
    x1, x2 = n // 3, (2 * n) // 3
    y1, y2 = round(x1 * m / n), round(x2 * m / n)
    solver = Aligner.from_cost(cost)
    try:
        solver.solve(_band(n, m, [(x1, y1, 1), (x2, y2, 1)], not ends.fixed), ends)
    except ParameterError:
        return
    solver.cumulative_cost()  # from now on γ of every row is kept
    for dy in moves:
        points = [(x1, int(np.clip(y1 + dy, 1, y2 - 1)), 1), (x2, y2, 1)]
        try:
            band = _band(n, m, points, not ends.fixed)
            align(cost, band, ends)
        except ParameterError:
            continue
        stats = _check_edit(solver, cost, band, ends)
        assert stats.settled_row <= n


def test_edits_settle_and_compute_fewer_rows():
    """A point dragged up and down before a later point (tolerance 0: every path to a later
    row crosses it): the re-solves stop at the later point and still give the fresh
    solve's result."""
    rng = np.random.default_rng(7)
    n, m = 400, 300
    # whole-number costs in a diagonal valley, as sign costs are along a take
    i, j = np.mgrid[0:n, 0:m]
    cost = np.round(np.abs(j - i * m / n) / 8) + rng.integers(0, 2, (n, m))
    ends = Ends(40, 30, 1.5)
    solver = Aligner.from_cost(cost)
    later = (260, 195, 0)
    solver.solve(_band(n, m, [(150, 112, 0), later], True), ends)
    solver.cumulative_cost()
    for dy in (3, -3, 3, 6, -2):
        band = _band(n, m, [(150, 112 + dy, 0), later], True)
        stats = _check_edit(solver, cost, band, ends)
        assert stats.settled_row <= later[0] + 1 + 16  # chunks of 8, then 16 rows
        f0, settled = stats.forward_rows
        assert settled == stats.settled_row
        assert stats.cells_computed == band.start[settled] - band.start[f0] < band.area


def test_costs_off_the_grid_are_recomputed_to_the_end():
    """Costs that are not whole multiples of the quantum (float sums may round): no row is
    kept after the edited ones, every row to the end is computed."""
    rng = np.random.default_rng(1)
    n, m = 120, 100
    cost = rng.random((n, m))
    assert not fixed.is_on_grid(cost)
    solver = Aligner.from_cost(cost)
    band = Band.from_constraints(n, m, 1.0, [(50, 40, 0)])
    solver.solve(band)
    band = Band.from_constraints(n, m, 1.0, [(50, 43, 0)])
    got = solver.solve(band, forward_only=True)
    assert solver.last_stats.settled_row == n
    assert np.array_equal(got.path, align(cost, band).path)


def test_fixed_point_grid():
    assert fixed.is_on_grid([0.0, 3.0, -2.5, np.inf, fixed.QUANTUM * 7])
    assert not fixed.is_on_grid([0.1])
    assert not fixed.is_on_grid([fixed.LIMIT * 2])
    v = fixed.on_grid(0.1)
    assert fixed.is_on_grid(v) and abs(v - 0.1) <= fixed.QUANTUM / 2


@pytest.mark.parametrize("skip", [0.5, 0.3])
def test_an_open_end_skip_off_the_grid_is_not_settled(skip):
    """An open-end skip of 0.3 is not a multiple of the quantum: no settling (0.5 is)."""
    n, m = 200, 160
    cost = np.round(np.random.default_rng(2).random((n, m)) * 2)
    ends = Ends(20, 16, skip)
    solver = Aligner.from_cost(cost)
    later = (150, 120, 0)
    solver.solve(_band(n, m, [(80, 64, 0), later], True), ends)
    band = _band(n, m, [(80, 67, 0), later], True)
    got = solver.solve(band, ends, forward_only=True)
    assert np.array_equal(got.path, align(cost, band, ends).path)
    assert (solver.last_stats.settled_row < n) == (skip == 0.5)
