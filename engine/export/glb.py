"""A take as a binary glTF 2.0 file (GLB): the skinned mannequin with its animation.

``glb_bytes(motion, roles=None, frames=None) -> bytes``; ``write_glb(motion, path, ...)``.

What is in the file (one scene, display space: metres, +Y up, as the renderer's):

* one node per skeleton joint, named as in the file, parented as in the file; its
  rest TRS is the bind frame's (the first exported frame) local translation and
  rotation, so a viewer without animation shows that pose;
* one skinned mesh: the procedural mannequin the renderer draws
  (:func:`engine.mesh.build_mannequin`, bound in the first exported frame), with
  ``POSITION``, ``NORMAL``, ``COLOR_0``, ``JOINTS_0`` and ``WEIGHTS_0`` (two-bone
  weights, padded to four), and a skin whose joints are all joint nodes, with
  ``inverseBindMatrices`` = inverse world matrices of the bind frame;
* one animation (``take``): per joint a ``rotation`` channel, and a ``translation``
  channel for joints whose translation changes (the root's path, 6-channel joints);
  ``LINEAR`` samplers on one time accessor ``k / fps`` seconds.

File coordinates map to display space by :func:`engine.render.scene.display_transform`
(``p' = s A p``): every translation is scaled by ``s`` and each root's rotation and
translation are turned by ``A``; children's local rotations are unchanged, so a
joint's world position from the node animation is exactly ``s A`` times the BVH's
forward kinematics.
"""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np

from engine.base.atomic import write_bytes
from engine.base.errors import ParameterError
from engine.model import rotations as rot
from engine.model.kinematics import forward_kinematics
from engine.model.motion import Motion

GLB_MAGIC = 0x46546C67  # "glTF"
CHUNK_JSON = 0x4E4F534A
CHUNK_BIN = 0x004E4942
FLOAT, UNSIGNED_SHORT, UNSIGNED_INT, UNSIGNED_BYTE = 5126, 5123, 5125, 5121
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963


class _Buffer:
    """The binary chunk and its bufferViews/accessors, built one array at a time."""

    def __init__(self, gltf: dict):
        self.gltf = gltf
        self.blob = bytearray()

    def add(
        self,
        array: np.ndarray,
        kind: str,
        component: int,
        target: int | None = None,
        minmax: bool = False,
        normalized: bool = False,
    ) -> int:
        """Append ``array`` (count, ...) as one accessor of ``kind`` (``"VEC3"``...);
        returns the accessor index."""
        dtype = {FLOAT: "<f4", UNSIGNED_SHORT: "<u2", UNSIGNED_INT: "<u4", UNSIGNED_BYTE: "u1"}[
            component
        ]
        data = np.ascontiguousarray(array, dtype=dtype)
        while len(self.blob) % 4:
            self.blob.append(0)
        view = {"buffer": 0, "byteOffset": len(self.blob), "byteLength": data.nbytes}
        if target is not None:
            view["target"] = target
        self.blob += data.tobytes()
        self.gltf["bufferViews"].append(view)
        acc = {
            "bufferView": len(self.gltf["bufferViews"]) - 1,
            "componentType": component,
            "count": int(data.shape[0]),
            "type": kind,
        }
        if normalized:
            acc["normalized"] = True
        if minmax:
            flat = data.reshape(data.shape[0], -1)
            cast = float if component == FLOAT else int
            acc["min"] = [cast(v) for v in flat.min(axis=0)]
            acc["max"] = [cast(v) for v in flat.max(axis=0)]
        self.gltf["accessors"].append(acc)
        return len(self.gltf["accessors"]) - 1


def _xyzw(q: np.ndarray) -> np.ndarray:
    """(w, x, y, z) -> glTF's (x, y, z, w), unit length."""
    q = rot.normalize(np.asarray(q, dtype=float))
    return np.concatenate([q[..., 1:], q[..., :1]], axis=-1)


