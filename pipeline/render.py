"""Offscreen rendering of series: stills, turntables and time-lapses to PNG, GIF and MP4.

Works with no display: without ``DISPLAY`` VTK renders through EGL (Mesa), or OSMesa where EGL is
missing.  A :class:`Renderer` draws one or more series (a liquid surface, particles, cloth...) with
a look chosen from the data: a polygonal series named ``surface`` as water (strongly specular),
other polygonal series as a shaded solid (cloth, jello), lines as tubes (hair), and points as
shaded spheres (point-Gaussian splats) when there is no surface.  A floor with a subtle grid sits
under the scene, three lights light it, and the camera is framed from the bounds of the frames
drawn, so it does not jump during a time-lapse.
"""

from __future__ import annotations

import ctypes.util
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

#: Debian packages that give VTK an offscreen OpenGL (what ``.ci/run`` installs).
GL_PACKAGES = "libegl1 libegl-mesa0 libgl1-mesa-dri (or libosmesa6)"


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
    # Skip VTK's attempt at an X server (a warning on stderr) and go straight to EGL, or to
    # OSMesa where no EGL library is installed. With neither, VTK would crash creating a
    # window: Renderer raises RenderUnavailableError instead.
    _WINDOW = _offscreen_window()
    if _WINDOW is not None:
        os.environ["VTK_DEFAULT_OPENGL_WINDOW"] = _WINDOW
    _CAN_RENDER = _WINDOW is not None
else:
    _CAN_RENDER = True

import pyvista as pv  # noqa: E402
from vtkmodules.util import numpy_support  # noqa: E402
from tqdm.auto import tqdm  # noqa: E402

from filters.validation import check_bool, check_int  # noqa: E402

from .series import read_collection, read_frame  # noqa: E402

__all__ = ["Renderer", "RenderUnavailableError", "turntable", "timelapse", "write_movie",
           "parse_size", "MOVIE_SUFFIXES"]

MOVIE_SUFFIXES = (".gif", ".mp4")


class RenderUnavailableError(RuntimeError):
    """No OpenGL library for offscreen rendering is installed (and there is no display)."""

    def __init__(self):
        super().__init__(f"cannot render: no display and no offscreen OpenGL (EGL or OSMesa); on "
                         f"Debian/Ubuntu install {GL_PACKAGES}")
WATER = "#2a7fcf"
SOLID = "#d9774f"
HAIR = "#6b4226"
POINTS = "#3b8fd9"
BACKGROUND = ("#f4f6f9", "#c9d3de")  # top, bottom gradient
_COLOR = "blobflow_color"  # scalar array drawn when colouring by an array (magnitude of vectors)


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


@dataclass
class _Layer:
    name: str
    entries: list           # (time, absolute path) per frame
    slot: object = None     # the PyVista dataset the actor draws; refilled every frame
    actor: object = None
    kind: str = "points"


def _grid_texture(cells: int = 16, size: int = 512) -> pv.Texture:
    image = np.full((size, size, 3), 236, dtype=np.uint8)
    step = size // cells
    for k in range(0, size, step):
        image[k:k + 2, :, :] = 222
        image[:, k:k + 2, :] = 222
    return pv.Texture(image)


def _kind(name: str, data) -> str:
    if data.GetNumberOfCells() == 0 and data.GetNumberOfPoints() == 0:
        return "empty"
    if hasattr(data, "GetNumberOfPolys") and data.GetNumberOfPolys() > 0:
        return "water" if name.startswith("surface") else "solid"
    if data.IsA("vtkUnstructuredGrid") and data.GetNumberOfCells() and data.GetCellType(0) > 4:
        return "solid"
    if hasattr(data, "GetNumberOfLines") and data.GetNumberOfLines() > 0:
        return "lines"
    return "points"


