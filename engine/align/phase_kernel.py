"""Pass-1 kernel: the ``splice_phase`` cost of a whole band row at a time (docs/method.md §2).

:func:`engine.align.metrics.splice_phase` computes one cell: θ of eq. 7 from the two
5-frame windows (a 5·K-point complex dot product), then the sign-code cost of the
hand take's codes turned by θ (three popcounts). Called once per band cell, the θ
dot product dominates (about 42 ns per cell). This module computes the same costs
a band row at a time, with the same arithmetic, in about a tenth of the time:

* **θ by diagonal sums.** With ``x_f = (x + i z)`` the K horizontal marker
  positions of frame ``f`` (complex), eq. 7's sums over the centred windows are
  ``Σ_d C(i+d, j+d) − L conj(μ_i) ν_j`` with ``C(p, q) = Σ_k conj(x_p,k) y_q,k``
  (d = −2..2, frames clipped at the ends, ``μ``/``ν`` the window centroids,
  ``L = 5K`` points). Every ``C`` value serves five cells of one diagonal, so a
  band row computes one new row of ``C`` (K complex products per cell, a loop
  over columns that vectorises) and keeps the last five in a ring buffer.
* **θ bins without libm**: a polynomial ``atan2`` (about 1e-5 rad) and a floor,
  written without branches so the column loop vectorises.
* **Costs inside the recurrence.** A row's θ bins become indices into the hand's mask
  table (one vectorised loop); the DTW recurrence (copies of ``engine.dtw``'s row and
  pair kernels) forms each cell's cost where it uses it, its popcounts filling the idle
  slots of the serial min/add chain, and prefetches the masks 64 cells ahead (θ drifts,
  so the reads wander over the table where the hardware prefetchers miss them).
* **Bit-parallel codes.** Each frame's 6K ternary sign codes are two bit masks
  (P: +1, Q: −1); the hand take's, for every θ bin, are in its rows (float64). The
  forward pass converts the hand frames its band reaches, as it reaches them, into a
  ring of frames (``(R, n_bins, 2)``, frame by frame: a band row reads one line per
  hand frame, and the rows after it read the same lines), so no ``(m, n_bins, 2)``
  table is written (16.6 MB for a 2-minute take: fresh pages cost a splice ~11 ms). ``Σ (s − s')² = |P ⊕ P'| + |Q ⊕ Q'| + 2 |(P ∧ Q') ∨ (Q ∧ P')|``
  with a hardware popcount.

Exactness: :func:`theta_bin` and :func:`cell_cost` are the *only* θ and cost
arithmetic; the per-cell metric (:func:`engine.align.metrics.splice_phase`, used by
views, reports and tests) calls them with the same operands in the same order
(no fast-math: no contraction, no reassociation; the five diagonal terms are
summed symmetrically, ``((C0 + C4) + (C1 + C3)) + C2``, so a reversed problem
gives bit-identical sums). The row kernel therefore gives exactly the per-cell
costs (tests compare every cell), and the DTW path is the same.

Plugged into :mod:`engine.dtw` as the ``"splice_phase"`` metric's row kernel
(``register_metric(..., prepare=prepare, forward=forward)``): ``align_features``,
the incremental ``Aligner`` and its backward passes all use it.
"""

from __future__ import annotations

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from engine.dtw import kernels as K

#: frames in the eq.-7 window (centre ± 2)
WINDOW = 5
#: header of a ``splice_phase`` row: [half, n_bins, mode, yaw_bin, step]
HEADER = 5
MODE_WINDOW = 0
MODE_YAW = 1

_TWO_PI = 2.0 * np.pi
_RING = 8  # ring-buffer rows of C (five in use; a power of two)
#: cells ahead whose hand masks the recurrence prefetches
AHEAD = 64
#: rows ahead whose values :func:`_scan` prefetches
ROWS_AHEAD = 8


@intrinsic
def popcount(typingctx, x):
    """Hardware population count of a uint64 (``llvm.ctpop``)."""
    if not isinstance(x, types.Integer):
        return None
    sig = types.uint64(types.uint64)

    def codegen(context, builder, signature, args):
        value = builder.zext(args[0], ir.IntType(64)) if args[0].type.width < 64 else args[0]
        return builder.ctpop(value)

    return sig, codegen


@intrinsic
def prefetch(typingctx, arr, idx):
    """Hint the CPU to bring ``arr[idx]``'s cache line in (``llvm.prefetch``, read, keep in
    all levels). Never faults: any index is allowed (no bounds, no wraparound). Declared
    unmangled: LLVM's auto-upgrade gives it the pointer type of its version (``p0`` or
    ``p0i8``)."""
    if not isinstance(arr, types.Array) or not isinstance(idx, types.Integer):
        return None
    sig = types.void(arr, idx)

    def codegen(context, builder, signature, args):
        ary = context.make_array(signature.args[0])(context, builder, args[0])
        i8p = ir.IntType(8).as_pointer()
        i32 = ir.IntType(32)
        fnty = ir.FunctionType(ir.VoidType(), [i8p, i32, i32, i32])
        fn = cgutils.get_or_insert_function(builder.module, fnty, "llvm.prefetch")
        ptr = builder.bitcast(builder.gep(ary.data, [args[1]]), i8p)
        builder.call(fn, [ptr, i32(0), i32(3), i32(1)])
        return context.get_dummy_value()

    return sig, codegen


_F0 = np.float32(0.0)
_C1 = np.float32(-0.0464964749)
_C2 = np.float32(0.15931422)
_C3 = np.float32(-0.327622764)
_HALF_PI = np.float32(1.5707963267948966)
_PI = np.float32(3.141592653589793)
_HALF = np.float32(0.5)


