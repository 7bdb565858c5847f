"""What an undoable edit did, in a few words: the page says it after Undo and Redo.

``describe(before, after)`` compares the edit parameters' values before and after one
edit (``webapp.state.Snapshot`` values against the session's) and names the change:
``matching point 2 moved (body 471 → 402, hand 56 → 42)``, ``W1 0.15 → 0.3``,
``matching point 1 tolerance 6 → global``. Frames are each file's own (as the table
counts them); points are numbered from 1, as the table and the refusals number them.
"""

from __future__ import annotations

#: the band widths: (fraction parameter, its label); ``NAME_s`` holds seconds, which win
WIDTHS = (("band", "W1"), ("refine_band", "W2"))


def _num(value) -> str:
    return f"{float(value):g}"


def _width(values: dict, name: str) -> str:
    seconds = values.get(f"{name}_s")
    return f"{_num(seconds)} s" if seconds is not None else _num(values.get(name))


def _tol(value) -> str:
    return "global" if value is None else _num(value)


def _points(before, after) -> str:
    """One point added, deleted or changed; else the counts."""
    before, after = list(before or ()), list(after or ())
    if len(after) == len(before) + 1:
        for k, p in enumerate(after):
            if k >= len(before) or before[k] != p:
                return f"matching point {k + 1} added (body {p.body}, hand {p.hand})"
    if len(after) == len(before) - 1:
        for k, p in enumerate(before):
            if k >= len(after) or after[k] != p:
                return f"matching point {k + 1} deleted (body {p.body}, hand {p.hand})"
    changed = [k for k, (a, b) in enumerate(zip(before, after)) if a != b]
    if len(before) == len(after) and len(changed) == 1:
        k = changed[0]
        a, b = before[k], after[k]
        moves = [
            f"{axis} {x} → {y}"
            for axis, x, y in (("body", a.body, b.body), ("hand", a.hand, b.hand))
            if x != y
        ]
        if moves:
            return f"matching point {k + 1} moved ({', '.join(moves)})"
        return f"matching point {k + 1} tolerance {_tol(a.tolerance)} → {_tol(b.tolerance)}"
    if not after:
        return f"{len(before)} matching points cleared"
    return f"matching points {len(before)} → {len(after)}"


def describe(before: dict, after: dict) -> str:
    """The edit from ``before`` to ``after`` in words: both dicts hold every edit
    parameter (``webapp.state.EDIT_PARAMS``); each change is said once (a width's
    fraction and seconds are one)."""
    parts = []
    if before.get("points") != after.get("points"):
        parts.append(_points(before.get("points"), after.get("points")))
    for name, label in WIDTHS:
        old, new = _width(before, name), _width(after, name)
        if old != new:
            parts.append(f"{label} {old} → {new}")
    if before.get("tolerance") != after.get("tolerance"):
        parts.append(f"tolerance T {_num(before['tolerance'])} → {_num(after['tolerance'])}")
    if before.get("max_unmatched_s") != after.get("max_unmatched_s"):
        old, new = (
            "default" if v is None else f"{_num(v)} s"
            for v in (before.get("max_unmatched_s"), after.get("max_unmatched_s"))
        )
        parts.append(f"open ends {old} → {new}")
    return "; ".join(parts) or "no change"
