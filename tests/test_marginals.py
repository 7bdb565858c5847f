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
    assert len(asked) >= 3  # before each sweep and before the subtraction at least
    assert np.array_equal(kept.spread, plain.spread) and kept.total == plain.total
    # a newer edit arrives during the work: the second look stops it
    looks = iter([False, True])
    with pytest.raises(Cancelled):
        row_spread(a, b, band, "sqeuclidean", col, 0.7, 0.0, cancelled=lambda: next(looks, True))


def _open_gamma(cost, skip, max_body, max_hand):
    """γ of every cell with open starts (naive.dtw_banded_open's virtual row and column)."""
    n, m = cost.shape
    g = np.full((n + 1, m + 1), np.inf)
    g[0, 0] = 0.0
    for c in range(1, m + 1):
        if c <= max_hand:
            g[0, c] = skip * c
    for r in range(1, n + 1):
        if r <= max_body:
            g[r, 0] = skip * r
    for i in range(n):
        for j in range(m):
            g[i + 1, j + 1] = cost[i, j] + min(g[i, j], g[i, j + 1], g[i + 1, j])
    return g[1:, 1:]


@pytest.mark.parametrize("seed", range(6))
def test_near_optimal_rows_match_brute_force(seed):
    """Cells whose cheapest path (open or fixed ends) is within a margin of the optimum."""
    from engine.dtw.marginals import near_optimal_rows

    rng = np.random.default_rng(seed)
    n, m = (int(v) for v in rng.integers(6, 25, size=2))
    a = rng.normal(size=(n, 2))
    b = rng.normal(size=(m, 2))
    cost = ((a[:, None, :] - b[None, :, :]) ** 2).sum(-1)
    is_open = seed % 2 == 1
    ends = Ends(3, 4, 0.7) if is_open else Ends()
    lim = (3, 4) if is_open else (0, 0)
    fwd = _open_gamma(cost, ends.skip, *lim)
    bwd = _open_gamma(cost[::-1, ::-1], ends.skip, *lim)[::-1, ::-1]
    through = fwd + bwd - cost
    total = through.min()
    margin = float(rng.uniform(0.5, 4.0))
    first, last, got_total, path = near_optimal_rows(
        a, b, Band.full(n, m), "sqeuclidean", margin, ends
    )
    assert got_total == pytest.approx(total)
    want = align_features(a, b, Band.full(n, m), ends=ends)
    assert np.array_equal(path, want.path) and got_total == want.cost
    for i in range(n):
        cols = np.flatnonzero(through[i] <= total + margin + 1e-9)
        strict = np.flatnonzero(through[i] <= total + margin - 1e-9)
        if cols.size == 0:
            assert first[i] == -1 and last[i] == -1
        else:
            assert cols.min() <= first[i] and last[i] <= cols.max()
            if strict.size:
                assert first[i] <= strict.min() and last[i] >= strict.max()


