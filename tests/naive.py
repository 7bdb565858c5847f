"""Plain-Python references for engine.dtw (slow, obvious, independent of numba).

Conventions match engine.dtw: rows are body frames, columns hand frames,
0-based; a path runs (0, 0) -> (n-1, m-1) with steps (1, 0), (0, 1), (1, 1);
ties prefer the diagonal, then the vertical step (i-1, j), then the horizontal
one (i, j-1).
"""

from __future__ import annotations

import math

INF = math.inf


def dtw_banded(cost, lo, hi):
    """(total, path, gamma) of banded DTW over ``cost[i][j]`` (lists or arrays).

    ``gamma`` is a dict {(i, j): cumulative cost} over band cells.
    """
    n = len(lo)
    m = len(cost[0])
    gamma = {}

    def g(i, j):
        if i == -1 and j == -1:
            return 0.0
        return gamma.get((i, j), INF)

    back = {}
    for i in range(n):
        for j in range(lo[i], hi[i] + 1):
            candidates = [
                (g(i - 1, j - 1), (i - 1, j - 1)),
                (g(i - 1, j), (i - 1, j)),
                (g(i, j - 1), (i, j - 1)),
            ]
            best_value, best_cell = candidates[0]
            for value, cell in candidates[1:]:
                if value < best_value:
                    best_value, best_cell = value, cell
            gamma[(i, j)] = float(cost[i][j]) + best_value
            back[(i, j)] = best_cell
    total = gamma[(n - 1, m - 1)]
    path = [(n - 1, m - 1)]
    while path[-1] != (0, 0):
        path.append(back[path[-1]])
    return total, path[::-1], gamma


def local_cost_matrix(a, b, metric="sqeuclidean"):
    """Dense cost lists: metric of rows a[i] and b[j] ('sqeuclidean', 'euclidean' or a function)."""

    def sq(x, y):
        return sum((float(p) - float(q)) ** 2 for p, q in zip(x, y))

    if metric == "sqeuclidean":
        f = sq
    elif metric == "euclidean":

        def f(x, y):
            return math.sqrt(sq(x, y))
    else:
        f = metric
    return [[f(a[i], b[j]) for j in range(len(b))] for i in range(len(a))]


def path_cost(cost, path):
    return sum(float(cost[i][j]) for i, j in path)


def is_monotone_continuous(path, n, m):
    """True if ``path`` runs (0, 0) -> (n-1, m-1) with steps (1,0), (0,1), (1,1)."""
    path = [tuple(int(v) for v in p) for p in path]
    if path[0] != (0, 0) or path[-1] != (n - 1, m - 1):
        return False
    for (i0, j0), (i1, j1) in zip(path, path[1:]):
        if (i1 - i0, j1 - j0) not in ((1, 0), (0, 1), (1, 1)):
            return False
    return True


def all_paths(lo, hi, m):
    """Every monotone continuous path inside the band (tiny bands only)."""
    n = len(lo)

    def inside(i, j):
        return 0 <= i < n and lo[i] <= j <= hi[i]

    def extend(path):
        i, j = path[-1]
        if (i, j) == (n - 1, m - 1):
            yield list(path)
            return
        for di, dj in ((1, 1), (1, 0), (0, 1)):
            if inside(i + di, j + dj):
                path.append((i + di, j + dj))
                yield from extend(path)
                path.pop()

    if inside(0, 0):
        yield from extend([(0, 0)])


def band_is_feasible(lo, hi, m):
    """Brute-force reachability: does any path fit in the band?"""
    n = len(lo)
    reach = set()
    for i in range(n):
        for j in range(lo[i], hi[i] + 1):
            if (i, j) == (0, 0) or {(i - 1, j - 1), (i - 1, j), (i, j - 1)} & reach:
                reach.add((i, j))
    return (n - 1, m - 1) in reach


def constraint_band(n, m, width, points):
    """docs/method.md eqs. 4-5 row by row, plus the points' own rows; no widening.

    ``points``: [(x, y, tol)], valid and sorted. Returns (lo, hi) lists; a row
    may come out empty (lo > hi) or disconnected: the caller compares it with
    engine.dtw only where it is feasible.
    """
    anchors = [(-1, -1, 0)] + [tuple(p) for p in points]
    if anchors[-1][0] != n - 1:
        anchors.append((n - 1, m - 1, 0))
    w_frames = None if width is None else width * n
    lo, hi = [0] * n, [m - 1] * n
    for (x0, y0, t0), (x1, y1, t1) in zip(anchors, anchors[1:]):
        dx, dy = x1 - x0, y1 - y0
        for i in range(x0 + 1, x1 + 1):
            low, high = y0 - t0, y1 + t1
            if w_frames is not None:
                lam = w_frames * math.sqrt(dx * dx + dy * dy) / (2 * dx)
                c = y0 + dy * (i - x0) / dx
                low = max(low, min(math.ceil(c - lam - 1e-9), math.floor(c)))
                high = min(high, max(math.floor(c + lam + 1e-9), math.ceil(c)))
            lo[i], hi[i] = max(low, 0), min(high, m - 1)
    for x, y, t in points:
        lo[x], hi[x] = max(lo[x], y - t, 0), min(hi[x], y + t, m - 1)
    return lo, hi


