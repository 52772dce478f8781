"""Time integrators for particle systems: explicit, symplectic, linearised and full backward Euler.

Every scheme has the same shape::

    info = scheme(system, state, h, **options)

``system`` supplies forces, energies and the implicit system matrix (see
:class:`filters.elastic.springs.SpringSystem`, whose interface this module relies on: ``masses``,
``inv_mass``, ``pinned``, ``forces(x, v)``, ``conservative_forces(x)``,
``damping_forces(xdir, v)``, ``potential_energy(x)``, ``system_matrix(x, xdir, h)``).
``state`` is anything with ``positions`` and ``velocities`` (N, 3) float64 arrays (a
:class:`filters.simulation.State`), advanced by one step ``h`` (s) **in place**; an optional
``state.extra`` dict keeps the warm start of the iterative solver, so that a checkpointed state
resumes bit-identically.  Each scheme returns a :class:`StepInfo`.

Schemes
-------
* :func:`forward_euler` — ``x += h v; v += h f(x, v) / m``.  Energy of an undamped oscillator grows
  by ``(1 + h^2 w^2)`` per step.
* :func:`symplectic_euler` — ``v += h f(x, v) / m; x += h v``.  Bounded energy error, unstable
  for ``h w > 2``.
* :func:`linearized_backward_euler` — one Newton step of backward Euler (Baraff & Witkin 1998,
  "Large steps in cloth simulation"):
  ``(M - h df/dv - h^2 df/dx) dv = h (f0 + h df/dx v0)``.
* :func:`backward_euler` — backward Euler solved by Newton's method with a backtracking line
  search on the incremental potential (Gast, Schroeder, Stomakhin, Jiang & Teran 2015,
  "Optimization integrator for large time steps", IEEE TVCG)::

      E(dx) = |dx - h v|_M^2 / (2 h^2) + U(x + dx) + dx^T C dx / (2 h)

  whose minimiser is the backward Euler step; every accepted iterate lowers ``E``, so the step
  cannot gain energy.  Axial damping directions are frozen at the start of the step so that the
  damping term is a true (quadratic) dissipation potential.  The robust default.
* :func:`implicit_advection` — the first-order form for particles advected by a velocity field
  ``dx/dt = v(x)``: ``(I - h dv/dx) dx = h v(x^n)`` (one linearised backward Euler step; the seed's
  slide dropped the ``h`` in front of the Jacobian).

Linear solves
-------------
``solver="pcg"``: preconditioned conjugate gradients in Numba, warm started from the previous
step's solution. For systems that offer ``implicit_operator(x, xdir, h)`` (a
:class:`filters.elastic.springs.SpringOperator`) the product is matrix-free (a symmetric 3x3 block, 6
numbers, per spring), with fused passes (``p`` update + product + ``p.Hp``; ``x``/``r`` update +
``|r|^2``) and a choice of per-particle block Jacobi, block symmetric Gauss-Seidel, or block SSOR
with Eisenstat's (1981) trick, whose two sweeps replace the product with ``H`` (the default of
:func:`backward_euler`); otherwise
block Jacobi on the CSR matrix of ``system_matrix`` (:func:`pcg`). All serial: on the busy 2-core
machine a parallel region per vector operation loses to one thread. ``solver="direct"``: SuperLU
(``scipy.sparse.linalg``) with a minimum-degree ordering on ``A + A^T``; ``solver="auto"``: PCG,
falling back to the direct solve when PCG does not converge in ``max_iter`` iterations. The choice
was made with ``benchmarks/bench_springs.py`` (see ``benchmarks/results/springs.json``). Pinned
particles are eliminated: their rows and columns are replaced by the identity with a zero
right-hand side. :func:`backward_euler` solves inexactly with an Eisenstat & Walker (1996) forcing
sequence.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from .elastic.springs import _operator_matvec
from .validation import check_choice, check_int, check_range

__all__ = [
    "StepInfo",
    "SCHEMES",
    "SOLVERS",
    "forward_euler",
    "symplectic_euler",
    "linearized_backward_euler",
    "backward_euler",
    "implicit_advection",
    "pcg",
    "pcg_operator",
    "PRECONDITIONERS",
    "solve_linear",
    "integrate",
]

SOLVERS = ("auto", "pcg", "direct")


@dataclass
class StepInfo:
    """What one integration step did.

    Attributes
    ----------
    newton_iterations : int
        Newton iterations (0 for explicit schemes, 1 for the linearised one).
    linear_iterations : int
        Total PCG iterations over the step (0 for direct solves).
    direct_solves : int
        Number of sparse direct factorisations.
    line_search_halvings : int
        Total step halvings of the line search.
    residual : float
        Final Newton step size ``max |d| / h`` (m/s) -- or, when :func:`backward_euler` stopped
        on quadratic convergence, the estimate ``|d_k|^2 / |d_{k-1}|`` of the next one --, or 0
        for explicit schemes.
    """

    newton_iterations: int = 0
    linear_iterations: int = 0
    direct_solves: int = 0
    line_search_halvings: int = 0
    residual: float = 0.0


# ---------------------------------------------------------------------------------------------
# Linear algebra in Numba
# ---------------------------------------------------------------------------------------------
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


def _vdot(a, b):
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
            c00 = a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1]
            c01 = a[1, 2] * a[2, 0] - a[1, 0] * a[2, 2]
            c02 = a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]
            det = a[0, 0] * c00 + a[0, 1] * c01 + a[0, 2] * c02
            if det <= 0.0:
                for r in range(3):
                    inv[i, r, r] = 1.0 / a[r, r] if a[r, r] > 0.0 else 1.0
                continue
            d = 1.0 / det
            inv[i, 0, 0] = c00 * d
            inv[i, 1, 0] = c01 * d
            inv[i, 2, 0] = c02 * d
            inv[i, 0, 1] = (a[0, 2] * a[2, 1] - a[0, 1] * a[2, 2]) * d
            inv[i, 1, 1] = (a[0, 0] * a[2, 2] - a[0, 2] * a[2, 0]) * d
            inv[i, 2, 1] = (a[0, 1] * a[2, 0] - a[0, 0] * a[2, 1]) * d
            inv[i, 0, 2] = (a[0, 1] * a[1, 2] - a[0, 2] * a[1, 1]) * d
            inv[i, 1, 2] = (a[0, 2] * a[1, 0] - a[0, 0] * a[1, 2]) * d
            inv[i, 2, 2] = (a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]) * d
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
        beta = rz_new / rz
        rz = rz_new
        _update_p(p_vec, z, beta)
        it += 1
    return it, rnorm / bnorm


@njit(cache=True)
def _update_p(p_vec, z, beta):
    for i in range(p_vec.shape[0]):
        p_vec[i] = z[i] + beta * p_vec[i]


def pcg(matrix, b, x0=None, *, tol=1e-6, max_iter=1000, block=None):
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
    """
    b = np.ascontiguousarray(b, dtype=np.float64)
    x = np.zeros_like(b) if x0 is None else np.array(x0, dtype=np.float64, copy=True)
    if block is None:
        block = 3 if b.shape[0] % 3 == 0 else 1
    if block not in (1, 3) or b.shape[0] % block:
        raise ValueError(f"block must be 1 or 3 and divide n = {b.shape[0]}, got {block!r}")
    it, res = _pcg(matrix.indptr, matrix.indices, matrix.data, b, x, float(tol), int(max_iter),
                   int(block))
    return x, int(it), float(res)


