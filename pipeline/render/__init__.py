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
        FPS_RANGE,
        MOVIE_SUFFIXES,
        RenderError,
        check_fps,
        check_movie_length,
        default_fps,
        frame_at_time,
        gif_limit,
        interesting_frame,
        max_views,
        parse_size,
        render_frames,
        render_run,
        render_still,
        timelapse,
        turntable,
        write_movie,
    )
    from .renderer import Renderer

#: What ``pipeline.render`` exports: every public name of :mod:`~pipeline.render.pictures` (the
#: module ``pipeline.render`` was before the package), the Renderer and the offscreen check.
_EXPORTS = {
    **dict.fromkeys(["render_still", "turntable", "timelapse", "render_frames", "render_run",
                     "write_movie", "frame_at_time", "interesting_frame", "parse_size",
                     "RenderError", "MOVIE_SUFFIXES", "FPS_RANGE", "check_fps", "max_views",
                     "gif_limit", "check_movie_length", "default_fps"], ".pictures"),
    "Renderer": ".renderer", "RenderUnavailableError": ".offscreen", "GL_PACKAGES": ".offscreen",
}

__all__ = ["render_still", "turntable", "timelapse", "render_frames", "render_run", "write_movie",
           "frame_at_time", "interesting_frame", "parse_size", "RenderError", "MOVIE_SUFFIXES",
           "FPS_RANGE", "check_fps", "max_views", "gif_limit", "check_movie_length",
           "default_fps", "Renderer", "RenderUnavailableError", "GL_PACKAGES"]

__getattr__, __dir__ = lazy_exports(__name__, globals(), _EXPORTS)
