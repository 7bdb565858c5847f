"""Alignment markers per arm: the paper's four points, from a skeleton or a marker set.

Majkowska et al. place four markers on each arm: two on the wrist (radial and
ulnar styloid), one on the forearm and one on the back of the hand. For a
skeletal take they are *virtual* markers at fixed offsets in the forearm and hand
joint frames, computed by forward kinematics; for a marker take (C3D/TRC) they
are the labelled markers themselves (pyomeca ``STYLr``, ``STYLu``, ``LARM*``,
``MEDH``/``LATH``/``INDEX``; Plug-in Gait ``RWRA``, ``RWRB``, ``RFRA``, ``RFIN``).

Output convention (:class:`ArmMarkers`): ``(F, 4, 3)`` in metres, y up, order
``p1`` radial wrist, ``p2`` ulnar wrist, ``p3`` forearm, ``p4`` back of the hand
(docs/method.md §3: ``f = p3 - (p1+p2)/2``, ``h = p4 - (p1+p2)/2``), with the shoulder
position subtracted when the take has a shoulder (docs/method.md §2.1).

The hand's rest frame (:class:`HandFrame`)
------------------------------------------
Offsets are defined in an anatomical frame of the rest pose so that two rigs
with different axes, rest poses and units give comparable markers:

* ``along``: the forearm's direction at rest (elbow -> wrist). Rigs whose
  forearm joint sits at the wrist (Leap ``rForeArm``) or that have none
  (ManipNet ``WRIST``) use wrist -> finger bases instead. The rest wrist is
  assumed straight (true of T/A-pose rigs).
* ``dorsal``: the normal of the back of the hand, from the finger bases (index
  and pinky/ring joint 1) when the rig has them; else from the elbow's flexion
  axis (the mean rotation vector of the elbow over the take: with the forearm at
  mid-pronation the back of the hand faces along it); else from the thumb; else
  the up axis. It is then snapped to the nearest axis of the rest frame (BVH rigs
  orient joints along their rest axes), so a body without fingers and a hand take
  from the same rig get the same frame.
* ``radial``: completes the right-handed frame (thumb side).

Marker offsets, with ``L`` the forearm length (estimated as palm length / 0.36
when the rig has no elbow apart from the wrist): ``p1, p2 = wrist ± 0.12 L radial``
and ``p3 = wrist - 0.5 L along`` in the forearm joint's frame; ``p4 = wrist +
0.4 L along + 0.1 L dorsal`` in the hand joint's frame.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from engine.base.errors import ParameterError, RoleError
from engine.base.limits import check_grid
from engine.model.fastkin import forward_kinematics, rotate_offset
from engine.model.kinematics import rest_positions
from engine.model.motion import MarkerSet, Motion

MARKER_NAMES = ("wrist_radial", "wrist_ulnar", "forearm", "hand")
#: marker offsets as fractions of the forearm length L
WRIST_HALF_WIDTH = 0.12
FOREARM_POINT = 0.5
HAND_POINT = 0.4
HAND_DORSAL = 0.1
#: hand length (wrist -> middle finger tip) / forearm length, to estimate L (anthropometric
#: means: hand ~0.108, forearm ~0.146 of body height); palm (wrist -> knuckles) / forearm
HAND_TO_FOREARM = 0.72
PALM_TO_FOREARM = 0.36
DEFAULT_FOREARM_M = 0.25

_AXES = np.vstack([np.eye(3), -np.eye(3)])


@dataclass(frozen=True)
class HandFrame:
    """Rest-pose geometry of one arm of a skeleton (file axes and units).

    Attributes
    ----------
    side : ``"right"`` or ``"left"``
    wrist : int
        The wrist joint (root of the transferred subtree).
    forearm_joint : int
        Joint whose world rotation carries the forearm (the elbow role when it is
        an ancestor of the wrist, else the wrist).
    hand_joint : int
        Joint whose rotation orients the palm (the ``hand`` role, else the wrist).
    shoulder : int or None
        Joint whose position is subtracted (the ``shoulder`` role).
    elbow_apart : bool
        True when the forearm joint sits away from the wrist (a real elbow).
    along, dorsal, radial : (3,) float unit vectors, rest world = rest joint axes
    forearm_length : float, file units
    palm_length : float or None, file units (wrist -> finger bases)
    hand_length : float or None, file units (wrist -> tip of the middle finger, else the
        longest finger, along its joints and End Site)
    dorsal_source : str
        ``"fingers"``, ``"elbow flexion"``, ``"thumb"`` or ``"up axis"``.
    """

    side: str
    wrist: int
    forearm_joint: int
    hand_joint: int
    shoulder: int | None
    elbow_apart: bool
    along: np.ndarray
    dorsal: np.ndarray
    radial: np.ndarray
    forearm_length: float
    palm_length: float | None
    hand_length: float | None
    dorsal_source: str

    @property
    def basis(self) -> np.ndarray:
        """(3, 3) rest anatomical frame, columns ``along, radial, dorsal``."""
        return np.column_stack([self.along, self.radial, self.dorsal])


@dataclass(frozen=True)
class ArmMarkers:
    """The four alignment markers of one arm.

    markers : (F, 4, 3) float, metres, y up (order of ``MARKER_NAMES``)
    fps : float
    side : str
    shoulder_subtracted : bool
    """

    markers: np.ndarray
    fps: float
    side: str
    shoulder_subtracted: bool

    @property
    def n_frames(self) -> int:
        return int(self.markers.shape[0])


# --------------------------------------------------------------------------------------------
# axes and units
# --------------------------------------------------------------------------------------------


def to_y_up(points: np.ndarray, up_axis: str) -> np.ndarray:
    """Points ``(..., 3)`` in a y-up frame: z-up data turn by -90° about x (``(x, z, -y)``)."""
    p = np.asarray(points, dtype=float)
    if up_axis == "y":
        return p
    if up_axis == "z":
        return np.stack([p[..., 0], p[..., 2], -p[..., 1]], axis=-1)
    raise ParameterError(f"up axis must be 'y' or 'z', got {up_axis!r}")


def up_vector(up_axis: str) -> np.ndarray:
    """The up direction ``(3,)`` in a take's own axes."""
    return np.array([0.0, 0.0, 1.0]) if up_axis == "z" else np.array([0.0, 1.0, 0.0])


