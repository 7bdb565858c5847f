"""Multi-resolution pass 1: a coarse solve at a capped frame rate guiding a narrow exact one.

Pass 1's sign-cost DTW ([M] eq. 6) costs the W1 band's cells: on a 2-minute pair at
120 fps about 40 M of them. Its features are signs of derivatives smoothed over 0.2 s, so
they change at most a few times per 0.1 s; at 120 fps neighbouring frames mostly carry the
same codes. Here pass 1 runs in two steps (docs/method.md §2, *Multi-resolution pass 1*):

1. **Coarse**: both takes' pass-1 rows decimated by ``k`` (every ``k``-th frame,
   ``k = constraints.pass1_decimation(fps)``: at most ``tolerances.PASS1_RATE_CAP_HZ``):
   the full-rate signs of those frames, the eq.-7 windows made from the coarse frames
   (``metrics.decimate_phase_rows``), then DTW in the same band at the
   coarse size (same width fraction, open-end room and unmatched limits rounded up), with
   the matching points on the coarse grid, tolerances rounded outward
   (``constraints.coarse_points``). ``k**2`` fewer cells.
2. **Fine**: the exact full-rate pass 1 on the cells within
   ``tolerances.PASS1_FINE_RADIUS_S`` seconds (Chebyshev) of the coarse path's fine cells
   (:func:`band_around_coarse`), intersected with the W1 band and the matching points'
   clips (so a point with tolerance 0 is passed exactly, at full rate); where the fine
   path runs along an edge of that strip which the W1 band does not have, the strip is
   widened there and the fine pass solved again (:func:`widen_where_pinched`).

Where the coarse problem cannot be built (points that the rounding brings into conflict)
or the narrow band holds no path for the ends, pass 1 falls back to the full-rate band
(``CoarsePass.fallback`` says why). Takes at or below the cap (``k = 1``) never come here.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from engine.base import tolerances as T
from engine.base.errors import ParameterError
from engine.dtw import Band, Ends, ends_through_points
from engine.dtw import constraints as C

#: pass 2 directly around the upsampled coarse path (no fine pass 1) when False; measured
#: in benchmarks/RESULTS.md (*Multi-resolution pass 1*): the fine pass is kept
FINE_PASS = True


@dataclass
class CoarseRows:
    """Pass-1 rows of both takes at the coarse rate.

    k : int >= 2, body frames per coarse frame (coarse frame ``r`` = fine frame ``r k``)
    n, m : coarse rows and columns (``ceil(n_fine / k)``, ``ceil(m_fine / k)``)
    fps : coarse rate (body fps / k)
    rows : (a, b) rows of the ``splice_phase`` metric on the coarse grid
    """

    k: int
    n: int
    m: int
    fps: float
    rows: tuple[np.ndarray, np.ndarray]
    chance: float | None = None


@dataclass
class CoarsePass:
    """The coarse solve of one pass 1 (kept on ``PassResult.coarse``).

    path : (k, 2) coarse cells; band : its Band; solver : Aligner or None (incremental
    re-solves); ends : its Ends; k : decimation; cells : coarse band cells; radius : the
    fine band's radius (fine frames); fine_cells : the fine band's cells; seconds : the
    coarse solve's wall time; fallback : None, or why pass 1 ran on the whole W1 band;
    fine_band : the full-rate band pass 1 solved last (the W1 band after a fallback);
    near : whether it also holds the near-optimal coarse cells (:func:`near_optimal_cells`);
    rounds : how many times the fine band was widened where the fine path ran along its
    edge (:func:`widen_where_pinched`); solved_cells : band cells of every fine solve
    together (an upper bound of the cells computed: a re-solve by an ``Aligner`` reuses
    the rows before the first widened one).
    """

    path: np.ndarray
    band: Band
    solver: object
    ends: Ends
    k: int
    cells: int
    radius: int
    fine_cells: int
    seconds: float
    fallback: str | None = None
    fine_band: Band | None = None
    near: bool = False
    rounds: int = 0
    solved_cells: int = 0


def coarse_limits(limits: tuple[int, int], k: int, n_c: int, m_c: int) -> tuple[int, int]:
    """Unmatched-end limits on the coarse grid, rounded up (never fewer frames than the
    fine limits allow), below each take's coarse length."""
    body = min(int(math.ceil(limits[0] / k)), n_c - 1)
    hand = min(int(math.ceil(limits[1] / k)), m_c - 1)
    return max(body, 0), max(hand, 0)


