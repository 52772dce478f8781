"""Symmetric eigen-decomposition and signed SVD of 3x3 matrices, allocation-free, for kernels.

* :func:`sym_eig3` -- cyclic Jacobi rotations (Jacobi 1846; Golub & Van Loan 2013, "Matrix
  computations", Sec. 8.5) on a symmetric 3x3 matrix, to machine precision.
* :func:`svd3` -- the *signed* (rotation-variant) SVD ``F = U diag(s) V^T`` with ``U`` and ``V``
  proper rotations (``det = +1``), ``s0 >= s1 >= |s2|`` and ``s2 < 0`` exactly when
  ``det F < 0`` (an inverted element; Irving, Teran & Fedkiw 2004, "Invertible finite elements
  for robust simulation of large deformation"), computed as McAdams et al. (2011, "Computing
  the singular value decomposition of 3x3 matrices with minimal branching and elementary
  floating point operations", UW-Madison TR1690) do: Jacobi on ``F^T F`` gives ``V``, then a
  Givens QR of ``F V`` gives ``U`` and the signed values, accurate also for small ``s``.
* :func:`sym_project_psd3` -- the nearest positive semi-definite matrix of a symmetric 3x3
  (negative eigenvalues clamped to 0).

All take and fill caller-owned arrays, so a kernel can keep its scratch per thread.
"""

from __future__ import annotations

import math

from numba import njit

__all__ = ["sym_eig3", "svd3", "sym_project_psd3"]

#: Jacobi sweeps are stopped when the off-diagonal mass falls below this fraction of the
#: matrix's squared Frobenius norm (round-off level).
_OFF_TOL = 1e-30
_MAX_SWEEPS = 32


@njit(cache=True, inline="always")
def _rotate(m, q, p, r):
    """One Jacobi rotation annihilating ``m[p, r]`` (``m`` symmetric, updated in place);
    accumulates the rotation into the columns of ``q``."""
    apr = m[p, r]
    if apr == 0.0:
        return
    theta = (m[r, r] - m[p, p]) / (2.0 * apr)
    t = 1.0 / (abs(theta) + math.sqrt(theta * theta + 1.0))
    if theta < 0.0:
        t = -t
    c = 1.0 / math.sqrt(t * t + 1.0)
    s = t * c
    o = 3 - p - r  # the third index
    mpp = m[p, p]
    mrr = m[r, r]
    m[p, p] = mpp - t * apr
    m[r, r] = mrr + t * apr
    m[p, r] = 0.0
    m[r, p] = 0.0
    mop = m[o, p]
    mor = m[o, r]
    m[o, p] = c * mop - s * mor
    m[p, o] = m[o, p]
    m[o, r] = s * mop + c * mor
    m[r, o] = m[o, r]
    for k in range(3):
        qkp = q[k, p]
        qkr = q[k, r]
        q[k, p] = c * qkp - s * qkr
        q[k, r] = s * qkp + c * qkr


@njit(cache=True)
def sym_eig3(a, w, q, m):
    """Eigen-decomposition ``a = q diag(w) q^T`` of a symmetric 3x3 matrix (cyclic Jacobi).

    Parameters
    ----------
    a : (3, 3) float64
        Symmetric matrix (only read).
    w : (3,) float64
        Filled with the eigenvalues, in no particular order.
    q : (3, 3) float64
        Filled with the orthonormal eigenvectors as columns (``det q = +1``).
    m : (3, 3) float64
        Scratch.
    """
    norm = 0.0
    for i in range(3):
        for j in range(3):
            m[i, j] = 0.5 * (a[i, j] + a[j, i])
            q[i, j] = 1.0 if i == j else 0.0
            norm += m[i, j] * m[i, j]
    for _ in range(_MAX_SWEEPS):
        off = m[0, 1] * m[0, 1] + m[0, 2] * m[0, 2] + m[1, 2] * m[1, 2]
        if off <= _OFF_TOL * norm:
            break
        _rotate(m, q, 0, 1)
        _rotate(m, q, 0, 2)
        _rotate(m, q, 1, 2)
    for i in range(3):
        w[i] = m[i, i]


