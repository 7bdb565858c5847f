"""The hands' close-up camera frames the spliced hand in every frame: the first and last
frames too (where a moving average of the hand's place leans on one side) and during
fast moves (a wave)."""

from __future__ import annotations

import numpy as np
import pytest

from engine.cli import main
from engine.io.bvh import read_bvh
from engine.render.offscreen import Preview

#: the app's close-up size (webapp.views.preview), pixels
SIZE = (330, 300)
PAIRS = {
    "wave-ok": (
        "bandai-namco/dataset-2_wave-right-hand_normal_001.bvh",
        "gestification/fingers-ok.bvh",
    ),
    "bye-hello": ("bandai-namco/dataset-1_bye_normal_001.bvh", "gestification/gesture-swiping.bvh"),
}


@pytest.fixture(scope="module", params=sorted(PAIRS))
def spliced(request, mocap_dir, tmp_path_factory):
    body, hand = (mocap_dir / p for p in PAIRS[request.param])
    out = tmp_path_factory.mktemp("closeup") / "spliced.bvh"
    assert main(["splice", str(body), str(hand), "-o", str(out), "--side", "right", "--quiet"]) == 0
    return read_bvh(out)


def test_the_closeup_keeps_the_hand_in_view_in_every_frame(spliced):
    preview = Preview(spliced, close_up_sides=("right",))
    view = preview.views[0]
    wrist = view.anatomy.hands["right"].wrist
    hand = sorted(spliced.skeleton.descendants(wrist))
    assert len(hand) > 10  # wrist and fingers
    w, h = SIZE
    worst = []
    for i in range(spliced.n_frames):
        px = preview.project(view.positions[i, hand], i, camera="hands", size=SIZE)
        # distance (pixels) the hand's joints reach outside the picture (<= 0: inside)
        worst.append(
            max((-px[:, 0]).max(), (px[:, 0] - w).max(), (-px[:, 1]).max(), (px[:, 1] - h).max())
        )
    worst = np.array(worst)
    assert worst.max() < -4, (
        f"frames {np.flatnonzero(worst >= -4)[:10]} cut the hand: {worst.max():.0f} px"
    )
    # and the hand is not a speck: its joints span a good part of the picture at frame 0
    px = preview.project(view.positions[0, hand], 0, camera="hands", size=SIZE)
    assert np.ptp(px, axis=0).max() > 0.1 * min(SIZE)


def test_the_first_frames_closeup_shows_the_hand(spliced, tmp_path):
    """Frame 0 rendered: skin-coloured pixels of the hand lie inside the picture, away
    from its edges (the picture is looked at in the report's screenshots)."""
    preview = Preview(spliced, close_up_sides=("right",))
    image = preview.frame(0, view="single", camera="hands", size=SIZE)
    from engine.render.video import to_png_bytes

    (tmp_path / "closeup0.png").write_bytes(to_png_bytes(image))
    view = preview.views[0]
    wrist = view.anatomy.hands["right"].wrist
    hand = sorted(spliced.skeleton.descendants(wrist))
    px = preview.project(view.positions[0, hand], 0, camera="hands", size=SIZE)
    cx, cy = np.clip(px.mean(axis=0).round().astype(int), 0, [SIZE[0] - 1, SIZE[1] - 1])
    background = image[2, 2].astype(int)
    patch = image[max(cy - 12, 0) : cy + 12, max(cx - 12, 0) : cx + 12].astype(int)
    assert (np.abs(patch - background).sum(axis=-1) > 30).mean() > 0.2  # the hand is drawn there