def coarse_band(rows: CoarseRows, band1: Band, points) -> tuple[Band, list]:
    """The pass-1 band on the coarse grid: the envelope of the full-rate band ``band1``
    (W1, points' clips, open-end room) on the coarse grid, :data:`COARSE_MARGIN` columns
    wider on each side, cut to the coarse points' clips (``constraints.coarse_points``).

    Coarse row ``r`` stands for the fine rows nearest it (``coarse_index``); its columns
    are the coarse columns of every cell of those rows, so the coarse band holds the
    coarse cell of every fine band cell (away from the points' own rows, whose fine clip
    holds one fine row), and every allowed crossing of a point."""
    k, n_c, m_c = rows.k, rows.n, rows.m
    pts_c = C.coarse_points(points, k, n_c, m_c)
    r = np.minimum(C.coarse_index(np.arange(band1.n), k), n_c - 1)
    lo = np.full(n_c, m_c - 1, np.int64)
    hi = np.zeros(n_c, np.int64)
    np.minimum.at(lo, r, np.minimum(C.coarse_index(band1.lo, k), m_c - 1))
    np.maximum.at(hi, r, np.minimum(C.coarse_index(band1.hi, k), m_c - 1))
    lo = np.maximum(lo - COARSE_MARGIN, 0)
    hi = np.minimum(hi + COARSE_MARGIN, m_c - 1)
    band = Band(lo, hi, m_c, open_ends=band1.open_ends)
    if pts_c:
        band = band.intersect(Band.from_constraints(n_c, m_c, None, pts_c, band1.open_ends))
    return band, pts_c


#: coarse columns added on each side of the coarse band (the coarse path may step
#: between the envelope's edges of neighbouring coarse rows)
COARSE_MARGIN = 1


