"""Shapes as signed distance functions: the one Plane, Sphere and Box of the package.

**Sign convention**: a shape's signed distance (m) is *negative inside the solid*, zero on its
surface and positive outside; its gradient, the unit normal, points out of the solid. A
:class:`Plane`'s solid is the half-space behind its normal; ``~shape`` (:class:`Complement`) turns
a solid into a container (a spherical tank: ``~Sphere(c, r)``, negative outside the ball).

Every shape is 1-Lipschitz (exact for the primitives, a bound for the combinations). The
combinations follow Ricci (1973): union ``a | b = min``, intersection ``a & b = max``,
difference ``a - b = max(a, -b)``. Shapes evaluate on NumPy arrays (``shape(points)``); the
consumers pack them for their Numba kernels: colliders with restitution and friction
(:class:`filters.elastic.contact.Colliders`), the curl-noise boundary ramp and the push-out of
advected particles (:func:`pack_shapes`, :func:`packed_distance`, :func:`packed_hessian`),
implicit surfaces (:mod:`filters.surface.csg`), SPH walls (:func:`filters.sph.boundary.box_boundary`
takes a :class:`Box`). Boxes have no continuous Hessian, so the ramp packs planes, spheres and
spherical containers only.

VTK has implicit functions too (vtkPlane, vtkSphere, vtkBox, vtkImplicitBoolean), but this
package does not import VTK, and these NumPy versions evaluate a whole block of points per call.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from .validation import check_finite, check_finite_vector, check_points

if TYPE_CHECKING:
    from collections.abc import Sequence

    from numpy.typing import ArrayLike

__all__ = [
    "Shape",
    "Plane",
    "Sphere",
    "Box",
    "Complement",
    "Union",
    "Intersection",
    "Difference",
    "pack_shapes",
    "packed_distance",
    "packed_hessian",
    "union_distance",
]


class Shape:
    """Base class: ``shape(points) -> (N,) signed distances`` (m), negative inside the solid.

    ``a | b`` (union), ``a & b`` (intersection), ``a - b`` (difference) and ``~a`` (complement)
    combine shapes.
    """

    def __call__(self, points) -> np.ndarray:
        return self.evaluate(check_points("points", points))

    def evaluate(self, points: np.ndarray) -> np.ndarray:  # pragma: no cover - abstract
        """Signed distances (m) at checked ``(N, 3) float64`` points, ``(N,)``."""
        raise NotImplementedError

    def bounds(self) -> tuple[np.ndarray, np.ndarray] | None:
        """``(lo, hi)`` (m) of the solid, or None if it is unbounded."""
        return None

    def __or__(self, other):
        return Union(self, other)

    def __and__(self, other):
        return Intersection(self, other)

    def __sub__(self, other):
        return Difference(self, other)

    def __invert__(self):
        return Complement(self)


def _vector(shape, name, size=3):
    value = tuple(check_finite_vector(name, getattr(shape, name), size).tolist())
    object.__setattr__(shape, name, value)
    return np.array(value)


@dataclass(frozen=True)
class Plane(Shape):
    """Half-space: the solid is behind the plane, on the side opposite to ``normal``.

    Parameters
    ----------
    point : (3,) float
        A point of the plane (m).
    normal : (3,) float
        Normal pointing out of the solid (into the free space), non-zero; normalised here.
    """

    point: tuple = (0.0, 0.0, 0.0)
    normal: tuple = (0.0, 0.0, 1.0)

    def __post_init__(self):
        _vector(self, "point")
        n = check_finite_vector("normal", self.normal, 3)
        length = float(np.linalg.norm(n))
        if length == 0.0:
            raise ValueError("normal must be a non-zero vector")
        object.__setattr__(self, "normal", tuple((n / length).tolist()))

    def evaluate(self, points: np.ndarray) -> np.ndarray:
        return (points - np.array(self.point)) @ np.array(self.normal)


@dataclass(frozen=True)
class Sphere(Shape):
    """Solid ball of ``radius`` (m) > 0 about ``center`` (m)."""

    center: tuple = (0.0, 0.0, 0.0)
    radius: float = 1.0

    def __post_init__(self):
        _vector(self, "center")
        object.__setattr__(self, "radius", check_finite("radius", self.radius, 0.0, math.inf,
                                                        low_inclusive=False))

    def evaluate(self, points: np.ndarray) -> np.ndarray:
        return np.linalg.norm(points - np.array(self.center), axis=1) - self.radius

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        c = np.array(self.center)
        return c - self.radius, c + self.radius


@dataclass(frozen=True)
class Box(Shape):
    """Solid axis-aligned box ``[lower, upper]`` (m), ``upper > lower`` on every axis; exact
    signed distance (Quilez's formulation)."""

    lower: tuple = (-1.0, -1.0, -1.0)
    upper: tuple = (1.0, 1.0, 1.0)

    def __post_init__(self):
        lower = _vector(self, "lower")
        upper = _vector(self, "upper")
        if not (upper > lower).all():
            raise ValueError(f"upper must exceed lower on every axis, got lower={lower.tolist()}, "
                             f"upper={upper.tolist()}")

    def evaluate(self, points: np.ndarray) -> np.ndarray:
        lo = np.array(self.lower)
        hi = np.array(self.upper)
        c = 0.5 * (lo + hi)
        half = 0.5 * (hi - lo)
        q = np.abs(points - c) - half
        outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
        inside = np.minimum(q.max(axis=1), 0.0)
        return outside + inside

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return np.array(self.lower), np.array(self.upper)


def _check_shape(name, value):
    if not isinstance(value, Shape):
        raise TypeError(f"{name} must be a Shape (Plane, Sphere, Box or a combination), "
                        f"got {type(value).__name__}")
    return value


@dataclass(frozen=True)
class Complement(Shape):
    """Everything but ``shape``: ``-shape``, a container (``~Sphere``: a spherical tank)."""

    shape: Shape

    def __post_init__(self):
        _check_shape("shape", self.shape)

    def evaluate(self, points: np.ndarray) -> np.ndarray:
        return -self.shape.evaluate(points)


@dataclass(frozen=True)
class _Binary(Shape):
    a: Shape
    b: Shape

    def __post_init__(self):
        _check_shape("a", self.a)
        _check_shape("b", self.b)


@dataclass(frozen=True)
class Union(_Binary):
    """``min(a, b)``: inside either."""

    def evaluate(self, points: np.ndarray) -> np.ndarray:
        return np.minimum(self.a.evaluate(points), self.b.evaluate(points))

    def bounds(self) -> tuple[np.ndarray, np.ndarray] | None:
        ba, bb = self.a.bounds(), self.b.bounds()
        if ba is None or bb is None:
            return None
        return np.minimum(ba[0], bb[0]), np.maximum(ba[1], bb[1])


@dataclass(frozen=True)
class Intersection(_Binary):
    """``max(a, b)``: inside both."""

    def evaluate(self, points: np.ndarray) -> np.ndarray:
        return np.maximum(self.a.evaluate(points), self.b.evaluate(points))

    def bounds(self) -> tuple[np.ndarray, np.ndarray] | None:
        ba, bb = self.a.bounds(), self.b.bounds()
        if ba is None:
            return bb
        if bb is None:
            return ba
        return np.maximum(ba[0], bb[0]), np.minimum(ba[1], bb[1])


@dataclass(frozen=True)
class Difference(_Binary):
    """``max(a, -b)``: inside ``a`` and outside ``b``."""

    def evaluate(self, points: np.ndarray) -> np.ndarray:
        return np.maximum(self.a.evaluate(points), -self.b.evaluate(points))

    def bounds(self) -> tuple[np.ndarray, np.ndarray] | None:
        return self.a.bounds()


# ---------------------------------------------------------------------------------------------
# Packed shapes for Numba kernels (the curl-noise ramp and the push-out of advected particles)
# ---------------------------------------------------------------------------------------------
_SDF_PLANE = 0
_SDF_SPHERE = 1
_SDF_INSIDE_SPHERE = 2


def _pack_row(i, shape) -> np.ndarray:
    if isinstance(shape, Plane):
        return np.array([_SDF_PLANE, *shape.point, *shape.normal, 0.0])
    if isinstance(shape, Sphere):
        return np.array([_SDF_SPHERE, *shape.center, 0.0, 0.0, 0.0, shape.radius])
    if isinstance(shape, Complement) and isinstance(shape.shape, Sphere):
        s = shape.shape
        return np.array([_SDF_INSIDE_SPHERE, *s.center, 0.0, 0.0, 0.0, s.radius])
    raise TypeError(
        f"shapes[{i}] must be a Plane, a Sphere or a spherical container ~Sphere (boxes and "
        f"combinations have no continuous Hessian for the curl-noise ramp), got {shape!r}")


def pack_shapes(shapes: Shape | Sequence[Shape] | np.ndarray) -> np.ndarray:
    """Pack planes, spheres and spherical containers into the ``(C, 8) float64`` rows that
    :func:`packed_distance` reads.

    Parameters
    ----------
    shapes : Shape or sequence of Shape, or a packed ``(C, 8)`` array
        :class:`Plane`, :class:`Sphere` or ``~Sphere`` objects; others raise TypeError.

    Returns
    -------
    (C, 8) float64 array, read-only
        Rows ``[kind, a0, a1, a2, b0, b1, b2, r]``.
    """
    if isinstance(shapes, np.ndarray):
        if shapes.ndim != 2 or shapes.shape[1] != 8:
            raise ValueError(f"packed shapes must have shape (C, 8), got {shapes.shape}")
        packed = np.ascontiguousarray(shapes, dtype=np.float64).copy()
    else:
        if isinstance(shapes, Shape):
            shapes = (shapes,)
        rows = [_pack_row(i, s) for i, s in enumerate(shapes)]
        packed = np.array(rows, dtype=np.float64).reshape(-1, 8)
    packed.setflags(write=False)
    return packed


@njit(cache=True)
def packed_distance(colliders, x, y, z):
    """Signed distance to the union of packed shapes, with the nearest one's unit normal.

    Parameters
    ----------
    colliders : (C, 8) float64
        Rows ``[kind, a0, a1, a2, b0, b1, b2, r]`` from :func:`pack_shapes`.
    x, y, z : float
        The point (m).

    Returns
    -------
    d, nx, ny, nz, index
        Distance (m, negative inside), outward unit normal (the SDF gradient) and the row of the
        nearest collider (-1 and ``d = inf`` when there is none).
    """
    best = np.inf
    bx = 0.0
    by = 0.0
    bz = 1.0
    bi = -1
    for c in range(colliders.shape[0]):
        kind = np.int64(colliders[c, 0])
        if kind == _SDF_PLANE:
            nx = colliders[c, 4]
            ny = colliders[c, 5]
            nz = colliders[c, 6]
            d = (x - colliders[c, 1]) * nx + (y - colliders[c, 2]) * ny + (z - colliders[c, 3]) * nz
        else:
            rx = x - colliders[c, 1]
            ry = y - colliders[c, 2]
            rz = z - colliders[c, 3]
            r = math.sqrt(rx * rx + ry * ry + rz * rz)
            if r > 0.0:
                nx = rx / r
                ny = ry / r
                nz = rz / r
            else:
                nx = 0.0
                ny = 0.0
                nz = 1.0
            if kind == _SDF_SPHERE:
                d = r - colliders[c, 7]
            else:
                d = colliders[c, 7] - r
                nx = -nx
                ny = -ny
                nz = -nz
        if d < best:
            best = d
            bx = nx
            by = ny
            bz = nz
            bi = c
    return best, bx, by, bz, bi


@njit(cache=True, inline="always")
def packed_hessian(colliders, c, x, y, z, nx, ny, nz):
    """Hessian of packed shape ``c``'s signed distance (the gradient of its unit normal) at
    ``(x, y, z)``, whose normal is ``(nx, ny, nz)``, as 6 entries ``xx, yy, zz, xy, xz, yz``
    (1/m); zero for a plane or ``c < 0``."""
    kind = np.int64(colliders[c, 0])
    if kind == _SDF_PLANE or c < 0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    rx = x - colliders[c, 1]
    ry = y - colliders[c, 2]
    rz = z - colliders[c, 3]
    r = math.sqrt(rx * rx + ry * ry + rz * rz)
    if r <= 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    s = 1.0 / r if kind == _SDF_SPHERE else -1.0 / r
    return (s * (1.0 - nx * nx), s * (1.0 - ny * ny), s * (1.0 - nz * nz),
            -s * nx * ny, -s * nx * nz, -s * ny * nz)


@njit(cache=True)
def _sdf_many(colliders, pts, d_out, n_out):
    for i in range(pts.shape[0]):
        d, nx, ny, nz, _ = packed_distance(colliders, pts[i, 0], pts[i, 1], pts[i, 2])
        d_out[i] = d
        n_out[i, 0] = nx
        n_out[i, 1] = ny
        n_out[i, 2] = nz


def union_distance(points: ArrayLike,
                   shapes: Shape | Sequence[Shape] | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance (m) to the union of packable ``shapes`` and the nearest one's normal.

    Parameters
    ----------
    points : (N, 3) array_like
        Query points (m).
    shapes : sequence of Shape or (C, 8) packed array
        See :func:`pack_shapes`.

    Returns
    -------
    d : (N,) float64
        Signed distance (m), negative inside a solid; ``inf`` with no shape.
    normals : (N, 3) float64
        Unit normals (the gradient of ``d``).
    """
    pts = check_points("points", points)
    packed = pack_shapes(shapes)
    d = np.empty(pts.shape[0])
    n = np.empty((pts.shape[0], 3))
    _sdf_many(packed, pts, d, n)
    return d, n
