"""Forward kinematics and resampling of ``Motion``.

FK: ``world_rot[j] = world_rot[parent] * local_rot[j]`` and
``world_pos[j] = world_pos[parent] + world_rot[parent] (local_translation[j])``.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from engine.model import rotations as rot
from engine.model.motion import Motion, Skeleton


def forward_kinematics(
    motion: Motion, start: int = 0, stop: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """World positions and rotations of every joint for frames ``[start, stop)``.

    Returns
    -------
    positions : (F, J, 3) float, file units
    rotations : (F, J, 4) float, unit quaternions (w, x, y, z)
    """
    local_r = motion.rotations[start:stop]
    local_t = motion.translations[start:stop]
    parents = motion.skeleton.parents
    world_r = np.empty_like(local_r)
    world_p = np.empty_like(local_t)
    for j, p in enumerate(parents):
        if p < 0:
            world_r[:, j] = local_r[:, j]
            world_p[:, j] = local_t[:, j]
        else:
            world_r[:, j] = rot.multiply(world_r[:, p], local_r[:, j])
            world_p[:, j] = world_p[:, p] + rot.rotate(world_r[:, p], local_t[:, j])
    return world_p, world_r


def end_site_positions(
    motion: Motion, world_pos: np.ndarray, world_rot: np.ndarray
) -> dict[int, np.ndarray]:
    """World positions ``(F, 3)`` of each joint's End Site, keyed by joint index."""
    return {
        j: world_pos[:, j] + rot.rotate(world_rot[:, j], off)
        for j, off in motion.skeleton.end_sites.items()
    }


def rest_positions(skeleton: Skeleton) -> np.ndarray:
    """(J, 3) world joint positions of the rest pose (offsets only, no rotation)."""
    pos = np.zeros((skeleton.n_joints, 3))
    for j, p in enumerate(skeleton.parents):
        pos[j] = skeleton.offsets[j] if p < 0 else pos[p] + skeleton.offsets[j]
    return pos


def sample(motion: Motion, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Local rotations and translations at fractional frame indices ``times (T,)``.

    Rotations are slerped and translations linearly interpolated between the two
    nearest frames; ``times`` are clipped to ``[0, F-1]``.

    Returns ``rotations (T, J, 4)`` and ``translations (T, J, 3)``.
    """
    f = motion.n_frames
    if f == 0:
        raise ValueError("sample: the motion has no frames")
    t = np.asarray(times, dtype=float)
    if t.ndim != 1 or not np.isfinite(t).all():
        raise ValueError(
            f"sample: times must be a 1-D array of finite frame indices, got shape {t.shape}"
        )
    t = np.clip(t, 0.0, f - 1)
    i0 = np.floor(t).astype(np.int64)
    i1 = np.minimum(i0 + 1, f - 1)
    w = (t - i0)[:, None]
    rots = rot.slerp(
        motion.rotations[i0],
        motion.rotations[i1],
        np.broadcast_to(w, (len(t), motion.skeleton.n_joints)),
    )
    trans = motion.translations[i0] * (1.0 - w[..., None]) + motion.translations[i1] * w[..., None]
    return rots, trans


def resample(motion: Motion, fps: float) -> Motion:
    """The same take at another frame rate (slerp for rotations, linear for translations).

    The output spans the same duration: ``round((F-1) * fps / motion.fps) + 1`` frames.
    """
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"resample: fps must be positive, got {fps}")
    f = motion.n_frames
    if f == 0:
        return replace(motion, fps=float(fps))
    n_out = max(1, int(round((f - 1) * fps / motion.fps)) + 1)
    times = np.arange(n_out) * (motion.fps / fps)
    rots, trans = sample(motion, times)
    return replace(motion, rotations=rots, translations=trans, fps=float(fps))
