"""The hands' close-up on long takes (pagefix6, strangers' R3-5 and R4-1): how much of the
spliced hand the picture shows, the front-only camera (before) beside the one that looks
from where the body does not hide the hand (after), in one run.

    .venv/bin/python -m benchmarks.bench_closeup [--step 40]

Splices LAFAN1 ``multipleActions1`` + ManipNet ``mug1_rightHand`` (right) and LAFAN1
``dance1`` + ``mug1_leftHand`` (left) with the CLI's defaults, then renders every
``step``-th body frame's 330 x 300 close-up twice (front only: the switch gain set out of
reach; chosen: the default) with the hand's mesh in pure green, and counts its pixels
against the hand drawn alone (``tests/test_closeup.hand_seen_in_closeup``). Prints the
share of frames where under half (a fifth) of the hand is seen.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
MOCAP = Path(os.environ.get("HANDSPLICE_MOCAP", ROOT.parent / "shared" / "data" / "mocap"))
PAIRS = (
    ("lafan1/multipleActions1_subject1.bvh", "manipnet/mug1_rightHand.bvh", "right"),
    ("lafan1/dance1_subject1.bvh", "manipnet/mug1_leftHand.bvh", "left"),
)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--step", type=int, default=40)
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT / "tests"))
    from test_closeup import hand_seen_in_closeup

    import engine.render.scene as scene
    from engine.cli import main as cli
    from engine.io.bvh import read_bvh
    from engine.render.offscreen import Preview

    gain = scene.HANDS_SWITCH_GAIN
    print(f"load: {os.getloadavg()[0]:.1f}")
    with tempfile.TemporaryDirectory() as tmp:
        for body, hand, side in PAIRS:
            out = Path(tmp) / "spliced.bvh"
            argv = ["splice", str(MOCAP / body), str(MOCAP / hand), "-o", str(out)]
            assert cli([*argv, "--side", side, "--quiet"]) == 0
            take = read_bvh(out)
            for mode, g in (("front only (before)", 2.0), ("chosen (after)", gain)):
                scene.HANDS_SWITCH_GAIN = g
                preview = Preview(take, close_up_sides=(side,))
                t = time.perf_counter()
                seen = np.array(
                    [
                        hand_seen_in_closeup(preview, f, side)[0]
                        for f in range(0, take.n_frames, args.step)
                    ]
                )
                print(
                    f"{Path(body).stem} ({side}) {mode}: {len(seen)} frames, "
                    f"seen < 0.5 in {100 * (seen < 0.5).mean():.1f} %, "
                    f"< 0.2 in {100 * (seen < 0.2).mean():.1f} %, mean {seen.mean():.2f} "
                    f"({(time.perf_counter() - t) / len(seen):.2f} s/frame, 2 renders each)"
                )
            scene.HANDS_SWITCH_GAIN = gain


if __name__ == "__main__":
    main()