#: Hampel spike filter: a frame whose marker leaves the median of its 3-frame neighbourhood
#: by more than this many robust standard deviations (of that distance, over the take) is
#: replaced by the median
SPIKE_SIGMAS = 5.0


def median3(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Elementwise median of three arrays: ``np.median(np.stack([a, b, c]), axis=0)``
    bit for bit (NaN where any is NaN), without sorting a stacked copy."""
    lo = np.minimum(a, b)
    hi = np.maximum(a, b)
    return np.maximum(lo, np.minimum(hi, c))


def despike(points: np.ndarray) -> np.ndarray:
    """Single-frame spikes removed from trajectories ``(F, K, 3)`` (or ``(F, D)``).

    Hampel filter per marker: ``r = |x - median(x[t-1..t+1])|``; frames with ``r`` above
    ``SPIKE_SIGMAS`` times a robust scale of ``r`` over the take (1.4826 median, or the
    90th percentile / 1.645 where most ``r`` are 0) take the median. Smooth motion and small jitter are left as they are
    (their ``r`` is within the take's own spread); a glove or optical glitch of one frame
    is removed before any derivative sees it. NaN gaps stay NaN.
    """
    p = np.asarray(points, dtype=float)
    if p.shape[0] < 3:
        return p.copy()
    flat = p.reshape(p.shape[0], -1, p.shape[-1]) if p.ndim >= 3 else p[:, :, None]
    before = np.concatenate([flat[:1], flat[:-1]])
    after = np.concatenate([flat[1:], flat[-1:]])
    med = median3(before, flat, after)
    r = np.linalg.norm(flat - med, axis=-1)  # (F, K), >= 0
    with np.errstate(invalid="ignore"):
        # scale of r (half-normal-like): 1.4826 x median, or q90 / 1.645 where most r are 0
        # (a monotone stretch is its own median)
        scale = np.maximum(1.4826 * np.nanmedian(r, axis=0), np.nanquantile(r, 0.9, axis=0) / 1.645)
        bad = r > SPIKE_SIGMAS * np.maximum(scale, 1e-9)
    out = np.where(bad[..., None], med, flat)
    return out.reshape(p.shape)


def resample_points(points: np.ndarray, fps: float, target_fps: float) -> np.ndarray:
    """Resampling of ``(F, ...)`` trajectories to ``target_fps`` without aliasing.

    Output has ``round((F-1) * target_fps / fps) + 1`` frames spanning the same
    duration (as :func:`engine.model.kinematics.resample`). Going to a lower rate, the
    trajectories are first low-passed by a Gaussian of ``0.5 / target_fps`` seconds:
    the new Nyquist frequency keeps about 30 % of its amplitude and frame-to-frame
    jitter of the faster take does not fold into the slow motion. Then linear
    interpolation. NaN gaps are filled for the filter and stay NaN in the output
    (frames that interpolate a gap frame).
    """
    p = np.asarray(points, dtype=float)
    f = p.shape[0]
    if f == 0 or fps == target_fps:
        return p.copy()
    n_out = check_grid("resampling", f, fps, target_fps)  # bounded before allocating
    gaps = None
    if target_fps < fps and f > 1:
        from scipy.ndimage import gaussian_filter1d

        from engine.align.metrics import _fill_gaps

        if np.isnan(p).any():
            gaps = np.isnan(p).astype(float)
            p = _fill_gaps(p)
        p = gaussian_filter1d(p, 0.5 * fps / target_fps, axis=0, mode="nearest")
    t = np.clip(np.arange(n_out) * (fps / target_fps), 0.0, f - 1)
    i0 = np.floor(t).astype(np.int64)
    i1 = np.minimum(i0 + 1, f - 1)
    w = (t - i0).reshape((-1,) + (1,) * (p.ndim - 1))
    out = p[i0] * (1.0 - w) + p[i1] * w
    if gaps is not None:
        out[(gaps[i0] * (1.0 - w) + gaps[i1] * w) > 0] = np.nan
    return out


# --------------------------------------------------------------------------------------------
# skeletons
# --------------------------------------------------------------------------------------------


def _unit(v: np.ndarray) -> np.ndarray:
    n = float(np.linalg.norm(v))
    return v / n if n > 0 else v


def _rest_vec(rest: np.ndarray, a: int, b: int) -> np.ndarray:
    return rest[b] - rest[a]


def _log_map(q: np.ndarray) -> np.ndarray:
    q = np.where(q[..., :1] < 0, -q, q)
    v = q[..., 1:]
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    ang = 2.0 * np.arctan2(s, q[..., :1])
    return np.where(s > 1e-12, v / np.where(s > 1e-12, s, 1.0) * ang, 0.0)


def _finger_bases(arm, hand: int, skeleton) -> list[int]:
    out = []
    for f in ("index", "middle", "ring", "pinky"):
        js = arm.fingers.get(f, [])
        if js and hand in skeleton.chain_to_root(js[0]):
            out.append(js[0])
    return out


def hand_frame(motion: Motion, roles, side: str) -> HandFrame:
    """The rest-pose anatomical frame of ``side``'s hand (see the module docstring).

    ``roles`` is an :class:`engine.model.roles.Roles` of ``motion.skeleton``. Raises
    ``RoleError`` when the side has no wrist, or when neither a forearm nor finger
    joints give the hand's direction.
    """
    sk = motion.skeleton
    arm = roles.side(side)
    wrist = roles.require(side, "wrist")
    hand_joint = arm.hand if arm.hand is not None else wrist
    rest = rest_positions(sk)
    chain = sk.chain_to_root(wrist)
    scale = max(
        float(np.linalg.norm(sk.offsets[1:], axis=1).max()) if sk.n_joints > 1 else 1.0, 1e-12
    )

    elbow = arm.elbow if (arm.elbow is not None and arm.elbow in chain) else None
    forearm_vec = _rest_vec(rest, elbow, wrist) if elbow is not None else None
    elbow_apart = forearm_vec is not None and np.linalg.norm(forearm_vec) > 1e-3 * scale
    bases = _finger_bases(arm, wrist, sk)
    palm_vec = np.mean([_rest_vec(rest, wrist, j) for j in bases], axis=0) if bases else None
    palm_length = float(np.linalg.norm(palm_vec)) if palm_vec is not None else None

    # without a forearm the hand points along its middle metacarpal (the hand's axis, in
    # line with the forearm), else along the mean of the finger bases
    middle = arm.fingers.get("middle", [])
    axis_vec = _rest_vec(rest, wrist, middle[0]) if middle and middle[0] in bases else palm_vec
    if elbow_apart:
        along = _unit(forearm_vec)
    elif axis_vec is not None and np.linalg.norm(axis_vec) > 1e-6 * scale:
        along = _unit(axis_vec)
    elif arm.hand_end is not None:
        along = _unit(_rest_vec(rest, wrist, arm.hand_end))
    elif sk.end_sites.get(hand_joint) is not None and np.linalg.norm(sk.end_sites[hand_joint]) > 0:
        along = _unit(np.asarray(sk.end_sites[hand_joint], dtype=float))
    else:
        raise RoleError(
            f"{side} hand of {_name(motion)}: no forearm and no finger joints to "
            f"tell which way the hand points"
        )

    hand_length = _hand_length(sk, arm, wrist, rest)
    if elbow_apart:
        length = float(np.linalg.norm(forearm_vec))
    elif hand_length:
        length = hand_length / HAND_TO_FOREARM
    elif palm_length:
        length = palm_length / PALM_TO_FOREARM
    else:
        length = DEFAULT_FOREARM_M / motion.meters_per_unit

    dorsal_est, source = _dorsal_estimate(motion, arm, side, wrist, elbow, along, rest, chain)
    dorsal = _snap_dorsal(dorsal_est, along)
    radial = np.cross(dorsal, along) if side == "right" else np.cross(along, dorsal)
    shoulder = arm.shoulder if (arm.shoulder is not None and arm.shoulder in chain) else None
    forearm_joint = elbow if elbow is not None else wrist
    return HandFrame(
        side=side,
        wrist=wrist,
        forearm_joint=forearm_joint,
        hand_joint=hand_joint,
        shoulder=shoulder,
        elbow_apart=bool(elbow_apart),
        along=along,
        dorsal=dorsal,
        radial=_unit(radial),
        forearm_length=length,
        palm_length=palm_length,
        hand_length=hand_length,
        dorsal_source=source,
    )


def _hand_length(sk, arm, wrist: int, rest: np.ndarray) -> float | None:
    """Wrist -> finger tip along the middle finger (else the longest finger), file units."""
    best = None
    for finger in ("middle", "index", "ring", "pinky"):
        js = arm.fingers.get(finger, [])
        if not js or wrist not in sk.chain_to_root(js[0]):
            continue
        last = js[-1]
        while True:  # follow single children below the last numbered joint (tips)
            kids = sk.children(last)
            if len(kids) != 1:
                break
            last = kids[0]
        length = float(np.linalg.norm(rest[js[0]] - rest[wrist]))
        chain = sk.chain_to_root(last)
        for j in chain[: chain.index(js[0])]:
            length += float(np.linalg.norm(sk.offsets[j]))
        if last in sk.end_sites:
            length += float(np.linalg.norm(sk.end_sites[last]))
        if finger == "middle":
            return length
        best = max(best or 0.0, length)
    return best


def _name(motion: Motion) -> str:
    return Path(motion.meta.source).name if motion.meta.source else "the take"


def _dorsal_estimate(motion, arm, side, wrist, elbow, along, rest, chain):
    sk = motion.skeleton
    sign = 1.0 if side == "right" else -1.0
    index = arm.fingers.get("index", [])
    outer = arm.fingers.get("pinky", []) or arm.fingers.get("ring", [])
    if (
        index
        and outer
        and wrist in sk.chain_to_root(index[0])
        and wrist in sk.chain_to_root(outer[0])
    ):
        radial = _rest_vec(rest, outer[0], index[0])
        n = np.cross(along, radial) if side == "right" else np.cross(radial, along)
        if np.linalg.norm(n) > 1e-9:
            return _unit(n), "fingers"
    if elbow is not None and sk.parents[elbow] >= 0 and motion.n_frames > 0:
        w = _log_map(motion.rotations[:, elbow]).mean(axis=0)
        w = w - along * np.dot(w, along)
        if np.linalg.norm(w) > np.radians(2.0):
            return sign * _unit(w), "elbow flexion"
    thumb = arm.fingers.get("thumb", [])
    if thumb and wrist in sk.chain_to_root(thumb[0]):
        r = _rest_vec(rest, wrist, thumb[0])
        r = r - along * np.dot(r, along)
        if np.linalg.norm(r) > 1e-9:
            n = np.cross(along, r) if side == "right" else np.cross(r, along)
            return _unit(n), "thumb"
    return up_vector(motion.meta.up_axis), "up axis"


def _snap_dorsal(estimate: np.ndarray, along: np.ndarray) -> np.ndarray:
    """Nearest rest axis to ``estimate`` among those not along the forearm, made ⊥ ``along``."""
    cands = [a for a in _AXES if abs(np.dot(a, along)) < 0.75]
    best = max(cands, key=lambda a: float(np.dot(a, estimate)))
    n = best - along * np.dot(best, along)
    return _unit(n)


def marker_offsets(frame: HandFrame) -> tuple[np.ndarray, np.ndarray]:
    """Rest-world offsets (file units) of ``p1..p4`` from the wrist and, per marker,
    0 if it rides the forearm joint or 1 if it rides the hand joint."""
    length = frame.forearm_length
    offs = np.stack(
        [
            WRIST_HALF_WIDTH * length * frame.radial,
            -WRIST_HALF_WIDTH * length * frame.radial,
            -FOREARM_POINT * length * frame.along,
            length * (HAND_POINT * frame.along + HAND_DORSAL * frame.dorsal),
        ]
    )
    return offs, np.array([0, 0, 0, 1])


def skeleton_markers(positions: np.ndarray, rotations: np.ndarray, frame: HandFrame) -> np.ndarray:
    """Virtual markers ``(F, 4, 3)`` (file units and axes) from FK results.

    positions, rotations : (F, J, 3), (F, J, 4) world joint positions and rotations
    (:func:`engine.model.kinematics.forward_kinematics`). At rest every world rotation is
    the identity, so a rest-world offset turns with the joint's world rotation.
    """
    offs, rides = marker_offsets(frame)
    wrist = positions[:, frame.wrist]
    out = np.empty(positions.shape[:1] + (4, 3))
    for k in range(4):
        joint = frame.hand_joint if rides[k] else frame.forearm_joint
        out[:, k] = wrist + rotate_offset(rotations[:, joint], offs[k])
    return out


def motion_markers(
    motion: Motion,
    side: str,
    roles=None,
    fps: float | None = None,
    frame: HandFrame | None = None,
    fk=None,
) -> ArmMarkers:
    """Alignment markers of one arm of a skeletal take, metres, y up.

    Parameters
    ----------
    motion : Motion
    side : ``"right"`` or ``"left"``
    roles : engine.model.roles.Roles, optional (found from joint names if omitted)
    fps : float, optional
        Resample the markers to this rate (:func:`resample_points`: low-passed first
        when the rate drops). Single-frame spikes are removed first (:func:`despike`).
    frame : HandFrame, optional (computed if omitted)
    fk : (positions, rotations), optional
        Precomputed forward kinematics of the whole take.
    """
    if roles is None:
        from engine.model.roles import find_roles

        roles = find_roles(motion.skeleton)
    if frame is None:
        frame = hand_frame(motion, roles, side)
    pos, wrot = fk if fk is not None else forward_kinematics(motion)
    mk = despike(_arm_markers(motion, frame, pos, wrot))
    subtracted = frame.shoulder is not None
    if fps is not None:
        mk = resample_points(mk, motion.fps, fps)
    return ArmMarkers(
        markers=mk, fps=float(fps or motion.fps), side=side, shoulder_subtracted=subtracted
    )


def _arm_markers(motion: Motion, frame: HandFrame, pos: np.ndarray, wrot: np.ndarray) -> np.ndarray:
    """``(F, 4, 3)`` markers in metres, y up, shoulder subtracted, from FK results."""
    mk = skeleton_markers(pos, wrot, frame)
    if frame.shoulder is not None:
        mk = mk - pos[:, frame.shoulder][:, None, :]
    return to_y_up(mk * motion.meters_per_unit, motion.meta.up_axis)


#: frames per block of forward kinematics in :func:`take_markers`
FK_CHUNK = 4096


def take_markers(
    motion: Motion,
    roles,
    frames: dict[str, HandFrame],
    fps: float | None = None,
    keep_rotations: bool = False,
    chunk: int = FK_CHUNK,
):
    """Markers of several arms and the trunk yaw of a skeletal take, by blocks of frames.

    The same values as :func:`motion_markers` and :func:`skeleton_yaw`, but forward
    kinematics runs ``chunk`` frames at a time, so memory holds the outputs plus one
    block of joint positions and rotations, not ``(F, J, 7)`` doubles for the whole take.

    Returns ``(markers, yaw, rotations)``: ``{side: (F', 4, 3)}`` metres, y up (``F'``
    frames at ``fps``, else the take's own); ``(F,)`` radians or None; world rotations
    ``(F, J, 4)`` of every joint when ``keep_rotations`` (else None).
    """
    f = motion.n_frames
    out = {s: np.empty((f, 4, 3)) for s in frames}
    pair = _yaw_joints(roles)
    lat = np.empty((f, 3)) if pair is not None else None
    rots = np.empty((f, motion.skeleton.n_joints, 4)) if keep_rotations else None
    for f0 in range(0, f, chunk):
        f1 = min(f, f0 + chunk)
        pos, wrot = forward_kinematics(motion.frames(f0, f1))
        for s, frame in frames.items():
            out[s][f0:f1] = _arm_markers(motion, frame, pos, wrot)
        if pair is not None:
            lat[f0:f1] = to_y_up(pos[:, pair[0]] - pos[:, pair[1]], motion.meta.up_axis)
        if rots is not None:
            rots[f0:f1] = wrot
    yaw = np.unwrap(np.arctan2(lat[:, 0], lat[:, 2])) if lat is not None else None
    out = {s: despike(mk) for s, mk in out.items()}  # as motion_markers
    if fps is not None:
        out = {s: resample_points(mk, motion.fps, fps) for s, mk in out.items()}
    return out, yaw, rots


def _yaw_joints(roles) -> tuple[int, int] | None:
    """(right, left) joints whose difference gives the trunk's lateral axis, or None."""
    for role in ("shoulder", "clavicle"):
        r, left = roles.get("right", role), roles.get("left", role)
        if r is not None and left is not None:
            return r, left
    return None


def skeleton_yaw(motion: Motion, roles, fk=None) -> np.ndarray | None:
    """Trunk heading about the vertical axis per frame (radians), or None.

    From the vector between the two shoulder joints (else the two clavicles):
    ``yaw = atan2(l_x, l_z)`` of the left-to-right vector in y-up axes, so that
    ``θ = yaw_body - yaw_hand`` turns the hand take onto the body (eq. 7 sign).
    """
    pair = _yaw_joints(roles)
    if pair is None:
        return None
    pos, _ = fk if fk is not None else forward_kinematics(motion)
    lat = to_y_up(pos[:, pair[0]] - pos[:, pair[1]], motion.meta.up_axis)
    return np.unwrap(np.arctan2(lat[:, 0], lat[:, 2]))


# --------------------------------------------------------------------------------------------
# marker sets
# --------------------------------------------------------------------------------------------


def marker_set_markers(markers: MarkerSet, side: str, fps: float | None = None) -> ArmMarkers:
    """Alignment markers of one arm of a marker take (C3D/TRC), metres, y up.

    Markers are found by :func:`engine.model.roles.find_marker_roles` (Plug-in Gait
    ``RWRA``/``RWRB``/``RFRA``/``RFIN``/``RSHO``; pyomeca ``STYLr``, ``STYLu``,
    ``LARM*``, ``LATH``, ``ACRO_tip``). A set whose labels carry no side (pyomeca's
    single arm) serves the side asked for. Without a forearm marker the midpoint of
    the elbow marker and the wrist is used. Gaps stay NaN here (the metrics fill
    them). ``RoleError`` names what is missing.
    """
    from engine.model.roles import find_marker_roles

    roles = find_marker_roles(markers.labels, side_hint=side)
    arm = roles.side(side)
    pts = markers.points
    missing = [r for r in ("wrist_radial", "wrist_ulnar", "hand") if arm.get(r) is None]
    if arm.get("forearm") is None and arm.get("elbow") is None:
        missing.append("forearm (or elbow)")
    if missing:
        raise RoleError(
            f"{side} arm of {Path(markers.meta.source).name or 'the marker set'}: "
            f"no marker for {', '.join(missing)} among {len(markers.labels)} labels"
        )
    radial = pts[:, arm["wrist_radial"]]
    ulnar = pts[:, arm["wrist_ulnar"]]
    if arm.get("forearm") is not None:
        forearm = pts[:, arm["forearm"]]
    else:
        forearm = 0.5 * (pts[:, arm["elbow"]] + 0.5 * (radial + ulnar))
    out = np.stack([radial, ulnar, forearm, pts[:, arm["hand"]]], axis=1)
    subtracted = arm.get("shoulder") is not None
    if subtracted:
        out = out - pts[:, arm["shoulder"]][:, None, :]
    out = despike(to_y_up(out * markers.meters_per_unit, markers.meta.up_axis))
    if fps is not None:
        out = resample_points(out, markers.fps, fps)
    return ArmMarkers(
        markers=out, fps=float(fps or markers.fps), side=side, shoulder_subtracted=subtracted
    )


def marker_set_yaw(markers: MarkerSet) -> np.ndarray | None:
    """Trunk heading from right/left pelvis or shoulder markers (``ASISr``/``ASISl``,
    ``RSHO``/``LSHO``, ``RASI``/``LASI``), or None."""
    labels = {lab.split(":")[-1].strip().lower(): k for k, lab in enumerate(markers.labels)}
    for r, left in (("RSHO", "LSHO"), ("ASISr", "ASISl"), ("RASI", "LASI")):
        if r.lower() in labels and left.lower() in labels:
            lat = markers.points[:, labels[r.lower()]] - markers.points[:, labels[left.lower()]]
            lat = to_y_up(lat, markers.meta.up_axis)
            good = np.isfinite(lat).all(axis=1)
            if good.sum() < 2:
                continue
            t = np.arange(len(lat))
            yaw = np.arctan2(lat[:, 0], lat[:, 2])
            return np.interp(t, t[good], np.unwrap(yaw[good]))
    return None


def take_sides(take: Motion | MarkerSet, roles=None) -> list[str]:
    """Sides (``"right"``, ``"left"``) for which ``take`` yields alignment markers."""
    if isinstance(take, MarkerSet):
        out = []
        for side in ("right", "left"):
            try:
                marker_set_markers(take, side)
            except RoleError:
                continue
            out.append(side)
        return out
    return list(roles.sides_found())
