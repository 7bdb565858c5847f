"""The hands' close-up camera frames the spliced hand in every frame: the first and last
frames too (where a moving average of the hand's place leans on one side) and during
fast moves (a wave); and it sees the hand where the body hides it from the front (the
strangers' R3-5 and R4-1: a long take's pose with the hand behind the torso showed the
elbow and torso, no spliced finger)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from engine.cli import main
from engine.io.bvh import read_bvh
from engine.render.offscreen import Preview
from engine.render.scene import HANDS_DIRECTIONS, HANDS_SWITCH_GAIN

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


def _cut_bvh(src: Path, dst: Path, start: int, count: int) -> Path:
    """``dst``: frames ``start`` to ``start + count`` of ``src``."""
    lines = src.read_text().splitlines()
    k = next(i for i, line in enumerate(lines) if line.startswith("MOTION"))
    motion = [line for line in lines[k + 3 :] if line.strip()][start : start + count]
    dst.write_text("\n".join([*lines[: k + 1], f"Frames: {len(motion)}", lines[k + 2], *motion]))
    return dst


def hand_seen_in_closeup(preview: Preview, i: int, side: str) -> tuple[float, float, bool]:
    """``(seen, area, cut)`` of the spliced hand in frame ``i``'s close-up as rendered:
    the hand's mesh is drawn in pure green, ``seen`` is the number of green pixels of the
    whole take's picture over those of the hand drawn alone (what the body hides from
    the camera is not seen), ``area`` the hand alone's share of the picture, ``cut``
    whether the hand alone reaches the picture's edge."""
    view = preview.views[0]
    mesh = view.mesh
    hand = mesh.part == mesh.part_names.index(f"{side}_hand")
    colors = mesh.colors.copy()
    colors[hand] = (0.0, 1.0, 0.0, 1.0)
    alone = mesh.faces[hand[mesh.faces].all(axis=1)]

    def green(m) -> np.ndarray:
        view.mesh = m
        img = preview.frame(i, view="single", camera="hands", size=SIZE).astype(int)
        return (img[..., 1] > img[..., 0] + 40) & (img[..., 1] > img[..., 2] + 40)

    try:
        whole = green(dataclasses.replace(mesh, colors=colors))
        drawn = green(dataclasses.replace(mesh, colors=colors, faces=alone))
    finally:
        view.mesh = mesh
    cut = bool(drawn[0].any() or drawn[-1].any() or drawn[:, 0].any() or drawn[:, -1].any())
    return whole.sum() / max(drawn.sum(), 1), drawn.sum() / drawn.size, cut


#: (body take, first frame, hand take, side): 7 s of a long take where the body hides
#: the spliced hand from the close-up's front view (R4-1: LAFAN1 multipleActions1 near
#: body frame 3488, the right hand behind the torso: none of it seen from the front)
HIDDEN = {
    "behind-torso": (
        "lafan1/multipleActions1_subject1.bvh",
        3388,
        "manipnet/mug1_rightHand.bvh",
        "right",
    ),
}


@pytest.mark.parametrize("case", sorted(HIDDEN))
def test_the_closeup_sees_a_hand_the_body_hides_from_the_front(case, mocap_dir, tmp_path):
    body, start, hand, side = HIDDEN[case]
    cut = _cut_bvh(mocap_dir / body, tmp_path / "body.bvh", start, 201)
    out = tmp_path / "spliced.bvh"
    args = ["splice", str(cut), str(mocap_dir / hand), "-o", str(out), "--side", side, "--quiet"]
    assert main(args) == 0
    preview = Preview(read_bvh(out), close_up_sides=(side,))
    view = preview.views[0]
    aspect, yfov = SIZE[0] / SIZE[1], np.radians(35.0)
    every = {f: view.hand_seen(f, aspect, yfov) for f in range(0, 201, 5)}
    front = {f: seen[0] for f, seen in every.items()}
    # the rule, from every direction's share (hands_direction skips the others when the
    # front's share is within HANDS_SWITCH_GAIN of all: no other can then gain that much)
    for f, seen in every.items():
        best = int(np.argmax(seen))
        want = HANDS_DIRECTIONS[best if seen[best] >= seen[0] + HANDS_SWITCH_GAIN else 0]
        assert view.hands_direction(f, aspect, yfov) == want, f
    hidden = min(front, key=front.get)
    assert front[hidden] < 0.3  # the body hides the hand from the front there
    seen, area, cut = hand_seen_in_closeup(preview, hidden, side)
    assert seen > 0.6, f"frame {hidden}: {seen:.0%} of the hand seen"
    assert area > 0.01 and not cut  # and drawn whole, large enough to judge
    # a frame where the front sees the hand keeps the front view
    free = max(front, key=front.get)
    assert view.hands_direction(free, aspect, yfov) == HANDS_DIRECTIONS[0]
