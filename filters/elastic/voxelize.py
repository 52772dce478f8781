"""Voxelising the interior of a closed triangle mesh on a cubic lattice.

:func:`voxelize_mesh` finds the lattice cells whose centres lie inside a closed, consistently
oriented mesh (parity of the crossings of a vertical ray through every cell centre), plus the
cells holding the mesh's vertices, so that every vertex can be embedded in an active cell.  The
spring jello (:func:`filters.elastic.topology.jello_from_mesh`) and the finite-element
tetrahedra (:func:`filters.elastic.tetmesh.tets_from_mesh`) are built on the same cells.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from ..memory import check_memory
from ..validation import check_points, check_range
from .surfaces import BYTES_PER_NODE, check_triangles, mesh_volume

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = ["Voxelization", "voxelize_mesh", "check_closed_manifold"]


def check_closed_manifold(tris: np.ndarray, n_points: int) -> None:
    """Raise ValueError unless the triangles ``tris`` (T, 3) over ``n_points`` vertices form a
    closed, consistently oriented 2-manifold (every edge in exactly two triangles, once in
    each direction)."""
    directed = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    dkeys = directed[:, 0] * n_points + directed[:, 1]
    if np.unique(dkeys).size != dkeys.size:
        raise ValueError("triangles are not a consistently oriented manifold: a directed edge "
                         "is used twice (flipped triangle or an edge shared by > 2 triangles)")
    und = np.sort(directed, axis=1)
    ukeys = und[:, 0] * n_points + und[:, 1]
    _, counts = np.unique(ukeys, return_counts=True)
    if np.any(counts != 2):
        raise ValueError("triangles must form a closed manifold: every edge must be shared by "
                         f"exactly two triangles ({int(np.sum(counts == 1))} boundary edges, "
                         f"{int(np.sum(counts > 2))} non-manifold edges)")


@njit(cache=True)
def _inside_parity(pts, tris, origin, h, dims, jitter):
    """Parity of +z ray crossings from every voxel centre (nx, ny, nz) uint8."""
    nx, ny, nz = dims[0], dims[1], dims[2]
    parity = np.zeros((nx, ny, nz), dtype=np.uint8)
    for t in range(tris.shape[0]):
        a = pts[tris[t, 0]]
        b = pts[tris[t, 1]]
        c = pts[tris[t, 2]]
        xmin = min(a[0], b[0], c[0])
        xmax = max(a[0], b[0], c[0])
        ymin = min(a[1], b[1], c[1])
        ymax = max(a[1], b[1], c[1])
        i0 = max(0, int(math.floor((xmin - origin[0]) / h - 0.5)))
        i1 = min(nx - 1, int(math.ceil((xmax - origin[0]) / h - 0.5)))
        j0 = max(0, int(math.floor((ymin - origin[1]) / h - 0.5)))
        j1 = min(ny - 1, int(math.ceil((ymax - origin[1]) / h - 0.5)))
        det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])
        if det == 0.0:
            continue
        for i in range(i0, i1 + 1):
            px = origin[0] + (i + 0.5) * h + jitter[0]
            for j in range(j0, j1 + 1):
                py = origin[1] + (j + 0.5) * h + jitter[1]
                l1 = ((b[0] - px) * (c[1] - py) - (c[0] - px) * (b[1] - py)) / det
                l2 = ((c[0] - px) * (a[1] - py) - (a[0] - px) * (c[1] - py)) / det
                l3 = 1.0 - l1 - l2
                if l1 < 0.0 or l2 < 0.0 or l3 < 0.0:
                    continue
                zhit = l1 * a[2] + l2 * b[2] + l3 * c[2]
                for k in range(nz):
                    if origin[2] + (k + 0.5) * h < zhit:
                        parity[i, j, k] ^= 1
    return parity


@dataclass(frozen=True)
class Voxelization:
    """The lattice cells that hold the interior of a closed mesh (:func:`voxelize_mesh`).

    Attributes
    ----------
    origin : (3,) float64
        Position (m) of lattice node ``(0, 0, 0)``; cell ``(i, j, k)`` spans
        ``origin + [i, i + 1] x [j, j + 1] x [k, k + 1] * spacing``.
    spacing : float
        Cell edge (m).
    dims : (3,) int64
        Cells of the lattice's box along x, y, z.
    cells : (C, 3) int64
        The active cells, in lexicographic order of ``(i, j, k)``.
    vertex_cells : (M, 3) int64
        The cell of every mesh vertex (all active).
    triangles : (T, 3) int64
        The mesh's triangles, oriented outward (positive volume).
    volume : float
        Volume (m^3) the mesh encloses.
    """

    origin: np.ndarray
    spacing: float
    dims: np.ndarray
    cells: np.ndarray
    vertex_cells: np.ndarray
    triangles: np.ndarray
    volume: float


def voxelize_mesh(points: ArrayLike, triangles: ArrayLike, spacing: float) -> Voxelization:
    """The cells of a cubic lattice whose centres lie inside a closed mesh, plus the cells of its
    vertices (so that every vertex can be embedded in an active cell).

    Inside is decided per cell centre by the parity of crossings of a vertical ray (jittered by
    ~1e-7 spacing off the lattice so that it never hits an edge exactly).

    Parameters
    ----------
    points : (M, 3) array_like
        Mesh vertices (m).
    triangles : (T, 3) int array_like
        Triangles of a closed, consistently oriented 2-manifold.
    spacing : float
        Cell edge (m), > 0.

    Returns
    -------
    Voxelization

    Raises
    ------
    ValueError
        If the mesh is not a closed consistently oriented manifold, encloses no volume, no cell
        centre lies inside it, or the lattice would not fit in memory.
    """
    pts = check_points("points", points)
    tris = check_triangles("triangles", triangles, pts.shape[0])
    spacing = check_range("spacing", spacing, 0.0, math.inf, low_inclusive=False)
    check_closed_manifold(tris, pts.shape[0])
    volume = mesh_volume(pts, tris)
    lo = pts.min(axis=0)
    hi = pts.max(axis=0)
    diag = float(np.linalg.norm(hi - lo))
    if abs(volume) <= 1e-9 * diag ** 3 or diag == 0.0:
        raise ValueError("the mesh encloses no volume (flat or degenerate): an elastic solid "
                         "needs an interior")
    if volume < 0.0:  # inward normals: flip so that the volume is positive
        tris = tris[:, ::-1].copy()
        volume = -volume
    origin = lo - 0.25 * spacing
    dims_f = np.maximum(np.ceil((hi + 0.25 * spacing - origin) / spacing), 1.0)
    # the lattice's box bounds its nodes; the parity grid holds one byte per cell
    check_memory(f"a lattice of {dims_f[0]:.0f} x {dims_f[1]:.0f} x {dims_f[2]:.0f} cells "
                 f"at spacing = {spacing:g} m", float(np.prod(dims_f + 1.0)) * BYTES_PER_NODE,
                 "increase spacing")
    dims = dims_f.astype(np.int64)
    jitter = np.array([1.234567e-7, 2.345678e-7]) * spacing
    parity = _inside_parity(pts, tris, origin, spacing, dims, jitter)
    active = parity.astype(bool)
    if not active.any():
        raise ValueError(f"no lattice cell centre lies inside the mesh at spacing = {spacing:g} m; "
                         "use a smaller spacing")
    cell = np.clip(np.floor((pts - origin) / spacing).astype(np.int64), 0, dims - 1)
    active[cell[:, 0], cell[:, 1], cell[:, 2]] = True
    cells = np.argwhere(active)  # (C, 3)
    return Voxelization(origin, float(spacing), dims, cells, cell, tris, float(volume))
