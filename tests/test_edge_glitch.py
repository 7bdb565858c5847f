"""A take's first or last frame that is a one-frame outlier pose is said as a reader note
(stranger 14 F4: hello-world's first frame, ``rIndex1`` about 170° off, was held for a
second in the spliced take with no word). The rule's measurement on every shared capture
is ``test_cli_info.test_info_json_on_every_capture`` (it reads them all)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import MOCAP

from engine.io.bvh import read_bvh
from engine.model import rotations as rot
from engine.model.edge_glitch import AGREE_DEG, AWAY_DEG, edge_outliers

#: the shared takes whose first frame the rule finds (measured: no other end, no inner frame)
GLITCHED = {"hello-world.bvh", "gesture-pointing.bvh", "thumbelina.bvh"}


def _turns(deg: list[float]) -> np.ndarray:
    """(frames, 1, 4): one joint turned about x by ``deg`` degrees per frame."""
    return rot.from_euler(np.array(deg, dtype=float)[:, None, None] * [1, 0, 0], "XYZ")


@pytest.mark.parametrize(
    "deg, found",
    [
        ([170, 0, 5, 10, 15], [0]),  # far from both neighbours, which agree
        ([0, 5, 10, 15, -170], [4]),  # the last frame alike
        ([170, 0, 5, 10, -175], [0, 4]),
        ([0, 5, 10, 15, 20], []),  # smooth
        ([170, 0, 60, 10, 15], []),  # the neighbours disagree: a fast move, not an outlier
        ([AWAY_DEG - 1, 0, 1, 2, 3], []),  # not far enough
        ([150, 0, AGREE_DEG + 1, 40, 50], []),  # the neighbours do not agree
        ([0, 170, 0, 5, 10], []),  # an inner glitch is not an end's
        ([170, 0, 5], []),  # too short to tell
    ],
)
def test_edge_outliers_rule(deg, found):
    hits = edge_outliers(_turns(deg), ["j"], [0])
    assert [f for f, _, _ in hits] == found
    assert all(name == "j" and d > AWAY_DEG for _, name, d in hits)


def test_the_reader_notes_a_glitched_first_frame_and_not_a_clean_take():
    take = read_bvh(MOCAP / "gestification/hello-world.bvh")
    (note,) = [n for n in take.meta.notes if "outlier" in n]
    assert note.startswith("hello-world.bvh: frame 0 is a one-frame outlier pose (rIndex1 is ")
    assert "which agree): a tracking glitch?" in note
    for clean in ("gestification/fingers-ok.bvh", "manipnet/mug1_rightHand.bvh"):
        assert not [n for n in read_bvh(MOCAP / clean).meta.notes if "outlier" in n]
