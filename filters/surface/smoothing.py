"""Feature-weighted Laplacian smoothing of reconstructed liquid surfaces, in Numba.

Löschner, Böttcher, Jeske & Bender (2023), "Weighted Laplacian smoothing for surface
reconstruction of particle-based fluids" (VMV 2023): plain Laplacian smoothing removes the
particle-scale bumps of a marching-cubes surface but also shrinks and erases thin features
(sheets, droplets); weighting each vertex's step by how *full* its particle neighbourhood is
smooths the bulk liquid fully and leaves thin features alone.

Here, for every vertex ``v``:

* fullness ``n_v = sum_j (1 - |v - x_j|^2 / R^2)`` over the particles ``x_j`` within ``R``
  (``R = reach_r * r``, default ``8 r``, four particle spacings: wide enough that the layers
  under a surface count, so that a sheet one particle thick looks half as full as a pool),
  divided by the value ``n_flat`` of a point half a spacing above the flat top of a lattice pool
  (computed per call on a small lattice, so it follows ``R`` and ``r``);
* weight ``w_v = smoothstep((n_v - low) / (high - low))`` with ``low = 0.5, high = 1``: flat
  liquid smoothed fully, small balls hardly, sheets and droplets not at all;
* ``iterations`` Jacobi sweeps ``v <- v + beta w_v (mean of v's edge neighbours - v)``.

Laplacian smoothing moves convex regions inward (mean-curvature flow); the weights, not a
volume constraint, limit that. The particles are sorted into cells by :mod:`filters.binning`;
measurements behind the defaults are in ``benchmarks/results/surface_notes.md``.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit, prange

from ..binning import fitting_cells, sort_into_cells
from ..elastic.topology import check_triangles
from ..validation import check_int, check_points, check_range

if TYPE_CHECKING:
    from numpy.typing import NDArray

__all__ = ["vertex_neighbors", "feature_weights", "weighted_laplacian", "smooth_surface"]


def vertex_neighbors(triangles: np.ndarray,
                     n_vertices: int) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Edge neighbours of every vertex of a triangle mesh as CSR arrays.

    Parameters
    ----------
    triangles : (M, 3) int
        Vertex indices.
    n_vertices : int
        Number of vertices.

    Returns
    -------
    offsets : (n_vertices + 1,) int64
    neighbors : (E,) int64
        ``neighbors[offsets[v]:offsets[v + 1]]`` are the vertices sharing an edge with ``v``,
        ascending, each once.
    """
    n_vertices = check_int("n_vertices", n_vertices, 0)
    t = check_triangles("triangles", triangles, n_vertices, allow_empty=True,
                        allow_degenerate=True)
    return _csr_neighbors(np.ascontiguousarray(t), n_vertices)


@njit(cache=True)
def _csr_neighbors(t, n):
    """Counting sort of the triangles' directed edges by their first vertex, then each vertex's
    short list sorted and deduplicated in place (an edge shared by two triangles appears twice)."""
    count = np.zeros(n + 1, np.int64)
    for f in range(t.shape[0]):
        for k in range(3):
            count[t[f, k] + 1] += 2
    for v in range(n):
        count[v + 1] += count[v]
    fill = count[:-1].copy()
    raw = np.empty(count[n], np.int64)
    for f in range(t.shape[0]):
        for k in range(3):
            a = t[f, k]
            raw[fill[a]] = t[f, (k + 1) % 3]
            raw[fill[a] + 1] = t[f, (k + 2) % 3]
            fill[a] += 2
    offsets = np.zeros(n + 1, np.int64)
    out = 0
    for v in range(n):
        lo = count[v]
        hi = count[v + 1]
        for i in range(lo + 1, hi):  # insertion sort in place: the lists are short
            x = raw[i]
            j = i - 1
            while j >= lo and raw[j] > x:
                raw[j + 1] = raw[j]
                j -= 1
            raw[j + 1] = x
        for i in range(lo, hi):
            if i == lo or raw[i] != raw[i - 1]:
                raw[out] = raw[i]
                out += 1
        offsets[v + 1] = out
    return offsets, raw[:out].copy()


