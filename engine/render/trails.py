"""Motion trails of both hands, coloured by gesture phase (docs/method.md §8).

The trail of a hand is the 3-D path of its wrist joint over a frame range, drawn
as a tube (``style="line"``) or as a ball at each sample (``style="spheres"``:
their spacing shows speed). With a per-frame phase array the colours are
preparation yellow, stroke red, hold blue, retraction magenta and rest grey
(codes as ``engine.gesture.phases.Phase``: REST=0, PREPARATION=1, STROKE=2,
HOLD=3, RETRACTION=4; letters ``-PSHR`` and names are accepted too). Without
phases each hand has its own colour (left teal, right orange).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from engine.mesh.mannequin import sweep

REST, PREPARATION, STROKE, HOLD, RETRACTION = range(5)
PHASE_COLORS = {
    REST: (0.55, 0.55, 0.55, 1.0),  # grey
    PREPARATION: (0.96, 0.80, 0.10, 1.0),  # yellow
    STROKE: (0.86, 0.10, 0.10, 1.0),  # red
    HOLD: (0.15, 0.40, 0.90, 1.0),  # blue (our choice)
    RETRACTION: (0.85, 0.15, 0.80, 1.0),  # magenta
}
HAND_COLORS = {
    "left": (0.05, 0.62, 0.62, 1.0),
    "right": (0.95, 0.50, 0.08, 1.0),
    "": (0.95, 0.50, 0.08, 1.0),
}
_NAMES = {
    "rest": REST,
    "-": REST,
    "": REST,
    "none": REST,
    "preparation": PREPARATION,
    "prep": PREPARATION,
    "p": PREPARATION,
    "stroke": STROKE,
    "s": STROKE,
    "hold": HOLD,
    "h": HOLD,
    "retraction": RETRACTION,
    "retract": RETRACTION,
    "r": RETRACTION,
}
STYLES = ("line", "spheres")


def phase_codes(phases: Sequence | np.ndarray, n_frames: int, field: str = "phases") -> np.ndarray:
    """(F,) int phase codes from ints, ``Phase`` members, letters or names.

    Raises ``ValueError`` naming the first unknown label or a length mismatch.
    """
    arr = np.asarray(phases, dtype=object).reshape(-1)
    if arr.shape[0] != n_frames:
        raise ValueError(f"{field}: expected {n_frames} per-frame phases, got {arr.shape[0]}")
    out = np.empty(n_frames, dtype=np.int64)
    for k, p in enumerate(arr):
        if isinstance(p, (int, np.integer)) and not isinstance(p, bool):
            code = int(p)
        elif isinstance(p, str):
            code = _NAMES.get(p.strip().lower(), -1)
        else:
            code = -1
        if code not in PHASE_COLORS:
            raise ValueError(
                f"{field}[{k}]: unknown phase {p!r}; expected 0-4 or one of "
                "rest, preparation, stroke, hold, retraction (or -PSHR)"
            )
        out[k] = code
    return out


def per_side_phases(phases, sides: Sequence[str], n_frames: int) -> dict[str, np.ndarray | None]:
    """Phase codes per hand: one array for both hands, ``{side: array}``, or an
    ``engine.gesture.phases.GesturePhases``."""
    if phases is None:
        return {s: None for s in sides}
    if hasattr(phases, "hands") and isinstance(phases.hands, Mapping):  # GesturePhases
        phases = {s: h.labels for s, h in phases.hands.items()}
    if isinstance(phases, Mapping):
        return {
            s: (phase_codes(phases[s], n_frames, f"phases[{s!r}]") if s in phases else None)
            for s in sides
        }
    codes = phase_codes(phases, n_frames)
    return {s: codes for s in sides}


def trail_arrays(
    points: np.ndarray, colors: np.ndarray, radius: float, style: str = "line", n_around: int = 8
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Geometry of one trail: vertices ``(V, 3)``, faces ``(T, 3)``, colours ``(V, 4)``.

    points : (N, 3) path samples, display space; colors : (N, 4) per sample.
    """
    points = np.asarray(points, dtype=float)
    colors = np.asarray(colors, dtype=float)
    if style not in STYLES:
        raise ValueError(f"trail style {style!r}: expected one of {', '.join(STYLES)}")
    if len(points) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros((0, 4))
    if style == "spheres" or len(points) < 2:
        import trimesh

        ball = trimesh.creation.icosphere(subdivisions=1)
        sv, sf = np.asarray(ball.vertices), np.asarray(ball.faces)
        verts = (points[:, None] + radius * sv[None]).reshape(-1, 3)
        faces = (sf[None] + (np.arange(len(points)) * len(sv))[:, None, None]).reshape(-1, 3)
        return verts, faces, np.repeat(colors, len(sv), axis=0)
    # drop repeated samples (a still hand) so the tube has a direction everywhere
    keep = np.concatenate([[True], np.linalg.norm(np.diff(points, axis=0), axis=1) > 1e-6])
    pts, cols = points[keep], colors[keep]
    if len(pts) < 2:
        return trail_arrays(points[:1], colors[:1], radius, "spheres")
    ref = np.cross(pts[-1] - pts[0], [0.0, 1.0, 0.0])
    if np.linalg.norm(ref) < 1e-9:
        ref = np.array([1.0, 0.0, 0.0])
    verts, faces, src = sweep(
        pts, np.full(len(pts), radius), np.full(len(pts), radius), ref, n_around=n_around, n_cap=1
    )
    return verts, faces, cols[src]


def trail_colors(codes: np.ndarray | None, side: str, n: int) -> np.ndarray:
    """(n, 4) colours of ``n`` samples: by phase code, else the hand's own colour."""
    if codes is None:
        return np.tile(HAND_COLORS.get(side, HAND_COLORS[""]), (n, 1))
    table = np.array([PHASE_COLORS[k] for k in range(5)])
    return table[codes]
