"""Hand takes from any rig (issue 12 item 4): every finger joint carried, the side from the
hand's geometry, no End Site stub under grafted fingers. Real captures: ManipNet's hands
(a 4-joint thumb with ``THUMB_CMC_AA``; exported in Unity's left-handed axes, so
``mug1_rightHand.bvh`` reads as a left hand in BVH's right-handed axes), BEAT, LAFAN1."""

from __future__ import annotations

import shutil
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest
from conftest import MOCAP

from benchmarks.split import strip_fingers
from engine.base.errors import RoleError
from engine.io.bvh import format_bvh, read_bvh, write_bvh
from engine.model import rotations as rot
from engine.model.fastkin import forward_kinematics
from engine.model.hand_side import geometric_side, mirror_take
from engine.model.kinematics import sample
from engine.model.roles import find_roles
from engine.splice import pipeline as P
from engine.splice import transfer as TR

MANIPNET = {
    "right": MOCAP / "manipnet" / "mug1_rightHand.bvh",
    "left": MOCAP / "manipnet" / "mug1_leftHand.bvh",
}


@pytest.fixture(scope="module")
def beat():
    return read_bvh(MOCAP / "beat" / "1_wayne_0_1_1.bvh")


def _manipnet(side: str, frames: int = 600):
    return read_bvh(MANIPNET[side]).frames(0, frames)


def _directions(pos, g, joint, basis, a, b):
    """Unit directions a -> b per frame in the anatomical frame of ``joint`` (F, 3)."""
    d = rot.rotate(rot.conjugate(g[:, joint]), pos[:, b] - pos[:, a]) @ basis
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def _thumb_errors(body, hand, side):
    """Worst angle (deg) between the spliced thumb's chords / bones and the hand take's, in
    each hand's anatomical frame, with a uniform time map; also returns the plan."""
    feats = P.prepare(body, hand, side=side)
    plan = P.plan_for(feats)
    h = feats.hand  # mirrored when the take was written in left-handed axes
    t = np.linspace(0.0, h.n_frames - 1, body.n_frames)
    out = TR.apply_transfer(plan, body, h, t, feats.body_fk)
    local, trans = sample(h, t)
    ph, gh = forward_kinematics(replace(h, rotations=local, translations=trans))
    po, go = forward_kinematics(out)
    sp = plan.sides[0]
    fb, fh = sp.body_frame, sp.hand_frame
    thumb = [
        fm
        for fm in sp.mapped
        if fm.hand
        in feats.hand.skeleton.descendants(feats.hand_roles.side(side).fingers["thumb"][0])
    ]
    errors = []
    # every driven thumb joint to the next: the hand's own bones (CMC_FE -> CMC_AA ...)
    for f0, f1 in zip(thumb, thumb[1:]):
        do = _directions(po, go, plan.out(fb.hand_joint), fb.basis, f0.body, f1.body)
        dh = _directions(ph, gh, fh.hand_joint, fh.basis, f0.hand, f1.hand)
        errors.append(np.degrees(np.arccos(np.clip(np.sum(do * dh, -1), -1, 1))).max())
    # and the chords between role joints (thumb1 -> thumb2 spans the inserted CMC_AA)
    ro, rh = find_roles(out.skeleton), feats.hand_roles
    jo, jh = ro.side(side).fingers["thumb"], rh.side(side).fingers["thumb"]
    for (a, b), (c, d) in zip(zip(jo, jo[1:]), zip(jh, jh[1:]), strict=True):
        do = _directions(po, go, plan.out(fb.hand_joint), fb.basis, a, b)
        dh = _directions(ph, gh, fh.hand_joint, fh.basis, c, d)
        errors.append(np.degrees(np.arccos(np.clip(np.sum(do * dh, -1), -1, 1))).max())
    return errors, plan, out


