"""Boundary particles of bodies in a liquid: solid layers under a body's surface.

A body in the liquid is sampled like the tank's walls (:func:`filters.sph.boundary.box_boundary`):
the fluid's own lattice continued into the solid, ``ceil(h / spacing)`` layers deep under its
surface, each particle with the fluid's lattice volume.  A fluid lattice next to a flat face of
the body then sees the neighbourhood it would see in the bulk (rest density), and the layers
fill half of a particle's kernel at the surface, which the DFSPH wall constraints need to keep
every particle out of the body (:mod:`filters.sph.dfsph`; one layer of surface samples does
not suffice).  Each particle carries the outward normal of the surface nearest to it, which
tells the body's faces apart.

:func:`solid_layers` samples the inside of any closed triangle mesh (rigid bodies: in the body
frame); :func:`locate_in_tets` gives the barycentric coordinates that carry such samples with a
deforming tetrahedral mesh (elastic bodies); :func:`mesh_distances` is the signed distance of a
closed mesh used by both (:func:`filters.rigid.sdf.mesh_distances`).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange
from numpy.typing import ArrayLike

from ..rigid.sdf import mesh_distances
from ..sph.boundary import BoundaryParticles, mesh_boundary

__all__ = ["solid_layers", "mesh_distances", "locate_in_tets"]


def solid_layers(vertices: ArrayLike, faces: ArrayLike, spacing: float, *,
                 support_factor: float = 2.0,
                 kernel: str = "cubic", layers: int | None = None,
                 origin: ArrayLike | None = None) -> BoundaryParticles:
    """Boundary particles filling the outer layers of the inside of a closed triangle mesh.

    The sampling of :func:`filters.sph.boundary.mesh_boundary` (the same function, without its
    check that the mesh is closed): the cell centres of a lattice that lie inside the mesh, at
    most ``layers * spacing`` under its surface, the lattice's steps fitted to whole cells across
    the mesh's bounding box, so that a box of any size has its first layer half a step inside
    every face.  A box whose sides are whole multiples of ``spacing`` gets exactly the tank's
    wall layers seen from the other side (:func:`filters.sph.boundary.box_boundary`).

    Parameters
    ----------
    vertices, faces, spacing, support_factor, kernel, layers, origin
        As :func:`filters.sph.boundary.mesh_boundary`.

    Returns
    -------
    BoundaryParticles
        Volumes: the lattice volume of its steps (:func:`filters.sph.boundary.lattice_volume`);
        normals: outward, of the surface nearest to each sample.
    """
    return mesh_boundary(vertices, faces, spacing, support_factor=support_factor,
                         kernel=kernel, check_closed=False, layers=layers, origin=origin)


@njit(parallel=True, cache=True)
def _locate(points, x, tets, inverse, out_tet, out_w):
    for i in prange(points.shape[0]):
        best = -np.inf
        for t in range(tets.shape[0]):
            a = tets[t, 0]
            rx = points[i, 0] - x[a, 0]
            ry = points[i, 1] - x[a, 1]
            rz = points[i, 2] - x[a, 2]
            b1 = inverse[t, 0, 0] * rx + inverse[t, 0, 1] * ry + inverse[t, 0, 2] * rz
            b2 = inverse[t, 1, 0] * rx + inverse[t, 1, 1] * ry + inverse[t, 1, 2] * rz
            b3 = inverse[t, 2, 0] * rx + inverse[t, 2, 1] * ry + inverse[t, 2, 2] * rz
            b0 = 1.0 - b1 - b2 - b3
            worst = min(b0, b1, b2, b3)
            if worst > best:
                best = worst
                out_tet[i] = t
                out_w[i, 0] = b0
                out_w[i, 1] = b1
                out_w[i, 2] = b2
                out_w[i, 3] = b3


def locate_in_tets(points: ArrayLike, positions: ArrayLike,
                   tets: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """The tetrahedron holding each point and its barycentric weights.

    A point outside every tetrahedron gets the one it is least outside of, with weights that
    extrapolate (some negative).

    Parameters
    ----------
    points : (P, 3) array_like
        Points (m).
    positions : (N, 3) array_like
        Nodes (m).
    tets : (T, 4) array_like of int
        Tetrahedra.

    Returns
    -------
    tet : (P,) int64
    weights : (P, 4) float64
        Point ``p`` is ``sum_k weights[p, k] positions[tets[tet[p], k]]``.
    """
    p = np.ascontiguousarray(points, dtype=np.float64)
    x = np.ascontiguousarray(positions, dtype=np.float64)
    t = np.ascontiguousarray(tets, dtype=np.int64)
    edges = x[t[:, 1:]] - x[t[:, :1]]  # (T, 3 edges, 3)
    inverse = np.ascontiguousarray(np.linalg.inv(np.transpose(edges, (0, 2, 1))))
    tet = np.zeros(p.shape[0], dtype=np.int64)
    w = np.zeros((p.shape[0], 4))
    if p.shape[0]:
        _locate(p, x, t, inverse, tet, w)
    return tet, w
