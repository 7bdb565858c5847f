"""``Aligner`` runs a solve's forward and backward rows on two threads at once
(``PARALLEL_DIRECTIONS``), its edits joining them where each thread gets half the cells:
the same paths, costs and γ as one thread, and a failure on the backward thread reaches
the caller."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from engine.dtw import Aligner, Band, align_features
from engine.dtw.align import Ends

SLACK = 2 * Aligner.GAMMA_EVERY + 4  # rows a pass may redo to resume from a stored row


def _pair(parallel: bool, make):
    solver = make()
    solver.PARALLEL_DIRECTIONS = parallel
    solver.PARALLEL_MIN_CELLS = 0  # small test bands take the threaded path too
    return solver


def _edits(n, m):
    """Bands of a drag sequence: a lone point dragged (every row changes), then points
    beside it (two segments change), an early point, a late one."""
    points = [[n // 2, m // 2, 0]]
    yield points
    for dy in (7, -5, 9):
        points = [[n // 2, m // 2 + dy, 0]]
        yield points
    points = [[n // 5, m // 5, 1], [n // 2, m // 2, 0], [4 * n // 5, 4 * m // 5, 2]]
    yield points
    for k, dy in ((1, 6), (1, -4), (0, 3), (2, -6), (2, 4)):
        points = [list(p) for p in points]
        points[k][1] += dy
        yield points


@pytest.mark.parametrize("ends", [None, Ends(40, 40, 0.4)])
@pytest.mark.parametrize("source", ["features", "cost"])
def test_two_threads_give_one_threads_results(source, ends):
    rng = np.random.default_rng(5)
    n, m = 320, 300
    a, b = rng.standard_normal((n, 3)), rng.standard_normal((m, 3))
    cost = rng.random((n, m))
    make = (lambda: Aligner(a, b)) if source == "features" else (lambda: Aligner.from_cost(cost))
    one, two = _pair(False, make), _pair(True, make)
    open_ends = ends is not None
    balanced = 0
    for step, points in enumerate(_edits(n, m)):
        band = Band.from_constraints(n, m, 0.3, points, open_ends=open_ends)
        r1, r2 = one.solve(band, ends), two.solve(band, ends)
        # random costs: no exact ties, so the junction (the only difference) cannot
        # change the path; the totals add the same costs in another order
        assert r2.path.tolist() == r1.path.tolist(), step
        assert r2.cost == pytest.approx(r1.cost, rel=1e-12), step
        s1, s2 = one.last_stats, two.last_stats
        forward = int(band.start[s2.forward_rows[1]] - band.start[s2.forward_rows[0]])
        backward = int(band.start[s2.backward_rows[1]] - band.start[s2.backward_rows[0]])
        # the edit waits for the longer side only: never more cells than one thread's
        # solve (the junction moves, so a later edit may compute more cells in all)
        assert max(forward, backward) <= s1.cells_computed + SLACK * m, step
        if 0 < step < 4 and s2.junction_row < n - 1:
            # a lone point dragged: its rows (all but a few at the start) recomputed,
            # half on each side of the junction
            balanced += 1
            assert abs(forward - backward) <= SLACK * m, (step, s2)
            assert s1.junction_row != s2.junction_row  # one thread: J at the last third
        if source == "features" and ends is None:
            fresh = align_features(a, b, band)
            assert r2.cost == pytest.approx(fresh.cost, rel=1e-12)
    assert balanced >= (1 if open_ends else 0)  # fixed ends: a lone point moves row 0 too
    np.testing.assert_allclose(
        two.cumulative_cost().dense(), one.cumulative_cost().dense(), rtol=1e-12
    )


def _threads_of_backward(solver) -> list[str]:
    names: list[str] = []
    backward = solver._backward

    def spy(*args):
        names.append(threading.current_thread().name)
        return backward(*args)

    solver._backward = spy
    return names


def test_backward_rows_run_on_a_second_thread_while_forward_rows_run():
    rng = np.random.default_rng(7)
    n = m = 240
    solver = _pair(True, lambda: Aligner.from_cost(rng.random((n, m))))
    names = _threads_of_backward(solver)
    solver.solve(Band.from_constraints(n, m, 0.3, [[n // 2, m // 2, 0]]))  # full solve + suffix
    solver.solve(Band.from_constraints(n, m, 0.3, [[n // 2, m // 2 + 5, 0]]))  # an edit
    assert len(names) == 2
    assert all(name != threading.current_thread().name for name in names), names
    serial = _pair(False, lambda: Aligner.from_cost(rng.random((n, m))))
    names = _threads_of_backward(serial)
    serial.solve(Band.from_constraints(n, m, 0.3, [[n // 2, m // 2, 0]]))
    assert names == [threading.current_thread().name]


def test_a_failure_on_the_backward_thread_reaches_the_caller():
    rng = np.random.default_rng(11)
    n = m = 200
    solver = _pair(True, lambda: Aligner.from_cost(rng.random((n, m))))
    solver.solve(Band.from_constraints(n, m, 0.3, [[n // 2, m // 2, 0]]))

    def broken(*args):
        raise MemoryError("backward rows")

    solver._backward = broken
    with pytest.raises(MemoryError, match="backward rows"):
        solver.solve(Band.from_constraints(n, m, 0.3, [[n // 2, m // 2 + 4, 0]]))


def test_an_edit_with_few_rows_on_each_side_stays_on_one_thread():
    """The second thread is for edits with many cells on both sides of the junction: an
    edit of a large band that recomputes a few rows does not wait for a thread to start
    (on a loaded machine, longer than its rows take); the junction is the same either way."""
    rng = np.random.default_rng(13)
    n = m = 240
    cost = rng.random((n, m))
    solver = _pair(True, lambda: Aligner.from_cost(cost))
    reference = _pair(True, lambda: Aligner.from_cost(cost))
    reference.PARALLEL_MIN_CELLS = 0
    names = _threads_of_backward(solver)
    lone = Band.from_constraints(n, m, 0.3, [[n // 2, m // 2, 0]], open_ends=True)
    solver.PARALLEL_MIN_CELLS = lone.area // 2
    points = [[n // 5, m // 5, 0], [n // 2, m // 2, 0], [3 * n // 4, 3 * m // 4, 0]]
    late = [*points, [9 * n // 10, 9 * m // 10, 0]]
    nudged = [*points, [9 * n // 10, 9 * m // 10 + 3, 0]]
    ends = Ends(skip=0.5)
    for k, pts in enumerate(([[n // 2, m // 2, 0]], [[n // 2, m // 2 + 6, 0]], late, nudged)):
        band = Band.from_constraints(n, m, 0.3, pts, open_ends=True)
        before = len(names)
        got, want = solver.solve(band, ends), reference.solve(band, ends)
        assert got.path.tolist() == want.path.tolist(), k
        assert solver.last_stats.junction_row == reference.last_stats.junction_row, k
        if k == 1:  # the lone point dragged: every row, half on each side, two threads
            assert names[before:] and names[-1] != threading.current_thread().name
        if k == 3:  # the last point nudged: a quarter of the rows, one thread
            assert names[before:] == [threading.current_thread().name], names[before:]
