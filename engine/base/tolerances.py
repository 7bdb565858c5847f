"""Numerical tolerances and work budgets, in one place (beside :mod:`engine.base.limits`,
which bounds outside input).

Tolerances
    ``FRAME_EPS``: slack when a frame number or a band edge computed in floating point is
    rounded (``floor(t + FRAME_EPS)``), so 2.9999999999 frames counts as 3.
    ``TINY``: guard added to a norm or a weight sum before dividing (unit vectors of
    near-zero length, weights that may all be zero); far below any real value.

Budgets (band cells; memory grows with them)
    ``INCREMENTAL_MAX_CELLS``: up to this pass-1 band area the splice keeps incremental
    ``Aligner`` solvers (γ for the cumulative views, partial re-solves; about 3-4 bytes
    per cell resident: backpointers both ways, γ of every 8th row); above it a one-shot
    solve (1 byte per cell).
    ``CUMULATIVE_MAX_CELLS``: the cumulative-cost (γ) view of a pass solved one-shot is
    refused above this many cells (about 18 bytes per cell, ~290 MB here).
    ``DENSE_PASS1_MAX_CELLS``: the app tabulates the pass-1 local costs of a pair once
    up to this many cells (8 bytes each), so a drag re-solves from the table.
    ``PARALLEL_MIN_CELLS``: from this band area on, an incremental ``Aligner`` runs a
    solve's forward and backward rows on two threads at once (below it a thread's start
    costs more than it saves).
    ``TRUST_MAX_CELLS``: the trust assessment (:mod:`engine.splice.uncertainty`) keeps γ of
    every cell it weighs, both ways (16 bytes a cell, plus a byte of backpointers); a
    pass whose band holds more cells is weighed on its cells nearest the pass's path
    (the widest radius that fits: about ±2.3 s at 10 minutes, 120 fps).
    ``TRUST_BLOCK_CELLS``: the trust holds γ of this many band cells at once (both ways, 17
    bytes a cell: ~17 MB), not of the whole band (:func:`engine.dtw.marginals.row_spread`
    sweeps the band by blocks of rows; the result is the same for any block size).

Pass-1 rate (multi-resolution pass 1, ``engine.splice.coarse``)
    ``PASS1_RATE_CAP_HZ``: pass 1's sign-cost DTW runs first on both takes decimated to at
    most this rate (a whole number of body frames per coarse frame); takes at or below it
    are solved as before, bit for bit.
    ``PASS1_FINE_RADIUS_S``: the exact full-rate pass 1 then runs only on cells within this
    many seconds (Chebyshev) of the upsampled coarse path, inside the W1 band and the
    matching points' clips.
    ``PASS1_NEAR_STEPS``: ... and on the cells of every other coarse alignment whose
    cheapest coarse path costs at most this many mean coarse path cells more than the
    coarse optimum (a stretch where the coarse signs nearly tie between two alignments:
    the full-rate optimum may take the other one), when the W1 band holds at least
    ``PASS1_NEAR_MIN_CELLS`` cells (long takes: the 10-minute pair at 120 fps needed it;
    on the 2-minute pair and every shorter bench case the strip alone gave the full-rate
    result, and the search would cost two more coarse passes, about a tenth of a splice).
"""

from __future__ import annotations

FRAME_EPS = 1e-9
TINY = 1e-12

INCREMENTAL_MAX_CELLS = 100_000_000
CUMULATIVE_MAX_CELLS = 16_000_000
DENSE_PASS1_MAX_CELLS = 6_000_000
PARALLEL_MIN_CELLS = 200_000
PASS1_RATE_CAP_HZ = 30.0
PASS1_FINE_RADIUS_S = 0.5
PASS1_NEAR_STEPS = 3.0
PASS1_NEAR_MIN_CELLS = 100_000_000
TRUST_MAX_CELLS = 40_000_000
TRUST_BLOCK_CELLS = 1_000_000
