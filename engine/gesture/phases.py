"""Gesture phases from the wrist's motion relative to the body (docs/method.md §8).

Each hand's wrist path, expressed in a body frame (origin at the same-side
shoulder or at the pelvis, pelvis yaw removed, metres), is cut into the phases
of Kita et al. (1998) as Table 1 of Majkowska et al. (2006) describes them:

=================  ===========================================================
``REST``           hand still near its rest position (between phrases)
``PREPARATION``    a movement that leaves the rest position (moves outward)
``STROKE``         a movement with high acceleration, the effortful part
``HOLD``           hand still (speed below ``hold_speed``) away from rest
``RETRACTION``     a movement that returns toward the rest position
=================  ===========================================================

How the labels are made (every threshold is a field of ``PhaseParameters``):

1. The path is smoothed and differentiated with a Savitzky-Golay filter
   (``smoothing_s``); speed ``|v|`` and acceleration magnitude ``|a|`` per frame.
2. Still frames: speed below ``hold_speed``. Still runs shorter than
   ``min_hold_s`` count as movement, movement runs shorter than ``min_move_s``
   as still. A still run within ``rest_radius`` of the rest position is REST,
   any other still run is HOLD.
3. The rest position is given, or estimated as the lowest wrist position
   (the arm hanging), refined to the median of the frames near it. Movement
   units that never leave the rest zone (``rest_radius``) are REST too.
4. Every movement run is cut into movement units at deep speed minima (a
   valley at most ``1 - valley_depth`` of the lower neighbouring peak).
5. Between two REST runs (an excursion): the first unit is PREPARATION if it
   starts at rest and moves outward, the last is RETRACTION if it ends at rest
   and moves inward; every other unit is a STROKE when its peak ``|a|`` reaches
   ``max(stroke_accel, stroke_accel_ratio * excursion peak)``, otherwise a
   preparation (moving outward) or a partial retraction (moving inward), as
   Table 1 has it.
6. Phrases follow the grammar ``P? (S|H)+ R?``: a REST, or a P after the
   expressive part, or an S/H after an R starts a new phrase. A phrase without a
   stroke or hold gets its most accelerated unit promoted to STROKE (Kita: every
   phrase has an expressive phase).

The expressive phase of a phrase is its strokes, or its holds when it has no
stroke (an independent hold), as Heloir et al. (2010) define it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntEnum

import numpy as np

from engine.base.errors import ParameterError


class Phase(IntEnum):
    """Per-frame gesture phase codes (shared with the renderer and the web app)."""

    REST = 0
    PREPARATION = 1
    STROKE = 2
    HOLD = 3
    RETRACTION = 4

    @property
    def letter(self) -> str:
        """One-letter code as in the literature: ``-``, P, S, H, R."""
        return "-PSHR"[int(self)]


#: Display colours (Heloir et al. Fig. 2: preparation yellow, stroke red,
#: retraction magenta; hold is our choice, rest grey).
PHASE_COLORS = {
    Phase.REST: "#9e9e9e",
    Phase.PREPARATION: "#f2c200",
    Phase.STROKE: "#e31a1c",
    Phase.HOLD: "#1f78b4",
    Phase.RETRACTION: "#d81bd8",
}


@dataclass(frozen=True)
class PhaseParameters:
    """User-tunable thresholds of the phase segmentation (SI units).

    Attributes
    ----------
    smoothing_s : float
        Savitzky-Golay window in seconds (at least 5 frames are used).
    hold_speed : float
        m/s; the wrist is still (hold or rest) below this speed.
    min_hold_s : float
        s; shorter still runs are treated as movement.
    min_move_s : float
        s; shorter movement runs are treated as still.
    rest_radius : float
        m; a still hand within this distance of the rest position is at REST.
    valley_depth : float
        in (0, 1); a speed minimum splits a movement into two units when it is at
        most ``(1 - valley_depth)`` times the lower of its two neighbouring peaks.
    stroke_accel : float
        m/s^2; absolute floor of the peak ``|a|`` of a stroke.
    stroke_accel_ratio : float
        in [0, 1]; a stroke's peak ``|a|`` is at least this fraction of the
        excursion's highest peak.
    radial_min : float
        m; a unit moves outward (inward) when its distance from rest grows
        (shrinks) by more than this.
    reference : ``"shoulder"`` or ``"pelvis"``
        Origin of the body frame the wrist is measured in.
    """

    smoothing_s: float = 0.2
    hold_speed: float = 0.12
    min_hold_s: float = 0.1
    min_move_s: float = 0.1
    rest_radius: float = 0.15
    valley_depth: float = 0.3
    stroke_accel: float = 1.0
    stroke_accel_ratio: float = 0.3
    radial_min: float = 0.02
    reference: str = "shoulder"

    def __post_init__(self) -> None:
        positive = ("smoothing_s", "hold_speed", "rest_radius", "valley_depth")
        for name in positive:
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ParameterError(
                    f"{name}: expected a positive number (phase parameter), got {v!r}"
                )
        for name in (
            "min_hold_s",
            "min_move_s",
            "stroke_accel",
            "stroke_accel_ratio",
            "radial_min",
        ):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ParameterError(f"{name}: expected a number >= 0 (phase parameter), got {v!r}")
        if self.valley_depth >= 1:
            raise ParameterError(
                f"valley_depth: expected < 1 (phase parameter), got {self.valley_depth!r}"
            )
        if self.stroke_accel_ratio > 1:
            raise ParameterError(
                f"stroke_accel_ratio: expected <= 1 (phase parameter), got {self.stroke_accel_ratio!r}"
            )
        if self.reference not in ("shoulder", "pelvis"):
            raise ParameterError(
                f"reference: expected 'shoulder' or 'pelvis' (phase parameter), got {self.reference!r}"
            )


@dataclass(frozen=True)
class PhaseSegment:
    """Frames ``[start, stop)`` of one phase."""

    phase: Phase
    start: int
    stop: int

    @property
    def n_frames(self) -> int:
        return self.stop - self.start


@dataclass(frozen=True)
class Phrase:
    """A gesture phrase ``P? (S|H)+ R?``: its segments, in time order."""

    segments: tuple[PhaseSegment, ...]

    @property
    def start(self) -> int:
        return self.segments[0].start

    @property
    def stop(self) -> int:
        return self.segments[-1].stop

    @property
    def pattern(self) -> str:
        """The phrase's phases as letters, e.g. ``"PSHR"``."""
        return "".join(s.phase.letter for s in self.segments)

    def expressive_segments(self) -> tuple[PhaseSegment, ...]:
        """Strokes, or the holds of a phrase without a stroke (independent hold)."""
        strokes = tuple(s for s in self.segments if s.phase == Phase.STROKE)
        return strokes or tuple(s for s in self.segments if s.phase == Phase.HOLD)