@numba.njit(cache=True, nogil=True, inline="always")
def theta_bin(num, den, nb):
    """θ bin of ``atan2(num, den)`` (float32 operands): ``floor(θ nb / 2π + 0.5) mod nb``,
    θ to about 1e-5 rad (a polynomial, no libm call).

    float32 and branch-free (selects only) so column loops vectorise 8 wide. Returns
    int32 in ``0..nb-1`` for any input (NaN included: never outside the code table).
    """
    ax = abs(den)
    ay = abs(num)
    mx = max(ax, ay)
    mn = min(ax, ay)
    a = mn / mx if mx > _F0 else _F0
    s = a * a
    r = ((_C1 * s + _C2) * s + _C3) * s * a + a
    r = _HALF_PI - r if ay > ax else r
    r = _PI - r if den < _F0 else r
    r = -r if num < _F0 else r
    x = np.floor(r * np.float32(nb / _TWO_PI) + _HALF)
    fnb = np.float32(nb)
    x = x + fnb if x < _F0 else x
    x = x if (x >= _F0 and x < fnb) else _F0  # NaN, or the wrap at exactly +π
    return np.int32(x)


@numba.njit(cache=True, nogil=True, inline="always")
def zg_cost(z, g, z2, g2):
    """Σ (s − s')² of ternary codes packed as masks Z (s ≠ 0) and G (s = +1) (uint64):
    ``|Z ⊕ Z'| + 4 |(G ⊕ G') ∧ Z ∧ Z'|`` (one code zero: 1; opposite signs: 4)."""
    return popcount(z ^ z2) + (popcount((g ^ g2) & z & z2) << np.uint64(2))


@numba.njit(cache=True, nogil=True, inline="always")
def cell_cost(p, q, p2, q2):
    """Σ (s − s')² of ternary codes packed as masks (P, Q) and (P', Q') (uint64, P ∧ Q = 0):
    :func:`zg_cost` of ``Z = P ∨ Q``, ``G = P`` (the row kernel's masks)."""
    return zg_cost(p | q, p, p2 | q2, p2)


@numba.njit(cache=True, nogil=True, inline="always")
def window_means(row, half):
    """Centroid ``(x, z)`` of the eq.-7 window stored in a ``splice_phase`` row."""
    sx = 0.0
    sz = 0.0
    for t in range(half):
        sx += row[HEADER + t]
        sz += row[HEADER + half + t]
    return sx / half, sz / half


@numba.njit(cache=True, nogil=True, inline="always")
def _slot(body_row, hand_row, half, k, d):
    """``C`` of window slot ``d``: Σ_c conj(x_c) y_c over the K markers (real, imaginary)."""
    re = np.float32(0.0)
    im = np.float32(0.0)
    for c in range(k):
        t = d * k + c
        bx = np.float32(body_row[HEADER + t])
        bz = np.float32(body_row[HEADER + half + t])
        hx = np.float32(hand_row[HEADER + t])
        hz = np.float32(hand_row[HEADER + half + t])
        re += bx * hx + bz * hz
        im += bx * hz - hx * bz
    return re, im


@numba.njit(cache=True, nogil=True)
def cell_theta_sums(body_row, hand_row, half):
    """``(num, den)`` of eq. 7 for one cell from the two rows' windows (the row kernel's
    arithmetic, term by term)."""
    k = half // WINDOW
    r0, i0 = _slot(body_row, hand_row, half, k, 0)
    r1, i1 = _slot(body_row, hand_row, half, k, 1)
    r2, i2 = _slot(body_row, hand_row, half, k, 2)
    r3, i3 = _slot(body_row, hand_row, half, k, 3)
    r4, i4 = _slot(body_row, hand_row, half, k, 4)
    re = ((r0 + r4) + (r1 + r3)) + r2
    im = ((i0 + i4) + (i1 + i3)) + i2
    bmx, bmz = window_means(body_row, half)
    hmx, hmz = window_means(hand_row, half)
    mbx = np.float32(bmx)
    mbz = np.float32(bmz)
    mhx = np.float32(hmx)
    mhz = np.float32(hmz)
    n = np.float32(half)
    den = re - n * (mbx * mhx + mbz * mhz)
    num = im - n * (mbx * mhz - mhx * mbz)
    return num, den


# --------------------------------------------------------------------------------------------
# per-problem data (from the rows) and the forward pass
# --------------------------------------------------------------------------------------------


@numba.njit(cache=True, nogil=True)
def _scan(rows, half, width, window, step):
    """One pass over a take's rows (each row's cache lines once): the masks Z = P ∨ Q and
    G = P (``(F, width, 2)`` uint64, frame by frame, see :func:`zg_cost`), the yaw bins and
    steps ``(F,)``, and, when ``window``, the frames the eq.-7 windows hold: ``(2, (F + 4) K)``
    float64 (x, then z; padded frame ``p``'s ``K`` markers at ``p K``: row ``r``'s own frame
    at ``p = r + 2``, two frames beyond each end from the end rows' windows) if slot ``d``
    of every row ``r`` holds padded frame ``r + 2 + step (d - 2)`` (``step`` 1: the rows are
    consecutive frames of a take, -1: of a take reversed), else ``(2, 0)`` (returned at
    the first row that differs). Values compared with ``==`` (a NaN never matches).

    Row ``s``'s windows are checked two rows after its own frame is stored (they reach
    padded frame ``s + 4``), while its lines are still in cache."""
    f = rows.shape[0]
    k = half // WINDOW
    pq = np.empty((f, width, 2), np.uint64)
    yaw = np.empty(f, np.int64)
    cost = np.empty(f)
    pad = np.empty((2, (f + 4) * k if window else 0))
    off = HEADER + 2 * half
    if window:
        for x in range(2):  # the frames beyond the ends, from the end rows' windows
            for d in range(WINDOW):
                o = step * (d - 2)
                src = HEADER + x * half + d * k
                if o < 0:
                    for c in range(k):
                        pad[x, (2 + o) * k + c] = rows[0, src + c]
                elif o > 0:
                    for c in range(k):
                        pad[x, (f + 1 + o) * k + c] = rows[f - 1, src + c]
    flat = rows.reshape(-1)
    used = off + 2 * width  # the columns read: rows' lines prefetched ROWS_AHEAD rows ahead
    for r in range(f + 2):
        if r + ROWS_AHEAD < f:  # (a row's lines are far apart: the prefetchers miss them)
            base = (r + ROWS_AHEAD) * rows.shape[1]
            for t in range(0, used, 8):
                prefetch(flat, np.uint64(base + t))
        if r < f:
            yaw[r] = int(rows[r, 3])
            cost[r] = rows[r, 4]
            src = rows[r, off : off + 2 * width]
            dst = pq[r]
            for b in range(width):  # (contiguous in and out: vectorises)
                p = np.uint64(src[2 * b])
                dst[b, 0] = p | np.uint64(src[2 * b + 1])
                dst[b, 1] = p
            if window:
                for x in range(2):
                    for c in range(k):
                        pad[x, (r + 2) * k + c] = rows[r, HEADER + x * half + 2 * k + c]
        s = r - 2
        if window and s >= 0:
            bad = 0
            for x in range(2):
                if step == 1:  # slots 0..4 = padded frames s..s+4: one contiguous run
                    got = rows[s, HEADER + x * half : HEADER + (x + 1) * half]
                    want = pad[x, s * k : s * k + half]
                    for t in range(half):
                        bad += got[t] != want[t]
                    continue
                for d in range(WINDOW):
                    src = HEADER + x * half + d * k
                    dst = (s + 2 + step * (d - 2)) * k
                    for c in range(k):
                        bad += rows[s, src + c] != pad[x, dst + c]
            if bad:
                return np.empty((2, 0)), pq, yaw, cost
    return pad, pq, yaw, cost


