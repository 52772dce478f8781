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
closed mesh used by both.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange
from numpy.typing import ArrayLike

from ..kernels import kernel_id
from ..rigid.sdf import body_distances, face_planes, grid_sdf, is_convex, pack_sdfs
from ..sph.boundary import BoundaryParticles, lattice_volume
from ..validation import check_int, check_range

__all__ = ["solid_layers", "mesh_distances", "locate_in_tets"]


def mesh_distances(vertices: ArrayLike, faces: ArrayLike, points: ArrayLike,
                   resolution: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance (m, negative inside) and outward unit normal of a closed triangle mesh
    at ``points``.

    Exact for a convex mesh (its face planes); otherwise interpolated on a distance grid of
    ``resolution`` cells along the mesh's longest extent (:func:`filters.rigid.sdf.grid_sdf`).

    Parameters
    ----------
    vertices : (V, 3) array_like
        Mesh vertices (m).
    faces : (F, 3) array_like of int
        Outward-oriented triangles of a closed mesh.
    points : (N, 3) array_like
        Where to evaluate (m).
    resolution : int
        Cells of the distance grid of a non-convex mesh, in [4, 256].

    Returns
    -------
    distance : (N,) float64
    normals : (N, 3) float64
    """
    v = np.ascontiguousarray(vertices, dtype=np.float64)
    f = np.ascontiguousarray(faces, dtype=np.int64)
    p = np.ascontiguousarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or not np.isfinite(p).all():
        raise ValueError(f"points must be a finite (N, 3) array, got shape {p.shape}")
    resolution = check_int("resolution", resolution, 4, 256)
    planes = face_planes(v, f)
    sdf = ("convex", planes) if is_convex(v, planes) else ("grid", *grid_sdf(v, f, resolution))
    d = np.empty(p.shape[0])
    n = np.empty_like(p)
    if p.shape[0]:
        body_distances(*pack_sdfs([sdf]), 0, p, np.zeros_like(p), 0.0, d, n)
    return d, n


def solid_layers(vertices: ArrayLike, faces: ArrayLike, spacing: float, *,
                 support_factor: float = 2.0,
                 kernel: str = "cubic", layers: int | None = None,
                 origin: ArrayLike | None = None) -> BoundaryParticles:
    """Boundary particles filling the outer layers of the inside of a closed triangle mesh.

    The samples are the cell centres ``origin + (i + 1/2) spacing`` of a lattice that lie inside
    the mesh, at most ``layers * spacing`` under its surface.  A box whose sides are whole
    multiples of ``spacing``, sampled from its corner, gets exactly the tank's wall layers seen
    from the other side (:func:`filters.sph.boundary.box_boundary`).

    Parameters
    ----------
    vertices : (V, 3) array_like
        Vertices (m) of a closed, outward-oriented triangle mesh.
    faces : (F, 3) array_like of int
        Its triangles.
    spacing : float
        The fluid's particle spacing (m), > 0.
    support_factor : float
        Kernel support over ``spacing``, in [1, 4].
    kernel : str
        Smoothing kernel (for the lattice volume).
    layers : int, optional
        Depth of the sampled shell in spacings, in [1, 8]; default ``ceil(support_factor)``
        (a full kernel support).  A body thinner than twice that is sampled through.
    origin : (3,) array_like, optional
        A lattice point (m); default the lower corner of the mesh's bounding box.

    Returns
    -------
    BoundaryParticles
        Volumes: the fluid's lattice volume (:func:`filters.sph.boundary.lattice_volume`);
        normals: outward, of the surface nearest to each sample.

    Raises
    ------
    ValueError
        For a bad parameter, or a mesh so small that no lattice point falls inside it.
    """
    v = np.ascontiguousarray(vertices, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 3 or v.shape[0] < 4 or not np.isfinite(v).all():
        raise ValueError(f"vertices must be a finite (V, 3) array with V >= 4, got {v.shape}")
    spacing = check_range("spacing", spacing, 0.0, math.inf, low_inclusive=False)
    support_factor = check_range("support_factor", support_factor, 1.0, 4.0)
    kernel_id(kernel)
    if layers is None:
        layers = int(math.ceil(support_factor - 1e-9))
    layers = check_int("layers", layers, 1, 8)
    lo = v.min(axis=0)
    hi = v.max(axis=0)
    if ((hi - lo) / spacing > 2000).any():
        raise ValueError("the mesh is more than 2000 spacings across; increase spacing")
    o = lo if origin is None else np.asarray(origin, dtype=np.float64)
    first = np.floor((lo - o) / spacing - 0.5).astype(np.int64)
    last = np.ceil((hi - o) / spacing - 0.5).astype(np.int64)
    axes = [o[k] + (np.arange(first[k], last[k] + 1) + 0.5) * spacing for k in range(3)]
    X, Y, Z = np.meshgrid(*axes, indexing="ij")
    grid = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)
    d, n = mesh_distances(v, faces, grid)
    keep = (d < -1e-9 * spacing) & (d >= -layers * spacing)
    if not keep.any():
        raise ValueError(f"no lattice point of spacing {spacing:g} m falls inside the mesh; "
                         f"decrease spacing")
    volume = lattice_volume(spacing, support_factor * spacing, kernel)
    points = grid[keep]
    return BoundaryParticles(points, np.full(points.shape[0], volume), n[keep])


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
