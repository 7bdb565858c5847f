"""Pass-2 kernel: the ``splice_angle`` cost (eq. 9) of a whole band row at a time.

Eq. 9 compares the body's hand vector ``h`` with the hand take's ``k`` after ``R``, the
smallest rotation taking the hand take's forearm vector ``g`` onto the body's ``f``:
``D2 = arccos(h · R k / (|h| |R k|))``. Rotating ``k`` per cell (three cross products)
and a libm ``arccos`` per cell cost about 40-90 ns per band cell, the bulk of pass 2.
This module computes the same quantity as dot products of per-frame vectors:

* **Per-frame vectors** (:func:`frame_rows`, once per take): with ``x = fore × hand``
  of each frame and ``w = g × f``,
  ``h · R k = h·k + (g·k)(f·h) − (g·h)(f·k) − ((g·u)(f·x_hand) + (h·k)|w|²) / (1 + c)``
  where ``c = g·f``, ``u = f × h`` (body), ``x_hand = g × k`` and ``|w|² = |g|²|f|² − c²``
  (Rodrigues' formula for ``R`` with Binet-Cauchy for the cross products; exact for
  any vectors, zero vectors included). A cell is six 3-D dot products and a few
  products; near-antiparallel forearms (``c < -0.999999``) use the half turn about the
  hand take's stored perpendicular axis ``a``: ``h · R k = 2 (a·k)(a·h) − h·k``.
* **arccos without libm** (:func:`acos`): fdlibm's rational approximation (within
  about 2 ulp of libm), written with selects only, so a column loop vectorises.
* Hand-take vectors are stored component by component (``(16 A, m)``), so a band
  row is one pass over contiguous columns per arm.

Exactness: :func:`arm_angle` is the only per-cell arithmetic; the per-cell metric
(:func:`engine.align.metrics.splice_angle`, used by views, reports and tests) calls it with
the same operands in the same order (no fast-math), so the row kernel gives the
per-cell costs bit for bit and the DTW path is the same. Against the rotation form
(:func:`engine.align.metrics.splice_angle_literal`, the code before this kernel) costs agree
to rounding (about 1e-15 rad, up to ~1e-8 rad where the angle is near 0 or π: arccos
amplifies the last bit of a cosine near ±1); tests and ``bench_splice_speed`` compare
paths on real captures.

numba's on-disk cache does not notice a change to this module in functions that inline it
from another module (``engine.align.metrics.splice_angle``): after editing the arithmetic here,
clear ``NUMBA_CACHE_DIR`` (the row-versus-cell test then catches any mismatch).
"""

from __future__ import annotations

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from engine.dtw import kernels as K

#: header of a ``splice_angle`` row: [arms, step]
HEADER = 2
#: values per arm in a row (see :func:`frame_rows`)
ARM = 16
FORE, HAND, CROSS, FH, FF, INV, PERP, PH = 0, 3, 6, 9, 10, 11, 12, 15
#: forearms closer to antiparallel than this cosine turn by a half turn
ANTIPARALLEL = -0.999999
#: a hand vector with |v|² below this is degenerate (its cells cost 0)
TINY_NORM2 = 1e-24


@intrinsic
def fma(typingctx, a, b, c):
    """``a * b + c`` rounded once (``llvm.fma.f64``): the same result in scalar and in
    vectorised loops (a hardware FMA where the CPU has one)."""
    if not all(isinstance(t, types.Float) for t in (a, b, c)):
        return None
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        f64 = ir.DoubleType()
        fnty = ir.FunctionType(f64, [f64, f64, f64])
        fn = builder.module.declare_intrinsic("llvm.fma", [f64], fnty)
        return builder.call(fn, args)

    return sig, codegen


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def dot3(ax, ay, az, bx, by, bz):
    """``a · b`` of 3-vectors with two FMAs."""
    return fma(az, bz, fma(ay, by, ax * bx))


