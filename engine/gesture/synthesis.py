"""Hand motion without a matching hand capture (Jin & Hahn 2005, §5; docs/method.md §7).

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

Bodies without finger joints (or with a thumb only) get the fingers of a
procedural flat hand grafted under each wrist (``graft_fingers``, through the
splice engineer's ``engine.splice.transfer.plan_transfer``: offsets turned into
the body's hand axes and scaled to its forearm); ``graft=False`` makes that an
error instead.

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

from dataclasses import dataclass, field, replace

import numpy as np

from engine.base.errors import ParameterError

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
    return HandPose(
        name, {"thumb": thumb, "index": index, "middle": middle, "ring": ring, "pinky": pinky}
    )


_FLAT = (0.0, 0.0)
_CURLED = (85.0, 100.0)
_THUMB_TUCKED = (30.0, 40.0, 50.0)
_THUMB_OPEN = (0.0, 0.0, 0.0)

#: The built-in pose library (angles in degrees, see ``HandPose``). "three" counts
#: index, middle and ring; "four" folds the thumb across the palm.
HAND_POSES: dict[str, HandPose] = {
    p.name: p
    for p in (
        _pose(
            "relaxed", (10.0, 10.0, 15.0), (15.0, 25.0), (20.0, 30.0), (25.0, 35.0), (30.0, 40.0)
        ),
        _pose("fist", (35.0, 45.0, 60.0), _CURLED, _CURLED, _CURLED, _CURLED),
        _pose("open", _THUMB_OPEN, _FLAT, _FLAT, _FLAT, _FLAT),
        _pose("point", _THUMB_TUCKED, _FLAT, _CURLED, _CURLED, _CURLED),
        _pose("ok", (25.0, 30.0, 30.0), (45.0, 60.0), (10.0, 10.0), (12.0, 12.0), (15.0, 15.0)),
        _pose("one", _THUMB_TUCKED, _FLAT, _CURLED, _CURLED, _CURLED),
        _pose("two", _THUMB_TUCKED, _FLAT, _FLAT, _CURLED, _CURLED),
        _pose("three", _THUMB_TUCKED, _FLAT, _FLAT, _FLAT, _CURLED),
        _pose("four", (40.0, 50.0, 50.0), _FLAT, _FLAT, _FLAT, _FLAT),
        _pose("five", _THUMB_OPEN, _FLAT, _FLAT, _FLAT, _FLAT),
    )
}


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
    return (
        (2 * t3 - 3 * t2 + 1) * p0
        + (t3 - 2 * t2 + t) * m0
        + (-2 * t3 + 3 * t2) * p1
        + (t3 - t2) * m1
    )


def _hermite_dt(p0, p1, m0, m1, t):
    t2 = t * t
    return (
        (6 * t2 - 6 * t) * p0
        + (3 * t2 - 4 * t + 1) * m0
        + (-6 * t2 + 6 * t) * p1
        + (3 * t2 - 2 * t) * m1
    )


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


def key_weights(
    n_frames: int, key_frames: np.ndarray, easing: str = "hermite", sigma: float = 0.2
) -> tuple[np.ndarray, np.ndarray]:
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


def interpolate_keys(
    n_frames: int, key_frames, key_values, easing: str = "hermite", sigma: float = 0.2
) -> np.ndarray:
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
    return np.asarray(angles, dtype=float) * check_warp(factor)


def check_warp(factor: float) -> float:
    """``factor`` if it can scale flexion angles (a finite number >= 0)."""
    if not (np.isfinite(factor) and factor >= 0):
        raise ParameterError(
            f"warp: expected a flexion scale factor >= 0 (1: as captured), got {factor!r}"
        )
    return float(factor)


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


def speed_matched_warp(
    body_keys, clip_keys, n_body: int, n_clip: int, body_fps: float, clip_fps: float
) -> np.ndarray:
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
                f"speed matching: {name} key frames must increase within [0, {n - 1}], got {k.tolist()}"
            )
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
# Finger joints of a skeleton and their flexion axes


@dataclass(frozen=True)
class HandRig:
    """The finger joints of one hand and their flexion axes.

    Attributes
    ----------
    side : ``"right"`` or ``"left"``
    wrist : int
    joints : (5, 3) int, joint index per finger (``FINGERS``) and anatomical number
        (MCP/PIP/DIP, thumb CMC/MCP/IP); -1 where the rig has none
    axes : (5, 3, 3) float, unit flexion axis of each joint in its rest (local) frame
    bones : (5, 3, 3) float, unit rest direction of the bone each joint moves
    palm_normal : (3,) float, unit, rest frame, pointing out of the palm
    """

    side: str
    wrist: int
    joints: np.ndarray
    axes: np.ndarray
    bones: np.ndarray
    palm_normal: np.ndarray

    @property
    def n_joints(self) -> int:
        return int((self.joints >= 0).sum())


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v)
    return v / n if n > 0 else v


def hand_rig(skeleton, side: str, roles=None) -> HandRig:
    """Finger joints of ``side`` and their flexion axes from the rest geometry.

    ``roles`` (``engine.model.roles.Roles``) is found from the joint names when omitted.
    Raises ``RoleError`` when the hand has no finger joints, saying that synthesis
    needs a skeleton with fingers.
    """
    from engine.base.errors import RoleError
    from engine.model.kinematics import rest_positions
    from engine.model.roles import find_roles

    roles = roles or find_roles(skeleton)
    arm = roles.side(side)
    if not arm.has_fingers:
        raise RoleError(
            f"{side} hand: the skeleton has no finger joints ({skeleton.n_joints} joints); hand "
            "synthesis needs finger joints (graft them with graft_fingers)"
        )
    wrist = roles.require(side, "wrist")
    joints = -np.ones((5, 3), dtype=np.int64)
    for f, finger in enumerate(FINGERS):
        for j, k in zip(arm.fingers[finger], arm.numbers[finger]):
            if 1 <= k <= 3:
                joints[f, k - 1] = j
    rest = rest_positions(skeleton)
    base = rest[arm.hand if arm.hand is not None else wrist]
    knuckles = [
        (f, rest[next(j for j in joints[f] if j >= 0)])
        for f in range(1, 5)
        if (joints[f] >= 0).any()
    ]
    if knuckles:
        forward = np.mean([k for _, k in knuckles], axis=0) - base
    else:  # thumb only: the thumb's direction stands in for the fingers'
        forward = rest[joints[0][joints[0] >= 0][-1]] - base
    if len(knuckles) >= 2:
        lateral = knuckles[0][1] - knuckles[-1][1]  # radial (index side) minus ulnar
    elif (joints[0] >= 0).any() and knuckles:
        lateral = rest[joints[0][joints[0] >= 0][0]] - knuckles[0][1]  # thumb is radial
    else:
        raise RoleError(f"{side} hand: too few finger joints to find the palm's orientation")
    normal = np.cross(lateral, forward) if side == "right" else np.cross(forward, lateral)
    if np.linalg.norm(normal) < 1e-9 * max(np.linalg.norm(forward), 1e-12) ** 2:
        raise RoleError(
            f"{side} hand: finger bases are in line with the wrist; cannot find "
            "the palm's orientation"
        )
    normal = _unit(normal)
    toward_pinky = -_unit(lateral - np.dot(lateral, normal) * normal)
    axes = np.zeros((5, 3, 3))
    bones = np.zeros((5, 3, 3))
    for f in range(5):
        chain = [j for j in joints[f] if j >= 0]
        curl = normal if f > 0 else _unit(normal + toward_pinky)
        for k in range(3):
            j = joints[f, k]
            if j < 0:
                continue
            nxt = chain.index(j) + 1
            kids = skeleton.children(j)
            if nxt < len(chain):
                bone = rest[chain[nxt]] - rest[j]
            elif kids:
                bone = rest[kids[0]] - rest[j]
            else:
                bone = rest[j] - rest[skeleton.parents[j]]
            axis = np.cross(_unit(bone), curl)
            if np.linalg.norm(axis) < 1e-6:
                axis = np.cross(_unit(forward), normal)
            axes[f, k] = _unit(axis)
            b = _unit(bone)
            bones[f, k] = _unit(b - np.dot(b, axes[f, k]) * axes[f, k])
    return HandRig(side, int(wrist), joints, axes, bones, normal)


def extract_flexion(motion, rig: HandRig) -> np.ndarray:
    """(F, 5, 3) flexion angles, degrees; NaN where the rig has no joint.

    The angle is that of the joint's bone, rotated by its local rotation and
    projected on the plane normal to the flexion axis, from its rest direction
    (positive toward the palm). Exact for rotations about the flexion axis; twist
    about the bone and sideways (abduction) swing do not count.
    """
    from engine.model import rotations as rot

    out = np.full((motion.n_frames, 5, 3), np.nan)
    for f in range(5):
        for k in range(3):
            j = rig.joints[f, k]
            if j < 0:
                continue
            axis, bone = rig.axes[f, k], rig.bones[f, k]
            now = rot.rotate(motion.rotations[:, j], np.broadcast_to(bone, (motion.n_frames, 3)))
            sin = np.cross(bone, now) @ axis
            cos = now @ bone
            out[:, f, k] = np.degrees(np.arctan2(sin, cos))
    return out


def apply_flexion(motion, rig: HandRig, angles: np.ndarray):
    """``motion`` with each finger joint rotated by ``angles (F, 5, 3)`` degrees about
    its flexion axis, relative to the rest pose. NaN angles keep the joint's rotation.
    """
    from engine.model import rotations as rot

    ang = np.asarray(angles, dtype=float)
    if ang.shape != (motion.n_frames, 5, 3):
        raise ParameterError(f"flexion angles: expected ({motion.n_frames}, 5, 3), got {ang.shape}")
    rots = motion.rotations.copy()
    for f in range(5):
        for k in range(3):
            j = rig.joints[f, k]
            if j < 0:
                continue
            a = ang[:, f, k]
            ok = np.isfinite(a)
            rots[ok, j] = rot.from_axis_angle(
                np.broadcast_to(rig.axes[f, k], (ok.sum(), 3)), np.radians(a[ok])
            )
    return replace(motion, rotations=rots)


def _for_rig(angles: np.ndarray, rig: HandRig) -> np.ndarray:
    """Angles for the joints a rig has: DIP from 2/3 PIP where missing, NaN elsewhere."""
    out = couple_dip(angles)
    out[..., rig.joints < 0] = np.nan
    return out


# ---------------------------------------------------------------------------
# Grafting fingers onto a body without them


# A procedural right hand, metres, palm down (-y), fingers along +x, thumb on -z.
# (joint name suffix, parent suffix, offset); Mixamo-style names so roles find them.
_DONOR_RIGHT = (
    ("ForeArm", None, (0.0, 0.0, 0.0)),
    ("Hand", "ForeArm", (0.26, 0.0, 0.0)),
    ("HandThumb1", "Hand", (0.02, -0.012, -0.02)),
    ("HandThumb2", "HandThumb1", (0.032, 0.0, -0.032)),
    ("HandThumb3", "HandThumb2", (0.025, 0.0, -0.018)),
    ("HandIndex1", "Hand", (0.09, 0.0, -0.025)),
    ("HandIndex2", "HandIndex1", (0.045, 0.0, 0.0)),
    ("HandIndex3", "HandIndex2", (0.025, 0.0, 0.0)),
    ("HandMiddle1", "Hand", (0.095, 0.0, -0.005)),
    ("HandMiddle2", "HandMiddle1", (0.05, 0.0, 0.0)),
    ("HandMiddle3", "HandMiddle2", (0.03, 0.0, 0.0)),
    ("HandRing1", "Hand", (0.09, 0.0, 0.015)),
    ("HandRing2", "HandRing1", (0.045, 0.0, 0.0)),
    ("HandRing3", "HandRing2", (0.028, 0.0, 0.0)),
    ("HandPinky1", "Hand", (0.08, 0.0, 0.033)),
    ("HandPinky2", "HandPinky1", (0.035, 0.0, 0.0)),
    ("HandPinky3", "HandPinky2", (0.02, 0.0, 0.0)),
)
_DONOR_TIPS = {
    "HandThumb3": 0.02,
    "HandIndex3": 0.02,
    "HandMiddle3": 0.022,
    "HandRing3": 0.02,
    "HandPinky3": 0.018,
}


def donor_hand(side: str = "right"):
    """A one-frame procedural hand (forearm, wrist, 15 finger joints), metres, rest =
    flat hand, used to graft fingers onto bodies without them. The left hand is the
    mirror image of the right (z negated)."""
    from engine.model.motion import Motion, MotionMeta, Skeleton

    if side not in ("right", "left"):
        raise ParameterError(f"side: expected 'right' or 'left', got {side!r}")
    prefix = "Right" if side == "right" else "Left"
    mirror = np.array([1.0, 1.0, 1.0 if side == "right" else -1.0])
    names = [prefix + n for n, _, _ in _DONOR_RIGHT]
    index = {n: i for i, (n, _, _) in enumerate(_DONOR_RIGHT)}
    parents = [-1 if p is None else index[p] for _, p, _ in _DONOR_RIGHT]
    offsets = np.array([o for _, _, o in _DONOR_RIGHT]) * mirror
    channels = [("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")]
    channels += [("Zrotation", "Xrotation", "Yrotation")] * (len(names) - 1)
    ends = {index[n]: _unit(offsets[index[n]]) * length for n, length in _DONOR_TIPS.items()}
    sk = Skeleton(
        names=names, parents=np.array(parents), offsets=offsets, channels=channels, end_sites=ends
    )
    return Motion.rest(
        sk, 1, 30.0, MotionMeta(units="m", source=f"procedural {side} hand", format="derived")
    )


def needs_graft(arm) -> bool:
    """True when an ``ArmRoles`` has fewer than two of index, middle, ring, pinky (the
    palm's orientation needs two; thumb-only rigs such as CMU count as finger-less)."""
    return sum(bool(arm.fingers[f]) for f in FINGERS[1:]) < 2


def graft_fingers(body, sides=("right", "left"), donor=None, roles=None):
    """``body`` with finger joints grafted under each hand of ``sides`` that lacks them.

    Uses the splice engineer's ``engine.splice.transfer.plan_transfer`` (offsets
    turned into the body's axes and scaled to its forearm). The grafted fingers
    hold the donor's rest pose (flat). ``donor`` (a hand ``Motion`` with that side's
    fingers) defaults to ``donor_hand(side)``. Hands with at least two of index..pinky
    are left as they are (``needs_graft``); a thumb-only hand gets the donor's fingers
    where it has none.
    """
    from engine.align.features import hand_frame
    from engine.model.motion import Motion
    from engine.model.roles import find_roles
    from engine.splice.transfer import plan_transfer

    motion = body
    for side in sides:
        roles = find_roles(motion.skeleton) if roles is None or motion is not body else roles
        if not needs_graft(roles.side(side)):
            continue
        hand = donor if donor is not None else donor_hand(side)
        hand_roles = find_roles(hand.skeleton, side_hint=side)
        plan = plan_transfer(
            motion,
            hand,
            roles,
            hand_roles,
            {side: hand_frame(motion, roles, side)},
            {side: hand_frame(hand, hand_roles, side)},
            (side,),
        )
        n, jn = motion.n_frames, plan.skeleton.n_joints
        rots = np.zeros((n, jn, 4))
        rots[..., 0] = 1.0
        bi = np.array([plan.out(j) for j in range(motion.skeleton.n_joints)])
        rots[:, bi] = motion.rotations
        trans = np.broadcast_to(plan.skeleton.offsets, (n, jn, 3)).copy()
        # a body joint below a joint inserted in its chain keeps its motion less the offset
        trans[:, bi] = motion.translations + (plan.skeleton.offsets[bi] - motion.skeleton.offsets)
        motion = Motion(plan.skeleton, rots, trans, motion.fps, motion.meta)
    return motion


# ---------------------------------------------------------------------------
# Result and front ends


@dataclass(frozen=True)
class SynthesisResult:
    """A body take with synthesized fingers.

    Attributes
    ----------
    motion : Motion, the body with finger rotations set
    angles : dict side -> (F, 5, 3) float degrees, the flexion applied (NaN: no joint)
    key_frames : dict side -> (K,) int, body key frames used
    clip_time : dict side -> (F,) float clip frames (clip synthesis), else empty
    """

    motion: object
    angles: dict
    key_frames: dict
    clip_time: dict = field(default_factory=dict)


def parse_pose_keys(specs, n_frames: int | None) -> list[tuple[int, str]]:
    """``["fist@0", "open@30", ...]`` -> sorted ``[(0, "fist"), (30, "open")]``.

    Frames may be negative (counted from the end). Errors name the bad item. With
    ``n_frames`` None (the take not read yet) only the form and the pose names are
    checked, and the frames are returned as written.
    """
    out = []
    for spec in specs:
        text = str(spec)
        name, sep, frame = text.partition("@")
        if not sep:
            raise ParameterError(f"pose key {text!r}: expected POSE@FRAME, e.g. fist@30")
        get_pose(name)
        try:
            k = int(frame)
        except ValueError:
            raise ParameterError(f"pose key {text!r}: frame {frame!r} is not an integer") from None
        if n_frames is None:
            out.append((k, name.strip().lower()))
            continue
        if k < 0:
            k += n_frames
        if not 0 <= k < n_frames:
            raise ParameterError(f"pose key {text!r}: frame outside 0..{n_frames - 1}")
        out.append((k, name.strip().lower()))
    if n_frames is None:
        return out
    out.sort()
    for (a, _), (b, _) in zip(out, out[1:]):
        if a == b:
            raise ParameterError(f"pose keys: two poses at frame {a}")
    return out


def synthesize_from_poses(
    body,
    keys,
    sides=("right", "left"),
    easing: str = "hermite",
    sigma: float = 0.2,
    roles=None,
    graft: bool = True,
) -> SynthesisResult:
    """(c) Key-frame interpolation between library poses on a body with fingers.

    Parameters
    ----------
    body : Motion with finger joints
    keys : list of ``(frame, pose name)`` or of ``"pose@frame"`` strings
    sides : hands to animate
    easing : ``"hermite"``, ``"gaussian"`` or ``"linear"``
    roles : engine.model.roles.Roles of ``body`` (found when omitted)
    graft : give a hand without finger joints the procedural ``donor_hand``'s
        fingers (``graft_fingers``); when False such a hand is an error
    """
    from engine.model.roles import find_roles

    if keys and isinstance(keys[0], str):
        keys = parse_pose_keys(keys, body.n_frames)
    if not keys:
        raise ParameterError("pose keys: give at least one POSE@FRAME")
    keys = sorted((int(k), str(n)) for k, n in keys)
    frames = np.array([k for k, _ in keys])
    vals = np.array([get_pose(n).angles for _, n in keys])
    curve = interpolate_keys(body.n_frames, frames, vals, easing, sigma)
    roles = roles or find_roles(body.skeleton)
    if graft and any(needs_graft(roles.side(s)) for s in sides):
        body = graft_fingers(body, sides, roles=roles)
        roles = find_roles(body.skeleton)
    motion = body
    angles, used = {}, {}
    for side in sides:
        rig = hand_rig(body.skeleton, side, roles)
        angles[side] = _for_rig(curve, rig)
        motion = apply_flexion(motion, rig, angles[side])
        used[side] = frames
    return SynthesisResult(motion=motion, angles=angles, key_frames=used)


def clip_key_frames(clip, rig: HandRig, params=None) -> np.ndarray:
    """Cycle boundaries of a hand clip: its first and last frame and the key poses
    of its fingertips in the wrist frame (``engine.gesture.keyposes``)."""
    from engine.gesture.keyposes import KeyPoseParameters, find_key_poses
    from engine.model import rotations as rot
    from engine.model.kinematics import forward_kinematics, rest_positions

    pos, wrot = forward_kinematics(clip)
    rest = rest_positions(clip.skeleton)
    scale = clip.meters_per_unit
    tips = []
    for f in range(5):
        chain = [j for j in rig.joints[f] if j >= 0]
        if not chain:
            continue
        last = chain[-1]
        bone = rest[last] - rest[clip.skeleton.parents[last]]
        tip = pos[:, last] + rot.rotate(wrot[:, last], bone)
        tips.append(tip)
    pts = np.stack(tips, axis=1) - pos[:, rig.wrist][:, None]
    inv = rot.conjugate(wrot[:, rig.wrist])[:, None]
    local = rot.rotate(np.broadcast_to(inv, pts.shape[:2] + (4,)), pts) * scale
    params = params or KeyPoseParameters(
        joint_weights=(1.0,) * local.shape[1], contrast_threshold=0.05, min_prominence=0.02
    )
    keys = find_key_poses(local, clip.fps, params, with_map=False).frames
    return np.unique(np.r_[0, keys, clip.n_frames - 1]).astype(np.int64)


def synthesize_from_clip(
    body,
    clip,
    side: str = "right",
    factor: float = 1.0,
    body_keys=None,
    clip_keys=None,
    clip_side: str | None = None,
    roles=None,
    clip_roles=None,
    graft: bool = True,
) -> SynthesisResult:
    """(a) Speed-matched temporal alignment of a hand clip, with (b) flexion warping.

    Parameters
    ----------
    body : Motion with finger joints on ``side``
    clip : Motion of a hand (any rig with finger joints; hand-only takes are fine)
    side : the body's hand to animate
    factor : flexion warp factor (1 = as captured)
    body_keys : body key frames; from ``key_poses(body, side)`` plus the first and
        last frame when omitted
    clip_keys : clip cycle boundaries; from ``clip_key_frames`` when omitted
    clip_side : the clip's hand; its only hand (or ``side``) when omitted
    graft : give a finger-less body hand the procedural ``donor_hand``'s fingers
    """
    from engine.gesture.keyposes import key_poses
    from engine.model.roles import find_roles, side_from_name

    roles = roles or find_roles(body.skeleton)
    if graft and needs_graft(roles.side(side)):
        body = graft_fingers(body, (side,), roles=roles)
        roles = find_roles(body.skeleton)
    rig = hand_rig(body.skeleton, side, roles)
    hint = side_from_name(clip.meta.source) if clip.meta.source else None
    clip_roles = clip_roles or find_roles(clip.skeleton, side_hint=hint or clip_side or side)
    if clip_side is None:
        found = [s for s in ("right", "left") if clip_roles.side(s).has_fingers]
        clip_side = side if side in found else (found[0] if found else side)
    clip_rig = hand_rig(clip.skeleton, clip_side, clip_roles)
    if body_keys is None:
        found = key_poses(body, side, with_map=False).frames
        body_keys = np.unique(np.r_[0, found, body.n_frames - 1])
    if clip_keys is None:
        clip_keys = clip_key_frames(clip, clip_rig)
    warp = speed_matched_warp(
        body_keys, clip_keys, body.n_frames, clip.n_frames, body.fps, clip.fps
    )
    src = extract_flexion(clip, clip_rig)
    i0 = np.floor(warp).astype(np.int64)
    i1 = np.minimum(i0 + 1, clip.n_frames - 1)
    w = (warp - i0)[:, None, None]
    angles = src[i0] * (1.0 - w) + src[i1] * w
    angles = _for_rig(warp_flexion(angles, factor), rig)
    motion = apply_flexion(body, rig, angles)
    return SynthesisResult(
        motion=motion,
        angles={side: angles},
        key_frames={side: np.asarray(body_keys, dtype=np.int64)},
        clip_time={side: warp},
    )
