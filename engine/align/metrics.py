"""Local-cost metrics for the two splicing passes (docs/method.md sections 2 and 3).

Pass 1 (phase matching, Majkowska et al. eq. 6): signs of the first and second
derivatives of the four arm markers, with a dead zone so a held hand reads 0,
after rotating the hand take about the vertical axis by θ (eq. 7, from a window
of 5 frames × markers, or from the trunk yaw of both takes).

Pass 2 (refinement, eqs. 8-9): angle between the hand vectors after the smallest
rotation that takes the hand take's forearm vector onto the body's.

Everything works on marker arrays from :mod:`engine.align.features` (metres, y up).

The costs reach the DTW engine (:mod:`engine.dtw`) through its metric plug-in:
each frame becomes one float64 row (:func:`phase_rows`, :meth:`AngleFeatures.rows`)
and the numba functions :func:`splice_phase` / :func:`splice_angle` (registered
as ``"splice_phase"`` / ``"splice_angle"``) compute a cell's cost inside the
kernel, for band cells only: no ``n x m`` matrix, memory proportional to the
frame counts plus one byte per band cell for the DTW's backpointers.

Implementation notes (where this differs from the paper, and why)
------------------------------------------------------------------
* θ is quantised to ``n_bins`` directions (default 72, 5°): the hand take's sign
  codes are precomputed for every direction and packed into two 48-bit masks
  (positive, negative), so a band cell costs θ of eq. 7, a polynomial ``atan2``
  and three popcounts instead of rotating 16 vectors. Whole band rows go through
  the row kernel of :mod:`engine.align.phase_kernel` (θ by diagonal sums of per-frame
  products, about a tenth of the per-cell time); :func:`splice_phase` computes one
  cell with the same float32 arithmetic, so both give the same costs bit for bit.
  :func:`phase_cost_reference` computes eq. 6 with exact θ (tests compare).
* The window of eq. 7 uses frames ``i-2..i+2`` clipped at the take's ends
  (edge frames repeated), so every window holds 5 × markers points.
* Pass 2's cost is computed as dot products of per-frame vectors (the rotation ``R``
  never built) with a branch-free fdlibm ``arccos``; whole band rows go through the row
  kernel of :mod:`engine.align.angle_kernel` (vectorised, about a fifth of the per-cell time),
  :func:`splice_angle` computes one cell with the same arithmetic (bit for bit).
  :func:`splice_angle_literal` is the rotation form (cross products, libm ``arccos``)
  it replaced; they agree to rounding and give the same paths on real captures (tests).
* With both arms aligned jointly, one θ is computed from both arms' markers
  (one trunk rotation for the take) and the two arms' costs are summed.
* The dead zone ``ε`` is relative to each take's own 90th-percentile marker speed
  (and acceleration), so a hand captured with a shrunken arm still reads holds as
  0 and movements as ±1.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from engine.align import angle_kernel as AK
from engine.align import phase_kernel as PK
from engine.base.errors import ParameterError
from engine.base.jit import FASTMATH_REASSOC
from engine.dtw import kernels as DK

# numba options: engine.base.jit (no nnan/ninf: NaN gaps in capture data are real)
_FASTMATH = set(FASTMATH_REASSOC)

#: window of eq. 7 in frames (the paper: 5 frames × 4 markers = 20 points)
THETA_WINDOW = 5
#: default number of quantised θ directions
THETA_BINS = 72


# --------------------------------------------------------------------------------------------
# derivatives and the dead zone
# --------------------------------------------------------------------------------------------


def savgol_window(fps: float, window_s: float = 0.2, polyorder: int = 3) -> int:
    """Odd Savitzky-Golay window length in frames for ``window_s`` seconds at ``fps``."""
    w = int(round(window_s * fps))
    w = max(w, polyorder + 2)
    return w + 1 if w % 2 == 0 else w


def derivatives(
    points: np.ndarray, fps: float, window_s: float = 0.2, polyorder: int = 3
) -> tuple[np.ndarray, np.ndarray]:
    """Velocity and acceleration of trajectories by Savitzky-Golay filtering.

    Parameters
    ----------
    points : (F, ...) float
        Trajectories along axis 0 (e.g. ``(F, K, 3)`` marker positions, metres).
    fps : float
        Frames per second of ``points``.
    window_s : float
        Smoothing window in seconds (rounded to an odd number of frames).

    Returns
    -------
    velocity : same shape as ``points``, units per second
    acceleration : same shape as ``points``, units per second²

    Takes shorter than the window use the longest odd window that fits (and a
    lower polynomial order); a take of 1-2 frames has zero derivatives.
    NaN gaps are filled by linear interpolation first (edges held). The ends are
    padded by point reflection (a steady motion continues; its acceleration reads 0).
    """
    p = np.asarray(points, dtype=float)
    if not (np.isfinite(fps) and fps > 0):
        raise ParameterError(f"derivatives: fps must be positive, got {fps}")
    f = p.shape[0]
    if f < 3:
        z = np.zeros_like(p)
        return z, z.copy()
    p = _fill_gaps(p)
    w = savgol_window(fps, window_s, polyorder)
    if w > f:
        w = f if f % 2 == 1 else f - 1
    order = min(polyorder, w - 1)
    dt = 1.0 / fps
    # Savitzky-Golay as a convolution; the ends are padded by point reflection
    # (2 x[0] - x[k]), which continues a steady motion instead of stopping it
    half = w // 2
    flat = p.reshape(f, -1)
    padded = np.concatenate(
        [2 * flat[:1] - flat[half:0:-1], flat, 2 * flat[-1:] - flat[-2 : -half - 2 : -1]], axis=0
    )
    v = _sg_apply(padded, w, order, 1, dt)[half : half + f].reshape(p.shape)
    if order < 2:
        a = np.gradient(v, dt, axis=0)
    else:
        a = _sg_apply(padded, w, order, 2, dt)[half : half + f].reshape(p.shape)
    return v, a


_SG_CACHE: dict[tuple, np.ndarray] = {}


def _sg_apply(x: np.ndarray, window: int, order: int, deriv: int, dt: float) -> np.ndarray:
    from scipy.ndimage import correlate1d
    from scipy.signal import savgol_coeffs

    key = (window, order, deriv)
    c = _SG_CACHE.get(key)
    if c is None:
        c = savgol_coeffs(window, order, deriv=deriv, use="dot")
        _SG_CACHE[key] = c
    return correlate1d(x, c, axis=0, mode="nearest") / dt**deriv


def _fill_gaps(p: np.ndarray) -> np.ndarray:
    """Linear interpolation over NaN frames along axis 0 (edges held); all-NaN -> 0."""
    if not np.isnan(p).any():
        return p
    flat = p.reshape(p.shape[0], -1).copy()
    t = np.arange(flat.shape[0])
    for c in range(flat.shape[1]):
        col = flat[:, c]
        good = np.isfinite(col)
        if not good.any():
            flat[:, c] = 0.0
        elif not good.all():
            flat[:, c] = np.interp(t, t[good], col[good])
    return flat.reshape(p.shape)


@dataclass(frozen=True)
class DeadZone:
    """Thresholds below which a velocity / acceleration component reads 0.

    velocity : float, units/s
    acceleration : float, units/s²
    """

    velocity: float
    acceleration: float


#: a derivative component reads 0 below this many standard deviations of the take's own
#: noise in that derivative (:func:`noise_floor`)
NOISE_SIGMAS = 2.0


def noise_floor(
    points: np.ndarray, fps: float, window_s: float = 0.2, polyorder: int = 3
) -> tuple[float, float]:
    """Standard deviation of the noise in one velocity and one acceleration component.

    The high-passed signal ``r = x - SG(x)`` (what the Savitzky-Golay smoother of
    :func:`derivatives` removes) is mostly noise; for white noise of deviation σ
    through a projection smoother ``var(r) = σ² (1 - c0)`` (``c0``: centre coefficient),
    so ``σ = 1.4826 MAD(r) / sqrt(1 - c0)`` (robust to real motion left in ``r``).
    The derivative filters pass it as ``σ |c1| / dt`` and ``σ |c2| / dt²``.
    Returns (units/s, units/s²); (0, 0) for takes shorter than the window.
    """
    from scipy.signal import savgol_coeffs

    p = _fill_gaps(np.asarray(points, dtype=float))
    f = p.shape[0]
    w = savgol_window(fps, window_s, polyorder)
    if f < w or w <= polyorder + 1:
        return 0.0, 0.0
    c0 = savgol_coeffs(w, polyorder, deriv=0, use="dot")
    flat = p.reshape(f, -1)
    r = flat - _sg_apply(flat, w, polyorder, 0, 1.0)
    r = r[w // 2 : f - w // 2]
    if r.size == 0:
        return 0.0, 0.0
    mad = float(np.median(np.abs(r - np.median(r, axis=0))))
    sigma = 1.4826 * mad / np.sqrt(max(1.0 - c0[w // 2], 1e-6))
    dt = 1.0 / fps
    c1 = savgol_coeffs(w, polyorder, deriv=1, use="dot")
    c2 = savgol_coeffs(w, polyorder, deriv=2, use="dot")
    return sigma * float(np.linalg.norm(c1)) / dt, sigma * float(np.linalg.norm(c2)) / dt**2


def dead_zone(
    velocity: np.ndarray,
    acceleration: np.ndarray,
    relative: float = 0.1,
    quantile: float = 0.9,
    noise: tuple[float, float] = (0.0, 0.0),
) -> DeadZone:
    """Dead zone sized from the take's own speed and acceleration distribution.

    ``ε_v = relative · q(|v|)`` where ``q`` is the ``quantile`` of the per-frame
    speeds of all markers (the same for ``ε_a`` on accelerations). A take whose
    arm moves half as far (a hand captured in a small volume) gets half the
    threshold, so holds read 0 in both takes and the sign codes stay comparable.
    ``noise`` (:func:`noise_floor`): the thresholds are at least ``NOISE_SIGMAS``
    times the take's own noise in a velocity / acceleration component.

    velocity, acceleration : (F, K, 3) float
    """
    if not 0.0 <= relative < 1.0:
        raise ParameterError(f"dead zone: relative must be in [0, 1), got {relative}")
    speed = np.linalg.norm(np.asarray(velocity, dtype=float), axis=-1).ravel()
    accel = np.linalg.norm(np.asarray(acceleration, dtype=float), axis=-1).ravel()
    speed = speed[np.isfinite(speed)]
    accel = accel[np.isfinite(accel)]
    ev = relative * float(np.quantile(speed, quantile)) if speed.size else 0.0
    ea = relative * float(np.quantile(accel, quantile)) if accel.size else 0.0
    return above_noise(DeadZone(velocity=ev, acceleration=ea), noise)


def above_noise(zone: DeadZone, noise: tuple[float, float]) -> DeadZone:
    """``zone`` raised to ``NOISE_SIGMAS`` times the take's noise (:func:`noise_floor`)
    where lower: jitter then does not flip a held hand's signs."""
    return DeadZone(
        velocity=max(zone.velocity, NOISE_SIGMAS * float(noise[0])),
        acceleration=max(zone.acceleration, NOISE_SIGMAS * float(noise[1])),
    )


