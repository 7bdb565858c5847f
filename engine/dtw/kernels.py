"""Numba kernels for banded DTW and the registry of local-cost metrics.

Storage (METHOD.md §4, "Memory"): a band is kept row by row. Cell ``(i, j)`` of
band row ``i`` (``lo[i] <= j <= hi[i]``) has the flat index
``start[i] + j - lo[i]``; ``start`` is the exclusive prefix sum of the row
widths (``Band.start``). Backpointers are one byte per band cell
(``DIAGONAL``, ``VERTICAL``, ``HORIZONTAL``: the step that entered the cell);
cumulative costs γ are kept only when asked for (the incremental ``Aligner``),
otherwise two rows of ``m + 1`` doubles suffice. Memory therefore grows with
the band area, never with ``n * m``.

Recurrence (Majkowska et al. eqs. 1-2)::

    γ(i, j) = D(i, j) + min(γ(i-1, j-1), γ(i-1, j), γ(i, j-1)),  γ = +inf outside the band

with ``γ(-1, -1) = 0``. Ties prefer the diagonal, then the vertical step
(``i-1, j``), then the horizontal one (``i, j-1``); ``tests/naive.py`` uses
the same order.

Local costs must not be NaN or ``-inf`` (``+inf`` is allowed and forbids a
cell): a kernel that meets one stops and reports the row, the public functions
turn that into a ``ValueError`` naming the cell.

Metrics
-------
A metric is a numba function of two feature rows returning the local cost::

    import numba
    from engine.dtw import register_metric
    from engine.dtw._config import FASTMATH       # fastmath without nnan/ninf

    @register_metric("forearm_palm_angle")
    @numba.njit(fastmath=FASTMATH, nogil=True)
    def forearm_palm_angle(body_row, hand_row):   # (d,) float64 each
        ...
        return angle                               # float, radians

    align_features(body, hand, band, metric="forearm_palm_angle")

The pass-1 sign-code cost (METHOD.md §2: sum of squared differences of the
velocity and acceleration sign codes) is the squared Euclidean distance of the
concatenated sign vectors, so ``"sqeuclidean"`` serves it as is (and fast).

``body_row`` is ``a[i]`` (a row of the first feature array), ``hand_row`` is
``b[j]``. The function must not raise and must not allocate much (it runs once
per band cell); it should return ``+inf`` rather than NaN for a cell that must
not be matched. Registered metrics work with ``align_features``, ``Aligner``
and ``local_cost_image``; the kernel is compiled once per process and metric
(not cached on disk, numba cannot cache kernels that take a function
argument). ``"sqeuclidean"`` and ``"euclidean"`` are built in with a
vectorised row kernel that is cached on disk; a numba function can also be
passed directly as ``metric=`` without registering it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba.core.dispatcher import Dispatcher

from ._config import njit, njit_cached
from .fixed import QUANTUM

DIAGONAL = np.uint8(0)  # came from (i-1, j-1)
VERTICAL = np.uint8(1)  # came from (i-1, j)
HORIZONTAL = np.uint8(2)  # came from (i, j-1)

# built-in metric kinds for the cached feature kernels
SQEUCLIDEAN = 0
EUCLIDEAN = 1
#: Euclidean rounded to ``fixed.QUANTUM`` (exact sums: ``engine.dtw.fixed``)
EUCLIDEAN_FIXED = 2
_PER_QUANTUM = 1.0 / QUANTUM

INF = np.inf
NEG_INF = -np.inf


# ---------------------------------------------------------------------------
# the recurrence, one row or two interleaved rows at a time
# ---------------------------------------------------------------------------
# γ rows live in buffers of m + 1 doubles indexed by absolute column + 1
# (index 0 is column -1). A row buffer is +inf outside its band row where the
# next row reads it (``_pad_row``). Loops run over slices starting at the
# band edge, so indices are provably non-negative (no wraparound code) and the
# minimum/addition chain along a row is the only serial dependency. Two rows
# are interleaved (row i at column t, row i+1 at column t-1) so two
# independent chains overlap: same arithmetic, same results, ~1.5x faster.

PAIR_MIN_WIDTH = 32  # rows narrower than this are done one at a time


@njit_cached()
def _dp_row(prev, cur, crow, lo, hi, bp_row, left0):
    """Row ``i`` of γ into ``cur`` from row ``i - 1`` in ``prev``.

    ``crow``: local costs by absolute column; ``bp_row``: the row's
    backpointers (``hi - lo + 1`` bytes); ``left0``: γ(i, lo - 1) (+inf, or
    the open-start edge ``_edge`` when ``lo == 0``). Returns True if a local
    cost in the row was NaN or -inf.
    """
    w = hi - lo + 1
    p = prev[lo : hi + 2]  # p[k] = γ(i-1, lo+k-1), p[k+1] = γ(i-1, lo+k)
    out = cur[lo + 1 : hi + 2]
    cost = crow[lo : hi + 1]
    left = left0
    bad = False
    for k in range(w):
        diag = p[k]
        up = p[k + 1]
        c = cost[k]
        du = min(diag, up)
        step_du = VERTICAL if up < diag else DIAGONAL
        step = HORIZONTAL if left < du else step_du
        g = c + min(left, du)
        bad |= not (c > NEG_INF)
        out[k] = g
        left = g
        bp_row[k] = step
    return bad


@njit_cached()
def _dp_pair(prev, mid, cur, crow_a, crow_b, lo_a, hi_a, lo_b, hi_b, bp_a, bp_b, left_a0, left_b0):
    """Rows ``i`` (``prev`` -> ``mid``) and ``i + 1`` (``mid`` -> ``cur``) interleaved.

    Needs ``lo_a <= lo_b <= hi_a + 1`` (a trimmed, feasible band). ``left_a0``,
    ``left_b0``: γ at column ``lo - 1`` of each row (``_dp_row``'s ``left0``).
    Returns a bit set: 1 if row ``i`` had a NaN/-inf local cost, 2 if row
    ``i + 1`` had. Pads ``mid`` for row ``i + 1``'s reads.
    """
    # phase 1: row i alone, columns lo_a .. min(hi_a, lo_b)
    end1 = min(hi_a, lo_b)
    pa = prev[lo_a : hi_a + 2]
    out_a = mid[lo_a + 1 : hi_a + 2]
    cost_a = crow_a[lo_a : hi_a + 1]
    left_a = left_a0
    bad_a = False
    for k in range(end1 - lo_a + 1):
        diag = pa[k]
        up = pa[k + 1]
        c = cost_a[k]
        du = min(diag, up)
        step_du = VERTICAL if up < diag else DIAGONAL
        bp_a[k] = HORIZONTAL if left_a < du else step_du
        g = c + min(left_a, du)
        bad_a |= not (c > NEG_INF)
        out_a[k] = g
        left_a = g
    mid[lo_a] = left_a0
    for q in range(hi_a + 2, hi_b + 2):
        mid[q] = INF
    # phase 2: row i at column t = lo_b+1 .. hi_a, row i+1 at column t-1
    w_b = hi_b - lo_b + 1
    cost_b = crow_b[lo_b : hi_b + 1]
    out_b = cur[lo_b + 1 : hi_b + 2]
    left_b = left_b0
    bad_b = False
    done_b = 0
    if hi_a >= lo_b + 1:
        count = hi_a - lo_b
        k_a = lo_b + 1 - lo_a
        pa2 = prev[lo_b + 1 : hi_a + 2]
        cost_a2 = crow_a[lo_b + 1 : hi_a + 1]
        out_a2 = mid[lo_b + 2 : hi_a + 2]
        bp_a2 = bp_a[k_a : k_a + count]
        a_diag = mid[lo_b]  # γ(i, t-2) for t = lo_b + 1
        a_up = mid[lo_b + 1]  # γ(i, t-1)
        for k in range(count):
            diag = pa2[k]
            up = pa2[k + 1]
            c = cost_a2[k]
            du = min(diag, up)
            step_du = VERTICAL if up < diag else DIAGONAL
            bp_a2[k] = HORIZONTAL if left_a < du else step_du
            g = c + min(left_a, du)
            bad_a |= not (c > NEG_INF)
            out_a2[k] = g
            left_a = g
            # row i+1 at column lo_b + k
            c2 = cost_b[k]
            du2 = min(a_diag, a_up)
            step_du2 = VERTICAL if a_up < a_diag else DIAGONAL
            bp_b[k] = HORIZONTAL if left_b < du2 else step_du2
            g2 = c2 + min(left_b, du2)
            bad_b |= not (c2 > NEG_INF)
            out_b[k] = g2
            left_b = g2
            a_diag = a_up
            a_up = g
        done_b = count
    # phase 3: row i+1 alone, the remaining columns
    pb = mid[lo_b + done_b : hi_b + 2]
    for k in range(w_b - done_b):
        diag = pb[k]
        up = pb[k + 1]
        c = cost_b[done_b + k]
        du = min(diag, up)
        step_du = VERTICAL if up < diag else DIAGONAL
        bp_b[done_b + k] = HORIZONTAL if left_b < du else step_du
        g = c + min(left_b, du)
        bad_b |= not (c > NEG_INF)
        out_b[done_b + k] = g
        left_b = g
    return (1 if bad_a else 0) | (2 if bad_b else 0)


@njit_cached()
def _edge(i, ends):
    """γ(i, -1): the cost of leaving body frames ``0..i`` unmatched (open start), or +inf.

    ``ends`` = ``[skip, max_body, max_hand, end_body, end_hand]`` (float64,
    ``Ends.array``): cost per unmatched frame and how many frames of each take may stay
    unmatched at the start and at the end (all 0: fixed ends).
    """
    if i + 1 <= ends[1]:
        return ends[0] * (i + 1)
    return INF


@njit_cached()
def _left0(lo, i, ends):
    """γ(i, lo[i] - 1): the open-start edge when row ``i`` reaches column 0, else +inf."""
    if lo[i] == 0:
        return _edge(i, ends)
    return INF


@njit_cached()
def _init_prev(prev, gamma, lo, hi, start, i0, ends):
    """Set ``prev`` to γ row ``i0 - 1`` (from ``gamma``) or to the virtual row -1.

    Row -1 is γ(-1, -1) = 0 and, with open ends, γ(-1, c) = skip · (c + 1) for the
    first ``max_hand`` columns (a path entering (0, c + 1) leaves hand frames
    ``0..c`` unmatched).
    """
    prev[:] = INF
    if i0 == 0:
        prev[0] = 0.0  # γ(-1, -1) = 0: the path starts with a diagonal step into (0, 0)
        m = prev.shape[0] - 1
        for c in range(min(int(ends[2]), m)):
            prev[c + 1] = ends[0] * (c + 1)
    else:
        r = i0 - 1
        w = hi[r] - lo[r] + 1
        prev[lo[r] + 1 : lo[r] + 1 + w] = gamma[start[r] : start[r] + w]
        prev[lo[r]] = _left0(lo, r, ends)


@njit_cached()
def _store_row(buf, gamma, lo, hi, start, i):
    w = hi[i] - lo[i] + 1
    gamma[start[i] : start[i] + w] = buf[lo[i] + 1 : lo[i] + 1 + w]


@njit_cached()
def _pad_row(buf, lo, hi, i, ends):
    """+inf in ``buf`` (row ``i``) at the columns row ``i + 1`` reads outside row ``i``
    (the open-start edge at column -1)."""
    buf[lo[i]] = _left0(lo, i, ends)  # column lo[i] - 1
    if i + 1 < lo.shape[0]:
        for k in range(hi[i] + 2, hi[i + 1] + 2):  # columns hi[i] + 1 .. hi[i+1]
            buf[k] = INF


@njit_cached()
def move_rows(src, gamma, has, lo, hi, old_start, new_start, r0, r1, shift):
    """γ of the stored rows ``r0..r1-1`` (``has``) from ``src`` at their ``old_start`` offsets
    to ``gamma`` at ``new_start`` (the same widths ``hi - lo + 1``, one offset difference for
    all), plus ``shift``; in the order that never overwrites a value not yet moved (``src``
    may be ``gamma``, the ranges overlapping). ``Aligner._forward_settling``: rows kept
    after an edit."""
    if r1 <= r0:
        return
    d = new_start[r0] - old_start[r0]
    if d > 0:
        for r in range(r1 - 1, r0 - 1, -1):
            if has[r]:
                a, b = old_start[r], new_start[r]
                for k in range(hi[r] - lo[r], -1, -1):
                    gamma[b + k] = src[a + k] + shift
    else:
        for r in range(r0, r1):
            if has[r]:
                a, b = old_start[r], new_start[r]
                for k in range(hi[r] - lo[r] + 1):
                    gamma[b + k] = src[a + k] + shift


@njit_cached()
def _keep(every, i, i1):
    """Store γ of row ``i`` (of a pass over rows ``..i1-1``)? ``every``: 0 never, 1 always,
    k > 1 every k-th row (``i % k == 0``) and the pass's last row."""
    return every == 1 or (every > 1 and (i % every == 0 or i == i1 - 1))


@njit_cached()
def _use_pair(lo, hi, i, i1):
    return (
        i + 1 < i1 and hi[i] - lo[i] >= PAIR_MIN_WIDTH and hi[i + 1] - lo[i + 1] >= PAIR_MIN_WIDTH
    )


# ---------------------------------------------------------------------------
# local cost rows
# ---------------------------------------------------------------------------
@njit_cached()
def fill_builtin(a, bT, kind, i, lo, hi, crow):
    """``crow[lo..hi]`` = cost of ``a[i]`` against ``b[lo..hi]`` (``bT`` is ``b.T``, contiguous)."""
    w = hi - lo + 1
    out = crow[lo : hi + 1]
    out[:] = 0.0
    for d in range(a.shape[1]):
        ad = a[i, d]
        col = bT[d, lo : hi + 1]
        for k in range(w):
            t = ad - col[k]
            out[k] += t * t
    if kind == EUCLIDEAN:
        for k in range(w):
            out[k] = np.sqrt(out[k])
    elif kind == EUCLIDEAN_FIXED:
        for k in range(w):
            out[k] = np.rint(np.sqrt(out[k]) * _PER_QUANTUM) * QUANTUM


@njit()
def fill_metric(metric, a, b, i, lo, hi, crow):
    ai = a[i]
    for j in range(lo, hi + 1):
        crow[j] = metric(ai, b[j])


# ---------------------------------------------------------------------------
# forward passes: rows i0..i1-1
# ---------------------------------------------------------------------------
# Each returns (bad_row, total): bad_row is the first row with a NaN/-inf local
# cost (-1 if none), total is γ(i1 - 1, m - 1) (meaningful when i1 == n).
# ``bp`` receives the backpointers of rows i0..i1-1 (flat, ``start`` offsets).
# ``gamma`` is the per-cell γ store (same flat offsets as ``bp``); ``keep_gamma``
# (int) says which rows are written to it (``_keep``: 0 none, then ``gamma`` may
# be any float64 array; 1 every row; k > 1 every k-th row and the last one).
# For i0 > 0 row i0 - 1 must already be in ``gamma``. The three kernels share
# the row functions and differ only in where a row's local costs come from.
#
# Open ends: ``ends`` = [skip, max_body, max_hand] sets the virtual row -1 and
# column -1 (``_init_prev``, ``_edge``); [0, 0, 0] is the paper's fixed start.
# ``last_col[i]`` receives γ(i, m - 1) for every computed row whose band
# reaches the last column (+inf otherwise) and ``last_row`` γ of row i1 - 1
# (valid inside its band): ``best_end`` picks the open end from them.


@njit_cached()
def _row_done(buf, lo, hi, i, ends, last_col, m):
    _pad_row(buf, lo, hi, i, ends)
    last_col[i] = buf[m] if hi[i] == m - 1 else INF


@njit_cached()
def _finish(prev, last_row, m):
    last_row[:] = prev[1 : m + 1]
    return prev[m]


@njit_cached()
def forward_matrix(cost, lo, hi, start, i0, i1, bp, gamma, keep_gamma, ends, last_col, last_row):
    m = cost.shape[1]
    prev = np.empty(m + 1)
    mid = np.full(m + 1, INF)
    cur = np.full(m + 1, INF)
    _init_prev(prev, gamma, lo, hi, start, i0, ends)
    i = i0
    while i < i1:
        if _use_pair(lo, hi, i, i1):
            bad = _dp_pair(
                prev,
                mid,
                cur,
                cost[i],
                cost[i + 1],
                lo[i],
                hi[i],
                lo[i + 1],
                hi[i + 1],
                bp[start[i] : start[i + 1]],
                bp[start[i + 1] : start[i + 2]],
                _left0(lo, i, ends),
                _left0(lo, i + 1, ends),
            )
            if bad:
                return (i if bad & 1 else i + 1), np.nan
            last_col[i] = mid[m] if hi[i] == m - 1 else INF
            _row_done(cur, lo, hi, i + 1, ends, last_col, m)
            if _keep(keep_gamma, i, i1):
                _store_row(mid, gamma, lo, hi, start, i)
            if _keep(keep_gamma, i + 1, i1):
                _store_row(cur, gamma, lo, hi, start, i + 1)
            prev, mid, cur = cur, prev, mid
            i += 2
        else:
            if _dp_row(
                prev, cur, cost[i], lo[i], hi[i], bp[start[i] : start[i + 1]], _left0(lo, i, ends)
            ):
                return i, np.nan
            _row_done(cur, lo, hi, i, ends, last_col, m)
            if _keep(keep_gamma, i, i1):
                _store_row(cur, gamma, lo, hi, start, i)
            prev, cur = cur, prev
            i += 1
    return -1, _finish(prev, last_row, m)


@njit_cached()
def forward_builtin(
    a, bT, kind, lo, hi, start, i0, i1, bp, gamma, keep_gamma, ends, last_col, last_row
):
    m = bT.shape[1]
    prev = np.empty(m + 1)
    mid = np.full(m + 1, INF)
    cur = np.full(m + 1, INF)
    crow_a = np.zeros(m)
    crow_b = np.zeros(m)
    _init_prev(prev, gamma, lo, hi, start, i0, ends)
    i = i0
    while i < i1:
        if _use_pair(lo, hi, i, i1):
            fill_builtin(a, bT, kind, i, lo[i], hi[i], crow_a)
            fill_builtin(a, bT, kind, i + 1, lo[i + 1], hi[i + 1], crow_b)
            bad = _dp_pair(
                prev,
                mid,
                cur,
                crow_a,
                crow_b,
                lo[i],
                hi[i],
                lo[i + 1],
                hi[i + 1],
                bp[start[i] : start[i + 1]],
                bp[start[i + 1] : start[i + 2]],
                _left0(lo, i, ends),
                _left0(lo, i + 1, ends),
            )
            if bad:
                return (i if bad & 1 else i + 1), np.nan
            last_col[i] = mid[m] if hi[i] == m - 1 else INF
            _row_done(cur, lo, hi, i + 1, ends, last_col, m)
            if _keep(keep_gamma, i, i1):
                _store_row(mid, gamma, lo, hi, start, i)
            if _keep(keep_gamma, i + 1, i1):
                _store_row(cur, gamma, lo, hi, start, i + 1)
            prev, mid, cur = cur, prev, mid
            i += 2
        else:
            fill_builtin(a, bT, kind, i, lo[i], hi[i], crow_a)
            if _dp_row(
                prev, cur, crow_a, lo[i], hi[i], bp[start[i] : start[i + 1]], _left0(lo, i, ends)
            ):
                return i, np.nan
            _row_done(cur, lo, hi, i, ends, last_col, m)
            if _keep(keep_gamma, i, i1):
                _store_row(cur, gamma, lo, hi, start, i)
            prev, cur = cur, prev
            i += 1
    return -1, _finish(prev, last_row, m)


@njit()
def forward_metric(
    metric, a, b, lo, hi, start, i0, i1, bp, gamma, keep_gamma, ends, last_col, last_row
):
    m = b.shape[0]
    prev = np.empty(m + 1)
    cur = np.full(m + 1, INF)
    crow = np.zeros(m)
    _init_prev(prev, gamma, lo, hi, start, i0, ends)
    for i in range(i0, i1):  # the metric dominates; one row at a time is enough
        fill_metric(metric, a, b, i, lo[i], hi[i], crow)
        if _dp_row(prev, cur, crow, lo[i], hi[i], bp[start[i] : start[i + 1]], _left0(lo, i, ends)):
            return i, np.nan
        _row_done(cur, lo, hi, i, ends, last_col, m)
        if _keep(keep_gamma, i, i1):
            _store_row(cur, gamma, lo, hi, start, i)
        prev, cur = cur, prev
    return -1, _finish(prev, last_row, m)


@njit_cached()
def best_end(last_row, last_col, lo, hi, ends, i_max):
    """The open end of the cheapest path: (total, i, j).

    Candidates: ``(n-1, j)`` with ``m-1-j <= end_hand`` (total γ + skip·(m-1-j)) and
    ``(i, m-1)`` with ``n-1-i <= end_body`` (γ + skip·(n-1-i)); only rows ``<= i_max``
    are read from ``last_col`` (``last_row`` is γ of row n-1). Ties: the last row wins,
    there the larger column; then the larger row. Fixed ends ([skip, 0, 0]) give
    γ(n-1, m-1) at (n-1, m-1).
    """
    n = lo.shape[0]
    m = last_row.shape[0]
    best = INF
    bi = n - 1
    bj = m - 1
    if i_max >= n - 1:
        j_min = max(lo[n - 1], m - 1 - int(ends[4]))
        for j in range(hi[n - 1], j_min - 1, -1):
            t = last_row[j] + ends[0] * (m - 1 - j)
            if t < best:
                best = t
                bi = n - 1
                bj = j
    for i in range(min(n - 2, i_max), max(0, n - 1 - int(ends[3])) - 1, -1):
        if hi[i] == m - 1:
            t = last_col[i] + ends[0] * (n - 1 - i)
            if t < best:
                best = t
                bi = i
                bj = m - 1
    return best, bi, bj


@njit_cached()
def cost_row_builtin(a, bT, kind, i, lo, hi):
    """Local costs of row ``i``, columns ``lo..hi`` (for error messages and views)."""
    crow = np.zeros(bT.shape[1])
    fill_builtin(a, bT, kind, i, lo, hi, crow)
    return crow[lo : hi + 1].copy()


@njit()
def cost_row_metric(metric, a, b, i, lo, hi):
    crow = np.zeros(b.shape[0])
    fill_metric(metric, a, b, i, lo, hi, crow)
    return crow[lo : hi + 1].copy()


# ---------------------------------------------------------------------------
# backtracking
# ---------------------------------------------------------------------------
@njit_cached()
def backtrack(bp, lo, start, i, j):
    """Path (k, 2) int64 ending at (i, j), following the backpointers back to where it
    entered the matrix: (0, 0), or with open ends any (0, c) or (r, 0)."""
    path = np.empty((i + j + 1, 2), np.int64)
    k = 0
    while True:
        path[k, 0] = i
        path[k, 1] = j
        k += 1
        step = bp[start[i] + j - lo[i]]
        if step == DIAGONAL:
            i -= 1
            j -= 1
        elif step == VERTICAL:
            i -= 1
        else:
            j -= 1
        if i < 0 or j < 0:  # came from the virtual row or column -1: the start
            break
    return path[:k][::-1].copy()


@njit_cached()
def _reversed_tail(rbp, rlo, rstart, r, c, n, m):
    """Backtrack in the reversed problem from reversed cell (r, c); original order."""
    tail = backtrack(rbp, rlo, rstart, r, c)
    k = tail.shape[0]
    out = np.empty((k, 2), np.int64)
    for q in range(k):
        out[q, 0] = n - 1 - tail[k - 1 - q, 0]
        out[q, 1] = m - 1 - tail[k - 1 - q, 1]
    return out


@njit_cached()
def join_path(gamma, bp, lo, hi, start, rgamma, rbp, rlo, rhi, rstart, J, ends, fcol, rcol):
    """Optimal path through the cheapest crossing from row ``J`` to row ``J + 1``.

    ``gamma``/``bp`` (band ``lo``, ``hi``, ``start``) hold forward γ of row
    ``J`` and the backpointers of rows ``0..J``; ``rgamma``/``rbp`` (reversed
    band ``rlo``, ``rhi``, ``rstart``) hold β of row ``J + 1`` and the backward
    backpointers of rows ``J + 1..n-1``, in reversed order. The crossing is
    ``(J, j) -> (J + 1, j + 1)`` (preferred on a tie) or ``(J + 1, j)``; the
    first cheapest ``j`` wins.

    With open ends (``ends``, see ``_edge``) a path may also end at ``(i, m-1)``
    for a row ``i <= J`` (forward ``fcol[i]`` = γ(i, m-1)) or start at ``(i, 0)``
    for a row ``i > J`` (``rcol[n-1-i]`` = β(i, 0), the reversed problem's
    ``last_col``); those count only when strictly cheaper than every crossing.
    Returns (total, path (k, 2) int64).
    """
    n = lo.shape[0]
    # reversed row n-1 is row 0 mirrored (columns m-1-hi[0] .. m-1-lo[0]); with open
    # ends row 0 need not reach column 0 (a point on the first body frame), so m is
    # not rhi[n-1] + 1
    m = rhi[n - 1] + lo[0] + 1
    r = n - 2 - J  # reversed index of row J + 1
    lo_n, hi_n = lo[J + 1], hi[J + 1]
    best = INF
    best_j = lo[J]
    best_next = lo[J]
    for j in range(lo[J], hi[J] + 1):
        g = gamma[start[J] + j - lo[J]]
        # β(J + 1, c) sits at reversed column m - 1 - c of reversed row r
        vert = INF
        if lo_n <= j <= hi_n:
            vert = rgamma[rstart[r] + (m - 1 - j) - rlo[r]]
        diag = INF
        if lo_n <= j + 1 <= hi_n:
            diag = rgamma[rstart[r] + (m - 2 - j) - rlo[r]]
        if diag <= vert:
            t = g + diag
            nxt = j + 1
        else:
            t = g + vert
            nxt = j
        if t < best or j == lo[J]:
            best = t
            best_j = j
            best_next = nxt
    kind = 0
    end_row = -1
    skip = ends[0]
    for i in range(max(0, n - 1 - int(ends[3])), J + 1):  # paths ending above the junction
        if hi[i] == m - 1:
            t = fcol[i] + skip * (n - 1 - i)
            if t < best:
                best = t
                kind = 1
                end_row = i
    for i in range(J + 1, min(int(ends[1]), n - 1) + 1):  # paths starting below it
        if lo[i] == 0:
            t = rcol[n - 1 - i] + skip * i
            if t < best:
                best = t
                kind = 2
                end_row = i
    if kind == 1:
        return best, backtrack(bp, lo, start, end_row, m - 1)
    if kind == 2:
        return best, _reversed_tail(rbp, rlo, rstart, n - 1 - end_row, m - 1, n, m)
    head = backtrack(bp, lo, start, J, best_j)
    tail = _reversed_tail(rbp, rlo, rstart, r, m - 1 - best_next, n, m)
    k_head = head.shape[0]
    k_tail = tail.shape[0]
    path = np.empty((k_head + k_tail, 2), np.int64)
    path[:k_head] = head
    path[k_head:] = tail
    return best, path


# ---------------------------------------------------------------------------
# metric registry
# ---------------------------------------------------------------------------
@njit_cached()
def sqeuclidean(x, y):
    """Squared Euclidean distance of two feature rows."""
    s = 0.0
    for d in range(x.shape[0]):
        t = x[d] - y[d]
        s += t * t
    return s


@njit_cached()
def euclidean(x, y):
    """Euclidean distance of two feature rows."""
    return np.sqrt(sqeuclidean(x, y))


@njit_cached()
def euclidean_fixed(x, y):
    """Euclidean distance of two feature rows rounded to the nearest multiple of
    ``fixed.QUANTUM`` (2**-24; exact sums, ``engine.dtw.fixed``)."""
    return np.rint(np.sqrt(sqeuclidean(x, y)) * _PER_QUANTUM) * QUANTUM


def _always_exact(a, b) -> bool:
    return True


@dataclass(frozen=True)
class Metric:
    """A registered local-cost metric: ``cell(a_row, b_row) -> float`` plus an optional
    built-in row kernel (``kind``) used instead of ``cell`` where it exists."""

    name: str
    cell: Dispatcher
    kind: int = -1
    #: optional row kernel: ``prepare(a, b) -> state`` once per problem, then
    #: ``forward(state, lo, hi, start, i0, i1, bp, gamma, keep_gamma, ends, last_col,
    #: last_row)`` as the ``forward_*`` kernels (open ends included); must give exactly ``cell``'s costs (see engine.align.phase_kernel)
    prepare: object = None
    forward: object = None
    #: optional ``row(a, b, i, lo, hi) -> (hi - lo + 1,)``: ``cell(a[i], b[j])`` for columns
    #: ``lo..hi``, exactly; a kernel cached on disk that calls ``cell`` by name, where
    #: ``cost_row_metric`` (the metric as an argument) compiles anew in every process
    row: object = None
    #: optional ``exact(a, b) -> bool``: True when every local cost of these rows is a whole
    #: multiple of ``engine.dtw.fixed.QUANTUM`` (``Aligner`` then reuses settled rows)
    exact: object = None


_METRICS: dict[str, Metric] = {
    "sqeuclidean": Metric("sqeuclidean", sqeuclidean, SQEUCLIDEAN),
    "euclidean": Metric("euclidean", euclidean, EUCLIDEAN),
    "euclidean_fixed": Metric(
        "euclidean_fixed", euclidean_fixed, EUCLIDEAN_FIXED, exact=_always_exact
    ),
}


def register_metric(
    name: str,
    fn: Dispatcher | None = None,
    *,
    replace: bool = False,
    prepare=None,
    forward=None,
    row=None,
    exact=None,
):
    """Register a numba metric ``fn(a_row, b_row) -> float`` under ``name``.

    Use as ``register_metric("name", fn)`` or as a decorator
    ``@register_metric("name")`` above ``@numba.njit``. Re-registering a name
    raises ``ValueError`` unless ``replace=True``; built-in names cannot be
    replaced. ``exact``: see :class:`Metric`.
    """

    def _register(f):
        if not isinstance(f, Dispatcher):
            raise TypeError(
                f"metric {name!r}: expected a numba.njit function of (a_row, b_row), "
                f"got {type(f).__name__}; decorate it with @numba.njit first"
            )
        if not isinstance(name, str) or not name:
            raise ValueError(f"metric name must be a non-empty string, got {name!r}")
        known = _METRICS.get(name)
        if known is not None and (known.kind >= 0 or not replace):
            if (
                known.cell is f
                and known.forward is forward
                and known.row is row
                and known.exact is exact
            ):
                return f
            raise ValueError(
                f"metric {name!r} is already registered"
                + ("" if known.kind >= 0 else "; pass replace=True to replace it")
            )
        _METRICS[name] = Metric(name, f, prepare=prepare, forward=forward, row=row, exact=exact)
        return f

    return _register if fn is None else _register(fn)


def metric_names() -> list[str]:
    """Names accepted as ``metric=``."""
    return sorted(_METRICS)


def get_metric(metric: str | Dispatcher) -> Metric:
    """Look up a metric by name, or wrap a numba function given directly."""
    if isinstance(metric, Dispatcher):
        for known in _METRICS.values():
            if known.cell is metric:
                return known
        return Metric(getattr(metric, "__name__", "metric"), metric)
    if isinstance(metric, str):
        try:
            return _METRICS[metric]
        except KeyError:
            raise ValueError(
                f"unknown metric {metric!r}; known: {', '.join(metric_names())} "
                "(register others with engine.dtw.register_metric)"
            ) from None
    raise TypeError(
        f"metric must be a registered name or a numba.njit function, got {type(metric).__name__}"
    )
