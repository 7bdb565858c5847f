"""The side a hand file's name says, against the side asked for (stranger R3-7).

``engine.model.roles.side_name_conflict`` is the one rule: ``info`` and ``splice`` with a
``--side`` that contradicts the file's name warn in one line (exit 0, the side asked for
wins); without ``--side`` the name decides, so nothing is said.
"""

from __future__ import annotations

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