def sign_dead_zone(x: np.ndarray, eps: float) -> np.ndarray:
    """``sgn_ε(x)``: 0 where ``|x| < eps`` else the sign, as int8."""
    x = np.asarray(x, dtype=float)
    out = np.zeros(x.shape, dtype=np.int8)
    out[x >= eps] = 1
    out[x <= -eps] = -1
    if eps <= 0:  # no dead zone: exact zeros still read 0
        out[x == 0] = 0
    return out


# --------------------------------------------------------------------------------------------
# pass-1 features
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PhaseFeatures:
    """Per-frame inputs of the pass-1 metric for one take.

    Attributes
    ----------
    markers : (F, K, 3) float, metres, y up
        Alignment markers (4 per arm, arms one after another), shoulder subtracted.
    velocity, acceleration : (F, K, 3) float
        Savitzky-Golay derivatives of ``markers`` (m/s, m/s²).
    zone : DeadZone
    codes : (F, K * 6) int8
        ``sgn_ε`` of velocity (x, y, z) then acceleration (x, y, z) per marker.
    yaw : (F,) float radians or None
        Trunk heading about the vertical axis (for ``theta="trunk"``).
    fps : float
    arms : int
        Number of arms (1 or 2); ``K = 4 * arms``.
    """

    markers: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    zone: DeadZone
    codes: np.ndarray
    yaw: np.ndarray | None
    fps: float
    arms: int

    @property
    def n_frames(self) -> int:
        return int(self.markers.shape[0])