@njit(parallel=True, cache=True)
def _fullness(v, sx, start, origin, cell, dims, R):
    """``sum_j (1 - (d / R)^2)`` over the sorted particles ``sx`` within ``R`` of each vertex."""
    nx = dims[0]
    ny = dims[1]
    nz = dims[2]
    out = np.zeros(v.shape[0])
    inv_r2 = 1.0 / (R * R)
    for i in prange(v.shape[0]):
        cx = int(math.floor((v[i, 0] - origin[0]) / cell))
        cy = int(math.floor((v[i, 1] - origin[1]) / cell))
        cz = int(math.floor((v[i, 2] - origin[2]) / cell))
        s = 0.0
        for z in range(max(cz - 1, 0), min(cz + 1, nz - 1) + 1):
            for y in range(max(cy - 1, 0), min(cy + 1, ny - 1) + 1):
                row = (z * ny + y) * nx
                xa = max(cx - 1, 0)
                xb = min(cx + 1, nx - 1)
                if xa > xb:
                    continue
                for k in range(start[row + xa], start[row + xb + 1]):
                    d0 = sx[k, 0] - v[i, 0]
                    d1 = sx[k, 1] - v[i, 1]
                    d2 = sx[k, 2] - v[i, 2]
                    q = (d0 * d0 + d1 * d1 + d2 * d2) * inv_r2
                    if q < 1.0:
                        t = 1.0 - q
                        s += t
        out[i] = s
    return out


def _raw_fullness(vertices, positions, R):
    if positions.shape[0] == 0:
        return np.zeros(vertices.shape[0])
    lo, cell, dims = fitting_cells(positions, R)
    _, start, sx = sort_into_cells(positions, lo, 1.0 / cell, dims)
    return _fullness(vertices, sx, start, lo, cell, dims, R)


def _flat_fullness(spacing, R):
    """Fullness of a point half a spacing above the middle of a flat lattice pool's top."""
    m = int(math.ceil(R / spacing)) + 1
    g = np.arange(-m, m + 1, dtype=np.float64) * spacing
    z = -np.arange(0, m + 1, dtype=np.float64) * spacing
    lat = np.stack(np.meshgrid(g, g, z, indexing="ij"), -1).reshape(-1, 3)
    return float(_raw_fullness(np.array([[0.0, 0.0, 0.5 * spacing]]), lat, R)[0])


