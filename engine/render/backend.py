"""Headless OpenGL for pyrender: EGL on Mesa, OSMesa as fallback, chosen automatically.

PyOpenGL fixes its platform when ``OpenGL`` is first imported, from the
``PYOPENGL_PLATFORM`` environment variable, so :func:`ensure_platform` must run
before anything imports ``pyrender`` or ``OpenGL``; every renderer in this package
calls it first. EGL is probed with ``ctypes`` (load ``libEGL``, enumerate devices,
initialise a display; no OpenGL import), then ``libOSMesa``. A variable already
set is respected, except an ``egl`` that does not work where OSMesa does. When
neither works, :class:`RenderBackendError` says what to install.

pyrender imports pyglet's window module on import (for its interactive viewer);
without pyglet's headless mode that loads X11 libraries (libX11, libXrender) and
fails on a machine without them, so :func:`ensure_platform` puts pyglet in headless
mode first (:func:`headless_pyglet`, the one place that does it).

OSMesa: pyrender's own OSMesa platform needs PyOpenGL >= 3.1.5 (pyrender pins
3.1.0), so :class:`OSMesaPlatform` creates the core-profile context through
``ctypes`` instead.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys
import threading

from engine.base.errors import HandSpliceError

# one lock for every OpenGL call in the process: pyrender and PyOpenGL keep global
# state, and the web app renders from several threads
GL_LOCK = threading.RLock()

_INSTALL_HINT = (
    "install Mesa's headless OpenGL: apt-get install libegl1 libegl-mesa0 "
    "libgl1-mesa-dri (EGL) or libosmesa6 (OSMesa), or set PYOPENGL_PLATFORM"
)


class RenderBackendError(HandSpliceError):
    """No headless OpenGL is available (neither EGL nor OSMesa works)."""


def _egl_works() -> bool:
    """True when libEGL loads and a device display initialises (ctypes only)."""
    try:
        egl = ctypes.CDLL(ctypes.util.find_library("EGL") or "libEGL.so.1")
    except OSError:
        return False
    try:
        get_proc = egl.eglGetProcAddress
        get_proc.restype = ctypes.c_void_p
        get_proc.argtypes = [ctypes.c_char_p]
        egl.eglInitialize.argtypes = [
            ctypes.c_void_p,
            ctypes.POINTER(ctypes.c_int),
            ctypes.POINTER(ctypes.c_int),
        ]
        egl.eglInitialize.restype = ctypes.c_uint
        egl.eglTerminate.argtypes = [ctypes.c_void_p]
        query_ptr = get_proc(b"eglQueryDevicesEXT")
        display_ptr = get_proc(b"eglGetPlatformDisplayEXT")
        if not query_ptr or not display_ptr:
            return False
        query = ctypes.CFUNCTYPE(
            ctypes.c_uint,
            ctypes.c_int,
            ctypes.POINTER(ctypes.c_void_p),
            ctypes.POINTER(ctypes.c_int),
        )(query_ptr)
        get_display = ctypes.CFUNCTYPE(
            ctypes.c_void_p, ctypes.c_uint, ctypes.c_void_p, ctypes.POINTER(ctypes.c_int)
        )(display_ptr)
        devices = (ctypes.c_void_p * 16)()
        count = ctypes.c_int(0)
        if not query(16, devices, ctypes.byref(count)) or count.value == 0:
            return False
        index = int(os.environ.get("EGL_DEVICE_ID", "0"))
        if not 0 <= index < count.value:
            return False
        display = get_display(0x313F, devices[index], None)  # EGL_PLATFORM_DEVICE_EXT
        if not display:
            return False
        major, minor = ctypes.c_int(), ctypes.c_int()
        ok = egl.eglInitialize(display, ctypes.byref(major), ctypes.byref(minor))
        if ok:
            egl.eglTerminate(display)
        return bool(ok) and (major.value, minor.value) >= (1, 4)
    except (AttributeError, OSError, ValueError):
        return False


def _osmesa_library() -> ctypes.CDLL | None:
    for name in (ctypes.util.find_library("OSMesa"), "libOSMesa.so.8", "libOSMesa.so.6"):
        if not name:
            continue
        try:
            return ctypes.CDLL(name)
        except OSError:
            continue
    return None


_CHOSEN: str | None = None


def headless_pyglet() -> None:
    """Put pyglet in headless mode (EGL, never X11); call before ``pyrender`` is imported.

    pyglet reads ``PYGLET_HEADLESS`` when it is first imported; when it was imported
    already, its option is set directly (effective until ``pyglet.window`` is imported).
    """
    os.environ["PYGLET_HEADLESS"] = "true"
    pyglet = sys.modules.get("pyglet")
    if pyglet is not None:
        pyglet.options["headless"] = True


def ensure_platform() -> str:
    """Choose and set ``PYOPENGL_PLATFORM`` (``"egl"`` or ``"osmesa"``) and return it.

    A value already set is kept, except ``egl`` when EGL does not work here and
    OSMesa does (the Makefile and the tests default to ``egl``): then ``osmesa`` is
    used. Raises :class:`RenderBackendError` naming the packages to install when
    neither works. Decided once per process. Puts pyglet in headless mode first.
    """
    global _CHOSEN
    headless_pyglet()
    if _CHOSEN is not None and os.environ.get("PYOPENGL_PLATFORM", "") == _CHOSEN:
        return _CHOSEN
    chosen = os.environ.get("PYOPENGL_PLATFORM", "").strip().lower()
    if "OpenGL" in sys.modules:  # too late to choose: PyOpenGL decided already
        _CHOSEN = chosen or None
        return chosen or "default"
    if chosen and chosen != "egl":
        _CHOSEN = chosen
        return chosen
    if _egl_works():
        os.environ["PYOPENGL_PLATFORM"] = _CHOSEN = "egl"
        return "egl"
    if _osmesa_library() is not None:
        os.environ["PYOPENGL_PLATFORM"] = _CHOSEN = "osmesa"
        return "osmesa"
    raise RenderBackendError(f"no headless OpenGL: EGL and OSMesa both failed; {_INSTALL_HINT}")


class OSMesaPlatform:
    """pyrender platform on OSMesa through ctypes (OpenGL 3.3 core profile)."""

    def __init__(self, viewport_width: int, viewport_height: int):
        self.viewport_width = viewport_width
        self.viewport_height = viewport_height
        self._lib = _osmesa_library()
        if self._lib is None:
            raise RenderBackendError(f"OSMesa: libOSMesa not found; {_INSTALL_HINT}")
        self._context = None
        self._buffer = None

    def init_context(self) -> None:
        import numpy as np

        lib = self._lib
        lib.OSMesaCreateContextAttribs.restype = ctypes.c_void_p
        lib.OSMesaCreateContextAttribs.argtypes = [ctypes.POINTER(ctypes.c_int), ctypes.c_void_p]
        attrs = (ctypes.c_int * 11)(
            0x22,
            0x1908,  # OSMESA_FORMAT, OSMESA_RGBA
            0x30,
            24,  # OSMESA_DEPTH_BITS
            0x33,
            0x34,  # OSMESA_PROFILE, OSMESA_CORE_PROFILE
            0x36,
            3,
            0x37,
            3,  # context version 3.3
            0,
        )
        self._context = lib.OSMesaCreateContextAttribs(attrs, None)
        if not self._context:
            raise RenderBackendError(
                "OSMesa: could not create an OpenGL 3.3 core context (Mesa too old?)"
            )
        self._buffer = np.zeros((self.viewport_height, self.viewport_width, 4), np.uint8)

    def make_current(self) -> None:
        lib = self._lib
        lib.OSMesaMakeCurrent.restype = ctypes.c_uint
        lib.OSMesaMakeCurrent.argtypes = [
            ctypes.c_void_p,
            ctypes.c_void_p,
            ctypes.c_uint,
            ctypes.c_int,
            ctypes.c_int,
        ]
        ok = lib.OSMesaMakeCurrent(
            self._context,
            self._buffer.ctypes.data,
            0x1401,  # UBYTE
            self.viewport_width,
            self.viewport_height,
        )
        if not ok:
            raise RenderBackendError("OSMesa: could not make the context current")

    def make_uncurrent(self) -> None:
        pass

    def delete_context(self) -> None:
        if self._context:
            self._lib.OSMesaDestroyContext.argtypes = [ctypes.c_void_p]
            self._lib.OSMesaDestroyContext(self._context)
        self._context = None
        self._buffer = None

    def supports_framebuffers(self) -> bool:
        return False


def _patch_pyopengl_osmesa() -> None:
    """PyOpenGL 3.1.0 returns the current OSMesa context as a ctypes pointer, which its
    per-context caches cannot hash; hand it back as an integer address."""
    import OpenGL.platform as gl_platform

    raw = getattr(gl_platform.PLATFORM, "OSMesa", None)
    if raw is None or getattr(gl_platform, "_handsplice_patched", False):
        return
    current = raw.OSMesaGetCurrentContext
    current.restype = ctypes.c_void_p
    current.argtypes = []

    def get_current_context() -> int:
        return current() or 0

    gl_platform.GetCurrentContext = get_current_context
    gl_platform.CurrentContextIsValid = get_current_context
    gl_platform._handsplice_patched = True


_SHARED = None


def shared_renderer(width: int, height: int):
    """The process's one ``pyrender.OffscreenRenderer``, resized to ``width x height``.

    Call under :data:`GL_LOCK`. One renderer serves every ``Preview``: pyrender's EGL
    platform terminates the (per-device, shared) EGL display when a renderer is
    deleted, which would break every other renderer of the process.
    """
    global _SHARED
    with GL_LOCK:
        if _SHARED is None:
            _SHARED = make_renderer(width, height)
        else:
            _SHARED.viewport_width = width
            _SHARED.viewport_height = height
        return _SHARED


def release_current(renderer) -> None:
    """Make ``renderer``'s context not current in this thread (call under GL_LOCK).

    pyrender leaves an EGL context current after rendering; another thread then
    cannot make it current (EGL_BAD_ACCESS). Releasing it after every render lets
    any thread render next."""
    platform = getattr(renderer, "_platform", None)
    if platform is None:
        return
    if isinstance(platform, OSMesaPlatform):
        lib = platform._lib
        lib.OSMesaMakeCurrent.argtypes = [
            ctypes.c_void_p,
            ctypes.c_void_p,
            ctypes.c_uint,
            ctypes.c_int,
            ctypes.c_int,
        ]
        lib.OSMesaMakeCurrent(None, None, 0, 0, 0)
        return
    display = getattr(platform, "_egl_display", None)
    if display is not None:
        from OpenGL.EGL import EGL_NO_CONTEXT, EGL_NO_SURFACE, eglMakeCurrent

        eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT)


def render_color(renderer, scene, depth: bool = False):
    """``(color (H, W, 3) uint8, depth (H, W) float32 metres or None)`` of ``scene``.

    Call under :data:`GL_LOCK`. pyrender always resolves, reads back and linearises the
    depth buffer too (a second full-frame blit, a float read and five whole-image numpy
    passes); a picture that does not need it (every one but the overlay's) reads the
    colour only: the same pixels, a few milliseconds less per panel."""
    inner = getattr(renderer, "_renderer", None)
    if depth or inner is None:
        return renderer.render(scene)
    _install_color_only_read()
    inner._handsplice_color_only = True
    try:
        return renderer.render(scene)
    finally:
        inner._handsplice_color_only = False


def _install_color_only_read() -> None:
    """Teach pyrender's ``Renderer`` to skip the depth readback when a caller asks
    (:func:`render_color`); every other caller gets pyrender's own read."""
    from pyrender.renderer import Renderer

    if getattr(Renderer, "_handsplice_read", None) is not None:
        return
    original = Renderer._read_main_framebuffer

    def read(self, scene, flags):
        if not getattr(self, "_handsplice_color_only", False):
            return original(self, scene, flags)
        return _read_color(self), None

    Renderer._handsplice_read = original
    Renderer._read_main_framebuffer = read


def _read_color(inner):
    """The resolved colour of pyrender's multisampled main framebuffer, (H, W, 3) uint8,
    top row first (what ``_read_main_framebuffer`` returns as colour)."""
    import numpy as np
    from OpenGL import GL

    width, height = inner._main_fb_dims
    GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, inner._main_fb_ms)
    GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, inner._main_fb)
    GL.glBlitFramebuffer(
        0, 0, width, height, 0, 0, width, height, GL.GL_COLOR_BUFFER_BIT, GL.GL_LINEAR
    )
    GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, inner._main_fb)
    data = GL.glReadPixels(0, 0, width, height, GL.GL_RGB, GL.GL_UNSIGNED_BYTE)
    return np.flip(np.frombuffer(data, dtype=np.uint8).reshape(height, width, 3), axis=0)


