"""Meshes for any skeleton: a procedural mannequin, user meshes, two-bone skinning.

``build_mannequin(skeleton, pose=...)`` / ``mannequin_for(motion)`` -> ``SkinnedMesh``;
``bind_mesh(path, skeleton)`` for a user's OBJ/PLY/GLB; ``two_bone_weights`` (Jin &
Hahn 2005) and ``linear_blend_skinning``; ``find_anatomy`` finds the body parts.
"""

from engine.mesh.anatomy import Anatomy, HandParts, find_anatomy
from engine.mesh.bind import bind_mesh, load_mesh
from engine.mesh.mannequin import build_mannequin, mannequin_for
from engine.mesh.skinning import (
    Bones,
    SkinnedMesh,
    linear_blend_skinning,
    skinning_matrices,
    two_bone_weights,
)

__all__ = [
    "Anatomy",
    "Bones",
    "HandParts",
    "SkinnedMesh",
    "bind_mesh",
    "build_mannequin",
    "find_anatomy",
    "linear_blend_skinning",
    "load_mesh",
    "mannequin_for",
    "skinning_matrices",
    "two_bone_weights",
]
