"""Conjugate gradients on a matrix-free :class:`filters.linalg.operator.BlockOperator`, in Numba.

Preconditioned by per-particle 3x3 block Jacobi or block symmetric Gauss-Seidel (one forward
and one backward sweep over the pairs per iteration, applied separately from the product).
Serial, with fused passes: ``p = z + beta p``, ``H p`` and ``p . H p`` in one product; the
updates of ``x`` and ``r`` with ``|r|^2`` in one loop; the preconditioner returns ``r . z``.
See :mod:`filters.linalg.ssor` for SSOR with Eisenstat's trick (the default of the
implicit schemes).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .dense3 import invert3_into
from .operator import apply_pair_block, diag_product, start_norm

__all__ = ["pcg_blocks"]


@njit(cache=True)
def _operator_block_inverse(pairs, free, blocks, diag):
    """Inverses of the particle diagonal blocks ``D_i + sum_s K_s`` (N, 3, 3) of the operator."""
    n = diag.shape[0]
    acc = np.zeros((n, 6))
    for s in range(pairs.shape[0]):
        a = pairs[s, 0]
        b = pairs[s, 1]
        for k in range(6):
            acc[a, k] += blocks[s, k]
            acc[b, k] += blocks[s, k]
    inv = np.empty((n, 3, 3))
    m = np.empty((3, 3))
    for i in range(n):
        for r in range(3):
            for q in range(3):
                m[r, q] = diag[i, r, q]
        if free[i] != 0.0:
            m[0, 0] += acc[i, 0]
            m[0, 1] += acc[i, 1]
            m[0, 2] += acc[i, 2]
            m[1, 0] += acc[i, 1]
            m[1, 1] += acc[i, 3]
            m[1, 2] += acc[i, 4]
            m[2, 0] += acc[i, 2]
            m[2, 1] += acc[i, 4]
            m[2, 2] += acc[i, 5]
        invert3_into(m, inv, i)
    return inv


@njit(cache=True)
def _op_update_matvec(pairs, free, blocks, diag, z, beta, p, y):
    """Fused ``p = z + beta p`` and ``y = H p``; returns ``p . H p`` (the CG curvature)."""
    acc = 0.0
    for i in range(p.shape[0]):
        p0 = z[i, 0] + beta * p[i, 0]
        p1 = z[i, 1] + beta * p[i, 1]
        p2 = z[i, 2] + beta * p[i, 2]
        p[i, 0] = p0
        p[i, 1] = p1
        p[i, 2] = p2
        acc += diag_product(diag, y, i, p0, p1, p2)
    # p is zero at pinned particles (see _pcg_operator), so no masks here; the rows of pinned
    # particles in y receive spring terms that the caller discards.
    for s in range(pairs.shape[0]):
        a = pairs[s, 0]
        b = pairs[s, 1]
        d0 = p[a, 0] - p[b, 0]
        d1 = p[a, 1] - p[b, 1]
        d2 = p[a, 2] - p[b, 2]
        k0, k1, k2 = apply_pair_block(blocks, s, d0, d1, d2)
        acc += d0 * k0 + d1 * k1 + d2 * k2
        y[a, 0] += k0
        y[a, 1] += k1
        y[a, 2] += k2
        y[b, 0] -= k0
        y[b, 1] -= k1
        y[b, 2] -= k2
    return acc


@njit(cache=True)
def _op_sgs(lo_ptr, lo_spring, lo_other, up_ptr, up_spring, up_other, free, blocks, inv, r_vec,
            z):
    """Block symmetric Gauss-Seidel preconditioner ``z = (D+U)^-1 D (D+L)^-1 r``; returns r.z.

    ``D`` are the particle diagonal blocks (``inv`` their inverses), ``L``/``U`` the
    off-diagonal spring blocks ``-(K_s + C_s/h)``, visited through the lower / upper halves of
    the particle -> spring incidence lists.  One forward and one backward sweep, ``z``
    overwritten in place.  ``r`` is zero at pinned particles, so ``z`` is too and their
    columns need no mask.
    """
    n = r_vec.shape[0]
    for i in range(n):  # forward: (D + L) y = r
        if free[i] == 0.0:
            z[i, 0] = 0.0
            z[i, 1] = 0.0
            z[i, 2] = 0.0
            continue
        a0 = r_vec[i, 0]
        a1 = r_vec[i, 1]
        a2 = r_vec[i, 2]
        for p in range(lo_ptr[i], lo_ptr[i + 1]):
            j = lo_other[p]
            k0, k1, k2 = apply_pair_block(blocks, lo_spring[p], z[j, 0], z[j, 1], z[j, 2])
            a0 += k0
            a1 += k1
            a2 += k2
        z[i, 0] = inv[i, 0, 0] * a0 + inv[i, 0, 1] * a1 + inv[i, 0, 2] * a2
        z[i, 1] = inv[i, 1, 0] * a0 + inv[i, 1, 1] * a1 + inv[i, 1, 2] * a2
        z[i, 2] = inv[i, 2, 0] * a0 + inv[i, 2, 1] * a1 + inv[i, 2, 2] * a2
    rz = 0.0
    for i in range(n - 1, -1, -1):  # backward: (D + U) z = D y
        if free[i] == 0.0:
            continue
        a0 = 0.0
        a1 = 0.0
        a2 = 0.0
        for p in range(up_ptr[i], up_ptr[i + 1]):
            j = up_other[p]
            k0, k1, k2 = apply_pair_block(blocks, up_spring[p], z[j, 0], z[j, 1], z[j, 2])
            a0 += k0
            a1 += k1
            a2 += k2
        z[i, 0] += inv[i, 0, 0] * a0 + inv[i, 0, 1] * a1 + inv[i, 0, 2] * a2
        z[i, 1] += inv[i, 1, 0] * a0 + inv[i, 1, 1] * a1 + inv[i, 1, 2] * a2
        z[i, 2] += inv[i, 2, 0] * a0 + inv[i, 2, 1] * a1 + inv[i, 2, 2] * a2
        rz += r_vec[i, 0] * z[i, 0] + r_vec[i, 1] * z[i, 1] + r_vec[i, 2] * z[i, 2]
    return rz


@njit(cache=True)
def _op_block_jacobi(inv, r_vec, z):
    rz = 0.0
    for i in range(r_vec.shape[0]):
        r0 = r_vec[i, 0]
        r1 = r_vec[i, 1]
        r2 = r_vec[i, 2]
        z0 = inv[i, 0, 0] * r0 + inv[i, 0, 1] * r1 + inv[i, 0, 2] * r2
        z1 = inv[i, 1, 0] * r0 + inv[i, 1, 1] * r1 + inv[i, 1, 2] * r2
        z2 = inv[i, 2, 0] * r0 + inv[i, 2, 1] * r1 + inv[i, 2, 2] * r2
        z[i, 0] = z0
        z[i, 1] = z1
        z[i, 2] = z2
        rz += r0 * z0 + r1 * z1 + r2 * z2
    return rz


@njit(cache=True)
def _op_precondition(sgs, lower, upper, free, blocks, inv, r_vec, z):
    if sgs:
        return _op_sgs(lower[0], lower[1], lower[2], upper[0], upper[1], upper[2], free, blocks,
                       inv, r_vec, z)
    return _op_block_jacobi(inv, r_vec, z)


@njit(cache=True)
def pcg_blocks(pairs, free, blocks, diag, lower, upper, b, x, tol, max_iter, sgs):
    """PCG for ``H x = b`` with a matrix-free block operator's arrays (vectors (N, 3)).

    Serial, with fused passes: ``p = z + beta p``, ``H p`` and ``p . H p`` in one product; the
    updates of ``x`` and ``r`` with ``|r|^2`` in one loop; the preconditioner returns ``r . z``.
    ``sgs`` selects block symmetric Gauss-Seidel (else block Jacobi).  Stops when
    ``|r| <= tol |b|``; returns (iterations, relative residual).
    """
    n = b.shape[0]
    inv = _operator_block_inverse(pairs, free, blocks, diag)
    r_vec = np.empty((n, 3))
    z = np.zeros((n, 3))
    p_vec = np.zeros((n, 3))
    ap = np.empty((n, 3))
    bnorm = start_norm(b, x)
    if bnorm == 0.0:
        return 0, 0.0
    # Pinned rows are the identity: x_i = b_i there, solved up front.  CG then runs on the free
    # particles with zeros at the pinned ones (r, z and p stay zero there because the pinned rows
    # of every product are masked out), so the spring loops need no masks.
    for i in range(n):
        if free[i] == 0.0:
            for k in range(3):
                x[i, k] = 0.0
    # r = b - H x (z = 0 so that the fused product computes H x with p = x)
    _op_update_matvec(pairs, free, blocks, diag, x, 0.0, p_vec, ap)
    rr = 0.0
    for i in range(n):
        fi = free[i]
        for k in range(3):
            r_vec[i, k] = fi * (b[i, k] - ap[i, k])
            rr += r_vec[i, k] * r_vec[i, k]
    rz = _op_precondition(sgs, lower, upper, free, blocks, inv, r_vec, z)
    beta = 0.0
    it = 0
    # the pinned part of b is solved exactly; only the free residual remains
    while math.sqrt(rr) > tol * bnorm and it < max_iter:
        pap = _op_update_matvec(pairs, free, blocks, diag, z, beta, p_vec, ap)
        if not pap > 0.0:
            break
        alpha = rz / pap
        rr = 0.0
        for i in range(n):
            fa = alpha * free[i]
            for k in range(3):
                x[i, k] += alpha * p_vec[i, k]
                r_vec[i, k] -= fa * ap[i, k]
                rr += r_vec[i, k] * r_vec[i, k]
        rz_new = _op_precondition(sgs, lower, upper, free, blocks, inv, r_vec, z)
        if not rz > 0.0:  # r . z underflowed (a state of ~1e-160): nothing left to solve
            it += 1
            break
        beta = rz_new / rz
        rz = rz_new
        it += 1
    for i in range(n):
        if free[i] == 0.0:
            for k in range(3):
                x[i, k] = b[i, k]
    return it, math.sqrt(rr) / bnorm