@pytest.mark.parametrize("block_cells", [1, 7, 50, 10**9])
@pytest.mark.parametrize("seed", range(3))
def test_blocks_of_rows_give_the_whole_bands_result(seed, block_cells):
    # the band swept by blocks of rows (γ kept at block boundaries, made again for the
    # backward pass) is the brute force's answer for any block size, open ends included
    rng = np.random.default_rng(200 + seed)
    n, m = rng.integers(8, 30, size=2)
    a = rng.normal(size=(n, 2))
    b = rng.normal(size=(m, 2))
    cost = ((a[:, None, :] - b[None, :, :]) ** 2).sum(-1)
    ends = Ends(body=int(rng.integers(0, n // 2)), hand=int(rng.integers(0, m // 2)), skip=0.4)
    through, total = _brute_open(cost, ends)
    band = Band.full(n, m)
    col = np.full(n, m / 3.0)
    rs = row_spread(a, b, band, "sqeuclidean", col, 0.5, 0.3, ends=ends, block_cells=block_cells)
    assert rs.total == pytest.approx(total)
    row_best = np.maximum(through.min(axis=1, keepdims=True), total)
    extra = np.maximum(through - row_best, 0.0)
    d = np.arange(m)[None, :] - col[:, None]
    w = np.exp(-extra / 0.5)
    assert np.allclose(rs.spread, np.sqrt((w * d**2).sum(1) / w.sum(1)))
    assert np.allclose(rs.reach, np.where(extra <= 0.3, np.abs(d), 0.0).max(1))
    # the dense-cost route (the app's table) by blocks: the same numbers
    rc = row_spread(
        a, b, band, "sqeuclidean", col, 0.5, 0.3, ends=ends, costs=cost, block_cells=block_cells
    )
    assert np.allclose(rc.spread, rs.spread) and np.allclose(rc.reach, rs.reach)


def test_the_weighing_holds_one_block_of_gamma_not_the_band():
    # 1.6 M band cells: γ of the whole band both ways would be ~27 MB; by blocks of 100 k
    # cells the sweep holds under 4 MB at once, and the result is bit for bit the same
    import tracemalloc

    rng = np.random.default_rng(5)
    n = m = 4000
    a = np.cumsum(rng.normal(size=(n, 1)), axis=0)
    b = a + 0.1 * rng.normal(size=(m, 1))
    band = Band.sakoe_chiba(n, m, 0.1)
    assert band.area > 1_500_000
    col = np.arange(n, dtype=float)
    ends = Ends(body=40, hand=40, skip=0.5)
    row_spread(a[:50], b[:50], Band.full(50, 50), "sqeuclidean", col[:50], 1.0, 1.0)  # JIT
    whole = row_spread(a, b, band, "sqeuclidean", col, 1.0, 1.0, ends=ends, block_cells=10**9)
    tracemalloc.start()
    try:
        parts = row_spread(a, b, band, "sqeuclidean", col, 1.0, 1.0, ends=ends, block_cells=100_000)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 4_000_000, peak
    assert parts.total == whole.total
    assert np.array_equal(parts.spread, whole.spread)
    assert np.array_equal(parts.reach, whole.reach)


@pytest.fixture(scope="module")
def phase_case():
    from benchmarks.split import make_case

    return make_case("lafan1", 3, crop_s=6.0)


@pytest.mark.parametrize("theta", ["window", "trunk", "none"])
def test_the_backward_pass_state_is_the_forward_state_reversed(phase_case, theta):
    # the backward pass's row-kernel state is made from the forward one without reversed
    # copies of the rows: every array as PhaseProblem(a[::-1], b[::-1]) makes it
    from engine.align import phase_kernel as PK
    from engine.dtw.align import Problem
    from engine.splice import pipeline as P

    f = P.prepare(phase_case.body, phase_case.hand, theta=theta)
    a, b = f.pass1_rows
    state = PK.prepare(a, b)
    got = state.reversed()
    want = PK.prepare(np.ascontiguousarray(a[::-1]), np.ascontiguousarray(b[::-1]))
    assert not want.fallback and not got.fallback
    for x, y in zip(got.args(), want.args(), strict=True):
        assert np.array_equal(np.asarray(x), np.asarray(y))
        assert getattr(x, "dtype", None) == getattr(y, "dtype", None)
    problem = Problem.from_features(a, b, "splice_phase")
    problem._rows_state = problem.metric.prepare(problem.a, problem.b)
    back = problem.reversed()
    assert np.shares_memory(back.a, a) and back._rows_state is not None


def test_the_pass1_spread_is_the_same_with_the_reversed_state(phase_case, monkeypatch):
    from engine.align import phase_kernel as PK
    from engine.splice import pipeline as P

    f = P.prepare(phase_case.body, phase_case.hand)
    a, b = f.pass1_rows
    band = Band.from_constraints(f.n, f.m, 0.3, [])
    col = np.linspace(0, f.m - 1, f.n)
    ends = Ends(body=10, hand=10, skip=2.0)
    got = row_spread(a, b, band, "splice_phase", col, 3.0, 1.0, ends=ends, block_cells=5000)
    monkeypatch.setattr(PK.PhaseProblem, "reversed", lambda self: None)  # reversed copies
    want = row_spread(a, b, band, "splice_phase", col, 3.0, 1.0, ends=ends)
    assert got.total == want.total
    assert np.array_equal(got.spread, want.spread) and np.array_equal(got.reach, want.reach)
