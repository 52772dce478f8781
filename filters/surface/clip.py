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
triangulated by the caller (``pipeline.liquid.ClipBox``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..validation import check_int, check_range

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


def clip_half_space(points, triangles, axis: int, value: float, keep: int, *, data=None,
                    eps: float = 0.0):
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
    # the edges that cross the plane, each once, and their new vertices
    e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    cross = ((d[e[:, 0]] > 0) & (d[e[:, 1]] < 0)) | ((d[e[:, 0]] < 0) & (d[e[:, 1]] > 0))
    e = np.sort(e[cross], axis=1)
    key = np.unique(e[:, 0] * n + e[:, 1])
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
    de = np.concatenate([kept[:, [0, 1]], kept[:, [1, 2]], kept[:, [2, 0]]])
    de = de[on_plane[de[:, 0]] & on_plane[de[:, 1]]]
    size = pts.shape[0]
    forward = de[:, 0] * size + de[:, 1]
    backward = de[:, 1] * size + de[:, 0]
    boundary = de[~np.isin(forward, backward)]
    return pts, kept, data, np.ascontiguousarray(boundary[:, ::-1])


@njit(cache=True)
def _chain(edges, n):
    """Simple loops of directed edges with as many edges in as out at every vertex: (order,
    starts).  A vertex where loops touch (a pinch: two edges out) is split, each loop closed as
    soon as the walk comes back to a vertex on it; an open chain gives a shorter ``order``."""
    m = edges.shape[0]
    first = np.zeros(n + 1, np.int64)  # out-edges of each vertex, in the edges' order
    for k in range(m):
        first[edges[k, 0] + 1] += 1
    for v in range(n):
        first[v + 1] += first[v]
    out = np.empty(m, np.int64)
    cursor = first[:n].copy()
    for k in range(m):
        out[cursor[edges[k, 0]]] = k
        cursor[edges[k, 0]] += 1
    cursor = first[:n].copy()  # the next unused out-edge of each vertex
    on_path = np.full(n, -1, np.int64)
    path = np.empty(m + 1, np.int64)
    order = np.empty(m, np.int64)
    starts = np.empty(m + 1, np.int64)
    count = 0
    loops = 0
    for k0 in range(m):
        start = edges[k0, 0]
        if cursor[start] >= first[start + 1]:
            continue
        path[0] = start
        on_path[start] = 0
        length = 1
        while length > 0:
            v = path[length - 1]
            if cursor[v] >= first[v + 1]:
                if length > 1:  # stuck away from the start: an open chain
                    starts[loops] = count
                    return order[:count].copy(), starts[:loops + 1].copy()
                on_path[v] = -1
                length = 0
                break
            w = edges[out[cursor[v]], 1]
            cursor[v] += 1
            if on_path[w] < 0:
                on_path[w] = length
                path[length] = w
                length += 1
                continue
            # back on the path: the loop from w to v
            starts[loops] = count
            loops += 1
            for i in range(on_path[w], length):
                order[count] = path[i]
                count += 1
                if i > on_path[w]:
                    on_path[path[i]] = -1
            length = on_path[w] + 1
    starts[loops] = count
    return order[:count].copy(), starts[:loops + 1].copy()


def cap_loops(points, edges, axis: int, lower, upper):
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
        If the edges do not form closed loops (an open chain).  Loops that touch at a vertex
        (a pinch, where the surface meets the wall at one point) are split there.
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
        loop_kept = loop[keep]
        for i, start in enumerate(keep):
            stop = keep[(i + 1) % keep.size]
            between = (np.arange(start + 1, stop) if stop > start
                       else np.r_[np.arange(start + 1, loop.size), np.arange(0, stop)])
            if between.size:
                runs[(int(loop[start]), int(loop[stop]))] = loop[between]
        loops.append(loop_kept)
    return loops, runs


def refill_runs(triangles, runs):
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
        for a, b in zip(chain[:-1], chain[1:]):
            tris.append((a, b, x))
            alive.append(True)
            g = len(tris) - 1
            for edge in ((a, b), (b, x), (x, a)):
                where[edge] = g
    return np.asarray([t for t, ok in zip(tris, alive) if ok], np.int64).reshape(-1, 3)


def wall_constraints(points, triangles, lower, upper):
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
    p = np.asarray(points, np.float64)
    t = np.asarray(triangles, np.int64).reshape(-1, 3)
    lower = np.asarray(lower, np.float64)
    upper = np.asarray(upper, np.float64)
    tol = WALL_TOLERANCE * float(np.max(upper - lower))
    on_lo = np.abs(p - lower) <= tol
    on_hi = np.abs(p - upper) <= tol
    free = (~(on_lo | on_hi)).astype(np.float64)
    faces = np.zeros(t.shape[0], bool)
    for on in (on_lo, on_hi):
        faces |= (on[t[:, 0]] & on[t[:, 1]] & on[t[:, 2]]).any(axis=1)
    return free, faces
