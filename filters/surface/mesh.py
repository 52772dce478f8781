"""Triangle-mesh utilities on arrays: stitching coincident points and checking watertightness.

Used to stitch the pieces contoured from the bricks of a :class:`filters.surface.grid.SparseGrid`
(their shared vertices are bitwise equal, so they are merged by exact coordinates) and to
measure meshes in tests and benchmarks (area, enclosed volume, closed, manifold, Euler
characteristic, connected components).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from ..binning import EMPTY_KEY, probe

if TYPE_CHECKING:
    from numpy.typing import NDArray

__all__ = ["merge_coincident", "piece_flags", "stitch", "MeshStats", "mesh_stats"]


@njit(cache=True)
def _merge(bits):
    n = bits.shape[0]
    capacity = 1024
    while capacity < 2 * n:
        capacity *= 2
    table = np.full(capacity, EMPTY_KEY, np.int64)
    slot_to_new = np.empty(capacity, np.int64)
    remap = np.empty(n, np.int64)
    first = np.empty(n, np.int64)
    count = 0
    for p in range(n):
        key = ((bits[p, 0] * 73856093) ^ (bits[p, 1] * 19349663)
               ^ (bits[p, 2] * 83492791)) & 0x3FFFFFFFFFFFFFFF
        i = probe(table, key)
        # resolve hash collisions by comparing the coordinates themselves
        mask = capacity - 1
        while table[i] != EMPTY_KEY:
            q = first[slot_to_new[i]]
            if table[i] == key and bits[q, 0] == bits[p, 0] and bits[q, 1] == bits[p, 1] \
                    and bits[q, 2] == bits[p, 2]:
                break
            i = (i + 1) & mask
        if table[i] == EMPTY_KEY:
            table[i] = key
            slot_to_new[i] = count
            first[count] = p
            count += 1
        remap[p] = slot_to_new[i]
    return remap, first[:count].copy()


def merge_coincident(points: np.ndarray,
                     triangles: np.ndarray) -> tuple[np.ndarray, NDArray[np.int64]]:
    """Merge points with bitwise equal coordinates and drop triangles that collapse.

    Parameters
    ----------
    points : (P, 3) float array
    triangles : (T, 3) int array

    Returns
    -------
    points : (P', 3)
        The distinct points, in order of first appearance.
    triangles : (T', 3) int64
        Re-indexed triangles with three distinct vertices.
    """
    points = np.ascontiguousarray(points)
    if points.shape[0] == 0:
        return points.copy(), np.zeros((0, 3), np.int64)
    view = points.view(np.int32 if points.dtype == np.float32 else np.int64).astype(np.int64)
    remap, first = _merge(view)
    tris = remap[np.asarray(triangles, dtype=np.int64)]
    ok = (tris[:, 0] != tris[:, 1]) & (tris[:, 1] != tris[:, 2]) & (tris[:, 0] != tris[:, 2])
    return points[first], np.ascontiguousarray(tris[ok])


@dataclass
class MeshStats:
    """Measures of a triangle mesh.

    Attributes
    ----------
    points, triangles : int
        Counts (points referenced by triangles only).
    area : float
        Total area (m^2).
    volume : float
        Enclosed volume by the divergence theorem (m^3); meaningful when ``closed``.
    closed : bool
        Every edge is shared by exactly two triangles.
    manifold : bool
        Edge-manifold with consistent orientation (each directed edge once) and vertex-manifold
        (the triangles around each vertex form one fan).
    euler : int
        Euler characteristic ``V - E + F``.
    components : int
        Connected components.
    """

    points: int
    triangles: int
    area: float
    volume: float
    closed: bool
    manifold: bool
    euler: int
    components: int


@njit(cache=True)
def _vertex_fans_ok(tris, nverts):
    """True if the link of every vertex is a single cycle (closed, oriented meshes)."""
    t = tris.shape[0]
    count = np.zeros(nverts + 1, np.int64)
    for f in range(t):
        for c in range(3):
            count[tris[f, c] + 1] += 1
    for v in range(nverts):
        count[v + 1] += count[v]
    fill = count[:-1].copy()
    a = np.empty(3 * t, np.int64)
    b = np.empty(3 * t, np.int64)
    for f in range(t):
        for c in range(3):
            v = tris[f, c]
            a[fill[v]] = tris[f, (c + 1) % 3]
            b[fill[v]] = tris[f, (c + 2) % 3]
            fill[v] += 1
    for v in range(nverts):
        s = count[v]
        e = count[v + 1]
        if e == s:
            continue
        # follow a -> b around the fan
        cur = a[s]
        steps = 0
        while True:
            found = -1
            for k in range(s, e):
                if a[k] == cur:
                    found = k
                    break
            if found < 0:
                return False
            cur = b[found]
            steps += 1
            if cur == a[s] or steps > e - s:
                break
        if steps != e - s:
            return False
    return True


@njit(cache=True)
def _components(tris, nverts):
    parent = np.arange(nverts)
    for f in range(tris.shape[0]):
        for c in range(1, 3):
            x = tris[f, 0]
            while parent[x] != x:
                parent[x] = parent[parent[x]]
                x = parent[x]
            y = tris[f, c]
            while parent[y] != y:
                parent[y] = parent[parent[y]]
                y = parent[y]
            if x != y:
                parent[max(x, y)] = min(x, y)
    used = np.zeros(nverts, np.bool_)
    for f in range(tris.shape[0]):
        for c in range(3):
            used[tris[f, c]] = True
    roots = 0
    for v in range(nverts):
        if used[v]:
            x = v
            while parent[x] != x:
                x = parent[x]
            if x == v:
                roots += 1
    return roots


def mesh_stats(points: np.ndarray, triangles: np.ndarray) -> MeshStats:
    """Area, volume, closedness, manifoldness, Euler characteristic and components of a mesh.

    Parameters
    ----------
    points : (P, 3) float array
        Vertex positions (m).
    triangles : (T, 3) int array
        Vertex indices.

    Returns
    -------
    MeshStats
    """
    pts = np.asarray(points, dtype=np.float64)
    tris = np.ascontiguousarray(triangles, dtype=np.int64)
    if tris.shape[0] == 0:
        return MeshStats(0, 0, 0.0, 0.0, True, True, 0, 0)
    p0, p1, p2 = pts[tris[:, 0]], pts[tris[:, 1]], pts[tris[:, 2]]
    cross = np.cross(p1 - p0, p2 - p0)
    area = 0.5 * float(np.linalg.norm(cross, axis=1).sum())
    volume = float(np.einsum("ij,ij->", p0, np.cross(p1, p2))) / 6.0
    nv = pts.shape[0]
    directed = np.stack([tris, np.roll(tris, -1, axis=1)], axis=-1).reshape(-1, 2)
    dkeys = directed[:, 0] * nv + directed[:, 1]
    ukeys = (np.minimum(directed[:, 0], directed[:, 1]) * nv
             + np.maximum(directed[:, 0], directed[:, 1]))
    _, ucount = np.unique(ukeys, return_counts=True)
    closed = bool((ucount == 2).all())
    oriented = np.unique(dkeys).size == dkeys.size
    manifold = closed and oriented and bool(_vertex_fans_ok(tris, nv))
    used = np.unique(tris).size
    euler = int(used - ucount.size + tris.shape[0])
    return MeshStats(points=int(used), triangles=int(tris.shape[0]), area=area, volume=volume,
                     closed=closed, manifold=manifold, euler=euler,
                     components=int(_components(tris, nv)))


@njit(cache=True)
def _stitch(bits, flags, tris):
    """Merge the flagged points with bitwise equal coordinates; remap ``tris`` in place.

    The kept points (first occurrences, in order) are moved to the front of ``bits`` and the
    triangles still with three distinct vertices to the front of ``tris``, both in place (no
    copy of a mesh that may hold tens of millions of vertices). Returns the numbers of points
    and triangles kept."""
    n = bits.shape[0]
    nflag = 0
    for p in range(n):
        if flags[p]:
            nflag += 1
    capacity = 1024
    while capacity < 2 * nflag:
        capacity *= 2
    table = np.full(capacity, EMPTY_KEY, np.int64)
    slot_point = np.empty(capacity, np.int64)  # the kept point's new index (its row is final)
    mask = capacity - 1
    remap = np.empty(n, np.int64)
    count = 0
    for p in range(n):
        # rows below ``count`` are final; row p (>= count) is not yet overwritten
        b0 = bits[p, 0]
        b1 = bits[p, 1]
        b2 = bits[p, 2]
        if flags[p]:
            key = ((b0 * 73856093) ^ (b1 * 19349663) ^ (b2 * 83492791)) & 0x3FFFFFFFFFFFFFFF
            i = probe(table, key)
            found = -1
            while table[i] != EMPTY_KEY:
                q = slot_point[i]
                if table[i] == key and bits[q, 0] == b0 and bits[q, 1] == b1 and bits[q, 2] == b2:
                    found = q
                    break
                i = (i + 1) & mask
            if found >= 0:
                remap[p] = found
                continue
            table[i] = key
            slot_point[i] = count
        remap[p] = count
        bits[count, 0] = b0
        bits[count, 1] = b1
        bits[count, 2] = b2
        count += 1
    kept = 0
    for t in range(tris.shape[0]):
        a = remap[tris[t, 0]]
        b = remap[tris[t, 1]]
        c = remap[tris[t, 2]]
        if a != b and b != c and a != c:
            # reversed (a, c, b): see pipeline.surface, flying edges orients inward
            tris[kept, 0] = a
            tris[kept, 1] = c
            tris[kept, 2] = b
            kept += 1
    return count, kept


@njit(cache=True)
def piece_flags(points, starts, lo, hi):
    """Flag the vertices that may have twins: on a boundary plane of their piece (``lo`` or
    ``hi``, per piece, index units) or with all coordinates integral (a voxel on the iso value).

    Parameters
    ----------
    points : (P, 3) float32
    starts : (K + 1,) int64
        Piece ``k`` owns points ``starts[k]:starts[k + 1]``.
    lo, hi : (K, 3) float32

    Returns
    -------
    (P,) bool
    """
    flags = np.zeros(points.shape[0], np.bool_)
    for k in range(starts.size - 1):
        for p in range(starts[k], starts[k + 1]):
            on_plane = False
            integral = True
            for a in range(3):
                v = points[p, a]
                if v == lo[k, a] or v == hi[k, a]:
                    on_plane = True
                if v != np.floor(v):
                    integral = False
            flags[p] = on_plane or integral
    return flags


def stitch(points: np.ndarray, triangles: np.ndarray, flags: np.ndarray, *,
           reverse: bool = True) -> tuple[NDArray[np.float32], np.ndarray]:
    """Merge points that may be duplicated (``flags``) by exact coordinates, in place.

    Both inputs are overwritten: the merged points are compacted to the front of ``points``
    (which must be C-contiguous float32 to be worked on in place) and the triangles to the front
    of ``triangles``; the results are views of those fronts.

    Parameters
    ----------
    points : (P, 3) float32
        Vertices (pieces concatenated).
    triangles : (T, 3) int32 or int64
        Vertex indices; overwritten with the merged indices (orientation reversed when
        ``reverse``).
    flags : (P,) bool
        Points that may have bitwise equal twins (on the faces shared between pieces).

    Returns
    -------
    points : (P', 3) float32
        A view of the front of ``points`` (when it was C-contiguous float32).
    triangles : (T', 3)
        A view of the front of the input ``triangles``.
    """
    points = np.ascontiguousarray(points, dtype=np.float32)
    if points.shape[0] == 0:
        return points, triangles[:0]
    bits = points.view(np.int32)
    count, kept = _stitch(bits, np.ascontiguousarray(flags), triangles)
    tris = triangles[:kept]
    if not reverse:
        tris[:, [1, 2]] = tris[:, [2, 1]]
    return points[:count], tris