# ---------------------------------------------------------------------------------------------
# Matrix-free PCG on a spring operator (see filters.elastic.springs.SpringOperator)
# ---------------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _inv3(a, out, i):
    """``out[i] = a^-1`` for a 3x3 SPD block ``a`` (diagonal inverse if not positive definite)."""
    c00 = a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1]
    c01 = a[1, 2] * a[2, 0] - a[1, 0] * a[2, 2]
    c02 = a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]
    det = a[0, 0] * c00 + a[0, 1] * c01 + a[0, 2] * c02
    if not det > 0.0:
        for r in range(3):
            for q in range(3):
                out[i, r, q] = 0.0
            out[i, r, r] = 1.0 / a[r, r] if a[r, r] > 0.0 else 1.0
        return
    d = 1.0 / det
    out[i, 0, 0] = c00 * d
    out[i, 1, 0] = c01 * d
    out[i, 2, 0] = c02 * d
    out[i, 0, 1] = (a[0, 2] * a[2, 1] - a[0, 1] * a[2, 2]) * d
    out[i, 1, 1] = (a[0, 0] * a[2, 2] - a[0, 2] * a[2, 0]) * d
    out[i, 2, 1] = (a[0, 1] * a[2, 0] - a[0, 0] * a[2, 1]) * d
    out[i, 0, 2] = (a[0, 1] * a[1, 2] - a[0, 2] * a[1, 1]) * d
    out[i, 1, 2] = (a[0, 2] * a[1, 0] - a[0, 0] * a[1, 2]) * d
    out[i, 2, 2] = (a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]) * d


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
        _inv3(m, inv, i)
    return inv


