"""The two-pass splice end to end: alignment accuracy on a split BEAT take, merge, transfer."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import MOCAP

from benchmarks.split import finger_error, finger_pairs, make_case
from engine.base.errors import ParameterError, RoleError
from engine.io.bvh import read_bvh, write_bvh
from engine.model import rotations as rot
from engine.model.roles import find_roles
from engine.splice import merge as MG
from engine.splice import pipeline as P
from engine.splice.report import build_report, dumps


@pytest.fixture(scope="module")
def beat_case():
    return make_case("beat", 0)


@pytest.fixture(scope="module")
def beat_result(beat_case):
    return P.splice(beat_case.body, beat_case.hand)


# ------------------------------------------------------------------------------------ merge


def test_median_warp_of_a_hand_built_path():
    path = np.array([[0, 0], [0, 1], [0, 2], [1, 3], [2, 3], [3, 4], [3, 5], [3, 6], [3, 7]])
    assert MG.median_warp(path, 4).tolist() == [1.0, 3.0, 3.0, 5.5]
    with pytest.raises(ParameterError, match="skips body frame 1"):
        MG.median_warp(np.array([[0, 0], [2, 1]]), 3)


def test_smoothing_blends_jumps_and_stays_monotone():
    w = np.repeat(np.arange(0, 40, 4.0), 4)  # stalls then jumps of 4 frames
    s = MG.smooth_warp(w, 3.0, m=40)
    assert np.all(np.diff(s) >= 0)
    assert np.abs(np.diff(s)).max() < 2.0  # no visible pop
    assert s[0] >= 0 and s[-1] <= 39
    assert np.array_equal(MG.smooth_warp(w, 0.0), w)


def test_grid_and_hand_frames_round_trip():
    g = np.array([0.0, 10.0, 29.0])
    h = MG.grid_to_hand_frames(g, 30.0, 120.0, 1000)
    assert h.tolist() == [0.0, 40.0, 116.0]
    assert np.allclose(MG.hand_frames_to_grid(h, 30.0, 120.0), g)


# ------------------------------------------------------------------------------ accuracy


def test_beat_split_pair_is_timed_within_a_body_frame(beat_case, beat_result):
    err_ms = np.abs(beat_result.alignment.map - beat_case.truth) / beat_case.hand.fps * 1000
    assert np.median(err_ms) <= 1000 / 30  # one body frame
    assert np.percentile(err_ms, 95) < 100
    pairs = finger_pairs(beat_result.motion, beat_case.reference)
    assert len(pairs) == 30
    got = finger_error(beat_result.motion, beat_case.reference, pairs)
    from engine.splice import transfer as TR

    oracle = TR.apply_transfer(
        P.plan_for(beat_result.features),
        beat_case.body,
        beat_case.hand,
        beat_case.truth,
        beat_result.features.body_fk,
    )
    assert got - finger_error(oracle, beat_case.reference, pairs) < 1.0


def test_pass2_refines_pass1(beat_case, beat_result):
    f, a = beat_result.features, beat_result.alignment
    p1 = f.grid_to_hand(MG.merge_path(a.pass1.path, f.n, f.m, a.blend))
    e1 = np.mean(np.abs(p1 - beat_case.truth))
    e2 = np.mean(np.abs(a.map - beat_case.truth))
    assert e2 < e1
    # pass 2 stays inside its band around the pass-1 path
    assert np.all(a.pass2.band.contains(a.pass2.path[:, 0], a.pass2.path[:, 1]))
    assert a.pass2.band.area < a.pass1.band.area


def test_self_splice_is_the_identity():
    beat = read_bvh(MOCAP / "beat/1_wayne_0_1_1.bvh")
    res = P.splice(beat, beat)
    assert np.abs(res.alignment.map - np.arange(beat.n_frames)).max() < 1.0
    plan = P.plan_for(res.features)
    for sp in plan.sides:  # same rig: rotations are copied, not converted
        assert rot.angle_between(sp.u_hand, rot.identity()) < 1e-6
        assert not sp.grafted and len(sp.mapped) == 15
    assert res.motion.skeleton.names == beat.skeleton.names


# ------------------------------------------------------------------------------ the output


def test_output_reads_back_with_fingers_and_an_unchanged_body(tmp_path, beat_case, beat_result):
    out = tmp_path / "spliced.bvh"
    write_bvh(beat_result.motion, out)
    back = read_bvh(out)
    assert back.n_frames == beat_case.body.n_frames and back.fps == beat_case.body.fps
    roles = find_roles(back.skeleton)
    for side in ("right", "left"):
        arm = roles.side(side)
        assert all(len(arm.fingers[f]) == 3 for f in arm.fingers)
    body = beat_case.body
    broles = find_roles(body.skeleton)
    wrists = {broles.side(s).wrist for s in ("right", "left")}
    for j, name in enumerate(body.skeleton.names):
        if j in wrists:
            continue
        k = back.skeleton.index(name)
        assert np.allclose(back.skeleton.offsets[k], body.skeleton.offsets[j], atol=1e-9)
        assert rot.angle_between(back.rotations[:, k], body.rotations[:, j]).max() < 1e-4, name


def test_graft_onto_a_fingerless_body_scales_to_its_hand():
    body = read_bvh(MOCAP / "bandai-namco/dataset-2_wave-right-hand_normal_001.bvh")
    hand = read_bvh(MOCAP / "gestification/gesture-pointing.bvh")  # mm, Leap rig
    res = P.splice(body, hand)
    assert res.features.sides == ("right",)
    sk = res.motion.skeleton
    plan = P.plan_for(res.features)
    (sp,) = plan.sides
    # Leap takes carry no forearm measurement (rForeArm sits on the wrist): the body keeps
    # its own wrist rotation and gets the fingers
    assert len(sp.grafted) == 15 and not sp.wrist
    w = body.skeleton.index("Hand_R")
    assert np.allclose(res.motion.rotations[:, sk.index("Hand_R")], body.rotations[:, w])
    roles = find_roles(sk)
    idx1 = roles.get("right", "index1")
    idx2 = roles.get("right", "index2")
    assert sk.parents[idx1] == roles.get("right", "wrist")
    # an index phalanx a few centimetres long in the body's units (cm)
    assert 1.0 < np.linalg.norm(sk.offsets[idx2]) < 6.0
    assert np.allclose(np.linalg.norm(res.motion.rotations, axis=-1), 1.0)
    # the left arm is untouched
    for name in ("LowerArm_L", "Hand_L"):
        j = body.skeleton.index(name)
        assert np.allclose(res.motion.rotations[:, sk.index(name)], body.rotations[:, j])


def test_wrist_rooted_hand_take_keeps_the_body_wrist():
    body = read_bvh(MOCAP / "bandai-namco/dataset-1_call_normal_001.bvh")
    hand = read_bvh(MOCAP / "manipnet/mug1_leftHand.bvh").frames(0, 600)
    res = P.splice(body, hand)
    assert res.features.sides == ("left",)
    (sp,) = P.plan_for(res.features).sides
    assert not sp.wrist
    w = body.skeleton.index("Hand_L")
    assert np.allclose(res.motion.rotations[:, w], body.rotations[:, w])
    # the joint inserted in the body's thumb (ManipNet's THUMB_CMC_AA) is in the thumb's
    # chain that ``handsplice info`` lists (stranger 7: it was carried but not listed)
    from engine.cli.info import describe_motion, format_text

    report = describe_motion(res.motion, "spliced.bvh")
    thumb = report["finger_chains"]["left"]["thumb"]
    inserted = [n for n in thumb if n.endswith("THUMB_CMC_AA")]
    assert len(inserted) == 1 and 0 < thumb.index(inserted[0]) < len(thumb) - 1, thumb
    assert f"thumb[{' '.join(thumb)}]" in " ".join(format_text(report).split())


# ------------------------------------------------------------------------ points and errors


def test_a_matching_point_with_zero_tolerance_is_on_the_path(beat_case):
    feats = P.prepare(beat_case.body, beat_case.hand)
    res = P.align_passes(feats, points=[(100, 60, 0)])
    for p in (res.pass1.path, res.pass2.path):
        cols = p[p[:, 0] == 100, 1]
        assert 60 in cols and cols.min() >= 60 - 1e-9
    # the paper's guarantee: the path crosses row 100 only at column 60
    assert (
        set(res.pass2.path[res.pass2.path[:, 0] == 100, 1]) == {60}
        or res.pass2.path[res.pass2.path[:, 0] == 100, 1].min() == 60
    )
    with pytest.raises(
        ParameterError,
        match=r"^matching point 2 \(body 90, hand 70\): body frame 90 is not after matching "
        r"point 1's body frame 100; body frames must increase",
    ):
        P.align_passes(feats, points=[(100, 60, 0), (90, 70, 0)])


def test_hand_points_are_converted_from_hand_frames(beat_case):
    res = P.splice(
        beat_case.body,
        beat_case.hand,
        points=[(100, 240, 4)],
        hand_points=True,
        transfer_fingers=False,
    )
    x, y, t = res.alignment.points[0]
    grid = 240 * 30.0 / beat_case.hand.fps
    assert x == 100 and y == round(grid) and t >= 4 * 30.0 / beat_case.hand.fps


def test_incremental_re_solve_matches_a_fresh_one(beat_case):
    feats = P.prepare(beat_case.body, beat_case.hand)
    first = P.align_passes(feats, incremental=True)
    moved = P.align_passes(feats, points=[(120, 100, 3)], previous=first, incremental=True)
    fresh = P.align_passes(feats, points=[(120, 100, 3)], incremental=False)
    assert moved.pass1.cost == pytest.approx(fresh.pass1.cost)
    assert moved.pass2.cost == pytest.approx(fresh.pass2.cost)
    assert moved.pass1.solver is first.pass1.solver  # reused, not rebuilt


def test_cost_images_and_local_costs(beat_case):
    feats = P.prepare(beat_case.body, beat_case.hand)
    res = P.align_passes(feats, incremental=True)
    rows, cols = np.arange(0, feats.n, 7), np.arange(0, feats.m, 5)
    for kind in ("pass1", "pass2", "cumulative1", "cumulative2"):
        img = P.cost_image(feats, kind, rows, cols, res)
        assert img.shape == (rows.size, cols.size)
    img = P.cost_image(feats, "pass2", rows, cols, res)
    dense = res.pass2.local_costs(rows, cols)
    assert np.allclose(img, dense)
    cum = P.cost_image(feats, "cumulative2", rows, cols, res)
    inside = res.pass2.band.contains(rows[:, None], cols[None, :])
    assert np.all(np.isnan(cum[~inside])) and np.all(np.isfinite(cum[inside]))
    # the path's local costs plus the open ends' skip cost add up to the pass cost
    skipped = P.unmatched_frames(res.pass1.path, feats.n, feats.m) * res.pass1.ends.skip
    assert res.pass1.path_costs().sum() + skipped == pytest.approx(res.pass1.cost)
    s1, s2 = P.wrist_speeds(feats)
    assert s1.shape == (feats.n,) and s2.shape == (feats.m,)


def test_pairs_that_cannot_work_are_clear_errors():
    body = read_bvh(MOCAP / "bandai-namco/dataset-1_bye_normal_001.bvh")
    lafan = read_bvh(MOCAP / "lafan1/dance1_subject1.bvh").frames(0, 100)
    with pytest.raises(RoleError, match="no finger joints"):
        P.prepare(body, lafan)
    leap = read_bvh(MOCAP / "gestification/hello-world.bvh")
    with pytest.raises(RoleError, match="no left hand"):
        P.prepare(body, leap, side="left")
    with pytest.raises(ParameterError, match="side"):
        P.prepare(body, leap, side="middle")


def test_report_has_the_map_both_passes_and_timings(beat_case, beat_result):
    rep = json.loads(dumps(build_report(beat_result, output_path="x.bvh")))
    assert len(rep["map"]) == beat_case.body.n_frames
    for key in ("pass1", "pass2"):
        # open ends (the default): the path starts on the first body or hand frame
        assert 0 in rep[key]["path"][0] and rep[key]["cost"] >= 0
        assert len(rep[key]["band"]["lo"]) == beat_case.body.n_frames
    p2 = rep["pass2"]["path"]
    assert rep["overlap"]["body"] == [p2[0][0], p2[-1][0]]
    assert 0 <= rep["overlap"]["hand"][0] <= rep["overlap"]["hand"][1] < beat_case.hand.n_frames
    assert rep["parameters"]["ends"] == "open"
    first, last = rep["overlap"]["body"]
    assert rep["unmatched_body"] == ([[0, first - 1]] if first > 0 else []) + (
        [[last + 1, beat_case.body.n_frames - 1]] if last < beat_case.body.n_frames - 1 else []
    )
    assert rep["parameters"]["band"] == 0.3 and rep["parameters"]["refine_band"] == 0.1
    assert {"prepare", "pass1", "pass2", "merge", "transfer", "total"} <= set(rep["timings_s"])
    assert rep["sides"] == ["right", "left"]
    assert rep["transfer"]["sides"]["right"]["grafted"]


def test_partial_hand_takes_rooted_at_the_shoulder_or_forearm(beat_case):
    from benchmarks.split import subset

    hand = beat_case.hand
    sk = hand.skeleton
    for root in ("right_collar", "right_elbow"):
        keep = np.zeros(sk.n_joints, dtype=bool)
        keep[sk.descendants(sk.index(root))] = True
        part = subset(hand, keep)
        res = P.splice(beat_case.body, part, side="right")
        assert res.features.sides == ("right",)
        err_ms = np.abs(res.alignment.map - beat_case.truth) / hand.fps * 1000
        assert np.median(err_ms) < 100  # one arm, no trunk: still on time
        (sp,) = P.plan_for(res.features).sides
        assert sp.wrist and len(sp.grafted) == 15


def test_trunk_theta_and_marker_set_alignment(beat_case):
    res = P.splice(beat_case.body, beat_case.hand, theta="trunk", transfer_fingers=False)
    err_ms = np.abs(res.alignment.map - beat_case.truth) / beat_case.hand.fps * 1000
    assert np.median(err_ms) <= 1000 / 30
    from engine.io import load_take

    markers = load_take(MOCAP / "pyomeca/markers_analogs.c3d")
    body = read_bvh(MOCAP / "bandai-namco/dataset-1_bye_normal_001.bvh")
    feats = P.prepare(body, markers, side="right")  # alignment works on marker takes
    res = P.align_passes(feats)
    assert res.map.shape == (body.n_frames,)
    with pytest.raises(Exception, match="marker take"):
        P.transfer(feats, res)