def band_around_coarse(path_c: np.ndarray, k: int, n: int, m: int, radius: int, is_open: bool):
    """Fine band of the cells within ``radius`` fine frames (Chebyshev) of the fine cells
    the coarse path's cells stand for (coarse cell ``(r, c)``: fine rows ``r k .. r k + k - 1``,
    columns ``c k .. c k + k - 1``); rows before its first or after its last coarse row
    take the range of its end cell (open ends, as ``Band.around_path``)."""
    p = np.asarray(path_c, np.int64)
    n_c = int(math.ceil(n / k))
    first = np.full(n_c, np.iinfo(np.int64).max, np.int64)
    last = np.full(n_c, -1, np.int64)
    np.minimum.at(first, p[:, 0], p[:, 1])
    np.maximum.at(last, p[:, 0], p[:, 1])
    r0, r1 = int(p[0, 0]), int(p[-1, 0])
    first[:r0], last[:r0] = p[0, 1], p[0, 1]
    first[r1 + 1 :], last[r1 + 1 :] = p[-1, 1], p[-1, 1]
    rows = np.arange(n)
    f = first[rows // k] * k
    g = np.minimum(last[rows // k] * k + k - 1, m - 1)
    r = int(radius)
    lo = np.maximum(f[np.maximum(rows - r, 0)] - r, 0)
    hi = np.minimum(g[np.minimum(rows + r, n - 1)] + r, m - 1)
    return Band(lo, hi, m, open_ends=is_open)


#: the fine path must keep this many fine frames (Chebyshev) from every edge of the fine
#: band that is not an edge of the W1 band; where it comes closer, the band is widened
#: there and pass 1 solved again (:func:`widen_where_pinched`)
EDGE_CLEARANCE = 1


def widen_where_pinched(path, band_f: Band, band1: Band, grow: int, is_open: bool):
    """The fine band widened where ``path`` (its optimum) comes within
    :data:`EDGE_CLEARANCE` frames of an edge that ``band1`` (the W1 band with the points'
    clips) does not have; None when it nowhere does.

    Rows whose path neighbourhood leaves ``band_f`` are *pinched*; in every row within
    ``grow`` rows of a pinched one the band takes in the cells within ``grow`` frames of
    the path (inside ``band1``), and the rows before (after) it as much of the left
    (right) edge as a path into those cells needs (a path never moves back).

    Why this gives the full-rate optimum where the coarse path strays: the optimum in
    the narrow band is the optimum of every path inside it, so a better path inside
    ``band1`` must leave the narrow band. When the optimum of the narrow band runs along
    its edge, a better path just outside is likely (the edge is what stops it), and the
    band grows there; when it keeps clear of every edge, no path within
    ``EDGE_CLEARANCE`` frames of it is better, but a better one that leaves and rejoins
    it farther away is not excluded (only the whole W1 band would show it)."""
    n, m = band_f.n, band_f.m
    d = EDGE_CLEARANCE
    near = Band.around_path(path, n, m, d, open_ends=is_open)
    need_lo = np.maximum(near.lo, band1.lo)
    need_hi = np.minimum(near.hi, band1.hi)
    pinched = (need_lo < band_f.lo) | (need_hi > band_f.hi)
    if not pinched.any():
        return None
    rows = np.flatnonzero(pinched)
    mark = np.zeros(n + 1, np.int64)  # rows within ``grow`` of a pinched row
    np.add.at(mark, np.maximum(rows - grow, 0), 1)
    np.add.at(mark, np.minimum(rows + grow + 1, n), -1)
    mark = np.cumsum(mark[:n]) > 0
    around = Band.around_path(path, n, m, grow, open_ends=is_open)
    lo = np.where(mark, np.minimum(band_f.lo, np.maximum(around.lo, band1.lo)), band_f.lo)
    hi = np.where(mark, np.maximum(band_f.hi, np.minimum(around.hi, band1.hi)), band_f.hi)
    lo = np.minimum.accumulate(lo[::-1])[::-1]  # reachable: earlier rows start no later
    hi = np.maximum.accumulate(hi)
    return Band(lo, hi, m, open_ends=band_f.open_ends).intersect(band1)


def near_optimal_cells(rows: CoarseRows, metric: str, band_c: Band, ends_c: Ends):
    """``(first, last)`` coarse columns per coarse row of the cells whose cheapest coarse
    path costs at most ``tolerances.PASS1_NEAR_STEPS`` mean path cells more than the
    coarse optimum (``engine.dtw.marginals.near_optimal_rows``): the other alignments
    the coarse signs nearly tie with, which the fine pass also looks at."""
    return _near_solve(rows, metric, band_c, ends_c)[1]


def _near_solve(rows: CoarseRows, metric: str, band_c: Band, ends_c: Ends):
    """``(coarse Alignment, (first, last))`` of :func:`near_optimal_cells`."""
    from engine.dtw.align import Alignment
    from engine.dtw.marginals import near_optimal_rows

    first, last, total, path = near_optimal_rows(
        *rows.rows, band_c, metric, T.PASS1_NEAR_STEPS, ends_c, per_cell=True
    )
    return Alignment(path=path, cost=total, band=band_c, ends=ends_c), (first, last)


def with_cells(band: Band, cells, k: int, radius: int) -> Band:
    """``band`` and the fine cells within ``radius`` fine frames (Chebyshev) of the fine
    cells that the coarse cells ``cells = (first, last)`` (column range per coarse row,
    ``-1`` where none) stand for (coarse cell ``(r, c)``: fine rows ``r k .. r k + k - 1``,
    columns ``c k .. c k + k - 1``)."""
    from scipy.ndimage import maximum_filter1d, minimum_filter1d

    first, last = cells
    n, m = band.n, band.m
    rc = np.minimum(np.arange(n) // k, len(first) - 1)
    some = last[rc] >= 0
    f = np.where(some, first[rc] * k, m)
    g = np.where(some, np.minimum(last[rc] * k + k - 1, m - 1), -1)
    size = 2 * int(radius) + 1
    lo = minimum_filter1d(f, size, mode="nearest")
    hi = maximum_filter1d(g, size, mode="nearest")
    near = hi >= 0  # rows within ``radius`` of a row with such cells
    lo = np.where(near, np.maximum(np.minimum(band.lo, lo - radius), 0), band.lo)
    hi = np.where(near, np.minimum(np.maximum(band.hi, hi + radius), m - 1), band.hi)
    return Band(lo, hi, m, open_ends=band.open_ends)


def upsample_path(path_c: np.ndarray, k: int, n: int, m: int, is_open: bool) -> np.ndarray:
    """A monotone, continuous fine path through the fine cells ``(r k, c k)`` of the coarse
    path (diagonal steps first between them); fixed ends run on to ``(n-1, m-1)``, open ends
    to the last row or column when the coarse path ends on its last row or column."""
    p = np.asarray(path_c, np.int64) * k
    p[:, 0] = np.minimum(p[:, 0], n - 1)
    p[:, 1] = np.minimum(p[:, 1], m - 1)
    end_i, end_j = int(p[-1, 0]), int(p[-1, 1])
    n_c, m_c = int(math.ceil(n / k)), int(math.ceil(m / k))
    last = np.asarray(path_c[-1])
    if not is_open or last[0] == n_c - 1:
        end_i = n - 1
    if not is_open or last[1] == m_c - 1:
        end_j = m - 1
    targets = np.vstack([p, [[end_i, end_j]]])
    out = [targets[0]]
    for a, b in zip(targets[:-1], targets[1:], strict=True):
        di, dj = int(b[0] - a[0]), int(b[1] - a[1])
        if di == 0 and dj == 0:
            continue
        d = min(di, dj)
        steps = np.zeros((di + dj - d, 2), np.int64)
        steps[:d] = 1
        steps[d : d + di - d, 0] = 1
        steps[d + di - d :, 1] = 1
        out.append(a + np.cumsum(steps, axis=0))
    return np.vstack(out).astype(np.int64)


def solve(
    fine_rows,
    rows: CoarseRows,
    band1: Band,
    width: float,
    points,
    is_open: bool,
    fine_limits,
    ends1: Ends,
    coarse_skip: float,
    solve_fn,
    metric: str,
    previous=None,
    fine_solver=None,
    incremental: bool = False,
    exact: bool = False,
    fps: float = 0.0,
):
    """Multi-resolution pass 1: ``(Alignment, fine solver, CoarsePass)``.

    ``solve_fn(rows, metric, band, solver, incremental, ends, exact)`` is the pipeline's
    one-pass solve; ``previous``: the last ``CoarsePass`` of the same features (its
    solver re-solves only the coarse rows an edit changes); ``band1``: the full-rate W1
    band with the points' clips (the fine band is cut to it)."""
    n, m = band1.n, band1.m
    t0 = time.perf_counter()
    radius = max(int(math.ceil(T.PASS1_FINE_RADIUS_S * fps)), rows.k)
    try:
        band_c, pts_c = coarse_band(rows, band1, points)
        ends_c = Ends()
        if is_open:
            lim = coarse_limits(fine_limits, rows.k, rows.n, rows.m)
            ends_c = ends_through_points(Ends(lim[0], lim[1], coarse_skip), pts_c, rows.n, rows.m)
        solver_c = previous.solver if previous is not None else None
        near = None
        if band1.area >= T.PASS1_NEAR_MIN_CELLS and solver_c is None and not incremental:
            # one forward pass gives the coarse path (the one-shot solve's) and γ for the
            # near-optimal cells
            al_c, near = _near_solve(rows, metric, band_c, ends_c)
        else:
            al_c, solver_c = solve_fn(
                rows.rows, metric, band_c, solver_c, incremental, ends_c, exact
            )
            if band1.area >= T.PASS1_NEAR_MIN_CELLS:
                near = near_optimal_cells(rows, metric, band_c, ends_c)
    except ParameterError as err:
        al, solver = solve_fn(fine_rows, metric, band1, fine_solver, incremental, ends1, exact)
        empty = np.zeros((0, 2), np.int64)
        info = CoarsePass(empty, band1, None, ends1, rows.k, 0, 0, band1.area, 0.0, str(err), band1)
        return al, solver, info
    path_c = np.asarray(al_c.path)
    t1 = time.perf_counter()
    fallback = None
    rounds, solved = 0, 0
    try:
        band_f = band_around_coarse(path_c, rows.k, n, m, radius, is_open)
        if near is not None:
            band_f = with_cells(band_f, near, rows.k, rows.k)
        band_f = band_f.intersect(band1)
        if FINE_PASS:
            al, solver = solve_fn(fine_rows, metric, band_f, fine_solver, incremental, ends1, exact)
            solved = band_f.area
            # widen the strip where the fine path runs along its edge, and solve again,
            # until the path keeps EDGE_CLEARANCE frames from every edge the W1 band does
            # not have (docs/method.md §2, *Multi-resolution pass 1*)
            grow = radius
            while True:
                wider = widen_where_pinched(al.path, band_f, band1, grow, is_open)
                if wider is None:
                    break
                band_f, grow, rounds = wider, 2 * grow, rounds + 1
                al, solver = solve_fn(fine_rows, metric, band_f, solver, incremental, ends1, exact)
                solved += band_f.area
        else:
            al, solver = None, None
    except ParameterError as err:  # the narrow band misses the ends or the points' clips
        fallback = str(err)
        band_f = band1
        al, solver = solve_fn(fine_rows, metric, band1, fine_solver, incremental, ends1, exact)
        solved = band1.area
    info = CoarsePass(
        path=path_c,
        band=band_c,
        solver=solver_c,
        ends=ends_c,
        k=rows.k,
        cells=band_c.area,
        radius=radius,
        fine_cells=band_f.area,
        seconds=t1 - t0,
        fallback=fallback,
        fine_band=band_f,
        near=near is not None,
        rounds=rounds,
        solved_cells=solved,
    )
    if al is None:  # no fine pass: the upsampled coarse path stands for pass 1
        al = _upsampled_alignment(path_c, rows.k, band_f, ends1, is_open, fine_rows, metric)
    return al, solver, info


def _upsampled_alignment(path_c, k, band_f, ends1, is_open, fine_rows, metric):
    from engine.align import metrics as M
    from engine.dtw.align import Alignment
    from engine.dtw.kernels import get_metric

    n, m = band_f.n, band_f.m
    path = upsample_path(path_c, k, n, m, is_open)
    a, b = fine_rows
    cost = float(np.sum(M.path_values(get_metric(metric).cell, a, b, path)))
    path.flags.writeable = False
    return Alignment(path=path, cost=cost, band=band_f, ends=ends1)