@pytest.mark.parametrize("side", ["right", "left"])
def test_manipnet_thumb_follows_its_source_on_a_body_with_fingers(beat, side):
    errors, plan, out = _thumb_errors(beat, _manipnet(side), side)
    assert len(errors) == 3 + 2  # CMC_FE, CMC_AA, MCP, IP bones; thumb1->2, thumb2->3 chords
    assert max(errors) < 1.0, errors
    inserted = [out.skeleton.names[j] for j in plan.sides[0].inserted]
    assert inserted == [f"{side}_thumb2_THUMB_CMC_AA"]
    # the body's own joints are all still there, the inserted one sits on the thumb
    names = out.skeleton.names
    assert set(beat.skeleton.names) <= set(names)
    k = names.index(inserted[0])
    assert names[out.skeleton.parents[k]] == f"{side}_thumb1"
    assert out.skeleton.parents[names.index(f"{side}_thumb2")] == k


def test_manipnet_thumb_follows_its_source_when_grafted(beat):
    body = strip_fingers(beat)
    errors, plan, _ = _thumb_errors(body, _manipnet("right"), "right")
    assert max(errors) < 1.0, errors
    assert len(plan.sides[0].grafted) == 16  # every ManipNet finger joint, CMC_AA included


def _arm_side(motion, side):
    return geometric_side(motion, find_roles(motion.skeleton).side(side)).side


@pytest.mark.parametrize("side", ["right", "left"])
def test_side_from_geometry_on_renamed_files(tmp_path, beat, side):
    """ManipNet's files renamed hand.bvh: no side in names or file name; the geometry
    tells (the Unity export makes mug1_rightHand a left hand in BVH axes), and the mirror
    image of each file is the other hand. The spliced hand has the side it is put on."""
    path = tmp_path / "hand.bvh"
    shutil.copyfile(MANIPNET[side], path)
    hand = read_bvh(path).frames(0, 600)
    body = strip_fingers(beat)  # grafted fingers: the output hand is the hand take's
    for take in (hand, mirror_take(hand)):
        arm = find_roles(take.skeleton).unsided
        assert arm is not None and arm.has_fingers  # no side from names or file name
        seen = geometric_side(take, arm).side
        assert seen in ("right", "left")
        res = P.splice(body, take)
        assert res.features.sides == (seen,)
        assert res.features.hand_roles.side_source[seen] == "geometry"
        assert _arm_side(res.motion, seen) == seen
    assert geometric_side(hand, find_roles(hand.skeleton).unsided).side != side
    assert geometric_side(mirror_take(hand), find_roles(hand.skeleton).unsided).side == side


@pytest.mark.parametrize("side", ["right", "left"])
def test_named_left_handed_axes_take_is_mirrored_onto_its_side(beat, side):
    res = P.splice(strip_fingers(beat), _manipnet(side))
    assert res.features.sides == (side,)
    assert any("mirrored" in n for n in P.plan_for(res.features).notes)
    assert _arm_side(res.motion, side) == side


def test_geometry_of_two_handed_takes_matches_their_names(beat):
    roles = find_roles(beat.skeleton)
    for side in ("right", "left"):
        assert geometric_side(beat, roles.side(side)).side == side
        assert geometric_side(mirror_take(beat), roles.side(side)).side != side
    for path in sorted((MOCAP / "gestification").glob("*.bvh")):
        take = read_bvh(path)
        assert geometric_side(take, find_roles(take.skeleton).right).side == "right", path.name


def _flat_hand(tmp_path):
    """A ManipNet skeleton squashed into one plane, at rest: no geometry tells its side."""
    hand = read_bvh(MANIPNET["right"])
    sk = hand.skeleton
    flat = replace(
        sk,
        offsets=sk.offsets * [1.0, 1.0, 0.0],
        end_sites={j: v * [1.0, 1.0, 0.0] for j, v in sk.end_sites.items()},
    )
    take = replace(
        hand.frames(0, 90),
        skeleton=flat,
        rotations=rot.identity((90, sk.n_joints)),
        translations=np.broadcast_to(flat.offsets, (90, sk.n_joints, 3)).copy(),
    )
    path = tmp_path / "hand.bvh"
    path.write_text(format_bvh(take))
    return path


def test_undecided_side_is_a_clear_error_naming_side(tmp_path, beat):
    path = _flat_hand(tmp_path)
    hand = read_bvh(path)
    with pytest.raises(RoleError, match=r"cannot tell which hand.*--side"):
        P.splice(beat, hand)
    body = tmp_path / "body.bvh"
    write_bvh(beat.frames(0, 90), body)
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "engine.cli",
            "splice",
            str(body),
            str(path),
            "-o",
            str(tmp_path / "out.bvh"),
        ],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 2, proc.stderr
    assert "--side" in proc.stderr and "Traceback" not in proc.stderr
    errors = [line for line in proc.stderr.splitlines() if "error" in line]
    assert len(errors) == 1 and "cannot tell which hand" in errors[0]
    res = P.splice(beat.frames(0, 90), hand, side="left")  # --side gives it
    assert res.features.sides == ("left",)


