"""Signed distance of a rigid body's mesh, in its body frame, for body-body contact.

Same sign convention as :mod:`filters.geometry`: negative inside the solid, the gradient (the
contact normal) pointing out of it.  Two representations, chosen per body:

* **convex** meshes: the largest signed distance to the triangles' planes,
  ``phi(x) = max_f (n_f . x - d_f)``.  Inside the solid this is the exact signed distance and its
  gradient the normal of the nearest face; outside it is a lower bound of the distance (exact
  in front of a face), which only makes contacts start a little early near edges and corners.
  Where several faces are within a tolerance of the largest value (on an edge, at a corner), the
  face the point moves into fastest is taken (its relative velocity is passed in): a box's corner
  pressed down on another box's top edge gets the top face's normal, not a side's.
* **any other** closed mesh: a grid of exact signed distances -- the distance to the nearest
  triangle (the closest-point test of Ericson 2005, "Real-Time Collision Detection", 5.1.5),
  the sign from the generalised winding number (Jacobson, Kavan & Sorkine-Hornung 2013, "Robust
  inside-outside segmentation using generalized winding numbers", with the triangle solid angle
  of Van Oosterom & Strackee 1983) -- interpolated trilinearly, as Guendelman, Bridson & Fedkiw
  (2003, "Nonconvex rigid bodies with stacking", SIGGRAPH) store their bodies' distances.  Its
  error is of the order of the cell near sharp features, and zero where the distance is linear.

All bodies' data are packed into flat arrays (:func:`pack_sdfs`) for the contact kernels, which
call :func:`body_distance`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit, prange

from ..validation import check_int

if TYPE_CHECKING:
    from collections.abc import Sequence

    from numpy.typing import ArrayLike, NDArray

__all__ = ["SDF_CONVEX", "SDF_GRID", "face_planes", "is_convex", "grid_sdf", "pack_sdfs",
           "body_distance", "body_distances", "triangle_distance", "winding_number",
           "convex_distance", "grid_distance", "mesh_distances"]

#: Kinds of body distance functions.
SDF_CONVEX = 0
SDF_GRID = 1

#: Cells left around the mesh on every side of a distance grid.
GRID_PADDING = 3


def face_planes(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Planes of the triangles, ``(F, 4)``: unit outward normal ``n`` and offset ``d``
    (``n . x = d`` on the face, ``< d`` behind it)."""
    a, b, c = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    n = np.cross(b - a, c - a)
    length = np.linalg.norm(n, axis=1)
    keep = length > 1e-14 * max(float(np.ptp(vertices, axis=0).max()), 1e-300) ** 2
    n = n[keep] / length[keep, None]
    d = np.einsum("ij,ij->i", n, (a[keep] + b[keep] + c[keep]) / 3.0)
    return np.ascontiguousarray(np.column_stack([n, d]))


@njit(cache=True)
def _max_violation(vertices, planes):
    worst = -np.inf
    for f in range(planes.shape[0]):
        for i in range(vertices.shape[0]):
            s = (planes[f, 0] * vertices[i, 0] + planes[f, 1] * vertices[i, 1]
                 + planes[f, 2] * vertices[i, 2] - planes[f, 3])
            if s > worst:
                worst = s
    return worst


def is_convex(vertices: np.ndarray, planes: np.ndarray, tol: float = 1e-9) -> bool:
    """Whether every vertex lies behind every face plane within ``tol`` times the extent."""
    extent = float(np.ptp(vertices, axis=0).max())
    return bool(_max_violation(vertices, planes) <= tol * extent)


