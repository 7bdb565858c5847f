"""The data model: ``Skeleton``, ``Motion`` and ``MarkerSet``.

Plain dataclasses over numpy arrays. Nothing here reads files (see ``engine.io``)
or computes kinematics (see ``engine.model.kinematics``).

Units are the file's own (``meta.units`` says which: ``"m"``, ``"cm"``, ``"mm"``,
``"in"``, ``"dm"`` or ``"unknown"``); ``Motion.meters_per_unit`` converts.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from engine.model import rotations as rot
from engine.model.translations import Translations

POSITION_CHANNELS = ("Xposition", "Yposition", "Zposition")
ROTATION_CHANNELS = ("Xrotation", "Yrotation", "Zrotation")
UNIT_TO_METERS = {"m": 1.0, "dm": 0.1, "cm": 0.01, "mm": 0.001, "in": 0.0254}


@dataclass(frozen=True)
class Skeleton:
    """A joint hierarchy at rest.

    Attributes
    ----------
    names : tuple of str, (J,)
        Joint names, parents before children (BVH order).
    parents : (J,) int array
        Index of each joint's parent, ``-1`` for the root(s).
    offsets : (J, 3) float array, file units
        Rest translation of each joint in its parent's frame.
    channels : tuple of tuple of str, (J,)
        BVH channel names per joint in file order, e.g.
        ``("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")``.
        A joint with no rotation channels keeps ``rotation_orders[j]`` = ``"ZXY"``.
    end_sites : dict {joint index: (3,) float array}
        Offsets of ``End Site`` blocks (leaf tips), in the joint's frame.
    """

    names: tuple[str, ...]
    parents: np.ndarray
    offsets: np.ndarray
    channels: tuple[tuple[str, ...], ...]
    end_sites: dict[int, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        parents = np.asarray(self.parents, dtype=np.int64)
        offsets = np.asarray(self.offsets, dtype=float).reshape(-1, 3)
        object.__setattr__(self, "parents", parents)
        object.__setattr__(self, "offsets", offsets)
        object.__setattr__(self, "names", tuple(self.names))
        object.__setattr__(self, "channels", tuple(tuple(c) for c in self.channels))
        n = len(self.names)
        if parents.shape != (n,) or offsets.shape != (n, 3) or len(self.channels) != n:
            raise ValueError(
                f"skeleton: {n} names but parents {parents.shape}, offsets {offsets.shape}, "
                f"{len(self.channels)} channel lists"
            )
        for j, p in enumerate(parents):
            if p >= j:
                raise ValueError(f"skeleton: joint {self.names[j]!r} has parent index {p} >= {j}")

    @property
    def n_joints(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        """Index of the joint called ``name`` (exact match); ``KeyError`` if absent."""
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"no joint named {name!r}") from None

    def rotation_order(self, j: int) -> str:
        """Euler order of joint ``j``'s rotation channels in file order, e.g. ``"ZXY"``."""
        order = "".join(c[0] for c in self.channels[j] if c in ROTATION_CHANNELS)
        return order if len(order) == 3 else "ZXY"

    def has_position_channels(self, j: int) -> bool:
        return any(c in POSITION_CHANNELS for c in self.channels[j])

    def children(self, j: int) -> list[int]:
        return [int(c) for c in np.flatnonzero(self.parents == j)]

    def descendants(self, j: int) -> list[int]:
        """``j`` and every joint below it, in index order."""
        keep = np.zeros(self.n_joints, dtype=bool)
        keep[j] = True
        for c in range(j + 1, self.n_joints):
            if self.parents[c] >= 0 and keep[self.parents[c]]:
                keep[c] = True
        return [int(c) for c in np.flatnonzero(keep)]

    def chain_to_root(self, j: int) -> list[int]:
        """Joint indices from ``j`` up to its root, ``j`` first."""
        chain = [j]
        while self.parents[chain[-1]] >= 0:
            chain.append(int(self.parents[chain[-1]]))
        return chain


@dataclass(frozen=True)
class MotionMeta:
    """Where a take came from and how to read its numbers.

    units : ``"m"``, ``"dm"``, ``"cm"``, ``"mm"``, ``"in"`` or ``"unknown"``
    up_axis : ``"y"`` or ``"z"``
    source : path of the file read, or a description
    format : ``"bvh"``, ``"c3d"``, ``"trc"`` or ``"derived"``
    notes : what the reader accepted but a user should know, one line each, naming
        the file (``"walk.trc: the header says 652 frames, 93 were read"``); the
        command line prints them on stderr, the app shows them with the open takes
    """

    units: str = "unknown"
    up_axis: str = "y"
    source: str = ""
    format: str = "bvh"
    notes: tuple[str, ...] = ()


