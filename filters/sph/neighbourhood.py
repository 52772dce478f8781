"""The DFSPH solver's per-step neighbourhood pass: fluid and boundary neighbours of cell-sorted
particles within the support, their kernel weights, densities, the factors ``alpha_i`` and what
the boundary contributes, wall by wall, in one fused Numba pass (see :mod:`filters.sph.dfsph`
for how the solves use them)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..kernels import kernel_w, kernel_w_dw

__all__ = ["neighbourhood_pass", "boundary_reach_mask", "mark_boundary_reach", "cell_range",
           "wall_key", "wall_of", "WALL_CLUSTERS", "SAME_WALL_COS"]

#: Wall clusters kept per fluid particle: the whole boundary, then up to three walls by normal.
WALL_CLUSTERS = 4
#: Absolute cosine of the angle within which two boundary normals belong to the same wall (45
#: degrees).
SAME_WALL_COS = 0.7


@njit(cache=True, inline="always", error_model="numpy")
def cell_range(q, origin, inv_cell, dim):
    """First and last cell index (clamped) within two cells of coordinate ``q``."""
    f = math.floor((q - origin) * inv_cell)
    lo = min(max(f - 2.0, 0.0), float(dim))
    hi = max(min(f + 2.0, dim - 1.0), -1.0)
    return int(lo), int(hi)


@njit(cache=True, inline="always", error_model="numpy")
def _gap(q, lo_edge, hi_edge):
    if q < lo_edge:
        return lo_edge - q
    if q > hi_edge:
        return q - hi_edge
    return 0.0


@njit(cache=True, error_model="numpy")
def boundary_reach_mask(xb, origin, cell, dims):
    """Cells of a grid (edge ``cell``) that have a boundary particle within two cells per axis:
    a fluid particle whose cell is not marked has no boundary neighbour within ``2 cell``."""
    mask = np.zeros(dims[0] * dims[1] * dims[2], dtype=np.bool_)
    mark_boundary_reach(mask, xb, origin, cell, dims)
    return mask


@njit(cache=True, error_model="numpy")
def mark_boundary_reach(mask, xb, origin, cell, dims):
    """Mark in ``mask`` the cells of :func:`boundary_reach_mask` for the particles ``xb`` (the
    mask of a union of particle sets is the union of their masks)."""
    inv = 1.0 / cell
    for b in range(xb.shape[0]):
        x0, x1 = cell_range(xb[b, 0], origin[0], inv, dims[0])
        y0, y1 = cell_range(xb[b, 1], origin[1], inv, dims[1])
        z0, z1 = cell_range(xb[b, 2], origin[2], inv, dims[2])
        for iz in range(z0, z1 + 1):
            for iy in range(y0, y1 + 1):
                row = (iz * dims[1] + iy) * dims[0]
                for ix in range(x0, x1 + 1):
                    mask[row + ix] = True


@njit(cache=True, inline="always", error_model="numpy")
def wall_key(mx, my, mz, dx, dy, dz):
    """The normal ``(mx, my, mz)`` of a boundary particle as :func:`wall_of` compares it, seen
    from a fluid particle at ``(dx, dy, dz)`` = ``x_i - x_b``: as given where it faces the
    particle (``n . (x_i - x_b) > 0``), twice as long where it does not (the particle lies
    beside or behind the surface the sample belongs to, e.g. beside an edge of a body)."""
    if mx * dx + my * dy + mz * dz > 0.0:
        return mx, my, mz
    return 2.0 * mx, 2.0 * my, 2.0 * mz


@njit(cache=True, inline="always", error_model="numpy")
def wall_of(i, mx, my, mz, nc, cn):
    """The first of particle ``i``'s wall clusters 1 .. nc - 1 whose normal is within 45 degrees
    of ``(mx, my, mz)`` (a :func:`wall_key`; a zero normal matches a zero one), else ``nc``.

    Normals match in either orientation (they may be given either way), except two that both
    face the particle: those in opposite directions are walls on opposite sides of it (the
    floor, and a body landing on it) and are two walls.  Scaling a normal by 2 is exact, so the
    either-orientation test is the unit normals' bit for bit."""
    m2 = mx * mx + my * my + mz * mz
    zero = m2 == 0.0
    for k in range(1, nc):
        cx = cn[i, k, 0]
        cy = cn[i, k, 1]
        cz = cn[i, k, 2]
        c2 = cx * cx + cy * cy + cz * cz
        if zero:
            if c2 == 0.0:
                return k
            continue
        dot = cx * mx + cy * my + cz * mz
        if m2 < 2.0 and c2 < 2.0:  # both face the particle
            if dot >= SAME_WALL_COS:
                return k
        elif abs(dot) >= SAME_WALL_COS * (2.0 if m2 > 2.0 else 1.0) * (2.0 if c2 > 2.0 else 1.0):
            return k
    return nc


