"""Quaternion and Euler-angle helpers (vectorised numpy).

Conventions
-----------
* Quaternions are ``(..., 4)`` float arrays ordered ``(w, x, y, z)``, unit norm.
* Rotation matrices act on column vectors: ``v_world = R @ v_local``.
* An Euler order such as ``"ZXY"`` lists BVH rotation channels in file order; the
  rotation is ``R = R_Z(a0) @ R_X(a1) @ R_Y(a2)`` (intrinsic, as BVH readers in
  Blender and MotionBuilder apply it). Angles are degrees at the API.
"""

from __future__ import annotations

import numpy as np

_AXIS = {"X": 0, "Y": 1, "Z": 2}


def identity(shape: tuple[int, ...] = ()) -> np.ndarray:
    """Identity quaternions of ``shape + (4,)``."""
    q = np.zeros(shape + (4,))
    q[..., 0] = 1.0
    return q


def normalize(q: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(..., 4)``; zero-norm inputs become identity."""
    q = np.asarray(q, dtype=float)
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    out = np.where(n > 0, q / np.where(n > 0, n, 1.0), identity(q.shape[:-1]))
    return out


def multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a * b`` (rotation b first, then a), broadcast ``(..., 4)``."""
    aw, ax, ay, az = np.moveaxis(np.asarray(a, dtype=float), -1, 0)
    bw, bx, by, bz = np.moveaxis(np.asarray(b, dtype=float), -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def conjugate(q: np.ndarray) -> np.ndarray:
    """Inverse of unit quaternions ``(..., 4)``."""
    q = np.asarray(q, dtype=float)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors ``v (..., 3)`` by unit quaternions ``q (..., 4)``."""
    q = np.asarray(q, dtype=float)
    v = np.asarray(v, dtype=float)
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def from_axis_angle(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Quaternions from unit ``axis (..., 3)`` and ``angle (...)`` in radians."""
    axis = np.asarray(axis, dtype=float)
    half = 0.5 * np.asarray(angle, dtype=float)[..., None]
    return np.concatenate([np.cos(half), np.sin(half) * axis], axis=-1)


def to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices ``(..., 3, 3)`` from quaternions ``(..., 4)``."""
    w, x, y, z = np.moveaxis(normalize(q), -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=-2,
    )


def from_matrix(m: np.ndarray) -> np.ndarray:
    """Quaternions ``(..., 4)`` (w >= 0) from rotation matrices ``(..., 3, 3)``."""
    m = np.asarray(m, dtype=float)
    t = np.stack(
        [
            1 + m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2],
            1 + m[..., 0, 0] - m[..., 1, 1] - m[..., 2, 2],
            1 - m[..., 0, 0] + m[..., 1, 1] - m[..., 2, 2],
            1 - m[..., 0, 0] - m[..., 1, 1] + m[..., 2, 2],
        ],
        axis=-1,
    )
    k = np.argmax(t, axis=-1)
    s = np.sqrt(np.maximum(np.take_along_axis(t, k[..., None], -1)[..., 0], 1e-300)) * 2.0
    q = np.empty(m.shape[:-2] + (4,))
    c0, c1, c2, c3 = (k == 0), (k == 1), (k == 2), (k == 3)
    q[..., 0] = np.select(
        [c0, c1, c2, c3],
        [
            s / 4,
            (m[..., 2, 1] - m[..., 1, 2]) / s,
            (m[..., 0, 2] - m[..., 2, 0]) / s,
            (m[..., 1, 0] - m[..., 0, 1]) / s,
        ],
    )
    q[..., 1] = np.select(
        [c0, c1, c2, c3],
        [
            (m[..., 2, 1] - m[..., 1, 2]) / s,
            s / 4,
            (m[..., 0, 1] + m[..., 1, 0]) / s,
            (m[..., 0, 2] + m[..., 2, 0]) / s,
        ],
    )
    q[..., 2] = np.select(
        [c0, c1, c2, c3],
        [
            (m[..., 0, 2] - m[..., 2, 0]) / s,
            (m[..., 0, 1] + m[..., 1, 0]) / s,
            s / 4,
            (m[..., 1, 2] + m[..., 2, 1]) / s,
        ],
    )
    q[..., 3] = np.select(
        [c0, c1, c2, c3],
        [
            (m[..., 1, 0] - m[..., 0, 1]) / s,
            (m[..., 0, 2] + m[..., 2, 0]) / s,
            (m[..., 1, 2] + m[..., 2, 1]) / s,
            s / 4,
        ],
    )
    q = normalize(q)
    return np.where(q[..., :1] < 0, -q, q)


def check_order(order: str) -> str:
    """Return ``order`` upper-cased if it is a 3-letter permutation of XYZ, else raise."""
    o = order.upper()
    if len(o) != 3 or sorted(o) != ["X", "Y", "Z"]:
        raise ValueError(f"rotation order {order!r}: expected a permutation of 'XYZ'")
    return o


def from_euler(angles_deg: np.ndarray, order: str) -> np.ndarray:
    """Quaternions ``(..., 4)`` from Euler angles ``(..., 3)`` in degrees, BVH channel order."""
    order = check_order(order)
    a = np.radians(np.asarray(angles_deg, dtype=float))
    q = identity(a.shape[:-1])
    for k, ax in enumerate(order):
        axis = np.zeros(3)
        axis[_AXIS[ax]] = 1.0
        q = multiply(q, from_axis_angle(axis, a[..., k]))
    return q


def to_euler(q: np.ndarray, order: str) -> np.ndarray:
    """Euler angles ``(..., 3)`` in degrees (BVH channel order) from quaternions.

    Inverse of :func:`from_euler`: the middle angle lies in [-90, 90] degrees (up to
    rounding), the others in [-180, 180]. Accurate to ~1e-12 degrees everywhere,
    including at and near gimbal lock, where the first angle is taken from the matrix
    and the last one absorbs the rest of the rotation.
    """
    order = check_order(order)
    m = to_matrix(q)
    i, j, k = (_AXIS[c] for c in order)
    # R = R_i(a) R_j(b) R_k(c); the permutation's parity decides the signs below
    p = 1.0 if (j - i) % 3 == 1 else -1.0
    a = np.arctan2(-p * m[..., j, k], m[..., k, k])
    ca, sa = np.cos(a), np.sin(a)
    # N = R_i(-a) R = R_j(b) R_k(c): b and c from well-conditioned entries of N
    n_ji = ca * m[..., j, i] + p * sa * m[..., k, i]
    n_jj = ca * m[..., j, j] + p * sa * m[..., k, j]
    n_kk = -p * sa * m[..., j, k] + ca * m[..., k, k]
    b = np.arctan2(p * m[..., i, k], n_kk)
    c = np.arctan2(p * n_ji, n_jj)
    return np.degrees(np.stack([a, b, c], axis=-1))


def slerp(q0: np.ndarray, q1: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Spherical interpolation, shortest arc; ``t`` broadcast against ``q (..., 4)``'s leading axes."""
    q0 = normalize(q0)
    q1 = normalize(q1)
    t = np.asarray(t, dtype=float)[..., None]
    dot = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(dot < 0, -q1, q1)
    dot = np.abs(dot)
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    sin_t = np.sin(theta)
    small = sin_t < 1e-6
    w0 = np.where(small, 1.0 - t, np.sin((1.0 - t) * theta) / np.where(small, 1.0, sin_t))
    w1 = np.where(small, t, np.sin(t * theta) / np.where(small, 1.0, sin_t))
    return normalize(w0 * q0 + w1 * q1)


def angle_between(q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
    """Geodesic angle in degrees between rotations ``(..., 4)`` (accurate near zero)."""
    d = multiply(conjugate(normalize(q0)), normalize(q1))
    return np.degrees(2.0 * np.arctan2(np.linalg.norm(d[..., 1:], axis=-1), np.abs(d[..., 0])))


def make_continuous(q: np.ndarray, axis: int = 0) -> np.ndarray:
    """Flip quaternion signs along ``axis`` (time) so consecutive samples lie in one hemisphere."""
    q = np.array(q, dtype=float, copy=True)
    q = np.moveaxis(q, axis, 0)
    for f in range(1, q.shape[0]):
        flip = np.sum(q[f] * q[f - 1], axis=-1) < 0
        q[f][flip] *= -1.0
    return np.moveaxis(q, 0, axis)
