"""One rigid body: a closed triangle mesh, a density, its mass properties and contact geometry.

A :class:`RigidBody` is the fixed part (model) of a body; where it is and how it moves lives in
the state of :class:`filters.rigid.simulation.RigidBodies`.  Its **body frame** is the mesh's
own axes with the origin moved to the centre of mass: a body at position ``p`` (its centre of
mass, m) with orientation ``q`` (a unit quaternion) has its vertices at
``p + R(q) (X - center)``, ``X`` the mesh's vertices as given.  Orientation ``(1, 0, 0, 0)``
therefore draws the mesh as it was given.

Contact points are the vertices plus points along every edge at most ``contact_spacing`` apart
(edge-edge contacts between boxes need the latter); the samples for a liquid coupling
are the boundary particles of :func:`filters.sph.boundary.mesh_boundary` (the mesh's outer
layers) in the body frame, with their SPH volumes.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from ..sph.boundary import BoundaryParticles, mesh_boundary
from ..validation import check_bool, check_int, check_points, check_range
from .mass import MassProperties, mass_properties
from .quaternion import quat_from_matrix
from .sdf import body_distances, face_planes, grid_sdf, is_convex, pack_sdfs

if TYPE_CHECKING:
    from typing import Any

    from numpy.typing import ArrayLike, NDArray

__all__ = ["RigidBody", "edge_points"]


def edge_points(vertices: np.ndarray, faces: np.ndarray, spacing: float) -> np.ndarray:
    """The vertices and points along every edge at most ``spacing`` (m) apart, ``(P, 3)``.

    Each undirected edge of length ``L`` gets ``ceil(L / spacing) - 1`` evenly spaced interior
    points; a vertex appears once.
    """
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    e = np.unique(e, axis=0)
    a, b = vertices[e[:, 0]], vertices[e[:, 1]]
    length = np.linalg.norm(b - a, axis=1)
    if math.isinf(spacing):
        pieces = np.ones(e.shape[0], dtype=np.int64)
    else:
        pieces = np.maximum(1, np.ceil(length / spacing - 1e-9)).astype(np.int64)
    inner = pieces - 1
    edge = np.repeat(np.arange(e.shape[0]), inner)
    first = np.repeat(np.cumsum(inner) - inner, inner)
    t = (np.arange(edge.size) - first + 1) / pieces[edge]
    interior = a[edge] + t[:, None] * (b[edge] - a[edge])
    used = np.unique(faces)
    return np.ascontiguousarray(np.concatenate([vertices[used], interior]))


class RigidBody:
    """A rigid body made from a closed triangle mesh of uniform density.

    Parameters
    ----------
    vertices : (V, 3) array_like
        Mesh vertices (m), in the place and orientation the body starts in by default.
    faces : (F, 3) array_like of int
        Outward-oriented triangles of a closed mesh (see
        :func:`filters.rigid.mass.check_closed_mesh` for what is refused).
    density : float
        Density (kg/m^3), > 0.
    restitution : float
        Coefficient of restitution in [0, 1]; a contact uses the larger of its two sides'.
    friction : float
        Coulomb friction coefficient, >= 0; a contact uses ``sqrt(mu_a mu_b)`` of its sides.
    fixed : bool
        A fixed body never moves (infinite mass): an obstacle of any shape for the others.
    contact_spacing : float, optional
        Largest distance (m) between contact points along an edge, > 0; ``inf`` for the
        vertices only.  Default a quarter of :attr:`radius`.
    sdf_resolution : int
        Cells along the longest extent of the distance grid of a non-convex body, in [4, 256].
    sample_spacing : float, optional
        Spacing (m) of the samples for a liquid coupling (:attr:`samples`), the liquid's
        particle spacing; none when omitted.
    sample_options : dict, optional
        Further arguments of :func:`filters.sph.boundary.mesh_boundary` (``support_factor``,
        ``kernel``, ``layers``, ``origin``).

    Attributes
    ----------
    properties : MassProperties
        Of the mesh as given (its ``center`` in the mesh's coordinates).
    mass : float
        (kg).
    center : (3,) float64
        Centre of mass (m) of the mesh as given: the default initial position.
    vertices : (V, 3) float64, read-only
        The mesh in the body frame (``X - center``).
    faces : (F, 3) int64, read-only
    inertia : (3, 3) float64, read-only
        Inertia tensor about the centre of mass in the body frame (kg m^2).
    principal_moments : (3,) float64
        Its eigenvalues, ascending (kg m^2).
    principal_rotation : (4,) float64
        Quaternion of the rotation from the principal axes to the body frame.
    radius : float
        Largest distance (m) of a vertex from the centre of mass.
    contact_points : (P, 3) float64, read-only
        Body-frame contact points (m).
    convex : bool
        Whether the mesh is convex (exact plane distances) or uses a distance grid.
    samples : BoundaryParticles or None
        Body-frame samples of the mesh's outer layers with their SPH volumes (m^3)
        (:func:`filters.sph.boundary.mesh_boundary`).
    """

    def __init__(self, vertices: ArrayLike, faces: ArrayLike, *, density: float = 1000.0,
                 restitution: float = 0.0, friction: float = 0.5, fixed: bool = False,
                 contact_spacing: float | None = None, sdf_resolution: int = 32,
                 sample_spacing: float | None = None, sample_options: dict[str, Any] | None = None):
        props = mass_properties(vertices, faces, density)
        self.properties: MassProperties = props
        self.density = float(density)
        self.restitution = check_range("restitution", restitution, 0.0, 1.0)
        self.friction = check_range("friction", friction, 0.0, math.inf, high_inclusive=False)
        self.fixed = check_bool("fixed", fixed)
        sdf_resolution = check_int("sdf_resolution", sdf_resolution, 4, 256)
        self.mass = props.mass
        self.center = props.center.copy()
        v = np.ascontiguousarray(np.asarray(vertices, dtype=np.float64) - props.center)
        f = np.ascontiguousarray(np.asarray(faces), dtype=np.int64)
        self.vertices = v
        self.faces = f
        self.inertia = props.inertia.copy()
        self.principal_moments = props.principal_moments.copy()
        self.principal_rotation = quat_from_matrix(props.principal_axes)
        self.radius = float(np.linalg.norm(v, axis=1).max())
        if contact_spacing is None:
            contact_spacing = 0.25 * self.radius
        contact_spacing = check_range("contact_spacing", contact_spacing, 0.0, math.inf,
                                      low_inclusive=False)
        self.contact_spacing = contact_spacing
        self.contact_points = edge_points(v, f, contact_spacing)
        planes = face_planes(v, f)
        self.convex = is_convex(v, planes)
        if self.convex:
            self.sdf = ("convex", planes)
        else:
            self.sdf = ("grid", *grid_sdf(v, f, sdf_resolution))
        self.samples: BoundaryParticles | None = None
        if sample_spacing is not None:
            options = dict(sample_options or {})
            self.samples = mesh_boundary(v, f, sample_spacing, **options)
        elif sample_options:
            raise ValueError("sample_options need a sample_spacing")
        for a in (self.vertices, self.faces, self.inertia, self.principal_moments,
                  self.principal_rotation, self.contact_points, self.center):
            a.setflags(write=False)

    def __repr__(self):
        kind = "convex" if self.convex else "non-convex"
        return (f"RigidBody({self.vertices.shape[0]} vertices, {kind}, mass={self.mass:.6g} kg"
                f"{', fixed' if self.fixed else ''})")

    def signed_distance(self, points: ArrayLike,
                        velocities: ArrayLike | None = None) -> tuple[NDArray[np.float64],
                                                                      NDArray[np.float64]]:
        """Signed distance (m) and outward normals of body-frame points, as contacts see them.

        Parameters
        ----------
        points : (N, 3) array_like
            Points in the body frame (m).
        velocities : (N, 3) array_like, optional
            Their velocities relative to the body (m/s), which pick the face at an edge of a
            convex body (see :mod:`filters.rigid.sdf`).

        Returns
        -------
        distance : (N,) float64
            Negative inside (m).
        normals : (N, 3) float64
            Unit outward normals, in the body frame.
        """
        p = check_points("points", points)
        u = np.zeros_like(p) if velocities is None else check_points("velocities", velocities)
        if u.shape != p.shape:
            raise ValueError("velocities must have the shape of points")
        d = np.empty(p.shape[0])
        n = np.empty_like(p)
        body_distances(*pack_sdfs([self.sdf]), 0, p, u, 0.0, d, n)
        return d, n