def phase_features(
    markers: np.ndarray,
    fps: float,
    yaw: np.ndarray | None = None,
    window_s: float = 0.2,
    relative: float = 0.1,
) -> PhaseFeatures:
    """Pass-1 features of one take.

    Parameters
    ----------
    markers : (F, K, 3) float, metres, y up
        ``K = 4 * arms`` alignment markers (order per arm: radial wrist, ulnar
        wrist, forearm, hand), shoulder already subtracted where known.
    fps : float
    yaw : (F,) float radians, optional
        Trunk heading, needed only for ``theta="trunk"``.
    window_s : float
        Savitzky-Golay window in seconds.
    relative : float
        Dead zone as a fraction of the take's 90th-percentile speed (and acceleration).
    """
    m = np.asarray(markers, dtype=float)
    if m.ndim != 3 or m.shape[2] != 3 or m.shape[1] % 4 != 0 or m.shape[1] == 0:
        raise ParameterError(f"phase features: markers must be (frames, 4*arms, 3), got {m.shape}")
    if m.shape[0] < 1:
        raise ParameterError("phase features: the take has no frames")
    m = _fill_gaps(m)
    v, a, zone = _filtered_derivatives(m, fps, window_s, relative)
    codes = np.concatenate(
        [sign_dead_zone(v, zone.velocity), sign_dead_zone(a, zone.acceleration)], axis=2
    )  # (F, K, 6)
    if yaw is not None:
        yaw = np.asarray(yaw, dtype=float).reshape(-1)
        if yaw.shape[0] != m.shape[0]:
            raise ParameterError(
                f"phase features: yaw has {yaw.shape[0]} frames, markers {m.shape[0]}"
            )
    return PhaseFeatures(
        markers=m,
        velocity=v,
        acceleration=a,
        zone=zone,
        codes=np.ascontiguousarray(codes.reshape(m.shape[0], -1)),
        yaw=yaw,
        fps=float(fps),
        arms=m.shape[1] // 4,
    )


#: widest derivative window, as a multiple of the asked one, for noisy takes
MAX_WINDOW_FACTOR = 3.0


def _filtered_derivatives(m: np.ndarray, fps: float, window_s: float, relative: float):
    """Derivatives and dead zone, the window widened for a noisy take.

    The window grows (1, 1.5, 2, 3 times ``window_s``) until the take's noise in a
    velocity component (:func:`noise_floor`, times ``NOISE_SIGMAS``) is below the
    motion-relative dead zone, so jitter does not decide the signs; the dead zone is
    never below the noise floor of the window used.
    """
    best = None
    for factor in (1.0, 1.5, 2.0, MAX_WINDOW_FACTOR):
        w = window_s * factor
        v, a = derivatives(m, fps, w)
        noise = noise_floor(m, fps, w)
        plain = dead_zone(v, a, relative)
        best = (v, a, above_noise(plain, noise))
        if NOISE_SIGMAS * noise[0] <= plain.velocity:
            break
    return best


def _theta_windows(markers: np.ndarray, frames) -> np.ndarray:
    """``(..., 2*W*K)`` float32: the eq.-7 window of each frame in ``frames`` (an int
    array of any shape), centred: horizontal ``x`` then ``z`` of frames ``f-2..f+2``
    (clipped at the ends) minus the window's centroid.

    Built for the asked frames only (the splice's pass 1 does not use these: its row
    kernel works from :func:`_raw_windows`; the per-cell θ of views and reports does)."""
    f, k, _ = markers.shape
    half = THETA_WINDOW // 2
    frames = np.asarray(frames, dtype=np.int64)
    idx = np.clip(frames[..., None] + np.arange(-half, half + 1), 0, f - 1)
    x = markers[idx, :, 0].reshape(frames.shape + (-1,))  # (..., W*K)
    z = markers[idx, :, 2].reshape(frames.shape + (-1,))
    x = x - x.mean(axis=-1, keepdims=True)
    z = z - z.mean(axis=-1, keepdims=True)
    return np.ascontiguousarray(np.concatenate([x, z], axis=-1), dtype=np.float32)


def _raw_windows(markers: np.ndarray, out: np.ndarray) -> None:
    """``out (F, 2*W*K)`` = x then z of the W-frame window around each frame, not
    centred per window (the pass-1 kernel subtracts each window's centroid in its sums,
    which lets one product serve five cells; :mod:`engine.align.phase_kernel`) but shifted
    by the take's mean horizontal position (θ does not change; float32 sums stay
    accurate)."""
    # the subtraction in the markers' own dtype, as numpy's ``markers - float(mean)``
    cx = markers.dtype.type(float(np.mean(markers[:, :, 0])))
    cz = markers.dtype.type(float(np.mean(markers[:, :, 2])))
    _raw_windows_kernel(markers, cx, cz, THETA_WINDOW, out)


@numba.njit(cache=True, nogil=True)
def _raw_windows_kernel(markers, cx, cz, window, out):
    """:func:`_raw_windows`' copy: slot ``w`` of row ``r`` holds frame ``r + w - window // 2``
    (clipped to the take)."""
    f, k, _ = markers.shape
    half = window // 2
    wk = window * k
    for r in range(f):
        for w in range(window):
            src = min(max(r + w - half, 0), f - 1)
            for c in range(k):
                out[r, w * k + c] = markers[src, c, 0] - cx
                out[r, wk + w * k + c] = markers[src, c, 2] - cz


