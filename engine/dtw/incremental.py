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
``i`` depends only on rows ``i..n-1``. The solver keeps both between calls. An
edit that changes band rows ``r0..r1`` (moving point ``k`` changes the two
segments beside it, rows ``x_{k-1}+1 .. x_{k+1}``) leaves forward rows before
``r0`` and backward rows after ``r1`` valid. The solver computes forward rows
up to a junction row ``J`` and backward rows after it, and joins them at the
cheapest crossing from row ``J`` to row ``J + 1``; only the rows between the
last valid forward row and the first valid backward row are computed, so the
cost of an edit does not depend on where ``J`` lies, but the next edit does.

* A full solve (the first one, or an edit that leaves no row reusable) runs
  forward over every row, so its path is exactly ``align_features``'s, and
  then also computes the backward rows of the band's last third by cells
  (``SUFFIX_SHARE``): 1.33x the cells of a forward-only solve. The first
  edit of any point whose edited rows reach into that last third (every
  point in the last third) then recomputes only the two segments beside it.
* After an edit, ``J`` is the row inside the edited rows ``r0-1 .. r1``
  nearest the start of that last third: further drags of the same point
  recompute only its two segments, and the junction stays where a later
  first edit of a point in the last third finds it. Editing a point in the
  first part and then one in the last third costs, once, the forward rows
  between them (they depend on the earlier edit; no scheme can avoid that
  without recomputing them on every drag of the early point).
* On bands of ``PARALLEL_MIN_CELLS`` or more (``PARALLEL_DIRECTIONS``) the forward
  and the backward rows of a solve run on two threads at once, and an edit's ``J``
  (still inside the edited rows) is the row that splits the rows to compute into
  two halves of equal cells instead: a lone point's drag changes the band in every
  row (its two segments are the whole take), and then waits for half of them.
* A forward-only re-solve (``solve(forward_only=True)``: a fresh solve's path, ties
  included) recomputes forward rows from the first edited row. When every local cost and
  the open-end skip are whole multiples of ``fixed.QUANTUM`` (the pass-1 sign costs;
  ``Problem.exact_costs``), γ sums are exact, and once a row after the edited ones has
  γ = old γ + C in every cell (one constant C), every later row is the old row + C with
  the same backpointers: the solve stops there and keeps them (``SETTLE``,
  ``_forward_settling``; ``SolveStats.settled_row``). A lone point dragged in a narrow
  band (the fine pass 1 around the coarse path) then costs the rows near it only.
* γ (and β) are stored for every ``GAMMA_EVERY``-th row and the last row of
  each pass only; a pass resumes from the nearest stored row (fewer than
  ``GAMMA_EVERY`` rows recomputed). Backpointers are kept for every cell.
  ``cumulative_cost()`` computes the missing γ rows once and switches the
  solver to keeping γ of every row (and, from then on, ``J`` to the end
  of the edited rows, since γ is needed up to the last row anyway).

