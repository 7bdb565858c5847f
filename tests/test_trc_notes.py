"""A TRC whose header promises more frames than it holds is read with a note, not silently.

The reader keeps the rows it finds (``meta.notes`` says how many of how many); the
command line prints the note as one line on stderr and exits 0; an upload's check carries
it, naming the user's file (not the name it is kept under), for the page. The browser
side (the note in the page, escaped) is ``test_browser_uploads.py``. Real data: pyomeca's
``markers.trc``, cut in ``tmp_path`` (the input is never modified).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest

from engine.cli import main
from engine.io import load_take
from engine.io.trc import parse_trc

MOCAP = Path(__file__).resolve().parents[2] / "shared" / "data" / "mocap"
TRC = MOCAP / "pyomeca" / "markers.trc"


def _header_frames(text: str) -> int:
    lines = text.splitlines()
    sep = "\t" if "\t" in lines[0] else ","
    keys = [k.strip() for k in lines[1].split(sep)]
    return int(lines[2].split(sep)[keys.index("NumFrames")])


def _with_rows(path: Path, rows: int, declared: int | None = None) -> str:
    """``path``'s text with only its first ``rows`` data rows (after the 5 header lines and
    any blank one), and optionally ``NumFrames`` set to ``declared``."""
    lines = path.read_text().splitlines(keepends=True)
    head, data = lines[:5], [ln for ln in lines[5:] if ln.strip(",\t \r\n")]
    if declared is not None:
        sep = "\t" if "\t" in head[0] else ","
        keys = [k.strip() for k in head[1].split(sep)]
        values = head[2].rstrip("\r\n").split(sep)
        values[keys.index("NumFrames")] = str(declared)
        head[2] = sep.join(values) + "\n"
    return "".join(head + data[:rows])


@pytest.fixture()
def cut_trc(tmp_path) -> Path:
    """The real TRC cut to its first 40 data rows; its header still says 652 frames."""
    before = hashlib.sha256(TRC.read_bytes()).hexdigest()
    path = tmp_path / "walk cut.trc"
    path.write_text(_with_rows(TRC, 40))
    yield path
    assert hashlib.sha256(TRC.read_bytes()).hexdigest() == before  # input untouched


def test_a_cut_trc_is_read_with_a_note(cut_trc):
    declared = _header_frames(cut_trc.read_text())
    assert declared == 652
    take = load_take(cut_trc)
    assert take.n_frames == 40
    assert take.meta.notes == ("walk cut.trc: the header says 652 frames, 40 were read",)


def test_the_real_file_is_noted_too():
    """pyomeca's own file declares 652 frames and holds 93 (the case a user found)."""
    take = load_take(TRC)
    assert take.meta.notes == (f"{TRC.name}: the header says 652 frames, 93 were read",)


def test_a_header_that_matches_gives_no_note(tmp_path):
    path = tmp_path / "whole.trc"
    path.write_text(_with_rows(TRC, 93, declared=93))
    take = load_take(path)
    assert take.n_frames == 93 and take.meta.notes == ()


def test_more_rows_than_the_header_says_is_noted(tmp_path):
    take = parse_trc(_with_rows(TRC, 50, declared=20), source=tmp_path / "grown.trc")
    assert take.n_frames == 50
    assert take.meta.notes == ("grown.trc: the header says 20 frames, 50 were read",)


def test_the_command_line_prints_the_note_once_and_succeeds(cut_trc, capsys):
    code = main(["info", "--json", str(cut_trc)])
    out, err = capsys.readouterr()
    assert code == 0
    lines = err.strip().splitlines()
    assert lines == ["handsplice: note: walk cut.trc: the header says 652 frames, 40 were read"]
    report = json.loads(out)
    assert report["frames"] == 40 and report["notes"] == [lines[0].split("note: ", 1)[1]]


def test_a_file_without_a_note_prints_nothing_on_stderr(tmp_path, capsys):
    path = tmp_path / "whole.trc"
    path.write_text(_with_rows(TRC, 93, declared=93))
    assert main(["info", str(path)]) == 0
    assert capsys.readouterr().err == ""


def test_an_upload_check_carries_the_note_with_the_users_file_name(tmp_path, sample_dir, cut_trc):
    from webapp import config, uploads

    cfg = config.AppConfig(
        sample_dir=sample_dir.resolve(),
        upload_dir=(tmp_path / "uploads").resolve(),
        max_upload_bytes=4 * 2**20,
        max_upload_files=3,
        max_upload_total_bytes=10 * 2**20,
    )
    name = "<img src=x>walk.trc"
    kept = uploads.check(cfg, uploads.stage_bytes(cfg, name, cut_trc.read_bytes()))
    expected = f"{name}: the header says 652 frames, 40 were read"
    assert kept.summary["frames"] == 40 and kept.summary["notes"] == [expected]
    assert kept.take.meta.notes == (expected,)
    assert kept.path.name != name  # kept under its hash; the note still names the user's file
    # a BVH reader's note travels the same way: the Leap/gestification extra zero row
    # (stranger 14 F4: left out in silence), for the upload line and the open takes' note
    leap = MOCAP / "gestification/hello-world.bvh"
    name = "session2_leap_hello.bvh"
    kept = uploads.check(cfg, uploads.stage_bytes(cfg, name, leap.read_bytes()))
    expected = (
        f"{name}: the header says 82 frames, the file has 83 data rows: the first, all zeros "
        "(the gestification exporter's extra row), was left out"
    )
    assert kept.summary["frames"] == 82 and kept.summary["notes"][0] == expected
    assert kept.take.meta.notes[0] == expected
    assert kept.summary["notes"][1].startswith(f"{name}: frame 0 is a one-frame outlier pose")
