"""How far the matched hand time could move: uncertainty per body frame (docs/method.md, "Trust").

For each pass, every band cell gets the cost of the cheapest path forced through it
(:mod:`engine.dtw.marginals`). A row where cells far from the chosen warp cost
little more than the optimum is a row the alignment could move at little price:
the fingers there may be mistimed. Per body frame ``i``::

    spread_p(i) = sqrt( Σ_j w_ij (j - warp_i)² / Σ_j w_ij ),  w_ij = exp(-(T_p(i, j) - T_p*) / τ_p)

for pass ``p`` in {1, 2}, with the temperature ``τ_p`` = ``KAPPA`` × the pass's mean
local cost per path step (the cost of a few frames' typical mismatch: scale-free
across metrics and takes). Costs: about two extra solves per pass (forward and
backward γ, 16 bytes per band cell); a band over ``TRUST_MAX_CELLS`` (a long take's
pass 1) is weighed on its cells nearest the pass's path (:func:`weighed_band`).

Per body frame, in milliseconds of the hand take (issue 17)::

    u(i) = max over |k - i| <= σ of  sqrt((W·spread_1)² + spread_2² + bend²)(k) · (1 + c̃(k)) / 2

* the passes' spreads and the bend term (:func:`warp_bend`) in quadrature (pass 1
  decides the gesture phase, pass 2 the timing within it; pass 1's sign costs are
  coarse and its spread counts ``W`` = :data:`PASS1_WEIGHT` = half); a plain sum ranks
  the frames as well but doubles the share of frames over 100 ms (19 % -> 41 %, the
  true error unchanged), which would turn the desync meter red;
* ``c̃``: the local evidence, the aligning pass's own path cost on the frame's row
  against the take's median path cost (:func:`path_mismatch`, smoothed over σ): a row
  whose matched cells cost several times the take's typical match is a row the path
  crosses without support, whatever the band's other cells cost (a typical row, c̃ = 1,
  keeps its spread);
* the maximum over the merge's blend window σ (``alignment.blend``): the smoothing
  spreads a mistimed row's error over its neighbours.

Against the true timing error of the accuracy bench's families (Spearman ρ pooled over
every body frame, ``benchmarks/bench_uncertainty.py``): quadrature of the spreads and
the bend alone 0.47; the terms above were checked on the tuning seeds.

Strokes: the body take's stroke phases (:mod:`engine.gesture.phases`) each get the
largest uncertainty inside them and a verdict against the 100 ms threshold at which
viewers notice hand/body desync (Jörg, Hodgins & O'Sullivan 2010): ``ok`` below
``AMBER_MS``, ``check`` up to ``DESYNC_MS``, ``desync`` above.

Pairs the motion does not pin (real pairs of two different performances): the accuracy
bench's families split one performance, so its true path is a near-perfect match and the
uncertainty is low but where it is hard (19 % of frames over 100 ms, pooled). A body take
and a hand take captured apart (the demo's Bandai wave + Leap OK signs) match nowhere
well: every row's cells cost about the same, and pass 2's spread alone is 100-250 ms on
most rows (the demo: median uncertainty 650 ms). That is true, not inflated: nothing in
the two motions fixes the timing there. Against the 100 ms threshold every stroke is then
red, which tells the user once per stroke what is a property of the whole pair. So the
take's **typical uncertainty** (``Uncertainty.typical_ms``: the median over the matched
rows) is reported once; where it is above ``DESYNC_MS`` the pair is *not pinned*
(``Uncertainty.pinned``) and each frame's and stroke's verdict measures what it adds to
that typical level (``typical`` up to ``AMBER_MS`` above it, ``check``, ``desync`` more
than ``DESYNC_MS`` above it): the places a matching point should go first still stand
out. Rows outside the overlap (open ends: the fingers hold the nearest matched pose, no
timing is chosen there) are ``unmatched``, not red, and do not count in a stroke's worst
value. ``uncertainty_ms`` itself is unchanged (the bench's ρ and flag ratio are computed
from it).

Suggestions: the least certain body frames, one per region (at least
``SUGGEST_GAP_S`` apart), as candidate matching points.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d, maximum_filter1d

from engine.base.tolerances import TRUST_MAX_CELLS
from engine.dtw.align import FIXED
from engine.dtw.band import Band
from engine.dtw.marginals import row_spread

#: temperature = KAPPA x the pass's mean local cost per path step (chosen on the tuning seeds)
KAPPA = 1.0
#: relative floor of the temperature (a perfect match must not make every row certain)
TEMPERATURE_FLOOR = 1e-3
#: viewers notice hand/body desync above about 0.1 s (Jörg, Hodgins & O'Sullivan 2010)
DESYNC_MS = 100.0
AMBER_MS = 50.0
#: suggested matching points are at least this far apart (seconds of the body take)
SUGGEST_GAP_S = 1.0
SUGGESTIONS = 3
#: half-window (seconds) of the bend term: where the timing changes rate within it, the
#: path (whose step cost favours one rate) may cut the corner (see :func:`warp_bend`);
#: chosen on the tuning seeds (0.1, 0.25, 0.5, 0.75, 1 s tried)
BEND_S = 0.25
#: weight of pass 1's spread beside pass 2's (its sign costs are coarse: chosen on the
#: tuning seeds, 0.5 and 1 tried)
PASS1_WEIGHT = 0.5


@dataclass(frozen=True)
class Stroke:
    """One stroke of the body take: frames ``start..end`` (inclusive), its worst uncertainty."""

    start: int
    end: int
    uncertainty_ms: float
    verdict: str  # "ok" | "check" | "desync"

    def as_dict(self) -> dict:
        return {
            "start": self.start,
            "end": self.end,
            "uncertainty_ms": round(float(self.uncertainty_ms), 1),
            "verdict": self.verdict,
        }


@dataclass(frozen=True)
class Uncertainty:
    """Uncertainty of one splice alignment.

    ms : (n,) float, milliseconds of the hand take per body frame
    pass1_ms, pass2_ms : (n,) float, each pass's part
    fps : float, body frames per second
    bend_ms : (n,) float or None, the bend term's part (:func:`warp_bend`)
    evidence : (n,) float or None, the path's cost on each row over the take's median
        (:func:`path_mismatch`)
    matched : (n,) bool or None, rows inside the alignment's overlap (None: all)
    typical_ms : float, the median of ``ms`` over the matched rows (:func:`typical_level`)
    """

    ms: np.ndarray
    pass1_ms: np.ndarray
    pass2_ms: np.ndarray
    fps: float
    bend_ms: np.ndarray | None = None
    evidence: np.ndarray | None = None
    matched: np.ndarray | None = None
    typical_ms: float = 0.0

    @property
    def pinned(self) -> bool:
        """True when the motion pins the timing somewhere: the typical uncertainty is at
        most ``DESYNC_MS`` (else the two takes look like different performances)."""
        return self.typical_ms <= DESYNC_MS

    def frame_verdicts(self) -> list[str]:
        """(n,) verdict per body frame (:func:`verdict` against the typical level;
        ``unmatched`` outside the overlap)."""
        base = self.typical_ms
        out = [verdict(float(v), base) for v in self.ms]
        if self.matched is not None:
            out = [v if m else UNMATCHED for v, m in zip(out, self.matched, strict=True)]
        return out

    def suggestions(self, count: int = SUGGESTIONS, gap_s: float = SUGGEST_GAP_S) -> list[int]:
        """Body frames of the ``count`` least certain places, at least ``gap_s`` apart.

        A place is scored by the uncertainty summed over ``gap_s`` around it, so a long
        uncertain stretch (many mistimed frames, where one matching point fixes most) comes
        before a one-frame spike; the frame returned is the least certain one of the stretch.
        Slow stretches are not ranked down: the largest true errors sit in holds and slow
        moves, and a point placed at the uncertainty's peak there lowered the hard families'
        p95 more than one at the stretch's visible (moving) edge (issue 17; measured on the
        tuning seeds, then on the reported ones: ``benchmarks/bench_uncertainty.py``).
        Only matched rows (``matched``) are offered and scored: outside the overlap no
        hand frame is matched, so a matching point there has nothing to fix (their
        uncertainty spans the whole unmatched stretch).
        """
        gap = max(1, int(round(gap_s * self.fps)))
        ms = np.asarray(self.ms, np.float64)
        if self.matched is not None:
            ms = np.where(np.asarray(self.matched, bool), ms, 0.0)
        n = len(ms)
        csum = np.concatenate([[0.0], np.cumsum(ms)])
        half = gap // 2
        lo = np.clip(np.arange(n) - half, 0, n)
        hi = np.clip(np.arange(n) + half + 1, 0, n)
        score = csum[hi] - csum[lo]
        order = np.argsort(-score, kind="stable")
        chosen: list[int] = []
        for i in order:
            if score[i] <= 0.0 or len(chosen) >= count:
                break
            a, b = int(lo[i]), int(hi[i])
            peak = a + int(np.argmax(ms[a:b]))
            if all(abs(peak - c) >= gap for c in chosen):
                chosen.append(peak)
        return chosen


#: verdict of rows and strokes outside the overlap (fingers hold a matched pose, untimed)
UNMATCHED = "unmatched"
#: verdict of a frame no less certain than its pair's typical level, in a pair not pinned
TYPICAL = "typical"


def verdict(ms: float, typical_ms: float = 0.0) -> str:
    """``ok`` / ``check`` / ``desync`` for an uncertainty in milliseconds.

    ``typical_ms``: the take's typical uncertainty (:attr:`Uncertainty.typical_ms`). Above
    ``DESYNC_MS`` the pair is not pinned anywhere, and the verdict measures what ``ms``
    adds to it: ``typical`` (up to ``AMBER_MS`` more), ``check``, ``desync`` (more than
    ``DESYNC_MS`` more).
    """
    if typical_ms > DESYNC_MS:
        extra = ms - typical_ms
        if extra > DESYNC_MS:
            return "desync"
        return "check" if extra > AMBER_MS else TYPICAL
    if ms > DESYNC_MS:
        return "desync"
    return "check" if ms > AMBER_MS else "ok"


def matched_rows(alignment, n: int) -> np.ndarray:
    """(n,) bool: body rows inside the alignment's overlap (``alignment.unmatched_body``)."""
    keep = np.ones(n, bool)
    for a, b in getattr(alignment, "unmatched_body", ()) or ():
        keep[max(0, int(a)) : min(n, int(b) + 1)] = False
    return keep