def feature_weights(vertices: np.ndarray, positions: np.ndarray, radius: float, *,
                    reach_r: float = 8.0, low: float = 0.5,
                    high: float = 1.0) -> NDArray[np.float64]:
    """Per-vertex smoothing weights in [0, 1] from the fullness of the particle neighbourhood.

    Parameters
    ----------
    vertices : (V, 3) float64
        Mesh vertices (m).
    positions : (N, 3) float64
        Particle centres (m), spacing ``2 * radius``.
    radius : float
        Particle radius ``r`` (m), > 0.
    reach_r : float
        Neighbourhood radius ``R`` over ``r``, in [1, 20]; default 8 (four spacings).
    low, high : float
        Fullness (relative to a flat surface) below which the weight is 0 and above which it is
        1, ``0 <= low < high <= 2``. Defaults 0.5 and 1 (see the module docstring).

    Returns
    -------
    (V,) float64
    """
    vertices = check_points("vertices", vertices)
    positions = check_points("positions", positions)
    radius = check_range("radius", radius, 0.0, math.inf, low_inclusive=False)
    reach_r = check_range("reach_r", reach_r, 1.0, 20.0)
    low = check_range("low", low, 0.0, 2.0)
    high = check_range("high", high, 0.0, 2.0)
    if not low < high:
        raise ValueError(f"low must be < high, got low={low}, high={high}")
    R = reach_r * radius
    n = _raw_fullness(vertices, positions, R) / _flat_fullness(2.0 * radius, R)
    u = np.clip((n - low) / (high - low), 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


@njit(parallel=True, cache=True)
def _sweeps(x, offsets, neighbors, step, free, iterations):
    y = x.copy()
    z = np.empty_like(x)
    for _ in range(iterations):
        for v in prange(x.shape[0]):
            a = offsets[v]
            b = offsets[v + 1]
            if b == a or step[v] == 0.0:
                z[v, 0] = y[v, 0]
                z[v, 1] = y[v, 1]
                z[v, 2] = y[v, 2]
                continue
            m0 = 0.0
            m1 = 0.0
            m2 = 0.0
            for k in range(a, b):
                u = neighbors[k]
                m0 += y[u, 0]
                m1 += y[u, 1]
                m2 += y[u, 2]
            inv = 1.0 / (b - a)
            s = step[v]
            z[v, 0] = y[v, 0] + s * free[v, 0] * (m0 * inv - y[v, 0])
            z[v, 1] = y[v, 1] + s * free[v, 1] * (m1 * inv - y[v, 1])
            z[v, 2] = y[v, 2] + s * free[v, 2] * (m2 * inv - y[v, 2])
        y, z = z, y
    return y


def weighted_laplacian(vertices: np.ndarray, triangles: np.ndarray, weights: np.ndarray, *,
                       iterations: int = 25, beta: float = 1.0,
                       free: np.ndarray | None = None) -> NDArray[np.float64]:
    """``iterations`` Jacobi sweeps ``v <- v + beta w_v (mean of edge neighbours - v)``.

    Parameters
    ----------
    vertices : (V, 3) float64
        Mesh vertices (m).
    triangles : (M, 3) int
        Vertex indices.
    weights : (V,) float64
        Per-vertex weights in [0, 1] (e.g. :func:`feature_weights`); 0 keeps a vertex fixed.
    iterations : int
        Number of sweeps, in [0, 10000].
    beta : float
        Step, in (0, 1].
    free : (V, 3) float64, optional
        Per-vertex, per-axis factors of the step in [0, 1] (0: the vertex does not move along
        that axis, e.g. a vertex on a wall of the liquid's tank,
        :func:`filters.surface.clip.wall_constraints`); all 1 by default.

    Returns
    -------
    (V, 3) float64
        Smoothed vertices (a new array; the input is not modified).
    """
    vertices = check_points("vertices", vertices)
    iterations = check_int("iterations", iterations, 0, 10000)
    beta = check_range("beta", beta, 0.0, 1.0, low_inclusive=False)
    w = np.ascontiguousarray(weights, dtype=np.float64)
    if w.shape != (vertices.shape[0],):
        raise ValueError(f"weights must have shape ({vertices.shape[0]},), got {w.shape}")
    if w.size and not (np.isfinite(w).all() and w.min() >= 0.0 and w.max() <= 1.0):
        raise ValueError("weights must be finite and in [0, 1]")
    if free is None:
        free = np.ones((vertices.shape[0], 3))
    free = np.ascontiguousarray(free, dtype=np.float64)
    if free.shape != vertices.shape:
        raise ValueError(f"free must have shape {vertices.shape}, got {free.shape}")
    if free.size and not (np.isfinite(free).all() and free.min() >= 0.0 and free.max() <= 1.0):
        raise ValueError("free must be finite and in [0, 1]")
    offsets, neighbors = vertex_neighbors(triangles, vertices.shape[0])
    if iterations == 0 or vertices.shape[0] == 0:
        return vertices.copy()
    return _sweeps(vertices, offsets, neighbors, beta * w, free, iterations)


def smooth_surface(vertices: np.ndarray, triangles: np.ndarray, positions: np.ndarray,
                   radius: float, *, iterations: int = 25, beta: float = 1.0, reach_r: float = 8.0,
                   low: float = 0.5, high: float = 1.0,
                   free: np.ndarray | None = None) -> NDArray[np.float64]:
    """:func:`feature_weights` then :func:`weighted_laplacian` (see the module docstring;
    ``free`` as there).

    Returns
    -------
    (V, 3) float64
        Smoothed vertices; the triangles are unchanged.
    """
    w = feature_weights(vertices, positions, radius, reach_r=reach_r, low=low, high=high)
    return weighted_laplacian(vertices, triangles, w, iterations=iterations, beta=beta,
                              free=free)