@njit(cache=True, inline="always", error_model="numpy")
def _home(q, origin, inv_cell, dim):
    return min(max(int(math.floor((q - origin) * inv_cell)), 0), dim - 1)


@njit(parallel=True, cache=True, error_model="numpy")
def neighbourhood_pass(x, start, origin, cell, dims, boundary, vol, mass, h, kind, ntab, ncnt, fw,
                       gsum, factor, nnb, rho, fsum, bvis, bvv, vrate, ncl, cphi, cgb, cvb, cn):
    """One fused pass per step: neighbours within ``h``, kernel gradients, density, ``alpha_i``.

    ``x`` must be sorted by the grid of cell ``cell`` (``h / 2`` padded) whose cell ranges are
    ``start`` (a counting sort of ``x`` itself); ``boundary`` is
    :meth:`filters.sph.boundary_set.BoundarySet.arrays`, sorted by its own grid of the same
    cell edge, whose ``mask`` (:func:`boundary_reach_mask`) marks the cells worth scanning.  Each
    particle scans the 5 x 5 rows of 5 consecutive cells around it (rows farther than ``h``
    skipped), so its neighbours come in a fixed order that depends only on the positions:
    results are bit-identical for any thread count.  The fluid scan only collects candidates
    (branch-free: every candidate is written, the count advances on hits); the kernels are
    evaluated on the hits.

    Writes, per particle ``i``: ``ntab[i, :ncnt[i]]`` the fluid neighbours ``j != i`` with
    ``r < h``; ``fw[i, k] = V_j W'(r_ij) / r_ij`` (float32, 1/m^2), so that ``V_j grad W_ij =
    fw[i, k] (x_i - x_j)`` (storing this scalar instead of the gradient vector halves what
    every solver iteration reads; ``fw`` is symmetric, so pair forces stay antisymmetric);
    ``gsum_i = sum_j V_j grad W_ij + sum_b V_b grad W_ib`` (1/m); ``factor_i = alpha_i`` (m^2,
    Bender & Koschier 2017, eq. 11, with rest volumes); ``nnb_i`` the number of neighbours
    (fluid and boundary); ``rho_i`` (kg/m^3, by summation, ``m W`` per fluid and ``rho0 V_b W``
    per boundary neighbour); ``fsum_i = sum_j fw_ij`` (1/m^2), which gives the fluid part of the
    implicit viscosity's diagonal; the boundary's viscosity block ``bvis_i = sum_b f_b V_b
    (W'(r) / r) x_ib x_ib^T / (r^2 + 0.01 h'^2)`` (1/m^3, xx yy zz xy xz yz; ``f_b`` the
    friction factor) and, for a moving boundary, its velocity term ``bvv_i = sum_b f_b V_b
    (W'(r) / r) (v_b . x_ib) x_ib / (r^2 + 0.01 h'^2)`` (1/s) and ``vrate_i = sum_b V_b v_b .
    grad W_ib`` (1/s, the boundary's part of ``D rho_i / D t / rho0``; zeros when static).

    The **wall clusters** of particle ``i``: cluster 0 sums every boundary neighbour, clusters
    1 to ``ncl_i - 1`` the boundary neighbours grouped by their normals (a neighbour joins the
    first cluster whose normal, that of its first member, is within 45 degrees of its own,
    either orientation unless both face the particle from opposite sides (:func:`wall_of`), or
    opens a new one; past :data:`WALL_CLUSTERS` it joins the last), so that each cluster is one
    wall of a corner or of a gap.  Per cluster ``k``: ``cphi[i, k] = sum V_b W_ib``
    (the fraction of the kernel the wall fills), ``cgb[i, k] = sum V_b grad W_ib`` (1/m),
    ``cvb[i, k] = sum V_b v_b . grad W_ib`` (1/s) and its normal ``cn[i, k]``; ``ncl_i = 0``
    without boundary neighbours.

    ``ntab`` has one spare column.  Returns the largest neighbour count: above
    ``ntab.shape[1] - 1`` the tables are truncated and the call must be repeated with wider ones.
    """
    (xb, bstart, borigin, bcell, bdims, bmask, bvol, bmass, bfvol, bnrm, bvel,
     moving) = boundary
    n = x.shape[0]
    cap = ntab.shape[1] - 1
    kcap = cphi.shape[1]
    h2 = h * h
    margin = h2 * (1.0 + 1e-6)
    eps = 0.01 * 0.25 * h2
    inv = 1.0 / cell
    binv = 1.0 / bcell
    w0 = kernel_w(kind, 0.0, h)
    best = np.zeros(n, dtype=np.int64)
    nbd = xb.shape[0]
    for i in prange(n):
        qx = x[i, 0]
        qy = x[i, 1]
        qz = x[i, 2]
        # -- collect the fluid neighbours (branch-free compaction into the row) --------------
        c = 0
        x0, x1 = cell_range(qx, origin[0], inv, dims[0])
        y0, y1 = cell_range(qy, origin[1], inv, dims[1])
        z0, z1 = cell_range(qz, origin[2], inv, dims[2])
        for iz in range(z0, z1 + 1):
            gz = _gap(qz, origin[2] + iz * cell, origin[2] + (iz + 1) * cell)
            for iy in range(y0, y1 + 1):
                gy = _gap(qy, origin[1] + iy * cell, origin[1] + (iy + 1) * cell)
                if gy * gy + gz * gz > margin:
                    continue
                row = (iz * dims[1] + iy) * dims[0]
                for j in range(start[row + x0], start[row + x1 + 1]):
                    dx = qx - x[j, 0]
                    dy = qy - x[j, 1]
                    dz = qz - x[j, 2]
                    ntab[i, min(c, cap)] = j
                    c += (dx * dx + dy * dy + dz * dz < h2) & (j != i)
        best[i] = c
        c = min(c, cap)
        ncnt[i] = c
        # -- kernels on the hits ---------------------------------------------------------------
        sw = w0
        sx = 0.0
        sy = 0.0
        sz = 0.0
        sq = 0.0
        sf = 0.0
        for k in range(c):
            j = ntab[i, k]
            dx = qx - x[j, 0]
            dy = qy - x[j, 1]
            dz = qz - x[j, 2]
            r2 = dx * dx + dy * dy + dz * dz
            r = math.sqrt(r2)
            w, dw = kernel_w_dw(kind, r, h)
            sw += w
            f = vol * dw / r if r > 0.0 else 0.0  # coincident: no gradient
            f32 = np.float32(f)
            fw[i, k] = f32
            f = np.float64(f32)  # the sums below use what the solves will use
            gx = f * dx
            gy = f * dy
            gz = f * dz
            sx += gx
            sy += gy
            sz += gz
            sq += gx * gx + gy * gy + gz * gz
            sf += f
        fsum[i] = sf
        # -- boundary particles (only where the mask says some are within reach) --------------
        bx = 0.0
        by = 0.0
        bz = 0.0
        sb = 0.0
        pb = 0.0
        vr = 0.0
        nb = 0
        nc = 1
        lk = 0
        lx = math.nan  # no last normal yet (NaN equals nothing)
        ly = math.nan
        lz = math.nan
        u0 = 0.0
        u1 = 0.0
        u2 = 0.0
        u3 = 0.0
        u4 = 0.0
        u5 = 0.0
        e0 = 0.0
        e1 = 0.0
        e2 = 0.0
        home = (_home(qz, borigin[2], binv, bdims[2]) * bdims[1]
                + _home(qy, borigin[1], binv, bdims[1])) * bdims[0] + _home(
                    qx, borigin[0], binv, bdims[0])
        if nbd > 0 and bmask[home]:
            x0, x1 = cell_range(qx, borigin[0], binv, bdims[0])
            y0, y1 = cell_range(qy, borigin[1], binv, bdims[1])
            z0, z1 = cell_range(qz, borigin[2], binv, bdims[2])
            for iz in range(z0, z1 + 1):
                gz = _gap(qz, borigin[2] + iz * bcell, borigin[2] + (iz + 1) * bcell)
                for iy in range(y0, y1 + 1):
                    gy = _gap(qy, borigin[1] + iy * bcell, borigin[1] + (iy + 1) * bcell)
                    if gy * gy + gz * gz > margin:
                        continue
                    row = (iz * bdims[1] + iy) * bdims[0]
                    for b in range(bstart[row + x0], bstart[row + x1 + 1]):
                        dx = qx - xb[b, 0]
                        dy = qy - xb[b, 1]
                        dz = qz - xb[b, 2]
                        r2 = dx * dx + dy * dy + dz * dz
                        if r2 >= h2:
                            continue
                        r = math.sqrt(r2)
                        w, dw = kernel_w_dw(kind, r, h)
                        sb += bmass[b] * w
                        pw = bvol[b] * w
                        pb += pw
                        f = bvol[b] * dw / r if r2 > 0.0 else 0.0
                        tx = f * dx
                        ty = f * dy
                        tz = f * dz
                        bx += tx
                        by += ty
                        bz += tz
                        vg = 0.0
                        if moving:
                            vg = bvel[b, 0] * tx + bvel[b, 1] * ty + bvel[b, 2] * tz
                            vr += vg
                        # the wall this particle belongs to (as the last one's, if the same normal)
                        mx, my, mz = wall_key(bnrm[b, 0], bnrm[b, 1], bnrm[b, 2], dx, dy, dz)
                        if mx == lx and my == ly and mz == lz:
                            k = lk
                        else:
                            k = wall_of(i, mx, my, mz, nc, cn)
                            if k == nc:
                                if nc < kcap:
                                    nc += 1
                                    cn[i, k, 0] = mx
                                    cn[i, k, 1] = my
                                    cn[i, k, 2] = mz
                                    cphi[i, k] = 0.0
                                    cgb[i, k, 0] = 0.0
                                    cgb[i, k, 1] = 0.0
                                    cgb[i, k, 2] = 0.0
                                    cvb[i, k] = 0.0
                                else:
                                    k = nc - 1
                            lk = k
                            lx = mx
                            ly = my
                            lz = mz
                        cphi[i, k] += pw
                        cgb[i, k, 0] += tx
                        cgb[i, k, 1] += ty
                        cgb[i, k, 2] += tz
                        cvb[i, k] += vg
                        if r2 == 0.0:
                            continue
                        nb += 1
                        q = bfvol[b] * dw / r / (r2 + eps)
                        u0 += q * dx * dx
                        u1 += q * dy * dy
                        u2 += q * dz * dz
                        u3 += q * dx * dy
                        u4 += q * dx * dz
                        u5 += q * dy * dz
                        if moving:
                            qv = q * (bvel[b, 0] * dx + bvel[b, 1] * dy + bvel[b, 2] * dz)
                            e0 += qv * dx
                            e1 += qv * dy
                            e2 += qv * dz
        bvis[i, 0] = u0
        bvis[i, 1] = u1
        bvis[i, 2] = u2
        bvis[i, 3] = u3
        bvis[i, 4] = u4
        bvis[i, 5] = u5
        bvv[i, 0] = e0
        bvv[i, 1] = e1
        bvv[i, 2] = e2
        vrate[i] = vr
        ncl[i] = nc if pb > 0.0 else 0
        cphi[i, 0] = pb
        cgb[i, 0, 0] = bx
        cgb[i, 0, 1] = by
        cgb[i, 0, 2] = bz
        cvb[i, 0] = vr
        cn[i, 0, 0] = 0.0
        cn[i, 0, 1] = 0.0
        cn[i, 0, 2] = 0.0
        nnb[i] = c + nb
        rho[i] = mass * sw + sb
        sx += bx
        sy += by
        sz += bz
        gsum[i, 0] = sx
        gsum[i, 1] = sy
        gsum[i, 2] = sz
        den = sx * sx + sy * sy + sz * sz + sq
        factor[i] = 1.0 / den if den > 1e-9 / h2 else 0.0
    top = 0
    for i in range(n):
        top = max(top, best[i])
    return top
