"""What the command line's help says is what the engine does (a new user's finding F1).

``splice --help`` said "default 0.3, at most 10s on long takes" for W1 while the engine
(``engine.dtw.constraints.BAND``) uses 1.5 s x sqrt(T) when narrower than 0.3: the help
now reads the rule's own description, and the description is checked against the rule.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from engine.dtw import constraints as C

ROOT = Path(__file__).resolve().parents[1]


def _splice_help() -> str:
    out = subprocess.run(
        [sys.executable, "-m", "engine.cli", "splice", "--help"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
        env={"COLUMNS": "1000", "PATH": "/usr/bin:/bin", "PYTHONPATH": str(ROOT)},
    ).stdout
    return " ".join(out.split())


def test_splice_help_states_the_engines_band_defaults():
    text = _splice_help()
    assert C.BAND.default_text in text and C.REFINE_BAND.default_text in text, text
    assert "at most 10s" not in text


@pytest.mark.parametrize("rule", [C.BAND, C.REFINE_BAND], ids=lambda r: r.name)
def test_the_default_text_is_what_default_for_applies(rule):
    fps = 30.0
    text = rule.default_text
    assert f"default {rule.default:g} of the body take" in text
    crossover = float(re.search(r"takes from ([\d.]+) s on", text).group(1))
    # below the crossover the fraction, above it the time width the text names
    assert rule.default_for(int((crossover - 1) * fps), fps) == C.Width(rule.default, C.FRACTION)
    for seconds in (crossover + 1, 120.0):
        width = rule.default_for(int(seconds * fps), fps)
        assert width.unit == C.SECONDS
        named = rule.default_s * (seconds**0.5 if "sqrt(T" in text else 1.0)
        assert width.value == pytest.approx(named, abs=0.06)
    if rule.max_cells is not None:  # 10 minutes at 120 fps: the cap the text names
        width = rule.default_for(600 * 120, 120.0)
        assert f"{rule.max_cells:,} cells" in text
        assert width.value < rule.default_s * 600**0.5


def test_the_page_names_the_unmatched_ends_remedies_as_the_command_lines():
    """The status line told a web user "--max-unmatched SECONDS allows longer unmatched
    ends", a flag with no control on the page: the page's sentence names the page's own
    field for the limit."""
    from engine.splice.report import unmatched_summary

    ranges = [(0, 499), (4087, 4586)]  # both ends cut by a 500-frame limit
    cli = unmatched_summary(ranges, 30.0, 500)
    page = unmatched_summary(ranges, 30.0, 500, front="page")
    assert "(--ends fixed matches every frame)" in cli
    assert ": --max-unmatched SECONDS allows longer unmatched ends" in cli
    assert page.startswith("body frames 0-499, 4087-4586 (33.3 s) have no hand match")
    assert "(the command line's --ends fixed matches every frame)" in page
    assert "a larger 'Unmatched ends at most (seconds)' (under the band widths)" in page
    # every flag the page names is the command line's
    for flag in re.finditer(r"--[a-z-]+", page):
        assert "command line" in page[max(0, flag.start() - 45) : flag.start()], page
