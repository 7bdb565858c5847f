"""The pass-1 row kernel (engine/phase_kernel.py) and the memory-bounded feature/transfer paths.

The row kernel must give exactly the per-cell ``splice_phase`` costs (so the DTW path is the
same), and those must be eq. 6 with θ quantised (the dense numpy reference), except where
the exact θ lies on the edge between two bins.
"""

from __future__ import annotations

import numba
import numpy as np
import pytest
from naive import dtw_banded

from engine import metrics as M
from engine import phase_kernel as PK
from engine.dtw import Aligner, Band, align_features
from engine.splice import pipeline as P
from engine.splice import transfer as TR
from engine.splice.split import make_case


@pytest.fixture(scope="module")
def case():
    return make_case("lafan1", 3, crop_s=6.0)


@pytest.fixture(scope="module")
def feats(case):
    return P.prepare(case.body, case.hand)


def _band_cells(band, rows):
    return [(int(i), np.arange(band.lo[i], band.hi[i] + 1)) for i in rows]


@pytest.mark.parametrize("theta", ["window", "trunk", "none"])
def test_row_kernel_gives_the_per_cell_costs_exactly(case, theta):
    f = P.prepare(case.body, case.hand, theta=theta)
    a, b = f.pass1_rows
    band = Band.from_constraints(f.n, f.m, 0.3, [])
    state = PK.prepare(a, b)
    rows = np.unique(np.r_[0, 1, 2, np.arange(0, f.n, 7), f.n - 2, f.n - 1])
    got = PK.cost_rows(state, band.lo, band.hi, rows)
    for (i, cols), row in zip(_band_cells(band, rows), got, strict=True):
        ref = M.cost_grid(M.splice_phase, a, b, np.array([i]), cols)[0]
        assert np.array_equal(row, ref), f"row {i}"


def test_per_cell_cost_is_eq6_with_theta_quantised(feats):
    """Against the dense numpy reference with exact θ: equal wherever θ is not within
    1e-3 rad of a bin edge (there float rounding may pick either bin)."""
    bp, hp = feats.body_phase, feats.hand_phase
    rows = np.arange(0, feats.n, 23)
    cols = np.arange(0, feats.m, 3)
    ref = M.phase_cost_reference(bp, hp)[np.ix_(rows, cols)]
    a, b = feats.pass1_rows
    got = M.cost_grid(M.splice_phase, a, b, rows, cols)
    ii, jj = np.meshgrid(rows, cols, indexing="ij")
    th = M.cell_theta_window(bp, hp, ii, jj)
    width = 2 * np.pi / feats.n_bins
    edge = np.abs((th / width + 0.5) - np.round(th / width + 0.5)) * width < 1e-3
    assert (~edge).sum() > 0.99 * edge.size
    assert np.array_equal(got[~edge], ref[~edge])


def test_pass1_path_equals_the_naive_dtw(feats):
    a, b = feats.pass1_rows
    n = 240
    a, b = a[:n], b[:n]
    band = Band.from_constraints(n, n, 0.3, [(120, 118, 3)])
    cost = M.cost_grid(M.splice_phase, a, b, np.arange(n), np.arange(n))
    total, path, _ = dtw_banded(cost.tolist(), band.lo.tolist(), band.hi.tolist())
    got = align_features(a, b, band, metric="splice_phase")
    assert got.cost == total
    assert [tuple(p) for p in got.path] == path


def test_aligner_with_the_row_kernel_matches_a_full_solve_after_edits(feats):
    a, b = feats.pass1_rows
    n, m = feats.n, feats.m
    pts = [[n // 4, m // 4, 2], [n // 2, m // 2, 2], [3 * n // 4, 3 * m // 4, 2]]
    solver = Aligner(a, b, metric="splice_phase")
    solver.solve(Band.from_constraints(n, m, 0.3, pts))
    for shift in (9, -7, 4):  # forward and backward passes both use the row kernel
        pts[2][1] = 3 * m // 4 + shift
        band = Band.from_constraints(n, m, 0.3, pts)
        inc = solver.solve(band)
        ref = align_features(a, b, band, metric="splice_phase")
        assert inc.cost == ref.cost
        assert solver.last_stats.fraction < 0.75


@numba.njit
def _bins(y, x, nb):
    out = np.zeros(y.shape[0], np.int64)
    for k in range(y.shape[0]):
        out[k] = PK.theta_bin(np.float32(y[k]), np.float32(x[k]), nb)
    return out


def test_popcount_and_theta_bins():
    rng = np.random.default_rng(1)
    x = rng.integers(0, 2**63, size=200, dtype=np.uint64)
    assert [int(M._popcount(v)) for v in x] == [bin(int(v)).count("1") for v in x]
    nb = 72
    th = rng.uniform(-np.pi, np.pi, 5000)
    exact = np.floor(th * nb / (2 * np.pi) + 0.5).astype(int) % nb
    far = np.abs((th * nb / (2 * np.pi) + 0.5) % 1.0 - 0.5) < 0.49  # > ~1e-3 rad from an edge
    r = rng.uniform(0.01, 10.0, th.size)  # any length
    got = _bins(r * np.sin(th), r * np.cos(th), nb)
    assert np.array_equal(got[far], exact[far])
    assert list(_bins(np.array([np.nan, 0.0, 0.0]), np.array([1.0, 0.0, -1.0]), nb)) == [0, 0, 36]


# --------------------------------------------------------------------------------------------
# memory: blockwise kinematics and transfer give the same numbers
# --------------------------------------------------------------------------------------------


def test_take_markers_by_blocks_equal_the_whole_take(case):
    from engine.features import hand_frame, motion_markers, skeleton_yaw, take_markers
    from engine.roles import find_roles

    hand = case.hand
    roles = find_roles(hand.skeleton)
    frames = {s: hand_frame(hand, roles, s) for s in ("right", "left")}
    mk, yaw, rots = take_markers(hand, roles, frames, fps=30.0, keep_rotations=True, chunk=37)
    for s in frames:
        ref = motion_markers(hand, s, roles, fps=30.0, frame=frames[s]).markers
        assert np.array_equal(mk[s], ref)
    assert np.array_equal(yaw, skeleton_yaw(hand, roles))
    from engine.fastkin import forward_kinematics

    assert np.array_equal(rots, forward_kinematics(hand)[1])


def test_transfer_by_blocks_equals_one_block(case, feats, monkeypatch):
    res = P.align_passes(feats)
    whole = P.transfer(feats, res)
    monkeypatch.setattr(TR, "TRANSFER_CHUNK", 50)
    blocks = P.transfer(feats, res)
    assert np.array_equal(whole.rotations, blocks.rotations)
    assert np.array_equal(whole.translations, blocks.translations)
    from engine.fastkin import continuous

    q = np.random.default_rng(2).standard_normal((40, 3, 4))
    ref = continuous(q)
    TR.continuous_inplace(q)
    assert np.array_equal(q, ref)
