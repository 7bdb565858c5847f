"""Skinned previews with pyrender, headless (EGL on Mesa, OSMesa fallback).

``Preview`` is built once per take (or set of takes) and renders frames as
``(H, W, 3) uint8`` arrays:

>>> preview = Preview([body, hand, spliced], labels=["body", "hand", "spliced"])
>>> image = preview.frame(120, view="side_by_side", camera="three-quarter", size=(960, 360))
>>> image = preview.frame(120, view="overlay", take=2, overlay_take=0)  # stick over skin
>>> image = preview.frame(120, trails=True, phases=phase_array)

Views: ``single`` (one take), ``side_by_side`` (each take in its own panel, its own
auto-framed camera; frames matched by time unless given), ``overlay`` (the stick
figure of ``overlay_take`` drawn over the skinned ``take``, in the same space;
where the sticks are hidden behind the skin they show through at half strength,
Heloir et al.'s re-creation check). Cameras: ``front``, ``side``,
``three-quarter`` and ``hands`` (a close-up that keeps both hands in view; see
:mod:`engine.render.scene`).

One OpenGL renderer per process is created lazily and reused by every
``Preview`` (resized on demand, :func:`engine.render.backend.shared_renderer`);
every OpenGL call holds :data:`engine.render.backend.GL_LOCK`, so previews may be
used from the threads of a Panel server (renders then run one at a time).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from engine.base.errors import ParameterError
from engine.mesh.skinning import SkinnedMesh
from engine.model.motion import Motion
from engine.render import trails as tr
from engine.render.backend import (
    GL_LOCK,
    ensure_platform,
    release_current,
    render_color,
    shared_renderer,
)
from engine.render.scene import CAMERAS, TakeView, floor_mesh_arrays, stick_arrays

VIEWS = ("single", "side_by_side", "overlay")
BACKGROUND = (0.96, 0.96, 0.97)
YFOV = np.radians(35.0)
MAX_SIZE = 4096
# directional lights fixed to the camera: ((pitch, yaw) degrees, intensity)
LIGHTS = (((-40.0, -30.0), 3.2), ((-10.0, 50.0), 1.3), ((60.0, 170.0), 1.0))
FLOOR_RADIUS = 0.8  # floor patch radius in body heights (at least ~1 framing radius)


def parse_size(size) -> tuple[int, int]:
    """``(width, height)`` from a tuple or a ``"WxH"`` string, each 16..4096."""
    if isinstance(size, str):
        parts = size.lower().split("x")
        if len(parts) != 2 or not all(p.strip().isdigit() and len(p.strip()) <= 5 for p in parts):
            raise ParameterError(
                f"size {size[:40]!r}: expected WIDTHxHEIGHT from 16 to {MAX_SIZE}, e.g. 640x480"
            )
        size = (int(parts[0]), int(parts[1]))
    try:
        w, h = (int(v) for v in size)
    except (TypeError, ValueError):
        raise ParameterError(f"size {size!r}: expected (width, height)") from None
    if not (16 <= w <= MAX_SIZE and 16 <= h <= MAX_SIZE):
        raise ParameterError(f"size {w}x{h}: width and height must lie in 16..{MAX_SIZE}")
    return w, h


class Preview:
    """Renders one or more takes (see the module docstring).

    Parameters
    ----------
    takes : Motion or sequence of Motion
    labels : names shown on side-by-side panels (default: file names)
    meshes : optional SkinnedMesh per take (``None`` entries: the mannequin); a
        user's mesh comes from :func:`engine.mesh.bind.bind_mesh`
    size : default ``(width, height)`` in pixels
    phases : per-frame gesture phases for the trails of take 0, or
        ``{take index: phases}``; each is one array for both hands,
        ``{"left": array, "right": array}`` or a ``GesturePhases``
    roles : optional ``engine.model.roles.Roles`` per take (``None``: found from names)
    close_up_sides : the hands the ``hands`` camera frames, e.g. ``("right",)`` (default all)
    views : optional ``TakeView`` per take (``None`` entries: built here) already built
        for that take with these options: a take shown again (the app's body and hand
        takes after each edit) is not prepared again (seconds for a long take)
    """

    def __init__(
        self,
        takes: Motion | Sequence[Motion],
        labels: Sequence[str] | None = None,
        meshes: Sequence[SkinnedMesh | None] | None = None,
        size: tuple[int, int] | str = (640, 480),
        phases=None,
        roles: Sequence | None = None,
        close_up_sides: Sequence | None = None,
        views: Sequence[TakeView | None] | None = None,
        cancelled=None,
    ):
        takes = [takes] if isinstance(takes, Motion) else list(takes)
        if not takes:
            raise ValueError("Preview: needs at least one take")
        for k, t in enumerate(takes):
            if not isinstance(t, Motion):
                raise TypeError(f"Preview: take {k} is a {type(t).__name__}, expected Motion")
        meshes = list(meshes) if meshes is not None else [None] * len(takes)
        if len(meshes) != len(takes):
            raise ValueError(f"Preview: {len(meshes)} meshes for {len(takes)} takes")
        if labels is None:
            labels = [_label(t, k) for k, t in enumerate(takes)]
        if len(labels) != len(takes):
            raise ValueError(f"Preview: {len(labels)} labels for {len(takes)} takes")
        self.size = parse_size(size)
        roles = list(roles) if roles is not None else [None] * len(takes)
        if len(roles) != len(takes):
            raise ValueError(f"Preview: {len(roles)} role sets for {len(takes)} takes")
        given = list(views) if views is not None else [None] * len(takes)
        if len(given) != len(takes):
            raise ValueError(f"Preview: {len(given)} views for {len(takes)} takes")
        for k, (t, v) in enumerate(zip(takes, given, strict=True)):
            if v is not None and v.motion is not t:
                raise ValueError(f"Preview: view {k} is not of take {k}")
        self.views = [
            v
            if v is not None
            else TakeView.from_motion(
                t,
                mesh=m,
                label=lab,
                roles=r,
                close_up_sides=close_up_sides,
                cancelled=cancelled,
            )
            for t, m, lab, r, v in zip(takes, meshes, labels, roles, given, strict=True)
        ]
        if phases is not None and not (
            isinstance(phases, Mapping) and all(isinstance(k, int) for k in phases)
        ):
            phases = {0: phases}
        self.phases: dict[int, object] = dict(phases or {})
        self._materials = None
        self._trail_cache: dict[tuple, object] = {}

    # ------------------------------------------------------------------ public
    @property
    def n_frames(self) -> int:
        """Frames of take 0."""
        return self.views[0].n_frames

    @property
    def fps(self) -> float:
        return float(self.views[0].motion.fps)

    def matched_frames(self, i: int) -> list[int]:
        """Frame of each take at the time of take 0's frame ``i`` (clipped to each take)."""
        t = self.views[0].check_frame(i) / self.views[0].motion.fps
        return [int(np.clip(round(t * v.motion.fps), 0, v.n_frames - 1)) for v in self.views]

    def frame(
        self,
        i: int,
        view: str = "single",
        camera: str = "three-quarter",
        size: tuple[int, int] | str | None = None,
        take: int = 0,
        overlay_take: int = 1,
        frames: Sequence[int] | None = None,
        trails: bool = False,
        trail_range: tuple[int, int] | None = None,
        trail_style: str = "line",
        phases=None,
        floor: bool = True,
    ) -> np.ndarray:
        """Render frame ``i`` (of take 0, or of ``take``) as ``(H, W, 3) uint8``.

        view : ``single`` | ``side_by_side`` | ``overlay``
        camera : ``front`` | ``side`` | ``three-quarter`` | ``hands`` (close-up)
        take : the skinned take of ``single`` and ``overlay``
        overlay_take : whose stick figure ``overlay`` draws (itself if only one take)
        frames : explicit frame per take (side by side, overlay); default by time
        trails : draw both hands' trails over ``trail_range`` (default the whole take)
        trail_style : ``line`` (a tube) or ``spheres`` (one ball per sample)
        phases : per-frame phases for the trails of ``take`` in this call (see the
            class); other panels use the phases given to the constructor
        floor : draw the floor patch (body takes)
        """
        if view not in VIEWS:
            raise ParameterError(f"view {view!r}: expected one of {', '.join(VIEWS)}")
        if camera not in CAMERAS:
            raise ParameterError(f"camera {camera!r}: expected one of {', '.join(CAMERAS)}")
        if trail_style not in tr.STYLES:
            raise ParameterError(
                f"trail style {trail_style!r}: expected one of {', '.join(tr.STYLES)}"
            )
        width, height = parse_size(size) if size is not None else self.size
        take = self._check_take(take, "take")
        options = dict(
            camera=camera,
            trails=trails,
            trail_range=trail_range,
            trail_style=trail_style,
            floor=floor,
        )
        if view == "side_by_side":
            picks = list(frames) if frames is not None else self.matched_frames(i)
            if len(picks) != len(self.views):
                raise ParameterError(f"frames: expected {len(self.views)} values, got {len(picks)}")
            n = len(self.views)
            widths = [width // n + (1 if k < width % n else 0) for k in range(n)]
            panels = []
            for k, (v, f, w) in enumerate(zip(self.views, picks, widths, strict=True)):
                img = self._render(
                    k,
                    v.check_frame(f),
                    (w, height),
                    phases=self._phases(k, phases, take),
                    **options,
                )
                panels.append(label_image(img, v.label) if n > 1 else img)
            out = np.concatenate(panels, axis=1)
            for x in np.cumsum(widths)[:-1]:
                out[:, max(0, x - 1) : x + 1] = 255
            return out
        if view == "overlay":
            other = self._check_take(overlay_take if len(self.views) > 1 else 0, "overlay_take")
            if frames is not None:
                fi, fo = (
                    (int(frames[take]), int(frames[other]))
                    if len(frames) == len(self.views)
                    else (int(frames[0]), int(frames[-1]))
                )
            else:
                base = self.views[take].check_frame(i)
                t = base / self.views[take].motion.fps
                fi = base
                fo = int(
                    np.clip(
                        round(t * self.views[other].motion.fps), 0, self.views[other].n_frames - 1
                    )
                )
            return self._render(
                take,
                fi,
                (width, height),
                stick=(other, fo),
                phases=self._phases(take, phases, take),
                **options,
            )
        return self._render(
            take,
            self.views[take].check_frame(i),
            (width, height),
            phases=self._phases(take, phases, take),
            **options,
        )

    def joint_positions(self, i: int, take: int = 0) -> np.ndarray:
        """(J, 3) world joint positions of ``take`` at frame ``i``, display space (metres, +Y up)."""
        view = self.views[self._check_take(take, "take")]
        return view.positions[view.check_frame(i)].copy()

    def project(
        self,
        points: np.ndarray,
        i: int,
        take: int = 0,
        camera: str = "three-quarter",
        size: tuple[int, int] | str | None = None,
    ) -> np.ndarray:
        """Pixel coordinates ``(N, 2)`` (x right, y down) of display-space ``points (N, 3)``
        in ``frame(i, view="single", take=take, camera=camera, size=size)``."""
        if camera not in CAMERAS:
            raise ParameterError(f"camera {camera!r}: expected one of {', '.join(CAMERAS)}")
        width, height = parse_size(size) if size is not None else self.size
        view = self.views[self._check_take(take, "take")]
        pose = view.camera_pose(view.check_frame(i), camera, width / height, YFOV)
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        cam = (pts - pose[:3, 3]) @ pose[:3, :3]  # camera frame: x right, y up, -z forward
        f = 1.0 / np.tan(0.5 * YFOV)
        depth = np.maximum(-cam[:, 2], 1e-9)
        x_ndc = f / (width / height) * cam[:, 0] / depth
        y_ndc = f * cam[:, 1] / depth
        return np.stack([(x_ndc + 1) * 0.5 * width, (1 - y_ndc) * 0.5 * height], axis=1)

    def close(self) -> None:
        """Drop cached trail meshes (the shared renderer stays for the other previews)."""
        with GL_LOCK:
            self._trail_cache.clear()

    def __enter__(self) -> Preview:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ---------------------------------------------------------------- internals
    def _check_take(self, k: int, field: str) -> int:
        if not isinstance(k, (int, np.integer)) or not 0 <= int(k) < len(self.views):
            raise ParameterError(f"{field} {k!r}: expected 0..{len(self.views) - 1}")
        return int(k)

    def _phases(self, k: int, phases, take: int):
        if phases is not None and k == take:
            return phases
        return self.phases.get(k)

    def _mesh(self, verts, faces, colors, normals=None, material="skin"):
        import pyrender

        if self._materials is None:
            self._materials = {
                "skin": pyrender.MetallicRoughnessMaterial(
                    baseColorFactor=(1.0, 1.0, 1.0, 1.0), metallicFactor=0.0, roughnessFactor=0.7
                ),
                "flat": pyrender.MetallicRoughnessMaterial(
                    baseColorFactor=(1.0, 1.0, 1.0, 1.0), metallicFactor=0.0, roughnessFactor=1.0
                ),
                "floor": pyrender.MetallicRoughnessMaterial(
                    baseColorFactor=(1.0, 1.0, 1.0, 1.0),
                    metallicFactor=0.0,
                    roughnessFactor=1.0,
                    alphaMode="BLEND",
                ),
            }
        if normals is None:
            from engine.mesh.skinning import vertex_normals

            normals = vertex_normals(verts, faces)
        prim = pyrender.Primitive(
            positions=np.asarray(verts, np.float32),
            normals=np.asarray(normals, np.float32),
            color_0=np.asarray(colors, np.float32),
            indices=np.asarray(faces, np.uint32),
            material=self._materials[material],
        )
        return pyrender.Mesh([prim])

    def _floor(self, k: int, i: int):
        """The floor patch under take ``k`` at frame ``i`` (None for a hand take)."""
        v = self.views[k]
        if v.floor_y is None:
            return None
        radius = max(FLOOR_RADIUS * v.height_m, 1.4 * v.radius * FLOOR_RADIUS / 1.1)
        verts, faces, colors = floor_mesh_arrays(
            v.targets[i], radius, v.floor_y - 1e-3, tile=0.5 * max(v.height_m / 1.75, 0.2)
        )
        normals = np.tile([0.0, 1.0, 0.0], (len(verts), 1))
        return self._mesh(verts, faces, colors, normals, "floor")

    def _trails(self, k: int, trail_range, style: str, phases):
        v = self.views[k]
        lo, hi = (0, v.n_frames) if trail_range is None else trail_range
        lo, hi = int(max(0, lo)), int(min(v.n_frames, hi))
        if hi - lo < 1:
            raise ParameterError(
                f"trail_range {trail_range}: empty for a take of {v.n_frames} frames"
            )
        hands = v.anatomy.hand_joints()
        codes = tr.per_side_phases(phases, list(hands), v.n_frames)
        key = (
            k,
            lo,
            hi,
            style,
            tuple((s, None if c is None else hash(c.tobytes())) for s, c in sorted(codes.items())),
        )
        if key in self._trail_cache:
            return self._trail_cache[key]
        step = max(1, (hi - lo) // 600)
        idx = np.arange(lo, hi, step)
        radius = 0.006 * max(v.height_m, 0.3) if v.anatomy.kind == "body" else 0.004
        if style == "spheres":
            radius *= 1.6
        parts = []
        for side, joint in hands.items():
            pts = v.positions[idx, joint]
            c = codes[side]
            cols = tr.trail_colors(None if c is None else c[idx], side, len(idx))
            parts.append(tr.trail_arrays(pts, cols, radius, style))
        parts = [p for p in parts if len(p[0])]
        mesh = None
        if parts:
            verts, faces, colors, n = [], [], [], 0
            for pv, pf, pc in parts:
                verts.append(pv)
                faces.append(pf + n)
                colors.append(pc)
                n += len(pv)
            mesh = self._mesh(
                np.vstack(verts), np.vstack(faces), np.vstack(colors), material="flat"
            )
        if len(self._trail_cache) > 16:
            self._trail_cache.clear()
        self._trail_cache[key] = mesh
        return mesh

    def _render(
        self,
        k: int,
        i: int,
        size: tuple[int, int],
        camera: str,
        trails: bool,
        trail_range,
        trail_style: str,
        floor: bool,
        phases=None,
        stick: tuple[int, int] | None = None,
    ) -> np.ndarray:
        ensure_platform()
        import pyrender

        v = self.views[k]
        verts, normals = v.vertices(i)
        with GL_LOCK:
            scene = pyrender.Scene(bg_color=(*BACKGROUND, 1.0), ambient_light=(0.38, 0.38, 0.4))
            scene.add(self._mesh(verts, v.mesh.faces, v.mesh.colors, normals))
            if floor:
                floor_mesh = self._floor(k, i)
                if floor_mesh is not None:
                    scene.add(floor_mesh)
            if trails:
                trail_mesh = self._trails(k, trail_range, trail_style, phases)
                if trail_mesh is not None:
                    scene.add(trail_mesh)
            width, height = size
            cam_pose = v.camera_pose(i, camera, width / height, YFOV)
            scene.add(
                pyrender.PerspectiveCamera(
                    yfov=YFOV,
                    aspectRatio=width / height,
                    znear=0.02 * v.radius,
                    zfar=60.0 * v.radius,
                ),
                pose=cam_pose,
            )
            for angles, power in LIGHTS:
                scene.add(
                    pyrender.DirectionalLight(color=np.ones(3), intensity=power),
                    pose=cam_pose @ _rotation(*angles),
                )
            renderer = self._get_renderer(width, height)
            try:
                color, depth = render_color(renderer, scene, depth=stick is not None)
                color = np.array(color[..., :3], dtype=np.uint8, copy=True)
                if stick is not None:
                    color = self._overlay(renderer, scene, color, depth, stick, v)
            finally:
                release_current(renderer)
        return color

    def _overlay(self, renderer, scene, color, depth, stick, base_view: TakeView) -> np.ndarray:
        k2, f2 = stick
        other = self.views[k2]
        pos = other.positions[f2]
        radius = 0.009 * base_view.height_m if base_view.anatomy.kind == "body" else 0.003
        verts, faces, colors = stick_arrays(
            pos, other.motion.skeleton.parents, other._visible, radius
        )
        for node in list(scene.mesh_nodes):
            node.mesh.is_visible = False
        scene.add(self._mesh(verts, faces, colors))
        s_color, s_depth = renderer.render(scene)
        for node in list(scene.mesh_nodes):
            node.mesh.is_visible = True
        mask = s_depth > 0
        in_front = mask & ((depth <= 0) | (s_depth <= depth * 1.002))
        alpha = np.where(in_front, 1.0, np.where(mask, 0.45, 0.0))[..., None]
        return (color * (1 - alpha) + s_color[..., :3] * alpha).round().astype(np.uint8)

    def _get_renderer(self, width: int, height: int):
        return shared_renderer(width, height)


def _rotation(pitch_deg: float, yaw_deg: float) -> np.ndarray:
    """4x4 rotation: yaw about +Y then pitch about +X (degrees)."""
    p, y = np.radians(pitch_deg), np.radians(yaw_deg)
    ry = np.array(
        [[np.cos(y), 0, np.sin(y), 0], [0, 1, 0, 0], [-np.sin(y), 0, np.cos(y), 0], [0, 0, 0, 1]]
    )
    rx = np.array(
        [[1, 0, 0, 0], [0, np.cos(p), -np.sin(p), 0], [0, np.sin(p), np.cos(p), 0], [0, 0, 0, 1]]
    )
    return ry @ rx


def _label(motion: Motion, k: int) -> str:
    from pathlib import Path

    src = motion.meta.source
    return Path(src).stem if src else f"take {k}"


def label_image(img: np.ndarray, text: str) -> np.ndarray:
    """Write ``text`` in the top-left corner of ``img`` (PIL default font)."""
    if not text:
        return img
    from PIL import Image, ImageDraw, ImageFont

    pil = Image.fromarray(img)
    draw = ImageDraw.Draw(pil)
    size = max(10, min(22, img.shape[0] // 22))
    try:
        font = ImageFont.load_default(size=size)
    except TypeError:  # Pillow < 10.1
        font = ImageFont.load_default()
    box = draw.textbbox((6, 4), text, font=font)
    draw.rectangle((box[0] - 3, box[1] - 2, box[2] + 3, box[3] + 2), fill=(255, 255, 255))
    draw.text((6, 4), text, fill=(30, 30, 30), font=font)
    return np.asarray(pil)


#: the caption strip's font size (pixels: Pillow's default font, legible at 100 %) and
#: most lines (a longer text is cut with an ellipsis; files carry it whole in metadata)
CAPTION_FONT_PX = 12
CAPTION_MAX_LINES = 4


def caption_strip(text: str, width: int, font_px: int = CAPTION_FONT_PX) -> np.ndarray:
    """``(H, width, 3) uint8``: ``text`` in dark grey on white, wrapped at words to
    ``width`` pixels (at most :data:`CAPTION_MAX_LINES` lines), to put under a video's
    frames: it covers nothing of the takes. ``H`` is the lines' height and a margin;
    ``(0, width, 3)`` for an empty text."""
    if not text or width <= 0:
        return np.zeros((0, max(int(width), 0), 3), np.uint8)
    from PIL import Image, ImageDraw, ImageFont

    try:
        font = ImageFont.load_default(size=font_px)
    except TypeError:  # Pillow < 10.1
        font = ImageFont.load_default()
    measure = ImageDraw.Draw(Image.new("RGB", (1, 1))).textlength
    room = width - 12
    lines: list[str] = []
    for word in str(text).split():
        if lines and measure(f"{lines[-1]} {word}", font=font) <= room:
            lines[-1] = f"{lines[-1]} {word}"
        else:
            lines.append(word)
    if len(lines) > CAPTION_MAX_LINES:
        lines = lines[:CAPTION_MAX_LINES]
        while lines[-1] and measure(lines[-1] + " …", font=font) > room:
            lines[-1] = lines[-1][:-1]
        lines[-1] += " …"
    step = font_px + 4
    pil = Image.new("RGB", (int(width), step * len(lines) + 6), (255, 255, 255))
    draw = ImageDraw.Draw(pil)
    for k, line in enumerate(lines):
        draw.text((6, 3 + step * k), line, fill=(40, 40, 40), font=font)
    return np.asarray(pil)
