"""Signed distances along lines from points to a triangle mesh, within a reach.

:func:`normal_offsets` answers, for every point ``p`` and direction ``d``, the ``t`` of least
``|t| <= reach`` where the line ``p + t d`` crosses the mesh (Möller & Trumbore 1997, both
sides), NaN where it crosses nothing within reach.

The search walks the line through a uniform grid (Amanatides & Woo 1987), outward from ``t =
0`` in both directions at once, nearest cell first, and stops as soon as the next cell starts
farther than the best crossing found: a line that meets the mesh near its origin (the common
case: a vertex moved to a neighbouring frame's surface) tests the triangles of one or two
cells. Each triangle is listed in every cell within ``PAD`` cells of it: a small one (a
marching-cubes triangle, at most two cells along each axis) in its bounding box's cells, a
larger one in the cells it meets, found by clipping it slab by slab and row by row, so the
long thin fans of a tank wall's cut faces occupy the cells along them only. A triangle is
tested only if the line passes within its bounding sphere about the centroid. The result is
the same for any cell size: every crossing within reach lies in a cell the walk visits before
it stops (the padding covers the rounding of the walk and the crossing test's edge slack),
and a tie between ``t`` and ``-t`` goes to the positive one.

Measured on the main job's frames: ``benchmarks/bench_across_frames.py``.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit, prange

from ..binning import MAX_CELLS, counting_sort
from ..elastic.topology import check_triangles
from ..validation import check_points, check_range

if TYPE_CHECKING:
    from numpy.typing import NDArray

__all__ = ["normal_offsets", "TriangleGrid", "EDGE_SLACK", "CELL_OVER_REACH"]

#: Barycentric slack of a crossing (relative): a line through an edge shared by two triangles
#: finds one of them rather than slipping between them.
EDGE_SLACK = 1e-9

#: Cell edge of the triangle grid over the search reach.
CELL_OVER_REACH = 1.0

#: How far beyond a triangle (in cells) the cells listing it reach.
PAD = 1e-5

#: A line is tested against a triangle only if it passes within this factor of the distance
#: from the triangle's centroid to its farthest corner: 1e-3 beyond it, far more than the edge
#: slack (2e-9 of an edge) and the rounding of the distance, so the skip never drops a crossing.
BOUND_GROWTH = 1.001

#: Triangles per chunk of the parallel binning.
_CHUNK = 4096


@njit(parallel=True, cache=True)
def _corner_edges(V, T):
    """(T, 13) float64: each triangle's first corner ``a`` and edges ``b - a``, ``c - a`` (the
    operands of the crossing test, stored together so that a test reads one row), then its
    centroid and the square of ``BOUND_GROWTH`` times its largest centroid-corner distance
    (a line farther than that from the centroid cannot cross it: the test is skipped)."""
    E = np.empty((T.shape[0], 13))
    for f in prange(T.shape[0]):
        a, b, c = T[f, 0], T[f, 1], T[f, 2]
        for axis in range(3):
            E[f, axis] = V[a, axis]
            E[f, 3 + axis] = V[b, axis] - V[a, axis]
            E[f, 6 + axis] = V[c, axis] - V[a, axis]
            E[f, 9 + axis] = (V[a, axis] + V[b, axis] + V[c, axis]) / 3.0
        r2 = 0.0
        for corner in (a, b, c):
            d2 = 0.0
            for axis in range(3):
                d2 += (V[corner, axis] - E[f, 9 + axis]) ** 2
            r2 = max(r2, d2)
        E[f, 12] = BOUND_GROWTH * BOUND_GROWTH * r2
    return E


@njit(cache=True, inline="always")
def _crossing(px, py, pz, dx, dy, dz, E, f):
    """``t`` where the line ``p + t d`` crosses triangle ``f`` (row ``f`` of
    :func:`_corner_edges`; Möller & Trumbore 1997, both sides), or infinity.

    Every quantity is computed whatever the others (no early exit): the tests' outcomes are
    data-dependent and mispredicted branches cost more than the arithmetic they skip."""
    e1x = E[f, 3]
    e1y = E[f, 4]
    e1z = E[f, 5]
    e2x = E[f, 6]
    e2y = E[f, 7]
    e2z = E[f, 8]
    qx = dy * e2z - dz * e2y
    qy = dz * e2x - dx * e2z
    qz = dx * e2y - dy * e2x
    det = e1x * qx + e1y * qy + e1z * qz
    inv = 1.0 / (det if det != 0.0 else 1.0)
    sx = px - E[f, 0]
    sy = py - E[f, 1]
    sz = pz - E[f, 2]
    u = (sx * qx + sy * qy + sz * qz) * inv
    rx = sy * e1z - sz * e1y
    ry = sz * e1x - sx * e1z
    rz = sx * e1y - sy * e1x
    v = (dx * rx + dy * ry + dz * rz) * inv
    t = (e2x * rx + e2y * ry + e2z * rz) * inv
    inside = ((det != 0.0) & (u >= -EDGE_SLACK) & (u <= 1.0 + EDGE_SLACK) & (v >= -EDGE_SLACK)
              & (u + v <= 1.0 + EDGE_SLACK))
    return t if inside else math.inf


# ---------------------------------------------------------------------------------------------
# Triangles into cells
# ---------------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _clip_plane(src, n, axis, value, keep_above, dst):
    """Polygon ``src[:n]`` clipped to ``x[axis] >= value`` (``keep_above``) or ``<= value``
    (Sutherland & Hodgman 1974), into ``dst``; returns its vertex count."""
    m = 0
    for i in range(n):
        j = i + 1 if i + 1 < n else 0
        ca = src[i, axis]
        cb = src[j, axis]
        ina = ca >= value if keep_above else ca <= value
        inb = cb >= value if keep_above else cb <= value
        if ina:
            dst[m, 0] = src[i, 0]
            dst[m, 1] = src[i, 1]
            dst[m, 2] = src[i, 2]
            m += 1
        if ina != inb:
            s = (value - ca) / (cb - ca)
            dst[m, 0] = src[i, 0] + s * (src[j, 0] - src[i, 0])
            dst[m, 1] = src[i, 1] + s * (src[j, 1] - src[i, 1])
            dst[m, 2] = src[i, 2] + s * (src[j, 2] - src[i, 2])
            dst[m, axis] = value
            m += 1
    return m


@njit(cache=True, inline="always")
def _band_extent(src, n, axis, lo, hi, along):
    """Extent along ``along`` of polygon ``src[:n]`` clipped to ``lo <= x[axis] <= hi``: the
    clipped polygon's vertices (those inside, and the edges' crossings of the two planes),
    without building it; ``(inf, -inf)`` when empty."""
    first = math.inf
    last = -math.inf
    for i in range(n):
        j = i + 1 if i + 1 < n else 0
        ca = src[i, axis]
        cb = src[j, axis]
        if lo <= ca <= hi:
            first = min(first, src[i, along])
            last = max(last, src[i, along])
        for value in (lo, hi):
            if (ca < value) != (cb < value) and ca != cb:
                x = src[i, along] + (value - ca) / (cb - ca) * (src[j, along] - src[i, along])
                first = min(first, x)
                last = max(last, x)
    return first, last


@njit(cache=True, inline="always")
def _cell_span(V, T, f, axis, origin, h, n):
    """Cells along ``axis`` of triangle ``f``'s box grown by PAD cells, clamped to the grid."""
    a = min(V[T[f, 0], axis], V[T[f, 1], axis], V[T[f, 2], axis])
    b = max(V[T[f, 0], axis], V[T[f, 1], axis], V[T[f, 2], axis])
    lo = int(min(max(math.floor((a - origin[axis]) / h - PAD), 0.0), n - 1.0))
    hi = int(min(max(math.floor((b - origin[axis]) / h + PAD), 0.0), n - 1.0))
    return lo, hi


