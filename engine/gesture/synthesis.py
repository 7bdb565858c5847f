"""Hand motion without a matching hand capture (Jin & Hahn 2005, §5; METHOD.md §7).

Three ways to give a body take moving fingers:

(a) ``synthesize_from_clip``: speed-matched temporal alignment of a short hand
    clip. The body's key poses (``engine.gesture.keyposes``) cut it into
    intervals; the clip's own key poses (from its fingertip paths in the wrist
    frame) cut it into cycles; body interval ``k`` plays clip cycle ``k mod m``
    uniformly scaled (a piecewise-linear time warp), so the cycle's end pose lands
    on the body's key pose. Outside the first and last key the clip runs at its
    own speed.
(b) ``warp_flexion``: spatial warping, every flexion angle times a factor (a
    "similar but different" action, e.g. a firmer or looser grip).
(c) ``synthesize_from_poses``: key-frame interpolation between poses of the
    built-in library ``HAND_POSES`` (relaxed, fist, open, point, ok, one..five)
    with linear, Hermite or Gaussian easing.

Representation. A hand pose is a flexion angle per finger joint, ``(5, 3)``
degrees (fingers thumb, index, middle, ring, pinky; joints from the palm out:
MCP, PIP, DIP, or for the thumb CMC, MCP, IP). An angle is applied relative to
the rest pose as a rotation about the joint's flexion axis, derived from the
skeleton's rest geometry: the palm normal ``n`` from the knuckle line and the
finger direction (side-aware, so a right-hand clip can drive a left hand), and
per joint ``axis = bone x n`` (bone = the joint's rest direction toward its
child; a leaf joint uses its incoming bone), so a positive angle curls the
finger toward the palm. The thumb curls toward ``n - l`` (palm and across toward
the little finger, ``l`` the unit index-to-pinky direction reversed) — an
approximation. Abduction and twist of the fingers are set to rest (lost from a
clip): only flexion is synthesized, as in the paper.

Coupling (Rijpkema & Girard, used by Jin & Hahn): ``theta_DIP = 2/3 theta_PIP``
wherever DIP is not given (every library pose, and clips whose fingers have no
DIP joint). All easings interpolate every joint with the same weight curve, so
the coupling holds on every synthesized frame.

Easing between key ``k`` (time ``x_k``, angle ``y_k``) and ``k + 1``:

* ``linear``: ``y = y_k + (y_{k+1} - y_k) u`` with ``u`` the fraction of time
  (continuous, but velocity jumps at keys).
* ``hermite``: the curve ``(x(t), y(t))`` is a cubic Hermite in both time and
  angle. ``y`` has zero tangents at keys (a finger starts and ends a bend slowly,
  Jin & Hahn §5); ``x`` has Catmull-Rom tangents from the neighbouring keys'
  times, clamped to ``[0.1, 3]`` times the interval so ``x(t)`` is monotone. For
  a frame time the cubic ``x(t) = time`` is solved for ``t`` (safeguarded Newton,
  to 1e-12) and ``y(t)`` evaluated. Velocity is zero at keys, continuous.
* ``gaussian``: a Gaussian-kernel step, ``s(u) = (Phi((u - 1/2)/sigma) - c u)``
  normalised to ``[0, 1]``, with ``c`` chosen so ``s'(0) = s'(1) = 0`` (no velocity
  jump at keys); ``sigma = 0.2`` of the interval.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from engine.errors import ParameterError

FINGERS = ("thumb", "index", "middle", "ring", "pinky")
EASINGS = ("hermite", "gaussian", "linear")
DIP_PER_PIP = 2.0 / 3.0


@dataclass(frozen=True)
class HandPose:
    """Flexion angles of one hand pose, degrees.

    ``flexion`` maps each finger to its joint angles from the palm out. Fingers
    other than the thumb give ``(MCP, PIP)``; their DIP is ``2/3 PIP``. The thumb
    gives ``(CMC, MCP, IP)``.
    """

    name: str
    flexion: dict[str, tuple[float, ...]]

    @property
    def angles(self) -> np.ndarray:
        """(5, 3) float degrees, fingers in ``FINGERS`` order, joints MCP/PIP/DIP."""
        out = np.zeros((5, 3))
        for f, finger in enumerate(FINGERS):
            vals = self.flexion[finger]
            if finger == "thumb":
                out[f] = vals
            else:
                out[f, :2] = vals
                out[f, 2] = DIP_PER_PIP * vals[1]
        return out


def _pose(name: str, thumb, index, middle, ring, pinky) -> HandPose:
    return HandPose(name, {"thumb": thumb, "index": index, "middle": middle, "ring": ring,
                           "pinky": pinky})


_FLAT = (0.0, 0.0)
_CURLED = (85.0, 100.0)
_THUMB_TUCKED = (30.0, 40.0, 50.0)
_THUMB_OPEN = (0.0, 0.0, 0.0)

#: The built-in pose library (angles in degrees, see ``HandPose``). "three" counts
#: index, middle and ring; "four" folds the thumb across the palm.
HAND_POSES: dict[str, HandPose] = {p.name: p for p in (
    _pose("relaxed", (10.0, 10.0, 15.0), (15.0, 25.0), (20.0, 30.0), (25.0, 35.0), (30.0, 40.0)),
    _pose("fist", (35.0, 45.0, 60.0), _CURLED, _CURLED, _CURLED, _CURLED),
    _pose("open", _THUMB_OPEN, _FLAT, _FLAT, _FLAT, _FLAT),
    _pose("point", _THUMB_TUCKED, _FLAT, _CURLED, _CURLED, _CURLED),
    _pose("ok", (25.0, 30.0, 30.0), (45.0, 60.0), (10.0, 10.0), (12.0, 12.0), (15.0, 15.0)),
    _pose("one", _THUMB_TUCKED, _FLAT, _CURLED, _CURLED, _CURLED),
    _pose("two", _THUMB_TUCKED, _FLAT, _FLAT, _CURLED, _CURLED),
    _pose("three", _THUMB_TUCKED, _FLAT, _FLAT, _FLAT, _CURLED),
    _pose("four", (40.0, 50.0, 50.0), _FLAT, _FLAT, _FLAT, _FLAT),
    _pose("five", _THUMB_OPEN, _FLAT, _FLAT, _FLAT, _FLAT),
)}


def get_pose(name: str) -> HandPose:
    """The library pose called ``name`` (case-insensitive); ``ParameterError`` names the choices."""
    key = str(name).strip().lower()
    if key not in HAND_POSES:
        raise ParameterError(f"unknown hand pose {name!r}; expected one of {', '.join(HAND_POSES)}")
    return HAND_POSES[key]


# ---------------------------------------------------------------------------
# Easing and key-frame interpolation


def gaussian_step(u: np.ndarray, sigma: float = 0.2) -> np.ndarray:
    """Gaussian-kernel step on ``u in [0, 1]`` with zero slope at both ends."""
    from scipy.special import ndtr

    u = np.clip(np.asarray(u, dtype=float), 0.0, 1.0)
    c = np.exp(-0.5 * (0.5 / sigma) ** 2) / (sigma * np.sqrt(2 * np.pi))  # phi(1/2σ)/σ

    def f(x):
        return ndtr((x - 0.5) / sigma) - c * x

    f0, f1 = f(0.0), f(1.0)
    return (f(u) - f0) / (f1 - f0)


def _hermite(p0, p1, m0, m1, t):
    t2, t3 = t * t, t * t * t
    return ((2 * t3 - 3 * t2 + 1) * p0 + (t3 - 2 * t2 + t) * m0
            + (-2 * t3 + 3 * t2) * p1 + (t3 - t2) * m1)


def _hermite_dt(p0, p1, m0, m1, t):
    t2 = t * t
    return ((6 * t2 - 6 * t) * p0 + (3 * t2 - 4 * t + 1) * m0
            + (-6 * t2 + 6 * t) * p1 + (3 * t2 - 2 * t) * m1)


def solve_hermite_time(x0: float, x1: float, m0: float, m1: float, x: np.ndarray) -> np.ndarray:
    """Parameter ``t in [0, 1]`` with ``x(t) = x`` for the monotone cubic Hermite ``x(t)``.

    ``x(t)`` runs from ``x0`` to ``x1 > x0`` with tangents ``m0, m1`` in
    ``[0, 3 (x1 - x0)]``. Newton steps safeguarded by bisection, to 1e-12.
    """
    x = np.clip(np.asarray(x, dtype=float), x0, x1)
    lo = np.zeros_like(x)
    hi = np.ones_like(x)
    t = (x - x0) / (x1 - x0)
    for _ in range(60):
        fx = _hermite(x0, x1, m0, m1, t) - x
        hi = np.where(fx > 0, t, hi)
        lo = np.where(fx <= 0, t, lo)
        d = _hermite_dt(x0, x1, m0, m1, t)
        step = np.where(d > 1e-15, fx / np.where(d > 1e-15, d, 1.0), np.inf)
        t_new = t - step
        bad = ~((t_new > lo) & (t_new < hi))
        t_new = np.where(bad, 0.5 * (lo + hi), t_new)
        if np.max(np.abs(t_new - t), initial=0.0) < 1e-13:
            t = t_new
            break
        t = t_new
    return t


def key_weights(n_frames: int, key_frames: np.ndarray, easing: str = "hermite",
                sigma: float = 0.2) -> tuple[np.ndarray, np.ndarray]:
    """Segment index and easing weight of every frame between sorted key frames.

    Returns ``segment (F,) int`` (key ``k`` to ``k + 1``; frames before the first
    key use segment 0 with weight 0, after the last the last segment with
    weight 1) and ``weight (F,) float in [0, 1]``.
    """
    if easing not in EASINGS:
        raise ParameterError(f"easing: expected one of {', '.join(EASINGS)}, got {easing!r}")
    keys = np.asarray(key_frames, dtype=float)
    if keys.ndim != 1 or len(keys) == 0:
        raise ParameterError("key frames: expected at least one key frame")
    if np.any(np.diff(keys) <= 0):
        raise ParameterError(f"key frames must be strictly increasing, got {keys.tolist()}")
    frames = np.arange(n_frames, dtype=float)
    if len(keys) == 1:
        return np.zeros(n_frames, dtype=np.int64), np.zeros(n_frames)
    seg = np.clip(np.searchsorted(keys, frames, side="right") - 1, 0, len(keys) - 2)
    x0, x1 = keys[seg], keys[seg + 1]
    u = np.clip((frames - x0) / (x1 - x0), 0.0, 1.0)
    if easing == "linear":
        w = u
    elif easing == "gaussian":
        w = gaussian_step(u, sigma)
    else:
        # Catmull-Rom tangents of time at each key, clamped per segment for monotone x(t)
        k = len(keys)
        tang = np.empty(k)
        tang[0] = keys[1] - keys[0]
        tang[-1] = keys[-1] - keys[-2]
        if k > 2:
            tang[1:-1] = 0.5 * (keys[2:] - keys[:-2])
        w = np.empty(n_frames)
        for s in range(k - 1):
            sel = seg == s
            if not sel.any():
                continue
            dx = keys[s + 1] - keys[s]
            m0 = np.clip(tang[s], 0.1 * dx, 3.0 * dx)
            m1 = np.clip(tang[s + 1], 0.1 * dx, 3.0 * dx)
            t = solve_hermite_time(keys[s], keys[s + 1], m0, m1, frames[sel])
            w[sel] = _hermite(0.0, 1.0, 0.0, 0.0, t)  # y(t) with zero tangents
    w = np.where(frames <= keys[0], 0.0, np.where(frames >= keys[-1], 1.0, w))
    return seg.astype(np.int64), w


def interpolate_keys(n_frames: int, key_frames, key_values, easing: str = "hermite",
                     sigma: float = 0.2) -> np.ndarray:
    """Interpolate values at sorted key frames to every frame.

    Parameters
    ----------
    n_frames : int
    key_frames : (K,) increasing frame numbers (may be fractional)
    key_values : (K, ...) float, e.g. (K, 5, 3) flexion angles
    easing : ``"hermite"``, ``"gaussian"`` or ``"linear"``

    Returns
    -------
    (n_frames, ...) float. Values before the first key hold the first pose, after
    the last key the last pose.
    """
    vals = np.asarray(key_values, dtype=float)
    keys = np.asarray(key_frames, dtype=float)
    if len(vals) != len(keys):
        raise ParameterError(f"key poses: {len(keys)} key frames but {len(vals)} poses")
    seg, w = key_weights(n_frames, keys, easing, sigma)
    if len(keys) == 1:
        return np.broadcast_to(vals[0], (n_frames,) + vals.shape[1:]).copy()
    w = w.reshape((-1,) + (1,) * (vals.ndim - 1))
    return vals[seg] * (1.0 - w) + vals[seg + 1] * w


def warp_flexion(angles: np.ndarray, factor: float) -> np.ndarray:
    """Spatial warping (Jin & Hahn §5): every flexion angle times ``factor``.

    ``angles (..., 5, 3)`` degrees; NaN (missing joints) stays NaN.
    """
    if not (np.isfinite(factor) and factor >= 0):
        raise ParameterError(f"flexion warp factor: expected a number >= 0, got {factor!r}")
    return np.asarray(angles, dtype=float) * float(factor)


def couple_dip(angles: np.ndarray) -> np.ndarray:
    """Fill missing (NaN) DIP angles of the four fingers with ``2/3 PIP``.

    ``angles (..., 5, 3)`` degrees; the thumb (row 0) is left as it is.
    """
    out = np.array(angles, dtype=float, copy=True)
    dip = out[..., 1:, 2]
    pip = out[..., 1:, 1]
    fill = np.isnan(dip) & np.isfinite(pip)
    dip[fill] = DIP_PER_PIP * pip[fill]
    out[..., 1:, 2] = dip
    return out


# ---------------------------------------------------------------------------
# Speed-matched temporal alignment


def speed_matched_warp(body_keys, clip_keys, n_body: int, n_clip: int, body_fps: float,
                       clip_fps: float) -> np.ndarray:
    """Clip time (fractional clip frame) for every body frame.

    Body interval ``[b_k, b_{k+1}]`` plays clip cycle ``[c_j, c_{j+1}]`` with
    ``j = k mod (len(clip_keys) - 1)``, scaled uniformly (speed matched, end poses on
    the key poses). Before ``b_0`` and after the last body key the clip plays at its
    own speed (``clip_fps / body_fps`` clip frames per body frame), clamped to the clip.

    Parameters
    ----------
    body_keys : (K,) increasing body frames, K >= 2
    clip_keys : (C,) increasing clip frames, C >= 2
    n_body, n_clip : int
    body_fps, clip_fps : float

    Returns
    -------
    (n_body,) float clip frames in ``[0, n_clip - 1]``
    """
    b = np.asarray(body_keys, dtype=float)
    c = np.asarray(clip_keys, dtype=float)
    for name, k, n in (("body", b, n_body), ("clip", c, n_clip)):
        if k.ndim != 1 or len(k) < 2:
            raise ParameterError(f"speed matching: need at least 2 {name} key frames, got {len(k)}")
        if np.any(np.diff(k) <= 0) or k[0] < 0 or k[-1] > n - 1:
            raise ParameterError(
                f"speed matching: {name} key frames must increase within [0, {n - 1}], got {k.tolist()}")
    rate = clip_fps / body_fps
    frames = np.arange(n_body, dtype=float)
    out = np.empty(n_body)
    n_cycles = len(c) - 1
    before = frames < b[0]
    out[before] = c[0] - (b[0] - frames[before]) * rate
    after = frames >= b[-1]
    last_cycle = (len(b) - 2) % n_cycles
    out[after] = c[last_cycle + 1] + (frames[after] - b[-1]) * rate
    inside = ~before & ~after
    k = np.clip(np.searchsorted(b, frames[inside], side="right") - 1, 0, len(b) - 2)
    j = k % n_cycles
    u = (frames[inside] - b[k]) / (b[k + 1] - b[k])
    out[inside] = c[j] + u * (c[j + 1] - c[j])
    return np.clip(out, 0.0, n_clip - 1)


# ---------------------------------------------------------------------------
# Result helpers


@dataclass(frozen=True)
class SynthesisResult:
    """A body take with synthesized fingers.

    Attributes
    ----------
    motion : Motion, the body with finger rotations set
    angles : dict side -> (F, 5, 3) float degrees, the flexion applied (NaN: no joint)
    key_frames : (K,) int, body key frames used
    clip_time : (F,) float or None, clip frame per body frame (clip synthesis)
    """

    motion: object
    angles: dict
    key_frames: np.ndarray
    clip_time: np.ndarray | None = None


def _replace_rotations(motion, rotations):
    return replace(motion, rotations=rotations)
