"""Render benchmark (issue 7): skinned frames of the BEAT skeleton with fingers.

    .venv/bin/python -m benchmarks.bench_render          # full run, writes RESULTS.md "render"
    .venv/bin/python -m benchmarks.bench_render --quick  # fewer repeats, prints only

Measures, in one run:
* ms per 640x480 skinned frame of ``beat/1_wayne_0_1_1.bvh`` (56 joints, 30 finger
  joints), warm: ``Preview.frame`` (skinning + floor + pyrender on the headless
  platform), median and best of interleaved repeats; and the time split into
  skinning (numpy LBS) and the rest;
* the same frames the straightforward way as reference: posed ``trimesh.Trimesh``
  -> ``pyrender.Mesh.from_trimesh`` -> a new scene each frame (same lights and
  camera, no floor), and the ratio;
* a 10 s clip at 30 fps (300 frames, the 250-frame take looped) to MP4, wall time;
* building a ``Preview`` (FK of the take, anatomy, mannequin, weights, framing).

Also writes ``benchmarks/figures/skeletons_contact_sheet.png``: one frame of every
BVH file in ../shared/data/mocap (mid-take, three-quarter camera), and
``benchmarks/figures/beat_hands.png``: BEAT's fingers in a close-up crop.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
MOCAP = Path(os.environ.get("HANDSPLICE_MOCAP", ROOT.parent / "shared" / "data" / "mocap"))
BEAT = MOCAP / "beat" / "1_wayne_0_1_1.bvh"
FIGURES = ROOT / "benchmarks" / "figures"
SIZE = (640, 480)


def _reference_frame(preview, i: int, renderer) -> np.ndarray:
    """One frame the straightforward way: trimesh -> pyrender.Mesh.from_trimesh."""
    import pyrender
    import trimesh

    from engine.render.offscreen import YFOV, _rotation

    v = preview.views[0]
    verts, _ = v.vertices(i)
    tm = trimesh.Trimesh(
        verts, v.mesh.faces, vertex_colors=(v.mesh.colors * 255).astype(np.uint8), process=False
    )
    scene = pyrender.Scene(bg_color=(0.96, 0.96, 0.97, 1.0), ambient_light=(0.38, 0.38, 0.4))
    scene.add(pyrender.Mesh.from_trimesh(tm, smooth=True))
    pose = v.camera_pose(i, "three-quarter", SIZE[0] / SIZE[1], YFOV)
    scene.add(pyrender.PerspectiveCamera(yfov=YFOV, aspectRatio=SIZE[0] / SIZE[1]), pose=pose)
    for angles, power in (((-40.0, -30.0), 3.2), ((-10.0, 50.0), 1.3), ((60.0, 170.0), 1.0)):
        scene.add(
            pyrender.DirectionalLight(color=np.ones(3), intensity=power),
            pose=pose @ _rotation(*angles),
        )
    color, _ = renderer.render(scene)
    return color


def bench_frames(repeats: int, per: int) -> dict:
    from engine.io.bvh import read_bvh
    from engine.render import Preview
    from engine.render.backend import GL_LOCK, release_current, shared_renderer

    motion = read_bvh(BEAT)
    t0 = time.perf_counter()
    preview = Preview(motion, size=SIZE)
    build_s = time.perf_counter() - t0
    v = preview.views[0]
    preview.frame(0)  # warm: shaders, buffers
    ours, bare, ref, skin = [], [], [], []
    frames = np.arange(motion.n_frames)
    k = 0
    with GL_LOCK:
        renderer = shared_renderer(*SIZE)
        _reference_frame(preview, 0, renderer)
        release_current(renderer)
    for _ in range(repeats):  # interleaved, so both see the same machine load
        t = time.perf_counter()
        for _ in range(per):
            preview.frame(int(frames[k % len(frames)]))
            k += 1
        ours.append((time.perf_counter() - t) / per * 1e3)
        t = time.perf_counter()
        for _ in range(per):
            preview.frame(int(frames[k % len(frames)]), floor=False)
            k += 1
        bare.append((time.perf_counter() - t) / per * 1e3)
        t = time.perf_counter()
        with GL_LOCK:
            for _ in range(per):
                _reference_frame(preview, int(frames[k % len(frames)]), renderer)
                k += 1
            release_current(renderer)
        ref.append((time.perf_counter() - t) / per * 1e3)
        t = time.perf_counter()
        for _ in range(per):
            v.vertices(int(frames[k % len(frames)]))
            k += 1
        skin.append((time.perf_counter() - t) / per * 1e3)
    return dict(
        build_s=build_s,
        ours=ours,
        bare=bare,
        ref=ref,
        skin=skin,
        vertices=v.mesh.n_vertices,
        triangles=len(v.mesh.faces),
        joints=motion.skeleton.n_joints,
        preview=preview,
        motion=motion,
    )


def bench_mp4(preview, n_frames: int = 300) -> float:
    import tempfile

    from engine.render.video import render_to_file

    frames = [i % preview.n_frames for i in range(n_frames)]
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        render_to_file(preview, Path(tmp) / "clip.mp4", frames=frames, fps=30.0, size=SIZE)
        wall = time.perf_counter() - t
        import imageio

        with imageio.get_reader(str(Path(tmp) / "clip.mp4")) as reader:
            count = sum(1 for _ in reader)
    if count != n_frames:
        raise RuntimeError(f"mp4 has {count} frames, expected {n_frames}")
    return wall


def contact_sheets() -> list[str]:
    """Write the skeleton contact sheet and the BEAT hand close-up; return notes."""
    from engine.io.bvh import read_bvh
    from engine.render import Preview, contact_sheet, write_image

    files = sorted(MOCAP.glob("**/*.bvh"))
    tiles, labels, notes = [], [], []
    for path in files:
        motion = read_bvh(path)
        with Preview(motion, size=(256, 256)) as preview:
            tiles.append(preview.frame(motion.n_frames // 2, camera="three-quarter"))
        a = preview.views[0].anatomy
        labels.append(f"{path.parent.name}/{path.stem}"[:34])
        hands = ", ".join(
            f"{s or 'hand'}: "
            + (
                f"{len(h.fingers)} captured fingers"
                + (" + procedural" if len(h.fingers) < 5 else "")
                if h.fingers
                else "procedural fingers"
            )
            for s, h in a.hands.items()
        )
        notes.append(f"{path.name} ({a.kind}; {hands})")
    FIGURES.mkdir(parents=True, exist_ok=True)
    write_image(
        contact_sheet(tiles, columns=6, labels=labels), FIGURES / "skeletons_contact_sheet.png"
    )
    # BEAT's hands: full frame at 640x480 and crops around both wrists
    motion = read_bvh(BEAT)
    with Preview(motion, size=SIZE) as preview:
        crops = []
        for f in (60, 130, 200):
            img = preview.frame(f, camera="front")
            pts = preview.project(
                preview.joint_positions(f)[
                    [motion.skeleton.index("right_wrist"), motion.skeleton.index("left_wrist")]
                ],
                f,
                camera="front",
            )
            for x, y in pts:
                x0 = int(np.clip(x - 40, 0, SIZE[0] - 80))
                y0 = int(np.clip(y - 40, 0, SIZE[1] - 80))
                crop = img[y0 : y0 + 80, x0 : x0 + 80]
                crops.append(np.kron(crop, np.ones((3, 3, 1), np.uint8)))
        write_image(contact_sheet(crops, columns=6), FIGURES / "beat_hands.png")
    return notes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repeats, print only")
    args = parser.parse_args()
    from engine.render.backend import ensure_platform

    platform = ensure_platform()
    from OpenGL import GL  # noqa: F401  (after the platform is chosen)

    repeats, per = (3, 5) if args.quick else (9, 10)
    r = bench_frames(repeats, per)
    ours_med, ours_min = statistics.median(r["ours"]), min(r["ours"])
    bare_med, bare_min = statistics.median(r["bare"]), min(r["bare"])
    ref_med, ref_min = statistics.median(r["ref"]), min(r["ref"])
    skin_med = statistics.median(r["skin"])
    mp4_s = bench_mp4(r["preview"], 300 if not args.quick else 60)
    notes = [] if args.quick else contact_sheets()
    lines = [
        "## Render (issue 7): skinned frames of the BEAT skeleton with fingers",
        "",
        f"`beat/1_wayne_0_1_1.bvh`: {r['joints']} joints (30 finger joints); mannequin "
        f"{r['vertices']} vertices, {r['triangles']} triangles; headless OpenGL: "
        f"{platform} (Mesa llvmpipe, CPU); {SIZE[0]}x{SIZE[1]}, three-quarter camera, floor on.",
        "",
        "| measure | ours, floor on (`Preview.frame`) | ours, no floor | reference, no floor "
        "(`Mesh.from_trimesh` per frame) | ratio ref / ours (no floor) | goal |",
        "|---|---|---|---|---|---|",
        f"| ms per frame, warm, median of {repeats}x{per} | {ours_med:.1f} | {bare_med:.1f} | "
        f"{ref_med:.1f} | {ref_med / bare_med:.2f} | < 60 |",
        f"| ms per frame, best run | {ours_min:.1f} | {bare_min:.1f} | {ref_min:.1f} | "
        f"{ref_min / bare_min:.2f} | |",
        f"| of which skinning (numpy LBS + normals), ms | {skin_med:.2f} | | | | |",
        f"| 10 s clip at 30 fps ({300 if not args.quick else 60} frames) to MP4, s | "
        f"{mp4_s:.1f} | | | | < 20 |",
        f"| build `Preview` (FK, anatomy, mannequin, weights, framing), s | "
        f"{r['build_s']:.2f} | | | | |",
        "",
        "Almost all of a frame is llvmpipe rasterising (pyrender's 4x MSAA, PBR shader, "
        f"3 lights); skinning is under 1 ms. The floor patch costs {ours_med - bare_med:.0f} ms "
        "of the median frame (its fragments are shaded like the body's; `floor=False` drops "
        "it). "
        "The reference builds the same posed mesh through trimesh and "
        "`pyrender.Mesh.from_trimesh` (which recomputes normals) and renders the same lights "
        "and camera. Timings are noisy: the 2-core machine is shared by ~7 engineers.",
    ]
    if notes:
        lines += [
            "",
            "Contact sheet of every BVH skeleton in ../shared/data/mocap "
            "(`benchmarks/figures/skeletons_contact_sheet.png`; BEAT finger close-ups "
            "in `benchmarks/figures/beat_hands.png`): " + "; ".join(notes) + ".",
        ]
    text = "\n".join(lines)
    print(text)
    if not args.quick:
        from benchmarks._results import write_section

        write_section("render", text)


if __name__ == "__main__":
    main()
