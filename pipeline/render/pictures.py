"""Offscreen renders of series: stills, turntables and time-lapses to PNG, GIF and MP4.

Works with no display (:mod:`pipeline.render.offscreen`: EGL, or OSMesa where EGL is missing).  The
pictures are drawn by :class:`pipeline.render.renderer.Renderer` (looks from the data, the run's
colliders, shadows, a camera framed once from robust bounds); this module turns them into
movies: a turntable orbits one time step (by default the most interesting one,
:func:`interesting_frame`) in ``N`` distinct views that loop seamlessly, a time-lapse draws
every time step, and :func:`render_frames` draws either one task per image, here or on a Dask
cluster.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from tqdm.auto import tqdm

from filters.memory import format_bytes, memory_limit
from filters.validation import check_range

from ..io.outfiles import atomic_path, temporary_path
from ..io.series import read_collection, read_frame
from .framing import frame_measures, interesting_index
from .offscreen import GL_PACKAGES, RenderUnavailableError
from .renderer import Renderer

if TYPE_CHECKING:
    from collections.abc import Iterable, Sequence
    from typing import Any

    from numpy.typing import ArrayLike

    SeriesPaths = str | Path | Sequence[str | Path]  # one series or several

__all__ = ["Renderer", "RenderUnavailableError", "turntable", "timelapse", "write_movie",
           "parse_size", "MOVIE_SUFFIXES", "interesting_frame", "frame_at_time", "render_run",
           "render_still", "render_frames", "GL_PACKAGES", "RenderError",
           "FPS_RANGE", "check_fps", "max_views", "gif_limit", "check_movie_length",
           "default_fps"]

MOVIE_SUFFIXES = (".gif", ".mp4")


def parse_size(text: str) -> tuple[int, int]:
    """Parse ``"WxH"`` into even pixel sizes (MP4 encoders need even sizes).

    Raises
    ------
    ValueError
        If the text is not two integers from 16 to 8192 joined by ``x``.
    """
    try:
        w, h = (int(v) for v in str(text).lower().split("x"))
    except ValueError:
        raise ValueError(f"size must be WIDTHxHEIGHT such as 640x480, got {text!r}") from None
    if not (16 <= w <= 8192 and 16 <= h <= 8192):
        raise ValueError(f"size must be between 16x16 and 8192x8192, got {text!r}")
    return w - w % 2, h - h % 2


def _series_list(series) -> list[Path]:
    return [Path(p) for p in ([series] if isinstance(series, (str, Path)) else series)]


def interesting_frame(series: SeriesPaths) -> tuple[int, str]:
    """The most interesting frame of a run's series, and why (:mod:`pipeline.render.framing`).

    The largest area of a liquid surface (:func:`pipeline.render.looks.is_liquid_surface`), else the
    largest sum of squared point velocities of the first series with a ``velocity`` array (the
    kinetic energy of unit masses), else the last frame.

    Parameters
    ----------
    series : str, Path or sequence of them
        Collections of one run (``.pvd`` or ``.series``); the first one's frames are counted.

    Returns
    -------
    index : int
        Frame index into the first series.
    reason : str
        What made it the most interesting.
    """
    collections = [(p, read_collection(p)) for p in _series_list(series)]
    n = len(collections[0][1]) if collections else 0
    same = [(p, e) for p, e in collections if len(e) == n and n]
    # a liquid surface decides alone; velocities are read only where there is none
    for wanted, first in ((0, True), (1, False)):
        for path, entries in same:
            if first and not _liquid_series(path, entries):
                continue
            values = [frame_measures(path.name, read_frame(path.parent / name))[wanted]
                      for _, name in entries]
            if values[0] is None:
                continue
            areas, energies = (values, None) if wanted == 0 else (None, values)
            index, reason = interesting_index(areas, energies)
            if reason != "last frame":
                return index, reason
    return max(n - 1, 0), "last frame"


def _liquid_series(path: Path, entries) -> bool:
    """Whether a series is a liquid's surface, by its first frame (looks.is_liquid_surface)."""
    from .looks import is_liquid_surface

    return bool(entries) and is_liquid_surface(path.name.split(".")[0],
                                               read_frame(path.parent / entries[0][1]))


