"""Particle attributes carried to a surface: kernel-weighted (Shepard) averages at its vertices.

The weights are the splatting kernel's profile (:mod:`filters.kernels`) at each vertex, so a
surface vertex takes the attributes (velocity, age, colour, ...) of the particles whose field
made it; the particles are binned by block as for the splat (:mod:`filters.surface.blocks`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit, prange

from ..binning import lookup
from ..kernels import ZHU_BRIDSON, splat_kernel_id, splat_profile
from ..validation import check_points
from .blocks import bin_by_block
from .grid import BLOCK_LIMIT, check_block_range, pack_key
from .splat import check_splat_args

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, NDArray

__all__ = ["interpolate_attributes"]


@njit(cache=True, inline="always")
def _block_gap(x, lo, size):
    """Distance along one axis from ``x`` to the block ``[lo, lo + size]`` (voxel units)."""
    if x < lo:
        return lo - x
    if x > lo + size:
        return x - lo - size
    return 0.0


@njit(cache=True)
def _nearest(x, P, start, table, ranks, reach, bsz, bx, by, bz):
    """Index of the particle nearest to ``x`` in the blocks within ``reach`` (or -1)."""
    best = -1
    best_d2 = np.inf
    for dz in range(-reach, reach + 1):
        for dy in range(-reach, reach + 1):
            for dx in range(-reach, reach + 1):
                v = lookup(table, ranks, pack_key(bx + dx, by + dy, bz + dz))
                if v < 0:
                    continue
                for q in range(start[v], start[v + 1]):
                    ex = x[0] - P[q, 0]
                    ey = x[1] - P[q, 1]
                    ez = x[2] - P[q, 2]
                    d2 = ex * ex + ey * ey + ez * ez
                    if d2 < best_d2:
                        best_d2 = d2
                        best = q
    return best


@njit(parallel=True, cache=True, fastmath=True)
def _shepard(X, P, H, V, start, table, ranks, reach, bsz, kernel, blob_a, blob_e):
    m = X.shape[0]
    k = V.shape[1]
    hmax = 0.0
    for q in range(H.shape[0]):
        hmax = max(hmax, H[q])
    hmax2 = hmax * hmax * (1.0 + 1e-6)
    out = np.zeros((m, k), np.float64)
    for t in prange(m):
        bx = np.int64(math.floor(X[t, 0] / bsz))
        by = np.int64(math.floor(X[t, 1] / bsz))
        bz = np.int64(math.floor(X[t, 2] / bsz))
        wsum = 0.0
        best = -1
        best_d2 = np.inf
        skipped = False
        for dz in range(-reach, reach + 1):
            gz = _block_gap(X[t, 2], (bz + dz) * bsz, bsz)
            for dy in range(-reach, reach + 1):
                gy = _block_gap(X[t, 1], (by + dy) * bsz, bsz)
                for dx in range(-reach, reach + 1):
                    gx = _block_gap(X[t, 0], (bx + dx) * bsz, bsz)
                    # a block farther than every support cannot weigh (if no kernel reaches
                    # the point at all, the nearest-particle search below sees every block)
                    if gx * gx + gy * gy + gz * gz > hmax2:
                        skipped = True
                        continue
                    v = lookup(table, ranks, pack_key(bx + dx, by + dy, bz + dz))
                    if v < 0:
                        continue
                    for q in range(start[v], start[v + 1]):
                        ex = X[t, 0] - P[q, 0]
                        ey = X[t, 1] - P[q, 1]
                        ez = X[t, 2] - P[q, 2]
                        d2 = ex * ex + ey * ey + ez * ez
                        if d2 < best_d2:
                            best_d2 = d2
                            best = q
                        h2 = H[q] * H[q]
                        if d2 < h2:
                            w = splat_profile(kernel if kernel != ZHU_BRIDSON else 1,
                                              np.float32(d2 / h2), blob_a, blob_e)
                            wsum += w
                            for c in range(k):
                                out[t, c] += w * V[q, c]
        if wsum == 0 and skipped:
            best = _nearest(X[t], P, start, table, ranks, reach, bsz, bx, by, bz)
        if wsum > 0:
            for c in range(k):
                out[t, c] /= wsum
        elif best >= 0:
            for c in range(k):
                out[t, c] = V[best, c]
    return out


def interpolate_attributes(points: np.ndarray, positions: np.ndarray, radius: ArrayLike,
                           values: ArrayLike, *, cell_size: float, kernel: str = "sph",
                           support_r: float | None = None,
                           blobbiness: float = 4.0) -> NDArray[np.float64]:
    """Kernel-weighted (Shepard) average of particle values at arbitrary points.

    ``u(x) = sum_j w_j u_j / sum_j w_j`` with ``w_j`` the kernel of particle ``j`` at ``x``
    (where no kernel reaches, the value of the nearest particle among those in the neighbouring
    blocks, and zero when there is none: surface vertices always lie within some support).

    Parameters
    ----------
    points : (M, 3) float64
        Where to interpolate (m), e.g. surface vertices.
    positions : (N, 3) float64
        Particle centres (m).
    radius : float or (N,) float64
        Particle radii (m).
    values : (N,) or (N, k) array
        Particle values (e.g. velocity, m/s).
    cell_size : float
        Voxel edge (m) used for the block index (the blocks are ``8`` voxels wide).
    kernel, support_r, blobbiness
        As in :func:`filters.surface.splat.splat_sparse`.

    Returns
    -------
    (M,) or (M, k) float64
    """
    points = check_points("points", points)
    positions, radii, kernel, cell_size, support_r, _, _, blobbiness, _ = check_splat_args(
        positions, radius, cell_size, kernel, support_r, None, 8, blobbiness, 1)
    bsz = 8
    H = radii * (support_r / cell_size)  # support radius, voxel units
    vals = np.asarray(values, dtype=np.float64)
    flat = vals.ndim == 1
    vals2 = vals.reshape(vals.shape[0], -1)
    if vals2.shape[0] != positions.shape[0]:
        raise ValueError(f"values must have {positions.shape[0]} rows, got {vals2.shape[0]}")
    if positions.shape[0] == 0 or points.shape[0] == 0:
        out = np.zeros((points.shape[0], vals2.shape[1]))
        return out[:, 0] if flat else out
    check_block_range("positions", positions, cell_size, bsz)
    table, ranks, unique, start, order = bin_by_block(positions, cell_size, bsz)
    P = np.ascontiguousarray(positions[order] / cell_size)
    Hs = np.ascontiguousarray(H[order])
    V = np.ascontiguousarray(vals2[order])
    reach = int(math.ceil((Hs.max() + 1.0) / bsz))
    X = np.ascontiguousarray(points / cell_size)
    # points whose neighbouring blocks leave the key range are farther than any support from
    # every particle (those keep a margin of more than ``reach`` blocks): they get 0, as points
    # with no particle near do, and are not looked up (their keys would wrap)
    with np.errstate(over="ignore", invalid="ignore"):
        home = np.floor(X / bsz)
    near = ((home >= -BLOCK_LIMIT + reach + 1) & (home <= BLOCK_LIMIT - reach - 2)).all(axis=1)
    args = (P, Hs, V, start, table, ranks, reach, bsz, splat_kernel_id(kernel),
            np.float32(blobbiness), np.float32(math.exp(-blobbiness)))
    if near.all():
        out = _shepard(X, *args)
    else:
        out = np.zeros((X.shape[0], V.shape[1]))
        out[near] = _shepard(np.ascontiguousarray(X[near]), *args)
    return out[:, 0] if flat else out