@numba.njit(cache=True, nogil=True)
def _window_sums(pad, half, f, step):
    """The eq.-7 window centroids of every row from :func:`_scan`'s frames (of ``step``):
    ``(F,)`` x and z (float32, :func:`window_means`' sums: values in the row's order, one
    after another), and the frames ``(2, K, F + 4)`` float32, marker by marker (columns
    contiguous)."""
    k = half // WINDOW
    cols = np.empty((2, k, f + 4))
    for p in range(f + 4):
        for x in range(2):
            for c in range(k):
                cols[x, c, p] = pad[x, p * k + c]
    sx = np.zeros(f)
    sz = np.zeros(f)
    for d in range(WINDOW):  # slot d of row r is padded frame r + o
        o = 2 + step * (d - 2)
        for c in range(k):
            cx = cols[0, c, o : o + f]
            cz = cols[1, c, o : o + f]
            for r in range(f):  # rows side by side: vectorises
                sx[r] += cx[r]
                sz[r] += cz[r]
    mx = np.zeros(f, np.float32)
    mz = np.zeros(f, np.float32)
    for r in range(f if half > 0 else 0):  # (no windows: centroids 0, as before)
        mx[r] = np.float32(sx[r] / half)
        mz[r] = np.float32(sz[r] / half)
    return mx, mz, cols.astype(np.float32)


def _take_arrays(rows: np.ndarray, half: int, width: int, window: bool):
    """Per-frame arrays of one take's rows: ``(x, z, mx, mz, pq, yaw, step)`` with the
    padded frame coordinates ``x``, ``z`` ``(K, F + 4)`` float32 (marker by marker; zeros
    unless ``window``), the window centroids ``mx``, ``mz`` ``(F,)`` float32, the masks
    ``pq`` ``(F, width, 2)`` and the yaw bins and step costs ``(F,)``; None when ``window``
    and the rows' windows are not those of consecutive frames.

    Rows of a whole take, of a contiguous part of one, or of either reversed (the
    backward passes) qualify; any other selection of rows (e.g. every other frame) does
    not, and the caller falls back to the per-cell metric.
    """
    rows = np.ascontiguousarray(rows, dtype=np.float64)
    f, k = rows.shape[0], half // WINDOW
    if not window:
        _, pq, yaw, cost = _scan(rows, half, width, False, 1)
        zeros = np.zeros((k, f + 4), np.float32)
        return zeros, zeros, np.zeros(f, np.float32), np.zeros(f, np.float32), pq, yaw, cost
    for step in (1, -1):  # window slot d holds row r + step (d - 2)
        pad, pq, yaw, cost = _scan(rows, half, width, True, step)
        if pad.shape[1]:
            mx, mz, cols = _window_sums(pad, half, f, step)
            return cols[0], cols[1], mx, mz, pq, yaw, cost
    return None


def _padded_coords(rows: np.ndarray, half: int):
    """x and z ``(F + 4, K)`` float32 of the frames the rows' windows hold, in row order
    (padded index ``p`` = row ``p - 2``'s own frame; two frames beyond each end from the
    end rows' windows), or None when the windows are not those of consecutive frames
    (:func:`_take_arrays`)."""
    got = _take_arrays(rows, half, 0, True)
    return None if got is None else (got[0].T.copy(), got[1].T.copy())


