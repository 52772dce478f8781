"""Rendering with no display: pick VTK's EGL (Mesa) or OSMesa window before VTK makes one.

Import this module before PyVista creates a plotter.  Without ``DISPLAY`` VTK would first try an
X server (a warning on stderr); this sets ``VTK_DEFAULT_OPENGL_WINDOW`` to the EGL window where
libEGL and a Mesa EGL vendor are installed, else to the OSMesa window.  With neither, VTK would
crash creating a window (measured: a segmentation fault): :func:`check_can_render` raises
:class:`RenderUnavailableError` instead, naming the packages to install.
"""

from __future__ import annotations

import ctypes.util
import os
from pathlib import Path

__all__ = ["GL_PACKAGES", "RenderUnavailableError", "check_can_render"]

#: Debian packages that give VTK an offscreen OpenGL (what ``.ci/run`` installs).
GL_PACKAGES = "libegl1 libegl-mesa0 libgl1-mesa-dri (or libosmesa6)"


class RenderUnavailableError(RuntimeError):
    """No OpenGL library for offscreen rendering is installed (and there is no display)."""

    def __init__(self):
        super().__init__(f"cannot render: no display and no offscreen OpenGL (EGL or OSMesa); on "
                         f"Debian/Ubuntu install {GL_PACKAGES}")


def _loadable(name: str) -> bool:
    """Whether the shared library ``lib<name>`` can be loaded (not just listed in a cache)."""
    path = ctypes.util.find_library(name)
    if path is None:
        return False
    try:
        ctypes.CDLL(path)
    except OSError:
        return False
    return True


def _offscreen_window() -> str | None:
    """VTK render window class for rendering with no display: EGL where libEGL and a Mesa EGL
    vendor are installed, else OSMesa, else None (nothing can render here)."""
    vendors = ("/usr/share/glvnd/egl_vendor.d", "/etc/glvnd/egl_vendor.d")
    if _loadable("EGL") and any(Path(d).is_dir() and any(Path(d).glob("*.json"))
                                for d in vendors):
        return "vtkEGLRenderWindow"
    if _loadable("OSMesa"):
        return "vtkOSOpenGLRenderWindow"
    return None


if not os.environ.get("DISPLAY") and "VTK_DEFAULT_OPENGL_WINDOW" not in os.environ:
    _WINDOW = _offscreen_window()
    if _WINDOW is not None:
        os.environ["VTK_DEFAULT_OPENGL_WINDOW"] = _WINDOW
    _CAN_RENDER = _WINDOW is not None
else:
    _CAN_RENDER = True


def check_can_render() -> None:
    """Raise :class:`RenderUnavailableError` where nothing can render (no display, no EGL or
    OSMesa)."""
    if not _CAN_RENDER:
        raise RenderUnavailableError()