def frame_at_time(series: SeriesPaths, time: float) -> int:
    """Index of the frame of ``series`` (its first collection) nearest ``time`` (s).

    Raises
    ------
    ValueError
        If ``time`` lies outside the series' time range by more than half a frame.
    """
    entries = read_collection(_series_list(series)[0])
    if not entries:
        raise ValueError("time: the series has no frames")
    times = np.array([t for t, _ in entries], dtype=np.float64)
    step = float(np.diff(times).mean()) if len(times) > 1 else 0.0
    if not (times[0] - 0.5 * step - 1e-12 <= time <= times[-1] + 0.5 * step + 1e-12):
        raise ValueError(f"time must be within the series' {times[0]:g} .. {times[-1]:g} s, "
                         f"got {time:g}")
    return int(np.argmin(np.abs(times - time)))


def write_movie(images: Iterable[np.ndarray], out: str | Path, *, fps: float = 24.0,
                count: int | None = None, progress: bool = True, desc: str = "render") -> Path:
    """Write images to ``out``: a ``.gif``, an ``.mp4`` or a folder of numbered PNG files.

    Parameters
    ----------
    images : iterable of (H, W, 3) uint8 arrays
    out : str or Path
        The file (``.gif`` loops forever; ``.mp4`` is H.264) or a folder for ``frame_%04d.png``.
    fps : float
        Frames per second of the movie.
    count : int, optional
        Number of images, for the progress bar.

    The file is written under a temporary name and renamed when complete.
    """
    import imageio.v2 as imageio

    out = Path(out)
    fps = check_fps(fps)
    bar = tqdm(images, total=count, unit="image", disable=not progress, desc=desc)
    if out.suffix.lower() in MOVIE_SUFFIXES:
        out.parent.mkdir(parents=True, exist_ok=True)
        # a name unique to this process, removed if anything fails or stops the writing
        with atomic_path(out) as tmp:
            if out.suffix.lower() == ".gif":
                writer = imageio.get_writer(tmp, mode="I", duration=1000.0 / fps, loop=0)
            else:
                writer = imageio.get_writer(tmp, fps=fps, codec="libx264", quality=7,
                                            macro_block_size=2, pixelformat="yuv420p",
                                            ffmpeg_log_level="error")
            try:
                for image in bar:
                    writer.append_data(image)
            except BaseException:
                _close_quietly(writer)
                raise
            try:
                writer.close()
            except (OSError, RuntimeError, ValueError) as exc:
                raise RenderError(f"the encoder could not write {out}: "
                                  f"{_last_line(exc)}") from None
    else:
        out.mkdir(parents=True, exist_ok=True)
        for k, image in enumerate(bar):
            with atomic_path(out / f"frame_{k:04d}.png") as tmp:
                imageio.imwrite(tmp, image)
    return out


def _close_quietly(writer) -> None:
    try:
        writer.close()
    except Exception:  # noqa: BLE001 - the first error is the one reported
        pass


def _last_line(exc: BaseException) -> str:
    """The last meaningful line of an encoder's error (ffmpeg's log is many lines)."""
    lines = [line.strip() for line in str(exc).splitlines() if line.strip()
             and not line.strip().endswith(":")]
    return lines[-1] if lines else type(exc).__name__


class RenderError(ValueError):
    """A movie cannot be written as asked (an encoder's refusal, a limit of the machine)."""


#: Frame rates a movie may have (frames per second): what the encoders and players take.
FPS_RANGE = (0.01, 1000.0)


def check_fps(fps: float) -> float:
    """``fps`` as a float within :data:`FPS_RANGE`, else ValueError naming the range."""
    return check_range("fps", fps, *FPS_RANGE)