# fdlibm e_acos.c (Sun Microsystems, 1993; "Permission to use, copy, modify, and
# distribute this software is freely granted, provided that this notice is preserved.")
_PIO2_HI = 1.57079632679489655800e00
_PIO2_LO = 6.12323399573676603587e-17
_PI = 3.14159265358979311600e00
_PS0 = 1.66666666666666657415e-01
_PS1 = -3.25565818622400915405e-01
_PS2 = 2.01212532134862925881e-01
_PS3 = -4.00555345006794114027e-02
_PS4 = 7.91534994289814532176e-04
_PS5 = 3.47933107596021167570e-05
_QS1 = -2.40339491173441421878e00
_QS2 = 2.02094576023350569471e00
_QS3 = -6.88283971605453293030e-01
_QS4 = 7.70381505559019352791e-02


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def acos(x):
    """``arccos(x)`` for ``x`` in [-1, 1] (radians), fdlibm's method without branches.

    ``|x| < 0.5``: ``π/2 − (x + x z R(z))`` with ``z = x²``; otherwise with
    ``z = (1 − |x|)/2``, ``s = √z``: ``2 (s + s R(z))`` or ``π − 2 (s + s R(z))``.
    ``R = P/Q`` is fdlibm's rational approximation of ``(asin(s) − s) / s³``.
    """
    a = abs(x)
    small = a < 0.5
    z = x * x if small else (1.0 - a) * 0.5
    p = z * fma(z, fma(z, fma(z, fma(z, fma(z, _PS5, _PS4), _PS3), _PS2), _PS1), _PS0)
    q = fma(z, fma(z, fma(z, fma(z, _QS4, _QS3), _QS2), _QS1), 1.0)
    r = p / q
    s = np.sqrt(z)
    t = s + s * r
    near = _PIO2_HI - (x - (_PIO2_LO - x * r))
    pos = 2.0 * t
    neg = _PI - (2.0 * t - 2.0 * _PIO2_LO)
    return near if small else (pos if x > 0.0 else neg)


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def arm_angle(
    fx, fy, fz, hx, hy, hz, ux, uy, uz, fh, ff, ih, gx, gy, gz, kx, ky, kz, xx, xy, xz, gk, gg, ik,
    ax, ay, az, ak,
):  # fmt: skip
    """D2 of one arm (radians): body ``f, h, u = f×h, f·h, |f|², 1/|h|``; hand ``g, k,
    x = g×k, g·k, |g|², 1/|k|`` and the half-turn axis ``a ⟂ g`` with ``a·k``
    (``1/|v|`` is 0 for a degenerate vector: the arm then costs 0)."""
    c = dot3(gx, gy, gz, fx, fy, fz)
    hk = dot3(hx, hy, hz, kx, ky, kz)
    gh = dot3(gx, gy, gz, hx, hy, hz)
    fk = dot3(fx, fy, fz, kx, ky, kz)
    gu = dot3(gx, gy, gz, ux, uy, uz)
    fxh = dot3(fx, fy, fz, xx, xy, xz)
    w2 = fma(gg, ff, -(c * c))
    main = hk + fma(gk, fh, -(gh * fk)) - fma(gu, fxh, hk * w2) / (1.0 + c)
    anti = fma(2.0 * ak, dot3(ax, ay, az, hx, hy, hz), -hk)
    dot = anti if c < ANTIPARALLEL else main
    norm = ih * ik
    cosine = dot * norm
    cosine = 1.0 if cosine > 1.0 else cosine
    cosine = -1.0 if cosine < -1.0 else cosine
    angle = acos(cosine)
    return angle if norm > 0.0 else 0.0


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def cell(body_row, hand_row):
    """D2 of one cell from two :func:`frame_rows` rows: step + Σ over arms."""
    arms = int(body_row[0])
    total = body_row[1]
    for arm in range(arms):
        o = HEADER + ARM * arm
        b = body_row[o : o + ARM]
        h = hand_row[o : o + ARM]
        total += arm_angle(
            b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7], b[8], b[9], b[10], b[11],
            h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8], h[9], h[10], h[11],
            h[12], h[13], h[14], h[15],
        )  # fmt: skip
    return total


# --------------------------------------------------------------------------------------------
# per-frame rows
# --------------------------------------------------------------------------------------------


