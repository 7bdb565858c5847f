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

Cost: two forward passes with γ kept for every band cell (8 bytes per cell per
direction, float64) plus the row reductions; about two solves' time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.base.errors import check_cancelled

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


@njit_cached()
def _row_spread(
    gf, gb, lo, hi, start, rlo, rstart, n, m, centre, total, temperature, margin, spread, reach
):
    """Rows of ``spread``/``reach`` from ``gf`` = γ - D (forward problem) and ``gb`` = γ of
    the reversed problem on the reversed band (``rlo``, ``rstart``): cell ``(i, j)`` is
    reversed cell ``(n-1-i, m-1-j)``, so ``T(i, j) = gf + gb``."""
    for i in range(n):
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
def _subtract_band(values, cost, lo, hi, start):
    """``values`` (flat band cells) minus the cost matrix's cells, in place."""
    for i in range(lo.shape[0]):
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
    cancelled : a callable or None; when it returns True between the steps (each γ sweep,
        every ``CANCEL_ROWS`` rows of the subtraction) ``engine.base.errors.Cancelled``
        is raised: the app gives up an assessment that a newer edit has made stale
    """
    if costs is not None:
        problem = Problem.from_cost(costs)
        if (problem.n, problem.m) != (len(a), len(b)):
            raise ValueError(f"costs: expected {(len(a), len(b))}, got {(problem.n, problem.m)}")
    else:
        problem = Problem.from_features(a, b, metric)
    band.check_fits((problem.n, problem.m), problem.what)
    check_cancelled(cancelled)
    gf, total = _gamma(problem, band, ends)
    check_cancelled(cancelled)
    # γf - D: subtract each cell's local cost once, row by row (no n x m array)
    if problem.kind == "matrix":
        _subtract_band(gf, problem.cost, band.lo, band.hi, band.start)
    else:
        for i in range(band.n):
            if i % CANCEL_ROWS == 0:
                check_cancelled(cancelled)
            lo, hi = int(band.lo[i]), int(band.hi[i])
            s = int(band.start[i])
            gf[s : s + hi - lo + 1] -= problem.cost_row(i, lo, hi)
    rband = band.reversed()
    check_cancelled(cancelled)
    gb, _ = _gamma(problem.reversed(), rband, ends)
    check_cancelled(cancelled)
    n, m = band.n, band.m
    spread = np.empty(n)
    reach = np.empty(n)
    centre = np.ascontiguousarray(np.broadcast_to(np.asarray(centre, np.float64), (n,)))
    _row_spread(
        gf,
        gb,
        band.lo,
        band.hi,
        band.start,
        rband.lo,
        rband.start,
        n,
        m,
        centre,
        total,
        float(temperature),
        float(margin),
        spread,
        reach,
    )
    return RowSpread(total=total, spread=spread, reach=reach)
