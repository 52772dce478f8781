"""Surface stages that read the particles on their second input port: feature-weighted smoothing
(:class:`FeatureSmoothing`) and particle arrays carried to the vertices
(:class:`InterpolateAttributes`), with the checks and particle reading the stages of
:mod:`pipeline.surface` share. :mod:`pipeline.surface` exports the stages and builds the chain.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonDataModel import vtkPointSet, vtkPolyData

from filters.geometry import Box
from filters.kernels import SPLAT_KERNELS
from filters.surface.attributes import interpolate_attributes
from filters.surface.clip import wall_constraints
from filters.surface.smoothing import smooth_surface
from filters.validation import check_choice, check_int, check_range

from ..algorithm import ParticleStage
from .contour import mesh_to_polydata
from .options import SURFACE_DEFAULTS

if TYPE_CHECKING:
    from collections.abc import Iterable, Sequence
    from typing import Any

__all__ = ["FeatureSmoothing", "InterpolateAttributes", "check_optional_str", "check_names",
           "check_optional_range", "particles_from", "radii_from"]


# --------------------------------------------------------------------------------------------
# Checks and particle reading shared by the stages
# --------------------------------------------------------------------------------------------


def check_optional_str(name: str, value: Any) -> str | None:
    """``value``: a point array name or None (TypeError naming ``name`` otherwise)."""
    if value is not None and not (isinstance(value, str) and value):
        raise TypeError(f"{name} must be a point array name or None, got {value!r}")
    return value


def check_names(name: str, values: Iterable[str]) -> tuple[str, ...]:
    """``values`` as a tuple of point array names (TypeError naming ``name`` otherwise)."""
    if isinstance(values, str):
        raise TypeError(f"{name} must be a sequence of point array names, got the string "
                        f"{values!r}")
    try:
        values = tuple(values)
    except TypeError:
        raise TypeError(f"{name} must be a sequence of point array names, got {values!r}") from None
    for v in values:
        if not (isinstance(v, str) and v):
            raise TypeError(f"{name} must hold point array names, got {v!r}")
    return values


def check_optional_range(name: str, value: float | None, low: float, high: float,
                         low_inclusive: bool = True) -> float | None:
    """None, or ``value`` checked by :func:`filters.validation.check_range`."""
    return None if value is None else check_range(name, value, low, high,
                                                  low_inclusive=low_inclusive)


def particles_from(inp: vtkPointSet) -> np.ndarray:
    """Particle positions (N, 3) float64 (m) of a vtkPointSet."""
    n = inp.GetNumberOfPoints()
    if n == 0:
        return np.zeros((0, 3))
    return numpy_support.vtk_to_numpy(inp.GetPoints().GetData()).astype(np.float64)


def radii_from(inp: vtkPointSet, positions: np.ndarray, radius: float,
               radius_array: str | None) -> float | np.ndarray:
    """The particle radii (m): ``radius`` or, when there are particles, the ``radius_array``."""
    if radius_array and positions.shape[0]:
        arr = inp.GetPointData().GetArray(radius_array)
        if arr is None:
            raise ValueError(f"radius_array {radius_array!r} is not a point array of the input")
        return numpy_support.vtk_to_numpy(arr).astype(np.float64).reshape(-1)
    return radius


# --------------------------------------------------------------------------------------------
# Stages
# --------------------------------------------------------------------------------------------


class FeatureSmoothing(ParticleStage):
    """Feature-weighted Laplacian smoothing of a liquid surface (Löschner et al. 2023).

    Input port 0: the triangle mesh; port 1: the particles (see
    :func:`filters.surface.smoothing.smooth_surface`): flat liquid is smoothed fully, sheets
    and droplets of a few particles are left alone.

    Parameters
    ----------
    iterations : int
        Jacobi sweeps, in [0, 10000]; 0 passes the mesh through.
    radius : float
        Particle radius ``r`` (m), > 0, where the particles have no ``radius_array``; with
        per-particle radii the largest sets the spacing the fullness is measured against.
    radius_array : str, optional
        Point array of the particles holding their radii (m).
    reach_r : float
        Neighbourhood radius over ``r``, in [1, 20].
    walls : filters.geometry.Box, optional
        The tank a surface was cut at (:class:`pipeline.surface.liquid.ClipBox`): vertices on a wall
        move only in it (on an edge only along it), over their neighbours off the flat faces on
        the walls, which follow them.
    """

    def __init__(self, iterations: int = SURFACE_DEFAULTS["feature_smoothing"], *,
                 radius: float = SURFACE_DEFAULTS["radius"], radius_array: str | None = None,
                 reach_r: float = 8.0, walls: Box | None = None):
        if walls is not None and not isinstance(walls, Box):
            raise TypeError(f"walls must be a filters.geometry.Box or None, got "
                            f"{type(walls).__name__}")
        self.walls = walls
        self.iterations = check_int("iterations", iterations, 0, 10000)
        self.radius = check_range("radius", radius, 0.0, math.inf, low_inclusive=False)
        self.radius_array = check_optional_str("radius_array", radius_array)
        self.reach_r = check_range("reach_r", reach_r, 1.0, 20.0)
        ParticleStage.__init__(self)

    def RequestData(self, request, inInfo, outInfo):
        mesh = vtkPolyData.GetData(inInfo[0], 0)
        out = vtkPolyData.GetData(outInfo, 0)
        out.ShallowCopy(mesh)
        if not self.iterations or mesh.GetNumberOfPoints() == 0:
            return 1
        particles = vtkPointSet.GetData(inInfo[1], 0)
        positions = particles_from(particles)
        radius = radii_from(particles, positions, self.radius, self.radius_array)
        radius = np.broadcast_to(np.asarray(radius, np.float64), (positions.shape[0],))
        r = float(radius.max()) if radius.size else 1.0
        pts = numpy_support.vtk_to_numpy(mesh.GetPoints().GetData())
        tris = numpy_support.vtk_to_numpy(mesh.GetPolys().GetConnectivityArray()).reshape(-1, 3)
        free, faces = None, np.zeros(len(tris), bool)
        if self.walls is not None:
            free, faces = wall_constraints(pts, tris, self.walls.lower, self.walls.upper)
        smoothed = smooth_surface(pts.astype(np.float64), tris[~faces],
                                  np.ascontiguousarray(positions, np.float64), r,
                                  iterations=self.iterations, reach_r=self.reach_r, free=free)
        out.ShallowCopy(mesh_to_polydata(smoothed.astype(pts.dtype), tris))
        return 1


class InterpolateAttributes(ParticleStage):
    """Particle point arrays carried to the vertices of a surface (Shepard weights of the
    splatting kernel, :func:`filters.surface.attributes.interpolate_attributes`).

    Input port 0: the mesh; port 1: the particles. The splatting options must be those of the
    :class:`MetaballSplat` that made the surface (:func:`surface_stages` passes them).

    Parameters
    ----------
    attributes : sequence of str
        Point arrays of the particles to interpolate (missing ones are ignored).
    radius, cell_size, kernel, support_r, blobbiness, radius_array
        As in :class:`MetaballSplat`.
    """

    def __init__(self, attributes: Sequence[str] = SURFACE_DEFAULTS["attributes"], *,
                 radius: float = SURFACE_DEFAULTS["radius"], cell_size: float | None = None,
                 kernel: str = SURFACE_DEFAULTS["kernel"], support_r: float | None = None,
                 blobbiness: float = 4.0, radius_array: str | None = None):
        self.attributes = check_names("attributes", attributes)
        self.radius = check_range("radius", radius, 0.0, math.inf, low_inclusive=False)
        self.cell_size = (self.radius / 2 if cell_size is None else
                          check_range("cell_size", cell_size, 0.0, math.inf, low_inclusive=False))
        self.kernel = check_choice("kernel", kernel, SPLAT_KERNELS)
        self.support_r = check_optional_range("support_r", support_r, 0.0, 1e3, False)
        self.blobbiness = check_range("blobbiness", blobbiness, 0.0, 100.0, low_inclusive=False)
        self.radius_array = check_optional_str("radius_array", radius_array)
        ParticleStage.__init__(self)

    def RequestData(self, request, inInfo, outInfo):
        mesh = vtkPolyData.GetData(inInfo[0], 0)
        particles = vtkPointSet.GetData(inInfo[1], 0)
        out = vtkPolyData.GetData(outInfo, 0)
        out.ShallowCopy(mesh)
        positions = particles_from(particles)
        if not positions.shape[0]:
            return 1
        names, values = [], []
        for name in self.attributes:
            arr = particles.GetPointData().GetArray(name)
            if arr is not None:
                names.append(name)
                values.append(numpy_support.vtk_to_numpy(arr).astype(np.float64))
        if not names:
            return 1
        radius = radii_from(particles, positions, self.radius, self.radius_array)
        radius = np.broadcast_to(np.asarray(radius, np.float64), (positions.shape[0],)).copy()
        n = mesh.GetNumberOfPoints()
        pd = out.GetPointData()
        if n == 0:
            result = [np.zeros((0,) + v.shape[1:], np.float64) for v in values]
        else:
            pts = numpy_support.vtk_to_numpy(mesh.GetPoints().GetData()).astype(np.float64)
            columns = [v.reshape(v.shape[0], -1) for v in values]
            # all attributes in one pass: the same kernel weights serve every column
            stacked = interpolate_attributes(
                pts, positions, radius, np.concatenate(columns, axis=1),
                cell_size=self.cell_size, kernel=self.kernel, support_r=self.support_r,
                blobbiness=self.blobbiness)
            result, start = [], 0
            for v, c in zip(values, columns, strict=False):
                part = stacked[:, start:start + c.shape[1]]
                result.append(np.ascontiguousarray(part).reshape((n,) + v.shape[1:]))
                start += c.shape[1]
        for name, array in zip(names, result, strict=False):
            vtk_array = numpy_support.numpy_to_vtk(np.ascontiguousarray(array), deep=True)
            vtk_array.SetName(name)
            pd.AddArray(vtk_array)
        return 1