def window_theta(body: PhaseFeatures, hand: PhaseFeatures, i: int, j: int) -> float:
    """θ of eq. 7 (radians) for body frame ``i`` and hand frame ``j``.

    ``R_y(θ)`` with ``x' = x cosθ + z sinθ``, ``z' = -x sinθ + z cosθ`` applied to
    the hand markers best aligns their window with the body's (least squares
    after removing the horizontal centroid; Kovar, Gleicher & Pighin 2002).
    """
    b = _theta_windows(body.markers, i).astype(float)
    h = _theta_windows(hand.markers, j).astype(float)
    n = b.size // 2
    bx, bz = b[:n], b[n:]
    hx, hz = h[:n], h[n:]
    num = float(np.sum(bx * hz - hx * bz))
    den = float(np.sum(bx * hx + bz * hz))
    return float(np.arctan2(num, den))


def cell_theta_window(
    body: PhaseFeatures, hand: PhaseFeatures, i: np.ndarray, j: np.ndarray
) -> np.ndarray:
    """Exact eq.-7 θ (radians) at cells ``(i, j)`` (vectorised :func:`window_theta`)."""
    b = _theta_windows(body.markers, i).astype(float)
    h = _theta_windows(hand.markers, j).astype(float)
    k = b.shape[-1] // 2
    num = np.sum(b[..., :k] * h[..., k:] - h[..., :k] * b[..., k:], axis=-1)
    den = np.sum(b[..., :k] * h[..., :k] + b[..., k:] * h[..., k:], axis=-1)
    return np.arctan2(num, den)


def rotate_y(v: np.ndarray, theta: np.ndarray | float) -> np.ndarray:
    """Rotate vectors ``(..., 3)`` about +y: ``x' = x cosθ + z sinθ``, ``z' = -x sinθ + z cosθ``."""
    v = np.asarray(v, dtype=float)
    t = np.asarray(theta, dtype=float)
    c, s = np.cos(t), np.sin(t)
    out = v.copy()
    out[..., 0] = v[..., 0] * c + v[..., 2] * s
    out[..., 2] = -v[..., 0] * s + v[..., 2] * c
    return out


def rotated_codes(hand: PhaseFeatures, n_bins: int = THETA_BINS) -> np.ndarray:
    """Sign codes of the hand take rotated by each quantised θ.

    Returns ``(F, n_bins, K * 6)`` int8; bin ``b`` is ``θ = 2π b / n_bins``.
    The dead zone is the hand take's own (rotation does not change speeds).
    """
    if n_bins < 1:
        raise ParameterError(f"rotated codes: n_bins must be >= 1, got {n_bins}")
    f, k, _ = hand.velocity.shape
    out = np.empty((f, n_bins, k, 6), dtype=np.int8)
    for b in range(n_bins):
        theta = 2.0 * np.pi * b / n_bins
        out[:, b, :, :3] = sign_dead_zone(rotate_y(hand.velocity, theta), hand.zone.velocity)
        out[:, b, :, 3:] = sign_dead_zone(
            rotate_y(hand.acceleration, theta), hand.zone.acceleration
        )
    return out.reshape(f, n_bins, k * 6)


# --------------------------------------------------------------------------------------------
# pass-1 rows for the DTW metric plug-in
# --------------------------------------------------------------------------------------------
#
# The DTW engine (engine.dtw) evaluates ``metric(a[i], b[j])`` for band cells only, so each
# frame becomes one float64 row holding everything the cell needs:
#
#   header : [L, n_bins, mode, yaw_bin, step]  L = length of the x (or z) half of the window;
#            step = constant added to every cell (0 in hand rows)
#   window : 2L values (x then z of the eq.-7 window, not centred but shifted by the take's
#            mean; empty in yaw mode)
#   codes  : body: 2 values (P, Q); hand: 2 * n_bins values (P_b, Q_b for every θ bin b)
#
# P and Q are bit masks of the components whose sign is +1 and -1 (up to 48 components:
# 8 markers x (3 velocity + 3 acceleration)), stored exactly as float64 integers. With
# s, s' in {-1, 0, 1}: (s - s')^2 = [P xor P'] + [Q xor Q'] + 2 [(P and Q') or (Q and P')].

_HEADER = PK.HEADER
MODE_WINDOW = PK.MODE_WINDOW
MODE_YAW = PK.MODE_YAW
MAX_COMPONENTS = 48


