"""The video paths made faster keep the pictures: the same pixels, the same GIF bytes.

* the floor patch leaves out tiles that would draw nothing (all four corners transparent),
  and draws the same picture;
* a frame read without pyrender's depth readback has the same colours as with it;
* GIF frames quantised on a worker thread (``GifFrames``) give the very bytes of the
  straightforward encoder;
* progress says how long is left (command line and page share ``remaining_text``).

Real data: the Bandai ``call`` take a user reported (171 frames).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from engine.io.bvh import read_bvh
from engine.render.scene import floor_mesh_arrays
from engine.render.video import GifFrames, gif_bytes, gif_frame, remaining_text

MOCAP = Path(__file__).resolve().parents[2] / "shared" / "data" / "mocap"
TAKE = MOCAP / "bandai-namco" / "dataset-1_call_normal_001.bvh"


@pytest.fixture(scope="module")
def preview():
    from engine.render.offscreen import Preview

    p = Preview(read_bvh(TAKE), size=(320, 240))
    yield p
    p.close()


@pytest.mark.parametrize("center", [(0.0, 0.0, 0.0), (0.37, 0.0, -1.21), (-2.6, 0.0, 0.9)])
def test_every_floor_tile_draws_something(center):
    radius, tile = 1.2, 0.5
    verts, faces, colors = floor_mesh_arrays(np.array(center), radius, 0.0, tile)
    alpha = colors[:, 3].reshape(-1, 4)
    assert len(alpha) > 4 and (alpha.max(axis=1) > 0).all()
    # nothing visible was dropped: the patch still reaches the fade's end all round
    dist = np.hypot(verts[:, 0] - center[0], verts[:, 2] - center[2])
    assert dist.max() >= radius and len(faces) == 2 * len(alpha)


def test_the_floor_draws_the_same_picture_without_its_empty_tiles(preview, monkeypatch):
    from engine.render import offscreen, scene

    frames = [0, 85, 170]
    trimmed = [preview.frame(i) for i in frames]

    def with_empty_tiles(center, radius, y, tile):
        """The patch as drawn before: the whole square of tiles around the circle."""
        verts, faces, colors = scene.floor_mesh_arrays(center, radius * 1.6, y, tile)
        dist = np.hypot(verts[:, 0] - center[0], verts[:, 2] - center[2])
        t = np.clip((dist - 0.45 * radius) / (0.55 * radius), 0.0, 1.0)
        colors[:, 3] = 1.0 - t * t * (3 - 2 * t)
        return verts, faces, colors

    monkeypatch.setattr(offscreen, "floor_mesh_arrays", with_empty_tiles)
    padded = [preview.frame(i) for i in frames]
    for a, b in zip(trimmed, padded):
        diff = np.abs(a.astype(int) - b.astype(int))
        assert diff.max() <= 1 and (diff.max(axis=2) > 0).mean() < 1e-3


def test_a_frame_without_the_depth_readback_has_the_same_colours(preview):
    import pyrender

    from engine.render.backend import GL_LOCK, release_current, render_color, shared_renderer

    preview.frame(40)  # the preview's materials exist
    v = preview.views[0]
    verts, normals = v.vertices(40)
    with GL_LOCK:
        scene = pyrender.Scene(bg_color=(0.9, 0.9, 0.9, 1.0), ambient_light=(0.4, 0.4, 0.4))
        scene.add(preview._mesh(verts, v.mesh.faces, v.mesh.colors, normals))
        pose = v.camera_pose(40, "three-quarter", 4 / 3, np.radians(35))
        scene.add(pyrender.PerspectiveCamera(yfov=np.radians(35), aspectRatio=4 / 3), pose=pose)
        scene.add(pyrender.DirectionalLight(intensity=3.0), pose=pose)
        renderer = shared_renderer(320, 240)
        try:
            color_only, no_depth = render_color(renderer, scene)
            color, depth = render_color(renderer, scene, depth=True)
            plain, plain_depth = renderer.render(scene)  # pyrender's own read
        finally:
            release_current(renderer)
    assert no_depth is None and depth is not None and (depth > 0).any()
    assert np.array_equal(color_only, color) and np.array_equal(color, plain[..., :3])
    assert np.array_equal(depth, plain_depth)
    assert len(np.unique(color_only.reshape(-1, 3), axis=0)) > 50  # a lit body, not a blank


def test_gif_frames_quantised_beside_the_render_give_the_same_bytes(preview):
    images = [preview.frame(i) for i in range(0, 171, 17)]
    with GifFrames() as frames:
        for image in images:
            frames.add(image)
        quantised = frames.images()
    assert len(quantised) == len(images) and all(q.mode == "P" for q in quantised)
    assert gif_bytes(quantised, 30.0) == gif_bytes(images, 30.0)
    assert gif_frame(images[3]).tobytes() == quantised[3].tobytes()


def test_remaining_time_is_said_between_the_first_and_the_last_step():
    assert remaining_text(10.0, 1, 171) == ""  # one step is no pace yet
    assert remaining_text(10.0, 20, 171) == "about 76 s left"
    assert remaining_text(30.0, 20, 171) == "about 4 min left"
    assert remaining_text(50.0, 171, 171) == ""


def test_the_command_line_shows_progress_and_time_left(tmp_path, capsys):
    from engine.cli import main

    out = tmp_path / "clip.gif"
    assert main(["render", str(TAKE), "-o", str(out), "--frames", "0:24", "--size", "160x120"]) == 0
    err = capsys.readouterr().err
    assert "24/24" in err and f"wrote {out}" in err
    from PIL import Image

    with Image.open(out) as gif:
        assert gif.n_frames == 24