class PhaseProblem:
    """The row kernel's arrays for one (body rows, hand rows) pair (see :func:`prepare`).

    ``fallback`` is True when the rows are not consecutive frames of a take (then the
    forward pass uses the per-cell metric; same costs, slower).
    """

    def __init__(self, a: np.ndarray, b: np.ndarray):
        half, nb, mode = int(a[0, 0]), int(a[0, 1]), int(a[0, 2])
        self.half, self.nb, self.mode = half, nb, mode
        self.n, self.m = a.shape[0], b.shape[0]
        self.fallback = False
        if 2 * nb * self.m >= 2**31:  # a mask index (_mask_index) would not fit int32
            self.fallback, self.a, self.b = True, a, b
            return
        window = mode == MODE_WINDOW
        body = _take_arrays(a, half, 1, window)
        b = np.ascontiguousarray(b, dtype=np.float64)
        hand = _take_arrays(b, half, 0, window) if body is not None else None
        if body is None or hand is None:
            self.fallback, self.a, self.b = True, a, b
            return
        bx, bz, bmx, bmz, bpq, byaw, bstep = body
        hx, hz, hmx, hmz, _, hyaw, _ = hand
        bnz = np.ascontiguousarray(bpq[:, 0, 0])  # Z: code ≠ 0
        bpos = np.ascontiguousarray(bpq[:, 0, 1])  # G: code = +1
        # body frames (n + 4, K), hand frames (K, m + 4): each kernel's reads contiguous
        self.body = (bx.T.copy(), bz.T.copy(), bmx, bmz, bnz, bpos, byaw, bstep)
        # the hand's masks stay in its rows: (m, 2 nb) float64 (P, Q of every bin), a view
        # (the forward pass converts the frames its band reaches, see _convert)
        off = HEADER + 2 * half
        self.hand = (hx, hz, hmx, hmz, b[:, off : off + 2 * nb], hyaw)

    def args(self) -> tuple:
        return (*self.body, *self.hand, self.mode, self.nb, self.half)

    def kernel_args(self) -> tuple:
        """:meth:`args` with the hand's masks as :func:`_convert` reads them."""
        hx, hz, hmx, hmz, masks, hyaw = self.hand
        return (
            *self.body,
            hx,
            hz,
            hmx,
            hmz,
            _mask_rows(masks),
            hyaw,
            self.mode,
            self.nb,
            self.half,
        )

    def reversed(self) -> PhaseProblem | None:
        """The state of both takes' rows reversed (a backward pass), made from this one
        without the rows: every array is per frame (the padded coordinates keep two
        frames beyond each end, so they reverse too), so it is this one's arrays in the
        opposite frame order, the same as ``PhaseProblem(a[::-1], b[::-1])``. None for the
        per-cell fallback (it needs the rows themselves)."""
        if self.fallback:
            return None
        out = PhaseProblem.__new__(PhaseProblem)
        out.half, out.nb, out.mode, out.n, out.m = self.half, self.nb, self.mode, self.n, self.m
        out.fallback = False
        out.body = tuple(np.ascontiguousarray(x[::-1]) for x in self.body)
        hx, hz, hmx, hmz, masks, hyaw = self.hand
        out.hand = (
            np.ascontiguousarray(hx[:, ::-1]),
            np.ascontiguousarray(hz[:, ::-1]),
            np.ascontiguousarray(hmx[::-1]),
            np.ascontiguousarray(hmz[::-1]),
            masks[::-1],  # a view with a negative row stride: no copy
            np.ascontiguousarray(hyaw[::-1]),
        )
        return out


def prepare(a: np.ndarray, b: np.ndarray) -> PhaseProblem:
    """Row-kernel data for ``splice_phase`` rows ``a`` (body, ``(n, d)``) and ``b`` (hand)."""
    return PhaseProblem(a, b)


def forward(
    state: PhaseProblem, lo, hi, start, i0, i1, bp, gamma, keep_gamma, ends, last_col, last_row
):
    """Rows ``i0..i1-1`` of the DTW forward pass (as ``engine.dtw.kernels.forward_*``,
    open ends included: ``ends``, ``last_col``, ``last_row``)."""
    if state.fallback:  # the per-cell metric from the registry (engine.align.metrics registers
        # it; importing engine.align.metrics here would make an import cycle)
        splice_phase = K.get_metric("splice_phase").cell

        return K.forward_metric(
            splice_phase,
            state.a,
            state.b,
            lo,
            hi,
            start,
            i0,
            i1,
            bp,
            gamma,
            keep_gamma,
            ends,
            last_col,
            last_row,
        )
    return _forward(
        *state.kernel_args(), lo, hi, start, i0, i1, bp, gamma, keep_gamma, ends, last_col, last_row
    )


def cost_rows(state: PhaseProblem, lo, hi, rows) -> list[np.ndarray]:
    """Local costs ``(hi[i] - lo[i] + 1,)`` of band rows ``i`` in ``rows``, by the row kernel."""
    lo = np.ascontiguousarray(lo, np.int64)
    hi = np.ascontiguousarray(hi, np.int64)
    out = []
    for i in rows:
        crow = _one_row(*state.kernel_args(), lo, hi, int(i))
        out.append(crow[lo[i] : hi[i] + 1].copy())
    return out


@numba.njit(cache=True, nogil=True, inline="always")
def _c_sweep4(p, c, clo, w, bx, bz, hx, hz, re, im, first):
    """Add markers ``c..c+3`` to ring row slices ``re``, ``im`` (from 0 when ``first``), one
    after another (``_slot``'s order)."""
    xa = bx[p, c]
    za = bz[p, c]
    xb = bx[p, c + 1]
    zb = bz[p, c + 1]
    xc = bx[p, c + 2]
    zc = bz[p, c + 2]
    xd = bx[p, c + 3]
    zd = bz[p, c + 3]
    hxa = hx[c, clo : clo + w]
    hza = hz[c, clo : clo + w]
    hxb = hx[c + 1, clo : clo + w]
    hzb = hz[c + 1, clo : clo + w]
    hxc = hx[c + 2, clo : clo + w]
    hzc = hz[c + 2, clo : clo + w]
    hxd = hx[c + 3, clo : clo + w]
    hzd = hz[c + 3, clo : clo + w]
    if first:
        for q in range(w):
            r = (_F0 + (xa * hxa[q] + za * hza[q])) + (xb * hxb[q] + zb * hzb[q])
            re[q] = (r + (xc * hxc[q] + zc * hzc[q])) + (xd * hxd[q] + zd * hzd[q])
            t = (_F0 + (xa * hza[q] - hxa[q] * za)) + (xb * hzb[q] - hxb[q] * zb)
            im[q] = (t + (xc * hzc[q] - hxc[q] * zc)) + (xd * hzd[q] - hxd[q] * zd)
    else:
        for q in range(w):
            r = (re[q] + (xa * hxa[q] + za * hza[q])) + (xb * hxb[q] + zb * hzb[q])
            re[q] = (r + (xc * hxc[q] + zc * hzc[q])) + (xd * hxd[q] + zd * hzd[q])
            t = (im[q] + (xa * hza[q] - hxa[q] * za)) + (xb * hzb[q] - hxb[q] * zb)
            im[q] = (t + (xc * hzc[q] - hxc[q] * zc)) + (xd * hzd[q] - hxd[q] * zd)