def pack_codes(codes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bit masks ``(P, Q)`` (float64, exact integers) of ternary codes ``(..., C)``, C <= 48."""
    c = np.asarray(codes)
    if c.shape[-1] > MAX_COMPONENTS:
        raise ParameterError(f"pack codes: at most {MAX_COMPONENTS} components, got {c.shape[-1]}")
    weights = np.uint64(1) << np.arange(c.shape[-1], dtype=np.uint64)
    pos = np.sum(np.where(c > 0, weights, np.uint64(0)), axis=-1, dtype=np.uint64)
    neg = np.sum(np.where(c < 0, weights, np.uint64(0)), axis=-1, dtype=np.uint64)
    return pos.astype(np.float64), neg.astype(np.float64)


def _yaw_bins(yaw: np.ndarray, n_bins: int) -> np.ndarray:
    return np.round(np.asarray(yaw, dtype=float) / (2 * np.pi) * n_bins) % n_bins


def phase_rows(
    body: PhaseFeatures,
    hand: PhaseFeatures,
    theta: str = "window",
    n_bins: int = THETA_BINS,
    yaw_offset: float = 0.0,
    step: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Rows for the ``"splice_phase"`` metric: body ``(n, 5 + 2h + 2B)`` and hand
    ``(m, 5 + 2h + 2B)`` float64, with ``B = n_bins`` and ``h`` the θ-window half-width
    (``THETA_WINDOW`` × markers for ``theta="window"``, else 0).

    Columns: 5 header values (``h``, ``B``, θ mode, trunk-yaw bin, ``step``; the hand's
    step is 0), ``2h`` raw window values (eq. 7), then the packed sign codes: the body's
    ``(p, q)`` followed by ``2B - 2`` zeros (padding to the hand's width), the hand's
    ``(p, q)`` pair for each of the ``B`` θ directions.

    theta : ``"window"`` (eq. 7), ``"trunk"`` (θ = body yaw − hand yaw − ``yaw_offset``)
        or ``"none"`` (θ = 0).
    n_bins : quantised directions of θ (bin ``b`` is ``2π b / n_bins``).
    step : constant added to every cell's cost. DTW counts each cell of the path once,
        so this charges every horizontal or vertical step: where costs are flat (a hold)
        the path keeps a steady rate instead of stalling and jumping. 0 is the paper's.
    """
    if body.arms != hand.arms:
        raise ParameterError(f"phase rows: body has {body.arms} arm(s), hand {hand.arms}")
    if not 1 <= n_bins <= 4096:
        raise ParameterError(f"phase rows: n_bins must be in 1..4096, got {n_bins}")
    if theta not in ("window", "trunk", "none"):
        raise ParameterError(f"theta must be 'window', 'trunk' or 'none', got {theta!r}")
    n, m = body.n_frames, hand.n_frames
    if theta == "window":
        mode, half = MODE_WINDOW, THETA_WINDOW * body.markers.shape[1]
        byaw, hyaw = np.zeros(n), np.zeros(m)
    else:
        mode, half = MODE_YAW, 0
        if theta == "trunk":
            if body.yaw is None or hand.yaw is None:
                raise ParameterError("theta='trunk' needs the trunk yaw of both takes")
            byaw = _yaw_bins(body.yaw, n_bins)
            hyaw = _yaw_bins(hand.yaw + yaw_offset, n_bins)
        else:
            byaw, hyaw = np.zeros(n), np.zeros(m)
    # the DTW engine wants rows of one width: the body's codes are padded with zeros
    width = _HEADER + 2 * half + 2 * n_bins
    a = np.zeros((n, width))
    b = np.zeros((m, width))
    for rows, yaw, st in ((a, byaw, float(step)), (b, hyaw, 0.0)):
        rows[:, 0] = half
        rows[:, 1] = n_bins
        rows[:, 2] = mode
        rows[:, 3] = yaw
        rows[:, 4] = st
    if half:
        _raw_windows(body.markers, a[:, _HEADER : _HEADER + 2 * half])
        _raw_windows(hand.markers, b[:, _HEADER : _HEADER + 2 * half])
    off = _HEADER + 2 * half
    a[:, off], a[:, off + 1] = pack_codes(body.codes)
    # the hand's (p, q) pairs written in place (no (m, B) arrays and copies)
    rotated_packed_codes(
        hand, n_bins, out=(b[:, off : off + 2 * n_bins : 2], b[:, off + 1 : off + 2 * n_bins : 2])
    )
    return a, b


def decimate_phase_rows(
    rows: tuple[np.ndarray, np.ndarray], body: PhaseFeatures, hand: PhaseFeatures, k: int
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`phase_rows`' rows of every ``k``-th frame (frames 0, k, 2k, ...) for a grid of
    ``fps / k``: the header and the sign codes of those frames (derivatives, dead zones and
    the hand's rotated masks of the full-rate take: nothing is recomputed), and the eq.-7
    windows made again from every ``k``-th marker frame (W frames of the coarse grid, as a
    take captured at that rate). ``body``, ``hand``: the features the rows were made from."""
    a, b = rows
    half = int(a[0, 0]) if a.shape[0] else 0
    a_c = np.ascontiguousarray(a[::k])
    b_c = np.ascontiguousarray(b[::k])
    if half:
        _raw_windows(np.ascontiguousarray(body.markers[::k]), a_c[:, _HEADER : _HEADER + 2 * half])
        _raw_windows(np.ascontiguousarray(hand.markers[::k]), b_c[:, _HEADER : _HEADER + 2 * half])
    return a_c, b_c


def rotated_packed_codes(
    hand: PhaseFeatures, n_bins: int = THETA_BINS, out=None
) -> tuple[np.ndarray, np.ndarray]:
    """``pack_codes(rotated_codes(hand, n_bins))`` without the ``(F, B, C)`` array:
    ``(F, n_bins)`` float64 masks P and Q (numba), written to ``out`` (two such arrays,
    e.g. strided views of :func:`phase_rows`' rows) when given."""
    f, k, _ = hand.velocity.shape
    if k * 6 > MAX_COMPONENTS:
        raise ParameterError(f"pack codes: at most {MAX_COMPONENTS} components, got {k * 6}")
    theta = 2.0 * np.pi * np.arange(n_bins) / n_bins
    if out is None:
        p = np.zeros((f, n_bins), dtype=np.float64)
        q = np.zeros((f, n_bins), dtype=np.float64)
    else:
        p, q = out
    _rotated_packed_kernel(
        np.ascontiguousarray(hand.velocity, dtype=np.float64),
        np.ascontiguousarray(hand.acceleration, dtype=np.float64),
        float(hand.zone.velocity),
        float(hand.zone.acceleration),
        np.cos(theta),
        np.sin(theta),
        p,
        q,
    )
    return p, q


@numba.njit(cache=True, inline="always")
def _sign_bits(val, eps, bit):
    """``(P, Q)`` bits of one component: ``bit`` in P where ``sgn_ε(val) = +1``, in Q
    where it is −1 (:func:`sign_dead_zone`'s rule; selects only, so bin loops vectorise)."""
    ok = eps > 0 or val != 0  # no dead zone: exact zeros still read 0
    up = val >= eps and ok
    down = (not up) and val <= -eps and ok
    zero = np.uint64(0)
    return (bit if up else zero), (bit if down else zero)


@numba.njit(cache=True)
def _rotated_packed_kernel(vel, acc, ev, ea, cos_t, sin_t, out_p, out_q):
    """Masks of every frame and θ bin: bins innermost (one frame's components turned
    by every θ at once, a loop that vectorises); the vertical component does not turn,
    so its bit is set once for all bins."""
    frames, markers = vel.shape[0], vel.shape[1]
    nb = cos_t.shape[0]
    pos = np.zeros(nb, np.uint64)
    neg = np.zeros(nb, np.uint64)
    for f in range(frames):
        for b in range(nb):
            pos[b] = 0
            neg[b] = 0
        for k in range(markers):
            for d in range(2):
                if d == 0:
                    x, y, z, eps = vel[f, k, 0], vel[f, k, 1], vel[f, k, 2], ev
                else:
                    x, y, z, eps = acc[f, k, 0], acc[f, k, 1], acc[f, k, 2], ea
                bx = np.uint64(1) << np.uint64(k * 6 + d * 3)
                by = bx << np.uint64(1)
                bz = bx << np.uint64(2)
                py, qy = _sign_bits(y, eps, by)
                for b in range(nb):
                    c = cos_t[b]
                    s = sin_t[b]
                    px, qx = _sign_bits(x * c + z * s, eps, bx)
                    pz, qz = _sign_bits(-x * s + z * c, eps, bz)
                    pos[b] |= (px | py) | pz
                    neg[b] |= (qx | qy) | qz
        for b in range(nb):
            out_p[f, b] = float(pos[b])
            out_q[f, b] = float(neg[b])


@numba.njit(cache=True)
def _popcount(x):
    """Population count of a uint64 (tests; kernels use ``phase_kernel.popcount``)."""
    return PK.popcount(x)


@numba.njit(cache=True, nogil=True, inline="always")
def _theta_bin(body_row, hand_row):
    """Index of the quantised θ (eq. 7) of one cell: window formula, or trunk-yaw difference.

    The same arithmetic as the pass-1 row kernel (:mod:`engine.align.phase_kernel`), so a cell
    costs the same here and there, bit for bit."""
    half = int(body_row[0])
    nb = int(body_row[1])
    if body_row[2] == 0.0:
        num, den = PK.cell_theta_sums(body_row, hand_row, half)
        return PK.theta_bin(num, den, nb)
    return int(body_row[3] - hand_row[3]) % nb


@numba.njit(cache=True, nogil=True)
def splice_phase(body_row, hand_row):
    """Pass-1 local cost ``D1`` (eq. 6) of one cell from :func:`phase_rows` rows.

    Whole band rows go through :func:`engine.align.phase_kernel.forward` (same costs)."""
    half = int(body_row[0])
    b = _theta_bin(body_row, hand_row)
    k = _HEADER + 2 * half
    p = np.uint64(body_row[k])
    q = np.uint64(body_row[k + 1])
    p2 = np.uint64(hand_row[k + 2 * b])
    q2 = np.uint64(hand_row[k + 2 * b + 1])
    return float(np.int64(PK.cell_cost(p, q, p2, q2))) + body_row[4]


# --------------------------------------------------------------------------------------------
# pass-2 features and rows
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class AngleFeatures:
    """Per-frame inputs of the pass-2 metric (eqs. 8-9) for one take.

    forearm : (F, A, 3) float unit vectors ``f = p3 - (p1 + p2)/2``
    hand : (F, A, 3) float unit vectors ``h = p4 - (p1 + p2)/2``
    """

    forearm: np.ndarray
    hand: np.ndarray

    @property
    def n_frames(self) -> int:
        return int(self.forearm.shape[0])

    def rows(self, step: float = 0.0) -> np.ndarray:
        """``(F, 2 + 16A)`` float64 rows for the ``"splice_angle"`` metric
        (:func:`engine.align.angle_kernel.frame_rows`: ``[A, step]``, then per arm ``f, h`` and
        the per-frame products a cell needs); ``step`` (radians) is added to every cell
        (put it in the body rows only; see :func:`phase_rows`)."""
        return AK.frame_rows(self.forearm, self.hand, step)


def angle_features(markers: np.ndarray, theta: np.ndarray | float | None = None) -> AngleFeatures:
    """Forearm and hand vectors (eq. 8) from ``(F, 4*A, 3)`` markers.

    ``theta`` (radians, scalar or ``(F,)``) rotates the take about the vertical
    axis first (used for the hand take, with θ taken along the pass-1 path).
    """
    m = _fill_gaps(np.asarray(markers, dtype=float))
    if m.ndim != 3 or m.shape[1] % 4 != 0 or m.shape[2] != 3 or m.shape[1] == 0:
        raise ParameterError(f"angle features: markers must be (frames, 4*arms, 3), got {m.shape}")
    f, k, _ = m.shape
    arms = m.reshape(f, k // 4, 4, 3)
    centre = 0.5 * (arms[:, :, 0] + arms[:, :, 1])
    fv = arms[:, :, 2] - centre
    hv = arms[:, :, 3] - centre
    if theta is not None:
        th = np.asarray(theta, dtype=float)
        if th.ndim == 1:
            th = th[:, None]
        fv = rotate_y(fv, th)
        hv = rotate_y(hv, th)
    return AngleFeatures(forearm=_unit(fv), hand=_unit(hv))


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.where(n > 1e-12, v / np.where(n > 1e-12, n, 1.0), 0.0)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def splice_angle(body_row, hand_row):
    """Pass-2 local cost ``D2`` (eq. 9, radians, summed over arms) of one cell.

    ``R`` is the smallest rotation taking the hand take's forearm vector ``f'``
    onto the body's ``f``; the cost is the angle between ``h`` and ``R h'``.
    Antiparallel forearms use a half turn about an axis perpendicular to ``f'``.
    Computed as dot products of per-frame vectors (:mod:`engine.align.angle_kernel`, whose
    row kernel gives the same costs bit for bit for whole band rows).
    """
    return AK.cell(body_row, hand_row)


@numba.njit(cache=True, fastmath=_FASTMATH, nogil=True)
def splice_angle_literal(body_row, hand_row):
    """``D2`` by rotating ``h'`` explicitly (cross products) and libm's ``arccos``: the
    per-cell code before :mod:`engine.align.angle_kernel` (references, tests, benchmarks).
    Same :meth:`AngleFeatures.rows`; agrees with :func:`splice_angle` to rounding."""
    arms = int(body_row[0])
    total = body_row[1]
    for a in range(arms):
        o = AK.HEADER + AK.ARM * a
        total += _angle_after_align(
            body_row[o],
            body_row[o + 1],
            body_row[o + 2],
            body_row[o + 3],
            body_row[o + 4],
            body_row[o + 5],
            hand_row[o],
            hand_row[o + 1],
            hand_row[o + 2],
            hand_row[o + 3],
            hand_row[o + 4],
            hand_row[o + 5],
        )
    return total


@numba.njit(cache=True, fastmath=_FASTMATH, inline="always")
def _angle_after_align(fx, fy, fz, hx, hy, hz, gx, gy, gz, kx, ky, kz):
    # R v = v + w×v + w×(w×v)/(1+c), w = g×f, c = g·f (g, f unit)
    c = gx * fx + gy * fy + gz * fz
    if c < -0.999999:
        if abs(gx) < 0.9:
            ax, ay, az = 0.0, -gz, gy
        else:
            ax, ay, az = gz, 0.0, -gx
        nrm = np.sqrt(ax * ax + ay * ay + az * az)
        ax /= nrm
        ay /= nrm
        az /= nrm
        d = ax * kx + ay * ky + az * kz
        rx = 2.0 * d * ax - kx
        ry = 2.0 * d * ay - ky
        rz = 2.0 * d * az - kz
    else:
        wx = gy * fz - gz * fy
        wy = gz * fx - gx * fz
        wz = gx * fy - gy * fx
        cx = wy * kz - wz * ky
        cy = wz * kx - wx * kz
        cz = wx * ky - wy * kx
        ccx = wy * cz - wz * cy
        ccy = wz * cx - wx * cz
        ccz = wx * cy - wy * cx
        inv = 1.0 / (1.0 + c)
        rx = kx + cx + ccx * inv
        ry = ky + cy + ccy * inv
        rz = kz + cz + ccz * inv
    nr = np.sqrt((rx * rx + ry * ry + rz * rz) * (hx * hx + hy * hy + hz * hz))
    if nr < 1e-12:
        return 0.0
    dot = (hx * rx + hy * ry + hz * rz) / nr
    if dot > 1.0:
        dot = 1.0
    elif dot < -1.0:
        dot = -1.0
    return np.arccos(dot)


@numba.njit(nogil=True)  # no cache: a dispatcher argument breaks numba's cache
def _grid_kernel(metric, a, b, rows, cols, out):
    for r in range(rows.shape[0]):
        ar = a[rows[r]]
        for c in range(cols.shape[0]):
            out[r, c] = metric(ar, b[cols[c]])


# ``_grid_kernel`` and ``_path_kernel`` for this module's two splice metrics, each calling its
# metric by name (no dispatcher argument), so that their machine code is cached on disk: a
# fresh process (a batch worker's pair, a server, the CLI) loads them instead of compiling
# them (seconds each). Other metrics go through the generic kernels.


@numba.njit(cache=True, nogil=True)
def _grid_kernel_phase(a, b, rows, cols, out):
    for r in range(rows.shape[0]):
        ar = a[rows[r]]
        for c in range(cols.shape[0]):
            out[r, c] = splice_phase(ar, b[cols[c]])


@numba.njit(cache=True, nogil=True)
def _grid_kernel_angle(a, b, rows, cols, out):
    for r in range(rows.shape[0]):
        ar = a[rows[r]]
        for c in range(cols.shape[0]):
            out[r, c] = splice_angle(ar, b[cols[c]])


def cost_grid(
    metric, a: np.ndarray, b: np.ndarray, rows: np.ndarray, cols: np.ndarray
) -> np.ndarray:
    """Local costs ``metric(a[rows[r]], b[cols[c]])`` as a ``(len(rows), len(cols))`` array.

    ``metric`` is one of this module's numba metrics (:func:`splice_phase`,
    :func:`splice_angle`); used for cost-matrix images and dense tests.
    """
    rows = np.ascontiguousarray(rows, dtype=np.int64)
    cols = np.ascontiguousarray(cols, dtype=np.int64)
    if rows.size and (rows.min() < 0 or rows.max() >= len(a)):
        raise ParameterError(f"cost grid: rows must lie in 0..{len(a) - 1}")
    if cols.size and (cols.min() < 0 or cols.max() >= len(b)):
        raise ParameterError(f"cost grid: columns must lie in 0..{len(b) - 1}")
    out = np.zeros((rows.size, cols.size), dtype=np.float64)
    if metric is splice_phase:
        _grid_kernel_phase(a, b, rows, cols, out)
    elif metric is splice_angle:
        _grid_kernel_angle(a, b, rows, cols, out)
    else:
        _grid_kernel(metric, a, b, rows, cols, out)
    return out


# --------------------------------------------------------------------------------------------
# plain references (tests, small takes)
# --------------------------------------------------------------------------------------------


def phase_cost_reference(
    body: PhaseFeatures, hand: PhaseFeatures, theta: str = "window", yaw_offset: float = 0.0
) -> np.ndarray:
    """Dense ``(n, m)`` D1 with θ exact (no quantisation), numpy; small takes only."""
    n, m = body.n_frames, hand.n_frames
    out = np.zeros((n, m))
    zb = body.codes.reshape(n, -1, 6).astype(np.int64)
    js = np.arange(m)
    for i in range(n):
        if theta == "window":
            th = np.array([window_theta(body, hand, i, j) for j in js])
        elif theta == "trunk":
            th = body.yaw[i] - (hand.yaw + yaw_offset)
        else:
            th = np.zeros(m)
        v = rotate_y(hand.velocity, th[:, None])
        a = rotate_y(hand.acceleration, th[:, None])
        hc = np.concatenate(
            [sign_dead_zone(v, hand.zone.velocity), sign_dead_zone(a, hand.zone.acceleration)],
            axis=2,
        ).astype(np.int64)
        out[i] = np.sum((zb[i][None] - hc) ** 2, axis=(1, 2))
    return out


def angle_cost_reference(body: AngleFeatures, hand: AngleFeatures) -> np.ndarray:
    """Dense ``(n, m)`` D2 by explicit rotation matrices (numpy); small takes only."""
    n, m = body.n_frames, hand.n_frames
    out = np.zeros((n, m))
    for i in range(n):
        for j in range(m):
            for a in range(body.forearm.shape[1]):
                f, h = body.forearm[i, a], body.hand[i, a]
                g, k = hand.forearm[j, a], hand.hand[j, a]
                out[i, j] += _reference_angle(f, h, g, k)
    return out


def _reference_angle(f, h, g, k) -> float:
    axis = np.cross(g, f)
    s = np.linalg.norm(axis)
    c = float(np.dot(g, f))
    if s < 1e-12:
        r = np.eye(3) if c > 0 else None
        if r is None:
            perp = np.array([0.0, -g[2], g[1]]) if abs(g[0]) < 0.9 else np.array([g[2], 0.0, -g[0]])
            perp /= np.linalg.norm(perp)
            r = 2.0 * np.outer(perp, perp) - np.eye(3)
    else:
        u = axis / s
        ux = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
        r = np.eye(3) + s * ux + (1 - c) * ux @ ux
    rk = r @ k
    nn = np.linalg.norm(rk) * np.linalg.norm(h)
    if nn < 1e-12:
        return 0.0
    return float(np.arccos(np.clip(np.dot(h, rk) / nn, -1.0, 1.0)))


def register_metrics() -> None:
    """Register ``"splice_phase"`` and ``"splice_angle"`` with ``engine.dtw`` (idempotent)."""
    from engine.dtw import register_metric

    register_metric(
        "splice_phase",
        splice_phase,
        replace=True,
        prepare=PK.prepare,
        forward=PK.forward,
        row=_cost_row_phase,
        exact=_phase_costs_exact,
    )
    register_metric(
        "splice_angle",
        splice_angle,
        replace=True,
        prepare=AK.prepare,
        forward=AK.forward,
        row=_cost_row_angle,
    )


def _phase_costs_exact(a, b) -> bool:
    """``splice_phase`` costs of rows ``a``, ``b`` are whole multiples of
    ``engine.dtw.fixed.QUANTUM``: sums of squared sign differences (whole numbers) plus
    the rows' step cost (header column 4), so when the step costs are."""
    from engine.dtw.fixed import is_on_grid

    return is_on_grid(a[:, 4]) and is_on_grid(b[:, 4])


# the DTW engine's cost row (``kernels.cost_row_metric``: the uncertainty sweep's local costs,
# row by row) for the two splice metrics, each calling its metric by name: cached on disk


@numba.njit(cache=True, nogil=True)
def _cost_row_phase(a, b, i, lo, hi):
    """``splice_phase(a[i], b[j])`` for ``j`` in ``lo..hi``: ``(hi - lo + 1,)`` float64."""
    out = np.empty(hi - lo + 1)
    ai = a[i]
    for j in range(lo, hi + 1):
        out[j - lo] = splice_phase(ai, b[j])
    return out


@numba.njit(cache=True, nogil=True)
def _cost_row_angle(a, b, i, lo, hi):
    """``splice_angle(a[i], b[j])`` for ``j`` in ``lo..hi``: ``(hi - lo + 1,)`` float64."""
    out = np.empty(hi - lo + 1)
    ai = a[i]
    for j in range(lo, hi + 1):
        out[j - lo] = splice_angle(ai, b[j])
    return out


@numba.njit(nogil=True)  # no cache: a dispatcher argument breaks numba's cache
def _path_kernel(metric, a, b, path, out):
    for k in range(path.shape[0]):
        out[k] = metric(a[path[k, 0]], b[path[k, 1]])


@numba.njit(cache=True, nogil=True)
def _path_kernel_phase(a, b, path, out):  # _path_kernel for splice_phase, cached (see above)
    for k in range(path.shape[0]):
        out[k] = splice_phase(a[path[k, 0]], b[path[k, 1]])


@numba.njit(cache=True, nogil=True)
def _path_kernel_angle(a, b, path, out):  # _path_kernel for splice_angle, cached (see above)
    for k in range(path.shape[0]):
        out[k] = splice_angle(a[path[k, 0]], b[path[k, 1]])


@numba.njit(cache=True, nogil=True)
def _path_kernel_builtin(kind, a, b, path, out):
    """_path_kernel for the DTW engine's built-in cells (``kind``: ``kernels.EUCLIDEAN``,
    ``EUCLIDEAN_FIXED``, the hand-spin pass's metric, or ``SQEUCLIDEAN``), cached (see
    above)."""
    for k in range(path.shape[0]):
        if kind == DK.EUCLIDEAN:
            out[k] = DK.euclidean(a[path[k, 0]], b[path[k, 1]])
        elif kind == DK.EUCLIDEAN_FIXED:
            out[k] = DK.euclidean_fixed(a[path[k, 0]], b[path[k, 1]])
        else:
            out[k] = DK.sqeuclidean(a[path[k, 0]], b[path[k, 1]])


def path_values(metric, a: np.ndarray, b: np.ndarray, path: np.ndarray) -> np.ndarray:
    """``metric(a[i], b[j])`` for every cell ``(i, j)`` of ``path (k, 2)``, as ``(k,)`` float64."""
    path = np.ascontiguousarray(path, dtype=np.int64).reshape(-1, 2)
    out = np.zeros(len(path), dtype=np.float64)
    if metric is splice_phase:
        _path_kernel_phase(a, b, path, out)
    elif metric is splice_angle:
        _path_kernel_angle(a, b, path, out)
    elif metric is DK.euclidean or metric is DK.sqeuclidean or metric is DK.euclidean_fixed:
        _path_kernel_builtin(DK.get_metric(metric).kind, a, b, path, out)
    else:
        _path_kernel(metric, a, b, path, out)
    return out