@njit(cache=True, inline="always")
def _apply_spring(blocks, s, d0, d1, d2):
    """``(K_s + C_s/h) d`` for spring ``s`` of the operator (symmetric 6-entry block)."""
    return (blocks[s, 0] * d0 + blocks[s, 1] * d1 + blocks[s, 2] * d2,
            blocks[s, 1] * d0 + blocks[s, 3] * d1 + blocks[s, 4] * d2,
            blocks[s, 2] * d0 + blocks[s, 4] * d1 + blocks[s, 5] * d2)


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
        y0 = diag[i, 0, 0] * p0 + diag[i, 0, 1] * p1 + diag[i, 0, 2] * p2
        y1 = diag[i, 1, 0] * p0 + diag[i, 1, 1] * p1 + diag[i, 1, 2] * p2
        y2 = diag[i, 2, 0] * p0 + diag[i, 2, 1] * p1 + diag[i, 2, 2] * p2
        y[i, 0] = y0
        y[i, 1] = y1
        y[i, 2] = y2
        acc += p0 * y0 + p1 * y1 + p2 * y2
    # p is zero at pinned particles (see _pcg_operator), so no masks here; the rows of pinned
    # particles in y receive spring terms that the caller discards.
    for s in range(pairs.shape[0]):
        a = pairs[s, 0]
        b = pairs[s, 1]
        d0 = p[a, 0] - p[b, 0]
        d1 = p[a, 1] - p[b, 1]
        d2 = p[a, 2] - p[b, 2]
        k0, k1, k2 = _apply_spring(blocks, s, d0, d1, d2)
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
            k0, k1, k2 = _apply_spring(blocks, lo_spring[p], z[j, 0], z[j, 1], z[j, 2])
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
            k0, k1, k2 = _apply_spring(blocks, up_spring[p], z[j, 0], z[j, 1], z[j, 2])
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
def _pcg_operator(pairs, free, blocks, diag, lower, upper, b, x, tol, max_iter, sgs):
    """PCG for ``H x = b`` with the matrix-free spring operator (vectors (N, 3)).

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
    bb = 0.0
    for i in range(n):
        for k in range(3):
            bb += b[i, k] * b[i, k]
    bnorm = math.sqrt(bb)
    if bnorm == 0.0:
        for i in range(n):
            for k in range(3):
                x[i, k] = 0.0
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
        beta = rz_new / rz
        rz = rz_new
        it += 1
    for i in range(n):
        if free[i] == 0.0:
            for k in range(3):
                x[i, k] = b[i, k]
    return it, math.sqrt(rr) / bnorm


# ---------------------------------------------------------------------------------------------
# SSOR-preconditioned CG with Eisenstat's trick (matrix-free spring operator)
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _ssor_setup(free, blocks, diag, up_ptr, up_spring, up_other, omega, dsc, dinv, ublk,
                gather, acc):
    """Scaled particle blocks ``D'_i = D_i / omega`` (``dsc``) and their inverses (``dinv``);
    with ``gather``, the spring blocks copied into upper-incidence order (``ublk``).

    One pass in particle order: the blocks of particle ``i``'s upper springs are summed in
    registers and pushed to the other end (``acc``, (N, 6) scratch), so that ``D_i`` is complete
    when ``i`` is reached (its lower springs were pushed before).
    """
    n = diag.shape[0]
    for i in range(n):
        for k in range(6):
            acc[i, k] = 0.0
    for i in range(n):
        s0 = acc[i, 0]
        s1 = acc[i, 1]
        s2 = acc[i, 2]
        s3 = acc[i, 3]
        s4 = acc[i, 4]
        s5 = acc[i, 5]
        for p in range(up_ptr[i], up_ptr[i + 1]):
            sp = up_spring[p]
            j = up_other[p]
            b0 = blocks[sp, 0]
            b1 = blocks[sp, 1]
            b2 = blocks[sp, 2]
            b3 = blocks[sp, 3]
            b4 = blocks[sp, 4]
            b5 = blocks[sp, 5]
            if gather:
                ublk[p, 0] = b0
                ublk[p, 1] = b1
                ublk[p, 2] = b2
                ublk[p, 3] = b3
                ublk[p, 4] = b4
                ublk[p, 5] = b5
            s0 += b0
            s1 += b1
            s2 += b2
            s3 += b3
            s4 += b4
            s5 += b5
            acc[j, 0] += b0
            acc[j, 1] += b1
            acc[j, 2] += b2
            acc[j, 3] += b3
            acc[j, 4] += b4
            acc[j, 5] += b5
        w = 1.0 / omega
        if free[i] == 0.0:  # identity row, not relaxed and not coupled
            w = 1.0
            s0 = 0.0
            s1 = 0.0
            s2 = 0.0
            s3 = 0.0
            s4 = 0.0
            s5 = 0.0
        m00 = (diag[i, 0, 0] + s0) * w
        m01 = (diag[i, 0, 1] + s1) * w
        m02 = (diag[i, 0, 2] + s2) * w
        m10 = (diag[i, 1, 0] + s1) * w
        m11 = (diag[i, 1, 1] + s3) * w
        m12 = (diag[i, 1, 2] + s4) * w
        m20 = (diag[i, 2, 0] + s2) * w
        m21 = (diag[i, 2, 1] + s4) * w
        m22 = (diag[i, 2, 2] + s5) * w
        dsc[i, 0, 0] = m00
        dsc[i, 0, 1] = m01
        dsc[i, 0, 2] = m02
        dsc[i, 1, 0] = m10
        dsc[i, 1, 1] = m11
        dsc[i, 1, 2] = m12
        dsc[i, 2, 0] = m20
        dsc[i, 2, 1] = m21
        dsc[i, 2, 2] = m22
        c00 = m11 * m22 - m12 * m21
        c01 = m12 * m20 - m10 * m22
        c02 = m10 * m21 - m11 * m20
        det = m00 * c00 + m01 * c01 + m02 * c02
        if not det > 0.0:  # not positive definite: diagonal inverse (never for H)
            for r in range(3):
                for q in range(3):
                    dinv[i, r, q] = 0.0
            dinv[i, 0, 0] = 1.0 / m00 if m00 > 0.0 else 1.0
            dinv[i, 1, 1] = 1.0 / m11 if m11 > 0.0 else 1.0
            dinv[i, 2, 2] = 1.0 / m22 if m22 > 0.0 else 1.0
            continue
        d = 1.0 / det
        dinv[i, 0, 0] = c00 * d
        dinv[i, 1, 0] = c01 * d
        dinv[i, 2, 0] = c02 * d
        dinv[i, 0, 1] = (m02 * m21 - m01 * m22) * d
        dinv[i, 1, 1] = (m00 * m22 - m02 * m20) * d
        dinv[i, 2, 1] = (m01 * m20 - m00 * m21) * d
        dinv[i, 0, 2] = (m01 * m12 - m02 * m11) * d
        dinv[i, 1, 2] = (m02 * m10 - m00 * m12) * d
        dinv[i, 2, 2] = (m00 * m11 - m01 * m10) * d


@njit(cache=True, inline="always")
def _pull(up_ptr, up_other, ublk, t, i):
    """``sum_j U_ij t_j`` over the springs stored with particle ``i`` (gather form)."""
    q0 = 0.0
    q1 = 0.0
    q2 = 0.0
    for p in range(up_ptr[i], up_ptr[i + 1]):
        j = up_other[p]
        k0, k1, k2 = _apply_spring(ublk, p, t[j, 0], t[j, 1], t[j, 2])
        q0 += k0
        q1 += k1
        q2 += k2
    return q0, q1, q2


@njit(cache=True, inline="always")
def _push(up_ptr, up_other, ublk, i, y0, y1, y2, sign, acc):
    """``acc_j += sign U_ji y`` for the springs stored with particle ``i`` (scatter form;
    ``sign`` is +1 or -1, so the sums are the same floating-point operations as ``+=`` / ``-=``)."""
    for p in range(up_ptr[i], up_ptr[i + 1]):
        j = up_other[p]
        k0, k1, k2 = _apply_spring(ublk, p, y0, y1, y2)
        acc[j, 0] += sign * k0
        acc[j, 1] += sign * k1
        acc[j, 2] += sign * k2


@njit(cache=True, inline="always")
def _mul3(m, i, a0, a1, a2):
    return (m[i, 0, 0] * a0 + m[i, 0, 1] * a1 + m[i, 0, 2] * a2,
            m[i, 1, 0] * a0 + m[i, 1, 1] * a1 + m[i, 1, 2] * a2,
            m[i, 2, 0] * a0 + m[i, 2, 1] * a1 + m[i, 2, 2] * a2)


@njit(cache=True)
def _ssor_apply(up_ptr, up_other, ublk, dinv, free, omega, r, beta, a, t, q, acc, w):
    """CG direction update ``a = r + beta a`` fused with the product ``w = S^-1 A S^-T a`` of
    Eisenstat's trick in the ``a = C x_hat`` coordinates.

    With ``P = D' + L`` (``D' = D / omega``, ``L`` the strictly lower spring blocks) and
    ``A = P + P^T - (2 - omega) D'``: backward solve ``P^T t = a`` (``q_i = sum_{j>i} K_ij t_j``),
    then forward solve ``P y = s`` with ``s = (omega - 1) a - (2 - omega) q``, pushing
    ``acc_j += K_ij y_i``; ``w = D'(t + y) = omega a + (omega - 1) q + acc``.  Each spring is
    visited twice; returns ``a . (t + y) = a . D'^-1 w`` (the CG curvature in the inner product
    ``u . D'^-1 v`` of these coordinates).  Pinned particles (``free`` 0) are decoupled: their
    ``t``, ``y`` and ``w`` are zero, whatever the sweeps push into their slots.
    """
    n = a.shape[0]
    for i in range(n - 1, -1, -1):
        # the sweep only reads a_j, t_j of j > i: a_i can be updated on the way
        a[i, 0] = r[i, 0] + beta * a[i, 0]
        a[i, 1] = r[i, 1] + beta * a[i, 1]
        a[i, 2] = r[i, 2] + beta * a[i, 2]
        acc[i, 0] = 0.0
        acc[i, 1] = 0.0
        acc[i, 2] = 0.0
        if free[i] == 0.0:
            t[i, 0] = 0.0
            t[i, 1] = 0.0
            t[i, 2] = 0.0
            q[i, 0] = 0.0
            q[i, 1] = 0.0
            q[i, 2] = 0.0
            continue
        q0, q1, q2 = _pull(up_ptr, up_other, ublk, t, i)
        q[i, 0] = q0
        q[i, 1] = q1
        q[i, 2] = q2
        t[i, 0], t[i, 1], t[i, 2] = _mul3(dinv, i, a[i, 0] + q0, a[i, 1] + q1, a[i, 2] + q2)
    c1 = omega - 1.0
    c2 = 2.0 - omega
    curv = 0.0
    for i in range(n):
        if free[i] == 0.0:
            w[i, 0] = 0.0
            w[i, 1] = 0.0
            w[i, 2] = 0.0
            continue
        y0, y1, y2 = _mul3(dinv, i, c1 * a[i, 0] - c2 * q[i, 0] + acc[i, 0],
                           c1 * a[i, 1] - c2 * q[i, 1] + acc[i, 1],
                           c1 * a[i, 2] - c2 * q[i, 2] + acc[i, 2])
        _push(up_ptr, up_other, ublk, i, y0, y1, y2, 1.0, acc)
        w0 = omega * a[i, 0] + c1 * q[i, 0] + acc[i, 0]
        w1 = omega * a[i, 1] + c1 * q[i, 1] + acc[i, 1]
        w2 = omega * a[i, 2] + c1 * q[i, 2] + acc[i, 2]
        w[i, 0] = w0
        w[i, 1] = w1
        w[i, 2] = w2
        curv += (a[i, 0] * (t[i, 0] + y0) + a[i, 1] * (t[i, 1] + y1)
                 + a[i, 2] * (t[i, 2] + y2))
    return curv


@njit(cache=True)
def _ssor_forward(up_ptr, up_other, ublk, dinv, free, s, y, acc):
    """Forward solve ``P y = s`` (push form) into ``y`` (zero at pinned particles)."""
    n = s.shape[0]
    for i in range(n):
        acc[i, 0] = 0.0
        acc[i, 1] = 0.0
        acc[i, 2] = 0.0
    for i in range(n):
        if free[i] == 0.0:
            y[i, 0] = 0.0
            y[i, 1] = 0.0
            y[i, 2] = 0.0
            continue
        y0, y1, y2 = _mul3(dinv, i, s[i, 0] + acc[i, 0], s[i, 1] + acc[i, 1],
                           s[i, 2] + acc[i, 2])
        y[i, 0] = y0
        y[i, 1] = y1
        y[i, 2] = y2
        _push(up_ptr, up_other, ublk, i, y0, y1, y2, 1.0, acc)


@njit(cache=True)
def _ssor_backward(up_ptr, up_other, ublk, dinv, free, a, t):
    """Backward solve ``P^T t = a`` (pull form; zero at pinned particles)."""
    for i in range(a.shape[0] - 1, -1, -1):
        if free[i] == 0.0:
            t[i, 0] = 0.0
            t[i, 1] = 0.0
            t[i, 2] = 0.0
            continue
        q0, q1, q2 = _pull(up_ptr, up_other, ublk, t, i)
        t[i, 0], t[i, 1], t[i, 2] = _mul3(dinv, i, a[i, 0] + q0, a[i, 1] + q1, a[i, 2] + q2)


@njit(cache=True)
def _ssor_unscale(up_ptr, up_other, ublk, dinv, free, rt, out):
    """``out = P D'^-1 rt`` (the residual of the original system from the one of the
    transformed system, ``rt = D' P^-1 r``); returns ``|out|^2``."""
    n = rt.shape[0]
    for i in range(n):
        out[i, 0] = rt[i, 0]
        out[i, 1] = rt[i, 1]
        out[i, 2] = rt[i, 2]
    for i in range(n):
        z0, z1, z2 = _mul3(dinv, i, rt[i, 0], rt[i, 1], rt[i, 2])
        _push(up_ptr, up_other, ublk, i, z0, z1, z2, -1.0, out)
    acc = 0.0
    for i in range(n):
        if free[i] == 0.0:
            out[i, 0] = 0.0
            out[i, 1] = 0.0
            out[i, 2] = 0.0
        acc += out[i, 0] * out[i, 0] + out[i, 1] * out[i, 1] + out[i, 2] * out[i, 2]
    return acc


