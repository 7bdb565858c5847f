"""Handedness of gesture phrases: RH, LH or 2H (Heloir, Neff & Kipp 2010, §3.1).

Per phrase, ``L_RH`` and ``L_LH`` are the path lengths (metres) of the right and
left wrist during the phrase's expressive phase (strokes, or an independent
hold), and ``d`` its duration (seconds). If ``|L_RH - L_LH| / d`` is below the
threshold (0.12 m/s in the paper) the phrase is ``2H``, else ``RH`` when
``L_RH > L_LH`` and ``LH`` otherwise (METHOD.md §8).

Choices of this implementation (the paper leaves them open):

* Paths are measured in the body frame (shoulder-relative, pelvis yaw removed,
  see ``engine.gesture.body``) on the phase segmenter's smoothed positions, so
  walking or turning does not count as hand movement and capture noise does not
  inflate a still hand's path.
* Phrases are found per hand; overlapping phrases of the two hands form one
  joint phrase, whose expressive phase is the union of both hands' expressive
  frames. A phrase of one hand alone has the other hand's path measured over the
  same frames.
* Units: every length is in metres whatever the file's units (the caller
  converts, ``Motion.meters_per_unit``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.errors import ParameterError
from engine.gesture.phases import GesturePhases

LABELS = ("RH", "LH", "2H")


@dataclass(frozen=True)
class HandednessParameters:
    """``threshold``: m/s; below it the per-second path difference means ``2H``."""

    threshold: float = 0.12

    def __post_init__(self) -> None:
        if not (np.isfinite(self.threshold) and self.threshold >= 0):
            raise ParameterError(
                f"handedness threshold: expected a number >= 0 (m/s), got {self.threshold!r}")


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


def classify(right: np.ndarray, left: np.ndarray, mask: np.ndarray, fps: float,
             threshold: float = 0.12) -> tuple[str, float, float, float, float]:
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
        raise ParameterError(f"handedness: right {right.shape} and left {left.shape} must both be (F, 3)")
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


def joint_phrases(phases: GesturePhases) -> list[tuple[int, int, np.ndarray]]:
    """Phrases of both hands merged where they overlap.

    Returns a list of ``(start, stop, expressive_mask)`` with ``expressive_mask``
    of shape ``(stop - start,)``: frames expressive for either hand.
    """
    spans = []
    masks = {}
    for side, hand in phases.hands.items():
        masks[side] = hand.expressive_mask()
        spans.extend((p.start, p.stop) for p in hand.phrases)
    spans.sort()
    merged: list[list[int]] = []
    for a, b in spans:
        if merged and a < merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], b)
        else:
            merged.append([a, b])
    union = np.zeros(phases.n_frames, dtype=bool)
    for m in masks.values():
        union |= m
    out = []
    for a, b in merged:
        mask = union[a:b].copy()
        if mask[:-1].sum() == 0:  # defensive: a phrase always has an expressive phase
            mask[:] = True
        out.append((a, b, mask))
    return out


def detect_handedness(phases: GesturePhases, params: HandednessParameters | None = None
                      ) -> tuple[PhraseHandedness, ...]:
    """Handedness of every joint phrase of a take (see module docstring).

    ``phases`` must hold both ``"right"`` and ``"left"`` hands.
    """
    params = params or HandednessParameters()
    missing = [s for s in ("right", "left") if s not in phases.hands]
    if missing:
        raise ParameterError(f"handedness needs both hands; missing {', '.join(missing)}")
    right = phases.hands["right"].positions
    left = phases.hands["left"].positions
    out = []
    for a, b, mask in joint_phrases(phases):
        # one frame past the phrase so its last expressive frame has a step
        stop = min(b + 1, phases.n_frames)
        full = np.zeros(stop - a, dtype=bool)
        full[: b - a] = mask
        if full[:-1].sum() == 0:
            continue  # a one-frame phrase at the take's end: nothing to measure
        label, l_r, l_l, d, diff = classify(right[a:stop], left[a:stop], full, phases.fps,
                                            params.threshold)
        out.append(PhraseHandedness(a, b, label, l_r, l_l, d, diff, _ranges(mask, a)))
    return tuple(out)


def _ranges(mask: np.ndarray, offset: int) -> tuple[tuple[int, int], ...]:
    m = np.concatenate([[False], mask, [False]]).astype(np.int8)
    d = np.diff(m)
    starts = np.flatnonzero(d == 1)
    stops = np.flatnonzero(d == -1)
    return tuple((int(a) + offset, int(b) + offset) for a, b in zip(starts, stops))
