"""What the bodies of a scene touch: floors, containers and solid colliders as one static dataset.

A scene declares its colliders once, with the shapes of :mod:`filters.geometry` that its
simulation uses (``flow.add_collider("tank", ~Box(lo, hi), role="container")``), and
:meth:`pipeline.Flow.run` writes them as ``colliders.vtp`` beside the series, so that ParaView
users see the tank, the sphere or the head next to the animated data and the renderer
(:mod:`pipeline.render`) draws them: a floor that receives shadows, a container as glass with
visible edges, solids in a neutral material.

The file is one polydata of triangles (and the floor's quad):

* cell data ``collider`` (int32): index of the collider each cell belongs to;
* cell data ``role`` (int8): 0 floor, 1 container, 2 solid (:data:`ROLES`);
* field data ``collider_names``, ``collider_roles``, ``collider_kinds`` (strings, one per
  collider) and, per collider, a float64 array named after it with the shape's parameters, so
  the exact geometry is read back, not only its tessellation (:func:`read_colliders`):

  ========================  =======================================  ======
  kind                      parameters                               size
  ========================  =======================================  ======
  ``plane``                 point (3), normal (3), drawn size (1)    7
  ``sphere``                centre (3), radius (1)                   4
  ``box``                   lower corner (3), upper corner (3)       6
  ``sphere_container``      inner sphere: centre (3), radius (1)     4
  ``box_container``         inner box: lower (3), upper (3)          6
  ``shape``                 bounds of a combination (6), contoured   6
  ========================  =======================================  ======

The colliders of the current scenes are static; one that moves would be an output series of its
own, written every frame like the bodies.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from vtkmodules.util import numpy_support
from vtkmodules.vtkCommonCore import vtkPoints, vtkStringArray
from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData

from filters.geometry import Box, Complement, Plane, Shape, Sphere
from filters.validation import check_finite, check_int

from .series import SeriesError, read_frame, write_frame

if TYPE_CHECKING:
    from collections.abc import Sequence

__all__ = ["Collider", "ROLES", "COLLIDERS_FILE", "colliders_dataset", "write_colliders",
           "read_colliders", "collider_mesh"]

#: Roles of a collider, in the order of their codes in the ``role`` cell array.
ROLES = ("floor", "container", "solid")
#: File name of the colliders beside a run's series.
COLLIDERS_FILE = "colliders.vtp"
_SIZES = {"plane": 7, "sphere": 4, "box": 6, "sphere_container": 4, "box_container": 6,
          "shape": 6}


@dataclass(frozen=True)
class Collider:
    """One named collider of a scene.

    Parameters
    ----------
    name : str
        A Python identifier, unique in the scene (``"tank"``, ``"floor"``, ``"ball"``).
    shape : filters.geometry.Shape
        Its solid, with the package's sign convention (negative inside the solid): a
        :class:`~filters.geometry.Plane` for a floor, ``~Box(lower, upper)`` for a tank whose
        inner box is ``[lower, upper]``, a :class:`~filters.geometry.Sphere` for a ball.
        Combinations of shapes are drawn by contouring their signed distance.
    role : {"floor", "container", "solid"}
        How it is drawn: a floor receiving shadows, a container as glass with visible edges, a
        solid in a neutral material.
    size : float
        Side of the square drawn for a plane (m), > 0; unused for other shapes.
    """

    name: str
    shape: Shape
    role: str = "solid"
    size: float = 2.0

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ValueError(f"name must be a Python identifier such as 'tank', got {self.name!r}")
        if not isinstance(self.shape, Shape):
            raise TypeError(f"shape must be a filters.geometry Shape (Plane, Sphere, Box, ~Box, "
                            f"...), got {type(self.shape).__name__}")
        if self.role not in ROLES:
            raise ValueError(f"role must be one of {', '.join(ROLES)}, got {self.role!r}")
        object.__setattr__(self, "size", check_finite("size", self.size, 0.0, math.inf,
                                                      low_inclusive=False))
        if _kind(self.shape) == "shape" and self.shape.bounds() is None:
            raise ValueError(f"collider {self.name!r}: a combination of shapes must be bounded "
                             f"(planes only as a floor on their own) to be drawn")

    @property
    def kind(self) -> str:
        """``plane``, ``sphere``, ``box``, ``sphere_container``, ``box_container`` or ``shape``."""
        return _kind(self.shape)

    def parameters(self) -> np.ndarray:
        """The shape's parameters as stored in the file (see the module's table), float64."""
        s = self.shape
        kind = self.kind
        if kind == "plane":
            return np.array([*s.point, *s.normal, self.size])
        if kind == "sphere":
            return np.array([*s.center, s.radius])
        if kind == "box":
            return np.array([*s.lower, *s.upper])
        if kind == "sphere_container":
            return np.array([*s.shape.center, s.shape.radius])
        if kind == "box_container":
            return np.array([*s.shape.lower, *s.shape.upper])
        lo, hi = s.bounds()
        return np.array([*lo, *hi], dtype=np.float64)


def _kind(shape) -> str:
    if isinstance(shape, Plane):
        return "plane"
    if isinstance(shape, Sphere):
        return "sphere"
    if isinstance(shape, Box):
        return "box"
    if isinstance(shape, Complement) and isinstance(shape.shape, Sphere):
        return "sphere_container"
    if isinstance(shape, Complement) and isinstance(shape.shape, Box):
        return "box_container"
    return "shape"


# -- tessellation --------------------------------------------------------------------------------
def _sphere(center, radius, resolution):
    """Points and triangles of a UV sphere whose vertices lie exactly at ``radius``."""
    n_theta, n_phi = 2 * resolution, resolution
    phi = np.linspace(0.0, math.pi, n_phi + 1)[1:-1]
    theta = np.linspace(0.0, 2.0 * math.pi, n_theta, endpoint=False)
    ring = np.stack([np.outer(np.sin(phi), np.cos(theta)), np.outer(np.sin(phi), np.sin(theta)),
                     np.repeat(np.cos(phi)[:, None], n_theta, axis=1)], axis=-1).reshape(-1, 3)
    unit = np.vstack([[0.0, 0.0, 1.0], ring, [0.0, 0.0, -1.0]])
    tris = []
    top, bottom = 0, len(unit) - 1
    index = np.arange(len(phi) * n_theta).reshape(len(phi), n_theta) + 1
    nxt = np.roll(np.arange(n_theta), -1)
    tris.append(np.column_stack([np.full(n_theta, top), index[0], index[0, nxt]]))
    for i in range(len(phi) - 1):
        a, b = index[i], index[i + 1]
        tris.append(np.column_stack([a, b, b[nxt]]))
        tris.append(np.column_stack([a, b[nxt], a[nxt]]))
    tris.append(np.column_stack([np.full(n_theta, bottom), index[-1, nxt], index[-1]]))
    return np.asarray(center) + radius * unit, np.vstack(tris)


def _box(lower, upper):
    """Points and triangles (outward normals) of the box ``[lower, upper]``."""
    lo, hi = np.asarray(lower), np.asarray(upper)
    corners = np.array([[(hi if (k >> a) & 1 else lo)[a] for a in range(3)] for k in range(8)])
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    tris = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    return corners, np.array(tris)


def _plane(point, normal, size):
    """The four corners of a square of side ``size`` centred on ``point``, normal ``normal``."""
    n = np.asarray(normal)
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(n, helper)
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    h = 0.5 * size
    corners = np.asarray(point) + h * np.array([-u - v, u - v, u + v, -u + v])
    return corners, np.array([[0, 1, 2, 3]])


def _contour(shape, resolution):
    """Triangles of the zero level of ``shape`` sampled over its padded bounds."""
    from ..surface.contour import flying_edges, image_of, polydata_to_mesh

    lo, hi = (np.asarray(b, dtype=np.float64) for b in shape.bounds())
    pad = 0.05 * float(np.max(hi - lo))
    lo, hi = lo - pad, hi + pad
    n = 2 * resolution
    axes = [np.linspace(lo[a], hi[a], n) for a in range(3)]
    z, y, x = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")
    values = shape(np.column_stack([x.ravel(), y.ravel(), z.ravel()])).reshape(n, n, n)
    image, _ = image_of(np.ascontiguousarray(values), (0.0, 0.0, 0.0))
    fe = flying_edges()
    fe.SetInputData(image)
    fe.Update()
    points, triangles = polydata_to_mesh(fe.GetOutput())
    points = lo + points * (hi - lo) / (n - 1)
    return points, triangles


def collider_mesh(collider: Collider, resolution: int = 24) -> tuple[np.ndarray, np.ndarray]:
    """Points ``(P, 3)`` (m) and cells ``(C, 3 or 4)`` (indices) drawing ``collider``.

    Spheres are UV spheres with every vertex at the radius (``resolution`` rings), boxes and
    box containers their six faces (outward normals for a solid, inward for a container),
    planes a square of ``collider.size``, and combinations the zero level of their signed
    distance on a ``2 * resolution`` cubed grid.
    """
    resolution = check_int("resolution", resolution, 4, 512)
    params = collider.parameters()
    kind = collider.kind
    if kind == "plane":
        return _plane(params[:3], params[3:6], params[6])
    if kind in ("sphere", "sphere_container"):
        points, cells = _sphere(params[:3], params[3], resolution)
    elif kind in ("box", "box_container"):
        points, cells = _box(params[:3], params[3:])
    else:
        return _contour(collider.shape, resolution)
    if kind.endswith("_container"):
        cells = cells[:, ::-1]  # normals into the container, towards what it holds
    return points, cells


# -- the dataset and its file ---------------------------------------------------------------------
def _check_colliders(colliders) -> list:
    colliders = list(colliders)
    for i, c in enumerate(colliders):
        if not isinstance(c, Collider):
            raise TypeError(f"colliders[{i}] must be a Collider, got {type(c).__name__}")
    names = [c.name for c in colliders]
    if len(set(names)) != len(names):
        raise ValueError(f"collider names must be unique, got {names}")
    return colliders


def colliders_dataset(colliders: Sequence[Collider], resolution: int = 24) -> vtkPolyData:
    """One vtkPolyData of every collider: cells, ``collider`` and ``role`` cell arrays and the
    exact parameters in field data (see the module's docstring)."""
    colliders = _check_colliders(colliders)
    points, sizes, connectivity, index, role = [], [], [], [], []
    base = 0
    for i, c in enumerate(colliders):
        p, cells = collider_mesh(c, resolution)
        cells = np.asarray(cells, dtype=np.int64)
        points.append(np.asarray(p, dtype=np.float64))
        connectivity.append(cells.ravel() + base)
        sizes.append(np.full(len(cells), cells.shape[1], dtype=np.int64))
        index.append(np.full(len(cells), i, dtype=np.int32))
        role.append(np.full(len(cells), ROLES.index(c.role), dtype=np.int8))
        base += len(p)
    offsets = np.concatenate([[0], np.cumsum(np.concatenate(sizes))]) if sizes else np.zeros(1)
    connectivity = np.concatenate(connectivity) if connectivity else np.zeros(0)
    index = np.concatenate(index) if index else np.zeros(0)
    role = np.concatenate(role) if role else np.zeros(0)
    poly = vtkPolyData()
    vtk_points = vtkPoints()
    vtk_points.SetDataTypeToDouble()
    all_points = np.vstack(points) if points else np.zeros((0, 3))
    vtk_points.SetData(numpy_support.numpy_to_vtk(np.ascontiguousarray(all_points), deep=True))
    poly.SetPoints(vtk_points)
    polys = vtkCellArray()
    polys.SetData(numpy_support.numpy_to_vtk(offsets.astype(np.int64), deep=True),
                  numpy_support.numpy_to_vtk(connectivity.astype(np.int64), deep=True))
    poly.SetPolys(polys)
    for name, values, dtype in (("collider", index, np.int32), ("role", role, np.int8)):
        array = numpy_support.numpy_to_vtk(values.astype(dtype), deep=True)
        array.SetName(name)
        poly.GetCellData().AddArray(array)
    field = poly.GetFieldData()
    for name, values in (("collider_names", [c.name for c in colliders]),
                         ("collider_roles", [c.role for c in colliders]),
                         ("collider_kinds", [c.kind for c in colliders])):
        strings = vtkStringArray()
        strings.SetName(name)
        for v in values:
            strings.InsertNextValue(v)
        field.AddArray(strings)
    for c in colliders:
        array = numpy_support.numpy_to_vtk(c.parameters(), deep=True)
        array.SetName(c.name)
        field.AddArray(array)
    return poly


def write_colliders(colliders: Sequence[Collider], path: str | Path) -> Path:
    """Write ``colliders`` to ``path`` (``colliders.vtp``), atomically, as
    :func:`colliders_dataset` makes them."""
    return write_frame(colliders_dataset(colliders), path)


def _strings(field, name, path) -> list[str]:
    array = field.GetAbstractArray(name)
    if array is None:
        raise SeriesError(f"{path} holds no {name!r} field array: not a blobflow colliders file")
    return [array.GetValue(i) for i in range(array.GetNumberOfValues())]


def read_colliders(path: str | Path) -> list[Collider]:
    """Read back the colliders of a ``colliders.vtp`` (exact shapes, from its field data).

    Combinations of shapes (kind ``shape``) come back as the box of their bounds, the only
    thing the file keeps of them besides their triangles.

    Raises
    ------
    pipeline.io.series.SeriesError
        If the file is missing, unreadable or not a colliders file.
    """
    path = Path(path)
    data = read_frame(path)
    field = data.GetFieldData()
    names = _strings(field, "collider_names", path)
    roles = _strings(field, "collider_roles", path)
    kinds = _strings(field, "collider_kinds", path)
    out = []
    for name, role, kind in zip(names, roles, kinds, strict=False):
        array = field.GetArray(name)
        if array is None or kind not in _SIZES or role not in ROLES:
            raise SeriesError(f"{path}: collider {name!r} ({kind}, {role}) cannot be read")
        v = numpy_support.vtk_to_numpy(array).astype(np.float64)
        if v.size != _SIZES[kind]:
            raise SeriesError(f"{path}: collider {name!r} has {v.size} parameters, a {kind} "
                              f"has {_SIZES[kind]}")
        if kind == "plane":
            shape, size = Plane(tuple(v[:3]), tuple(v[3:6])), float(v[6])
        elif kind in ("sphere", "sphere_container"):
            shape, size = Sphere(tuple(v[:3]), float(v[3])), 2.0
        else:
            shape, size = Box(tuple(v[:3]), tuple(v[3:])), 2.0
        if kind.endswith("_container"):
            shape = ~shape
        out.append(Collider(name, shape, role, size))
    return out