@njit(cache=True)
def _triangle_cells(V, T, f, origin, h, dims, out, write, scratch):
    """The cells within PAD cells of triangle ``f`` (keys ``(z ny + y) nx + x``), written to
    ``out`` when ``write``; returns their number.

    A triangle whose box spans at most two cells along every axis (a marching-cubes triangle)
    lists its box's cells; a larger one is clipped to each slab of cells along z, the slab's
    polygon to each row along y, and the row's polygon covers a range of cells along x (each
    clip grown by PAD cells)."""
    nx, ny = dims[0], dims[1]
    x0, x1 = _cell_span(V, T, f, 0, origin, h, dims[0])
    y0, y1 = _cell_span(V, T, f, 1, origin, h, dims[1])
    z0, z1 = _cell_span(V, T, f, 2, origin, h, dims[2])
    n = 0
    if x1 - x0 <= 1 and y1 - y0 <= 1 and z1 - z0 <= 1:
        for z in range(z0, z1 + 1):
            for y in range(y0, y1 + 1):
                for x in range(x0, x1 + 1):
                    if write:
                        out[n] = (z * ny + y) * nx + x
                    n += 1
        return n
    tri = scratch[0]
    tmp = scratch[1]
    slab = scratch[2]
    for c in range(3):
        for axis in range(3):
            tri[c, axis] = (V[T[f, c], axis] - origin[axis]) / h  # in cells
    for z in range(z0, z1 + 1):
        m = _clip_plane(tri, 3, 2, z - PAD, True, tmp)
        m = _clip_plane(tmp, m, 2, z + 1.0 + PAD, False, slab)
        if m == 0:
            continue
        lo = math.inf
        hi = -math.inf
        for i in range(m):
            lo = min(lo, slab[i, 1])
            hi = max(hi, slab[i, 1])
        for y in range(max(int(math.floor(lo - PAD)), y0), min(int(math.floor(hi + PAD)), y1) + 1):
            first, last = _band_extent(slab, m, 1, y - PAD, y + 1.0 + PAD, 0)
            if first > last:
                continue
            for x in range(max(int(math.floor(first - PAD)), x0),
                           min(int(math.floor(last + PAD)), x1) + 1):
                if write:
                    out[n] = (z * ny + y) * nx + x
                n += 1
    return n