@dataclass(frozen=True)
class Motion:
    """A skeletal take: per-frame local rotations and translations.

    Attributes
    ----------
    skeleton : Skeleton
    rotations : (F, J, 4) float array
        Local joint rotations as unit quaternions ``(w, x, y, z)``.
    translations : (F, J, 3) float array, file units
        Local joint translations: the position channels where a joint has them
        (the root's path, or every joint in 6-channel files), else the rest offset.
        Held as a :class:`~engine.model.translations.Translations` (an array given is
        converted): a joint constant over the take is stored once, not per frame; it
        reads as the ``(F, J, 3)`` array (indexing, ``np.asarray``, arithmetic).
    fps : float
        Frames per second.
    meta : MotionMeta
    """

    skeleton: Skeleton
    rotations: np.ndarray
    translations: np.ndarray
    fps: float
    meta: MotionMeta = field(default_factory=MotionMeta)

    def __post_init__(self) -> None:
        r = np.asarray(self.rotations, dtype=float)
        t = self.translations
        if not isinstance(t, Translations):
            t = np.asarray(t, dtype=float)
        j = self.skeleton.n_joints
        if r.ndim != 3 or r.shape[1:] != (j, 4):
            raise ValueError(f"motion: rotations must be (frames, {j}, 4), got {r.shape}")
        if t.shape != r.shape[:2] + (3,):
            raise ValueError(f"motion: translations must be {r.shape[:2] + (3,)}, got {t.shape}")
        object.__setattr__(self, "rotations", r)
        object.__setattr__(self, "translations", Translations.of(t))
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise ValueError(f"motion: fps must be positive, got {self.fps}")

    @property
    def n_frames(self) -> int:
        return int(self.rotations.shape[0])

    @property
    def duration(self) -> float:
        """Seconds from the first to one frame past the last."""
        return self.n_frames / self.fps

    @property
    def root_translation(self) -> np.ndarray:
        """(F, 3) root position channels, file units."""
        return self.translations[:, 0]

    @property
    def meters_per_unit(self) -> float:
        """Scale from file units to metres (1.0 when units are unknown)."""
        return UNIT_TO_METERS.get(self.meta.units, 1.0)

    def frames(self, start: int, stop: int | None = None) -> Motion:
        """The frame range ``[start, stop)`` as a new Motion."""
        return replace(
            self,
            rotations=self.rotations[start:stop],
            translations=self.translations.frames(start, stop),
        )

    @classmethod
    def rest(
        cls,
        skeleton: Skeleton,
        n_frames: int = 1,
        fps: float = 30.0,
        meta: MotionMeta | None = None,
    ) -> Motion:
        """A take that holds the rest pose for ``n_frames`` frames."""
        rots = rot.identity((n_frames, skeleton.n_joints))
        trans = Translations(skeleton.offsets, [], np.zeros((n_frames, 0, 3)))
        return cls(skeleton, rots, trans, fps, meta or MotionMeta(format="derived"))


@dataclass(frozen=True)
class MarkerSet:
    """Labelled 3-D marker trajectories (C3D, TRC).

    Attributes
    ----------
    labels : tuple of str, (M,)
    points : (F, M, 3) float array, file units; gaps (occluded markers) are NaN
    fps : float
    meta : MotionMeta (``format`` is ``"c3d"`` or ``"trc"``)
    """

    labels: tuple[str, ...]
    points: np.ndarray
    fps: float
    meta: MotionMeta = field(default_factory=MotionMeta)

    def __post_init__(self) -> None:
        p = np.asarray(self.points, dtype=float)
        object.__setattr__(self, "points", p)
        object.__setattr__(self, "labels", tuple(self.labels))
        if p.ndim != 3 or p.shape[1:] != (len(self.labels), 3):
            raise ValueError(
                f"markers: points must be (frames, {len(self.labels)}, 3), got {p.shape}"
            )
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise ValueError(f"markers: fps must be positive, got {self.fps}")

    @property
    def n_frames(self) -> int:
        return int(self.points.shape[0])

    @property
    def duration(self) -> float:
        return self.n_frames / self.fps

    @property
    def meters_per_unit(self) -> float:
        return UNIT_TO_METERS.get(self.meta.units, 1.0)

    def marker(self, label: str) -> np.ndarray:
        """(F, 3) trajectory of the marker called ``label``."""
        try:
            return self.points[:, self.labels.index(label)]
        except ValueError:
            raise KeyError(f"no marker labelled {label!r}") from None