def frame_rows(fore: np.ndarray, hand: np.ndarray, step: float = 0.0) -> np.ndarray:
    """``(F, 2 + 16 A)`` float64 rows of the ``"splice_angle"`` metric.

    fore, hand : (F, A, 3) float, the forearm and hand vectors of ``A`` arms (unit or
        zero; :func:`engine.align.metrics.angle_features`).
    step : radians added to every cell (put it in the body rows only).

    Row: ``[A, step]`` then per arm ``fore (3), hand (3), fore × hand (3), fore · hand,
    |fore|², 1/|hand|, a (3), a · hand`` with ``a`` the unit axis perpendicular to the
    forearm used for a half turn (zero for a zero forearm) and ``1/|hand|`` zero where
    ``|hand|² <`` :data:`TINY_NORM2`. The same layout serves the
    body take (``f, h``) and the hand take (``g, k``).
    """
    fore = np.ascontiguousarray(fore, dtype=np.float64)
    hand = np.ascontiguousarray(hand, dtype=np.float64)
    f, a = fore.shape[:2]
    out = np.zeros((f, HEADER + ARM * a))
    out[:, 0] = a
    out[:, 1] = float(step)
    _frame_rows_kernel(fore, hand, out)
    return out


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _frame_rows_kernel(fore, hand, out):
    for r in range(fore.shape[0]):
        for arm in range(fore.shape[1]):
            o = HEADER + ARM * arm
            fx, fy, fz = fore[r, arm, 0], fore[r, arm, 1], fore[r, arm, 2]
            hx, hy, hz = hand[r, arm, 0], hand[r, arm, 1], hand[r, arm, 2]
            row = out[r, o : o + ARM]
            row[0], row[1], row[2] = fx, fy, fz
            row[3], row[4], row[5] = hx, hy, hz
            row[6] = fy * hz - fz * hy
            row[7] = fz * hx - fx * hz
            row[8] = fx * hy - fy * hx
            row[9] = dot3(fx, fy, fz, hx, hy, hz)
            row[10] = dot3(fx, fy, fz, fx, fy, fz)
            hh = dot3(hx, hy, hz, hx, hy, hz)
            row[11] = 1.0 / np.sqrt(hh) if hh >= TINY_NORM2 else 0.0
            # half-turn axis: perpendicular to the forearm (as the rotation form chose it)
            if abs(fx) < 0.9:
                ax, ay, az = 0.0, -fz, fy
            else:
                ax, ay, az = fz, 0.0, -fx
            nrm = np.sqrt(ax * ax + ay * ay + az * az)
            if nrm > 0.0:
                ax /= nrm
                ay /= nrm
                az /= nrm
            else:
                ax = ay = az = 0.0
            row[12], row[13], row[14] = ax, ay, az
            row[15] = dot3(ax, ay, az, hx, hy, hz)


# --------------------------------------------------------------------------------------------
# the row kernel (engine.dtw's metric plug-in)
# --------------------------------------------------------------------------------------------


#: most band cells whose costs a state keeps between solves (``keep_costs``; 64 MB)
KEEP_MAX_CELLS = 8_000_000


class AngleProblem:
    """The row kernel's arrays for one (body rows, hand rows) pair: the body rows as
    they are, the hand rows component by component ``(16 A, m)``.

    ``keep_costs`` (``engine.dtw.align.SharedCosts``): a whole-band forward pass keeps its
    local costs (one float64 per band cell, bands up to :data:`KEEP_MAX_CELLS`) and the
    next whole-band pass over the same band arrays reads them instead of computing them
    (the same floats: pass 2's two open-end solves differ only in their ends).
    """

    def __init__(self, a: np.ndarray, b: np.ndarray):
        arms = int(a[0, 0]) if len(a) else 0
        self.a = np.ascontiguousarray(a, dtype=np.float64)
        self.hand_t = np.ascontiguousarray(b[:, HEADER : HEADER + ARM * arms].T, dtype=np.float64)
        self.arms = arms
        self.keep_costs = False
        self.kept = None  # (lo, hi, costs (area,)) of the last whole-band pass


def prepare(a: np.ndarray, b: np.ndarray) -> AngleProblem:
    """Row-kernel data for ``splice_angle`` rows ``a`` (body, ``(n, d)``) and ``b`` (hand)."""
    return AngleProblem(a, b)


def forward(
    state: AngleProblem, lo, hi, start, i0, i1, bp, gamma, keep_gamma, ends, last_col, last_row
):
    """Rows ``i0..i1-1`` of the DTW forward pass (as ``engine.dtw.kernels.forward_*``,
    open ends included)."""
    mode, store = _NO_STORE, _EMPTY
    whole = i0 == 0 and i1 == len(lo)
    if state.keep_costs and whole:
        kept = state.kept
        if kept is not None and kept[0] is lo and kept[1] is hi:
            mode, store = _READ, kept[2]
        elif int(start[-1]) <= KEEP_MAX_CELLS:
            mode, store = _WRITE, np.empty(int(start[-1]))
    res = _forward(
        state.a, state.hand_t, lo, hi, start, i0, i1, bp, gamma, keep_gamma, ends, last_col,
        last_row, mode, store,
    )  # fmt: skip
    if mode == _WRITE:
        # a bad cost stops the pass early: then the rows after it were not written
        state.kept = (lo, hi, store) if res[0] < 0 else None
    return res