@numba.njit(cache=True, nogil=True)
def _c_row(p, clo, chi, bx, bz, hx, hz, cre, cim):
    """Ring row ``p`` of C over padded hand columns ``clo..chi`` (float32).

    Markers are added one after another (``_slot``'s order, from 0), four per sweep over
    the columns (fewer passes over the ring row); loops index slices from 0, so numba
    emits no negative-index wraparound code and they vectorise.
    """
    s = p & (_RING - 1)
    w = chi - clo + 1
    re = cre[s, clo : chi + 1]
    im = cim[s, clo : chi + 1]
    k = bx.shape[1]
    c = 0
    while c + 3 < k:
        _c_sweep4(p, c, clo, w, bx, bz, hx, hz, re, im, c == 0)
        c += 4
    if c == 0:
        for q in range(w):
            re[q] = _F0
            im[q] = _F0
    while c < k:
        xa = bx[p, c]
        za = bz[p, c]
        hxa = hx[c, clo : chi + 1]
        hza = hz[c, clo : chi + 1]
        for q in range(w):
            re[q] += xa * hxa[q] + za * hza[q]
            im[q] += xa * hza[q] - hxa[q] * za
        c += 1


@numba.njit(cache=True, nogil=True)
def _ensure_c(i, next_p, i0, i1, lo, hi, bx, bz, hx, hz, cre, cim):
    """Compute ring rows up to ``i + 4``; returns the next ring row to compute."""
    while next_p <= i + 4:
        r0 = max(next_p - 4, i0)
        r1 = min(next_p, i1 - 1)
        clo = lo[r0] + next_p - r0
        chi = hi[r0] + next_p - r0
        for r in range(r0 + 1, r1 + 1):
            clo = min(clo, lo[r] + next_p - r)
            chi = max(chi, hi[r] + next_p - r)
        _c_row(next_p, clo, chi, bx, bz, hx, hz, cre, cim)
        next_p += 1
    return next_p


@numba.njit(cache=True, nogil=True)
def _ring_mask(frames):
    """``R - 1`` for the ring of hand frames' masks: ``R`` the power of two above ``frames``
    (the most hand frames in use at once: a frame's slot is not reused while in use)."""
    r = 1
    while r <= frames:
        r *= 2
    return r - 1


def _mask_rows(masks: np.ndarray) -> tuple:
    """The hand's masks view ``(m, 2 nb)`` (``PhaseProblem.hand[4]``, rows of a contiguous
    buffer, row stride positive or, reversed, negative) as :func:`_convert` reads it:
    ``(flat, start, row_stride)``, a contiguous 1-D view of the rows' span, frame ``j``'s
    values at ``flat[start + j row_stride :][: 2 nb]`` (contiguous: the conversion
    vectorises)."""
    m, w = masks.shape
    if m == 0 or masks.strides[1] != masks.itemsize or masks.strides[0] % masks.itemsize:
        masks = np.ascontiguousarray(masks)
    rs = masks.strides[0] // masks.itemsize
    if m <= 1:
        return np.ascontiguousarray(masks).reshape(-1), 0, w
    first = masks[m - 1] if rs < 0 else masks[0]  # the row lowest in memory
    span = (m - 1) * abs(rs) + w  # inside the rows' buffer: from that row to the other end
    flat = np.lib.stride_tricks.as_strided(first, shape=(span,), strides=(masks.itemsize,))
    return flat, (m - 1) * -rs if rs < 0 else 0, rs


@numba.njit(cache=True, nogil=True)
def _convert(masks, nb, j0, j1, codes, rmask):
    """Hand frames ``j0..j1``'s masks Z = P ∨ Q and G = P of every θ bin into ring slot
    ``j & rmask`` of ``codes`` (``(R, nb, 2)`` uint64 flat, frame by frame; indexed by
    :func:`_mask_index`), from ``masks`` = :func:`_mask_rows` of the rows' P, Q of every
    bin. Returns the next frame to convert.

    The forward pass converts the frames its band reaches as it goes, instead of a
    ``(m, nb, 2)`` table in ``prepare``: the ring stays in cache, and a splice writes no
    16.6 MB table to fresh pages (a 2-minute hand take at 72 bins; ~4,000 page faults).
    A frame's 2 nb values convert in one contiguous loop (vectorised); rows
    :data:`ROWS_AHEAD` ahead are prefetched (18 lines of masks each)."""
    flat, start, rs = masks
    n = 2 * nb
    for j in range(j0, j1 + 1):
        ahead = start + (j + ROWS_AHEAD) * rs  # (past the take's end: a prefetch never faults)
        for t in range(0, n, 8):
            prefetch(flat, np.int64(ahead + t))
        s0 = start + j * rs
        src = flat[s0 : s0 + n]
        d0 = (j & rmask) * n
        dst = codes[d0 : d0 + n]
        for t in range(n):
            dst[t] = np.uint64(src[t])
        for b in range(nb):
            p = dst[2 * b]
            dst[2 * b] = p | dst[2 * b + 1]
            dst[2 * b + 1] = p
    return max(j0, j1 + 1)


@numba.njit(cache=True, nogil=True, inline="always")
def _mask_index(b, j, nb):
    """Index in ``codes`` of hand column ``j``'s Z mask turned to θ bin ``b`` (its G mask
    follows): ``2 (j nb + b)``, int32 (:class:`PhaseProblem` checks that it fits)."""
    return np.int32(2) * (np.int32(j) * np.int32(nb) + np.int32(b))


