"""Long body/hand pairs from real captures, bands in seconds, and today's code for comparison.

Used by ``bench_splice_speed`` and ``bench_dtw`` (issue 13).

* :func:`make_long_pair` - a ``seconds``-long pair at ``fps``: LAFAN1 takes
  (``multipleActions1``, ``dance1``; real captures, 30 fps) played one after the
  other (alternating, each shifted so the root continues where the last stopped)
  until long enough, resampled, given synthetic fingers; the body take without
  fingers, the hand take the same performance re-timed by a smooth random warp
  (``benchmarks.split.make_hand_take``: rate ``exp(0.2 n(t))``, ``n`` smooth
  noise of 1 s correlation), arms shrunk, trunk still, turned 20°, 0.5° noise.
  Returns the takes and the true hand frame of every body frame.
* :func:`pair_files` - the same pair written to BVH once and reused (the timing
  runs read them back, as the CLI does).
* :func:`band_fraction` - the fraction-of-n band width that gives a half-width of
  ``seconds`` (the engine's bands take fractions; engineer "rules" adds seconds).
* :func:`baseline_tree` - the engine as it was at ``BASELINE`` (``git archive``
  into a temporary folder, no change to the repository), for side-by-side runs.
"""

from __future__ import annotations

import os
import subprocess
import tarfile
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
#: the code issue 13 measured ("today"): main when the work began
BASELINE = os.environ.get("HANDSPLICE_BASELINE", "4c44a19")
CACHE = Path(tempfile.gettempdir()) / "handsplice-long-pairs"
SOURCES = ("lafan1/multipleActions1_subject1.bvh", "lafan1/dance1_subject1.bvh")


def _concatenate(parts):
    """Takes of one skeleton played one after another; each root continues (horizontally)
    from where the previous part stopped."""
    from engine.model.motion import Motion

    first = parts[0]
    sk = first.skeleton
    roots = np.flatnonzero(sk.parents < 0)
    up = 2 if first.meta.up_axis == "z" else 1
    rots, trans = [first.rotations], [first.translations]
    for part in parts[1:]:
        t = part.translations.copy()
        shift = trans[-1][-1, roots] - t[0, roots]
        shift[:, up] = 0.0
        t[:, roots] += shift
        rots.append(part.rotations)
        trans.append(t)
    return Motion(sk, np.concatenate(rots), np.concatenate(trans), first.fps, first.meta)


def trunk_tilt(motion) -> np.ndarray:
    """``(F,)`` degrees between the hips-to-neck (else head) vector and the up axis."""
    from engine.model.kinematics import forward_kinematics

    names = [n.lower() for n in motion.skeleton.names]
    top = next(j for j, n in enumerate(names) if n in ("neck", "head"))
    hips = int(np.flatnonzero(motion.skeleton.parents < 0)[0])
    pos = forward_kinematics(motion)[0]
    v = pos[:, top] - pos[:, hips]
    up = 2 if motion.meta.up_axis == "z" else 1
    cos = v[:, up] / np.maximum(np.linalg.norm(v, axis=1), 1e-12)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def typical_frame(motion) -> int:
    """The frame whose trunk tilt is nearest the take's median tilt (the performer's
    usual posture)."""
    tilt = trunk_tilt(motion)
    return int(np.argmin(np.abs(tilt - np.median(tilt))))


def make_long_pair(seconds: float, fps: float = 120.0, seed: int = 0, still: str = "middle"):
    """(body, hand, truth): takes of ``seconds`` at ``fps`` and the true hand frame
    ``(n,)`` of every body frame (see the module docstring). ``still``: the hand take's
    trunk and legs hold the middle frame's pose (``"middle"``, the split bench's rule) or
    the :func:`typical_frame`'s (``"typical"``)."""
    from engine.io.bvh import read_bvh
    from engine.model.kinematics import resample
    from engine.model.roles import find_roles

    try:
        from benchmarks.split import MOCAP, add_fingers, make_hand_take, strip_fingers
    except ImportError:  # the baseline tree (git archive BASELINE) had it in the package
        from engine.splice.split import MOCAP, add_fingers, make_hand_take, strip_fingers

    takes = [read_bvh(MOCAP / s) for s in SOURCES]
    base_fps = takes[0].fps
    need = int(round(seconds * base_fps)) + 1
    parts, have, k = [], 0, 0
    while have < need:
        part = takes[k % len(takes)]
        part = part.frames(0, min(part.n_frames, need - have))
        parts.append(part)
        have += part.n_frames
        k += 1
    base = _concatenate(parts)
    if fps != base_fps:
        base = resample(base, fps)
    base = base.frames(0, int(round(seconds * fps)))
    rng = np.random.default_rng(seed)
    full = add_fingers(base, rng)
    roles = find_roles(full.skeleton)
    body = strip_fingers(full, roles)
    hand, hand_t, orig_t = make_hand_take(
        full,
        rng,
        fps=fps,
        scale=1.0,
        warp_sigma=0.2,
        shrink=0.6,
        yaw_deg=20.0,
        noise_deg=0.5,
        roles=roles,
        still_frame=None if still == "middle" else typical_frame(full),
    )
    body_t = np.arange(body.n_frames) / body.fps
    truth = np.interp(body_t, orig_t, hand_t) * hand.fps
    body, hand = _exact_offsets(body), _exact_offsets(hand)
    body = replace(body, meta=replace(body.meta, source=f"long{seconds:g}s-body.bvh"))
    hand = replace(hand, meta=replace(hand.meta, source=f"long{seconds:g}s-hand.bvh"))
    return body, hand, truth


