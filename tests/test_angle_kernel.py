"""The pass-2 row kernel (engine/align/angle_kernel.py).

It must give exactly the per-cell ``splice_angle`` costs (so every view, report and the DTW
agree), those must be eq. 9 (the rotation form that was the metric before the kernel, and
the numpy reference with explicit rotation matrices) to rounding, and the DTW path on real
captures must be the one the rotation form gives.
"""

from __future__ import annotations

import numba
import numpy as np
import pytest

from benchmarks.split import make_case
from engine.align import angle_kernel as AK
from engine.align import metrics as M
from engine.dtw import Aligner, Band, Ends, align_features
from engine.splice import pipeline as P


@pytest.fixture(scope="module", params=[("lafan1", 3), ("beat", 1)], ids=["lafan1", "beat"])
def pass2(request):
    """Pass-2 rows and band of a real split case, as the splice builds them."""
    family, seed = request.param
    case = make_case(family, seed, crop_s=8.0)
    feats = P.prepare(case.body, case.hand)
    result = P.align_passes(feats)
    return result.pass2


def test_row_kernel_gives_the_per_cell_costs_exactly(pass2):
    a, b = pass2.rows
    band = pass2.band
    state = AK.prepare(a, b)
    n = len(a)
    for i in np.unique(np.r_[0, 1, np.arange(0, n, 5), n - 1]):
        lo, hi = int(band.lo[i]), int(band.hi[i])
        row = AK.cost_row(state, int(i), lo, hi)
        ref = M.cost_grid(M.splice_angle, a, b, np.array([i]), np.arange(lo, hi + 1))[0]
        assert np.array_equal(row, ref), f"row {i}"


def test_costs_are_eq9_to_rounding(pass2):
    """Against the rotation form (cross products, libm arccos) on every band cell of a
    sample of rows, and against explicit rotation matrices (numpy) on a small grid."""
    a, b = pass2.rows
    band = pass2.band
    rows = np.arange(0, len(a), 13)
    for i in rows:
        cols = np.arange(band.lo[i], band.hi[i] + 1)
        new = M.cost_grid(M.splice_angle, a, b, np.array([i]), cols)[0]
        old = M.cost_grid(M.splice_angle_literal, a, b, np.array([i]), cols)[0]
        # arccos near 0 amplifies the cosine's last bit to ~1e-8 rad; elsewhere ~1e-15
        assert np.allclose(new, old, rtol=0, atol=1e-7), f"row {i}"
        assert np.median(np.abs(new - old)) < 1e-12
    step = a[0, 1]
    arms = int(a[0, 0])
    body = M.AngleFeatures(
        forearm=a[:, 2:].reshape(len(a), arms, AK.ARM)[::40, :, 0:3],
        hand=a[:, 2:].reshape(len(a), arms, AK.ARM)[::40, :, 3:6],
    )
    hand = M.AngleFeatures(
        forearm=b[:, 2:].reshape(len(b), arms, AK.ARM)[::40, :, 0:3],
        hand=b[:, 2:].reshape(len(b), arms, AK.ARM)[::40, :, 3:6],
    )
    ref = M.angle_cost_reference(body, hand) + step
    got = M.cost_grid(M.splice_angle, a, b, np.arange(0, len(a), 40), np.arange(0, len(b), 40))
    assert np.allclose(got, ref, rtol=0, atol=1e-7)