@dataclass(frozen=True)
class HandPhases:
    """Phase segmentation of one hand.

    Attributes
    ----------
    labels : (F,) uint8 array of ``Phase`` codes
    segments : tuple of PhaseSegment, covering every frame in order
    phrases : tuple of Phrase
    positions : (F, 3) float, metres, smoothed wrist path in the body frame
    speed : (F,) float, m/s
    acceleration : (F,) float, m/s^2 (magnitude)
    rest_position : (3,) float, metres, body frame
    fps : float
    """

    labels: np.ndarray
    segments: tuple[PhaseSegment, ...]
    phrases: tuple[Phrase, ...]
    positions: np.ndarray
    speed: np.ndarray
    acceleration: np.ndarray
    rest_position: np.ndarray
    fps: float

    def expressive_mask(self) -> np.ndarray:
        """(F,) bool: frames in an expressive phase of some phrase."""
        mask = np.zeros(len(self.labels), dtype=bool)
        for phrase in self.phrases:
            for seg in phrase.expressive_segments():
                mask[seg.start : seg.stop] = True
        return mask


@dataclass(frozen=True)
class GesturePhases:
    """Both hands' phases for a take. ``hands`` maps ``"right"``/``"left"`` to HandPhases.

    ``paths`` (``engine.gesture.body.ArmPaths``) holds the arm points in the body
    frame when the phases come from a ``Motion``.
    """

    hands: dict[str, HandPhases]
    fps: float
    n_frames: int
    params: PhaseParameters = field(default_factory=PhaseParameters)
    paths: object = None

    def labels(self, side: str) -> np.ndarray:
        return self.hands[side].labels


# ---------------------------------------------------------------------------
# Signal helpers