@njit(cache=True, inline="always")
def triangle_distance(px, py, pz, v, f, t):
    """Squared distance from point ``p`` to triangle ``t`` of mesh ``(v, f)`` (Ericson 2005)."""
    ax, ay, az = v[f[t, 0], 0], v[f[t, 0], 1], v[f[t, 0], 2]
    bx, by, bz = v[f[t, 1], 0], v[f[t, 1], 1], v[f[t, 1], 2]
    cx, cy, cz = v[f[t, 2], 0], v[f[t, 2], 1], v[f[t, 2], 2]
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        qx, qy, qz = ax, ay, az
    else:
        bpx, bpy, bpz = px - bx, py - by, pz - bz
        d3 = abx * bpx + aby * bpy + abz * bpz
        d4 = acx * bpx + acy * bpy + acz * bpz
        vc = d1 * d4 - d3 * d2
        cpx, cpy, cpz = px - cx, py - cy, pz - cz
        d5 = abx * cpx + aby * cpy + abz * cpz
        d6 = acx * cpx + acy * cpy + acz * cpz
        vb = d5 * d2 - d1 * d6
        va = d3 * d6 - d5 * d4
        if d3 >= 0.0 and d4 <= d3:
            qx, qy, qz = bx, by, bz
        elif vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
            s = d1 / (d1 - d3)
            qx, qy, qz = ax + s * abx, ay + s * aby, az + s * abz
        elif d6 >= 0.0 and d5 <= d6:
            qx, qy, qz = cx, cy, cz
        elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
            s = d2 / (d2 - d6)
            qx, qy, qz = ax + s * acx, ay + s * acy, az + s * acz
        elif va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
            s = (d4 - d3) / ((d4 - d3) + (d5 - d6))
            qx, qy, qz = bx + s * (cx - bx), by + s * (cy - by), bz + s * (cz - bz)
        else:
            denom = 1.0 / (va + vb + vc)
            s = vb * denom
            w = vc * denom
            qx = ax + s * abx + w * acx
            qy = ay + s * aby + w * acy
            qz = az + s * abz + w * acz
    dx, dy, dz = px - qx, py - qy, pz - qz
    return dx * dx + dy * dy + dz * dz


@njit(cache=True)
def winding_number(px, py, pz, v, f):
    """Generalised winding number of point ``p`` with respect to the mesh ``(v, f)``: 1 inside a
    closed outward-oriented mesh, 0 outside (Jacobson et al. 2013)."""
    total = 0.0
    for t in range(f.shape[0]):
        ax, ay, az = v[f[t, 0], 0] - px, v[f[t, 0], 1] - py, v[f[t, 0], 2] - pz
        bx, by, bz = v[f[t, 1], 0] - px, v[f[t, 1], 1] - py, v[f[t, 1], 2] - pz
        cx, cy, cz = v[f[t, 2], 0] - px, v[f[t, 2], 1] - py, v[f[t, 2], 2] - pz
        la = math.sqrt(ax * ax + ay * ay + az * az)
        lb = math.sqrt(bx * bx + by * by + bz * bz)
        lc = math.sqrt(cx * cx + cy * cy + cz * cz)
        det = ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) + az * (bx * cy - by * cx)
        den = (la * lb * lc + (ax * bx + ay * by + az * bz) * lc
               + (bx * cx + by * cy + bz * cz) * la + (cx * ax + cy * ay + cz * az) * lb)
        total += 2.0 * math.atan2(det, den)
    return total / (4.0 * math.pi)