@njit(parallel=True, cache=True)
def _bin_triangles(V, T, origin, h, dims):
    """Every (cell key, triangle) pair of :func:`_triangle_cells`, triangle by triangle."""
    nt = T.shape[0]
    chunks = (nt + _CHUNK - 1) // _CHUNK
    counts = np.empty(nt, np.int64)
    none = np.empty(0, np.int64)
    for c in prange(chunks):
        scratch = np.empty((3, 12, 3))  # a clipped triangle has at most 7 vertices
        for f in range(c * _CHUNK, min(nt, (c + 1) * _CHUNK)):
            counts[f] = _triangle_cells(V, T, f, origin, h, dims, none, False, scratch)
    first = np.empty(nt + 1, np.int64)
    total = 0
    for f in range(nt):
        first[f] = total
        total += counts[f]
    first[nt] = total
    keys = np.empty(total, np.int64)
    owner = np.empty(total, np.int32)
    for c in prange(chunks):
        scratch = np.empty((3, 12, 3))
        for f in range(c * _CHUNK, min(nt, (c + 1) * _CHUNK)):
            _triangle_cells(V, T, f, origin, h, dims, keys[first[f]:first[f + 1]], True, scratch)
            owner[first[f]:first[f + 1]] = f
    return keys, owner


# ---------------------------------------------------------------------------------------------
# The walk
# ---------------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _visit(cell, px, py, pz, dx, dy, dz, dd, reach, start, items, E, best, best_abs):
    """The best crossing so far updated with the triangles of ``cell`` (``dd = |d|^2``)."""
    for k in range(start[cell], start[cell + 1]):
        f = items[k]
        wx = E[f, 9] - px
        wy = E[f, 10] - py
        wz = E[f, 11] - pz
        cx = wy * dz - wz * dy
        cy = wz * dx - wx * dz
        cz = wx * dy - wy * dx
        if cx * cx + cy * cy + cz * cz > E[f, 12] * dd:
            continue  # the line passes outside the triangle's bounding sphere
        t = _crossing(px, py, pz, dx, dy, dz, E, f)
        a = abs(t)
        if a <= reach and (a < best_abs or (a == best_abs and t > best)):
            best_abs = a
            best = t
    return best, best_abs


@njit(cache=True, inline="always")
def _first_boundary(q, e, inv, c, h, forward):
    """Parameter along ``+-e`` (``forward``: along ``+e``; ``inv = 1 / e``) at which the walk
    leaves cell ``c`` through its next face along this axis, from the local coordinate ``q``;
    inf if ``e == 0``. (The walk's parameters only choose cells: their rounding is covered by
    PAD, the crossings' ``t`` come from the crossing test.)"""
    if e == 0.0:
        return math.inf
    if forward:
        return ((c + (1 if e > 0.0 else 0)) * h - q) * inv
    return (q - (c + (1 if e < 0.0 else 0)) * h) * inv


