"""Pass 1's band with open ends: room for the unmatched ends (issue 12).

The paper's band (METHOD.md §4) is a strip of half-width ``Λ`` around the diagonal from
``(0, 0)`` to ``(n-1, m-1)``. With open ends the true path runs from ``(0, s)`` (the hand
take starts ``s`` frames earlier) or ``(s, 0)`` to ``(n-1, m-1-e)`` or ``(n-1-e, m-1)``:
a straight path of another slope, ``s`` frames off the diagonal at the first row and
``e`` at the last. Where ``s`` or ``e`` exceeds ``Λ`` (a hand take 1-2 s longer at each
end of a 5-8 s body take), the strip leaves the true ends out and pass 1 must end on the
strip's edge; pass 2 refines around that path and cannot recover.

:func:`open_end_band` widens the strip toward both sides by ``E(i)``, ``E`` at the first
and last rows, tapering linearly to 0 at the middle row. ``E = min(Λ, limit)``: any
straight path whose unmatched ends are each up to ``Λ + E`` (twice the half-width) off
the diagonal stays inside (the deviation from the diagonal is linear in the row, and so is
the allowance), and the band never reaches further than the unmatched limits allow. On
short takes the pass-1 band grows by about half its area; on long takes ``E`` is capped at
:data:`MAX_ROOM_S` seconds and its taper at :data:`TAPER_WIDTHS` times ``E`` (about 10 %
more cells on a 2-minute pair). Pass 2's band (around the pass-1 path) does not grow.
Matching points keep their tolerance clips (the widened band is intersected with them).

Takes of different lengths (:func:`inside_band`): the paper's strip assumes the hand
take spans the body take at another tempo (slope ``m/n``). A shorter take recorded
during a longer one (a 33 s hand take inside a 2-minute body take) runs at about the
same rate (slope 1) from an unknown offset ``d = i - j`` anywhere in ``[0, n - m]``
(``[n - m, 0]`` when the hand take is longer), and the strip around the corner-to-corner
diagonal misses most of those paths. The band then also holds every cell within the
slope-1 half-width ``Λ1 = W / √2`` (the paper's ``Λ`` for a segment of slope 1) of a
placement whose ends the unmatched limits allow. Its cost: ``min(n, m) · (|n - m| + 2 Λ1)``
cells; nothing when the takes last as long (the placements are the diagonal itself).
"""

from __future__ import annotations

import math

import numpy as np

from engine.dtw import Band

__all__ = ["inside_band", "open_end_band", "placement_offsets"]


#: the widening at each end is at most this many seconds (real takes start and end a few
#: seconds apart; on long takes the band's own width in seconds already covers more)
MAX_ROOM_S = 4.0
#: the widening tapers to nothing over at most this many times its own width (rows)
TAPER_WIDTHS = 8.0


