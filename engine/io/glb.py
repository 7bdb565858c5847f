"""What a GLB (binary glTF 2.0) holds, for ``handsplice info``: its skeleton, skins,
animations and their frames, read from the file's JSON chunk (the binary chunk is not
read: every count and time range comes from the accessors' ``count``/``min``/``max``).

``read_glb_summary(path) -> GlbSummary``. The skeleton is the first skin's joints (the
nodes it names, parented as the node tree says, rest offsets = the nodes' translations,
metres); the frames are those of the first animation's longest time accessor (HandSplice's
exports, ``engine.export.glb``: one ``take`` animation sampled at the take's rate).

A file that is not a GLB, or whose JSON does not hold together (an index past its list,
a node with two parents), is refused with ``MotionFormatError`` naming the file and the
field.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from engine.base.errors import MotionFormatError
from engine.base.json_text import JsonTextError, parse_json
from engine.base.limits import MAX_GLB_JSON_BYTES, MAX_JOINTS
from engine.model.motion import Skeleton

GLB_MAGIC = b"glTF"
CHUNK_JSON = 0x4E4F534A


@dataclass
class Animation:
    """One glTF animation: its name, channels, and the frames of its longest sampler
    (``frames`` time samples from ``start_s`` to ``end_s`` seconds)."""

    name: str
    channels: int
    frames: int
    start_s: float
    end_s: float

    @property
    def fps(self) -> float:
        """Samples per second (evenly sampled, as HandSplice writes them); 0 for one sample."""
        span = self.end_s - self.start_s
        return (self.frames - 1) / span if self.frames > 1 and span > 0 else 0.0


@dataclass
class GlbSummary:
    """What :func:`read_glb_summary` found. ``skeleton`` None: the file has no skin."""

    path: Path
    generator: str
    nodes: int
    skeleton: Skeleton | None
    skinned_vertices: int
    skinned_meshes: list[str] = field(default_factory=list)
    animations: list[Animation] = field(default_factory=list)


def _json_chunk(path: Path) -> dict:
    with path.open("rb") as f:
        header = f.read(20)
        if len(header) < 20 or header[:4] != GLB_MAGIC:
            raise MotionFormatError(path, "not a GLB file (no binary glTF header)")
        version, total, length, kind = struct.unpack("<IIII", header[4:20])
        if version != 2:
            raise MotionFormatError(path, f"glTF version {version}; expected 2")
        if kind != CHUNK_JSON:
            raise MotionFormatError(path, "the first chunk is not the JSON chunk")
        if length > MAX_GLB_JSON_BYTES:
            raise MotionFormatError(
                path, f"a JSON chunk of {length:,} bytes (more than {MAX_GLB_JSON_BYTES:,})"
            )
        text = f.read(length)
    if len(text) < length:
        raise MotionFormatError(path, f"JSON chunk: {len(text):,} of {length:,} bytes (truncated?)")
    try:
        doc = parse_json(text, finite=False)
    except JsonTextError as exc:
        raise MotionFormatError(path, f"JSON chunk: {exc.detail}") from None
    if not isinstance(doc, dict):
        raise MotionFormatError(path, "JSON chunk: expected an object")
    return doc


def _list(path: Path, doc: dict, key: str) -> list:
    value = doc.get(key, [])
    if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
        raise MotionFormatError(path, f"{key}: expected a list of objects")
    return value


def _index(path: Path, value, count: int, where: str) -> int:
    if not isinstance(value, int) or isinstance(value, bool) or not 0 <= value < count:
        shown = repr(value) if len(repr(value)) <= 40 else repr(value)[:40] + "…"
        raise MotionFormatError(path, f"{where}: {shown} is not an index below {count}")
    return value


def _skeleton(path: Path, nodes: list, skin: dict) -> Skeleton:
    """The skin's joints as a Skeleton: parents before children (depth first from the
    joints whose parent is no joint), names, rest translations as offsets."""
    joints = skin.get("joints", [])
    if not isinstance(joints, list) or not joints:
        raise MotionFormatError(path, "skins[0].joints: expected a non-empty list")
    if len(joints) > MAX_JOINTS:
        raise MotionFormatError(path, f"{len(joints):,} joints (more than {MAX_JOINTS:,})")
    joints = [_index(path, j, len(nodes), "skins[0].joints") for j in joints]
    parent: dict[int, int] = {}
    for k, node in enumerate(nodes):
        for c in node.get("children", []):
            c = _index(path, c, len(nodes), f"nodes[{k}].children")
            if c in parent:
                raise MotionFormatError(path, f"nodes[{c}] has two parents: not a node tree")
            parent[c] = k
    members = set(joints)
    order: list[int] = []
    stack = [j for j in reversed(joints) if parent.get(j) not in members]
    while stack:
        j = stack.pop()
        if j in order:
            raise MotionFormatError(path, f"nodes[{j}]: its children lead back to it")
        order.append(j)
        kids = [c for c in nodes[j].get("children", []) if c in members]
        stack.extend(reversed(kids))
    if len(order) != len(members):
        raise MotionFormatError(path, "skins[0].joints: the joints' node tree has a cycle")
    at = {j: k for k, j in enumerate(order)}
    names = [str(nodes[j].get("name") or f"node{j}") for j in order]
    offsets = np.zeros((len(order), 3))
    for k, j in enumerate(order):
        t = nodes[j].get("translation", [0.0, 0.0, 0.0])
        try:
            offsets[k] = np.asarray(t, dtype=float).reshape(3)
        except (TypeError, ValueError):
            raise MotionFormatError(path, f"nodes[{j}].translation: expected 3 numbers") from None
    parents = [at.get(parent.get(j), -1) for j in order]
    return Skeleton(names, parents, offsets, [()] * len(order))


def _animation(path: Path, doc: dict, k: int, anim: dict) -> Animation:
    accessors = _list(path, doc, "accessors")
    samplers = anim.get("samplers", [])
    channels = anim.get("channels", [])
    if not isinstance(samplers, list) or not isinstance(channels, list):
        raise MotionFormatError(path, f"animations[{k}]: samplers and channels must be lists")
    frames, start, end = 0, 0.0, 0.0
    for s, sampler in enumerate(samplers):
        where = f"animations[{k}].samplers[{s}].input"
        acc = accessors[_index(path, sampler.get("input"), len(accessors), where)]
        count = acc.get("count", 0)
        if not isinstance(count, int) or count < 0:
            raise MotionFormatError(path, f"{where}: count {count!r} is not a whole number")
        if count > frames:
            lo, hi = acc.get("min", [0.0]), acc.get("max", [0.0])
            try:
                start, end = float(lo[0]), float(hi[0])
            except (TypeError, ValueError, IndexError):
                raise MotionFormatError(path, f"{where}: no time range (min/max)") from None
            frames = count
    return Animation(str(anim.get("name") or f"animation {k}"), len(channels), frames, start, end)


def read_glb_summary(path: str | Path) -> GlbSummary:
    """Read what ``path`` (a .glb) holds; see the module's docstring.

    Raises ``MotionFormatError`` (not a GLB, a broken JSON chunk) or ``OSError``."""
    path = Path(path)
    if path.is_dir():
        raise MotionFormatError(path, "is a folder, expected a .glb file")
    doc = _json_chunk(path)
    try:
        return _summary(path, doc)
    except (AttributeError, TypeError, KeyError) as exc:  # a field of another type than glTF's
        raise MotionFormatError(path, f"JSON chunk: not glTF's layout ({exc})") from None


def _summary(path: Path, doc: dict) -> GlbSummary:
    nodes = _list(path, doc, "nodes")
    skins = _list(path, doc, "skins")
    meshes = _list(path, doc, "meshes")
    accessors = _list(path, doc, "accessors")
    skeleton = _skeleton(path, nodes, skins[0]) if skins else None
    skinned, vertices = [], 0
    for k, node in enumerate(nodes):
        if "skin" not in node or "mesh" not in node:
            continue
        mesh = meshes[_index(path, node["mesh"], len(meshes), f"nodes[{k}].mesh")]
        skinned.append(str(mesh.get("name") or node.get("name") or f"mesh {node['mesh']}"))
        for primitive in mesh.get("primitives", []):
            position = (primitive.get("attributes") or {}).get("POSITION")
            if position is not None:
                where = f"nodes[{k}]'s mesh POSITION"
                count = accessors[_index(path, position, len(accessors), where)].get("count", 0)
                vertices += count if isinstance(count, int) else 0
    animations = [_animation(path, doc, k, a) for k, a in enumerate(_list(path, doc, "animations"))]
    asset = doc.get("asset") if isinstance(doc.get("asset"), dict) else {}
    return GlbSummary(
        path=path,
        generator=str(asset.get("generator", "")),
        nodes=len(nodes),
        skeleton=skeleton,
        skinned_vertices=vertices,
        skinned_meshes=skinned,
        animations=animations,
    )