@njit(parallel=True, cache=True)
def _walk_all(p, d, rows, start, items, origin, h, dims, E, reach, out):
    nx, ny, nz = dims[0], dims[1], dims[2]
    inv_h = 1.0 / h
    for r in prange(rows.shape[0]):
        i = rows[r]
        px = p[i, 0] - origin[0]  # grid coordinates for the walk
        py = p[i, 1] - origin[1]
        pz = p[i, 2] - origin[2]
        dx = d[i, 0]
        dy = d[i, 1]
        dz = d[i, 2]
        dd = dx * dx + dy * dy + dz * dz
        ix = 1.0 / dx if dx != 0.0 else math.inf
        iy = 1.0 / dy if dy != 0.0 else math.inf
        iz = 1.0 / dz if dz != 0.0 else math.inf
        # the segment |t| <= reach clipped to the grid's box [0, dims h]
        ta = -reach
        tb = reach
        inside = True
        for axis in range(3):
            q = px if axis == 0 else (py if axis == 1 else pz)
            e = dx if axis == 0 else (dy if axis == 1 else dz)
            inv = ix if axis == 0 else (iy if axis == 1 else iz)
            top = dims[axis] * h
            if e == 0.0:
                inside = inside and 0.0 <= q <= top
            else:
                t1 = -q * inv
                t2 = (top - q) * inv
                ta = max(ta, min(t1, t2))
                tb = min(tb, max(t1, t2))
        out[i] = np.nan
        if not inside or ta > tb:
            continue
        ts = min(max(0.0, ta), tb)  # the segment's point nearest t = 0
        cx = min(max(int(math.floor((px + ts * dx) * inv_h)), 0), nx - 1)
        cy = min(max(int(math.floor((py + ts * dy) * inv_h)), 0), ny - 1)
        cz = min(max(int(math.floor((pz + ts * dz) * inv_h)), 0), nz - 1)
        best, best_abs = _visit((cz * ny + cy) * nx + cx, p[i, 0], p[i, 1], p[i, 2], dx, dy, dz,
                                dd, reach, start, items, E, np.nan, math.inf)
        # forward (t from ts up to tb) and backward (t from ts down to ta) walks: per axis the
        # parameter of the next face and the parameter per cell (Amanatides & Woo 1987)
        sx = 1 if dx > 0.0 else -1
        sy = 1 if dy > 0.0 else -1
        sz = 1 if dz > 0.0 else -1
        stx = h * abs(ix)
        sty = h * abs(iy)
        stz = h * abs(iz)
        fx, fy, fz = cx, cy, cz
        tfx = _first_boundary(px, dx, ix, cx, h, True)
        tfy = _first_boundary(py, dy, iy, cy, h, True)
        tfz = _first_boundary(pz, dz, iz, cz, h, True)
        bx, by, bz = cx, cy, cz
        tbx = _first_boundary(px, dx, ix, cx, h, False)
        tby = _first_boundary(py, dy, iy, cy, h, False)
        tbz = _first_boundary(pz, dz, iz, cz, h, False)
        forward_end = tb if ts >= 0.0 else -math.inf
        backward_end = -ta if ts <= 0.0 else -math.inf
        while True:
            ef = min(tfx, tfy, tfz)  # |t| where the next cell forward begins
            eb = min(tbx, tby, tbz)
            go_f = ef <= forward_end and ef <= best_abs
            go_b = eb <= backward_end and eb <= best_abs
            if not (go_f or go_b):
                break
            if go_f and (not go_b or ef <= eb):
                if tfx <= tfy and tfx <= tfz:
                    fx += sx
                    tfx += stx
                elif tfy <= tfz:
                    fy += sy
                    tfy += sty
                else:
                    fz += sz
                    tfz += stz
                if 0 <= fx < nx and 0 <= fy < ny and 0 <= fz < nz:
                    best, best_abs = _visit((fz * ny + fy) * nx + fx, p[i, 0], p[i, 1], p[i, 2],
                                            dx, dy, dz, dd, reach, start, items, E, best,
                                            best_abs)
                else:
                    forward_end = -math.inf
            else:
                if tbx <= tby and tbx <= tbz:
                    bx -= sx
                    tbx += stx
                elif tby <= tbz:
                    by -= sy
                    tby += sty
                else:
                    bz -= sz
                    tbz += stz
                if 0 <= bx < nx and 0 <= by < ny and 0 <= bz < nz:
                    best, best_abs = _visit((bz * ny + by) * nx + bx, p[i, 0], p[i, 1], p[i, 2],
                                            dx, dy, dz, dd, reach, start, items, E, best,
                                            best_abs)
                else:
                    backward_end = -math.inf
        out[i] = best