@njit(cache=True)
def _wdot(dinv, u, v):
    """``u . D'^-1 v`` (the inner product of the ``a`` coordinates)."""
    acc = 0.0
    for i in range(u.shape[0]):
        z0, z1, z2 = _mul3(dinv, i, v[i, 0], v[i, 1], v[i, 2])
        acc += u[i, 0] * z0 + u[i, 1] * z1 + u[i, 2] * z2
    return acc


@njit(cache=True)
def _pcg_ssor(pairs, free, blocks, diag, upper, b, x, tol, max_iter, omega, work, ordered):
    """SSOR-preconditioned CG for ``H x = b`` with Eisenstat's (1981) trick.

    The preconditioner is ``M = P D'^-1 P^T`` with ``P = D/omega + L`` (symmetric successive
    over-relaxation on the 3x3 particle blocks); CG runs on ``S^-1 H S^-T`` (``M = S S^T``),
    whose product costs one backward and one forward sweep over the springs and no separate
    product with ``H`` (Eisenstat 1981, "Efficient implementation of a class of preconditioned
    conjugate gradient methods", SIAM J. Sci. Stat. Comput.).  Every few iterations the
    recursive residual is mapped back to the original system (``r = P D'^-1 r_tilde``, half an
    iteration's work) and CG stops when ``|r| <= tol |b|``; after a breakdown or at the
    iteration limit the true residual ``|b - H x|`` is recomputed and CG restarted (with a
    tighter goal) if it is still above ``tol |b|``.  Pinned particles (``free`` 0) are
    decoupled identity rows.  ``work`` holds the scratch arrays (see :func:`_ssor_workspace`);
    ``ordered`` says that spring ``s`` is upper incidence ``s`` (then ``blocks`` is streamed in
    place instead of copied).  Returns (iterations, relative residual).
    """
    up_ptr, up_spring, up_other = upper
    n = b.shape[0]
    dsc, dinv, ublk, t, qv, acc, w, r, pv, ax, res, acc6 = work
    if ordered:  # spring s is upper incidence s: stream the operator's blocks in place
        ublk = blocks
    _ssor_setup(free, blocks, diag, up_ptr, up_spring, up_other, omega, dsc, dinv, ublk,
                not ordered, acc6)
    bb = 0.0
    for i in range(n):
        for k in range(3):
            bb += b[i, k] * b[i, k]
    bnorm = math.sqrt(bb)
    if bnorm == 0.0:
        for i in range(n):
            for k in range(3):
                x[i, k] = 0.0
        return 0, 0.0
    for i in range(n):
        if free[i] == 0.0:
            for k in range(3):
                x[i, k] = b[i, k]
    it = 0
    true_rel = 1.0
    check = 8  # most iterations between residual checks
    zero_start = True
    for i in range(n):
        if free[i] != 0.0 and (x[i, 0] != 0.0 or x[i, 1] != 0.0 or x[i, 2] != 0.0):
            zero_start = False
            break
    for attempt in range(4):
        # residual of the original system (no product needed for a zero start)
        if attempt == 0 and zero_start:
            for i in range(n):
                for k in range(3):
                    res[i, k] = 0.0
        else:
            _operator_matvec(pairs, free, blocks, diag, x, res)
        rr = 0.0
        for i in range(n):
            fi = free[i]
            for k in range(3):
                res[i, k] = fi * (b[i, k] - res[i, k])
                rr += res[i, k] * res[i, k]
        true_rel = math.sqrt(rr) / bnorm
        if true_rel <= tol or it >= max_iter:
            break
        goal = (0.5 ** attempt * tol * bnorm) ** 2
        since = check
        # correction e solves H e = res: CG in a = C e_hat coordinates, a0 = 0
        # r_tilde = D' P^-1 res  (= res + acc of the forward solve)
        _ssor_forward(up_ptr, up_other, ublk, dinv, free, res, t, acc)
        for i in range(n):
            r[i, 0], r[i, 1], r[i, 2] = _mul3(dsc, i, t[i, 0], t[i, 1], t[i, 2])
            for k in range(3):
                ax[i, k] = 0.0
                pv[i, k] = r[i, k]
        rho = _wdot(dinv, r, r)
        beta = 0.0  # first direction: pv = r
        since = 0
        ratio = 0.0  # |r|^2 / rho at the last check
        converged = False
        while it < max_iter:
            # Map the recursive residual back to H (half an iteration's work) when the ratio
            # seen at the last check predicts convergence, or every ``check`` iterations.
            if since >= check or ratio * rho <= 2.0 * goal:
                since = 0
                rr = _ssor_unscale(up_ptr, up_other, ublk, dinv, free, r, acc)
                if rr <= goal:
                    converged = True
                    break
                ratio = rr / rho if rho > 0.0 else 0.0
            since += 1
            curv = _ssor_apply(up_ptr, up_other, ublk, dinv, free, omega, r, beta, pv, t, qv,
                               acc, w)
            if not curv > 0.0:
                break
            alpha = rho / curv
            rho_new = 0.0
            for i in range(n):
                for k in range(3):
                    ax[i, k] += alpha * pv[i, k]
                    r[i, k] -= alpha * w[i, k]
                z0, z1, z2 = _mul3(dinv, i, r[i, 0], r[i, 1], r[i, 2])
                rho_new += r[i, 0] * z0 + r[i, 1] * z1 + r[i, 2] * z2
            beta = rho_new / rho
            rho = rho_new
            it += 1
        # e = P^-T a
        _ssor_backward(up_ptr, up_other, ublk, dinv, free, ax, t)
        for i in range(n):
            fi = free[i]
            for k in range(3):
                x[i, k] += fi * t[i, k]
        if converged:
            # the recursive residual (checked against the true one only after a breakdown or
            # at the iteration limit: it drifts from it by rounding alone)
            true_rel = math.sqrt(rr) / bnorm
            break
    return it, true_rel


