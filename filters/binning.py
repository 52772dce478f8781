"""Binning points into cells and indexing integer keys: the one counting sort of the package.

Three tools shared by the neighbour search, the SPH solver, the splatting and smoothing kernels
and the mesh stitching:

* **Cells of a uniform grid.** :func:`cell_keys` gives the cell of every point (x fastest),
  :func:`counting_sort` orders any integer keys into buckets (parallel and stable: each of
  ``nchunks`` chunks counts its points per bucket, one prefix sum over (bucket, chunk), each
  chunk scatters its points; Green 2008, "Particle simulation using CUDA"; Hoetzlein 2014,
  "Fast fixed-radius nearest neighbors"), and :func:`sort_into_cells` combines them with a
  gather of the points in cell order. :func:`fitting_cells` sizes such a grid over a cloud,
  growing the cells over a sparse domain so that the grid stays small.
* **An open-addressing hash index of int64 keys** (linear probing, Fibonacci hashing): the
  table behind the sparse voxel blocks and the merging of coincident mesh vertices.
  :func:`index_keys` indexes a key array; :func:`probe`, :func:`lookup` and :func:`insert_key`
  are the ``@njit`` operations other kernels call.

A stable counting sort has one result, so the order is the same for any number of chunks or
threads: everything built on it is deterministic.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit, prange

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

__all__ = [
    "cell_keys",
    "counting_sort",
    "gather_points",
    "sort_into_cells",
    "cell_window",
    "fitting_cells",
    "MAX_CELLS",
    "EMPTY_KEY",
    "probe",
    "lookup",
    "insert_key",
    "index_keys",
]

#: Largest number of cells :func:`fitting_cells` aims for (32 MB of cell offsets).
MAX_CELLS = 4_000_000


# --------------------------------------------------------------------------------------------
# Cells of a uniform grid and the counting sort
# --------------------------------------------------------------------------------------------
@njit(parallel=True, cache=True, error_model="numpy")
def cell_keys(x, origin, inv_cell, dims):
    """Cell index of every point in a uniform grid, x fastest.

    Parameters
    ----------
    x : (N, 3) float64
        Points (m).
    origin : (3,) float64
        Corner of cell ``(0, 0, 0)`` (m).
    inv_cell : float
        Inverse cell edge (1/m).
    dims : (3,) int64
        Cells along x, y, z.

    Returns
    -------
    (N,) int64
        ``(iz * dims[1] + iy) * dims[0] + ix`` with ``i = floor((x - origin) * inv_cell)``
        clamped to the grid (in floating point before the conversion to an integer, so that
        points far outside, even ``+-1.7e308`` apart, land in the border cells).
    """
    n = x.shape[0]
    nx = dims[0]
    ny = dims[1]
    nz = dims[2]
    keys = np.empty(n, dtype=np.int64)
    for i in prange(n):
        cx = int(min(max(np.floor((x[i, 0] - origin[0]) * inv_cell), 0.0), nx - 1.0))
        cy = int(min(max(np.floor((x[i, 1] - origin[1]) * inv_cell), 0.0), ny - 1.0))
        cz = int(min(max(np.floor((x[i, 2] - origin[2]) * inv_cell), 0.0), nz - 1.0))
        keys[i] = (cz * ny + cy) * nx + cx
    return keys


@njit(parallel=True, cache=True, error_model="numpy")
def counting_sort(keys, nkeys, nchunks):
    """Stable counting sort of ``keys`` in ``[0, nkeys)``.

    Parameters
    ----------
    keys : (N,) int64
        Bucket of every item.
    nkeys : int
        Number of buckets.
    nchunks : int
        Chunks counted and scattered in parallel, >= 1 (1: serial). The result does not
        depend on it; the scratch is ``nchunks * nkeys`` counts.

    Returns
    -------
    start : (nkeys + 1,) int64
        Bucket ``k`` holds ``order[start[k]:start[k + 1]]``.
    order : (N,) int32
        Item indices in bucket order, ascending within each bucket.
    """
    n = keys.shape[0]
    chunk = (n + nchunks - 1) // nchunks
    counts = np.zeros((nchunks, nkeys), dtype=np.int64)
    for c in prange(nchunks):
        lo = c * chunk
        hi = min(n, lo + chunk)
        for i in range(lo, hi):
            counts[c, keys[i]] += 1
    start = np.empty(nkeys + 1, dtype=np.int64)
    total = 0
    for k in range(nkeys):
        start[k] = total
        for c in range(nchunks):
            t = counts[c, k]
            counts[c, k] = total
            total += t
    start[nkeys] = total
    order = np.empty(n, dtype=np.int32)
    for c in prange(nchunks):
        lo = c * chunk
        hi = min(n, lo + chunk)
        for i in range(lo, hi):
            k = keys[i]
            order[counts[c, k]] = i
            counts[c, k] += 1
    return start, order


@njit(parallel=True, cache=True)
def gather_points(x, order):
    """``x[order]`` for (N, 3) points and an index array (parallel)."""
    out = np.empty((order.shape[0], 3))
    for k in prange(order.shape[0]):
        i = order[k]
        out[k, 0] = x[i, 0]
        out[k, 1] = x[i, 1]
        out[k, 2] = x[i, 2]
    return out


def sort_into_cells(points: np.ndarray, origin: ArrayLike, inv_cell: float, dims: ArrayLike,
                    nchunks: int = 1) -> tuple[NDArray[np.int32], NDArray[np.int64],
                                               NDArray[np.float64]]:
    """Points sorted into the cells of a uniform grid (x fastest).

    Parameters
    ----------
    points : (N, 3) float64
        Points (m).
    origin, inv_cell, dims
        The grid, as in :func:`cell_keys`.
    nchunks : int
        As in :func:`counting_sort`.

    Returns
    -------
    order : (N,) int32
        Point indices in cell order.
    start : (C + 1,) int64
        Cell ``c`` holds ``order[start[c]:start[c + 1]]``.
    sorted_points : (N, 3) float64
        ``points[order]``.
    """
    dims = np.asarray(dims, dtype=np.int64)
    keys = cell_keys(points, np.asarray(origin, dtype=np.float64), float(inv_cell), dims)
    start, order = counting_sort(keys, int(np.prod(dims)), int(nchunks))
    return order, start, gather_points(points, order)


@njit(cache=True, inline="always")
def cell_window(cidx, dims, reach, start, origin, cell):
    """Corner (m) of cell ``cidx`` and the window of cells within ``reach`` of it: returns
    ``(ox, oy, oz, xa, xb, ya, yb, za, zb, total)`` with the inclusive x / y / z cell ranges and
    the number of points in the window (points sorted by :func:`sort_into_cells`, ``start``
    its cell offsets)."""
    nx = dims[0]
    ny = dims[1]
    nz = dims[2]
    ix = cidx % nx
    iy = (cidx // nx) % ny
    iz = cidx // (nx * ny)
    xa = max(ix - reach, 0)
    xb = min(ix + reach, nx - 1)
    ya = max(iy - reach, 0)
    yb = min(iy + reach, ny - 1)
    za = max(iz - reach, 0)
    zb = min(iz + reach, nz - 1)
    total = 0
    for z in range(za, zb + 1):
        for y in range(ya, yb + 1):
            row = (z * ny + y) * nx
            total += start[row + xb + 1] - start[row + xa]
    return (origin[0] + ix * cell, origin[1] + iy * cell, origin[2] + iz * cell,
            xa, xb, ya, yb, za, zb, total)


def fitting_cells(points: np.ndarray, width: float,
                  max_cells: int = MAX_CELLS) -> tuple[NDArray[np.float64], float,
                                                       NDArray[np.int64]]:
    """A uniform grid over ``points`` with cells at least ``width`` wide.

    Cells are padded by ``1e-9`` relative, so that the 27 cells around a point hold every point
    within ``width`` whatever the rounding of the binning. Over a large sparse domain the cells
    grow until there are at most about ``max_cells`` (up to twice that): more candidates per
    cell, the same sums.

    Parameters
    ----------
    points : (N, 3) float64, N >= 1
        Points (m).
    width : float
        Smallest cell edge (m), > 0.
    max_cells : int
        Cell budget.

    Returns
    -------
    origin : (3,) float64
        The points' lower corner (m).
    cell : float
        Cell edge (m).
    dims : (3,) int64
        Cells along x, y, z.
    """
    lo = points.min(axis=0)
    with np.errstate(over="ignore"):  # +-1.7e308 apart: the extent overflows; cap it
        extent = np.minimum(points.max(axis=0) - lo, np.finfo(np.float64).max)
    cell = width * (1.0 + 1e-9)
    with np.errstate(over="ignore"):
        count = float(np.prod(np.floor(extent / cell) + 1.0))
    # grow the cells until they fit: one step by the cube root of the excess for a cloud spread
    # along all three axes (then within the +1 per axis of the budget, as always); more steps,
    # by the root of as many axes as the cloud spreads along, for thinner spreads (one step
    # would leave a cloud spread along one axis with up to max_cells ** (2/3) times too many
    # cells, and cell counts past int64 at a 1e300 spread)
    first = True
    while count > (max_cells if first else 2 * max_cells):
        if math.isinf(count):  # extent / cell overflowed (points ~1e308 apart)
            cell = max(cell, float(extent.max()) / max_cells)
        else:
            axes = max(int((np.floor(extent / cell) > 0).sum()), 1)
            cell *= max((count / max_cells) ** (1.0 / axes), 1.0 + 1e-6)
        first = False
        with np.errstate(over="ignore"):
            count = float(np.prod(np.floor(extent / cell) + 1.0))
    return lo, cell, (np.floor(extent / cell) + 1.0).astype(np.int64)


# --------------------------------------------------------------------------------------------
# Open-addressing hash index of int64 keys
# --------------------------------------------------------------------------------------------
#: The value of an empty slot of a hash table (keys are never -1).
EMPTY_KEY = -1


@njit(cache=True, inline="always")
def probe(table, key):
    """Slot of ``key`` in ``table`` (linear probing), or of the empty slot where it would go.

    ``table`` is a power-of-two (C,) int64 array of keys, :data:`EMPTY_KEY` where free.
    """
    mask = table.size - 1
    h = key * -7046029254386353131  # Fibonacci hashing, wraps in int64
    i = (h ^ (h >> 29)) & mask
    while table[i] != EMPTY_KEY and table[i] != key:
        i = (i + 1) & mask
    return i


@njit(cache=True, inline="always")
def lookup(table, values, key):
    """Value stored for ``key``, or -1 if absent."""
    i = probe(table, key)
    if table[i] == EMPTY_KEY:
        return -1
    return values[i]


@njit(cache=True)
def _rehash(unique, count, capacity):
    table = np.full(capacity, EMPTY_KEY, np.int64)
    values = np.empty(capacity, np.int64)
    for u in range(count):
        i = probe(table, unique[u])
        table[i] = unique[u]
        values[i] = u
    return table, values


@njit(cache=True, inline="always")
def insert_key(table, values, unique, count, key):
    """Insert ``key`` (if new) into a growing index.

    ``table``/``values`` map keys to ranks, ``unique[:count]`` lists the keys in order of
    insertion. Returns ``(table, values, unique, count, rank)``: the arrays (reallocated,
    twice as large, when full) and the key's rank.
    """
    i = probe(table, key)
    if table[i] != EMPTY_KEY:
        return table, values, unique, count, values[i]
    if 2 * (count + 1) > table.size:
        table, values = _rehash(unique, count, 2 * table.size)
        i = probe(table, key)
    if count == unique.size:
        grown = np.empty(2 * unique.size, np.int64)
        grown[:count] = unique[:count]
        unique = grown
    table[i] = key
    values[i] = count
    unique[count] = key
    return table, values, unique, count + 1, count


@njit(cache=True)
def index_keys(keys):
    """Hash index of integer keys.

    Parameters
    ----------
    keys : (M,) int64
        Keys (never :data:`EMPTY_KEY`), possibly repeated.

    Returns
    -------
    table, values : (C,) int64
        The open-addressing table and the rank stored for each key (see :func:`lookup`).
    unique : (U,) int64
        The distinct keys in order of first appearance.
    inverse : (M,) int64
        Rank of each input key in ``unique``.
    """
    n = keys.size
    table = np.full(1024, EMPTY_KEY, np.int64)
    values = np.empty(1024, np.int64)
    unique = np.empty(1024, np.int64)
    inverse = np.empty(n, np.int64)
    count = 0
    for t in range(n):
        table, values, unique, count, r = insert_key(table, values, unique, count, keys[t])
        inverse[t] = r
    return table, values, unique[:count].copy(), inverse
