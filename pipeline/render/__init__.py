"""Offscreen pictures of series: stills, turntables, timelapses and movies.

:func:`render_still`, :func:`turntable` and :func:`timelapse` draw one or several series as
``blobflow render`` does (:mod:`~pipeline.render.pictures`); :func:`render_frames` draws one
image per frame, serially or on a Dask cluster. Underneath: the :class:`Renderer`
(:mod:`~pipeline.render.renderer`), its actors and materials (:mod:`~pipeline.render.actors`,
:mod:`~pipeline.render.looks`), the camera's framing (:mod:`~pipeline.render.framing`), the
choice of an offscreen OpenGL (:mod:`~pipeline.render.offscreen`) and the gallery's stills
(:mod:`~pipeline.render.gallery`).
"""

from typing import TYPE_CHECKING

from .._lazy import lazy_exports

if TYPE_CHECKING:
    from .offscreen import GL_PACKAGES, RenderUnavailableError
    from .pictures import (
        RenderError,
        frame_at_time,
        interesting_frame,
        parse_size,
        render_frames,
        render_run,
        render_still,
        timelapse,
        turntable,
        write_movie,
    )
    from .renderer import Renderer

_EXPORTS = {
    **dict.fromkeys(["render_still", "turntable", "timelapse", "render_frames", "render_run",
                     "write_movie", "frame_at_time", "interesting_frame", "parse_size",
                     "RenderError"], ".pictures"),
    "Renderer": ".renderer", "RenderUnavailableError": ".offscreen", "GL_PACKAGES": ".offscreen",
}

__all__ = ["render_still", "turntable", "timelapse", "render_frames", "render_run", "write_movie",
           "frame_at_time", "interesting_frame", "parse_size", "RenderError", "Renderer",
           "RenderUnavailableError", "GL_PACKAGES"]

__getattr__, __dir__ = lazy_exports(__name__, globals(), _EXPORTS)
