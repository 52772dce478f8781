"""Closed triangle surfaces as the elastic builders take them: the triangle check, the enclosed
volume, and the memory a lattice node costs (shared by :mod:`filters.elastic.topology`,
:mod:`filters.elastic.voxelize` and :mod:`filters.elastic.tetmesh`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

__all__ = ["BYTES_PER_NODE", "check_triangles", "mesh_volume"]

#: Memory per particle of a spring simulation (bytes), for the up-front check: measured 1.9 KiB
#: per node on 325,000 hair nodes (positions, springs, the implicit solver's blocks, one frame
#: and its XDMF export), rounded up.
BYTES_PER_NODE = 2048


def check_triangles(name: str, triangles: ArrayLike, n_points: int, *, allow_empty: bool = False,
                    allow_degenerate: bool = False) -> NDArray[np.int64]:
    """Return ``triangles`` as a (T, 3) int64 array indexing ``n_points`` points, or raise.

    ``allow_empty`` accepts T = 0 (an empty surface); ``allow_degenerate`` accepts triangles
    with a repeated vertex (marching cubes can produce them)."""
    tris = np.asarray(triangles)
    if tris.ndim != 2 or tris.shape[1] != 3 or (tris.shape[0] == 0 and not allow_empty):
        raise ValueError(f"{name} must be a {'' if allow_empty else 'non-empty '}(T, 3) array of "
                         f"vertex indices, got shape {tris.shape}")
    if tris.size == 0:
        return np.zeros((0, 3), np.int64)
    if not np.issubdtype(tris.dtype, np.integer):
        raise TypeError(f"{name} must hold integers, got {tris.dtype}")
    tris = tris.astype(np.int64)
    if tris.min() < 0 or tris.max() >= n_points:
        raise ValueError(f"{name} must index vertices in [0, {n_points - 1}]")
    if not allow_degenerate and np.any((tris[:, 0] == tris[:, 1]) | (tris[:, 1] == tris[:, 2])
                                       | (tris[:, 0] == tris[:, 2])):
        raise ValueError(f"{name} contains degenerate triangles (a repeated vertex)")
    return tris


def mesh_volume(points: ArrayLike, triangles: ArrayLike) -> float:
    """Signed volume (m^3) enclosed by a closed triangle mesh (positive for outward normals)."""
    p = np.asarray(points, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64)
    return float(np.einsum("ij,ij->i", p[t[:, 0]], np.cross(p[t[:, 1]], p[t[:, 2]])).sum() / 6.0)
