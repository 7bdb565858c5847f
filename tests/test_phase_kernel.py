"""The pass-1 row kernel (engine/align/phase_kernel.py) and the memory-bounded feature/transfer paths.

The row kernel must give exactly the per-cell ``splice_phase`` costs (so the DTW path is the
same), and those must be eq. 6 with θ quantised (the dense numpy reference), except where
the exact θ lies on the edge between two bins.
"""

from __future__ import annotations

import numba
import numpy as np
import pytest
from naive import dtw_banded

from benchmarks.split import make_case
from engine.align import metrics as M
from engine.align import phase_kernel as PK
from engine.dtw import Aligner, Band, align_features
from engine.splice import pipeline as P
from engine.splice import transfer as TR


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
    """Against numpy: θ of eq. 7 in float64 (``cell_theta_window``) rounded to its bin, the
    hand's sign codes turned by the bin's angle (``rotated_codes``), Σ (s − s')². Equal
    wherever θ is not within 1e-3 rad of a bin edge (there rounding may pick either bin)."""
    bp, hp = feats.body_phase, feats.hand_phase
    nb = feats.n_bins
    rows = np.arange(0, feats.n, 11)
    cols = np.arange(0, feats.m, 2)
    ii, jj = np.meshgrid(rows, cols, indexing="ij")
    th = M.cell_theta_window(bp, hp, ii, jj)
    x = th * nb / (2 * np.pi) + 0.5
    bins = np.floor(x).astype(int) % nb
    edge = np.abs(x - np.round(x)) * (2 * np.pi / nb) < 1e-3
    hand_codes = M.rotated_codes(hp, nb).astype(int)  # (m, nb, C)
    body_codes = bp.codes.astype(int)
    ref = np.sum((body_codes[ii] - hand_codes[jj, bins]) ** 2, axis=-1)
    a, b = feats.pass1_rows
    got = M.cost_grid(M.splice_phase, a, b, rows, cols)
    assert (~edge).sum() > 0.95 * edge.size
    assert np.array_equal(got[~edge], ref[~edge])


