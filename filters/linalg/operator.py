"""Matrix-free SPD operators of 3x3 blocks: the implicit systems of particles joined in pairs.

:class:`BlockOperator` holds ``H = D + sum_s [e_a - e_b] K_s [e_a - e_b]^T``: per particle ``i`` a
3x3 diagonal block ``D_i``, per pair ``s = (a, b)`` a symmetric 3x3 block ``K_s`` stored as its 6
distinct entries; rows and columns of fixed particles are the identity (``free`` masks them).
The implicit system of damped springs (Baraff & Witkin 1998) has this form
(:meth:`filters.elastic.springs.SpringSystem.implicit_operator`), 6 numbers per spring instead
of about 39 CSR non-zeros with their column indices. The conjugate-gradient solvers of
:mod:`filters.linalg.block_cg` and :mod:`filters.linalg.ssor` work on it.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

if TYPE_CHECKING:
    from numpy.typing import NDArray

__all__ = ["BlockOperator", "block_matvec", "apply_pair_block", "diag_product", "start_norm"]


@njit(cache=True, inline="always")
def start_norm(b, x):
    """``|b|`` of a right-hand side (N, 3); when it is 0, ``x`` is set to 0 (the solution)."""
    bb = 0.0
    for i in range(b.shape[0]):
        for k in range(3):
            bb += b[i, k] * b[i, k]
    bnorm = math.sqrt(bb)
    if bnorm == 0.0:
        for i in range(x.shape[0]):
            for k in range(3):
                x[i, k] = 0.0
    return bnorm


@njit(cache=True, inline="always")
def diag_product(diag, y, i, p0, p1, p2):
    """``y[i] = D_i p_i`` for the particle block ``diag[i]``; returns ``p_i . D_i p_i``."""
    y0 = diag[i, 0, 0] * p0 + diag[i, 0, 1] * p1 + diag[i, 0, 2] * p2
    y1 = diag[i, 1, 0] * p0 + diag[i, 1, 1] * p1 + diag[i, 1, 2] * p2
    y2 = diag[i, 2, 0] * p0 + diag[i, 2, 1] * p1 + diag[i, 2, 2] * p2
    y[i, 0] = y0
    y[i, 1] = y1
    y[i, 2] = y2
    return p0 * y0 + p1 * y1 + p2 * y2


@njit(cache=True)
def block_matvec(pairs, free, blocks, diag, p, y):
    """``y = H p`` for a :class:`BlockOperator`'s arrays (vectors ``p``, ``y`` of shape (N, 3));
    returns ``p . H p``."""
    acc = 0.0
    for i in range(p.shape[0]):
        acc += diag_product(diag, y, i, p[i, 0], p[i, 1], p[i, 2])
    for s in range(pairs.shape[0]):
        a = pairs[s, 0]
        b = pairs[s, 1]
        fa = free[a]
        fb = free[b]
        d0 = fa * p[a, 0] - fb * p[b, 0]
        d1 = fa * p[a, 1] - fb * p[b, 1]
        d2 = fa * p[a, 2] - fb * p[b, 2]
        k0, k1, k2 = apply_pair_block(blocks, s, d0, d1, d2)
        acc += d0 * k0 + d1 * k1 + d2 * k2
        y[a, 0] += fa * k0
        y[a, 1] += fa * k1
        y[a, 2] += fa * k2
        y[b, 0] -= fb * k0
        y[b, 1] -= fb * k1
        y[b, 2] -= fb * k2
    return acc


@njit(cache=True, inline="always")
def apply_pair_block(blocks, s, d0, d1, d2):
    """``K_s d`` for pair ``s`` (the symmetric 6-entry block ``blocks[s]``)."""
    return (blocks[s, 0] * d0 + blocks[s, 1] * d1 + blocks[s, 2] * d2,
            blocks[s, 1] * d0 + blocks[s, 3] * d1 + blocks[s, 4] * d2,
            blocks[s, 2] * d0 + blocks[s, 4] * d1 + blocks[s, 5] * d2)


class BlockOperator:
    """A matrix-free SPD operator ``H p = D p + sum_s [e_a - e_b] K_s (p_a - p_b)`` (see the
    module docstring). Rows and columns of fixed particles are the identity.

    Parameters
    ----------
    pairs : (S, 2) int64 array
        Particle pairs.
    free : (N,) float64 array
        1 for free particles, 0 for fixed ones.
    blocks : (S, 6) float64 array
        Pair blocks, filled by the caller (overwritten in place between solves).
    diag : (N, 3, 3) float64 array
        Particle blocks, filled by the caller.
    inc_ptr, inc_spring, inc_other : int64 arrays
        Particle -> pair incidence in CSR form (the pair and its other end).

    Attributes
    ----------
    lower, upper : tuple of 3 int64 arrays
        Particle ``i`` -> incident pairs whose other end ``j`` is ``< i`` (``lower``) or
        ``> i`` (``upper``), in CSR form ``(ptr (N+1,), spring, other)``, for the forward and
        backward Gauss-Seidel sweeps.
    upper_ordered : bool
        True when the pairs are in upper-incidence order (``pairs[:, 0] < pairs[:, 1]``,
        sorted by ``pairs[:, 0]``), so that ``upper[1]`` is ``arange(S)`` and the SSOR sweeps
        (:mod:`filters.linalg.ssor`) stream ``blocks`` in place.
    """

    def __init__(self, pairs: np.ndarray, free: np.ndarray, blocks: np.ndarray, diag: np.ndarray,
                 inc_ptr: np.ndarray, inc_spring: np.ndarray, inc_other: np.ndarray):
        self.pairs = pairs
        self.free = free
        self.blocks = blocks
        self.diag = diag
        n = diag.shape[0]
        node = np.repeat(np.arange(n), np.diff(inc_ptr))
        halves = []
        for keep in (inc_other < node, inc_other > node):
            ptr = np.zeros(n + 1, dtype=np.int64)
            np.cumsum(np.bincount(node[keep], minlength=n), out=ptr[1:])
            halves.append((ptr, np.ascontiguousarray(inc_spring[keep], dtype=np.int64),
                           np.ascontiguousarray(inc_other[keep], dtype=np.int64)))
        self.lower, self.upper = halves
        s = pairs.shape[0]
        self.upper_ordered = bool(self.upper[1].shape[0] == s
                                  and np.array_equal(self.upper[1], np.arange(s)))

    def pair_lookup(self) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """Sorted keys ``min(a, b) N + max(a, b)`` of the pairs and the pair of every key
        (int64 arrays (S,)), computed once: finds the pair of two particles by bisection."""
        if getattr(self, "_lookup", None) is None:
            n = self.diag.shape[0]
            lo = np.minimum(self.pairs[:, 0], self.pairs[:, 1]).astype(np.int64)
            hi = np.maximum(self.pairs[:, 0], self.pairs[:, 1]).astype(np.int64)
            keys = lo * n + hi
            order = np.argsort(keys, kind="stable")
            self._lookup = (np.ascontiguousarray(keys[order]),
                            np.ascontiguousarray(order, dtype=np.int64))
        return self._lookup

    @property
    def shape(self) -> tuple[int, int]:
        """``(3N, 3N)``."""
        n = 3 * self.diag.shape[0]
        return (n, n)

    def matvec(self, p: np.ndarray) -> NDArray[np.float64]:
        """``H p`` for ``p`` of shape (N, 3) or (3N,); same shape out."""
        p = np.ascontiguousarray(p, dtype=np.float64)
        y = np.empty_like(p)
        block_matvec(self.pairs, self.free, self.blocks, self.diag, p.reshape(-1, 3),
                         y.reshape(-1, 3))
        return y

    def __matmul__(self, p):
        return self.matvec(p)
