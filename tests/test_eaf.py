"""ELAN and CSV export/import of gesture phases and handedness."""

from __future__ import annotations

import numpy as np
import pytest
from gesture_traj import REST, build, phrase_psh_r

from engine.base.errors import MotionFormatError, ParameterError
from engine.gesture.handedness import detect_handedness
from engine.gesture.phases import GesturePhases, Phase, PhaseSegment, segment_trajectory
from engine.io.eaf import (
    GestureAnnotations,
    phase_boundaries,
    phase_constraints,
    read_csv,
    read_eaf,
    write_csv,
    write_eaf,
)


@pytest.fixture(scope="module", params=[30.0, 120.0, 29.97])
def analysed(request):
    fps = request.param
    right, _ = build(phrase_psh_r() + phrase_psh_r()[1:], fps)
    left = np.repeat(REST[None], len(right), axis=0)
    left[len(right) // 2 :] = right[len(right) // 2 :] * np.array([-1.0, 1.0, 1.0])
    phases = GesturePhases(
        hands={"right": segment_trajectory(right, fps), "left": segment_trajectory(left, fps)},
        fps=fps,
        n_frames=len(right),
    )
    return phases, detect_handedness(phases)


def _check_round_trip(back: GestureAnnotations, phases: GesturePhases, hands) -> None:
    assert back.fps == pytest.approx(phases.fps, rel=1e-5)
    for side in ("right", "left"):
        np.testing.assert_array_equal(back.labels(side, phases.n_frames), phases.labels(side))
        want = [s for s in phases.hands[side].segments if s.phase != Phase.REST]
        assert list(back.phases[side]) == want
    assert [h[2] for h in back.handedness] == [h.label for h in hands]
    assert [(h[0], h[1]) for h in back.handedness] == [(h.start, h.stop) for h in hands]


def test_eaf_opens_in_pympi_and_round_trips(analysed, tmp_path):
    from pympi.Elan import Eaf

    phases, hands = analysed
    assert [h.label for h in hands] == ["RH", "2H"]
    path = tmp_path / "take.eaf"
    write_eaf(path, phases, hands, source="take.bvh")
    eaf = Eaf(str(path))
    assert {"Phase RH", "Phase LH", "Handedness"} <= set(eaf.get_tier_names())
    values = {a[2] for a in eaf.get_annotation_data_for_tier("Phase RH")}
    assert values == {"preparation", "stroke", "hold", "retraction"}
    assert dict(eaf.get_properties())["source"] == "take.bvh"
    back = read_eaf(path)
    _check_round_trip(back, phases, hands)
    assert back.n_frames == phases.n_frames and back.source == "take.bvh"
    # a file saved again by pympi (as ELAN would) still reads back the same
    from pympi.Elan import to_eaf

    to_eaf(str(tmp_path / "again.eaf"), eaf)
    _check_round_trip(read_eaf(tmp_path / "again.eaf"), phases, hands)


def test_csv_round_trips(analysed, tmp_path):
    phases, hands = analysed
    path = tmp_path / "take.csv"
    write_csv(path, phases, hands)
    lines = path.read_text().splitlines()
    assert lines[0] == "tier,start_frame,stop_frame,start_s,stop_s,value"
    _check_round_trip(read_csv(path), phases, hands)


def test_human_corrections_are_read(tmp_path):
    from pympi.Elan import Eaf, to_eaf

    eaf = Eaf(author="coder")
    eaf.add_tier("Phase RH")
    eaf.add_annotation("Phase RH", 1000, 1500, "P")
    eaf.add_annotation("Phase RH", 1500, 2000, "Stroke")
    eaf.add_annotation("Phase RH", 2000, 2400, "rest")
    eaf.add_tier("Handedness")
    eaf.add_annotation("Handedness", 1000, 2000, "rh")
    to_eaf(str(tmp_path / "human.eaf"), eaf)
    with pytest.raises(ParameterError, match="fps"):
        read_eaf(tmp_path / "human.eaf")
    ann = read_eaf(tmp_path / "human.eaf", fps=30.0)
    assert list(ann.phases["right"]) == [
        PhaseSegment(Phase.PREPARATION, 30, 45),
        PhaseSegment(Phase.STROKE, 45, 60),
    ]
    assert ann.handedness == ((30, 60, "RH"),)
    labels = ann.labels("right", 80)
    assert labels[29] == Phase.REST and labels[30] == Phase.PREPARATION and labels[60] == Phase.REST


def test_bad_annotations_name_the_place(tmp_path):
    from pympi.Elan import Eaf, to_eaf

    eaf = Eaf()
    eaf.add_tier("Phase LH")
    eaf.add_annotation("Phase LH", 100, 900, "wiggle")
    to_eaf(str(tmp_path / "bad.eaf"), eaf)
    with pytest.raises(MotionFormatError, match=r"bad.eaf tier 'Phase LH' at 100 ms.*wiggle"):
        read_eaf(tmp_path / "bad.eaf", fps=30.0)
    (tmp_path / "bad.csv").write_text(
        "tier,start_frame,stop_frame,start_s,stop_s,value\nPhase RH,1,x,0.1,0.2,stroke\n"
    )
    with pytest.raises(MotionFormatError, match="bad.csv line 2"):
        read_csv(tmp_path / "bad.csv")
    (tmp_path / "garbage.eaf").write_text("<not xml")
    with pytest.raises(MotionFormatError, match="garbage.eaf"):
        read_eaf(tmp_path / "garbage.eaf", fps=30.0)
    with pytest.raises(FileNotFoundError):
        read_eaf(tmp_path / "missing.eaf")


def test_write_is_atomic(analysed, tmp_path):
    phases, hands = analysed
    path = tmp_path / "keep.eaf"
    path.write_text("old")
    with pytest.raises(AttributeError):
        write_eaf(path, phases, [object()])  # fails while building: the old file stays
    assert path.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["keep.eaf"]


def test_phase_boundaries_become_splicing_constraints():
    P, S, H, R = Phase.PREPARATION, Phase.STROKE, Phase.HOLD, Phase.RETRACTION
    body = [
        PhaseSegment(P, 10, 20),
        PhaseSegment(S, 20, 30),
        PhaseSegment(H, 30, 40),
        PhaseSegment(R, 40, 50),
    ]
    assert phase_boundaries(body) == [
        (10, Phase.REST, P),
        (20, P, S),
        (30, S, H),
        (40, H, R),
        (50, R, Phase.REST),
    ]
    # the hand take lacks the hold: its other boundaries still pair up
    hand = [PhaseSegment(P, 5, 12), PhaseSegment(S, 12, 25), PhaseSegment(R, 25, 33)]
    pts = phase_constraints(body, hand, tolerance=2, n_body=60, n_hand=40)
    assert pts == [(10, 5, 2), (20, 12, 2), (50, 33, 2)]
    with pytest.raises(ParameterError, match="tolerance"):
        phase_constraints(body, hand, tolerance=-1)
