"""Numba versions of the kinematics the splice runs on every call.

Same conventions and results as :mod:`engine.model.kinematics` and :mod:`engine.model.rotations`
(quaternions ``(w, x, y, z)``; ``tests/test_features.py`` compares them), without
numpy's per-call overhead, which dominates for a few hundred frames:

* :func:`forward_kinematics` - world positions and rotations of every joint;
* :func:`qmul`, :func:`qmul_conj` - batched quaternion products ``a * b`` and
  ``a^-1 * b`` over ``(F, K, 4)`` arrays;
* :func:`continuous` - flip quaternion signs so consecutive frames share a hemisphere
  (:func:`continuous_inplace` without copies).
"""

from __future__ import annotations

import numba
import numpy as np

from engine.base.jit import FASTMATH
from engine.model.motion import Motion
from engine.model.translations import Translations

_FASTMATH = set(FASTMATH)  # engine.base.jit: the one place for numba options


@numba.njit(cache=True, fastmath=_FASTMATH, inline="always")
def _mul(aw, ax, ay, az, bw, bx, by, bz):
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


@numba.njit(cache=True, fastmath=_FASTMATH)
def _fk_kernel(rot, trans, parents, wpos, wrot):
    frames, joints = rot.shape[0], rot.shape[1]
    for f in range(frames):
        for j in range(joints):
            p = parents[j]
            if p < 0:
                for c in range(4):
                    wrot[f, j, c] = rot[f, j, c]
                for c in range(3):
                    wpos[f, j, c] = trans[f, j, c]
                continue
            qw, qx, qy, qz = wrot[f, p, 0], wrot[f, p, 1], wrot[f, p, 2], wrot[f, p, 3]
            w, x, y, z = _mul(
                qw, qx, qy, qz, rot[f, j, 0], rot[f, j, 1], rot[f, j, 2], rot[f, j, 3]
            )
            wrot[f, j, 0] = w
            wrot[f, j, 1] = x
            wrot[f, j, 2] = y
            wrot[f, j, 3] = z
            # rotate the local translation by the parent's world rotation
            vx, vy, vz = trans[f, j, 0], trans[f, j, 1], trans[f, j, 2]
            tx = 2.0 * (qy * vz - qz * vy)
            ty = 2.0 * (qz * vx - qx * vz)
            tz = 2.0 * (qx * vy - qy * vx)
            wpos[f, j, 0] = wpos[f, p, 0] + vx + qw * tx + (qy * tz - qz * ty)
            wpos[f, j, 1] = wpos[f, p, 1] + vy + qw * ty + (qz * tx - qx * tz)
            wpos[f, j, 2] = wpos[f, p, 2] + vz + qw * tz + (qx * ty - qy * tx)


def forward_kinematics(motion: Motion, frames=None) -> tuple[np.ndarray, np.ndarray]:
    """World positions ``(F, J, 3)`` (file units) and rotations ``(F, J, 4)`` of every joint.

    ``frames``: only these frames (a slice, an int array, or an int: then ``(1, J, ...)``);
    each frame's values are the same floats as in the whole take's (frames are independent),
    and a slice of a contiguous take is read in place (no copy of the take)."""
    trans = motion.translations
    if not isinstance(trans, Translations):  # a plain array is the caller's: not written
        trans = np.array(trans, dtype=np.float64)
    rot = motion.rotations
    if frames is not None:
        if isinstance(frames, (int, np.integer)):
            f = int(frames) % max(rot.shape[0], 1)
            frames = slice(f, f + 1)
        rot, trans = rot[frames], trans[frames]
    rot = np.ascontiguousarray(rot, dtype=np.float64)
    # ``trans``: the local translations of the frames asked for, a fresh array (Translations
    # makes one when read). The kernel reads trans[f, j] before it writes wpos[f, j] and
    # never after, so they become the world positions in place (no second (F, J, 3) array)
    wpos = np.ascontiguousarray(np.asarray(trans), dtype=np.float64)
    parents = np.ascontiguousarray(motion.skeleton.parents, dtype=np.int64)
    wrot = np.zeros(rot.shape)
    _fk_kernel(rot, wpos, parents, wpos, wrot)
    return wpos, wrot


