"""Key poses from the pose-space distance map (Jin & Hahn 2005, §4; docs/method.md §7).

``M(i, j) = sum_t w_t |P_t(i) - P_t(j)|`` over the arm's shoulder, elbow, wrist
and hand tip (Jin & Hahn eq. 1), with the root translation and the pelvis yaw
removed (positions in the body frame of ``engine.gesture.body``, metres).

Local contrast enhancement (the paper gives no formula; this is ours): the local
mean ``mu(i, j)`` of ``M`` over a ``contrast_window_s`` square is computed; where
``mu < contrast_threshold`` the map is multiplied by
``min(contrast_threshold / mu, max_gain)``, so small, hand-tip driven motion
reaches the same scale as large arm motion while truly static stretches
(``M ~ 0``) stay near zero.

Stepwise search (§4): from frame ``i`` (first ``i = 0``) take the first local
maximum of the enhanced row ``M(i, j > i)`` whose prominence is at least
``min_prominence``; look ``search_radius_s`` past it for a higher local maximum
and move there while one exists; that frame ``j`` is a key frame; repeat from
``i = j`` until the row has no more maxima.

Memory: the search needs only the rows at key frames (each computed from a
block of ``2h + 1`` rows for the local mean), so long takes never hold an
``F x F`` matrix; ``pose_distance_map`` builds the full (or strided) map for
display in row chunks.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.base.errors import ParameterError

JOINTS = ("shoulder", "elbow", "wrist", "hand_tip")


@dataclass(frozen=True)
class KeyPoseParameters:
    """Tunable parameters of the key-pose search.

    Attributes
    ----------
    joint_weights : floats, one per point
        Weights ``w_t`` of shoulder, elbow, wrist and hand tip; the tip is raised
        (Jin & Hahn start equal and raise the tip to catch finger-driven motion).
        Other point sets (e.g. five fingertips of a hand clip) give one weight each.
    contrast_threshold : float
        Weighted metres; local mean distance below which contrast is raised;
        0 turns enhancement off.
    contrast_window_s : float
        Side of the square window of the local mean, seconds.
    max_gain : float
        Largest contrast gain (>= 1).
    min_prominence : float
        Weighted metres, in the enhanced map; smaller maxima are noise.
    search_radius_s : float
        Seconds past the first maximum searched for a higher one.
    max_map_frames : int
        Longest side of the map returned for display; longer takes get a strided map.
    """

    joint_weights: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 2.0)
    contrast_threshold: float = 0.25
    contrast_window_s: float = 0.5
    max_gain: float = 4.0
    min_prominence: float = 0.1
    search_radius_s: float = 0.1
    max_map_frames: int = 1500

    def __post_init__(self) -> None:
        w = np.asarray(self.joint_weights, dtype=float)
        if w.ndim != 1 or len(w) < 1 or not np.all(np.isfinite(w)) or np.any(w < 0) or w.sum() <= 0:
            raise ParameterError(
                f"key poses joint_weights: expected one weight >= 0 per point (shoulder, elbow, "
                f"wrist, hand tip) with a positive sum, got {self.joint_weights!r}"
            )
        for name in ("contrast_threshold", "min_prominence", "search_radius_s"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ParameterError(f"key poses {name}: expected a number >= 0, got {v!r}")
        if not (np.isfinite(self.contrast_window_s) and self.contrast_window_s > 0):
            raise ParameterError(
                f"key poses contrast_window_s: expected > 0, got {self.contrast_window_s!r}"
            )
        if not (np.isfinite(self.max_gain) and self.max_gain >= 1):
            raise ParameterError(f"key poses max_gain: expected >= 1, got {self.max_gain!r}")
        if int(self.max_map_frames) < 2:
            raise ParameterError(
                f"key poses max_map_frames: expected >= 2, got {self.max_map_frames!r}"
            )


@dataclass(frozen=True)
class KeyPoses:
    """Key frames and the pose-space distance map.

    Attributes
    ----------
    frames : (K,) int array
        Key frames, increasing.
    distance_map : (G, G) float32
        ``M`` at frames ``map_frames`` (weighted metres).
    enhanced_map : (G, G) float32
        ``M`` after local contrast enhancement.
    map_frames : (G,) int array
        Frames of the map rows/columns (every frame, or a stride for long takes).
    fps : float
    """

    frames: np.ndarray
    distance_map: np.ndarray
    enhanced_map: np.ndarray
    map_frames: np.ndarray
    fps: float


class _PoseSpace:
    """Rows of the raw and enhanced distance map, computed on demand."""

    def __init__(
        self, points: np.ndarray, weights: np.ndarray, fps: float, params: KeyPoseParameters
    ):
        self.points = points
        self.weights = weights
        self.n = len(points)
        self.params = params
        self.half = max(1, int(round(0.5 * params.contrast_window_s * fps)))

    def raw_rows(self, a: int, b: int) -> np.ndarray:
        """``M[a:b, :]`` as float64."""
        out = np.zeros((b - a, self.n))
        for t, w in enumerate(self.weights):
            if w == 0:
                continue
            d = self.points[a:b, None, t, :] - self.points[None, :, t, :]
            out += w * np.sqrt(np.einsum("ijk,ijk->ij", d, d))
        return out

    def rows(self, a: int, b: int) -> tuple[np.ndarray, np.ndarray]:
        """Raw and enhanced ``M[a:b, :]``."""
        from scipy.ndimage import uniform_filter1d

        h = self.half
        lo, hi = max(0, a - h), min(self.n, b + h)
        block = self.raw_rows(lo, hi)
        raw = block[a - lo : b - lo]
        tau = self.params.contrast_threshold
        if tau <= 0:
            return raw, raw.copy()
        size = 2 * h + 1
        mean = uniform_filter1d(block, size, axis=1, mode="nearest")
        # edge-replicate rows so every output row sees a full (2h + 1)-row window
        mean = np.pad(mean, ((lo - (a - h), (b + h) - hi), (0, 0)), mode="edge")
        mean = uniform_filter1d(mean, size, axis=0, mode="nearest")[h : h + (b - a)]
        gain = np.ones_like(mean)
        low = mean < tau
        gain[low] = np.minimum(tau / np.maximum(mean[low], 1e-12), self.params.max_gain)
        return raw, raw * gain


def _as_points(points: np.ndarray, fps: float, n_weights: int = 4) -> np.ndarray:
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 3 or pts.shape[1:] != (n_weights, 3) or len(pts) < 1:
        raise ParameterError(
            f"key poses: points must be (frames, {n_weights}, 3), one point per joint weight "
            f"(shoulder, elbow, wrist, hand tip), got {pts.shape}"
        )
    if not (np.isfinite(fps) and fps > 0):
        raise ParameterError(f"key poses: fps must be positive, got {fps!r}")
    if not np.all(np.isfinite(pts)):
        from engine.gesture.phases import fill_gaps

        pts = fill_gaps(pts.reshape(len(pts), -1)).reshape(pts.shape)
    return pts


def pose_distance_map(
    points: np.ndarray, fps: float, params: KeyPoseParameters | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Raw and contrast-enhanced pose-space distance maps for display.

    Parameters
    ----------
    points : (F, 4, 3) float, metres
        Shoulder, elbow, wrist and hand tip in the body frame.
    fps : float
    params : KeyPoseParameters

    Returns
    -------
    distance_map, enhanced_map : (G, G) float32, weighted metres
    map_frames : (G,) int, the frames sampled (stride ``ceil(F / max_map_frames)``).
        With a stride > 1 the contrast's local mean is taken on the strided grid, so
        the enhanced map is an approximation of the full-resolution one (the key
        frames never use it).
    """
    params = params or KeyPoseParameters()
    pts = _as_points(points, fps, len(params.joint_weights))
    space = _PoseSpace(pts, np.asarray(params.joint_weights, float), fps, params)
    n = len(pts)
    stride = int(np.ceil(n / int(params.max_map_frames)))
    frames = np.arange(0, n, stride)
    g = len(frames)
    raw = np.zeros((g, g), dtype=np.float32)
    enh = np.zeros((g, g), dtype=np.float32)
    if stride == 1:
        chunk = max(1, 262144 // max(n, 1))
        for k in range(0, g, chunk):
            r, e = space.rows(k, min(g, k + chunk))
            raw[k : k + len(r)] = r
            enh[k : k + len(e)] = e
    else:
        # long takes: the map at every stride-th frame, the local mean on that grid
        # (window shrunk by the stride), so display costs O(G^2) not O(F * G * window)
        sub = _PoseSpace(pts[frames], space.weights, fps / stride, params)
        for k in range(0, g, 512):
            r, e = sub.rows(k, min(g, k + 512))
            raw[k : k + len(r)] = r
            enh[k : k + len(e)] = e
    return raw, enh, frames


def stepwise_key_frames(
    row_of, n_frames: int, fps: float, params: KeyPoseParameters, start: int = 0
) -> np.ndarray:
    """The stepwise local-maximum search over rows given by ``row_of(i) -> (F,)``.

    Returns the key frames (after ``start``), increasing.
    """
    from scipy.signal import find_peaks

    radius = max(0, int(round(params.search_radius_s * fps)))
    keys = []
    i = int(start)
    while i < n_frames - 2:
        row = np.asarray(row_of(i), dtype=float)[i:]
        peaks, _ = find_peaks(
            row, prominence=params.min_prominence if params.min_prominence > 0 else None
        )
        peaks = peaks[peaks > 0]
        if len(peaks) == 0:
            break
        j = int(peaks[0])
        while True:
            near = peaks[(peaks > j) & (peaks <= j + radius)]
            higher = near[row[near] > row[j]]
            if len(higher) == 0:
                break
            j = int(higher[np.argmax(row[higher])])
        keys.append(i + j)
        i = i + j
    return np.asarray(keys, dtype=np.int64)


def find_key_poses(
    points: np.ndarray, fps: float, params: KeyPoseParameters | None = None, with_map: bool = True
) -> KeyPoses:
    """Key frames of one arm (and the maps for display).

    Parameters
    ----------
    points : (F, K, 3) float, metres
        Shoulder, elbow, wrist and hand tip in the body frame (root translation and
        pelvis yaw removed), K = 4; or any K points with K joint weights.
    fps : float
    params : KeyPoseParameters
    with_map : bool
        Also build the (possibly strided) maps; when False they are ``(0, 0)``.

    Returns
    -------
    KeyPoses
    """
    params = params or KeyPoseParameters()
    pts = _as_points(points, fps, len(params.joint_weights))
    space = _PoseSpace(pts, np.asarray(params.joint_weights, float), fps, params)
    frames = stepwise_key_frames(lambda i: space.rows(i, i + 1)[1][0], len(pts), fps, params)
    if with_map:
        raw, enh, map_frames = pose_distance_map(pts, fps, params)
    else:
        raw = enh = np.zeros((0, 0), dtype=np.float32)
        map_frames = np.zeros(0, dtype=np.int64)
    return KeyPoses(
        frames=frames, distance_map=raw, enhanced_map=enh, map_frames=map_frames, fps=float(fps)
    )


def key_poses(
    motion,
    side: str = "right",
    params: KeyPoseParameters | None = None,
    arms=None,
    with_map: bool = True,
    paths=None,
) -> KeyPoses:
    """Key poses of one arm of a full-body take (root translation and pelvis yaw removed).

    Parameters
    ----------
    motion : engine.model.motion.Motion
    side : ``"right"`` or ``"left"``
    params : KeyPoseParameters
    arms : engine.gesture.body.BodyArms, found from joint roles when omitted
    with_map : also return the distance maps
    paths : engine.gesture.body.ArmPaths already computed for ``motion`` (optional)
    """
    from engine.gesture.body import SIDES, arm_paths

    if side not in SIDES:
        raise ParameterError(f"side: expected 'right' or 'left', got {side!r}")
    paths = paths or arm_paths(motion, arms)
    return find_key_poses(paths.points[side], motion.fps, params, with_map=with_map)
