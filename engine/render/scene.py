"""A take prepared for display: units, up axis, skinning, framing (no OpenGL here).

Display space is metres with +Y up. A take's file coordinates are mapped by
``p_display = scale * A @ p_file``, with ``A`` the identity for Y-up files and
``(x, y, z) -> (x, z, -y)`` for Z-up files, and ``scale`` the file's metres per
unit (``Motion.meters_per_unit``), or, when the units are unknown, the scale that
makes the character 1.75 m tall (a hand take: a 19 cm hand).

Framing follows the character: the camera looks at the centre of the posed
joints' bounding box, smoothed over +-0.4 s, from a fixed distance that fits the
character's largest pose, and from a fixed direction relative to the take's
median facing (pelvis rotation applied to the rest-pose facing), so a video does
not zoom or swing. The hands' close-up follows the hands' joints the same way, drawn
towards each frame's own hand wherever the average would let it leave the picture
(the first and last frames, fast moves). It looks from the front (slightly from the
right and above) unless the body hides the hand from there (a crouch, a hand behind the
torso): then from the direction of :data:`HANDS_DIRECTIONS` that sees most of the hand
(:meth:`TakeView.hands_direction`, a coarse depth test of the posed mesh's vertices).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from engine.base.errors import ParameterError, RoleError, check_cancelled
from engine.mesh.anatomy import Anatomy, find_anatomy
from engine.mesh.mannequin import build_mannequin
from engine.mesh.skinning import SkinnedMesh
from engine.model import rotations as rot
from engine.model.fastkin import forward_kinematics  # numba: every frame of a long take
from engine.model.motion import Motion

CAMERAS = ("front", "side", "three-quarter", "hands")
# camera direction per name: (azimuth towards the character's right, elevation), degrees;
# "hands" is a close-up from the front that keeps both hands in view
_CAMERA_ANGLES = {
    "front": (0.0, 8.0),
    "side": (90.0, 5.0),
    "three-quarter": (40.0, 14.0),
    "hands": (15.0, 18.0),
}
#: directions the hands' close-up may look from (azimuth towards the character's right,
#: elevation; degrees), the front one (``_CAMERA_ANGLES["hands"]``) first
HANDS_DIRECTIONS = tuple(
    (az, el)
    for el in (18.0, 55.0, -20.0)
    for az in (15.0, 60.0, -30.0, 105.0, -75.0, 150.0, -120.0, 195.0)
)
#: a direction other than the front is taken when it sees this much more of the hand
#: (fraction of the hand's vertices), so a hand the front sees well stays seen from there
HANDS_SWITCH_GAIN = 0.15
#: the coarse depth test's grid, cells across the picture's shorter side
_OCCLUSION_CELLS = 72
#: how far (metres) a vertex may lie behind the front-most surface of its cell and count
#: as seen (the mesh's own thickness at a grazing angle)
_OCCLUSION_SLACK = 0.012
#: how far the hand's mesh reaches beyond its joints' box (fingertips past the last
#: joint, the palm's thickness), in hand lengths: the close-up keeps this in view
HAND_MESH_REACH = 0.25
_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 1e-12, n, 1.0)


def look_at(eye: np.ndarray, target: np.ndarray, up: np.ndarray) -> np.ndarray:
    """4x4 camera pose (OpenGL: the camera looks down its -Z) at ``eye`` facing ``target``."""
    back = _unit(eye - target)
    right = np.cross(up, back)
    if np.linalg.norm(right) < 1e-9:
        right = np.cross(
            np.array([0.0, 0.0, 1.0]) if abs(back[1]) > 0.9 else np.array([0.0, 1.0, 0.0]), back
        )
    right = _unit(right)
    true_up = np.cross(back, right)
    pose = np.eye(4)
    pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = right, true_up, back, eye
    return pose


def display_transform(motion: Motion, anatomy: Anatomy) -> tuple[float, np.ndarray]:
    """``(scale, axes)`` with ``p_display = scale * axes @ p_file`` (metres, +Y up).

    ``axes`` (3, 3) is the identity for Y-up files, ``(x, y, z) -> (x, z, -y)`` for
    Z-up ones; ``scale`` the file's metres per unit, or, units unknown, the scale that
    makes the character 1.75 m tall (a hand: 19 cm). The renderer and the glTF export
    share it."""
    axes = _Z_UP if motion.meta.up_axis.lower() == "z" else np.eye(3)
    if motion.meta.units in ("m", "cm", "mm", "in", "dm"):
        scale = motion.meters_per_unit
    else:
        scale = 1.75 / anatomy.height if anatomy.height > 0 else 1.0
    return float(scale), axes


#: frames whose joints are computed at once while a view is prepared (forward kinematics
#: and display positions of a block, ~4 MB for 52 joints): the view keeps what framing
#: needs of every frame (bounds, the anchor's rotation), never every frame's joints
BLOCK_FRAMES = 2048
#: posed frames a view keeps (the frames on screen, a neighbour being scrubbed to)
POSE_CACHE_FRAMES = 8


class FrameJoints:
    """A take's world joints by frame, computed when indexed (forward kinematics of the
    frames asked for only): ``view.positions[i]`` ``(J, 3)``, ``view.positions[frames,
    joints]``, ``view.rotations[i]`` ``(J, 4)``; numpy's indexing, the first index over
    frames. The same floats as the whole take's arrays would hold (frames are independent).

    ``view.positions`` holds display-space positions (metres, +Y up), ``view.rotations``
    world rotations in the file's frame (for skinning). A frame's arrays are read-only
    (they are shared with the view's small cache of posed frames)."""

    def __init__(self, view: TakeView, part: int):
        self._view, self._part = view, part

    @property
    def shape(self) -> tuple[int, int, int]:
        return (self._view.n_frames, self._view.motion.skeleton.n_joints, 3 + self._part)

    def __len__(self) -> int:
        return self._view.n_frames

    def __getitem__(self, key):
        key = key if isinstance(key, tuple) else (key,)
        frames, rest = key[0], key[1:]
        if isinstance(frames, (int, np.integer)):
            whole = self._view.pose(int(frames))[self._part]
            return whole[rest] if rest else whole
        if not isinstance(frames, slice):
            frames = np.asarray(frames)
            if frames.dtype == bool:
                frames = np.flatnonzero(frames)
            frames = np.where(frames < 0, frames + self._view.n_frames, frames)
        block = self._view.poses(frames)[self._part]
        if isinstance(frames, slice):
            return block[(slice(None), *rest)]
        return block[(np.arange(len(block)).reshape(frames.shape), *rest)]


@dataclass
class TakeView:
    """One take ready to draw: mesh, framing, and world joints of any frame on demand.

    Build with :meth:`from_motion`. Arrays are in display space (metres, +Y up).
    A view holds the take (``motion``), the mesh and per-frame framing (a few floats a
    frame); the joints of a frame are computed when it is drawn (:meth:`pose`, forward
    kinematics of one frame: microseconds), so a 10-minute take's view is a few MB
    instead of its (F, J, 7) float64 world joints (0.2 GB for 52 joints at 72,000 frames).

    motion : Motion
    anatomy : Anatomy
    mesh : SkinnedMesh (rest pose, file units)
    scale : float, metres per file unit used
    axes : (3, 3) file-to-display rotation
    positions : (F, J, 3) world joint positions, display space (:class:`FrameJoints`:
        computed for the frames indexed)
    rotations : (F, J, 4) world joint rotations, file frame (for skinning; the same)
    targets : (F, 3) smoothed look-at points
    radius : float, metres; the sphere the camera keeps in view
    facing, right : (3,) unit horizontal vectors (the take's median facing)
    floor_y : float or None (no floor for a hand take)
    """

    motion: Motion
    anatomy: Anatomy
    mesh: SkinnedMesh
    scale: float
    axes: np.ndarray
    targets: np.ndarray
    radius: float
    facing: np.ndarray
    right: np.ndarray
    view_up: np.ndarray
    floor_y: float | None
    label: str = ""
    _visible: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    hand_targets: np.ndarray | None = None
    hand_radius: float = 0.0
    #: (V,) bool: the mesh's vertices of the hands the close-up frames
    hand_vertices: np.ndarray | None = None
    _hands_dirs: dict = field(default_factory=dict)
    _posed: dict = field(default_factory=dict, repr=False)

    @property
    def positions(self) -> FrameJoints:
        """(F, J, 3) world joint positions, display space, computed for the frames indexed
        (made on each access: a view held by its own attribute would be a reference cycle,
        freed only by the garbage collector, with its take)."""
        return FrameJoints(self, 0)

    @property
    def rotations(self) -> FrameJoints:
        """(F, J, 4) world joint rotations, file frame, computed for the frames indexed."""
        return FrameJoints(self, 1)

    def poses(self, frames) -> tuple[np.ndarray, np.ndarray]:
        """World joints of ``frames`` (a slice or an int array): display positions
        ``(K, J, 3)`` and file-frame rotations ``(K, J, 4)``."""
        pos, wrot = forward_kinematics(self.motion, frames)
        return self.scale * np.einsum("ij,fkj->fki", self.axes, pos), wrot

    def pose(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """World joints of frame ``i``: display positions ``(J, 3)`` and file-frame
        rotations ``(J, 4)`` (read-only; the last :data:`POSE_CACHE_FRAMES` are kept)."""
        i = self.check_frame(i)
        hit = self._posed.get(i)
        if hit is None:
            pos, wrot = self.poses(slice(i, i + 1))
            hit = (pos[0], wrot[0])
            for a in hit:
                a.flags.writeable = False
            if len(self._posed) >= POSE_CACHE_FRAMES:
                self._posed.pop(next(iter(self._posed)))
            self._posed[i] = hit
        return hit

    @classmethod
    def from_motion(
        cls,
        motion: Motion,
        mesh: SkinnedMesh | None = None,
        anatomy: Anatomy | None = None,
        label: str = "",
        bind_frame: int = 0,
        roles=None,
        close_up_sides=None,
        cancelled=None,
    ) -> TakeView:
        """Prepare ``motion``; the mannequin is bound in captured frame ``bind_frame``.

        ``roles`` (``engine.model.roles.Roles``) fixes the arm and finger joints; default:
        found from the names (a hand take's side from its file name).
        ``close_up_sides`` (e.g. ``("right",)``): the hands the ``hands`` camera frames
        (default all).

        The take's frames are posed :data:`BLOCK_FRAMES` at a time for the framing
        (per-frame bounds of the visible and the hand joints, the anchor's rotation).
        ``cancelled``: a callable asked before each block; once it returns True the view
        is given up (``engine.base.errors.Cancelled``: the app's preview of an edit's
        spliced take, 0.75 s of CPU at 72,000 frames, when a newer edit is being solved)."""
        if motion.n_frames < 1:
            raise ValueError(f"{label or 'take'}: has no frames to render")
        if not 0 <= bind_frame < motion.n_frames:
            raise ValueError(
                f"{label or 'take'}: bind frame {bind_frame} outside 0..{motion.n_frames - 1}"
            )
        pos, wrot = forward_kinematics(motion, bind_frame)
        bind_pos, bind_rot = pos[0], wrot[0]
        if anatomy is None:
            from engine.model.roles import side_from_name

            anatomy = find_anatomy(
                motion.skeleton,
                bind_pos,
                bind_rot,
                roles=roles,
                side_hint=side_from_name(motion.meta.source or ""),
            )
        name = Path(motion.meta.source).name if motion.meta.source else label or "take"
        if anatomy.kind != "body" and not anatomy.hands:
            raise RoleError(
                f"{name}: neither a body (hips, spine, arms or legs) nor a hand "
                "(wrist with fingers) found by joint name; nothing to draw "
                "(rename the joints or pass --roles)"
            )
        scale, axes = display_transform(motion, anatomy)
        visible = np.ones(motion.skeleton.n_joints, bool)
        visible[list(anatomy.hidden)] = False
        anchor = (
            anatomy.pelvis if anatomy.kind == "body" else next(iter(anatomy.hands.values())).wrist
        )
        # the hands' close-up: the hands' joints (wrists and fingers)
        hand_joints = sorted(
            {
                d
                for side, h in anatomy.hands.items()
                if close_up_sides is None or side in close_up_sides
                for d in motion.skeleton.descendants(h.wrist)
            }
        )
        track = _Framing.of(motion, scale, axes, visible, anchor, hand_joints, cancelled)
        if not (track.extent > 0).any():
            raise ParameterError(
                f"{name}: every joint sits at one point in every frame (all "
                "offsets and motion zero); nothing to draw"
            )
        if mesh is None:
            mesh = build_mannequin(motion.skeleton, anatomy, pose=(bind_pos, bind_rot))
        elif mesh.bind_positions.shape[0] != motion.skeleton.n_joints:
            raise ValueError(
                f"{label or 'take'}: the mesh is bound to "
                f"{mesh.bind_positions.shape[0]} joints, the skeleton has "
                f"{motion.skeleton.n_joints}"
            )
        lo, hi = track.lo, track.hi
        center = 0.5 * (lo + hi)
        half_diag = 0.5 * np.linalg.norm(hi - lo, axis=1)
        height_m = anatomy.height * scale
        margin = 0.12 * height_m if anatomy.kind == "body" else 0.08 * height_m
        radius = float(
            max(
                np.percentile(half_diag, 95) + margin,
                0.5 * height_m if anatomy.kind == "body" else 0.1,
            )
        )
        win = max(1, int(round(0.4 * motion.fps)))
        targets = _moving_average(center, win)
        # facing: the bind pose's facing carried by the pelvis (or wrist) rotation
        rel = rot.multiply(track.anchor, rot.conjugate(bind_rot[anchor]))
        fwd = rot.rotate(rel, anatomy.forward) @ axes.T
        up_hand = rot.rotate(rel, anatomy.up) @ axes.T
        if anatomy.kind == "body":
            flat = fwd.copy()
            flat[:, 1] = 0.0
            mean = np.mean(_unit(flat), axis=0)
            facing = _unit(mean) if np.linalg.norm(mean) > 1e-6 else np.array([0.0, 0.0, 1.0])
            view_up = np.array([0.0, 1.0, 0.0])
        else:
            # a hand: look at the back of the hand, fingers up in the image
            facing = -_unit(np.mean(_unit(fwd), axis=0))
            view_up = _unit(np.mean(_unit(up_hand), axis=0))
            view_up = _unit(view_up - np.dot(view_up, facing) * facing)
        right = _unit(np.cross(facing, view_up))
        view = cls(
            motion,
            anatomy,
            mesh,
            float(scale),
            axes,
            targets,
            radius,
            facing,
            right,
            view_up,
            None,
            label,
            visible,
        )
        # the mesh reaches beyond the joints (head, feet, a hand take's forearm): measure
        # it on a few frames for the floor height, the framing radius and centre offset
        sample = np.unique(
            np.linspace(0, motion.n_frames - 1, min(motion.n_frames, 24)).round().astype(int)
        )
        offsets, radii, lowest = [], [], []
        for f in sample:
            verts = view.vertices(int(f))[0]
            vlo, vhi = verts.min(axis=0), verts.max(axis=0)
            offsets.append(0.5 * (vlo + vhi) - center[f])
            radii.append(0.5 * np.linalg.norm(vhi - vlo))
            lowest.append(vlo[1])
        view._posed.clear()  # the sampled frames are not the ones the page shows first
        view.targets = targets + np.median(offsets, axis=0)
        if anatomy.kind == "body" and hand_joints:
            h_lo, h_hi = track.hand_lo, track.hand_hi
            h_half = 0.5 * np.linalg.norm(h_hi - h_lo, axis=1)
            view.hand_radius = float(np.percentile(h_half, 90) + 0.9 * anatomy.hand_length * scale)
            view.hand_targets = _keep_in_view(
                0.5 * (h_lo + h_hi),
                h_half + HAND_MESH_REACH * anatomy.hand_length * scale,
                view.hand_radius,
                win,
            )
            parts = [
                k
                for k, name in enumerate(view.mesh.part_names)
                if name.endswith("_hand")
                and (close_up_sides is None or name[: -len("_hand")] in close_up_sides)
            ]
            if parts and len(view.mesh.part) == len(view.mesh.vertices):
                view.hand_vertices = np.isin(view.mesh.part, parts)
        view.radius = float(max(radius - margin, np.percentile(radii, 95)) * 1.04)
        if anatomy.kind == "body":
            view.floor_y = float(min(lowest))
        return view

    @property
    def n_frames(self) -> int:
        return self.motion.n_frames

    @property
    def height_m(self) -> float:
        return float(self.anatomy.height * self.scale)

    def check_frame(self, i: int) -> int:
        i = int(i)
        if not -self.n_frames <= i < self.n_frames:
            raise ParameterError(
                f"{self.label or 'take'}: frame {i} is outside 0..{self.n_frames - 1}"
            )
        return i % self.n_frames

    def vertices(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """Skinned vertices and normals ``(V, 3)`` of frame ``i``, display space."""
        disp, wrot = self.pose(i)
        file_pos = disp @ self.axes / self.scale  # back to file frame
        verts, normals = self.mesh.pose(file_pos, wrot)
        return self.scale * verts @ self.axes.T, normals @ self.axes.T

    def camera_pose(self, i: int, camera: str, aspect: float, yfov: float) -> np.ndarray:
        """4x4 pose of the camera ``camera`` (front, side, three-quarter, hands) at frame ``i``.

        ``hands`` frames both hands' joints (a hand take: the whole take, as ``front``
        at a slight angle)."""
        if camera not in _CAMERA_ANGLES:
            raise ValueError(f"camera {camera!r}: expected one of {', '.join(CAMERAS)}")
        i = self.check_frame(i)
        half = 0.5 * min(yfov, 2 * np.arctan(np.tan(0.5 * yfov) * aspect))
        if camera == "hands" and self.hand_targets is not None:
            radius, target = self.hand_radius, self.hand_targets[i]
            direction = self._direction(*self.hands_direction(i, aspect, yfov))
        else:
            radius, target = self.radius, self.targets[i]
            direction = self._direction(*_CAMERA_ANGLES[camera])
        dist = radius / np.sin(half) * 1.02
        return look_at(target + dist * direction, target, self.view_up)

    def _direction(self, az_deg: float, el_deg: float) -> np.ndarray:
        """Unit vector from the look-at point towards the camera at (azimuth, elevation)."""
        az, el = np.radians(az_deg), np.radians(el_deg)
        horizontal = np.cos(az) * self.facing + np.sin(az) * self.right
        return np.cos(el) * horizontal + np.sin(el) * self.view_up

    def hands_direction(self, i: int, aspect: float = 1.1, yfov: float = np.radians(35.0)):
        """``(azimuth, elevation)`` degrees the hands' close-up looks from at frame ``i``:
        the front one of :data:`HANDS_DIRECTIONS` unless another sees at least
        :data:`HANDS_SWITCH_GAIN` more of the hand's vertices (:meth:`hand_seen`); then the
        one that sees most (the first of equals). Cached per frame."""
        i = self.check_frame(i)
        key = (i, round(float(aspect), 3), round(float(yfov), 4))
        if key not in self._hands_dirs:
            if self.hand_vertices is None or not self.hand_vertices.any():
                choice = _CAMERA_ANGLES["hands"]
            elif self.hand_seen(i, aspect, yfov, first=1)[0] + HANDS_SWITCH_GAIN > 1.0:
                choice = HANDS_DIRECTIONS[0]  # no direction can see the gain more than it
            else:
                seen = self.hand_seen(i, aspect, yfov)
                best = int(np.argmax(seen))
                choice = HANDS_DIRECTIONS[best if seen[best] >= seen[0] + HANDS_SWITCH_GAIN else 0]
            if len(self._hands_dirs) > 4096:
                self._hands_dirs.clear()
            self._hands_dirs[key] = choice
        return self._hands_dirs[key]

    def hand_seen(
        self, i: int, aspect: float = 1.1, yfov: float = np.radians(35.0), first: int | None = None
    ) -> np.ndarray:
        """Fraction of the close-up hand's mesh vertices seen from each of
        :data:`HANDS_DIRECTIONS` (the ``first`` of them only, if given) at frame ``i``
        (a coarse depth test: every vertex of the
        posed mesh is projected into a grid of about :data:`_OCCLUSION_CELLS` cells a
        side; a hand vertex is seen when no other vertex of its cell or the 8 around it
        lies more than :data:`_OCCLUSION_SLACK` in front of it, and it is in the picture).
        """
        verts = self.vertices(self.check_frame(i))[0]
        hand = self.hand_vertices
        target = self.hand_targets[i]
        half = 0.5 * min(yfov, 2 * np.arctan(np.tan(0.5 * yfov) * aspect))
        dist = self.hand_radius / np.sin(half) * 1.02
        f = 1.0 / np.tan(0.5 * yfov)
        rows = _OCCLUSION_CELLS
        cols = max(int(round(rows * aspect)), 1)
        directions = HANDS_DIRECTIONS[:first] if first is not None else HANDS_DIRECTIONS
        seen = np.zeros(len(directions))
        rel = verts - target
        for k, (az, el) in enumerate(directions):
            pose = look_at(dist * self._direction(az, el), np.zeros(3), self.view_up)
            cam = (rel - pose[:3, 3]) @ pose[:3, :3]
            depth = -cam[:, 2]
            ok = depth > 1e-3
            d = np.where(ok, depth, 1.0)
            x = (f / aspect * cam[:, 0] / d + 1) * 0.5 * cols
            y = (1 - f * cam[:, 1] / d) * 0.5 * rows
            inside = ok & (x >= 0) & (x < cols) & (y >= 0) & (y < rows)
            cx = np.clip(x.astype(np.int64), 0, cols - 1)
            cy = np.clip(y.astype(np.int64), 0, rows - 1)
            front = np.full((rows + 2, cols + 2), np.inf)
            other = inside & ~hand
            np.minimum.at(front, (cy[other] + 1, cx[other] + 1), depth[other])
            nearest = front[1:-1, 1:-1].copy()
            for dy in (0, 1, 2):
                for dx in (0, 1, 2):
                    np.minimum(nearest, front[dy : dy + rows, dx : dx + cols], out=nearest)
            mine = hand & inside
            visible = depth[mine] <= nearest[cy[mine], cx[mine]] + _OCCLUSION_SLACK
            seen[k] = visible.sum() / max(int(hand.sum()), 1)
        return seen


@dataclass
class _Framing:
    """What a view's framing needs of every frame of a take, gathered :data:`BLOCK_FRAMES`
    frames at a time: bounds ``lo``, ``hi`` (F, 3) of the visible joints and ``hand_lo``,
    ``hand_hi`` (F, 3) of the close-up's hand joints (display space, metres; None without
    hand joints), the anchor joint's world rotation ``anchor`` (F, 4, file frame), and
    ``extent`` (3,): the spread of every joint over every frame (file units)."""

    lo: np.ndarray
    hi: np.ndarray
    hand_lo: np.ndarray | None
    hand_hi: np.ndarray | None
    anchor: np.ndarray
    extent: np.ndarray

    @classmethod
    def of(cls, motion, scale, axes, visible, anchor: int, hand_joints, cancelled=None) -> _Framing:
        frames = motion.n_frames
        lo, hi = np.empty((frames, 3)), np.empty((frames, 3))
        hands = np.empty((2, frames, 3)) if hand_joints else None
        turn = np.empty((frames, 4))
        low, high = np.full(3, np.inf), np.full(3, -np.inf)
        for a in range(0, frames, BLOCK_FRAMES):
            check_cancelled(cancelled)
            b = min(a + BLOCK_FRAMES, frames)
            pos, wrot = forward_kinematics(motion, slice(a, b))
            low = np.minimum(low, pos.min(axis=(0, 1)))
            high = np.maximum(high, pos.max(axis=(0, 1)))
            disp = scale * np.einsum("ij,fkj->fki", axes, pos)
            shown = disp[:, visible]
            lo[a:b], hi[a:b] = shown.min(axis=1), shown.max(axis=1)
            if hands is not None:
                hp = disp[:, hand_joints]
                hands[0, a:b], hands[1, a:b] = hp.min(axis=1), hp.max(axis=1)
            turn[a:b] = wrot[:, anchor]
        return cls(
            lo,
            hi,
            None if hands is None else hands[0],
            None if hands is None else hands[1],
            turn,
            high - low,
        )


def _keep_in_view(centres: np.ndarray, reach: np.ndarray, radius: float, half: int) -> np.ndarray:
    """Look-at points ``(F, 3)`` that follow ``centres (F, 3)`` smoothly (a centred moving
    average over ``2*half+1`` frames) but keep, in every frame, the ball of ``reach (F,)``
    around that frame's centre inside the ball of ``radius`` the camera frames: where the
    average strays further (a fast move, or the first and last frames, whose average
    leans on one side), the point is drawn towards the frame's own centre just enough."""
    smooth = _moving_average(centres, half)
    off = centres - smooth
    dist = np.linalg.norm(off, axis=1)
    allowed = np.maximum(radius - reach, 0.0)
    pull = np.where(dist > allowed, (dist - allowed) / np.where(dist > 0, dist, 1.0), 0.0)
    return smooth + pull[:, None] * off


def _moving_average(x: np.ndarray, half: int) -> np.ndarray:
    """Centred moving average over ``2*half+1`` frames along axis 0 (edges shrink)."""
    if half <= 0 or len(x) < 2:
        return x.copy()
    c = np.cumsum(np.vstack([np.zeros((1,) + x.shape[1:]), x]), axis=0)
    idx = np.arange(len(x))
    lo = np.clip(idx - half, 0, len(x))
    hi = np.clip(idx + half + 1, 0, len(x))
    return (c[hi] - c[lo]) / (hi - lo)[:, None]


def floor_mesh_arrays(
    center: np.ndarray, radius: float, y: float, tile: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A round checkered floor patch at height ``y`` around ``center`` whose opacity
    (colour alpha) fades to zero towards ``radius``. Tiles are aligned to the world
    grid, so the pattern stays put while the patch follows the character.

    A tile whose four corners are all transparent is left out: it would draw nothing
    (alpha is interpolated between the corners) yet the rasteriser would shade every
    pixel it covers (a third of the patch's tiles; the floor is the largest surface of
    a frame).

    Returns vertices ``(V, 3)``, faces ``(T, 3)``, colours ``(V, 4)``.
    """
    n = int(np.ceil(radius / tile)) + 1
    i0 = int(np.floor(center[0] / tile))
    k0 = int(np.floor(center[2] / tile))
    ii, kk = np.meshgrid(
        np.arange(i0 - n, i0 + n + 1), np.arange(k0 - n, k0 + n + 1), indexing="ij"
    )
    ii, kk = ii.ravel(), kk.ravel()
    mid = np.stack([(ii + 0.5) * tile - center[0], (kk + 0.5) * tile - center[2]], 1)
    keep = np.hypot(mid[:, 0], mid[:, 1]) < radius + tile
    ii, kk = ii[keep], kk[keep]
    corners = np.array([[0, 0], [1, 0], [1, 1], [0, 1]])
    xs = (ii[:, None] + corners[None, :, 0]) * tile
    zs = (kk[:, None] + corners[None, :, 1]) * tile
    seen = (np.hypot(xs - center[0], zs - center[2]) < radius).any(axis=1)  # alpha > 0 somewhere
    ii, kk, xs, zs = ii[seen], kk[seen], xs[seen], zs[seen]
    verts = np.stack([xs, np.full_like(xs, y), zs], -1).reshape(-1, 3)
    base = 4 * np.arange(len(ii))
    faces = np.concatenate(
        [np.stack([base, base + 2, base + 1], 1), np.stack([base, base + 3, base + 2], 1)]
    )
    dark = (ii + kk) % 2 == 0
    col = np.where(dark[:, None], [0.72, 0.74, 0.77], [0.84, 0.85, 0.88])
    col = np.repeat(col, 4, axis=0)
    dist = np.hypot(verts[:, 0] - center[0], verts[:, 2] - center[2])
    t = np.clip((dist - 0.45 * radius) / (0.55 * radius), 0.0, 1.0)
    alpha = 1.0 - t * t * (3 - 2 * t)
    colors = np.hstack([col, alpha[:, None]])
    return verts, faces, colors


def _template_cylinder(n: int = 8) -> tuple[np.ndarray, np.ndarray]:
    theta = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring = np.stack([np.cos(theta), np.sin(theta), np.zeros(n)], 1)
    verts = np.vstack([ring, ring + [0, 0, 1.0]])
    k = np.arange(n)
    k1 = (k + 1) % n
    faces = np.vstack([np.stack([k, k1, n + k1], 1), np.stack([k, n + k1, n + k], 1)])
    return verts, faces


def _template_sphere() -> tuple[np.ndarray, np.ndarray]:
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=1)
    return np.asarray(s.vertices), np.asarray(s.faces)


_CYL = _template_cylinder()
_SPH = None


def stick_arrays(
    positions: np.ndarray,
    parents: np.ndarray,
    visible: np.ndarray,
    radius: float,
    color=(0.05, 0.6, 0.25, 1.0),
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A stick figure: a cylinder per bone and a ball per joint.

    positions : (J, 3) display space; parents : (J,); visible : (J,) bool.
    Returns vertices, faces, colours.
    """
    global _SPH
    if _SPH is None:
        _SPH = _template_sphere()
    cv, cf = _CYL
    sv, sf = _SPH
    idx = [j for j in range(len(parents)) if parents[j] >= 0 and visible[j] and visible[parents[j]]]
    verts, faces, count = [], [], 0
    if idx:
        a = positions[parents[idx]]
        b = positions[idx]
        d = b - a
        length = np.linalg.norm(d, axis=1)
        z = _unit(d)
        ref = np.where(np.abs(z[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
        x = _unit(np.cross(ref, z))
        y = np.cross(z, x)
        local = cv[None] * np.array([radius, radius, 1.0])
        v = (
            a[:, None]
            + local[..., :1] * x[:, None]
            + local[..., 1:2] * y[:, None]
            + local[..., 2:3] * length[:, None, None] * z[:, None]
        )
        verts.append(v.reshape(-1, 3))
        faces.append((cf[None] + (np.arange(len(idx)) * len(cv))[:, None, None]).reshape(-1, 3))
        count += v.shape[0] * v.shape[1]
    joints = positions[visible]
    if len(joints):
        v = joints[:, None] + 1.6 * radius * sv[None]
        verts.append(v.reshape(-1, 3))
        faces.append(
            (sf[None] + count + (np.arange(len(joints)) * len(sv))[:, None, None]).reshape(-1, 3)
        )
    verts = np.vstack(verts)
    faces = np.vstack(faces)
    colors = np.broadcast_to(np.asarray(color, float), (len(verts), 4))
    return verts, faces, colors