Memory: one byte per band cell and direction for backpointers plus γ/β of
every 8th row, i.e. about 3-4 bytes per cell resident (18 once
``cumulative_cost()`` is used; address space is reserved for 18 either way),
e.g. 27 MB at most for 2,000 x 2,000 with a 30 % band. The γ stores are
anonymous memory in 4 kB pages (``_sparse_floats``): only the pages of the
rows kept become resident (numpy's huge pages made the whole store resident).
For one-shot large problems use ``align_features`` (1 byte per cell).

An ``Aligner`` is bound to one cost source; it serialises its calls with a
lock (safe to share between threads, but calls do not run in parallel).
"""

from __future__ import annotations

import mmap
import threading
import time
from dataclasses import dataclass

import numpy as np
from numba.core.dispatcher import Dispatcher

from engine.base import tolerances as T

from . import fixed
from . import kernels as K
from .align import FIXED, Alignment, Ends, Problem, as_ends, check_band, check_ends, check_total
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
    #: an edit's forward rows stopped here: rows from it on are the old ones plus a
    #: constant (``Aligner._forward_settling``); ``n`` when every row was computed
    settled_row: int = -1

    @property
    def fraction(self) -> float:
        """cells_computed / cells_in_band."""
        return self.cells_computed / max(self.cells_in_band, 1)


def _sparse_floats(count: int) -> np.ndarray:
    """``count`` float64 in anonymous memory that becomes resident page by page as it
    is written, never in huge pages.

    γ is stored for every ``GAMMA_EVERY``-th row only, at the band's flat offsets:
    the array spans the band, but only the pages of rows written are resident.
    numpy asks the kernel for 2 MB huge pages on large arrays, which made every
    page resident (about 8 bytes per band cell, 460 MB more per app session at
    10k x 4k); plain 4 kB pages keep it near 1 byte per cell.
    """
    size = max(count, 1) * 8
    buf = mmap.mmap(-1, size, flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS)
    if hasattr(mmap, "MADV_NOHUGEPAGE"):
        try:
            buf.madvise(mmap.MADV_NOHUGEPAGE)
        except OSError:  # kernels without transparent huge pages
            pass
    return np.frombuffer(buf, dtype=np.float64, count=max(count, 1))


class _Side:
    """Stored rows of one direction (forward γ, or backward β in reversed row order).

    Backpointers are kept for every computed cell, γ for the rows ``has``
    marks (``kernels._keep``). Rows ``0..valid-1`` (in this direction's own
    order) are valid for the current band.
    """

    def __init__(self, n: int, m: int):
        self.gamma = np.empty(0, np.float64)
        self.bp = np.empty(0, np.uint8)
        self.has = np.zeros(n, bool)
        self.valid = 0
        self.last_col = np.full(n, np.inf)  # γ(i, m-1) per row (open ends, kernels.best_end)
        self.last_row = np.full(m, np.inf)  # γ of the last row computed

    def ensure(self, area: int, start: np.ndarray) -> None:
        """Capacity for ``area`` cells, keeping the stored rows below ``valid``
        (band offsets ``start``, unchanged for those rows)."""
        if self.gamma.size >= area:
            return
        cap = int(area * 1.25) + 16
        gamma = _sparse_floats(cap)
        bp = np.empty(cap, np.uint8)
        keep = int(start[self.valid])
        bp[:keep] = self.bp[:keep]
        for r in np.flatnonzero(self.has[: self.valid]):  # touch only the stored rows
            gamma[start[r] : start[r + 1]] = self.gamma[start[r] : start[r + 1]]
        self.gamma, self.bp = gamma, bp

    def resume_row(self, row: int) -> int:
        """First row to compute so that rows up to ``row`` follow a stored one."""
        stored = np.flatnonzero(self.has[:row])
        return int(stored[-1]) + 1 if stored.size else 0


class Aligner:
    """Banded DTW solver that keeps its rows between calls (see module docstring).

    Parameters
    ----------
    a : (n, d) float array
        Body-take features; ``b`` : (m, d) hand-take features.
    metric : str or numba function
        As for ``align_features``.
    """

    #: share of the band's cells, at its end, whose backward rows a full solve
    #: also computes (see the module docstring)
    SUFFIX_SHARE = 1.0 / 3.0
    #: γ/β are stored for every GAMMA_EVERY-th row (and the last row of each
    #: pass); a pass resumes from the nearest stored row, recomputing fewer
    #: than GAMMA_EVERY rows. ``cumulative_cost()`` switches to every row.
    GAMMA_EVERY = 8
    #: forward and backward rows of one solve run on two threads at once (only the wall
    #: time changes), and an edit's junction splits the rows to compute into halves of
    #: equal cells (the junction only decides how exact ties break); below
    #: PARALLEL_MIN_CELLS band cells (``engine.base.tolerances``) a thread costs more
    #: than it saves
    PARALLEL_DIRECTIONS = True
    PARALLEL_MIN_CELLS = T.PARALLEL_MIN_CELLS
    #: a forward-only edit of exact costs (``fixed``) stops at the first settled row
    SETTLE = True

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
        self._fwd = _Side(self.n, self.m)  # forward rows [0, fwd.valid) valid for self._band
        self._bwd = _Side(self.n, self.m)  # backward rows [n - bwd.valid, n) are valid
        self._ends: Ends = FIXED
        self._every = self.GAMMA_EVERY  # 1 once cumulative_cost() was asked for
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
    def stores_every_row(self) -> bool:
        """True once ``cumulative_cost()`` was used (γ of every row: 8 bytes per cell)."""
        return self._every == 1

    @property
    def band(self) -> Band | None:
        """Band of the last solve."""
        return self._band

    def solve(self, band: Band, ends: Ends | None = None, forward_only: bool = False) -> Alignment:
        """Optimal path in ``band``, reusing every row the edit cannot change.

        ``ends`` (``engine.dtw.Ends``, default fixed): open ends; a change of ends
        recomputes every row (the virtual start row and column change).

        ``forward_only``: the path a full forward solve (``align_features``) gives, ties
        included: forward rows are recomputed from the first edited row to the last row
        and the path is traced back from the end (no backward rows, no junction, whose
        crossing may break exact ties another way). An edit then costs the band's cells
        from its first edited row on, not only its two segments."""
        check_band(band, self._problem)
        ends = as_ends(ends)
        check_ends(band, ends)
        with self._lock:
            if ends != self._ends:
                every = self._every
                self.reset()
                self._every = every
                self._ends = ends
            return self._solve(band, forward_only)

    def cumulative_cost(self) -> BandValues:
        """Forward cumulative cost γ of every cell of the current band.

        Rows whose γ is not stored (solves keep γ of every
        ``GAMMA_EVERY``-th row only) or that the last re-solve left to the
        backward pass are computed here first; from then on this solver keeps
        γ of every row, so after further edits only the rows that changed are
        recomputed. Raises ``RuntimeError`` before the first solve.
        """
        with self._lock:
            band = self._band
            if band is None:
                raise RuntimeError("cumulative_cost() needs a solve() first")
            self._every = 1
            fwd = self._fwd
            missing = np.flatnonzero(~fwd.has[: fwd.valid])
            first = int(missing[0]) if missing.size else fwd.valid
            self._compute(self._problem, fwd, band, first, band.n)
            return BandValues(band, fwd.gamma[: band.area].copy())

    # -- internals -----------------------------------------------------------
    def _solve(self, band: Band, forward_only: bool = False) -> Alignment:
        t0 = time.perf_counter()
        n = self.n
        old = self._band
        if old is None:
            r0, r1 = 0, n - 1
        else:
            changed = np.flatnonzero((old.lo != band.lo) | (old.hi != band.hi))
            r0, r1 = (int(changed[0]), int(changed[-1])) if changed.size else (n, -1)
            if r0 > r1 and self._last is not None:  # same band (Band.__eq__): nothing to do
                self.last_stats = SolveStats(
                    (0, 0), (n, n), 0, band.area, n - 1, time.perf_counter() - t0
                )
                return self._last
        fwd, bwd = self._fwd, self._bwd
        complete = old is not None and fwd.valid >= n  # forward rows of every old row
        # stored rows keep their flat offsets: widths before r0 (forward) and
        # after r1 (backward, counted from the end) did not change
        fwd.valid = min(fwd.valid, r0)
        bwd.valid = min(bwd.valid, n - 1 - r1)
        f_valid, b_valid = fwd.valid, n - bwd.valid
        rband = band.reversed()
        self._band, self._rband, self._last = band, rband, None

        split = self._split_row(band)
        full = f_valid == 0 and b_valid >= n  # nothing reusable: forward over every row
        if full or forward_only:
            junction = n - 1
        else:
            # any J with J + 1 between f_valid and b_valid needs the same rows;
            # prefer one inside the edited rows (further drags of the same point
            # stay minimal) and there the one nearest the split row (or, once
            # cumulative_cost() is in use, the end of the edited rows: γ is
            # needed up to the last row anyway)
            pref = split if self._every > 1 else n - 1
            if self._every > 1 and f_valid < b_valid and self._halves(band):
                # rows on both sides of J are computed, on two threads at once: the J
                # that gives each thread half the cells (an edit waits for the longer side)
                mid = (int(band.start[f_valid]) + int(band.start[b_valid])) // 2
                pref = int(np.searchsorted(band.start, mid, side="left")) - 1
            if r0 <= r1:
                pref = min(max(pref, r0 - 1), r1)
            lo_j = min(f_valid, b_valid) - 1
            hi_j = max(f_valid, b_valid) - 1
            junction = max(0, min(max(pref, lo_j), hi_j))
        f0 = fwd.resume_row(min(f_valid, junction + 1))
        forward = (f0, max(f0, junction + 1))
        backward = (junction + 1, junction + 1)
        settled = n
        if forward_only and complete and r1 < n - 1 and self._exact():
            # rows after the first settled one are the old rows plus a constant (fixed.py)
            cells, settled = self._forward_settling(band, old, f0, r1 + 1)
            total, i_end, j_end = K.best_end(
                self._fwd_last_row(band), fwd.last_col, band.lo, band.hi, self._ends.array(), n - 1
            )
            path = K.backtrack(fwd.bp, band.lo, band.start, i_end, j_end)
            forward = (f0, settled)
        elif junction == n - 1:
            # a full solve also computes the backward rows of the last third (cheap first
            # edits there): they do not depend on the forward rows, so both run at once
            suffix = full and split < n - 1 and not forward_only
            cells, back = self._both_directions(
                band, f0, junction + 1, rband, split + 1 if suffix else None
            )
            total, i_end, j_end = K.best_end(
                self._fwd_last_row(band), fwd.last_col, band.lo, band.hi, self._ends.array(), n - 1
            )
            path = K.backtrack(fwd.bp, band.lo, band.start, i_end, j_end)
            if suffix:
                cells += back
                backward = (split + 1, n)
        else:
            cells, back = self._both_directions(band, f0, junction + 1, rband, junction + 1)
            cells += back
            backward = (junction + 1, self._last_backward_end)
            total, path = self._join(band, rband, junction)
        check_total(total)
        path.flags.writeable = False
        self._last = Alignment(path=path, cost=float(total), band=band, ends=self._ends)
        self.last_stats = SolveStats(
            forward, backward, cells, band.area, junction, time.perf_counter() - t0, settled
        )
        return self._last

    def _exact(self) -> bool:
        """Sums of this problem's costs and open-end skips are exact (``fixed``): an
        edit's forward rows may stop at the first settled row."""
        return self.SETTLE and self._problem.exact_costs() and fixed.is_on_grid(self._ends.skip)

    def _forward_settling(self, band: Band, old: Band, f0: int, tail: int) -> tuple[int, int]:
        """Forward rows from ``f0`` after an edit whose band rows ``tail..n-1`` are the old
        band's, stopping at the first settled row; ``(cells computed, rows computed up to)``.

        The old forward rows from ``tail`` on (every one valid for ``old``) move to the
        new band's offsets first (backpointers by one memmove, the stored γ rows by
        ``kernels.move_rows``). Rows are then computed in chunks ending at a row whose
        old γ is stored (chunks of 8, 16, 32, ... rows); when a chunk's last row ``s``
        has γ = old γ + C in every cell (C one constant; exact: ``fixed``), every later
        row is the old row + C with the same backpointers (the recurrence adds and
        compares only), so they are kept: stored γ and the last column's γ get + C.
        Rows whose open-start edge γ(i, -1) is finite (``Ends.body``) do not shift with
        C and are always computed. The result is a fresh forward solve's, ties included."""
        n = self.n
        side = self._fwd
        delta = int(band.start[tail]) - int(old.start[tail])
        old_bp, old_gamma = side.bp, side.gamma
        kept = tail + np.flatnonzero(side.has[tail:n])  # old stored rows, unchanged band
        old_bp, old_gamma = side.bp, side.gamma
        side.ensure(band.area, band.start)  # may reallocate (keeps rows below valid)
        a0, a1 = int(old.start[tail]), int(old.area)
        side.bp[a0 + delta : a1 + delta] = old_bp[a0:a1]  # a memmove (ranges may overlap)
        if delta != 0 or side.gamma is not old_gamma:
            K.move_rows(
                old_gamma, side.gamma, side.has, band.lo, band.hi, old.start, band.start,
                tail, n, 0.0,
            )  # fmt: skip
        # candidates: old stored rows after which no row has a finite open-start edge
        edge = np.flatnonzero((band.lo == 0) & (np.arange(n) + 1 <= self._ends.body))
        first = max(tail, int(edge[-1]) if edge.size else 0)
        cands = kept[kept >= first]
        problem = self._problem
        i, cells, step, target = f0, 0, self.GAMMA_EVERY, first
        while True:
            k = int(np.searchsorted(cands, target))
            if k >= cands.size or cands[k] >= n - 1:
                return cells + self._compute(problem, side, band, i, n), n
            s = int(cands[k])
            off, w = int(band.start[s]), int(band.hi[s] - band.lo[s] + 1)
            before = side.gamma[off : off + w].copy()
            cells += self._compute(problem, side, band, i, s + 1)
            shift = _constant_shift(side.gamma[off : off + w], before)
            if shift is not None:
                if shift != 0.0:
                    K.move_rows(
                        side.gamma, side.gamma, side.has, band.lo, band.hi, band.start,
                        band.start, s + 1, n, shift,
                    )  # fmt: skip
                    side.last_col[s + 1 : n] += shift
                side.valid = n  # ``has`` of the later rows is the old one
                return cells, s + 1
            i, step = s + 1, 2 * step
            target = s + step

    def _split_row(self, band: Band) -> int:
        """Last row before the band's final ``SUFFIX_SHARE`` of cells (0..n-1)."""
        target = band.area * (1.0 - self.SUFFIX_SHARE)
        first_of_suffix = int(np.searchsorted(band.start, target, side="left"))
        return min(max(first_of_suffix - 1, 0), band.n - 1)

    def _reversed_problem(self) -> Problem:
        if self._reverse is None:
            self._reverse = self._problem.reversed()
        return self._reverse

    def _halves(self, band: Band) -> bool:
        """An edit of ``band`` joins its rows where each direction gets half the cells
        (from ``PARALLEL_MIN_CELLS`` band cells on); the junction decides how exact ties
        break, so it depends on the band only, not on whether a thread is used."""
        return self.PARALLEL_DIRECTIONS and band.area >= self.PARALLEL_MIN_CELLS

    def _parallel(self, forward_cells: int, backward_cells: int) -> bool:
        """Forward and backward rows of a solve run on two threads: both directions have
        at least half ``PARALLEL_MIN_CELLS`` cells to compute in this call (an edit of a
        large band that recomputes a few rows on each side would wait longer for the
        thread to start, on a loaded machine, than for its rows)."""
        return (
            self.PARALLEL_DIRECTIONS
            and 2 * min(forward_cells, backward_cells) >= self.PARALLEL_MIN_CELLS
        )

    def _both_directions(
        self, band: Band, f0: int, f1: int, rband: Band, first_backward: int | None
    ) -> tuple[int, int]:
        """Forward rows ``[f0, f1)`` and, unless ``first_backward`` is None, backward rows
        ``first_backward..n-1`` (``_backward``); (forward cells, backward cells).

        The two directions share no data (their own ``_Side``, the reversed problem), and
        the kernels release the GIL: with ``PARALLEL_DIRECTIONS`` and work on both sides
        the backward rows run on a second thread meanwhile, so an edit whose rows lie on
        both sides of the junction waits for the longer side only."""
        if first_backward is None:
            return self._compute(self._problem, self._fwd, band, f0, f1), 0
        backward_rows = self.n - first_backward
        r0 = self._bwd.resume_row(min(self._bwd.valid, backward_rows))
        backward_cells = int(rband.start[backward_rows] - rband.start[r0])
        forward_cells = int(band.start[f1] - band.start[f0]) if f1 > f0 else 0
        if not self._parallel(forward_cells, backward_cells) or self._bwd.valid >= backward_rows:
            cells = self._compute(self._problem, self._fwd, band, f0, f1)
            return cells, self._backward(rband, first_backward)
        self._reversed_problem()  # made here, not on both threads
        result: dict = {}

        def run_backward():
            try:
                result["cells"] = self._backward(rband, first_backward)
            except BaseException as exc:  # re-raised on the calling thread
                result["error"] = exc

        worker = threading.Thread(target=run_backward, name="hs-dtw-backward", daemon=True)
        worker.start()
        try:
            cells = self._compute(self._problem, self._fwd, band, f0, f1)
        finally:
            worker.join()
        if "error" in result:
            raise result["error"]
        return cells, result["cells"]

    def _backward(self, rband: Band, first_row: int) -> int:
        """Make backward rows ``first_row..n-1`` valid with β of ``first_row`` stored."""
        n = self.n
        bwd = self._bwd
        target = n - first_row  # reversed rows [0, target) needed, the last one stored
        r0 = bwd.resume_row(min(bwd.valid, target))
        self._last_backward_end = n - r0
        return self._compute(self._reversed_problem(), bwd, rband, r0, target)

    def _compute(self, problem: Problem, side: _Side, band: Band, i0: int, i1: int) -> int:
        """Rows [i0, i1) of one direction (its own row order); returns cells computed.

        Needs row ``i0 - 1`` stored (``side.resume_row``). Afterwards rows up to
        ``max(side.valid, i1)`` are valid and row ``i1 - 1`` is stored.
        """
        if i1 <= i0:
            return 0
        side.ensure(band.area, band.start)
        every = self._every
        bad, _ = problem.forward(
            band.lo,
            band.hi,
            band.start,
            i0,
            i1,
            side.bp,
            side.gamma,
            every,
            # the reversed problem starts at this one's end (Ends.reversed)
            (self._ends if problem is self._problem else self._ends.reversed()).array(),
            side.last_col,
            side.last_row,
        )
        if bad >= 0:
            side.valid = min(side.valid, i0)
            raise problem.bad_cost_error(int(bad), band, reversed_=problem is not self._problem)
        if every > 1:
            side.has[i0:i1] = False
            side.has[-(-i0 // every) * every : i1 : every] = True
        else:
            side.has[i0:i1] = True
        side.has[i1 - 1] = True
        side.valid = max(side.valid, i1)
        return int(band.start[i1] - band.start[i0])

    def _fwd_last_row(self, band: Band) -> np.ndarray:
        """γ of row n-1 by column (valid inside its band row; the last row is always stored)."""
        row = np.full(self.m, np.inf)
        i = band.n - 1
        w = int(band.hi[i] - band.lo[i] + 1)
        row[band.lo[i] : band.hi[i] + 1] = self._fwd.gamma[band.start[i] : band.start[i] + w]
        return row

    def _join(self, band: Band, rband: Band, J: int):
        """Cheapest crossing from row J (forward γ) to row J + 1 (backward β)."""
        fwd, bwd = self._fwd, self._bwd
        return K.join_path(
            fwd.gamma, fwd.bp, band.lo, band.hi, band.start,
            bwd.gamma, bwd.bp, rband.lo, rband.hi, rband.start, J,
            self._ends.array(), fwd.last_col, bwd.last_col,
        )  # fmt: skip


def _constant_shift(new: np.ndarray, old: np.ndarray) -> float | None:
    """C when ``new`` = ``old`` + C in every cell (the same cells infinite, every γ
    below ``fixed.LIMIT / 4``), else None."""
    finite = np.isfinite(old)
    if not finite.any() or not np.array_equal(finite, np.isfinite(new)):
        return None
    a, b = new[finite], old[finite]
    if max(np.abs(a).max(), np.abs(b).max()) >= fixed.LIMIT / 4:
        return None
    d = a - b
    c = d[0]
    return float(c) if np.all(d == c) else None
