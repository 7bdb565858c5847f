"""Exports of a take for other programs: ``glb`` (glTF 2.0 binary, skinned and animated)."""

from engine.export.glb import glb_bytes, write_glb

__all__ = ["glb_bytes", "write_glb"]