PRECONDITIONERS = ("sgs", "block_jacobi", "ssor")

#: Loosest relative PCG tolerance of a Newton solve as a multiple of ``newton_tol / |d_prev|``
#: (see :func:`backward_euler`).
_STEP_FORCING = 0.3

#: Over-relaxation factor of the "ssor" preconditioner (see :func:`pcg_operator`).
DEFAULT_OMEGA = 1.6


def _ssor_workspace(operator):
    """Scratch arrays of :func:`_pcg_ssor`, kept on the operator (which a SpringSystem reuses
    for every solve) so that a solve allocates nothing."""
    n = operator.diag.shape[0]
    s = operator.upper[1].shape[0]
    work = getattr(operator, "_ssor_work", None)
    if work is None or work[0].shape[0] != n or work[2].shape[0] != s:
        work = (np.empty((n, 3, 3)), np.empty((n, 3, 3)), np.empty((s, 6)),
                *(np.empty((n, 3)) for _ in range(8)), np.empty((n, 6)))
        try:
            operator._ssor_work = work
        except AttributeError:  # pragma: no cover - operators without a __dict__
            pass
    return work


def pcg_operator(operator, b, x0=None, *, tol=1e-6, max_iter=1000, preconditioner="sgs",
                 omega=DEFAULT_OMEGA):
    """Solve ``operator @ x = b`` by PCG with a matrix-free spring operator, in Numba.

    Parameters
    ----------
    operator : filters.elastic.springs.SpringOperator
        The SPD implicit system matrix (from ``SpringSystem.implicit_operator``), (3N, 3N).
    b : (N, 3) or (3N,) float64 array
        Right-hand side.
    x0 : array like ``b``, optional
        Warm start (zeros if omitted); not modified.
    tol : float
        Relative residual ``|b - A x| / |b|`` to reach.
    max_iter : int
        Iteration limit.
    preconditioner : {"sgs", "block_jacobi", "ssor"}
        Block symmetric Gauss-Seidel (two sweeps over the springs per iteration, about half the
        iterations of block Jacobi on cloth), per-particle 3x3 block Jacobi, or block symmetric
        successive over-relaxation with Eisenstat's trick (:func:`_pcg_ssor`: the two sweeps
        *replace* the product with ``H``, so an iteration costs two passes over the springs;
        with ``omega`` near its optimum the preconditioned condition number is
        ``O(sqrt(kappa))`` on model problems (Axelsson 1994, "Iterative solution methods"),
        so the iterations grow like ``kappa^(1/4)`` instead of ``kappa^(1/2)``; ``tol``
        applies to the residual of ``H``, mapped back from the transformed system every few
        iterations).
    omega : float
        Over-relaxation factor of ``"ssor"``, in (0, 2) (1 is symmetric Gauss-Seidel).

    Returns
    -------
    x : float64 array shaped like ``b``
    iterations : int
    relative_residual : float
    """
    check_choice("preconditioner", preconditioner, PRECONDITIONERS)
    check_range("omega", omega, 0.0, 2.0, low_inclusive=False, high_inclusive=False)
    b = np.ascontiguousarray(b, dtype=np.float64)
    shape = b.shape
    b3 = b.reshape(-1, 3)
    x = np.zeros_like(b3) if x0 is None else np.array(x0, dtype=np.float64).reshape(-1, 3)
    x = np.ascontiguousarray(x)
    if preconditioner == "ssor":
        it, res = _pcg_ssor(operator.pairs, operator.free, operator.blocks, operator.diag,
                            operator.upper, b3, x, float(tol), int(max_iter), float(omega),
                            _ssor_workspace(operator),
                            bool(getattr(operator, "upper_ordered", False)))
        return x.reshape(shape), int(it), float(res)
    it, res = _pcg_operator(operator.pairs, operator.free, operator.blocks, operator.diag,
                            operator.lower, operator.upper, b3, x,
                            float(tol), int(max_iter), preconditioner == "sgs")
    return x.reshape(shape), int(it), float(res)


