"""The offscreen :class:`Renderer`: frames of series, with their colliders, as images.

A :class:`Renderer` draws one or more series (a liquid surface, particles, cloth...) with a look
chosen from the data (:mod:`pipeline.render.looks`): a liquid's surface as water (shiny; the
surface stages tag it, :func:`pipeline.render.looks.is_liquid_surface`), other polygonal series as
matte solids (cloth, jello), lines as tubes (hair), points
carrying an ``age`` array (emitted particles) as smoke, other points as small spheres.  The
colliders of the run (``colliders.vtp`` beside the series, :mod:`pipeline.io.colliders`) are drawn
with them: containers as glass with dark edges, solids in a neutral grey, and the floor where
the scene declares it.  A key spotlight casts shadows (VTK's shadow-map pass) onto the floor and
the bodies, so contact reads; the camera is framed once from robust bounds
(:mod:`pipeline.render.framing`), so it neither jumps nor follows stray drops.  Images are
rendered at :data:`SUPERSAMPLE` times the size and box-filtered down.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pyvista as pv  # noqa: E402
from vtkmodules.util import numpy_support  # noqa: E402
from vtkmodules.vtkFiltersCore import vtkPolyDataNormals, vtkTubeFilter  # noqa: E402
from vtkmodules.vtkFiltersGeometry import vtkDataSetSurfaceFilter  # noqa: E402
from vtkmodules.vtkRenderingCore import vtkLight, vtkRenderer  # noqa: E402

from filters.validation import check_bool, check_int  # noqa: E402

from ..io.colliders import COLLIDERS_FILE, collider_mesh, read_colliders  # noqa: E402
from ..io.series import read_collection, read_frame  # noqa: E402
from . import (  # noqa: E402
    actors,
    looks,
    offscreen,  # noqa: F401  (chooses EGL/OSMesa before PyVista loads VTK's windows)
)
from .framing import (  # noqa: E402
    CLIP_REACH,
    clipping_range,
    frame_measures,
    interesting_index,
    join_bounds,
    robust_bounds,
)

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = ["Renderer", "SUPERSAMPLE"]

#: Images are drawn this many times larger per side and box-filtered down (anti-aliasing that
#: keeps the depth buffer the glass and smoke layer needs, unlike VTK's SSAA pass).
SUPERSAMPLE = 1.5
_COLOR = "blobflow_color"  # scalar array drawn when colouring by an array (magnitude of vectors)
_RGBA = "blobflow_rgba"    # smoke sprite colours


@dataclass
class _Layer:
    name: str
    entries: list           # (time, absolute path) per frame
    slot: object = None     # the dataset the actor draws; refilled every frame
    actor: object = None
    kind: str = "points"
    of_particles: bool = False  # a surface contoured around particles (looks.is_particle_surface)


def _kind(name: str, data) -> str:
    if data.GetNumberOfCells() == 0 and data.GetNumberOfPoints() == 0:
        return "empty"
    if hasattr(data, "GetNumberOfPolys") and data.GetNumberOfPolys() > 0:
        return "water" if looks.is_liquid_surface(name, data) else "solid"
    if data.IsA("vtkUnstructuredGrid") and data.GetNumberOfCells() and data.GetCellType(0) > 4:
        return "solid"
    if hasattr(data, "GetNumberOfLines") and data.GetNumberOfLines() > 0:
        return "lines"
    if data.GetPointData().GetArray("age") is not None:
        return "smoke"
    return "points"


def _points_of(data) -> np.ndarray:
    points = data.GetPoints() if hasattr(data, "GetPoints") else None
    if points is None or data.GetNumberOfPoints() == 0:
        return np.zeros((0, 3))
    return numpy_support.vtk_to_numpy(points.GetData())


class Renderer:
    """Draw frames of one or more series offscreen, with the run's colliders.

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
        Draw a floor with a grid under the scene: at the declared floor, else at the bottom of
        the container, else a little below the lowest point drawn.
    text : bool
        Overlay the time and the point and triangle counts.
    frames : sequence of int, optional
        Indices of the frames that will be drawn, used to frame the camera (all when omitted).
    bounds : sequence of 6 float, optional
        ``(xmin, xmax, ymin, ymax, zmin, zmax)`` (m) to frame instead of the robust bounds of
        the data and colliders, to keep the same view for different series.
    clim : (float, float), optional
        Colour range for ``color_by`` instead of the range over the frames drawn.
    colliders : "auto", str, Path or None
        ``colliders.vtp`` to draw: ``"auto"`` takes the one beside the first series when there
        is one; None draws none.
    shadows : bool
        Shadows from the key light (VTK's shadow-map pass).
    age_scale : float, optional
        Age (s) at which smoke sprites have faded out, instead of the oldest age over the
        frames drawn.

    Raises
    ------
    FileNotFoundError, pipeline.io.series.SeriesError
        For a missing or malformed series or colliders file.
    ValueError
        If ``color_by`` names no point array of the series.
    RenderUnavailableError
        With no display and neither EGL nor OSMesa installed (VTK would crash).
    """

    def __init__(self, series: str | Path | Sequence[str | Path], *,
                 size: tuple[int, int] = (640, 480), color_by: str | None = None,
                 floor: bool = True, text: bool = True, frames: Sequence[int] | None = None,
                 bounds: Sequence[float] | None = None, clim: Sequence[float] | None = None,
                 colliders: str | Path | None = "auto", shadows: bool = True,
                 age_scale: float | None = None):
        if isinstance(series, (str, Path)):
            series = [series]
        if not series:
            raise ValueError("series must name at least one .pvd or .series file")
        offscreen.check_can_render()
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
        self.shadows = check_bool("shadows", shadows)
        if age_scale is not None and not (np.isfinite(age_scale) and age_scale > 0):
            raise ValueError(f"age_scale must be a positive number of seconds, got {age_scale!r}")
        self.color_by = color_by
        if isinstance(colliders, str) and colliders == "auto":
            beside = Path(series[0]).parent / COLLIDERS_FILE
            colliders = beside if beside.is_file() else None
        self.colliders = read_colliders(colliders) if colliders is not None else []
        indices = list(range(len(self.times))) if frames is None else list(frames)
        self._setup(indices, floor, text, bounds, clim, age_scale)

    # -- setup ---------------------------------------------------------------------------------
    def _frame(self, layer: _Layer, index: int):
        if not layer.entries:
            return pv.PolyData()
        index = min(index, len(layer.entries) - 1)
        return pv.wrap(read_frame(layer.entries[index][1]))

    def _survey(self, indices):
        """Kinds of the layers, robust bounds, colour range and oldest age over the frames, and
        what makes a frame interesting (liquid surface area, kinetic energy)."""
        for layer in self.layers:
            for i in indices:  # the first frame with data decides the look
                data = self._frame(layer, i)
                layer.kind = _kind(layer.name, data)
                layer.of_particles = looks.is_particle_surface(layer.name, data)
                if layer.kind != "empty":
                    break
        kinds = {layer.kind for layer in self.layers}
        # With a liquid surface its particles would only clutter the picture; smoke is drawn
        # from its particles, never from a surface contoured around them.
        if "smoke" in kinds:
            self.layers = [layer for layer in self.layers if not layer.of_particles]
        elif "water" in kinds:
            self.layers = [layer for layer in self.layers if layer.kind != "points"]
        boxes, clim, oldest = [], [np.inf, -np.inf], 0.0
        areas, energies = {}, {}
        for layer in self.layers:
            for i in indices:
                data = self._frame(layer, i)
                measures = frame_measures(layer.name, data)
                if measures[0] is not None:
                    areas.setdefault(layer.name, {})[i] = measures[0]
                if measures[1] is not None:
                    energies.setdefault(layer.name, {})[i] = measures[1]
                if data.n_points:
                    boxes.append(robust_bounds(_points_of(data)))
                if "age" in data.point_data and data.n_points:
                    oldest = max(oldest, float(np.max(data.point_data["age"])))
                if self.color_by and self.color_by in data.point_data:
                    values = np.asarray(data.point_data[self.color_by], dtype=np.float64)
                    values = np.linalg.norm(values, axis=1) if values.ndim == 2 else values
                    if values.size:
                        clim = [min(clim[0], values.min()), max(clim[1], values.max())]
        # one series per criterion: the first liquid surface, the first with velocities
        def first(table):
            return [table[next(iter(table))].get(i, 0.0) for i in indices] if table else None

        self._measures = (list(indices), first(areas), first(energies))
        return join_bounds(*boxes), clim, oldest

    def _setup(self, indices, floor, text, fixed_bounds, fixed_clim, age_scale):
        data_bounds, clim, oldest = self._survey(indices)
        if self.color_by and not np.isfinite(clim[0]):
            names = set()
            for layer in self.layers:
                names |= set(self._frame(layer, indices[0] if indices else 0).point_data.keys())
            raise ValueError(f"color_by must name a point array; "
                             f"arrays: {', '.join(sorted(names)) or 'none'}")
        framed = [c for c in self.colliders if c.role != "floor"]
        if fixed_bounds is not None:
            bounds = np.asarray(fixed_bounds, dtype=np.float64).reshape(6)
        else:
            bounds = join_bounds(data_bounds, *[self._collider_bounds(c) for c in framed])
            if bounds is None:
                bounds = np.array([-0.5, 0.5, -0.5, 0.5, 0.0, 1.0])
            ground = self._declared_floor()
            if ground is not None:  # the ground the bodies fall to is part of the picture
                bounds[4] = min(bounds[4], ground)
                bounds[5] = max(bounds[5], ground)
        self.bounds = bounds
        self.age_scale = float(age_scale) if age_scale is not None else (oldest or 1.0)
        if fixed_clim is not None:
            clim = [float(fixed_clim[0]), float(fixed_clim[1])]
        self.clim = clim if np.isfinite(clim[0]) else None
        if self.clim and self.clim[0] == self.clim[1]:
            self.clim = [self.clim[0], self.clim[0] + 1.0]
        self.center = 0.5 * (bounds[0::2] + bounds[1::2])
        self.radius = max(0.5 * float(np.linalg.norm(bounds[1::2] - bounds[0::2])), 1e-3)
        self.floor_z = self._floor_height()
        self.floor_half = 2.0 * self.radius

        ss = SUPERSAMPLE
        # A square window, cropped to the image: VTK 9's shadow-map pass projects its square
        # map with the window's aspect ratio and leaves strips of the floor beyond 1 / aspect
        # of the scene in false shadow (measured here, whatever the light's cone).
        self._inner = (int(round(self.size[0] * ss)), int(round(self.size[1] * ss)))
        side = max(self._inner)
        p = pv.Plotter(off_screen=True, window_size=(side, side), lighting="none")
        p.theme.allow_empty_mesh = True  # a frame with no particles is a valid, empty scene
        p.set_background(looks.BACKGROUND[1], top=looks.BACKGROUND[0])
        self.plotter = p
        self._scene = p.renderer
        # the second layer: glass, container edges, smoke and text, drawn over the opaque scene
        # with its depth buffer, casting no shadows
        self._over = vtkRenderer()
        self._over.SetLayer(1)
        self._over.SetPreserveDepthBuffer(True)
        self._over.SetPreserveColorBuffer(True)
        self._over.SetActiveCamera(self._scene.GetActiveCamera())
        self._over.UseDepthPeelingOff()
        p.render_window.SetNumberOfLayers(2)
        p.render_window.AddRenderer(self._over)
        self._key = pv.Light(light_type="scene light", intensity=0.85, positional=True,
                             cone_angle=60.0, exponent=0.0)
        p.add_light(self._key)
        p.add_light(pv.Light(light_type="headlight", intensity=0.42))
        fill = vtkLight()
        fill.SetLightTypeToHeadlight()
        fill.SetIntensity(0.6)
        self._over.AddLight(fill)
        self._passes = None
        if self.shadows:
            self._passes = actors.shadow_passes()
            self._scene.SetPass(self._passes)
        if floor:
            self._add_floor()
        self._add_colliders()
        for layer in self.layers:
            self._add_layer(layer, indices[0] if indices else 0)
        self._shown = None  # the frame the layers hold for drawing (none labelled yet)
        self._text = None
        if text:
            self._text = actors.label(self._inner, side, ss)
            self._over.AddViewProp(self._text)
        if self.color_by and self.clim:
            self._over.AddViewProp(actors.scalar_bar(self.color_by, self.clim, self._inner,
                                                     side, SUPERSAMPLE))

    @staticmethod
    def _collider_bounds(collider):
        points, _ = collider_mesh(collider, resolution=8)
        if collider.kind.startswith("sphere"):
            c, r = collider.parameters()[:3], collider.parameters()[3]
            return np.column_stack([c - r, c + r]).reshape(6)
        return robust_bounds(points, 0.0)

    def _declared_floor(self) -> float | None:
        """Height (m) of the lowest horizontal floor collider, or None."""
        floors = [c.parameters() for c in self.colliders if c.role == "floor"
                  and c.kind == "plane" and abs(c.parameters()[5]) > 0.99]
        return float(min(f[2] for f in floors)) if floors else None

    def _floor_height(self) -> float:
        """The declared floor (the lowest horizontal one), else the bottom of a container, else
        a little below the bounds (nothing seems to rest on it)."""
        floor = self._declared_floor()
        if floor is not None:
            return floor
        containers = [self._collider_bounds(c) for c in self.colliders if c.role == "container"]
        if containers:
            return float(min(b[4] for b in containers))
        return float(self.bounds[4] - 0.15 * self.radius)

    def _add_floor(self):
        c = self.center
        side = 2.0 * self.floor_half
        plane = pv.Plane(center=(c[0], c[1], self.floor_z - 1e-4 * self.radius),
                         direction=(0, 0, 1), i_size=side, j_size=side)
        texture = pv.Texture(looks.grid_texture_image())
        actor = self.plotter.add_mesh(plane, texture=texture, name="floor")
        looks.apply_material(actor.GetProperty(), "floor")

    def _add_colliders(self):
        for collider in self.colliders:
            if collider.role != "floor":  # the floor drawn under the scene stands for floors
                actors.collider_actors(collider, self._scene, self._over, self._pixel_size(0.8))

    def _pixel_size(self, pixels: float) -> float:
        """World length (m) of ``pixels`` image pixels at the framed centre's distance, for
        lines that keep their width in pixels whatever the image size (at least 0.2 % of the
        scene's radius)."""
        half_angle = math.radians(15.0)
        view = 2.0 * self._distance() * math.tan(half_angle)  # the image's height there (m)
        return max(pixels * view / self.size[1], 0.002 * self.radius)

    def _distance(self) -> float:
        """Camera distance (m) at which the framed bounds' sphere fills 30 degrees, plus 5 %."""
        return self.radius / math.sin(math.radians(15.0)) * 1.05

    def _fill(self, layer: _Layer, data) -> None:
        """Show ``data`` in the layer's actor, with the colour array as a scalar (magnitude)."""
        if layer.kind in ("points", "smoke"):
            data = self._without_strays(data)
        layer.slot.copy_from(data, deep=False)
        if layer.kind == "smoke":
            if data.n_points == 0:
                return
            age = data.point_data["age"] if "age" in data.point_data else None
            layer.slot.point_data[_RGBA] = looks.smoke_colors(
                _points_of(data), age, self.age_scale,
                zrange=(self.floor_z, self.bounds[5]))
            if "size" not in data.point_data:
                layer.slot.point_data["size"] = np.full(data.n_points, self._point_radius(data))
            return
        if self.color_by and self.color_by in data.point_data:
            values = np.asarray(data.point_data[self.color_by], dtype=np.float64)
            values = np.linalg.norm(values, axis=1) if values.ndim == 2 else values
            layer.slot.point_data[_COLOR] = values
        name = None
        if layer.actor is not None and hasattr(layer.actor.mapper, "array_name"):
            name = layer.actor.mapper.array_name
        if name and name in layer.slot.point_data:
            # copy_from() resets the active scalars the mapper draws: restore them.
            layer.slot.point_data.active_scalars_name = name

    def _without_strays(self, data):
        """A point cloud without its NaN points and those beyond the clipping reach
        (:data:`pipeline.render.framing.CLIP_REACH` framed radii from the centre): out of the
        picture anyway, they would stretch VTK's bounds and with them the shadows' frustum."""
        if data.n_points == 0:
            return data
        points = _points_of(data)
        with np.errstate(invalid="ignore"):
            keep = np.linalg.norm(points - self.center, axis=1) <= CLIP_REACH * self.radius
        if keep.all():
            return data
        kept = pv.PolyData(np.ascontiguousarray(points[keep]))
        for name in data.point_data.keys():
            kept.point_data[name] = np.asarray(data.point_data[name])[keep]
        return kept

    def _point_radius(self, data) -> float:
        """Half the mean spacing of ``data``'s points in the framed box (dense blocks look
        filled), at most a fifth of the scene's radius."""
        extent = np.maximum(self.bounds[1::2] - self.bounds[0::2], 1e-6)
        n = max(data.n_points, 1)
        spacing = float(np.prod(extent) / n) ** (1 / 3) if data.n_points > 1 else 0.05 * self.radius
        return 0.5 * min(spacing, 0.2 * self.radius)

    def _add_layer(self, layer: _Layer, index: int):
        data = self._frame(layer, index)
        layer.slot = type(data)()
        self._fill(layer, data)
        p = self.plotter
        if layer.kind == "smoke":
            layer.actor = actors.smoke_actor(layer.slot, _RGBA)
            self._over.AddActor(layer.actor)
            return
        kwargs = {}
        if self.color_by and self.clim and _COLOR in layer.slot.point_data:
            kwargs = dict(scalars=_COLOR, clim=self.clim, cmap="viridis", show_scalar_bar=False)
        source = layer.slot
        if layer.kind in ("water", "solid"):
            if not isinstance(source, pv.PolyData):
                surface = vtkDataSetSurfaceFilter()
                surface.SetInputData(source)
                source = surface
            # Water is drawn with normals split at sharp edges (its walls' cuts, see
            # looks.WATER_FEATURE_ANGLE), on this drawn copy only: the written surface stays
            # closed, with its own normals.
            normals = vtkPolyDataNormals()
            if layer.kind == "water":
                normals.SplittingOn()
                normals.SetFeatureAngle(looks.WATER_FEATURE_ANGLE)
            else:
                normals.SplittingOff()
            normals.ConsistencyOn()
            if isinstance(source, pv.DataSet):
                normals.SetInputData(source)
            else:
                normals.SetInputConnection(source.GetOutputPort())
            source = normals
        if layer.kind == "water":
            kwargs = kwargs or {"color": looks.WATER}
            # Opaque on purpose: with slight transparency, depth peeling under supersampling
            # showed the liquid's underside through thin sheets as block-shaped pits.
            layer.actor = p.add_mesh(source, smooth_shading=True, **kwargs)
            looks.apply_material(layer.actor.GetProperty(), "water")
        elif layer.kind == "solid":
            kwargs = kwargs or {"color": looks.SOLID}
            layer.actor = p.add_mesh(source, smooth_shading=True, **kwargs)
            looks.apply_material(layer.actor.GetProperty(), "solid")
        elif layer.kind == "lines":
            kwargs = kwargs or {"color": looks.HAIR}
            tubes = vtkTubeFilter()
            tubes.SetInputData(layer.slot)
            tubes.SetRadius(0.004 * self.radius)
            tubes.SetNumberOfSides(6)
            tubes.CappingOff()
            layer.actor = p.add_mesh(tubes, smooth_shading=True, **kwargs)
            looks.apply_material(layer.actor.GetProperty(), "lines")
        else:
            lut = None
            if "scalars" in kwargs:
                lut = pv.LookupTable(cmap="viridis")
                lut.scalar_range = tuple(self.clim)
            layer.actor = actors.glyph_actor(layer.slot, self._point_radius(data),
                                             kwargs.get("color", looks.POINTS), lut, _COLOR)
            self._scene.AddActor(layer.actor)

    @property
    def key_light_position(self) -> tuple[float, float, float]:
        """Position (m) of the shadow-casting key light for the last :meth:`render` (it follows
        the camera's azimuth)."""
        return tuple(float(v) for v in self._key.position)

    def interesting(self) -> tuple[int, str]:
        """The most interesting of the frames the renderer was framed on, and why
        (:func:`pipeline.render.framing.interesting_index`: largest liquid surface area, else
        largest kinetic energy, else the last frame)."""
        indices, areas, energies = self._measures
        if not indices:
            return 0, "last frame"
        k, reason = interesting_index(areas, energies)
        if areas is None and energies is None:
            k = len(indices) - 1
        return indices[k], reason

    # -- drawing -------------------------------------------------------------------------------
    def _place_camera(self, azimuth: float, elevation: float = 24.0):
        camera = self.plotter.camera
        # 30 degrees across the image's height, in a square window cropped to the image
        w, h = self.size
        camera.view_angle = 2.0 * math.degrees(math.atan(math.tan(math.radians(15.0))
                                                         * max(w, h) / h))
        distance = self._distance()
        az, el = math.radians(azimuth - 55.0), math.radians(elevation)
        offset = distance * np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az),
                                      math.sin(el)])
        camera.focal_point = tuple(self.center)
        camera.position = tuple(self.center + offset)
        camera.up = (0.0, 0.0, 1.0)
        position, focal, cone = looks.key_light(self.center, self.radius, azimuth, self.floor_z,
                                                self.floor_half)
        self._key.position = tuple(position)
        self._key.focal_point = tuple(focal)
        self._key.cone_angle = cone
        # one clipping range for both layers, so that their depths compare
        self._scene.ResetCameraClippingRange()
        near, far = self._scene.GetActiveCamera().GetClippingRange()
        self._over.ResetCameraClippingRange()
        over_near, over_far = self._over.GetActiveCamera().GetClippingRange()
        # from what is framed when a stray particle or a NaN would stretch it (blank images)
        self._scene.GetActiveCamera().SetClippingRange(*clipping_range(
            (min(near, over_near), max(far, over_far)), distance, self.radius))

    def _show(self, index: int) -> None:
        """Fill every layer with frame ``index`` and label it."""
        points = triangles = 0
        for layer in self.layers:
            data = self._frame(layer, index)
            self._fill(layer, data)
            points += data.n_points
            if hasattr(data, "GetNumberOfPolys"):
                triangles += data.GetNumberOfPolys()
        if self._text is not None:
            t = self.times[index] if len(self.times) else 0.0
            words = f"t = {t:.2f} s    {points:,} points"
            if triangles:
                words += f"    {triangles:,} triangles"
            self._text.SetInput(words)
        self._shown = index

    def render(self, index: int = -1, azimuth: float = 0.0) -> np.ndarray:
        """Draw frame ``index`` seen from ``azimuth`` degrees about the vertical axis.

        Azimuths are taken modulo 360, so that 360 draws exactly the image of 0.

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
        if index != self._shown:  # a turntable draws one frame from many sides: read it once
            self._show(index)
        self._place_camera(float(azimuth) % 360.0)
        self.plotter.render()
        image = np.asarray(self.plotter.screenshot(return_img=True))[..., :3]
        w, h = self.size
        (iw, ih), side = self._inner, image.shape[0]
        top, left = (side - ih) // 2, (side - iw) // 2
        image = np.ascontiguousarray(image[top:top + ih, left:left + iw])
        if (iw, ih) == (w, h):
            return image
        from PIL import Image

        # box filter: each output pixel the mean of the window pixels it covers
        return np.asarray(Image.fromarray(image).resize((w, h), Image.Resampling.BOX))

    def pixels_of(self, points: ArrayLike) -> np.ndarray:
        """Where world points fall in the image of the last :meth:`render`.

        Parameters
        ----------
        points : (N, 3) float
            Positions (m).

        Returns
        -------
        (N, 2) float
            ``(column, row)`` in pixels of the returned image (row 0 at the top); points
            outside the view fall outside ``[0, width) x [0, height)``.
        """
        from vtkmodules.vtkRenderingCore import vtkCoordinate

        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        side = self.plotter.render_window.GetSize()[1]
        (iw, ih) = self._inner
        left, top = (side - iw) // 2, (side - ih) // 2
        coordinate = vtkCoordinate()
        coordinate.SetCoordinateSystemToWorld()
        out = np.empty((len(points), 2))
        for k, p in enumerate(points):
            coordinate.SetValue(*p)
            x, y = coordinate.GetComputedDoubleDisplayValue(self._scene)
            out[k] = ((x - left) * self.size[0] / iw, (side - y - top) * self.size[1] / ih)
        return out

    def close(self) -> None:
        """Release the render window."""
        if self._passes is not None:
            self._passes.ReleaseGraphicsResources(self.plotter.render_window)
            self._scene.SetPass(None)
        self.plotter.render_window.RemoveRenderer(self._over)
        self.plotter.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