@njit(parallel=True, cache=True)
def _grid_values(v, f, origin, cell, nx, ny, nz, out):
    for idx in prange(nx * ny * nz):
        i = idx // (ny * nz)
        j = (idx // nz) % ny
        k = idx % nz
        px = origin[0] + i * cell
        py = origin[1] + j * cell
        pz = origin[2] + k * cell
        best = np.inf
        for t in range(f.shape[0]):
            d2 = triangle_distance(px, py, pz, v, f, t)
            if d2 < best:
                best = d2
        d = math.sqrt(best)
        if winding_number(px, py, pz, v, f) > 0.5:
            d = -d
        out[i, j, k] = d


def grid_sdf(vertices: np.ndarray, faces: np.ndarray,
             resolution: int = 32) -> tuple[NDArray[np.float64], float, NDArray[np.float64]]:
    """Exact signed distances of a closed mesh on a grid around it.

    Parameters
    ----------
    vertices : (V, 3) float64 array
        Vertices (m), in the frame the grid is to be in.
    faces : (F, 3) int64 array
        Outward-oriented triangles.
    resolution : int
        Cells along the mesh's longest extent, >= 4.

    Returns
    -------
    origin : (3,) float64
        Position (m) of node (0, 0, 0).
    cell : float
        Node spacing (m).
    values : (nx, ny, nz) float64
        Signed distances (m), negative inside, with :data:`GRID_PADDING` cells beyond the mesh
        on every side.
    """
    lo = vertices.min(axis=0)
    hi = vertices.max(axis=0)
    cell = float((hi - lo).max()) / resolution
    origin = lo - GRID_PADDING * cell
    dims = np.ceil((hi - lo) / cell).astype(np.int64) + 2 * GRID_PADDING + 1
    values = np.empty(tuple(int(n) for n in dims))
    _grid_values(vertices, faces, origin, cell, int(dims[0]), int(dims[1]), int(dims[2]), values)
    return origin, cell, values


def pack_sdfs(sdfs: Sequence[tuple]) -> tuple[NDArray[np.int64], NDArray[np.int64],
                                              NDArray[np.float64], NDArray[np.float64],
                                              NDArray[np.float64]]:
    """Pack the bodies' distance functions for :func:`body_distance`.

    Parameters
    ----------
    sdfs : sequence of tuples
        Per body ``("convex", planes (F, 4))`` or ``("grid", origin, cell, values)``.

    Returns
    -------
    kinds : (B,) int64
        :data:`SDF_CONVEX` or :data:`SDF_GRID`.
    plane_start : (B + 1,) int64
        Body ``b``'s planes are rows ``plane_start[b]:plane_start[b + 1]`` of ``planes``.
    planes : (P, 4) float64
    grid_meta : (B, 8) float64
        ``origin (3), cell, nx, ny, nz, offset`` of a grid body's values in ``grid_values``.
    grid_values : (G,) float64
    """
    b = len(sdfs)
    kinds = np.zeros(b, dtype=np.int64)
    plane_start = np.zeros(b + 1, dtype=np.int64)
    planes = []
    meta = np.zeros((b, 8))
    values = []
    offset = 0
    for i, sdf in enumerate(sdfs):
        if sdf[0] == "convex":
            kinds[i] = SDF_CONVEX
            planes.append(sdf[1])
            plane_start[i + 1] = plane_start[i] + sdf[1].shape[0]
        else:
            kinds[i] = SDF_GRID
            plane_start[i + 1] = plane_start[i]
            origin, cell, grid = sdf[1], sdf[2], sdf[3]
            meta[i] = [*origin, cell, *grid.shape, offset]
            values.append(grid.ravel())
            offset += grid.size
    planes = np.concatenate(planes) if planes else np.zeros((0, 4))
    values = np.concatenate(values) if values else np.zeros(0)
    return (kinds, plane_start, np.ascontiguousarray(planes), meta,
            np.ascontiguousarray(values))


@njit(cache=True)
def convex_distance(planes, start, stop, x, y, z, ux, uy, uz, tie):
    """Largest plane distance over rows ``start:stop`` of ``planes`` at ``(x, y, z)``, and the
    normal; among faces within ``tie`` (m) of the largest, the one the velocity ``u`` moves into
    fastest (least ``n . u``), with that face's own distance (so that the contact is exactly
    that face's half-space)."""
    best = -np.inf
    for f in range(start, stop):
        s = planes[f, 0] * x + planes[f, 1] * y + planes[f, 2] * z - planes[f, 3]
        if s > best:
            best = s
    pick = -1
    rate = np.inf
    value = best
    for f in range(start, stop):
        s = planes[f, 0] * x + planes[f, 1] * y + planes[f, 2] * z - planes[f, 3]
        if s >= best - tie:
            un = planes[f, 0] * ux + planes[f, 1] * uy + planes[f, 2] * uz
            if un < rate:
                rate = un
                pick = f
                value = s
    return value, planes[pick, 0], planes[pick, 1], planes[pick, 2]


@njit(cache=True)
def grid_distance(values, offset, nx, ny, nz, ox, oy, oz, cell, x, y, z):
    """Trilinear signed distance and normalised gradient of a packed grid at ``(x, y, z)``;
    beyond the grid, the value at the nearest grid point plus the distance to it."""
    fx = (x - ox) / cell
    fy = (y - oy) / cell
    fz = (z - oz) / cell
    cx = min(max(fx, 0.0), nx - 1.0)
    cy = min(max(fy, 0.0), ny - 1.0)
    cz = min(max(fz, 0.0), nz - 1.0)
    outside = math.sqrt((fx - cx) ** 2 + (fy - cy) ** 2 + (fz - cz) ** 2) * cell
    i = min(int(cx), nx - 2)
    j = min(int(cy), ny - 2)
    k = min(int(cz), nz - 2)
    tx = cx - i
    ty = cy - j
    tz = cz - k
    c = np.empty(8)
    for a in range(2):
        for b in range(2):
            for e in range(2):
                c[4 * a + 2 * b + e] = values[offset + ((i + a) * ny + (j + b)) * nz + (k + e)]
    # trilinear value and its derivatives
    c00 = c[0] * (1 - tx) + c[4] * tx
    c01 = c[1] * (1 - tx) + c[5] * tx
    c10 = c[2] * (1 - tx) + c[6] * tx
    c11 = c[3] * (1 - tx) + c[7] * tx
    c0 = c00 * (1 - ty) + c10 * ty
    c1 = c01 * (1 - ty) + c11 * ty
    value = c0 * (1 - tz) + c1 * tz
    gz = c1 - c0
    gy = (c10 - c00) * (1 - tz) + (c11 - c01) * tz
    d00 = c[4] - c[0]
    d01 = c[5] - c[1]
    d10 = c[6] - c[2]
    d11 = c[7] - c[3]
    gx = ((d00 * (1 - ty) + d10 * ty) * (1 - tz) + (d01 * (1 - ty) + d11 * ty) * tz)
    if outside > 0.0:
        gx = fx - cx
        gy = fy - cy
        gz = fz - cz
    g = math.sqrt(gx * gx + gy * gy + gz * gz)
    if g > 0.0:
        return value + outside, gx / g, gy / g, gz / g
    return value + outside, 0.0, 0.0, 1.0


@njit(cache=True)
def body_distance(kinds, plane_start, planes, grid_meta, grid_values, body, x, y, z,
                  ux, uy, uz, tie):
    """Signed distance (m) and outward unit normal of packed body ``body`` at the body-frame
    point ``(x, y, z)`` moving at ``u`` relative to it (see :func:`convex_distance`)."""
    if kinds[body] == SDF_CONVEX:
        return convex_distance(planes, plane_start[body], plane_start[body + 1], x, y, z,
                               ux, uy, uz, tie)
    m = grid_meta[body]
    return grid_distance(grid_values, np.int64(m[7]), np.int64(m[4]), np.int64(m[5]),
                         np.int64(m[6]), m[0], m[1], m[2], m[3], x, y, z)


@njit(parallel=True, cache=True)
def body_distances(kinds, plane_start, planes, grid_meta, grid_values, body, points, velocities,
                   tie, out_d, out_n):
    """:func:`body_distance` at many body-frame points (N, 3) with relative velocities (N, 3),
    into ``out_d`` (N,) and ``out_n`` (N, 3)."""
    for i in prange(points.shape[0]):
        d, n0, n1, n2 = body_distance(kinds, plane_start, planes, grid_meta, grid_values, body,
                                      points[i, 0], points[i, 1], points[i, 2],
                                      velocities[i, 0], velocities[i, 1], velocities[i, 2], tie)
        out_d[i] = d
        out_n[i, 0] = n0
        out_n[i, 1] = n1
        out_n[i, 2] = n2


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
