"""Offsets between surfaces along vertex normals, and surfaces smoothed across frames.

A liquid surface reconstructed frame by frame moves, between two frames, by what the liquid's
motion explains plus what the reconstruction adds (flattening, volume correction, sampling).
The second part can be averaged over neighbouring frames once every surface is carried to
the same instant by the liquid's motion: for a vertex ``v`` of frame ``k`` with normal ``n``,
let ``v_j`` be ``v`` moved with the particles to frame ``k + j`` and ``t_j`` the signed distance
along ``n`` from ``v_j`` to frame ``k + j``'s surface; the smoothed vertex is

    ``v + n * o``, ``o = sum_j w_j t_j / sum_j w_j``  (``t_0 = 0``; terms with no crossing
    within ``reach`` left out: a drop merging or splitting is not smeared over frames),

with the offsets ``o`` smoothed over the mesh first (a few averaging sweeps over each vertex's
edge neighbours): the particles' displacements vary from particle to particle, and offsets
taken vertex by vertex would print that noise on the surface.

This is the motion-compensated temporal filter of a level set (the surfaces' zero sets
averaged along the flow; e.g. Bhattacharya, Gao & Bargteil 2011 smooth a particle level set
in time), applied to a mesh: the topology of frame ``k`` is kept and each vertex moves along
its own normal only. Static surfaces are left where they are (every ``t_j`` is zero), and a
rigid motion that the displacements describe leaves them unchanged too.

:func:`normal_offsets` does the search: every triangle of the other surface is listed in the
cells of a uniform grid (cells ``2 reach`` wide) that its bounding box overlaps, and every
point casts its segment ``v + t n, |t| <= reach`` against the triangles of the cells the
segment's box overlaps (Möller & Trumbore 1997), keeping the crossing of least ``|t|``;
points are independent (parallel, no races).
Measurements behind it: ``benchmarks/results/splash_motion_notes.md``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..binning import MAX_CELLS, counting_sort
from ..elastic.topology import check_triangles
from ..validation import check_int, check_points, check_range
from .attributes import interpolate_attributes
from .clip import wall_constraints
from .smoothing import vertex_neighbors

__all__ = ["normal_offsets", "smooth_across_frames", "follow_particles_across_frames",
           "vertex_normals"]

#: Barycentric slack of a crossing (relative): a line through an edge shared by two triangles
#: finds one of them rather than slipping between them.
EDGE_SLACK = 1e-9

#: Cell width of the triangle grid over the search reach.
CELL_OVER_REACH = 2.0


@njit(cache=True)
def _triangle_cells(V, T, origin, cell, dims):
    """Every (cell, triangle) pair of a triangle and a cell its bounding box overlaps.

    Triangles are binned by their boxes, not their centroids: the cut faces on a tank's walls
    are a few large fans, and a centroid grid would need cells as wide as they are."""
    nx, ny = dims[0], dims[1]
    box = np.empty((T.shape[0], 6), np.int64)
    total = 0
    for f in range(T.shape[0]):
        for axis in range(3):
            box[f, 2 * axis], box[f, 2 * axis + 1] = _cell_range(V, T, f, axis, origin, cell,
                                                                 dims[axis])
        total += ((box[f, 1] - box[f, 0] + 1) * (box[f, 3] - box[f, 2] + 1)
                  * (box[f, 5] - box[f, 4] + 1))
    keys = np.empty(total, np.int64)
    owner = np.empty(total, np.int64)
    k = 0
    for f in range(T.shape[0]):
        for z in range(box[f, 4], box[f, 5] + 1):
            for y in range(box[f, 2], box[f, 3] + 1):
                for x in range(box[f, 0], box[f, 1] + 1):
                    keys[k] = (z * ny + y) * nx + x
                    owner[k] = f
                    k += 1
    return keys, owner


@njit(cache=True, inline="always")
def _cell_range(V, T, f, axis, origin, cell, n):
    a = min(V[T[f, 0], axis], V[T[f, 1], axis], V[T[f, 2], axis])
    b = max(V[T[f, 0], axis], V[T[f, 1], axis], V[T[f, 2], axis])
    lo = int(min(max(math.floor((a - origin[axis]) / cell), 0.0), n - 1.0))
    hi = int(min(max(math.floor((b - origin[axis]) / cell), 0.0), n - 1.0))
    return lo, hi


@njit(cache=True, inline="always")
def _cells_along(p, d, i, axis, reach, origin, cell, n):
    """The cells along ``axis`` that the segment ``p[i] + t d[i]``, ``|t| <= reach``, touches
    (an empty range when it misses the grid)."""
    a = (p[i, axis] - reach * abs(d[i, axis]) - origin[axis]) / cell
    b = (p[i, axis] + reach * abs(d[i, axis]) - origin[axis]) / cell
    if b < 0.0 or a >= n:
        return 0, -1
    return int(max(math.floor(a), 0.0)), int(min(math.floor(b), n - 1.0))


@njit(parallel=True, cache=True)
def _offsets(p, d, start, items, origin, cell, dims, V, T, reach, out):
    nx, ny, nz = dims[0], dims[1], dims[2]
    for i in prange(p.shape[0]):
        x0, x1 = _cells_along(p, d, i, 0, reach, origin, cell, nx)
        y0, y1 = _cells_along(p, d, i, 1, reach, origin, cell, ny)
        z0, z1 = _cells_along(p, d, i, 2, reach, origin, cell, nz)
        best = np.nan
        best_abs = math.inf
        for z in range(z0, z1 + 1):
            for y in range(y0, y1 + 1):
                for x in range(x0, x1 + 1):
                    c = (z * ny + y) * nx + x
                    for k in range(start[c], start[c + 1]):
                        t = _crossing(p, d, i, V, T, items[k])
                        if abs(t) <= reach and abs(t) < best_abs:
                            best_abs = abs(t)
                            best = t
        out[i] = best


@njit(cache=True, inline="always")
def _crossing(p, d, i, V, T, f):
    """``t`` where the line ``p[i] + t d[i]`` crosses triangle ``f`` (Möller & Trumbore 1997,
    both sides), or infinity."""
    a = T[f, 0]
    e1x = V[T[f, 1], 0] - V[a, 0]
    e1y = V[T[f, 1], 1] - V[a, 1]
    e1z = V[T[f, 1], 2] - V[a, 2]
    e2x = V[T[f, 2], 0] - V[a, 0]
    e2y = V[T[f, 2], 1] - V[a, 1]
    e2z = V[T[f, 2], 2] - V[a, 2]
    qx = d[i, 1] * e2z - d[i, 2] * e2y
    qy = d[i, 2] * e2x - d[i, 0] * e2z
    qz = d[i, 0] * e2y - d[i, 1] * e2x
    det = e1x * qx + e1y * qy + e1z * qz
    if det == 0.0:
        return math.inf
    inv = 1.0 / det
    sx = p[i, 0] - V[a, 0]
    sy = p[i, 1] - V[a, 1]
    sz = p[i, 2] - V[a, 2]
    u = (sx * qx + sy * qy + sz * qz) * inv
    if u < -EDGE_SLACK or u > 1.0 + EDGE_SLACK:
        return math.inf
    rx = sy * e1z - sz * e1y
    ry = sz * e1x - sx * e1z
    rz = sx * e1y - sy * e1x
    v = (d[i, 0] * rx + d[i, 1] * ry + d[i, 2] * rz) * inv
    if v < -EDGE_SLACK or u + v > 1.0 + EDGE_SLACK:
        return math.inf
    return (e2x * rx + e2y * ry + e2z * rz) * inv


def normal_offsets(points, directions, vertices, triangles, reach: float):
    """Signed distance along ``directions`` from every point to a triangle mesh, within ``reach``.

    Parameters
    ----------
    points : (P, 3) float64
        Line origins (m).
    directions : (P, 3) float64
        Unit directions (e.g. vertex normals); the distances are in units of their length.
    vertices : (V, 3) float64
        The other mesh's vertices (m).
    triangles : (T, 3) int
        The other mesh's triangles.
    reach : float
        Largest ``|t|`` searched (m), > 0.

    Returns
    -------
    (P,) float64
        ``t`` of the crossing ``points + t directions`` of least ``|t|`` (positive along the
        direction), NaN where the line crosses no triangle within ``reach``.

    Raises
    ------
    ValueError
        For points or directions of different shapes, non-finite values, triangles that do not
        index the vertices, or ``reach <= 0``.
    """
    p = check_points("points", points)
    d = check_points("directions", directions)
    if d.shape != p.shape:
        raise ValueError(f"directions must have the shape of points {p.shape}, got {d.shape}")
    V = check_points("vertices", vertices)
    T = np.ascontiguousarray(check_triangles("triangles", triangles, V.shape[0],
                                             allow_empty=True, allow_degenerate=True),
                             dtype=np.int64)
    reach = check_range("reach", reach, 0.0, math.inf, low_inclusive=False)
    out = np.full(p.shape[0], np.nan)
    if p.shape[0] == 0 or T.shape[0] == 0:
        return out
    # cells twice as wide as the search (a segment's box overlaps at most 2 x 2 x 2 of them),
    # wider where that would make more than MAX_CELLS
    lo = V.min(axis=0) - reach
    size = V.max(axis=0) + reach - lo
    cell = CELL_OVER_REACH * reach
    while np.prod(np.floor(size / cell) + 1.0) > MAX_CELLS:
        cell *= 1.5
    dims = (np.floor(size / cell) + 1.0).astype(np.int64)
    keys, owner = _triangle_cells(V, T, lo, cell, dims)
    start, order = counting_sort(keys, int(np.prod(dims)), 1)
    items = owner[order]
    _offsets(p, d, start, items, lo, cell, dims, V, T, reach, out)
    return out


def smooth_across_frames(points, triangles, others, weights, reach: float, *, normals=None,
                         sweeps: int = 10, fixed=None):
    """Vertices of one frame's surface moved along their normals toward neighbouring frames'.

    Parameters
    ----------
    points : (P, 3) float64
        Vertices of frame ``k``'s surface (m).
    triangles : (T, 3) int
        Its triangles.
    others : sequence of ((P, 3) float64, (V, 3) float64, (T, 3) int)
        Per neighbouring frame ``k + j``: ``points`` moved with the liquid to that frame, and
        that frame's surface (vertices, triangles).
    weights : sequence of float
        ``w_0`` (frame ``k`` itself) then one weight per entry of ``others``; all >= 0,
        ``w_0 > 0``.
    reach : float
        Largest offset taken from a neighbour (m), > 0; farther crossings (a merge, a split, a
        drop leaving) are left out and the remaining weights renormalised.
    normals : (P, 3) float64, optional
        Unit vertex normals; default :func:`vertex_normals`.
    sweeps : int
        Sweeps of smoothing of the offsets over the mesh, in [0, 1000], each ``o <- (o + mean
        of the edge neighbours' o) / 2``: the particles' displacements vary from particle to
        particle, and offsets taken vertex by vertex would print that noise on the surface
        (without them the ``drop`` scene's surface looks crumpled; see
        ``benchmarks/results/splash_motion_notes.md``).
    fixed : (P,) bool, optional
        Vertices that do not move (e.g. those on a tank's walls); their offsets are held at
        zero through the sweeps.

    Returns
    -------
    (P, 3) float64
        ``points + normals * o``, ``o`` the smoothed ``sum_j w_j t_j / sum_j w_j`` over the
        frames with a crossing (:func:`normal_offsets`; ``t_0 = 0``).
    """
    p = check_points("points", points)
    t = check_triangles("triangles", triangles, p.shape[0], allow_empty=True,
                        allow_degenerate=True)
    n = vertex_normals(p, t) if normals is None else check_points("normals", normals)
    if n.shape != p.shape:
        raise ValueError(f"normals must have the shape of points {p.shape}, got {n.shape}")
    reach = check_range("reach", reach, 0.0, math.inf, low_inclusive=False)
    sweeps = check_int("sweeps", sweeps, 0, 1000)
    hold = np.zeros(p.shape[0], bool) if fixed is None else np.asarray(fixed, bool)
    if hold.shape != (p.shape[0],):
        raise ValueError(f"fixed must have shape ({p.shape[0]},), got {hold.shape}")
    others = list(others)
    w = np.asarray(weights, dtype=np.float64).reshape(-1)
    if w.size != len(others) + 1:
        raise ValueError(f"weights must have {len(others) + 1} entries (frame k, then one per "
                         f"neighbouring frame), got {w.size}")
    if not (np.isfinite(w).all() and w.min() >= 0.0 and w[0] > 0.0):
        raise ValueError(f"weights must be finite and >= 0, the first > 0, got {w.tolist()}")
    total = np.full(p.shape[0], w[0])
    shift = np.zeros(p.shape[0])
    for (moved, vertices, other_triangles), wj in zip(others, w[1:]):
        moved = check_points("others[j][0]", moved)
        if moved.shape != p.shape:
            raise ValueError(f"moved points must have the shape of points {p.shape}, got "
                             f"{moved.shape}")
        found = normal_offsets(moved, n, vertices, other_triangles, reach)
        ok = np.isfinite(found)
        shift[ok] += wj * found[ok]
        total[ok] += wj
    offset = np.where(hold, 0.0, shift / total)
    if sweeps and p.shape[0]:
        starts, neighbors = vertex_neighbors(t, p.shape[0])
        offset = _smooth_offsets(offset, starts, neighbors, hold, sweeps)
    return p + offset[:, None] * n


def follow_particles_across_frames(points, triangles, positions, neighbours, weights,
                                  radius: float, *, cell_size: float | None = None, box=None,
                                  reach_r: float = 1.0, sweeps: int = 10):
    """:func:`smooth_across_frames` with the vertices carried to the other frames by particles.

    Parameters
    ----------
    points : (P, 3) float64
        Vertices of frame ``k``'s surface (m).
    triangles : (T, 3) int
        Its triangles.
    positions : (N, 3) float64
        Frame ``k``'s particles (m).
    neighbours : sequence of ((M,) int, (M, 3) float64, (V, 3) float64, (T', 3) int)
        Per neighbouring frame ``k + j``: the rows of ``positions`` of the particles it has too,
        where they are in it, and its surface (vertices, triangles). The vertices move by the
        particles' displacement interpolated at them (Shepard weights of the SPH kernel,
        :func:`filters.surface.attributes.interpolate_attributes`).
    weights : sequence of float
        ``w_0`` (frame ``k``), then one per neighbour (see :func:`smooth_across_frames`).
    radius : float
        Particle radius ``r`` (m), > 0.
    cell_size : float, optional
        Voxel edge of the interpolation's block index (m); default ``r / 2``.
    box : (lower, upper), optional
        The tank's inner box (m): vertices on its walls are held, the result kept inside it.
    reach_r : float
        Largest offset taken from a neighbour, over ``r`` (default 1: half a spacing), > 0.
    sweeps : int
        Smoothing sweeps of the offsets (:func:`smooth_across_frames`).

    Returns
    -------
    (P, 3) float64
    """
    p = check_points("points", points)
    x = check_points("positions", positions)
    radius = check_range("radius", radius, 0.0, math.inf, low_inclusive=False)
    reach_r = check_range("reach_r", reach_r, 0.0, math.inf, low_inclusive=False)
    cell_size = 0.5 * radius if cell_size is None else check_range(
        "cell_size", cell_size, 0.0, math.inf, low_inclusive=False)
    neighbours = [(np.asarray(rows, np.int64), where, vertices, other_triangles)
                  for rows, where, vertices, other_triangles in neighbours]
    moved = [None] * len(neighbours)
    pending = list(range(len(neighbours)))
    while pending:
        # the neighbours that share their particles share the Shepard weights at the vertices:
        # one interpolation of their displacements side by side (the same numbers, bit for bit)
        rows = neighbours[pending[0]][0]
        same = [j for j in pending if np.array_equal(neighbours[j][0], rows)]
        u = interpolate_attributes(p, x[rows], radius,
                                   np.hstack([np.asarray(neighbours[j][1], np.float64) - x[rows]
                                              for j in same]), cell_size=cell_size)
        for c, j in enumerate(same):
            moved[j] = p + u[:, 3 * c:3 * c + 3]
        pending = [j for j in pending if j not in same]
    others = [(m, vertices, other_triangles)
              for m, (_, _, vertices, other_triangles) in zip(moved, neighbours)]
    fixed = None
    if box is not None:
        lower, upper = (np.asarray(b, np.float64) for b in box)
        # the faces cut at the tank's walls stay on them
        fixed = wall_constraints(p, triangles, lower, upper)[0].min(axis=1) < 1.0
    out = smooth_across_frames(p, triangles, others, weights, reach_r * radius, fixed=fixed,
                               sweeps=sweeps)
    return out if box is None else np.clip(out, lower, upper)


@njit(cache=True)
def _smooth_offsets(offset, starts, neighbors, hold, sweeps):
    a = offset.copy()
    b = np.empty_like(a)
    for _ in range(sweeps):
        for v in range(a.shape[0]):
            m = starts[v + 1] - starts[v]
            if hold[v] or m == 0:
                b[v] = a[v]
                continue
            s = 0.0
            for k in range(starts[v], starts[v + 1]):
                s += a[neighbors[k]]
            b[v] = 0.5 * (a[v] + s / m)
        a, b = b, a
    return a


def vertex_normals(points, triangles):
    """Area-weighted unit vertex normals of a triangle mesh (outward for an outward-oriented
    closed mesh); a vertex of no triangle, or of triangles of zero area only, gets ``(0, 0,
    0)`` (it then does not move in :func:`smooth_across_frames`).

    Parameters
    ----------
    points : (P, 3) float64
        Vertices (m).
    triangles : (T, 3) int
        Vertex indices.

    Returns
    -------
    (P, 3) float64
    """
    p = check_points("points", points)
    t = check_triangles("triangles", triangles, p.shape[0], allow_empty=True,
                        allow_degenerate=True)
    face = np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]])
    n = np.zeros_like(p)
    for corner in range(3):
        for axis in range(3):
            n[:, axis] += np.bincount(t[:, corner], weights=face[:, axis], minlength=p.shape[0])
    length = np.linalg.norm(n, axis=1)
    return np.divide(n, length[:, None], out=np.zeros_like(n), where=length[:, None] > 0.0)