class Renderer:
    """Draw frames of one or more series offscreen.

    Parameters
    ----------
    series : sequence of str or Path
        ``.pvd`` or ``.series`` files sharing their frame times (e.g. ``particles.pvd`` and
        ``surface.pvd`` of one run).  The first one's times drive the frames.
    size : (int, int)
        Image width and height in pixels.
    color_by : str, optional
        Point array to colour by (vector arrays by magnitude), with a scalar bar; the colour
        range is fixed over the frames drawn.  Default: a fixed colour per kind of layer.
    floor : bool
        Draw a floor with a grid under the scene.
    text : bool
        Overlay the time and the point and triangle counts.
    frames : sequence of int, optional
        Indices of the frames that will be drawn, used to frame the camera (all when omitted).
    bounds : sequence of 6 float, optional
        ``(xmin, xmax, ymin, ymax, zmin, zmax)`` (m) to frame instead of the data's bounds, to
        keep the same view for different series.
    clim : (float, float), optional
        Colour range for ``color_by`` instead of the range over the frames drawn.

    Raises
    ------
    FileNotFoundError, pipeline.series.SeriesError
        For a missing or malformed series.
    ValueError
        If ``color_by`` names no point array of the series.
    RenderUnavailableError
        With no display and neither EGL nor OSMesa installed (VTK would crash).
    """

    def __init__(self, series: Sequence, *, size=(640, 480), color_by: str | None = None,
                 floor: bool = True, text: bool = True, frames: Sequence[int] | None = None,
                 bounds: Sequence[float] | None = None, clim: Sequence[float] | None = None):
        if isinstance(series, (str, Path)):
            series = [series]
        if not series:
            raise ValueError("series must name at least one .pvd or .series file")
        if not _CAN_RENDER:
            raise RenderUnavailableError()
        self.layers = []
        for path in series:
            path = Path(path)
            entries = [(t, path.parent / name) for t, name in read_collection(path)]
            name = path.name.split(".")[0]
            self.layers.append(_Layer(name, entries))
        self.times = np.array([t for t, _ in self.layers[0].entries], dtype=np.float64)
        if not (isinstance(size, (tuple, list)) and len(size) == 2):
            raise TypeError(f"size must be (width, height) in pixels, got {size!r}")
        self.size = (check_int("size[0]", size[0], 16, 16384), check_int("size[1]", size[1], 16,
                                                                          16384))
        if color_by is not None and not isinstance(color_by, str):
            raise TypeError(f"color_by must be a point array name or None, got {color_by!r}")
        floor = check_bool("floor", floor)
        text = check_bool("text", text)
        self.color_by = color_by
        indices = list(range(len(self.times))) if frames is None else list(frames)
        self._setup(indices, floor, text, bounds, clim)

    # -- setup ---------------------------------------------------------------------------------
    def _frame(self, layer: _Layer, index: int):
        if not layer.entries:
            return pv.PolyData()
        index = min(index, len(layer.entries) - 1)
        return pv.wrap(read_frame(layer.entries[index][1]))

    def _setup(self, indices, floor, text, fixed_bounds, fixed_clim):
        bounds = np.array([np.inf, -np.inf] * 3)
        clim = [np.inf, -np.inf]
        for layer in self.layers:
            for i in indices:
                data = self._frame(layer, i)
                if layer.kind in ("points", "empty"):
                    layer.kind = _kind(layer.name, data)
                if data.n_points:
                    b = np.array(data.bounds)
                    bounds[0::2] = np.minimum(bounds[0::2], b[0::2])
                    bounds[1::2] = np.maximum(bounds[1::2], b[1::2])
                if self.color_by and self.color_by in data.point_data:
                    values = np.asarray(data.point_data[self.color_by], dtype=np.float64)
                    values = np.linalg.norm(values, axis=1) if values.ndim == 2 else values
                    if values.size:
                        clim = [min(clim[0], values.min()), max(clim[1], values.max())]
        # With a liquid surface, its particles would only clutter the picture.
        if any(layer.kind == "water" for layer in self.layers):
            self.layers = [l for l in self.layers if l.kind != "points"]
        if self.color_by and not np.isfinite(clim[0]):
            names = set()
            for layer in self.layers:
                names |= set(self._frame(layer, indices[0] if indices else 0).point_data.keys())
            raise ValueError(f"color_by must name a point array; arrays: {', '.join(sorted(names)) or 'none'}")
        if fixed_bounds is not None:
            bounds = np.asarray(fixed_bounds, dtype=np.float64).reshape(6)
        elif not np.isfinite(bounds[0]):
            bounds = np.array([-0.5, 0.5, -0.5, 0.5, 0.0, 1.0])
        self.bounds = bounds
        if fixed_clim is not None:
            clim = [float(fixed_clim[0]), float(fixed_clim[1])]
        self.clim = clim if np.isfinite(clim[0]) else None
        if self.clim and self.clim[0] == self.clim[1]:
            self.clim = [self.clim[0], self.clim[0] + 1.0]

        p = pv.Plotter(off_screen=True, window_size=self.size, lighting="three lights")
        p.theme.allow_empty_mesh = True  # a frame with no particles is a valid, empty scene
        p.set_background(BACKGROUND[1], top=BACKGROUND[0])
        p.enable_anti_aliasing("ssaa")  # FXAA is not supported by EGL/OSMesa builds
        self.plotter = p
        center = 0.5 * (bounds[0::2] + bounds[1::2])
        self.radius = max(0.5 * float(np.linalg.norm(bounds[1::2] - bounds[0::2])), 1e-3)
        self.center = center
        if floor:
            extent = 4.0 * self.radius
            plane = pv.Plane(center=(center[0], center[1], bounds[4] - 1e-3 * self.radius),
                             direction=(0, 0, 1), i_size=extent, j_size=extent)
            p.add_mesh(plane, texture=_grid_texture(), ambient=0.25, diffuse=0.8, specular=0.0,
                       name="floor")
        for layer in self.layers:
            self._add_layer(layer, indices[0] if indices else 0)
        self._text = p.add_text("", position="upper_left", font_size=10, color="#20262e") if text else None
        if self.color_by and self.clim:
            p.add_scalar_bar(title=self.color_by, color="#20262e", vertical=True,
                             position_x=0.88, position_y=0.15, height=0.7, width=0.06)

    def _fill(self, layer: _Layer, data) -> None:
        """Show ``data`` in the layer's actor, with the colour array as a scalar (magnitude)."""
        layer.slot.copy_from(data, deep=False)
        if self.color_by and self.color_by in data.point_data:
            values = np.asarray(data.point_data[self.color_by], dtype=np.float64)
            values = np.linalg.norm(values, axis=1) if values.ndim == 2 else values
            layer.slot.point_data[_COLOR] = values
            if layer.actor is not None and layer.actor.mapper.array_name == "__rgba__":
                # PyVista bakes point-Gaussian colours into an RGBA array when the actor is
                # made; map each new frame's values through the same lookup table.
                lut = layer.actor.mapper.lookup_table
                colors = lut.MapScalars(layer.slot.point_data.GetArray(_COLOR), 0, -1)
                layer.slot.point_data["__rgba__"] = numpy_support.vtk_to_numpy(colors).copy()
        name = layer.actor.mapper.array_name if layer.actor is not None else None
        if name and name in layer.slot.point_data:
            # copy_from() resets the active scalars the mapper draws: restore them.
            layer.slot.point_data.active_scalars_name = name

    def _add_layer(self, layer: _Layer, index: int):
        data = self._frame(layer, index)
        layer.slot = type(data)()
        self._fill(layer, data)
        kwargs = {}
        if self.color_by and self.clim and _COLOR in layer.slot.point_data:
            kwargs = dict(scalars=_COLOR, clim=self.clim, cmap="viridis", show_scalar_bar=False)
        p = self.plotter
        if layer.kind == "water":
            kwargs = kwargs or {"color": WATER}
            # Opaque on purpose: with slight transparency, depth peeling under SSAA showed the
            # liquid's underside through thin sheets as block-shaped pits.
            layer.actor = p.add_mesh(layer.slot, smooth_shading=True, specular=0.9,
                                     specular_power=60, diffuse=0.75, ambient=0.08, **kwargs)
        elif layer.kind == "solid":
            kwargs = kwargs or {"color": SOLID}
            layer.actor = p.add_mesh(layer.slot, smooth_shading=True, specular=0.3,
                                     specular_power=20, **kwargs)
        elif layer.kind == "lines":
            kwargs = kwargs or {"color": HAIR}
            layer.actor = p.add_mesh(layer.slot, render_lines_as_tubes=True, line_width=3, **kwargs)
        else:
            kwargs = kwargs or {"color": POINTS}
            layer.actor = p.add_mesh(layer.slot, style="points_gaussian",
                                     render_points_as_spheres=True, emissive=False, **kwargs)
            n = max(data.n_points, 1)
            extent = np.maximum(self.bounds[1::2] - self.bounds[0::2], 1e-6)
            # Radius so that a dense block of particles looks filled: half the mean spacing.
            spacing = float(np.prod(extent) / n) ** (1 / 3) if data.n_points > 1 else 0.05 * self.radius
            layer.actor.mapper.scale_factor = 0.5 * min(spacing, 0.05 * self.radius * 4)

    # -- drawing -------------------------------------------------------------------------------
    def _place_camera(self, azimuth: float, elevation: float = 22.0):
        camera = self.plotter.camera
        camera.view_angle = 30.0
        distance = self.radius / math.sin(math.radians(15.0)) * 1.05
        az, el = math.radians(azimuth - 55.0), math.radians(elevation)
        offset = distance * np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az),
                                      math.sin(el)])
        camera.focal_point = tuple(self.center)
        camera.position = tuple(self.center + offset)
        camera.up = (0.0, 0.0, 1.0)
        self.plotter.renderer.ResetCameraClippingRange()

    def render(self, index: int = -1, azimuth: float = 0.0) -> np.ndarray:
        """Draw frame ``index`` seen from ``azimuth`` degrees about the vertical axis.

        Returns
        -------
        (H, W, 3) uint8 array
            The image.
        """
        n = len(self.times)
        if n == 0:
            index = 0
        elif not -n <= index < n:
            raise IndexError(f"index must be in [{-n}, {n - 1}], got {index}")
        index = index % n if n else 0
        points = triangles = 0
        for layer in self.layers:
            data = self._frame(layer, index)
            self._fill(layer, data)
            points += data.n_points
            if hasattr(data, "GetNumberOfPolys"):
                triangles += data.GetNumberOfPolys()
        if self._text is not None:
            t = self.times[index] if n else 0.0
            words = f"t = {t:.2f} s    {points:,} points"
            if triangles:
                words += f"    {triangles:,} triangles"
            self._text.SetText(2, words)  # 2: upper-left corner
        self._place_camera(azimuth)
        self.plotter.render()
        return np.asarray(self.plotter.screenshot(return_img=True))

    def close(self) -> None:
        """Release the render window."""
        self.plotter.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def write_movie(images, out, *, fps: float = 24.0, count: int | None = None,
                progress: bool = True, desc: str = "render") -> Path:
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
    bar = tqdm(images, total=count, unit="image", disable=not progress, desc=desc)
    if out.suffix.lower() in MOVIE_SUFFIXES:
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = out.with_name(f".{out.stem}.tmp{out.suffix}")
        if out.suffix.lower() == ".gif":
            writer = imageio.get_writer(tmp, mode="I", duration=1000.0 / fps, loop=0)
        else:
            writer = imageio.get_writer(tmp, fps=fps, codec="libx264", quality=7,
                                        macro_block_size=2, pixelformat="yuv420p")
        try:
            for image in bar:
                writer.append_data(image)
        except BaseException:
            writer.close()
            tmp.unlink(missing_ok=True)
            raise
        writer.close()
        os.replace(tmp, out)
    else:
        out.mkdir(parents=True, exist_ok=True)
        for k, image in enumerate(bar):
            tmp = out / f".frame_{k:04d}.tmp.png"
            imageio.imwrite(tmp, image)
            os.replace(tmp, out / f"frame_{k:04d}.png")
    return out


