"""A take's world joint rotations, made when read instead of kept.

The transfer reads the body's world rotations block by block, and the hand-spin rows one
joint of them: keeping them for every frame costs 32 bytes a joint a frame (48 MB for a
22-joint body take of 72,000 frames). :class:`WorldRotations` is that ``(F, J, 4)`` array
for reading: indexing runs the forward kinematics (``engine.model.fastkin``) of the frames
indexed, :data:`CHUNK` frames at a time, and keeps only what was asked for. Every frame
is computed on its own, so the values are the same floats as
``fastkin.forward_kinematics(motion)[1]``.
"""

from __future__ import annotations

import numpy as np

from engine.model.fastkin import forward_kinematics
from engine.model.motion import Motion

#: frames posed at a time when a read spans many (a few MB of temporaries)
CHUNK = 4096


class WorldRotations:
    """``(F, J, 4)`` float64 world rotations ``(w, x, y, z)`` of ``motion``'s joints."""

    __slots__ = ("motion",)

    def __init__(self, motion: Motion):
        self.motion = motion

    @property
    def shape(self) -> tuple[int, int, int]:
        return (self.motion.n_frames, self.motion.skeleton.n_joints, 4)

    @property
    def ndim(self) -> int:
        return 3

    @property
    def dtype(self) -> np.dtype:
        return np.dtype(np.float64)

    def __len__(self) -> int:
        return self.shape[0]

    def __array__(self, dtype=None, copy=None):
        out = self[:]
        return out if dtype is None else out.astype(dtype, copy=False)

    def __getitem__(self, key):
        key = key if isinstance(key, tuple) else (key,)
        first = key[0] if key else slice(None)
        rest = key[1:]
        if first is Ellipsis or first is None or any(np.ndim(k) > 0 for k in rest):
            return np.asarray(self)[key]  # numpy's rules for these (the whole array)
        frames = np.arange(self.shape[0])[first]
        if frames.ndim == 0:
            return forward_kinematics(self.motion, int(frames))[1][0][rest]
        if frames.ndim != 1:
            return np.asarray(self)[key]
        out = None
        for a in range(0, max(frames.size, 1), CHUNK):
            part = frames[a : a + CHUNK]
            step = part[1] - part[0] if part.size > 1 else 1
            if (
                part.size
                and step > 0
                and np.array_equal(part, part[0] + step * np.arange(part.size))
            ):
                which = slice(int(part[0]), int(part[-1]) + 1, int(step))
            else:
                which = part
            block = forward_kinematics(self.motion, which)[1][(slice(None),) + rest]
            if out is None:
                out = np.empty((frames.size,) + block.shape[1:])
            out[a : a + part.size] = block
        return out
