"""Joint roles: every real capture, other rigs' conventions, overrides and errors."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import mocap_files
from role_expectations import FINGERS, body_rig, expected_roles, rig

from engine.base.errors import ParameterError, RoleError
from engine.io.bvh import read_bvh
from engine.model import rotations as rot
from engine.model.kinematics import forward_kinematics
from engine.model.roles import (
    MARKER_ROLES,
    ROLE_NAMES,
    find_marker_roles,
    find_roles,
    load_role_overrides,
    name_tokens,
    nearest_names,
    side_from_name,
)

BVH_FILES = mocap_files("**/*.bvh")
_CACHE: dict = {}


def _motion(path):
    if path not in _CACHE:
        _CACHE[path] = read_bvh(path)
    return _CACHE[path]


def _arm_names(roles, side):
    d = roles.to_dict()[side]
    return {
        **{k: d[k] for k in ("clavicle", "shoulder", "elbow", "wrist", "hand", "hand_end")},
        "fingers": d["fingers"],
    }


def test_every_capture_is_covered():
    assert len(BVH_FILES) >= 27  # the shared captures are all here
    for path in BVH_FILES:
        expected_roles(path)  # KeyError names a file nobody described


@pytest.mark.parametrize("path", BVH_FILES, ids=lambda p: p.name)
def test_roles_of_real_captures(path):
    motion = _motion(path)
    roles = find_roles(motion.skeleton, side_hint=side_from_name(path))
    for side, expected in expected_roles(path).items():
        assert _arm_names(roles, side) == expected, (path.name, side)


@pytest.mark.parametrize("path", BVH_FILES, ids=lambda p: p.name)
def test_roles_follow_the_hierarchy(path):
    """Shoulder above elbow above wrist; fingers below the wrist, joints 1..3 in order."""
    sk = _motion(path).skeleton
    roles = find_roles(sk, side_hint=side_from_name(path))
    for side in ("right", "left"):
        arm = roles.side(side)
        chain = [j for j in (arm.clavicle, arm.shoulder, arm.elbow, arm.wrist) if j is not None]
        for upper, lower in zip(chain, chain[1:], strict=False):
            assert upper in sk.chain_to_root(lower)[1:], (side, sk.names[upper], sk.names[lower])
        for f in FINGERS:
            joints = arm.fingers[f]
            if joints:
                assert arm.wrist in sk.chain_to_root(joints[0])[1:]
            for a, b in zip(joints, joints[1:], strict=False):
                assert a in sk.chain_to_root(b)[1:]
        if arm.wrist is not None:
            # the wrist is the root of the hand: every finger joint is below it
            below = set(sk.descendants(arm.wrist))
            assert set(j for f in FINGERS for j in arm.fingers[f]) <= below


def test_manipnet_side_comes_from_hint_or_stays_unsided():
    path = next(p for p in BVH_FILES if p.name == "mug1_leftHand.bvh")
    sk = _motion(path).skeleton
    assert side_from_name(path) == "left"
    plain = find_roles(sk)
    assert plain.right.wrist is None and plain.left.wrist is None
    assert plain.unsided is not None and sk.names[plain.unsided.wrist] == "WRIST"
    with pytest.raises(RoleError, match="carry no side.*--side left"):
        plain.require("left", "wrist")
    hinted = find_roles(sk, side_hint="left")
    assert hinted.side_source["left"] == "hint" and hinted.unsided is None
    assert sk.names[hinted.require("left", "index2")] == "INDEX_PIP_FE"


def test_side_hint_does_not_move_sided_joints():
    path = next(p for p in BVH_FILES if p.name.startswith("dataset-2_wave-right"))
    sk = _motion(path).skeleton
    a, b = find_roles(sk), find_roles(sk, side_hint="left")
    assert a.to_dict() == b.to_dict()


# --------------------------------------------------------------------------- other rigs


@pytest.mark.parametrize(
    "style,prefix",
    [
        ("mixamo", "mixamorig:"),
        ("mixamo", ""),
        ("humanik", ""),
        ("biped", ""),
        ("unreal", ""),
        ("rigify", ""),
    ],
)
def test_other_conventions(style, prefix):
    sk = body_rig(style, prefix)
    roles = find_roles(sk)
    n = sk.names
    expect = {
        "mixamo": (
            "{p}RightShoulder",
            "{p}RightArm",
            "{p}RightForeArm",
            "{p}RightHand",
            "{p}RightHandIndex2",
            "{p}RightHandPinky4",
        ),
        "humanik": (
            "RightShoulder",
            "RightArm",
            "RightForeArm",
            "RightHand",
            "RightHandIndex2",
            "RightHandPinky4",
        ),
        "biped": (
            "Bip01 R Clavicle",
            "Bip01 R UpperArm",
            "Bip01 R Forearm",
            "Bip01 R Hand",
            "Bip01 R Finger11",
            "Bip01 R Finger4Nub",
        ),
        "unreal": ("clavicle_r", "upperarm_r", "lowerarm_r", "hand_r", "index_02_r", None),
        "rigify": (
            "DEF-shoulder.R",
            "DEF-upper_arm.R",
            "DEF-forearm.R",
            "DEF-hand.R",
            "DEF-f_index.02.R",
            None,
        ),
    }[style]
    clavicle, shoulder, elbow, wrist, index2, pinky_tip = (
        e.format(p=prefix) if e else None for e in expect
    )
    arm = roles.right
    assert (n[arm.clavicle], n[arm.shoulder], n[arm.elbow], n[arm.wrist]) == (
        clavicle,
        shoulder,
        elbow,
        wrist,
    )
    assert n[roles.require("right", "index2")] == index2
    assert roles.name(arm.tips["pinky"]) == pinky_tip
    assert all(len(arm.fingers[f]) == 3 for f in FINGERS)
    left = roles.left
    assert n[left.wrist] == wrist.replace("Right", "Left").replace(" R ", " L ").replace(
        "_r", "_l"
    ).replace(".R", ".L")
    assert all(len(left.fingers[f]) == 3 for f in FINGERS)


def test_humanik_metacarpals_and_roll_bones():
    sk = body_rig("humanik")
    arm = find_roles(sk).right
    assert sk.names[arm.metacarpals["index"]] == "RightInHandIndex"
    assert arm.metacarpals["thumb"] is None
    assert sk.names[arm.fingers["index"][0]] == "RightHandIndex1"
    roles_joints = {sk.names[j] for j in arm.joints()}
    assert "RightArmRoll" not in roles_joints and "RightForeArmRoll" not in roles_joints


def test_unreal_metacarpal_and_twist():
    sk = body_rig("unreal")
    arm = find_roles(sk).left
    assert sk.names[arm.metacarpals["pinky"]] == "pinky_metacarpal_l"
    assert sk.names[arm.shoulder] == "upperarm_l"  # not upperarm_twist_01_l


@pytest.mark.parametrize(
    "name,tokens",
    [
        ("mixamorig:RightHandIndex1", ["right", "hand", "index", "1"]),
        ("Hand_R", ["hand", "r"]),
        ("lhand", ["l", "hand"]),
        ("rShldr", ["r", "shldr"]),
        ("RFingers", ["r", "fingers"]),
        ("LeftInHandIndex", ["left", "in", "hand", "index"]),
        ("INDEX_PIP_FE", ["index", "pip", "fe"]),
        ("right_index1", ["right", "index", "1"]),
        ("lowerback", ["lowerback"]),
        ("RING_MCP", ["ring", "mcp"]),
        ("DEF-f_index.01.R", ["def", "f", "index", "01", "r"]),
    ],
)
def test_name_tokens(name, tokens):
    assert name_tokens(name) == tokens


def test_side_from_name():
    assert side_from_name("mug1_rightHand.bvh") == "right"
    assert side_from_name("/x/y/mug1_leftHand.bvh") == "left"
    assert side_from_name("fair1_wave_hello.bvh") is None
    assert side_from_name("left_and_right.bvh") is None


# --------------------------------------------------------------------------- chain, landmarks


def test_chain_shoulder_to_fingertips():
    beat = _motion(next(p for p in BVH_FILES if p.parent.name == "beat")).skeleton
    roles = find_roles(beat)
    chain = [beat.names[j] for j in roles.chain("right")]
    assert chain[:3] == ["right_shoulder", "right_elbow", "right_wrist"]
    assert len(chain) == 3 + 15 and set(chain[3:]) == {
        f"right_{f}{k}" for f in FINGERS for k in (1, 2, 3)
    }
    assert [beat.names[j] for j in roles.chain("right", start="clavicle", fingers=False)] == [
        "right_collar",
        "right_shoulder",
        "right_elbow",
        "right_wrist",
    ]
    hik = body_rig("humanik")
    chain = [hik.names[j] for j in find_roles(hik).chain("left", fingers=False)]
    assert chain == ["LeftArm", "LeftForeArm", "LeftHand"]  # roll bones are side branches
    leap = _motion(next(p for p in BVH_FILES if p.name == "hello-world.bvh")).skeleton
    assert [leap.names[j] for j in find_roles(leap).chain("right", fingers=False)] == [
        "rForeArm",
        "rHand",
    ]
    with pytest.raises(RoleError, match="left wrist"):
        find_roles(leap).chain("left")


def _world_point(pos, wrot, landmark):
    return pos[:, landmark.joint] + rot.rotate(wrot[:, landmark.joint], landmark.offset)


def test_hand_landmark_is_the_knuckles_on_beat():
    """BEAT has fingers: the hand point, fixed in the wrist frame, follows middle1."""
    motion = _motion(next(p for p in BVH_FILES if p.parent.name == "beat"))
    roles = find_roles(motion.skeleton)
    pos, wrot = forward_kinematics(motion, 0, 40)
    for side in ("right", "left"):
        lm = roles.landmarks(side)
        assert lm["hand"].source == "finger bases"
        middle1 = roles.require(side, "middle1")
        err = np.linalg.norm(_world_point(pos, wrot, lm["hand"]) - pos[:, middle1], axis=1)
        assert err.max() < 1e-3  # metres; the 6-channel file's translations ~ offsets
        forearm = _world_point(pos, wrot, lm["forearm"])
        elbow, wrist = pos[:, roles.side(side).elbow], pos[:, roles.side(side).wrist]
        assert np.linalg.norm(forearm - (elbow + wrist) / 2, axis=1).max() < 1e-3


def test_landmarks_without_fingers_or_elbow():
    bandai = _motion(next(p for p in BVH_FILES if p.name.startswith("dataset-2_wave-right")))
    lm = find_roles(bandai.skeleton).landmarks("right")
    assert lm["hand"].source.startswith("estimated")
    forearm_len = np.linalg.norm(bandai.skeleton.offsets[bandai.skeleton.index("Hand_R")])
    assert np.linalg.norm(lm["hand"].offset) == pytest.approx(0.4 * forearm_len)
    leap = _motion(next(p for p in BVH_FILES if p.name == "hello-world.bvh"))
    roles = find_roles(leap.skeleton)
    lm = roles.landmarks("right")
    assert lm["forearm"].source.startswith("estimated")
    pos, wrot = forward_kinematics(leap, 0, 30)
    wrist = pos[:, roles.right.wrist]
    to_hand = _world_point(pos, wrot, lm["hand"]) - wrist
    to_forearm = _world_point(pos, wrot, lm["forearm"]) - wrist
    assert (np.einsum("fi,fi->f", to_hand, to_forearm) < 0).all()  # on opposite sides


def test_cmu_hand_is_the_zero_length_palm_joint():
    cmu = _motion(next(p for p in BVH_FILES if p.name.startswith("cmu1_"))).skeleton
    roles = find_roles(cmu)
    assert cmu.names[roles.right.wrist] == "RightWrist"
    assert cmu.names[roles.right.hand] == "rhand"
    assert roles.landmarks("right")["hand"].source == "hand_end joint"


# --------------------------------------------------------------------------- overrides, errors


def test_overrides_flat_nested_and_null():
    bandai = _motion(next(p for p in BVH_FILES if p.name.startswith("dataset-2_wave-right")))
    sk = bandai.skeleton
    roles = find_roles(
        sk, overrides={"right.wrist": "LowerArm_R", "left.clavicle": None, "right.index1": "Hand_R"}
    )
    assert sk.names[roles.right.wrist] == "LowerArm_R" and roles.right.hand == roles.right.wrist
    assert roles.left.clavicle is None and sk.names[roles.left.shoulder] == "UpperArm_L"
    assert roles.get("right", "index1") == sk.index("Hand_R")
    assert roles.side_source == {"right": "override", "left": "override"}
    nested = find_roles(sk, overrides={"right": {"wrist": "LowerArm_R"}})
    assert nested.right.wrist == roles.right.wrist
    # Biped-style override onto a rig whose names the matcher cannot read
    odd = rig([("root", None), ("a", "root"), ("b", "a"), ("c", "b")])
    assert find_roles(odd).right.wrist is None
    mapped = find_roles(
        odd, overrides={"right.shoulder": "a", "right.elbow": "b", "right.wrist": "c"}
    )
    assert mapped.chain("right") == [1, 2, 3]


def test_override_errors():
    sk = body_rig("mixamo")
    with pytest.raises(ParameterError, match="right.wirst.*right.wrist"):
        find_roles(sk, overrides={"right.wirst": "RightHand"})
    with pytest.raises(ParameterError, match="'middle.wrist'"):
        find_roles(sk, overrides={"middle.wrist": "RightHand"})
    with pytest.raises(ParameterError, match="expected a joint name or null"):
        find_roles(sk, overrides={"right.wrist": 3})
    with pytest.raises(RoleError, match="no joint named 'RightHnad'.*RightHand"):
        find_roles(sk, overrides={"right.wrist": "RightHnad"})


def test_load_role_overrides(tmp_path):
    good = tmp_path / "map.json"
    good.write_text(json.dumps({"right.wrist": "Bip01_R_Hand", "left": {"index1": None}}))
    assert load_role_overrides(good) == {"right.wrist": "Bip01_R_Hand", "left.index1": None}
    bad = tmp_path / "bad.json"
    bad.write_text('{\n  "right.wrist": "X",\n  oops\n}')
    with pytest.raises(ParameterError, match=r"bad\.json: line 3, column \d+: not valid JSON"):
        load_role_overrides(bad)
    listed = tmp_path / "list.json"
    listed.write_text("[1, 2]")
    with pytest.raises(ParameterError, match=r"list\.json: expected an object"):
        load_role_overrides(listed)
    with pytest.raises(FileNotFoundError):
        load_role_overrides(tmp_path / "missing.json")


def test_missing_role_lists_nearest_names():
    bandai = _motion(next(p for p in BVH_FILES if p.name.startswith("dataset-2_wave-right")))
    roles = find_roles(bandai.skeleton)
    with pytest.raises(RoleError) as err:
        roles.require("right", "index1")
    msg = str(err.value)
    assert msg.startswith("right index1: no joint found among 22 joints (nearest names: ")
    assert "Hand_R" in msg and '"right.index1": "NAME"' in msg and "\n" not in msg
    odd = rig([("root", None), ("Bras_D", "root"), ("Coude_D", "Bras_D"), ("Poignet_D", "Coude_D")])
    with pytest.raises(RoleError, match="right wrist: no joint found"):
        find_roles(odd).require("right", "wrist")
    assert nearest_names(["RightHand", "Hips", "LeftHand"], "right", "wrist")[0] == "RightHand"


def test_role_names_and_lookup():
    sk = body_rig("mixamo")
    arm = find_roles(sk).right
    flat = arm.flat()
    assert set(flat) == set(ROLE_NAMES)
    assert sk.names[flat["thumb3"]] == "RightHandThumb3" and flat["index_metacarpal"] is None
    with pytest.raises(ParameterError, match="unknown role 'wirst'.*wrist"):
        arm.get("wirst")
    with pytest.raises(ParameterError, match="side must be"):
        find_roles(sk).side("middle")


def test_to_dict_is_json_ready():
    roles = find_roles(body_rig("humanik"))
    names = json.loads(json.dumps(roles.to_dict()))
    assert names["right"]["wrist"] == "RightHand"
    assert names["left"]["metacarpals"]["index"] == "LeftInHandIndex"
    idx = json.loads(json.dumps(roles.to_dict(indices=True)))
    assert idx["right"]["wrist"] == roles.right.wrist
    assert idx["right"]["fingers"]["index"] == roles.right.fingers["index"]


# --------------------------------------------------------------------------- marker sets


def test_marker_roles_plug_in_gait_and_pyomeca():
    pig = [
        "C7",
        "RSHO",
        "RUPA",
        "RELB",
        "RFRA",
        "RWRA",
        "RWRB",
        "RFIN",
        "LSHO",
        "LELB",
        "LWRA",
        "LWRB",
        "LFIN",
        "Sub:RKNE",
    ]
    roles = find_marker_roles(pig)
    assert {r: pig[i] for r, i in roles.right.items()} == {
        "shoulder": "RSHO",
        "elbow": "RELB",
        "forearm": "RFRA",
        "wrist_radial": "RWRA",
        "wrist_ulnar": "RWRB",
        "hand": "RFIN",
    }
    assert roles.left["forearm"] is None and pig[roles.require("left", "wrist_ulnar")] == "LWRB"
    with pytest.raises(RoleError, match="left forearm: no marker found"):
        roles.require("left", "forearm")
    pyomeca = [
        "Daphnee:EPICm",
        "Daphnee:EPICl",
        "Daphnee:STYLr",
        "Daphnee:STYLu",
        "Daphnee:MEDH",
        "Daphnee:LATH",
        "Daphnee:LARMm",
        "Daphnee:LARMl",
        "Daphnee:ACRO_tip",
    ]
    plain = find_marker_roles(pyomeca)
    assert plain.right == dict.fromkeys(MARKER_ROLES) and plain.unsided is not None
    with pytest.raises(RoleError, match="carry no side.*--side right"):
        plain.require("right", "hand")
    hinted = find_marker_roles(pyomeca, side_hint="right")
    assert {r: pyomeca[i] for r, i in hinted.right.items()} == {
        "shoulder": "Daphnee:ACRO_tip",
        "elbow": "Daphnee:EPICl",
        "forearm": "Daphnee:LARMl",
        "wrist_radial": "Daphnee:STYLr",
        "wrist_ulnar": "Daphnee:STYLu",
        "hand": "Daphnee:LATH",
    }  # lateral epicondyle and 2nd metacarpal win
    assert json.loads(json.dumps(hinted.to_dict()))["side_source"]["right"] == "hint"
    suffixed = find_marker_roles(["RS_R", "US_R", "LE_L"])
    assert suffixed.right["wrist_radial"] == 0 and suffixed.left["elbow"] == 2
