"""A hand take whose file name and joint names carry no side (stranger 12, F2).

Its geometry tells which hand its fingers form in the file's axes; whether those axes are
right-handed nothing in the take tells (ManipNet's files are Unity's left-handed axes: its
``mug1_rightHand`` forms a left hand). So the side is never chosen silently: the CLI says
it on one line naming ``--side``, the page's upload line warns naming the Side to choose.
Each real named hand-only take is copied without its side (file and joint names): the side
it is then spliced as is the named one, or the warning names the flag that gives it.
"""

from __future__ import annotations

import re
import shutil

import pytest
from conftest import MOCAP

from engine.base.errors import HandSpliceError
from engine.cli import main
from engine.io.bvh import read_bvh
from engine.model.hand_side import geometric_side, unnamed_side_warning
from engine.model.roles import find_roles, side_from_name

BODY = MOCAP / "bandai-namco/dataset-2_wave-right-hand_normal_001.bvh"
#: every real hand-only take whose name or joint names say its side: (path, named side)
NAMED = [(MOCAP / "manipnet" / f"mug1_{s}Hand.bvh", s) for s in ("right", "left")] + [
    (p, "right") for p in sorted((MOCAP / "gestification").glob("*.bvh"))
]


def _unnamed_copy(path, tmp_path):
    """``path`` copied as ``hand.bvh`` with the side letter taken off its joint names
    (Leap's ``rHand`` -> ``Hand``); ManipNet's joints carry none."""
    text = re.sub(r"\b(ROOT|JOINT) r(?=[A-Z])", r"\1 ", path.read_text())
    out = tmp_path / "hand.bvh"
    out.write_text(text)
    take = read_bvh(out)
    assert side_from_name(out) is None and find_roles(take.skeleton).unsided is not None
    return out, take


@pytest.mark.parametrize("path,named", NAMED, ids=[p.stem for p, _ in NAMED])
def test_a_renamed_named_take_gets_its_side_or_a_warning_naming_it(tmp_path, path, named):
    out, take = _unnamed_copy(path, tmp_path)
    seen = geometric_side(take, find_roles(take.skeleton).unsided).side
    warning = unnamed_side_warning(out.name, take, None, "pass --side {side}")
    assert warning is not None and "\n" not in warning  # never silent, one line
    assert warning.startswith("hand.bvh: ") and f"spliced as the {seen} hand" in warning
    # the named side: the one it is spliced as, or the one the warning says how to give
    assert seen == named or f"pass --side {named}" in warning, warning


def test_the_names_give_the_side_without_a_warning():
    take = read_bvh(NAMED[0][0])
    assert unnamed_side_warning(NAMED[0][0].name, take, None, "pass --side {side}") is None


@pytest.mark.parametrize("side", ["right", "left"])
def test_cli_says_the_side_it_guessed_and_the_flag(tmp_path, capsys, monkeypatch, side):
    """Stranger 12: ``mug1_leftHand.bvh`` copied as ``mug1.bvh`` was spliced as the right hand
    without a word. The warning comes before the long work (stopped here)."""
    import engine.splice.retime as retime

    def stop(*args, **kwargs):
        raise HandSpliceError("stopped here")

    monkeypatch.setattr(retime, "splice_takes", stop)
    hand = tmp_path / "mug1.bvh"
    shutil.copyfile(MOCAP / "manipnet" / f"mug1_{side}Hand.bvh", hand)
    code = main(["splice", str(BODY), str(hand), "-o", str(tmp_path / "out.bvh"), "--quiet"])
    assert code == 2
    lines = [
        ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("handsplice: warning")
    ]
    assert len(lines) == 1, lines
    assert lines[0].startswith("handsplice: warning: mug1.bvh: its file name and joint names ")
    assert f"pass --side {side}" in lines[0]  # the hand it was captured as
    # a side given is the user's: no warning
    main(["splice", str(BODY), str(hand), "-o", str(tmp_path / "o.bvh"), "--quiet", "--side", side])
    assert "handsplice: warning" not in capsys.readouterr().err


def test_batch_notes_carry_the_warning_unless_the_manifest_gives_the_side(tmp_path):
    from engine.jobs.batch import PairJob, side_notes

    hand = tmp_path / "mug1.bvh"
    shutil.copyfile(MOCAP / "manipnet" / "mug1_leftHand.bvh", hand)
    take = read_bvh(hand)
    job = PairJob(line=2, name="p", body=str(BODY), hand=str(hand), side="auto")
    (note,) = side_notes(job, take)
    assert note.startswith("mug1.bvh: ") and note.endswith("set its side column to left")
    assert side_notes(PairJob(2, "p", str(BODY), str(hand), "left"), take) == ()


def test_info_says_the_side_splice_takes_a_side_less_hand_as(tmp_path, capsys, monkeypatch):
    """Stranger 14 F6: ``info`` on a hand take whose names carry no side says the side
    ``splice`` without ``--side`` takes it as (its geometry, the same rule)."""
    import json

    import engine.splice.retime as retime

    def stop(*args, **kwargs):
        raise HandSpliceError("stopped here")

    monkeypatch.setattr(retime, "splice_takes", stop)
    hand = tmp_path / "mug1.bvh"
    shutil.copyfile(MOCAP / "manipnet" / "mug1_rightHand.bvh", hand)
    main(["splice", str(BODY), str(hand), "-o", str(tmp_path / "out.bvh"), "--quiet"])
    spliced = re.search(r"spliced as the (\w+) hand", capsys.readouterr().err).group(1)
    assert main(["info", str(hand), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["geometry_side"]["side"] == spliced
    assert main(["info", str(hand)]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert f"splice without --side takes it as the {spliced} hand" in text, text
    named = MOCAP / "manipnet" / "mug1_rightHand.bvh"  # the name gives the side: nothing said
    assert main(["info", str(named), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["geometry_side"] is None
