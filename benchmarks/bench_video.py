"""GIF/MP4 renders, this tree against a reference commit side by side (the renders issue).

    .venv/bin/python -m benchmarks.bench_video                 # 2 rounds, writes RESULTS.md "video"
    .venv/bin/python -m benchmarks.bench_video --quick         # 1 round, prints only
    .venv/bin/python -m benchmarks.bench_video --reference REV # another reference (default b3485ff)

The reference's ``engine`` and ``webapp`` are taken from git (``git archive REV``) into a
temporary folder; each measurement is a fresh process with one tree first on the path,
the two trees interleaved, so both see the same machine load. Workloads, on the take a
user reported (Bandai ``dataset-1_call_normal_001.bvh``, 171 frames at 30 fps):

* ``cli gif`` / ``cli mp4``: ``handsplice render TAKE -o OUT --quiet`` (640x480, the whole
  take), wall time of the process and its CPU time (all threads: llvmpipe's, the GIF
  quantiser's; ffmpeg's for MP4);
* ``app gif`` / ``app mp4``: the download buttons' ``webapp.backend.preview_video`` on
  the pair call + ``gestification/fingers-ok.bvh`` (three panels and the spliced hands
  close up, 1020x300; three panels, 720x272, before findings7), timed inside
  the process after the pair is opened and one frame rendered (as the server has).

The pictures: every frame of the two trees' CLI GIFs is compared pixel by pixel, and
``benchmarks/figures/video_before_after.png`` puts one frame of each side by side.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
MOCAP = Path(os.environ.get("HANDSPLICE_MOCAP", ROOT.parent / "shared" / "data" / "mocap"))
TAKE = MOCAP / "bandai-namco" / "dataset-1_call_normal_001.bvh"
HAND = MOCAP / "gestification" / "fingers-ok.bvh"
FIGURE = ROOT / "benchmarks" / "figures" / "video_before_after.png"
REFERENCE = "b3485ff"

#: the app's download, timed inside the process (prints a JSON line)
APP_SCRIPT = """
import json, resource, sys, time
from pathlib import Path
from webapp import backend
body, hand, fmt = Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3]
prepared = backend.prepare(body, hand, "right")
solution = backend.solve(prepared, None, None, [])
backend.render_frame(prepared, solution, 0, backend.VIDEO_CAMERA, False, backend.VIDEO_SIZE)
backend.render_closeup(prepared, solution, 0)  # the page's preview has drawn both
def cpu():
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime
c0, w0 = cpu(), time.perf_counter()
data = backend.preview_video(prepared, solution, fmt)
print(json.dumps({"wall": time.perf_counter() - w0, "cpu": cpu() - c0, "bytes": len(data)}))
"""


#: the profile behind the changes (cProfile with CPU time, b3485ff, 2026-12-02)
WHERE_THE_TIME_GOES = """Where a render's time goes (cProfile, CPU time, b3485ff; per 640x480 frame of
the CLI GIF, ~100 ms CPU): llvmpipe rasterising in `glReadPixels`'s wait ~50 ms (of which
the floor patch ~25 ms: the largest surface, every pixel PBR-shaded with three lights, a
third of its tiles fully transparent; the 4x MSAA ~30 ms of the whole, measured by
patching pyrender's sample count: keeping it, as dropping it makes the edges jagged),
pyrender's Python per frame (scene, nodes, uniforms, buffer upload) ~15 ms, the mannequin's
skinning and normals ~2 ms, Pillow's median-cut quantisation for the GIF ~25-35 ms (after
the last frame, with the progress bar already full), and starting the command (imports,
pyrender, the FK kernel) ~5 s CPU once. The app's three panels (720x272) cost ~200 ms CPU
a frame: raster ~60, pyrender's Python ~45 (three scenes), quantisation ~30.
Changed, each giving the same pictures: the floor's fully transparent tiles are not drawn;
the colour is read back without pyrender's depth readback and linearisation (the overlay
still reads depth); GIF frames are quantised on a worker thread as they are rendered
(Pillow releases the interpreter lock: the quantisation overlaps the rendering where a core
is free, and the bar's end is the file's end; the same GIF bytes, tested); the app's MP4 is
fed to ffmpeg frame by frame (it encoded after the last frame before). Wall times here
are dominated by the machine's load (load average 11-15 during the run: a process got a
fifth of a core); the CPU ratios are the figure to read. An in-process A/B of the app's
GIF (40 frames, threaded against serial quantisation, 3 interleaved repeats) gave the same
CPU (4.9 s each) and the same wall time at that load: the overlap only pays where a core
is idle. Left as they were, since each would change the pictures: the MSAA, the size, the
floor's shading.
"""


def _reference_tree(rev: str, folder: Path) -> Path:
    """``engine`` and ``webapp`` of ``rev`` under ``folder`` (git archive)."""
    archive = folder / "ref.tar"
    with archive.open("wb") as out:
        subprocess.run(
            ["git", "archive", rev, "engine", "webapp"], cwd=ROOT, stdout=out, check=True
        )
    with tarfile.open(archive) as tar:
        tar.extractall(folder / "tree", filter="data")
    return folder / "tree"


def _env(tree: Path) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(tree)
    env.setdefault("PYOPENGL_PLATFORM", "egl")
    env["NUMBA_CACHE_DIR"] = str(ROOT / ".numba_cache")
    return env


def _cli(tree: Path, out: Path) -> dict:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    cmd = [sys.executable, "-m", "engine.cli", "render", str(TAKE), "-o", str(out), "--quiet"]
    subprocess.run(cmd, env=_env(tree), check=True, cwd=tree)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"wall": wall, "cpu": cpu, "bytes": out.stat().st_size}


def _app(tree: Path, fmt: str) -> dict:
    done = subprocess.run(
        [sys.executable, "-c", APP_SCRIPT, str(TAKE), str(HAND), fmt],
        env=_env(tree),
        check=True,
        cwd=tree,
        capture_output=True,
        text=True,
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def _gif_frames(path: Path) -> list[np.ndarray]:
    from PIL import Image, ImageSequence

    with Image.open(path) as im:
        return [np.asarray(f.convert("RGB")) for f in ImageSequence.Iterator(im)]


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one round, print only")
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--reference", default=REFERENCE)
    args = parser.parse_args(argv)
    rounds = 1 if args.quick else args.rounds
    results: dict[tuple[str, str], list[dict]] = {}
    with tempfile.TemporaryDirectory(prefix="bench-video-") as tmp:
        folder = Path(tmp)
        trees = {"reference": _reference_tree(args.reference, folder), "this tree": ROOT}
        outs = {}
        for r in range(rounds):
            for work in ("cli gif", "cli mp4", "app gif", "app mp4"):
                for name, tree in trees.items():
                    fmt = work.split()[1]
                    if work.startswith("cli"):
                        out = folder / f"{name.replace(' ', '_')}_{r}.{fmt}"
                        got = _cli(tree, out)
                        outs[(name, fmt)] = out
                    else:
                        got = _app(tree, fmt)
                    results.setdefault((work, name), []).append(got)
                    print(
                        f"round {r + 1} {work:8s} {name:10s} wall {got['wall']:6.1f} s "
                        f"cpu {got['cpu']:6.1f} s  {got['bytes'] / 1024:.0f} KiB",
                        flush=True,
                    )
        ref, new = _gif_frames(outs[("reference", "gif")]), _gif_frames(outs[("this tree", "gif")])
        same_count = len(ref) == len(new)
        diffs = [np.abs(a.astype(int) - b.astype(int)) for a, b in zip(ref, new)]
        max_diff = max(int(d.max()) for d in diffs)
        changed = float(np.mean([(d.max(axis=2) > 0).mean() for d in diffs]))
        mid = len(ref) // 2
        from PIL import Image

        pair = np.concatenate(
            [ref[mid], np.full((ref[mid].shape[0], 8, 3), 255, np.uint8), new[mid]], 1
        )
        if not args.quick:
            Image.fromarray(pair).save(FIGURE)
        else:
            Image.fromarray(pair).save(folder.parent / "video_before_after.png")

    rows = []
    for work in ("cli gif", "cli mp4", "app gif", "app mp4"):
        r = results[(work, "reference")]
        n = results[(work, "this tree")]
        med = lambda xs, k: float(np.median([x[k] for x in xs]))  # noqa: E731
        rows.append(
            f"| {work} | {med(r, 'wall'):.1f} | {med(n, 'wall'):.1f} | "
            f"{med(n, 'wall') / med(r, 'wall'):.2f} | {med(r, 'cpu'):.1f} | {med(n, 'cpu'):.1f} | "
            f"{med(n, 'cpu') / med(r, 'cpu'):.2f} |"
        )
    text = (
        f"## GIF/MP4 renders: this tree against {args.reference}, side by side\n\n"
        f"`{TAKE.name}` (171 frames at 30 fps). CLI: `handsplice render TAKE -o OUT --quiet`, "
        "640x480, the whole process. App: `webapp.backend.preview_video` on the pair with "
        f"`{HAND.name}` (three panels, and since findings7 the spliced hands close up right "
        f"of them: 720x272 before, 1020x300 after), after the pair is open. Median of {rounds} "
        "interleaved rounds (fresh processes); CPU counts every thread and child (llvmpipe, "
        "the GIF quantiser, ffmpeg).\n\n"
        f"| render | {args.reference} wall, s | this tree wall, s | ratio | "
        f"{args.reference} CPU, s | this tree CPU, s | ratio |\n"
        "|---|---|---|---|---|---|---|\n" + "\n".join(rows) + "\n\n"
        f"Pictures: the CLI GIFs have {len(ref)} and {len(new)} frames "
        f"({'same' if same_count else 'different'} count); pixels that differ: "
        f"{100 * changed:.4f} % of a frame on average, by at most {max_diff} levels of 255 "
        "(the floor's fully transparent tiles are no longer drawn; the rounding of the "
        "blend at their edge). One frame of each: `benchmarks/figures/video_before_after.png` "
        f"(left {args.reference}, right this tree).\n\n" + WHERE_THE_TIME_GOES
    )
    print(text)
    if not args.quick:
        sys.path.insert(0, str(ROOT))
        from benchmarks._results import write_section

        write_section("video", text)


if __name__ == "__main__":
    main()
