"""Framing a render: robust bounds of what moves, and the most interesting moment of a series.

The camera of a movie is placed once, from bounds that ignore stray drops (per-axis
percentiles of the points of every frame) joined with the bounds of the containers and solid
colliders, so that it neither jumps nor zooms out to follow a few particles flying away.  The
turntable of a run is taken at the frame where the most happens: the largest area of a liquid
surface (a splash), else the largest kinetic energy of the bodies (sum of squared point
velocities), else the last frame.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from collections.abc import Sequence

    from numpy.typing import ArrayLike
    from vtkmodules.vtkCommonDataModel import vtkDataObject

__all__ = ["robust_bounds", "join_bounds", "surface_area", "kinetic_energy",
           "interesting_index", "frame_measures", "clipping_range", "ROBUST_PERCENT",
           "CLIP_REACH", "STRAY_FACTOR"]

#: Points below this percentile or above ``100 -`` it, per axis and frame, are left out of the
#: framing (strays).
ROBUST_PERCENT = 1.0
#: Points farther from the median point than this many times the median distance to it are
#: left out of the framing before the percentiles (a particle flung kilometres away).
STRAY_FACTOR = 20.0


def robust_bounds(points: ArrayLike, percent: float = ROBUST_PERCENT) -> np.ndarray | None:
    """``(xmin, xmax, ymin, ymax, zmin, zmax)`` of the points between the ``percent`` and
    ``100 - percent`` percentiles on each axis, or None for no (finite) points; non-finite
    points, and points farther from the median point than :data:`STRAY_FACTOR` times the
    median distance to it, are left out first.

    Parameters
    ----------
    points : (N, 3) float
        Positions (m).
    percent : float
        Percent of the points cut from each end of each axis, in [0, 50).
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if not 0.0 <= percent < 50.0:
        raise ValueError(f"percent must be in [0, 50), got {percent!r}")
    if not np.isfinite(points).all():  # a NaN or infinite point is nowhere: not framed
        points = points[np.isfinite(points).all(axis=1)]
    if len(points) > 2:
        # a stray far beyond the rest (more than STRAY_FACTOR times the median distance from
        # the median point) is left out before the percentiles, which a few strays among
        # fewer than 100 points would still reach
        distance = np.linalg.norm(points - np.median(points, axis=0), axis=1)
        typical = float(np.median(distance))
        if typical > 0:
            points = points[distance <= STRAY_FACTOR * typical]
    if len(points) == 0:
        return None
    if percent == 0.0 or len(points) < 50:
        lo, hi = points.min(axis=0), points.max(axis=0)
    else:
        lo, hi = np.percentile(points, [percent, 100.0 - percent], axis=0)
    return np.column_stack([lo, hi]).reshape(6)


#: Radii of the framed sphere, beyond its centre's distance, within which everything drawn
#: normally lies (the floor square reaches about 3 radii from the centre).
CLIP_REACH = 4.0


def clipping_range(fitted: tuple[float, float], distance: float,
                   radius: float) -> tuple[float, float]:
    """The camera's near and far clipping distances (m).

    ``fitted`` is VTK's range fitted to every actor. A particle flying far away (or a NaN
    point) stretches it so far that its near plane, a fixed fraction of the far one, moves
    past the whole scene and every image comes out blank; the range is then taken from the
    framed sphere (``radius`` m around the focal point, ``distance`` m from the camera),
    ``CLIP_REACH`` radii deep on each side. A range within that is kept as VTK fitted it.

    Parameters
    ----------
    fitted : (float, float)
        VTK's ``(near, far)``.
    distance : float
        Camera to focal point (m).
    radius : float
        Radius of the framed bounds' sphere (m), > 0.
    """
    near, far = (float(v) for v in fitted)
    reach = CLIP_REACH * radius
    if math.isfinite(near) and math.isfinite(far) and 0.0 < near < far <= distance + reach:
        return near, far
    far = distance + reach
    return max(distance - reach, 1e-3 * far), far


def join_bounds(*bounds: ArrayLike | None) -> np.ndarray | None:
    """The box holding every given ``(xmin, xmax, ...)`` box (None entries are skipped)."""
    boxes = [np.asarray(b, dtype=np.float64).reshape(6) for b in bounds if b is not None]
    if not boxes:
        return None
    boxes = np.array(boxes)
    out = np.empty(6)
    out[0::2] = boxes[:, 0::2].min(axis=0)
    out[1::2] = boxes[:, 1::2].max(axis=0)
    return out


def surface_area(points: ArrayLike, triangles: ArrayLike) -> float:
    """Total area (m^2) of triangles ``(T, 3)`` (indices) over ``points`` ``(P, 3)`` (m)."""
    points = np.asarray(points, dtype=np.float64)
    triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    if len(triangles) == 0:
        return 0.0
    a, b, c = (points[triangles[:, k]] for k in range(3))
    return 0.5 * float(np.linalg.norm(np.cross(b - a, c - a), axis=1).sum())


def kinetic_energy(velocities: ArrayLike) -> float:
    """Sum of squared speeds (m^2/s^2) of ``(N, 3)`` velocities: twice the kinetic energy of
    unit masses."""
    v = np.asarray(velocities, dtype=np.float64).reshape(-1, 3)
    return float(np.einsum("ij,ij->", v, v))


def interesting_index(areas: Sequence[float] | None,
                      energies: Sequence[float] | None) -> tuple[int, str]:
    """Index of the most interesting frame and why: the largest liquid surface area when the
    series has one, else the largest kinetic energy, else the last frame.

    Parameters
    ----------
    areas : sequence of float or None
        Liquid surface area per frame (m^2), or None without a liquid surface.
    energies : sequence of float or None
        Sum of squared point speeds per frame, or None without velocities.

    Returns
    -------
    index : int
        The frame (the first of equal maxima).
    reason : str
        ``"largest surface area"``, ``"largest kinetic energy"`` or ``"last frame"``.
    """
    for values, reason in ((areas, "largest surface area"), (energies, "largest kinetic energy")):
        if values is not None and len(values) and np.max(values) > 0.0:
            return int(np.argmax(values)), reason
    n = len(areas) if areas is not None else len(energies) if energies is not None else 0
    return max(n - 1, 0), "last frame"


def frame_measures(name: str, data: vtkDataObject) -> tuple[float | None, float | None]:
    """``(liquid surface area (m^2) or None, sum of squared point speeds or None)`` of one
    frame of the series ``name``: the area for a liquid's surface
    (:func:`pipeline.render.looks.is_liquid_surface`: tagged so, or an untagged polygonal frame of a
    series named ``surface*``), the energy where the frame has a ``velocity`` point array."""
    from .looks import is_liquid_surface

    area = energy = None
    polys = data.GetPolys() if hasattr(data, "GetPolys") else None
    if polys is not None and is_liquid_surface(name, data):
        if polys.GetNumberOfCells():
            from ..surface.contour import polydata_to_mesh

            area = surface_area(*polydata_to_mesh(data))
        else:
            area = 0.0
    velocity = data.GetPointData().GetArray("velocity")
    if velocity is not None:
        from vtkmodules.util import numpy_support

        energy = kinetic_energy(numpy_support.vtk_to_numpy(velocity))
    return area, energy
