"""Skinned previews: offscreen pyrender (EGL on Mesa, OSMesa fallback), trails, video.

``Preview(takes).frame(i, view=..., camera=..., size=...) -> (H, W, 3) uint8``;
``render_to_file(preview, "out.mp4")``. Importing this package does not import
pyrender/OpenGL: the headless platform is chosen first (``backend.ensure_platform``).
"""

from engine.render.backend import RenderBackendError, ensure_platform
from engine.render.offscreen import VIEWS, Preview, parse_size
from engine.render.scene import CAMERAS
from engine.render.video import (
    contact_sheet,
    render_to_file,
    to_png_bytes,
    write_gif,
    write_image,
    write_mp4,
)

__all__ = [
    "CAMERAS",
    "VIEWS",
    "Preview",
    "RenderBackendError",
    "contact_sheet",
    "ensure_platform",
    "parse_size",
    "render_to_file",
    "to_png_bytes",
    "write_gif",
    "write_image",
    "write_mp4",
]
