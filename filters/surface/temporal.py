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

:func:`normal_offsets` (:mod:`filters.surface.linecast`) does the search: every point walks
its segment ``v + t n, |t| <= reach`` through a grid of the other surface's triangles, nearest
cell first, keeping the crossing of least ``|t|`` (Möller & Trumbore 1997); points are
independent (parallel, no races). Vertices held in place (``fixed``) cast nothing.
Measurements behind it: ``benchmarks/results/splash_motion_notes.md`` and
``benchmarks/bench_across_frames.py`` (the main job's frames).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from ..elastic.topology import check_triangles
from ..validation import check_int, check_points, check_range
from .attributes import interpolate_attributes
from .clip import wall_constraints
from .linecast import TriangleGrid, normal_offsets
from .smoothing import vertex_neighbors

if TYPE_CHECKING:
    from collections.abc import Sequence

    from numpy.typing import ArrayLike, NDArray

__all__ = ["normal_offsets", "smooth_across_frames", "follow_particles_across_frames",
           "vertex_normals"]

def smooth_across_frames(points: np.ndarray, triangles: np.ndarray,
                         others: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]],
                         weights: Sequence[float], reach: float, *,
                         normals: np.ndarray | None = None, sweeps: int = 10,
                         fixed: np.ndarray | None = None) -> NDArray[np.float64]:
    """Vertices of one frame's surface moved along their normals toward neighbouring frames'.

    Parameters
    ----------
    points : (P, 3) float64
        Vertices of frame ``k``'s surface (m).
    triangles : (T, 3) int
        Its triangles.
    others : sequence of ((P, 3) float64, (V, 3) float64, (T, 3) int)
        Per neighbouring frame ``k + j``: ``points`` moved with the liquid to that frame, and
        that frame's surface (vertices, triangles); or ``(moved points, grid)`` with the
        surface's :class:`filters.surface.linecast.TriangleGrid` built with this ``reach``
        (a surface that serves several frames is then binned once).
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
    n = _vertex_normals(p, np.ascontiguousarray(t, np.int64)) if normals is None else (
        check_points("normals", normals))
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
    free = np.flatnonzero(~hold)
    total = np.full(p.shape[0], w[0])
    shift = np.zeros(p.shape[0])
    for other, wj in zip(others, w[1:], strict=True):
        moved = check_points("others[j][0]", other[0])
        grid = other[1] if len(other) == 2 else TriangleGrid(other[1], other[2], reach)
        if not isinstance(grid, TriangleGrid) or grid.reach != reach:
            raise ValueError("others[j] must be (moved, vertices, triangles) or (moved, grid), "
                             f"the grid a TriangleGrid built with reach {reach}")
        if moved.shape != p.shape:
            raise ValueError(f"moved points must have the shape of points {p.shape}, got "
                             f"{moved.shape}")
        # a held vertex's offset is zero whatever it finds: only the others cast their lines
        found = grid.offsets(moved, n, only=free)
        ok = np.isfinite(found)
        shift[ok] += wj * found[ok]
        total[ok] += wj
    offset = np.where(hold, 0.0, shift / total)
    if sweeps and p.shape[0]:
        starts, neighbors = vertex_neighbors(t, p.shape[0])
        offset = _smooth_offsets(offset, starts, neighbors, hold, sweeps)
    return p + offset[:, None] * n


def follow_particles_across_frames(points: np.ndarray, triangles: np.ndarray, positions: np.ndarray,
                                   neighbours: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray,
                                                              np.ndarray]],
                                   weights: Sequence[float], radius: float, *,
                                   cell_size: float | None = None,
                                   box: tuple[ArrayLike, ArrayLike] | None = None,
                                   reach_r: float = 1.0, sweeps: int = 10) -> NDArray[np.float64]:
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
        where they are in it, and its surface (vertices, triangles), or ``(rows, where,
        grid)`` with the surface's :class:`filters.surface.linecast.TriangleGrid` built with
        reach ``reach_r r``. The vertices move by the particles' displacement interpolated at
        them (Shepard weights of the SPH kernel,
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
    neighbours = [(np.asarray(rows, np.int64), where, *surface)
                  for rows, where, *surface in neighbours]
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
    others = [(m, *surface) for m, (_, _, *surface) in zip(moved, neighbours, strict=True)]
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


def vertex_normals(points: np.ndarray, triangles: np.ndarray) -> NDArray[np.float64]:
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
    t = np.ascontiguousarray(check_triangles("triangles", triangles, p.shape[0],
                                             allow_empty=True, allow_degenerate=True), np.int64)
    return _vertex_normals(p, t)


@njit(cache=True)
def _vertex_normals(p, t):
    """Area-weighted unit normals, summed corner by corner in triangle order (the sums of
    ``np.cross`` face normals that ``np.bincount`` forms per corner, added corner after
    corner: the same operations in the same order, so the same bits as that NumPy form)."""
    nv = p.shape[0]
    corner = np.zeros((3, nv, 3))
    for f in range(t.shape[0]):
        a, b, c = t[f, 0], t[f, 1], t[f, 2]
        e1x = p[b, 0] - p[a, 0]
        e1y = p[b, 1] - p[a, 1]
        e1z = p[b, 2] - p[a, 2]
        e2x = p[c, 0] - p[a, 0]
        e2y = p[c, 1] - p[a, 1]
        e2z = p[c, 2] - p[a, 2]
        fx = e1y * e2z - e1z * e2y
        fy = e1z * e2x - e1x * e2z
        fz = e1x * e2y - e1y * e2x
        for k in range(3):
            v = t[f, k]
            corner[k, v, 0] += fx
            corner[k, v, 1] += fy
            corner[k, v, 2] += fz
    out = np.zeros((nv, 3))
    for v in range(nv):
        nx = ((0.0 + corner[0, v, 0]) + corner[1, v, 0]) + corner[2, v, 0]
        ny = ((0.0 + corner[0, v, 1]) + corner[1, v, 1]) + corner[2, v, 1]
        nz = ((0.0 + corner[0, v, 2]) + corner[1, v, 2]) + corner[2, v, 2]
        length = math.sqrt((nx * nx + ny * ny) + nz * nz)
        if length > 0.0:
            out[v, 0] = nx / length
            out[v, 1] = ny / length
            out[v, 2] = nz / length
    return out