def release_renderer() -> None:
    """Delete the shared renderer (its OpenGL context); the next render makes a new one."""
    global _SHARED
    with GL_LOCK:
        if _SHARED is not None:
            _SHARED.delete()
            _SHARED = None


def make_renderer(width: int, height: int):
    """A new ``pyrender.OffscreenRenderer`` on the chosen platform (call under GL_LOCK).

    Prefer :func:`shared_renderer`; deleting one EGL renderer invalidates the others."""
    platform = ensure_platform()
    import pyrender

    if platform != "osmesa":
        try:
            return pyrender.OffscreenRenderer(width, height)
        except Exception as exc:  # EGL probed fine but the context failed
            raise RenderBackendError(
                f"headless OpenGL ({platform}) failed: {type(exc).__name__}: {exc}; "
                f"try PYOPENGL_PLATFORM=osmesa, or {_INSTALL_HINT}"
            ) from exc

    _patch_pyopengl_osmesa()

    class _OSMesaRenderer(pyrender.OffscreenRenderer):
        def _create(self):
            from pyrender.renderer import Renderer

            self._platform = OSMesaPlatform(self.viewport_width, self.viewport_height)
            self._platform.init_context()
            self._platform.make_current()
            self._renderer = Renderer(self.viewport_width, self.viewport_height)

    try:
        return _OSMesaRenderer(width, height)
    except RenderBackendError:
        raise
    except Exception as exc:
        raise RenderBackendError(
            f"headless OpenGL (osmesa) failed: {type(exc).__name__}: {exc}; {_INSTALL_HINT}"
        ) from exc
