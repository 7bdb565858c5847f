"""Constructed wrist paths with known gesture phases, for tests, benchmarks and
teaching (the answer is known by construction).

A script is a list of steps; each step moves the wrist (body frame, metres, y up)
with a smoothstep from where it is to a target, or holds it, and records the
phase it was built to be. Speeds and accelerations are those of real gestures
(0.5-2 m/s, strokes several times the preparation's acceleration).
"""

from __future__ import annotations

import numpy as np

from engine.gesture.phases import Phase

REST = np.array([0.0, -0.5, 0.05])  # wrist below the shoulder, arm hanging


def smoothstep(u: np.ndarray) -> np.ndarray:
    u = np.clip(u, 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


def build(script, fps: float = 60.0, start=REST) -> tuple[np.ndarray, np.ndarray]:
    """Positions (F, 3) and the phase labels (F,) a script was built with.

    Steps: ``("rest", seconds)``, ``("hold", seconds)``, and
    ``(phase, seconds, target)`` for phase in ``"prep"``, ``"stroke"``,
    ``"retract"`` (``target`` a 3-vector, or None for the rest position).
    """
    names = {
        "rest": Phase.REST,
        "hold": Phase.HOLD,
        "prep": Phase.PREPARATION,
        "stroke": Phase.STROKE,
        "retract": Phase.RETRACTION,
    }
    pos = [np.asarray(start, dtype=float)]
    labels = []
    here = np.asarray(start, dtype=float)
    for step in script:
        kind, seconds = step[0], step[1]
        n = int(round(seconds * fps))
        if kind in ("rest", "hold"):
            pts = np.repeat(here[None], n, axis=0)
        else:
            target = REST if step[2] is None else np.asarray(step[2], dtype=float)
            u = smoothstep(np.arange(1, n + 1) / n)[:, None]
            pts = here + (target - here) * u
            here = target
        pos.extend(pts)
        labels.extend([names[kind]] * n)
    labels = [labels[0]] + labels
    return np.asarray(pos), np.asarray(labels, dtype=np.uint8)


def phrase_psh_r(space=(0.1, -0.1, 0.35), beat=(0.1, -0.3, 0.35)) -> list:
    """rest, preparation, two beat strokes, hold, retraction, rest."""
    return [
        ("rest", 0.6),
        ("prep", 0.5, space),
        ("stroke", 0.2, beat),
        ("stroke", 0.2, space),
        ("hold", 0.5),
        ("retract", 0.6, None),
        ("rest", 0.6),
    ]


def random_phrase(rng: np.random.Generator, hold: bool = False) -> list:
    """A random phrase script: rest, preparation to a random point in gesture space,
    1-4 beat strokes (or one independent hold), retraction, rest.

    Gesture space: 0.2-0.45 m in front of and up to 0.3 m beside the shoulder;
    beats of 0.1-0.3 m lasting 0.15-0.3 s.
    """
    space = np.array([rng.uniform(-0.1, 0.3), rng.uniform(-0.25, 0.05), rng.uniform(0.2, 0.45)])
    script: list = [("rest", rng.uniform(0.3, 0.8)), ("prep", rng.uniform(0.35, 0.7), space)]
    if hold:
        script.append(("hold", rng.uniform(0.5, 1.2)))
    else:
        for _ in range(int(rng.integers(1, 5))):
            direction = rng.normal(size=3)
            direction /= np.linalg.norm(direction)
            beat = space + direction * rng.uniform(0.1, 0.3)
            dur = rng.uniform(0.15, 0.3)
            script += [("stroke", dur, beat), ("stroke", dur, space)]
        if rng.random() < 0.5:
            script.append(("hold", rng.uniform(0.2, 0.6)))
    script += [("retract", rng.uniform(0.4, 0.8), None), ("rest", rng.uniform(0.3, 0.8))]
    return script