def _direct(matrix, b):
    from scipy.sparse.linalg import splu

    lu = splu(matrix.tocsc(), permc_spec="MMD_AT_PLUS_A",
              options={"SymmetricMode": True, "DiagPivotThresh": 0.0})
    return lu.solve(b)


def solve_linear(matrix, b, x0=None, *, solver="auto", tol=1e-6, max_iter=1000):
    """Solve ``matrix @ x = b`` with the chosen solver.

    Parameters
    ----------
    matrix : scipy.sparse.csr_matrix
        SPD system matrix.
    b : (n,) float64 array
        Right-hand side.
    x0 : (n,) float64 array, optional
        Warm start for PCG.
    solver : {"auto", "pcg", "direct"}
        ``"auto"`` runs PCG and falls back to the direct solve if it has not converged.
    tol, max_iter : float, int
        PCG relative tolerance and iteration limit.

    Returns
    -------
    x : (n,) float64 array
    iterations : int
        PCG iterations (including those of a PCG attempt before a fallback).
    direct : bool
        Whether a direct solve produced ``x``.
    """
    check_choice("solver", solver, SOLVERS)
    if solver == "direct":
        return _direct(matrix, b), 0, True
    x, it, res = pcg(matrix, b, x0, tol=tol, max_iter=max_iter)
    if res <= tol or solver == "pcg":
        return x, it, False
    return _direct(matrix, b), it, True


# ---------------------------------------------------------------------------------------------
# Small helpers
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _incremental_potential_parts(dx, v, masses, h):
    # serial: a parallel reduction over a few thousand particles cost ~6 ms on the busy machine
    acc = 0.0
    for i in range(dx.shape[0]):
        for k in range(3):
            t = dx[i, k] - h * v[i, k]
            acc += masses[i] * t * t
    return 0.5 * acc / (h * h)


def _extra(state):
    extra = getattr(state, "extra", None)
    return extra if isinstance(extra, dict) else None


def _check_h(h):
    return check_range("h", h, 0.0, math.inf, low_inclusive=False)


# ---------------------------------------------------------------------------------------------
# Explicit schemes
# ---------------------------------------------------------------------------------------------
def forward_euler(system, state, h):
    """Forward (explicit) Euler: ``x += h v; v += h f(x, v) / m``, in place.

    Parameters
    ----------
    system : SpringSystem-like
        Supplies ``forces(x, v)`` (N) and ``inv_mass`` (1/kg, 0 for pinned particles).
    state : State-like
        ``positions`` (m) and ``velocities`` (m/s), (N, 3), advanced in place.
    h : float
        Time step (s), > 0.

    Returns
    -------
    StepInfo
    """
    h = _check_h(h)
    x, v = state.positions, state.velocities
    f = system.forces(x, v)
    x += h * v
    v += h * f * system.inv_mass[:, None]
    return StepInfo()


def symplectic_euler(system, state, h):
    """Symplectic (semi-implicit) Euler: ``v += h f(x, v) / m; x += h v``, in place.

    Uses the system's fused Numba kernel when it has one (``symplectic_step``).
    Arguments as in :func:`forward_euler`.
    """
    h = _check_h(h)
    x, v = state.positions, state.velocities
    if hasattr(system, "symplectic_step"):
        system.symplectic_step(x, v, h)
    else:  # pragma: no cover - generic systems
        v += h * system.forces(x, v) * system.inv_mass[:, None]
        x += h * v
    return StepInfo()


# ---------------------------------------------------------------------------------------------
# Implicit schemes
# ---------------------------------------------------------------------------------------------
def _warm(state, key, n):
    extra = _extra(state)
    if extra is not None and key in extra and extra[key].size == n:
        return np.array(extra[key], dtype=np.float64).ravel()
    return None


def _store_warm(state, key, value):
    extra = _extra(state)
    if extra is not None:
        extra[key] = value.reshape(-1, 3).copy()


def linearized_backward_euler(system, state, h, *, solver="auto", tol=1e-6, max_iter=1000,
                              preconditioner="ssor", omega=None):
    """One Newton step of backward Euler (Baraff & Witkin 1998), in place.

    Solves ``(M/h^2 + C/h + K) dv = (f0 - h K v0) / h`` with ``K = -df/dx`` (made definite) and
    ``C = -df/dv`` at the start of the step, then ``v += dv; x += h v``.  Cheap (one solve) but,
    on a flat cloth released under gravity, unstable above ``h ~ 0.012`` s: the first solve
    sees no transverse stiffness.  Use :func:`backward_euler` for large steps.

    Parameters
    ----------
    system, state, h
        As in :func:`forward_euler`.
    solver : {"auto", "pcg", "direct"}
        Linear solver (see :func:`solve_linear`).
    tol, max_iter : float, int
        PCG tolerance and iteration limit.
    preconditioner : {"ssor", "block_jacobi", "sgs"}
        As in :func:`backward_euler` (SSOR: 25 instead of 92 iterations, 8-10 instead of
        15-18 ms per step on the hanging 64x64 benchmark cloth).
    omega : float, optional
        Over-relaxation factor of ``"ssor"`` (default :data:`DEFAULT_OMEGA`).

    Returns
    -------
    StepInfo
    """
    h = _check_h(h)
    check_choice("solver", solver, SOLVERS)
    check_choice("preconditioner", preconditioner, PRECONDITIONERS)
    x, v = state.positions, state.velocities
    n = x.shape[0]
    f0 = system.forces(x, v)
    if solver != "direct" and hasattr(system, "implicit_operator"):
        mat = system.implicit_operator(x, x, h)  # matrix-free (see backward_euler)
    else:
        mat = system.system_matrix(x, x, h)
    # K v0 = -(df/dx) v0 = H v0 - (M/h^2 + C/h) v0 on free particles; compute it from the matrix.
    kv = (mat @ v.ravel()).reshape(n, 3)
    kv -= (system.masses[:, None] / (h * h)) * v
    kv += system.damping_forces(x, v) / h
    rhs = (f0 - h * kv) / h
    rhs[system.pinned] = 0.0
    dv, it, direct = _newton_direction(system, x, x, h, rhs, _warm(state, "lbe_warm", 3 * n),
                                       solver, tol, max_iter, preconditioner, omega)
    _store_warm(state, "lbe_warm", dv)
    v += dv.reshape(n, 3)
    v[system.pinned] = 0.0
    x += h * v
    return StepInfo(newton_iterations=1, linear_iterations=it, direct_solves=int(direct))