def typical_level(ms: np.ndarray, matched: np.ndarray | None = None) -> float:
    """The take's typical uncertainty: the median of ``ms`` over the matched rows (all rows
    when none is matched)."""
    ms = np.asarray(ms, np.float64)
    if matched is not None and np.any(matched):
        ms = ms[np.asarray(matched, bool)]
    return float(np.median(ms)) if len(ms) else 0.0


def pass_spread(result, warp: np.ndarray, kappa: float = KAPPA, cancelled=None) -> np.ndarray:
    """(n,) grid columns: the weighted spread of one pass's cheap cells around ``warp``.

    result : pipeline.PassResult (rows, metric, band, path, cost)
    warp : (n,) float, grid hand frame per body frame
    cancelled : callable or None: ``engine.base.errors.Cancelled`` once it returns True
    """
    a, b = result.rows
    temperature = kappa * max(float(result.cost) / max(len(result.path), 1), TEMPERATURE_FLOOR)
    ends = getattr(result, "ends", None) or FIXED
    costs = getattr(result, "cost_table", None)  # the app's tabulated pass-1 costs
    band = weighed_band(result.band, np.asarray(result.path))
    return row_spread(
        a,
        b,
        band,
        result.metric,
        warp,
        temperature,
        margin=0.0,
        ends=ends,
        costs=costs,
        cancelled=cancelled,
    ).spread