@numba.njit(cache=True, fastmath=_FASTMATH)
def _qmul_kernel(a, b, out, conj_a):
    s = -1.0 if conj_a else 1.0
    for i in range(a.shape[0]):
        w, x, y, z = _mul(
            a[i, 0], s * a[i, 1], s * a[i, 2], s * a[i, 3], b[i, 0], b[i, 1], b[i, 2], b[i, 3]
        )
        out[i, 0] = w
        out[i, 1] = x
        out[i, 2] = y
        out[i, 3] = z


def _batched(a, b, conj_a: bool) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    shape = np.broadcast_shapes(a.shape, b.shape)
    a2 = np.ascontiguousarray(np.broadcast_to(a, shape)).reshape(-1, 4)
    b2 = np.ascontiguousarray(np.broadcast_to(b, shape)).reshape(-1, 4)
    out = np.empty(a2.shape)  # every entry written by the kernel
    _qmul_kernel(a2, b2, out, conj_a)
    return out.reshape(shape)


@numba.njit(cache=True, nogil=True)
def _rotate_offset_kernel(q, v, out):
    """IEEE arithmetic (no fast-math) in :func:`engine.model.rotations.rotate`'s order."""
    v0, v1, v2 = v[0], v[1], v[2]
    for f in range(q.shape[0]):
        w, u0, u1, u2 = q[f, 0], q[f, 1], q[f, 2], q[f, 3]
        t0 = 2.0 * (u1 * v2 - u2 * v1)
        t1 = 2.0 * (u2 * v0 - u0 * v2)
        t2 = 2.0 * (u0 * v1 - u1 * v0)
        out[f, 0] = (v0 + w * t0) + (u1 * t2 - u2 * t1)
        out[f, 1] = (v1 + w * t1) + (u2 * t0 - u0 * t2)
        out[f, 2] = (v2 + w * t2) + (u0 * t1 - u1 * t0)


