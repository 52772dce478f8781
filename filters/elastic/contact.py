"""Static colliders of elastic objects: contact with restitution and Coulomb friction.

A :class:`Colliders` object holds shapes of :mod:`filters.geometry` — half-spaces
(:class:`~filters.geometry.Plane`), :class:`~filters.geometry.Sphere` and axis-aligned
:class:`~filters.geometry.Box`, each either a *solid* (particles stay outside) or a *container*
``~shape`` (particles stay inside) — whose union is the obstacle, packed into arrays with their
restitution and friction.  Its arrays can be passed to the Numba functions
:func:`union_sdf`, :func:`resolve_particle` and :func:`resolve_contacts` from any ``@njit``
kernel (springs, SPH, advected particles), or used through :meth:`Colliders.resolve`.

Elastic objects (cloth, hair, jello) use these colliders through
:class:`filters.elastic.contact_model.ContactModel`, which solves contacts and friction inside
every time step; :meth:`Colliders.resolve` is the projection for particles that move on their
own (it can add elastic energy to particles joined by springs).

Contact response of :meth:`Colliders.resolve` (per particle, per primitive it penetrates, after
the particle has moved):
with signed distance ``phi < thickness`` and outward normal ``n``, the particle is projected to
``phi = thickness``; if it approaches (``v_n = v . n < 0``) its normal velocity becomes
``-e v_n`` (restitution ``e``) and its tangential velocity ``v_t`` is reduced by Coulomb friction,
``v_t <- v_t max(0, 1 - mu (1 + e) |v_n| / |v_t|)`` (Bridson, Fedkiw & Anderson 2002, "Robust
treatment of collisions, contact and friction for cloth animation").  Signed distances of boxes
follow Quilez's exact box SDF.

Array layouts (float64, C-contiguous):

* ``planes`` (P, 6): unit normal (3), offset ``d`` (the plane is ``n . x = d``, the solid side
  ``n . x < d``), restitution, friction;
* ``spheres`` (S, 7): centre (3), radius, side (+1 solid ball, -1 container), restitution,
  friction;
* ``boxes`` (B, 9): lower corner (3), upper corner (3), side (+1 solid, -1 container),
  restitution, friction.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit, prange

from ..geometry import Box, Complement, Plane, Shape, Sphere
from ..validation import check_points, check_range

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

__all__ = ["Colliders", "union_sdf", "primitive_sdf", "resolve_particle", "resolve_contacts"]


@njit(cache=True, inline="always")
def _plane(p, row):
    phi = row[0] * p[0] + row[1] * p[1] + row[2] * p[2] - row[3]
    return phi, row[0], row[1], row[2]


@njit(cache=True, inline="always")
def _sphere(p, row):
    d0 = p[0] - row[0]
    d1 = p[1] - row[1]
    d2 = p[2] - row[2]
    r = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    if r > 0.0:
        n0, n1, n2 = d0 / r, d1 / r, d2 / r
    else:
        n0, n1, n2 = 0.0, 0.0, 1.0
    side = row[4]
    return side * (r - row[3]), side * n0, side * n1, side * n2


@njit(cache=True, inline="always")
def _box(p, row):
    c = np.empty(3)
    q = np.empty(3)
    for k in range(3):
        c[k] = 0.5 * (row[k] + row[3 + k])
        q[k] = abs(p[k] - c[k]) - 0.5 * (row[3 + k] - row[k])
    out2 = 0.0
    for k in range(3):
        if q[k] > 0.0:
            out2 += q[k] * q[k]
    side = row[6]
    if out2 > 0.0:
        dist = math.sqrt(out2)
        n = np.zeros(3)
        for k in range(3):
            if q[k] > 0.0:
                n[k] = math.copysign(q[k], p[k] - c[k]) / dist
        return side * dist, side * n[0], side * n[1], side * n[2]
    # inside: the nearest face
    kmax = 0
    for k in range(1, 3):
        if q[k] > q[kmax]:
            kmax = k
    n = np.zeros(3)
    n[kmax] = 1.0 if p[kmax] >= c[kmax] else -1.0
    return side * q[kmax], side * n[0], side * n[1], side * n[2]


@njit(cache=True)
def union_sdf(p, planes, spheres, boxes):
    """Signed distance (m) of point ``p`` (3,) to the union of the colliders and its normal.

    Returns
    -------
    (phi, n0, n1, n2) : floats
        ``phi`` > 0 outside every obstacle; ``n`` the unit outward normal of the nearest one.
        ``phi = inf`` when there are no colliders.
    """
    best = np.inf
    b0, b1, b2 = 0.0, 0.0, 1.0
    for j in range(planes.shape[0]):
        phi, n0, n1, n2 = _plane(p, planes[j])
        if phi < best:
            best, b0, b1, b2 = phi, n0, n1, n2
    for j in range(spheres.shape[0]):
        phi, n0, n1, n2 = _sphere(p, spheres[j])
        if phi < best:
            best, b0, b1, b2 = phi, n0, n1, n2
    for j in range(boxes.shape[0]):
        phi, n0, n1, n2 = _box(p, boxes[j])
        if phi < best:
            best, b0, b1, b2 = phi, n0, n1, n2
    return best, b0, b1, b2


@njit(cache=True, inline="always")
def primitive_sdf(p, planes, spheres, boxes, c):
    """Signed distance (m) of point ``p`` (3,) to primitive ``c`` of the packed colliders,
    counted over planes, then spheres, then boxes; with its unit outward normal and friction.

    Returns
    -------
    (phi, n0, n1, n2, mu) : floats
    """
    if c < planes.shape[0]:
        phi, n0, n1, n2 = _plane(p, planes[c])
        return phi, n0, n1, n2, planes[c, 5]
    c -= planes.shape[0]
    if c < spheres.shape[0]:
        phi, n0, n1, n2 = _sphere(p, spheres[c])
        return phi, n0, n1, n2, spheres[c, 6]
    c -= spheres.shape[0]
    phi, n0, n1, n2 = _box(p, boxes[c])
    return phi, n0, n1, n2, boxes[c, 8]


@njit(cache=True, inline="always")
def _respond(x, v, phi, n0, n1, n2, thickness, e, mu):
    if phi >= thickness:
        return 0
    push = thickness - phi
    x[0] += push * n0
    x[1] += push * n1
    x[2] += push * n2
    vn = v[0] * n0 + v[1] * n1 + v[2] * n2
    if vn < 0.0:
        t0 = v[0] - vn * n0
        t1 = v[1] - vn * n1
        t2 = v[2] - vn * n2
        vt = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
        scale = 0.0
        if vt > 0.0:
            scale = max(0.0, 1.0 - mu * (1.0 + e) * (-vn) / vt)
        v[0] = scale * t0 - e * vn * n0
        v[1] = scale * t1 - e * vn * n1
        v[2] = scale * t2 - e * vn * n2
    return 1


@njit(cache=True)
def resolve_particle(x, v, planes, spheres, boxes, thickness):
    """Resolve the contacts of one particle in place (``x``, ``v`` are (3,) views).

    Every primitive is visited in turn (planes, spheres, boxes), so a particle in a corner is
    pushed out of both walls.  Returns the number of contacts.
    """
    hits = 0
    for j in range(planes.shape[0]):
        phi, n0, n1, n2 = _plane(x, planes[j])
        hits += _respond(x, v, phi, n0, n1, n2, thickness, planes[j, 4], planes[j, 5])
    for j in range(spheres.shape[0]):
        phi, n0, n1, n2 = _sphere(x, spheres[j])
        hits += _respond(x, v, phi, n0, n1, n2, thickness, spheres[j, 5], spheres[j, 6])
    for j in range(boxes.shape[0]):
        # a container's corner: one push along the diagonal, then one per face still too near
        for _ in range(4 if boxes[j, 6] < 0.0 else 1):
            phi, n0, n1, n2 = _box(x, boxes[j])
            hit = _respond(x, v, phi, n0, n1, n2, thickness, boxes[j, 7], boxes[j, 8])
            hits += hit
            if hit == 0:
                break
    return hits


@njit(parallel=True, cache=True)
def resolve_contacts(positions, velocities, planes, spheres, boxes, thickness, skip):
    """Resolve contacts of all particles in place; particles with ``skip[i]`` are left alone.

    Returns the number of contacts.
    """
    hits = 0
    for i in prange(positions.shape[0]):
        if skip.shape[0] > 0 and skip[i]:
            continue
        hits += resolve_particle(positions[i], velocities[i], planes, spheres, boxes, thickness)
    return hits


@njit(parallel=True, cache=True)
def _sdf_many(points, planes, spheres, boxes, out):
    for i in prange(points.shape[0]):
        phi, n0, n1, n2 = union_sdf(points[i], planes, spheres, boxes)
        out[i, 0] = phi
        out[i, 1] = n0
        out[i, 2] = n1
        out[i, 3] = n2


class Colliders:
    """A union of static planes, spheres and boxes.

    Parameters
    ----------
    restitution : float
        Default coefficient of restitution in [0, 1] for primitives added without one.
    friction : float
        Default Coulomb friction coefficient, >= 0.
    thickness : float
        Particles are kept this far (m), >= 0, outside every obstacle (a particle radius).

    Attributes
    ----------
    shapes : tuple of filters.geometry.Shape
        The obstacles, in the order they were added.
    planes, spheres, boxes : float64 arrays
        The obstacles packed for the Numba kernels (layouts in the module docstring).

    Examples
    --------
    >>> c = Colliders(restitution=0.2, friction=0.4).add(Plane((0, 0, 0), (0, 0, 1)))
    >>> c = c.add(Sphere((0, 0, 0.5), 0.3))
    """

    def __init__(self, *, restitution: float = 0.0, friction: float = 0.3, thickness: float = 0.0):
        self.restitution = check_range("restitution", restitution, 0.0, 1.0)
        self.friction = check_range("friction", friction, 0.0)
        self.thickness = check_range("thickness", thickness, 0.0)
        self.planes = np.zeros((0, 6))
        self.spheres = np.zeros((0, 7))
        self.boxes = np.zeros((0, 9))
        self.shapes: tuple = ()

    def _coeffs(self, restitution, friction):
        e = self.restitution if restitution is None else check_range("restitution", restitution,
                                                                      0.0, 1.0)
        mu = self.friction if friction is None else check_range("friction", friction, 0.0)
        return e, mu

    def add(self, shape: Shape, *, restitution: float | None = None,
            friction: float | None = None) -> Colliders:
        """Add an obstacle: a :class:`filters.geometry.Plane` (the half-space behind it), a
        :class:`~filters.geometry.Sphere` or :class:`~filters.geometry.Box` (solid), or a
        container ``~Sphere(...)`` / ``~Box(...)`` (particles stay inside).

        Parameters
        ----------
        shape : filters.geometry.Shape
            One of the above; other shapes raise TypeError.
        restitution : float, optional
            Coefficient of restitution in [0, 1]; default the object's.
        friction : float, optional
            Coulomb friction coefficient, >= 0; default the object's.

        Returns
        -------
        Colliders
            ``self``, so that calls chain.
        """
        e, mu = self._coeffs(restitution, friction)
        inside = isinstance(shape, Complement)
        solid = shape.shape if inside else shape
        side = -1.0 if inside else 1.0
        if isinstance(solid, Plane) and not inside:
            normal = np.array(solid.normal)
            row = np.r_[normal, normal @ np.array(solid.point), e, mu]
            self.planes = np.ascontiguousarray(np.vstack([self.planes, row]))
        elif isinstance(solid, Sphere):
            row = np.r_[solid.center, solid.radius, side, e, mu]
            self.spheres = np.ascontiguousarray(np.vstack([self.spheres, row]))
        elif isinstance(solid, Box):
            row = np.r_[solid.lower, solid.upper, side, e, mu]
            self.boxes = np.ascontiguousarray(np.vstack([self.boxes, row]))
        else:
            raise TypeError(f"shape must be a Plane, a Sphere, a Box or a container ~Sphere / "
                            f"~Box, got {shape!r}")
        self.shapes = self.shapes + (shape,)
        return self

    def __len__(self):
        return self.planes.shape[0] + self.spheres.shape[0] + self.boxes.shape[0]

    def sdf(self, points: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Signed distance (M,) (m) and outward normal (M, 3) of the union at ``points``."""
        pts = check_points("points", points)
        out = np.empty((pts.shape[0], 4))
        _sdf_many(pts, self.planes, self.spheres, self.boxes, out)
        return out[:, 0].copy(), out[:, 1:].copy()

    def resolve(self, positions: np.ndarray, velocities: np.ndarray,
                skip: np.ndarray | None = None) -> int:
        """Project penetrating particles out and apply restitution and friction, in place.

        Parameters
        ----------
        positions, velocities : (N, 3) float64 C-contiguous arrays
            Modified in place (m, m/s).
        skip : (N,) bool array, optional
            Particles to leave alone (pinned ones).

        Returns
        -------
        int
            Number of contacts resolved.
        """
        if len(self) == 0:
            return 0
        for name, a in (("positions", positions), ("velocities", velocities)):
            if not (isinstance(a, np.ndarray) and a.dtype == np.float64 and a.ndim == 2
                    and a.shape[1] == 3 and a.flags.c_contiguous):
                raise ValueError(f"{name} must be a C-contiguous (N, 3) float64 array")
        if velocities.shape != positions.shape:
            raise ValueError("velocities must have the shape of positions")
        skip = np.zeros(0, dtype=np.bool_) if skip is None else np.ascontiguousarray(skip, bool)
        return int(resolve_contacts(positions, velocities, self.planes, self.spheres, self.boxes,
                                    self.thickness, skip))
