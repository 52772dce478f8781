"""Tetrahedral meshes for the finite elements: boxes and the interior of any closed surface.

Both builders cut cubic lattice cells into the six tetrahedra of the Kuhn split
(:mod:`filters.simplices`), which is the same in every cell, so neighbouring cells share their
faces' diagonals and the mesh is conforming; every tetrahedron is a congruent copy of one
shape (edges ``h, h sqrt 2, h sqrt 3``), so the mesh has no slivers.

* :func:`box_tets` -- a box of ``nx x ny x nz`` cells (beams, blocks).
* :func:`tets_from_mesh` -- any closed, consistently oriented triangle mesh: every lattice
  cell that holds some of its interior (those of the spring jello of
  :func:`filters.elastic.topology.jello_from_mesh`, :func:`filters.elastic.voxelize.
  voxelize_mesh`, plus the cells the surface cuts) is cut into six tetrahedra, each with the
  fraction of it inside the surface, computed exactly (:func:`filters.elastic.cutcells.
  tet_fractions`), and the mesh's vertices are embedded in their tetrahedra with barycentric
  weights, so the simulation's output is the user's mesh, deformed by the elements' linear
  displacement field (free-form deformation, Sederberg & Parry 1986).  The fractions scale
  every element's mass and stiffness (the finite cell method, Parvizian, Duster & Rank 2007),
  so the body weighs and resists like its surface although the elements' hull is
  stair-cased: a cube column under its own weight shortens within 1 % of linear elasticity's
  ``rho g H^2 / (2 E)`` at 8 cells along it, where whole hull elements were 19 % (and at 4
  cells 32 %) too stiff.  The lattice is used instead of a conforming mesher: it needs no extra
  library (TetGen is AGPL; fTetWild is MPL-2.0 but a compiled dependency), it is
  deterministic and fast, it keeps the user's surface exact at rest whatever its quality, and
  it gives the spring jello and the finite elements the same lattice.
* :func:`tets_from_arrays` -- a user's own tetrahedral mesh, as it is (checked: tetrahedra,
  none inverted or flat, one connected body); its boundary faces are its surface.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from ..simplices import CORNER_OFFSETS, KUHN_TETS, kuhn_locate
from ..validation import check_finite_vector, check_int, check_points, check_range
from .cutcells import tet_fractions
from .surfaces import check_triangles
from .topology import Embedding
from .voxelize import voxelize_mesh

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

__all__ = ["TetMesh", "box_tets", "lattice_tets", "tets_from_mesh", "tets_from_arrays",
           "tet_volumes", "OUTWARD_FACES", "MIN_FRACTION"]


@dataclass(frozen=True)
class TetMesh:
    """Nodes and positively oriented tetrahedra, optionally with a surface mesh embedded.

    Attributes
    ----------
    positions : (N, 3) float64 array
        Rest positions of the nodes (m).
    tets : (T, 4) int64 array
        Node indices of every tetrahedron, ``det[x1 - x0, x2 - x0, x3 - x0] > 0``.
    embedding : filters.elastic.topology.Embedding or None
        The user's surface: per vertex the 4 nodes of its tetrahedron and barycentric weights.
    volume : float
        Volume (m^3) of the solid the mesh stands for: the embedded surface's when there is
        one, else the tetrahedra's.
    fractions : (T,) float64 array or None
        Fraction (0-1] of every tetrahedron inside the solid, which scales its mass and
        stiffness; None when every tetrahedron is whole.
    """

    positions: np.ndarray
    tets: np.ndarray
    embedding: Embedding | None
    volume: float
    fractions: np.ndarray | None = None


def tet_volumes(positions: np.ndarray, tets: np.ndarray) -> NDArray[np.float64]:
    """Signed volumes (T,) (m^3) ``det[x1 - x0, x2 - x0, x3 - x0] / 6`` of tetrahedra."""
    x = np.asarray(positions, dtype=np.float64)
    t = np.asarray(tets, dtype=np.int64)
    e1 = x[t[:, 1]] - x[t[:, 0]]
    e2 = x[t[:, 2]] - x[t[:, 0]]
    e3 = x[t[:, 3]] - x[t[:, 0]]
    return np.einsum("ij,ij->i", e1, np.cross(e2, e3)) / 6.0


def lattice_tets(cells: np.ndarray, origin: np.ndarray,
                 spacing: float) -> tuple[NDArray[np.float64], NDArray[np.int64],
                                          NDArray[np.int64]]:
    """Nodes and Kuhn tetrahedra of a set of lattice cells.

    Parameters
    ----------
    cells : (C, 3) int array
        Cell indices ``(i, j, k)`` (non-negative, distinct).
    origin : (3,) float
        Position (m) of lattice node ``(0, 0, 0)``.
    spacing : float
        Cell edge (m), > 0.

    Returns
    -------
    positions : (N, 3) float64
        The cells' corners (m), ordered by lattice index (x slowest, z fastest).
    tets : (6 C, 4) int64
        Six positively oriented tetrahedra per cell, cell by cell.
    corners : (C, 8) int64
        Node of every corner ``i + 2 j + 4 k`` of every cell.
    """
    cells = np.asarray(cells, dtype=np.int64).reshape(-1, 3)
    spacing = check_range("spacing", spacing, 0.0, math.inf, low_inclusive=False)
    origin = check_finite_vector("origin", origin, 3)
    if cells.size and cells.min() < 0:
        raise ValueError("cells must have non-negative indices")
    nd = cells.max(axis=0, initial=0) + 2
    corner_ijk = cells[:, None, :] + CORNER_OFFSETS[None, :, :]  # (C, 8, 3)
    lin = (corner_ijk[..., 0] * nd[1] + corner_ijk[..., 1]) * nd[2] + corner_ijk[..., 2]
    node_ids, local = np.unique(lin.ravel(), return_inverse=True)
    corners = local.reshape(-1, 8).astype(np.int64)
    ijk = np.stack([node_ids // (nd[1] * nd[2]), (node_ids // nd[2]) % nd[1], node_ids % nd[2]],
                   1)
    positions = origin + ijk * spacing
    tets = corners[:, KUHN_TETS].reshape(-1, 4)
    return np.ascontiguousarray(positions), np.ascontiguousarray(tets), corners


def box_tets(shape: ArrayLike, size: ArrayLike, origin: ArrayLike = (0.0, 0.0, 0.0)) -> TetMesh:
    """A box of ``nx x ny x nz`` cells, each cut into six tetrahedra.

    Parameters
    ----------
    shape : sequence of 3 int
        Cells along x, y, z, each >= 1.
    size : sequence of 3 float
        Edge lengths (m) of the box, > 0 (cells need not be cubes).
    origin : sequence of 3 float
        Lower corner (m).

    Returns
    -------
    TetMesh
        ``(nx + 1)(ny + 1)(nz + 1)`` nodes, node ``(i, j, k)`` at index
        ``(i (ny + 1) + j)(nz + 1) + k``; ``6 nx ny nz`` tetrahedra.
    """
    dims = [check_int(f"shape[{a}]", v, 1) for a, v in enumerate(shape)] if len(shape) == 3 \
        else None
    if dims is None:
        raise ValueError(f"shape must have 3 entries, got {shape!r}")
    size = check_finite_vector("size", size, 3)
    if np.any(size <= 0.0):
        raise ValueError(f"size must be > 0 along every axis, got {size.tolist()}")
    origin = check_finite_vector("origin", origin, 3)
    cells = np.stack(np.meshgrid(*[np.arange(d) for d in dims], indexing="ij"), -1).reshape(-1, 3)
    positions, tets, _ = lattice_tets(cells, np.zeros(3), 1.0)
    positions = origin + positions * (size / np.array(dims, dtype=np.float64))
    return TetMesh(positions, tets, None, float(np.prod(size)))


#: Smallest volume fraction a kept tetrahedron counts with (one that holds a vertex of the
#: surface but, cut at a corner, almost none of its interior).
MIN_FRACTION = 1e-3


def tets_from_mesh(points: ArrayLike, triangles: ArrayLike, *, spacing: float) -> TetMesh:
    """Tetrahedralise the interior of a closed mesh on a lattice and embed the mesh in it.

    Parameters
    ----------
    points : (M, 3) array_like
        Vertices (m) of a closed, consistently oriented triangle mesh.
    triangles : (T, 3) int array_like
        Its triangles.
    spacing : float
        Lattice cell edge (m), > 0.

    Returns
    -------
    TetMesh
        Six tetrahedra per lattice cell that holds some of the interior (every cell whose
        centre lies inside the mesh, of the mesh's vertices, or that the surface cuts), less
        those wholly outside; ``fractions`` is the part of each inside the mesh (at least
        :data:`MIN_FRACTION`); ``embedding`` places every mesh vertex in its tetrahedron with
        barycentric weights, exact at rest; ``volume`` is the mesh's, which the fractions'
        volumes add up to.

    Raises
    ------
    ValueError
        As :func:`filters.elastic.voxelize.voxelize_mesh`.
    """
    vox = voxelize_mesh(points, triangles, spacing)
    pts = np.asarray(points, dtype=np.float64)
    dims = vox.dims
    grid = np.zeros(tuple(int(d) for d in dims), dtype=np.bool_)
    grid[vox.cells[:, 0], vox.cells[:, 1], vox.cells[:, 2]] = True
    _mark_cut_cells(pts, vox.triangles, vox.origin, vox.spacing, grid)
    cells = np.argwhere(grid)  # lexicographic
    positions, tets, corners = lattice_tets(cells, vox.origin, vox.spacing)
    fractions = tet_fractions(positions, tets, pts, vox.triangles, vox.origin, vox.spacing, dims)
    # the cell of every vertex, as a row of ``cells`` (both in lexicographic order)
    cell_lin = (cells[:, 0] * dims[1] + cells[:, 1]) * dims[2] + cells[:, 2]
    vc = vox.vertex_cells
    vert_lin = (vc[:, 0] * dims[1] + vc[:, 1]) * dims[2] + vc[:, 2]
    rows = np.searchsorted(cell_lin, vert_lin)
    local = np.clip((pts - vox.origin) / vox.spacing - vc, 0.0, 1.0)
    which, weights = kuhn_locate(local)
    nodes = corners[rows][np.arange(rows.size)[:, None], KUHN_TETS[which]]
    # keep the tetrahedra with some interior, and those that hold a vertex
    keep = fractions > 1e-9
    keep[6 * rows + which] = True
    kept = tets[keep]
    used, inverse = np.unique(kept.ravel(), return_inverse=True)
    renumber = np.full(positions.shape[0], -1, dtype=np.int64)
    renumber[used] = np.arange(used.size)
    embedding = Embedding(np.ascontiguousarray(renumber[nodes]), weights,
                          check_triangles("triangles", vox.triangles, pts.shape[0]), pts.copy())
    return TetMesh(np.ascontiguousarray(positions[used]),
                   np.ascontiguousarray(inverse.reshape(-1, 4), dtype=np.int64), embedding,
                   vox.volume, np.maximum(fractions[keep], MIN_FRACTION))


@njit(cache=True)
def _mark_cut_cells(pts, tris, origin, spacing, grid):
    """Mark in ``grid`` (nx, ny, nz) every cell that the bounding box of a triangle meets."""
    dims = grid.shape
    for t in range(tris.shape[0]):
        lo = np.empty(3, np.int64)
        hi = np.empty(3, np.int64)
        for k in range(3):
            a = min(pts[tris[t, 0], k], pts[tris[t, 1], k], pts[tris[t, 2], k])
            b = max(pts[tris[t, 0], k], pts[tris[t, 1], k], pts[tris[t, 2], k])
            lo[k] = max(0, int(math.floor((a - origin[k]) / spacing)))
            hi[k] = min(dims[k] - 1, int(math.floor((b - origin[k]) / spacing)))
        for i in range(lo[0], hi[0] + 1):
            for j in range(lo[1], hi[1] + 1):
                for k in range(lo[2], hi[2] + 1):
                    grid[i, j, k] = True


#: The faces of a positively oriented tetrahedron ``(0, 1, 2, 3)``, each ordered so that its
#: normal points out of it.
OUTWARD_FACES = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]], dtype=np.int64)


def tets_from_arrays(points: ArrayLike, tets: ArrayLike, *, name: str = "mesh") -> TetMesh:
    """A user's tetrahedral mesh, simulated as it is: checked, and its boundary as its surface.

    Parameters
    ----------
    points : (N, 3) array_like
        Node positions (m).
    tets : (T, 4) int array_like
        Linear tetrahedra.  All of one orientation: a mesh written with the opposite
        convention (every tetrahedron negative) is reoriented; a mix means inverted elements.
    name : str
        The parameter the mesh came from, for messages.

    Returns
    -------
    TetMesh
        The nodes the tetrahedra use (unused ones dropped, the others renumbered in order),
        positively oriented tetrahedra, and as ``embedding`` the boundary faces (those of one
        tetrahedron only), oriented outward, over the boundary nodes (one node each, weight
        1): the surface that is drawn and touches colliders.  ``volume`` is the tetrahedra's.

    Raises
    ------
    ValueError
        Naming ``name``: a shape other than (T, 4), indices out of range, a flat (degenerate)
        tetrahedron, inverted ones, or several bodies (parts that share no node).
    """
    pts = check_points(f"{name} points", points)
    t = np.asarray(tets)
    if t.ndim != 2 or t.shape[1] != 4 or t.shape[0] == 0:
        raise ValueError(f"{name}: tetrahedra must be a non-empty (T, 4) array of node indices, "
                         f"got shape {t.shape}")
    if not np.issubdtype(t.dtype, np.integer):
        raise TypeError(f"{name}: tetrahedra must hold integers, got {t.dtype}")
    t = t.astype(np.int64)
    if t.min() < 0 or t.max() >= pts.shape[0]:
        raise ValueError(f"{name}: tetrahedra must index nodes in [0, {pts.shape[0] - 1}]")
    used, inverse = np.unique(t.ravel(), return_inverse=True)
    x = np.ascontiguousarray(pts[used])
    t = inverse.reshape(-1, 4).astype(np.int64)
    vol = tet_volumes(x, t)
    edges = x[t] - x[t[:, :1]]
    scale = np.abs(edges).max(axis=(1, 2))
    flat = ~(np.abs(vol) > 1e-9 * scale**3)
    if flat.any():
        i = int(np.flatnonzero(flat)[0])
        raise ValueError(f"{name}: {int(flat.sum())} of {len(t)} tetrahedra are flat "
                         f"(degenerate; the first, {i}, has volume {vol[i]:.3g} m^3)")
    negative = vol < 0.0
    if negative.all():  # the other orientation convention: reorient every one
        t = t[:, [0, 2, 1, 3]]
        vol = -vol
    elif negative.any():
        i = int(np.flatnonzero(negative)[0])
        raise ValueError(f"{name}: {int(negative.sum())} of {len(t)} tetrahedra are inverted "
                         f"(oriented against the rest; the first is {i})")
    bodies = _count_bodies(t, x.shape[0])
    if bodies > 1:
        raise ValueError(f"{name}: the mesh holds {bodies} separate bodies (parts that share no "
                         "node); give one body per simulation")
    faces = t[:, OUTWARD_FACES].reshape(-1, 3)
    key = np.sort(faces, axis=1)
    _, first, counts = np.unique(key, axis=0, return_index=True, return_counts=True)
    boundary = faces[np.sort(first[counts == 1])]
    nodes, tris = np.unique(boundary.ravel(), return_inverse=True)
    embedding = Embedding(nodes[:, None].astype(np.int64), np.ones((nodes.size, 1)),
                          tris.reshape(-1, 3).astype(np.int64), x[nodes].copy())
    return TetMesh(x, np.ascontiguousarray(t), embedding, float(vol.sum()))


def _count_bodies(tets, n):
    """Number of connected parts of tetrahedra ``tets`` over ``n`` nodes (sharing a node)."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    rows = np.repeat(tets[:, 0], 3)
    cols = tets[:, 1:].ravel()
    graph = sp.coo_matrix((np.ones(rows.size), (rows, cols)), shape=(n, n))
    return int(connected_components(graph, directed=False)[0])