def _exact_offsets(motion):
    """Joints without position channels sit exactly at their OFFSET (interpolation leaves
    1e-6 of rounding, which BVH cannot hold)."""
    sk = motion.skeleton
    trans = motion.translations.copy()
    for j in range(sk.n_joints):
        if not sk.has_position_channels(j):
            trans[:, j] = sk.offsets[j]
    return replace(motion, translations=trans)


def pair_files(seconds: float, fps: float = 120.0, seed: int = 0) -> tuple[Path, Path, Path]:
    """BVH files (body, hand) and ``truth.npy`` of :func:`make_long_pair`, made once."""
    from engine.io.bvh import write_bvh

    folder = CACHE / f"{seconds:g}s-{fps:g}fps-{seed}"
    body_p, hand_p, truth_p = folder / "body.bvh", folder / "hand.bvh", folder / "truth.npy"
    if not truth_p.exists():
        folder.mkdir(parents=True, exist_ok=True)
        body, hand, truth = make_long_pair(seconds, fps, seed)
        write_bvh(body, body_p)
        write_bvh(hand, hand_p)
        np.save(truth_p, truth)
    return body_p, hand_p, truth_p


def band_fraction(n: int, m: int, fps: float, seconds: float) -> float:
    """Band width (fraction of ``n``, as ``Band.from_constraints`` and ``refine_radius``
    read it) whose vertical half-width is ``seconds`` of hand frames at ``fps``."""
    return 2.0 * seconds * fps / float(np.hypot(n, m))


def drift_seconds(truth: np.ndarray, m: int, fps: float) -> float:
    """Largest distance (s) of the true path from the band's centre line."""
    n = truth.shape[0]
    centre = (np.arange(n) + 1.0) * m / n - 1.0
    return float(np.max(np.abs(truth - centre)) / fps)


def baseline_tree(
    ref: str = BASELINE, parts: tuple[str, ...] = ("engine", "benchmarks"), name: str = "baseline"
) -> Path:
    """A folder ``CACHE/NAME-SHA`` holding the folders ``parts`` as at ``ref`` (made once)."""
    sha = subprocess.run(
        ["git", "rev-parse", "--short", ref], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout.strip()
    folder = CACHE / f"{name}-{sha}"
    if not all((folder / part).is_dir() for part in parts):
        folder.mkdir(parents=True, exist_ok=True)
        tar = subprocess.run(
            ["git", "archive", "--format=tar", sha, *parts],
            cwd=ROOT,
            capture_output=True,
            check=True,
        ).stdout
        with tempfile.TemporaryFile() as fh:
            fh.write(tar)
            fh.seek(0)
            with tarfile.open(fileobj=fh) as tf:
                tf.extractall(folder, filter="data")
    return folder


def run_child(code: str, *args: str, tree: Path | None = None, timeout: float = 3600) -> dict:
    """Run ``code`` in a fresh interpreter with ``tree`` (default: this checkout) first on
    the path; returns the JSON object it prints last."""
    import json
    import sys

    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(tree or ROOT), str(ROOT)])
    if tree is not None:  # its own numba cache (other code, same function names)
        env["NUMBA_CACHE_DIR"] = str(Path(tree) / ".numba_cache")
    out = subprocess.run(
        [sys.executable, "-c", code, *args],
        cwd=tree or ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )
    if out.returncode != 0:
        raise RuntimeError(f"child failed ({out.returncode}): {out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])