def turntable(series, out, *, frames: int = 36, time_index: int = -1, size=(640, 480),
              color_by: str | None = None, fps: float = 24.0, progress: bool = True) -> Path:
    """Orbit the camera once around one time step of ``series``.

    Frame ``k`` of ``frames`` looks from azimuth ``360 k / (frames - 1)`` degrees, so the last
    frame returns to the first view.

    Parameters
    ----------
    series : str, Path or sequence of them
        Collections to draw together (see :class:`Renderer`).
    out : str or Path
        ``.gif``, ``.mp4`` or a folder of PNG files.
    frames : int
        Number of images, >= 2.
    time_index : int
        Which time step (default the last).
    """
    if not (isinstance(frames, int) and frames >= 2):
        raise ValueError(f"frames must be an integer >= 2, got {frames!r}")
    with Renderer(series, size=size, color_by=color_by, frames=[time_index]) as renderer:
        images = (renderer.render(time_index, 360.0 * k / (frames - 1)) for k in range(frames))
        return write_movie(images, out, fps=fps, count=frames, progress=progress, desc="turntable")


def timelapse(series, out, *, orbit: float = 0.0, size=(640, 480), color_by: str | None = None,
              fps: float | None = None, progress: bool = True) -> Path:
    """Draw every time step of ``series`` in order, optionally orbiting ``orbit`` degrees overall.

    ``fps`` defaults to the series' own frame rate (from its times), so the movie plays in real
    time.
    """
    with Renderer(series, size=size, color_by=color_by) as renderer:
        n = len(renderer.times)
        if fps is None:
            fps = 1.0 / float(np.diff(renderer.times).mean()) if n > 1 else 24.0
        images = (renderer.render(i, orbit * i / max(n - 1, 1)) for i in range(max(n, 1)))
        return write_movie(images, out, fps=fps, count=n, progress=progress, desc="time-lapse")


