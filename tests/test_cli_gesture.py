"""``handsplice analyze`` and ``handsplice synthesize`` end to end (in process)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import MOCAP

from engine.cli import main

WAVE = MOCAP / "bandai-namco" / "dataset-2_wave-right-hand_normal_001.bvh"
BEAT = MOCAP / "beat" / "1_wayne_0_1_1.bvh"
CLIP = MOCAP / "gestification" / "clenching.bvh"


def _one_error_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("handsplice: error:")
    return err[0]


def test_analyze_summary_json_eaf_and_csv(tmp_path, capsys):
    from engine.io.eaf import read_csv, read_eaf

    eaf, csv = tmp_path / "wave.eaf", tmp_path / "out" / "wave.csv"
    csv.parent.mkdir()  # an output's folder must exist (a typo is refused, not created)
    assert main(["analyze", str(WAVE), "--eaf", str(eaf), "--csv", str(csv)]) == 0
    text = capsys.readouterr().out
    assert "right phrases: PSR" in text and " RH: " in text
    assert main(["analyze", str(WAVE), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["n_frames"] == 187 and data["fps"] == 30.0 and data["units"] == "cm"
    assert data["phase_codes"] == {
        "rest": 0,
        "preparation": 1,
        "stroke": 2,
        "hold": 3,
        "retraction": 4,
    }
    right = np.array(data["hands"]["right"]["labels"])
    assert len(right) == 187 and set(right) <= {0, 1, 2, 3, 4}
    assert [h["label"] for h in data["handedness"]] == ["RH"]
    assert len(data["hands"]["right"]["key_frames"]) >= 10
    for back in (read_eaf(eaf), read_csv(csv)):
        np.testing.assert_array_equal(back.labels("right", 187), right)
        assert [h[2] for h in back.handedness] == ["RH"]


def test_analyze_thresholds_change_the_result(capsys):
    assert main(["analyze", str(WAVE), "--json", "--threshold", "5"]) == 0
    assert [h["label"] for h in json.loads(capsys.readouterr().out)["handedness"]] == ["2H"]
    assert main(["analyze", str(WAVE), "--json", "--hold-speed", "100"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert set(data["hands"]["right"]["labels"]) <= {0, 3}


@pytest.mark.parametrize(
    "argv, match",
    [
        (["analyze", "missing.bvh"], "missing.bvh"),
        (["analyze", str(MOCAP / "pyomeca" / "markers.trc")], "skeletal take"),
        (["analyze", str(MOCAP / "gestification" / "clenching.bvh")], "right shoulder"),
        (["analyze", str(WAVE), "--hold-speed", "-1"], "--hold-speed: expected a positive"),
        (["synthesize", str(WAVE), "-o", "{tmp}/x.bvh", "--no-graft"], "no finger joints"),
        (["synthesize", str(BEAT), "-o", "{tmp}/x.bvh", "--poses", "claw@3"], "unknown hand pose"),
        (["synthesize", str(BEAT), "-o", "{tmp}/x.bvh", "--poses", "fist@999"], "outside"),
        (
            ["synthesize", str(BEAT), "-o", "{tmp}/x.bvh", "--clip", str(CLIP), "--side", "both"],
            "one hand",
        ),
    ],
)
def test_bad_input_is_one_line_and_exit_2(argv, match, tmp_path, capsys):
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    assert main(argv) == 2
    assert match in _one_error_line(capsys)
    assert not (tmp_path / "x.bvh").exists()


def test_synthesize_poses_and_clip(tmp_path, capsys):
    from engine.gesture.synthesis import extract_flexion, get_pose, hand_rig
    from engine.io.bvh import read_bvh

    out = tmp_path / "hands.bvh"
    assert (
        main(
            [
                "synthesize",
                str(BEAT),
                "-o",
                str(out),
                "--poses",
                "open@0",
                "fist@60",
                "point@-1",
                "--easing",
                "gaussian",
                "--side",
                "left",
            ]
        )
        == 0
    )
    assert "3 key poses (gaussian) on left" in capsys.readouterr().out
    back = read_bvh(out)
    angles = extract_flexion(back, hand_rig(back.skeleton, "left"))
    np.testing.assert_allclose(angles[60], get_pose("fist").angles, atol=1e-4)
    np.testing.assert_allclose(angles[249], get_pose("point").angles, atol=1e-4)
    clip_out = tmp_path / "clip.bvh"
    assert (
        main(["synthesize", str(BEAT), "-o", str(clip_out), "--clip", str(CLIP), "--warp", "0.8"])
        == 0
    )
    assert "on the right hand" in capsys.readouterr().out
    assert read_bvh(clip_out).n_frames == 250


def test_synthesize_grafts_fingers_onto_a_body_without_them(tmp_path, capsys):
    from engine.io.bvh import read_bvh
    from engine.model.roles import find_roles

    out = tmp_path / "grafted.bvh"
    assert main(["synthesize", str(WAVE), "-o", str(out), "--poses", "relaxed@0", "fist@-1"]) == 0
    assert "grafted" in capsys.readouterr().out
    roles = find_roles(read_bvh(out).skeleton)
    assert all(len(roles.side(s).fingers["index"]) == 3 for s in ("right", "left"))