@numba.njit(cache=True, nogil=True)
def _theta_cells(
    i, lo_i, hi_i, bmx, bmz, byaw, hmx, hmz, hyaw, mode, nb, half, cre, cim, cells, rmask
):
    """``cells[lo_i..hi_i]`` = :func:`_mask_index` of each cell's θ bin in band row ``i``
    (hand frame ``j`` at ring slot ``j & rmask``, see :func:`_convert`)
    (ring rows ``i..i+4`` ready in window mode). A loop of selects and float32 arithmetic
    only: it vectorises."""
    w = hi_i - lo_i + 1
    out = cells[lo_i : hi_i + 1]
    if mode == MODE_WINDOW:
        # ring rows i..i+4 at columns j..j+4, as slices from lo_i (no wraparound code)
        r0 = cre[i & (_RING - 1), lo_i:]
        r1 = cre[(i + 1) & (_RING - 1), lo_i + 1 :]
        r2 = cre[(i + 2) & (_RING - 1), lo_i + 2 :]
        r3 = cre[(i + 3) & (_RING - 1), lo_i + 3 :]
        r4 = cre[(i + 4) & (_RING - 1), lo_i + 4 :]
        s0 = cim[i & (_RING - 1), lo_i:]
        s1 = cim[(i + 1) & (_RING - 1), lo_i + 1 :]
        s2 = cim[(i + 2) & (_RING - 1), lo_i + 2 :]
        s3 = cim[(i + 3) & (_RING - 1), lo_i + 3 :]
        s4 = cim[(i + 4) & (_RING - 1), lo_i + 4 :]
        mx = hmx[lo_i:]
        mz = hmz[lo_i:]
        mbx = bmx[i]
        mbz = bmz[i]
        n = np.float32(half)
        for k in range(w):
            re = ((r0[k] + r4[k]) + (r1[k] + r3[k])) + r2[k]
            im = ((s0[k] + s4[k]) + (s1[k] + s3[k])) + s2[k]
            den = re - n * (mbx * mx[k] + mbz * mz[k])
            num = im - n * (mbx * mz[k] - mx[k] * mbz)
            out[k] = theta_bin(num, den, nb)
    else:
        yb = byaw[i]
        hy = hyaw[lo_i:]
        for k in range(w):
            out[k] = np.int32((yb - hy[k]) % nb)
    j = np.int32(lo_i)  # bins -> mask indices (a second loop: both vectorise)
    rm = np.int32(rmask)
    for k in range(w):
        out[k] = _mask_index(out[k], j & rm, nb)
        j += np.int32(1)


#: entries of a row's cost table: every value of :func:`zg_cost` (0..64 + 4·64)
_TABLE = 64 + 4 * 64 + 1


@numba.njit(cache=True, nogil=True)
def _cost_table(st, tab):
    """``tab[c] = float(c) + st``: the local cost of a cell whose codes differ by ``c``
    (Σ (s − s')²) in a body row with step cost ``st``; one read per cell instead of a
    conversion and an addition (the same float)."""
    for c in range(_TABLE):
        tab[c] = float(np.int64(c)) + st


@numba.njit(cache=True, nogil=True, inline="always")
def _index_cost(z, g, tab, codes, u):
    """Local cost of body masks ``(z, g)`` (cost table ``tab`` of the row's step cost, see
    :func:`_cost_table`) against the hand's masks at ``codes[u], codes[u + 1]`` (``u`` from
    :func:`_mask_index`): Σ (s − s')² + step cost.

    ``codes``: the ring of the hand's (Z, G) masks flat, frame by frame (``(R, n_bins, 2)``,
    :func:`_convert`; a band row's cells read one line per hand frame, and the next band
    rows read the same lines); unsigned indices (no wraparound code). The only place a
    pass-1 cell's cost is formed.
    """
    v = np.uint64(u)
    return tab[zg_cost(z, g, codes[v], codes[v + np.uint64(1)])]


@numba.njit(cache=True, nogil=True)
def _code_costs(lo_i, hi_i, z, g, st, codes, cells, crow):
    """``crow[lo_i..hi_i]`` = Σ (s − s')² + ``st`` of the body masks ``(z, g)`` against the
    hand's masks at each cell's ``cells`` index."""
    tab = np.empty(_TABLE)
    _cost_table(st, tab)
    w = hi_i - lo_i + 1
    bb = cells[lo_i : hi_i + 1]
    cost = crow[lo_i : hi_i + 1]
    for k in range(w):
        cost[k] = _index_cost(z, g, tab, codes, bb[k])


@numba.njit(cache=True, nogil=True)
def _fill(
    i,
    lo_i,
    hi_i,
    bmx,
    bmz,
    bnz,
    bpos,
    byaw,
    bstep,
    hmx,
    hmz,
    codes,
    hyaw,
    mode,
    nb,
    half,
    cre,
    cim,
    cells,
    crow,
    rmask,
):
    """``crow[lo_i..hi_i]`` = local costs of band row ``i`` (ring rows ``i..i+4`` ready, the
    hand's masks of frames ``lo_i..hi_i`` in ``codes``, see :func:`_convert`): the row's θ
    bins as mask indices, then the popcount costs."""
    _theta_cells(
        i, lo_i, hi_i, bmx, bmz, byaw, hmx, hmz, hyaw, mode, nb, half, cre, cim, cells, rmask
    )
    _code_costs(lo_i, hi_i, bnz[i], bpos[i], bstep[i], codes, cells, crow)


@numba.njit(cache=True, nogil=True)
def _one_row(
    bx,
    bz,
    bmx,
    bmz,
    bnz,
    bpos,
    byaw,
    bstep,
    hx,
    hz,
    hmx,
    hmz,
    masks,
    hyaw,
    mode,
    nb,
    half,
    lo,
    hi,
    i,
):
    m = hmx.shape[0]
    rmask = _ring_mask(hi[i] - lo[i] + 1)
    codes = np.empty((rmask + 1) * nb * 2, np.uint64)
    _convert(masks, nb, lo[i], hi[i], codes, rmask)
    cre = np.zeros((_RING, m + 4), np.float32)
    cim = np.zeros((_RING, m + 4), np.float32)
    cells = np.zeros(m, np.int32)
    crow = np.zeros(m)
    if mode == MODE_WINDOW:
        _ensure_c(i, i, i, i + 1, lo, hi, bx, bz, hx, hz, cre, cim)
    _fill(
        i,
        lo[i],
        hi[i],
        bmx,
        bmz,
        bnz,
        bpos,
        byaw,
        bstep,
        hmx,
        hmz,
        codes,
        hyaw,
        mode,
        nb,
        half,
        cre,
        cim,
        cells,
        crow,
        rmask,
    )
    return crow


