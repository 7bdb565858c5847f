"""The side a hand file's name says, against the side asked for (stranger R3-7).

``engine.model.roles.side_name_conflict`` is the one rule: ``info`` and ``splice`` with a
``--side`` that contradicts the file's name warn in one line (exit 0, the side asked for
wins); without ``--side`` the name decides, so nothing is said.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import MOCAP, cropped_bvh

from engine.cli import main
from engine.model.roles import side_name_conflict

MUG = MOCAP / "manipnet" / "mug1_rightHand.bvh"
BODY = MOCAP / "bandai-namco/dataset-2_wave-right-hand_normal_001.bvh"


@pytest.fixture(scope="module")
def right_named(tmp_path_factory) -> Path:
    """ManipNet's hand take (no side in its joint names) cut to 2 s, named ``..._rightHand``."""
    return cropped_bvh(MUG, tmp_path_factory.mktemp("hand") / "mug_rightHand.bvh", 240)


def test_the_rule_names_the_file_and_both_sides():
    text = side_name_conflict("takes/mug1_rightHand.bvh", "left")
    assert text == (
        "mug1_rightHand.bvh: the file name says right but the side asked for is left; "
        "taking it as the left hand"
    )
    assert side_name_conflict("mug1_rightHand.bvh", "right") is None
    assert side_name_conflict("mug1_rightHand.bvh", None) is None
    assert side_name_conflict("mug1_rightHand.bvh", "auto") is None
    assert side_name_conflict("hello-world.bvh", "left") is None


def test_info_with_a_contradicting_side_warns_in_one_line(right_named, capsys):
    assert main(["info", str(right_named), "--side", "left"]) == 0
    out, err = capsys.readouterr()
    warnings = [x for x in err.splitlines() if "warning" in x]
    assert warnings == [
        "handsplice: warning: mug_rightHand.bvh: the file name says right but the side asked "
        "for is left; taking it as the left hand (leave --side out to follow the name)"
    ], err
    assert "Traceback" not in err
    assert main(["info", str(right_named)]) == 0  # the name decides: nothing to say
    assert "warning" not in capsys.readouterr().err


@pytest.mark.timeout(1500)  # a whole splice: kernels compile on a cold cache
def test_splice_with_a_contradicting_side_warns_and_splices(right_named, tmp_path, capsys):
    out = tmp_path / "o.bvh"
    code = main(
        ["splice", str(BODY), str(right_named), "-o", str(out), "--side", "left", "--quiet"]
    )
    err = capsys.readouterr().err
    assert code == 0 and out.is_file(), err
    assert (
        sum("warning: mug_rightHand.bvh: the file name says right" in x for x in err.splitlines())
        == 1
    )


HELLO = MOCAP / "gestification" / "hello-world.bvh"  # joints rHand, rIndex1...: a right hand
LEFT_NAMED_WARNING = (
    "pointing_left_hand.bvh: the file name says left but its joint names are a right hand "
    "(rHand); taking it as the right hand"
)


@pytest.fixture(scope="module")
def left_named_right_hand(tmp_path_factory) -> Path:
    """Stranger 14 F2: a Leap right-hand take saved under a "left" name."""
    out = tmp_path_factory.mktemp("named") / "pointing_left_hand.bvh"
    out.write_bytes(HELLO.read_bytes())
    return out


def test_joint_names_are_stronger_than_a_file_name(left_named_right_hand):
    """The one rule (``hand_file_side``): a name saying the other side than the joint names
    gives the joints' side, with one warning; a name the joints agree with, or that gives
    the side of a side-less rig, is taken silently."""
    from engine.io import load_take
    from engine.model.roles import HandFileSide, hand_file_side

    hello = load_take(HELLO).skeleton
    assert hand_file_side(left_named_right_hand, hello) == HandFileSide("right", LEFT_NAMED_WARNING)
    assert hand_file_side("pointing_right_hand.bvh", hello) == HandFileSide("right")
    assert hand_file_side("hello.bvh", hello) == HandFileSide(None)
    mug = load_take(MUG).skeleton  # no side in its joint names: the file name decides
    assert hand_file_side("mug1_leftHand.bvh", mug) == HandFileSide("left")


def test_rh_and_lh_tokens_of_a_file_name_say_its_side():
    """Stranger 14 F6: ``RH``/``LH`` between ``_ - . space`` is the labs' side; only as a
    whole token (``rhythm``, ``birch``, ``lhasa`` say nothing)."""
    from engine.model.roles import side_from_name

    assert side_from_name("gloves_RH_mug.bvh") == "right"
    assert side_from_name("takes/s01-lh.grasp.bvh") == "left"
    assert side_from_name("cup RH.bvh") == "right"
    for name in ("rhythm.bvh", "birch_take.bvh", "lhasa_walk.bvh", "RH_LH.bvh", "rh_left.bvh"):
        assert side_from_name(name) is None, name


def test_batch_notes_a_file_name_saying_the_other_side(left_named_right_hand):
    from engine.io import load_take
    from engine.jobs.batch import PairJob, side_notes

    job = PairJob(1, "p", str(BODY), str(left_named_right_hand), "auto")
    assert side_notes(job, load_take(left_named_right_hand)) == (LEFT_NAMED_WARNING,)
    asked = PairJob(1, "p", str(BODY), str(left_named_right_hand), "right")  # the joints'
    assert side_notes(asked, load_take(left_named_right_hand)) == (LEFT_NAMED_WARNING,)
    other = PairJob(1, "p", str(BODY), str(left_named_right_hand), "left")  # refused later
    assert side_notes(other, load_take(left_named_right_hand)) == ()


@pytest.mark.timeout(1500)  # a whole splice: kernels compile on a cold cache
def test_splice_warns_when_the_file_name_says_the_other_side(
    left_named_right_hand, tmp_path, capsys
):
    """The CLI splices a right hand named left as the right hand (its joints), saying why."""
    out = tmp_path / "o.bvh"
    code = main(["splice", str(BODY), str(left_named_right_hand), "-o", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert code == 0 and out.is_file(), err
    warnings = [x for x in err.splitlines() if "warning" in x]
    assert warnings == [f"handsplice: warning: {LEFT_NAMED_WARNING}"], err
    assert main(["info", str(out), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["hand_sides"] == ["right"]


def test_info_warns_when_the_file_name_says_the_other_side(left_named_right_hand, capsys):
    """``info`` says it too, with no ``--side`` or with the joints' side (nothing else)."""
    for extra in ([], ["--side", "right"]):
        assert main(["info", str(left_named_right_hand), *extra]) == 0
        warnings = [x for x in capsys.readouterr().err.splitlines() if "warning" in x]
        assert warnings == [f"handsplice: warning: {LEFT_NAMED_WARNING}"], extra


def test_serve_takes_the_joints_side_of_a_left_named_right_hand(left_named_right_hand):
    """``serve BODY HAND`` without ``--side``: the same rule (it used to open the pair as
    left, which the hand lacks)."""
    from webapp.serve_cli import _named_side

    assert _named_side(left_named_right_hand) == ("right", LEFT_NAMED_WARNING)
    assert _named_side(MUG) == ("right", None)  # mug1_rightHand.bvh: no side in its joints