def weighed_band(band, path: np.ndarray, max_cells: int | None = None):
    """The cells of ``band`` a pass's spread weighs: all of them up to ``max_cells``
    (default ``engine.base.tolerances.TRUST_MAX_CELLS``), else
    those within the widest radius of ``path`` ((k, 2) body, hand grid frames) that fits.

    γ both ways is kept for every weighed cell (16 bytes a cell): a 10-minute pair's
    pass-1 band (180 M cells) would take 2.9 GB and two more pass-1 solves' time after
    every edit. A cell more than the radius (about 2.3 s at 10 minutes, 120 fps; wider
    than pass 2's band) from the path weighs ``exp(-extra / τ)`` with an extra cost of
    that many frames' mismatch: next to nothing on any row the motion pins, and a row it
    does not pin is over the 100 ms threshold within the radius already."""
    max_cells = TRUST_MAX_CELLS if max_cells is None else int(max_cells)
    if band.area <= max_cells:
        return band
    radius = max(1, int(max_cells // (2 * band.n)))
    while True:
        near = Band.around_path(path, band.n, band.m, radius, open_ends=band.open_ends)
        weighed = band.intersect(near)
        if weighed.area <= max_cells or radius == 1:
            return weighed
        radius = max(1, int(radius * max_cells / weighed.area * 0.95))


def warp_bend(warp: np.ndarray, half: int) -> np.ndarray:
    """(n,) grid columns: how much the warp's rate changes around each row.

    ``|(w(i + h) - w(i)) - (w(i) - w(i - h))|``: the hand frames the timing gains or
    loses over the ``h`` rows after ``i`` against the ``h`` rows before, zero where the
    timing keeps one rate (about ``h² |w''(i)|`` on a smooth warp); near the ends of the
    take ``h`` shrinks to the rows there are (0 on the first and last row). Pass 2's
    step cost favours one rate, so where the rate changes the path lags by a part of this.
    warp : (n,) float grid hand frame per body frame; half : int >= 1, rows
    """
    w = np.asarray(warp, np.float64)
    n = len(w)
    if n < 3 or half < 1:
        return np.zeros(n)
    idx = np.arange(n)
    h = np.minimum(np.minimum(idx, n - 1 - idx), half)
    return np.abs(w[idx + h] - 2.0 * w + w[idx - h])


def path_mismatch(result, n: int, sigma: float = 0.0) -> np.ndarray:
    """(n,) float >= 0: each row's mean local cost on the pass's path over the take's
    median (rows the path leaves unmatched: 1, a typical row), smoothed by a Gaussian of
    ``sigma`` rows.

    result : pipeline.PassResult (path (k, 2), rows, metric); n : rows of the body take
    """
    path = np.asarray(result.path)
    cost = np.asarray(result.path_costs(), np.float64)
    rows = path[:, 0]
    total = np.bincount(rows, weights=cost, minlength=n)[:n]
    count = np.bincount(rows, minlength=n)[:n]
    mean = np.where(count > 0, total / np.maximum(count, 1), np.nan)
    typical = float(np.nanmedian(mean)) if np.any(count > 0) else 0.0
    if not (np.isfinite(typical) and typical > 0.0):
        return np.zeros(n)
    rel = np.where(count > 0, mean / typical, 1.0)
    rel = np.where(np.isfinite(rel), rel, 1.0)
    return gaussian_filter1d(rel, sigma, mode="nearest") if sigma > 0 else rel


def aligned_by_pass1(features) -> bool:
    """True when the map follows pass 1's path (a hand take without a forearm and no spin
    signal: :func:`engine.splice.pipeline.align_passes`)."""
    from engine.splice import pipeline as P  # the pipeline does not import this module

    return P.hand_lacks_forearm(features) and not P.uses_spin(features)


def blend_reach(values: np.ndarray, sigma: float) -> np.ndarray:
    """(n,) the largest of ``values`` within ``±round(sigma)`` rows of each row (the merge's
    Gaussian blend of σ rows carries a row's timing to its neighbours)."""
    half = int(round(sigma))
    if half < 1:
        return np.asarray(values, np.float64).copy()
    return maximum_filter1d(np.asarray(values, np.float64), 2 * half + 1, mode="nearest")


def alignment_uncertainty(
    features, alignment, bend_s: float = BEND_S, cancelled=None
) -> Uncertainty:
    """Uncertainty per body frame of a :class:`~engine.splice.pipeline.SpliceAlignment`.

    Both passes count, also where pass 1 is the alignment (a hand take without a
    forearm): pass 2's costs are then flat over its band, so its spread is the band's,
    which is what such a take leaves unconfirmed (measured: on the forearm-less rig
    families pass 1's spread alone ranks their frames well within a take, but makes
    the whole take look far more certain than its errors are). ``bend_s``: half-window
    (seconds) of the bend term (:func:`warp_bend`). The local evidence is the path cost
    of the pass whose path the map follows (:func:`aligned_by_pass1`). ``cancelled``: a
    callable; once it returns True, ``engine.base.errors.Cancelled`` is raised (between
    the γ sweeps).
    """
    warp = np.asarray(alignment.warp, np.float64)
    p1, p2 = alignment.pass1, alignment.pass2
    n = len(warp)
    frame_ms = 1000.0 / float(features.fps)
    ms1 = pass_spread(p1, warp, cancelled=cancelled) * frame_ms
    ms2 = pass_spread(p2, warp, cancelled=cancelled) * frame_ms
    half = max(1, int(round(bend_s * float(features.fps))))
    bend = warp_bend(warp, half) * frame_ms
    sigma = float(getattr(alignment, "blend", 0.0) or 0.0)
    final = p1 if aligned_by_pass1(features) else p2
    evidence = path_mismatch(final, n, sigma)
    spread = np.sqrt((PASS1_WEIGHT * ms1) ** 2 + ms2**2 + bend**2)
    ms = blend_reach(spread * 0.5 * (1.0 + evidence), sigma)
    matched = matched_rows(alignment, n)
    return Uncertainty(
        ms=ms,
        pass1_ms=ms1,
        pass2_ms=ms2,
        fps=float(features.fps),
        bend_ms=bend,
        evidence=evidence,
        matched=matched,
        typical_ms=typical_level(ms, matched),
    )


def strokes(uncertainty: Uncertainty, labels: np.ndarray, stroke_label: int) -> list[Stroke]:
    """Stroke runs of ``labels`` ((n,) ints, one phase per body frame) with their verdicts.

    A stroke's value is its worst uncertainty over its matched rows, judged against the
    take's typical level (:func:`verdict`); a stroke with no matched row is ``unmatched``
    (its value then over all its rows)."""
    labels = np.asarray(labels)
    out: list[Stroke] = []
    n = len(labels)
    i = 0
    while i < n:
        if labels[i] != stroke_label:
            i += 1
            continue
        j = i
        while j + 1 < n and labels[j + 1] == stroke_label:
            j += 1
        values = uncertainty.ms[i : j + 1]
        inside = None if uncertainty.matched is None else uncertainty.matched[i : j + 1]
        if inside is not None and not np.any(inside):
            worst, word = float(values.max()), UNMATCHED
        else:
            worst = float(values[inside].max() if inside is not None else values.max())
            word = verdict(worst, uncertainty.typical_ms)
        out.append(Stroke(start=i, end=j, uncertainty_ms=worst, verdict=word))
        i = j + 1
    return out


def summary_line(stroke_list: list[Stroke], typical_ms: float = 0.0) -> str:
    """``"3 of 12 strokes may show desync: body frames 120-140, ..."`` (or that none may).

    When the pair is not pinned (``typical_ms`` > ``DESYNC_MS``) it says so once, and
    counts the strokes that stand out above that typical level."""
    bad = [s for s in stroke_list if s.verdict == "desync"]
    if typical_ms > DESYNC_MS:
        head = (
            f"the two takes' motions do not pin the timing anywhere (typical uncertainty "
            f"±{typical_ms:.0f} ms, over {DESYNC_MS:.0f} ms: different performances?): "
            "place matching points by eye"
        )
        if not stroke_list:
            return head
        where = ", ".join(f"{s.start}-{s.end}" for s in bad[:6]) + (", ..." if len(bad) > 6 else "")
        tail = (
            f"; {len(bad)} of {len(stroke_list)} strokes are {DESYNC_MS:.0f} ms less certain "
            f"still: body frames {where}"
            if bad
            else f"; none of {len(stroke_list)} strokes stands out from that"
        )
        return head + tail
    if not stroke_list:
        return "no gesture strokes found in the body take"
    if not bad:
        return (
            f"none of {len(stroke_list)} strokes is likely to show desync (all under "
            f"{DESYNC_MS:.0f} ms)"
        )
    where = ", ".join(f"{s.start}-{s.end}" for s in bad[:6]) + (", ..." if len(bad) > 6 else "")
    return f"{len(bad)} of {len(stroke_list)} strokes may show desync: body frames {where}"


@dataclass(frozen=True)
class Assessment:
    """Everything the report, the CLI and the app say about trust in one alignment.

    uncertainty : Uncertainty
    strokes : list of Stroke (the body take's strokes, first spliced arm)
    suggestions : list of (body frame, hand-file frame) the least certain places, with the
        hand frame the alignment matches there now (a user checks and corrects it)
    """

    uncertainty: Uncertainty
    strokes: list
    suggestions: list

    @property
    def summary(self) -> str:
        return summary_line(self.strokes, self.uncertainty.typical_ms)

    def report_fields(self) -> dict:
        """``uncertainty_ms``, ``strokes``, ``suggested_points`` and ``desync`` for REPORT.json."""
        return {
            "uncertainty_ms": [round(float(v), 1) for v in self.uncertainty.ms],
            "strokes": [s.as_dict() for s in self.strokes],
            "suggested_points": [[int(b), round(float(h), 2)] for b, h in self.suggestions],
            "desync": {
                "threshold_ms": DESYNC_MS,
                "typical_ms": round(float(self.uncertainty.typical_ms), 1),
                "pinned": bool(self.uncertainty.pinned),
                "summary": self.summary,
            },
        }


def assess(
    features, alignment, stroke_labels: np.ndarray, stroke_code: int, cancelled=None
) -> Assessment:
    """Uncertainty, strokes and suggested points of a splice alignment.

    features : pipeline.SpliceFeatures; alignment : pipeline.SpliceAlignment
    stroke_labels : (n,) gesture phase codes of the body take, one per body frame
        (``engine.gesture.phases.marker_phase_labels(features.body_markers, features.fps)``)
    stroke_code : int, the code of a stroke in ``stroke_labels`` (``Phase.STROKE``)
    cancelled : callable or None (:func:`alignment_uncertainty`)
    """
    unc = alignment_uncertainty(features, alignment, cancelled=cancelled)
    hand_map = np.asarray(alignment.map, np.float64)
    picks = [(i, float(hand_map[i])) for i in unc.suggestions()]
    return Assessment(
        uncertainty=unc, strokes=strokes(unc, stroke_labels, int(stroke_code)), suggestions=picks
    )
