"""Bind a user's own mesh (OBJ, PLY, GLB/GLTF, STL, OFF) to a skeleton.

``bind_mesh(path_or_trimesh, skeleton) -> SkinnedMesh``: the mesh is assumed to
be modelled in the skeleton's rest pose (or in ``pose``, e.g. a captured frame),
in the skeleton's file units and axes. ``transform`` (4x4) converts it first
(another unit or up axis), and ``fit=True`` scales and moves it so its bounding
box matches the skeleton's along the body's up direction (feet on the lowest
joint, centred on the joints).

Weights follow Jin & Hahn (see :mod:`engine.mesh.skinning`): each vertex's
nearest bone and the nearest bone adjacent to it, split by the angular median at
their shared joint. With no owner information the nearest bone decides, so a
mesh modelled with the hands touching the thighs (arms down) may bind finger
vertices to the leg: model or bind in a T- or A-pose with the hands clear.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from engine.base.errors import HandSpliceError
from engine.mesh.anatomy import find_anatomy
from engine.mesh.mannequin import skeleton_bones
from engine.mesh.skinning import SkinnedMesh, two_bone_weights, vertex_normals
from engine.model.kinematics import rest_positions
from engine.model.motion import Skeleton

MESH_FORMATS = (".obj", ".ply", ".glb", ".gltf", ".stl", ".off")
DEFAULT_COLOR = (0.62, 0.66, 0.72, 1.0)


class MeshFormatError(HandSpliceError, ValueError):
    """A mesh file cannot be read or holds no triangles."""


def load_mesh(path: str | Path):
    """Read a triangle mesh (a GLB/GLTF scene is flattened into one mesh).

    Returns ``trimesh.Trimesh``. Raises ``FileNotFoundError`` or
    :class:`MeshFormatError` naming the file.
    """
    import trimesh

    path = Path(path)
    if path.suffix.lower() not in MESH_FORMATS:
        raise MeshFormatError(
            f"{path.name}: unsupported mesh format; expected one of {', '.join(MESH_FORMATS)}"
        )
    if not path.exists():
        raise FileNotFoundError(2, "no such file", str(path))
    try:
        mesh = trimesh.load(path, force="mesh", process=False)
    except Exception as exc:  # trimesh raises many kinds on broken files
        raise MeshFormatError(
            f"{path.name}: cannot read the mesh ({type(exc).__name__}: {exc})"
        ) from exc
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise MeshFormatError(f"{path.name}: holds no triangles")
    return mesh


def bind_mesh(
    mesh,
    skeleton: Skeleton,
    pose: tuple[np.ndarray, np.ndarray] | None = None,
    transform: np.ndarray | None = None,
    fit: bool = False,
    blend: float = 0.5,
    color=None,
) -> SkinnedMesh:
    """Skin a mesh to ``skeleton`` with two-bone weights.

    Parameters
    ----------
    mesh : path or ``trimesh.Trimesh``
        Modelled in the bind pose, in the skeleton's units and axes (after
        ``transform`` and ``fit``).
    skeleton : Skeleton
    pose : (positions (J, 3), rotations (J, 4)), optional
        World pose the mesh is modelled in; default the rest pose.
    transform : (4, 4) float, optional
        Applied to the mesh's vertices first (units, axes, placement).
    fit : bool
        Scale and move the mesh so its extent along the body's up direction is
        1.08 times the joints' (head top and soles beyond the joints), its lowest
        point at the lowest joint and its centre over the joints' centre.
    blend : float in (0, 1], width of the weight blend at joints
    color : RGBA in [0, 1] for meshes without vertex colours

    Returns
    -------
    SkinnedMesh (``part`` all ``"body"``)
    """
    import trimesh

    if not isinstance(mesh, trimesh.Trimesh):
        mesh = load_mesh(mesh)
    verts = np.asarray(mesh.vertices, dtype=float)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    if len(verts) == 0 or len(faces) == 0:
        raise MeshFormatError("bind_mesh: the mesh holds no triangles")
    if not np.all(np.isfinite(verts)):
        raise MeshFormatError("bind_mesh: the mesh has non-finite vertex coordinates")
    if transform is not None:
        t = np.asarray(transform, dtype=float)
        if t.shape != (4, 4):
            raise ValueError(f"bind_mesh: transform must be 4x4, got {t.shape}")
        verts = verts @ t[:3, :3].T + t[:3, 3]
    if pose is None:
        pos, rots = rest_positions(skeleton), None
    else:
        pos, rots = np.asarray(pose[0], float), np.asarray(pose[1], float)
        if pos.shape != (skeleton.n_joints, 3) or rots.shape != (skeleton.n_joints, 4):
            raise ValueError(
                f"bind_mesh: pose must be ({skeleton.n_joints}, 3) positions and "
                f"({skeleton.n_joints}, 4) rotations"
            )
    anatomy = find_anatomy(skeleton, pos, rots)
    if fit:
        verts = _fit(verts, pos, anatomy)
    bones, _, _ = skeleton_bones(skeleton, anatomy, pos, rots)
    joints, weights = two_bone_weights(verts, bones, blend=blend)
    colors = _colors(mesh, len(verts), color)
    from engine.model import rotations as rot

    return SkinnedMesh(
        vertices=verts,
        faces=faces,
        normals=vertex_normals(verts, faces),
        colors=colors,
        joints=joints,
        weights=weights,
        bind_positions=pos,
        bind_rotations=rot.identity((skeleton.n_joints,)) if rots is None else rots,
        part=np.zeros(len(verts), np.int64),
        part_names=("body",),
    )


def _fit(verts: np.ndarray, joints: np.ndarray, anatomy) -> np.ndarray:
    up = anatomy.up
    visible = np.ones(len(joints), bool)
    visible[list(anatomy.hidden)] = False
    jp = joints[visible]
    j_h = jp @ up
    v_h = verts @ up
    j_ext = float(np.ptp(j_h))
    v_ext = float(np.ptp(v_h))
    if v_ext <= 0 or j_ext <= 0:
        raise MeshFormatError("bind_mesh: cannot fit a flat mesh or skeleton")
    scale = 1.08 * j_ext / v_ext
    v = verts * scale
    # centre across, lowest point on the lowest joint
    v_center = v.mean(axis=0)
    j_center = jp.mean(axis=0)
    shift = (j_center - v_center) - np.dot(j_center - v_center, up) * up
    shift += (j_h.min() - 0.02 * j_ext - (v @ up).min()) * up
    return v + shift


def _colors(mesh, n: int, color) -> np.ndarray:
    if color is not None:
        rgba = np.asarray(color, float).reshape(-1)
        if rgba.shape[0] == 3:
            rgba = np.append(rgba, 1.0)
        return np.tile(rgba, (n, 1))
    try:
        vc = np.asarray(mesh.visual.vertex_colors, dtype=float)
        if vc.shape == (n, 4) and mesh.visual.kind == "vertex":
            return vc / 255.0
    except (AttributeError, ValueError):
        pass
    return np.tile(DEFAULT_COLOR, (n, 1))