def test_pass1_path_equals_the_naive_dtw(feats):
    a, b = feats.pass1_rows
    n = min(feats.n, feats.m)
    a, b = a[:n], b[:n]
    band = Band.from_constraints(n, n, 0.3, [(n // 2, n // 2 - 2, 3)])
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
    odd = _bins(
        np.array([np.nan, 1.0, np.nan, 0.0, 0.0]), np.array([1.0, np.nan, np.nan, 0.0, -1.0]), nb
    )
    assert ((odd >= 0) & (odd < nb)).all()  # never indexes outside the code table
    assert list(odd[3:]) == [0, 36]


# --------------------------------------------------------------------------------------------
# memory: blockwise kinematics and transfer give the same numbers
# --------------------------------------------------------------------------------------------


def test_take_markers_by_blocks_equal_the_whole_take(case):
    from engine.align.features import hand_frame, motion_markers, skeleton_yaw, take_markers
    from engine.model.roles import find_roles

    hand = case.hand
    roles = find_roles(hand.skeleton)
    frames = {s: hand_frame(hand, roles, s) for s in ("right", "left")}
    mk, yaw, rots = take_markers(hand, roles, frames, fps=30.0, keep_rotations=True, chunk=37)
    for s in frames:
        ref = motion_markers(hand, s, roles, fps=30.0, frame=frames[s]).markers
        assert np.array_equal(mk[s], ref)
    assert np.array_equal(yaw, skeleton_yaw(hand, roles))
    from engine.model.fastkin import forward_kinematics

    assert np.array_equal(rots, forward_kinematics(hand)[1])


def test_transfer_by_blocks_equals_one_block(case, feats, monkeypatch):
    res = P.align_passes(feats)
    whole = P.transfer(feats, res)
    monkeypatch.setattr(TR, "TRANSFER_CHUNK", 50)
    blocks = P.transfer(feats, res)
    assert np.array_equal(whole.rotations, blocks.rotations)
    assert np.array_equal(whole.translations, blocks.translations)
    from engine.model.fastkin import continuous

    q = np.random.default_rng(2).standard_normal((40, 3, 4))
    ref = continuous(q)
    TR.continuous_inplace(q)
    assert np.array_equal(q, ref)


def test_transfer_reads_only_the_hand_joints_it_needs_and_gives_the_same_take(
    case, feats, monkeypatch
):
    """The transfer samples and chains only the hand joints it reads (and their ancestors),
    rotations only: the spliced take is the one made from every joint, bit for bit, and
    the rotations are :func:`sample`'s and :func:`forward_kinematics`' floats."""
    from dataclasses import replace

    from engine.model.fastkin import forward_kinematics, sample, sample_rotations, world_rotations

    res = P.align_passes(feats)
    plan = P.plan_for(feats)
    hand = feats.hand
    used = TR.hand_joints_read(plan, hand.skeleton)
    assert 0 < used.size < hand.skeleton.n_joints  # the legs are not read
    for j in used:
        assert set(hand.skeleton.chain_to_root(int(j))) <= set(used.tolist())
    part = P.transfer(feats, res)
    every = np.arange(hand.skeleton.n_joints)
    monkeypatch.setattr(TR, "hand_joints_read", lambda plan, sk: every)
    whole = P.transfer(feats, res)
    assert np.array_equal(part.rotations, whole.rotations)
    assert np.array_equal(part.translations, whole.translations)
    t = np.r_[-2.0, np.linspace(0, hand.n_frames - 1, 257) * 0.997, hand.n_frames + 1.5]
    r_all, tr_all = sample(hand, t)
    assert np.array_equal(sample_rotations(hand, t, used), r_all[:, used])
    moved = replace(hand, rotations=r_all, translations=tr_all)
    world = world_rotations(r_all, hand.skeleton.parents)
    assert np.array_equal(world, forward_kinematics(moved)[1])


def test_rows_of_every_other_frame_fall_back_to_the_per_cell_metric(feats):
    a, b = feats.pass1_rows
    a, b = np.ascontiguousarray(a[::2]), np.ascontiguousarray(b[::2])
    assert PK.prepare(a, b).fallback
    n, m = a.shape[0], b.shape[0]
    band = Band.from_constraints(n, m, 0.4, [])
    cost = M.cost_grid(M.splice_phase, a, b, np.arange(n), np.arange(m))
    total, _, _ = dtw_banded(cost.tolist(), band.lo.tolist(), band.hi.tolist())
    assert align_features(a, b, band, metric="splice_phase").cost == total
    assert not PK.prepare(*feats.pass1_rows).fallback


def test_fast_sampling_and_normalising_match_the_numpy_ones(case):
    from engine.model import kinematics, rotations
    from engine.model.fastkin import normalize_inplace, sample

    hand = case.hand
    t = np.r_[-1.0, np.linspace(0, hand.n_frames - 1, 301), hand.n_frames + 3.5]
    r, tr = sample(hand, t)
    r_ref, tr_ref = kinematics.sample(hand, t)
    assert np.allclose(r, r_ref, atol=1e-12) and np.allclose(tr, tr_ref, atol=1e-12)
    q = np.random.default_rng(3).standard_normal((20, 4, 4))
    q[3, 1] = 0.0
    ref = rotations.normalize(q)
    normalize_inplace(q)
    assert np.allclose(q, ref, atol=1e-15)


# --------------------------------------------------------------------------------------------
# the row kernel's pieces (flat mask table, four-marker C sweeps, the window check) against
# the per-cell metric on real rows
# --------------------------------------------------------------------------------------------


def _rows_with_markers(markers, p, q, n_bins, step, hand):
    """``splice_phase`` rows (window mode) of real ``markers (F, K, 3)`` with the masks
    ``p``, ``q`` (body: ``(F,)``; hand: ``(F, n_bins)``)."""
    f, k, _ = markers.shape
    half = PK.WINDOW * k
    rows = np.zeros((f, PK.HEADER + 2 * half + 2 * n_bins))
    rows[:, 0], rows[:, 1], rows[:, 4] = half, n_bins, step
    M._raw_windows(markers, rows[:, PK.HEADER : PK.HEADER + 2 * half])
    off = PK.HEADER + 2 * half
    if hand:
        rows[:, off : off + 2 * n_bins : 2] = p
        rows[:, off + 1 : off + 2 * n_bins : 2] = q
    else:
        rows[:, off], rows[:, off + 1] = p, q
    return rows


@pytest.mark.parametrize("markers", [1, 2, 3, 4, 5, 6, 7, 8, 9])
def test_row_kernel_costs_equal_the_per_cell_metric_for_any_marker_count(feats, markers):
    """C rows are summed four markers per sweep, then one by one: every count from 1 to 9
    (real marker tracks, the take's own masks) gives the per-cell costs exactly."""
    bm, hm = feats.body_phase.markers, feats.hand_phase.markers
    reps = -(-markers // bm.shape[1])
    bm = np.concatenate([bm + 0.01 * r for r in range(reps)], axis=1)[:, :markers]
    hm = np.concatenate([hm - 0.02 * r for r in range(reps)], axis=1)[:, :markers]
    a0, b0 = feats.pass1_rows
    nb, off = int(a0[0, 1]), PK.HEADER + 2 * int(a0[0, 0])
    a = _rows_with_markers(bm, a0[:, off], a0[:, off + 1], nb, 0.25, hand=False)
    b = _rows_with_markers(
        hm, b0[:, off : off + 2 * nb : 2], b0[:, off + 1 : off + 2 * nb : 2], nb, 0.0, hand=True
    )
    state = PK.prepare(a, b)
    assert not state.fallback
    band = Band.from_constraints(feats.n, feats.m, 0.3, [])
    rows = np.unique(np.r_[0, 1, np.arange(0, feats.n, 13), feats.n - 1])
    got = PK.cost_rows(state, band.lo, band.hi, rows)
    for (i, cols), row in zip(_band_cells(band, rows), got, strict=True):
        ref = M.cost_grid(M.splice_phase, a, b, np.array([i]), cols)[0]
        assert np.array_equal(row, ref), f"{markers} markers, row {i}"


@pytest.mark.parametrize(
    ("reverse", "steps"), [(False, "same"), (True, "same"), (False, "varying")]
)
def test_forward_pass_equals_the_per_cell_forward_pass(feats, reverse, steps):
    """The whole forward pass (every band cell's backpointer, the last column, the last row
    inside its band, the total) with open ends, constraints and rows of both orders (backward passes reverse
    them) is the engine's per-cell forward pass with ``splice_phase``; also when the body
    rows' step costs change along the take (runs of equal ones: the row kernel's cost tables
    are remade only where the step cost changes)."""
    from engine.dtw import Ends
    from engine.dtw import kernels as KD

    a, b = feats.pass1_rows
    if steps == "varying":
        a = a.copy()
        runs = np.random.default_rng(3).choice([0.0, 0.25, 1.5], size=-(-a.shape[0] // 5))
        a[:, 4] = np.repeat(runs, 5)[: a.shape[0]]
        assert len(np.unique(a[:, 4])) == 3
    if reverse:
        a, b = np.ascontiguousarray(a[::-1]), np.ascontiguousarray(b[::-1])
    n, m = feats.n, feats.m
    band = Band.from_constraints(n, m, 0.3, [(n // 3, m // 3, 4)], open_ends=True)
    ends = Ends(n // 5, m // 5, 7.5).array()
    state = PK.prepare(a, b)
    assert not state.fallback
    out = []
    for kernel in ("rows", "cells"):
        bp = np.full(band.area, 9, np.uint8)
        last_col, last_row = np.empty(n), np.empty(m)
        args = (band.lo, band.hi, band.start, 0, n, bp, np.empty(1), 0, ends, last_col, last_row)
        if kernel == "rows":
            res = PK.forward(state, *args)
        else:
            res = KD.forward_metric(M.splice_phase, a, b, *args)
        out.append((res, bp, last_col, last_row[band.lo[-1] : band.hi[-1] + 1]))
    (r1, *x1), (r2, *x2) = out
    assert r1 == r2 and r1[0] == -1
    for u, v in zip(x1, x2, strict=True):
        assert np.array_equal(u, v)


def _padded_coords_numpy(rows, half):
    """The window check as numpy comparisons (the reference of the numba one)."""
    f, k = rows.shape[0], half // PK.WINDOW
    win = rows[:, PK.HEADER : PK.HEADER + 2 * half].reshape(f, 2, PK.WINDOW, k)
    for step in (1, -1):
        pad = np.empty((f + 4, 2, k))
        pad[2 : f + 2] = win[:, :, 2]
        for d in range(PK.WINDOW):
            off = step * (d - 2)
            if off < 0:
                pad[2 + off] = win[0][:, d]
            elif off > 0:
                pad[f + 1 + off] = win[f - 1][:, d]
        if all(
            np.array_equal(win[:, :, d], pad[2 + step * (d - 2) : 2 + step * (d - 2) + f])
            for d in range(PK.WINDOW)
        ):
            return pad[:, 0].astype(np.float32), pad[:, 1].astype(np.float32)
    return None


def test_window_check_accepts_takes_parts_and_reversals_only(feats):
    a, _ = feats.pass1_rows
    half = int(a[0, 0])
    cases = {
        "whole": a,
        "reversed": a[::-1],
        "part": a[40:170],
        "reversed part": a[170:40:-1],
        "every other": a[::2],
        "shuffled": a[np.r_[1, 0, 2 : a.shape[0]]],
    }
    for name, rows in cases.items():
        got, ref = (
            PK._padded_coords(np.ascontiguousarray(rows), half),
            _padded_coords_numpy(rows, half),
        )
        assert (got is None) == (ref is None) == (name in ("every other", "shuffled")), name
        if ref is not None:
            assert all(np.array_equal(g, r) for g, r in zip(got, ref, strict=True)), name


@pytest.mark.parametrize("bad", [np.nan, -np.inf])
def test_forward_pass_reports_the_first_row_with_a_bad_cost_as_the_per_cell_pass(feats, bad):
    """A body row whose cost is NaN or -inf (its step cost) stops the row kernel at that row,
    as the per-cell forward pass does, whether the row is done alone (narrow, at a
    matching point) or interleaved with the next (wide); a row of +inf costs is allowed."""
    from engine.dtw import Ends
    from engine.dtw import kernels as KD

    a0, b = feats.pass1_rows
    n, m = feats.n, feats.m
    band = Band.from_constraints(n, m, 0.3, [(n // 3, m // 3, 4)], open_ends=True)
    ends = Ends(n // 5, m // 5, 7.5).array()
    narrow = int(np.argmin(band.hi - band.lo))
    assert band.hi[narrow] - band.lo[narrow] < 32 <= band.hi[n // 2 + 7] - band.lo[n // 2 + 7]
    for row in (narrow, n // 2 + 7, n // 2 + 8, n - 1):
        a = a0.copy()
        a[n - 3, 4] = np.inf  # allowed: those cells are forbidden, not bad
        a[row, 4] = bad
        got = []
        for kernel in ("rows", "cells"):
            bp = np.zeros(band.area, np.uint8)
            args = (band.lo, band.hi, band.start, 0, n, bp, np.empty(1), 0, ends)
            last = (np.empty(n), np.empty(m))
            if kernel == "rows":
                got.append(PK.forward(PK.prepare(a, b), *args, *last)[0])
            else:
                got.append(KD.forward_metric(M.splice_phase, a, b, *args, *last)[0])
        assert got == [row, row], (row, got)


def test_two_popcount_cost_and_cost_table_equal_the_sum_of_squared_differences():
    """The row kernel's cost (Z, G masks, two popcounts, a per-row table of floats) is
    Σ (s − s')² + step for any ternary codes, and ``cell_cost`` (P, Q masks) agrees."""
    rng = np.random.default_rng(7)
    s = rng.integers(-1, 2, size=(400, 48))
    t = rng.integers(-1, 2, size=(400, 48))
    s[:20] = 0  # holds: all zero
    t[20:40] = -s[20:40]  # opposite signs everywhere: the largest cost
    p, q = M.pack_codes(s)
    p2, q2 = M.pack_codes(t)
    tab = np.empty(PK._TABLE)
    PK._cost_table(0.75, tab)
    for k in range(s.shape[0]):
        want = int(((s[k] - t[k]) ** 2).sum())
        P, Q, P2, Q2 = (np.uint64(v[k]) for v in (p, q, p2, q2))
        assert int(PK.cell_cost(P, Q, P2, Q2)) == want
        codes = np.array([P2 | Q2, P2], np.uint64)  # the hand's (Z, G) at index 0
        assert PK._index_cost(P | Q, P, tab, codes, 0) == float(want) + 0.75


def test_phase_rows_write_the_same_hand_masks_as_rotated_packed_codes(feats):
    """``phase_rows`` writes the rotated masks into its rows in place: the same values as
    the (F, B) arrays of ``rotated_packed_codes``."""
    _, b = M.phase_rows(feats.body_phase, feats.hand_phase, n_bins=feats.n_bins)
    hp, hq = M.rotated_packed_codes(feats.hand_phase, feats.n_bins)
    off = PK.HEADER + int(b[0, 0]) * 2
    assert np.array_equal(b[:, off : off + 2 * feats.n_bins : 2], hp)
    assert np.array_equal(b[:, off + 1 : off + 2 * feats.n_bins : 2], hq)


def test_converted_hand_masks_are_the_rows_masks_at_every_bin_and_frame(feats):
    """Each (θ bin, hand frame)'s masks in the forward pass's ring, where the kernel reads
    them (``_convert``, then ``_mask_index`` of the frame's ring slot), are the rows'
    (P ∨ Q, P), forward and reversed, in a ring smaller than the take (slots reused) and
    converted in pieces as the forward pass does."""
    a, b = feats.pass1_rows
    nb, off = int(b[0, 1]), PK.HEADER + 2 * int(b[0, 0])
    p = b[:, off : off + 2 * nb : 2].astype(np.uint64)  # (m, nb)
    q = b[:, off + 1 : off + 2 * nb : 2].astype(np.uint64)
    m = b.shape[0]
    rmask = PK._ring_mask(m // 3)
    assert rmask + 1 < m
    for state, sl in (
        (PK.prepare(a, b), slice(None)),
        (PK.prepare(a, b).reversed(), slice(None, None, -1)),
    ):
        want_z, want_g = (p | q)[sl], p[sl]
        rows_ = PK._mask_rows(state.hand[4])
        codes = np.zeros((rmask + 1) * nb * 2, np.uint64)
        done = 0
        for top in range(rmask // 2, m + rmask // 2, rmask // 2):  # a ring's worth at a time
            first = done
            done = PK._convert(rows_, nb, done, min(top, m - 1), codes, rmask)
            frames = np.arange(max(done - rmask - 1, 0), done)
            assert frames[0] <= first
            bins, fr = np.meshgrid(np.arange(nb), frames)
            at = PK._mask_index.py_func(bins, fr & rmask, nb).astype(np.int64)
            assert np.array_equal(codes[at], want_z[frames])
            assert np.array_equal(codes[at + 1], want_g[frames])
        assert done == m
