"""Spherical splatting kernels on the sparse voxel grid, in Numba.

Particle ``j`` of radius ``r_j`` has support radius ``h_j = support_r * r_j`` (m) and
``q = |x - x_j| / h_j``; the profiles ``K(q^2)`` are those of :mod:`filters.kernels`
(``blobby``, Blinn 1982; ``metaball``, Wyvill et al. 1986; ``sph``; ``zhu_bridson``):

* ``blobby``, ``metaball``: ``f(x) = sum_j K(q_j^2)``;
* ``sph``: the SPH volume (colour) field ``f(x) = sum_j (m_j / rho_j) W(|x - x_j|, h_j)`` with
  the cubic spline of Monaghan (1992) and the particle densities from the same kernel,
  ``rho_j = sum_k m_k W(|x_j - x_k|, (h_j + h_k) / 2)``, ``m_j ~ r_j^3`` -- the field
  splashsurf reconstructs (Löschner et al. 2023); ``f`` is about 1 inside a liquid;
* ``zhu_bridson`` (Zhu & Bridson 2005, "Animating sand as a fluid"): the signed distance to a
  sphere of the weighted mean radius about the weighted mean centre,
  ``phi(x) = |x - xbar(x)| - rbar(x)`` with weights ``(1 - q^2)^3``.

The implicit value is ``g = iso - f`` (negative inside), for ``zhu_bridson`` ``g = phi`` in
voxel units. Blocks are chosen by :mod:`filters.surface.blocks`: the bound of a block is
the sum of every reaching particle's profile at its distance from the block grown by one voxel.

Each evaluated block gathers its particles once, filters them per voxel row and sums the
profiles in a loop the compiler vectorises across particles (a per-particle scatter over rows
did not vectorise and was 2x slower); every voxel's sum runs in a fixed order, so the values are
bitwise identical for any number of threads.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..binning import lookup
from ..kernels import ZHU_BRIDSON, splat_kernel_id, splat_profile, splat_row_profile
from .blocks import bin_by_block, blocks_meeting_box, classify_and_evaluate, grown_block_box
from .grid import SparseGrid, check_budget, dilate_keys, pack_key, unpack_key

__all__ = ["sphere_grid"]


@njit(cache=True, inline="always")
def _near_slots(bx, by, bz, lox, loy, loz, hix, hiy, hiz, bsz, hmax, table, ranks, reach, slots):
    """Home-block slots within ``hmax`` of the box [lo, hi] (voxel units); returns the count."""
    c = 0
    h2 = hmax * hmax
    for dz in range(-reach, reach + 1):
        gz = max((bz + dz) * bsz - hiz, 0.0, loz - (bz + dz + 1) * bsz)
        for dy in range(-reach, reach + 1):
            gy = max((by + dy) * bsz - hiy, 0.0, loy - (by + dy + 1) * bsz)
            for dx in range(-reach, reach + 1):
                gx = max((bx + dx) * bsz - hix, 0.0, lox - (bx + dx + 1) * bsz)
                if gx * gx + gy * gy + gz * gz >= h2:
                    continue
                v = lookup(table, ranks, pack_key(bx + dx, by + dy, bz + dz))
                if v >= 0:
                    slots[c] = v
                    c += 1
    return c


@njit(parallel=True, cache=True)
def _gather_scaled(pos, order, scale):
    out = np.empty((order.size, 3), np.float64)
    for t in prange(order.size):
        p = order[t]
        out[t, 0] = pos[p, 0] * scale
        out[t, 1] = pos[p, 1] * scale
        out[t, 2] = pos[p, 2] * scale
    return out


@njit(parallel=True, cache=True, fastmath=True)
def _sph_amplitudes(P, H, M, unique, start, table, ranks, reach, bsz, hmax, uniform):
    """``A_j = (m_j / rho_j) * 8 / (pi h_j^3)`` in voxel units, gathered per particle.

    ``rho_j = sum_k m_k W(|x_j - x_k|, (h_j + h_k) / 2)``; with ``uniform`` (all radii equal)
    the masses and supports are equal and a float32 SIMD loop is used."""
    n = P.shape[0]
    A = np.empty(n, np.float32)
    width = 2 * reach + 1
    h0 = np.float32(H[0])
    inv0 = np.float32(1.0) / (h0 * h0)
    for u in prange(unique.size):
        bx, by, bz = unpack_key(unique[u])
        slots = np.empty(width ** 3, np.int64)
        ns = _near_slots(bx, by, bz, bx * bsz, by * bsz, bz * bsz, (bx + 1) * bsz,
                         (by + 1) * bsz, (bz + 1) * bsz, bsz, hmax, table, ranks, reach, slots)
        # gather the candidate particles once per home block (float32, contiguous)
        total = 0
        for s in range(ns):
            total += start[slots[s] + 1] - start[slots[s]]
        cx = np.empty(total, np.float32)
        cy = np.empty(total, np.float32)
        cz = np.empty(total, np.float32)
        ch = np.empty(total, np.float64)
        cm = np.empty(total, np.float64)
        c = 0
        ox = np.float64(bx * bsz)
        oy = np.float64(by * bsz)
        oz = np.float64(bz * bsz)
        for s in range(ns):
            v = slots[s]
            for q in range(start[v], start[v + 1]):
                cx[c] = P[q, 0] - ox
                cy[c] = P[q, 1] - oy
                cz[c] = P[q, 2] - oz
                ch[c] = H[q]
                cm[c] = M[q]
                c += 1
        for p in range(start[u], start[u + 1]):
            px = np.float32(P[p, 0] - ox)
            py = np.float32(P[p, 1] - oy)
            pz = np.float32(P[p, 2] - oz)
            if uniform:
                acc = np.float32(0.0)
                for k in range(total):
                    ex = px - cx[k]
                    ey = py - cy[k]
                    ez = pz - cz[k]
                    q2 = (ex * ex + ey * ey + ez * ez) * inv0
                    q2 = q2 if q2 < np.float32(1.0) else np.float32(1.0)
                    acc += splat_row_profile(2, q2, np.float32(0.0), np.float32(0.0))
                # m and h equal: V = 1 / sum w * (pi h^3 / 8), A = V * 8 / (pi h^3)
                A[p] = np.float32(1.0) / acc
            else:
                rho = 0.0
                for k in range(total):
                    ex = px - cx[k]
                    ey = py - cy[k]
                    ez = pz - cz[k]
                    d2 = np.float64(ex * ex + ey * ey + ez * ez)
                    hh = 0.5 * (H[p] + ch[k])
                    if d2 < hh * hh:
                        w = splat_profile(2, np.float32(d2 / (hh * hh)), np.float32(0.0),
                                          np.float32(0.0))
                        rho += cm[k] * w * 8.0 / (math.pi * hh * hh * hh)
                A[p] = M[p] / rho * 8.0 / (math.pi * H[p] ** 3)
    return A


@njit(cache=True, fastmath=True)
def _zhu_bridson_block(buf, acc, bx, by, bz, bsz, P, H, R, start, table, ranks, reach, far):
    """Zhu & Bridson (2005) values ``|x - xbar| - rbar`` (voxel units) at the voxels of block
    (bx, by, bz): ``buf`` (n, n, n) float32 (z, y, x), ``acc`` (4, n, n, n) scratch."""
    n = buf.shape[0]
    ox = bx * bsz
    oy = by * bsz
    oz = bz * bsz
    buf[:] = 0.0
    acc[:] = 0.0
    top = np.float32(n - 1)
    for dz in range(-reach, reach + 1):
        for dy in range(-reach, reach + 1):
            for dx in range(-reach, reach + 1):
                v = lookup(table, ranks, pack_key(bx + dx, by + dy, bz + dz))
                if v < 0:
                    continue
                for q in range(start[v], start[v + 1]):
                    # particle in voxel units relative to the block's first voxel
                    px = np.float32(P[q, 0] - ox)
                    py = np.float32(P[q, 1] - oy)
                    pz = np.float32(P[q, 2] - oz)
                    h = np.float32(H[q])
                    if px + h < 0 or py + h < 0 or pz + h < 0:
                        continue
                    if px - h > top or py - h > top or pz - h > top:
                        continue
                    h2 = h * h
                    inv_h2 = np.float32(1.0) / h2
                    z0 = max(0, int(math.ceil(pz - h)))
                    z1 = min(n - 1, int(math.floor(pz + h)))
                    y0 = max(0, int(math.ceil(py - h)))
                    y1 = min(n - 1, int(math.floor(py + h)))
                    rq = np.float32(R[q])
                    for mz in range(z0, z1 + 1):
                        ez = np.float32(mz) - pz
                        rz = ez * ez
                        for my in range(y0, y1 + 1):
                            ey = np.float32(my) - py
                            ryz = rz + ey * ey
                            if ryz >= h2:
                                continue
                            half = math.sqrt(h2 - ryz)
                            x0 = max(0, int(math.ceil(px - half)))
                            x1 = min(n - 1, int(math.floor(px + half)))
                            for mx in range(x0, x1 + 1):
                                ex = np.float32(mx) - px
                                q2 = min((ex * ex + ryz) * inv_h2, np.float32(1.0))
                                t = np.float32(1.0) - q2
                                w = t * t * t
                                buf[mz, my, mx] += w
                                acc[0, mz, my, mx] += w * px
                                acc[1, mz, my, mx] += w * py
                                acc[2, mz, my, mx] += w * pz
                                acc[3, mz, my, mx] += w * rq
    for mz in range(n):
        for my in range(n):
            for mx in range(n):
                w = buf[mz, my, mx]
                if w > 0:
                    ex = np.float32(mx) - acc[0, mz, my, mx] / w
                    ey = np.float32(my) - acc[1, mz, my, mx] / w
                    ez = np.float32(mz) - acc[2, mz, my, mx] / w
                    buf[mz, my, mx] = (math.sqrt(ex * ex + ey * ey + ez * ez)
                                       - acc[3, mz, my, mx] / w)
                else:
                    buf[mz, my, mx] = far


@njit(parallel=True, cache=True, fastmath=True)
def _evaluate_zhu_bridson(targets, out, first, bsz, P, H, R, start, table, ranks, reach, far):
    """Fill ``out[first + t]`` with the zhu_bridson voxel values of block ``targets[t]``."""
    for t in prange(targets.size):
        bx, by, bz = unpack_key(targets[t])
        acc = np.empty((4, bsz, bsz, bsz), np.float32)
        _zhu_bridson_block(out[first + t], acc, bx, by, bz, bsz, P, H, R, start, table, ranks,
                           reach, far)


@njit(parallel=True, cache=True, fastmath=True)
def _sample_points(X, P, H, A, R, start, table, ranks, reach, bsz, hmax, kernel, blob_a, blob_e,
                   iso, far):
    """Implicit values at points ``X`` (K, 3) in voxel units (gathered per point)."""
    m = X.shape[0]
    out = np.empty(m, np.float32)
    width = 2 * reach + 1
    for t in prange(m):
        x = X[t, 0]
        y = X[t, 1]
        z = X[t, 2]
        bx = np.int64(math.floor(x / bsz))
        by = np.int64(math.floor(y / bsz))
        bz = np.int64(math.floor(z / bsz))
        slots = np.empty(width ** 3, np.int64)
        ns = _near_slots(bx, by, bz, x, y, z, x, y, z, bsz, hmax, table, ranks, reach, slots)
        f = 0.0
        w0 = 0.0
        wx = 0.0
        wy = 0.0
        wz = 0.0
        wr = 0.0
        for s in range(ns):
            v = slots[s]
            for q in range(start[v], start[v + 1]):
                ex = x - P[q, 0]
                ey = y - P[q, 1]
                ez = z - P[q, 2]
                d2 = ex * ex + ey * ey + ez * ez
                h2 = H[q] * H[q]
                if d2 < h2:
                    if kernel == ZHU_BRIDSON:
                        tt = 1.0 - d2 / h2
                        w = tt * tt * tt
                        w0 += w
                        wx += w * P[q, 0]
                        wy += w * P[q, 1]
                        wz += w * P[q, 2]
                        wr += w * R[q]
                    else:
                        f += A[q] * splat_profile(kernel, np.float32(d2 / h2), blob_a, blob_e)
        if kernel == ZHU_BRIDSON:
            if w0 > 0:
                ex = x - wx / w0
                ey = y - wy / w0
                ez = z - wz / w0
                out[t] = math.sqrt(ex * ex + ey * ey + ez * ez) - wr / w0
            else:
                out[t] = far
        else:
            out[t] = iso - f
    return out


@njit(parallel=True, cache=True, fastmath=True)
def _upper_bounds(targets, bsz, P, H, A, start, table, ranks, reach, hmax, kernel, blob_a,
                  blob_e):
    """Upper bound of the summed field over each block's box extended by one voxel (-1 when
    no particle reaches it); for zhu_bridson 1 if any particle reaches it, else -1."""
    m = targets.size
    bound = np.empty(m, np.float64)
    width = 2 * reach + 1
    for t in prange(m):
        bx, by, bz, lox, loy, loz, hix, hiy, hiz = grown_block_box(targets[t], bsz)
        slots = np.empty(width ** 3, np.int64)
        ns = _near_slots(bx, by, bz, lox, loy, loz, hix, hiy, hiz, bsz, hmax, table, ranks,
                         reach, slots)
        b = 0.0
        near = False
        for s in range(ns):
            v = slots[s]
            for q in range(start[v], start[v + 1]):
                ex = max(lox - P[q, 0], 0.0, P[q, 0] - hix)
                ey = max(loy - P[q, 1], 0.0, P[q, 1] - hiy)
                ez = max(loz - P[q, 2], 0.0, P[q, 2] - hiz)
                d2 = ex * ex + ey * ey + ez * ez
                h2 = H[q] * H[q]
                if d2 < h2:
                    near = True
                    if kernel != ZHU_BRIDSON:
                        b += A[q] * splat_profile(kernel, np.float32(d2 / h2), blob_a, blob_e)
        if not near:
            bound[t] = -1.0
        else:
            bound[t] = b if kernel != ZHU_BRIDSON else 1.0
    return bound


@njit(parallel=True, cache=True, fastmath=True)
def _evaluate_sum(targets, out, first, bsz, P, H, A, start, table, ranks, reach, hmax, kernel,
                  blob_a, blob_e, iso):
    """Voxel values of blocks ``targets`` for the summed kernels, into ``out[first + t]``.

    Each block gathers the particles that reach it into contiguous float32 arrays; each row of
    voxels keeps those within reach of the row; each voxel then sums over that short list in a
    branch-free loop that the compiler vectorises across particles. The order of the sum is
    fixed by the data, not by the threads."""
    width = 2 * reach + 1
    top = np.float32(bsz - 1)
    for t in prange(targets.size):
        bx, by, bz = unpack_key(targets[t])
        ox = bx * bsz
        oy = by * bsz
        oz = bz * bsz
        buf = out[first + t]
        slots = np.empty(width ** 3, np.int64)
        ns = _near_slots(bx, by, bz, ox, oy, oz, ox + bsz - 1.0, oy + bsz - 1.0, oz + bsz - 1.0,
                         bsz, hmax, table, ranks, reach, slots)
        total = 0
        for s in range(ns):
            total += start[slots[s] + 1] - start[slots[s]]
        cx = np.empty(total, np.float32)
        cy = np.empty(total, np.float32)
        cz = np.empty(total, np.float32)
        ch = np.empty(total, np.float32)
        ca = np.empty(total, np.float32)
        c = 0
        for s in range(ns):
            v = slots[s]
            for q in range(start[v], start[v + 1]):
                px = np.float32(P[q, 0] - ox)
                py = np.float32(P[q, 1] - oy)
                pz = np.float32(P[q, 2] - oz)
                h = np.float32(H[q])
                ex = max(-px, np.float32(0.0), px - top)
                ey = max(-py, np.float32(0.0), py - top)
                ez = max(-pz, np.float32(0.0), pz - top)
                if ex * ex + ey * ey + ez * ez >= h * h:
                    continue
                cx[c] = px
                cy[c] = py
                cz[c] = pz
                ch[c] = np.float32(1.0) / (h * h)
                ca[c] = A[q]
                c += 1
        rx = np.empty(c, np.float32)
        rd = np.empty(c, np.float32)
        ri = np.empty(c, np.float32)
        ra = np.empty(c, np.float32)
        for mz in range(bsz):
            z = np.float32(mz)
            for my in range(bsz):
                y = np.float32(my)
                m = 0
                for k in range(c):
                    ey = y - cy[k]
                    ez = z - cz[k]
                    ex = max(cx[k] - top, np.float32(0.0), -cx[k])
                    d = (ey * ey + ez * ez) * ch[k]
                    if d + ex * ex * ch[k] < np.float32(1.0):
                        rx[m] = cx[k]
                        rd[m] = d
                        ri[m] = ch[k]
                        ra[m] = ca[k]
                        m += 1
                for mx in range(bsz):
                    x = np.float32(mx)
                    acc = np.float32(0.0)
                    for k in range(m):
                        ex = x - rx[k]
                        q2 = ex * ex * ri[k] + rd[k]
                        q2 = q2 if q2 < np.float32(1.0) else np.float32(1.0)
                        acc += ra[k] * splat_row_profile(kernel, q2, blob_a, blob_e)
                    buf[mz, my, mx] = iso - acc


def sphere_grid(positions: np.ndarray, radii: np.ndarray, cell_size: float, *, kernel: str,
                support_r: float, iso: float, block_size: int, blobbiness: float, max_bytes: int,
                skip_interior: bool = True, evaluate_all: bool = False,
                domain: tuple[np.ndarray, np.ndarray] | None = None) -> SparseGrid:
    """Implicit values of spherical kernels on the blocks of the voxel lattice near the surface.

    Parameters
    ----------
    positions : (N, 3) float64
        Particle centres (m), checked (finite, within the block keys' range).
    radii : (N,) float64
        Particle radii ``r`` (m), > 0.
    cell_size : float
        Voxel edge (m), > 0.
    kernel : str
        One of :data:`filters.kernels.SPLAT_KERNELS`.
    support_r : float
        Support radius as a multiple of the particle radius, ``h = support_r * r``.
    iso : float
        Iso value of the summed field (0 for ``zhu_bridson``).
    block_size : int
        Voxels per block edge.
    blobbiness : float
        ``a`` of the blobby profile.
    max_bytes : int
        Memory budget (bytes).
    skip_interior : bool
        Mark blocks whose corner samples are all clearly inside without evaluating them.
    evaluate_all : bool
        Evaluate every candidate block (the dense grid's values).
    domain : tuple of two (3,) arrays, optional
        ``(lower, upper)`` (m): only blocks that meet this box (grown by one voxel) are
        candidates; the others count as outside (for a field then intersected with the box).

    Returns
    -------
    SparseGrid
        Implicit values (negative inside) on the evaluated blocks.
    """
    bsz = block_size
    n = positions.shape[0]
    H = radii * (support_r / cell_size)  # support radius, voxel units
    if n and H.max() > 64 * block_size:
        raise ValueError(f"support_r * radius / cell_size must be <= {64 * block_size}; "
                         f"increase cell_size or block_size")
    kid = splat_kernel_id(kernel)
    far = float(H.max()) if n else 1.0
    inside_value = -iso if kid != ZHU_BRIDSON else -far
    outside_value = iso if kid != ZHU_BRIDSON else far
    empty = SparseGrid(cell_size, bsz, np.zeros(0, np.int64),
                       np.zeros((0, bsz, bsz, bsz), np.float32), np.zeros(0, np.int64),
                       inside_value, outside_value)
    if n == 0:
        return empty
    check_budget(n * 96, max_bytes, f"particle bookkeeping for {n} particles")
    # bin particles by home block, numbered in sorted (x-major) order whatever the particle
    # order: neighbouring blocks stay close in memory (a radially sorted input was 2x slower in
    # first-seen order)
    table, ranks, unique, start, order = bin_by_block(positions, cell_size, bsz, True)
    P = _gather_scaled(positions, order, 1.0 / cell_size)  # voxel units, in block order
    Hs = H[order]
    del H
    uniform = bool(Hs.min() == Hs.max())
    Rs = ((radii[order] / cell_size).astype(np.float32) if kid == ZHU_BRIDSON
          else np.zeros(1, np.float32))
    hmax = float(Hs.max())
    reach = int(math.ceil((hmax + 1.0) / bsz))  # blocks whose particles reach a block's box
    if kid == 2:
        M = (np.ones(1) if uniform else radii[order] ** 3 / radii.max() ** 3)
        del radii
        A = _sph_amplitudes(P, Hs, M, unique, start, table, ranks, reach, bsz, hmax, uniform)
        del M
    else:
        del radii
        A = np.ones(n, np.float32)
    del order
    ba = np.float32(blobbiness)
    be = np.float32(math.exp(-blobbiness))
    iso32 = np.float32(iso)
    far32 = np.float32(far)
    # candidate blocks: those holding a voxel within some particle's support
    active = dilate_keys(unique, int(math.ceil(hmax / bsz - 1e-9)))
    if domain is not None:
        active = active[blocks_meeting_box(active, bsz, cell_size, *domain)]
    if kid == ZHU_BRIDSON:
        def evaluate(targets, data, first):
            _evaluate_zhu_bridson(targets, data, first, bsz, P, Hs, Rs, start, table, ranks,
                                  reach, far32)
    else:
        def evaluate(targets, data, first):
            _evaluate_sum(targets, data, first, bsz, P, Hs, A, start, table, ranks, reach, hmax,
                          kid, ba, be, iso32)

    def corner_values(points):
        return _sample_points(points, P, Hs, A, Rs, start, table, ranks, reach, bsz, hmax, kid,
                              ba, be, iso32, far32)

    def upper_bounds(targets):
        return _upper_bounds(targets, bsz, P, Hs, A, start, table, ranks, reach, hmax, kid, ba,
                             be)

    def outside(bound):
        return (bound < 0) | ((bound < iso) if kid != ZHU_BRIDSON else False)

    return classify_and_evaluate(
        active, block_size=bsz, cell_size=cell_size, max_bytes=max_bytes,
        inside_value=inside_value, outside_value=outside_value, evaluate=evaluate,
        corner_values=corner_values if skip_interior and not evaluate_all else None,
        inside_margin=0.25 * iso if kid != ZHU_BRIDSON else 0.5 * bsz,
        upper_bounds=upper_bounds if not evaluate_all else None, outside=outside)