_NO_STORE, _WRITE, _READ = 0, 1, 2
_EMPTY = np.empty(0)


@numba.njit(cache=True, nogil=True)
def _costs(a, ht, i, lo, hi, start, crow, mode, store):
    """``crow[lo..hi]`` = the local costs of band row ``i``: computed (:func:`_fill`; kept in
    ``store`` when ``mode`` is write) or read from ``store``."""
    w = hi - lo + 1
    s = store[start[i] : start[i] + w] if mode != _NO_STORE else store
    if mode == _READ:
        crow[lo : hi + 1] = s
        return
    _fill(a, ht, i, lo, hi, crow)
    if mode == _WRITE:
        s[:] = crow[lo : hi + 1]


def cost_row(state: AngleProblem, i: int, lo: int, hi: int) -> np.ndarray:
    """Local costs ``(hi - lo + 1,)`` of body row ``i`` against hand frames ``lo..hi``."""
    crow = np.zeros(state.hand_t.shape[1])
    _fill(state.a, state.hand_t, i, lo, hi, crow)
    return crow[lo : hi + 1].copy()


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _fill(a, ht, i, lo, hi, crow):
    """``crow[lo..hi]`` = D2 of body row ``i`` against hand frames ``lo..hi``."""
    w = hi - lo + 1
    out = crow[lo : hi + 1]
    row = a[i]
    step = row[1]
    for t in range(w):
        out[t] = step
    for arm in range(int(row[0])):
        o = HEADER + ARM * arm
        b = row[o : o + ARM]
        fx, fy, fz, hx, hy, hz = b[0], b[1], b[2], b[3], b[4], b[5]
        ux, uy, uz, fh, ff, ih = b[6], b[7], b[8], b[9], b[10], b[11]
        c0 = ARM * arm
        gx = ht[c0, lo : hi + 1]
        gy = ht[c0 + 1, lo : hi + 1]
        gz = ht[c0 + 2, lo : hi + 1]
        kx = ht[c0 + 3, lo : hi + 1]
        ky = ht[c0 + 4, lo : hi + 1]
        kz = ht[c0 + 5, lo : hi + 1]
        xx = ht[c0 + 6, lo : hi + 1]
        xy = ht[c0 + 7, lo : hi + 1]
        xz = ht[c0 + 8, lo : hi + 1]
        gk = ht[c0 + 9, lo : hi + 1]
        gg = ht[c0 + 10, lo : hi + 1]
        ik = ht[c0 + 11, lo : hi + 1]
        ax = ht[c0 + 12, lo : hi + 1]
        ay = ht[c0 + 13, lo : hi + 1]
        az = ht[c0 + 14, lo : hi + 1]
        ak = ht[c0 + 15, lo : hi + 1]
        for t in range(w):
            out[t] += arm_angle(
                fx, fy, fz, hx, hy, hz, ux, uy, uz, fh, ff, ih,
                gx[t], gy[t], gz[t], kx[t], ky[t], kz[t], xx[t], xy[t], xz[t], gk[t], gg[t],
                ik[t], ax[t], ay[t], az[t], ak[t],
            )  # fmt: skip


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _forward(
    a, ht, lo, hi, start, i0, i1, bp, gamma, keep_gamma, ends, last_col, last_row, mode, store
):
    """As ``engine.dtw.kernels.forward_builtin`` (open ends included), local costs from
    :func:`_costs`."""
    m = ht.shape[1]
    prev = np.empty(m + 1)
    mid = np.full(m + 1, K.INF)
    cur = np.full(m + 1, K.INF)
    crow_a = np.zeros(m)
    crow_b = np.zeros(m)
    K._init_prev(prev, gamma, lo, hi, start, i0, ends)
    i = i0
    while i < i1:
        if K._use_pair(lo, hi, i, i1):
            _costs(a, ht, i, lo[i], hi[i], start, crow_a, mode, store)
            _costs(a, ht, i + 1, lo[i + 1], hi[i + 1], start, crow_b, mode, store)
            bad = K._dp_pair(
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
            _costs(a, ht, i, lo[i], hi[i], start, crow_a, mode, store)
            if K._dp_row(
                prev, cur, crow_a, lo[i], hi[i], bp[start[i] : start[i + 1]], K._left0(lo, i, ends)
            ):
                return i, np.nan
            K._row_done(cur, lo, hi, i, ends, last_col, m)
            if K._keep(keep_gamma, i, i1):
                K._store_row(cur, gamma, lo, hi, start, i)
            prev, cur = cur, prev
            i += 1
    return -1, K._finish(prev, last_row, m)