def display_motion(motion: Motion, scale: float, axes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Local rotations (F, J, 4) (w, x, y, z) and translations (F, J, 3) in display space:
    translations scaled by ``scale``, each root turned by ``axes``."""
    q_axes = rot.from_matrix(axes)
    rots = motion.rotations.copy()
    trans = motion.translations * scale
    roots = np.flatnonzero(motion.skeleton.parents < 0)
    rots[:, roots] = rot.multiply(q_axes, rots[:, roots])
    trans[:, roots] = trans[:, roots] @ axes.T
    return rots, trans


def glb_bytes(
    motion: Motion, roles=None, frames: range | None = None, copyright: str | None = None
) -> bytes:
    """The take (frames ``frames``, default all) as a GLB with the skinned mannequin.

    ``roles`` (``engine.model.roles.Roles``) fixes arms and fingers as for the renderer.
    ``copyright``: the credit of the takes it was made from (their sources and licences),
    written as the file's ``asset.copyright`` (glTF 2.0: "a copyright message suitable for
    display to credit the content creator"); none when None or empty.
    """
    from engine.mesh.anatomy import find_anatomy
    from engine.mesh.mannequin import build_mannequin
    from engine.model.roles import side_from_name
    from engine.render.scene import display_transform

    if frames is not None:
        if len(frames) == 0 or frames.step != 1:
            raise ParameterError("frames: expected a non-empty range of consecutive frames")
        motion = motion.frames(frames.start, frames.stop)
    if motion.n_frames < 1:
        raise ParameterError("the take has no frames to export")
    skel = motion.skeleton
    pos, wrot = forward_kinematics(motion, 0, 1)
    anatomy = find_anatomy(
        skel, pos[0], wrot[0], roles=roles, side_hint=side_from_name(motion.meta.source or "")
    )
    mesh = build_mannequin(skel, anatomy, pose=(pos[0], wrot[0]))
    scale, axes = display_transform(motion, anatomy)
    rots, trans = display_motion(motion, scale, axes)
    rots = rot.make_continuous(rots, axis=0)

    gltf: dict = {
        "asset": {
            "version": "2.0",
            "generator": "HandSplice",
            **({"copyright": str(copyright)} if copyright else {}),
        },
        "scene": 0,
        "scenes": [{"name": Path(motion.meta.source or "take").stem, "nodes": []}],
        "nodes": [],
        "meshes": [],
        "skins": [],
        "animations": [],
        "materials": [],
        "buffers": [],
        "bufferViews": [],
        "accessors": [],
    }
    buf = _Buffer(gltf)
    j_count = skel.n_joints
    for j in range(j_count):
        node = {
            "name": skel.names[j],
            "translation": [float(v) for v in trans[0, j]],
            "rotation": [float(v) for v in _xyzw(rots[0, j])],
        }
        children = skel.children(j)
        if children:
            node["children"] = children
        gltf["nodes"].append(node)
    roots = [int(j) for j in np.flatnonzero(skel.parents < 0)]

    # skin: inverse bind matrices from the bind frame's world transforms (display space)
    disp = Motion(skel, rots[:1], trans[:1], motion.fps, motion.meta)
    bind_pos, bind_rot = forward_kinematics(disp)
    world = np.tile(np.eye(4), (j_count, 1, 1))
    world[:, :3, :3] = rot.to_matrix(bind_rot[0])
    world[:, :3, 3] = bind_pos[0]
    ibm = np.linalg.inv(world)
    ibm[:, 3] = (0.0, 0.0, 0.0, 1.0)
    ibm_acc = buf.add(np.swapaxes(ibm, 1, 2).reshape(j_count, 16), "MAT4", FLOAT)  # column-major
    skin = {"joints": list(range(j_count)), "inverseBindMatrices": ibm_acc, "name": "skeleton"}
    if len(roots) == 1:  # the common root of all joints (none when the file has several)
        skin["skeleton"] = roots[0]
    gltf["skins"].append(skin)

    # mesh: the mannequin's bind-pose vertices in display space
    verts = scale * mesh.vertices @ axes.T
    normals = mesh.normals @ axes.T
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    joints, weights = _four_influences(mesh.joints, mesh.weights)
    attributes = {
        "POSITION": buf.add(verts, "VEC3", FLOAT, ARRAY_BUFFER, minmax=True),
        "NORMAL": buf.add(normals, "VEC3", FLOAT, ARRAY_BUFFER),
        "COLOR_0": buf.add(np.clip(mesh.colors, 0.0, 1.0), "VEC4", FLOAT, ARRAY_BUFFER),
        "JOINTS_0": buf.add(joints, "VEC4", UNSIGNED_SHORT, ARRAY_BUFFER),
        "WEIGHTS_0": buf.add(weights, "VEC4", FLOAT, ARRAY_BUFFER),
    }
    index_type = UNSIGNED_SHORT if mesh.n_vertices < 65536 else UNSIGNED_INT
    indices = buf.add(mesh.faces.reshape(-1), "SCALAR", index_type, ELEMENT_ARRAY_BUFFER)
    gltf["materials"].append(
        {
            "name": "mannequin",
            "doubleSided": False,
            "pbrMetallicRoughness": {
                "baseColorFactor": [1.0, 1.0, 1.0, 1.0],
                "metallicFactor": 0.0,
                "roughnessFactor": 0.8,
            },
        }
    )
    gltf["meshes"].append(
        {
            "name": "mannequin",
            "primitives": [
                {"attributes": attributes, "indices": indices, "material": 0, "mode": 4}
            ],
        }
    )
    gltf["nodes"].append({"name": "mannequin", "mesh": 0, "skin": 0})
    gltf["scenes"][0]["nodes"] = roots + [j_count]

    # animation: rotation per joint, translation where it moves
    times = np.arange(motion.n_frames) / float(motion.fps)
    t_acc = buf.add(times, "SCALAR", FLOAT, minmax=True)
    samplers, channels = [], []

    def channel(node: int, path: str, values: np.ndarray, kind: str) -> None:
        samplers.append(
            {"input": t_acc, "output": buf.add(values, kind, FLOAT), "interpolation": "LINEAR"}
        )
        channels.append({"sampler": len(samplers) - 1, "target": {"node": node, "path": path}})

    tol = 1e-6 * max(1.0, float(np.abs(trans).max()))
    for j in range(j_count):
        channel(j, "rotation", _xyzw(rots[:, j]), "VEC4")
        if np.ptp(trans[:, j], axis=0).max() > tol:
            channel(j, "translation", trans[:, j], "VEC3")
    gltf["animations"].append({"name": "take", "samplers": samplers, "channels": channels})

    while len(buf.blob) % 4:
        buf.blob.append(0)
    gltf["buffers"].append({"byteLength": len(buf.blob)})
    text = json.dumps(gltf, separators=(",", ":")).encode("utf-8")
    text += b" " * (-len(text) % 4)
    total = 12 + 8 + len(text) + 8 + len(buf.blob)
    return b"".join(
        [
            struct.pack("<III", GLB_MAGIC, 2, total),
            struct.pack("<II", len(text), CHUNK_JSON),
            text,
            struct.pack("<II", len(buf.blob), CHUNK_BIN),
            bytes(buf.blob),
        ]
    )


def _four_influences(joints: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(V, K<=4) joints and weights -> (V, 4) with unused slots (0, 0), one entry per joint,
    weights summing to 1."""
    v, k = joints.shape
    if k > 4:
        raise ValueError(f"skin: {k} influences per vertex, glTF's JOINTS_0 holds 4")
    j4 = np.zeros((v, 4), np.int64)
    w4 = np.zeros((v, 4), float)
    j4[:, :k], w4[:, :k] = joints, weights
    for a in range(4):  # merge repeats of a joint into its first slot
        for b in range(a + 1, 4):
            same = (j4[:, b] == j4[:, a]) & (w4[:, b] > 0)
            w4[same, a] += w4[same, b]
            w4[same, b] = 0.0
    j4[w4 <= 0] = 0
    w4 = np.maximum(w4, 0.0)
    w4 /= np.maximum(w4.sum(axis=1, keepdims=True), 1e-12)
    return j4, w4.astype(np.float32)


def write_glb(
    motion: Motion,
    path: str | Path,
    roles=None,
    frames: range | None = None,
    copyright: str | None = None,
) -> Path:
    """Write :func:`glb_bytes` to ``path`` atomically."""
    path = Path(path)
    write_bytes(path, glb_bytes(motion, roles=roles, frames=frames, copyright=copyright))
    return path
