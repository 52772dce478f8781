"""Conjugate gradients on a CSR matrix, preconditioned by its inverse diagonal blocks, in Numba.

For SPD systems given as ``scipy.sparse`` CSR matrices (the assembled implicit system of
:meth:`filters.elastic.springs.SpringSystem.system_matrix`): block Jacobi with 3x3 blocks (one per
particle, which captures the anisotropy of the springs at a particle) or 1x1 (plain Jacobi).
Serial on purpose: thousands of tiny parallel regions per solve lose to one thread on a busy
machine (a descheduled worker stalls every barrier), and NumPy's BLAS-backed dot products stall
the same way (:func:`vdot` keeps them in Numba).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from .dense3 import invert3_into
from .scale import unit_scale

if TYPE_CHECKING:
    from numpy.typing import NDArray
    from scipy.sparse import csr_matrix

__all__ = ["pcg", "vdot"]


@njit(cache=True)
def _spmv(indptr, indices, data, x, y):
    for r in range(indptr.shape[0] - 1):
        acc = 0.0
        for p in range(indptr[r], indptr[r + 1]):
            acc += data[p] * x[indices[p]]
        y[r] = acc


@njit(cache=True)
def _dot(a, b):
    acc = 0.0
    for i in range(a.shape[0]):
        acc += a[i] * b[i]
    return acc


def vdot(a: np.ndarray, b: np.ndarray) -> float:
    """``sum(a * b)`` of two float64 arrays in Numba: NumPy's ``vdot`` calls BLAS, whose
    threads stall on a busy 2-core machine (measured: a 12k-vector ``ddot`` up to 12 ms, and a
    settle test 3-5x slower under pytest than as a script); the Newton loop takes several per
    iteration."""
    return float(_dot(np.ascontiguousarray(a, dtype=np.float64).reshape(-1),
                      np.ascontiguousarray(b, dtype=np.float64).reshape(-1)))


@njit(cache=True)
def _block_jacobi(indptr, indices, data, block):
    """Inverse diagonal blocks (n/block, block, block) of a CSR matrix (block 1 or 3)."""
    n = indptr.shape[0] - 1
    nb = n // block
    inv = np.zeros((nb, block, block))
    for i in range(nb):
        a = np.zeros((block, block))
        for r in range(block):
            row = i * block + r
            for p in range(indptr[row], indptr[row + 1]):
                c = indices[p] - i * block
                if 0 <= c < block:
                    a[r, c] = data[p]
        if block == 1:
            inv[i, 0, 0] = 1.0 / a[0, 0] if a[0, 0] > 0.0 else 1.0
        else:
            invert3_into(a, inv, i)
    return inv


@njit(cache=True)
def _precondition(inv, r_vec, z):
    block = inv.shape[1]
    rr = 0.0
    rz = 0.0
    for i in range(inv.shape[0]):
        for p in range(block):
            acc = 0.0
            for q in range(block):
                acc += inv[i, p, q] * r_vec[i * block + q]
            z[i * block + p] = acc
            rr += r_vec[i * block + p] * r_vec[i * block + p]
            rz += r_vec[i * block + p] * acc
    return rr, rz


@njit(cache=True)
def _pcg(indptr, indices, data, b, x, tol, max_iter, block):
    """Block-Jacobi PCG for SPD ``A x = b``; ``x`` holds the warm start and the result.

    The preconditioner inverts the ``block`` x ``block`` diagonal blocks (3: one per particle,
    which captures the anisotropy of the springs at a particle; 1: plain Jacobi).  Serial on
    purpose: thousands of tiny parallel regions per solve lose to one thread on a busy machine
    (a descheduled worker stalls every barrier).  Stops when ``|r| <= tol |b|``.  Returns
    (iterations, relative residual).
    """
    n = b.shape[0]
    inv = _block_jacobi(indptr, indices, data, block)
    r_vec = np.empty(n)
    _spmv(indptr, indices, data, x, r_vec)
    for i in range(n):
        r_vec[i] = b[i] - r_vec[i]
    bnorm = math.sqrt(_dot(b, b))
    if bnorm == 0.0:
        for i in range(n):
            x[i] = 0.0
        return 0, 0.0
    z = np.empty(n)
    rr, rz = _precondition(inv, r_vec, z)
    p_vec = z.copy()
    ap = np.empty(n)
    rnorm = math.sqrt(rr)
    it = 0
    while rnorm > tol * bnorm and it < max_iter:
        _spmv(indptr, indices, data, p_vec, ap)
        pap = _dot(p_vec, ap)
        if pap <= 0.0:
            break
        alpha = rz / pap
        for i in range(n):
            x[i] += alpha * p_vec[i]
            r_vec[i] -= alpha * ap[i]
        rr, rz_new = _precondition(inv, r_vec, z)
        rnorm = math.sqrt(rr)
        if not rz > 0.0:  # r . z underflowed (a state of ~1e-160): nothing left to solve
            it += 1
            break
        beta = rz_new / rz
        rz = rz_new
        _update_p(p_vec, z, beta)
        it += 1
    return it, rnorm / bnorm


@njit(cache=True)
def _update_p(p_vec, z, beta):
    for i in range(p_vec.shape[0]):
        p_vec[i] = z[i] + beta * p_vec[i]


def pcg(matrix: csr_matrix, b: np.ndarray, x0: np.ndarray | None = None, *, tol: float = 1e-6,
        max_iter: int = 1000, block: int | None = None) -> tuple[NDArray[np.float64], int, float]:
    """Solve the SPD system ``matrix @ x = b`` by block-Jacobi-preconditioned CG in Numba.

    Parameters
    ----------
    matrix : scipy.sparse.csr_matrix, (n, n)
        Symmetric positive definite matrix.
    b : (n,) float64 array
        Right-hand side.
    x0 : (n,) float64 array, optional
        Warm start (zeros if omitted); not modified.
    tol : float
        Relative residual ``|b - A x| / |b|`` to reach.
    max_iter : int
        Iteration limit.
    block : {1, 3}, optional
        Size of the diagonal blocks the preconditioner inverts; 3 (per particle) when ``n`` is a
        multiple of 3, else 1 (Jacobi).

    Returns
    -------
    x : (n,) float64 array
    iterations : int
    relative_residual : float

    Notes
    -----
    The system is solved at unit scale (:func:`filters.linalg.scale.unit_scale`), so a
    right-hand side of 1e-200 or of denormals gives its (tiny) solution, and a zero one zero.
    """
    b = np.ascontiguousarray(b, dtype=np.float64)
    if block is None:
        block = 3 if b.shape[0] % 3 == 0 else 1
    if block not in (1, 3) or b.shape[0] % block:
        raise ValueError(f"block must be 1 or 3 and divide n = {b.shape[0]}, got {block!r}")
    s, bs, xs = unit_scale(b, x0)
    if s == 0.0:
        return np.zeros_like(b), 0, 0.0
    x = np.zeros_like(b) if xs is None else np.array(xs, dtype=np.float64, copy=True)
    it, res = _pcg(matrix.indptr, matrix.indices, matrix.data, np.ascontiguousarray(bs), x,
                   float(tol), int(max_iter), int(block))
    if s != 1.0:
        x *= s
    return x, int(it), float(res)
