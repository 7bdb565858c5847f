"""Property tests for engine.dtw bands and paths (hypothesis)."""

from __future__ import annotations

import naive
import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from engine.base.errors import ParameterError
from engine.dtw import Aligner, Band, align

SETTINGS = settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@st.composite
def problems(draw, max_n=24, max_m=24):
    """(n, m, width, points) with points sorted in x, non-decreasing in y."""
    n = draw(st.integers(1, max_n))
    m = draw(st.integers(1, max_m))
    width = draw(st.one_of(st.none(), st.floats(0.0, 1.5)))
    k = draw(st.integers(0, min(4, n)))
    xs = sorted(draw(st.lists(st.integers(0, n - 1), min_size=k, max_size=k, unique=True)))
    ys = sorted(draw(st.lists(st.integers(0, m - 1), min_size=k, max_size=k)))
    tols = draw(st.lists(st.integers(0, 3), min_size=k, max_size=k))
    return n, m, width, [(x, y, t) for x, y, t in zip(xs, ys, tols)]


def build(n, m, width, points):
    try:
        return Band.from_constraints(n, m, width, points)
    except ParameterError:
        return None


@SETTINGS
@given(problems(), st.integers(0, 2**32 - 1))
def test_path_is_inside_band_monotone_continuous_and_meets_points(problem, seed):
    n, m, width, points = problem
    band = build(n, m, width, points)
    hard_lo, hard_hi = naive.tolerance_band(n, m, points)
    # the constructor refuses exactly when the tolerance clips admit no path
    assert (band is not None) == naive.band_is_feasible(hard_lo, hard_hi, m)
    assume(band is not None)
    # the band stays inside the clips and contains the eq. 4-5 band wherever that one is usable
    assert (band.lo >= hard_lo).all() and (band.hi <= hard_hi).all()
    cost = np.random.default_rng(seed).random((n, m))
    r = align(cost, band)
    path = r.path
    assert naive.is_monotone_continuous(path.tolist(), n, m)
    assert band.contains(path[:, 0], path[:, 1]).all()
    for x, y, tol in points:
        cols = path[path[:, 0] == x, 1]
        assert cols.size and (np.abs(cols - y) <= tol).all(), (x, y, tol, cols)
        if tol == 0:
            assert [x, y] in path.tolist()
    assert r.cost == pytest.approx(naive.path_cost(cost, path), rel=1e-12)
    total, ref_path, _ = naive.dtw_banded(cost, band.lo.tolist(), band.hi.tolist())
    assert r.cost == pytest.approx(total, rel=1e-12)
    assert [tuple(p) for p in path.tolist()] == ref_path


@SETTINGS
@given(problems())
def test_band_contains_formula_band_and_widens_only_to_connect(problem):
    n, m, width, points = problem
    assume(width is not None)
    band = build(n, m, width, points)
    assume(band is not None)
    lo, hi = naive.constraint_band(n, m, width, points)
    mask = band.mask()
    usable_lo, usable_hi = naive.trim(lo, hi)
    for i in range(n):  # the formula's cells that a path could use are kept
        assert mask[i, usable_lo[i] : usable_hi[i] + 1].all()
    if naive.band_is_feasible(lo, hi, m):
        # nothing to widen: the band is the formula band, minus cells no path can use
        trimmed = Band(np.asarray(lo), np.asarray(hi), m)
        assert band == trimmed


@SETTINGS
@given(problems(max_n=40, max_m=40), st.data())
def test_incremental_resolve_equals_full_solve(problem, data):
    n, m, width, points = problem
    band = build(n, m, width, points)
    assume(band is not None and points)
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    cost = rng.random((n, m))
    solver = Aligner.from_cost(cost)
    solver.solve(band)
    for _ in range(3):  # move one point at a time, as the app does
        k = data.draw(st.integers(0, len(points) - 1))
        x, y, t = points[k]
        y_new = data.draw(st.integers(0, m - 1))
        t_new = data.draw(st.integers(0, 3))
        moved = points[:k] + [(x, y_new, t_new)] + points[k + 1 :]
        new_band = build(n, m, width, moved)
        if new_band is None:
            continue
        points, band = moved, new_band
        r = solver.solve(band)
        full = align(cost, band)
        assert r.cost == pytest.approx(full.cost, rel=1e-12)
        assert r.path.tolist() == full.path.tolist()
        assert band.contains(r.path[:, 0], r.path[:, 1]).all()


@SETTINGS
@given(problems(), st.integers(0, 4))
def test_around_path_contains_path_and_keeps_points(problem, radius):
    n, m, width, points = problem
    band = build(n, m, width, points)
    assume(band is not None)
    path = align(np.ones((n, m)), band).path
    ring = Band.around_path(path, n, m, radius, points=points)
    assert ring.contains(path[:, 0], path[:, 1]).all()
    cheb = np.abs(np.argwhere(ring.mask())[:, None, :] - path[None, :, :]).max(-1).min(-1)
    assert (cheb <= radius).all()
    hard_lo, hard_hi = naive.tolerance_band(n, m, points)
    assert (ring.lo >= hard_lo).all() and (ring.hi <= hard_hi).all()


@SETTINGS
@given(
    st.integers(1, 12),
    st.integers(1, 12),
    st.lists(st.tuples(st.integers(-1, 12), st.integers(-1, 12)), min_size=1, max_size=12),
)
def test_band_constructor_accepts_exactly_the_feasible_bands(n, m, rows):
    rows = (rows * n)[:n]
    lo = np.array([min(r) for r in rows])
    hi = np.array([max(r) for r in rows])
    valid = (lo >= 0).all() and (hi <= m - 1).all()
    feasible = valid and naive.band_is_feasible(lo.tolist(), hi.tolist(), m)
    try:
        band = Band(lo, hi, m)
    except ParameterError:
        assert not feasible
        return
    assert feasible
    # trimming removes only cells no path can use
    used = (
        {tuple(c) for p in naive.all_paths(lo.tolist(), hi.tolist(), m) for c in p}
        if (n * m <= 30)
        else None
    )
    if used is not None:
        kept = {tuple(c) for c in np.argwhere(band.mask())}
        assert used <= kept