@pytest.mark.parametrize("open_ends", [False, True])
def test_dtw_path_is_the_rotation_forms_path(pass2, open_ends):
    """Today's per-cell metric (rotation form) and the row kernel give the same path on
    real data, with fixed and with open ends; the incremental solver too, after an edit."""
    a, b = pass2.rows
    band = pass2.band
    ends = pass2.ends if open_ends else Ends()
    new = align_features(a, b, band, metric="splice_angle", ends=ends)
    old = align_features(a, b, band, metric=M.splice_angle_literal, ends=ends)
    assert np.array_equal(new.path, old.path)
    assert new.cost == pytest.approx(old.cost, rel=1e-12, abs=1e-9)
    solver = Aligner(a, b, metric="splice_angle")
    assert np.array_equal(solver.solve(band, ends).path, new.path)
    n, m = len(a), len(b)
    i, j = int(new.path[len(new.path) // 2, 0]), int(new.path[len(new.path) // 2, 1])
    edited = Band.around_path(
        new.path, n, m, 12, points=[(i, min(j + 3, m - 1), 1)], open_ends=open_ends
    )
    got = solver.solve(edited, ends)
    ref = align_features(a, b, edited, metric=M.splice_angle_literal, ends=ends)
    assert np.array_equal(got.path, ref.path)


@numba.njit(error_model="numpy")
def _acos_all(x, out):
    for t in range(x.shape[0]):
        out[t] = AK.acos(x[t])


def test_acos_is_within_one_ulp_of_libm():
    rng = np.random.default_rng(0)
    x = np.concatenate(
        [
            rng.uniform(-1.0, 1.0, 200_000),
            1.0 - rng.uniform(0.0, 1e-6, 20_000),
            -1.0 + rng.uniform(0.0, 1e-6, 20_000),
            [-1.0, 1.0, 0.0, 0.5, -0.5, np.nextafter(0.5, 0.0), np.nextafter(-0.5, 0.0)],
        ]
    )
    got = np.empty_like(x)
    _acos_all(x, got)
    ref = np.arccos(x)
    assert np.all(np.abs(got - ref) <= np.spacing(ref) + 1e-300)
    assert got[-7] == np.pi and got[-6] == 0.0


def test_degenerate_vectors_cost_nothing_and_zero_forearms_compare_hands():
    rng = np.random.default_rng(3)
    h = rng.normal(size=(4, 1, 3))
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    f = np.zeros((4, 1, 3))  # no measured forearm: R is the identity
    body = M.AngleFeatures(forearm=f, hand=h)
    hand = M.AngleFeatures(forearm=f, hand=h[::-1].copy())
    got = M.cost_grid(M.splice_angle, body.rows(), hand.rows(), np.arange(4), np.arange(4))
    expect = np.arccos(np.clip(h[:, 0] @ h[::-1, 0].T, -1.0, 1.0))
    assert np.allclose(got, expect, atol=1e-7)
    zero = M.AngleFeatures(forearm=f, hand=np.zeros((4, 1, 3)))
    got = M.cost_grid(M.splice_angle, body.rows(), zero.rows(), np.arange(4), np.arange(4))
    assert np.array_equal(got, np.zeros((4, 4)))


def test_shared_costs_solves_equal_one_shot_solves_and_compute_the_costs_once(pass2, monkeypatch):
    """``SharedCosts`` (the CLI's two pass-2 solves): each solve is ``align_features``'s, bit
    for bit, with other ends too; the second whole-band pass reads the kept costs (the
    cost function is not called again), and another band is computed afresh."""
    from engine.dtw.align import SharedCosts

    a, b = pass2.rows
    band = pass2.band
    n, m = len(a), len(b)
    shared = SharedCosts(a, b, metric="splice_angle")
    ends = [Ends(n // 5, m // 5, 0.4), Ends(n // 5, m // 5, 0.1), Ends()]
    first = shared.solve(band, ends[0])
    state = shared.problem._rows_state
    assert state.kept is not None and state.kept[2].shape == (band.area,)
    calls = []
    real = AK._forward

    def counting(*args):
        calls.append(args[-2])  # the mode: 0 compute, 1 compute and keep, 2 read kept
        return real(*args)

    monkeypatch.setattr(AK, "_forward", counting)
    got = [first] + [shared.solve(band, e) for e in ends[1:]]
    assert calls == [AK._READ, AK._READ]
    for e, g in zip(ends, got, strict=True):
        ref = align_features(a, b, band, metric="splice_angle", ends=e)
        assert np.array_equal(g.path, ref.path) and g.cost == ref.cost
    wider = Band.around_path(np.asarray(first.path), n, m, 6, open_ends=True)
    calls.clear()
    other = shared.solve(wider, ends[0])
    assert calls == [AK._WRITE]
    ref = align_features(a, b, wider, metric="splice_angle", ends=ends[0])
    assert np.array_equal(other.path, ref.path) and other.cost == ref.cost
