"""Splatting ellipsoidal (anisotropic) kernels onto the sparse / dense voxel grids, in Numba.

Particle ``j`` with kernel centre ``c_j`` (m), kernel matrix ``G_j`` (symmetric, 1/m; see
:func:`filters.surface.anisotropy.anisotropic_kernels`) and amplitude ``a_j`` adds

    ``a_j K(|G_j (x - c_j)|^2)``

to the field, with ``K`` one of the unit-support kernels of :mod:`filters.surface.splat` as a
function
of ``q^2`` (peak 1): ``sph`` (Monaghan's cubic spline), ``metaball`` (Wyvill et al. 1986) or
``blobby`` (Blinn 1982). This is Yu & Turk's (2013) anisotropic kernel ``W(r, G) = sigma det(G)
P(|G r|)``: the ``det(G)`` and the normalisation ``sigma`` live in ``a_j``. For the ``sph``
kernel :func:`filters.surface.splat.splat_sparse_anisotropic` uses ``a_j = V_j (8 / pi)
det(G_j) gain(a_j)`` with the SPH volume ``V_j`` (m^3, voxel units inside; for ellipsoids under
the ellipsoidal kernels themselves, :func:`filters.surface.volumes.anisotropic_volumes`), i.e.
the SPH colour field ``sum_j V_j W_j(x)``, which is about 1 inside the liquid, with the
amplitudes of stretched kernels raised by :func:`filters.surface.volumes.stretched_gain`; for
the other kernels
``a_j = det(G_j) h_j^3`` (1 for the volume-keeping matrices of :mod:`filters.surface.anisotropy`,
more
where their long axis is capped), which keeps each particle's integral that of the isotropic
kernel.

The output is the same as :func:`filters.surface.splat.splat_sparse` /
:func:`filters.surface.splat.splat_dense`:
an implicit value ``g = iso - f`` (negative inside) on a :class:`filters.surface.grid.SparseGrid`
or :class:`filters.surface.grid.DenseField`, so :func:`pipeline.surface.contour_sparse` /
:func:`pipeline.surface.contour_dense` and ``MarchingCubes`` contour it unchanged.

Evaluation. The quadratic form along a voxel row ``(y, z)`` is a parabola in ``e = x - c_x``:
``q^2 = (m_xx e + b) e + c`` with ``b = 2 (m_xy e_y + m_xz e_z)`` and
``c = m_yy e_y^2 + m_zz e_z^2 + 2 m_yz e_y e_z`` (``M = G^T G`` in voxel units). Each block
gathers the particles whose bounding boxes and bounding spheres (longest semi-axis) reach it;
per voxel plane, each particle's exact range of rows follows from its shadow on the yz plane
(``q^2`` minimised over ``e_x`` is a quadratic form in ``(e_y, e_z)``), and its row
polynomials are written row by row, kept where the row's segment meets the block (the
parabola's vertex clamped to the row, written always and counted only if kept: no branch);
each voxel then sums a branch-free, vectorisable loop -- the same cost per contribution as
the isotropic splat (about 19 contributions per voxel row for both on a 100k block).

Determinism and sparsity follow :mod:`filters.surface.splat`: particles binned by block with a
serial
counting sort, every voxel written by one task summing in a fixed order (bitwise identical for
any thread count), only blocks that particles can reach considered; outside blocks rejected by
an upper bound of the field (``K <= 1`` and ``|G r|^2 >= |r|^2 / S^2`` with ``S`` the longest
semi-axis), deep inside blocks detected by corner samples, and
a consistency pass evaluates every skipped block whose neighbours disagree with its sign.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit, prange

from ..binning import EMPTY_KEY, insert_key, lookup
from ..kernels import splat_kernel_id, splat_row_profile
from ..validation import check_choice, check_int, check_points, check_range
from .blocks import bin_by_block, blocks_meeting_box, classify_and_evaluate, grown_block_box
from .grid import (
    DEFAULT_MAX_BYTES,
    DenseField,
    SparseGrid,
    check_block_range,
    check_budget,
    pack_key,
    unpack_key,
)

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

__all__ = [
    "ANISOTROPIC_KERNELS",
    "ANISOTROPIC_ISO",
    "ellipsoid_grid",
    "splat_ellipsoids_sparse",
    "splat_ellipsoids_dense",
]

#: Kernels the ellipsoid splatter supports (ids as in :mod:`filters.surface.splat`).
ANISOTROPIC_KERNELS = ("blobby", "metaball", "sph")

#: Default iso values of the anisotropic fields: those of the isotropic kernels
#: (:data:`filters.kernels.SPLAT_DEFAULTS`), so that a drop whose kernels are (nearly) spherical
#: comes out as with isotropic kernels; the ``sph`` amplitudes of stretched kernels are raised
#: instead (:func:`filters.surface.volumes.stretched_gain`).
ANISOTROPIC_ISO = {"sph": 0.6, "metaball": 0.5, "blobby": 0.5}

# --------------------------------------------------------------------------------------------
# Per-particle preparation
# --------------------------------------------------------------------------------------------


@njit(parallel=True, cache=True)
def _prepare_ellipsoids(C, G, order, scale, cell):
    """Centres in voxel units (block order), ``M = (cell G)^2`` as 6 entries, bounding-box half
    extents ``e_k = sqrt((M^-1)_kk)`` (voxels), the longest semi-axis ``S = 1 / sqrt(
    lambda_min(M))`` (voxels, closed-form eigenvalues of a symmetric 3x3, Smith 1961; kept
    within ``[max e_k, |e|]``) and ``L = 1 / S^2``."""
    n = order.size
    P = np.empty((n, 3))
    M6 = np.empty((n, 6))
    E = np.empty((n, 3))
    S = np.empty(n)
    L = np.empty(n)
    for t in prange(n):
        p = order[t]
        for a in range(3):
            P[t, a] = C[p, a] * scale
        g = G[p]
        # M = (cell G)^T (cell G), G symmetric
        m = np.empty((3, 3))
        for a in range(3):
            for b in range(3):
                s = 0.0
                for k in range(3):
                    s += g[k, a] * g[k, b]
                m[a, b] = s * cell * cell
        m00 = m[0, 0]
        m11 = m[1, 1]
        m22 = m[2, 2]
        m01 = 0.5 * (m[0, 1] + m[1, 0])
        m02 = 0.5 * (m[0, 2] + m[2, 0])
        m12 = 0.5 * (m[1, 2] + m[2, 1])
        M6[t, 0] = m00
        M6[t, 1] = m11
        M6[t, 2] = m22
        M6[t, 3] = m01
        M6[t, 4] = m02
        M6[t, 5] = m12
        c00 = m11 * m22 - m12 * m12
        c11 = m00 * m22 - m02 * m02
        c22 = m00 * m11 - m01 * m01
        det = m00 * c00 - m01 * (m01 * m22 - m12 * m02) + m02 * (m01 * m12 - m11 * m02)
        # tiny safety margin: the box must contain the ellipsoid after float32 rounding
        E[t, 0] = math.sqrt(max(c00 / det, 0.0)) * (1.0 + 1e-5) + 1e-4
        E[t, 1] = math.sqrt(max(c11 / det, 0.0)) * (1.0 + 1e-5) + 1e-4
        E[t, 2] = math.sqrt(max(c22 / det, 0.0)) * (1.0 + 1e-5) + 1e-4
        # smallest eigenvalue of M
        q = (m00 + m11 + m22) / 3.0
        p1 = m01 * m01 + m02 * m02 + m12 * m12
        p2 = (m00 - q) ** 2 + (m11 - q) ** 2 + (m22 - q) ** 2 + 2.0 * p1
        if p2 <= 1e-24 * q * q:
            lmin = q
        else:
            pp = math.sqrt(p2 / 6.0)
            b00 = (m00 - q) / pp
            b11 = (m11 - q) / pp
            b22 = (m22 - q) / pp
            b01 = m01 / pp
            b02 = m02 / pp
            b12 = m12 / pp
            r = 0.5 * (b00 * (b11 * b22 - b12 * b12) - b01 * (b01 * b22 - b12 * b02)
                       + b02 * (b01 * b12 - b11 * b02))
            r = min(max(r, -1.0), 1.0)
            lmin = q + 2.0 * pp * math.cos(math.acos(r) / 3.0 + 2.0 * math.pi / 3.0)
        big = math.sqrt(E[t, 0] ** 2 + E[t, 1] ** 2 + E[t, 2] ** 2)
        sr = 1.0 / math.sqrt(lmin) if lmin > 0.0 else big
        sr = min(max(sr * (1.0 + 1e-4) + 1e-4, E[t, 0], E[t, 1], E[t, 2]), big)
        S[t] = sr
        L[t] = 1.0 / (sr * sr)
    return P, M6, E, S, L


@njit(cache=True)
def _touched_blocks(P, E, start, unique, bsz):
    """Distinct keys of the blocks that some particle's bounding box touches: per home block
    ``unique[u]`` (particles ``start[u]:start[u + 1]``), the box of blocks spanned by its
    particles' boxes (tighter than dilating every home block by the largest reach: the long
    axes of flattened kernels reach a second block only on some sides)."""
    table = np.full(1024, EMPTY_KEY, np.int64)
    values = np.empty(1024, np.int64)
    out = np.empty(1024, np.int64)
    count = 0
    inv = 1.0 / bsz
    for u in range(unique.size):
        lo0 = lo1 = lo2 = np.int64(1 << 40)
        hi0 = hi1 = hi2 = -np.int64(1 << 40)
        for q in range(start[u], start[u + 1]):
            lo0 = min(lo0, np.int64(math.floor((P[q, 0] - E[q, 0]) * inv)))
            lo1 = min(lo1, np.int64(math.floor((P[q, 1] - E[q, 1]) * inv)))
            lo2 = min(lo2, np.int64(math.floor((P[q, 2] - E[q, 2]) * inv)))
            hi0 = max(hi0, np.int64(math.floor((P[q, 0] + E[q, 0]) * inv)))
            hi1 = max(hi1, np.int64(math.floor((P[q, 1] + E[q, 1]) * inv)))
            hi2 = max(hi2, np.int64(math.floor((P[q, 2] + E[q, 2]) * inv)))
        for bz in range(lo2, hi2 + 1):
            for by in range(lo1, hi1 + 1):
                for bx in range(lo0, hi0 + 1):
                    table, values, out, count, _ = insert_key(table, values, out, count,
                                                           pack_key(bx, by, bz))
    return np.sort(out[:count])


# --------------------------------------------------------------------------------------------
# Evaluation
# --------------------------------------------------------------------------------------------


@njit(parallel=True, cache=True, fastmath=True)
def _evaluate_blocks(targets, out, first, bsz, P, M6, E, S, BE, A, start, table, ranks, reach,
                     kernel, blob_a, blob_e, iso):
    """Voxel values of blocks ``targets`` into ``out[first + t]`` (see the module docstring)."""
    top = bsz - 1.0
    one = np.float32(1.0)
    zero = np.float32(0.0)
    two = np.float32(2.0)
    for t in prange(targets.size):
        bx, by, bz = unpack_key(targets[t])
        ox = bx * bsz
        oy = by * bsz
        oz = bz * bsz
        buf = out[first + t]
        # neighbouring home blocks whose particles' boxes can reach this block (per-axis gap
        # between the blocks against the largest half extent among their particles)
        width = 2 * reach + 1
        near = np.empty(width ** 3, np.int64)
        nn = 0
        total = 0
        for dz in range(-reach, reach + 1):
            gz = max(abs(dz) - 1, 0) * bsz
            for dy in range(-reach, reach + 1):
                gy = max(abs(dy) - 1, 0) * bsz
                for dx in range(-reach, reach + 1):
                    gx = max(abs(dx) - 1, 0) * bsz
                    v = lookup(table, ranks, pack_key(bx + dx, by + dy, bz + dz))
                    if v < 0:
                        continue
                    if gx > BE[v, 0] or gy > BE[v, 1] or gz > BE[v, 2]:
                        continue
                    near[nn] = v
                    nn += 1
                    total += start[v + 1] - start[v]
        # candidates: bounding box and bounding sphere (longest semi-axis) reach the block
        cx = np.empty(total, np.float32)
        cy = np.empty(total, np.float32)
        cz = np.empty(total, np.float32)
        cm = np.empty((total, 6), np.float32)
        ca = np.empty(total, np.float32)
        cl = np.empty(total, np.float32)
        c = 0
        for s_ in range(nn):
            v = near[s_]
            for q in range(start[v], start[v + 1]):
                px = P[q, 0] - ox
                py = P[q, 1] - oy
                pz = P[q, 2] - oz
                if (px + E[q, 0] < 0.0 or px - E[q, 0] > top or py + E[q, 1] < 0.0
                        or py - E[q, 1] > top or pz + E[q, 2] < 0.0 or pz - E[q, 2] > top):
                    continue
                gx = max(-px, 0.0, px - top)
                gy = max(-py, 0.0, py - top)
                gz = max(-pz, 0.0, pz - top)
                if gx * gx + gy * gy + gz * gz >= S[q] * S[q]:
                    continue
                cx[c] = np.float32(px)
                cy[c] = np.float32(py)
                cz[c] = np.float32(pz)
                for k in range(6):
                    cm[c, k] = np.float32(M6[q, k])
                ca[c] = A[q]
                cl[c] = np.float32(E[q, 2])
                c += 1
        # per voxel plane, each candidate's exact range of rows (its shadow on the yz plane:
        # q^2 minimised over e_x is alpha e_y^2 + beta e_y e_z + gamma e_z^2), then its row
        # polynomials q^2 = a x^2 + b x + c in the voxel's x, written row by row
        al = np.empty(c, np.float32)
        hal = np.empty(c, np.float32)
        be_ = np.empty(c, np.float32)
        ga = np.empty(c, np.float32)
        for k in range(c):
            m00 = cm[k, 0]
            al[k] = cm[k, 1] - cm[k, 3] * cm[k, 3] / m00
            hal[k] = np.float32(0.5) / al[k]
            be_[k] = two * (cm[k, 5] - cm[k, 3] * cm[k, 4] / m00)
            ga[k] = cm[k, 2] - cm[k, 4] * cm[k, 4] / m00
        ra = np.empty((bsz, c), np.float32)
        rb = np.empty((bsz, c), np.float32)
        rc = np.empty((bsz, c), np.float32)
        ramp = np.empty((bsz, c), np.float32)
        rown = np.zeros(bsz, np.int64)
        topf = np.float32(top)
        for mz in range(bsz):
            z = np.float32(mz)
            rown[:] = 0
            for k in range(c):
                ez = z - cz[k]
                if abs(ez) > cl[k]:
                    continue
                bb = be_[k] * ez
                disc = bb * bb - np.float32(4.0) * al[k] * (ga[k] * ez * ez - one)
                if disc <= zero:
                    continue
                sq = np.sqrt(disc)
                y0 = max(int(math.ceil(cy[k] + (-bb - sq) * hal[k])), 0)
                y1 = min(int(math.floor(cy[k] + (-bb + sq) * hal[k])), bsz - 1)
                a = cm[k, 0]
                xk = cx[k]
                b0 = two * cm[k, 4] * ez
                b1 = two * cm[k, 3]
                c0 = cm[k, 2] * ez * ez
                c1 = two * cm[k, 5] * ez
                c2 = cm[k, 1]
                amp = ca[k]
                h2a = np.float32(0.5) / a
                for my in range(y0, y1 + 1):
                    ey = np.float32(my) - cy[k]
                    b = b1 * ey + b0
                    cc = (c2 * ey + c1) * ey + c0
                    # kept if the row's segment meets the block: q^2 at the parabola's vertex
                    # clamped to x in [0, top] below 1 (written always, counted if kept)
                    ex = min(max(xk - b * h2a, zero), topf) - xk
                    j = rown[my]
                    ra[my, j] = a
                    rb[my, j] = b - two * a * xk
                    rc[my, j] = (a * xk - b) * xk + cc
                    ramp[my, j] = amp
                    rown[my] = j + (1 if (a * ex + b) * ex + cc < one else 0)
            for my in range(bsz):
                m = rown[my]
                rowa = ra[my]
                rowb = rb[my]
                rowc = rc[my]
                rowm = ramp[my]
                for mx in range(bsz):
                    x = np.float32(mx)
                    acc = np.float32(0.0)
                    for k in range(m):
                        q2 = (rowa[k] * x + rowb[k]) * x + rowc[k]
                        q2 = q2 if q2 < one else one
                        q2 = abs(q2)  # rounding can leave -1e-7 near the centre
                        acc += rowm[k] * splat_row_profile(kernel, q2, blob_a, blob_e)
                    buf[mz, my, mx] = iso - acc


@njit(cache=True, inline="always")
def _field_at(x, y, z, P, M6, E, A, start, table, ranks, offs, bsz, kernel, blob_a, blob_e,
              stop):
    """Field at a point (voxel units); returns early once it reaches ``stop``."""
    bx = np.int64(math.floor(x / bsz))
    by = np.int64(math.floor(y / bsz))
    bz = np.int64(math.floor(z / bsz))
    f = 0.0
    for o in range(offs.shape[0]):
        v = lookup(table, ranks, pack_key(bx + offs[o, 0], by + offs[o, 1], bz + offs[o, 2]))
        if v < 0:
            continue
        for q in range(start[v], start[v + 1]):
            ex = x - P[q, 0]
            ey = y - P[q, 1]
            ez = z - P[q, 2]
            if abs(ex) > E[q, 0] or abs(ey) > E[q, 1] or abs(ez) > E[q, 2]:
                continue
            q2 = (M6[q, 0] * ex * ex + M6[q, 1] * ey * ey + M6[q, 2] * ez * ez
                  + 2.0 * (M6[q, 3] * ex * ey + M6[q, 4] * ex * ez + M6[q, 5] * ey * ez))
            if q2 < 1.0:
                f += A[q] * splat_row_profile(kernel, np.float32(max(q2, 0.0)), blob_a, blob_e)
        if f >= stop:
            return f
    return f


@njit(parallel=True, cache=True, fastmath=True)
def _sample_points(X, P, M6, E, A, start, table, ranks, offs, bsz, kernel, blob_a, blob_e, iso,
                   stop):
    """Implicit values ``iso - f`` at points ``X`` (K, 3) in voxel units; where ``f`` reaches
    ``stop`` the sum stops early (the value is then only known to be <= ``iso - stop``)."""
    out = np.empty(X.shape[0], np.float32)
    for t in prange(X.shape[0]):
        out[t] = iso - _field_at(X[t, 0], X[t, 1], X[t, 2], P, M6, E, A, start, table, ranks,
                                 offs, bsz, kernel, blob_a, blob_e, stop)
    return out


@njit(parallel=True, cache=True, fastmath=True)
def _upper_bounds(targets, bsz, P, E, L, A, start, table, ranks, offs, kernel, blob_a, blob_e,
                  stop):
    """Upper bound of the field over each block's box grown by one voxel; -1 if no particle's
    bounding box reaches it. The sum stops once it reaches ``stop`` (only ``bound < stop``
    matters)."""
    bound = np.empty(targets.size)
    for t in prange(targets.size):
        bx, by, bz, lox, loy, loz, hix, hiy, hiz = grown_block_box(targets[t], bsz)
        b = 0.0
        near = False
        for o in range(offs.shape[0]):
            v = lookup(table, ranks, pack_key(bx + offs[o, 0], by + offs[o, 1], bz + offs[o, 2]))
            if v < 0:
                continue
            for q in range(start[v], start[v + 1]):
                ex = max(lox - P[q, 0], 0.0, P[q, 0] - hix)
                ey = max(loy - P[q, 1], 0.0, P[q, 1] - hiy)
                ez = max(loz - P[q, 2], 0.0, P[q, 2] - hiz)
                if ex > E[q, 0] or ey > E[q, 1] or ez > E[q, 2]:
                    continue
                q2 = (ex * ex + ey * ey + ez * ez) * L[q]
                if q2 < 1.0:
                    near = True
                    b += A[q] * splat_row_profile(kernel, np.float32(q2), blob_a, blob_e)
            if b >= stop:
                break
        bound[t] = b if near else -1.0
    return bound


# --------------------------------------------------------------------------------------------
# Grid assembly
# --------------------------------------------------------------------------------------------


def _check_inputs(centres, G, amplitude, cell_size, kernel, iso, block_size, blobbiness,
                  max_bytes, trusted=False):
    centres = check_points("centres", centres)
    n = centres.shape[0]
    try:
        G = np.ascontiguousarray(G, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError("G must be an (N, 3, 3) array of numbers") from None
    if G.shape != (n, 3, 3):
        raise ValueError(f"G must have shape ({n}, 3, 3), got {G.shape}")
    if n and not trusted and not np.isfinite(G).all():
        raise ValueError("G must be finite")
    try:
        amplitude = np.ascontiguousarray(np.broadcast_to(amplitude, (n,)), dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"amplitude must be a number or have shape ({n},)") from None
    if n and not (np.isfinite(amplitude).all() and amplitude.min() >= 0):
        raise ValueError("amplitude must be finite and >= 0")
    kernel = check_choice("kernel", kernel, ANISOTROPIC_KERNELS)
    cell_size = check_range("cell_size", cell_size, 0.0, math.inf, low_inclusive=False)
    iso = ANISOTROPIC_ISO[kernel] if iso is None else iso
    iso = check_range("iso", iso, 0.0, math.inf, low_inclusive=False)
    block_size = check_int("block_size", block_size, 4, 64)
    blobbiness = check_range("blobbiness", blobbiness, 0.0, 100.0, low_inclusive=False)
    max_bytes = check_int("max_bytes", max_bytes, 1)
    if n and not trusted:
        det = np.linalg.det(G)
        if not (det > 0).all():
            raise ValueError("G must be positive definite for every particle (det(G) > 0)")
    return centres, G, amplitude, kernel, cell_size, iso, block_size, blobbiness, max_bytes


def ellipsoid_grid(centres: np.ndarray, G: np.ndarray, amplitude: ArrayLike, cell_size: float, *,
                   kernel: str = "sph", iso: float | None = None, block_size: int = 8,
                   blobbiness: float = 4.0, max_bytes: int = DEFAULT_MAX_BYTES,
                   skip_interior: bool = True, evaluate_all: bool = False, trusted: bool = False,
                   domain: tuple[ArrayLike, ArrayLike] | None = None) -> SparseGrid:
    """Implicit values of ellipsoidal kernels on the blocks of the voxel lattice near the surface.

    Parameters as in :func:`splat_ellipsoids_sparse`; ``evaluate_all`` evaluates every
    candidate block (the dense grid's values); ``trusted`` skips the checks of ``G`` (finite,
    positive definite) for matrices from :func:`filters.surface.anisotropy.kernel_matrices`;
    ``domain`` ``(lower, upper)`` (m) keeps only the candidate blocks that meet that box grown
    by one voxel (the others count as outside), as in :func:`filters.surface.spheres.sphere_grid`.

    Returns
    -------
    SparseGrid
    """
    (centres, G, amplitude, kernel, cell_size, iso, bsz, blobbiness,
     max_bytes) = _check_inputs(centres, G, amplitude, cell_size, kernel, iso, block_size,
                                blobbiness, max_bytes, trusted)
    kid = splat_kernel_id(kernel)
    n = centres.shape[0]
    if n == 0:
        return SparseGrid(cell_size, bsz, np.zeros(0, np.int64),
                          np.zeros((0, bsz, bsz, bsz), np.float32), np.zeros(0, np.int64),
                          -iso, iso)
    # before any key is computed: far-apart centres must not wrap past 2^20 blocks
    check_block_range("centres", centres, cell_size, bsz)
    check_budget(n * 200, max_bytes, f"particle bookkeeping for {n} particles")
    table, ranks, unique, start, order = bin_by_block(centres, cell_size, bsz)
    P, M6, E, SR, L = _prepare_ellipsoids(centres, G, order, 1.0 / cell_size,
                                          float(cell_size))
    A = np.ascontiguousarray(amplitude[order], dtype=np.float32)
    del order
    BE = np.ascontiguousarray(np.maximum.reduceat(E, start[:-1], axis=0))  # per home block
    emax = float(E.max())
    if emax > 64 * bsz:
        raise ValueError(f"kernel extent / cell_size must be <= {64 * bsz}; increase cell_size "
                         f"or block_size")
    reach = int(math.ceil((emax + 1.0) / bsz))
    # neighbouring block offsets, nearest first (early exits in the sampling and the bounds)
    rng = np.arange(-reach, reach + 1)
    offs = np.stack(np.meshgrid(rng, rng, rng, indexing="ij"), -1).reshape(-1, 3)
    offs = np.ascontiguousarray(offs[np.argsort((offs**2).sum(axis=1), kind="stable")])
    # only the blocks a particle's box can reach from a point at a block's lower corner
    # (corner samples), or from a block grown by one voxel (bounds): per-axis gaps against the
    # largest half extent, their length against the largest box half diagonal
    diag2 = float(1.0 / L.min()) * (1.0 + 1e-6)
    gap = np.where(offs > 0, offs * bsz, np.where(offs < 0, (-offs - 1) * bsz, 0)).astype(float)
    keep = (gap.max(axis=1) <= emax) & ((gap**2).sum(axis=1) <= diag2)
    offs_corner = np.ascontiguousarray(offs[keep])
    gap = np.maximum((np.abs(offs) - 1) * bsz - 1.0, 0.0)
    keep = (gap.max(axis=1) <= emax) & ((gap**2).sum(axis=1) <= diag2)
    offs_block = np.ascontiguousarray(offs[keep])
    ba = np.float32(blobbiness)
    be = np.float32(math.exp(-blobbiness))
    iso32 = np.float32(iso)
    # candidate blocks: per home block, the box of blocks its particles' bounding boxes touch
    active = _touched_blocks(P, E, start, unique, bsz)
    if domain is not None:
        active = active[blocks_meeting_box(active, bsz, cell_size, *domain)]

    def evaluate(targets, data, first):
        _evaluate_blocks(targets, data, first, bsz, P, M6, E, SR, BE, A, start, table, ranks,
                         reach, kid, ba, be, iso32)

    def corner_values(points):
        return _sample_points(points, P, M6, E, A, start, table, ranks, offs_corner, bsz, kid,
                              ba, be, iso32, 1.25 * iso)

    def upper_bounds(targets):
        return _upper_bounds(targets, bsz, P, E, L, A, start, table, ranks, offs_block, kid,
                             ba, be, iso)

    return classify_and_evaluate(
        active, block_size=bsz, cell_size=cell_size, max_bytes=max_bytes, inside_value=-iso,
        outside_value=iso, evaluate=evaluate,
        corner_values=corner_values if skip_interior and not evaluate_all else None,
        inside_margin=0.25 * iso, upper_bounds=upper_bounds if not evaluate_all else None,
        outside=lambda bound: bound < iso)


def splat_ellipsoids_sparse(centres: np.ndarray, G: np.ndarray, amplitude: ArrayLike,
                            cell_size: float, *, kernel: str = "sph", iso: float | None = None,
                            block_size: int = 8, blobbiness: float = 4.0,
                            skip_interior: bool = True,
                            max_bytes: int = DEFAULT_MAX_BYTES) -> SparseGrid:
    """Splat ellipsoidal kernels onto the blocks of the voxel lattice the surface passes near.

    Parameters
    ----------
    centres : (N, 3) float64
        Kernel centres ``c_j`` (m), within the block keys' range (about ``2**20 * block_size
        * cell_size`` of the origin; :func:`filters.surface.grid.check_block_range`), else
        ValueError.
    G : (N, 3, 3) float64
        Symmetric positive-definite kernel matrices (1/m): the kernel of particle ``j`` is
        ``K(|G_j (x - c_j)|^2)``, zero outside the ellipsoid ``|G_j r| < 1``.
    amplitude : float or (N,) float64
        ``a_j`` (dimensionless: the peak of each contribution to the summed field).
    cell_size : float
        Voxel edge (m), > 0.
    kernel : {"blobby", "metaball", "sph"}
        Kernel profile ``K`` (see :mod:`filters.surface.splat`).
    iso : float, optional
        Iso value of the summed field (default :data:`ANISOTROPIC_ISO`), > 0.
    block_size : int
        Voxels per block edge, in [4, 64].
    blobbiness : float
        ``a`` of the blobby kernel, in (0, 100].
    skip_interior : bool
        Skip blocks that coarse samples show to be deep inside.
    max_bytes : int
        Memory budget (bytes); :class:`filters.surface.grid.GridTooLargeError` above it.

    Returns
    -------
    SparseGrid
        Implicit values ``iso - f`` (negative inside), as
        :func:`filters.surface.splat.splat_sparse`.
    """
    return ellipsoid_grid(centres, G, amplitude, cell_size, kernel=kernel, iso=iso,
                          block_size=block_size, blobbiness=blobbiness, max_bytes=max_bytes,
                          skip_interior=skip_interior)


def splat_ellipsoids_dense(centres: np.ndarray, G: np.ndarray, amplitude: ArrayLike,
                           cell_size: float, *, kernel: str = "sph", iso: float | None = None,
                           block_size: int = 8, blobbiness: float = 4.0,
                           max_bytes: int = DEFAULT_MAX_BYTES,
                           domain: tuple[ArrayLike, ArrayLike] | None = None) -> DenseField:
    """Like :func:`splat_ellipsoids_sparse` but every reachable voxel evaluated, returned as a
    dense box (:class:`filters.surface.grid.DenseField`) covering the evaluated blocks plus one
    outside voxel layer; voxels no kernel reaches hold ``iso``; ``domain`` as in
    :func:`ellipsoid_grid`."""
    centres = check_points("centres", centres)
    if centres.shape[0]:
        cs = check_range("cell_size", cell_size, 0.0, math.inf, low_inclusive=False)
        check_block_range("centres", centres, cs, check_int("block_size", block_size, 4, 64))
        Gc = np.asarray(G, dtype=np.float64)
        if Gc.shape == (centres.shape[0], 3, 3):
            ext_m = float(np.sqrt(np.max(np.linalg.inv(Gc @ Gc)[:, [0, 1, 2], [0, 1, 2]])))
            ext = (centres.max(axis=0) - centres.min(axis=0) + 2 * ext_m) / cs + 3
            check_budget(int(4 * np.prod(ext)), int(max_bytes),
                         f"a dense grid of about {ext.astype(int).tolist()} voxels")
    grid = ellipsoid_grid(centres, G, amplitude, cell_size, kernel=kernel, iso=iso,
                          block_size=block_size, blobbiness=blobbiness, max_bytes=max_bytes,
                          evaluate_all=True, domain=domain)
    return grid.to_dense(max_bytes=max_bytes)