def fill_gaps(points: np.ndarray) -> np.ndarray:
    """Linearly interpolate NaN frames of ``points (F, D)``; edges hold the nearest value.

    A column with no finite value raises ``ParameterError``.
    """
    pts = np.array(points, dtype=float, copy=True)
    frames = np.arange(len(pts))
    for d in range(pts.shape[1]):
        ok = np.isfinite(pts[:, d])
        if ok.all():
            continue
        if not ok.any():
            raise ParameterError("trajectory has no finite sample")
        pts[~ok, d] = np.interp(frames[~ok], frames[ok], pts[ok, d])
    return pts


def derivatives(
    positions: np.ndarray, fps: float, smoothing_s: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Smoothed positions, velocity and acceleration of ``positions (F, D)``.

    Savitzky-Golay (cubic) over a window of ``smoothing_s`` seconds (odd, >= 5
    frames, shrunk for short takes). Returns three ``(F, D)`` arrays in units,
    units/s and units/s^2.
    """
    from scipy.signal import savgol_filter

    pos = np.asarray(positions, dtype=float)
    n = len(pos)
    if n < 2:
        z = np.zeros_like(pos)
        return pos.copy(), z, z.copy()
    window = max(5, int(round(smoothing_s * fps)) | 1)
    window = min(window, n if n % 2 else n - 1)
    if window < 3:
        vel = np.gradient(pos, axis=0) * fps
        return pos.copy(), vel, np.gradient(vel, axis=0) * fps
    order = min(3, window - 1)
    dt = 1.0 / fps
    smooth = savgol_filter(pos, window, order, axis=0, mode="interp")
    vel = savgol_filter(pos, window, order, deriv=1, delta=dt, axis=0, mode="interp")
    acc = savgol_filter(pos, window, order, deriv=2, delta=dt, axis=0, mode="interp")
    return smooth, vel, acc


def _runs(mask: np.ndarray) -> list[tuple[bool, int, int]]:
    """Runs of equal values of a bool array: ``(value, start, stop)``."""
    if len(mask) == 0:
        return []
    change = np.flatnonzero(np.diff(mask.astype(np.int8))) + 1
    bounds = np.concatenate([[0], change, [len(mask)]])
    return [(bool(mask[a]), int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:])]


def _drop_short(mask: np.ndarray, value: bool, min_len: int) -> np.ndarray:
    """Flip runs equal to ``value`` shorter than ``min_len`` frames (not at the ends
    when they touch the take's border and the take is longer than the run)."""
    out = mask.copy()
    if min_len <= 1:
        return out
    for v, a, b in _runs(mask):
        if v == value and b - a < min_len and not (a == 0 and b == len(mask)):
            out[a:b] = not value
    return out


def _estimate_rest(positions: np.ndarray, up: int, radius: float) -> np.ndarray:
    """Rest position: median of the frames near the lowest wrist position.

    Captures often start and end with the hand already moving away from or toward a
    hanging arm, so stillness is not required; the lowest point is taken as rest.
    """
    lowest = positions[np.argmin(positions[:, up])]
    near = positions[np.linalg.norm(positions - lowest, axis=1) <= 0.5 * radius]
    return np.median(near, axis=0)


def _split_units(speed: np.ndarray, start: int, stop: int, depth: float) -> list[tuple[int, int]]:
    """Cut the movement run ``[start, stop)`` at deep speed minima."""
    from scipy.signal import find_peaks

    s = speed[start:stop]
    if len(s) < 3:
        return [(start, stop)]
    valleys, props = find_peaks(-s, prominence=0.0)
    cuts = []
    for v, prom in zip(valleys, props["prominences"]):
        lower_peak = s[v] + prom
        if lower_peak > 0 and s[v] <= (1.0 - depth) * lower_peak:
            cuts.append(int(v) + start)
    bounds = [start] + cuts + [stop]
    return [(a, b) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]


# ---------------------------------------------------------------------------
# Segmentation of one trajectory


def segment_trajectory(
    positions: np.ndarray,
    fps: float,
    params: PhaseParameters | None = None,
    rest_position: np.ndarray | None = None,
    up_axis: int = 1,
) -> HandPhases:
    """Phase labels and phrases of one wrist path.

    Parameters
    ----------
    positions : (F, 3) float, metres
        Wrist positions in a body frame (see module docstring); NaN gaps are
        interpolated.
    fps : float
        Frames per second.
    params : PhaseParameters
    rest_position : (3,) float, metres, optional
        Where the hand rests; estimated when omitted.
    up_axis : int
        Index of the vertical coordinate in ``positions`` (default 1, y up).

    Returns
    -------
    HandPhases
    """
    params = params or PhaseParameters()
    pos = np.asarray(positions, dtype=float)
    if pos.ndim != 2 or pos.shape[1] != 3 or len(pos) == 0:
        raise ParameterError(f"positions: expected (frames, 3) with frames >= 1, got {pos.shape}")
    if not (np.isfinite(fps) and fps > 0):
        raise ParameterError(f"fps: expected a positive number, got {fps!r}")
    n = len(pos)
    smooth, vel, acc = derivatives(fill_gaps(pos), fps, params.smoothing_s)
    speed = np.linalg.norm(vel, axis=1)
    accel = np.linalg.norm(acc, axis=1)

    still = speed < params.hold_speed
    still = _drop_short(still, False, int(round(params.min_move_s * fps)))
    still = _drop_short(still, True, int(round(params.min_hold_s * fps)))

    if rest_position is None:
        rest = _estimate_rest(smooth, up_axis, params.rest_radius)
    else:
        rest = np.asarray(rest_position, dtype=float).reshape(3)
    radial = np.linalg.norm(smooth - rest, axis=1)

    # still runs -> REST / HOLD; movement runs -> units
    items: list[tuple[str, int, int]] = []  # kind in {"rest", "hold", "move"}
    for v, a, b in _runs(still):
        if v:
            at_rest = np.median(radial[a:b]) <= params.rest_radius
            items.append(("rest" if at_rest else "hold", a, b))
        else:
            for ua, ub in _split_units(speed, a, b, params.valley_depth):
                # fidgeting that never leaves the rest zone is rest, not a gesture
                at_rest = radial[ua:ub].max() <= params.rest_radius
                items.append(("rest" if at_rest else "move", ua, ub))
    items = _merge_items(items)

    labels = np.zeros(n, dtype=np.uint8)
    # excursions: maximal spans of non-rest items
    i = 0
    while i < len(items):
        if items[i][0] == "rest":
            i += 1
            continue
        j = i
        while j < len(items) and items[j][0] != "rest":
            j += 1
        # the take's first (last) frame counts as rest when the hand is in the rest zone
        _label_excursion(
            items[i:j],
            labels,
            radial,
            accel,
            params,
            from_rest=i > 0 or radial[0] <= params.rest_radius,
            to_rest=j < len(items) or radial[-1] <= params.rest_radius,
        )
        i = j

    segments = _segments(labels)
    phrases = _parse_phrases(segments, labels, accel)
    segments = _segments(labels)  # promotion may have relabelled units
    return HandPhases(
        labels=labels,
        segments=segments,
        phrases=phrases,
        positions=smooth,
        speed=speed,
        acceleration=accel,
        rest_position=rest,
        fps=float(fps),
    )


def _merge_items(items: list[tuple[str, int, int]]) -> list[tuple[str, int, int]]:
    """Join neighbouring rest items (movement units are kept apart)."""
    out: list[tuple[str, int, int]] = []
    for kind, a, b in items:
        if out and kind == out[-1][0] and kind in ("rest", "hold"):
            out[-1] = (kind, out[-1][1], b)
        else:
            out.append((kind, a, b))
    return out


def _label_excursion(items, labels, radial, accel, params, from_rest: bool, to_rest: bool) -> None:
    moves = [(a, b) for kind, a, b in items if kind == "move"]
    peak = max((float(accel[a:b].max()) for a, b in moves), default=0.0)
    stroke_floor = max(params.stroke_accel, params.stroke_accel_ratio * peak)
    first_move = next((k for k, it in enumerate(items) if it[0] == "move"), None)
    last_move = max((k for k, it in enumerate(items) if it[0] == "move"), default=None)
    for k, (kind, a, b) in enumerate(items):
        if kind == "hold":
            labels[a:b] = Phase.HOLD
            continue
        dr = radial[b - 1] - radial[a]
        if k == first_move and k == 0 and from_rest and dr > params.radial_min:
            labels[a:b] = Phase.PREPARATION
        elif k == last_move and k == len(items) - 1 and to_rest and dr < -params.radial_min:
            labels[a:b] = Phase.RETRACTION
        elif accel[a:b].max() >= stroke_floor:
            labels[a:b] = Phase.STROKE
        elif dr < -params.radial_min:
            labels[a:b] = Phase.RETRACTION
        elif dr > params.radial_min:
            labels[a:b] = Phase.PREPARATION
        else:
            labels[a:b] = Phase.STROKE


def _segments(labels: np.ndarray) -> tuple[PhaseSegment, ...]:
    if len(labels) == 0:
        return ()
    change = np.flatnonzero(np.diff(labels.astype(np.int16))) + 1
    bounds = np.concatenate([[0], change, [len(labels)]])
    return tuple(
        PhaseSegment(Phase(int(labels[a])), int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:])
    )


def _parse_phrases(segments, labels: np.ndarray, accel: np.ndarray) -> tuple[Phrase, ...]:
    """Group segments into phrases ``P? (S|H)+ R?`` and promote strokeless phrases."""
    phrases: list[list[PhaseSegment]] = []
    current: list[PhaseSegment] = []
    state = "empty"  # empty | prep | core | retr

    def close():
        nonlocal current, state
        if current:
            phrases.append(current)
        current, state = [], "empty"

    for seg in segments:
        ph = seg.phase
        if ph == Phase.REST:
            close()
        elif ph == Phase.PREPARATION:
            if state in ("core", "retr"):
                close()
            current.append(seg)
            state = "prep"
        elif ph in (Phase.STROKE, Phase.HOLD):
            if state == "retr":
                close()
            current.append(seg)
            state = "core"
        else:  # RETRACTION
            current.append(seg)
            state = "retr"
    close()

    out = []
    for segs in phrases:
        if not any(s.phase in (Phase.STROKE, Phase.HOLD) for s in segs):
            moving = [s for s in segs if s.phase in (Phase.PREPARATION, Phase.RETRACTION)]
            best = max(moving, key=lambda s: float(accel[s.start : s.stop].max()))
            labels[best.start : best.stop] = Phase.STROKE
            segs = [PhaseSegment(Phase.STROKE, s.start, s.stop) if s is best else s for s in segs]
        out.append(Phrase(tuple(_merge_same(segs))))
    return tuple(out)


def _merge_same(segs: list[PhaseSegment]) -> list[PhaseSegment]:
    out: list[PhaseSegment] = []
    for s in segs:
        if out and out[-1].phase == s.phase and out[-1].stop == s.start:
            out[-1] = PhaseSegment(s.phase, out[-1].start, s.stop)
        else:
            out.append(s)
    return out


# ---------------------------------------------------------------------------
# A whole take


def segment_phases(
    motion, params: PhaseParameters | None = None, arms=None, rest_positions: dict | None = None
) -> GesturePhases:
    """Phases of both hands of a full-body take.

    Parameters
    ----------
    motion : engine.model.motion.Motion
        Any units and up axis; positions are converted to metres in the body frame
        (``engine.gesture.body``).
    params : PhaseParameters
    arms : engine.gesture.body.BodyArms, found from joint roles when omitted
    rest_positions : dict side -> (3,) metres in the body frame relative to
        ``params.reference``; estimated per hand when omitted

    Returns
    -------
    GesturePhases with ``hands["right"]`` and ``hands["left"]``
    """
    from engine.gesture.body import SIDES, arm_paths

    params = params or PhaseParameters()
    paths = arm_paths(motion, arms)
    hands = {}
    for side in SIDES:
        rest = (rest_positions or {}).get(side)
        hands[side] = segment_trajectory(
            paths.wrist(side, params.reference), motion.fps, params, rest_position=rest
        )
    return GesturePhases(
        hands=hands, fps=float(motion.fps), n_frames=motion.n_frames, params=params, paths=paths
    )


def marker_phase_labels(markers: np.ndarray, fps: float) -> np.ndarray:
    """Gesture phase codes (:class:`Phase`) per frame of the wrist of a virtual-marker set.

    markers : (frames, 4A, 3) float, metres (``engine.align.features`` markers: the first two of
        each arm straddle the wrist); the first arm's wrist centre is segmented.
    Returns ``(frames,)`` int codes.
    """
    wrist = 0.5 * (markers[:, 0] + markers[:, 1])
    return np.asarray(segment_trajectory(wrist, fps).labels)
