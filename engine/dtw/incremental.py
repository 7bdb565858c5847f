"""Incremental DTW: re-solve after a band edit, recomputing only rows that can change.

Used by the app while a person drags matching points::

    from engine.dtw import Aligner, Band

    solver = Aligner(body_features, hand_features, metric="sqeuclidean")
    # or: solver = Aligner.from_cost(cost_matrix)
    first = solver.solve(Band.from_constraints(n, m, 0.3, points))   # full solve
    points[2] = (x, y_new, tol)
    again = solver.solve(Band.from_constraints(n, m, 0.3, points))   # partial re-solve
    solver.last_stats        # what was recomputed, and how long it took
    solver.cumulative_cost() # γ inside the current band (views.BandValues)

``solve(band)`` returns the same ``Alignment`` (path, cost) that
``align``/``align_features`` would give for that band (cost equal up to
floating-point rounding; on exact ties the path may differ, with equal cost).

How rows are reused
-------------------
Forward γ in row ``i`` depends only on band rows ``0..i``; the backward
cost-to-go β (the same recurrence run from ``(n-1, m-1)`` backwards) in row
``i`` depends only on rows ``i..n-1``. The solver keeps both per band cell. An
edit that changes band rows ``r0..r1`` (moving point ``k`` changes the two
segments beside it, rows ``x_{k-1}+1 .. x_{k+1}``) leaves forward rows before
``r0`` and backward rows after ``r1`` valid. The solver computes forward rows
up to a junction row ``J`` and backward rows after it, and joins them at the
cheapest crossing from row ``J`` to row ``J + 1``. The first solve is forward
only; the first edit costs as much as a forward-only re-solve (rows ``r0`` to
the end) and leaves the backward rows after ``r1`` in place, so further drags
of the same point recompute only rows ``r0..r1``.

Memory: about 18 bytes per band cell (γ and β as float64, two byte-sized
backpointers), e.g. 27 MB for 2,000 x 2,000 with a 30 % band. For one-shot
large problems use ``align_features`` (1 byte per cell).

An ``Aligner`` is bound to one cost source; it serialises its calls with a
lock (safe to share between threads, but calls do not run in parallel).
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import numpy as np
from numba.core.dispatcher import Dispatcher

from . import kernels as K
from .align import Alignment, Problem, _check_band, check_total
from .band import Band
from .views import BandValues


@dataclass(frozen=True)
class SolveStats:
    """What the last ``Aligner.solve`` computed.

    ``forward_rows``/``backward_rows`` are half-open row ranges of the
    original problem; ``cells_computed`` counts band cells evaluated;
    ``seconds`` is wall time of the whole call.
    """

    forward_rows: tuple[int, int]
    backward_rows: tuple[int, int]
    cells_computed: int
    cells_in_band: int
    junction_row: int
    seconds: float

    @property
    def fraction(self) -> float:
        """cells_computed / cells_in_band."""
        return self.cells_computed / max(self.cells_in_band, 1)


class _Store:
    """Per-cell γ and backpointers for one direction, grown on demand."""

    def __init__(self):
        self.gamma = np.empty(0, np.float64)
        self.bp = np.empty(0, np.uint8)

    def ensure(self, area: int, keep: int) -> None:
        """Capacity for ``area`` cells, keeping the first ``keep`` entries."""
        if self.gamma.size >= area:
            return
        cap = int(area * 1.25) + 16
        gamma = np.empty(cap, np.float64)
        bp = np.empty(cap, np.uint8)
        gamma[:keep] = self.gamma[:keep]
        bp[:keep] = self.bp[:keep]
        self.gamma, self.bp = gamma, bp


class Aligner:
    """Banded DTW solver that keeps its rows between calls (see module docstring).

    Parameters
    ----------
    a : (n, d) float array
        Body-take features; ``b`` : (m, d) hand-take features.
    metric : str or numba function
        As for ``align_features``.
    """

    def __init__(self, a, b, metric: str | Dispatcher = "sqeuclidean"):
        self._init(Problem.from_features(a, b, metric))

    @classmethod
    def from_cost(cls, cost) -> Aligner:
        """Solver over a precomputed (n, m) local-cost matrix."""
        self = cls.__new__(cls)
        self._init(Problem.from_cost(cost))
        return self

    def _init(self, problem: Problem) -> None:
        self._problem = problem
        self._reverse: Problem | None = None
        self._lock = threading.Lock()
        self.reset()

    def reset(self) -> None:
        """Forget all stored rows (the next solve is a full one)."""
        self._band: Band | None = None
        self._rband: Band | None = None
        self._fwd = _Store()
        self._bwd = _Store()
        self._f_valid = 0  # forward rows [0, f_valid) are valid for self._band
        self._b_valid = self.n  # backward rows [b_valid, n) are valid
        self._last: Alignment | None = None
        self.last_stats: SolveStats | None = None

    @property
    def n(self) -> int:
        """Body frames (rows)."""
        return self._problem.n

    @property
    def m(self) -> int:
        """Hand frames (columns)."""
        return self._problem.m

    @property
    def band(self) -> Band | None:
        """Band of the last solve."""
        return self._band

    def solve(self, band: Band) -> Alignment:
        """Optimal path in ``band``, reusing every row the edit cannot change."""
        _check_band(band, self._problem)
        with self._lock:
            return self._solve(band)

    def cumulative_cost(self) -> BandValues:
        """Forward cumulative cost γ of every cell of the current band.

        Rows the last re-solve left to the backward pass are computed here
        (once) first. Raises ``RuntimeError`` before the first solve.
        """
        with self._lock:
            band = self._band
            if band is None:
                raise RuntimeError("cumulative_cost() needs a solve() first")
            self._forward_rows(band, self._f_valid, band.n)
            return BandValues(band, self._fwd.gamma[: band.area].copy())

    # -- internals -----------------------------------------------------------
    def _solve(self, band: Band) -> Alignment:
        t0 = time.perf_counter()
        n = self.n
        old = self._band
        if old is not None and old == band and self._last is not None:
            self.last_stats = SolveStats(
                (0, 0), (n, n), 0, band.area, n - 1, time.perf_counter() - t0
            )
            return self._last
        if old is None:
            r0, r1 = 0, n - 1
        else:
            changed = np.flatnonzero((old.lo != band.lo) | (old.hi != band.hi))
            r0, r1 = (int(changed[0]), int(changed[-1])) if changed.size else (n, -1)
        f_valid = min(self._f_valid, r0)
        b_valid = max(self._b_valid, r1 + 1)
        # stored rows keep their flat offsets: widths before r0 (forward) and
        # after r1 (backward, counted from the end) did not change
        rband = band.reversed()
        self._band, self._rband, self._last = band, rband, None
        self._f_valid, self._b_valid = f_valid, b_valid

        junction = min(max(r1, f_valid - 1), b_valid - 1)  # any J in [f_valid-1, b_valid-1] works
        cells = self._forward_rows(band, f_valid, junction + 1)
        if junction == n - 1:
            total = self._fwd_total(band)
            path = K.backtrack(self._fwd.bp, band.lo, band.start, n - 1, self.m - 1)
        else:
            cells += self._backward_rows(rband, junction + 1)
            total, path = self._join(band, rband, junction)
        check_total(total)
        path.flags.writeable = False
        self._last = Alignment(path=path, cost=float(total), band=band)
        self.last_stats = SolveStats(
            (f_valid, max(f_valid, junction + 1)),
            (junction + 1, b_valid),
            cells,
            band.area,
            junction,
            time.perf_counter() - t0,
        )
        return self._last

    def _forward_rows(self, band: Band, i0: int, i1: int) -> int:
        """Compute forward rows [i0, i1) into the store; returns cells computed."""
        if i1 <= i0:
            return 0
        self._fwd.ensure(band.area, int(band.start[i0]))
        bad, _ = self._problem.forward(
            band.lo, band.hi, band.start, i0, i1, self._fwd.bp, self._fwd.gamma, True
        )
        if bad >= 0:
            self._f_valid = int(bad)
            raise self._problem.bad_cost_error(int(bad), band)
        self._f_valid = max(self._f_valid, i1)
        return int(band.start[i1] - band.start[i0])

    def _backward_rows(self, rband: Band, first_row: int) -> int:
        """Compute backward rows [first_row, b_valid) (reversed rows n-b_valid .. n-1-first_row)."""
        n = self.n
        r0, r1 = n - self._b_valid, n - first_row
        if r1 <= r0:
            return 0
        if self._reverse is None:
            self._reverse = self._problem.reversed()
        self._bwd.ensure(rband.area, int(rband.start[r0]))
        bad, _ = self._reverse.forward(
            rband.lo, rband.hi, rband.start, r0, r1, self._bwd.bp, self._bwd.gamma, True
        )
        if bad >= 0:
            self._b_valid = n - int(bad)
            raise self._reverse.bad_cost_error(int(bad), rband, reversed_=True)
        self._b_valid = first_row
        return int(rband.start[r1] - rband.start[r0])

    def _fwd_total(self, band: Band) -> float:
        return float(self._fwd.gamma[band.area - 1])  # last cell of the last row is (n-1, m-1)

    def _join(self, band: Band, rband: Band, J: int):
        """Cheapest crossing from row J (forward γ) to row J + 1 (backward β)."""
        n, m = self.n, self.m
        lo_j, hi_j = int(band.lo[J]), int(band.hi[J])
        gamma = self._fwd.gamma[band.start[J] : band.start[J + 1]]
        r = n - 2 - J  # reversed index of row J + 1
        # β of row J + 1 in original column order lo..hi
        beta = self._bwd.gamma[rband.start[r] : rband.start[r + 1]][::-1]
        lo_n, hi_n = int(band.lo[J + 1]), int(band.hi[J + 1])
        cols = np.arange(lo_j, hi_j + 1)
        beta_at = np.full(m + 1, np.inf)
        beta_at[lo_n : hi_n + 1] = beta
        diag = beta_at[cols + 1]
        vert = beta_at[cols]
        use_diag = diag <= vert
        nxt = np.where(use_diag, diag, vert)
        totals = gamma + nxt
        k = int(np.argmin(totals))
        total = float(totals[k])
        j = lo_j + k
        j_next = j + 1 if use_diag[k] else j
        head = K.backtrack(self._fwd.bp, band.lo, band.start, J, j)
        tail = K.backtrack(self._bwd.bp, rband.lo, rband.start, r, m - 1 - j_next)
        tail = np.column_stack((n - 1 - tail[::-1, 0], m - 1 - tail[::-1, 1]))
        return total, np.ascontiguousarray(np.concatenate((head, tail)), dtype=np.int64)
