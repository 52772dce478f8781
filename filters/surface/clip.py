"""Cutting a closed triangle mesh by an axis-aligned plane, exactly and watertight.

:func:`clip_half_space` keeps the part of a closed, consistently oriented mesh on one side of
the plane ``x_axis = value``: vertices within ``eps`` of the plane are put on it, every edge
that crosses it gets one new vertex (shared by both triangles of the edge, its coordinate along
``axis`` exactly ``value``), triangles are cut into the kept triangle or quadrilateral, and the
boundary of what is kept (the cut) is returned as directed edges: the loops that a cap on the
plane, facing away from the kept side, must follow (reversed boundary edges of the kept part),
so that mesh + cap is closed again. Point data are interpolated linearly at the new vertices.
Cutting by the six planes of a box one after the other (each cap cut by the next planes like
any face) gives the surface of a liquid cut exactly at the walls of its tank; the caps are
triangulated by the caller (``pipeline.surface.liquid.ClipBox``).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from ..validation import check_int, check_range

if TYPE_CHECKING:
    from numpy.typing import NDArray

__all__ = ["clip_half_space", "cap_loops", "refill_runs", "wall_constraints", "WALL_TOLERANCE"]

#: A vertex within this fraction of a box's largest side of one of its walls lies on it
#: (:func:`wall_constraints`): vtkPolyData keeps float32 points, and VTK's smoothing rescales
#: them, so vertices put on a wall come back up to ~1e-7 of the box's size off it.
WALL_TOLERANCE = 1e-6


@njit(cache=True)
def _cut(tris, d, edge_key, edge_vertex, n_points):
    """Kept triangles of a cut (vertex ``n_points + k`` is the new vertex of the edge of key
    ``edge_key[k]``, sorted) and the directed on-plane edges of the kept triangles."""
    t = tris.shape[0]
    out = np.empty((2 * t, 3), np.int64)
    m = 0
    poly = np.empty(4, np.int64)
    for f in range(t):
        a = tris[f, 0]
        b = tris[f, 1]
        c = tris[f, 2]
        da = d[a]
        db = d[b]
        dc = d[c]
        if da >= 0.0 and db >= 0.0 and dc >= 0.0:
            if da == 0.0 and db == 0.0 and dc == 0.0:
                continue  # lying in the plane: the cap replaces it
            out[m, 0] = a
            out[m, 1] = b
            out[m, 2] = c
            m += 1
            continue
        if da <= 0.0 and db <= 0.0 and dc <= 0.0:
            continue
        k = 0
        for e in range(3):
            v = tris[f, e]
            w = tris[f, (e + 1) % 3]
            if d[v] >= 0.0:
                poly[k] = v
                k += 1
            if (d[v] > 0.0 and d[w] < 0.0) or (d[v] < 0.0 and d[w] > 0.0):
                key = min(v, w) * n_points + max(v, w)
                poly[k] = n_points + edge_vertex[np.searchsorted(edge_key, key)]
                k += 1
        for e in range(1, k - 1):
            out[m, 0] = poly[0]
            out[m, 1] = poly[e]
            out[m, 2] = poly[e + 1]
            m += 1
    return out[:m].copy()


@njit(cache=True)
def _crossing_keys(tris, d, n_points):
    """Keys ``min * n_points + max`` of the edges whose ends lie strictly on both sides of the
    plane (signed distances ``d``), once per triangle side (an edge inside the mesh twice)."""
    keys = np.empty(3 * tris.shape[0], np.int64)
    m = 0
    for f in range(tris.shape[0]):
        for e in range(3):
            v = tris[f, e]
            w = tris[f, (e + 1) % 3]
            if (d[v] > 0.0 and d[w] < 0.0) or (d[v] < 0.0 and d[w] > 0.0):
                keys[m] = min(v, w) * n_points + max(v, w)
                m += 1
    return keys[:m].copy()


@njit(cache=True)
def _plane_edges(tris, on_plane):
    """The directed edges ``(tris[f, e], tris[f, e + 1])`` with both ends on the plane, side
    ``e = 0, 1, 2`` in turn, triangles in order within each."""
    out = np.empty((3 * tris.shape[0], 2), np.int64)
    m = 0
    for e in range(3):
        for f in range(tris.shape[0]):
            v = tris[f, e]
            w = tris[f, (e + 1) % 3]
            if on_plane[v] and on_plane[w]:
                out[m, 0] = v
                out[m, 1] = w
                m += 1
    return out[:m].copy()


def clip_half_space(points: np.ndarray, triangles: np.ndarray, axis: int, value: float, keep: int,
                    *, data: np.ndarray | None = None,
                    eps: float = 0.0) -> tuple[NDArray[np.float64], NDArray[np.int64],
                                               NDArray[np.float64] | None, NDArray[np.int64]]:
    """Cut a closed triangle mesh by the plane ``x_axis = value``.

    Parameters
    ----------
    points : (P, 3) float64
        Vertices (m).
    triangles : (T, 3) int64
        Vertex indices of a closed, consistently oriented mesh.
    axis : int
        0, 1 or 2.
    value : float
        Position of the plane (m).
    keep : int
        +1 keeps ``x_axis >= value``, -1 keeps ``x_axis <= value``.
    data : (P, K) float64, optional
        Point data, interpolated at the new vertices.
    eps : float
        Vertices closer than this to the plane (m) are put on it, >= 0.

    Returns
    -------
    points : (P', 3) float64
        The vertices, the new ones appended (unused ones are kept).
    triangles : (T', 3) int64
        The kept triangles.
    data : (P', K) float64 or None
    cap : (E, 2) int64
        Directed edges ``(u, v)`` on the plane: the boundary of the cap, oriented so that a cap
        triangulated with them as its boundary faces away from the kept side.
    """
    axis = check_int("axis", axis, 0, 2)
    if keep not in (1, -1):
        raise ValueError(f"keep must be +1 or -1, got {keep!r}")
    value = float(value)
    eps = check_range("eps", eps, 0.0, math.inf)
    pts = np.array(points, dtype=np.float64)
    tris = np.ascontiguousarray(triangles, dtype=np.int64).reshape(-1, 3)
    n = pts.shape[0]
    d = keep * (pts[:, axis] - value)
    on = np.abs(d) <= eps
    d[on] = 0.0
    pts[on, axis] = value
    if not (d <= 0.0).any():  # the whole mesh strictly on the kept side: nothing to cut
        data = None if data is None else np.array(data, np.float64)
        return pts, tris.copy(), data, np.zeros((0, 2), np.int64)
    # the edges that cross the plane, each once, and their new vertices
    key = np.unique(_crossing_keys(tris, d, n))
    i, j = key // n, key % n
    t = d[i] / (d[i] - d[j])
    new = pts[i] + t[:, None] * (pts[j] - pts[i])
    new[:, axis] = value
    kept = _cut(tris, d, key, np.arange(key.size), n)
    pts = np.concatenate([pts, new])
    if data is not None:
        data = np.asarray(data, np.float64)
        data = np.concatenate([data, data[i] + t[:, None] * (data[j] - data[i])])
    # boundary of the kept part: directed edges on the plane whose reverse no kept triangle has
    on_plane = np.concatenate([on, np.ones(key.size, bool)])
    de = _plane_edges(kept, on_plane)
    size = pts.shape[0]
    forward = de[:, 0] * size + de[:, 1]
    backward = de[:, 1] * size + de[:, 0]
    boundary = de[~np.isin(forward, backward)]
    return pts, kept, data, np.ascontiguousarray(boundary[:, ::-1])


@njit(cache=True)
def _chain(edges, n):
    """Simple loops of directed edges where every vertex has as many edges out as in: (order,
    starts). A vertex with two or more edges out (the surface pinched onto the plane at one
    point, two loops touching there) is in as many loops; each walk is cut into a loop as soon
    as it comes back to a vertex it has passed, so no loop repeats a vertex. Empty ``order`` if
    some vertex has more edges out than in."""
    m_edges = edges.shape[0]
    count = np.zeros(n + 1, np.int64)
    for k in range(m_edges):
        count[edges[k, 0] + 1] += 1
    first = np.cumsum(count)  # out-edges of v: by_source[first[v]:first[v + 1]]
    fill = first[:-1].copy()
    by_source = np.empty(m_edges, np.int64)
    for k in range(m_edges):
        by_source[fill[edges[k, 0]]] = k
        fill[edges[k, 0]] += 1
    nxt_free = first[:-1].copy()  # next unused out-edge of each vertex
    pos = np.full(n, -1, np.int64)  # position of a vertex on the current walk
    path = np.empty(m_edges + 1, np.int64)
    order = np.empty(m_edges, np.int64)
    starts = np.empty(m_edges + 1, np.int64)
    failed = (np.zeros(0, np.int64), np.zeros(1, np.int64))
    m = 0
    loops = 0
    for k0 in range(m_edges):
        v = edges[k0, 0]
        if nxt_free[v] >= first[v + 1]:
            continue  # every edge out of v is in a loop already
        length = 1
        path[0] = v
        pos[v] = 0
        while True:
            if nxt_free[v] >= first[v + 1]:
                if length == 1:
                    pos[v] = -1
                    break
                return failed  # a walk stuck before closing: unbalanced edges
            e = by_source[nxt_free[v]]
            nxt_free[v] += 1
            w = edges[e, 1]
            if pos[w] >= 0:  # closed a loop path[pos[w]:]
                p = pos[w]
                starts[loops] = m
                loops += 1
                for i in range(p, length):
                    order[m] = path[i]
                    m += 1
                    if i > p:
                        pos[path[i]] = -1
                length = p + 1
                v = w
            else:
                path[length] = w
                pos[w] = length
                length += 1
                v = w
    starts[loops] = m
    return order[:m].copy(), starts[:loops + 1].copy()


def cap_loops(points: np.ndarray, edges: np.ndarray, axis: int, lower: np.ndarray,
              upper: np.ndarray) -> tuple[list[NDArray[np.int64]], dict]:
    """The loops of a cap's boundary ``edges`` on the plane normal to ``axis``, with the runs
    of points along the box's edges (points exactly on a second wall, as the cuts put them)
    reduced to their ends.

    Returns
    -------
    loops : list of (L,) int64
        Vertex indices of each simplified loop, in the edges' direction.
    runs : dict
        ``(u, w) -> (k,) int64``: the points removed between consecutive loop vertices ``u``
        and ``w`` (in order from ``u`` to ``w``), for :func:`refill_runs`.

    Raises
    ------
    ValueError
        If the edges do not form closed loops (a vertex with more edges out than in). A vertex
        with two edges out and two in (the surface touching the plane at one point) is in two
        loops.
    """
    edges = np.ascontiguousarray(edges, dtype=np.int64)
    order, starts = _chain(edges, int(points.shape[0]))
    if order.size != edges.shape[0]:
        raise ValueError("the cut's edges do not form closed loops")
    lower = np.asarray(lower, np.float64)
    upper = np.asarray(upper, np.float64)
    others = [a for a in range(3) if a != axis]
    loops, runs = [], {}
    for k in range(starts.size - 1):
        loop = order[starts[k]:starts[k + 1]]
        p = points[loop]
        # a point is redundant if it and both neighbours lie on the same box edge line
        redundant = np.zeros(loop.size, bool)
        for a in others:
            for wall in (lower[a], upper[a]):
                on = p[:, a] == wall
                redundant |= on & np.roll(on, 1) & np.roll(on, -1)
        if redundant.all():  # a loop all along the box's edges: keep its corners
            redundant[:] = False
        if not redundant.any():
            loops.append(loop)
            continue
        keep = np.flatnonzero(~redundant)
        if keep.size < 3:
            # out along the box's edges and back to the same corner (a film of liquid pressed
            # into a corner of the wall): nothing left to triangulate once reduced, so the
            # loop stays whole (a sliver, closed by a fan)
            loops.append(loop)
            continue
        loop_kept = loop[keep]
        for i, start in enumerate(keep):
            stop = keep[(i + 1) % keep.size]
            between = (np.arange(start + 1, stop) if stop > start
                       else np.r_[np.arange(start + 1, loop.size), np.arange(0, stop)])
            if between.size:
                runs[(int(loop[start]), int(loop[stop]))] = loop[between]
        loops.append(loop_kept)
    return loops, runs


def refill_runs(triangles: np.ndarray, runs: dict) -> NDArray[np.int64]:
    """Put the removed points of :func:`cap_loops` back: the cap triangle with the directed edge
    ``(u, w)`` of a run becomes a fan from its third vertex over ``u, v_1, ..., v_k, w`` (run
    after run, so a triangle with two such edges is split twice).

    Parameters
    ----------
    triangles : (T, 3) int64
        The cap's triangles (over the simplified loops), oriented with the loops.
    runs : dict
        From :func:`cap_loops`.

    Returns
    -------
    (T', 3) int64
    """
    tris = [tuple(int(v) for v in t) for t in np.asarray(triangles, np.int64).reshape(-1, 3)]
    if not runs:
        return np.asarray(tris, np.int64).reshape(-1, 3)
    alive = [True] * len(tris)
    where = {}
    for f, t in enumerate(tris):
        for e in range(3):
            where[(t[e], t[(e + 1) % 3])] = f
    for (u, w), between in runs.items():
        f = where.pop((u, w), None)
        if f is None or not alive[f]:
            raise ValueError("a cap triangle along a box edge is missing")
        t = tris[f]
        e = t.index(u)
        x = t[(e + 2) % 3]
        alive[f] = False
        chain = [u, *map(int, between), w]
        for a, b in zip(chain[:-1], chain[1:], strict=False):
            tris.append((a, b, x))
            alive.append(True)
            g = len(tris) - 1
            for edge in ((a, b), (b, x), (x, a)):
                where[edge] = g
    kept = [t for t, ok in zip(tris, alive, strict=False) if ok]
    return np.asarray(kept, np.int64).reshape(-1, 3)


def wall_constraints(points: np.ndarray, triangles: np.ndarray, lower: np.ndarray,
                     upper: np.ndarray) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Which vertices lie on the walls of the box ``[lower, upper]`` and which triangles are
    the flat faces on them (a mesh cut by :func:`clip_half_space`, whose cut vertices lie on
    the walls exactly, up to rounding: vtkPolyData keeps float32 points, and VTK's smoothing
    rescales them; within 1e-6 of the box's size).

    Parameters
    ----------
    points : (V, 3) float64
    triangles : (T, 3) int64
    lower, upper : (3,) float
        The box (m).

    Returns
    -------
    free : (V, 3) float64
        1 where a vertex may move along an axis, 0 along the axes of the walls it lies on (a
        vertex on a wall slides in it, on an edge along the edge, a corner stays).
    faces : (T,) bool
        Triangles with their three vertices on the same wall.
    """
    p = np.ascontiguousarray(points, np.float64).reshape(-1, 3)
    t = np.ascontiguousarray(triangles, np.int64).reshape(-1, 3)
    lower = np.asarray(lower, np.float64)
    upper = np.asarray(upper, np.float64)
    tol = WALL_TOLERANCE * float(np.max(upper - lower))
    return _wall_constraints(p, t, lower, upper, tol)


@njit(cache=True)
def _wall_constraints(p, t, lower, upper, tol):
    # bit a of on_lo / on_hi: the vertex lies on the lower / upper wall normal to axis a
    on_lo = np.zeros(p.shape[0], np.uint8)
    on_hi = np.zeros(p.shape[0], np.uint8)
    free = np.ones((p.shape[0], 3), np.float64)
    for v in range(p.shape[0]):
        for a in range(3):
            if abs(p[v, a] - lower[a]) <= tol:
                on_lo[v] |= 1 << a
                free[v, a] = 0.0
            if abs(p[v, a] - upper[a]) <= tol:
                on_hi[v] |= 1 << a
                free[v, a] = 0.0
    faces = np.zeros(t.shape[0], np.bool_)
    for f in range(t.shape[0]):
        a, b, c = t[f, 0], t[f, 1], t[f, 2]
        faces[f] = ((on_lo[a] & on_lo[b] & on_lo[c]) | (on_hi[a] & on_hi[b] & on_hi[c])) != 0
    return free, faces