def open_end_band(
    band: Band,
    width: float,
    limits: tuple[int, int],
    points=(),
    fps: float | None = None,
    taper: float = 0.5,
) -> Band:
    """``band`` (from ``Band.from_constraints(n, m, width, points, open_ends=True)``)
    widened for unmatched ends.

    Parameters
    ----------
    band : Band, ``n`` rows, ``m`` columns
    width : float, the band width as a fraction of ``n`` (``W = width * n``)
    limits : (body, hand) frames that may stay unmatched at each end (grid frames)
    points : matching points ``(x, y, tol)`` (grid frames); their clips are kept
    fps : frame rate of the grid; with it ``E`` is at most :data:`MAX_ROOM_S` seconds and
        the taper at most :data:`TAPER_WIDTHS` times ``E`` rows (long takes: about 10 %
        more pass-1 cells instead of 40 %)
    taper : share of the take over which the widening falls from ``E`` to 0 at each end
    """
    n, m = band.n, band.m
    if n < 2 or width <= 0:
        return band
    lam = width * math.sqrt(n * n + m * m) / 2.0
    body_lim, hand_lim = limits
    cap = lam if fps is None else min(lam, MAX_ROOM_S * fps)
    e_hand = min(cap, float(hand_lim))  # hand frames unmatched: columns off the diagonal
    e_body = min(cap, float(body_lim) * m / n)  # body frames unmatched, in columns
    i = np.arange(n, dtype=float)
    span = taper * (n - 1)
    if fps is not None:
        span = min(span, TAPER_WIDTHS * max(e_hand, e_body) * n / m)
    span = max(span, 1.0)
    start = np.clip(1.0 - i / span, 0.0, 1.0)
    end = np.clip(1.0 - (n - 1 - i) / span, 0.0, 1.0)
    # hand starts earlier / body ends later: columns above; body starts earlier / hand
    # ends later: columns below
    up = np.round(e_hand * start + e_body * end).astype(np.int64)
    down = np.round(e_body * start + e_hand * end).astype(np.int64)
    lo = np.maximum(band.lo - down, 0)
    hi = np.minimum(band.hi + up, m - 1)
    inside = inside_band(n, m, width, limits)
    if inside is not None:  # union row by row, on the rows the placements reach
        rows = inside[0] <= inside[1]
        lo = np.where(rows, np.minimum(lo, inside[0]), lo)
        hi = np.where(rows, np.maximum(hi, inside[1]), hi)
    wide = Band(lo, hi, m, open_ends=True)
    if points:
        wide = wide.intersect(Band.from_constraints(n, m, None, points, open_ends=True))
    return wide


def inside_band(
    n: int, m: int, width: float, limits: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray] | None:
    """``(lo, hi)`` columns per row, ``(n,)`` int each, of the cells near a slope-1 path
    that places the shorter take inside the longer one (module docstring), or None when
    the takes last as long or the limits allow no such placement.

    A slope-1 path with offset ``d`` (body frame minus hand frame) leaves ``max(d, 0)``
    body and ``max(-d, 0)`` hand frames unmatched at the start and ``n - m - d`` (body, if
    positive) or ``d - (n - m)`` (hand) at the end, so ``limits = (body, hand)`` allow
    ``d`` in ``[-hand, body] ∩ [n - m - body, n - m + hand]``; of these, the offsets that
    keep the shorter take inside, ``[min(0, n - m), max(0, n - m)]``, are covered, each
    widened by ``Λ1 = width · n / √2`` columns (drift, as the paper's band allows)."""
    diff = n - m
    if diff == 0 or n < 2 or m < 2:
        return None
    body_lim, hand_lim = int(limits[0]), int(limits[1])
    d_lo = max(min(0, diff), -hand_lim, diff - body_lim)
    d_hi = min(max(0, diff), body_lim, diff + hand_lim)
    if d_lo > d_hi:
        return None
    reach = width * n / math.sqrt(2.0)
    i = np.arange(n, dtype=float)
    lo = np.maximum(np.floor(i - d_hi - reach), 0.0).astype(np.int64)
    hi = np.minimum(np.ceil(i - d_lo + reach), m - 1.0).astype(np.int64)
    return lo, hi


def placement_offsets(n: int, m: int, limits: tuple[int, int]) -> tuple[int, int] | None:
    """``(d_lo, d_hi)``: the offsets (body frame minus hand frame, grid frames) of the
    slope-1 placements of the shorter take inside the longer one that :func:`inside_band`
    covers, or None when it covers none (takes as long, or limits that allow none). The
    band's width across them, ``d_hi - d_lo``, comes from the takes' lengths and the
    unmatched-end limits, not from W1 (which only widens each placement by ``Λ1``): the
    app says so beside W1."""
    diff = n - m
    if diff == 0 or n < 2 or m < 2:
        return None
    body_lim, hand_lim = int(limits[0]), int(limits[1])
    d_lo = max(min(0, diff), -hand_lim, diff - body_lim)
    d_hi = min(max(0, diff), body_lim, diff + hand_lim)
    return None if d_lo > d_hi else (d_lo, d_hi)
