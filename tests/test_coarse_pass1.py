"""Multi-resolution pass 1 (issue 13): a coarse sign-cost solve at <= 30 Hz guiding an exact
full-rate pass 1 in a narrow band around it (``engine.splice.coarse``)."""

from __future__ import annotations

import numpy as np
import pytest

from engine.base import tolerances as T
from engine.base.errors import ParameterError
from engine.dtw import Band, align_features
from engine.dtw import constraints as C
from engine.io.bvh import read_bvh, write_bvh
from engine.model.kinematics import resample
from engine.splice import coarse as CO
from engine.splice import pipeline as P
from engine.splice.end_band import open_end_band
from webapp import backend


def test_decimation_follows_the_rate_cap():
    assert T.PASS1_RATE_CAP_HZ == 30.0
    got = {fps: C.pass1_decimation(fps) for fps in (24, 25, 29.97, 30, 30.0003, 50, 60, 100, 120)}
    assert got == {24: 1, 25: 1, 29.97: 1, 30: 1, 30.0003: 1, 50: 2, 60: 2, 100: 4, 120: 4}
    assert all(fps / C.pass1_decimation(fps) <= 30.0 * 1.01 for fps in np.linspace(31, 240, 50))


def _fine_crossings(x, y, tol, m):
    t = int(np.floor(tol + 1e-9))
    return range(max(y - t, 0), min(y + t, m - 1) + 1)