def _newton_direction(system, x, xdir, h, rhs, warm, solver, tol, max_iter, preconditioner,
                      omega=None):
    """Solve ``H(x, xdir) d = rhs`` (rhs (N, 3)); matrix-free PCG when the system offers it."""
    if solver != "direct" and hasattr(system, "implicit_operator"):
        op = system.implicit_operator(x, xdir, h)
        d, it, res = pcg_operator(op, rhs, warm, tol=tol, max_iter=max_iter,
                                  preconditioner=preconditioner,
                                  omega=DEFAULT_OMEGA if omega is None else omega)
        if res <= tol or solver == "pcg":
            return d.ravel(), it, False
        return _direct(system.system_matrix(x, xdir, h), rhs.ravel()), it, True
    mat = system.system_matrix(x, xdir, h)
    return solve_linear(mat, rhs.ravel(), warm, solver=solver, tol=tol, max_iter=max_iter)


def backward_euler(system, state, h, *, solver="auto", newton_tol=1e-3, max_newton=20,
                   tol=1e-3, max_iter=1000, callback=None, preconditioner="ssor",
                   forcing=0.1, extrapolate=False, omega=None):
    """Backward Euler by Newton iterations with a line search on the incremental potential.

    Minimises ``E(dx) = |dx - h v|_M^2/(2h^2) + U(x + dx) + dx^T C dx/(2h)`` over the position
    increment ``dx`` (Gast et al. 2015), with ``U`` the elastic plus gravitational potential and
    ``C`` the damping matrix with directions frozen at the start of the step.  Newton directions
    solve ``(M/h^2 + K(x + dx) + C/h) d = -grad E`` with ``K`` made definite, so every ``d`` is a
    descent direction; a backtracking (Armijo) line search accepts only decreases of ``E``.
    Then ``v = dx / h``, ``x += dx``.

    Parameters
    ----------
    system, state, h
        As in :func:`forward_euler`.
    solver : {"auto", "pcg", "direct"}
        Linear solver for the Newton directions (see :func:`solve_linear`).
    newton_tol : float
        Stop when ``max |d| / h`` (m/s) falls below this (1 mm/s by default: well below what
        an animation shows, and 2x fewer Newton iterations than 1e-5 on the benchmark cloth),
        or when two full steps converge quadratically (``|d_k| < |d_{k-1}| / 4``) and the
        next step, estimated as ``|d_k|^2 / |d_{k-1}|``, would be below ``newton_tol / 2``
        (3.17 -> 2.75 Newton iterations per step on the 64x64 benchmark cloth).
    max_newton : int
        Newton iteration limit.
    tol, max_iter : float, int
        PCG relative tolerance (inexact Newton) and iteration limit per solve.  With
        ``forcing``, ``tol`` is the tightest tolerance the forcing sequence may ask for.
    callback : callable, optional
        Called after every Newton iteration as ``callback(iteration, step_norm, potential)``.
    preconditioner : {"ssor", "block_jacobi", "sgs"}
        Preconditioner of the matrix-free PCG (systems with ``implicit_operator``): block
        symmetric successive over-relaxation with Eisenstat's trick (the default: on the 64x64
        benchmark cloth 3.3x fewer iterations than block Jacobi at ~2x the cost per
        iteration, 10.5 instead of 16.0 ms per step), per-particle 3x3 block Jacobi, or block
        symmetric Gauss-Seidel applied separately from the product (2.4x fewer iterations than
        block Jacobi but ~2.5x the cost per iteration); see ``benchmarks/results/springs.json``.
    forcing : float or None
        Largest relative PCG tolerance of the inexact Newton iterations: the first solve uses
        ``forcing``, later ones the Eisenstat & Walker (1996, "Choosing the forcing terms in an
        inexact Newton method", SIAM J. Sci. Comput.) choice 2,
        ``eta_k = 0.9 (|g_k| / |g_{k-1}|)^2`` (safeguarded), clipped to ``[tol, forcing]``.
        Far from the solution the solve is loose, near it as tight as ``tol`` -- but never
        tighter than ``0.3 newton_tol / |d_prev|`` (``|d_prev|`` the previous Newton step,
        ``max |d| / h``): once the steps approach ``newton_tol`` the last direction only has to
        be accurate to a fraction of it (Newton steps shrink).  This floor cut the PCG
        iterations of the 64x64 benchmark cloth from 28 to 21 per step with the same Newton
        iterations.  ``None``: every solve to ``tol`` (the fixed-tolerance behaviour).
    extrapolate : bool
        Also try the start ``dx = h (v + dv_prev)`` (the previous step's velocity change, kept in
        ``state.extra["newton_dv"]``) and keep it if it has the lowest incremental potential.
    omega : float, optional
        Over-relaxation factor of ``"ssor"``, in (0, 2) (default :data:`DEFAULT_OMEGA`).

    Returns
    -------
    StepInfo
    """
    h = _check_h(h)
    check_range("newton_tol", newton_tol, 0.0, math.inf, low_inclusive=False)
    if forcing is not None:
        check_range("forcing", forcing, 0.0, 1.0, low_inclusive=False, high_inclusive=False)
    check_int("max_newton", max_newton, 1)
    check_choice("solver", solver, SOLVERS)
    check_choice("preconditioner", preconditioner, PRECONDITIONERS)
    if omega is not None:
        check_range("omega", omega, 0.0, 2.0, low_inclusive=False, high_inclusive=False)
    x0, v = state.positions, state.velocities
    n = x0.shape[0]
    m = system.masses
    pinned = system.pinned
    free = ~pinned

    def potential(dx):
        e = _incremental_potential_parts(dx, v_free, m, h)
        e += system.potential_energy(x0 + dx)
        e -= 0.5 / h * _vdot(dx, system.damping_forces(x0, dx))
        return e

    def gradient(dx):
        g = m[:, None] * (dx - h * v_free) / (h * h)
        g -= system.conservative_forces(x0 + dx)
        g -= system.damping_forces(x0, dx) / h
        g[pinned] = 0.0
        return g

    v_free = v.copy()
    v_free[pinned] = 0.0
    # Start from the better of the inertial guess h v and the free-fall guess h v + h^2 g.
    dx = h * v_free
    e = potential(dx)
    trial = dx + (h * h) * np.where(free[:, None], system.gravity[None, :], 0.0)
    e_trial = potential(trial)
    if e_trial < e:
        dx, e = trial, e_trial
    dv_prev = _warm(state, "newton_dv", 3 * n) if extrapolate else None
    if dv_prev is not None:
        trial = h * (v_free + dv_prev.reshape(n, 3))
        trial[pinned] = 0.0
        e_trial = potential(trial)
        if e_trial < e:
            dx, e = trial, e_trial
    info = StepInfo()
    warm = _warm(state, "newton_warm", 3 * n)
    first_direction = None
    eta = tol if forcing is None else max(tol, forcing)
    gnorm_prev = None
    prev_step = 0.0
    full_before = False
    for it in range(max_newton):
        g = gradient(dx)
        gnorm = math.sqrt(_vdot(g, g))
        if forcing is not None and gnorm_prev is not None:
            # Eisenstat & Walker (1996), choice 2 (gamma = 0.9, alpha = 2) with safeguard
            eta_new = 0.9 * (gnorm / gnorm_prev) ** 2
            if 0.9 * eta * eta > 0.1:
                eta_new = max(eta_new, 0.9 * eta * eta)
            eta = min(max(forcing, tol), max(eta_new, tol))
            if prev_step > 0.0:
                # Near convergence the step only has to be accurate to a fraction of newton_tol
                # (Newton steps shrink, so |d_k| <= |d_{k-1}|): no tighter than that.
                eta = max(eta, min(forcing, _STEP_FORCING * newton_tol / prev_step))
        gnorm_prev = gnorm
        d, lin_it, direct = _newton_direction(system, x0 + dx, x0, h, -g, warm, solver, eta,
                                              max_iter, preconditioner, omega)
        info.linear_iterations += lin_it
        info.direct_solves += int(direct)
        info.newton_iterations = it + 1
        d = d.reshape(n, 3)
        d[pinned] = 0.0
        if first_direction is None:
            first_direction = d.copy()
        warm = None
        slope = _vdot(g, d)
        step_norm = float(np.abs(d).max()) / h if d.size else 0.0
        older_step, prev_step = prev_step, step_norm
        info.residual = step_norm
        if slope >= 0.0:  # not a descent direction (inexact solve): steepest descent instead
            d = -g / (m[:, None] / (h * h))
            slope = _vdot(g, d)
        alpha = 1.0
        accepted = False
        for _ in range(40):
            trial = dx + alpha * d
            e_trial = potential(trial)
            if e_trial <= e + 1e-4 * alpha * slope:
                accepted = True
                break
            alpha *= 0.5
            info.line_search_halvings += 1
        if not accepted:
            break  # no decrease possible: converged to round-off
        dx, e = trial, e_trial
        if callback is not None:
            callback(it, step_norm * alpha, e)
        if step_norm * alpha < newton_tol:
            break
        if alpha == 1.0 and full_before and step_norm < 0.25 * older_step and (
                step_norm * step_norm / older_step < 0.5 * newton_tol):
            # Quadratic convergence (two full steps, contraction < 1/4): the next step would be
            # ~ |d_k|^2 / |d_{k-1}|, well below newton_tol (Deuflhard 2004, "Newton methods
            # for nonlinear problems"): skip the solve that would only confirm it.
            info.residual = step_norm * step_norm / older_step
            break
        full_before = alpha == 1.0
    if first_direction is not None:
        _store_warm(state, "newton_warm", first_direction)
    if extrapolate:
        dv = dx / h - v_free
        dv[pinned] = 0.0
        _store_warm(state, "newton_dv", dv)
    x0 += dx
    v[:] = dx / h
    v[pinned] = 0.0
    return info