def render_run(series_paths, directory, *, turntable_frames: int = 24, size=(640, 480),
               progress: bool = True) -> dict[str, Path]:
    """The renders ``blobflow run`` makes of a finished run.

    A turntable GIF of the last frame (``turntable.gif``, half size) and a time-lapse MP4 of all
    frames with a slow quarter orbit (``movie.mp4``), both in ``directory``.

    Returns
    -------
    dict of str to Path
        ``{"turntable": ..., "movie": ...}``.
    """
    directory = Path(directory)
    series_paths = list(series_paths)
    small = (size[0] // 2 - (size[0] // 2) % 2, size[1] // 2 - (size[1] // 2) % 2)
    return {
        "turntable": turntable(series_paths, directory / "turntable.gif", frames=turntable_frames,
                               size=small, progress=progress),
        "movie": timelapse(series_paths, directory / "movie.mp4", orbit=90.0, size=size,
                           progress=progress),
    }


# -- frame-parallel rendering (serial, or on a Dask cluster) --------------------------------------
def render_frame_task(series, out_file, time, options) -> None:
    """Task: draw one image (``options``: index, azimuth, size, color_by, bounds, clim) to PNG."""
    import imageio.v2 as imageio

    with Renderer(series, size=options["size"], color_by=options["color_by"],
                  frames=[options["index"]], bounds=options["bounds"],
                  clim=options["clim"]) as renderer:
        image = renderer.render(options["index"], options["azimuth"])
    out_file = Path(out_file)
    tmp = out_file.with_name(f".{out_file.stem}.tmp.png")
    imageio.imwrite(tmp, image)
    os.replace(tmp, out_file)


def render_frames(series, out, *, client=None, turntable_frames: int | None = None,
                  time_index: int = -1, orbit: float = 0.0, size=(640, 480),
                  color_by: str | None = None, fps: float | None = None,
                  progress: bool = True) -> Path:
    """Render a time-lapse (or a turntable) one task per image, here or on a Dask cluster.

    The same images as :func:`timelapse` / :func:`turntable`, drawn by independent tasks (each
    with its own renderer and the camera framed from all the frames), so a cluster can draw them
    in parallel; the result is byte-identical either way.  See :func:`timelapse` for the
    parameters; ``client`` is a ``dask.distributed.Client`` or ``None`` (serial).

    Raises
    ------
    pipeline.frames.FramesError
        If some images failed on every attempt.
    """
    import imageio.v2 as imageio

    from .frames import FramesError, run_tasks

    series = [str(Path(p)) for p in ([series] if isinstance(series, (str, Path)) else series)]
    out = Path(out)
    if turntable_frames is not None:
        frames = [time_index]
    else:
        frames = None
    with Renderer(series, size=size, color_by=color_by, frames=frames, floor=False,
                  text=False) as probe:
        bounds, clim, times = probe.bounds.tolist(), probe.clim, probe.times
    n = len(times)
    if turntable_frames is not None:
        views = [(time_index % max(n, 1), 360.0 * k / (turntable_frames - 1))
                 for k in range(turntable_frames)]
        fps = fps or 24.0
    else:
        views = [(i, orbit * i / max(n - 1, 1)) for i in range(max(n, 1))]
        if fps is None:
            fps = 1.0 / float(np.diff(times).mean()) if n > 1 else 24.0
    movie = out.suffix.lower() in MOVIE_SUFFIXES
    folder = out.with_name(f".{out.stem}.frames") if movie else out
    folder.mkdir(parents=True, exist_ok=True)
    jobs = []
    for k, (index, azimuth) in enumerate(views):
        options = {"index": index, "azimuth": azimuth, "size": tuple(size), "color_by": color_by,
                   "bounds": bounds, "clim": clim}
        t = float(times[index]) if n else 0.0
        jobs.append((k, t, (render_frame_task, series, str(folder / f"frame_{k:04d}.png"), t, options)))
    _, failures = run_tasks(jobs, client=client, progress=progress, desc="render")
    if failures:
        raise FramesError(failures, out)
    if movie:
        pngs = [folder / f"frame_{k:04d}.png" for k in range(len(views))]
        write_movie((imageio.imread(p) for p in pngs), out, fps=fps, count=len(pngs),
                    progress=False)
        for p in pngs:
            p.unlink()
        folder.rmdir()
    return out
