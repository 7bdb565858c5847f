"""The BVH reader's data rows, read in chunks (issue 13): same poses, same errors, and
memory that follows the take's arrays, not a Python object per value."""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from conftest import MOCAP
from test_bvh import MALFORMED, SMALL, _first_data_line, _small_lines

from engine.base.errors import MotionFormatError
from engine.io import bvh
from engine.io.bvh import parse_bvh, read_bvh

REAL = [SMALL, MOCAP / "lafan1" / "dance1_subject1.bvh"]


@pytest.fixture
def tiny_chunks(monkeypatch):
    """Chunks of 4 rows: every take crosses many chunk boundaries."""
    monkeypatch.setattr(bvh, "ROWS_PER_CHUNK", 4)


@pytest.mark.parametrize("path", REAL, ids=lambda p: p.name)
def test_chunks_give_the_same_poses(path: Path, monkeypatch):
    whole = read_bvh(path)
    monkeypatch.setattr(bvh, "ROWS_PER_CHUNK", 7)
    chunked = read_bvh(path)
    np.testing.assert_array_equal(chunked.rotations, whole.rotations)
    np.testing.assert_array_equal(chunked.translations, whole.translations)
    assert (chunked.fps, chunked.meta) == (whole.fps, whole.meta)


@pytest.mark.parametrize("case", list(MALFORMED))
def test_malformed_rows_give_the_same_error_in_any_chunk(case: str, tmp_path: Path, tiny_chunks):
    text, line, fragment = MALFORMED[case]
    f = tmp_path / "walk.bvh"
    f.write_text(text)
    with pytest.raises(MotionFormatError) as err:
        read_bvh(f)
    assert err.value.line == line, str(err.value)
    assert fragment in str(err.value)


def _edited(edits: dict[tuple[int, int], str], keep_rows: int | None = None) -> str:
    """The small take with value ``col`` of data row ``r`` replaced (``None``: dropped)."""
    lines = _small_lines()
    d = _first_data_line()
    for (r, col), value in edits.items():
        vals = lines[d + r].split()
        vals[col] = value
        lines[d + r] = " ".join(v for v in vals if v is not None)
    if keep_rows is not None:
        lines = lines[: d + keep_rows]
    return "\n".join(lines)


def _error(text: str) -> MotionFormatError:
    with pytest.raises(MotionFormatError) as err:
        parse_bvh(text, "walk.bvh")
    return err.value


def test_a_character_no_number_has_wins_over_an_earlier_wrong_count(tiny_chunks):
    d = _first_data_line()
    err = _error(_edited({(1, 0): "1 2", (30, 3): "x7"}))
    assert err.line == d + 31 and "'x7'" in str(err)


def test_wrong_count_wins_over_an_earlier_unreadable_number(tiny_chunks):
    d = _first_data_line()
    err = _error(_edited({(2, 0): "1.2.3", (40, 0): "1 2"}))
    assert err.line == d + 41 and "found 55" in str(err)


def test_truncation_wins_over_an_earlier_overflow(tiny_chunks):
    err = _error(_edited({(3, 1): "1e999"}, keep_rows=20))
    assert "ends after 20 data rows" in str(err)


def test_unreadable_number_in_a_late_chunk_names_its_line(tiny_chunks):
    d = _first_data_line()
    err = _error(_edited({(45, 2): "1.2.3"}))
    assert err.line == d + 46 and "value 3 is '1.2.3'" in str(err)


def test_the_largest_absurd_value_is_named_whatever_its_chunk(tiny_chunks):
    d = _first_data_line()
    err = _error(_edited({(2, 1): "2e9", (50, 4): "-9e9"}))
    assert err.line == d + 51 and "value 5 is '-9e9'" in str(err)


def _long_take(n_frames: int) -> str:
    """The small take's skeleton with ``n_frames`` rows of varied values."""
    lines = _small_lines()
    d = _first_data_line()
    rows = np.random.default_rng(0).uniform(-170, 170, (n_frames, len(lines[d].split())))
    head = [ln if not ln.startswith("Frames:") else f"Frames: {n_frames}" for ln in lines[:d]]
    return "\n".join(head + [" ".join(f"{v:.6f}" for v in r) for r in rows]) + "\n"


def test_reading_allocates_little_beyond_the_take():
    """Peak traced memory of parsing stays within the lines and the pose arrays plus a
    few chunks (a Python float or str per value, as before issue 13, is ~6x the text)."""
    text = _long_take(12000)
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        base = tracemalloc.get_traced_memory()[0]
        m = parse_bvh(text, "long.bvh")
        peak = tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()
    arrays = m.rotations.nbytes + m.translations.nbytes
    assert m.n_frames == 12000
    assert peak < 1.6 * len(text) + arrays + 8e6, (peak, len(text), arrays)


@pytest.mark.parametrize("frames", [1, 3, 2048, 10**6])
def test_the_writers_pieces_are_the_whole_text(frames: int, tmp_path: Path):
    """``iter_bvh`` joined is ``format_bvh`` for any piece size (pieces that split the data
    lines anywhere, one piece for all of them), and ``write_bvh`` writes the same bytes."""
    m = parse_bvh(_long_take(50), "long.bvh")
    whole = bvh.format_bvh(m)
    assert "".join(bvh.iter_bvh(m, frames=frames)) == whole
    out = tmp_path / "out.bvh"
    bvh.write_bvh(m, out)
    assert out.read_bytes() == whole.encode("utf-8")


def test_writing_a_long_take_holds_a_piece_of_its_text_not_all_of_it(tmp_path: Path):
    """``write_bvh`` streams the text and makes the Euler angles a few joints at a time: the
    peak traced memory stays within a third of the file and twice the pose arrays (the
    text held whole with its lines, or every joint's Euler intermediates at once, are
    several times that)."""
    m = parse_bvh(_long_take(12000), "long.bvh")
    out = tmp_path / "out.bvh"
    channels = m.rotations.nbytes + m.translations.nbytes  # the (F, C) values, float64
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        base = tracemalloc.get_traced_memory()[0]
        bvh.write_bvh(m, out)
        peak = tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()
    size = out.stat().st_size
    assert size > 5e6
    assert peak < size / 3 + 2 * channels, (peak, size, channels)
