"""Handedness of gesture phrases: RH, LH or 2H (Heloir, Neff & Kipp 2010, §3.1).

Per phrase, ``L_RH`` and ``L_LH`` are the path lengths (metres) of the right and
left wrist during the phrase's expressive phase (strokes, or an independent
hold), and ``d`` its duration (seconds). If ``|L_RH - L_LH| / d`` is below the
threshold (0.12 m/s in the paper) the phrase is ``2H``, else ``RH`` when
``L_RH > L_LH`` and ``LH`` otherwise (docs/method.md §8).

Choices of this implementation (the paper leaves them open):

* Paths are measured in the body frame (shoulder-relative, pelvis yaw removed,
  see ``engine.gesture.body``) and smoothed like the phase segmenter's, so
  walking or turning does not count as hand movement and capture noise does not
  inflate a still hand's path.
* The point measured is the hand tip by default (``point="tip"``), so a wave
  made by turning the wrist counts; ``point="wrist"`` measures the wrist.
* An independent hold has almost no path for either hand, so the paper's rule
  would call every hold-only phrase 2H; for a joint phrase without any stroke
  the whole phrase (preparation, hold, retraction) is measured instead
  (``hold_span="phrase"``; ``"hold"`` keeps the paper's literal rule).
* Phrases are found per hand; phrases of the two hands that overlap by at
  least 30 % of the shorter form one joint phrase, whose expressive phase is the union of both hands' expressive
  frames. A phrase of one hand alone has the other hand's path measured over the
  same frames.
* Units: every length is in metres whatever the file's units (the caller
  converts, ``Motion.meters_per_unit``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.base.errors import ParameterError
from engine.gesture.phases import GesturePhases

LABELS = ("RH", "LH", "2H")
MERGE_OVERLAP = 0.3


@dataclass(frozen=True)
class HandednessParameters:
    """Parameters of the handedness rule.

    threshold : m/s; below it the per-second path difference means ``2H``.
    point : ``"tip"`` (hand tip) or ``"wrist"``, the point whose path is measured.
    hold_span : ``"phrase"`` or ``"hold"``, what is measured for a stroke-less phrase.
    """

    threshold: float = 0.12
    point: str = "tip"
    hold_span: str = "phrase"

    def __post_init__(self) -> None:
        if not (np.isfinite(self.threshold) and self.threshold >= 0):
            raise ParameterError(
                f"threshold: expected a handedness threshold >= 0 (m/s), got {self.threshold!r}"
            )
        if self.point not in ("tip", "wrist"):
            raise ParameterError(
                f"point: expected 'tip' or 'wrist' (handedness), got {self.point!r}"
            )
        if self.hold_span not in ("phrase", "hold"):
            raise ParameterError(
                f"handedness hold_span: expected 'phrase' or 'hold', got {self.hold_span!r}"
            )


@dataclass(frozen=True)
class PhraseHandedness:
    """One phrase's handedness.

    Attributes
    ----------
    start, stop : int
        Frames ``[start, stop)`` of the (joint) phrase.
    label : ``"RH"``, ``"LH"`` or ``"2H"``
    right_length, left_length : float
        Metres travelled by each wrist during the expressive frames.
    duration : float
        Seconds of expressive frames.
    difference : float
        ``|L_RH - L_LH| / d`` in m/s.
    expressive : tuple of (start, stop)
        Frame ranges of the expressive phase.
    """

    start: int
    stop: int
    label: str
    right_length: float
    left_length: float
    duration: float
    difference: float
    expressive: tuple[tuple[int, int], ...]


def path_length(positions: np.ndarray, mask: np.ndarray) -> float:
    """Length of the path ``positions (F, 3)`` over the steps ``i -> i+1`` with ``mask[i]``.

    ``mask (F,) bool``; the last frame has no step. Units are those of ``positions``.
    """
    pos = np.asarray(positions, dtype=float)
    steps = np.linalg.norm(np.diff(pos, axis=0), axis=1)
    m = np.asarray(mask, dtype=bool)[:-1]
    return float(steps[m].sum())


def classify(
    right: np.ndarray, left: np.ndarray, mask: np.ndarray, fps: float, threshold: float = 0.12
) -> tuple[str, float, float, float, float]:
    """Handedness of one phrase from both wrists' paths.

    Parameters
    ----------
    right, left : (F, 3) float, metres
        Wrist paths over (at least) the phrase's frames.
    mask : (F,) bool
        Expressive frames; each contributes one step of ``1/fps`` seconds.
    fps : float
    threshold : float, m/s

    Returns
    -------
    (label, right_length m, left_length m, duration s, difference m/s)
    """
    right = np.asarray(right, dtype=float)
    left = np.asarray(left, dtype=float)
    mask = np.asarray(mask, dtype=bool)
    if right.shape != left.shape or right.ndim != 2 or right.shape[1] != 3:
        raise ParameterError(
            f"handedness: right {right.shape} and left {left.shape} must both be (F, 3)"
        )
    if mask.shape != (len(right),):
        raise ParameterError(f"handedness: mask must be ({len(right)},), got {mask.shape}")
    if not (np.isfinite(fps) and fps > 0):
        raise ParameterError(f"handedness: fps must be positive, got {fps!r}")
    n_steps = int(mask[:-1].sum())
    if n_steps == 0:
        raise ParameterError("handedness: the expressive phase has no frames")
    duration = n_steps / fps
    l_r = path_length(right, mask)
    l_l = path_length(left, mask)
    diff = abs(l_r - l_l) / duration
    if diff < threshold:
        label = "2H"
    else:
        label = "RH" if l_r > l_l else "LH"
    return label, l_r, l_l, duration, diff


def joint_phrases(
    phases: GesturePhases, hold_span: str = "phrase"
) -> list[tuple[int, int, np.ndarray]]:
    """Phrases of both hands merged where they overlap by at least ``MERGE_OVERLAP``
    of the shorter one (a brief overlap only trims the later phrase, so phrases
    of the two hands do not chain into one long span in continuous motion).

    Returns a list of ``(start, stop, expressive_mask)`` with ``expressive_mask``
    of shape ``(stop - start,)``: frames expressive for either hand (strokes and
    independent holds); a phrase with no stroke in either hand is expressive over
    its whole span when ``hold_span == "phrase"``.
    """
    from engine.gesture.phases import Phase

    spans = []
    union = np.zeros(phases.n_frames, dtype=bool)
    strokes = np.zeros(phases.n_frames, dtype=bool)
    for hand in phases.hands.values():
        union |= hand.expressive_mask()
        strokes |= hand.labels == Phase.STROKE
        spans.extend((p.start, p.stop) for p in hand.phrases)
    spans.sort()
    merged: list[list[int]] = []
    for a, b in spans:
        if merged and a < merged[-1][1]:
            prev = merged[-1]
            overlap = min(b, prev[1]) - a
            if overlap >= MERGE_OVERLAP * min(b - a, prev[1] - prev[0]):
                prev[1] = max(prev[1], b)
                continue
            a = prev[1]  # a brief overlap: the later phrase starts where the earlier ends
            if b <= a:
                continue
        merged.append([a, b])
    out = []
    for a, b in merged:
        mask = union[a:b].copy()
        if (hold_span == "phrase" and not strokes[a:b].any()) or mask[:-1].sum() == 0:
            mask[:] = True
        out.append((a, b, mask))
    return out


def hand_paths(phases: GesturePhases, point: str = "tip") -> dict[str, np.ndarray]:
    """(F, 3) smoothed paths, metres, shoulder-relative body frame, of each hand's ``point``.

    Without arm paths (phases built from bare trajectories) the wrist paths of the
    phase segmentation are used.
    """
    from engine.gesture.phases import derivatives

    paths = getattr(phases, "paths", None)
    if paths is None or point == "wrist":
        return {side: hand.positions for side, hand in phases.hands.items()}
    out = {}
    for side in phases.hands:
        p = paths.points[side]
        rel = p[:, 3] - p[:, 0] if phases.params.reference == "shoulder" else p[:, 3]
        out[side] = derivatives(rel, phases.fps, phases.params.smoothing_s)[0]
    return out


def detect_handedness(
    phases: GesturePhases, params: HandednessParameters | None = None
) -> tuple[PhraseHandedness, ...]:
    """Handedness of every joint phrase of a take (see module docstring).

    ``phases`` must hold both ``"right"`` and ``"left"`` hands.
    """
    params = params or HandednessParameters()
    missing = [s for s in ("right", "left") if s not in phases.hands]
    if missing:
        raise ParameterError(f"handedness needs both hands; missing {', '.join(missing)}")
    paths = hand_paths(phases, params.point)
    right, left = paths["right"], paths["left"]
    out = []
    for a, b, mask in joint_phrases(phases, params.hold_span):
        # one frame past the phrase so its last expressive frame has a step
        stop = min(b + 1, phases.n_frames)
        full = np.zeros(stop - a, dtype=bool)
        full[: b - a] = mask
        if full[:-1].sum() == 0:
            continue  # a one-frame phrase at the take's end: nothing to measure
        label, l_r, l_l, d, diff = classify(
            right[a:stop], left[a:stop], full, phases.fps, params.threshold
        )
        out.append(PhraseHandedness(a, b, label, l_r, l_l, d, diff, _ranges(mask, a)))
    return tuple(out)


def _ranges(mask: np.ndarray, offset: int) -> tuple[tuple[int, int], ...]:
    m = np.concatenate([[False], mask, [False]]).astype(np.int8)
    d = np.diff(m)
    starts = np.flatnonzero(d == 1)
    stops = np.flatnonzero(d == -1)
    return tuple((int(a) + offset, int(b) + offset) for a, b in zip(starts, stops))
