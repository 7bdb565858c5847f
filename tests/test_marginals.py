"""Min-marginal costs (engine.dtw.marginals) against a brute-force reference."""

import numpy as np
import pytest

from engine.dtw import Band, align_features
from engine.dtw.align import Ends
from engine.dtw.marginals import row_spread


def _brute_through(cost):
    """T(i, j) by plain forward and backward recurrences on a dense matrix."""
    n, m = cost.shape
    f = np.full((n + 1, m + 1), np.inf)
    f[0, 0] = 0.0
    for i in range(n):
        for j in range(m):
            f[i + 1, j + 1] = cost[i, j] + min(f[i, j], f[i, j + 1], f[i + 1, j])
    g = np.full((n + 1, m + 1), np.inf)
    rc = cost[::-1, ::-1]
    g[0, 0] = 0.0
    for i in range(n):
        for j in range(m):
            g[i + 1, j + 1] = rc[i, j] + min(g[i, j], g[i, j + 1], g[i + 1, j])
    fb = f[1:, 1:]
    bb = g[1:, 1:][::-1, ::-1]
    return fb + bb - cost, f[n, m]


@pytest.mark.parametrize("seed", range(4))
def test_spread_and_reach_match_brute_force(seed):
    rng = np.random.default_rng(seed)
    n, m = rng.integers(5, 30, size=2)
    a = rng.normal(size=(n, 2))
    b = rng.normal(size=(m, 2))
    cost = ((a[:, None, :] - b[None, :, :]) ** 2).sum(-1)
    through, total = _brute_through(cost)
    band = Band.full(n, m)
    centre = np.asarray(align_features(a, b, band).path)
    col = np.zeros(n)
    for i, j in centre:  # the last column matched to each row
        col[i] = j
    temp, margin = 0.7, 1.5
    rs = row_spread(a, b, band, "sqeuclidean", col, temp, margin)
    assert rs.total == pytest.approx(total)
    assert np.allclose(through.min(axis=1), total)  # every row meets the optimum
    extra = np.maximum(through - total, 0.0)
    d = np.arange(m)[None, :] - col[:, None]
    w = np.exp(-extra / temp)
    want = np.sqrt((w * d**2).sum(1) / w.sum(1))
    assert np.allclose(rs.spread, want)
    want_reach = np.where(extra <= margin, np.abs(d), 0.0).max(1)
    assert np.allclose(rs.reach, want_reach)


def test_an_ambiguous_row_spreads_wider_than_a_distinct_one():
    # a flat stretch (a hold) in both takes: the rows inside it can match anywhere in it
    t = np.linspace(0, 4 * np.pi, 80)
    a = np.sin(t)
    a[30:50] = a[30]
    b = a.copy()
    band = Band.sakoe_chiba(80, 80, 0.3)
    col = np.arange(80, dtype=float)
    rs = row_spread(a.reshape(-1, 1), b.reshape(-1, 1), band, "sqeuclidean", col, 1e-3, 1e-6)
    assert rs.spread[40] > 3 * max(rs.spread[10], 0.5)
    assert rs.reach[40] >= 5 and rs.reach[10] <= 1


def _brute_open(cost, ends):
    """T(i, j) with open ends: fresh starts on the first row/column within the limits."""
    n, m = cost.shape

    def forward(c):
        f = np.full((n, m), np.inf)
        for i in range(n):
            for j in range(m):
                best = np.inf
                if i == 0 and j == 0:
                    best = 0.0
                elif j == 0 and i <= ends.body:
                    best = ends.skip * i
                elif i == 0 and j <= ends.hand:
                    best = ends.skip * j
                if i > 0 and j > 0:
                    best = min(best, f[i - 1, j - 1])
                if i > 0:
                    best = min(best, f[i - 1, j])
                if j > 0:
                    best = min(best, f[i, j - 1])
                f[i, j] = c[i, j] + best
        return f

    f = forward(cost)
    b = forward(cost[::-1, ::-1])[::-1, ::-1]
    ends_total = [f[n - 1, j] + ends.skip * (m - 1 - j) for j in range(m) if m - 1 - j <= ends.hand]
    ends_total += [
        f[i, m - 1] + ends.skip * (n - 1 - i) for i in range(n) if n - 1 - i <= ends.body
    ]
    return f + b - cost, min(ends_total)


@pytest.mark.parametrize("seed", range(4))
def test_open_ends_through_costs_match_brute_force(seed):
    rng = np.random.default_rng(100 + seed)
    n, m = rng.integers(6, 25, size=2)
    a = rng.normal(size=(n, 1))
    b = rng.normal(size=(m, 1))
    cost = (a - b.T) ** 2
    ends = Ends(
        body=int(rng.integers(0, n // 2)),
        hand=int(rng.integers(0, m // 2)),
        skip=float(rng.uniform(0.1, 1.0)),
    )
    through, total = _brute_open(cost, ends)
    band = Band.full(n, m)
    col = np.full(n, m / 2.0)
    rs = row_spread(a, b, band, "sqeuclidean", col, 0.5, 0.3, ends=ends)
    assert rs.total == pytest.approx(total)
    row_best = np.maximum(through.min(axis=1, keepdims=True), total)
    extra = np.maximum(through - row_best, 0.0)
    d = np.arange(m)[None, :] - col[:, None]
    w = np.exp(-extra / 0.5)
    assert np.allclose(rs.spread, np.sqrt((w * d**2).sum(1) / w.sum(1)))


def test_a_cancelled_spread_stops_between_its_sweeps_and_a_kept_one_is_unchanged():
    """drag150: the app gives up a trust assessment once a newer edit is being solved;
    ``cancelled`` is asked between the γ sweeps (and rows of the subtraction) and stops the
    work with ``Cancelled``; asked and never true, it changes nothing."""
    from engine.base.errors import Cancelled

    rng = np.random.default_rng(7)
    a, b = rng.normal(size=(40, 2)), rng.normal(size=(35, 2))
    band = Band.full(40, 35)
    col = np.asarray(align_features(a, b, band).path)[:, 1][:40].astype(float)
    col = np.resize(col, 40)
    plain = row_spread(a, b, band, "sqeuclidean", col, 0.7, 0.0)
    asked = []
    kept = row_spread(
        a, b, band, "sqeuclidean", col, 0.7, 0.0, cancelled=lambda: asked.append(1) and False
    )
    assert len(asked) >= 4  # before and after each of the two sweeps at least
    assert np.array_equal(kept.spread, plain.spread) and kept.total == plain.total
    # a newer edit arrives during the work: the second look stops it
    looks = iter([False, True])
    with pytest.raises(Cancelled):
        row_spread(
            a, b, band, "sqeuclidean", col, 0.7, 0.0, cancelled=lambda: next(looks, True)
        )
