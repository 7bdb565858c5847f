"""What Undo and Redo say they did (webapp.edit_words) and what the downloads say of an
alignment the motion does not pin (webapp.views.trust.unpinned_words): stranger 6,
findings 8 and 2. The page shows both (tests/test_browser_findings6.py)."""

from __future__ import annotations

from types import SimpleNamespace

from engine.io.session import MatchPoint
from webapp.edit_words import describe

BASE = {
    "band": 0.3,
    "band_s": None,
    "refine_band": 0.1,
    "refine_band_s": None,
    "tolerance": 2.0,
    "points": (),
    "max_unmatched_s": None,
}


def _with(**values) -> dict:
    return {**BASE, **values}


def test_point_edits_are_named_by_their_number_and_frames():
    one = (MatchPoint(471, 56, None),)
    moved = (MatchPoint(402, 56, None),)
    assert describe(_with(), _with(points=one)) == "matching point 1 added (body 471, hand 56)"
    assert describe(_with(points=one), _with()) == "matching point 1 deleted (body 471, hand 56)"
    assert describe(_with(points=one), _with(points=moved)) == (
        "matching point 1 moved (body 471 → 402)"
    )
    two = (MatchPoint(10, 5, None), MatchPoint(471, 56, 6.0))
    both = (MatchPoint(10, 5, None), MatchPoint(402, 42, 6.0))
    assert describe(_with(points=two), _with(points=both)) == (
        "matching point 2 moved (body 471 → 402, hand 56 → 42)"
    )
    tol = (MatchPoint(10, 5, None), MatchPoint(471, 56, None))
    assert describe(_with(points=two), _with(points=tol)) == (
        "matching point 2 tolerance 6 → global"
    )
    assert describe(_with(points=two), _with()) == "2 matching points cleared"


def test_widths_tolerance_and_open_ends_are_named_as_the_page_labels_them():
    assert describe(_with(band=0.15), _with(band=0.3)) == "W1 0.15 → 0.3"
    assert describe(_with(), _with(refine_band_s=2.0)) == "W2 0.1 → 2 s"
    assert describe(_with(tolerance=6.0), _with()) == "tolerance T 6 → 2"
    assert describe(_with(), _with(max_unmatched_s=1.5)) == "open ends default → 1.5 s"
    assert describe(_with(), _with()) == "no change"


def _trust(pinned: bool, frames=(141, 261)):
    return SimpleNamespace(
        uncertainty=SimpleNamespace(pinned=pinned, typical_ms=705.4),
        suggestions=[(f, 3.0) for f in frames],
    )


def test_the_downloads_warn_only_when_the_timing_is_not_pinned():
    from webapp.views.trust import unpinned_words

    assert unpinned_words(None) == ""
    assert unpinned_words(_trust(True)) == ""
    words = unpinned_words(_trust(False))
    assert "does not pin the timing" in words and "±705 ms" in words
    assert "Check body frames 141, 261 in the preview" in words
    assert "Check body frame 141 in" in unpinned_words(_trust(False, (141,)))
    assert "Check it in the preview" in unpinned_words(_trust(False, ()))
