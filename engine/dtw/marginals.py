"""Min-marginal costs: the cheapest path through every band cell (docs/method.md, "Trust").

For a banded DTW problem with local costs ``D`` and cumulative costs γ (forward,
from ``(0, 0)``) and β (backward, the same recurrence run on both sequences
reversed, from ``(n-1, m-1)``), the cheapest monotone path that is forced
through cell ``(i, j)`` costs::

    T(i, j) = γ(i, j) + β(i, j) - D(i, j)        (D is counted in both γ and β)

With open ends (:class:`engine.dtw.Ends`) γ carries the skip cost of the frames left
out at the start and β those at the end, so ``T`` is still the total of the cheapest
path through the cell and ``T*`` is the best open end's total.

``T`` equals the optimal total ``T*`` on the optimal path and grows as a cell
moves away from every cheap path. ``T - T*`` (the *extra cost* of a cell) is
what the splice's uncertainty is built on (:mod:`engine.splice.uncertainty`): a
row whose cells far from the chosen column have small extra cost is a row where
the alignment could move at little price.

Cost: three sweeps of the band (forward, backward, and the forward again block by block)
plus the row reductions; γ is held for one block of rows at a time both ways
(``TRUST_BLOCK_CELLS`` cells, 17 bytes each) and at the last row of every block, so the
memory does not grow with the band.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.base.errors import check_cancelled
from engine.base.tolerances import TRUST_BLOCK_CELLS

from . import kernels as K
from ._config import njit_cached
from .align import FIXED, Ends, Problem, check_total
from .band import Band

#: rows of the Python subtraction loop between two looks at ``cancelled`` (:func:`row_spread`)
CANCEL_ROWS = 1024


@dataclass(frozen=True, eq=False)
class RowSpread:
    """Per-row summaries of the extra cost ``T - T*`` over a band.

    total : float, the optimal total ``T*``
    spread : (n,) float, columns; the root-mean-square distance of the row's cells from
        ``centre`` weighted by ``exp(-(T - T_i) / temperature)``, ``T_i`` the row's cheapest
        through-cost (``T*`` on every row the optimal path visits)
    reach : (n,) float, columns; the largest ``|j - centre|`` with ``T - T_i <= margin``
    """

    total: float
    spread: np.ndarray
    reach: np.ndarray


def _blocks(band: Band, cells: int) -> list[tuple[int, int]]:
    """Row ranges ``[r0, r1)`` of the band holding about ``cells`` cells each (one row
    at least)."""
    out = []
    r0 = 0
    while r0 < band.n:
        r1 = int(np.searchsorted(band.start, band.start[r0] + cells, side="right")) - 1
        r1 = min(max(r1, r0 + 1), band.n)
        out.append((r0, r1))
        r0 = r1
    return out


def _sweep(problem: Problem, band: Band, r0: int, r1: int, before, e, last_col, last_row):
    """γ of band rows ``r0..r1-1`` from γ of row ``r0 - 1`` (``before``; None when
    ``r0 == 0``), in a buffer of those rows only.

    Returns ``(gamma, start)``: row ``i``'s cells are ``gamma[start[i] : start[i + 1]]``
    for ``r0 - 1 <= i < r1`` (``start`` is ``band.start`` shifted; other rows' offsets are
    meaningless). ``last_col`` (n,) receives γ of the last column of these rows,
    ``last_row`` γ of row ``r1 - 1`` (the kernels' convention)."""
    base = int(band.start[r0 - 1]) if r0 > 0 else 0
    start = band.start - base
    start.setflags(write=False)  # as band.start: the kernels' compiled (read-only) signatures
    size = int(band.start[r1]) - base
    gamma = np.empty(size, np.float64)
    bp = np.empty(size, np.uint8)  # not read: the kernels write backpointers
    if r0 > 0:
        gamma[: len(before)] = before
    bad, _ = problem.forward(band.lo, band.hi, start, r0, r1, bp, gamma, 1, e, last_col, last_row)
    if bad >= 0:
        raise problem.bad_cost_error(int(bad), band)
    return gamma, start


def _row_of(gamma, start, i: int) -> np.ndarray:
    return gamma[start[i] : start[i + 1]].copy()


@njit_cached()
def _row_spread(
    gf,
    gb,
    lo,
    hi,
    start,
    rlo,
    rstart,
    i0,
    i1,
    n,
    m,
    centre,
    total,
    temperature,
    margin,
    spread,
    reach,
):
    """Rows ``i0..i1-1`` of ``spread``/``reach`` from ``gf`` = γ - D (forward problem) and
    ``gb`` = γ of the reversed problem on the reversed band (``rlo``, ``rstart``): cell
    ``(i, j)`` is reversed cell ``(n-1-i, m-1-j)``, so ``T(i, j) = gf + gb``."""
    for i in range(i0, i1):
        ri = n - 1 - i
        c = centre[i]
        # the row's cheapest through-cost: T* on rows the optimal path visits; higher on
        # rows an open-ended path leaves unmatched (their spread is then about the cheapest
        # way to match that row at all)
        best = np.inf
        for j in range(lo[i], hi[i] + 1):
            t = gf[start[i] + j - lo[i]] + gb[rstart[ri] + m - 1 - j - rlo[ri]]
            if t < best:
                best = t
        if best < total:
            best = total
        wsum = 0.0
        dsum = 0.0
        far = 0.0
        for j in range(lo[i], hi[i] + 1):
            rj = m - 1 - j
            t = gf[start[i] + j - lo[i]] + gb[rstart[ri] + rj - rlo[ri]]
            extra = t - best
            if extra < 0.0:
                extra = 0.0
            d = j - c
            if extra <= margin and abs(d) > far:
                far = abs(d)
            if temperature > 0.0:
                w = np.exp(-extra / temperature)
                wsum += w
                dsum += w * d * d
        spread[i] = np.sqrt(dsum / wsum) if wsum > 0.0 else 0.0
        reach[i] = far


@njit_cached()
def _subtract_band(values, cost, lo, hi, start, i0, i1):
    """``values`` (flat cells of band rows ``i0..i1-1``) minus the cost matrix's cells, in
    place."""
    for i in range(i0, i1):
        for j in range(lo[i], hi[i] + 1):
            values[start[i] + j - lo[i]] -= cost[i, j]


def row_spread(
    a,
    b,
    band: Band,
    metric,
    centre,
    temperature: float,
    margin: float,
    ends: Ends = FIXED,
    costs=None,
    block_cells: int = TRUST_BLOCK_CELLS,
    cancelled=None,
) -> RowSpread:
    """Per-row spread of the cheap cells around ``centre`` for features ``a``, ``b``.

    a : (n, d) float body feature rows; b : (m, d) float hand feature rows
    band : Band over (n, m); metric : a registered metric name or numba function
    centre : (n,) float, the column each row is measured from (the chosen warp)
    temperature : float > 0, cost units; the weight of a cell is ``exp(-extra / temperature)``
    margin : float >= 0, cost units; ``reach`` counts cells with ``extra <= margin``
    ends : engine.dtw.Ends, the open ends of the pass (the same limits hold at both ends,
        so the backward pass on the reversed problem uses them as they are)
    costs : (n, m) float64 ``metric(a[i], b[j])`` of every cell when already tabulated (the
        app's pass-1 table), read instead of evaluating the metric: the same values, without
        a metric call per cell and a Python call per row
    block_cells : band cells whose γ is held at once (both ways, 17 bytes a cell); the
        result does not depend on it (the forward γ is kept at block boundaries and made
        again block by block while the backward pass runs: three sweeps instead of two)
    cancelled : a callable or None; when it returns True between the steps (each block's
        sweep, every ``CANCEL_ROWS`` rows of the subtraction) ``engine.base.errors.Cancelled``
        is raised: the app gives up an assessment that a newer edit has made stale
    """
    if costs is not None:
        problem = Problem.from_cost(costs)
        if (problem.n, problem.m) != (len(a), len(b)):
            raise ValueError(f"costs: expected {(len(a), len(b))}, got {(problem.n, problem.m)}")
    else:
        problem = Problem.from_features(a, b, metric)
    band.check_fits((problem.n, problem.m), problem.what)
    n, m = band.n, band.m
    e = ends.array()
    blocks = _blocks(band, max(1, int(block_cells)))
    # forward: γ of every band row, kept only at the last row of each block (checkpoints)
    last_col = np.empty(n)
    last_row = np.empty(m)
    checkpoints: dict[int, np.ndarray] = {}
    before = None
    for r0, r1 in blocks:
        check_cancelled(cancelled)
        gamma, start = _sweep(problem, band, r0, r1, before, e, last_col, last_row)
        before = checkpoints[r1 - 1] = _row_of(gamma, start, r1 - 1)
        del gamma
    total, _, _ = K.best_end(last_row, last_col, band.lo, band.hi, e, n - 1)
    check_total(total)
    total = float(total)
    # backward: the reversed problem's rows in order are the forward blocks from the last;
    # each block's forward γ is made again from its checkpoint and the pair reduced
    rproblem = problem.reversed()
    rband = band.reversed()
    re = ends.reversed().array()  # the reversed problem starts at this one's end
    rlast_col = np.empty(n)
    rlast_row = np.empty(m)
    spread = np.empty(n)
    reach = np.empty(n)
    centre = np.ascontiguousarray(np.broadcast_to(np.asarray(centre, np.float64), (n,)))
    rbefore = None
    for r0, r1 in reversed(blocks):
        check_cancelled(cancelled)
        gb, rstart = _sweep(rproblem, rband, n - r1, n - r0, rbefore, re, rlast_col, rlast_row)
        rbefore = _row_of(gb, rstart, n - r0 - 1)
        gf, start = _sweep(
            problem, band, r0, r1, checkpoints.pop(r0 - 1, None), e, last_col, last_row
        )
        check_cancelled(cancelled)
        # γf - D: subtract each cell's local cost once, row by row (no n x m array)
        if problem.kind == "matrix":
            _subtract_band(gf, problem.cost, band.lo, band.hi, start, r0, r1)
        else:
            for i in range(r0, r1):
                if i % CANCEL_ROWS == 0:
                    check_cancelled(cancelled)
                lo, hi = int(band.lo[i]), int(band.hi[i])
                s = int(start[i])
                gf[s : s + hi - lo + 1] -= problem.cost_row(i, lo, hi)
        _row_spread(
            gf,
            gb,
            band.lo,
            band.hi,
            start,
            rband.lo,
            rstart,
            r0,
            r1,
            n,
            m,
            centre,
            total,
            float(temperature),
            float(margin),
            spread,
            reach,
        )
        del gf, gb
    return RowSpread(total=total, spread=spread, reach=reach)


def _gamma(problem: Problem, band: Band, ends: Ends) -> tuple[np.ndarray, float]:
    """γ for every band cell (flat, ``band.start`` offsets) and the optimal total.

    With open ends γ includes the skip cost of the frames left out before the cell."""
    bp = np.empty(band.area, np.uint8)
    gamma = np.empty(band.area, np.float64)
    last_col = np.empty(band.n)
    last_row = np.empty(band.m)
    e = ends.array()
    bad, _ = problem.forward(
        band.lo, band.hi, band.start, 0, band.n, bp, gamma, 1, e, last_col, last_row
    )
    if bad >= 0:
        raise problem.bad_cost_error(int(bad), band)
    total, _, _ = K.best_end(last_row, last_col, band.lo, band.hi, e, band.n - 1)
    check_total(total)
    return gamma, float(total)


def near_optimal_rows(a, b, band: Band, metric, margin: float, ends: Ends = FIXED, per_cell=False):
    """Column range of each row's cells whose cheapest path costs at most ``T* + margin``.

    Returns ``(first, last, total, path)``: ``(n,)`` int64 arrays (``-1`` in both on a row
    with no such cell), ``T*`` and the optimal path (``align_features``' own: the same
    forward pass and backtrack). ``per_cell``: ``margin`` is per path cell (the margin
    used is ``margin * T* / len(path)``). ``T(i, j)`` is computed without the local costs,
    as ``γ(i, j)`` plus the cheapest way on from the cell: the smallest β of its
    successors in the band, or, on the last row or column, the skip cost of ending there
    (open ends). Cost: two forward passes keeping γ of every cell (17 bytes per cell
    while it runs).
    """
    problem = Problem.from_features(a, b, metric)
    band.check_fits((problem.n, problem.m), problem.what)
    bp = np.empty(band.area, np.uint8)
    gf = np.empty(band.area, np.float64)
    last_col = np.empty(band.n)
    last_row = np.empty(band.m)
    e = ends.array()
    bad, _ = problem.forward(
        band.lo, band.hi, band.start, 0, band.n, bp, gf, 1, e, last_col, last_row
    )
    if bad >= 0:
        raise problem.bad_cost_error(int(bad), band)
    total, i_end, j_end = K.best_end(last_row, last_col, band.lo, band.hi, e, band.n - 1)
    check_total(total)
    path = K.backtrack(bp, band.lo, band.start, i_end, j_end)
    del bp
    if per_cell:
        margin = float(margin) * float(total) / len(path)
    rband = band.reversed()
    gb, _ = _gamma(problem.reversed(), rband, ends.reversed())
    n = band.n
    first = np.full(n, -1, np.int64)
    last = np.full(n, -1, np.int64)
    _near_rows(
        gf,
        gb,
        band.lo,
        band.hi,
        band.start,
        rband.lo,
        rband.start,
        band.m,
        e,
        float(total) + float(margin),
        first,
        last,
    )
    path.flags.writeable = False
    return first, last, float(total), path


@njit_cached()
def _near_rows(gf, gb, lo, hi, start, rlo, rstart, m, ends, limit, first, last):
    """Rows of ``first``/``last`` for :func:`near_optimal_rows`; β of cell ``(i, j)`` is the
    reversed problem's γ at ``(n-1-i, m-1-j)``."""
    n = lo.shape[0]
    skip = ends[0]
    max_body = int(ends[3])  # the end's limits: β's open end
    max_hand = int(ends[4])
    for i in range(n):
        ri = n - 1 - i
        for j in range(lo[i], hi[i] + 1):
            on = np.inf
            if i + 1 < n:
                r1 = ri - 1
                if lo[i + 1] <= j <= hi[i + 1]:
                    on = min(on, gb[rstart[r1] + m - 1 - j - rlo[r1]])
                if lo[i + 1] <= j + 1 <= hi[i + 1]:
                    on = min(on, gb[rstart[r1] + m - 2 - j - rlo[r1]])
            if j + 1 <= hi[i]:
                on = min(on, gb[rstart[ri] + m - 2 - j - rlo[ri]])
            if i == n - 1 and m - 1 - j <= max_hand:
                on = min(on, skip * (m - 1 - j))
            if j == m - 1 and n - 1 - i <= max_body:
                on = min(on, skip * (n - 1 - i))
            if gf[start[i] + j - lo[i]] + on <= limit:
                if first[i] < 0:
                    first[i] = j
                last[i] = j