class TriangleGrid:
    """A triangle mesh's triangles listed in the cells of a grid, for line casts within a reach.

    Build it once for a surface that several point sets are cast against (a frame's surface
    serves ``2 K`` neighbouring frames in :func:`filters.surface.temporal.smooth_across_frames`).

    Parameters
    ----------
    vertices : (V, 3) float64
        The mesh's vertices (m).
    triangles : (T, 3) int
        Its triangles.
    reach : float
        Largest ``|t|`` the casts search (m), > 0.
    cell_over_reach : float
        Cell edge over ``reach`` (> 0); the casts' results do not depend on it (widened where
        the grid would exceed ``filters.binning.MAX_CELLS`` cells).
    """

    def __init__(self, vertices: np.ndarray, triangles: np.ndarray, reach: float, *,
                 cell_over_reach: float = CELL_OVER_REACH):
        self.vertices = check_points("vertices", vertices)
        self.triangles = np.ascontiguousarray(
            check_triangles("triangles", triangles, self.vertices.shape[0], allow_empty=True,
                            allow_degenerate=True), dtype=np.int64)
        self.reach = check_range("reach", reach, 0.0, math.inf, low_inclusive=False)
        cell_over_reach = check_range("cell_over_reach", cell_over_reach, 0.0, math.inf,
                                      low_inclusive=False)
        self.start = self.items = None
        if self.triangles.shape[0] == 0:
            return
        V = self.vertices
        self.origin = V.min(axis=0) - self.reach
        size = V.max(axis=0) + self.reach - self.origin
        cell = cell_over_reach * self.reach
        while np.prod(np.floor(size / cell) + 1.0) > MAX_CELLS:
            cell *= 1.5
        self.cell = cell
        self.dims = (np.floor(size / cell) + 1.0).astype(np.int64)
        keys, owner = _bin_triangles(V, self.triangles, self.origin, cell, self.dims)
        # one chunk: half the scratch of two (fresh memory costs here as much as the sort)
        self.start, order = counting_sort(keys, int(np.prod(self.dims)), 1)
        self.items = owner[order]
        self.corner_edges = _corner_edges(V, self.triangles)

    def offsets(self, points: np.ndarray, directions: np.ndarray, *,
                only: np.ndarray | None = None) -> NDArray[np.float64]:
        """:func:`normal_offsets` of ``points`` along ``directions`` to this mesh.

        Parameters
        ----------
        points, directions : (P, 3) float64
            Line origins (m) and directions.
        only : (M,) int, optional
            Cast the lines of these rows only (the others' results are NaN).

        Returns
        -------
        (P,) float64
            NaN where a line crosses nothing within the reach.
        """
        p = check_points("points", points)
        d = check_points("directions", directions)
        if d.shape != p.shape:
            raise ValueError(f"directions must have the shape of points {p.shape}, got "
                             f"{d.shape}")
        rows = np.arange(p.shape[0]) if only is None else np.asarray(only, np.int64).reshape(-1)
        if rows.size and (rows.min() < 0 or rows.max() >= p.shape[0]):
            raise ValueError(f"only must index the {p.shape[0]} points")
        out = np.full(p.shape[0], np.nan)
        if rows.size and self.start is not None:
            _walk_all(p, d, rows, self.start, self.items, self.origin, self.cell, self.dims,
                      self.corner_edges, self.reach, out)
        return out


def normal_offsets(points: np.ndarray, directions: np.ndarray, vertices: np.ndarray,
                   triangles: np.ndarray, reach: float, *,
                   cell_over_reach: float = CELL_OVER_REACH) -> NDArray[np.float64]:
    """Signed distance along ``directions`` from every point to a triangle mesh, within ``reach``.

    Parameters
    ----------
    points : (P, 3) float64
        Line origins (m).
    directions : (P, 3) float64
        Directions (e.g. unit vertex normals); the distances are in units of their length.
    vertices : (V, 3) float64
        The other mesh's vertices (m).
    triangles : (T, 3) int
        The other mesh's triangles.
    reach : float
        Largest ``|t|`` searched (m), > 0.
    cell_over_reach : float
        Cell edge of the search grid over ``reach`` (> 0); the result does not depend on it.

    Returns
    -------
    (P,) float64
        ``t`` of the crossing ``points + t directions`` of least ``|t|`` (positive along the
        direction; of ``t`` and ``-t`` the positive one), NaN where the line crosses no
        triangle within ``reach``.

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
    grid = TriangleGrid(vertices, triangles, reach, cell_over_reach=cell_over_reach)
    return grid.offsets(p, d)
