"""One call for a take's gesture analysis: phases, handedness and key poses.

``analyze_take(motion)`` is what ``handsplice analyze`` and the web app call;
``GestureAnalysis.to_dict()`` is the JSON the CLI prints with ``--json``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from engine.gesture.handedness import HandednessParameters, PhraseHandedness, detect_handedness
from engine.gesture.keyposes import KeyPoseParameters, KeyPoses, find_key_poses
from engine.gesture.phases import GesturePhases, PhaseParameters, segment_phases


@dataclass(frozen=True)
class GestureAnalysis:
    """Phases (per-frame labels, ``Phase`` codes), handedness per phrase and key poses
    per side (with the pose-space distance maps when asked for)."""

    phases: GesturePhases
    handedness: tuple[PhraseHandedness, ...]
    key_poses: dict[str, KeyPoses]
    source: str = ""
    units: str = ""

    def to_dict(self) -> dict:
        """JSON-ready summary (no distance maps)."""
        sides = {}
        for side, hand in self.phases.hands.items():
            sides[side] = {
                "labels": hand.labels.astype(int).tolist(),
                "segments": [
                    {
                        "phase": s.phase.name.lower(),
                        "code": int(s.phase),
                        "start": s.start,
                        "stop": s.stop,
                    }
                    for s in hand.segments
                ],
                "phrases": [
                    {"start": p.start, "stop": p.stop, "pattern": p.pattern} for p in hand.phrases
                ],
                "rest_position_m": [round(float(v), 6) for v in hand.rest_position],
                "key_frames": self.key_poses[side].frames.astype(int).tolist()
                if side in self.key_poses
                else [],
            }
        return {
            "source": self.source,
            "fps": self.phases.fps,
            "n_frames": self.phases.n_frames,
            "units": self.units,
            "phase_codes": {"rest": 0, "preparation": 1, "stroke": 2, "hold": 3, "retraction": 4},
            "hands": sides,
            "handedness": [
                {
                    "start": h.start,
                    "stop": h.stop,
                    "label": h.label,
                    "right_length_m": round(h.right_length, 6),
                    "left_length_m": round(h.left_length, 6),
                    "duration_s": round(h.duration, 6),
                    "difference_m_per_s": round(h.difference, 6),
                    "expressive": [list(r) for r in h.expressive],
                }
                for h in self.handedness
            ],
            "parameters": {"phases": asdict(self.phases.params)},
        }


def analyze_take(
    motion,
    phase_params: PhaseParameters | None = None,
    handedness_params: HandednessParameters | None = None,
    key_params: KeyPoseParameters | None = None,
    arms=None,
    with_maps: bool = False,
) -> GestureAnalysis:
    """Phases, handedness and key poses of a full-body take (any units, any heading).

    ``arms`` (``engine.gesture.body.BodyArms``) is found from joint roles when omitted.
    """
    phases = segment_phases(motion, phase_params, arms=arms)
    hands = detect_handedness(phases, handedness_params)
    keys = {
        side: find_key_poses(phases.paths.points[side], motion.fps, key_params, with_map=with_maps)
        for side in phases.hands
    }
    return GestureAnalysis(
        phases=phases,
        handedness=hands,
        key_poses=keys,
        source=str(motion.meta.source),
        units=str(motion.meta.units),
    )


def summary_lines(result: GestureAnalysis) -> list[str]:
    """Human-readable lines for the CLI."""
    from pathlib import Path

    ph = result.phases
    name = Path(result.source).name if result.source else "take"
    lines = [f"{name}: {ph.n_frames} frames at {ph.fps:g} fps, units {result.units or 'unknown'}"]
    for side, hand in ph.hands.items():
        counts = np.bincount(hand.labels, minlength=5)
        share = ", ".join(
            f"{p}={c / max(ph.n_frames, 1):.0%}"
            for p, c in zip(("rest", "prep", "stroke", "hold", "retr"), counts)
        )
        phrases = " ".join(f"{p.pattern}[{p.start}-{p.stop})" for p in hand.phrases) or "-"
        lines.append(f"{side:5s} phrases: {phrases}")
        lines.append(f"{'':5s} frames: {share}")
        if side in result.key_poses:
            k = result.key_poses[side].frames
            lines.append(f"{'':5s} key poses ({len(k)}): {' '.join(map(str, k.tolist())) or '-'}")
    for h in result.handedness:
        lines.append(
            f"phrase [{h.start}-{h.stop}) {h.label}: L_RH {h.right_length:.2f} m, "
            f"L_LH {h.left_length:.2f} m over {h.duration:.2f} s "
            f"-> {h.difference:.3f} m/s"
        )
    if not result.handedness:
        lines.append("no gesture phrases")
    return lines