# --------------------------------------------------------------------------------------------
# the recurrence with the sign-code costs inline
# --------------------------------------------------------------------------------------------
# ``engine.dtw.kernels._dp_row`` / ``_dp_pair`` with each cell's local cost formed where it
# is used (``_index_cost`` at the cells of the row's θ bins) instead of read from a cost row,
# and the backpointers left to a vectorised pass over the finished rows (``_row_steps``):
# the serial min/add chain carries only what it needs, the popcount work fills its idle
# issue slots, and no cost row goes through the cache. Same operands, same order, same
# floats and steps (tests compare with the cost-row kernels cell by cell).


@numba.njit(cache=True, nogil=True)
def _row_steps(prev, cur, lo, hi, bp_row):
    """Backpointers of band row ``lo..hi`` from its finished γ rows: ``prev`` (row ``i - 1``)
    and ``cur`` (row ``i``, with ``cur[lo]`` = γ(i, lo - 1), the row's ``left0``). The
    recurrence's comparisons on the values it compared (``engine.dtw.kernels._dp_row``:
    ties prefer the diagonal, then the vertical step); vectorises."""
    w = hi - lo + 1
    diag = prev[lo : hi + 1]
    up = prev[lo + 1 : hi + 2]
    left = cur[lo : hi + 1]
    for k in range(w):
        d = diag[k]
        u = up[k]
        du = min(d, u)
        step_du = K.VERTICAL if u < d else K.DIAGONAL
        bp_row[k] = K.HORIZONTAL if left[k] < du else step_du


@numba.njit(cache=True, nogil=True)
def _dp_row_codes(prev, cur, z, g, st, tab, codes, cells, lo, hi, bp_row, left0):
    """``engine.dtw.kernels._dp_row`` with the costs of body masks ``(z, g)`` (cost table
    ``tab`` of step cost ``st``) against the hand's masks at ``cells`` (:func:`_mask_index`
    of each cell's θ bin, by absolute column, :data:`AHEAD` entries past the row readable)
    formed inline; the masks :data:`AHEAD` cells ahead are prefetched (θ drifts, so the
    reads wander over the table: the hardware prefetchers miss them). Backpointers by
    :func:`_row_steps`; sets ``cur[lo] = left0``."""
    w = hi - lo + 1
    pr = prev[lo : hi + 2]
    out = cur[lo + 1 : hi + 2]
    bb = cells[lo : hi + 1 + AHEAD]
    left = left0
    bad = not (st > K.NEG_INF)  # a cost is NaN or -inf exactly when st is (masks: counts)
    for k in range(w):
        prefetch(codes, np.uint64(bb[k + AHEAD]))
        c = _index_cost(z, g, tab, codes, bb[k])
        g_ = c + min(left, min(pr[k], pr[k + 1]))
        out[k] = g_
        left = g_
    cur[lo] = left0
    _row_steps(prev, cur, lo, hi, bp_row)
    return bad


@numba.njit(cache=True, nogil=True)
def _dp_pair_codes(
    prev,
    mid,
    cur,
    za,
    ga,
    sta,
    tab_a,
    zb,
    gb,
    stb,
    tab_b,
    codes,
    cells_a,
    cells_b,
    lo_a,
    hi_a,
    lo_b,
    hi_b,
    bp_a,
    bp_b,
    left_a0,
    left_b0,
):
    """``engine.dtw.kernels._dp_pair`` (rows ``i``, ``i + 1`` interleaved) with the costs
    formed inline as in :func:`_dp_row_codes` (row ``i``: masks ``za, ga``, step ``sta``,
    table ``tab_a``, cells ``cells_a``; row ``i + 1``: ``zb, gb, stb, tab_b, cells_b``);
    backpointers of both rows by :func:`_row_steps` at the end; sets ``cur[lo_b] = left_b0``."""
    # phase 1: row i alone, columns lo_a .. min(hi_a, lo_b)
    end1 = min(hi_a, lo_b)
    pa = prev[lo_a : hi_a + 2]
    out_a = mid[lo_a + 1 : hi_a + 2]
    ba = cells_a[lo_a : hi_a + 1 + AHEAD]
    left_a = left_a0
    bad_a = not (sta > K.NEG_INF)  # as _dp_row_codes
    for k in range(end1 - lo_a + 1):
        prefetch(codes, np.uint64(ba[k + AHEAD]))
        c = _index_cost(za, ga, tab_a, codes, ba[k])
        g = c + min(left_a, min(pa[k], pa[k + 1]))
        out_a[k] = g
        left_a = g
    mid[lo_a] = left_a0
    for q in range(hi_a + 2, hi_b + 2):
        mid[q] = K.INF
    # phase 2: row i at column t = lo_b+1 .. hi_a, row i+1 at column t-1
    w_b = hi_b - lo_b + 1
    bb = cells_b[lo_b : hi_b + 1 + AHEAD]
    out_b = cur[lo_b + 1 : hi_b + 2]
    left_b = left_b0
    bad_b = not (stb > K.NEG_INF)
    done_b = 0
    if hi_a >= lo_b + 1:
        count = hi_a - lo_b
        pa2 = prev[lo_b + 1 : hi_a + 2]
        ba2 = cells_a[lo_b + 1 : hi_a + 1 + AHEAD]
        out_a2 = mid[lo_b + 2 : hi_a + 2]
        a_diag = mid[lo_b]  # γ(i, t-2) for t = lo_b + 1
        a_up = mid[lo_b + 1]  # γ(i, t-1)
        for k in range(count):
            prefetch(codes, np.uint64(ba2[k + AHEAD]))
            c = _index_cost(za, ga, tab_a, codes, ba2[k])
            g = c + min(left_a, min(pa2[k], pa2[k + 1]))
            out_a2[k] = g
            left_a = g
            # row i+1 at column lo_b + k
            prefetch(codes, np.uint64(bb[k + AHEAD]))
            c2 = _index_cost(zb, gb, tab_b, codes, bb[k])
            g2 = c2 + min(left_b, min(a_diag, a_up))
            out_b[k] = g2
            left_b = g2
            a_diag = a_up
            a_up = g
        done_b = count
    # phase 3: row i+1 alone, the remaining columns
    pb = mid[lo_b + done_b : hi_b + 2]
    ob = out_b[done_b:]
    b3 = bb[done_b:]
    for k in range(w_b - done_b):
        prefetch(codes, np.uint64(b3[k + AHEAD]))
        c = _index_cost(zb, gb, tab_b, codes, b3[k])
        g = c + min(left_b, min(pb[k], pb[k + 1]))
        ob[k] = g
        left_b = g
    cur[lo_b] = left_b0
    _row_steps(prev, mid, lo_a, hi_a, bp_a)
    _row_steps(mid, cur, lo_b, hi_b, bp_b)
    return (1 if bad_a else 0) | (2 if bad_b else 0)