def gif_limit(size: tuple[int, int]) -> tuple[int, str]:
    """The most images a GIF of ``size`` (width, height) may have, and why: it holds them all
    in memory until it is written, so only as many as fit
    :func:`filters.memory.memory_limit`."""
    width, height = (int(v) for v in size)
    per_image = width * height * 4  # RGB, and the palette image made when it is written
    limit = int(max(memory_limit() // per_image, 1))
    return limit, (f"a GIF holds all its images in memory until it is written: {limit} images "
                   f"of {width}x{height} ({format_bytes(per_image)} each) fit the memory limit "
                   f"of {format_bytes(memory_limit())}")


def max_views(size: tuple[int, int], out: str | Path) -> tuple[int, str]:
    """The most views a turntable ``out`` of ``size`` (width, height) may have, and why.

    More than ``pi * width`` views turn the camera by less than a pixel at the image's edge
    from one view to the next; a GIF may also have only as many images as fit in memory
    (:func:`gif_limit`).
    """
    width = int(size[0])
    limit = int(math.pi * width)
    why = (f"{limit} views (pi times the {width}-pixel width) already turn the camera by less "
           f"than a pixel at the image's edge from one view to the next")
    if Path(out).suffix.lower() == ".gif":
        memory, reason = gif_limit(size)
        if memory < limit:
            return memory, reason
    return limit, why


def check_movie_length(count: int, size: tuple[int, int], out: str | Path, *,
                       turntable: bool) -> None:
    """Refuse, before drawing, a movie of more images than :func:`max_views` (a turntable)
    or :func:`gif_limit` (a GIF) allow; the message states the limit and why."""
    if turntable:
        limit, why = max_views(size, out)
    elif Path(out).suffix.lower() == ".gif":
        limit, why = gif_limit(size)
    else:
        return
    if count > limit:
        what = "views" if turntable else "frames"
        raise RenderError(f"{count} {what} are more than this movie can have: {why}")


def default_fps(times: ArrayLike) -> float:
    """The frame rate that plays ``times`` (s) in real time, within :data:`FPS_RANGE`."""
    times = np.asarray(times, dtype=np.float64)
    if len(times) < 2:
        return 24.0
    step = float(np.diff(times).mean())
    fps = 1.0 / step if step > 0 else FPS_RANGE[1]
    return float(min(max(fps, FPS_RANGE[0]), FPS_RANGE[1]))


def _turntable_index(series, time_index, time) -> tuple[int, str]:
    """The time step a turntable shows: ``time`` (s), else ``time_index``, else the most
    interesting frame."""
    if time is not None:
        return frame_at_time(series, float(time)), f"t = {float(time):g} s"
    if time_index is not None:
        return int(time_index), f"frame {int(time_index)}"
    return interesting_frame(series)


def turntable(series: SeriesPaths, out: str | Path, *, frames: int = 36,
              time_index: int | None = None, time: float | None = None,
              size: tuple[int, int] = (640, 480),
              color_by: str | None = None,
              fps: float = 24.0, progress: bool = True) -> Path:
    """Orbit the camera once around one time step of ``series``: a seamless loop.

    Frame ``k`` of ``frames`` looks from azimuth ``360 k / frames`` degrees: ``frames``
    distinct views, the next one after the last being the first (no repeated frame when the
    movie loops).

    Parameters
    ----------
    series : str, Path or sequence of them
        Collections to draw together (see :class:`pipeline.render.renderer.Renderer`).
    out : str or Path
        ``.gif``, ``.mp4`` or a folder of PNG files.
    frames : int
        Number of images, >= 2.
    time_index : int, optional
        Which time step (an index of the first series).
    time : float, optional
        Which time (s): the nearest frame; overrides ``time_index``.  With neither, the most
        interesting frame (:func:`interesting_frame`).
    """
    if not (isinstance(frames, int) and not isinstance(frames, bool) and frames >= 2):
        raise ValueError(f"frames must be an integer >= 2, got {frames!r}")
    check_movie_length(frames, size, out, turntable=True)
    check_fps(fps)
    index, _ = _turntable_index(series, time_index, time)
    with Renderer(series, size=size, color_by=color_by, frames=[index]) as renderer:
        images = (renderer.render(index, 360.0 * k / frames) for k in range(frames))
        return write_movie(images, out, fps=fps, count=frames, progress=progress, desc="turntable")


def timelapse(series: SeriesPaths, out: str | Path, *, orbit: float = 0.0,
              size: tuple[int, int] = (640, 480), color_by: str | None = None,
              fps: float | None = None, progress: bool = True) -> Path:
    """Draw every time step of ``series`` in order, optionally orbiting ``orbit`` degrees overall.

    ``fps`` defaults to the series' own frame rate (from its times), so the movie plays in real
    time.  The camera is framed once from all the frames.
    """
    check_movie_length(len(read_collection(_series_list(series)[0])), size, out,
                       turntable=False)
    with Renderer(series, size=size, color_by=color_by) as renderer:
        n = len(renderer.times)
        if fps is None:
            fps = default_fps(renderer.times)
        images = (renderer.render(i, orbit * i / max(n - 1, 1)) for i in range(max(n, 1)))
        return write_movie(images, out, fps=fps, count=n, progress=progress, desc="time-lapse")


def render_still(series: SeriesPaths, out: str | Path, *, time_index: int | None = None,
                 time: float | None = None, size: tuple[int, int] = (640, 480),
                 azimuth: float = 0.0, text: bool = True) -> tuple[Path, int]:
    """Draw one image of ``series`` to a PNG file (atomically): at ``time`` (s), else at
    ``time_index``, else at the most interesting frame.

    Returns
    -------
    path : Path
        The PNG written.
    index : int
        The frame drawn.
    """
    import imageio.v2 as imageio

    index, _ = _turntable_index(series, time_index, time)
    with Renderer(series, size=size, frames=[index], text=text) as renderer:
        image = renderer.render(index, azimuth)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(out) as tmp:
        imageio.imwrite(tmp, image)
    return out, index


def render_run(series_paths: Sequence[str | Path], directory: str | Path, *,
               turntable_frames: int = 24, size: tuple[int, int] = (640, 480),
               time: float | None = None, progress: bool = True) -> dict[str, Path]:
    """The renders ``blobflow run`` makes of a finished run.

    A turntable GIF of the frame nearest ``time`` (s; a scene's
    :attr:`~pipeline.scene.Scene.still`) when the run reaches it, else of the most interesting
    frame (``turntable.gif``, ``turntable_frames`` distinct views) and a time-lapse MP4 of all
    frames with a slow quarter orbit (``movie.mp4``), both ``size`` and in ``directory``, drawn by
    one renderer framed on the whole run (each frame is read once to frame the camera and pick
    the turntable's time).

    Returns
    -------
    dict of str to Path
        ``{"turntable": ..., "movie": ...}``.
    """
    if not (isinstance(turntable_frames, int) and turntable_frames >= 2):
        raise ValueError(f"turntable_frames must be an integer >= 2, got {turntable_frames!r}")
    directory = Path(directory)
    with Renderer(list(series_paths), size=size) as renderer:
        index, _ = renderer.interesting()
        n = len(renderer.times)
        if time is not None and n and time <= renderer.times[-1] + 1e-9:
            index = int(np.argmin(np.abs(renderer.times - time)))
        views = (renderer.render(index, 360.0 * k / turntable_frames)
                 for k in range(turntable_frames))
        spin = write_movie(views, directory / "turntable.gif", fps=24.0, count=turntable_frames,
                           progress=progress, desc="turntable")
        fps = default_fps(renderer.times)
        images = (renderer.render(i, 90.0 * i / max(n - 1, 1)) for i in range(max(n, 1)))
        movie = write_movie(images, directory / "movie.mp4", fps=fps, count=n, progress=progress,
                            desc="time-lapse")
    return {"turntable": spin, "movie": movie}


# -- frame-parallel rendering (serial, or on a Dask cluster) --------------------------------------
def render_frame_task(series: SeriesPaths, out_file: str, time: float, options: dict) -> None:
    """Task: draw one image (``options``: index, azimuth, size, color_by, bounds, clim,
    age_scale) to PNG."""
    import imageio.v2 as imageio

    with Renderer(series, size=options["size"], color_by=options["color_by"],
                  frames=[options["index"]], bounds=options["bounds"],
                  clim=options["clim"], age_scale=options["age_scale"]) as renderer:
        image = renderer.render(options["index"], options["azimuth"])
    with atomic_path(Path(out_file)) as tmp:
        imageio.imwrite(tmp, image)


def render_frames(series: SeriesPaths, out: str | Path, *, client: Any = None,
                  turntable_frames: int | None = None, time_index: int | None = None,
                  time: float | None = None,
                  orbit: float = 0.0, size: tuple[int, int] = (640, 480),
                  color_by: str | None = None, fps: float | None = None,
                  progress: bool = True) -> Path:
    """Render a time-lapse (or a turntable) one task per image, here or on a Dask cluster.

    The same images as :func:`timelapse` / :func:`turntable`, drawn by independent tasks (each
    with its own renderer and the camera framed from all the frames), so a cluster can draw them
    in parallel; the result is byte-identical either way.  See :func:`timelapse` for the
    parameters; ``client`` is a ``dask.distributed.Client`` or ``None`` (serial).

    Raises
    ------
    pipeline.tasks.FramesError
        If some images failed on every attempt.
    """
    import imageio.v2 as imageio

    from ..tasks import FramesError, run_tasks

    series = [str(p) for p in _series_list(series)]
    out = Path(out)
    frames = None
    if turntable_frames is not None:
        check_movie_length(turntable_frames, size, out, turntable=True)
    else:
        check_movie_length(len(read_collection(series[0])), size, out, turntable=False)
    if turntable_frames is not None:
        index, _ = _turntable_index(series, time_index, time)
        frames = [index]
    with Renderer(series, size=size, color_by=color_by, frames=frames, floor=False,
                  text=False, shadows=False) as probe:
        bounds, clim, times = probe.bounds.tolist(), probe.clim, probe.times
        age_scale = probe.age_scale
    n = len(times)
    if turntable_frames is not None:
        views = [(index % max(n, 1), 360.0 * k / turntable_frames)
                 for k in range(turntable_frames)]
        fps = fps or 24.0
    else:
        views = [(i, orbit * i / max(n - 1, 1)) for i in range(max(n, 1))]
        if fps is None:
            fps = default_fps(times)
    fps = check_fps(fps)
    movie = out.suffix.lower() in MOVIE_SUFFIXES
    # the images of a movie go to a folder of this process's own, removed however it ends
    folder = temporary_path(out.with_suffix(".frames")) if movie else out
    folder.mkdir(parents=True, exist_ok=True)
    pngs = [folder / f"frame_{k:04d}.png" for k in range(len(views))]
    try:
        jobs = []
        for k, (index, azimuth) in enumerate(views):
            options = {"index": index, "azimuth": azimuth, "size": tuple(size),
                       "color_by": color_by, "bounds": bounds, "clim": clim,
                       "age_scale": age_scale}
            t = float(times[index]) if n else 0.0
            jobs.append((k, t, (render_frame_task, series, str(pngs[k]), t, options)))
        _, failures = run_tasks(jobs, client=client, progress=progress, desc="render")
        if failures:
            raise FramesError(failures, out)
        if movie:
            write_movie((imageio.imread(p) for p in pngs), out, fps=fps, count=len(pngs),
                        progress=False)
    finally:
        if movie:
            for p in pngs:
                p.unlink(missing_ok=True)
            folder.rmdir()
    return out