def test_wrist_keeps_no_end_site_stub_once_fingers_are_grafted(tmp_path):
    """LAFAN1's RightHand ends in a zero-length End Site; with fingers grafted under it
    the written BVH has none there (Blender would draw a stub bone)."""
    body = read_bvh(MOCAP / "lafan1" / "dance1_subject1.bvh").frames(300, 420)
    assert np.linalg.norm(body.skeleton.end_sites[body.skeleton.index("RightHand")]) == 0
    res = P.splice(body, _manipnet("right", 500), side="right")
    path = tmp_path / "out.bvh"
    write_bvh(res.motion, path)
    text = path.read_text().splitlines()
    start = next(i for i, line in enumerate(text) if line.strip() == "JOINT RightHand")
    depth, block = 0, []
    for line in text[start + 1 :]:  # RightHand's own lines, children's blocks skipped
        s = line.strip()
        if s == "{":
            depth += 1
        elif s == "}":
            depth -= 1
            if depth == 0:
                break
        elif depth == 1:
            block.append(s)
    assert "End Site" not in block and any(s.startswith("JOINT RightHand_") for s in block)
    back = read_bvh(path)
    assert back.skeleton.index("RightHand") not in back.skeleton.end_sites
    # every finger tip keeps its End Site; the left wrist (nothing grafted) keeps its own
    assert back.skeleton.index("LeftHand") in back.skeleton.end_sites


def test_a_manipnet_rig_pair_is_timed_within_a_body_frame():
    """The bench's ManipNet family, one case: a wrist-rooted hand take (no forearm) whose
    names and file name carry no side. Its side comes from geometry; pass 2 compares the
    hand's turning (no forearm to compare the hand against), within a body frame (median)."""
    from benchmarks.split_rigs import make_rig_case

    case = make_rig_case("manipnet", 0)
    assert case.hand.skeleton.names[:3] == ("WRIST", "THUMB_CMC_FE", "THUMB_CMC_AA")
    res = P.splice(case.body, case.hand)
    f = res.features
    assert f.sides == (case.params["side"],)
    assert f.hand_roles.side_source[case.params["side"]] == "geometry"
    assert P.hand_lacks_forearm(f) and P.uses_spin(f)
    err_ms = np.abs(res.alignment.map - case.truth) / case.hand.fps * 1000.0
    assert np.median(err_ms) <= 1000.0 / case.body.fps
    # every ManipNet finger joint is grafted and the thumb keeps its 4 joints
    names = res.motion.skeleton.names
    assert sum("THUMB_CMC_AA" in n for n in names) == 1


def test_geometric_side_ignores_units_and_orientation():
    """The same hand in centimetres instead of metres, turned 120 deg about a tilted axis
    (another up axis, another facing): the same side."""
    hand = mirror_take(_manipnet("right", 300))  # back to right-handed axes: a right hand
    arm = find_roles(hand.skeleton, side_hint="right").right
    assert geometric_side(hand, arm).side == "right"
    turn = rot.from_axis_angle(
        np.array([0.3, 0.5, 0.8]) / np.linalg.norm([0.3, 0.5, 0.8]), np.radians(120.0)
    )
    rots, trans = hand.rotations.copy(), hand.translations * 100.0
    root = 0
    rots[:, root] = rot.multiply(turn, rots[:, root])
    trans[:, root] = rot.rotate(turn, trans[:, root])
    sk = hand.skeleton
    moved = replace(
        hand,
        rotations=rots,
        translations=trans,
        skeleton=replace(
            sk,
            offsets=sk.offsets * 100.0,
            end_sites={j: v * 100.0 for j, v in sk.end_sites.items()},
        ),
    )
    assert geometric_side(moved, arm).side == "right"
    assert geometric_side(mirror_take(moved, axis=2), arm).side == "left"