def test_coarse_points_never_exclude_an_allowed_crossing():
    """Every hand frame a point allows at its body frame has its coarse column inside the
    coarse point's window on the coarse row, also where points share a coarse row."""
    rng = np.random.default_rng(7)
    checked = 0
    for _ in range(400):
        k = int(rng.integers(2, 6))
        n, m = int(rng.integers(40, 300)), int(rng.integers(40, 300))
        n_c, m_c = -(-n // k), -(-m // k)
        xs = np.sort(rng.choice(np.arange(1, n - 1), size=int(rng.integers(1, 5)), replace=False))
        ys = np.sort(rng.integers(0, m, size=len(xs)))
        tols = rng.choice([0.0, 1.0, 2.5, 7.0, 30.0], size=len(xs))
        pts = [(int(x), int(y), float(t)) for x, y, t in zip(xs, ys, tols, strict=True)]
        try:
            fine = Band.from_constraints(n, m, None, pts)  # crossings a path can reach
        except ParameterError:
            continue  # points no path joins: refused before any coarse grid
        cpts = C.coarse_points(pts, k, n_c, m_c)
        xs_c = [p[0] for p in cpts]
        assert xs_c == sorted(set(xs_c))  # strictly increasing coarse rows
        assert all(b[1] >= a[1] for a, b in zip(cpts, cpts[1:]))  # hand frames never decrease
        clip = Band.from_constraints(n_c, m_c, None, cpts)
        for x, y, tol in pts:
            xc = int(C.coarse_index(x, k).clip(0, n_c - 1))
            allowed = range(fine.lo[x], fine.hi[x] + 1)
            assert set(allowed) <= set(_fine_crossings(x, y, tol, m))
            for j in allowed:
                jc = int(C.coarse_index(j, k).clip(0, m_c - 1))
                assert clip.lo[xc] <= jc <= clip.hi[xc], (k, x, y, tol, j, cpts)
                checked += 1
    assert checked > 5000


@pytest.mark.parametrize("is_open", [False, True])
def test_coarse_band_holds_every_fine_band_cell(is_open):
    """The coarse band (width, points, open-end room, rounded on the coarse grid) holds the
    coarse cell of every cell of the full-rate band on the rows both grids share (away
    from the points' own rows, which the test above checks: a point's row clips one fine
    row, its coarse row stands for ``k``)."""
    rng = np.random.default_rng(11 + is_open)
    for _ in range(60):
        k = int(rng.integers(2, 5))
        fps = 30.0 * k
        n, m = int(rng.integers(200, 900)), int(rng.integers(200, 900))
        width = float(rng.choice([0.05, 0.1, 0.3]))
        npts = int(rng.integers(0, 3))
        xs = np.sort(rng.choice(np.arange(5, n - 5), size=npts, replace=False))
        ys = np.sort(np.clip((xs * m / n + rng.integers(-10, 10, npts)).astype(int), 0, m - 1))
        pts = [(int(x), int(y), float(rng.choice([0.0, 3.0]))) for x, y in zip(xs, ys, strict=True)]
        try:
            fine = Band.from_constraints(n, m, width, pts, open_ends=is_open)
        except ParameterError:
            continue
        limits = C.unmatched_limits(n, m, fps, None) if is_open else None
        if is_open:
            fine = open_end_band(fine, width, limits, pts, fps)
        rows = CO.CoarseRows(k, -(-n // k), -(-m // k), fps / k, (None, None))
        coarse, _ = CO.coarse_band(rows, fine, pts)
        for i in range(n):
            if any(abs(i - p[0]) <= k for p in pts):
                continue
            r = min(int(C.coarse_index(i, k)), rows.n - 1)
            jc = C.coarse_index(np.arange(fine.lo[i], fine.hi[i] + 1), k).clip(0, rows.m - 1)
            assert coarse.lo[r] <= jc.min() and jc.max() <= coarse.hi[r], (k, n, m, width, pts, i)


@pytest.fixture(scope="module")
def lafan(mocap_dir):
    return read_bvh(mocap_dir / "lafan1" / "dance1_subject1.bvh")


def test_takes_at_30_fps_solve_pass1_at_full_rate_as_before(sample_dir):
    beat = read_bvh(sample_dir / "beat" / "1_wayne_0_1_1.bvh")
    body, hand = beat.frames(0, 240), beat.frames(3, 243)
    feats = P.prepare(body, hand)
    assert feats.fps == pytest.approx(30.0, rel=1e-3) and feats.coarse is None
    res = P.align_passes(feats, ends="fixed")
    band1 = Band.from_constraints(feats.n, feats.m, C.BAND.resolve(None, feats.n, feats.fps))
    want = align_features(*feats.pass1_rows, band1, metric="splice_phase")
    assert res.pass1.coarse is None and res.pass1.band == band1
    assert np.array_equal(res.pass1.path, want.path) and res.pass1.cost == want.cost


@pytest.fixture(scope="module")
def pair120(sample_dir):
    """A real pair at 120 fps: BEAT's take (fingers, forearms) as the body, the same
    performance 0.2 s later as the hand take (both resampled from 30 fps)."""
    beat = read_bvh(sample_dir / "beat" / "1_wayne_0_1_1.bvh")
    return resample(beat.frames(0, 240), 120.0), resample(beat.frames(6, 246), 120.0)


def test_points_with_zero_tolerance_are_passed_exactly_at_full_rate(pair120):
    feats = P.prepare(*pair120)
    assert feats.coarse is not None and feats.coarse.k == 4
    free = P.align_passes(feats)
    x = feats.n // 2
    on = int(free.pass2.path[free.pass2.path[:, 0] == x][0, 1])
    for dy in (-7, -2, 3, 9):  # not on the coarse grid, off the free path
        y = on + dy
        res = P.align_passes(feats, points=[(x, y, 0.0)])
        assert res.pass1.coarse is not None and res.pass1.coarse.fallback is None
        fine = res.pass1.coarse.fine_band  # the narrow full-rate band pass 1 solved
        assert fine.area < 0.6 * res.pass1.band.area
        for name in ("pass1", "pass2"):
            path = getattr(res, name).path
            cols = path[path[:, 0] == x, 1]
            nxt = path[path[:, 0] == x + 1, 1]
            assert y in cols and nxt.min() in (y, y + 1), (name, dy)  # crosses row x at y
        assert res.warp[x] == pytest.approx(y, abs=1e-6)


def test_multires_pass1_gives_the_full_rate_path_on_a_real_120fps_pair(pair120):
    feats = P.prepare(*pair120)
    multi = P.align_passes(feats)
    coarse, feats.coarse = feats.coarse, None
    try:
        full = P.align_passes(feats)
    finally:
        feats.coarse = coarse
    assert multi.pass1.coarse.cells * 10 < full.pass1.band.area
    assert multi.pass1.cost == pytest.approx(full.pass1.cost, rel=1e-12)
    assert np.array_equal(multi.pass2.path, full.pass2.path)
    assert np.array_equal(multi.map, full.map)


def _files(tmp_path, body, hand):
    bp, hp = tmp_path / "body.bvh", tmp_path / "hand.bvh"
    write_bvh(body, bp)
    write_bvh(hand, hp)
    return bp, hp


def test_app_edit_chain_equals_fresh_splices_on_a_real_60_120fps_forearmless_pair(
    lafan, sample_dir, tmp_path
):
    """LAFAN1 dance1 at 60 fps (body) with ManipNet mug1 at 120 fps (a hand without a
    forearm, whose edits re-solve forward only): every edit of the app's chain gives the
    fresh CLI solve's paths and costs, coarse ones included, keeps its coarse solver, and
    its fine pass 1 stops at the first settled row."""
    body = resample(lafan.frames(0, 300), 60.0)
    hand = read_bvh(sample_dir / "manipnet" / "mug1_rightHand.bvh").frames(0, 1300)
    prep = backend.prepare(*_files(tmp_path, body, hand), "right")
    feats = prep.features
    assert feats.coarse is not None and feats.coarse.k == 2 and P.hand_lacks_forearm(feats)
    sol = backend.solve(prep, None, None, [])
    n, m = feats.n, feats.m
    x, y = n // 2, int(sol.cache["engine"].warp[n // 2])
    edits = [[(x, y + dy, 0.0)] for dy in (0, 10, -10, 5)]
    edits += [[(n // 4, m // 4, 2.0), (x, y + dy, 0.0)] for dy in (5, -5)]
    settled = 0
    for k, points in enumerate(edits):
        before = sol.cache["engine"]
        sol = backend.solve(prep, None, None, points, previous=sol)
        got = sol.cache["engine"]
        fresh = P.align_passes(feats, points=points)
        assert np.array_equal(got.pass1.coarse.path, fresh.pass1.coarse.path), k
        for name in ("pass1", "pass2"):
            assert np.array_equal(getattr(got, name).path, getattr(fresh, name).path), (k, name)
        assert np.array_equal(got.map, fresh.map), k
        assert got.pass1.coarse.solver is before.pass1.coarse.solver  # kept between edits
        assert got.pass1.cost == fresh.pass1.cost and got.pass2.cost == fresh.pass2.cost, k
        # pass 1's sign costs are exact (engine.dtw.fixed): its rows after the edit settle
        stats = got.pass1.solver.last_stats
        settled += stats.settled_row < n and stats.cells_computed < got.pass1.solver.band.area
    assert settled >= 3


def test_app_edit_chain_on_a_real_120fps_pair_with_forearms(pair120, tmp_path):
    """Junction re-solves (a hand take with a forearm): same pass-1 cost and the same
    pass-2 path and map as the fresh solve; the coarse and fine solvers recompute part of
    their bands only."""
    prep = backend.prepare(*_files(tmp_path, *pair120), "auto")
    feats = prep.features
    assert feats.coarse is not None and not P.hand_lacks_forearm(feats)
    sol = backend.solve(prep, None, None, [])
    n = feats.n
    x, y = n // 2, int(sol.cache["engine"].warp[n // 2])
    partial = 0
    for k, dy in enumerate((0, 8, -8, 4)):
        points = [(x, y + dy, 0.0)]
        sol = backend.solve(prep, None, None, points, previous=sol)
        got = sol.cache["engine"]
        fresh = P.align_passes(feats, points=points)
        assert got.pass1.cost == pytest.approx(fresh.pass1.cost, rel=1e-12), k
        assert np.array_equal(got.pass2.path, fresh.pass2.path), k
        assert np.array_equal(got.map, fresh.map), k
        stats = got.pass1.solver.last_stats
        partial += stats.cells_computed < got.pass1.band.area
    assert partial >= 2


def test_coarse_rows_are_every_kth_full_rate_row(pair120):
    """The coarse pass-1 rows reuse the full-rate signs (derivatives over the same 0.2 s,
    the takes' own dead zones, the hand's rotated masks) at every k-th frame; only the
    eq.-7 windows are made again from the coarse frames."""
    from engine.align import metrics as M

    feats = P.prepare(*pair120)
    cr = feats.coarse
    assert cr is not None and cr.k == 4
    a, b = feats.pass1_rows
    a_c, b_c = cr.rows
    assert (cr.n, cr.m) == (len(a[::4]), len(b[::4])) == (len(a_c), len(b_c))
    half = int(a[0, 0])
    codes = slice(M._HEADER + 2 * half, None)
    assert np.array_equal(a_c[:, codes], a[::4, codes])
    assert np.array_equal(b_c[:, codes], b[::4, codes])
    assert np.array_equal(a_c[:, : M._HEADER], a[::4, : M._HEADER])
    win = np.zeros((cr.n, 2 * half))
    M._raw_windows(np.ascontiguousarray(feats.body_phase.markers[::4]), win)
    assert np.array_equal(a_c[:, M._HEADER : M._HEADER + 2 * half], win)


def _valley_costs(n, k, shift, rows):
    """Fine (n x n) and coarse costs: the fine costs fall towards a valley that leaves the
    diagonal by ``shift`` frames over ``rows`` (every column nearer the valley is cheaper);
    the coarse costs know only the diagonal."""
    i = np.arange(n)[:, None]
    j = np.arange(n)[None, :]
    bump = np.clip(np.minimum(i - rows[0], rows[1] - i), 0, None)
    valley = i + np.minimum(bump, shift)
    fine = 0.1 + np.minimum(np.abs(j - valley) / 80.0, 1.0)
    nc = -(-n // k)
    ic = np.arange(nc)[:, None]
    jc = np.arange(nc)[None, :]
    coarse = 0.1 + np.minimum(np.abs(jc - ic) / 20.0, 1.0)
    return fine, coarse


def _matrix_solve(rows, metric, band, solver, incremental, ends, exact):
    from engine.dtw import align

    return align(rows, band, ends), None


@pytest.mark.parametrize("is_open", [False, True])
def test_fine_band_widens_where_the_fine_path_runs_along_its_edge(is_open):
    """A coarse path on the diagonal and a fine optimum 40 frames off it (the strip is
    about 12 frames wide): the narrow solve runs along the strip's edge, the strip widens
    there until the path keeps clear of it, and pass 1 gives the whole band's optimum."""
    from engine.dtw import Ends, align

    n, k, fps = 240, 4, 20.0  # radius: 0.5 s = 10 frames
    fine, coarse = _valley_costs(n, k, 40, (60, 180))
    band1 = Band.from_constraints(n, n, 0.8, None, open_ends=is_open)
    ends = Ends(20, 20, 0.5) if is_open else Ends()
    rows = CO.CoarseRows(k, coarse.shape[0], coarse.shape[1], fps / k, coarse)
    want = align(fine, band1, ends)
    lim = (20, 20) if is_open else None
    al, _, info = CO.solve(
        fine, rows, band1, 0.8, [], is_open, lim, ends, 0.5, _matrix_solve, "m", fps=fps
    )
    assert info.fallback is None and info.rounds >= 1
    assert info.fine_band.area < band1.area
    assert np.array_equal(al.path, want.path) and al.cost == pytest.approx(want.cost)
    # the first strip alone missed it: its optimum ran along the edge
    strip = CO.band_around_coarse(info.path, k, n, n, info.radius, is_open).intersect(band1)
    narrow = align(fine, strip, ends)
    assert narrow.cost > want.cost + 1.0
    assert CO.widen_where_pinched(narrow.path, strip, band1, info.radius, is_open) is not None
    assert CO.widen_where_pinched(al.path, info.fine_band, band1, info.radius, is_open) is None


def test_no_widening_when_the_fine_path_keeps_clear_of_the_edge():
    from engine.dtw import Ends, align

    n, k, fps = 240, 4, 20.0
    fine, coarse = _valley_costs(n, k, 0, (60, 180))  # both on the diagonal
    band1 = Band.from_constraints(n, n, 0.8, None)
    rows = CO.CoarseRows(k, coarse.shape[0], coarse.shape[1], fps / k, coarse)
    al, _, info = CO.solve(
        fine, rows, band1, 0.8, [], False, None, Ends(), 0.0, _matrix_solve, "m", fps=fps
    )
    assert info.rounds == 0 and info.solved_cells == info.fine_band.area
    assert np.array_equal(al.path, align(fine, band1).path)


def test_long_takes_also_solve_the_near_optimal_coarse_cells(pair120, monkeypatch):
    """From PASS1_NEAR_MIN_CELLS W1 cells on, the fine band also holds every coarse cell
    whose cheapest coarse path is within PASS1_NEAR_STEPS mean path cells of the coarse
    optimum (here forced on for a short pair): a superset of the strip, same result."""
    from engine.dtw.marginals import near_optimal_rows

    feats = P.prepare(*pair120)
    plain = P.align_passes(feats)
    assert not plain.pass1.coarse.near  # a short pair: the strip only
    monkeypatch.setattr(T, "PASS1_NEAR_MIN_CELLS", 0)
    res = P.align_passes(feats, incremental=False)  # one forward pass: coarse path and γ
    inc = P.align_passes(feats, incremental=True)  # the coarse Aligner's path, then γ
    assert inc.pass1.coarse.near and np.array_equal(inc.pass1.coarse.path, res.pass1.coarse.path)
    assert np.array_equal(inc.pass1.coarse.fine_band.lo, res.pass1.coarse.fine_band.lo)
    cp, k = res.pass1.coarse, feats.coarse.k
    assert cp.near and cp.fallback is None
    fine, strip = cp.fine_band, plain.pass1.coarse.fine_band
    assert np.all(fine.lo <= strip.lo) and np.all(fine.hi >= strip.hi)
    first, last, _, path_c = near_optimal_rows(
        *feats.coarse.rows, cp.band, "splice_phase", T.PASS1_NEAR_STEPS, cp.ends, per_cell=True
    )
    assert np.array_equal(path_c, cp.path)  # the one-shot coarse solve's path
    for r in np.flatnonzero(last >= 0):  # the fine cells of every near-optimal coarse cell
        for i in range(r * k, min(r * k + k, feats.n)):
            assert fine.lo[i] <= max(first[r] * k, res.pass1.band.lo[i])
            assert fine.hi[i] >= min(last[r] * k, res.pass1.band.hi[i])
    assert res.pass1.cost == pytest.approx(plain.pass1.cost, rel=1e-12)
    assert np.array_equal(res.map, plain.map)