# ---------------------------------------------------------------------------------------------
# First-order (velocity field) form
# ---------------------------------------------------------------------------------------------
@njit(parallel=True, cache=True)
def _implicit_advection(v, jac, h, dx):
    for i in prange(v.shape[0]):
        a = np.empty((3, 3))
        for p in range(3):
            for q in range(3):
                a[p, q] = -h * jac[i, p, q]
            a[p, p] += 1.0
        # Cramer's rule on the 3x3 system a dx = h v.
        c00 = a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1]
        c01 = a[1, 2] * a[2, 0] - a[1, 0] * a[2, 2]
        c02 = a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]
        det = a[0, 0] * c00 + a[0, 1] * c01 + a[0, 2] * c02
        b0 = h * v[i, 0]
        b1 = h * v[i, 1]
        b2 = h * v[i, 2]
        inv = 1.0 / det
        dx[i, 0] = inv * (b0 * c00 + b1 * (a[0, 2] * a[2, 1] - a[0, 1] * a[2, 2])
                          + b2 * (a[0, 1] * a[1, 2] - a[0, 2] * a[1, 1]))
        dx[i, 1] = inv * (b0 * c01 + b1 * (a[0, 0] * a[2, 2] - a[0, 2] * a[2, 0])
                          + b2 * (a[0, 2] * a[1, 0] - a[0, 0] * a[1, 2]))
        dx[i, 2] = inv * (b0 * c02 + b1 * (a[0, 1] * a[2, 0] - a[0, 0] * a[2, 1])
                          + b2 * (a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]))


def implicit_advection(positions, velocity, jacobian, h):
    """Linearised backward Euler for particles in a velocity field ``dx/dt = v(x)``.

    Solves ``(I - h dv/dx) dx = h v(x^n)`` per particle (3x3 systems in Numba).  For a linear
    field ``v = A x`` this is exactly backward Euler, ``x^{n+1} = (I - h A)^{-1} x^n``.

    Parameters
    ----------
    positions : (N, 3) array_like
        Particle positions ``x^n`` (m).
    velocity : (N, 3) array_like
        Field velocity ``v(x^n)`` (m/s) at the particles.
    jacobian : (N, 3, 3) array_like
        Field gradient ``dv/dx`` (1/s) at the particles, ``jacobian[i, p, q] = dv_p/dx_q``.
    h : float
        Time step (s), > 0.

    Returns
    -------
    (N, 3) float64 array
        New positions ``x^n + dx`` (m).

    Raises
    ------
    ValueError
        If ``I - h dv/dx`` is singular for some particle, or shapes disagree.
    """
    from .validation import check_points

    x = check_points("positions", positions)
    v = check_points("velocity", velocity)
    jac = np.ascontiguousarray(jacobian, dtype=np.float64)
    if v.shape != x.shape or jac.shape != (x.shape[0], 3, 3):
        raise ValueError("velocity must be (N, 3) and jacobian (N, 3, 3) with N = len(positions)")
    h = _check_h(h)
    dx = np.empty_like(x)
    _implicit_advection(v, jac, h, dx)
    if not np.isfinite(dx).all():
        raise ValueError("I - h dv/dx is singular for some particle: reduce h")
    return x + dx


# ---------------------------------------------------------------------------------------------
SCHEMES = {
    "forward": forward_euler,
    "symplectic": symplectic_euler,
    "linearized": linearized_backward_euler,
    "newton": backward_euler,
}


def integrate(system, state, h, scheme="newton", **options):
    """Advance ``state`` by one step with the named scheme.

    Parameters
    ----------
    system, state, h
        As in :func:`forward_euler`.
    scheme : {"forward", "symplectic", "linearized", "newton"}
        Integration scheme.
    **options
        Passed to the scheme (solver options of the implicit ones).

    Returns
    -------
    StepInfo
    """
    check_choice("scheme", scheme, tuple(SCHEMES))
    return SCHEMES[scheme](system, state, h, **options)