def tolerance_band(n, m, points):
    """The hard clips alone (width None)."""
    return constraint_band(n, m, None, points)


def dtaidistance_window_band(n, m, window):
    """dtaidistance's window as (lo, hi): row i spans
    i - max(0, n-m) - window + 1 .. i + max(0, m-n) + window - 1 (clipped)."""
    lo = [max(0, i - max(0, n - m) - window + 1) for i in range(n)]
    hi = [min(m - 1, i + max(0, m - n) + window - 1) for i in range(n)]
    return lo, hi


def trim(lo, hi):
    """Drop cells no path can use: lo -> running max, hi -> running min from the end."""
    lo2, hi2 = list(lo), list(hi)
    for i in range(1, len(lo2)):
        lo2[i] = max(lo2[i], lo2[i - 1])
    for i in range(len(hi2) - 2, -1, -1):
        hi2[i] = min(hi2[i], hi2[i + 1])
    return lo2, hi2


def dtw_banded_open(cost, lo, hi, skip=0.0, max_body=0, max_hand=0, end_body=None, end_hand=None):
    """(total, path) of banded DTW with open ends (engine.dtw.Ends), plainly.

    ``end_body``/``end_hand`` (None: ``max_body``/``max_hand``): the end's own limits.

    A path may start at (0, 0), at (i, 0) with i <= max_body or at (0, j) with
    j <= max_hand, and end at (n-1, m-1), (i, m-1) with n-1-i <= max_body or (n-1, j)
    with m-1-j <= max_hand; every frame left unmatched costs ``skip``. Written as the
    virtual row and column -1: γ(-1, -1) = 0, γ(-1, c) = skip·(c+1) for c+1 <= max_hand,
    γ(r, -1) = skip·(r+1) for r+1 <= max_body. Ties at the end: the last row wins (the
    larger column first), then the larger row. ``max_body = max_hand = 0`` is
    :func:`dtw_banded`.
    """
    n = len(lo)
    m = len(cost[0])
    gamma = {}

    def g(i, j):
        if i == -1 and j == -1:
            return 0.0
        if i == -1:
            return skip * (j + 1) if j + 1 <= max_hand else INF
        if j == -1:
            return skip * (i + 1) if i + 1 <= max_body else INF
        return gamma.get((i, j), INF)

    back = {}
    for i in range(n):
        for j in range(lo[i], hi[i] + 1):
            candidates = [
                (g(i - 1, j - 1), (i - 1, j - 1)),
                (g(i - 1, j), (i - 1, j)),
                (g(i, j - 1), (i, j - 1)),
            ]
            best_value, best_cell = candidates[0]
            for value, cell in candidates[1:]:
                if value < best_value:
                    best_value, best_cell = value, cell
            gamma[(i, j)] = float(cost[i][j]) + best_value
            back[(i, j)] = best_cell
    end_body = max_body if end_body is None else end_body
    end_hand = max_hand if end_hand is None else end_hand
    ends = [(n - 1, j) for j in range(m - 1, -1, -1) if m - 1 - j <= end_hand]
    ends += [(i, m - 1) for i in range(n - 2, -1, -1) if n - 1 - i <= end_body]
    total, end = INF, (n - 1, m - 1)
    for i, j in ends:
        if (i, j) in gamma:
            t = gamma[(i, j)] + skip * ((m - 1 - j) + (n - 1 - i))
            if t < total:
                total, end = t, (i, j)
    path = [end]
    while True:
        prev = back[path[-1]]
        if prev[0] < 0 or prev[1] < 0:
            break
        path.append(prev)
    return total, path[::-1]


def is_open_path(path, n, m, max_body, max_hand):
    """True if ``path`` is monotone and continuous and starts and ends within the limits."""
    path = [tuple(int(v) for v in p) for p in path]
    (i0, j0), (i1, j1) = path[0], path[-1]
    if not ((i0 == 0 and j0 <= max_hand) or (j0 == 0 and i0 <= max_body)):
        return False
    if not ((i1 == n - 1 and m - 1 - j1 <= max_hand) or (j1 == m - 1 and n - 1 - i1 <= max_body)):
        return False
    return all(
        (b[0] - a[0], b[1] - a[1]) in ((1, 0), (0, 1), (1, 1)) for a, b in zip(path, path[1:])
    )