def rotate_offset(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """One offset ``v (3,)`` turned by every unit quaternion ``q (F, 4)``: ``(F, 3)``, the
    same floats as ``engine.model.rotations.rotate(q, v)`` in one pass (no cross-product
    temporaries)."""
    q = np.ascontiguousarray(q, dtype=np.float64)
    out = np.empty((q.shape[0], 3))
    _rotate_offset_kernel(q, np.asarray(v, dtype=np.float64), out)
    return out


def qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a * b`` for broadcastable ``(..., 4)`` quaternion arrays."""
    return _batched(a, b, False)


def qmul_conj(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a^-1 * b`` (``a`` unit) for broadcastable ``(..., 4)`` quaternion arrays."""
    return _batched(a, b, True)


def continuous(q: np.ndarray) -> np.ndarray:
    """Quaternions ``(F, ..., 4)`` with signs flipped so frame ``f`` and ``f-1`` have a
    non-negative dot product (as :func:`engine.model.rotations.make_continuous`)."""
    q = np.array(q, dtype=float, copy=True)
    if q.shape[0] < 2:
        return q
    dots = np.sum(q[1:] * q[:-1], axis=-1)
    flips = np.where(dots < 0, -1.0, 1.0)
    sign = np.concatenate([np.ones((1,) + flips.shape[1:]), np.cumprod(flips, axis=0)], axis=0)
    return q * sign[..., None]


@numba.njit(cache=True, nogil=True)
def _continuous_kernel(q):
    """Frame by frame (each frame's joints after the previous frame's: memory order; a
    joint's frames are still corrected in order, so the flips are the same)."""
    frames, joints = q.shape[0], q.shape[1]
    for f in range(1, frames):
        for j in range(joints):
            d = (
                q[f, j, 0] * q[f - 1, j, 0]
                + q[f, j, 1] * q[f - 1, j, 1]
                + q[f, j, 2] * q[f - 1, j, 2]
                + q[f, j, 3] * q[f - 1, j, 3]
            )
            if d < 0.0:
                for c in range(4):
                    q[f, j, c] = -q[f, j, c]


def continuous_inplace(q: np.ndarray) -> None:
    """:func:`continuous` in place for a C-contiguous float64 ``(F, J, 4)`` array (no copies:
    frame ``f`` is flipped when its dot product with the already corrected ``f - 1`` is
    negative, which is the same sign as :func:`continuous`'s cumulative product)."""
    if q.ndim != 3 or q.shape[-1] != 4 or q.dtype != np.float64 or not q.flags.c_contiguous:
        raise ValueError(
            f"continuous_inplace: need a C-contiguous float64 (F, J, 4) array, "
            f"got {q.dtype} {q.shape}"
        )
    _continuous_kernel(q)


@numba.njit(cache=True, fastmath=_FASTMATH, inline="always")
def _unit4(w, x, y, z):
    n = np.sqrt(w * w + x * x + y * y + z * z)
    if n > 0.0:
        return w / n, x / n, y / n, z / n
    return 1.0, 0.0, 0.0, 0.0


@numba.njit(cache=True, fastmath=_FASTMATH, inline="always")
def _slerp(rot, i0, i1, w, j):
    """Joint ``j``'s rotation at fraction ``w`` between frames ``i0`` and ``i1`` (unit)."""
    aw, ax, ay, az = _unit4(rot[i0, j, 0], rot[i0, j, 1], rot[i0, j, 2], rot[i0, j, 3])
    bw, bx, by, bz = _unit4(rot[i1, j, 0], rot[i1, j, 1], rot[i1, j, 2], rot[i1, j, 3])
    dot = aw * bw + ax * bx + ay * by + az * bz
    if dot < 0.0:
        bw, bx, by, bz, dot = -bw, -bx, -by, -bz, -dot
    theta = np.arccos(min(dot, 1.0))
    s = np.sin(theta)
    if s < 1e-6:
        w0, w1 = 1.0 - w, w
    else:
        w0, w1 = np.sin((1.0 - w) * theta) / s, np.sin(w * theta) / s
    return _unit4(w0 * aw + w1 * bw, w0 * ax + w1 * bx, w0 * ay + w1 * by, w0 * az + w1 * bz)


@numba.njit(cache=True, fastmath=_FASTMATH, inline="always")
def _frame_pair(tk, frames):
    """Frames ``(i0, i1)`` around fractional frame ``tk`` (clipped to the take) and the
    fraction between them."""
    tk = min(max(tk, 0.0), frames - 1.0)
    i0 = int(np.floor(tk))
    return i0, min(i0 + 1, frames - 1), tk - i0


@numba.njit(cache=True, fastmath=_FASTMATH, nogil=True)
def _sample_kernel(rot, trans, t, out_r, out_t):
    frames = rot.shape[0]
    for k in range(t.shape[0]):
        i0, i1, w = _frame_pair(t[k], frames)
        for j in range(rot.shape[1]):
            qw, qx, qy, qz = _slerp(rot, i0, i1, w, j)
            out_r[k, j, 0] = qw
            out_r[k, j, 1] = qx
            out_r[k, j, 2] = qy
            out_r[k, j, 3] = qz
            for c in range(3):
                out_t[k, j, c] = trans[i0, j, c] * (1.0 - w) + trans[i1, j, c] * w


def sample(motion: Motion, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`engine.model.kinematics.sample` (slerp / linear at fractional frames ``times (T,)``,
    clipped to the take) in one numba loop: ``(T, J, 4)`` rotations, ``(T, J, 3)``
    translations (equal to rounding)."""
    if motion.n_frames == 0:
        raise ValueError("sample: the motion has no frames")
    t = np.ascontiguousarray(times, dtype=np.float64)
    if t.ndim != 1 or not np.isfinite(t).all():
        raise ValueError(
            f"sample: times must be a 1-D array of finite frame indices, got shape {t.shape}"
        )
    rot = np.ascontiguousarray(motion.rotations, dtype=np.float64)
    trans = np.ascontiguousarray(motion.translations, dtype=np.float64)
    out_r = np.empty((t.shape[0],) + rot.shape[1:])
    out_t = np.empty((t.shape[0],) + trans.shape[1:])
    _sample_kernel(rot, trans, t, out_r, out_t)
    return out_r, out_t


@numba.njit(cache=True, fastmath=_FASTMATH, nogil=True)
def _sample_rotations_kernel(rot, t, joints, out_r):
    frames = rot.shape[0]
    for k in range(t.shape[0]):
        i0, i1, w = _frame_pair(t[k], frames)
        for a in range(joints.shape[0]):
            qw, qx, qy, qz = _slerp(rot, i0, i1, w, joints[a])
            out_r[k, a, 0] = qw
            out_r[k, a, 1] = qx
            out_r[k, a, 2] = qy
            out_r[k, a, 3] = qz


def sample_rotations(motion: Motion, times: np.ndarray, joints: np.ndarray) -> np.ndarray:
    """:func:`sample`'s rotations of ``joints`` only: ``(T, len(joints), 4)``, the same floats
    (no translations)."""
    t = np.ascontiguousarray(times, dtype=np.float64)
    if motion.n_frames == 0 or t.ndim != 1 or not np.isfinite(t).all():
        return sample(motion, times)[0][:, joints]  # sample's errors
    rot = np.ascontiguousarray(motion.rotations, dtype=np.float64)
    out_r = np.empty((t.shape[0], len(joints), 4))
    _sample_rotations_kernel(rot, t, np.ascontiguousarray(joints, dtype=np.int64), out_r)
    return out_r


@numba.njit(cache=True, nogil=True)
def _place_body_kernel(rots, trans, body_rot, body_trans, offsets, delta, index):
    for f in range(rots.shape[0]):
        for j in range(rots.shape[1]):
            rots[f, j, 0] = 1.0
            for c in range(1, 4):
                rots[f, j, c] = 0.0
            for c in range(3):
                trans[f, j, c] = offsets[j, c]
        for k in range(index.shape[0]):
            o = index[k]
            for c in range(4):
                rots[f, o, c] = body_rot[f, k, c]
            for c in range(3):
                trans[f, o, c] = body_trans[f, k, c] + delta[k, c]


def place_body(rots, trans, body_rot, body_trans, offsets, delta, index) -> None:
    """Frames of an output take with more joints than the body, in place (one pass):
    every joint at the identity rotation and its rest ``offsets (J, 3)``, then body joint
    ``k`` at output joint ``index[k]`` with the body's rotation and translation plus
    ``delta[k]`` (``rots (F, J, 4)``, ``trans (F, J, 3)`` C-contiguous float64;
    ``body_rot (F, K, 4)``, ``body_trans (F, K, 3)``)."""
    _place_body_kernel(
        rots,
        trans,
        np.ascontiguousarray(body_rot, dtype=np.float64),
        np.ascontiguousarray(body_trans, dtype=np.float64),
        np.ascontiguousarray(offsets, dtype=np.float64),
        np.ascontiguousarray(delta, dtype=np.float64),
        np.ascontiguousarray(index, dtype=np.int64),
    )


@numba.njit(cache=True, fastmath=_FASTMATH)
def _world_rotations_kernel(rot, parents, wrot):
    """:func:`_fk_kernel`'s rotations alone."""
    for f in range(rot.shape[0]):
        for j in range(rot.shape[1]):
            p = parents[j]
            if p < 0:
                for c in range(4):
                    wrot[f, j, c] = rot[f, j, c]
                continue
            w, x, y, z = _mul(
                wrot[f, p, 0],
                wrot[f, p, 1],
                wrot[f, p, 2],
                wrot[f, p, 3],
                rot[f, j, 0],
                rot[f, j, 1],
                rot[f, j, 2],
                rot[f, j, 3],
            )
            wrot[f, j, 0] = w
            wrot[f, j, 1] = x
            wrot[f, j, 2] = y
            wrot[f, j, 3] = z


def world_rotations(local: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """World rotations ``(F, J, 4)`` of local rotations ``(F, J, 4)`` (``parents (J,)``: each
    parent before its children, -1 for a root): :func:`forward_kinematics`' rotations, the
    same floats, without the positions."""
    rot = np.ascontiguousarray(local, dtype=np.float64)
    wrot = np.empty(rot.shape)
    _world_rotations_kernel(rot, np.ascontiguousarray(parents, dtype=np.int64), wrot)
    return wrot


@numba.njit(cache=True, fastmath=_FASTMATH, nogil=True)
def _normalize_kernel(q):
    for f in range(q.shape[0]):
        for j in range(q.shape[1]):
            w, x, y, z = _unit4(q[f, j, 0], q[f, j, 1], q[f, j, 2], q[f, j, 3])
            q[f, j, 0] = w
            q[f, j, 1] = x
            q[f, j, 2] = y
            q[f, j, 3] = z


def normalize_inplace(q: np.ndarray) -> None:
    """Unit quaternions in place (C-contiguous float64 ``(F, J, 4)``); zero -> identity."""
    if q.ndim != 3 or q.shape[-1] != 4 or q.dtype != np.float64 or not q.flags.c_contiguous:
        raise ValueError(
            f"normalize_inplace: need a C-contiguous float64 (F, J, 4) array, "
            f"got {q.dtype} {q.shape}"
        )
    _normalize_kernel(q)
