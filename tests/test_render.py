"""Headless rendering: silhouettes, finger motion in the hand region, views, trails,
video files, the ``render`` CLI and the OpenGL platform choice."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
from dataclasses import replace

import numpy as np
import pytest
from conftest import MOCAP, ROOT, mocap_files

from engine.io.bvh import read_bvh
from engine.model import rotations as rot
from engine.model.roles import find_roles
from engine.render import Preview, render_to_file
from engine.render.backend import RenderBackendError, ensure_platform
from engine.render.offscreen import BACKGROUND

ALL_BVH = mocap_files()
BEAT = MOCAP / "beat" / "1_wayne_0_1_1.bvh"
BANDAI = MOCAP / "bandai-namco" / "dataset-2_wave-both-hands_normal_001.bvh"
BG = np.array(BACKGROUND) * 255


def silhouette(img: np.ndarray, floor: bool = False) -> np.ndarray:
    """Pixels that are neither background nor (light grey) floor."""
    diff = np.abs(img.astype(float) - BG).max(axis=2)
    mask = diff > 12
    if not floor:
        grey = (np.ptp(img.astype(float), axis=2) < 14) & (img.min(axis=2) > 150)
        mask &= ~grey
    return mask


@pytest.fixture(scope="module")
def beat():
    return read_bvh(BEAT)


@pytest.fixture(scope="module")
def beat_preview(beat):
    preview = Preview(beat.frames(0, 60), size=(160, 120))
    yield preview
    preview.close()


def test_headless_egl_is_chosen_and_renders(beat_preview):
    assert ensure_platform() in ("egl", "osmesa")
    img = beat_preview.frame(10, camera="front", floor=False)
    assert img.shape == (120, 160, 3) and img.dtype == np.uint8
    mask = silhouette(img)
    ys, xs = np.nonzero(mask)
    # a standing person fills most of the height and a fraction of the width
    height = ys.max() - ys.min()
    assert 0.55 * 120 < height < 120
    assert 0.1 * 160 < xs.max() - xs.min() < 0.8 * 160
    assert 0.04 < mask.mean() < 0.4


def test_silhouette_follows_the_size(beat_preview):
    small = silhouette(beat_preview.frame(5, size=(80, 60), floor=False))
    large = silhouette(beat_preview.frame(5, size=(320, 240), floor=False))
    assert small.shape == (60, 80) and large.shape == (240, 320)
    ratio = large.sum() / max(small.sum(), 1)
    assert 10 < ratio < 22  # area scales with the square of the size (16)


def test_hand_region_changes_when_only_fingers_move(beat):
    motion = beat.frames(0, 1)
    sk = motion.skeleton
    roles = find_roles(sk)
    fingers = [
        j
        for side in ("right", "left")
        for f, js in roles.side(side).fingers.items()
        if f != "thumb"
        for j in js
    ]
    rots = np.concatenate([motion.rotations, motion.rotations])
    curl = rot.from_axis_angle(np.array([0.0, 0.0, 1.0]), np.radians(70))
    rots[1, fingers] = rot.multiply(rots[1, fingers], curl)
    both = replace(motion, rotations=rots, translations=np.concatenate([motion.translations] * 2))
    size = (320, 240)
    with Preview(both, size=size) as preview:
        a = preview.frame(0, camera="front", floor=False)
        b = preview.frame(1, camera="front", floor=False)
        wrists = preview.project(
            preview.joint_positions(0)[[roles.side("right").wrist, roles.side("left").wrist]],
            0,
            camera="front",
        )
    changed = np.abs(a.astype(int) - b.astype(int)).max(axis=2) > 30
    assert changed.sum() > 20, "curling the fingers changed nothing visible"
    ys, xs = np.nonzero(changed)
    # every changed pixel lies near a wrist (a hand length is ~ 1/9 of the body)
    radius = 0.12 * size[1]
    near = np.zeros(len(xs), bool)
    for wx, wy in wrists:
        near |= np.hypot(xs - wx, ys - wy) < radius
    assert near.mean() > 0.99


@pytest.mark.parametrize("path", ALL_BVH, ids=[p.name for p in ALL_BVH])
def test_every_real_skeleton_renders(path):
    motion = read_bvh(path)
    motion = motion.frames(0, min(motion.n_frames, 120))
    with Preview(motion, size=(64, 64)) as preview:
        img = preview.frame(motion.n_frames // 2, camera="three-quarter", floor=False)
    mask = silhouette(img)
    assert mask.mean() > 0.03
    ys, xs = np.nonzero(mask)
    # the character is framed: not cut by the borders on all sides, and big enough
    assert max(ys.max() - ys.min(), xs.max() - xs.min()) > 0.5 * 64


def test_views_side_by_side_and_overlay(beat):
    body = beat.frames(0, 30)
    with Preview([body, body], labels=["body", "copy"], size=(200, 100)) as preview:
        pair = preview.frame(3, view="side_by_side", floor=False)
        assert pair.shape == (100, 200, 3)
        left, right = pair[:, :99], pair[:, 101:]
        assert silhouette(left).sum() > 100 and silhouette(right).sum() > 100
        single = preview.frame(3, size=(200, 100), floor=False)
        over = preview.frame(3, view="overlay", size=(200, 100), floor=False)

    def green(img):
        img = img.astype(int)
        return (img[..., 1] > img[..., 0] + 40) & (img[..., 1] > img[..., 2] + 40)

    assert green(over).sum() > 30 and green(single).sum() == 0  # the stick figure shows


def test_trails_are_coloured_by_phase():
    motion = read_bvh(BANDAI)
    phases = np.full(motion.n_frames, 2)  # STROKE everywhere -> red
    with Preview(motion, size=(160, 160)) as preview:
        plain = preview.frame(100, floor=False)
        red = preview.frame(100, trails=True, phases=phases, floor=False)
        own = preview.frame(100, trails=True, floor=False, trail_style="spheres")

    def reddish(img):
        return (img[..., 0] > 150) & (img[..., 1] < 90) & (img[..., 2] < 90)

    assert reddish(red).sum() > 40 and reddish(plain).sum() == 0
    orange = (own[..., 0] > 180) & (own[..., 1] > 80) & (own[..., 1] < 170) & (own[..., 2] < 80)
    assert orange.sum() > 20  # right hand's own colour without phases
    with pytest.raises(ValueError, match="unknown phase"):
        Preview(motion, size=(32, 32)).frame(0, trails=True, phases=["jump"] * motion.n_frames)


def test_bad_parameters_raise(beat_preview):
    from engine.base.errors import ParameterError

    with pytest.raises(ParameterError, match="view"):
        beat_preview.frame(0, view="panorama")
    with pytest.raises(ParameterError, match="camera"):
        beat_preview.frame(0, camera="top")
    with pytest.raises(ParameterError, match="outside"):
        beat_preview.frame(10_000)
    with pytest.raises(ParameterError, match="size"):
        beat_preview.frame(0, size="big")


def test_gif_and_mp4_are_written_and_readable(tmp_path, beat_preview):
    import imageio.v3 as iio

    frames = range(0, 8)
    gif = render_to_file(beat_preview, tmp_path / "clip.gif", frames=frames, size=(64, 48))
    mp4 = render_to_file(beat_preview, tmp_path / "clip.mp4", frames=frames, size=(66, 50))
    seen = []
    png = render_to_file(
        beat_preview,
        tmp_path / "sheet.png",
        frames=frames,
        size=(64, 48),
        progress=lambda d, t: seen.append((d, t)),
    )
    g = iio.imread(gif, index=None)
    assert g.shape[0] == 8 and g.shape[1:3] == (48, 64)
    import imageio

    with imageio.get_reader(str(mp4)) as reader:
        m = [f for f in reader]
    assert len(m) == 8 and m[0].shape[:2] == (50, 66)
    assert seen[-1] == (8, 8)
    sheet = iio.imread(png)
    assert sheet.shape[0] > 48 and sheet.shape[1] > 64
    assert not list(tmp_path.glob(".*"))  # no temporary files left behind


def test_preview_is_safe_across_threads(beat_preview):
    results = {}

    def work(k):
        results[k] = beat_preview.frame(7, size=(96, 72), floor=False)

    threads = [threading.Thread(target=work, args=(k,)) for k in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(results) == 3
    assert all(np.array_equal(results[0], results[k]) for k in (1, 2))


def test_cli_render_png_and_bad_input(tmp_path, capsys):
    from engine.cli import main

    out = tmp_path / "frame.png"
    assert (
        main(["render", str(BEAT), "-o", str(out), "--frame", "5", "--size", "96x72", "--quiet"])
        == 0
    )
    import imageio.v3 as iio

    assert iio.imread(out).shape == (72, 96, 3)
    bad = [
        ["render", str(tmp_path / "missing.bvh"), "-o", str(tmp_path / "a.png")],
        ["render", str(BEAT), "-o", str(tmp_path / "a.jpg")],
        ["render", str(BEAT), "-o", str(tmp_path / "a.png"), "--size", "0x10"],
        ["render", str(BEAT), "-o", str(tmp_path / "a.png"), "--frame", "100000"],
        ["render", str(BEAT), "-o", str(tmp_path / "a.gif"), "--frames", "50:10"],
        ["render", str(BEAT), "-o", str(tmp_path / "a.png"), "--view", "overlay"],
        ["render", str(MOCAP / "pyomeca" / "markers.trc"), "-o", str(tmp_path / "a.png")],
    ]
    for argv in bad:
        assert main(argv + ["--quiet"]) == 2, argv
        err = capsys.readouterr().err
        assert err.startswith("handsplice: error:") and err.count("\n") == 1, err
    assert not (tmp_path / "a.png").exists() and not (tmp_path / "a.gif").exists()


def test_cli_render_compare_gif(tmp_path):
    from engine.cli import main

    out = tmp_path / "cmp.gif"
    assert (
        main(
            [
                "render",
                str(BEAT),
                "--compare",
                str(BEAT),
                "-o",
                str(out),
                "--frames",
                "0:4",
                "--size",
                "120x60",
                "--trails",
                "--quiet",
            ]
        )
        == 0
    )
    import imageio.v3 as iio

    assert iio.imread(out, index=None).shape == (4, 60, 120, 3)


def test_osmesa_fallback_renders():
    code = (
        "import numpy as np\n"
        "from engine.io.bvh import read_bvh\n"
        "from engine.render import Preview\n"
        f"m = read_bvh({str(BEAT)!r}).frames(0, 2)\n"
        "img = Preview(m, size=(48, 48)).frame(0, floor=False)\n"
        "print((np.abs(img.astype(int) - 245).max(axis=2) > 20).mean())\n"
    )
    env = dict(os.environ, PYOPENGL_PLATFORM="osmesa")
    done = subprocess.run(
        [sys.executable, "-c", code], env=env, cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert float(done.stdout.strip().splitlines()[-1]) > 0.03


def test_clear_message_when_no_backend_works(monkeypatch):
    import engine.render.backend as backend

    monkeypatch.delenv("PYOPENGL_PLATFORM", raising=False)
    monkeypatch.delitem(sys.modules, "OpenGL", raising=False)
    monkeypatch.setattr(backend, "_CHOSEN", None)
    monkeypatch.setattr(backend, "_egl_works", lambda: False)
    monkeypatch.setattr(backend, "_osmesa_library", lambda: None)
    with pytest.raises(RenderBackendError, match="apt-get install libegl1"):
        ensure_platform()
    monkeypatch.setattr(backend, "_osmesa_library", lambda: object())
    assert ensure_platform() == "osmesa"
    # the Makefile's default egl, on a machine where only OSMesa works: OSMesa
    monkeypatch.setattr(backend, "_CHOSEN", None)
    monkeypatch.setenv("PYOPENGL_PLATFORM", "egl")
    assert ensure_platform() == "osmesa"


def test_z_up_metres_and_y_up_centimetres_render_alike():
    """The same motion written Y-up in cm and Z-up in m gives the same picture."""
    from test_mesh import humanoid

    from engine.model.motion import Motion, MotionMeta, Skeleton

    sk = humanoid()
    rng = np.random.default_rng(4)
    n = 3
    axis = rng.normal(size=(n, sk.n_joints, 3))
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    rots = rot.from_axis_angle(axis, rng.uniform(-0.3, 0.3, size=(n, sk.n_joints)))
    trans = np.broadcast_to(sk.offsets, (n, sk.n_joints, 3)).copy()
    y_up = Motion(sk, rots, trans, 30.0, MotionMeta(units="cm", up_axis="y"))
    # Z-up: (x, y, z) -> (x, -z, y), metres; rotations conjugated by the axis change
    to_z = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
    q = rot.from_matrix(to_z)
    sk_z = Skeleton(sk.names, sk.parents, sk.offsets @ to_z.T / 100.0, sk.channels)
    rots_z = rot.multiply(rot.multiply(q, rots), rot.conjugate(q))
    z_up = Motion(sk_z, rots_z, trans @ to_z.T / 100.0, 30.0, MotionMeta(units="m", up_axis="z"))
    with Preview([y_up, z_up], size=(96, 96)) as preview:
        a = preview.frame(2, take=0, camera="three-quarter")
        b = preview.frame(2, take=1, camera="three-quarter")
    assert silhouette(a).sum() > 200
    assert np.abs(a.astype(int) - b.astype(int)).max() <= 2


def test_png_bytes_round_trip(beat_preview):
    import io

    from PIL import Image

    from engine.render import to_png_bytes

    img = beat_preview.frame(1, size=(40, 30), floor=False)
    back = np.asarray(Image.open(io.BytesIO(to_png_bytes(img))))
    assert np.array_equal(back, img)


def test_hands_camera_is_a_close_up(beat_preview, beat):
    sk = beat.skeleton
    wrists = beat_preview.joint_positions(20)[[sk.index("right_wrist"), sk.index("left_wrist")]]
    near = beat_preview.project(wrists, 20, camera="hands")
    far = beat_preview.project(wrists, 20, camera="front")
    assert np.linalg.norm(near[0] - near[1]) > 1.8 * np.linalg.norm(far[0] - far[1])
    assert np.all((near > 0) & (near < [160, 120]))  # both hands in the picture
    assert silhouette(beat_preview.frame(20, camera="hands", floor=False)).mean() > 0.1


def test_a_view_poses_frames_when_drawn_and_keeps_no_joints_of_every_frame(beat):
    """A take's view holds its framing (a few floats a frame), not every frame's world
    joints (issue 13: +0.7 GB for the app's three views of a 10-minute take); the joints of
    any frames it is asked for are the whole take's forward kinematics, to the bit."""
    from engine.model.fastkin import forward_kinematics
    from engine.render.scene import TakeView

    view = TakeView.from_motion(beat)
    frames, joints = beat.n_frames, beat.skeleton.n_joints
    held = sum(v.nbytes for v in vars(view).values() if isinstance(v, np.ndarray))
    # targets and hand targets, (F, 3) each, and a few per-joint flags: no (F, J, ...) array
    assert held < 64 * frames + 64 * joints < frames * joints * 7 * 8 // 10
    assert view.positions.shape == (frames, joints, 3) and len(view.rotations) == frames
    pos, wrot = forward_kinematics(beat)
    shown = view.scale * np.einsum("ij,fkj->fki", view.axes, pos)
    picks = np.array([0, frames // 2, frames - 1, 7])
    assert np.array_equal(view.positions[picks], shown[picks])
    assert np.array_equal(view.positions[picks, 3], shown[picks, 3])
    assert np.array_equal(view.positions[5:9, [1, 2]], shown[5:9, [1, 2]])
    assert np.array_equal(view.rotations[-1], wrot[-1])
    assert np.array_equal(view.positions[frames // 2, 4], shown[frames // 2, 4])
    assert len(view._posed) <= 8  # a few posed frames are kept, not the take
