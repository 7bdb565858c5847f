"""GIFs play at the take's rate: per-frame centisecond delays from cumulative rounding
(issue 14 item 9: a fixed 30 ms delay played 30 fps takes 10 % fast). Each test reads
the GIF back and checks its total duration."""

from __future__ import annotations

import io

import pytest
from conftest import ROOT, open_demo_session
from PIL import Image

from engine.cli import main
from engine.io.bvh import read_bvh
from engine.render.video import GIF_MIN_DELAY_CS, gif_schedule
from webapp import backend

BVH = ROOT / "sample_data" / "bandai-namco" / "dataset-2_wave-right-hand_normal_001.bvh"


def gif_delays_ms(data: bytes) -> list[int]:
    """Every frame's delay in ms, as a viewer reads it."""
    with Image.open(io.BytesIO(data)) as im:
        delays = []
        for k in range(im.n_frames):
            im.seek(k)
            delays.append(im.info["duration"])
    return delays


@pytest.mark.parametrize("fps", [10, 24, 25, 29.97, 30, 48, 60, 100, 120])
def test_schedule_total_is_exact_and_delays_playable(fps):
    n = 137
    kept, delays = gif_schedule(n, fps)
    assert kept[0] == 0 and kept == sorted(set(kept)) and kept[-1] < n
    assert sum(delays) == 10 * round(100 * n / fps)  # whole take, to the centisecond
    assert abs(sum(delays) - 1000 * n / fps) <= 5
    assert min(delays) >= 10 * GIF_MIN_DELAY_CS and all(d % 10 == 0 for d in delays)
    if fps <= 100 / GIF_MIN_DELAY_CS:
        assert len(kept) == n  # no frame dropped at 50 fps or less
        assert max(delays) - min(delays) <= 10


def test_cli_gif_plays_at_the_takes_rate(tmp_path):
    fps = read_bvh(BVH).fps  # 30 fps: the old fixed delay was 30 ms (10 % fast)
    out = tmp_path / "clip.gif"
    assert main(["render", str(BVH), "-o", str(out), "--frames", "0:45", "--size", "96x72"]) == 0
    delays = gif_delays_ms(out.read_bytes())
    assert len(delays) == 45
    assert abs(sum(delays) - 1000 * 45 / fps) <= 5  # 1500 ms; was 1350 ms
    assert set(delays) <= {30, 40}


def test_app_gif_plays_at_the_takes_rate(tmp_path):
    session = open_demo_session(tmp_path / "uploads")
    prepared, solution = session.prepared, session.solution
    assert prepared.body.fps == 30 and prepared.n > 20
    data = backend.preview_video(prepared, solution, "gif", max_frames=20, size=(96, 72))
    delays = gif_delays_ms(data)
    # every body frame (30 fps, not thinned to 10 fps): 20 frames from the start frame
    assert len(delays) == 20
    assert abs(sum(delays) - 1000 * 20 / 30) <= 5
    assert set(delays) <= {30, 40}


def test_app_video_frames_keep_the_rate_under_30_fps():
    """120 fps: every 4th frame (30 fps); 100 fps: every 4th (25 fps); a long take: the
    window from the start frame, moved back to stay full length."""
    shown, fps = backend.video_frames(839, 120.0)
    assert (shown.step, fps) == (4, 30.0) and len(shown) == 210
    shown, fps = backend.video_frames(580, 100.0)
    assert (shown.step, fps) == (4, 25.0)
    shown, fps = backend.video_frames(4587, 30.0, start=4500, max_frames=300)
    assert (shown.start, shown.stop, shown.step, fps) == (4287, 4587, 1, 30.0)
    shown, _ = backend.video_frames(4587, 30.0, start=1000, max_frames=300)
    assert (shown.start, len(shown)) == (1000, 300)