@njit(cache=True)
def sym_project_psd3(a, w, q, m):
    """Replace the symmetric 3x3 ``a`` by its nearest positive semi-definite matrix, in place.

    Eigenvalues below 0 are set to 0 (the projection of Teran et al. 2005, "Robust quasistatic
    finite elements and flesh simulation").  ``w``, ``q``, ``m`` are scratch as in
    :func:`sym_eig3`.  Returns True when ``a`` was changed.
    """
    sym_eig3(a, w, q, m)
    if w[0] >= 0.0 and w[1] >= 0.0 and w[2] >= 0.0:
        return False
    for k in range(3):
        if w[k] < 0.0:
            w[k] = 0.0
    for i in range(3):
        for j in range(3):
            a[i, j] = (q[i, 0] * w[0] * q[j, 0] + q[i, 1] * w[1] * q[j, 1]
                       + q[i, 2] * w[2] * q[j, 2])
    return True


@njit(cache=True, inline="always")
def _givens_rows(b, u, i, j, col):
    """Rotate rows ``i, j`` of ``b`` so that ``b[j, col] = 0`` and ``b[i, col] >= 0``;
    accumulate the transpose of the rotation into the columns ``i, j`` of ``u``."""
    x = b[i, col]
    y = b[j, col]
    r = math.sqrt(x * x + y * y)
    if r == 0.0:
        return
    c = x / r
    s = y / r
    for k in range(3):
        bi = b[i, k]
        bj = b[j, k]
        b[i, k] = c * bi + s * bj
        b[j, k] = -s * bi + c * bj
    b[j, col] = 0.0
    for k in range(3):
        ui = u[k, i]
        uj = u[k, j]
        u[k, i] = c * ui + s * uj
        u[k, j] = -s * ui + c * uj


@njit(cache=True)
def svd3(f, u, s, v, m, w):
    """Signed SVD ``f = u diag(s) v^T`` of a 3x3 matrix (see the module docstring).

    Parameters
    ----------
    f : (3, 3) float64
        The matrix (only read).
    u, v : (3, 3) float64
        Filled with rotations (``det = +1``).
    s : (3,) float64
        Filled with ``s0 >= s1 >= |s2|``; ``s2`` has the sign of ``det f``.
    m : (3, 3) float64
        Scratch.
    w : (3,) float64
        Scratch.
    """
    # V: eigenvectors of F^T F, sorted by decreasing eigenvalue, as a rotation
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for k in range(3):
                acc += f[k, i] * f[k, j]
            u[i, j] = acc  # u used as scratch for F^T F
    sym_eig3(u, w, v, m)
    for i in range(2):  # selection sort of three values, columns of v alongside
        best = i
        for j in range(i + 1, 3):
            if w[j] > w[best]:
                best = j
        if best != i:
            w[i], w[best] = w[best], w[i]
            for k in range(3):
                v[k, i], v[k, best] = v[k, best], v[k, i]
    det_v = (v[0, 0] * (v[1, 1] * v[2, 2] - v[1, 2] * v[2, 1])
             - v[0, 1] * (v[1, 0] * v[2, 2] - v[1, 2] * v[2, 0])
             + v[0, 2] * (v[1, 0] * v[2, 1] - v[1, 1] * v[2, 0]))
    if det_v < 0.0:
        for k in range(3):
            v[k, 2] = -v[k, 2]
    # B = F V, then Givens QR: B = U R with R upper triangular, diagonal up to round-off
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for k in range(3):
                acc += f[i, k] * v[k, j]
            m[i, j] = acc
            u[i, j] = 1.0 if i == j else 0.0
    _givens_rows(m, u, 0, 1, 0)
    _givens_rows(m, u, 0, 2, 0)
    _givens_rows(m, u, 1, 2, 1)
    for i in range(3):
        s[i] = m[i, i]
