"""A take's local joint translations, its constant joints stored once.

In most takes only the root moves: every other joint's translation is its bone offset,
the same in every frame (a 10-minute 120 fps take with fingers: 86 MB of float64
repeating 52 rows). :class:`Translations` is the ``(F, J, 3)`` array of ``Motion``
stored as the values of its constant joints ``fixed (J, 3)`` and the frames of the
others ``moving (F, K, 3)`` (``joints (K,)`` ascending), and behaves as that array for
reading: indexing, ``np.asarray``, arithmetic and numpy functions give plain arrays
whose values are those of the whole array, bit for bit (only the frames and joints
indexed are made). It is not written through: ``copy()`` gives a plain array to change.
``frames`` and ``scaled`` give a ``Translations`` again (a take's frames, a take mirrored
or in other units) without making the whole array.
"""

from __future__ import annotations

import numpy as np
from numpy.lib.mixins import NDArrayOperatorsMixin


class Translations(NDArrayOperatorsMixin):
    """``(F, J, 3)`` float64 translations: ``fixed (J, 3)`` for every frame except at
    ``joints (K,)``, whose frames are ``moving (F, K, 3)``.

    ``fixed[joints]`` is not read (kept as frame 0's values where there is a frame)."""

    __slots__ = ("fixed", "joints", "moving")
    __array_priority__ = 20.0

    def __init__(self, fixed: np.ndarray, joints: np.ndarray, moving: np.ndarray):
        fixed = np.array(fixed, dtype=np.float64).reshape(-1, 3)  # a copy: small
        joints = np.array(joints, dtype=np.int64).reshape(-1)
        moving = np.asarray(moving, dtype=np.float64)
        if moving.ndim != 3 or moving.shape[1:] != (joints.size, 3):
            raise ValueError(
                f"translations: moving must be (frames, {joints.size}, 3), got {moving.shape}"
            )
        if joints.size and (
            joints.min() < 0 or joints.max() >= fixed.shape[0] or np.any(np.diff(joints) <= 0)
        ):
            raise ValueError(f"translations: joints {joints} are not ascending joint indices")
        fixed.setflags(write=False)
        joints.setflags(write=False)
        object.__setattr__(self, "fixed", fixed)
        object.__setattr__(self, "joints", joints)
        object.__setattr__(self, "moving", moving)

    def __setattr__(self, name, value):
        raise AttributeError("Translations is read-only")

    def __reduce__(self):
        return (Translations, (self.fixed, self.joints, self.moving))

    @classmethod
    def of(cls, array) -> Translations:
        """``array (F, J, 3)`` with each joint constant over the frames (bit for bit: -0.0
        and 0.0 differ) stored once; a ``Translations`` is returned as it is."""
        if isinstance(array, Translations):
            return array
        a = np.asarray(array, dtype=np.float64)
        if a.ndim != 3 or a.shape[2] != 3:
            raise ValueError(f"translations must be (frames, joints, 3), got {a.shape}")
        n, j = a.shape[:2]
        if n == 0:
            return cls(np.zeros((j, 3)), np.arange(j), a)
        bits = a.view(np.int64) if a.flags.c_contiguous else a.copy().view(np.int64)
        varies = np.zeros(j, dtype=bool)
        for s in range(1, n, 4096):  # a few MB at a time
            varies |= (bits[s : s + 4096] != bits[:1]).any(axis=(0, 2))
        joints = np.flatnonzero(varies)
        return cls(a[0].copy(), joints, np.ascontiguousarray(a[:, joints]))

    def compact(self) -> Translations:
        """The same values with every joint constant over the frames (bit for bit) stored
        once; ``self`` when each of ``joints`` varies."""
        if self.moving.shape[0] == 0 or self.joints.size == 0:
            return self
        inner = Translations.of(self.moving)
        if inner.joints.size == self.joints.size:
            return self
        fixed = self.fixed.copy()
        fixed[self.joints] = inner.fixed
        return Translations(fixed, self.joints[inner.joints], inner.moving)

    # -------------------------------------------------------------- array protocol

    @property
    def shape(self) -> tuple[int, int, int]:
        return (self.moving.shape[0], self.fixed.shape[0], 3)

    @property
    def ndim(self) -> int:
        return 3

    @property
    def dtype(self) -> np.dtype:
        return np.dtype(np.float64)

    @property
    def size(self) -> int:
        f, j, _ = self.shape
        return f * j * 3

    @property
    def nbytes(self) -> int:
        """Bytes of the whole array (as numpy's ``nbytes`` of a broadcast view);
        :attr:`stored_nbytes` is what is held."""
        return self.size * 8

    @property
    def stored_nbytes(self) -> int:
        return self.fixed.nbytes + self.moving.nbytes

    def __len__(self) -> int:
        return self.shape[0]

    def __array__(self, dtype=None, copy=None):
        out = self._assemble(self.fixed, self.moving)
        return out if dtype is None else out.astype(dtype, copy=False)

    def copy(self) -> np.ndarray:
        """The whole ``(F, J, 3)`` array, a plain writable array."""
        return np.asarray(self)

    def _assemble(self, fixed: np.ndarray, moving: np.ndarray) -> np.ndarray:
        out = np.empty(moving.shape[:-2] + fixed.shape, dtype=np.result_type(fixed, moving))
        out[...] = fixed
        out[..., self.joints, :] = moving
        return out

    def frames(self, start: int | None, stop: int | None = None, step: int | None = None):
        """Frames ``[start:stop:step]`` as a ``Translations`` (``moving`` is a view)."""
        return Translations(self.fixed, self.joints, self.moving[start:stop:step])

    def __getitem__(self, key):
        key = key if isinstance(key, tuple) else (key,)
        first = key[0] if key else slice(None)
        if first is Ellipsis or first is None or (np.ndim(first) > 1 and _is_bool(first)):
            return np.asarray(self)[key]
        rest = key[1:]
        moving = self.moving[first]  # S + (K, 3)
        lead = moving.ndim - 2
        j_key = rest[0] if rest else slice(None)
        if np.ndim(first) > 0 and not isinstance(first, slice) and np.ndim(j_key) > 0:
            return np.asarray(self)[key]  # two index arrays pair up: numpy's rules
        if j_key is Ellipsis or j_key is None:
            return self._assemble(self.fixed, moving)[(slice(None),) * lead + rest]
        chosen = np.arange(self.fixed.shape[0])[j_key]  # () or (m,) joints
        col = np.full(self.fixed.shape[0], -1, dtype=np.int64)
        col[self.joints] = np.arange(self.joints.size)
        c = col[chosen]
        out = np.empty(moving.shape[:-2] + chosen.shape + (3,))
        out[...] = self.fixed[chosen]
        if chosen.ndim == 0:
            if c >= 0:
                out[...] = moving[..., int(c), :]
        else:
            hit = c >= 0
            if hit.any():
                out[..., hit, :] = moving[..., c[hit], :]
        return out[(slice(None),) * (lead + chosen.ndim) + rest[1:]]

    def __array_ufunc__(self, ufunc, method, *inputs, **kwargs):
        """numpy's functions and operators see the whole array (a plain one is returned)."""
        inputs = tuple(np.asarray(x) if isinstance(x, Translations) else x for x in inputs)
        if "out" in kwargs:
            kwargs["out"] = tuple(
                np.asarray(x) if isinstance(x, Translations) else x for x in kwargs["out"]
            )
        return getattr(ufunc, method)(*inputs, **kwargs)

    def scaled(self, factor) -> Translations:
        """``self * factor`` (a scalar or per-axis ``(3,)``) stored as compactly: the same
        floats as the whole array times ``factor``."""
        factor = np.asarray(factor, dtype=np.float64)
        if factor.ndim > 1:
            raise ValueError(f"translations: factor must be a scalar or (3,), got {factor.shape}")
        return Translations(self.fixed * factor, self.joints, self.moving * factor)

    def __repr__(self) -> str:
        return (
            f"Translations(shape={self.shape}, moving joints {self.joints.tolist()}, "
            f"{self.stored_nbytes} bytes held)"
        )


def _is_bool(key) -> bool:
    return np.asarray(key).dtype == bool