@numba.njit(cache=True, nogil=True)
def _forward(
    bx,
    bz,
    bmx,
    bmz,
    bnz,
    bpos,
    byaw,
    bstep,
    hx,
    hz,
    hmx,
    hmz,
    masks,
    hyaw,
    mode,
    nb,
    half,
    lo,
    hi,
    start,
    i0,
    i1,
    bp,
    gamma,
    keep_gamma,
    ends,
    last_col,
    last_row,
):
    """As ``engine.dtw.kernels.forward_builtin`` (open ends included): a row's θ bins as
    mask indices by :func:`_theta_cells`, its costs formed inside the recurrence
    (:func:`_dp_pair_codes`, :func:`_dp_row_codes`)."""
    m = hmx.shape[0]
    reach = 1  # the hand frames two band rows reach: the ring's size (the band is monotone)
    for r in range(i0, i1):
        reach = max(reach, hi[min(r + 1, i1 - 1)] - lo[r] + 1)
    rmask = _ring_mask(reach)
    codes = np.empty((rmask + 1) * nb * 2, np.uint64)
    done = lo[i0] if i1 > i0 else 0  # the next hand frame to convert
    prev = np.empty(m + 1)
    mid = np.full(m + 1, K.INF)
    cur = np.full(m + 1, K.INF)
    cells_a = np.zeros(m + AHEAD, np.int32)  # AHEAD more: the prefetches read past a row
    cells_b = np.zeros(m + AHEAD, np.int32)
    tab_a = np.empty(_TABLE)
    tab_b = np.empty(_TABLE)
    window = mode == MODE_WINDOW
    ring_w = m + 4 if window else 1
    cre = np.empty((_RING, ring_w), np.float32)
    cim = np.empty((_RING, ring_w), np.float32)
    st_a = np.nan  # the step costs tab_a and tab_b hold (NaN: none yet; rebuilt when they differ)
    st_b = np.nan
    next_p = i0
    K._init_prev(prev, gamma, lo, hi, start, i0, ends)
    i = i0
    while i < i1:
        done = _convert(masks, nb, done, hi[i + 1] if i + 1 < i1 else hi[i], codes, rmask)
        if K._use_pair(lo, hi, i, i1):
            if window:
                next_p = _ensure_c(i + 1, next_p, i0, i1, lo, hi, bx, bz, hx, hz, cre, cim)
            lo_a, hi_a = lo[i], hi[i]
            lo_b, hi_b = lo[i + 1], hi[i + 1]
            _theta_cells(
                i,
                lo_a,
                hi_a,
                bmx,
                bmz,
                byaw,
                hmx,
                hmz,
                hyaw,
                mode,
                nb,
                half,
                cre,
                cim,
                cells_a,
                rmask,
            )
            _theta_cells(
                i + 1,
                lo_b,
                hi_b,
                bmx,
                bmz,
                byaw,
                hmx,
                hmz,
                hyaw,
                mode,
                nb,
                half,
                cre,
                cim,
                cells_b,
                rmask,
            )
            if not (bstep[i] == st_a):
                st_a = bstep[i]
                _cost_table(st_a, tab_a)
            if not (bstep[i + 1] == st_b):
                st_b = bstep[i + 1]
                _cost_table(st_b, tab_b)
            bad = _dp_pair_codes(
                prev,
                mid,
                cur,
                bnz[i],
                bpos[i],
                bstep[i],
                tab_a,
                bnz[i + 1],
                bpos[i + 1],
                bstep[i + 1],
                tab_b,
                codes,
                cells_a,
                cells_b,
                lo_a,
                hi_a,
                lo_b,
                hi_b,
                bp[start[i] : start[i + 1]],
                bp[start[i + 1] : start[i + 2]],
                K._left0(lo, i, ends),
                K._left0(lo, i + 1, ends),
            )
            if bad:
                return (i if bad & 1 else i + 1), np.nan
            last_col[i] = mid[m] if hi[i] == m - 1 else K.INF
            K._row_done(cur, lo, hi, i + 1, ends, last_col, m)
            if K._keep(keep_gamma, i, i1):
                K._store_row(mid, gamma, lo, hi, start, i)
            if K._keep(keep_gamma, i + 1, i1):
                K._store_row(cur, gamma, lo, hi, start, i + 1)
            prev, mid, cur = cur, prev, mid
            i += 2
        else:
            if window:
                next_p = _ensure_c(i, next_p, i0, i1, lo, hi, bx, bz, hx, hz, cre, cim)
            _theta_cells(
                i,
                lo[i],
                hi[i],
                bmx,
                bmz,
                byaw,
                hmx,
                hmz,
                hyaw,
                mode,
                nb,
                half,
                cre,
                cim,
                cells_a,
                rmask,
            )
            if not (bstep[i] == st_a):
                st_a = bstep[i]
                _cost_table(st_a, tab_a)
            if _dp_row_codes(
                prev,
                cur,
                bnz[i],
                bpos[i],
                bstep[i],
                tab_a,
                codes,
                cells_a,
                lo[i],
                hi[i],
                bp[start[i] : start[i + 1]],
                K._left0(lo, i, ends),
            ):
                return i, np.nan
            K._row_done(cur, lo, hi, i, ends, last_col, m)
            if K._keep(keep_gamma, i, i1):
                K._store_row(cur, gamma, lo, hi, start, i)
            prev, cur = cur, prev
            i += 1
    return -1, K._finish(prev, last_row, m)
